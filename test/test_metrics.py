"""Tests of fusion_planner.core.global_planning.metrics."""

import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from fusion_planner.core import raster
from fusion_planner.core.global_planning import metrics
from fusion_planner.core.errors import InvalidInput
from fusion_planner.core.grid import GridMap


def _rotate(path, angle, shift):
    c, s = math.cos(angle), math.sin(angle)
    return np.asarray(path, float) @ np.array([[c, s], [-s, c]]) + shift


def test_length_of_simple_polylines():
    assert metrics.path_length([[0, 0], [3, 4]]) == 5.0
    assert metrics.path_length([[1, 1]]) == 0.0
    assert metrics.path_length([[0, 0], [1, 0], [1, 0], [1, 2]]) == 3.0
    square = [[0, 0], [2, 0], [2, 2], [0, 2], [0, 0]]
    assert metrics.path_length(square) == 8.0


def test_turning_of_simple_polylines():
    assert metrics.turning_angle_deg([[0, 0], [1, 0], [1, 1]]) == pytest.approx(90.0)
    assert metrics.turning_angle_deg([[0, 0], [1, 0], [1, -1]]) == pytest.approx(90.0)
    assert metrics.turning_angle_deg([[0, 0], [1, 0], [2, 0], [5, 0]]) == 0.0
    assert metrics.turning_angle_deg([[0, 0], [1, 0], [0, 0]]) == pytest.approx(180.0)
    # Left then right: absolute values add.
    zigzag = [[0, 0], [1, 0], [2, 1], [3, 1]]
    assert metrics.turning_angle_deg(zigzag) == pytest.approx(90.0)
    # Zero-length segments carry no heading.
    assert metrics.turning_angle_deg([[0, 0], [1, 0], [1, 0], [1, 1]]) == pytest.approx(90.0)
    assert metrics.turning_angle_deg([[0, 0]]) == 0.0
    assert metrics.turning_angle_deg([[0, 0], [1, 1]]) == 0.0


def test_key_points_of_simple_polylines():
    straight = [[0, 0], [1, 0], [2, 0], [3, 0]]
    assert metrics.key_point_indices(straight).tolist() == [0, 3]
    ell = [[0, 0], [1, 0], [2, 0], [2, 1], [2, 2]]
    assert metrics.key_point_indices(ell).tolist() == [0, 2, 4]
    stairs = [[0, 0], [1, 0], [1, 1], [2, 1], [2, 2]]
    assert metrics.key_point_indices(stairs).tolist() == [0, 1, 2, 3, 4]
    assert metrics.key_point_indices([[0, 0], [1, 0], [1, 0], [2, 0]]).tolist() == [0, 3]
    assert metrics.key_point_indices([[0, 0], [1, 0], [0, 0]]).tolist() == [0, 1, 2]
    assert metrics.key_point_indices([[5, 5]]).tolist() == [0]
    assert metrics.key_point_indices([[5, 5], [5, 5]]).tolist() == [0, 1]
    assert metrics.key_point_indices([[5, 5], [5, 5], [5, 5]]).tolist() == [0, 2]


def test_key_points_on_a_grid_path_with_float_noise():
    grid = GridMap(np.zeros((10, 10), bool), resolution=0.05, origin=(-3.7, 1.3, 0.0))
    cells = [[0, 0], [1, 1], [2, 2], [3, 3], [3, 4], [3, 5], [3, 6]]
    path = grid.world_of(np.array(cells))
    assert metrics.key_point_indices(path).tolist() == [0, 3, 6]
    assert metrics.turning_angle_deg(path) == pytest.approx(45.0)


@settings(max_examples=30, deadline=None)
@given(st.lists(st.tuples(st.integers(-5, 5), st.integers(-5, 5)), min_size=1, max_size=12),
       st.floats(-math.pi, math.pi), st.floats(-50, 50))
def test_metrics_are_rigid_motion_invariant(points, angle, shift):
    path = np.array(points, float)
    moved = _rotate(path, angle, shift)
    assert metrics.path_length(moved) == pytest.approx(metrics.path_length(path), abs=1e-9)
    assert metrics.turning_angle_deg(moved) == pytest.approx(
        metrics.turning_angle_deg(path), abs=1e-6)
    keys = metrics.key_point_indices(path)
    assert keys[0] == 0 and keys[-1] == len(path) - 1
    assert np.all(np.diff(keys) > 0)
    # Dropping the non-key vertices changes neither length nor turning.
    if len(path) > 2:
        assert metrics.path_length(path[keys]) == pytest.approx(metrics.path_length(path))
        assert metrics.turning_angle_deg(path[keys]) == pytest.approx(
            metrics.turning_angle_deg(path), abs=1e-6)


def test_min_clearance_is_min_over_path_cells():
    rng = np.random.default_rng(4)
    occupied = rng.random((15, 15)) < 0.15
    grid = GridMap(occupied, resolution=0.2)
    for _ in range(20):
        path = rng.uniform(0.05, 2.95, size=(4, 2))
        cells = raster.path_cells(grid, path)
        expected = grid.clearance[cells[:, 0], cells[:, 1]].min()
        assert metrics.min_clearance(grid, path) == expected


def test_min_clearance_outside_and_empty_map():
    occupied = np.zeros((5, 5), bool)
    occupied[2, 4] = True
    grid = GridMap(occupied, resolution=1.0)
    assert metrics.min_clearance(grid, [[0.5, 0.5], [0.5, 4.5]]) == 4.0
    assert metrics.min_clearance(grid, [[0.5, 0.5], [-0.5, 0.5]]) == 0.0
    assert metrics.min_clearance(grid, [[3.5, 2.5], [4.5, 2.5]]) == 0.0  # through the obstacle
    empty = GridMap(np.zeros((5, 5), bool), resolution=1.0)
    assert metrics.min_clearance(empty, [[0.5, 0.5], [4.5, 4.5]]) == math.inf


@pytest.mark.parametrize('bad', [np.zeros((0, 2)), np.zeros((3,)), [[0, 0], [np.nan, 1]],
                                 [['a', 'b']]])
def test_bad_paths_raise(bad):
    with pytest.raises(InvalidInput):
        metrics.path_length(bad)
    with pytest.raises(InvalidInput):
        metrics.turning_angle_deg(bad)
    with pytest.raises(InvalidInput):
        metrics.key_point_indices(bad)
