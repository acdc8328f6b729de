"""``fusion-planner demo``: the three ROS 2 nodes driving a robot in the simulator.

Usage::

    fusion-planner demo [--scenario FILE] [--time-limit S] [--real-time-factor F]
        [--plot PNG] [--no-plot] [--gif GIF | --no-gif] [--record MCAP | --no-record]
        [--processes]

Runs ``simulator``, ``global_planner`` and ``local_planner`` headless on a
scenario (default: the bundled ``config/scenarios/demo.yaml``, with moving
obstacles and an obstacle the map does not show) until the robot arrives or
the simulated time limit passes:

- by default in this process, the three nodes in one executor
  (:func:`make_executor`; their callbacks are short);
- with ``--processes``, as three processes of the installed executables
  (``--ros-args --params-file config/params.yaml`` plus the scenario's robot
  as ``-p`` overrides), talking over DDS; their logs go beside the picture.

The simulator publishes the simulated time on ``/clock`` and the planners run
on it (``use_sim_time``), ``--real-time-factor`` times faster than the wall
clock at most. The three nodes run in lockstep (their ``lockstep``
parameter): each simulator step publishes one sensor set, the global planner
answers it with its plan, the local planner with a TwistStamped command
stamped alike, and only then does the world step on. The same scenario gives
the same run, step for step, at any real-time factor the machine sustains;
a slower machine just takes longer. While it runs, a progress line on stderr (redrawn in place on a
terminal, see :class:`~fusion_planner.cli.progress.StatusLine`) shows the
simulated time, the distance to the goal, the collisions so far and an
estimate of the wall time left (from the share of the straight-line
distance covered). At the end one outcome line goes to stdout (arrived,
simulated time, driven path length, collisions, minimum clearance); the
last progress line shows the same time. What happens after the simulated
time limit is not part of the run: the reported time never exceeds it.
The run is written out, each file beside the picture unless told otherwise:

- a picture (default ``output/demo.png``, ``--no-plot`` for none) and an
  animated GIF (``output/demo.gif``), drawn like ``fusion-planner sim
  --plot/--gif``;
- an MCAP recording (``output/demo.mcap``) of ``map``, ``plan``,
  ``plan_markers``, ``local_plan``, ``odom``, ``ground_truth``, ``amcl_pose``,
  ``scan``, ``obstacles``, ``cmd_vel``, ``goal_pose``, ``goal_outcome`` and
  ``/diagnostics`` in ROS 2 message encoding
  (CDR, ``ros2msg`` schemas), stamped with the simulated time, for Foxglove
  or ``ros2 bag play`` (see :mod:`fusion_planner.cli.recording`).

Before anything runs, the extras the chosen outputs need (``plot``,
``record``) and ROS 2 are checked and the output paths prepared
(:mod:`fusion_planner.cli.requirements`,
:mod:`fusion_planner.cli.output_paths`): a missing one is one line and exit
status 2.

Exit status: 0 the robot arrived without a collision, 1 it did not arrive or
collided, 2 bad input (unreadable scenario, ROS 2 or an extra not
importable, an output path that cannot be written). Every
ROS topic used is relative, so ``ROS_DOMAIN_ID`` keeps runs apart.
"""

import bisect
import math
import os
import pathlib
import signal
import subprocess
import sys
import threading
import time
from dataclasses import fields

import numpy as np

from fusion_planner.cli.output_paths import prepare_file, prepare_folder
from fusion_planner.cli.progress import StatusLine, eta_s, format_duration
from fusion_planner.cli.recording import DefinitionNotFound, TopicRecorder
from fusion_planner.cli.requirements import require
from fusion_planner.core.errors import InvalidInput
from fusion_planner.core.simulation.scenario import load_scenario
from fusion_planner.core.simulation.episodes import follower_params

EXIT_OK, EXIT_FAILED, EXIT_BAD_INPUT = 0, 1, 2

#: Default picture of the run.
DEFAULT_PLOT = pathlib.Path('output') / 'demo.png'
#: Folder of the node logs with ``--processes``, beside the picture.
LOG_FOLDER = 'demo_logs'
#: Default speed-up of simulated time over wall time [1].
DEFAULT_REAL_TIME_FACTOR = 10.0
#: Wall period of the progress line [s].
PROGRESS_PERIOD_S = 0.25
#: Wall period of the simulator's diagnostics during the demo [s].
SIMULATOR_STATUS_PERIOD_S = 0.25
#: Wall time without the simulated clock advancing after which the run is
#: abandoned [s].
CLOCK_STALL_S = 30.0
#: The simulator's ``lockstep_timeout`` in the demo [s]: a machine that
#: stalls a node for seconds slows the run down instead of changing it (the
#: world running free); below :data:`CLOCK_STALL_S`, so a node that never
#: answers still ends in a report, not a hang.
LOCKSTEP_TIMEOUT_S = 20.0
#: Wall time allowed on top of ``time limit / real-time factor`` [s] (start-up,
#: discovery, a slower machine).
WALL_SLACK_S = 60.0
#: Wall time the final simulator status is waited for after the end [s].
FINAL_STATUS_WAIT_S = 3.0
#: Wall time a node process gets to exit after SIGINT before it is killed [s].
PROCESS_STOP_TIMEOUT_S = 10.0
#: Wall time the executor gets to finish its callbacks when stopping [s].
SPIN_STOP_TIMEOUT_S = 5.0
#: Timeout of one ``spin_once`` of the background spinner [s].
SPIN_POLL_S = 0.05
#: Slack of the time-limit comparisons [s] (float stamps).
TIME_EPS_S = 1e-6
#: Node names of the package, in start order.
NODES = ('simulator', 'global_planner', 'local_planner')
#: Queue depth of the recorder's subscriptions [messages] (deep: a busy
#: executor must not lose messages before they are written).
RECORD_DEPTH = 100


