"""Lockstep: the same scenario gives the same run at any real-time factor.

Launch-free, over real DDS: the three nodes in one executor of this
process, wired as ``fusion-planner demo`` wires them (all three with
``lockstep``), and a monitor recording the simulator's ground truth; the
two runs compared differ in speed and in executor (rclpy's
SingleThreadedExecutor, the demo's). Every
wait is bounded. Also the pieces alone: the step sets of
:class:`~fusion_planner.ros.lockstep.StepInputs`, and a simulator in lockstep
that gets unstamped commands or none (an error or a report, never a hang).
"""

import threading
import time

import pytest

rclpy = pytest.importorskip('rclpy')

from diagnostic_msgs.msg import DiagnosticArray  # noqa: E402
from geometry_msgs.msg import Twist, TwistStamped  # noqa: E402
from nav_msgs.msg import Odometry  # noqa: E402
from rclpy.executors import SingleThreadedExecutor  # noqa: E402
from rclpy.node import Node  # noqa: E402
from rclpy.parameter import Parameter  # noqa: E402
from rclpy.qos import QoSProfile, ReliabilityPolicy  # noqa: E402
from rosgraph_msgs.msg import Clock  # noqa: E402
from std_msgs.msg import Header  # noqa: E402
from visualization_msgs.msg import MarkerArray  # noqa: E402

from fusion_planner.cli import demo_command as demo  # noqa: E402
from fusion_planner.core.errors import InvalidInput  # noqa: E402
from fusion_planner.core.simulation.scenario import load_scenario  # noqa: E402
from fusion_planner.ros import conversions as conv  # noqa: E402
from fusion_planner.ros import simulator as sim  # noqa: E402
from fusion_planner.ros.local_planner import LocalPlannerNode  # noqa: E402
from fusion_planner.ros.lockstep import StepInputs  # noqa: E402

from test_closed_loop import PEOPLE, UNKNOWN_BOX, write_scenario  # noqa: E402

#: Simulated time limit of one run [s] (the robot needs about 25 s).
SIM_TIME_LIMIT_S = 60.0
#: Wall time budget of one run [s].
WALL_LIMIT_S = 120.0
#: Wall time budget of the simulator-only waits [s].
WAIT_S = 10.0


# -- the step sets, alone ----------------------------------------------------------------

def _stamped(seconds, data=None):
    msg = Odometry()
    msg.header.stamp = conv.seconds_to_stamp(seconds)
    msg.child_frame_id = data or ''
    return msg


def test_a_step_is_handed_over_once_complete_in_the_given_order_whatever_the_arrival_order():
    steps = []
    def on_step(stamp, msgs):
        steps.append((stamp, [m.child_frame_id for m in msgs]))

    inputs = StepInputs(('odom', 'scan', 'plan'), on_step)
    inputs.add('plan', _stamped(0.1, 'p1'))
    inputs.add('scan', _stamped(0.1, 's1'))
    assert steps == []  # odom of 0.1 s missing
    inputs.add('scan', _stamped(0.2, 's2'))  # the next step's, early
    inputs.add('odom', _stamped(0.1, 'o1'))
    assert steps == [(100_000_000, ['o1', 's1', 'p1'])]
    for name in ('plan', 'odom'):
        inputs.add(name, _stamped(0.2, name[0] + '2'))
    assert steps[-1] == (200_000_000, ['o2', 's2', 'p2'])


def test_a_repeat_of_the_last_step_is_reported_and_an_older_or_incomplete_step_is_dropped():
    steps, repeats = [], []
    inputs = StepInputs(('odom', 'scan'), lambda stamp, msgs: steps.append(stamp),
                        on_repeat=repeats.append)
    inputs.add('odom', _stamped(0.1))          # step 0.1 never completes
    for name in ('odom', 'scan'):
        inputs.add(name, _stamped(0.2))
    inputs.add('scan', _stamped(0.1))          # late: its step is past
    inputs.add('odom', _stamped(0.2))          # the held world, published again
    assert steps == [200_000_000]
    assert repeats == [200_000_000]
    inputs.add('scan', _stamped(0.3))
    inputs.add('odom', _stamped(0.3))
    assert steps == [200_000_000, 300_000_000]


