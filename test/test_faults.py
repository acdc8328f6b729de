"""Faults in a running closed loop: sensors stop, the clock jumps back, the planner dies.

The three nodes run in one SingleThreadedExecutor of this process on a short
corridor, on simulated time, wired as the demo wires them
(:mod:`fusion_planner.cli.demo_command`) but running free, as on a robot
(:func:`free_running`: a lost input is a fault to survive, where in lockstep
it would hold the world); a monitor records clock, odometry,
plans and diagnostics, and every command the local planner publishes is
recorded with the simulated time it was computed at and the times of the
inputs it used (odometry stamp, odometry and scan receipt). Faults are
injected at a simulated time, and every promise is checked in simulated
time, so a slow machine slows a run down instead of failing it; every wait
is bounded.

- Odometry stops: every command later than ``odom_timeout`` (0.5 s) after
  the last odometry arrived is zero; the robot drives on when odometry is
  back. Ages count from arrival on the node's clock, as the node counts them
  (robust to a sender's clock offset); the last message can arrive a step
  after it was sent.
- Scans stop: every command later than ``scan_timeout`` after the last scan
  arrived is zero (``on_stale_scan: stop``) or no faster than
  ``stale_scan_speed`` (``slow``, set at run time).
- The simulator restarts, so its clock jumps back to 0 (a reset): no node
  reports a fault, no moving command uses an input of before the jump (one
  stamped or received later than the command's time), and the robot
  reaches the goal in the new run.
- The global planner is killed and restarted: the robot stops within
  ``plan_timeout`` and reaches the goal on the new planner's plan.
"""

import contextlib
import math
import time

import numpy as np
import pytest
import yaml

rclpy = pytest.importorskip('rclpy')

from geometry_msgs.msg import PoseStamped  # noqa: E402
from rclpy.executors import SingleThreadedExecutor  # noqa: E402
from rclpy.node import Node  # noqa: E402
from rclpy.parameter import Parameter  # noqa: E402

from fusion_planner.cli import demo_command as demo  # noqa: E402
from fusion_planner.core.grid import GridMap  # noqa: E402
from fusion_planner.core.map_files import save_map_server  # noqa: E402
from fusion_planner.core.simulation.scenario import load_scenario  # noqa: E402
from fusion_planner.ros.global_planner import GlobalPlannerNode  # noqa: E402
from fusion_planner.ros.qos import RELIABLE_QOS  # noqa: E402
from fusion_planner.ros.simulator import SimulatorNode  # noqa: E402

#: Requested speed-up; the lockstep makes the achieved one what the CPU allows.
REAL_TIME_FACTOR = 10.0
#: Control and simulation step [s].
DT = 0.05
#: How long a fault lasts [s of simulated time].
FAULT_S = 1.5
#: Simulated time limit of a run [s] (the robot needs about 10 s unhindered).
SIM_LIMIT_S = 60.0
#: Wall time limit of one wait [s].
WALL_LIMIT_S = 60.0
#: Slack on simulated-time comparisons [s] (sums of steps are inexact).
EPS_S = 1e-3
#: Speed [m/s] above which a command counts as moving.
MOVING_MPS = 0.05


@pytest.fixture(scope='module')
def corridor(tmp_path_factory):
    """A 9 m x 3 m walled corridor; the robot drives 6.9 m along it."""
    folder = tmp_path_factory.mktemp('faults')
    occupied = np.zeros((30, 90), dtype=bool)
    occupied[[0, -1], :] = True
    occupied[:, [0, -1]] = True
    save_map_server(GridMap(occupied, resolution=0.1), folder / 'corridor.yaml')
    doc = {'name': 'corridor', 'map': 'corridor.yaml',
           'robot': {'start': [1.05, 1.55, 0.0], 'radius': 0.2, 'max_speed': 0.8},
           'goal': [7.95, 1.55], 'limits': {'time_limit_s': SIM_LIMIT_S, 'dt': DT},
           'scan': {'beams': 90, 'range_max': 5.0}}
    path = folder / 'corridor_run.yaml'
    path.write_text(yaml.safe_dump(doc))
    return path


class Muted:
    """Stands in for a sensor's publisher and drops what it is given (the sensor stopped)."""

    def publish(self, msg):
        pass


def free_running(params):
    """The demo's parameters (:func:`demo.node_parameters`) without lockstep, in place.

    The simulator still waits for a late controller (``sync_with_controller``,
    one step per command with ``max_command_lag`` 0), so a busy machine slows
    the run down rather than changing it much.
    """
    for values in params.values():
        values['lockstep'] = False
    params['simulator'].update(sync_with_controller=True, max_command_lag=0.0)
    return params


