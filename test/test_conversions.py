"""Tests of fusion_planner.ros.conversions: message <-> core, validated (no DDS)."""

import array
import math

import numpy as np
import pytest
from geometry_msgs.msg import (
    PoseStamped, PoseWithCovarianceStamped, Quaternion, Twist, TwistStamped)
from hypothesis import given, settings
from hypothesis import strategies as st
from nav_msgs.msg import OccupancyGrid, Odometry, Path
from sensor_msgs.msg import LaserScan
from visualization_msgs.msg import Marker, MarkerArray

from fusion_planner.core.errors import InvalidInput, MapError
from fusion_planner.core.grid import GridMap
from fusion_planner.ros import conversions as conv

NAN = float('nan')
INF = float('inf')


def stamp(t=0.0):
    return conv.seconds_to_stamp(t)


def pose_stamped(x, y, yaw=0.0, frame='map'):
    msg = PoseStamped()
    msg.header.frame_id = frame
    msg.pose.position.x = x
    msg.pose.position.y = y
    msg.pose.orientation = conv.quaternion_of_yaw(yaw)
    return msg


def occupancy(width, height, data, resolution=0.1, frame='map', origin=(0.0, 0.0), q=None):
    msg = OccupancyGrid()
    msg.header.frame_id = frame
    msg.info.width = width
    msg.info.height = height
    msg.info.resolution = resolution
    msg.info.origin.position.x, msg.info.origin.position.y = origin
    msg.info.origin.orientation = q or Quaternion(w=1.0)
    msg.data = array.array('b', data)
    return msg


def cylinder(marker_id, x, y, diameter=0.5, t=0.0, ns='obs', action=Marker.ADD, frame='map'):
    m = Marker()
    m.header.frame_id = frame
    m.header.stamp = stamp(t)
    m.ns = ns
    m.id = marker_id
    m.type = Marker.CYLINDER
    m.action = action
    m.pose.position.x = x
    m.pose.position.y = y
    m.pose.orientation.w = 1.0
    m.scale.x = m.scale.y = diameter
    m.scale.z = 1.0
    return m


# -- stamps and frames --------------------------------------------------------

@given(st.floats(0.0, 2.0e9))
def test_stamp_round_trip_within_a_nanosecond_scale(t):
    back = conv.stamp_to_seconds(conv.seconds_to_stamp(t))
    assert abs(back - t) <= 1e-9 * max(1.0, t)


@pytest.mark.parametrize('bad', [-1.0, NAN, INF, 2.0 ** 31])
def test_stamp_refuses_negative_and_non_finite(bad):
    with pytest.raises(InvalidInput):
        conv.seconds_to_stamp(bad)


def test_frame_check_accepts_empty_and_refuses_other():
    assert conv.check_frame('', 'map', 'goal') == 'map'
    assert conv.check_frame('map', 'map', 'goal') == 'map'
    with pytest.raises(InvalidInput, match="'odom'"):
        conv.check_frame('odom', 'map', 'goal')


# -- quaternions and poses ----------------------------------------------------

@given(st.floats(-math.pi, math.pi))
def test_yaw_round_trip(yaw):
    back = conv.yaw_of_quaternion(conv.quaternion_of_yaw(yaw))
    assert abs(math.remainder(back - yaw, 2 * math.pi)) < 1e-9


def test_slightly_non_unit_quaternion_is_normalised():
    q = conv.quaternion_of_yaw(0.7)
    scaled = Quaternion(x=q.x * 1.02, y=q.y * 1.02, z=q.z * 1.02, w=q.w * 1.02)
    assert conv.yaw_of_quaternion(scaled) == pytest.approx(0.7)


@pytest.mark.parametrize('q', [Quaternion(x=0.0, y=0.0, z=0.0, w=0.0),
                               Quaternion(x=0.0, y=0.0, z=0.0, w=2.0),
                               Quaternion(x=0.0, y=0.0, z=NAN, w=1.0),
                               Quaternion(x=INF, y=0.0, z=0.0, w=1.0)])
def test_bad_quaternions_are_refused(q):
    with pytest.raises(InvalidInput):
        conv.yaw_of_quaternion(q)