def test_a_marker_array_is_placed_by_its_first_marker_and_an_empty_one_names_no_step():
    steps = []
    inputs = StepInputs(('obstacles',), lambda stamp, msgs: steps.append(stamp))
    inputs.add('obstacles', MarkerArray())
    assert steps == []
    inputs.add('obstacles', MarkerArray(markers=[
        conv.delete_all_marker('map', conv.seconds_to_stamp(0.5))]))
    assert steps == [500_000_000]


# -- three nodes in lockstep -----------------------------------------------------------------

@pytest.fixture(scope='module')
def scenario_path(tmp_path_factory):
    """The closed-loop room: an obstacle the map lacks, two people, one of them bouncing."""
    return write_scenario(tmp_path_factory.mktemp('lockstep'), 'lockstep',
                          start=(1.05, 1.05, 0.0), goal=(9.05, 1.05),
                          unknown=[UNKNOWN_BOX], moving=PEOPLE)


def spinning(executor, nodes):
    """A :class:`~fusion_planner.cli.demo_command.Spinner` of ``executor`` with ``nodes``."""
    for node in nodes:
        executor.add_node(node)
    return demo.Spinner(executor)


def lockstep_run(context, scenario_path, real_time_factor, executor):
    """One run as the demo wires it; returns ``(arrival time [s], [(stamp, x, y, yaw)])``.

    The trajectory is the simulator's ground truth up to the arrival the
    local planner reported, as published (exact floats), one pose per step
    (the world held at t = 0 repeats its pose a number of times that
    depends on the wall clock).
    """
    scenario = load_scenario(scenario_path)
    params = demo.node_parameters(scenario, scenario_path, real_time_factor)
    recorder = demo.RunRecorder(scenario, params['local_planner']['goal_tolerance'],
                                SIM_TIME_LIMIT_S)
    truth = []
    monitor = Node('lockstep_monitor', context=context)
    demo.attach_recorder(monitor, recorder)
    monitor.create_subscription(
        Odometry, 'ground_truth', lambda msg: truth.append((
            conv.stamp_to_nanoseconds(msg.header.stamp), msg.pose.pose.position.x,
            msg.pose.pose.position.y, msg.pose.pose.orientation.z)),
        QoSProfile(depth=10_000, reliability=ReliabilityPolicy.RELIABLE))
    nodes = [monitor] + demo.make_nodes(context, params)
    spinner = spinning(executor, nodes)
    try:
        failure = demo.watch(recorder, SIM_TIME_LIMIT_S, WALL_LIMIT_S)
    finally:
        demo.shutdown_executor(spinner, nodes)
    assert failure is None, failure
    arrived_ns = round(recorder.arrived_at * conv.NS_PER_S)
    per_step = {row[0]: row for row in truth if row[0] <= arrived_ns}
    return recorder.arrived_at, [per_step[stamp] for stamp in sorted(per_step)]


def test_two_lockstep_runs_at_different_speeds_drive_the_same_trajectory(context, scenario_path):
    slow_arrival, slow = lockstep_run(context, scenario_path, 4.0,
                                      SingleThreadedExecutor(context=context))
    fast_arrival, fast = lockstep_run(context, scenario_path, 1000.0, demo.make_executor(context))
    assert slow_arrival == fast_arrival
    assert len(slow) == len(fast) > 100
    assert slow == fast  # every pose of every step, bit for bit


# -- the simulator in lockstep, alone ----------------------------------------------------

