"""Property tests of the search engine against an independent reference.

Every planner (Dijkstra, A* with 4-, 8- and 16-neighbourhoods, the improved
A*) runs on random small maps and is compared with
``scipy.sparse.csgraph.dijkstra`` on a graph built here from the move rules
alone (nothing of :mod:`fusion_planner.core.global_planning.neighbourhood` is used):

- a path is found exactly when the reference reaches the goal;
- the optimal planners' costs equal the reference distance, the improved
  A*'s cost is at least the reference and within a loose weight bound;
- every path starts and ends where asked, enters no blocked (or inflated)
  cell, and each step is a move of the neighbourhood that cuts no corner;
- refined paths keep their clearance, keep their ends and are not longer
  than the grid path;
- the limits: an expansion budget, a time budget, cancellation, start == goal.

Jump-point pruning is one of the optimal planners here; test_search_engines.py
checks it on structured maps (rooms, mazes) as well.
"""

from dataclasses import replace
import math
from fractions import Fraction

import numpy as np
import pytest
from hypothesis import assume, given, settings
from hypothesis import strategies as st
from scipy.sparse import csr_matrix
from scipy.sparse.csgraph import dijkstra as csgraph_dijkstra

from fusion_planner.core.global_planning import metrics, search
from fusion_planner.core.errors import (
    NoValidPathCouldBeFound, PlannerCancelled, PlannerTimedOut)
from fusion_planner.core.grid import GridMap
from fusion_planner.core.global_planning.planner import GlobalPlanner, PlannerConfig

#: Largest side of a random map [cells].
MAX_SIDE = 30
#: Slack of cost comparisons [cells]: sums of 1 and sqrt(2) in another order.
COST_TOL = 1e-9
#: Slack of length and position comparisons [m].
LENGTH_TOL = 1e-9
#: Loose bound on the improved A*'s cost over the optimum for gamma <= 1
#: (the heuristic weight w_n of eqs. (6)-(8) is 1 + gamma (e - 1) ~ 2.72 at
#: the start distance).
IMPROVED_COST_BOUND = 2.8

#: Hypothesis budgets: bounded, no per-example deadline (CI machines vary).
PROPERTY_SETTINGS = settings(max_examples=200, deadline=None)
SLOW_PROPERTY_SETTINGS = settings(max_examples=150, deadline=None)

#: Planners with an optimality guarantee: name -> (neighbourhood, policy).
OPTIMAL_PLANNERS = {
    'dijkstra-4': (4, search.dijkstra(4)),
    'dijkstra-8': (8, search.dijkstra(8)),
    'dijkstra-16': (16, search.dijkstra(16)),
    'astar-4-manhattan': (4, search.astar(4)),
    'astar-8-octile': (8, search.astar(8)),
    'astar-8-euclidean': (8, search.astar(8, 'euclidean')),
    'astar-16-euclidean': (16, search.astar(16)),
    'jump-points-8-octile': (8, search.astar(8, jump_points=True)),
    'jump-points-8-euclidean': (8, search.astar(8, 'euclidean', jump_points=True)),
    'jump-points-dijkstra-8': (8, search.SearchPolicy(heuristic='zero', jump_points=True)),
}

#: The improved A* per neighbourhood, with an admissible heuristic each.
IMPROVED_HEURISTIC = {4: 'manhattan', 8: 'octile', 16: 'euclidean'}


# ---------------------------------------------------------------------------
# The independent reference: move rules and a scipy shortest-path graph
# ---------------------------------------------------------------------------

def _reference_steps(neighbourhood):
    """``(d_row, d_col)`` steps of a 4-, 8- or 16-neighbourhood."""
    steps = [(dr, dc) for dr in (-1, 0, 1) for dc in (-1, 0, 1) if abs(dr) + abs(dc) == 1]
    if neighbourhood >= 8:
        steps += [(dr, dc) for dr in (-1, 1) for dc in (-1, 1)]
    if neighbourhood == 16:
        steps += [(dr, dc) for dr in (-2, -1, 1, 2) for dc in (-2, -1, 1, 2)
                  if abs(dr) != abs(dc)]
    return steps