def add_parser(subparsers):
    """Register the ``demo`` sub-command."""
    parser = subparsers.add_parser(
        'demo', help='run the three ROS 2 nodes on a simulated scenario',
        description='Run simulator, global_planner and local_planner headless on a scenario '
                    'with moving obstacles until the robot arrives or the time limit passes; '
                    'print the outcome and draw the run. Exit status: 0 arrived without '
                    'collision, 1 otherwise, 2 bad input.')
    parser.add_argument('--scenario', metavar='FILE',
                        help='scenario YAML (default: the bundled config/scenarios/demo.yaml)')
    parser.add_argument('--time-limit', type=float, metavar='S',
                        help="simulated time limit [s] "
                             "(default: the scenario's limits.time_limit_s)")
    parser.add_argument('--real-time-factor', type=float, default=DEFAULT_REAL_TIME_FACTOR,
                        metavar='F',
                        help='simulated seconds per wall second (default: %(default)s)')
    parser.add_argument('--plot', default=str(DEFAULT_PLOT), metavar='PNG',
                        help='picture of the run (default: %(default)s)')
    parser.add_argument('--no-plot', action='store_true',
                        help='do not draw the picture (the other files still go beside '
                             'its path)')
    gif = parser.add_mutually_exclusive_group()
    gif.add_argument('--gif', metavar='GIF',
                     help='animation of the run (default: beside the picture, as .gif)')
    gif.add_argument('--no-gif', action='store_true', help='do not write the animation')
    record = parser.add_mutually_exclusive_group()
    record.add_argument('--record', metavar='MCAP',
                        help='record the topics to an MCAP file (default: beside the picture, '
                             'as .mcap)')
    record.add_argument('--no-record', action='store_true', help='do not record the topics')
    parser.add_argument('--processes', action='store_true',
                        help='run the nodes as three processes of the installed executables '
                             'instead of one executor in this process')
    parser.set_defaults(func=run)
    return parser


# -- wiring -----------------------------------------------------------------------

def node_parameters(scenario, scenario_path, real_time_factor):
    """Parameter overrides that set the three nodes up for a scenario.

    Parameters
    ----------
    scenario : Scenario
    scenario_path : str or os.PathLike
        The file the simulator loads.
    real_time_factor : float
        Simulated seconds per wall second.

    Returns
    -------
    dict
        ``{node name: {parameter: value}}``; values typed as the nodes
        declare them (floats stay floats). The three nodes run in lockstep
        (stamped commands); the planners on simulated time;
        the robot radius, speed limits and follower tuning come from the
        scenario (:func:`~fusion_planner.core.simulation.episodes.follower_params`), the
        control and simulation rates from its ``limits.dt``.

    Raises
    ------
    InvalidInput
        If the scenario's follower overrides are invalid.
    """
    from fusion_planner.ros import global_planner, local_planner, simulator

    rate = 1.0 / scenario.limits.dt
    planner = scenario.planner
    follower = follower_params(scenario)
    local = {f.name: getattr(follower, f.name) for f in fields(follower)
             if f.name not in ('apf', 'control_period')}
    local.update({local_planner.APF_PREFIX + f.name: getattr(follower.apf, f.name)
                  for f in fields(follower.apf) if f.name != 'robot_radius'})
    local.update(control_rate=rate, lockstep=True, enable_stamped_cmd_vel=True)
    values = {
        'simulator': {'scenario': str(scenario_path), 'rate': rate,
                      'real_time_factor': float(real_time_factor), 'publish_goal': True,
                      'lockstep': True, 'enable_stamped_cmd_vel': True, 'start_paused': True,
                      'lockstep_timeout': LOCKSTEP_TIMEOUT_S,
                      'diagnostics_period': SIMULATOR_STATUS_PERIOD_S},
        'global_planner': {'lockstep': True,
                           'algorithm': planner.algorithm, 'neighbourhood': planner.neighbourhood,
                           'alpha': planner.alpha, 'beta': planner.beta, 'gamma': planner.gamma,
                           'refine': planner.refine, 'robot_radius': planner.robot_radius,
                           'safety_distance': planner.safety_distance},
        'local_planner': local,
    }
    specs = {'simulator': simulator.PARAMETER_SPECS,
             'global_planner': global_planner.PARAMETER_SPECS,
             'local_planner': local_planner.PARAMETER_SPECS}
    typed = {}
    for node, params in values.items():
        kinds = {s.name: type(s.default) for s in specs[node]}
        # a core field the node does not declare keeps the node's default
        typed[node] = {name: kinds[name](value) for name, value in params.items() if name in kinds}
        if node != 'simulator':
            typed[node]['use_sim_time'] = True
    return typed


def ros_arg_overrides(params):
    """``-p name:=value`` arguments for ``--ros-args`` (YAML-typed values).

    Examples
    --------
    >>> ros_arg_overrides({'rate': 20.0, 'publish_goal': True, 'neighbourhood': 8})
    ['-p', 'rate:=20.0', '-p', 'publish_goal:=true', '-p', 'neighbourhood:=8']
    """
    out = []
    for name, value in params.items():
        if isinstance(value, bool):
            text = 'true' if value else 'false'
        elif isinstance(value, float):
            text = repr(value)
        else:
            text = str(value)
        out += ['-p', f'{name}:={text}']
    return out