def test_pose_stamped_conversion_and_refusals():
    assert conv.pose_stamped_to_xy_yaw(pose_stamped(1.0, 2.0, 0.5), 'map') == pytest.approx((1, 2, 0.5))
    assert conv.pose_stamped_to_xy_yaw(pose_stamped(1.0, 2.0, frame=''), 'map')[:2] == (1.0, 2.0)
    with pytest.raises(InvalidInput):
        conv.pose_stamped_to_xy_yaw(pose_stamped(NAN, 2.0), 'map')
    with pytest.raises(InvalidInput):
        conv.pose_stamped_to_xy_yaw(pose_stamped(1.0, INF), 'map')
    with pytest.raises(InvalidInput):
        conv.pose_stamped_to_xy_yaw(pose_stamped(1.0, 2.0, frame='odom'), 'map')


def test_odometry_and_amcl_pose():
    odom = Odometry()
    odom.header.frame_id = 'map'
    odom.pose.pose.position.x = 3.0
    odom.pose.pose.orientation = conv.quaternion_of_yaw(-1.0)
    odom.twist.twist.linear.x = 0.4
    odom.twist.twist.angular.z = -0.2
    assert conv.odometry_to_xy_yaw(odom, 'map') == pytest.approx((3.0, 0.0, -1.0))
    assert conv.odometry_to_velocity(odom) == pytest.approx((0.4, -0.2))
    odom.twist.twist.angular.z = NAN
    with pytest.raises(InvalidInput):
        conv.odometry_to_velocity(odom)
    amcl = PoseWithCovarianceStamped()
    amcl.header.frame_id = 'map'
    amcl.pose.pose.position.y = -2.0
    amcl.pose.pose.orientation.w = 1.0
    assert conv.pose_with_covariance_to_xy_yaw(amcl, 'map') == (0.0, -2.0, 0.0)
    amcl.header.frame_id = 'odom'
    with pytest.raises(InvalidInput):
        conv.pose_with_covariance_to_xy_yaw(amcl, 'map')


# -- velocity -----------------------------------------------------------------

def test_twist_round_trips_and_refuses_nan():
    assert conv.twist_to_velocity(conv.velocity_to_twist(0.3, -0.5)) == (0.3, -0.5)
    stamped = conv.velocity_to_twist_stamped(0.3, 0.1, 'base_link', stamp(1.0))
    assert isinstance(stamped, TwistStamped) and stamped.header.frame_id == 'base_link'
    assert conv.twist_to_velocity(stamped) == (0.3, 0.1)
    with pytest.raises(InvalidInput):
        conv.velocity_to_twist(NAN, 0.0)
    bad = Twist()
    bad.linear.x = INF
    with pytest.raises(InvalidInput):
        conv.twist_to_velocity(bad)


# -- maps ---------------------------------------------------------------------

def test_grid_map_round_trip_keeps_cells_geometry_and_unknown():
    rng = np.random.default_rng(3)
    occupied = rng.random((7, 9)) < 0.3
    unknown = (rng.random((7, 9)) < 0.2) & ~occupied
    grid = GridMap(occupied, 0.25, (1.0, -2.0, 0.4), unknown=unknown)
    msg = conv.grid_map_to_occupancy_grid(grid, 'map', stamp(2.0))
    values = np.frombuffer(msg.data, np.int8).reshape(7, 9)
    assert set(np.unique(values)) <= {-1, 0, 100}
    assert np.array_equal(values == 100, occupied) and np.array_equal(values == -1, unknown)
    back = conv.occupancy_grid_to_grid_map(msg, 'map', unknown_is_occupied=False)
    assert np.array_equal(back.occupied, occupied)
    assert back.resolution == pytest.approx(0.25)
    assert back.origin == pytest.approx(grid.origin)
    assert np.array_equal(conv.occupancy_grid_to_grid_map(msg, 'map', True).occupied,
                          occupied | unknown)


def test_occupancy_grid_row_zero_is_at_the_origin():
    msg = occupancy(3, 2, [0, 0, 100, 0, 0, 0], resolution=1.0)
    grid = conv.occupancy_grid_to_grid_map(msg, 'map')
    assert grid.occupied[0, 2] and grid.occupied.sum() == 1
    assert grid.cell_of(np.array([2.5, 0.5])).tolist() == [0, 2]


