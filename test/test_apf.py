"""Tests of the potential fields (fusion_planner.core.local_planning.apf): eqs. (9)-(18) as properties."""

import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from fusion_planner.core.local_planning import apf
from fusion_planner.core.local_planning.apf import (
    ApfParams, adaptive_step, attractive_force, classic_repulsive_force,
    improved_repulsive_force, velocity_repulsion)
from fusion_planner.core.errors import InvalidInput

PARAMS = ApfParams(k_att=1.0, k_rep=0.05, rho0=1.0, n=2.0, mu=0.01)
ORIGIN = np.zeros(2)

coordinate = st.floats(-5.0, 5.0, allow_nan=False)
point = st.tuples(coordinate, coordinate).map(np.array)


def arc(centre, radius, start, stop, count=40):
    """Points on a circular arc [m]."""
    angles = np.linspace(start, stop, count)
    return np.asarray(centre) + radius * np.c_[np.cos(angles), np.sin(angles)]


# -- parameters ---------------------------------------------------------------------

def test_default_params_are_valid():
    params = ApfParams()
    assert params.rho > params.d_min > 0


@pytest.mark.parametrize('changes', [
    {'k_att': 0.0}, {'k_att': -1.0}, {'k_rep': -0.1}, {'rho0': 0.0}, {'n': 0.0},
    {'mu': -1.0}, {'l0': 0.0}, {'d_min': 1.0, 'rho': 0.5}, {'robot_radius': -0.1},
    {'k_att': float('nan')}, {'rho0': float('inf')}, {'k_rep': '1'}, {'n': True},
])
def test_bad_params_are_refused(changes):
    with pytest.raises(InvalidInput):
        ApfParams(**changes)


# -- attraction, eq. (10) ----------------------------------------------------------

@given(point, point)
def test_attraction_points_at_goal_with_magnitude_gamma_rho(q, goal):
    force = attractive_force(q, goal, PARAMS)
    assert np.allclose(force, PARAMS.k_att * (goal - q))
    assert math.isclose(np.linalg.norm(force), PARAMS.k_att * np.linalg.norm(goal - q),
                        rel_tol=1e-9, abs_tol=1e-12)


def test_attraction_refuses_bad_positions():
    with pytest.raises(InvalidInput):
        attractive_force([float('nan'), 0.0], ORIGIN, PARAMS)
    with pytest.raises(InvalidInput):
        attractive_force([0.0, 0.0, 0.0], ORIGIN, PARAMS)


# -- classic repulsion, eq. (12) ---------------------------------------------------------

def test_classic_repulsion_is_zero_beyond_rho0_and_pushes_away_inside():
    far = np.array([[PARAMS.rho0 + 0.01, 0.0], [0.0, -PARAMS.rho0 - 0.5]])
    assert np.array_equal(classic_repulsive_force(ORIGIN, far, PARAMS), np.zeros(2))
    near = np.array([[0.5, 0.0]])
    force = classic_repulsive_force(ORIGIN, near, PARAMS)
    assert force[0] < 0 and abs(force[1]) < 1e-12


def test_classic_repulsion_matches_eq_12_and_grows_when_closer():
    distances = np.linspace(0.05, 0.99, 30)
    magnitudes = [np.linalg.norm(classic_repulsive_force(ORIGIN, [[d, 0.0]], PARAMS))
                  for d in distances]
    expected = PARAMS.k_rep * (1 / distances - 1 / PARAMS.rho0) / distances**2
    assert np.allclose(magnitudes, expected)
    assert np.all(np.diff(magnitudes) < 0)


def test_distance_is_measured_from_the_robot_boundary():
    inflated = ApfParams(k_rep=0.05, rho0=1.0, robot_radius=0.3)
    # 1.2 m from the centre is 0.9 m from the boundary: inside rho0
    assert np.linalg.norm(classic_repulsive_force(ORIGIN, [[1.2, 0.0]], inflated)) > 0
    assert np.linalg.norm(classic_repulsive_force(ORIGIN, [[1.2, 0.0]], PARAMS)) == 0
    expected = 0.05 * (1 / 0.9 - 1) / 0.81
    assert math.isclose(np.linalg.norm(classic_repulsive_force(ORIGIN, [[1.2, 0.0]], inflated)),
                        expected, rel_tol=1e-9)


def test_repulsion_is_a_weighted_sum_over_points():
    points = np.array([[0.4, 0.1], [-0.3, 0.5], [0.2, -0.6]])
    weights = np.array([1.0, 2.0, 0.5])
    total = classic_repulsive_force(ORIGIN, points, PARAMS, weights)
    parts = sum(w * classic_repulsive_force(ORIGIN, p[None], PARAMS)
                for p, w in zip(points, weights))
    assert np.allclose(total, parts)


# -- improved repulsion, eqs. (15)-(16) ---------------------------------------------------

