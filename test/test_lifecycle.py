"""The nodes are managed: lifecycle transitions asked over DDS from another process.

The local planner runs as its own process (``autostart: false``); this test
process is the lifecycle manager (lifecycle_msgs services, as ``ros2
lifecycle set`` and nav2_lifecycle_manager call them) and the robot (plan,
odometry, scans in; stock-QoS cmd_vel subscriber).
"""

import math
import os
import subprocess
import sys
import time

import pytest

rclpy = pytest.importorskip('rclpy')

from geometry_msgs.msg import Twist  # noqa: E402
from lifecycle_msgs.msg import State, Transition  # noqa: E402
from lifecycle_msgs.srv import ChangeState, GetState  # noqa: E402
from nav_msgs.msg import Odometry  # noqa: E402
from nav_msgs.msg import Path  # noqa: E402
from rclpy.executors import SingleThreadedExecutor  # noqa: E402
from sensor_msgs.msg import LaserScan  # noqa: E402

from conftest import REPO  # noqa: E402
from fusion_planner.ros import conversions as conv  # noqa: E402
from fusion_planner.ros.qos import LATCHED_QOS, SENSOR_QOS  # noqa: E402

#: Longest wait for a service answer or a message [s].
WAIT_S = 20.0
#: Rate of the fake robot's odometry and scans [Hz].
SENSOR_RATE_HZ = 20.0


def start_node(module, *ros_args):
    env = dict(os.environ, PYTHONPATH=str(REPO))
    return subprocess.Popen([sys.executable, '-m', f'fusion_planner.ros.{module}', '--ros-args',
                             *ros_args], env=env, stdout=subprocess.PIPE,
                            stderr=subprocess.STDOUT, text=True)


class Manager:
    """Lifecycle client of one node, plus a fake robot around a local planner."""

    def __init__(self, context, node_name, odom_frame='map'):
        self.odom_frame = odom_frame
        self.node = rclpy.create_node('lifecycle_manager', context=context)
        self.executor = SingleThreadedExecutor(context=context)
        self.executor.add_node(self.node)
        self.get_state = self.node.create_client(GetState, f'/{node_name}/get_state')
        self.change_state = self.node.create_client(ChangeState, f'/{node_name}/change_state')
        self.commands = []  # (wall time [s], v, omega)
        self.node.create_subscription(Twist, 'cmd_vel', self._on_cmd, 10)  # stock QoS
        self.odom_pub = self.node.create_publisher(Odometry, 'odom', 10)
        self.scan_pub = self.node.create_publisher(LaserScan, 'scan', SENSOR_QOS)
        self.plan_pub = self.node.create_publisher(Path, 'plan', LATCHED_QOS)
        self.node.create_timer(1.0 / SENSOR_RATE_HZ, self._publish_sensors)

    def _on_cmd(self, msg):
        self.commands.append((time.monotonic(), *conv.twist_to_velocity(msg)))

    def _publish_sensors(self):
        stamp = self.node.get_clock().now().to_msg()
        odom = Odometry()
        odom.header.frame_id, odom.header.stamp = self.odom_frame, stamp
        odom.pose.pose.orientation.w = 1.0
        self.odom_pub.publish(odom)
        scan = LaserScan()
        scan.header.frame_id, scan.header.stamp = 'base_link', stamp
        scan.angle_min, scan.angle_increment = -math.pi, math.pi / 90
        scan.range_min, scan.range_max = 0.05, 8.0
        scan.ranges = [math.inf] * 180
        self.scan_pub.publish(scan)

    def spin_until(self, condition, timeout=WAIT_S):
        deadline = time.monotonic() + timeout
        while not condition() and time.monotonic() < deadline:
            self.executor.spin_once(timeout_sec=0.02)
        return condition()

    def spin_for(self, seconds):
        self.spin_until(lambda: False, seconds)

    def call(self, client, request):
        assert client.wait_for_service(timeout_sec=WAIT_S), 'the node process did not come up'
        future = client.call_async(request)
        assert self.spin_until(future.done), 'no answer'
        return future.result()

    def state(self):
        return self.call(self.get_state, GetState.Request()).current_state.id

    def transition(self, transition_id):
        request = ChangeState.Request(transition=Transition(id=transition_id))
        return self.call(self.change_state, request).success

    def moving_since(self, t):
        return [c for c in self.commands if c[0] >= t and (c[1] or c[2])]

    def commands_since(self, t):
        return [c for c in self.commands if c[0] >= t]

    def close(self):
        self.executor.shutdown()
        self.node.destroy_node()


def test_local_planner_lifecycle_over_dds_with_a_repeated_transition(context):
    proc = start_node('local_planner', '-p', 'autostart:=false', '-p', 'odom_frame_id:=map')
    manager = Manager(context, 'local_planner')
    try:
        assert manager.state() == State.PRIMARY_STATE_UNCONFIGURED
        manager.plan_pub.publish(conv.path_to_msg([[0.0, 0.0], [5.0, 0.0]], 'map',
                                                  conv.seconds_to_stamp(1.0)))
        assert manager.transition(Transition.TRANSITION_CONFIGURE)
        assert manager.state() == State.PRIMARY_STATE_INACTIVE
        manager.spin_for(1.0)
        assert not manager.commands, 'an inactive local planner commands nothing'

        assert manager.transition(Transition.TRANSITION_ACTIVATE)
        assert manager.spin_until(lambda: manager.moving_since(0.0)), 'active, it drives'
        # Asked twice: refused, and the node lives on in its state.
        assert not manager.transition(Transition.TRANSITION_ACTIVATE)
        assert manager.state() == State.PRIMARY_STATE_ACTIVE
        assert not manager.transition(Transition.TRANSITION_CONFIGURE)

        assert manager.transition(Transition.TRANSITION_DEACTIVATE)
        t0 = time.monotonic()
        manager.spin_for(1.5)
        after = manager.commands_since(t0 - 0.5)
        assert after and not manager.moving_since(t0 + 0.2), 'deactivated: it stops'
        assert len(manager.commands_since(t0 + 0.2)) == 0, 'and then stays silent'

        assert not manager.transition(Transition.TRANSITION_DEACTIVATE)  # twice again
        assert manager.transition(Transition.TRANSITION_CLEANUP)
        assert manager.state() == State.PRIMARY_STATE_UNCONFIGURED
        # Configured again: the latched plan arrives again and the robot drives.
        assert manager.transition(Transition.TRANSITION_CONFIGURE)
        assert manager.transition(Transition.TRANSITION_ACTIVATE)
        t1 = time.monotonic()
        assert manager.spin_until(lambda: manager.moving_since(t1))
        assert proc.poll() is None, 'the node died'
    finally:
        manager.close()
        proc.terminate()
        output, _ = proc.communicate(timeout=15.0)
    assert 'Traceback' not in output
    assert "lifecycle transition id 3 refused in state 'active'" in output, output


@pytest.mark.parametrize('module', ['global_planner', 'local_planner', 'simulator'])
def test_every_node_activates_itself_by_default(context, module):
    proc = start_node(module)
    manager = Manager(context, module)
    try:
        assert manager.spin_until(lambda: manager.state() == State.PRIMARY_STATE_ACTIVE, 20.0)
    finally:
        manager.close()
        proc.terminate()
        proc.communicate(timeout=15.0)
