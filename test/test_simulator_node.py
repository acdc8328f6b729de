"""The simulator node alone on the bundled demo scenario, probed over DDS.

A probe node subscribes every output and publishes velocity commands. The
simulator runs free (no controller to wait for) unless a test says
otherwise; every wait is bounded.
"""

import math
import pathlib
import re
import threading
import time

import numpy as np
import pytest

rclpy = pytest.importorskip('rclpy')

from diagnostic_msgs.msg import DiagnosticArray  # noqa: E402
from geometry_msgs.msg import (  # noqa: E402
    PoseStamped, PoseWithCovarianceStamped, Twist, TwistStamped)
from nav_msgs.msg import OccupancyGrid, Odometry, Path  # noqa: E402
from rclpy.executors import SingleThreadedExecutor  # noqa: E402
from rclpy.node import Node  # noqa: E402
from rclpy.parameter import Parameter  # noqa: E402
from rclpy.qos import qos_profile_sensor_data  # noqa: E402
from rosgraph_msgs.msg import Clock  # noqa: E402
from sensor_msgs.msg import LaserScan  # noqa: E402
from visualization_msgs.msg import MarkerArray  # noqa: E402

from fusion_planner.cli.demo_command import Spinner, shutdown_executor  # noqa: E402
from fusion_planner.core.simulation.contact_blame import ContactEvent  # noqa: E402
from fusion_planner.core.simulation.scenario import load_scenario  # noqa: E402
from fusion_planner.ros import conversions as conv  # noqa: E402
from fusion_planner.ros import fuzz  # noqa: E402
from fusion_planner.ros import simulator as sim  # noqa: E402

REPO = pathlib.Path(__file__).resolve().parent.parent
DEMO = REPO / 'config' / 'scenarios' / 'demo.yaml'
WAIT_S = 10.0
#: Period of the test's condition polls [s].
POLL_S = 0.005
#: Fuzzed bad messages per input sent over DDS [1] (1,000 each go in process:
#: test_fuzz_inputs.py).
DDS_BAD_MESSAGES = 100


class Probe:
    """The simulator under test plus a node recording its outputs."""

    def __init__(self, context, **overrides):
        overrides.setdefault('scenario', str(DEMO))
        overrides.setdefault('sync_with_controller', False)
        self.sim = sim.SimulatorNode(
            context=context,
            parameter_overrides=[Parameter(k, value=v) for k, v in overrides.items()])
        self.node = Node('probe', context=context)
        self.lock = threading.Lock()
        self.got = {name: [] for name in ('clock', 'odom', 'scan', 'obstacles', 'goal', 'diag',
                                          'truth', 'amcl')}
        subscriptions = (
            ('clock', Clock, 'clock', 10),
            ('odom', Odometry, 'odom', 10),  # stock QoS (reliable), as RViz and Nav2
            ('truth', Odometry, 'ground_truth', 10),
            ('amcl', PoseWithCovarianceStamped, 'amcl_pose', sim.LATCHED_QOS),
            ('scan', LaserScan, 'scan', qos_profile_sensor_data),
            ('obstacles', MarkerArray, 'obstacles', 10),
            ('goal', PoseStamped, 'goal_pose', 10),
            ('diag', DiagnosticArray, 'diagnostics', 50),
        )
        for name, msg_type, topic, qos in subscriptions:
            self.node.create_subscription(msg_type, topic, self._recorder(name), qos)
        self.cmd_pub = self.node.create_publisher(
            TwistStamped if overrides.get('enable_stamped_cmd_vel') else Twist, 'cmd_vel', 10)
        self.executor = SingleThreadedExecutor(context=context)
        self.executor.add_node(self.sim)
        self.executor.add_node(self.node)
        self.spinner = Spinner(self.executor)

    def _recorder(self, name):
        def record(msg):
            with self.lock:
                self.got[name].append((time.monotonic(), msg))
        return record

    def messages(self, name):
        with self.lock:
            return [m for _, m in self.got[name]]

    def sim_time(self):
        clocks = self.messages('clock')
        return conv.stamp_to_seconds(clocks[-1].clock) if clocks else 0.0

    def wait_until(self, condition, timeout_s=WAIT_S):
        deadline = time.monotonic() + timeout_s
        while time.monotonic() < deadline:
            if condition():
                return True
            time.sleep(POLL_S)
        return condition()

    def sim_status(self):
        for msg in reversed(self.messages('diag')):
            for status in msg.status:
                if status.name.endswith('/simulator'):
                    return {kv.key: kv.value for kv in status.values}
        return {}

    def close(self):
        shutdown_executor(self.spinner, [self.sim, self.node])