def _touched_cells(d_row, d_col):
    """Cells whose closed square the segment between two cell centres touches.

    Cell ``(r, c)`` is the square ``[r - 1/2, r + 1/2] x [c - 1/2, c + 1/2]``;
    the segment runs from the centre of ``(0, 0)`` to that of
    ``(d_row, d_col)``. Exact (fractions), by the slab test. A diagonal step
    touches both orthogonal neighbours at their shared corner, so requiring
    every touched cell free is exactly "no corner cutting"; a knight step
    (1, 2) touches (0, 1) and (1, 1).
    """
    half = Fraction(1, 2)
    touched = []
    for r in range(min(0, d_row), max(0, d_row) + 1):
        for c in range(min(0, d_col), max(0, d_col) + 1):
            lo, hi = Fraction(0), Fraction(1)
            for centre, delta in ((r, d_row), (c, d_col)):
                if delta == 0:
                    if abs(centre) > half:
                        lo, hi = Fraction(1), Fraction(0)
                    continue
                a = (centre - half) / delta
                b = (centre + half) / delta
                lo, hi = max(lo, min(a, b)), min(hi, max(a, b))
            if lo <= hi:
                touched.append((r, c))
    return touched


def _reference_moves(neighbourhood):
    """``(d_row, d_col, cost, crossed)`` with ``crossed`` the touched cells
    other than the source and the target."""
    moves = []
    for dr, dc in _reference_steps(neighbourhood):
        crossed = [cell for cell in _touched_cells(dr, dc) if cell not in ((0, 0), (dr, dc))]
        moves.append((dr, dc, math.hypot(dr, dc), crossed))
    return moves


def _reference_distances(free, start, neighbourhood):
    """Shortest-path costs [cells] from ``start`` to every cell, shape (H, W).

    A step from a cell needs its target and every cell it crosses free; the
    source itself is not checked, so a start inside the inflation can be
    left (as the planner documents). ``inf`` where unreachable.
    """
    h, w = free.shape
    pad = 2
    padded = np.zeros((h + 2 * pad, w + 2 * pad), bool)
    padded[pad:pad + h, pad:pad + w] = free
    rows, cols = np.mgrid[0:h, 0:w]
    sources, targets, weights = [], [], []
    for dr, dc, cost, crossed in _reference_moves(neighbourhood):
        ok = padded[rows + dr + pad, cols + dc + pad].copy()
        for cr, cc in crossed:
            ok &= padded[rows + cr + pad, cols + cc + pad]
        src_r, src_c = rows[ok], cols[ok]
        sources.append(src_r * w + src_c)
        targets.append((src_r + dr) * w + src_c + dc)
        weights.append(np.full(src_r.size, cost))
    edges = (np.concatenate(sources), np.concatenate(targets))
    graph = csr_matrix((np.concatenate(weights), edges), shape=(h * w, h * w))
    dist = csgraph_dijkstra(graph, directed=True, indices=start[0] * w + start[1])
    return dist.reshape(h, w)


def _assert_valid_path(cells, start, goal, free, neighbourhood):
    """Ends, free cells (the start exempt), legal steps, no corner cutting;
    returns the path cost [cells]."""
    cells = np.asarray(cells)
    assert cells.ndim == 2 and cells.shape[1] == 2 and len(cells) >= 1
    assert tuple(cells[0]) == tuple(start), 'path does not start at the start cell'
    assert tuple(cells[-1]) == tuple(goal), 'path does not end at the goal cell'
    h, w = free.shape
    moves = {(dr, dc): (cost, crossed)
             for dr, dc, cost, crossed in _reference_moves(neighbourhood)}
    total = 0.0
    for (r0, c0), (r1, c1) in zip(cells[:-1].tolist(), cells[1:].tolist()):
        step = (r1 - r0, c1 - c0)
        assert step in moves, f'step {step} at cell {(r0, c0)} is not a {neighbourhood}-move'
        assert 0 <= r1 < h and 0 <= c1 < w and free[r1, c1], f'path enters blocked cell {(r1, c1)}'
        cost, crossed = moves[step]
        for cr, cc in crossed:
            r, c = r0 + cr, c0 + cc
            assert 0 <= r < h and 0 <= c < w and free[r, c], (
                f'step {step} from {(r0, c0)} cuts the corner of blocked cell {(r, c)}')
        total += cost
    return total


