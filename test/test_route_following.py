"""The pieces of route following: the route, the speed policy, progress, passing people, centring."""

import math

import numpy as np
import pytest

from fusion_planner.core.errors import (
    InvalidInput, NoValidPathCouldBeFound, StartOccupied)
from fusion_planner.core.global_planning.centring import centre_path
from fusion_planner.core.global_planning.planner import GlobalPlanner, PlannerConfig
from fusion_planner.core.grid import GridMap
from fusion_planner.core.local_planning.controller_base import FollowerParams, Observation
from fusion_planner.core.local_planning.progress import ProgressMonitor
from fusion_planner.core.local_planning.replanning import GridReplanner
from fusion_planner.core.local_planning.route import Route
from fusion_planner.core.local_planning.field_follower import FieldFollower
from fusion_planner.core.local_planning.free_arc import turn_round_error
from fusion_planner.core.local_planning.follow import make_controller
from fusion_planner.core.local_planning.speed_policy import (
    ROTATE_FIRST_RAD, braking_path_gap, turn_cap, turn_speed)
from fusion_planner.core.local_planning.yielding import passing_bounds, route_closures
from fusion_planner.core.simulation.world import integrate_unicycle

PARAMS = FollowerParams(max_speed=1.0, max_accel=1.0, max_omega=2.0, robot_radius=0.2)
NO_CIRCLES = np.zeros((0, 3))


def wall(a, b, spacing=0.02):
    a, b = np.asarray(a, float), np.asarray(b, float)
    count = max(2, int(np.linalg.norm(b - a) / spacing) + 1)
    return a + np.linspace(0.0, 1.0, count)[:, None] * (b - a)


# -- route ----------------------------------------------------------------------------------

def test_the_station_only_moves_forward_and_the_carrot_follows_the_path():
    route = Route(np.array([[0.0, 0.0], [4.0, 0.0], [4.0, 3.0]]))
    assert route.length == pytest.approx(7.0)
    assert route.project(np.array([2.0, 0.3])) == pytest.approx(2.0)
    assert route.project(np.array([0.5, 0.0])) == pytest.approx(2.0)        # never back
    assert route.point_at(5.0) == pytest.approx([4.0, 1.0])
    assert route.remaining == pytest.approx(5.0)
    np.testing.assert_allclose(route.tangent_at(5.0), [0.0, 1.0], atol=1e-12)


def test_offsets_are_signed_by_side_and_turns_are_found_at_the_corner():
    route = Route(np.array([[0.0, 0.0], [4.0, 0.0], [4.0, 3.0]]))
    points = np.array([[1.0, 0.4], [2.0, -0.3]])
    distance, index = route.nearest(points, 0.0, 3.0)
    np.testing.assert_allclose(route.signed_offsets(points, distance, index), [0.4, -0.3])
    distances, turns = route.sharpest_turns(3.0, 4.5)
    assert turns.max() == pytest.approx(math.pi / 2)
    assert distances[np.argmax(turns)] < 1.0
    assert route.along_to_first(np.array([[3.0, 0.1]]), 0.0, 7.0, 0.2) == pytest.approx(2.8,
                                                                                        abs=0.06)
    assert route.along_to_first(np.array([[3.0, 1.0]]), 0.0, 3.5, 0.2) == math.inf


# -- speed policy -----------------------------------------------------------------------------

def test_turns_cap_the_speed_and_a_straight_route_does_not():
    assert turn_cap(Route(np.array([[0.0, 0.0], [20.0, 0.0]])), 0.0, PARAMS) == PARAMS.max_speed
    corner = Route(np.array([[0.0, 0.0], [2.0, 0.0], [2.0, 5.0]]))
    far, near = turn_cap(corner, 1.2, PARAMS), turn_cap(corner, 1.8, PARAMS)
    assert near < far <= PARAMS.max_speed
    assert turn_speed(np.array([0.1, 1.0]), PARAMS)[1] < turn_speed(np.array([0.1, 1.0]),
                                                                     PARAMS)[0]