@pytest.fixture
def probe(context, request):
    p = Probe(context, **getattr(request, 'param', {}))
    yield p
    p.close()


def test_default_scenario_is_the_bundled_demo():
    assert sim.default_scenario_path().resolve() == DEMO.resolve()


@pytest.mark.parametrize('probe', [{'real_time_factor': 5.0}], indirect=True)
def test_clock_advances_and_never_outruns_the_real_time_factor(probe):
    assert probe.wait_until(lambda: probe.sim_time() > 0.5)
    wall0, sim0 = time.monotonic(), probe.sim_time()
    time.sleep(2.0)
    factor = (probe.sim_time() - sim0) / (time.monotonic() - wall0)
    # Only the upper bound is the simulator's promise: on a loaded machine
    # the wall clock may outrun it, but sim time must never outrun the factor.
    assert 0.0 < factor < 6.0, factor
    odom = probe.messages('odom')[-1]
    assert odom.header.frame_id == 'odom' and odom.child_frame_id == 'base_link'
    truth = probe.messages('truth')[-1]
    assert truth.header.frame_id == 'map' and truth.child_frame_id == 'base_link'
    scan = probe.messages('scan')[-1]
    assert scan.header.frame_id == 'base_link'
    assert len(scan.ranges) == probe.sim.scenario.scan.beams


@pytest.mark.parametrize('probe', [{'odom_scale_error': 0.1, 'odom_yaw_drift': 0.0,
                                    'localization_noise': 0.0,
                                    'localization_yaw_noise': 0.0}], indirect=True)
def test_odometry_drifts_from_the_truth_and_the_localization_does_not(probe):
    assert probe.wait_until(lambda: probe.messages('odom') and probe.messages('amcl'))
    first = probe.messages('odom')[-1].pose.pose.position
    assert (first.x, first.y) == (0.0, 0.0), 'odometry starts at the origin (REP-105)'
    start = probe.messages('truth')[-1].pose.pose.position
    forward = Twist()
    forward.linear.x = 0.5
    for _ in range(60):
        probe.cmd_pub.publish(forward)
        time.sleep(0.025)
    assert probe.wait_until(lambda: probe.messages('truth')[-1].twist.twist.linear.x == 0.0)
    truth = probe.messages('truth')[-1].pose.pose.position
    odom = probe.messages('odom')[-1].pose.pose.position
    travelled = math.hypot(truth.x - start.x, truth.y - start.y)
    assert travelled > 0.3
    assert math.hypot(odom.x, odom.y) == pytest.approx(1.1 * travelled, rel=1e-3)
    assert probe.wait_until(lambda: abs(
        probe.messages('amcl')[-1].pose.pose.position.x - truth.x) < 1e-6)
    assert probe.messages('amcl')[-1].header.frame_id == 'map'


def test_late_subscriber_gets_the_known_map_without_unknown_obstacles(probe, context):
    scenario = load_scenario(DEMO)
    time.sleep(0.5)
    late = Node('late_map_reader', context=context)
    maps = []
    late.create_subscription(OccupancyGrid, 'map', maps.append, sim.LATCHED_QOS)
    probe.executor.add_node(late)
    try:
        assert probe.wait_until(lambda: maps)
        grid = conv.occupancy_grid_to_grid_map(maps[0], 'map')
        assert np.array_equal(grid.occupied, scenario.grid.occupied)
        assert not np.array_equal(grid.occupied, scenario.true_grid().occupied)
    finally:
        probe.executor.remove_node(late)
        late.destroy_node()