@settings(max_examples=60, deadline=None)
@given(point, point, st.floats(0.5, 3.0))
def test_improved_repulsion_matches_eqs_15_16_for_one_point(obstacle, goal, n):
    params = ApfParams(k_rep=0.05, rho0=1.0, n=n)
    q = obstacle + np.array([0.3, 0.4])           # 0.5 m from the obstacle
    rho, rho_g = 0.5, np.linalg.norm(goal - q)
    if rho_g < 1e-3:
        return
    inverse = 1 / rho - 1 / params.rho0
    rep1 = params.k_rep * inverse * rho_g**n / rho**2 * (q - obstacle) / rho         # eq. (15)
    rep2 = 0.5 * n * params.k_rep * inverse**2 * rho_g**(n - 1) * (goal - q) / rho_g  # eq. (16)
    force = improved_repulsive_force(q, goal, obstacle[None], params)
    assert np.allclose(force, rep1 + rep2, rtol=1e-9, atol=1e-12)


def test_improved_repulsion_vanishes_at_the_goal():
    goal = np.array([5.0, 0.0])
    wall = arc(goal + [0.0, 0.9], 0.5, -math.pi, 0.0)      # an obstacle 0.4 m beside the goal
    assert np.array_equal(improved_repulsive_force(goal, goal, wall, PARAMS), np.zeros(2))
    magnitudes = [np.linalg.norm(improved_repulsive_force(goal - [s, 0.0], goal, wall, PARAMS))
                  for s in (0.5, 0.1, 0.01, 0.001)]
    assert np.all(np.diff(magnitudes) < 0) and magnitudes[-1] < 1e-2
    # while the classic repulsion does not: the goal is not an equilibrium (section 2.1.4)
    classic_total = (attractive_force(goal, goal, PARAMS)
                     + classic_repulsive_force(goal, wall, PARAMS))
    improved_total = attractive_force(goal, goal, PARAMS) + improved_repulsive_force(
        goal, goal, wall, PARAMS)
    assert np.linalg.norm(classic_total) > 0.1
    assert np.linalg.norm(improved_total) == 0.0


def test_improved_repulsion_is_zero_beyond_rho0():
    far = arc(ORIGIN, PARAMS.rho0 + 0.05, 0.0, 2 * math.pi)
    assert np.array_equal(improved_repulsive_force(ORIGIN, [3.0, 0.0], far, PARAMS), np.zeros(2))
    assert np.array_equal(velocity_repulsion(ORIGIN, [1.0, 0.0], far, None, PARAMS), np.zeros(2))


def test_second_component_points_at_the_goal():
    # obstacle straight behind the robot, goal to the side: eq. (15) pushes along +x,
    # eq. (16) pulls toward the goal (+y); both show in the sum
    force = improved_repulsive_force(ORIGIN, [0.0, 2.0], [[-0.5, 0.0]], PARAMS)
    assert force[0] > 0 and force[1] > 0


# -- empty sets, NaN guard, bad input -------------------------------------------------------

@pytest.mark.parametrize('empty', [np.zeros((0, 2)), [], np.zeros(0)])
def test_no_points_give_no_force(empty):
    assert np.array_equal(classic_repulsive_force(ORIGIN, empty, PARAMS), np.zeros(2))
    assert np.array_equal(improved_repulsive_force(ORIGIN, [1.0, 1.0], empty, PARAMS), np.zeros(2))
    assert np.array_equal(velocity_repulsion(ORIGIN, [1.0, 0.0], empty, None, PARAMS), np.zeros(2))


@settings(max_examples=80, deadline=None)
@given(st.lists(point, min_size=1, max_size=20), point, st.floats(0.0, 0.5))
def test_forces_are_finite_even_for_points_on_or_inside_the_robot(points, goal, radius):
    params = ApfParams(k_rep=0.05, rho0=1.0, robot_radius=radius, mu=0.01)
    q = points[0].copy()                       # one point exactly at q
    pts = np.array(points)
    for force in (classic_repulsive_force(q, pts, params),
                  improved_repulsive_force(q, goal, pts, params),
                  velocity_repulsion(q, [0.5, -0.2], pts, np.zeros_like(pts), params)):
        assert force.shape == (2,) and np.all(np.isfinite(force))


def test_point_inside_the_robot_pushes_out():
    params = ApfParams(k_rep=0.05, rho0=1.0, robot_radius=0.3)
    force = classic_repulsive_force(ORIGIN, [[0.1, 0.0]], params)
    assert np.all(np.isfinite(force)) and force[0] < 0


@pytest.mark.parametrize('points', [np.zeros((3,)), np.zeros((2, 3)), [[0.0, float('inf')]]])
def test_bad_point_sets_are_refused(points):
    with pytest.raises(InvalidInput):
        classic_repulsive_force(ORIGIN, points, PARAMS)


