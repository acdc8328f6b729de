"""The nodes in a ROS 2 stack: separate processes over DDS, stock-QoS peers.

Each node runs as its own process (``python -m fusion_planner.ros.<node>``);
this process plays the rest of the stack with stock QoS (reliable, volatile,
depth 10, as RViz, Nav2 and ``ros2 topic echo`` subscribe) where a stack
would: a Nav2-style volatile plan publisher, AMCL's latched pose, a
TwistStamped controller, a lifecycle manager (test_lifecycle.py).
"""

import math
import time

import numpy as np
import pytest

rclpy = pytest.importorskip('rclpy')

from diagnostic_msgs.msg import DiagnosticArray  # noqa: E402
from geometry_msgs.msg import PoseWithCovarianceStamped, TwistStamped  # noqa: E402
from nav_msgs.msg import Odometry, Path  # noqa: E402
from sensor_msgs.msg import LaserScan  # noqa: E402
from std_msgs.msg import String  # noqa: E402
from lifecycle_msgs.msg import State, Transition  # noqa: E402
from std_srvs.srv import Trigger  # noqa: E402

from fusion_planner.ros import conversions as conv  # noqa: E402
from fusion_planner.ros.frames import compose  # noqa: E402
from fusion_planner.ros.qos import LATCHED_QOS, SENSOR_QOS  # noqa: E402
from test_closed_loop import (  # noqa: E402
    PEOPLE, UNKNOWN_BOX, Run, assert_arrived_safely, report, sigint_and_wait, write_scenario)
from test_lifecycle import Manager, start_node  # noqa: E402

#: Odometry drift of the drifting run: distance error per metre, heading error per metre.
DRIFT = {'odom_scale_error': 0.05, 'odom_yaw_drift': 0.02}
#: Wall time allowed for a reaction [s].
WAIT_S = 20.0


def free_running(overrides=None):
    """Node parameter overrides for a stack on the wall clock (no lockstep), as a robot runs."""
    merged = {'simulator': {'lockstep': False, 'sync_with_controller': True,
                            'max_command_lag': 0.0},
              'global_planner': {'lockstep': False}, 'local_planner': {'lockstep': False}}
    for node, values in (overrides or {}).items():
        merged[node].update(values)
    return merged


@pytest.fixture
def scenario(tmp_path):
    return write_scenario(tmp_path / 'scenario', 'stack', start=(1.05, 1.05, 0.0),
                          goal=(9.05, 1.05), unknown=[UNKNOWN_BOX], moving=PEOPLE)


def odometry_drift(start, odom, truth):
    """Distance [m] between where odometry puts the robot (from the start) and where it is."""
    odom_in_map = compose(start, conv.pose_to_xy_yaw(odom.pose.pose))
    return math.hypot(odom_in_map[0] - truth[0], odom_in_map[1] - truth[1])


def test_drifting_odometry_and_stamped_commands_reach_the_goal_judged_in_ground_truth(
        context, scenario, tmp_path):
    run = Run(context, scenario, in_process=False, log_dir=tmp_path / 'logs',
              overrides=free_running({'simulator': DRIFT,
                                      'local_planner': {'enable_stamped_cmd_vel': True}}))
    odometry, commands = [], []
    run.monitor.create_subscription(Odometry, 'odom', odometry.append, 10)  # stock QoS
    run.monitor.create_subscription(TwistStamped, 'cmd_vel', commands.append, 10)
    try:
        failure = run.wait_arrival()
        status = assert_arrived_safely(run, failure)  # judged on ground_truth
        report('drifting odometry', run, status)
        drift = odometry_drift(run.scenario.start, odometry[-1], run.recorder.poses[-1])
        print(f'odometry drift over the run: {drift:.2f} m')
        assert drift > 0.3
        assert odometry[-1].header.frame_id == 'odom'
        # TwistStamped end to end: the simulator followed the publisher's type and drove.
        moving = [c for c in commands if c.twist.linear.x > 0.0]
        assert moving and all(c.header.frame_id == 'base_link' for c in moving)
    finally:
        results = sigint_and_wait(run.procs)
        run.close()
    for name, (code, log) in results.items():
        assert code == 0 and 'Traceback' not in log, f'{name}: exit {code}\n{log[-3000:]}'