@pytest.mark.parametrize('msg, fragment', [
    (occupancy(3, 2, [0] * 5), 'data has 5 values'),
    (occupancy(3, 2, [0] * 6, resolution=0.0), 'resolution'),
    (occupancy(3, 2, [0] * 6, resolution=NAN), 'resolution'),
    (occupancy(3, 2, [0] * 6, origin=(NAN, 0.0)), 'origin'),
    (occupancy(3, 2, [0] * 6, frame='odom'), "'odom'"),
    (occupancy(3, 2, [0] * 6, q=Quaternion(x=0.0, y=0.0, z=0.0, w=0.0)), 'quaternion'),
    (occupancy(0, 2, []), 'width'),
    (occupancy(3, 2, [0, 0, 0, 0, 0, 101]), 'outside -1..100'),
])
def test_bad_occupancy_grids_raise_map_error(msg, fragment):
    with pytest.raises(MapError, match=fragment):
        conv.occupancy_grid_to_grid_map(msg, 'map')


def test_occupancy_grid_cell_limit_checked_before_data():
    msg = occupancy(5000, 5000, [])
    with pytest.raises(MapError, match='limit'):
        conv.occupancy_grid_to_grid_map(msg, 'map', max_cells=1_000_000)


# -- paths --------------------------------------------------------------------

def test_path_round_trip_and_headings_follow_segments():
    path = np.array([[0.0, 0.0], [1.0, 0.0], [1.0, 0.0], [1.0, 2.0], [0.0, 2.0]])
    msg = conv.path_to_msg(path, 'map', stamp(1.0), final_yaw=0.3)
    assert msg.header.frame_id == 'map' and len(msg.poses) == len(path)
    assert np.allclose(conv.path_from_msg(msg, 'map'), path)
    yaws = [conv.yaw_of_quaternion(p.pose.orientation) for p in msg.poses]
    assert yaws == pytest.approx([0.0, 0.0, math.pi / 2, math.pi, 0.3])


def test_path_headings_zero_length_start_takes_first_direction():
    headings = conv.path_headings(np.array([[0.0, 0.0], [0.0, 0.0], [0.0, 1.0]]))
    assert headings == pytest.approx([math.pi / 2] * 3)
    assert conv.path_headings(np.array([[2.0, 2.0]])).tolist() == [0.0]


def test_bad_paths_are_refused():
    with pytest.raises(InvalidInput):
        conv.path_to_msg(np.zeros((0, 2)), 'map', stamp())
    with pytest.raises(InvalidInput):
        conv.path_to_msg([[0.0, 0.0], [NAN, 1.0]], 'map', stamp())
    with pytest.raises(InvalidInput, match='empty'):
        conv.path_from_msg(Path(), 'map')
    msg = conv.path_to_msg([[0.0, 0.0], [1.0, 1.0]], 'map', stamp())
    msg.poses[1].pose.position.x = NAN
    with pytest.raises(InvalidInput):
        conv.path_from_msg(msg, 'map')
    other = conv.path_to_msg([[0.0, 0.0], [1.0, 1.0]], 'odom', stamp())
    with pytest.raises(InvalidInput):
        conv.path_from_msg(other, 'map')


def test_plan_from_msg_gives_none_for_the_empty_stop_plan_in_the_right_frame():
    empty = Path()
    empty.header.frame_id = 'map'
    assert conv.plan_from_msg(empty, 'map') is None
    empty.header.frame_id = 'odom'
    with pytest.raises(InvalidInput, match="'odom'"):
        conv.plan_from_msg(empty, 'map')
    msg = conv.path_to_msg([[0.0, 0.0], [1.0, 1.0]], 'map', stamp())
    assert conv.plan_from_msg(msg, 'map').tolist() == [[0.0, 0.0], [1.0, 1.0]]


# -- scans --------------------------------------------------------------------

def scan(ranges, angle_min=0.0, increment=math.pi / 2, range_min=0.1, range_max=10.0, intensities=()):
    msg = LaserScan()
    msg.header.frame_id = 'base_link'
    msg.angle_min = angle_min
    msg.angle_increment = increment
    msg.range_min = range_min
    msg.range_max = range_max
    msg.ranges = [float(r) for r in ranges]
    msg.intensities = [float(i) for i in intensities]
    return msg


def test_scan_endpoints_in_map_frame():
    pts = conv.scan_to_points(scan([1.0, 2.0, 3.0, 4.0]), (1.0, 1.0, math.pi / 2))
    assert pts == pytest.approx(np.array([[1.0, 2.0], [-1.0, 1.0], [1.0, -2.0], [5.0, 1.0]]))


def test_scan_drops_invalid_ranges_and_ignores_intensities():
    pts = conv.scan_to_points(scan([NAN, INF, -1.0, 0.05, 10.0, 50.0, 2.0], increment=0.1,
                                   intensities=[1.0, 2.0]), (0.0, 0.0, 0.0))
    assert pts.shape == (1, 2)
    assert np.hypot(*pts[0]) == pytest.approx(2.0)
    assert conv.scan_to_points(scan([]), (0.0, 0.0, 0.0)).shape == (0, 2)