def node_command(node):
    """The command line that starts a node's process.

    The console script installed beside this Python (a pip install into the
    same environment), else ``python -m fusion_planner.ros.<node>`` (a source
    tree or a colcon workspace, whose scripts live in lib/fusion_planner).
    """
    script = pathlib.Path(sys.executable).parent / node
    if script.is_file() and os.access(script, os.X_OK):
        return [str(script)]
    return [sys.executable, '-m', f'fusion_planner.ros.{node}']


# -- watching -----------------------------------------------------------------------

def _seconds(stamp):
    """A ``builtin_interfaces/Time`` in seconds."""
    return stamp.sec + stamp.nanosec * 1e-9


class RunRecorder:
    """What the demo watches of a run, fed with ROS messages (no rclpy needed).

    Parameters
    ----------
    scenario : Scenario
        Gives the goal and the number of moving obstacles.
    goal_tolerance : float
        The local planner's arrival radius [m].
    time_limit_s : float, optional
        Simulated time limit [s]: the run ends there, so later messages
        (odometry, obstacles, statuses, an arrival) are not recorded and the
        simulated time stops at it. Default: none.

    Notes
    -----
    Methods are called from executor threads and read from the main thread;
    a lock guards the state.
    """

    def __init__(self, scenario, goal_tolerance, time_limit_s=math.inf):
        self.scenario = scenario
        self.time_limit_s = float(time_limit_s)
        self.ended = False  # the clock passed the limit, or end() was called
        self.goal = np.asarray(scenario.goal, dtype=float)
        # The plan ends at the centre of the goal's cell, up to half a cell
        # diagonal from the goal; one diagonal of slack covers that.
        self.arrival_radius = float(goal_tolerance) + math.sqrt(2.0) * scenario.grid.resolution
        self._lock = threading.Lock()
        self.sim_time = 0.0
        self.clock_wall = time.monotonic()  # wall time the clock last advanced
        self.started_wall = None  # wall time the simulated clock was first seen moving
        self.started_sim = 0.0  # the simulated time then [s] (late when discovery was slow)
        self.arrived_wall = None  # wall time the arrival was seen
        self.poses = []        # (x, y, yaw)
        self.pose_times = []   # simulated stamp of each pose [s]
        self.tracks = []       # (K, 2) per obstacle message
        self.track_times = []  # simulated stamp of each obstacle message [s]
        self.escape_points = []  # (x, y) where the local planner reported a new stuck event
        self.stuck_events = 0
        self.plan = None       # the latest non-empty plan, (N, 2)
        self.plans = []        # every non-empty plan, oldest first
        self.planner_status = {}
        self.local_status = {}
        self.sim_status = {}
        self.sim_status_wall = 0.0
        self.arrived_at = None  # simulated time of arrival [s]
        self._arrival_claim = None  # stamp of an 'arrived' status still to be judged [s]
        self.failure = None

    def end(self):
        """End the run now: what comes later is not recorded (the limit becomes now)."""
        with self._lock:
            self.time_limit_s = min(self.time_limit_s, self.sim_time)
            self.ended = True

    def past_limit(self, t):
        """Whether simulated time ``t`` [s] lies after the time limit."""
        return t > self.time_limit_s + TIME_EPS_S

    def on_clock(self, msg):
        t = _seconds(msg.clock)
        with self._lock:
            self.ended = self.ended or self.past_limit(t)
            t = min(t, self.time_limit_s)
            if t != self.sim_time:
                self.clock_wall = time.monotonic()
                if self.started_wall is None:
                    self.started_wall, self.started_sim = self.clock_wall, t
            self.sim_time = t

    def on_ground_truth(self, msg):
        """The true pose (map frame): what the plots, metrics and arrival judge."""
        if self.past_limit(_seconds(msg.header.stamp)):
            return
        p = msg.pose.pose
        yaw = 2.0 * math.atan2(p.orientation.z, p.orientation.w)
        with self._lock:
            self.poses.append((p.position.x, p.position.y, yaw))
            self.pose_times.append(_seconds(msg.header.stamp))
            self._judge_arrival()

    def on_obstacles(self, msg):
        if msg.markers and self.past_limit(_seconds(msg.markers[0].header.stamp)):
            return
        k = len(self.scenario.moving_obstacles)
        positions = np.full((k, 2), np.nan)
        for marker in msg.markers:
            if 0 <= marker.id < k:
                positions[marker.id] = (marker.pose.position.x, marker.pose.position.y)
        with self._lock:
            if self.tracks and np.isnan(positions).any():
                positions = np.where(np.isnan(positions), self.tracks[-1], positions)
            self.tracks.append(positions)
            self.track_times.append(_seconds(msg.markers[0].header.stamp) if msg.markers
                                    else self.sim_time)

    def on_plan(self, msg):
        """A non-empty plan; the same plan again (a lockstep answer) is not a new one."""
        if len(msg.poses):
            plan = np.array([(q.pose.position.x, q.pose.position.y) for q in msg.poses])
            with self._lock:
                if self.plan is None or not np.array_equal(plan, self.plan):
                    self.plan = plan
                    self.plans.append(plan)

    def on_diagnostics(self, msg, namespace='/'):
        """Take the statuses of the nodes under ``namespace`` from ``/diagnostics``."""
        stamp = _seconds(msg.header.stamp)  # sender's clock
        prefix = namespace.rstrip('/') + '/'
        with self._lock:
            if self.ended:
                return  # nothing after the limit counts
        for status in msg.status:
            values = {kv.key: kv.value for kv in status.values}
            with self._lock:
                if status.name == prefix + 'local_planner':
                    self.local_status = values
                    stuck = int(values.get('stuck_events', 0))
                    if stuck > self.stuck_events and self.poses:
                        # reported as it happens: the robot is where it was last seen
                        self.escape_points.append(self.poses[-1][:2])
                    self.stuck_events = max(self.stuck_events, stuck)
                    if values.get('status') == 'arrived' and self.arrived_at is None \
                            and not self.past_limit(stamp):
                        self._arrival_claim = stamp  # the local planner runs on simulated time
                        self._judge_arrival()
                    if values.get('status') == 'failed':
                        self.failure = f'local planner failed: {values.get("last_error", "")}'
                elif status.name == prefix + 'global_planner':
                    self.planner_status = values
                elif status.name == prefix + 'simulator':
                    self.sim_status = values
                    self.sim_status_wall = time.monotonic()

    def _judge_arrival(self):
        """Accept a claimed arrival once the true pose of its time is in (lock held).

        The status and the ground truth come on different topics, in either
        order: the claim waits for the pose stamped at or after it, and is
        judged on the pose of its own time.
        """
        claim = self._arrival_claim
        if claim is None or not self.pose_times or self.pose_times[-1] < claim - TIME_EPS_S:
            return
        self._arrival_claim = None
        x, y, _ = self.poses[max(bisect.bisect_right(self.pose_times, claim + TIME_EPS_S) - 1, 0)]
        if math.hypot(x - self.goal[0], y - self.goal[1]) <= self.arrival_radius:
            self.arrived_at = claim
            self.arrived_wall = time.monotonic()

    def real_time_factor(self):
        """Simulated over wall time from the first clock tick seen to arrival (or now); NaN before."""
        with self._lock:
            if self.started_wall is None:
                return math.nan
            end = self.arrived_wall if self.arrived_wall is not None else time.monotonic()
            sim_end = self.arrived_at if self.arrived_at is not None else self.sim_time
        return (sim_end - self.started_sim) / max(end - self.started_wall, 1e-9)

    def distance_to_goal(self):
        """Distance [m] from the last true pose to the goal (inf before any)."""
        if not self.poses:
            return math.inf
        x, y, _ = self.poses[-1]
        return float(math.hypot(x - self.goal[0], y - self.goal[1]))

    def collisions(self):
        """Contact events reported by the simulator so far."""
        with self._lock:
            return int(self.sim_status.get('collisions', 0))

    def snapshot(self):
        """``(sim time [s], distance to goal [m], collisions)`` now; the time stops at arrival."""
        with self._lock:
            sim_time = self.arrived_at if self.arrived_at is not None else self.sim_time
            return sim_time, self.distance_to_goal(), int(self.sim_status.get('collisions', 0))

    def result(self, reached, failure):
        """An :class:`~fusion_planner.core.simulation.episodes.EpisodeResult` of the run (for the figure)."""
        from fusion_planner.core.simulation.episodes import EpisodeResult
        from fusion_planner.ros.local_planner import key_nodes_of

        with self._lock:
            trajectory = np.array(self.poses, dtype=float).reshape(-1, 3)
            tracks = self._tracks_at(self.pose_times)
            escapes = np.array(self.escape_points, dtype=float).reshape(-1, 2)
            sim = dict(self.sim_status)
            local = dict(self.local_status)
            plan = self.plan
            time_s = self.arrived_at if self.arrived_at is not None else self.sim_time
        odom_length = float(np.sum(np.hypot(*np.diff(trajectory[:, :2], axis=0).T))) \
            if len(trajectory) > 1 else 0.0
        return EpisodeResult(
            scenario=self.scenario.name, controller=str(local.get('controller', 'fusion')),
            seed=self.scenario.seed, reached=reached,
            collisions=int(sim.get('collisions', 0)), time_s=time_s,
            # the simulator's count lags by up to a status period; odometry may miss
            # messages: the larger is the more recent
            path_length_m=max(float(sim.get('distance_travelled_m', 0.0)), odom_length),
            min_clearance_m=float(sim.get('min_clearance_m', 'nan')),
            stuck_events=int(local.get('stuck_events', 0)), failure=failure,
            plan_length_m=None if plan is None else
            float(np.sum(np.hypot(*np.diff(plan, axis=0).T))),
            trajectory=trajectory, obstacle_tracks=tracks, plan_path=plan,
            key_nodes=None if plan is None else key_nodes_of(plan), escape_points=escapes)

    def _tracks_at(self, times):
        """Obstacle centres (T, K, 2) [m] last seen at or before each of ``times`` [s].

        None without obstacle messages; before the first one, its positions.
        Call with the lock held.
        """
        if not self.tracks:
            return None
        k = len(self.scenario.moving_obstacles)
        tracks = np.array(self.tracks, dtype=float).reshape(-1, k, 2)
        index = np.searchsorted(np.asarray(self.track_times), np.asarray(times), side='right') - 1
        return tracks[np.clip(index, 0, len(tracks) - 1)]