def test_side_walls_are_not_in_the_braking_path_a_blocking_point_is():
    route = Route(np.array([[0.0, 0.0], [10.0, 0.0]]))
    walls = np.vstack([wall((0.0, 0.4), (10.0, 0.4)), wall((0.0, -0.4), (10.0, -0.4))])
    pose = np.array([1.0, 0.0, 0.0])
    free = braking_path_gap(pose, route, 1.0, walls, np.zeros((0, 2)), NO_CIRCLES, PARAMS)
    assert free == math.inf
    blocker = np.array([[2.0, 0.0]])
    gap = braking_path_gap(pose, route, 1.0, np.vstack([walls, blocker]), blocker, NO_CIRCLES,
                           PARAMS)
    assert 0.5 < gap < 1.0


def test_driving_on_past_a_post_at_the_present_clearance_is_allowed_closing_in_is_not():
    route = Route(np.array([[0.0, 0.0], [10.0, 0.0]]))
    post = np.array([[1.3, 0.21]])                      # 1 cm from the robot's side, ahead
    parallel = braking_path_gap(np.array([1.3, 0.0, 0.0]), route, 1.3, post, np.zeros((0, 2)),
                                NO_CIRCLES, PARAMS)
    toward = braking_path_gap(np.array([1.0, 0.0, 0.3]), route, 1.0, post, np.zeros((0, 2)),
                              NO_CIRCLES, PARAMS)
    assert parallel == math.inf
    assert toward < 0.5


def test_a_person_on_the_route_brakes_a_robot_far_off_it_no_sooner_than_it_can_get_there():
    # a robot 3 m down a side corridor, driving back up it toward its route, while a person
    # crosses the route at the robot's station: it can drive 3 m before it reaches them
    route = Route(np.array([[0.0, 4.0], [10.0, 4.0]]))
    person = np.array([[5.0, 4.0, 0.25]])
    pose = np.array([5.0, 1.0, math.pi / 2])
    gap = braking_path_gap(pose, route, 5.0, np.zeros((0, 2)), np.zeros((0, 2)), person, PARAMS)
    assert gap > 2.0
    on_route = braking_path_gap(np.array([4.0, 4.0, 0.0]), route, 4.0, np.zeros((0, 2)),
                                np.zeros((0, 2)), person, PARAMS)
    assert on_route < 0.8


def test_a_robot_far_off_its_direction_turns_on_the_spot_first_and_drives_when_closer():
    ctrl = FieldFollower(PARAMS)
    ctrl.set_path(np.array([[0.0, 0.0], [5.0, 0.0]]), np.array([[5.0, 0.0]]))

    def command(yaw, v):
        obs = Observation(pose=np.array([0.0, 0.0, yaw]), velocity=np.array([v, 0.0]),
                          obstacle_points=np.zeros((0, 2)), tracked=np.zeros((0, 5)), time=0.0)
        return ctrl.compute(obs)

    across = command(math.pi / 2, 0.5)                   # 90 degrees off, moving: brake, turn
    assert across.v == pytest.approx(0.5 - PARAMS.max_accel * PARAMS.control_period)
    assert across.omega < 0.0
    standing = command(ROTATE_FIRST_RAD + 0.05, 0.0)
    assert standing.v == 0.0 and standing.omega < 0.0
    closer = command(ROTATE_FIRST_RAD - 0.05, 0.0)
    assert closer.v > 0.0


@pytest.mark.parametrize('name, period, gain', [('fusion', 0.05, 4.0), ('fusion', 0.1, 2.5),
                                                ('apf', 0.05, 2.0)])
def test_fusion_turns_onto_its_route_with_its_own_heading_gain(name, period, gain):
    """``route_heading_gain`` (4), at most 1 / (4 periods); apf keeps ``heading_gain``."""
    p = FollowerParams(max_speed=1.0, max_accel=1.0, max_omega=2.0, max_alpha=100.0,
                       control_period=period, heading_gain=2.0, route_heading_gain=4.0)
    ctrl = make_controller(name, p)
    ctrl.set_path(np.array([[0.0, 0.0], [5.0, 0.0]]), np.array([[0.0, 0.0], [5.0, 0.0]]))
    obs = Observation(pose=np.array([0.0, 0.0, -0.1]), velocity=np.array([0.5, 0.0]),
                      obstacle_points=np.zeros((0, 2)), tracked=np.zeros((0, 5)), time=0.0)
    assert ctrl.compute(obs).omega == pytest.approx(gain * 0.1)


