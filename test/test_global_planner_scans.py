"""The global_planner node learns obstacles from ``scan``: replans around them, forgets them.

Over real DDS with the harness of test_global_planner_node: a wall with a gap
below and above it, a scan that shows the planned gap closed, then the same
scan with the gap open again.
"""

import math

import numpy as np
import pytest
from rclpy.parameter import Parameter
from sensor_msgs.msg import LaserScan

from fusion_planner.core.simulation.world import Rectangle, StaticScene
from fusion_planner.ros import conversions as conv
from fusion_planner.ros.global_planner import GlobalPlannerNode
from test_global_planner_node import GOAL, START, Harness, odom_msg, wall_map

BEAMS = 360
RANGE_MAX = 6.0  # [m]
PERSISTENCE_S = 0.3  # [s], node (wall) time here


def scan_msg(grid, origin, rectangles=()):
    """A 360-beam LaserScan from ``origin`` (robot yaw 0) of the map plus rectangles."""
    angles = np.linspace(-math.pi, math.pi, BEAMS, endpoint=False)
    directions = np.column_stack([np.cos(angles), np.sin(angles)])
    ranges = StaticScene(grid, rectangles=rectangles).cast(np.asarray(origin), directions, RANGE_MAX)
    msg = LaserScan()
    msg.header.frame_id = 'base_link'
    msg.angle_min, msg.angle_max = float(angles[0]), float(angles[-1])
    msg.angle_increment = float(angles[1] - angles[0])
    msg.range_min, msg.range_max = 0.05, RANGE_MAX
    msg.ranges = np.where(ranges < RANGE_MAX, ranges, np.inf).astype(np.float32).tolist()
    return msg


@pytest.fixture
def harness(context):
    h = Harness(context, overrides=[Parameter('obstacle_persistence', value=PERSISTENCE_S)])
    h.scan_pub = h.tester.create_publisher(LaserScan, 'scan', 10)
    assert h.spin_until(lambda: h.scan_pub.get_subscription_count() > 0)
    yield h
    h.close()


def through_gap(path):
    """'low' or 'high': the gap of wall_map the path passes (x = 4 m)."""
    y = np.interp(4.05, path[:, 0], path[:, 1])
    return 'low' if y < 1.0 else 'high'


def gap_closer(gap):
    """A rectangle closing one gap of wall_map, 0.3 m in front of the wall."""
    return (Rectangle(min=(3.6, 0.0), max=(3.8, 1.0)) if gap == 'low'
            else Rectangle(min=(3.6, 5.0), max=(3.8, 6.0)))


def show(harness, grid, robot, rectangles, seconds):
    """Publish the robot's pose and scans of the world for ``seconds`` of wall time."""
    harness.odom_pub.publish(odom_msg(*robot))
    scan = scan_msg(grid, robot, rectangles)
    for _ in range(int(seconds / 0.05)):
        harness.scan_pub.publish(scan)
        harness.spin_for(0.05)


def test_a_gap_closed_in_the_scans_is_planned_around_then_forgotten(harness):
    grid = wall_map()
    harness.setup_world(grid)
    assert harness.send_goal(*GOAL)
    first = conv.path_from_msg(harness.plans[-1], 'map')
    gap = through_gap(first)
    robot = (3.0, 0.5 if gap == 'low' else 5.5)
    count = len(harness.plans)
    show(harness, grid, robot, [gap_closer(gap)], 3 * PERSISTENCE_S)
    assert harness.spin_until(lambda: len(harness.plans) > count), 'no replan'
    detour = conv.path_from_msg(harness.plans[-1], 'map')
    assert len(detour) and through_gap(detour) != gap
    assert np.hypot(*(detour[-1] - GOAL)) < 0.1
    assert harness.spin_until(lambda: int(harness.diag_values().get('scan_obstacle_cells', 0)) > 0)
    assert harness.diag_values()['last_outcome'] == 'succeeded'
    # The closer is gone: the beams through the gap clear its cells, and the
    # next goal takes the shorter way again.
    show(harness, grid, robot, [], 3 * PERSISTENCE_S)
    assert len(harness.planner._layer.confirmed_cells()) == 0
    harness.odom_pub.publish(odom_msg(*START))
    harness.spin_for(0.2)
    assert harness.send_goal(*GOAL)
    again = conv.path_from_msg(harness.plans[-1], 'map')
    assert through_gap(again) == gap
    assert harness.spin_until(lambda: harness.diag_values().get('scan_obstacle_cells') == '0')


def test_an_obstacle_off_the_plan_is_learnt_without_replanning(harness):
    grid = wall_map()
    harness.setup_world(grid)
    assert harness.send_goal(*GOAL)
    gap = through_gap(conv.path_from_msg(harness.plans[-1], 'map'))
    other = 'high' if gap == 'low' else 'low'
    count = len(harness.plans)
    robot = (3.0, 3.0)
    show(harness, grid, robot, [gap_closer(other)], 3 * PERSISTENCE_S)
    assert len(harness.planner._layer.confirmed_cells()) > 0
    assert len(harness.plans) == count, 'replanned although the plan was not blocked'


def test_without_mark_obstacles_there_is_no_scan_subscription(context):
    node = GlobalPlannerNode(context=context, namespace='/gp_no_scan',
                             parameter_overrides=[Parameter('mark_obstacles', value=False)])
    try:
        assert not any(name.endswith('/scan') for name, _ in
                       node.get_subscriber_names_and_types_by_node(node.get_name(),
                                                                   node.get_namespace()))
    finally:
        node.destroy_node()
