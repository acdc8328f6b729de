"""Tests of the ``'dwa'`` baseline (fusion_planner.core.local_planning.dwa)."""

import math

import numpy as np
import pytest

from fusion_planner.core.errors import InvalidInput
from fusion_planner.core.grid import GridMap
from fusion_planner.core.local_planning import dwa, follow
from fusion_planner.core.local_planning.controller_base import FollowerParams, Observation
from fusion_planner.core.simulation.episodes import run_episode
from fusion_planner.core.simulation.scenario import scenario_from_dict

STRAIGHT = np.array([[0.0, 0.0], [6.0, 0.0]])


def observe(pose=(0.0, 0.0, 0.0), velocity=(0.0, 0.0), points=(), tracked=(), time=0.0):
    return Observation(pose=np.array(pose, float), velocity=np.array(velocity, float),
                       obstacle_points=np.array(points, float).reshape(-1, 2),
                       tracked=np.array(tracked, float).reshape(-1, 5), time=time)


def controller(**params):
    ctrl = follow.make_controller('dwa', FollowerParams(control_period=0.1, max_speed=0.8, **params))
    ctrl.set_path(STRAIGHT, STRAIGHT)
    return ctrl


def room(unknown=(), moving=()):
    """A 10 x 4 m empty room, start (1, 2) facing +x, goal (9, 2)."""
    doc = {'robot': {'start': [1.0, 2.0, 0.0], 'radius': 0.2}, 'goal': [9.0, 2.0],
           'unknown_obstacles': list(unknown), 'moving_obstacles': list(moving),
           'limits': {'time_limit_s': 40.0}, 'scan': {'beams': 180, 'range_max': 6.0}}
    return scenario_from_dict(doc, grid=GridMap(np.zeros((40, 100), bool), 0.1))


def test_dwa_is_a_controller_of_the_simulation():
    assert isinstance(follow.make_controller('dwa', FollowerParams()), dwa.DynamicWindow)
    assert 'dwa' in follow.CONTROLLER_NAMES


def test_rollout_follows_exact_arcs_and_straight_lines():
    poses = dwa.rollout(np.array([1.0, 2.0, math.pi / 2]), np.array([1.0, 0.5]),
                        np.array([1.0, 0.0]), np.array([0.5 * math.pi, 2.0]))
    # a quarter circle of radius 1 to the left, then three quarters
    assert poses[0, 0] == pytest.approx([0.0, 3.0, math.pi])
    assert poses[0, 1] == pytest.approx([1.0 - 1.0 + math.cos(2.0), 2.0 + math.sin(2.0), math.pi / 2 + 2.0])
    assert poses[1, 1] == pytest.approx([1.0, 3.0, math.pi / 2])


def test_free_travel_stops_before_the_first_contact():
    clearance = np.array([[0.3, 0.2, 0.1], [0.3, -0.1, 0.4], [-0.2, 0.5, 0.5]])
    free = dwa.free_travel(clearance, np.array([1.0, 2.0, 3.0]), threshold=0.05)
    assert free.tolist() == [math.inf, 1.0, 0.0]


@pytest.mark.parametrize('seed', range(20))
def test_commands_stay_in_the_dynamic_window(seed):
    rng = np.random.default_rng(seed)
    ctrl = controller()
    p = ctrl.params
    v0, w0 = rng.uniform(0.0, 0.8), rng.uniform(-2.0, 2.0)
    points = rng.uniform([-1.0, -2.0], [4.0, 2.0], size=(30, 2))
    points = points[np.hypot(*points.T) > 0.3]
    cmd = ctrl.compute(observe((0.0, 0.0, rng.uniform(-1, 1)), (v0, w0), points))
    assert 0.0 <= cmd.v <= p.max_speed and abs(cmd.omega) <= p.max_omega
    assert abs(cmd.v - v0) <= p.max_accel * p.control_period + 1e-9
    assert abs(cmd.omega - w0) <= p.max_alpha * p.control_period + 1e-9


def test_it_brakes_for_a_wall_it_sees_ahead():
    wall = np.column_stack([np.full(41, 0.6), np.linspace(-1.0, 1.0, 41)])
    ctrl = controller()
    p = ctrl.params
    cmd = ctrl.compute(observe(velocity=(0.8, 0.0), points=wall))
    free = 0.6 - p.robot_radius - p.safety_distance
    assert cmd.v < 0.8 and cmd.v * p.control_period + cmd.v**2 / (2 * p.max_accel) <= free


def test_it_steers_for_a_person_predicted_on_its_way():
    # a person 1.5 m ahead walking toward the robot: going straight on would meet them
    ctrl = controller()
    person = [[1.5, 0.0, -0.4, 0.0, 0.3]]
    plain = controller().compute(observe(velocity=(0.6, 0.0)))
    cmd = ctrl.compute(observe(velocity=(0.6, 0.0), tracked=person))
    assert plain.omega == pytest.approx(0.0, abs=1e-9)
    assert cmd.v < plain.v or abs(cmd.omega) > 0.1


def test_arrives_and_stays_in_the_goal_tolerance():
    ctrl = controller()
    cmd = ctrl.compute(observe(pose=(5.95, 0.0, 0.0), velocity=(0.1, 0.0)))
    assert cmd.status == 'arrived' and cmd.v < 0.1


def test_no_plan_and_bad_observations():
    ctrl = follow.make_controller('dwa', FollowerParams())
    assert ctrl.compute(observe()).status == 'no_path'
    with pytest.raises(InvalidInput):
        ctrl.compute('not an observation')
    with pytest.raises(InvalidInput):
        ctrl.set_path(np.array([[0.0, np.nan]]), STRAIGHT)
    ctrl.set_path(STRAIGHT, STRAIGHT)
    # non-finite scan points and tracks are ignored, not propagated
    cmd = ctrl.compute(observe(points=[[np.inf, 0.0], [np.nan, 1.0]],
                               tracked=[[np.nan, 0.0, 0.0, 0.0, 0.3]]))
    assert cmd.status == 'moving' and math.isfinite(cmd.v) and math.isfinite(cmd.omega)


def test_drives_an_empty_room_to_the_goal_near_top_speed():
    result = run_episode(room(), 'dwa', record=False)
    assert result.reached and result.collisions == 0
    assert result.time_ratio < 1.5


def test_a_closed_way_ends_by_the_progress_checker_without_contact():
    result = run_episode(room([{'rectangle': {'min': [5.0, 0.0], 'max': [5.3, 4.0]}}]), 'dwa',
                         record=False)
    assert result.outcome == 'controller_failed' and 'no progress' in result.failure
    assert result.collisions == 0 and result.stuck_events == 1
    assert result.time_s < 10.0 + 8.0      # drives up to the wall, then 10 s without progress


def test_lets_a_person_cross_without_contact():
    person = {'radius': 0.3, 'model': 'bounce', 'position': [5.0, 3.5], 'velocity': [0.0, -0.3]}
    result = run_episode(room(moving=[person]), 'dwa', record=False)
    assert result.reached and result.collisions == 0
