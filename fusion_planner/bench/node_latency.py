"""Goal-to-Path latency of the global planner node on a building floor, from another process.

Starts the ``global_planner`` node as a subprocess, publishes a generated
4000 x 4000 building floor (:mod:`building_map`, 0.05 m cells) and a start
pose, and once the node has accepted and prepared the map, publishes goals
one at a time and times each from publishing the goal to receiving the
non-empty Path that runs from the start to it. Beside each latency it
prints pyastar2d's search time on the same inflated grid for the same cells
(measured in this process right after the node's answer, so that both see
the same load on a shared machine; the median of :data:`PEER_REPEATS`),
their ratio, and the node's peak resident memory
(``VmHWM``) at the end.

Notes
-----
- The latency includes everything a user waits for: DDS delivery of the
  goal, the node's search, refinement and metrics, building and delivering
  the Path message. The Path is received as raw bytes: converting its
  thousands of poses into Python objects here happens after the clock stops
  (a C++ follower would not pay it; a Python one pays it once more). The map's preparation happens before, when the map arrives; its
  time is the node's log line "prepared for planning in ... s" and is
  reported as the wait for the map.
- The node runs with its defaults but ``robot_radius`` (0.2 m), the
  ``algorithm`` asked for, ``mark_obstacles`` off (no scans here) and
  ``pose_topic_type: odometry`` (the start pose is map-frame odometry).
- The node and this process talk on a DDS domain of their own
  (:func:`~fusion_planner.ros.domain.claim_private_domain`): on the shared
  default domain another process's map or Path would reach them.
- Needs ROS 2 (the ``ros`` extra or a sourced install) and, for the ratio,
  pyastar2d (the ``bench`` extra); both are checked before any work.
"""

import json
import os
import pathlib
import signal
import statistics
import subprocess
import sys
import tempfile
import time

import numpy as np

from fusion_planner.bench.building_map import BuildingSpec, building_map, far_pairs
from fusion_planner.cli.requirements import require
from fusion_planner.core.errors import InvalidInput
from fusion_planner.core.grid import GridMap
from fusion_planner.ros.domain import claim_private_domain

EXIT_OK, EXIT_FAILED, EXIT_BAD_INPUT = 0, 1, 2

#: Robot radius [m] of the node and of the peer's inflated grid.
ROBOT_RADIUS = 0.2
#: Least start-goal distance [m] by default.
MIN_DISTANCE_M = 100.0
#: Waits [s]: the node to start and prepare the map, one Path.
MAP_TIMEOUT_S = 180.0
PLAN_TIMEOUT_S = 120.0
#: pyastar2d's time per goal is the median of this many searches (one
#: search on a shared machine swings by 2x).
PEER_REPEATS = 3
#: Targets: latency over pyastar2d's search time, and the node's peak memory.
TARGET_OVER_PYASTAR = 3.0
TARGET_PEAK_MB = 1024.0
#: Largest distance [m] between a Path's last pose and the goal.
GOAL_MATCH_M = 0.1


def add_arguments(parser):
    """Options of ``fusion-planner bench node``."""
    parser.add_argument('--seeds', type=int, nargs='+', default=[1, 2], metavar='N',
                        help='building floors to generate (default: %(default)s)')
    parser.add_argument('--goals', type=int, default=2, metavar='N',
                        help='goals per floor (default: %(default)s)')
    parser.add_argument('--algorithm', default='improved', choices=('improved', 'astar'),
                        help='the node\'s algorithm parameter (default: %(default)s)')
    parser.add_argument('--side-m', type=float, default=BuildingSpec().side_m, metavar='M',
                        help='floor side [m] (default: %(default)s)')
    parser.add_argument('--min-distance', type=float, default=MIN_DISTANCE_M, metavar='M',
                        help='least start-goal distance [m] (default: %(default)s)')
    parser.add_argument('--json', action='store_true', help='print one JSON object')


