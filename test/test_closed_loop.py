"""Closed loop over real DDS: simulator, global_planner and local_planner together.

Launch-free: the nodes run in a SingleThreadedExecutor of this process, or as
processes started with ``--ros-args --params-file config/params.yaml``; a
monitor node in this process watches ``clock``, ``odom``, ``plan`` and
``diagnostics``. Every wait is bounded. The simulator runs faster than real
time (``real_time_factor``) in lockstep with the local planner (sim time via
``clock``, ``use_sim_time`` in the planners), so a slow machine slows the run
down instead of changing it.

The scenario: a 10 m x 6 m room with a wall rising from the floor in the
middle, an obstacle the map does not show on the straight way to the wall's
end, one person walking up and down across the plan and one bouncing around.
Starts and goals sit at cell centres: OccupancyGrid's float32 resolution
(0.1 -> 0.100000001) moves a point on a cell border to the cell below, which
would make the plan here differ from the core's (reported upstream).
"""

import math
import os
import pathlib
import re
import signal
import subprocess
import sys
import time

import numpy as np
import pytest
import yaml

rclpy = pytest.importorskip('rclpy')

from geometry_msgs.msg import PoseStamped  # noqa: E402
from rclpy.executors import SingleThreadedExecutor  # noqa: E402
from rclpy.node import Node  # noqa: E402

from fusion_planner.cli import demo_command as demo  # noqa: E402
from fusion_planner.core.grid import GridMap  # noqa: E402
from fusion_planner.core.map_files import save_map_server  # noqa: E402
from fusion_planner.core.simulation.scenario import load_scenario  # noqa: E402
from fusion_planner.ros.global_planner import GlobalPlannerParams  # noqa: E402

REPO = pathlib.Path(__file__).resolve().parent.parent
PARAMS_FILE = REPO / 'config' / 'params.yaml'

#: Requested speed-up; the lockstep makes the achieved one what the CPU allows.
REAL_TIME_FACTOR = 10.0
#: Simulated time budget of one run [s] (the robot needs about 25 s).
SIM_TIME_LIMIT_S = 60.0
#: Wall time budget of one run [s].
WALL_LIMIT_S = 50.0
#: Wall time a node process gets to exit on SIGINT [s].
SIGINT_TIMEOUT_S = 10.0
#: How long [s] a process that did not stop is given to print its stacks.
STACK_DUMP_WAIT_S = 3.0


# -- scenario files -----------------------------------------------------------------

def write_map(folder):
    """A 10 m x 6 m room at 0.1 m with a wall from the floor to y = 2.2 m at x = 4.8-5.2 m."""
    occupied = np.zeros((60, 100), dtype=bool)
    occupied[0:22, 48:52] = True
    save_map_server(GridMap(occupied, resolution=0.1), folder / 'room.yaml')
    return 'room.yaml'


def write_scenario(folder, name, start, goal, unknown=(), moving=(), map_name=None):
    """Write a scenario YAML beside the room map; returns its path."""
    folder.mkdir(parents=True, exist_ok=True)
    doc = {
        'name': name, 'map': map_name or write_map(folder), 'seed': 1,
        'robot': {'start': list(start), 'radius': 0.2, 'max_speed': 0.8},
        'goal': list(goal),
        'unknown_obstacles': list(unknown),
        'moving_obstacles': list(moving),
        'limits': {'time_limit_s': SIM_TIME_LIMIT_S, 'dt': 0.05},
        'scan': {'beams': 180, 'range_max': 6.0},
    }
    path = folder / f'{name}.yaml'
    path.write_text(yaml.safe_dump(doc))
    return path


def write_two_way_map(folder):
    """A 10 m x 6 m room at 0.1 m around a 4 m x 3.6 m block: a 1 m way below it, 1.4 m above."""
    occupied = np.zeros((60, 100), dtype=bool)
    occupied[10:46, 30:70] = True
    folder.mkdir(parents=True, exist_ok=True)
    save_map_server(GridMap(occupied, resolution=0.1), folder / 'two_ways.yaml')
    return 'two_ways.yaml'