def attach_recorder(node, recorder):
    """Subscribe a (monitor) node's topics into a :class:`RunRecorder`.

    Returns the ``/diagnostics`` subscription (see :func:`goal_when_heard`).
    """
    from diagnostic_msgs.msg import DiagnosticArray
    from nav_msgs.msg import Odometry, Path
    from rosgraph_msgs.msg import Clock
    from visualization_msgs.msg import MarkerArray

    from fusion_planner.ros.diagnostics import DIAGNOSTICS_TOPIC
    from fusion_planner.ros.qos import LATCHED_QOS, RELIABLE_QOS

    node.create_subscription(Clock, 'clock', recorder.on_clock, 10)
    node.create_subscription(Odometry, 'ground_truth', recorder.on_ground_truth, RELIABLE_QOS)
    node.create_subscription(MarkerArray, 'obstacles', recorder.on_obstacles, 10)
    node.create_subscription(Path, 'plan', recorder.on_plan, LATCHED_QOS)
    namespace = node.get_namespace()
    return node.create_subscription(DiagnosticArray, DIAGNOSTICS_TOPIC,
                                    lambda msg: recorder.on_diagnostics(msg, namespace), 50)


# -- running ------------------------------------------------------------------------

def namespace_ros_args(namespace):
    """``--ros-args`` rules that put a node under ``namespace`` with its own clock.

    rclpy's time source listens on the absolute ``/clock``, and the simulator
    publishes the relative ``clock``; under a namespace ``/robot1`` the rule
    ``/clock:=clock`` makes the nodes follow ``/robot1/clock``, so two
    simulated robots keep two clocks apart.

    Examples
    --------
    >>> namespace_ros_args('/robot1')
    ['-r', '__ns:=/robot1', '-r', '/clock:=clock']
    """
    return ['-r', f'__ns:={namespace}', '-r', '/clock:=clock']


