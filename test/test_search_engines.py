"""The compiled search loop against the pure-Python one.

Both loops of :func:`~fusion_planner.core.global_planning.search.grid_search`
must give the same path, cost, expansion and generation counts for every
policy, on random maps and on structured ones (rooms with doors, mazes), and
stop at the same expansion budget. The pure-Python loop is itself checked
against an independent reference in test_search_properties.py, so equality
here carries the optimality of A*-8 and Dijkstra over to the compiled loop.
"""

import numpy as np
import pytest
from hypothesis import assume, given, settings
from hypothesis import strategies as st

from fusion_planner.bench.building_map import BuildingSpec, building_map
from fusion_planner.core.errors import InvalidInput, NoValidPathCouldBeFound, PlannerTimedOut
from fusion_planner.core.global_planning import kernel, search

pytestmark = pytest.mark.skipif(not kernel.AVAILABLE, reason='numba is not installed')

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


@pytest.mark.parametrize('name', sorted(POLICIES))
@ENGINE_SETTINGS
@given(scene=scenes())
def test_compiled_loop_matches_the_python_loop(name, scene):
    occupied, start, goal = scene
    compiled, python = _both(~occupied, start, goal, POLICIES[name])
    _assert_same(compiled, python)


@pytest.mark.parametrize('name', ('astar-8', 'improved-8', 'dijkstra-8'))
@settings(max_examples=60, deadline=None)
@given(scene=scenes(), budget=st.integers(1, 400))
def test_both_loops_stop_at_the_same_expansion_budget(name, scene, budget):
    occupied, start, goal = scene
    compiled, python = _both(~occupied, start, goal, POLICIES[name], max_expansions=budget)
    _assert_same(compiled, python)


def test_a_search_that_outgrows_the_initial_heap_is_unchanged():
    """More open nodes than the compiled loop's first heap holds."""
    free = np.ones((200, 200), bool)
    free[100, 1:] = False
    compiled, python = _both(free, (199, 199), (0, 199), search.dijkstra(8))
    _assert_same(compiled, python)
    assert compiled.generated > search._INITIAL_HEAP


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
