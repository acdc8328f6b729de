"""The compiled search loop against the pure-Python one, and jump points.

Both loops of :func:`~fusion_planner.core.global_planning.search.grid_search`
must give the same path, cost, expansion and generation counts for every
policy, on random maps and on structured ones (rooms with doors, mazes), and
stop at the same expansion budget. The pure-Python loop is itself checked
against an independent reference in test_search_properties.py, so equality
here carries the optimality of A*-8 and Dijkstra over to the compiled loop.

Jump-point pruning must find a path exactly when plain A*-8 does, at the
same cost, through legal 8-moves that cut no corner, on the same maps and
from starts inside the inflation.

Landmark bounds must leave the exact A* (4, 8, jump points) at the cost it
finds without them, from free starts and from starts inside the inflation,
with both loops giving the same result.
"""

import numpy as np
import pytest
from hypothesis import assume, given, settings
from hypothesis import strategies as st

from fusion_planner.bench.building_map import BuildingSpec, building_map
from fusion_planner.core.errors import (
    InvalidInput, NoValidPathCouldBeFound, PlannerCancelled, PlannerTimedOut)
from fusion_planner.core.global_planning import kernel, landmarks, search
from fusion_planner.core.global_planning.planner import GlobalPlanner, PlannerConfig
from fusion_planner.core.grid import GridMap

needs_numba = pytest.mark.skipif(not kernel.AVAILABLE, reason='numba is not installed')
#: The loops this machine can run.
ENGINES = search.ENGINES if kernel.AVAILABLE else ('python',)

#: Every policy the planner can run.
POLICIES = {
    'dijkstra-8': search.dijkstra(8),
    'dijkstra-4': search.dijkstra(4),
    'astar-4': search.astar(4),
    'astar-8': search.astar(8),
    'astar-8-euclidean': search.astar(8, 'euclidean'),
    'astar-16': search.astar(16),
    'improved-8': search.improved_astar(),
    'improved-8-octile-gamma0': search.improved_astar(gamma=0.0, heuristic='octile'),
    'improved-4': search.improved_astar(neighbourhood=4, heuristic='manhattan'),
    'improved-16': search.improved_astar(neighbourhood=16),
    'improved-weighted': search.improved_astar(alpha=0.7, beta=1.3, gamma=0.5),
}

ENGINE_SETTINGS = settings(max_examples=150, deadline=None)


def _both(free, start, goal, policy, **limits):
    """Results (or the exception type) of both loops on one padded grid each."""
    outcomes = []
    for engine in search.ENGINES:
        try:
            outcomes.append(search.grid_search(search.PaddedGrid(free), start, goal, policy,
                                               engine=engine, **limits))
        except (NoValidPathCouldBeFound, PlannerTimedOut) as err:
            outcomes.append(type(err))
    return outcomes


def _assert_same(compiled, python):
    if isinstance(python, type):
        assert compiled is python
        return
    assert not isinstance(compiled, type), f'compiled loop raised {compiled}'
    assert compiled.cells.tolist() == python.cells.tolist()
    assert compiled.cost == python.cost
    assert compiled.expanded == python.expanded
    assert compiled.generated == python.generated


@st.composite
def scenes(draw):
    """A random or structured small map and a free start and goal."""
    kind = draw(st.sampled_from(('random', 'rooms', 'maze')))
    seed = draw(st.integers(0, 2**32 - 1))
    rng = np.random.default_rng(seed)
    if kind == 'random':
        occupied = rng.random((draw(st.integers(1, 40)), draw(st.integers(1, 40)))) \
            < draw(st.floats(0.0, 0.6))
    elif kind == 'rooms':
        spec = BuildingSpec(side_m=draw(st.sampled_from((24.0, 36.0, 48.0))), room_m=12.0,
                            door_m=2.0, wall_m=1.0, resolution=1.0,
                            furniture_m=(1.0, 3.0), furniture_margin_m=1.0)
        occupied = building_map(spec, seed)
    else:
        occupied = _maze(draw(st.integers(2, 12)), rng)
    free_cells = np.argwhere(~occupied)
    assume(len(free_cells) > 0)
    start = tuple(int(v) for v in free_cells[draw(st.integers(0, len(free_cells) - 1))])
    goal = tuple(int(v) for v in free_cells[draw(st.integers(0, len(free_cells) - 1))])
    return occupied, start, goal