def write_walled_off_map(folder):
    """The room of :func:`write_map` with a closed 1.6 m x 2 m box of 0.2 m walls at its right."""
    occupied = np.zeros((60, 100), dtype=bool)
    occupied[0:22, 48:52] = True
    occupied[34:58, 78:98] = True
    occupied[36:56, 80:96] = False
    folder.mkdir(parents=True, exist_ok=True)
    save_map_server(GridMap(occupied, resolution=0.1), folder / 'walled_off.yaml')
    return 'walled_off.yaml'


#: A wall the map does not show, closing the shorter way (above the block).
UPPER_WAY_CLOSED = {'rectangle': {'min': [4.8, 4.6], 'max': [5.2, 6.0]}}
#: Wall time budget of a run that has to turn back [s].
DETOUR_WALL_LIMIT_S = 150.0

#: An obstacle the map does not show, on the straight line from the start to the wall's end.
UNKNOWN_BOX = {'circle': {'center': [3.0, 1.6], 'radius': 0.3}}
#: People: one walking across the plan's second half, one bouncing around the first.
PEOPLE = (
    {'radius': 0.25, 'model': 'waypoints', 'points': [[6.8, 0.5], [6.8, 5.5]], 'speed': 0.35},
    {'radius': 0.25, 'model': 'bounce', 'position': [2.0, 4.0], 'velocity': [0.2, -0.2]},
)


@pytest.fixture(scope='module')
def scenario_path(tmp_path_factory):
    """The closed-loop scenario: unknown static obstacle plus two moving obstacles."""
    return write_scenario(tmp_path_factory.mktemp('closed_loop'), 'closed_loop',
                          start=(1.05, 1.05, 0.0), goal=(9.05, 1.05),
                          unknown=[UNKNOWN_BOX], moving=PEOPLE)


# -- harness -----------------------------------------------------------------------

class Run:
    """The nodes of one test run, a monitor and its recorder, spun in the background."""

    def __init__(self, context, scenario_file, ros_args=(), in_process=True, log_dir=None,
                 overrides=None):
        self.context = context
        self.scenario = load_scenario(scenario_file)
        self.params = demo.node_parameters(self.scenario, scenario_file, REAL_TIME_FACTOR)
        for node, values in (overrides or {}).items():
            self.params[node].update(values)
        self.recorder = demo.RunRecorder(self.scenario,
                                         self.params['local_planner']['goal_tolerance'])
        self.nodes, self.procs = [], []
        self.wall_start = time.monotonic()
        cli_args = ['--ros-args', *ros_args] if ros_args else None
        self.monitor = Node('test_monitor', context=context, cli_args=cli_args)
        self.nodes.append(self.monitor)
        self.diagnostics_sub = demo.attach_recorder(self.monitor, self.recorder)
        self.executor = SingleThreadedExecutor(context=context)
        self.tick = lambda: None  # in one process the simulator sends the goal
        if in_process:
            self.nodes += demo.make_nodes(context, self.params, ros_args)
        else:
            # Discovery can outlast a fast run: as the demo does, the monitor
            # sends the goal once it hears every node (the world waits for it).
            self.params['simulator']['publish_goal'] = False
            self.tick = demo.goal_when_heard(self.monitor, self.diagnostics_sub,
                                             self.recorder, self.scenario.goal)
            env = dict(os.environ)
            env['PYTHONPATH'] = os.pathsep.join(filter(None, [str(REPO), env.get('PYTHONPATH')]))
            env['PYTHONFAULTHANDLER'] = '1'  # a node that hangs prints its stacks (sigint_and_wait)
            self.procs = start_node_processes(self.params, ros_args, log_dir, env)
        for node in self.nodes:
            self.executor.add_node(node)
        self.spinner = demo.Spinner(self.executor)

    def alive(self):
        for name, proc, log_path in self.procs:
            if proc.poll() is not None:
                return f'{name} exited with {proc.returncode}: {log_path.read_text()[-2000:]}'
        return None

    def wait_arrival(self, time_limit_s=SIM_TIME_LIMIT_S, wall_limit_s=WALL_LIMIT_S):
        """None on arrival, else the failure sentence."""
        failure = demo.watch(self.recorder, time_limit_s, wall_limit_s, self.alive,
                             tick=self.tick)
        self.wall_time = time.monotonic() - self.wall_start
        if failure is not None and self.procs and self.recorder.plan is None:
            failure += f' (no plan; {self.discovery()})'
        return failure

    def discovery(self):
        """What the monitor has discovered: the goal waits for all of it (one line)."""
        monitor = self.monitor
        publishers = [f'{i.node_namespace.rstrip("/")}/{i.node_name}'
                      for i in monitor.get_publishers_info_by_topic('/diagnostics')]
        return (f'ground truth poses heard: {len(self.recorder.pose_times)}; nodes: '
                f'{sorted(monitor.get_node_names_and_namespaces())}; /diagnostics publishers: '
                f'{publishers}, matched: {self.diagnostics_sub.get_publisher_count()}')

    def wait_for(self, condition, wall_limit_s, period_s=0.05):
        """Poll ``condition()`` until true or the wall limit; returns its last value."""
        deadline = time.monotonic() + wall_limit_s
        while time.monotonic() < deadline:
            self.tick()
            value = condition()
            if value:
                return value
            time.sleep(period_s)
        return condition()

    def final_status(self):
        """The simulator's status published after now (bounded wait)."""
        demo.wait_final_status(self.recorder, time.monotonic())
        return dict(self.recorder.sim_status)

    def close(self):
        """Stop spinning, destroy the nodes; processes are left to the caller."""
        demo.shutdown_executor(self.spinner, self.nodes)


