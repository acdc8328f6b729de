"""The fast paths of the planning core agree with their plain definitions.

- the engine's integer goal sector equals ``neighbourhood.sector_of``;
- the legal-move bitmasks equal the move rules checked cell by cell;
- the inflated mask from the bounded distance transform equals
  ``clearance > radius`` from the whole-map transform, bit for bit;
- clearance computed around given cells equals the whole-map clearance;
- the variable neighbourhood finds a path of the same cost as the full one
  under the same weight;
- the improved A*'s default weight keeps its cost within ``1 + gamma`` of
  the optimum.
"""

import contextlib
import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from scipy import ndimage

from fusion_planner.core import grid as grid_module
from fusion_planner.core import raster
from fusion_planner.core.global_planning import metrics, neighbourhood, search
from fusion_planner.core.errors import NoValidPathCouldBeFound
from fusion_planner.core.grid import GridMap

SETTINGS = settings(max_examples=120, deadline=None)


@st.composite
def occupancy(draw, max_side=28):
    height = draw(st.integers(1, max_side))
    width = draw(st.integers(1, max_side))
    density = draw(st.floats(0.0, 0.5))
    seed = draw(st.integers(0, 2 ** 31 - 1))
    return np.random.default_rng(seed).random((height, width)) < density


def test_integer_sector_matches_the_trigonometric_one():
    for d_row in range(-40, 41):
        for d_col in range(-40, 41):
            assert search._sector(d_row, d_col) == neighbourhood.sector_of(d_row, d_col)
    # Offsets whose angle is close to a sector border (22.5 + k * 45 deg).
    for d_row, d_col in ((408, 985), (-985, 408), (1393, 3363), (3363, -1393), (-2378, -985)):
        assert search._sector(d_row, d_col) == neighbourhood.sector_of(d_row, d_col)


@pytest.mark.parametrize('n', (4, 8, 16))
@SETTINGS
@given(occupied=occupancy())
def test_allowed_move_bits_follow_the_move_rules(n, occupied):
    free = ~occupied
    padded = search.PaddedGrid(free)
    bits = padded.allowed_moves(n)
    height, width = free.shape

    def is_free(r, c):
        return 0 <= r < height and 0 <= c < width and free[r, c]

    for r in range(height):
        for c in range(width):
            mask = bits[padded.index((r, c))]
            for i, (dr, dc, _, crossed) in enumerate(neighbourhood.moves(n)):
                legal = is_free(r + dr, c + dc) and all(is_free(r + a, c + b) for a, b in crossed)
                assert bool(mask >> i & 1) == legal


@SETTINGS
@given(occupied=occupancy(), resolution=st.sampled_from((0.05, 0.1, 0.3, 1.0)),
       radius_cells=st.floats(0.0, 6.0))
def test_bounded_inflation_equals_the_whole_map_transform(occupied, resolution, radius_cells):
    radius = radius_cells * resolution
    reference = GridMap(occupied, resolution).clearance > radius
    fresh = GridMap(occupied, resolution)  # no whole-map clearance yet
    assert np.array_equal(fresh.traversable(radius), reference)
    for exact in (resolution, math.sqrt(2) * resolution, 2 * resolution):
        assert np.array_equal(GridMap(occupied, resolution).traversable(exact),
                              GridMap(occupied, resolution).clearance > exact)


@SETTINGS
@given(occupied=occupancy(), resolution=st.sampled_from((0.05, 0.25, 1.0)))
def test_local_clearance_equals_the_whole_map(occupied, resolution):
    with _local_queries():
        _check_local_clearance(occupied, resolution)


def _check_local_clearance(occupied, resolution):
    whole = GridMap(occupied, resolution).clearance
    assert np.array_equal(whole[occupied], np.zeros(int(occupied.sum())))
    if occupied.any():
        unit = ndimage.distance_transform_edt(~occupied)
        np.testing.assert_allclose(whole, unit * resolution, rtol=1e-12)
    local = GridMap(occupied, resolution)
    cells = np.argwhere(np.ones(occupied.shape, bool))
    order = np.random.default_rng(0).permutation(len(cells))
    got = local.clearance_of_cells(cells[order])  # computed around the cells
    assert local._clearance is None  # the whole map was not needed
    assert np.array_equal(got, whole[cells[order, 0], cells[order, 1]])
    path = local.world_of(cells[order][:7])
    whole_map = GridMap(occupied, resolution)
    assert metrics.min_clearance(local, path) == metrics.min_clearance(whole_map, path)


@contextlib.contextmanager
def _local_queries():
    """Force the local clearance path on small maps (no whole-map fallback)."""
    saved = grid_module.SMALL_MAP_CELLS, grid_module.LOCAL_QUERY_MAX_WORK
    grid_module.SMALL_MAP_CELLS, grid_module.LOCAL_QUERY_MAX_WORK = 0, math.inf
    try:
        yield
    finally:
        grid_module.SMALL_MAP_CELLS, grid_module.LOCAL_QUERY_MAX_WORK = saved


def test_local_clearance_of_a_far_cell_on_a_wide_map():
    with _local_queries():
        _check_wide_map()


def _check_wide_map():
    occupied = np.zeros((3, 400), bool)
    occupied[0, 0] = True
    grid = GridMap(occupied, 0.5)
    got = grid.clearance_of_cells(np.array([[2, 399], [1, 1], [0, 0]]))
    np.testing.assert_array_equal(got, grid.clearance[[2, 1, 0], [399, 1, 0]])
    # Along row 2 (y = 1.25 m) over every column: nearest to the obstacle at (0, 0).
    expected = GridMap(occupied, 0.5).clearance[2].min()
    assert raster.segment_clearance(grid, (0.25, 1.25), (199.75, 1.25)) == expected == 1.0