def test_reference_moves_follow_the_stated_rules():
    """The reference derives the crossed cells the issue states."""
    moves = {(dr, dc): sorted(crossed) for dr, dc, _, crossed in _reference_moves(16)}
    assert len(moves) == 16
    assert moves[(0, 1)] == [] and moves[(-1, 0)] == []
    assert moves[(1, 1)] == [(0, 1), (1, 0)]
    assert moves[(-1, 1)] == [(-1, 0), (0, 1)]
    assert moves[(1, 2)] == [(0, 1), (1, 1)]
    assert moves[(-1, -2)] == [(-1, -1), (0, -1)]
    assert moves[(2, 1)] == [(1, 0), (1, 1)]
    assert moves[(-2, 1)] == [(-1, 0), (-1, 1)]


def test_reference_distances_on_a_hand_made_map():
    """A wall with a diagonal gap: no corner cutting, the detour is measured."""
    free = np.ones((3, 3), bool)
    free[0, 1] = free[1, 0] = False
    dist = _reference_distances(free, (0, 0), 8)
    assert np.isinf(dist[1, 1])  # the diagonal squeezes between two blocks
    assert np.isinf(dist[2, 2])  # (0, 0) is walled in
    free[1, 0] = True
    dist = _reference_distances(free, (0, 0), 8)
    assert dist[1, 1] == pytest.approx(2.0)
    assert dist[2, 2] == pytest.approx(2.0 + math.sqrt(2.0))


# ---------------------------------------------------------------------------
# Random maps
# ---------------------------------------------------------------------------

@st.composite
def random_maps(draw, max_side=MAX_SIDE):
    """An occupancy array with random density and a free start and goal."""
    height = draw(st.integers(1, max_side))
    width = draw(st.integers(1, max_side))
    density = draw(st.floats(0.0, 0.6))
    seed = draw(st.integers(0, 2**32 - 1))
    occupied = np.random.default_rng(seed).random((height, width)) < density
    free_cells = np.argwhere(~occupied)
    assume(len(free_cells) > 0)
    start = tuple(int(v) for v in free_cells[draw(st.integers(0, len(free_cells) - 1))])
    goal = tuple(int(v) for v in free_cells[draw(st.integers(0, len(free_cells) - 1))])
    return occupied, start, goal


def _search_or_none(free, start, goal, policy):
    try:
        return search.grid_search(search.PaddedGrid(free), start, goal, policy)
    except NoValidPathCouldBeFound:
        return None


@pytest.mark.parametrize('name', sorted(OPTIMAL_PLANNERS))
@PROPERTY_SETTINGS
@given(scene=random_maps())
def test_optimal_planner_matches_reference(name, scene):
    """Found exactly when reachable, optimal cost, a legal path."""
    neighbourhood, policy = OPTIMAL_PLANNERS[name]
    occupied, start, goal = scene
    free = ~occupied
    reference = _reference_distances(free, start, neighbourhood)[goal]
    found = _search_or_none(free, start, goal, policy)
    assert (found is not None) == np.isfinite(reference), (
        f'{name}: found={found is not None} but the reference distance is {reference}')
    if found is None:
        return
    assert found.cost == pytest.approx(reference, abs=COST_TOL)
    step_sum = _assert_valid_path(found.cells, start, goal, free, neighbourhood)
    assert found.cost == pytest.approx(step_sum, abs=COST_TOL)
    assert found.expanded <= found.generated