@pytest.mark.parametrize('kwargs', [dict(increment=0.0), dict(increment=-0.1),
                                    dict(increment=NAN), dict(angle_min=INF),
                                    dict(range_min=-1.0), dict(range_max=0.05),
                                    dict(range_max=NAN)])
def test_scan_bad_geometry_refused(kwargs):
    with pytest.raises(InvalidInput):
        conv.scan_to_points(scan([1.0, 2.0], **kwargs), (0.0, 0.0, 0.0))


def test_scan_overflowing_beams_are_dropped():
    pts = conv.scan_to_points(scan([1.0, 1.0, 1.0], angle_min=1e308, increment=1e308), (0.0, 0.0, 0.0))
    assert pts.shape == (1, 2) and np.all(np.isfinite(pts))


def test_scan_frame_and_pose_checked():
    with pytest.raises(InvalidInput):
        conv.scan_to_points(scan([1.0]), (0.0, 0.0, 0.0), frame_id='laser')
    with pytest.raises(InvalidInput):
        conv.scan_to_points(scan([1.0]), (NAN, 0.0, 0.0))


# -- obstacles ----------------------------------------------------------------

def test_tracker_estimates_velocity_from_successive_poses():
    tracker = conv.ObstacleTracker('map', smoothing=0.0)
    for k in range(5):
        t = 0.1 * k
        obs, rejected = tracker.update(
            MarkerArray(markers=[cylinder(1, 1.0 + 0.5 * t, 2.0 - 0.2 * t, t=t),
                                 cylinder(2, 5.0, 5.0, diameter=1.0, t=t)]), now_s=t)
        assert rejected == []
    by_x = obs[np.argsort(obs[:, 0])]
    assert by_x[0] == pytest.approx([1.2, 1.92, 0.5, -0.2, 0.25])
    assert by_x[1] == pytest.approx([5.0, 5.0, 0.0, 0.0, 0.5])


def test_tracker_moves_a_track_ahead_to_the_query_time():
    tracker = conv.ObstacleTracker('map', timeout_s=1.0, smoothing=0.0)
    for t in (0.0, 0.1):
        tracker.update(MarkerArray(markers=[cylinder(1, 1.0 + 0.4 * t, 2.0, t=t)]), now_s=t)
    assert tracker.obstacles(0.35)[0, :2] == pytest.approx([1.14, 2.0])  # 0.25 s after its marker
    assert tracker.obstacles(0.05)[0, :2] == pytest.approx([1.04, 2.0])  # earlier: where it was seen
    assert tracker.obstacles(1.05)[0, :2] == pytest.approx([1.42, 2.0])  # 0.95 s ahead


def test_tracker_delete_deleteall_timeout_and_teleport():
    tracker = conv.ObstacleTracker('map', timeout_s=1.0, max_speed=5.0, smoothing=0.0)
    tracker.update(MarkerArray(markers=[cylinder(1, 0.0, 0.0, t=1.0), cylinder(2, 3.0, 0.0, t=1.0),
                                        cylinder(1, 0.0, 0.0, t=1.0, ns='other')]), now_s=1.0)
    assert len(tracker) == 3
    obs, _ = tracker.update(MarkerArray(markers=[cylinder(1, 0, 0, action=Marker.DELETE)]), now_s=1.1)
    assert len(obs) == 2  # only ('obs', 1) deleted, not ('other', 1)
    obs, _ = tracker.update(MarkerArray(markers=[cylinder(2, 100.0, 0.0, t=2.0)]), now_s=2.0)
    assert obs[obs[:, 0] == 100.0][0, 2:4].tolist() == [0.0, 0.0]  # a jump is not a speed
    assert len(tracker.obstacles(3.5)) == 0  # both timed out
    tracker.update(MarkerArray(markers=[cylinder(1, 0.0, 0.0, t=4.0), cylinder(2, 1.0, 0.0, t=4.0)]), 4.0)
    obs, _ = tracker.update(MarkerArray(markers=[cylinder(0, 0, 0, action=Marker.DELETEALL),
                                                 cylinder(7, 2.0, 2.0, t=4.1)]), now_s=4.1)
    assert obs.shape == (1, 5) and obs[0, 0] == 2.0


