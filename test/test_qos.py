"""LatchedOrVolatile over DDS: a publisher in another process, latched or volatile.

Only a reliable transient-local subscription gets what a latched publisher
sent before it joined; a volatile publisher matches only volatile
subscriptions. The pair must take both, each message exactly once.
"""

import subprocess
import sys
import textwrap
import time

import pytest

rclpy = pytest.importorskip('rclpy')

from nav_msgs.msg import Path  # noqa: E402
from rclpy.executors import SingleThreadedExecutor  # noqa: E402
from rclpy.qos import ReliabilityPolicy  # noqa: E402

from fusion_planner.ros.qos import LatchedOrVolatile  # noqa: E402

#: The publisher process: one message before anybody listens, one once a
#: subscriber matched, then it waits to be killed.
PUBLISHER = textwrap.dedent('''
    import sys, time
    import rclpy
    from nav_msgs.msg import Path
    from rclpy.qos import DurabilityPolicy, QoSProfile, ReliabilityPolicy
    reliability, durability = sys.argv[1:3]
    rclpy.init()
    node = rclpy.create_node('peer_publisher')
    qos = QoSProfile(depth=1, reliability=getattr(ReliabilityPolicy, reliability),
                     durability=getattr(DurabilityPolicy, durability))
    pub = node.create_publisher(Path, 'plan', qos)
    def path(sec):
        msg = Path()
        msg.header.frame_id = 'map'
        msg.header.stamp.sec = sec
        return msg
    pub.publish(path(1))
    print('first sent', flush=True)
    while pub.get_subscription_count() == 0:
        rclpy.spin_once(node, timeout_sec=0.05)
    time.sleep(1.0)  # both subscriptions of the pair match
    pub.publish(path(2))
    print('second sent', flush=True)
    while True:
        rclpy.spin_once(node, timeout_sec=0.1)
''')
#: Longest wait for a message [s].
WAIT_S = 10.0


@pytest.mark.parametrize('reliability, durability, volatile_side, expected', [
    ('RELIABLE', 'TRANSIENT_LOCAL', 'RELIABLE', [1, 2]),   # map_server, our planner
    ('RELIABLE', 'VOLATILE', 'RELIABLE', [2]),             # Nav2's planner_server
    ('RELIABLE', 'TRANSIENT_LOCAL', 'BEST_EFFORT', [1, 2]),  # AMCL's amcl_pose
    ('BEST_EFFORT', 'VOLATILE', 'BEST_EFFORT', [2]),       # a best-effort localiser
])
def test_latched_and_volatile_publishers_are_heard_once_per_message(
        context, reliability, durability, volatile_side, expected):
    peer = subprocess.Popen([sys.executable, '-c', PUBLISHER, reliability, durability],
                            stdout=subprocess.PIPE, text=True)
    node = rclpy.create_node('pair_subscriber', context=context)
    executor = SingleThreadedExecutor(context=context)
    executor.add_node(node)
    try:
        assert peer.stdout.readline().strip() == 'first sent'
        time.sleep(0.5)  # the first message is history by the time we join
        got = []
        pair = LatchedOrVolatile(node, Path, 'plan', lambda m: got.append(m.header.stamp.sec),
                                 getattr(ReliabilityPolicy, volatile_side))
        deadline = time.monotonic() + WAIT_S
        while time.monotonic() < deadline and got != expected:
            executor.spin_once(timeout_sec=0.05)
        for _ in range(20):  # a second copy would arrive within this
            executor.spin_once(timeout_sec=0.05)
        assert got == expected
        assert pair.get_publisher_count() == 1
    finally:
        peer.kill()
        peer.wait()
        executor.shutdown()
        node.destroy_node()