def test_cancel_stops_the_robot_and_nothing_resumes(context, scenario, tmp_path):
    run = Run(context, scenario, in_process=False, log_dir=tmp_path / 'logs',
              overrides=free_running())
    outcomes = []
    run.monitor.create_subscription(String, 'goal_outcome', lambda m: outcomes.append(m.data), 10)
    cancel = run.monitor.create_client(Trigger, 'cancel_goal')
    try:
        assert run.wait_for(lambda: run.recorder.poses and math.hypot(
            run.recorder.poses[-1][0] - 1.05, run.recorder.poses[-1][1] - 1.05) > 1.0, 40.0), \
            f'the robot did not leave the start: {run.discovery()}'
        assert cancel.wait_for_service(timeout_sec=WAIT_S)
        future = cancel.call_async(Trigger.Request())
        assert run.wait_for(future.done, WAIT_S) and future.result().success
        assert run.wait_for(lambda: outcomes == ['cancelled'], WAIT_S), \
            f'goal outcomes heard: {outcomes}'
        stopped_at = run.recorder.sim_time + 1.0  # braking takes well under a second
        assert run.wait_for(lambda: run.recorder.sim_time > stopped_at, WAIT_S)
        where = run.recorder.poses[-1]
        resume_by = run.recorder.sim_time + 5.0
        assert run.wait_for(lambda: run.recorder.sim_time > resume_by, 30.0)
        assert math.dist(run.recorder.poses[-1][:2], where[:2]) < 0.02, 'something resumed'
        assert outcomes == ['cancelled']
        assert math.dist(run.recorder.poses[-1][:2], run.scenario.goal) > 1.0
    finally:
        results = sigint_and_wait(run.procs)
        run.close()
    for name, (code, log) in results.items():
        assert code == 0 and 'Traceback' not in log, f'{name}: exit {code}\n{log[-3000:]}'


def amcl_pose(node, x, y, yaw, frame='map', covariance=0.01):
    msg = PoseWithCovarianceStamped()
    msg.header.frame_id, msg.header.stamp = frame, node.get_clock().now().to_msg()
    msg.pose.pose = conv.xy_yaw_to_pose((x, y, yaw))
    msg.pose.covariance[0] = covariance
    return msg