def test_a_robot_turning_round_beside_a_wall_turns_away_from_it():
    """Driving 6 cm from a wall on its right, a robot told to turn round clockwise turns left."""
    pose = np.array([2.0, 0.0, 0.0])
    wall_right = wall((-1.0, -0.26), (4.0, -0.26))
    toward_wall = -0.9 * math.pi
    assert turn_round_error(pose, 0.6, toward_wall, wall_right, PARAMS) == pytest.approx(
        toward_wall + 2.0 * math.pi)
    assert turn_round_error(pose, 0.6, -toward_wall, wall_right, PARAMS) == -toward_wall
    assert turn_round_error(pose, 0.0, toward_wall, wall_right, PARAMS) == toward_wall  # standing
    assert turn_round_error(pose, 0.6, -1.0, wall_right, PARAMS) == -1.0     # not turning round
    farther = wall((-1.0, -0.5), (4.0, -0.5))                  # the short way's arc is free
    assert turn_round_error(pose, 0.6, toward_wall, farther, PARAMS) == toward_wall


def clearance_braking_for_a_box_seen_late(odometry_scale, tell_commands, dt=0.05):
    """Least clearance [m] of a robot at 0.8 m/s that sees a box across its route 0.5 m ahead.

    The robot sheds at most ``max_accel * dt`` of speed a period, as a base does; its
    odometry reports ``odometry_scale`` times its speed; with ``tell_commands`` the
    controller is told its last command (the local planner node tells it).
    """
    p = FollowerParams(max_speed=0.8, max_accel=1.0, max_omega=2.0, robot_radius=0.2,
                       control_period=dt)
    controller = make_controller('fusion', p)
    controller.set_path(np.array([[0.0, 0.0], [10.0, 0.0]]), np.array([[10.0, 0.0]]))
    box = wall((4.0, -1.0), (4.0, 1.0))
    pose, v, omega, last = np.zeros(3), 0.8, 0.0, None
    least = math.inf
    for k in range(100):
        seen = box if 4.0 - pose[0] - p.robot_radius < 0.5 else np.zeros((0, 2))
        command = controller.compute(Observation(
            pose.copy(), np.array([odometry_scale * v, omega]), seen, np.zeros((0, 5)), k * dt,
            commanded=last if tell_commands else None))
        last = (command.v, command.omega)
        dv = p.max_accel * dt
        v, omega = min(max(command.v, v - dv), v + dv), command.omega
        pose = integrate_unicycle(pose, v, omega, dt)
        least = min(least, float(np.min(np.hypot(*(box - pose[:2]).T))) - p.robot_radius)
    return least


@pytest.mark.parametrize('odometry_scale', [0.9, 1.0, 1.05, 1.1])
def test_odometry_that_overstates_the_speed_does_not_hold_the_brakes_back(odometry_scale):
    """Braking from the measured speed brakes at a fifth of the robot's power at 5 % too fast.

    0.05 m/s may be shed a period; odometry 5 % fast reads 0.84 m/s at 0.8 m/s, and a
    command 0.05 below that sheds 0.01 m/s. Braking from the last command stops clear.
    """
    assert clearance_braking_for_a_box_seen_late(odometry_scale, tell_commands=True) > 0.05
    untold = clearance_braking_for_a_box_seen_late(odometry_scale, tell_commands=False)
    assert (untold > 0.05) == (odometry_scale <= 1.0)


def test_an_observation_refuses_a_bad_last_command():
    with pytest.raises(InvalidInput, match='commanded'):
        Observation(np.zeros(3), np.zeros(2), np.zeros((0, 2)), np.zeros((0, 5)), 0.0,
                    commanded=(math.nan, 0.0))
    with pytest.raises(InvalidInput, match='commanded'):
        Observation(np.zeros(3), np.zeros(2), np.zeros((0, 2)), np.zeros((0, 5)), 0.0,
                    commanded=(0.5,))