def test_bad_weights_are_refused():
    with pytest.raises(InvalidInput):
        improved_repulsive_force(ORIGIN, [1.0, 0.0], [[0.5, 0.0]], PARAMS, weights=[-1.0])
    with pytest.raises(InvalidInput):
        improved_repulsive_force(ORIGIN, [1.0, 0.0], [[0.5, 0.0]], PARAMS, weights=[1.0, 1.0])


# -- velocity repulsion, eq. (17) ----------------------------------------------------------

def test_velocity_repulsion_acts_only_when_closing_in():
    obstacle = np.array([[0.5, 0.0]])
    toward = velocity_repulsion(ORIGIN, [0.5, 0.0], obstacle, None, PARAMS)
    away = velocity_repulsion(ORIGIN, [-0.5, 0.0], obstacle, None, PARAMS)
    along = velocity_repulsion(ORIGIN, [0.0, 0.5], obstacle, None, PARAMS)
    assert toward[0] < 0 and np.array_equal(away, np.zeros(2)) and np.allclose(along, 0.0)
    expected = PARAMS.mu * 0.5 * math.exp(1 / 0.5 - 1 / PARAMS.rho0)
    assert math.isclose(-toward[0], expected, rel_tol=1e-9)


def test_velocity_repulsion_uses_relative_velocity():
    obstacle = np.array([[0.5, 0.0]])
    # a robot at rest, an obstacle coming at it: pushed away
    coming = velocity_repulsion(ORIGIN, [0.0, 0.0], obstacle, np.array([[-0.4, 0.0]]), PARAMS)
    assert coming[0] < 0
    # the robot following an obstacle that moves away as fast: nothing
    same = velocity_repulsion(ORIGIN, [0.4, 0.0], obstacle, np.array([[0.4, 0.0]]), PARAMS)
    assert np.allclose(same, 0.0)
    faster = velocity_repulsion(ORIGIN, [0.0, 0.0], obstacle, np.array([[-0.8, 0.0]]), PARAMS)
    assert np.linalg.norm(faster) > np.linalg.norm(coming)


def test_velocity_repulsion_is_finite_at_tiny_distances():
    force = velocity_repulsion(ORIGIN, [1.0, 0.0], [[1e-9, 0.0]], None, PARAMS)
    assert np.all(np.isfinite(force))


def test_velocity_repulsion_refuses_mismatched_velocities():
    with pytest.raises(InvalidInput):
        velocity_repulsion(ORIGIN, [1.0, 0.0], [[0.5, 0.0]], np.zeros((2, 2)), PARAMS)


# -- adaptive step, eq. (18) -------------------------------------------------------------------

def test_adaptive_step_branches():
    p = ApfParams(step_alpha=0.8, step_beta=1.6, l0=0.5, d_min=0.3, rho=1.2)
    v = 0.7
    assert math.isclose(adaptive_step(0.1, v, p), 0.8 * 0.5 * 0.1 * v)       # d < d_min
    assert math.isclose(adaptive_step(0.6, v, p), 1.6 * 0.5 * 0.6 * v)       # d_min <= d < rho
    assert adaptive_step(1.2, v, p) == 0.5                                   # d >= rho: l0
    assert adaptive_step(math.inf, v, p) == 0.5                              # nothing around
    assert adaptive_step(-0.2, v, p) == 0.0                                  # touching
    assert math.isclose(adaptive_step(0.6, -v, p), adaptive_step(0.6, v, p))  # |v|


def test_adaptive_step_is_vectorised_and_smaller_near_obstacles():
    p = ApfParams()
    d = np.array([0.05, 0.2, 0.5, 0.9, 2.0])
    steps = adaptive_step(d, 1.0, p)
    assert steps.shape == d.shape
    assert np.all(np.diff(steps[:4]) > 0) and steps[-1] == p.l0


def test_adaptive_step_refuses_nan():
    with pytest.raises(InvalidInput):
        adaptive_step(float('nan'), 1.0, ApfParams())
    with pytest.raises(InvalidInput):
        adaptive_step(0.5, float('inf'), ApfParams())


# -- cost ------------------------------------------------------------------------------------

def test_a_720_beam_scan_gives_finite_forces():
    # Its speed is measured by `fusion-planner bench local`, not here.
    rng = np.random.default_rng(1)
    angles = np.linspace(-math.pi, math.pi, 720, endpoint=False)
    ranges = rng.uniform(0.3, 3.0, 720)
    scan = np.c_[ranges * np.cos(angles), ranges * np.sin(angles)]
    velocities = np.zeros_like(scan)
    assert np.all(np.isfinite(improved_repulsive_force(ORIGIN, [4.0, 1.0], scan, PARAMS)))
    assert np.all(np.isfinite(velocity_repulsion(ORIGIN, [0.5, 0.0], scan, velocities, PARAMS)))


def test_named_constants_are_sane():
    assert 0 < apf.MIN_DISTANCE < 0.01
    assert math.isfinite(math.exp(apf.MAX_VELOCITY_EXPONENT))