def start_node_processes(params, ros_args, log_dir, env):
    """The three nodes as ``python -m fusion_planner.ros.<node> --ros-args --params-file ...``."""
    log_dir.mkdir(parents=True, exist_ok=True)
    procs = []
    for name in demo.NODES:
        cmd = [sys.executable, '-m', f'fusion_planner.ros.{name}', '--ros-args',
               '--params-file', str(PARAMS_FILE), *ros_args, *demo.ros_arg_overrides(params[name])]
        log_path = log_dir / f'{name}.log'
        with open(log_path, 'wb') as log:
            proc = subprocess.Popen(cmd, stdout=log, stderr=subprocess.STDOUT, env=env)
        procs.append((name, proc, log_path))
    return procs


def sigint_and_wait(procs):
    """SIGINT every process; returns ``{name: (exit code, log text)}`` (kills stragglers).

    A straggler gets SIGABRT first: with ``PYTHONFAULTHANDLER`` set, Python prints every
    thread's stack into its log, which the failing assertion shows (a node that once did
    not stop within 10 s of SIGINT in CI left no clue of where it was).
    """
    for _, proc, _ in procs:
        if proc.poll() is None:
            proc.send_signal(signal.SIGINT)
    out = {}
    for name, proc, log_path in procs:
        try:
            code = proc.wait(timeout=SIGINT_TIMEOUT_S)
        except subprocess.TimeoutExpired:
            proc.send_signal(signal.SIGABRT)
            try:
                proc.wait(timeout=STACK_DUMP_WAIT_S)
            except subprocess.TimeoutExpired:
                proc.kill()
            code = f'killed after {SIGINT_TIMEOUT_S} s'
            proc.wait()
        out[name] = (code, log_path.read_text(errors='replace'))
    return out


def assert_arrived_safely(run, failure):
    """Arrived, no contact event, positive clearance all the way."""
    assert failure is None, failure
    status = run.final_status()
    # the lockstep first: a run that ran free (a stalled node) is not the scenario's run
    why = f"lockstep: {status.get('lockstep')}; simulator status: {status}"
    assert int(status['collisions']) == 0, why
    assert float(status['min_clearance_m']) > 0.0, why
    pose = run.recorder.poses[-1]
    goal = run.scenario.goal
    assert math.hypot(pose[0] - goal[0], pose[1] - goal[1]) <= run.recorder.arrival_radius
    return status


