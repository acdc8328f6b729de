"""Tests of fusion_planner.core.global_planning.refine: redundant nodes and smoothing."""

import math

import numpy as np
import pytest
from hypothesis import HealthCheck, assume, given, settings
from hypothesis import strategies as st

from fusion_planner.core import raster
from fusion_planner.core.global_planning import metrics, refine, search
from fusion_planner.core.errors import InvalidInput, NoValidPathCouldBeFound
from fusion_planner.core.grid import GridMap

#: Slack for float comparisons of lengths [m] and angles [deg].
LENGTH_TOL = 1e-9
ANGLE_TOL = 1e-6


def _random_map(rng, size=40):
    """A map of random rectangles with a random resolution and origin."""
    occupied = np.zeros((size, size), bool)
    for _ in range(int(rng.integers(4, 14))):
        r, c = rng.integers(0, size, 2)
        h, w = rng.integers(1, size // 4, 2)
        occupied[r:r + h, c:c + w] = True
    occupied |= rng.random((size, size)) < 0.03
    resolution = float(rng.choice([0.05, 0.25, 1.0]))
    origin = (float(rng.uniform(-5, 5)), float(rng.uniform(-5, 5)), 0.0)
    return GridMap(occupied, resolution, origin)


def _case(seed):
    """(grid, raw path, robot radius, safety distance) or None if unreachable."""
    rng = np.random.default_rng(seed)
    grid = _random_map(rng)
    radius = float(rng.choice([0.0, 1.0, 1.5])) * grid.resolution
    safety = float(rng.choice([0.0, 1.0, 2.5])) * grid.resolution
    traversable = grid.traversable(radius)
    free = np.argwhere(traversable)
    if len(free) < 2:
        return None
    start, goal = free[rng.choice(len(free), 2, replace=False)]
    try:
        found = search.grid_search(search.PaddedGrid(traversable), tuple(start), tuple(goal),
                                   search.astar(8))
    except NoValidPathCouldBeFound:
        return None
    return grid, grid.world_of(found.cells), radius, safety


def _cases(count, first_seed=0):
    cases = []
    seed = first_seed
    while len(cases) < count and seed < first_seed + 20 * count:  # bounded
        case = _case(seed)
        seed += 1
        if case is not None and len(case[1]) > 2:
            cases.append(case)
    return cases


@pytest.fixture(scope='module')
def random_cases():
    cases = _cases(24)
    assert len(cases) == 24
    return cases


def _is_subsequence(sub, full):
    j = 0
    for point in sub:
        while j < len(full) and not np.array_equal(full[j], point):  # bounded by len(full)
            j += 1
        if j == len(full):
            return False
        j += 1
    return True


def _check_refinement(grid, raw, radius, safety, tolerate):
    """Assert every guarantee of prune + smooth; return (pruned, smoothed)."""
    spacing = grid.resolution / 2
    pruned = refine.prune_redundant(grid, raw, radius, safety, tolerate_input_margin=tolerate)
    smooth = refine.smooth_path(grid, pruned, radius, safety, spacing)
    # Endpoints exactly preserved.
    for path in (pruned, smooth):
        assert np.array_equal(path[0], raw[0]) and np.array_equal(path[-1], raw[-1])
    # Pruned nodes are input nodes, no more than the input's key points.
    assert _is_subsequence(pruned, raw)
    assert len(pruned) <= len(metrics.key_point_indices(raw))
    # Never longer, never more turning.
    assert metrics.path_length(pruned) <= metrics.path_length(raw) + LENGTH_TOL
    assert metrics.path_length(smooth) <= metrics.path_length(pruned) + LENGTH_TOL
    assert metrics.turning_angle_deg(smooth) <= metrics.turning_angle_deg(raw) + ANGLE_TOL
    # Safety: inside the map, clearance > radius, no worse than the input.
    raw_clearance = metrics.min_clearance(grid, raw)
    assert raw_clearance > radius  # the search path is traversable
    for path in (pruned, smooth):
        cells = raster.path_cells(grid, path)
        assert grid.contains(cells).all()
        clearance = metrics.min_clearance(grid, path)
        assert clearance > radius
        assert clearance >= min(raw_clearance, radius + safety)
    # Evenly sampled.
    assert np.hypot(*np.diff(smooth, axis=0).T).max() <= spacing + LENGTH_TOL
    return pruned, smooth


@pytest.mark.parametrize('tolerate', [False, True])
def test_refinement_guarantees_on_random_maps(random_cases, tolerate):
    raw_keys = raw_turn = pruned_keys = smooth_turn = 0
    shorter = 0
    for grid, raw, radius, safety in random_cases:
        pruned, smooth = _check_refinement(grid, raw, radius, safety, tolerate)
        raw_keys += len(metrics.key_point_indices(raw))
        pruned_keys += len(pruned)
        raw_turn += metrics.turning_angle_deg(raw)
        smooth_turn += metrics.turning_angle_deg(smooth)
        shorter += metrics.path_length(smooth) < metrics.path_length(raw) - LENGTH_TOL
    # On typical maps refinement removes key points and turning.
    assert pruned_keys < 0.8 * raw_keys
    assert smooth_turn < 0.8 * raw_turn
    assert shorter >= len(random_cases) // 2


@settings(max_examples=20, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(st.integers(1000, 10**6), st.booleans())
def test_refinement_guarantees_hypothesis(seed, tolerate):
    case = _case(seed)
    assume(case is not None and len(case[1]) > 2)
    _check_refinement(*case, tolerate)


def test_tolerating_the_input_margin_prunes_more(random_cases):
    strict = sum(len(refine.prune_redundant(g, p, r, s)) for g, p, r, s in random_cases)
    relaxed = sum(len(refine.prune_redundant(g, p, r, s, tolerate_input_margin=True))
                  for g, p, r, s in random_cases)
    assert relaxed <= strict


@pytest.mark.parametrize('tolerate', [False, True])
def test_window_reach_is_the_farthest_safe_node_of_each_window(random_cases, tolerate):
    # The batched reach against one segment test per (node, later node).
    window = refine.WINDOW_NODES
    for grid, raw, radius, safety in random_cases[:8]:
        gpts = grid.world_to_grid(raw)
        steps = raster.grid_segments_clearance(grid, gpts[:-1], gpts[1:])
        needed = refine._needed_clearance(steps, radius, safety, tolerate, window)
        reach = refine._window_reach(grid, gpts, radius, needed)
        last = len(raw) - 1
        for i in range(last):
            end = min(i + window, last)
            safe = [j for j in range(i + 1, end + 1)
                    if refine._is_safe(raster.segment_clearance(grid, raw[i], raw[j]), radius,
                                       min(radius + safety, steps[i:j].min()) if tolerate
                                       else radius + safety)]
            if end in safe and end < last:
                assert reach[i] == -1  # reachable past the window: looked up later
            else:
                assert reach[i] == (max(safe) if safe else i + 1)


def test_staircase_in_open_map_becomes_one_segment():
    grid = GridMap(np.zeros((10, 10), bool), resolution=0.5)
    cells = [[0, 0], [0, 1], [1, 1], [1, 2], [2, 2], [2, 3], [3, 3]]
    raw = grid.world_of(np.array(cells))
    pruned = refine.prune_redundant(grid, raw, 0.0, 0.5)
    assert np.array_equal(pruned, raw[[0, -1]])


def test_segment_is_safe_thresholds():
    occupied = np.zeros((7, 7), bool)
    occupied[3, 3] = True
    grid = GridMap(occupied, resolution=1.0)
    a, b = (0.5, 0.5), (6.5, 0.5)  # row 0; nearest cell (0, 3) is 3 m from the obstacle
    assert refine.segment_is_safe(grid, a, b, 0.0, 3.0)
    assert not refine.segment_is_safe(grid, a, b, 0.0, 3.01)
    assert refine.segment_is_safe(grid, a, b, 2.9, 0.0)
    assert not refine.segment_is_safe(grid, a, b, 3.0, 0.0)  # needs clearance > radius
    assert not refine.segment_is_safe(grid, a, (-0.5, 0.5), 0.0, 0.0)  # leaves the map
    with pytest.raises(InvalidInput):
        refine.segment_is_safe(grid, a, b, -1.0, 0.0)
    with pytest.raises(InvalidInput):
        refine.segment_is_safe(grid, a, b, 0.0, math.nan)


def _corridor():
    """A one-cell-wide L corridor: every cell is next to a wall."""
    occupied = np.ones((8, 8), bool)
    occupied[1, 1:7] = False
    occupied[1:7, 6] = False
    return GridMap(occupied, resolution=1.0)


def test_path_inside_the_safety_margin_keeps_its_steps():
    grid = _corridor()
    cells = [[1, c] for c in range(1, 7)] + [[r, 6] for r in range(2, 7)]
    raw = grid.world_of(np.array(cells))
    pruned = refine.prune_redundant(grid, raw, 0.0, 2.0)
    # Only the key points remain; no shortcut through the wall.
    assert np.array_equal(pruned, raw[metrics.key_point_indices(raw)])
    smooth = refine.smooth_path(grid, pruned, 0.0, 2.0, 0.5)
    assert metrics.min_clearance(grid, smooth) >= metrics.min_clearance(grid, raw)
    assert np.array_equal(smooth[0], raw[0]) and np.array_equal(smooth[-1], raw[-1])


def test_start_inside_inflation_uses_original_steps():
    occupied = np.zeros((9, 9), bool)
    occupied[0, 0] = True
    grid = GridMap(occupied, resolution=1.0)
    radius = 1.2  # cell (0, 1) has clearance 1: inside the inflation
    cells = [[0, 1], [1, 2], [2, 3], [3, 3], [4, 3], [5, 4], [6, 5], [7, 6]]
    raw = grid.world_of(np.array(cells))
    pruned = refine.prune_redundant(grid, raw, radius, 0.0)
    assert np.array_equal(pruned[:2], raw[:2])  # the first, unsafe step is kept as it was
    smooth = refine.smooth_path(grid, pruned, radius, 0.0, 0.5)
    # Apart from the first step, nothing touches a cell within the radius.
    rest = smooth[smooth[:, 0] >= raw[1, 0]]
    assert metrics.min_clearance(grid, rest) > radius
    assert len(pruned) < len(metrics.key_point_indices(raw))


def test_open_corner_is_rounded():
    grid = GridMap(np.zeros((20, 20), bool), resolution=1.0)
    nodes = np.array([[0.5, 0.5], [15.5, 0.5], [15.5, 15.5]])
    smooth = refine.smooth_path(grid, nodes, 0.0, 0.0, 0.5)
    d = np.diff(smooth, axis=0)
    heading = np.arctan2(d[:, 1], d[:, 0])
    assert np.abs(np.diff(heading)).max() <= math.radians(5.0) + 1e-9
    assert metrics.turning_angle_deg(smooth) == pytest.approx(90.0)
    assert metrics.path_length(smooth) < metrics.path_length(nodes)


def test_corner_next_to_obstacle_shrinks_or_stays_sharp():
    occupied = np.zeros((12, 12), bool)
    occupied[2:11, 1:10] = True  # a block filling the inside of the corner
    grid = GridMap(occupied, resolution=1.0)
    nodes = np.array([[0.5, 0.5], [10.5, 0.5], [10.5, 11.5]])
    smooth = refine.smooth_path(grid, nodes, 0.0, 0.0, 0.5)
    legs = metrics.min_clearance(grid, nodes)
    assert metrics.min_clearance(grid, smooth) >= legs
    assert metrics.path_length(smooth) <= metrics.path_length(nodes) + LENGTH_TOL
    # The corner point is cut by no more than a shrunken arc.
    assert np.hypot(*(smooth - nodes[1]).T).min() < 2.0


def test_degenerate_inputs():
    grid = GridMap(np.zeros((5, 5), bool), resolution=1.0)
    one = np.array([[1.5, 1.5]])
    assert np.array_equal(refine.prune_redundant(grid, one, 0.0, 0.0), one)
    assert np.array_equal(refine.smooth_path(grid, one, 0.0, 0.0, 0.5), one)
    same = np.array([[1.5, 1.5], [1.5, 1.5]])
    assert np.array_equal(refine.smooth_path(grid, same, 0.0, 0.0, 0.5), same)
    back = np.array([[0.5, 0.5], [3.5, 0.5], [1.5, 0.5]])  # a reversal stays sharp
    smooth = refine.smooth_path(grid, back, 0.0, 0.0, 0.5)
    assert np.array_equal(smooth[-1], back[-1])
    assert metrics.turning_angle_deg(smooth) == pytest.approx(180.0)


@pytest.mark.parametrize('spacing', [0.0, -1.0, math.inf, math.nan, 'x', True])
def test_bad_spacing_raises(spacing):
    grid = GridMap(np.zeros((5, 5), bool), resolution=1.0)
    with pytest.raises(InvalidInput):
        refine.smooth_path(grid, [[0.5, 0.5], [2.5, 2.5]], 0.0, 0.0, spacing)


def test_bad_points_raise():
    grid = GridMap(np.zeros((5, 5), bool), resolution=1.0)
    with pytest.raises(InvalidInput):
        refine.prune_redundant(grid, [[0.5, np.nan], [2.5, 2.5]], 0.0, 0.0)
    with pytest.raises(InvalidInput):
        refine.prune_redundant(grid, np.zeros((0, 2)), 0.0, 0.0)
    with pytest.raises(InvalidInput):
        refine.prune_redundant(grid, [[0.5, 0.5], [2.5, 2.5]], 0.0, -0.1)