@pytest.mark.parametrize('field, value', [('x', NAN), ('scale', 0.0), ('scale', NAN),
                                          ('scale', 1e6), ('scale', -1.0), ('frame', 'odom'),
                                          ('type', Marker.CUBE), ('action', 7)])
def test_tracker_refuses_bad_markers_one_by_one(field, value):
    bad = cylinder(1, 1.0, 1.0)
    if field == 'x':
        bad.pose.position.x = value
    elif field == 'scale':
        bad.scale.x = value
    elif field == 'frame':
        bad.header.frame_id = value
    elif field == 'type':
        bad.type = value
    else:
        bad.action = value
    tracker = conv.ObstacleTracker('map')
    obs, rejected = tracker.update(MarkerArray(markers=[bad, cylinder(2, 3.0, 3.0)]), now_s=0.5)
    assert len(rejected) == 1 and "'obs'/1" in rejected[0]
    assert obs.shape == (1, 5) and obs[0, 0] == 3.0


def test_tracker_caps_the_number_of_tracks():
    tracker = conv.ObstacleTracker('map', max_tracks=3)
    obs, rejected = tracker.update(MarkerArray(markers=[cylinder(i, i, 0.0) for i in range(5)]), 0.0)
    assert len(obs) == 3 and len(rejected) == 2


def test_obstacles_to_markers_round_trip_through_tracker():
    obstacles = np.array([[1.0, 2.0, 0.3, 0.0, 0.4], [-1.0, 0.5, 0.0, 0.0, 0.2]])
    msg = conv.obstacles_to_markers(obstacles, 'map', stamp(1.0), ids=[10, 11])
    assert [m.id for m in msg.markers] == [10, 11]
    assert all(m.type == Marker.CYLINDER and m.action == Marker.ADD for m in msg.markers)
    tracked, rejected = conv.ObstacleTracker('map').update(msg, now_s=1.0)
    assert rejected == []
    assert np.allclose(tracked[:, [0, 1, 4]], obstacles[:, [0, 1, 4]])
    with pytest.raises(InvalidInput):
        conv.obstacles_to_markers([[0.0, 0.0, 0.0, 0.0, 0.0]], 'map', stamp())
    with pytest.raises(InvalidInput):
        conv.obstacles_to_markers(obstacles, 'map', stamp(), ids=[1])


finite_or_not = st.one_of(st.floats(allow_nan=True, allow_infinity=True, width=64),
                          st.sampled_from([0.0, 1e300, -1e300]))


@settings(max_examples=200, deadline=None)
@given(st.lists(st.tuples(st.sampled_from([Marker.ADD, Marker.DELETE, Marker.DELETEALL, 5]),
                          st.sampled_from([Marker.CYLINDER, Marker.SPHERE]),
                          st.integers(-3, 3), finite_or_not, finite_or_not, finite_or_not),
                max_size=12))
def test_tracker_never_raises_and_outputs_finite(markers):
    tracker = conv.ObstacleTracker('map')
    msg = MarkerArray()
    for action, kind, marker_id, x, y, scale in markers:
        m = cylinder(marker_id, 0.0, 0.0, action=action)
        m.type = kind
        m.pose.position.x, m.pose.position.y, m.scale.x = x, y, scale
        msg.markers.append(m)
    obs, _ = tracker.update(msg, now_s=1.0)
    obs, _ = tracker.update(msg, now_s=1.1)
    assert obs.ndim == 2 and obs.shape[1] == 5 and np.all(np.isfinite(obs))
    assert np.all(obs[:, 4] > 0)


@settings(max_examples=200, deadline=None)
@given(st.lists(finite_or_not, max_size=30), finite_or_not, finite_or_not,
       finite_or_not, finite_or_not)
def test_scan_conversion_only_raises_invalid_input(ranges, angle_min, increment, range_min, range_max):
    msg = scan([], angle_min, increment, range_min, range_max)
    with np.errstate(over='ignore'):
        msg.ranges = array.array('f', np.asarray(ranges, np.float32).tobytes())
    try:
        pts = conv.scan_to_points(msg, (0.0, 0.0, 0.0))
    except InvalidInput:
        return
    assert pts.shape[1] == 2 and np.all(np.isfinite(pts))


FAR = 2 * conv.MAX_COORDINATE_M