def make_nodes(context, params, ros_args=()):
    """The three nodes for ``params`` (see :func:`node_parameters`) in one context.

    Parameters
    ----------
    context : rclpy.Context
    params : dict
        ``{node name: {parameter: value}}``.
    ros_args : sequence of str
        ROS arguments of every node, as after ``--ros-args`` on a command line
        (e.g. :func:`namespace_ros_args`).

    Returns
    -------
    list of rclpy.node.Node
        Simulator, global planner, local planner. Destroy them when done.
    """
    from rclpy.parameter import Parameter

    from fusion_planner.ros.global_planner import GlobalPlannerNode
    from fusion_planner.ros.local_planner import LocalPlannerNode
    from fusion_planner.ros.simulator import SimulatorNode

    classes = {'simulator': SimulatorNode, 'global_planner': GlobalPlannerNode,
               'local_planner': LocalPlannerNode}
    nodes = []
    try:
        for name in NODES:
            overrides = [Parameter(k, value=v) for k, v in params[name].items()]
            cli_args = ['--ros-args', *ros_args] if ros_args else None
            nodes.append(classes[name](context=context, parameter_overrides=overrides,
                                       cli_args=cli_args))
    except BaseException:
        for node in nodes:
            node.destroy_node()
        raise
    return nodes


def start_processes(params, params_file, log_dir, extra_ros_args=(), env=None):
    """Start the three node processes.

    Parameters
    ----------
    params : dict
        ``{node name: {parameter: value}}`` passed as ``-p`` overrides.
    params_file : str or os.PathLike
        Passed as ``--params-file``.
    log_dir : pathlib.Path
        Each process writes ``<node>.log`` (stdout and stderr) here.
    extra_ros_args : sequence of str
        Appended after ``--ros-args`` (e.g. ``-r __ns:=/robot1``).
    env : dict, optional
        Environment; default this process's.

    Returns
    -------
    list of (str, subprocess.Popen, pathlib.Path)
        Node name, process and log file of each.
    """
    log_dir.mkdir(parents=True, exist_ok=True)
    procs = []
    for name in NODES:
        cmd = node_command(name) + ['--ros-args', '--params-file', str(params_file),
                                    *extra_ros_args, *ros_arg_overrides(params[name])]
        log_path = log_dir / f'{name}.log'
        with open(log_path, 'wb') as log:
            procs.append((name, subprocess.Popen(cmd, stdout=log, stderr=subprocess.STDOUT,
                                                 env=env), log_path))
    return procs


def stop_processes(procs, timeout_s=PROCESS_STOP_TIMEOUT_S):
    """SIGINT every process, wait, kill what is left; returns ``{node: exit code}``."""
    for _, proc, _ in procs:
        if proc.poll() is None:
            proc.send_signal(signal.SIGINT)
    codes = {}
    deadline = time.monotonic() + timeout_s
    for name, proc, _ in procs:
        try:
            codes[name] = proc.wait(timeout=max(deadline - time.monotonic(), 0.1))
        except subprocess.TimeoutExpired:
            proc.kill()
            codes[name] = proc.wait()
    return codes