# -- progress --------------------------------------------------------------------------------

def test_time_without_progress_counts_from_the_last_progress_and_survives_a_new_plan():
    monitor = ProgressMonitor(min_progress=0.15)
    assert monitor.update(0.0, 10.0) == 0.0
    assert monitor.update(10.0, 9.9) == 10.0            # 0.1 m is not progress
    assert monitor.update(11.0, 9.8) == 0.0
    monitor.rebase(15.0)                                # a longer new plan
    assert monitor.update(20.0, 15.0) == 9.0            # the clock was kept
    assert monitor.update(21.0, 14.8) == 0.0
    assert monitor.update(5.0, 14.8) == 0.0             # the clock went back: start over
    assert monitor.update(12.0, 14.8) == 7.0
    monitor.restart(12.0, 18.0)                         # a new plan given the full allowance
    assert monitor.update(13.0, 18.5) == 1.0            # farther than at the restart: no progress
    assert monitor.update(14.0, 17.8) == 0.0


def test_time_a_robot_is_pushed_away_from_the_goal_is_not_time_without_progress():
    monitor = ProgressMonitor(min_progress=0.15)
    monitor.update(0.0, 5.0)
    assert monitor.update(2.0, 5.0) == 2.0
    assert monitor.update(3.0, 6.0, pushed=True) == 2.0    # chased 1 m back
    assert monitor.update(4.0, 6.0, pushed=True) == 3.0    # held where it was: counts
    assert monitor.update(5.0, 5.5, pushed=True) == 4.0    # evading towards the goal: counts
    assert monitor.update(6.0, 6.5) == 5.0                 # driving away on its own: counts
    monitor.rebase(8.0)                                    # a longer new plan: no push
    assert monitor.update(7.0, 8.0, pushed=True) == 6.0
    assert monitor.update(8.0, 7.8) == 0.0


# -- passing people --------------------------------------------------------------------------

def test_a_person_walking_along_the_route_is_passed_on_the_roomier_side_and_kept_there():
    route = Route(np.array([[0.0, 0.0], [10.0, 0.0]]))
    person = np.array([[3.0, 0.1, -0.35, 0.0, 0.3]])
    left, right, side = passing_bounds(route, person, 0.9, 0.9, PARAMS, 0)
    assert side == -1 and right == math.inf and left == pytest.approx(0.1 - 0.6)
    _, right, side = passing_bounds(route, person, 0.9, 0.9, PARAMS, 1)    # side kept
    assert side == 1 and right == pytest.approx(-(0.1 + 0.6))


def test_a_side_that_has_become_a_little_too_narrow_is_not_given_up_across_the_persons_way():
    route = Route(np.array([[0.0, 0.0], [10.0, 0.0]]))
    person = np.array([[3.0, -0.15, -0.35, 0.0, 0.3]])
    # on its left, 0.62 - 0.2 m for the robot's centre, 0.45 m of it within the person's
    # reach (radii and margin): 3 cm short, and plenty of room on its right
    _, right, side = passing_bounds(route, person, 0.62, 1.5, PARAMS, 1)
    assert side == 1 and right == pytest.approx(-(-0.15 + 0.6))
    # no room on the left even without the margin: over to the right
    _, _, side = passing_bounds(route, person, 0.5, 1.5, PARAMS, 1)
    assert side == -1


def test_no_bounds_for_a_crossing_person_a_person_far_ahead_or_no_room():
    route = Route(np.array([[0.0, 0.0], [20.0, 0.0]]))
    crossing = np.array([[3.0, 0.0, 0.0, 0.4, 0.3]])
    far = np.array([[12.0, 0.0, -0.35, 0.0, 0.3]])
    walking = np.array([[3.0, 0.0, -0.35, 0.0, 0.3]])
    assert passing_bounds(route, crossing, 0.9, 0.9, PARAMS, 0) == (math.inf, math.inf, 0)
    assert passing_bounds(route, far, 0.9, 0.9, PARAMS, 0) == (math.inf, math.inf, 0)
    assert passing_bounds(route, walking, 0.5, 0.5, PARAMS, 0) == (math.inf, math.inf, 0)


