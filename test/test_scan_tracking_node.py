"""The local planner node tracks people from its own scan.

Over DDS: the simulator's ground-truth ``obstacles`` go to another topic
(remapped), so the local planner's ``obstacles`` input has no publisher; the
robot must avoid a walker crossing its way with what its laser shows, and
the node publishes the walker's track with its velocity on ``tracks``. In
process: bad scans are refused, or not tracked with a reason.
"""

import math
import time

import numpy as np
import pytest
import yaml

rclpy = pytest.importorskip('rclpy')

from nav_msgs.msg import Odometry  # noqa: E402
from rclpy.executors import SingleThreadedExecutor  # noqa: E402
from rclpy.node import Node  # noqa: E402
from rclpy.parameter import Parameter  # noqa: E402
from sensor_msgs.msg import LaserScan  # noqa: E402
from visualization_msgs.msg import Marker, MarkerArray  # noqa: E402

from fusion_planner.cli import demo_command as demo  # noqa: E402
from fusion_planner.core.grid import GridMap  # noqa: E402
from fusion_planner.core.map_files import save_map_server  # noqa: E402
from fusion_planner.core.simulation.scenario import load_scenario  # noqa: E402
from fusion_planner.core.simulation.world import ray_circle_distances  # noqa: E402
from fusion_planner.ros import conversions as conv  # noqa: E402
from fusion_planner.ros.fuzz import FuzzTarget  # noqa: E402
from fusion_planner.ros.global_planner import GlobalPlannerNode  # noqa: E402
from fusion_planner.ros.local_planner import LocalPlannerNode  # noqa: E402
from fusion_planner.ros.scan_tracks import fuse  # noqa: E402
from fusion_planner.ros.simulator import SimulatorNode  # noqa: E402

from test_faults import free_running  # noqa: E402

REAL_TIME_FACTOR = 10.0
SIM_TIME_LIMIT_S = 40.0
WALL_LIMIT_S = 60.0
#: Where the simulator's ground truth goes instead of ``obstacles``.
TRUTH_REMAP = ['--ros-args', '-r', 'obstacles:=true_obstacles']
#: A person crossing the robot's straight way at x = 5 m, back and forth.
WALKER = {'radius': 0.25, 'model': 'waypoints', 'points': [[5.0, 0.6], [5.0, 5.4]],
          'speed': 0.6}


def write_room_scenario(folder):
    """An empty 10 m x 6 m room, the robot crossing it along y = 3.05 m, one walker."""
    occupied = np.zeros((60, 100), dtype=bool)
    save_map_server(GridMap(occupied, resolution=0.1), folder / 'room.yaml')
    doc = {'name': 'crossing_walker', 'map': 'room.yaml', 'seed': 1,
           'robot': {'start': [1.05, 3.05, 0.0], 'radius': 0.2, 'max_speed': 0.8},
           'goal': [9.05, 3.05], 'moving_obstacles': [WALKER],
           'limits': {'time_limit_s': SIM_TIME_LIMIT_S, 'dt': 0.05},
           'scan': {'beams': 360, 'range_max': 8.0, 'noise_std': 0.01}}
    path = folder / 'crossing_walker.yaml'
    path.write_text(yaml.safe_dump(doc))
    return path


def test_local_planner_avoids_a_walker_with_no_obstacles_publisher(context, tmp_path):
    path = write_room_scenario(tmp_path)
    scenario = load_scenario(path)
    # free running: in lockstep the local planner would wait for each step's obstacles
    params = free_running(demo.node_parameters(scenario, path, REAL_TIME_FACTOR))
    recorder = demo.RunRecorder(scenario, params['local_planner']['goal_tolerance'])

    def overrides(name):
        return [Parameter(k, value=v) for k, v in params[name].items()]

    monitor = Node('test_monitor', context=context, cli_args=TRUTH_REMAP)
    demo.attach_recorder(monitor, recorder)
    tracks = []
    monitor.create_subscription(MarkerArray, 'tracks', tracks.append, 10)
    nodes = [monitor,
             SimulatorNode(context=context, parameter_overrides=overrides('simulator'),
                           cli_args=TRUTH_REMAP),
             GlobalPlannerNode(context=context, parameter_overrides=overrides('global_planner')),
             LocalPlannerNode(context=context, parameter_overrides=overrides('local_planner'))]
    local = nodes[-1]
    executor = SingleThreadedExecutor(context=context)
    for node in nodes:
        executor.add_node(node)
    spinner = demo.Spinner(executor)
    try:
        failure = demo.watch(recorder, SIM_TIME_LIMIT_S, WALL_LIMIT_S)
        assert failure is None, failure
        assert local.count_publishers('obstacles') == 0
        demo.wait_final_status(recorder, time.monotonic())
        status = dict(recorder.sim_status)
        assert int(status['collisions']) == 0, status
        # the walker crossed close in front of the robot: an encounter, not a stroll
        poses = np.array(recorder.poses)[:, 0:2]
        walker_at = np.array(recorder.tracks)[:, 0, :]
        index = np.searchsorted(recorder.track_times, recorder.pose_times)
        index = index.clip(0, len(walker_at) - 1)
        assert np.hypot(*(poses - walker_at[index]).T).min() < 1.5
        goal = scenario.goal
        assert math.hypot(poses[-1, 0] - goal[0], poses[-1, 1] - goal[1]) \
            <= recorder.arrival_radius
        # the node published the walker's track with its velocity
        speeds = [math.dist((m.points[0].x, m.points[0].y), (m.points[1].x, m.points[1].y))
                  for msg in tracks for m in msg.markers
                  if m.type == Marker.ARROW and m.action == Marker.ADD]
        assert speeds and np.median(speeds) == pytest.approx(WALKER['speed'], abs=0.2)
    finally:
        demo.shutdown_executor(spinner, nodes)