def watch(recorder, time_limit_s, wall_limit_s, alive=lambda: None, progress=None,
          tick=lambda: None):
    """Wait until arrival, failure, the simulated time limit or a stall.

    Parameters
    ----------
    recorder : RunRecorder
    time_limit_s : float
        Simulated time limit [s].
    wall_limit_s : float
        Wall time limit [s].
    alive : callable
        Returns None while the nodes run, else a sentence why they stopped.
    progress : callable, optional
        ``progress(sim_time, distance, collisions)`` every
        :data:`PROGRESS_PERIOD_S`.
    tick : callable, optional
        Called every :data:`PROGRESS_PERIOD_S` (e.g. a :func:`goal_when_heard`).

    Returns
    -------
    str or None
        None on arrival, else the failure sentence.
    """
    start = time.monotonic()
    for _ in range(int(wall_limit_s / PROGRESS_PERIOD_S) + 1):
        sim_time, distance, collisions = recorder.snapshot()
        if progress is not None:
            progress(sim_time, distance, collisions)
        if recorder.arrived_at is not None:
            return None
        if recorder.failure is not None:
            return recorder.failure
        if sim_time >= time_limit_s:
            return (f'time_limit: the goal was not reached within {time_limit_s:g} s '
                    'of simulated time')
        stopped = alive()
        if stopped is not None:
            return stopped
        tick()
        if time.monotonic() - recorder.clock_wall > CLOCK_STALL_S:
            return f'the simulated clock has not advanced for {CLOCK_STALL_S:g} s of wall time'
        if time.monotonic() - start > wall_limit_s:
            break
        time.sleep(PROGRESS_PERIOD_S)
    return f'wall time limit of {wall_limit_s:.0f} s reached'


def goal_when_heard(node, diagnostics_sub, recorder, goal):
    """A ``tick`` for :func:`watch` that sends ``goal`` once the monitor hears every node.

    With the nodes in other processes, DDS discovery can take longer than a
    fast run: the monitor sends the goal itself (the simulator's
    ``publish_goal`` off) once it has heard the simulator's ground truth
    and its ``/diagnostics`` subscription ``diagnostics_sub`` hears the
    three nodes (:func:`nodes_heard`). The world is held until the first plan, so
    nothing of the run is missed: neither the first poses nor a status.
    """
    from geometry_msgs.msg import PoseStamped

    from fusion_planner.ros.conversions import seconds_to_stamp
    from fusion_planner.ros.goal_sender import GoalSender
    from fusion_planner.ros.qos import RELIABLE_QOS

    sender = GoalSender(node.create_publisher(PoseStamped, 'goal_pose', RELIABLE_QOS))

    def tick():
        if recorder.plan is not None:
            sender.on_plan()
        elif recorder.pose_times and nodes_heard(node, diagnostics_sub):
            # in the simulator's default frame, which the demo keeps
            sender.poll(goal, 'map', seconds_to_stamp(recorder.sim_time))
    return tick


def nodes_heard(node, diagnostics_sub):
    """Whether ``diagnostics_sub`` of ``node`` hears the three nodes in its namespace.

    The graph must know a ``/diagnostics`` publisher of each of
    :data:`NODES` under ``node``'s namespace (a graph entry comes before
    its match), and the subscription must be matched to at least as many
    publishers. Publishers are looked up by topic, not by node name: a node
    of a process that has just ended can stay in the graph under the same
    name, unmatched, for a while.
    """
    from fusion_planner.ros.diagnostics import DIAGNOSTICS_TOPIC

    namespace = node.get_namespace()
    publishers = {(info.node_name, info.node_namespace)
                  for info in node.get_publishers_info_by_topic(DIAGNOSTICS_TOPIC)}
    return (all((name, namespace) in publishers for name in NODES)
            and diagnostics_sub.get_publisher_count() >= len(NODES))


class Spinner:
    """Spin an executor in a background thread until :meth:`stop`.

    Parameters
    ----------
    executor : rclpy.executors.Executor
        With its nodes added.

    Notes
    -----
    The thread calls ``spin_once`` with a short timeout, so :meth:`stop`
    returns within :data:`SPIN_POLL_S` plus the callback in progress, and
    the nodes can be destroyed safely afterwards.

    Give it a single-threaded executor (:func:`make_executor`): rclpy 7.1's
    ``MultiThreadedExecutor`` busy-waits on a callback group whose callback
    is still running and starves the callbacks themselves of the GIL (the
    closed loop ran at 0.2x real time with it, 6x with one thread).
    """

    def __init__(self, executor):
        self.executor = executor
        self._stop = threading.Event()
        self.error = None
        self._thread = threading.Thread(target=self._run, name='spinner', daemon=True)
        self._thread.start()

    def _run(self):
        from rclpy.executors import ExternalShutdownException

        try:
            while not self._stop.is_set():
                self.executor.spin_once(timeout_sec=SPIN_POLL_S)
        except (ExternalShutdownException, KeyboardInterrupt):
            pass
        except Exception as err:  # noqa: BLE001 - reported by whoever stops us
            self.error = err

    def stop(self):
        """Stop spinning and wait for every callback in progress (bounded)."""
        self._stop.set()
        self._thread.join(timeout=SPIN_STOP_TIMEOUT_S)
        self.executor.shutdown(timeout_sec=SPIN_STOP_TIMEOUT_S)


def make_executor(context):
    """A single-threaded executor for nodes in this process.

    rclpy's EventsExecutor (its C++ event queue, rather than a wait set
    rebuilt in Python on every spin: the lockstep demo ran 1.4x faster with
    it, 6.7-7.1x against 4.2-5.1x real time at ``--real-time-factor 1000`` on
    a busy machine), else ``SingleThreadedExecutor`` where this rclpy lacks
    it.
    """
    try:
        from rclpy.experimental import EventsExecutor
    except ImportError:
        from rclpy.executors import SingleThreadedExecutor
        return SingleThreadedExecutor(context=context)
    return EventsExecutor(context=context)


def shutdown_executor(spinner, nodes, context=None):
    """Stop spinning, destroy the nodes, shut the context down (each step optional)."""
    import rclpy

    if spinner is not None:
        spinner.stop()
    for node in nodes:
        node.destroy_node()
    if context is not None:
        rclpy.try_shutdown(context=context)