@pytest.mark.parametrize('probe', [{}, {'enable_stamped_cmd_vel': True}], indirect=True)
def test_commands_move_the_robot_and_a_nan_command_stops_it(probe):
    pub = probe.cmd_pub
    stamped = pub.msg_type is TwistStamped
    assert probe.wait_until(lambda: pub.get_subscription_count() > 0)
    assert probe.wait_until(lambda: probe.messages('odom'))
    start = probe.messages('odom')[-1].pose.pose.position

    def command(v):
        twist = Twist()
        twist.linear.x = v
        return conv.velocity_to_twist_stamped(v, 0.0, 'base_link', conv.seconds_to_stamp(0.0)) \
            if stamped and math.isfinite(v) else (TwistStamped(twist=twist) if stamped else twist)

    def speed():
        return probe.messages('truth')[-1].twist.twist.linear.x

    for _ in range(40):
        pub.publish(command(0.4))
        time.sleep(0.025)
    assert speed() > 0.2
    now = probe.messages('odom')[-1].pose.pose.position
    assert math.hypot(now.x - start.x, now.y - start.y) > 0.05
    for _ in range(40):
        pub.publish(command(math.nan))
        time.sleep(0.025)
    assert speed() == 0.0
    assert probe.wait_until(lambda: int(probe.sim_status().get('rejected', 0)) >= 1)


def test_hundreds_of_fuzzed_bad_messages_are_refused_quietly_and_commands_still_drive(
        probe, capfd):
    plan_pub = probe.node.create_publisher(Path, 'plan', sim.LATCHED_QOS)
    assert probe.wait_until(lambda: probe.cmd_pub.get_subscription_count() > 0
                            and plan_pub.get_subscription_count() > 0)
    robot = probe.sim.scenario.robot
    limits = (sim.MAX_COMMAND_FACTOR * robot.max_speed, sim.MAX_COMMAND_FACTOR * robot.max_omega)
    capfd.readouterr()  # only what the bad messages cause counts
    started = time.monotonic()
    inputs = [(probe.cmd_pub, fuzz.twists(*limits, bad_only=True)),
              (plan_pub, fuzz.paths(bad_only=True))]
    refused = fuzz.publish_all_refused(
        inputs, DDS_BAD_MESSAGES, lambda: probe.sim._diagnostics.values['rejected'],
        probe.wait_until)
    assert min(refused.values()) >= 0.95 * DDS_BAD_MESSAGES, refused
    elapsed = time.monotonic() - started
    values = probe.sim._diagnostics.values
    assert values['faults'] == 0, values['last_error']
    err = capfd.readouterr().err
    lines = fuzz.problem_lines(err, probe.sim)
    assert 2 <= len(lines) <= fuzz.allowed_problem_lines(2, elapsed), lines
    assert 'Traceback' not in err
    # Refused commands stopped the robot; a good one drives it.
    assert probe.wait_until(lambda: probe.messages('truth')[-1].twist.twist.linear.x == 0.0)
    good = Twist()
    good.linear.x, good.angular.z = 0.3, 0.5

    def turning():
        return probe.messages('truth')[-1].twist.twist.angular.z == 0.5

    deadline = time.monotonic() + WAIT_S
    while time.monotonic() < deadline and not turning():
        probe.cmd_pub.publish(good)
        time.sleep(0.025)
    assert turning()


def test_robot_stops_when_commands_stop(probe):
    moving = Twist()
    moving.linear.x = 0.4
    for _ in range(30):
        probe.cmd_pub.publish(moving)
        time.sleep(0.025)
    assert probe.messages('truth')[-1].twist.twist.linear.x > 0.0
    time.sleep(2.0)  # > cmd_timeout (0.5 s) + braking at max_accel
    assert probe.messages('truth')[-1].twist.twist.linear.x == 0.0


def test_a_collision_is_reported_with_what_the_robot_touched_and_where(probe):
    backwards = Twist()
    backwards.linear.x = -0.5  # from (1.5, 1.5) facing +x, into the wall behind

    def collision_lines():
        return [s.message for msg in probe.messages('diag') for s in msg.status
                if s.name.endswith('/simulator') and s.message.startswith('collision ')]

    deadline = time.monotonic() + WAIT_S
    while time.monotonic() < deadline and not collision_lines():
        probe.cmd_pub.publish(backwards)
        time.sleep(0.025)
    lines = collision_lines()
    assert lines and lines[0].startswith('collision 1 (with a wall or static obstacle) at t = '), \
        lines
    x, y = map(float, re.search(r'robot at \(([-\d.]+), ([-\d.]+)\)', lines[0]).groups())
    scenario = probe.sim.scenario
    assert y == pytest.approx(1.5) and x < 1.5
    # the robot's disc touches the wall: its centre lies within a radius (plus the rounding
    # of the message and the cell-centre distances) of an occupied cell
    assert scenario.grid.clearance_at([[x, y]])[0] <= scenario.robot.radius \
        + scenario.grid.resolution