def run(args):
    """Run the benchmark; 0 when every goal got its Path, 1 otherwise."""
    if args.goals < 1 or not args.seeds:
        raise InvalidInput('--goals must be positive and --seeds not empty')
    require('ros', 'bench node')
    require('bench', 'bench node (its pyastar2d ratio)', modules=('pyastar2d',))
    claim_private_domain()
    records = []
    for seed in args.seeds:
        try:
            records.append(measure_floor(seed, args.goals, args.algorithm, args.side_m,
                                         args.min_distance))
        except NodeFailed as err:
            print(f'error: floor {seed}: {err}', file=sys.stderr)
            return EXIT_FAILED
    report = {'algorithm': args.algorithm, 'floors': records}
    if args.json:
        print(json.dumps(report))
    else:
        print(format_report(report))
    ok = all(goal['latency_s'] is not None for floor in records for goal in floor['goals'])
    return EXIT_OK if ok else EXIT_FAILED


def measure_floor(seed, goals, algorithm, side_m, min_distance_m=MIN_DISTANCE_M):
    """Start a node, give it one floor and ``goals`` goals; return the figures.

    Returns
    -------
    dict
        ``seed``, ``map_wait_s`` (publishing the map until the node reports
        it accepted and prepared), ``goals`` (per goal ``distance_m``,
        ``latency_s`` or None, ``pyastar2d_s``, ``path_length_m``),
        ``peak_rss_mb`` of the node or None.
    """
    spec = BuildingSpec(side_m=side_m)
    grid = GridMap(building_map(spec, seed), spec.resolution)
    free = grid.traversable(ROBOT_RADIUS)
    start_cell, goal_cells = far_goals(free, goals, min_distance_m / spec.resolution, seed)
    start_xy = grid.world_of(start_cell)
    with NodeProcess(algorithm) as node, Client(grid) as client:
        t0 = time.perf_counter()
        client.publish_map()
        if not client.wait_for(lambda: client.map_accepted, MAP_TIMEOUT_S, node):
            raise NodeFailed(f'the node did not accept the map within {MAP_TIMEOUT_S:g} s'
                             + node.last_error())
        map_wait = time.perf_counter() - t0
        client.publish_start(start_xy)
        results = []
        for goal in goal_cells:
            goal_xy = grid.world_of(goal)
            latency, length = client.plan_to(goal_xy, PLAN_TIMEOUT_S, node)
            # right after the node's answer, so that both see the same load
            peer_s = pyastar2d_seconds(free, start_cell, goal)
            results.append({'distance_m': float(np.hypot(*(goal_xy - start_xy))),
                            'latency_s': latency, 'pyastar2d_s': peer_s,
                            'path_length_m': length})
        peak = node.peak_rss_mb()
    return {'seed': seed, 'map_wait_s': map_wait, 'goals': results, 'peak_rss_mb': peak}


def far_goals(free, count, min_distance_cells, seed):
    """A start cell and ``count`` goal cells reachable from it, each far from it.

    Returns
    -------
    start : tuple of int
    goals : list of tuple of int
    """
    from scipy import ndimage
    start = far_pairs(free, 1, min_distance_cells, seed)[0][0]
    labels, _ = ndimage.label(free)  # 4-connected: what 8-moves without corner cutting reach
    rows, cols = np.nonzero(labels == labels[start])
    far = np.hypot(rows - start[0], cols - start[1]) >= min_distance_cells
    rows, cols = rows[far], cols[far]
    picks = np.random.default_rng(seed).choice(len(rows), size=count, replace=False)
    return start, [(int(rows[i]), int(cols[i])) for i in picks]


def pyastar2d_seconds(free, start, goal):
    """pyastar2d's search time [s] on the inflated grid, the median of
    :data:`PEER_REPEATS` searches (the bench extra, checked by run)."""
    import pyastar2d

    weights = np.where(free, 1.0, np.inf).astype(np.float32)
    times = []
    for _ in range(PEER_REPEATS):
        t0 = time.perf_counter()
        pyastar2d.astar_path(weights, start, goal, allow_diagonal=True)
        times.append(time.perf_counter() - t0)
    return statistics.median(times)


class NodeFailed(Exception):
    """The node died or did not answer in time."""