def wait_final_status(recorder, after_wall):
    """Wait (bounded) for a simulator status newer than ``after_wall`` (monotonic [s])."""
    deadline = time.monotonic() + FINAL_STATUS_WAIT_S
    while time.monotonic() < deadline and recorder.sim_status_wall <= after_wall:
        time.sleep(0.05)


def run(args):
    """Run the demo; returns the exit status (see the module docstring)."""
    require('ros', 'demo')
    plot_path, gif_path, mcap_path = prepare_outputs(args)
    log_dir = pathlib.Path(args.plot).parent / LOG_FOLDER
    if args.processes:
        prepare_folder(log_dir, '--processes logs')
    import rclpy

    from fusion_planner.ros.simulator import default_scenario_path, share_file

    if not (args.real_time_factor > 0 and math.isfinite(args.real_time_factor)):
        raise InvalidInput(
            f'--real-time-factor must be a positive number, got {args.real_time_factor!r}')
    scenario_path = pathlib.Path(args.scenario or default_scenario_path()).resolve()
    scenario = load_scenario(scenario_path)
    time_limit = scenario.limits.time_limit_s if args.time_limit is None else args.time_limit
    if not (time_limit > 0 and math.isfinite(time_limit)):
        raise InvalidInput(f'--time-limit must be a positive number of seconds, got {time_limit!r}')
    params = node_parameters(scenario, scenario_path, args.real_time_factor)
    recorder = RunRecorder(scenario, params['local_planner']['goal_tolerance'], time_limit)
    wall_limit = time_limit / args.real_time_factor * 3.0 + WALL_SLACK_S
    mode = 'three processes' if args.processes else 'one process'
    print(f"demo: scenario '{scenario.name}' ({scenario_path}), {mode}, "
          f'real-time factor {args.real_time_factor:g}, time limit {time_limit:g} s',
          file=sys.stderr)
    start_distance = math.hypot(scenario.start[0] - scenario.goal[0],
                                scenario.start[1] - scenario.goal[1])

    status_line = StatusLine()

    def progress(sim_time, distance, collisions, force=False):
        started = recorder.started_wall
        elapsed = 0.0 if started is None else time.monotonic() - started
        eta = eta_s(elapsed, min(max(1.0 - distance / max(start_distance, 1e-9), 0.0), 1.0))
        status_line.show(f'  sim {sim_time:7.2f} s   distance to goal {distance:6.2f} m   '
                         f'collisions {collisions}   ETA {format_duration(eta)}', force)

    context = rclpy.Context()
    # Ctrl-C stays a KeyboardInterrupt here: the finally below stops everything.
    rclpy.init(context=context, signal_handler_options=rclpy.signals.SignalHandlerOptions.NO)
    wall_start = time.monotonic()
    procs, nodes, spinner, topic_recorder = [], [], None, None
    try:
        from rclpy.node import Node
        from rclpy.parameter import Parameter

        # on simulated time: the recording is stamped with it
        nodes.append(Node('demo_monitor', context=context,
                          parameter_overrides=[Parameter('use_sim_time', value=True)]))
        diagnostics_sub = attach_recorder(nodes[0], recorder)
        if mcap_path is not None:
            topic_recorder = start_recording(nodes[0], mcap_path)
        executor = make_executor(context)
        executor.add_node(nodes[0])
        tick = lambda: None  # noqa: E731 - nothing to do each poll in one process
        if args.processes:
            params['simulator']['publish_goal'] = False
            tick = goal_when_heard(nodes[0], diagnostics_sub, recorder, scenario.goal)
            procs = start_processes(params, share_file('config/params.yaml'), log_dir)

            def alive():
                for name, proc, log_path in procs:
                    if proc.poll() is not None:
                        return f'node {name} exited with code {proc.returncode} (log: {log_path})'
                return None
        else:
            nodes += make_nodes(context, params)
            for node in nodes[1:]:  # keep the progress line readable: warnings and errors only
                node.get_logger().set_level(rclpy.logging.LoggingSeverity.WARN)
            for node in nodes[1:]:
                executor.add_node(node)

            def alive():
                return None if context.ok() else 'ROS was shut down'
        spinner = Spinner(executor)
        failure = watch(recorder, time_limit, wall_limit, alive, progress, tick)
        end_wall = time.monotonic()
        if failure is None:
            wait_final_status(recorder, end_wall)  # collisions and distance at the end
        recorder.end()
        progress(*recorder.snapshot(), force=True)  # the time of the outcome line
        wall_time = end_wall - wall_start
    finally:
        status_line.close()
        codes = stop_processes(procs) if procs else {}
        shutdown_executor(spinner, nodes, context)
        if topic_recorder is not None:
            counts = topic_recorder.close()
    reached = failure is None
    result = recorder.result(reached, failure)
    collided = result.collisions > 0
    clearance = (f'{result.min_clearance_m:.3f} m' if math.isfinite(result.min_clearance_m)
                 else 'n/a')
    print(f"arrived: {'yes' if reached else 'no'}   sim time: {result.time_s:.2f} s   "
          f'(wall {wall_time:.1f} s with start-up, {recorder.real_time_factor():.1f}x real time)   '
          f'path length: {result.path_length_m:.2f} m   collisions: {result.collisions}   '
          f'min clearance: {clearance}')
    if failure is not None:
        print(f'not arrived: {failure}', file=sys.stderr)
    bad_exits = {name: code for name, code in codes.items() if code != 0}
    if bad_exits:
        print(f'node processes exited with {bad_exits} (logs in {log_dir})', file=sys.stderr)
    _draw(scenario, result, plot_path, gif_path)
    if topic_recorder is not None:
        print(f'recording: {mcap_path} ({sum(counts.values())} messages on '
              f'{sum(1 for n in counts.values() if n)} topics)', file=sys.stderr)
    return EXIT_OK if reached and not collided else EXIT_FAILED