def test_local_planner_takes_a_latched_pose_and_a_volatile_plan_and_is_silent_when_idle(context):
    manager = Manager(context, 'local_planner', odom_frame='odom')  # odometry, scans, cmd_vel
    node = manager.node
    # AMCL's pose, latched before the local planner exists: (1, 2) facing +y.
    amcl_pub = node.create_publisher(PoseWithCovarianceStamped, 'amcl_pose', LATCHED_QOS)
    amcl_pub.publish(amcl_pose(node, 1.0, 2.0, math.pi / 2))
    plan_pub = node.create_publisher(Path, 'plan', 10)  # volatile, as Nav2's planner_server
    errors = []  # the local planner's last_error on /diagnostics
    node.create_subscription(DiagnosticArray, '/diagnostics', lambda m: errors.extend(
        {kv.key: kv.value for kv in s.values}.get('last_error', '') for s in m.status
        if s.name == '/local_planner'), 10)
    # Brought up by a lifecycle manager, so that our cmd_vel subscriber is matched
    # before its first command.
    proc = start_node('local_planner', '-p', 'autostart:=false')
    try:
        assert manager.state() == State.PRIMARY_STATE_UNCONFIGURED  # matched both ways
        assert manager.transition(Transition.TRANSITION_CONFIGURE)
        assert manager.spin_until(lambda: manager.node.count_publishers('/cmd_vel') > 0)
        manager.spin_for(0.5)
        assert manager.transition(Transition.TRANSITION_ACTIVATE)
        assert manager.spin_until(lambda: manager.commands, WAIT_S), 'no first command'
        manager.spin_for(1.5)
        assert len(manager.commands) == 1 and not manager.moving_since(0.0), 'idle: one zero'
        # Bad inputs: a pose in a frame nobody knows, a localizer that lost track.
        amcl_pub.publish(amcl_pose(node, 1.0, 2.0, math.pi / 2, frame='world'))
        assert manager.spin_until(lambda: any("frame 'world'" in e for e in errors), WAIT_S)
        amcl_pub.publish(amcl_pose(node, 1.0, 2.0, math.pi / 2, covariance=math.nan))
        assert manager.spin_until(lambda: any('covariance' in e for e in errors), WAIT_S)
        assert manager.spin_until(lambda: plan_pub.get_subscription_count() > 0)
        plan_pub.publish(conv.path_to_msg([[1.0, 2.0], [1.0, 6.0]], 'map',
                                          node.get_clock().now().to_msg()))
        assert manager.spin_until(lambda: len(manager.moving_since(0.0)) >= 10, WAIT_S)
        last = manager.moving_since(0.0)[-1]
        assert last[1] > 0.0 and abs(last[2]) < 0.1, last  # straight ahead in the odom frame
        assert proc.poll() is None
    finally:
        manager.close()
        proc.terminate()
        output, _ = proc.communicate(timeout=15.0)
    assert "frame 'world'" in output, output  # one line; the NaN one is rate-limited with it
    assert 'incompatible QoS' not in output, output
    assert 'Traceback' not in output


def test_simulator_takes_twist_stamped_from_another_process_and_refuses_a_nan(context):
    proc = start_node('simulator')  # subscribed as Twist until it sees our publisher
    node = rclpy.create_node('stamped_driver', context=context)
    truth, statuses = [], []
    node.create_subscription(Odometry, 'ground_truth', truth.append, 10)
    node.create_subscription(DiagnosticArray, '/diagnostics', lambda m: statuses.extend(
        s for s in m.status if s.name == '/simulator'), 10)
    node.create_subscription(LaserScan, 'scan', lambda m: None, SENSOR_QOS)
    pub = node.create_publisher(TwistStamped, 'cmd_vel', 10)
    executor = rclpy.executors.SingleThreadedExecutor(context=context)
    executor.add_node(node)

    def drive(v, seconds):
        end = time.monotonic() + seconds
        while time.monotonic() < end:
            pub.publish(_stamped(v))
            executor.spin_once(timeout_sec=0.05)

    try:
        deadline = time.monotonic() + WAIT_S
        while time.monotonic() < deadline and not (truth and pub.get_subscription_count() > 0):
            executor.spin_once(timeout_sec=0.05)
        assert truth and pub.get_subscription_count() > 0, 'the simulator never took TwistStamped'
        drive(0.4, 2.0)
        assert truth[-1].twist.twist.linear.x > 0.2
        drive(math.nan, 2.0)
        assert truth[-1].twist.twist.linear.x == 0.0
        assert any(int({kv.key: kv.value for kv in s.values}['rejected']) > 0 for s in statuses)
        assert proc.poll() is None
    finally:
        executor.shutdown()
        node.destroy_node()
        proc.terminate()
        output, _ = proc.communicate(timeout=15.0)
    assert 'cmd_vel is published as TwistStamped' in output, output
    assert 'Traceback' not in output


def _stamped(v):
    msg = TwistStamped()
    msg.header.frame_id = 'base_link'
    msg.twist.linear.x = v
    return msg


def test_odometry_drift_measure():
    start = np.array([1.0, 1.0, math.pi / 2])
    odom = Odometry()
    odom.pose.pose = conv.xy_yaw_to_pose((2.0, 0.0, 0.0))  # 2 m ahead of the start
    assert odometry_drift(start, odom, (1.0, 3.0)) == pytest.approx(0.0, abs=1e-9)
    assert odometry_drift(start, odom, (1.0, 2.5)) == pytest.approx(0.5)