def _maze(cells, rng):
    """A perfect maze of ``cells`` x ``cells`` rooms, corridors one cell wide."""
    side = 2 * cells + 1
    occupied = np.ones((side, side), bool)
    occupied[1::2, 1::2] = False
    seen = {(0, 0)}
    stack = [(0, 0)]
    while stack:  # bounded: each room is pushed once
        r, c = stack[-1]
        options = [(r + dr, c + dc) for dr, dc in ((0, 1), (1, 0), (0, -1), (-1, 0))
                   if 0 <= r + dr < cells and 0 <= c + dc < cells and (r + dr, c + dc) not in seen]
        if not options:
            stack.pop()
            continue
        nr, nc = options[int(rng.integers(len(options)))]
        occupied[r + nr + 1, c + nc + 1] = False
        seen.add((nr, nc))
        stack.append((nr, nc))
    return occupied


@needs_numba
@pytest.mark.parametrize('name', sorted(POLICIES))
@ENGINE_SETTINGS
@given(scene=scenes())
def test_compiled_loop_matches_the_python_loop(name, scene):
    occupied, start, goal = scene
    compiled, python = _both(~occupied, start, goal, POLICIES[name])
    _assert_same(compiled, python)


@needs_numba
@pytest.mark.parametrize('name', ('astar-8', 'improved-8', 'dijkstra-8'))
@settings(max_examples=60, deadline=None)
@given(scene=scenes(), budget=st.integers(1, 400))
def test_both_loops_stop_at_the_same_expansion_budget(name, scene, budget):
    occupied, start, goal = scene
    compiled, python = _both(~occupied, start, goal, POLICIES[name], max_expansions=budget)
    _assert_same(compiled, python)


@needs_numba
def test_a_search_that_outgrows_the_initial_heap_is_unchanged():
    """More open nodes than the compiled loop's first heap holds."""
    free = np.ones((200, 200), bool)
    free[100, 1:] = False
    compiled, python = _both(free, (199, 199), (0, 199), search.dijkstra(8))
    _assert_same(compiled, python)
    assert compiled.generated > search._INITIAL_HEAP


@needs_numba
def test_search_reuses_its_grid_across_engines():
    free = ~building_map(BuildingSpec(side_m=24.0, room_m=12.0, door_m=2.0, wall_m=1.0,
                                      resolution=1.0, furniture_m=(1.0, 3.0),
                                      furniture_margin_m=1.0), seed=3)
    grid = search.PaddedGrid(free)
    grid.prepare(8)
    cells = np.argwhere(free)
    start, goal = tuple(cells[0]), tuple(cells[-1])
    first = search.grid_search(grid, start, goal, search.astar(8), engine='compiled')
    second = search.grid_search(grid, start, goal, search.astar(8), engine='python')
    third = search.grid_search(grid, start, goal, search.astar(8), engine='compiled')
    _assert_same(first, second)
    _assert_same(third, second)


def test_unknown_engine_is_refused():
    with pytest.raises(InvalidInput, match='engine'):
        search.grid_search(search.PaddedGrid(np.ones((3, 3), bool)), (0, 0), (2, 2),
                           search.astar(8), engine='fortran')


def _assert_legal(cells, start, goal, free):
    """Start and goal as asked; 8-moves onto free cells, no corner cut."""
    assert tuple(cells[0]) == tuple(start) and tuple(cells[-1]) == tuple(goal)
    steps = np.diff(cells, axis=0)
    assert (np.abs(steps).max(axis=1) == 1).all() if len(steps) else True
    for (r, c), (dr, dc) in zip(cells[:-1], steps):
        assert free[r + dr, c + dc]
        if dr and dc:
            assert free[r + dr, c] and free[r, c + dc], 'a corner was cut'