class NodeProcess:
    """The global planner node in a subprocess (a context manager).

    Parameters
    ----------
    algorithm : str
        Its ``algorithm`` parameter.
    """

    def __init__(self, algorithm):
        root = str(pathlib.Path(__file__).resolve().parents[2])
        env = dict(os.environ)
        env['PYTHONPATH'] = root + os.pathsep + env.get('PYTHONPATH', '')
        self._log = tempfile.TemporaryFile(mode='w+')  # a pipe could fill and block the node
        self.process = subprocess.Popen(
            [sys.executable, '-m', 'fusion_planner.ros.global_planner', '--ros-args',
             '-p', f'robot_radius:={ROBOT_RADIUS}', '-p', f'algorithm:={algorithm}',
             '-p', 'mark_obstacles:=false', '-p', 'pose_topic_type:=odometry',
             '--log-level', 'warn'],
            env=env, stdout=subprocess.DEVNULL, stderr=self._log, text=True)

    def __enter__(self):
        return self

    def __exit__(self, *exc):
        if self.process.poll() is None:
            self.process.send_signal(signal.SIGINT)
            try:
                self.process.wait(timeout=10.0)
            except subprocess.TimeoutExpired:
                self.process.kill()
                self.process.wait()
        self._log.close()
        return False

    def alive(self):
        """Whether the node still runs."""
        return self.process.poll() is None

    def last_error(self):
        """How the node ended and its last log line, as a clause (``''`` if nothing)."""
        self._log.seek(0)
        lines = [line for line in self._log.read().splitlines() if line.strip()]
        status = '' if self.alive() else f'; the node exited with status {self.process.returncode}'
        return status + (f'; its last log line: {lines[-1]}' if lines else '')

    def peak_rss_mb(self):
        """Peak resident set size [MB] of the node so far (``VmHWM``), or None."""
        try:
            status = pathlib.Path(f'/proc/{self.process.pid}/status').read_text()
        except OSError:
            return None
        for line in status.splitlines():
            if line.startswith('VmHWM:'):
                return float(line.split()[1]) / 1024.0
        return None


class Client:
    """This process's ROS side: publishes map, start and goals, receives Paths.

    Parameters
    ----------
    grid : GridMap
        The floor, published as an OccupancyGrid in frame ``map``.
    """

    def __init__(self, grid):
        import rclpy
        from diagnostic_msgs.msg import DiagnosticArray
        from geometry_msgs.msg import PoseStamped
        from nav_msgs.msg import OccupancyGrid, Odometry, Path
        from rclpy.qos import DurabilityPolicy, QoSProfile, ReliabilityPolicy
        self._rclpy = rclpy
        self.grid = grid
        self.context = rclpy.Context()
        rclpy.init(context=self.context)
        self.node = rclpy.create_node('node_latency_client', context=self.context)
        latched = QoSProfile(depth=1, reliability=ReliabilityPolicy.RELIABLE,
                             durability=DurabilityPolicy.TRANSIENT_LOCAL)
        self.map_pub = self.node.create_publisher(OccupancyGrid, 'map', latched)
        self.odom_pub = self.node.create_publisher(Odometry, 'odom', 10)
        self.goal_pub = self.node.create_publisher(PoseStamped, 'goal_pose', 10)
        self.paths = []
        self.start_xy = None
        self.map_accepted = False
        # Raw bytes: the arrival is timed, not this process's conversion of
        # thousands of poses into Python objects (done after the clock stops).
        self.node.create_subscription(Path, 'plan', self._on_path, latched, raw=True)
        self._path_type = Path
        self.node.create_subscription(DiagnosticArray, 'diagnostics', self._on_diagnostics, 10)
        self.executor = rclpy.executors.SingleThreadedExecutor(context=self.context)
        self.executor.add_node(self.node)
        self._types = (PoseStamped, Odometry)

    def __enter__(self):
        return self

    def __exit__(self, *exc):
        self.executor.shutdown()
        self.node.destroy_node()
        self._rclpy.try_shutdown(context=self.context)
        return False

    def _on_path(self, data):
        self.paths.append((time.perf_counter(), data))

    def _on_diagnostics(self, msg):
        if any(status.message.startswith('map accepted') for status in msg.status):
            self.map_accepted = True

    def publish_map(self):
        """Publish the floor (latched)."""
        from fusion_planner.ros import conversions as conv
        self.map_pub.publish(conv.grid_map_to_occupancy_grid(
            self.grid, 'map', conv.seconds_to_stamp(0.0)))

    def publish_start(self, xy):
        """Publish the robot's pose as odometry, a few times (best effort)."""
        self.start_xy = np.asarray(xy, float)
        _, odometry = self._types
        msg = odometry()
        msg.header.frame_id = 'map'
        msg.child_frame_id = 'base_link'
        msg.pose.pose.position.x, msg.pose.pose.position.y = (float(v) for v in xy)
        msg.pose.pose.orientation.w = 1.0
        for _ in range(5):  # bounded
            self.odom_pub.publish(msg)
            self.executor.spin_once(timeout_sec=0.05)

    def plan_to(self, goal_xy, timeout_s, node):
        """Publish a goal; return (latency [s], path length [m]) or (None, None)."""
        from rclpy.serialization import deserialize_message

        from fusion_planner.ros import conversions as conv
        pose_stamped, _ = self._types
        msg = pose_stamped()
        msg.header.frame_id = 'map'
        msg.pose.position.x, msg.pose.position.y = (float(v) for v in goal_xy)
        msg.pose.orientation.w = 1.0
        seen = len(self.paths)
        t0 = time.perf_counter()
        self.goal_pub.publish(msg)
        path = None

        def arrived():
            nonlocal seen, path
            while seen < len(self.paths) and path is None:  # bounded: the paths received
                when, data = self.paths[seen]
                seen += 1
                received = deserialize_message(data, self._path_type)
                if not received.poses:
                    continue  # an empty Path: a failed plan (or the old goal's)
                points = conv.path_from_msg(received, 'map')
                if np.hypot(*(points[-1] - goal_xy)) <= GOAL_MATCH_M and \
                        np.hypot(*(points[0] - self.start_xy)) <= GOAL_MATCH_M:
                    path = (when, points)
            return path is not None

        if not self.wait_for(arrived, timeout_s, node):
            return None, None
        when, points = path
        return when - t0, float(np.hypot(*np.diff(points, axis=0).T).sum())

    def wait_for(self, condition, timeout_s, node):
        """Spin until ``condition()`` holds, the node dies or the time is up."""
        deadline = time.monotonic() + timeout_s
        while time.monotonic() < deadline and node.alive():  # bounded by the deadline
            if condition():
                return True
            self.executor.spin_once(timeout_sec=0.01)
        return condition()