# -- bad scans at the node, in process ------------------------------------------------

def _scan_msg(stamp_s, ranges, frame='base_link'):
    msg = LaserScan()
    msg.header.frame_id = frame
    msg.header.stamp = conv.seconds_to_stamp(stamp_s)
    msg.angle_min, msg.angle_increment = -math.pi, 2 * math.pi / len(ranges)
    msg.range_min, msg.range_max = 0.05, 8.0
    msg.ranges = [float(r) for r in ranges]
    return msg


def _odometry_msg(stamp_s, x=1.0, y=3.0):
    msg = Odometry()
    msg.header.frame_id = 'map'
    msg.header.stamp = conv.seconds_to_stamp(stamp_s)
    msg.pose.pose.position.x, msg.pose.pose.position.y = x, y
    msg.pose.pose.orientation.w = 1.0
    return msg


def _walker_ranges(centre, beams=360, origin=(1.0, 3.0)):
    angles = -math.pi + 2 * math.pi * np.arange(beams) / beams
    directions = np.stack([np.cos(angles), np.sin(angles)], axis=1)
    return ray_circle_distances(np.array(origin), directions, np.array([centre]),
                                np.array([0.25]))


def test_bad_scans_at_the_node_are_refused_or_not_tracked_with_a_reason(context):
    target = FuzzTarget(LocalPlannerNode(context=context, parameter_overrides=[
        Parameter('use_sim_time', value=True),
        Parameter('odom_frame_id', value='map')]))  # odometry in the map frame: no correction
    node = target.node
    try:
        grid = GridMap(np.zeros((60, 100), dtype=bool), resolution=0.1)
        target.deliver('map', conv.grid_map_to_occupancy_grid(grid, 'map',
                                                              conv.seconds_to_stamp(0.0)))
        # a walker crossing 4 m ahead at 0.6 m/s: tracked, with its velocity
        for k in range(20):
            t = 10.0 + 0.1 * k
            target.deliver('odom', _odometry_msg(t))
            target.deliver('scan', _scan_msg(t, _walker_ranges((5.0, 1.5 + 0.06 * k))))
        tracked = node._scan_tracks.movers(11.9)[0]
        assert tracked.shape == (1, 5) and tracked[0, 3] == pytest.approx(0.6, abs=0.15)
        rejected = target.diagnostics()['rejected']
        # another frame: refused (a defective message), the tracks untouched
        target.deliver('scan', _scan_msg(12.0, _walker_ranges((5.0, 2.7)), frame='laser'))
        values = target.diagnostics()
        assert values['rejected'] == rejected + 1 and 'frame' in values['last_error']
        # far older than the odometry: a valid message, not tracked, and said why
        target.deliver('odom', _odometry_msg(12.0))
        target.deliver('scan', _scan_msg(5.0, _walker_ranges((5.0, 2.7))))
        values = target.diagnostics()
        assert values['rejected'] == rejected + 1
        assert 'before the latest odometry' in values['scan_tracking']
        # NaN ranges and a scan that saw nothing are no returns: tracked, the walker coasts
        nan_ranges = _walker_ranges((5.0, 2.7))
        nan_ranges[::2] = np.nan
        target.deliver('scan', _scan_msg(12.0, nan_ranges))
        assert target.diagnostics()['scan_tracking'] == 'tracking'
        target.deliver('odom', _odometry_msg(12.1))
        target.deliver('scan', _scan_msg(12.1, np.full(360, np.inf)))
        assert target.diagnostics()['scan_tracking'] == 'tracking'
        assert len(node._scan_tracks.movers(12.1)[0]) == 1
        assert target.diagnostics()['faults'] == 0
    finally:
        node.destroy_node()


def test_fused_obstacles_keep_the_scan_tracks_turn_estimates_and_nan_for_the_others():
    scan = np.array([[1.0, 0.0, 0.5, 0.0, 0.3], [5.0, 0.0, 0.0, 0.5, 0.3],
                     [9.0, 0.0, 0.5, 0.0, 0.3]])
    external = np.array([[1.1, 0.0, 0.4, 0.0, 0.25]])         # the same person as scan track 0
    tracked, turns = fuse(scan, external, np.array([0.2, 0.4, 0.1]))
    assert tracked[:, 0].tolist() == [1.1, 5.0, 9.0]
    assert np.isnan(turns[0]) and turns[1:].tolist() == [0.4, 0.1]
    alone, alone_turns = fuse(scan, np.zeros((0, 5)), np.array([0.2, 0.4, 0.1]))
    assert len(alone) == 3 and alone_turns.tolist() == [0.2, 0.4, 0.1]