class LockstepProbe:
    """A lockstep simulator on the bundled demo; a probe listens (and publishes Twist commands
    unless the simulator takes TwistStamped)."""

    def __init__(self, context, **overrides):
        self.sim = sim.SimulatorNode(context=context, parameter_overrides=[
            Parameter(name, value=value) for name, value in dict(
                scenario=str(sim.default_scenario_path()), lockstep=True, real_time_factor=50.0,
                diagnostics_period=0.1, **overrides).items()])
        self.node = Node('lockstep_probe', context=context)
        self.lock = threading.Lock()
        self.clock_s = 0.0
        self.statuses = []
        self.node.create_subscription(Clock, 'clock', self._on_clock, 10)
        self.node.create_subscription(DiagnosticArray, 'diagnostics', self._on_diagnostics, 50)
        if not overrides.get('enable_stamped_cmd_vel'):  # one topic, one type per process
            self.cmd_pub = self.node.create_publisher(Twist, 'cmd_vel', 10)
        self.spinner = spinning(SingleThreadedExecutor(context=context), [self.sim, self.node])

    def _on_clock(self, msg):
        with self.lock:
            self.clock_s = conv.stamp_to_seconds(msg.clock)

    def _on_diagnostics(self, msg):
        with self.lock:
            self.statuses += [s for s in msg.status if s.name.endswith('/simulator')]

    def wait_until(self, condition, timeout_s=WAIT_S):
        deadline = time.monotonic() + timeout_s
        while time.monotonic() < deadline and not condition():
            time.sleep(0.01)
        return condition()

    def status_with(self, text):
        with self.lock:
            return next((s for s in self.statuses if text in s.message
                         or any(text in kv.value for kv in s.values)), None)

    def lockstep_after(self, heard):
        """The ``lockstep`` value of the latest status after the first ``heard`` ones (or None)."""
        with self.lock:
            later = self.statuses[heard:]
        values = [kv.value for s in later[-1:] for kv in s.values if kv.key == 'lockstep']
        return values[0] if values else None

    def close(self):
        demo.shutdown_executor(self.spinner, [self.sim, self.node])


def test_unstamped_commands_to_a_lockstep_simulator_are_an_error_and_the_world_runs_on(context):
    probe = LockstepProbe(context, enable_stamped_cmd_vel=False)
    try:
        assert probe.wait_until(lambda: probe.clock_s > 0.0)
        probe.cmd_pub.publish(Twist())  # cannot name the step it answers
        assert probe.wait_until(lambda: probe.status_with('lockstep needs stamped') is not None)
        status = probe.status_with('lockstep needs stamped')
        assert status.level == sim.ERROR
        assert 'enable_stamped_cmd_vel' in status.message
        running_from = probe.clock_s
        assert probe.wait_until(lambda: probe.clock_s > running_from + 1.0)  # no hang
    finally:
        probe.close()


def test_a_lockstep_step_nobody_answers_is_reported_after_the_timeout_and_the_world_runs_on(
        context):
    probe = LockstepProbe(context, enable_stamped_cmd_vel=True, lockstep_timeout=0.3)
    try:
        assert probe.wait_until(lambda: probe.clock_s > 0.0)
        first_step = probe.clock_s
        time.sleep(0.2)  # within the timeout: the world waits for the command
        assert probe.clock_s == first_step
        assert probe.wait_until(lambda: probe.clock_s > first_step + 1.0)
        assert probe.status_with('within 0.3 s of wall time') is not None
    finally:
        probe.close()


def test_after_a_timeout_any_stamped_answer_brings_the_lockstep_back(context):
    probe = LockstepProbe(context, enable_stamped_cmd_vel=True, lockstep_timeout=3.0)
    cmd_pub = probe.node.create_publisher(TwistStamped, 'cmd_vel', 10)
    try:
        assert probe.wait_until(lambda: probe.clock_s > 0.0)
        first_step = probe.clock_s
        assert probe.wait_until(lambda: probe.clock_s > first_step + 1.0)  # running free
        heard = len(probe.statuses)
        # The answer to the first step comes long after it: the world has moved
        # on, and now waits for the answer to its current step.
        cmd_pub.publish(TwistStamped(header=Header(stamp=conv.seconds_to_stamp(first_step))))
        assert probe.wait_until(lambda: probe.lockstep_after(heard) == 'on')
        held = probe.clock_s
        time.sleep(0.3)  # within the timeout
        assert probe.clock_s == held
        cmd_pub.publish(TwistStamped(header=Header(stamp=conv.seconds_to_stamp(held))))
        assert probe.wait_until(lambda: probe.clock_s > held)
        stepped = probe.clock_s
        time.sleep(0.3)
        assert probe.clock_s == stepped  # one step per answer
    finally:
        probe.close()


def test_a_lockstep_local_planner_without_stamped_commands_is_refused_with_a_reason(context):
    with pytest.raises(InvalidInput, match='lockstep needs enable_stamped_cmd_vel'):
        LocalPlannerNode(context=context, parameter_overrides=[
            Parameter('lockstep', value=True)])