def format_report(report):
    """The text report: per floor the map wait, per goal the latency beside pyastar2d."""
    lines = [f'global planner node, algorithm {report["algorithm"]}: goal -> Path latency '
             'measured from another process',
             f'{"floor":<8}{"goal":>6}{"dist [m]":>10}{"path [m]":>10}{"latency [s]":>13}'
             f'{"pyastar2d [s]":>15}{"ratio":>8}']
    ratios, peaks = [], []
    for floor in report['floors']:
        peaks.append(floor['peak_rss_mb'])
        for k, goal in enumerate(floor['goals']):
            latency, peer = goal['latency_s'], goal['pyastar2d_s']
            ratio = latency / peer if latency is not None and peer else None
            if ratio is not None:
                ratios.append(ratio)
            lines.append(
                f'{"s" + str(floor["seed"]):<8}{k:>6}{goal["distance_m"]:>10.1f}'
                f'{_fmt(goal["path_length_m"], ".1f"):>10}{_fmt(latency, ".3f"):>13}'
                f'{_fmt(peer, ".3f"):>15}{_fmt(ratio, ".2f"):>8}')
        lines.append(f'{"":<8}map sent to prepared: {floor["map_wait_s"]:.2f} s; node peak RSS '
                     f'{_fmt(floor["peak_rss_mb"], ".0f")} MB')
    if ratios:
        worst = max(ratios)
        lines.append(f'[{"met" if worst <= TARGET_OVER_PYASTAR else "NOT met"}] latency <= '
                     f'{TARGET_OVER_PYASTAR:g}x pyastar2d search: worst {worst:.2f}x, median '
                     f'{statistics.median(ratios):.2f}x')
    known = [p for p in peaks if p is not None]
    if known:
        lines.append(f'[{"met" if max(known) < TARGET_PEAK_MB else "NOT met"}] node peak RSS < '
                     f'{TARGET_PEAK_MB:.0f} MB: largest {max(known):.0f} MB')
    return '\n'.join(lines)


def _fmt(value, spec):
    return '-' if value is None else format(value, spec)