def test_a_person_on_the_route_ahead_closes_it_from_wall_to_wall_for_a_replan():
    """A line across a 1 m corridor at the person, stopping short of its walls; not beyond them."""
    route = Route(np.array([[0.0, 0.0], [10.0, 0.0]]))
    walls = np.vstack([wall((0.0, 0.5), (10.0, 0.5), 0.1), wall((0.0, -0.5), (10.0, -0.5), 0.1)])
    person = np.array([[1.5, 0.05, -0.3, 0.0, 0.3]])
    closure = route_closures(route, np.zeros(2), person, walls, PARAMS, 0.05)
    assert np.allclose(closure[:, 0], 1.5)
    assert np.min(closure[:, 1]) < -0.3 and np.max(closure[:, 1]) > 0.3     # across the corridor
    assert np.all(np.abs(closure[:, 1]) < 0.5)                             # not into the walls
    open_side = route_closures(route, np.zeros(2), person, walls[walls[:, 1] > 0], PARAMS, 0.05)
    reach = 0.05 + 0.3 + 0.1 + 2 * PARAMS.robot_radius                    # past the person by a robot
    assert np.min(open_side[:, 1]) == pytest.approx(-reach, abs=0.05)


def test_a_robot_pushed_back_behind_its_station_closes_the_route_at_the_person_who_pushed_it():
    route = Route(np.array([[0.0, 0.0], [10.0, 0.0]]))
    for x in range(6):
        route.project(np.array([float(x), 0.0]))            # its best point so far: x = 5
    assert route.station == pytest.approx(5.0)
    person = np.array([[3.5, 0.0, 0.3, 0.0, 0.3]])          # walked it back to x = 2
    closure = route_closures(route, np.array([2.0, 0.0]), person, np.zeros((0, 2)), PARAMS, 0.05)
    assert len(closure) and np.allclose(closure[:, 0], 3.5)


def test_no_closure_for_a_crossing_person_one_beside_the_robot_or_one_yet_to_come_near():
    route = Route(np.array([[0.0, 0.0], [10.0, 0.0]]))
    crossing = np.array([[1.5, 0.0, 0.0, 0.4, 0.3]])
    beside = np.array([[0.45, 0.0, -0.3, 0.0, 0.3]])      # nearer than the robot, them and a margin
    far = np.array([[3.0, 0.0, -0.3, 0.0, 0.3]])
    assert len(route_closures(route, np.zeros(2), far, np.zeros((0, 2)), PARAMS, 0.05)) == 0
    assert len(route_closures(route, np.zeros(2), crossing, np.zeros((0, 2)), PARAMS, 0.05)) == 0
    assert len(route_closures(route, np.zeros(2), beside, np.zeros((0, 2)), PARAMS, 0.05)) == 0
    assert len(route_closures(route, np.zeros(2), np.zeros((0, 5)), np.zeros((0, 2)), PARAMS, 0.05)) == 0


# -- centring the plan --------------------------------------------------------------------

def corridor(width_cells, length_cells=80, resolution=0.05):
    occupied = np.ones((width_cells + 4, length_cells), bool)
    occupied[2:-2, :] = False
    return GridMap(occupied, resolution)


#: Centring reads the whole clearance map when it is prepared, else windows.
CLEARANCE_SOURCES = pytest.mark.parametrize('whole_clearance', (False, True),
                                            ids=('windows', 'whole-map'))


@CLEARANCE_SOURCES
def test_a_path_along_a_wall_moves_to_the_safety_distance_and_no_further(whole_clearance):
    grid = corridor(40)                                 # 2 m wide, walls at y = 0.1 and 2.1
    if whole_clearance:
        grid.clearance
    assert grid.clearance_ready == whole_clearance
    path = np.column_stack([np.linspace(0.2, 3.8, 73), np.full(73, 0.35)])
    centred = centre_path(grid, path, robot_radius=0.2, safety_distance=0.3)
    np.testing.assert_allclose(centred[[0, -1]], path[[0, -1]])
    middle = centred[10:-10]
    assert np.all(grid.clearance_at(middle) >= 0.5 - 0.05)
    assert np.all(middle[:, 1] < 1.0)                   # not pushed to the corridor's middle