class Loop:
    """Simulator, global and local planner and a monitor, spun in the background."""

    def __init__(self, context, scenario_path):
        self.context = context
        self.scenario = load_scenario(scenario_path)
        self.params = free_running(
            demo.node_parameters(self.scenario, scenario_path, REAL_TIME_FACTOR))
        self.recorder = demo.RunRecorder(self.scenario,
                                         self.params['local_planner']['goal_tolerance'])
        self.monitor = Node('fault_monitor', context=context)
        demo.attach_recorder(self.monitor, self.recorder)
        self.goal_pub = self.monitor.create_publisher(PoseStamped, 'goal_pose', RELIABLE_QOS)
        self.sim, self.planner, self.local = demo.make_nodes(context, self.params)
        # (simulated time [s], v, omega, latest input time [s]: odometry stamp and
        # receipt, scan receipt; -inf without inputs)
        self.commands = []
        publish_command = self.local._publish_command

        def record(v, omega, idle=False):
            node = self.local
            times = [node._odom[0], node._odom_received] if node._odom is not None else []
            times += [node._scan[1]] if node._scan is not None else []
            self.commands.append((node._now_s(), v, omega, max(times, default=-math.inf)))
            publish_command(v, omega, idle)
        self.local._publish_command = record
        self.executor = self.spinner = None
        self._spin()

    def nodes(self):
        """The nodes alive now (the global planner is None while it is dead)."""
        return [n for n in (self.monitor, self.sim, self.planner, self.local) if n is not None]

    def _spin(self):
        self.executor = SingleThreadedExecutor(context=self.context)
        for node in self.nodes():
            self.executor.add_node(node)
        self.spinner = demo.Spinner(self.executor)

    @contextlib.contextmanager
    def paused(self):
        """Stop spinning (simulated time stands still), let the caller swap nodes, spin again."""
        self.spinner.stop()
        try:
            yield
        finally:
            self._spin()

    def wait_for(self, condition, wall_limit_s=WALL_LIMIT_S):
        deadline = time.monotonic() + wall_limit_s
        while time.monotonic() < deadline:
            if condition():
                return True
            time.sleep(0.01)
        return condition()

    def sim_time(self):
        return self.sim.world.time

    def wait_sim_time(self, t):
        return self.wait_for(lambda: self.sim_time() >= t)

    def moving_since(self, t):
        return any(c[0] > t and c[1] > MOVING_MPS for c in list(self.commands))

    def commands_after(self, t):
        return [c for c in list(self.commands) if c[0] > t + EPS_S]

    def timeout(self, name):
        """The local planner's parameter ``name`` [s]."""
        return self.local.get_parameter(name).value

    def mute(self, name):
        """Drop what the simulator publishes on ``_<name>_pub`` from now on; returns the time.

        Read after the swap, the time is no earlier than the stamp of the last
        message that went out.
        """
        setattr(self.sim, f'_{name}_pub', Muted())
        return self.sim_time()

    def unmute(self, name, publisher):
        setattr(self.sim, f'_{name}_pub', publisher)
        return self.sim_time()

    def send_goal_until_planned(self):
        """Publish the scenario's goal until the global planner has a plan for it."""
        msg = PoseStamped()
        msg.header.frame_id = 'map'
        msg.pose.position.x, msg.pose.position.y = self.scenario.goal
        msg.pose.orientation.w = 1.0
        deadline = time.monotonic() + WALL_LIMIT_S
        while time.monotonic() < deadline and self.planner._plan is None:
            if self.goal_pub.get_subscription_count() > 0:
                self.goal_pub.publish(msg)
            self.wait_for(lambda: self.planner._plan is not None, 0.5)
        return self.planner._plan is not None

    def assert_arrives_safely(self):
        failure = demo.watch(self.recorder, SIM_LIMIT_S, WALL_LIMIT_S)
        assert failure is None, failure
        assert self.sim.world.contact_events == 0
        for node in (self.sim, self.planner, self.local):
            values = node._diagnostics.values
            assert values['faults'] == 0, (node.get_name(), values['last_error'])
        assert self.spinner.error is None, self.spinner.error

    def close(self):
        demo.shutdown_executor(self.spinner, self.nodes())


@pytest.fixture
def loop(context, corridor):
    run = Loop(context, corridor)
    yield run
    run.close()