def output_paths(args):
    """The picture, animation and recording files of a run (None: not wanted).

    Returns
    -------
    plot, gif, mcap : pathlib.Path or None
        ``--plot`` (None with ``--no-plot``); ``--gif`` / ``--record`` when
        given, else the ``--plot`` path with the suffix ``.gif`` / ``.mcap``;
        None with ``--no-gif`` / ``--no-record``.

    Examples
    --------
    >>> import argparse
    >>> output_paths(argparse.Namespace(plot='out/run.png', no_plot=False, gif=None,
    ...                                 no_gif=False, record=None, no_record=True))
    (PosixPath('out/run.png'), PosixPath('out/run.gif'), None)
    """
    plot = pathlib.Path(args.plot)
    gif = None if args.no_gif else pathlib.Path(args.gif or plot.with_suffix('.gif'))
    mcap = None if args.no_record else pathlib.Path(args.record or plot.with_suffix('.mcap'))
    return None if args.no_plot else plot, gif, mcap


def prepare_outputs(args):
    """:func:`output_paths`, after checking their extras and preparing their folders.

    Raises
    ------
    MissingExtra
        The ``plot`` extra for the picture or the animation, the ``record``
        extra for the recording.
    OutputPathError
        A path that cannot be written.
    """
    plot, gif, mcap = output_paths(args)
    if plot is not None or gif is not None:
        require('plot', 'demo (its picture and animation)', alternative='give --no-plot --no-gif')
    if mcap is not None:
        require('record', 'demo (its recording)', alternative='give --no-record')
    for option, path in (('--plot', plot), ('--gif', gif), ('--record', mcap)):
        if path is not None:
            prepare_file(path, option)
    return plot, gif, mcap


def recorded_topics():
    """The topics the demo records: ``(name, message class, subscription QoS)``.

    Each QoS is compatible with the publisher's: transient local for the
    latched ``map``, ``plan`` and ``amcl_pose``, best effort for the laser
    ``scan``, reliable otherwise; deep (:data:`RECORD_DEPTH`). ``odom`` is in
    the drifting odom frame, ``ground_truth`` and ``amcl_pose`` in map.
    The demo's local planner publishes ``TwistStamped`` on ``cmd_vel``.
    """
    from diagnostic_msgs.msg import DiagnosticArray
    from geometry_msgs.msg import PoseStamped, PoseWithCovarianceStamped, TwistStamped
    from nav_msgs.msg import OccupancyGrid, Odometry, Path
    from rclpy.qos import DurabilityPolicy, QoSProfile, ReliabilityPolicy
    from sensor_msgs.msg import LaserScan
    from std_msgs.msg import String
    from visualization_msgs.msg import MarkerArray

    latched = QoSProfile(depth=1, reliability=ReliabilityPolicy.RELIABLE,
                         durability=DurabilityPolicy.TRANSIENT_LOCAL)
    sensor = QoSProfile(depth=RECORD_DEPTH, reliability=ReliabilityPolicy.BEST_EFFORT)
    reliable = QoSProfile(depth=RECORD_DEPTH, reliability=ReliabilityPolicy.RELIABLE)
    return (('map', OccupancyGrid, latched), ('plan', Path, latched),
            ('plan_markers', MarkerArray, reliable), ('local_plan', Path, reliable),
            ('odom', Odometry, reliable), ('ground_truth', Odometry, reliable),
            ('amcl_pose', PoseWithCovarianceStamped, latched), ('scan', LaserScan, sensor),
            ('obstacles', MarkerArray, reliable), ('tracks', MarkerArray, reliable),
            ('cmd_vel', TwistStamped, reliable),
            ('goal_pose', PoseStamped, reliable), ('goal_outcome', String, reliable),
            ('/diagnostics', DiagnosticArray, reliable))


def start_recording(node, path):
    """A :class:`~fusion_planner.cli.recording.TopicRecorder` of :func:`recorded_topics`.

    Returns None, after one line on stderr saying why, when the file or a
    message definition is unavailable: the demo runs without a recording
    then. (The ``record`` extra and the folder are checked before the run.)
    """
    try:
        return TopicRecorder(node, path, recorded_topics())
    except (OSError, DefinitionNotFound) as err:
        print(f'no recording: {err}', file=sys.stderr)
    return None


def _draw(scenario, result, plot_path, gif_path):
    """Write the picture and the animation (those not None); a failure to draw is reported."""
    if plot_path is None and gif_path is None:
        return
    from fusion_planner.cli.animation import animate_episode
    from fusion_planner.cli.sim_plot import episode_title, plot_episode

    outputs = (
        ('picture', plot_path, lambda: plot_episode(
            scenario, result, plot_path, title='ROS 2 nodes, ' + episode_title(scenario, result))),
        ('animation', gif_path, lambda: animate_episode(scenario, result, gif_path,
                                                        scenario.limits.dt)))
    for kind, path, draw in outputs:
        if path is None:
            continue
        try:
            draw()
        except (OSError, ValueError) as err:
            print(f'could not write {path}: {err}', file=sys.stderr)
            continue
        print(f'{kind}: {path}', file=sys.stderr)