@pytest.mark.parametrize('neighbourhood', (4, 8, 16))
@PROPERTY_SETTINGS
@given(scene=random_maps(), gamma=st.floats(0.0, 1.0))
def test_improved_astar_is_complete_and_bounded(neighbourhood, scene, gamma):
    """The improved A* finds a path exactly when one exists, never below the
    optimum and within a loose weight bound of it."""
    occupied, start, goal = scene
    free = ~occupied
    policy = search.improved_astar(gamma=gamma, neighbourhood=neighbourhood,
                                   heuristic=IMPROVED_HEURISTIC[neighbourhood])
    reference = _reference_distances(free, start, neighbourhood)[goal]
    found = _search_or_none(free, start, goal, policy)
    assert (found is not None) == np.isfinite(reference)
    if found is None:
        return
    step_sum = _assert_valid_path(found.cells, start, goal, free, neighbourhood)
    assert found.cost == pytest.approx(step_sum, abs=COST_TOL)
    assert found.cost >= reference - COST_TOL
    assert found.cost <= IMPROVED_COST_BOUND * reference + COST_TOL, (
        f'improved A* cost {found.cost:.4f} exceeds {IMPROVED_COST_BOUND} x optimum '
        f'{reference:.4f} (gamma={gamma})')


@pytest.mark.parametrize('neighbourhood', (4, 8, 16))
@PROPERTY_SETTINGS
@given(scene=random_maps())
def test_planner_config_default_improved_astar(neighbourhood, scene):
    """The improved A* as configured by default (only the neighbourhood
    varied) is complete and never below the optimum."""
    occupied, start, goal = scene
    free = ~occupied
    policy = PlannerConfig(neighbourhood=neighbourhood, refine=False).policy()
    reference = _reference_distances(free, start, neighbourhood)[goal]
    found = _search_or_none(free, start, goal, policy)
    assert (found is not None) == np.isfinite(reference)
    if found is not None:
        _assert_valid_path(found.cells, start, goal, free, neighbourhood)
        assert found.cost >= reference - COST_TOL


# ---------------------------------------------------------------------------
# Inflation
# ---------------------------------------------------------------------------

@st.composite
def inflated_maps(draw):
    """A GridMap, an inflation radius, a start off the obstacles (possibly
    inside the inflation) and a goal outside the inflation."""
    occupied, _, _ = draw(random_maps())
    resolution = draw(st.sampled_from((0.05, 0.1, 0.5, 1.0)))
    radius = draw(st.floats(0.0, 2.5)) * resolution
    grid = GridMap(occupied, resolution)
    traversable = grid.traversable(radius)
    starts = np.argwhere(~occupied)
    goals = np.argwhere(traversable)
    assume(len(goals) > 0)
    start = tuple(int(v) for v in starts[draw(st.integers(0, len(starts) - 1))])
    goal = tuple(int(v) for v in goals[draw(st.integers(0, len(goals) - 1))])
    return grid, radius, start, goal


INFLATION_PLANNERS = {
    'dijkstra-8': (8, search.dijkstra(8)),
    'astar-4-manhattan': (4, search.astar(4)),
    'astar-8-octile': (8, search.astar(8)),
    'astar-8-planner-default': (8, PlannerConfig(algorithm='astar', refine=False).policy()),
    'astar-16-euclidean': (16, search.astar(16)),
    'improved-8': (8, PlannerConfig(refine=False).policy()),
}