def assert_all_stopped_after(loop, t):
    """Every command computed later than ``t`` is zero, and there are some."""
    after = loop.commands_after(t)
    assert after, f'no command after t = {t:.2f} s'
    moving = [c for c in after if c[1] != 0.0 or c[2] != 0.0]
    assert not moving, f'moving at t = {moving[0][0]:.2f} s, stop due at {t:.2f} s'


def last_arrival(loop, name):
    """When the local planner received its last ``odom`` or ``scan`` [s, node clock]."""
    local = loop.local
    return local._odom_received if name == 'odom' else local._scan[1]


def test_odometry_or_scans_stopping_stop_or_slow_the_robot_and_it_drives_on(loop):
    assert loop.wait_for(lambda: loop.moving_since(0.0)), 'the robot never started'

    odom_pub = loop.sim._odom_pub
    stopped = loop.mute('odom')
    assert loop.wait_sim_time(stopped + loop.timeout('odom_timeout') + FAULT_S)
    assert_all_stopped_after(loop, last_arrival(loop, 'odom') + loop.timeout('odom_timeout'))
    back = loop.unmute('odom', odom_pub)
    assert loop.wait_for(lambda: loop.moving_since(back)), 'no motion after odometry came back'

    scan_pub = loop.sim._scan_pub
    stopped = loop.mute('scan')
    assert loop.wait_sim_time(stopped + loop.timeout('scan_timeout') + FAULT_S)
    assert_all_stopped_after(loop, last_arrival(loop, 'scan') + loop.timeout('scan_timeout'))
    back = loop.unmute('scan', scan_pub)
    assert loop.wait_for(lambda: loop.moving_since(back)), 'no motion after scans came back'

    slow = 0.1  # [m/s]
    assert all(r.successful for r in loop.local.set_parameters([
        Parameter('on_stale_scan', value='slow'), Parameter('stale_scan_speed', value=slow)]))
    stopped = loop.mute('scan')
    assert loop.wait_sim_time(stopped + loop.timeout('scan_timeout') + FAULT_S)
    after = loop.commands_after(last_arrival(loop, 'scan') + loop.timeout('scan_timeout'))
    assert after and max(c[1] for c in after) <= slow + 1e-9
    assert any(c[1] > 0.0 for c in after), 'slow, not stopped'
    loop.unmute('scan', scan_pub)

    loop.assert_arrives_safely()


def test_simulator_restart_jumps_the_clock_back_without_stale_motion_or_faults(loop, context):
    assert loop.wait_for(lambda: loop.moving_since(0.0) and loop.sim_time() > 3.0)
    with loop.paused():
        before = loop.sim_time()
        loop.sim.destroy_node()
        restarted = dict(loop.params['simulator'], start_paused=False)  # a reset runs on at once
        loop.sim = SimulatorNode(context=context, parameter_overrides=[
            Parameter(k, value=v) for k, v in restarted.items()])
        odom_pub = loop.sim._odom_pub
        loop.mute('odom')  # its odometry comes up late: only the old one is at hand
    assert loop.wait_sim_time(FAULT_S)
    jumped = [c for c in list(loop.commands) if c[0] < before - EPS_S]
    assert jumped, 'the local planner never ran on the new clock'
    loop.unmute('odom', odom_pub)
    loop.assert_arrives_safely()
    stale = [c for c in loop.commands if (c[1] != 0.0 or c[2] != 0.0) and c[3] > c[0] + EPS_S]
    assert not stale, f'moving at t = {stale[0][0]:.2f} s on an input of t = {stale[0][3]:.2f} s'


def test_global_planner_killed_and_restarted_stops_the_robot_then_it_drives_on(loop, context):
    assert loop.wait_for(lambda: loop.moving_since(0.0) and loop.sim_time() > 2.0)
    with loop.paused():
        loop.planner.destroy_node()
        killed = loop.sim_time()
        loop.planner = None
    timeout = loop.timeout('plan_timeout')
    assert loop.wait_sim_time(killed + timeout + FAULT_S)
    assert_all_stopped_after(loop, killed + timeout + DT)  # checked once per control step
    with loop.paused():
        loop.planner = GlobalPlannerNode(context=context, parameter_overrides=[
            Parameter(k, value=v) for k, v in loop.params['global_planner'].items()])
    assert loop.send_goal_until_planned(), 'the new global planner made no plan'
    loop.assert_arrives_safely()
    assert math.dist(loop.recorder.plan[-1], loop.scenario.goal) < 0.2