@pytest.mark.parametrize('heuristic', ('octile', 'euclidean', 'zero'))
@ENGINE_SETTINGS
@given(scene=scenes())
def test_jump_points_find_the_plain_astar_cost(heuristic, scene):
    occupied, start, goal = scene
    free = ~occupied
    grid = search.PaddedGrid(free)
    plain = search.SearchPolicy(heuristic=heuristic)
    jumping = search.SearchPolicy(heuristic=heuristic, jump_points=True)
    try:
        expected = search.grid_search(grid, start, goal, plain).cost
    except NoValidPathCouldBeFound:
        with pytest.raises(NoValidPathCouldBeFound):
            search.grid_search(grid, start, goal, jumping)
        return
    found = search.grid_search(grid, start, goal, jumping)
    assert found.cost == pytest.approx(expected, abs=1e-9)
    _assert_legal(found.cells, start, goal, free)
    steps = np.abs(np.diff(found.cells, axis=0)).sum(axis=1)
    assert found.cost == pytest.approx(float(np.where(steps == 2, np.sqrt(2.0), 1.0).sum()),
                                       abs=1e-9)


@ENGINE_SETTINGS
@given(scene=scenes(), seed=st.integers(0, 2**32 - 1))
def test_jump_points_leave_a_blocked_start_by_the_shortest_way(scene, seed):
    """A start that is not traversable (inside the inflation) is left as A*-8 leaves it."""
    occupied, _, goal = scene
    free = ~occupied
    blocked = np.argwhere(occupied)
    assume(len(blocked) > 0)
    start = tuple(int(v) for v in blocked[np.random.default_rng(seed).integers(len(blocked))])
    grid = search.PaddedGrid(free)
    try:
        expected = search.grid_search(grid, start, goal, search.astar(8)).cost
    except NoValidPathCouldBeFound:
        with pytest.raises(NoValidPathCouldBeFound):
            search.grid_search(grid, start, goal, search.astar(8, jump_points=True))
        return
    found = search.grid_search(grid, start, goal, search.astar(8, jump_points=True))
    assert found.cost == pytest.approx(expected, abs=1e-9)
    _assert_legal(found.cells[1:], found.cells[1], goal, free)


@pytest.mark.parametrize('engine', ENGINES)
def test_jump_points_respect_the_limits(engine):
    free = np.ones((300, 300), bool)
    free[150, :-2] = False
    grid = search.PaddedGrid(free)
    policy = search.astar(8, jump_points=True)
    with pytest.raises(PlannerTimedOut):
        search.grid_search(grid, (0, 0), (299, 0), policy, max_expansions=1, engine=engine)
    with pytest.raises(PlannerCancelled):
        search.grid_search(grid, (0, 0), (299, 0), policy, cancel=lambda: True, engine=engine)
    found = search.grid_search(grid, (0, 0), (299, 0), policy, engine=engine)
    assert found.expanded < 100  # jump points, not cells
    assert search.grid_search(grid, (5, 5), (5, 5), policy).cells.tolist() == [[5, 5]]


def test_jump_points_need_the_fixed_8_neighbourhood():
    with pytest.raises(InvalidInput, match='jump points'):
        search.astar(4, jump_points=True)
    with pytest.raises(InvalidInput, match='jump points'):
        search.SearchPolicy(variable_neighbourhood=True, jump_points=True)


def test_a_numba_that_fails_to_import_falls_back_to_python(monkeypatch):
    """numba found but broken: the search still answers, then runs in Python."""
    import sys
    monkeypatch.setattr(kernel, 'AVAILABLE', True)
    monkeypatch.setattr(kernel, '_compiled', False)
    monkeypatch.setitem(sys.modules, 'numba', None)  # import numba raises ImportError
    free = np.ones((30, 30), bool)
    free[15, :-2] = False
    grid = search.PaddedGrid(free)
    grid.prepare(8)
    assert kernel.AVAILABLE is False
    found = search.grid_search(grid, (0, 0), (29, 0), search.astar(8))
    expected = search.grid_search(grid, (0, 0), (29, 0), search.astar(8), engine='python')
    _assert_same(found, expected)
    jumped = search.grid_search(grid, (0, 0), (29, 0), search.astar(8, jump_points=True))
    assert jumped.cost == pytest.approx(expected.cost, abs=1e-9)