def report(name, run, status):
    """One line of measured figures (shown with ``pytest -s``)."""
    sim = run.recorder.arrived_at
    print(f'\n{name}: arrived at sim {sim:.2f} s, wall {run.wall_time:.1f} s (including start-up), '
          f"collisions {status['collisions']}, "
          f"min clearance {float(status['min_clearance_m']):.3f} m, "
          f"travelled {float(status['distance_travelled_m']):.2f} m, "
          f"simulator real-time factor {float(status['real_time_factor']):.2f}")


# -- tests ---------------------------------------------------------------------------

def test_three_nodes_in_one_executor_reach_the_goal_without_collision(context, scenario_path):
    run = Run(context, scenario_path)
    try:
        failure = run.wait_arrival()
        status = assert_arrived_safely(run, failure)
        report('one executor', run, status)
        # The first plan was made on the known map: it runs into the unknown
        # box, which the robot passed around (positive clearance above).
        plan = run.recorder.plans[0]
        box = np.array(UNKNOWN_BOX['circle']['center'])
        assert np.min(np.hypot(*(plan - box).T)) < UNKNOWN_BOX['circle']['radius'] + 0.2
        # The moving obstacles really moved (each went at least 0.5 m from its start).
        tracks = np.array(run.recorder.tracks)  # (T, K, 2)
        farthest = np.max(np.linalg.norm(tracks - tracks[0], axis=2), axis=0)
        assert np.all(farthest > 0.5), farthest
    finally:
        run.close()


def test_three_processes_reach_the_goal_and_stop_on_sigint(context, scenario_path, tmp_path):
    run = Run(context, scenario_path, in_process=False, log_dir=tmp_path)
    try:
        failure = run.wait_arrival()
        status = assert_arrived_safely(run, failure)
        report('three processes', run, status)
    finally:
        results = sigint_and_wait(run.procs)
        run.close()
    for name, (code, log) in results.items():
        assert code == 0, f'{name}: exit {code}\n{log[-3000:]}'
        assert 'Traceback' not in log, f'{name}:\n{log[-3000:]}'


def test_a_new_goal_in_mid_run_reroutes_the_robot(context, tmp_path):
    first_goal, second_goal = (9.05, 1.05), (1.55, 5.05)
    path = write_scenario(tmp_path, 'reroute', start=(1.05, 1.05, 0.0), goal=first_goal)
    run = Run(context, path)
    try:
        # Wait until the robot follows the first plan and has left the start.
        moved = run.wait_for(lambda: run.recorder.plan is not None and len(run.recorder.poses) > 0
                             and math.hypot(run.recorder.poses[-1][0] - 1.05,
                                            run.recorder.poses[-1][1] - 1.05) > 1.0, 30.0)
        assert moved, 'the robot never started on the first plan'
        assert np.hypot(*(run.recorder.plan[-1] - first_goal)) < 0.2
        publish_goal(run, second_goal)
        rerouted = run.wait_for(
            lambda: np.hypot(*(run.recorder.plan[-1] - second_goal)) < 0.2, 10.0)
        assert rerouted, f'no plan to the new goal; last plan ends at {run.recorder.plan[-1]}'
        # Arrive at the new goal (the recorder measures against the scenario's goal).
        run.recorder.goal = np.array(second_goal)
        run.recorder.arrived_at = None
        failure = run.wait_arrival()
        assert failure is None, failure
        x, y, _ = run.recorder.poses[-1]
        assert math.hypot(x - second_goal[0], y - second_goal[1]) <= run.recorder.arrival_radius
        assert math.hypot(x - first_goal[0], y - first_goal[1]) > 5.0
        assert int(run.final_status()['collisions']) == 0
    finally:
        run.close()