def test_positions_beyond_the_coordinate_limit_are_refused_as_corrupt():
    assert conv.pose_stamped_to_xy_yaw(pose_stamped(conv.MAX_COORDINATE_M, 0.0), 'map')[0] \
        == conv.MAX_COORDINATE_M
    with pytest.raises(InvalidInput, match='corrupt'):
        conv.pose_stamped_to_xy_yaw(pose_stamped(0.0, -FAR), 'map')
    path = conv.path_to_msg([[0.0, 0.0], [FAR, 1.0]], 'map', stamp())
    with pytest.raises(InvalidInput, match='corrupt'):
        conv.path_from_msg(path, 'map')
    _, rejected = conv.ObstacleTracker('map').update(
        MarkerArray(markers=[cylinder(1, FAR, 0.0)]), now_s=0.0)
    assert len(rejected) == 1 and 'corrupt' in rejected[0]
    with pytest.raises(InvalidInput, match='range_max'):
        conv.scan_to_points(scan([1.0], range_max=FAR), (0.0, 0.0, 0.0))


@pytest.mark.parametrize('msg', [occupancy(3, 2, [0] * 6, origin=(FAR, 0.0)),
                                 occupancy(3, 2, [0] * 6, resolution=conv.MAX_COORDINATE_M)])
def test_maps_reaching_beyond_the_coordinate_limit_are_refused(msg):
    with pytest.raises(MapError, match='reaches'):
        conv.occupancy_grid_to_grid_map(msg, 'map')


def test_rates_beyond_the_limit_are_refused_as_corrupt():
    odom = Odometry()
    odom.twist.twist.linear.x = 2 * conv.MAX_RATE
    with pytest.raises(InvalidInput, match='corrupt'):
        conv.odometry_to_velocity(odom)
    command = Twist()
    command.angular.z = -2 * conv.MAX_RATE
    with pytest.raises(InvalidInput, match='corrupt'):
        conv.twist_to_velocity(command)


def test_points_marker_and_delete_all():
    marker = conv.points_marker([[0.0, 1.0], [2.0, 3.0]], 'map', stamp(), 'key_nodes')
    assert [(p.x, p.y) for p in marker.points] == [(0.0, 1.0), (2.0, 3.0)]
    assert conv.points_marker(np.zeros((0, 2)), 'map', stamp(), 'x').points == []
    assert conv.delete_all_marker('map', stamp()).action == Marker.DELETEALL


# -- map -> odom correction ------------------------------------------------------------

def test_a_localization_pose_older_than_the_odometry_history_keeps_the_correction():
    from fusion_planner.ros.frames import ODOM_HISTORY, Localization
    localization = Localization(max_gap=0.5)
    localization.add_odometry(1.0, (0.0, 0.0, 0.0), (0.0, 0.0))
    assert localization.add_localization(0.5, np.array([2.0, 1.0, 0.0]))  # the first: taken
    np.testing.assert_allclose(localization.map_from_odom, [2.0, 1.0, 0.0])
    for k in range(ODOM_HISTORY):              # the robot drives 1 m/s along x from t = 2 s
        localization.add_odometry(2.0 + 0.1 * k, (0.1 * k, 0.0, 0.0), (1.0, 0.0))
    assert not localization.add_localization(1.5, np.array([9.0, 9.0, 0.0]))  # too late to pair
    np.testing.assert_allclose(localization.map_from_odom, [2.0, 1.0, 0.0])
    assert localization.add_localization(3.0, np.array([3.0, 1.0, 0.0]))  # within the history
    np.testing.assert_allclose(localization.map_from_odom, [2.0, 1.0, 0.0], atol=1e-9)


def test_a_localization_pose_before_any_odometry_is_kept_for_the_first_odometry():
    # AMCL's latched pose reaches a new subscriber at once, often before odometry does.
    from fusion_planner.ros.frames import Localization
    localization = Localization(max_gap=0.5)
    assert not localization.add_localization(0.5, np.array([1.0, 2.0, math.pi / 2]))
    assert localization.map_from_odom is None
    assert localization.add_odometry(1.0, (0.0, 0.0, 0.0), (0.0, 0.0))  # now paired
    np.testing.assert_allclose(localization.map_from_odom, [1.0, 2.0, math.pi / 2])
    assert not localization.add_odometry(1.1, (0.1, 0.0, 0.0), (1.0, 0.0))  # used once
    localization.clear()
    localization.add_localization(0.5, np.array([1.0, 2.0, 0.0]))
    localization.clear()  # a clock reset forgets a kept pose too
    assert not localization.add_odometry(1.0, (0.0, 0.0, 0.0), (0.0, 0.0))
    assert localization.map_from_odom is None