LANDMARK_POLICIES = {
    'astar-4': search.astar(4, landmarks=True),
    'astar-8': search.astar(8, landmarks=True),
    'astar-8-euclidean': search.astar(8, 'euclidean', landmarks=True),
    'jump-points': search.astar(8, jump_points=True, landmarks=True),
}


@needs_numba
@pytest.mark.parametrize('name', sorted(LANDMARK_POLICIES))
@settings(max_examples=80, deadline=None)
@given(scene=scenes(), count=st.integers(1, 4), blocked_start=st.booleans(),
       seed=st.integers(0, 2**32 - 1))
def test_landmarks_keep_astar_exact(name, scene, count, blocked_start, seed):
    occupied, start, goal = scene
    free = ~occupied
    if blocked_start and occupied.any():
        blocked = np.argwhere(occupied)
        start = tuple(int(v) for v in blocked[np.random.default_rng(seed).integers(len(blocked))])
    policy = LANDMARK_POLICIES[name]
    bounded = search.PaddedGrid(free)
    bounded.landmarks = landmarks.distance_table(bounded, count)
    outcomes = []
    for engine in search.ENGINES:
        try:
            outcomes.append(search.grid_search(bounded, start, goal, policy, engine=engine))
        except NoValidPathCouldBeFound as err:
            outcomes.append(type(err))
    try:
        expected = search.grid_search(search.PaddedGrid(free), start, goal, policy)
    except NoValidPathCouldBeFound:
        assert outcomes == [NoValidPathCouldBeFound] * 2
        return
    _assert_same(*outcomes)
    found = outcomes[0]
    assert found.cost == pytest.approx(expected.cost, abs=1e-9)
    assert tuple(found.cells[0]) == start and tuple(found.cells[-1]) == goal


def test_landmarks_need_the_exact_astar_with_4_or_8_neighbours():
    for bad in (dict(neighbourhood=16), dict(heuristic='zero'), dict(gamma=0.2),
                dict(variable_neighbourhood=True), dict(alpha=0.5)):
        with pytest.raises(InvalidInput, match='landmarks'):
            search.SearchPolicy(landmarks=True, **bad)


def test_landmarks_sit_in_the_largest_component_and_span_it():
    free = np.ones((30, 40), bool)
    free[:, 10] = False  # a 10-column strip on the left, the rest on the right
    grid = search.PaddedGrid(free)
    table = landmarks.distance_table(grid, 3)
    assert table.shape == (len(grid.passable), 3)
    right = grid.index((15, 30))
    left = grid.index((15, 2))
    assert np.isfinite(table[right]).all() and np.isinf(table[left]).all()
    sites = [grid.cells(np.flatnonzero(table[:, i] == 0)).tolist() for i in range(3)]
    corners = [[0, 11], [0, 39], [29, 11], [29, 39]]
    assert all(len(site) == 1 and site[0] in corners for site in sites), sites
    assert len({tuple(site[0]) for site in sites}) == 3
    assert landmarks.distance_table(search.PaddedGrid(np.zeros((4, 4), bool))) is None


@needs_numba
def test_prepare_gives_landmarks_to_the_exact_astar_on_small_maps_only(monkeypatch):
    grid = GridMap(np.random.default_rng(1).random((60, 60)) < 0.2, 0.1)
    for config, expected in ((PlannerConfig(algorithm='astar'), True),
                             (PlannerConfig(algorithm='astar', jump_points=False), True),
                             (PlannerConfig(algorithm='improved'), False),
                             (PlannerConfig(algorithm='dijkstra'), False),
                             (PlannerConfig(algorithm='astar', neighbourhood=16), False),
                             (PlannerConfig(algorithm='astar', landmarks=False), False)):
        planner = GlobalPlanner(grid, config)
        planner.prepare()
        assert (planner._padded.landmarks is not None) == expected, config
    monkeypatch.setattr(landmarks, 'MAX_CELLS', 60 * 60 - 1)
    planner = GlobalPlanner(grid, PlannerConfig(algorithm='astar'))
    planner.prepare()
    assert planner._padded.landmarks is None