def test_a_way_closed_by_an_unknown_wall_is_learnt_and_the_robot_arrives_by_the_other(
        context, tmp_path):
    path = write_scenario(tmp_path, 'closed_way', start=(1.05, 3.05, 0.0), goal=(9.05, 3.05),
                          unknown=[UPPER_WAY_CLOSED], map_name=write_two_way_map(tmp_path))
    run = Run(context, path)
    try:
        failure = run.wait_arrival(wall_limit_s=DETOUR_WALL_LIMIT_S)
        status = assert_arrived_safely(run, failure)
        report('closed way', run, status)
        plans = list(run.recorder.plans)
        # The first plan takes the shorter way above the block, into the unknown wall ...
        assert plans[0][:, 1].max() > 4.6, 'the first plan does not use the upper way'
        # ... the scans revealed it, and the last plan and the robot pass below the block.
        assert int(run.recorder.planner_status['scan_obstacle_cells']) > 0
        for name, points in (('last plan', plans[-1]), ('robot', np.array(run.recorder.poses))):
            beside_block = points[(points[:, 0] > 3.5) & (points[:, 0] < 6.5), 1]
            assert (beside_block < 1.0).any(), f'{name} did not pass below the block'
    finally:
        run.close()


def publish_goal(run, goal):
    """Publish a goal_pose from the monitor (after the planner listens)."""
    goal_pub = run.monitor.create_publisher(PoseStamped, 'goal_pose', 10)
    assert run.wait_for(lambda: goal_pub.get_subscription_count() > 0, 10.0)
    msg = PoseStamped()
    msg.header.frame_id = 'map'
    msg.pose.position.x, msg.pose.position.y = goal
    msg.pose.orientation.w = 1.0
    goal_pub.publish(msg)


def test_an_unreachable_goal_fails_and_the_robot_does_not_move(context, tmp_path):
    start = (1.05, 1.05, 0.0)
    path = write_scenario(tmp_path, 'unreachable', start=start, goal=(8.85, 4.55),
                          map_name=write_walled_off_map(tmp_path))
    run = Run(context, path, overrides={'simulator': {'start_paused': False}})
    try:
        failed = run.wait_for(
            lambda: run.recorder.planner_status.get('last_outcome') == 'no_valid_path', 30.0)
        assert failed, run.recorder.planner_status
        t0 = run.recorder.sim_time
        assert run.wait_for(lambda: run.recorder.sim_time > t0 + 3.0, 30.0), 'the clock stopped'
        poses = np.array(run.recorder.poses)
        assert len(poses) and np.abs(poses[:, :2] - start[:2]).max() < 1e-6, 'the robot moved'
        assert run.recorder.local_status.get('status') == 'no_path'
        assert run.recorder.plan is None  # only empty plans were published
    finally:
        run.close()


def test_a_goal_in_an_obstacle_moves_to_the_nearest_free_cell_and_is_reached(context, tmp_path):
    path = write_scenario(tmp_path, 'goal_in_wall', start=(1.05, 1.05, 0.0), goal=(1.55, 4.55))
    run = Run(context, path)
    try:
        assert run.wait_for(lambda: run.recorder.plan is not None, 30.0), 'no first plan'
        requested = (5.0, 2.25)  # 5 cm above the wall's top: inside its inflation
        publish_goal(run, requested)
        moved = run.wait_for(lambda: float(run.recorder.planner_status.get('goal_moved_m', 0)) > 0,
                             30.0)
        assert moved, run.recorder.planner_status
        goal_moved = float(run.recorder.planner_status['goal_moved_m'])
        assert goal_moved <= GlobalPlannerParams().goal_tolerance
        used_goal = run.recorder.plan[-1]
        assert math.dist(used_goal, requested) == pytest.approx(goal_moved, abs=1e-3)
        run.recorder.goal = np.array(used_goal)
        run.recorder.arrived_at = None
        assert run.wait_arrival() is None
        assert int(run.final_status()['collisions']) == 0
    finally:
        run.close()