@pytest.mark.parametrize('escape, passive, judged', [
    (False, True, 'passive: the robot could not have escaped'),
    (True, False, 'avoidable: an escape existed'),
    (False, False, 'avoidable: the robot was not standing or retreating'),
])
def test_a_contact_with_a_person_is_logged_with_how_it_was_judged(escape, passive, judged):
    event = ContactEvent(3.0, (1.0, 2.0), 0.4, person=2, approach=0.9, escape=escape,
                         passive=passive)
    assert sim._contact_kind(event) == f'with moving obstacle 2, {judged}'


def test_obstacle_markers_are_id_stable_cylinders_of_the_moving_obstacles(probe):
    scenario = probe.sim.scenario
    assert probe.wait_until(lambda: len(probe.messages('obstacles')) >= 10)
    arrays = probe.messages('obstacles')
    k = len(scenario.moving_obstacles)
    for array in arrays:
        assert sorted(m.id for m in array.markers) == list(range(k))
    radii = sorted(m.radius for m in scenario.moving_obstacles)
    assert sorted(m.scale.x / 2 for m in arrays[-1].markers) == pytest.approx(radii)
    first = {m.id: (m.pose.position.x, m.pose.position.y) for m in arrays[0].markers}
    last = {m.id: (m.pose.position.x, m.pose.position.y) for m in arrays[-1].markers}
    assert any(math.dist(first[i], last[i]) > 0.01 for i in first)


@pytest.mark.parametrize('probe', [{'publish_goal': True}], indirect=True)
def test_publishes_the_scenario_goal_once_a_subscriber_listens(probe):
    assert probe.wait_until(lambda: probe.messages('goal'))
    goal = probe.messages('goal')[0]
    assert goal.header.frame_id == 'map'
    assert (goal.pose.position.x, goal.pose.position.y) == pytest.approx(probe.sim.scenario.goal)


@pytest.mark.parametrize('probe', [{'start_paused': True}], indirect=True)
def test_start_paused_holds_the_world_until_the_first_plan(probe):
    assert probe.wait_until(lambda: len(probe.messages('clock')) >= 3)
    time.sleep(0.5)
    assert probe.sim_time() == 0.0
    plan_pub = probe.node.create_publisher(Path, 'plan', sim.LATCHED_QOS)
    plan_pub.publish(conv.path_to_msg([[1.0, 1.0], [2.0, 2.0]], 'map', conv.seconds_to_stamp(0.0)))
    assert probe.wait_until(lambda: probe.sim_time() > 0.5)


@pytest.mark.parametrize('probe', [{'sync_with_controller': True, 'max_command_lag': 0.0,
                                    'real_time_factor': 20.0}], indirect=True)
def test_lockstep_waits_for_a_late_controller_then_runs_on(probe):
    stop = threading.Event()

    def controller():  # answers every clock tick, like a local planner
        seen = 0
        while not stop.is_set():
            n = len(probe.messages('clock'))
            if n > seen:
                seen = n
                probe.cmd_pub.publish(Twist())
            time.sleep(0.002)

    thread = threading.Thread(target=controller, daemon=True)
    thread.start()
    time.sleep(1.0)
    stop.set()
    thread.join()
    stalled_at = probe.sim_time()
    time.sleep(0.5)  # within COMMAND_WAIT_LIMIT_S: the world waits
    assert probe.sim_time() - stalled_at <= 2 * 0.05 + 1e-6
    assert probe.wait_until(lambda: probe.sim_time() > stalled_at + 1.0,
                            sim.COMMAND_WAIT_LIMIT_S + WAIT_S)


def test_a_rate_too_low_for_the_robot_is_refused_with_a_reason(context):
    from fusion_planner.core.errors import InvalidInput
    with pytest.raises(InvalidInput, match='rate 1 Hz'):
        sim.SimulatorNode(context=context, parameter_overrides=[
            Parameter('scenario', value=str(DEMO)), Parameter('rate', value=1.0),
            Parameter('scan_rate', value=1.0)])
