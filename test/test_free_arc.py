"""The last check of a route follower's command: it can stop on its arc clear of every scan point."""

import math

import numpy as np
import pytest

from fusion_planner.core.errors import InvalidInput
from fusion_planner.core.local_planning.controller_base import FollowerParams, Observation
from fusion_planner.core.local_planning.follow import make_controller
from fusion_planner.core.local_planning.free_arc import (
    arc_points, free_arc_speed, free_arc_turn, stopping_distance)

PARAMS = FollowerParams(max_speed=1.0, max_accel=1.0, max_omega=2.0, robot_radius=0.2)


def line(a, b, spacing=0.02):
    a, b = np.asarray(a, float), np.asarray(b, float)
    count = max(2, int(np.linalg.norm(b - a) / spacing) + 1)
    return a + np.linspace(0.0, 1.0, count)[:, None] * (b - a)


def closest_on_stop(pose, v, omega, points):
    """Smallest boundary gap [m] to ``points`` while stopping on the arc of ``(v, omega)``."""
    lengths = math.copysign(1.0, v) * np.linspace(0.0, stopping_distance(v, PARAMS), 400)
    positions = arc_points(pose, omega / v, lengths)
    d = positions[:, None, :] - points[None, :, :]
    return float(np.min(np.hypot(d[..., 0], d[..., 1]))) - PARAMS.robot_radius


def test_a_wall_within_the_stopping_distance_bounds_the_speed_to_one_that_stops_clear():
    pose = np.array([0.0, 0.0, 0.0])
    wall = line([0.6, -1.0], [0.6, 1.0])
    v = free_arc_speed(pose, 1.0, 0.0, wall, PARAMS)
    assert 0.0 < v < 1.0
    assert closest_on_stop(pose, v, 0.0, wall) >= PARAMS.safety_distance - 1e-9
    assert free_arc_speed(pose, 1.0, 0.0, wall + [3.0, 0.0], PARAMS) == 1.0


def test_turning_into_a_wall_beside_the_robot_is_bounded_driving_along_it_is_not():
    pose = np.array([0.0, 0.0, 0.0])
    wall = line([-1.0, 0.35], [3.0, 0.35])                       # 0.15 m beside the robot
    assert free_arc_speed(pose, 1.0, 0.0, wall, PARAMS) == 1.0
    v = free_arc_speed(pose, 1.0, 2.0, wall, PARAMS)             # turning left, into it
    assert v < 1.0
    assert closest_on_stop(pose, v, 2.0, wall) >= PARAMS.safety_distance - 1e-9
    assert free_arc_speed(pose, 1.0, -2.0, wall, PARAMS) == 1.0   # turning away


def test_a_passage_narrower_than_the_safety_distance_is_driven_at_the_present_clearance():
    pose = np.array([0.0, 0.0, 0.0])
    walls = np.vstack([line([-1.0, 0.21], [3.0, 0.21]), line([-1.0, -0.21], [3.0, -0.21])])
    assert free_arc_speed(pose, 1.0, 0.0, walls, PARAMS) == 1.0
    assert free_arc_speed(pose, 1.0, 0.5, walls, PARAMS) <= 0.25  # a turn closes in


def test_reversing_is_checked_behind_and_turning_in_place_is_left_alone():
    pose = np.array([0.0, 0.0, 0.0])
    behind = line([-0.5, -1.0], [-0.5, 1.0])
    assert free_arc_speed(pose, 1.0, 0.0, behind, PARAMS) == 1.0
    v = free_arc_speed(pose, -1.0, 0.0, behind, PARAMS)
    assert -1.0 < v <= 0.0
    assert closest_on_stop(pose, v, 0.0, behind) >= PARAMS.safety_distance - 1e-9
    assert free_arc_speed(pose, 0.0, 2.0, behind, PARAMS) == 0.0
    assert free_arc_speed(pose, 0.7, 0.0, np.zeros((0, 2)), PARAMS) == 0.7


def test_a_robot_too_fast_to_stop_on_its_arc_is_steered_to_a_free_one():
    pose = np.array([0.0, 0.0, 0.0])
    wall = line([-1.0, 0.35], [3.0, 0.35])                       # 0.15 m to the left
    assert free_arc_speed(pose, 1.0, 1.5, wall, PARAMS) < 1.0     # it wants to turn into it
    omega = free_arc_turn(pose, 1.0, (0.5, 1.5), 1.5, wall, PARAMS)
    assert 0.5 <= omega < 1.5
    assert free_arc_speed(pose, 1.0, omega, wall, PARAMS) == 1.0
    assert free_arc_turn(pose, 1.0, (-0.5, 0.5), 0.3, wall, PARAMS) == pytest.approx(0.3)


def test_a_person_not_yet_tracked_as_moving_is_evaded_by_fusion():
    """A tentative mover walking at the route 0.8 m ahead: fusion's command changes for it."""
    controller = make_controller('fusion', PARAMS)
    controller.set_path(np.array([[0.0, 0.0], [8.0, 0.0]]), np.array([[8.0, 0.0]]))
    person = np.array([[1.2, 0.7, 0.0, -0.4, 0.25]])              # crosses the route
    surface = person[0, :2] + 0.25 * np.stack(
        [np.cos(np.linspace(-2.5, -0.6, 12)), np.sin(np.linspace(-2.5, -0.6, 12))], axis=1)
    base = dict(pose=np.zeros(3), velocity=np.array([0.9, 0.0]), obstacle_points=surface,
                tracked=np.zeros((0, 5)), time=0.0)
    unaware = controller.compute(Observation(**base))
    controller.reset()
    controller.set_path(np.array([[0.0, 0.0], [8.0, 0.0]]), np.array([[8.0, 0.0]]))
    aware = controller.compute(Observation(**base, tentative=person))
    assert unaware.v > 0.85                                       # its points are beside the route
    # the one-step limits allow 0.05 m/s and 0.2 rad/s of change: the evasion takes them
    assert aware.v < unaware.v - 0.04 or abs(aware.omega - unaware.omega) > 0.15


@pytest.mark.parametrize('tentative', [np.zeros((2, 4)), np.array([[0.0, 0.0, 0.0, 0.0, -1.0]])])
def test_bad_tentative_movers_are_refused(tentative):
    with pytest.raises(InvalidInput, match='tentative'):
        Observation(pose=np.zeros(3), velocity=np.zeros(2), obstacle_points=np.zeros((0, 2)),
                    tracked=np.zeros((0, 5)), time=0.0, tentative=tentative)