@pytest.mark.parametrize('n, heuristic', ((8, 'euclidean'), (8, 'octile'), (16, 'euclidean')))
@SETTINGS
@given(occupied=occupancy(max_side=24), gamma=st.sampled_from((0.0, 0.2, 0.5)),
       data=st.data())
def test_variable_neighbourhood_costs_the_same_as_the_full_one(
        n, heuristic, occupied, gamma, data):
    free = ~occupied
    cells = np.argwhere(free)
    if len(cells) < 2:
        return
    start = tuple(int(v) for v in cells[data.draw(st.integers(0, len(cells) - 1))])
    goal = tuple(int(v) for v in cells[data.draw(st.integers(0, len(cells) - 1))])
    padded = search.PaddedGrid(free)
    results = []
    for variable in (True, False):
        policy = search.SearchPolicy(n, heuristic, 1.0, 1.0, gamma, variable)
        try:
            results.append(search.grid_search(padded, start, goal, policy).cost)
        except NoValidPathCouldBeFound:
            results.append(None)
    if results[0] is None:
        assert results[1] is None
    else:
        assert results[0] == pytest.approx(results[1], abs=1e-9)


@SETTINGS
@given(occupied=occupancy(max_side=24), data=st.data())
def test_default_improved_astar_is_within_its_weight_of_the_optimum(occupied, data):
    free = ~occupied
    cells = np.argwhere(free)
    if len(cells) < 2:
        return
    start = tuple(int(v) for v in cells[data.draw(st.integers(0, len(cells) - 1))])
    goal = tuple(int(v) for v in cells[data.draw(st.integers(0, len(cells) - 1))])
    padded = search.PaddedGrid(free)
    try:
        optimum = search.grid_search(padded, start, goal, search.astar(8)).cost
    except NoValidPathCouldBeFound:
        return
    policy = search.improved_astar()
    found = search.grid_search(padded, start, goal, policy).cost
    assert optimum - 1e-9 <= found <= (1.0 + policy.gamma) * optimum + 1e-9


def test_planning_a_large_map_needs_no_whole_clearance_map_and_replans_on_its_preparation():
    from fusion_planner.core.global_planning.planner import GlobalPlanner, PlannerConfig
    occupied = np.random.default_rng(3).random((400, 400)) < 0.03
    occupied[:3, :3] = occupied[-3:, -3:] = False
    grid = GridMap(occupied, 0.05)
    assert occupied.size > grid_module.SMALL_MAP_CELLS
    planner = GlobalPlanner(grid, PlannerConfig(robot_radius=0.05, safety_distance=0.05))
    first = planner.plan(grid.world_of((0, 0)), grid.world_of((399, 399)))
    prepared = planner._search_grid()
    second = planner.plan(grid.world_of((399, 399)), grid.world_of((0, 0)))
    assert planner._search_grid() is prepared  # same map and radius: reused
    assert grid._clearance is None  # inflation, refinement and metrics worked locally
    whole = GridMap(occupied, 0.05)
    for result in (first, second):
        assert result.metrics.min_clearance_m == metrics.min_clearance(whole, result.path)
        assert result.metrics.min_clearance_m > 0.05


@SETTINGS
@given(occupied=occupancy(), yaw=st.sampled_from((0.0, 0.7, -2.5)),
       seed=st.integers(0, 2 ** 31 - 1))
def test_clearance_at_points_equals_the_whole_map(occupied, yaw, seed):
    with _local_queries():
        grid = GridMap(occupied, 0.25, (1.0, -2.0, yaw))
        rng = np.random.default_rng(seed)
        corners = grid.grid_to_world(rng.uniform(-2, np.array(occupied.shape[::-1]) + 2,
                                                 (40, 2)))
        got = grid.clearance_at(corners)
        assert grid._clearance is None or not occupied.any()
        cells = grid.cell_of(corners)
        inside = grid.contains(cells)
        expected = np.zeros(len(cells))
        whole = GridMap(occupied, 0.25, (1.0, -2.0, yaw)).clearance
        expected[inside] = whole[cells[inside, 0], cells[inside, 1]]
        np.testing.assert_array_equal(got, expected)
        # The frame change and its inverse agree.
        np.testing.assert_allclose(grid.world_to_grid(corners),
                                   grid.world_to_grid(grid.grid_to_world(
                                       grid.world_to_grid(corners))), atol=1e-9)


def test_prepare_builds_everything_a_plan_needs_once():
    """After ``prepare`` a plan builds nothing: same grid, no new tables."""
    from fusion_planner.core.global_planning.planner import GlobalPlanner, PlannerConfig
    occupied = np.zeros((60, 80), bool)
    occupied[10:50, 40] = True
    grid = GridMap(occupied, 0.05)
    planner = GlobalPlanner(grid, PlannerConfig(robot_radius=0.1))
    assert planner.prepare() >= 0.0
    padded = planner._search_grid()
    built = (dict(padded._allowed), dict(padded._tables), dict(grid._traversable))
    planner.plan(grid.world_of((30, 5)), grid.world_of((30, 75)))
    assert planner._search_grid() is padded
    assert (padded._allowed, padded._tables, grid._traversable) == built
    planner.reconfigure(robot_radius=0.2)  # another inflation: prepared again
    planner.prepare()
    assert planner._search_grid() is not padded
    assert 0.2 in grid._traversable