@CLEARANCE_SOURCES
def test_a_passage_narrower_than_the_safety_distance_is_crossed_through_its_middle(
        whole_clearance):
    grid = corridor(14)                                 # 0.7 m wide, middle at y = 0.45
    if whole_clearance:
        grid.clearance
    assert grid.clearance_ready == whole_clearance
    path = np.column_stack([np.linspace(0.2, 3.8, 73), np.full(73, 0.33)])
    before = corridor(14).clearance_at(path)
    centred = centre_path(grid, path, robot_radius=0.2, safety_distance=0.3)
    assert np.all(grid.clearance_at(centred) >= before)
    assert np.all(np.abs(centred[10:-10, 1] - 0.45) < 0.04)


def test_centring_is_off_for_a_point_robot_and_can_be_turned_off():
    grid = corridor(14)
    path = np.column_stack([np.linspace(0.2, 3.8, 73), np.full(73, 0.33)])
    np.testing.assert_array_equal(centre_path(grid, path, 0.0, 0.0), path)
    config = PlannerConfig(robot_radius=0.2, safety_distance=0.3)
    plain = GlobalPlanner(grid, PlannerConfig(robot_radius=0.2, safety_distance=0.3,
                                              centre=False)).plan((0.3, 0.33), (3.7, 0.6))
    centred = GlobalPlanner(grid, config).plan((0.3, 0.33), (3.7, 0.6))
    assert centred.metrics.min_clearance_m >= plain.metrics.min_clearance_m
    assert not np.array_equal(centred.path, plain.path)


def test_a_one_cell_wide_map_leaves_the_path_as_it_is():
    occupied = np.zeros((1, 5), bool)
    occupied[0, 4] = True
    grid = GridMap(occupied, 0.25)
    result = GlobalPlanner(grid, PlannerConfig(algorithm='dijkstra', neighbourhood=4,
                                               safety_distance=0.05)).plan((0.125, 0.125),
                                                                           (0.625, 0.125))
    np.testing.assert_allclose(result.path[[0, -1]], [[0.125, 0.125], [0.625, 0.125]])


# -- replanning that proves unreachability ----------------------------------------------------

def test_a_replan_with_a_comfort_margin_is_retried_with_the_radius_alone():
    grid = corridor(24)                                 # 1.2 m wide, middle at y = 0.7 ...
    occupied = grid.occupied.copy()
    occupied[2:8, 38:42] = occupied[-8:-2, 38:42] = True   # ... but a 0.6 m slit halfway
    grid = GridMap(occupied, grid.resolution)
    config = PlannerConfig(robot_radius=0.35)
    with pytest.raises(NoValidPathCouldBeFound):
        GridReplanner(grid, config)((0.5, 0.7), (3.5, 0.7), np.zeros((0, 2)))
    path, _ = GridReplanner(grid, config, robot_radius=0.2)((0.5, 0.7), (3.5, 0.7),
                                                             np.zeros((0, 2)))
    assert np.allclose(path[-1], [3.5, 0.7], atol=0.05)


def test_a_wedged_robot_proves_nothing_about_the_goal():
    grid = corridor(8)                                  # 0.4 m: the robot only just fits
    with pytest.raises(StartOccupied):
        GridReplanner(grid, PlannerConfig(robot_radius=0.2))((0.5, 0.3), (3.5, 0.3),
                                                             np.zeros((0, 2)))


@pytest.mark.parametrize('radius', [-0.1, float('nan'), 'wide'])
def test_a_replanner_refuses_a_bad_robot_radius(radius):
    with pytest.raises(InvalidInput):
        GridReplanner(corridor(12), PlannerConfig(), robot_radius=radius)