def test_two_namespaced_robots_do_not_cross_talk(context, tmp_path):
    robots = {
        '/robot1': write_scenario(tmp_path / 'r1', 'robot1', start=(1.05, 1.05, 0.0),
                                  goal=(9.05, 1.05)),
        '/robot2': write_scenario(tmp_path / 'r2', 'robot2', start=(1.05, 5.05, 0.0),
                                  goal=(8.55, 4.55)),
    }
    runs = {}
    try:
        for ns, path in robots.items():
            runs[ns] = Run(context, path, ros_args=demo.namespace_ros_args(ns), in_process=False,
                           log_dir=tmp_path / ns.strip('/') / 'logs')
        # Both robots drive at once: waiting for either sends each its goal once
        # heard, so no world is held (its clock still) while the other drives.
        ticks = [run.tick for run in runs.values()]

        def tick_all():
            for tick in ticks:
                tick()
        for run in runs.values():
            run.tick = tick_all
        for ns, run in runs.items():
            failure = run.wait_arrival()
            assert failure is None, f'{ns}: {failure}'
            goal = np.array(run.scenario.goal)
            # Each robot's plan goes to its own goal, and each arrives at it.
            assert np.hypot(*(run.recorder.plan[-1] - goal)) < 0.2, ns
            x, y, _ = run.recorder.poses[-1]
            assert math.hypot(x - goal[0], y - goal[1]) <= run.recorder.arrival_radius, ns
        # One publisher per robot topic; nothing on the global names.
        monitor = runs['/robot1'].monitor
        for ns in robots:
            for topic in ('odom', 'cmd_vel', 'plan', 'clock', 'scan'):
                assert monitor.count_publishers(f'{ns}/{topic}') == 1, f'{ns}/{topic}'
        for topic in ('/odom', '/cmd_vel', '/plan', '/clock', '/goal_pose'):
            assert monitor.count_publishers(topic) == 0, topic
    finally:
        results = {}
        for ns, run in runs.items():
            results[ns] = sigint_and_wait(run.procs)
            run.close()
    for ns, result in results.items():
        for name, (code, log) in result.items():
            assert code == 0 and 'Traceback' not in log, f'{ns}/{name}: exit {code}\n{log[-3000:]}'


def test_demo_command_runs_headless_prints_the_outcome_and_draws(scenario_path, tmp_path):
    picture = tmp_path / 'demo.png'
    env = dict(os.environ)
    env['PYTHONPATH'] = os.pathsep.join(filter(None, [str(REPO), env.get('PYTHONPATH')]))
    done = subprocess.run(
        [sys.executable, '-m', 'fusion_planner.cli.main', 'demo', '--scenario', str(scenario_path),
         '--real-time-factor', str(REAL_TIME_FACTOR), '--plot', str(picture)],
        capture_output=True, text=True, env=env, timeout=WALL_LIMIT_S + 30)
    assert done.returncode == 0, done.stdout + done.stderr[-3000:]
    outcome = done.stdout.strip().splitlines()[-1]
    assert outcome.startswith('arrived: yes'), outcome
    for field in ('sim time:', 'path length:', 'collisions: 0', 'min clearance:'):
        assert field in outcome
    assert 'distance to goal' in done.stderr  # the progress line
    # stderr is not a terminal: whole progress lines, the last one at the outcome's time
    assert '\r' not in done.stderr
    progress_times = re.findall(r'^ {2}sim +(\d+\.\d\d) s', done.stderr, flags=re.M)
    assert progress_times[-1] == re.search(r'sim time: (\d+\.\d\d) s', outcome).group(1)
    assert picture.stat().st_size > 10_000
    assert 'Traceback' not in done.stderr


def test_demo_command_refuses_a_bad_scenario_without_traceback(tmp_path):
    bad = tmp_path / 'bad.yaml'
    bad.write_text('map: nowhere.yaml\nrobot: {start: [1, 1, 0]}\ngoal: [2, 2]\n')
    env = dict(os.environ)
    env['PYTHONPATH'] = os.pathsep.join(filter(None, [str(REPO), env.get('PYTHONPATH')]))
    done = subprocess.run([sys.executable, '-m', 'fusion_planner.cli.main', 'demo',
                           '--scenario', str(bad), '--plot', str(tmp_path / 'x.png')],
                          capture_output=True, text=True, env=env, timeout=60)
    assert done.returncode == 2
    assert 'robot.radius' in done.stderr and 'Traceback' not in done.stderr
    assert not (tmp_path / 'x.png').exists()