@pytest.mark.parametrize('name', sorted(INFLATION_PLANNERS))
@PROPERTY_SETTINGS
@given(case=inflated_maps())
def test_inflated_search_stays_out_of_the_inflation(name, case):
    """With a radius, no path cell but the start has clearance <= radius, and
    a path is found exactly when one exists on the inflated grid (leaving a
    start that lies inside the inflation is allowed)."""
    neighbourhood, policy = INFLATION_PLANNERS[name]
    grid, radius, start, goal = case
    traversable = grid.traversable(radius)
    reference = _reference_distances(traversable, start, neighbourhood)[goal]
    found = _search_or_none(traversable, start, goal, policy)
    assert (found is not None) == np.isfinite(reference), (
        f'{name}: found={found is not None}, reference distance {reference}, start {start} '
        f'clearance {grid.clearance[start]:.3f} m, radius {radius:.3f} m')
    if found is None:
        return
    cells = found.cells
    clearance = grid.clearance[cells[1:, 0], cells[1:, 1]]
    assert np.all(clearance > radius), 'a path cell lies inside the inflation'
    _assert_valid_path(cells, start, goal, traversable, neighbourhood)
    if not policy.variable_neighbourhood:
        assert found.cost == pytest.approx(reference, abs=COST_TOL)


@pytest.mark.parametrize('name', sorted(INFLATION_PLANNERS))
def test_start_inside_the_inflation_is_left_by_the_shortest_way(name):
    """A start one cell from a wall, inside a 1-cell inflation: the planner
    must step straight away from the wall, as the reference does."""
    neighbourhood, policy = INFLATION_PLANNERS[name]
    occupied = np.zeros((6, 5), bool)
    occupied[0, 2] = True
    grid = GridMap(occupied, 1.0)
    traversable = grid.traversable(1.0)
    start, goal = (1, 2), (4, 2)
    assert not traversable[start] and traversable[goal]
    reference = _reference_distances(traversable, start, neighbourhood)[goal]
    assert reference == pytest.approx(3.0)
    found = _search_or_none(traversable, start, goal, policy)
    assert found is not None, f'{name} found no way out of a start inside the inflation'
    _assert_valid_path(found.cells, start, goal, traversable, neighbourhood)
    assert found.cost == pytest.approx(reference, abs=COST_TOL)


# ---------------------------------------------------------------------------
# Refined paths (GlobalPlanner)
# ---------------------------------------------------------------------------

@st.composite
def refine_cases(draw):
    """A GridMap with a random origin, a robot radius, a safety distance, an
    algorithm, and a start and goal outside the inflation."""
    occupied, _, _ = draw(random_maps(max_side=24))
    resolution = draw(st.sampled_from((0.05, 0.25, 1.0)))
    origin = (draw(st.floats(-5.0, 5.0)), draw(st.floats(-5.0, 5.0)),
              draw(st.one_of(st.just(0.0), st.floats(-math.pi, math.pi))))
    grid = GridMap(occupied, resolution, origin)
    robot_radius = draw(st.floats(0.0, 1.5)) * resolution
    safety = draw(st.floats(0.0, 2.0)) * resolution
    algorithm = draw(st.sampled_from(('dijkstra', 'astar', 'improved')))
    neighbourhood = draw(st.sampled_from((4, 8, 16)))
    cells = np.argwhere(grid.traversable(robot_radius))
    assume(len(cells) > 0)
    start = tuple(int(v) for v in cells[draw(st.integers(0, len(cells) - 1))])
    goal = tuple(int(v) for v in cells[draw(st.integers(0, len(cells) - 1))])
    config = PlannerConfig(algorithm=algorithm, neighbourhood=neighbourhood, refine=True,
                           robot_radius=robot_radius, safety_distance=safety)
    return grid, config, start, goal


@SLOW_PROPERTY_SETTINGS
@given(case=refine_cases())
def test_refined_paths_keep_clearance_ends_and_length(case):
    """Refined and centred paths: clearance > robot radius, exact ends at
    the cell centres; refined alone, never longer than the grid path."""
    grid, config, start, goal = case
    planner = GlobalPlanner(grid, config)
    start_xy, goal_xy = grid.world_of(np.array([start, goal]))
    reachable = np.isfinite(_reference_distances(
        grid.traversable(config.robot_radius), start, config.neighbourhood)[goal])
    if not reachable:
        with pytest.raises(NoValidPathCouldBeFound):
            planner.plan(start_xy, goal_xy)
        return
    result = planner.plan(start_xy, goal_xy)
    path = result.path
    assert path.ndim == 2 and path.shape[1] == 2 and np.all(np.isfinite(path))
    np.testing.assert_allclose(path[0], start_xy, rtol=0, atol=LENGTH_TOL)
    np.testing.assert_allclose(path[-1], goal_xy, rtol=0, atol=LENGTH_TOL)
    clearance = metrics.min_clearance(grid, path)
    assert clearance > config.robot_radius, (
        f'refined path clearance {clearance:.4f} m <= robot radius {config.robot_radius:.4f} m')
    assert result.metrics.min_clearance_m > config.robot_radius
    assert result.metrics.length_m == pytest.approx(metrics.path_length(path), abs=LENGTH_TOL)
    # Centring (on by default) trades length for clearance; refinement alone never lengthens.
    refined = GlobalPlanner(grid, replace(config, centre=False)).plan(start_xy, goal_xy).path
    assert (metrics.path_length(refined)
            <= metrics.path_length(result.grid_path) + LENGTH_TOL * max(1.0, len(refined)))


# ---------------------------------------------------------------------------
# Limits
# ---------------------------------------------------------------------------

#: Side of the open map the limit tests search across [cells]; its far
#: corner needs many more expansions than the engine's check interval.
BIG_SIDE = 200

ALL_POLICIES = dict(OPTIMAL_PLANNERS, **{
    f'improved-{n}': (n, search.improved_astar(neighbourhood=n, heuristic=IMPROVED_HEURISTIC[n]))
    for n in (4, 8, 16)})


def _big_open_grid():
    """A wide map with a wall to walk around, so every planner works hard."""
    free = np.ones((BIG_SIDE, BIG_SIDE), bool)
    free[BIG_SIDE // 2, :-2] = False
    return search.PaddedGrid(free)


@pytest.mark.parametrize('name', sorted(ALL_POLICIES))
def test_tiny_expansion_budget_times_out(name):
    _, policy = ALL_POLICIES[name]
    with pytest.raises(PlannerTimedOut):
        search.grid_search(_big_open_grid(), (0, 0), (BIG_SIDE - 1, 0), policy, max_expansions=1)


@pytest.mark.parametrize('name', sorted(ALL_POLICIES))
def test_cancel_stops_the_search(name):
    _, policy = ALL_POLICIES[name]
    with pytest.raises(PlannerCancelled):
        search.grid_search(_big_open_grid(), (0, 0), (BIG_SIDE - 1, 0), policy,
                           cancel=lambda: True)


def test_zero_time_budget_times_out():
    with pytest.raises(PlannerTimedOut):
        search.grid_search(_big_open_grid(), (0, 0), (BIG_SIDE - 1, 0), search.dijkstra(8),
                           time_limit_s=0.0)


def test_generous_limits_do_not_stop_a_search():
    calls = []
    found = search.grid_search(_big_open_grid(), (0, 0), (BIG_SIDE - 1, 0), search.astar(8),
                               max_expansions=BIG_SIDE ** 2 + 1, time_limit_s=600.0,
                               cancel=lambda: calls.append(1) and False)
    assert tuple(found.cells[-1]) == (BIG_SIDE - 1, 0)


@pytest.mark.parametrize('name', sorted(ALL_POLICIES))
def test_start_equal_goal_is_a_one_cell_path(name):
    _, policy = ALL_POLICIES[name]
    free = np.ones((5, 7), bool)
    found = search.grid_search(search.PaddedGrid(free), (2, 3), (2, 3), policy)
    assert found.cells.tolist() == [[2, 3]]
    assert found.cost == 0.0


@pytest.mark.parametrize('refine', (False, True))
def test_planner_start_equal_goal(refine):
    grid = GridMap(np.zeros((6, 6), bool), 0.5, (1.0, -2.0, 0.0))
    centre = grid.world_of(np.array([3, 2]))
    result = GlobalPlanner(grid, PlannerConfig(refine=refine)).plan(centre, centre)
    assert len(result.path) == 1
    np.testing.assert_allclose(result.path[0], centre)
    assert result.metrics.length_m == 0.0
