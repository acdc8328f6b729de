"""Our planners beside peer grid path planners: time, path length, memory.

Runs our Dijkstra, A*-8 and improved A* (without and with refinement)
beside pyastar2d (C++), tcod's path-finding (C), pathfinding (pure Python),
python-motion-planning (Python with numba helpers) and networkx, on sampled
rows of the MovingAI maps, a 1024 x 1024 map with 20 % random obstacles
(corner to corner), Nav2's planner benchmarking protocol (2000 x 2000
maps at 0.05 m with 10, 15 and 20 % obstacles, 100 start/goal pairs at least
3 m apart, robot-radius inflation) and generated building floors (4000 x
4000 at 0.05 m, rooms of 20 m with 1.5 m doors and furniture, robot radius
0.2 m, pairs at least 100 m apart; ours beside pyastar2d and tcod only),
and prints per map and planner the
median planning time, expansions where known, path length over the optimum
of the same corner rule, the time to prepare the map, and (with --memory)
the peak memory.

Notes
-----
- Peers are the optional ``bench`` extra (``pip install
  'fusion_planner[bench]'``); a peer asked for (``--planners``, default all)
  that does not import stops the run before it starts, with one line naming
  the extra. They never become runtime dependencies: each is imported
  inside its adapter.
- The MovingAI suite reads the maps of ``bench movingai``; when they are
  absent and the suites were not chosen (``--suites``), the other suites
  run and a note says why MovingAI was left out.
- Corner rule and cost model (:data:`PLANNERS`): ours, tcod (configured
  with a diagonal condition), pathfinding (``only_when_no_obstacle``),
  python-motion-planning (``strict_collision``) and networkx (the graph
  built here) never cut a corner and price a diagonal at sqrt 2, so their
  optimum is the MovingAI ``optimal_length`` / our A*-8 cost. pyastar2d
  cuts corners and prices a diagonal at 1 (Chebyshev); its paths are
  measured in Euclidean length against the optimum *with* corner cutting
  (computed with tcod's integer A*, costs 10000 / 14142, within 2e-5 of the
  exact value, or scipy's Dijkstra when tcod is missing). tcod's costs are
  integers (10000 / 14142), so its paths may be longer than the float
  optimum by that rounding.
- Path length is the Euclidean length of the returned cell path [cells];
  the refined path of our improved A* is any-angle and smoothed, so it is
  usually *shorter* than the grid optimum (ratio < 1). It counts as valid
  when its grid path is and every cell it touches is clear of the
  inflation (``min_clearance_m`` above the robot radius).
- Time is the wall time and the CPU time of the planning call alone; the
  map preparation (our map object, inflation, padded grid and move tables;
  a peer's graph or grid object) is timed once per map and reported apart
  ("prep", CPU; the JSON has its wall time too).
  Medians over the pairs of a map. The CPU time is the steadier figure on a
  loaded machine.
- Nav2's protocol (``tools/planner_benchmarking/metrics.py`` of
  navigation2): 100 random pairs per map, seed 33, a 100-cell side buffer,
  start and goal outside the inflation and more than 3 m apart, a pair kept
  only when a path exists. Their 100 m x 100 m maps are not distributed as
  arrays here, so ours are generated: axis-aligned rectangular obstacles
  with sides of 0.25 to 1 m placed at random until the occupied fraction
  reaches the density; the robot radius is Nav2's default 0.22 m.
- Pure-Python peers are slow on big maps: each planner has a time budget per
  map (``--budget``) after which its remaining pairs are skipped (and
  counted), and networkx is skipped on maps over
  :data:`NETWORKX_MAX_CELLS` cells (its graph needs gigabytes there).
- ``--memory`` runs every (map, planner) once more in a fresh process and
  reports its peak resident set size (``VmHWM``) and the increase over a
  process that only builds the map. The ``big`` suite plans on a
  4000 x 4000 map of the Nav2 kind with our default planner and A*-8 and
  always measures memory that way.
"""

import json
import math
import os
import pathlib
import statistics
import subprocess
import sys
import time
from dataclasses import asdict, dataclass, field, replace

import numpy as np
from scipy import ndimage

from fusion_planner.bench import movingai as movingai_bench
from fusion_planner.bench.building_map import BuildingSpec, building_map, far_pairs
from fusion_planner.cli.output_paths import prepare_file
from fusion_planner.cli.progress import Progress
from fusion_planner.cli.requirements import require
from fusion_planner.core.global_planning import kernel, metrics
from fusion_planner.core.errors import (
    InvalidInput, MapError, NoValidPathCouldBeFound, PlannerTimedOut)
from fusion_planner.core.grid import GridMap
from fusion_planner.core.map_files import load_movingai, movingai_cell, read_scenarios
from fusion_planner.core.global_planning.planner import GlobalPlanner, PlannerConfig

EXIT_OK, EXIT_FAILED, EXIT_BAD_INPUT = 0, 1, 2

SUITES = ('movingai', 'random', 'nav2', 'big', 'building')
DEFAULT_SUITES = ('movingai', 'random', 'nav2')

#: Side [cells], obstacle fraction and seed of the random map.
RANDOM_SIDE = 1024
RANDOM_DENSITY = 0.2
RANDOM_SEED = 20240501
#: Timed repeats of the single corner-to-corner pair of the random map.
RANDOM_REPEATS = 5
#: Random start/goal pairs on the same map (no target: the landmark
#: bounds of the exact A* help most corner to corner, so these show how
#: it fares elsewhere), more than half the map's side apart, and the
#: suffix of that scenario's name.
RANDOM_PAIRS = 20
RANDOM_PAIRS_SUFFIX = '-pairs'

#: Nav2's protocol: map side [cells], resolution [m], densities, pairs per
#: map, seed, side buffer [cells], least start-goal distance [m], robot
#: radius [m] (nav2_params.yaml's default).
NAV2_SIDE = 2000
NAV2_RESOLUTION = 0.05
NAV2_DENSITIES = (0.10, 0.15, 0.20)
NAV2_PAIRS = 100
NAV2_SEED = 33
NAV2_SIDE_BUFFER = 100
NAV2_MIN_DISTANCE_M = 3.0
NAV2_ROBOT_RADIUS = 0.22
#: Side range [m] of the generated rectangular obstacles.
NAV2_OBSTACLE_SIDE_M = (0.25, 1.0)
#: Draws of a start/goal pair before a map is declared unusable.
MAX_PAIR_DRAWS = 100_000

#: The big-map memory target: side [cells] and density.
BIG_SIDE = 4000
BIG_DENSITY = 0.2

#: The building floors (:mod:`building_map`): seeds (one map each), pairs
#: per map, least start-goal distance [m], robot radius [m]; quick mode's
#: floor side [m]. Only our planners and the compiled peers run on them.
BUILDING_SEEDS = (1, 2, 3)
BUILDING_PAIRS = 2
BUILDING_MIN_DISTANCE_M = 100.0
BUILDING_ROBOT_RADIUS = 0.2
QUICK_BUILDING_SIDE_M = 40.0
QUICK_BUILDING_MIN_DISTANCE_M = 15.0
COMPILED_PEERS = ('pyastar2d', 'tcod')

#: MovingAI rows per map by default (sampled evenly over the buckets).
DEFAULT_MOVINGAI_ROWS = 10
#: Per planner and map: once its planning time exceeds this [s], the rest of
#: its pairs are skipped.
DEFAULT_BUDGET_S = 120.0
#: networkx needs roughly 2 kB per cell of graph; above this many cells it
#: is skipped.
NETWORKX_MAX_CELLS = 1_100_000
#: Integer costs of tcod's graphs: orthogonal and diagonal step.
TCOD_ORTHOGONAL = 10_000
TCOD_DIAGONAL = 14_142
#: Largest accepted gap between an "optimal" planner's length and the
#: optimum [cells], for sums of 1 and sqrt 2 in another order.
OPTIMAL_TOLERANCE = 1e-6
#: Quick mode (tests): sides [cells], pairs and rows.
QUICK_RANDOM_SIDE = 64
QUICK_RANDOM_PAIRS = 2
QUICK_NAV2_SIDE = 160
QUICK_NAV2_PAIRS = 3
QUICK_NAV2_SIDE_BUFFER = 10
QUICK_MOVINGAI_ROWS = 2
QUICK_BIG_SIDE = 200

#: Targets on the median planning CPU time of the improved A* and A*-8 over
#: pyastar2d's on the same inflated grid: on the random map, and on the
#: building floors and the MovingAI maps whose name holds one of
#: :data:`STRUCTURED_MAPS` (walls that force detours).
TARGET_OVER_PYASTAR_RANDOM = 1.0
TARGET_OVER_PYASTAR_STRUCTURED = 2.0
STRUCTURED_MAPS = ('maze', 'room')
TARGET_IMPROVED_LENGTH_RATIO = 1.03
TARGET_PREP_S = 0.5
TARGET_BIG_MEMORY_MB = 1024.0
ROOT2 = math.sqrt(2.0)


@dataclass(frozen=True)
class PlannerInfo:
    """What a planner is and which rules its paths follow.

    Attributes
    ----------
    name, label : str
    kind : str
        ``'ours'`` or ``'peer'``.
    language : str
        What its search loop runs in.
    cuts_corners : bool
        True when a diagonal step may pass between two blocked cells.
    cost_model : str
        How steps are priced.
    optimal : bool
        Whether its paths must equal the optimum of its corner rule.
    package : str
        pip name of a peer (``''`` for ours).
    """

    name: str
    label: str
    kind: str
    language: str
    cuts_corners: bool
    cost_model: str
    optimal: bool
    package: str = ''


#: What our search loop runs in (:mod:`kernel`).
OUR_LOOP = 'numba' if kernel.AVAILABLE else 'Python'

#: Every planner of the benchmark, in table order.
PLANNERS = {
    'dijkstra': PlannerInfo('dijkstra', 'ours Dijkstra', 'ours', OUR_LOOP, False,
                            'octile: 1 / sqrt 2', True),
    'astar': PlannerInfo('astar', 'ours A*-8', 'ours', OUR_LOOP, False,
                         'octile: 1 / sqrt 2, octile h', True),
    'jps': PlannerInfo('jps', 'ours A*-8 jump points', 'ours', OUR_LOOP, False,
                       'octile: 1 / sqrt 2, octile h', True),
    'improved': PlannerInfo('improved', 'ours improved A*', 'ours', OUR_LOOP, False,
                            'octile: 1 / sqrt 2, weighted Euclidean h', False),
    'improved_refined': PlannerInfo('improved_refined', 'ours improved+refine', 'ours', OUR_LOOP,
                                    False, 'any-angle after refinement', False),
    'pyastar2d': PlannerInfo('pyastar2d', 'pyastar2d', 'peer', 'C++', True,
                             'Chebyshev: diagonal 1, L-inf h', False, 'pyastar2d'),
    'tcod': PlannerInfo('tcod', 'tcod A*', 'peer', 'C', False,
                        'integer 10000 / 14142, octile h', True, 'tcod'),
    'pathfinding': PlannerInfo('pathfinding', 'pathfinding A*', 'peer', 'Python', False,
                               'octile: 1 / sqrt 2, octile h', True, 'pathfinding'),
    'pmp': PlannerInfo('pmp', 'python-motion-planning A*', 'peer', 'Python+numba', False,
                       'Euclidean steps, Euclidean h', True, 'python-motion-planning'),
    'networkx': PlannerInfo('networkx', 'networkx A*', 'peer', 'Python', False,
                            'octile: 1 / sqrt 2, octile h', True, 'networkx'),
}
OURS = tuple(name for name, info in PLANNERS.items() if info.kind == 'ours')
PEERS = tuple(name for name, info in PLANNERS.items() if info.kind == 'peer')
PURE_PYTHON_PEERS = ('pathfinding', 'pmp', 'networkx')


@dataclass
class Scenario:
    """One map and its start/goal pairs.

    Attributes
    ----------
    suite, name : str
    occupied : ndarray of bool, shape (H, W)
        The obstacles (before inflation).
    resolution : float
        Cell edge [m].
    robot_radius : float
        Inflation radius [m] of every planner.
    pairs : list of tuple
        ``((row, col) start, (row, col) goal)``.
    optimal : list of float or None
        Optimum without corner cutting per pair [cells], when known before
        running (MovingAI).
    spec : dict
        How to rebuild this scenario in another process (``--memory``).
    description : str
    """

    suite: str
    name: str
    occupied: np.ndarray
    resolution: float
    robot_radius: float
    pairs: list
    optimal: list = None
    spec: dict = field(default_factory=dict)
    description: str = ''


@dataclass
class Row:
    """Figures of one planner on one scenario.

    Attributes
    ----------
    suite, scenario, planner : str
    pairs : int
        Pairs attempted (the others were skipped by the budget).
    skipped : int
        Pairs skipped by the time budget.
    found : int
        Paths returned.
    valid : int
        Paths that start and end where asked, use 8-moves on free cells and
        follow the planner's corner rule.
    optimal_exact : int or None
        For the optimal planners: paths within :data:`OPTIMAL_TOLERANCE`
        of the optimum of their corner rule.
    ratio_median, ratio_max : float
        Path length over the optimum of the same corner rule.
    time_median_ms, cpu_median_ms : float
        Planning call, wall and CPU time [ms].
    expanded_median : float or None
        Expanded nodes, when the planner reports them.
    prep_s, prep_wall_s : float
        Map preparation (once per map), CPU and wall time [s].
    peak_rss_mb, peak_rss_over_map_mb : float or None
        With ``--memory``: peak resident set size of a fresh process that
        plans the first pair, and its increase over one that only builds the
        map [MB].
    note : str
    cpu_ms : list of float
        CPU time of each attempted pair, in pair order [ms].
    """

    suite: str
    scenario: str
    planner: str
    pairs: int = 0
    skipped: int = 0
    found: int = 0
    valid: int = 0
    optimal_exact: int = None
    ratio_median: float = math.nan
    ratio_max: float = math.nan
    time_median_ms: float = math.nan
    cpu_median_ms: float = math.nan
    expanded_median: float = None
    prep_s: float = math.nan
    prep_wall_s: float = math.nan
    peak_rss_mb: float = None
    peak_rss_over_map_mb: float = None
    note: str = ''
    cpu_ms: list = field(default_factory=list)


# ---------------------------------------------------------------------------
# Maps and pairs
# ---------------------------------------------------------------------------

def random_map(side, density, seed):
    """Random obstacles, cell by cell, with the two corners kept open.

    Parameters
    ----------
    side : int
        Map side [cells].
    density : float
        Probability that a cell is an obstacle, in [0, 1).
    seed : int

    Returns
    -------
    ndarray of bool, shape (side, side)
        True where occupied; the 2 x 2 blocks at cells (0, 0) and
        (side - 1, side - 1) are free.
    """
    occupied = np.random.default_rng(seed).random((side, side)) < density
    occupied[:2, :2] = False
    occupied[-2:, -2:] = False
    return occupied


def nav2_map(side, density, resolution, seed):
    """A map of Nav2's benchmark kind: random rectangles up to a density.

    Parameters
    ----------
    side : int
        Map side [cells].
    density : float
        Occupied fraction to reach, in [0, 0.9].
    resolution : float
        Cell edge [m]; the rectangle sides are :data:`NAV2_OBSTACLE_SIDE_M`.
    seed : int

    Returns
    -------
    ndarray of bool, shape (side, side)
    """
    rng = np.random.default_rng(seed)
    lo, hi = (max(1, round(v / resolution)) for v in NAV2_OBSTACLE_SIDE_M)
    occupied = np.zeros((side, side), bool)
    mean_area = ((lo + hi) / 2) ** 2
    for _ in range(side * side):  # bounded: each batch adds cells
        missing = density - occupied.mean()
        if missing <= 0:
            break
        # About half of the rectangles still needed, so the density is not overshot.
        batch = max(1, int(missing * side * side / mean_area / 2))
        sizes = rng.integers(lo, hi + 1, size=(batch, 2))
        corners = rng.integers(0, side, size=(batch, 2))
        for (h, w), (r, c) in zip(sizes.tolist(), corners.tolist()):
            occupied[r:r + h, c:c + w] = True
    return occupied


def nav2_pairs(traversable, count, resolution, seed, side_buffer, min_distance_m, reachable):
    """Start/goal pairs as Nav2's ``metrics.py`` draws them.

    Parameters
    ----------
    traversable : ndarray of bool, shape (H, W)
        Cells outside the inflation.
    count : int
        Pairs wanted.
    resolution : float
        Cell edge [m].
    seed : int
    side_buffer : int
        Cells kept clear of the map border.
    min_distance_m : float
        Least start-goal distance [m] (strictly more).
    reachable : callable
        ``reachable(start, goal) -> bool``; pairs without a path are drawn
        again (Nav2 drops pairs where a planner fails).

    Returns
    -------
    list of tuple
        ``((row, col), (row, col))``.

    Raises
    ------
    MapError
        If :data:`MAX_PAIR_DRAWS` draws give too few pairs.
    """
    rng = np.random.default_rng(seed)
    height, width = traversable.shape
    pairs = []
    for _ in range(MAX_PAIR_DRAWS):  # bounded
        if len(pairs) == count:
            return pairs
        upper = (height - side_buffer, width - side_buffer)
        start = tuple(int(v) for v in rng.integers(side_buffer, upper))
        goal = tuple(int(v) for v in rng.integers(side_buffer, upper))
        if not (traversable[start] and traversable[goal]):
            continue
        if math.dist(start, goal) * resolution <= min_distance_m:
            continue
        if reachable(start, goal):
            pairs.append((start, goal))
    raise MapError(f'only {len(pairs)} of {count} start/goal pairs found in {MAX_PAIR_DRAWS} draws')


def build_scenario(spec):
    """Rebuild a scenario from its spec (also in a ``--memory`` child).

    Parameters
    ----------
    spec : dict
        ``{'suite': 'random', 'side', 'density', 'seed', 'repeats'}`` (corner
        to corner) or with ``'pairs'`` instead of ``'repeats'`` (random pairs),
        ``{'suite': 'nav2' or 'big', 'side', 'density', 'seed', 'pairs',
        'side_buffer'}``, ``{'suite': 'building', 'side_m', 'seed', 'pairs',
        'min_distance_m'}`` or ``{'suite': 'movingai', 'map', 'scen', 'rows'}``.

    Returns
    -------
    Scenario
    """
    suite = spec['suite']
    if suite == 'random' and 'pairs' in spec:
        occupied = random_map(spec['side'], spec['density'], spec['seed'])
        side = spec['side']
        labels, _ = ndimage.label(~occupied)  # 4-connected: what 8-moves without corner cutting reach
        pairs = nav2_pairs(~occupied, spec['pairs'], 1.0, spec['seed'], 0, side // 2,
                           lambda start, goal: labels[start] == labels[goal])
        return Scenario('random', f'random{side}{RANDOM_PAIRS_SUFFIX}', occupied, 1.0, 0.0,
                        pairs, spec=spec,
                        description=f'the same map, {spec["pairs"]} random pairs more than '
                                    f'{side // 2} cells apart')
    if suite == 'random':
        occupied = random_map(spec['side'], spec['density'], spec['seed'])
        side = spec['side']
        pair = ((0, 0), (side - 1, side - 1))
        return Scenario('random', f'random{side}', occupied, 1.0, 0.0,
                        [pair] * spec['repeats'], spec=spec,
                        description=f'{side} x {side}, {100 * spec["density"]:.0f} % random '
                                    f'cells, corner to corner x {spec["repeats"]} repeats')
    if suite in ('nav2', 'big'):
        side = spec['side']
        occupied = nav2_map(side, spec['density'], NAV2_RESOLUTION, spec['seed'])
        grid = GridMap(occupied, NAV2_RESOLUTION)
        planner = GlobalPlanner(grid, PlannerConfig(algorithm='astar', refine=False,
                                                    robot_radius=NAV2_ROBOT_RADIUS))

        def reachable(start, goal):
            try:
                planner.plan(grid.world_of(start), grid.world_of(goal))
            except NoValidPathCouldBeFound:
                return False
            return True

        if 'pair_cells' in spec:  # pairs found by the parent (memory probes)
            pairs = [tuple(tuple(cell) for cell in pair) for pair in spec['pair_cells']]
        elif suite == 'big':
            pairs = [_corner_pair(grid.traversable(NAV2_ROBOT_RADIUS), reachable)]
        else:
            pairs = nav2_pairs(grid.traversable(NAV2_ROBOT_RADIUS), spec['pairs'],
                               NAV2_RESOLUTION, spec['seed'], spec['side_buffer'],
                               NAV2_MIN_DISTANCE_M, reachable)
        name = (f'nav2-{100 * spec["density"]:.0f}%' if suite == 'nav2'
                else f'big{side}-{100 * spec["density"]:.0f}%')
        return Scenario(suite, name, occupied, NAV2_RESOLUTION, NAV2_ROBOT_RADIUS, pairs,
                        spec=spec,
                        description=f'{side} x {side} at {NAV2_RESOLUTION} m, '
                                    f'{100 * spec["density"]:.0f} % rectangles, '
                                    f'robot radius {NAV2_ROBOT_RADIUS} m, {len(pairs)} pairs')
    if suite == 'building':
        floor = BuildingSpec(side_m=spec['side_m'])
        occupied = building_map(floor, spec['seed'])
        if 'pair_cells' in spec:
            pairs = [tuple(tuple(cell) for cell in pair) for pair in spec['pair_cells']]
        else:
            traversable = GridMap(occupied, floor.resolution).traversable(BUILDING_ROBOT_RADIUS)
            pairs = far_pairs(traversable, spec['pairs'],
                              spec['min_distance_m'] / floor.resolution, spec['seed'])
        side = occupied.shape[0]
        return Scenario('building', f'building{side}-s{spec["seed"]}', occupied,
                        floor.resolution, BUILDING_ROBOT_RADIUS, pairs, spec=spec,
                        description=f'{side} x {side} at {floor.resolution} m, rooms of '
                                    f'{floor.room_m:g} m, doors of {floor.door_m:g} m, '
                                    f'furniture, robot radius {BUILDING_ROBOT_RADIUS} m, '
                                    f'{len(pairs)} pairs at least {spec["min_distance_m"]:g} m '
                                    'apart')
    if suite == 'movingai':
        grid = load_movingai(spec['map'])
        rows = read_scenarios(spec['scen'])
        chosen = [rows[i] for i in movingai_bench.sample_rows(rows, spec['rows'])]
        height = grid.shape[0]
        pairs = [(movingai_cell(r.start_col, r.start_row, height),
                  movingai_cell(r.goal_col, r.goal_row, height)) for r in chosen]
        name = pathlib.Path(spec['map']).stem
        return Scenario('movingai', name, grid.occupied, 1.0, 0.0, pairs,
                        optimal=[r.optimal_length for r in chosen], spec=spec,
                        description=f'{grid.shape[1]} x {grid.shape[0]}, {len(pairs)} rows')
    raise InvalidInput(f'unknown suite {suite!r}')


def _corner_pair(traversable, reachable):
    """A reachable pair of free cells near opposite corners (big suite)."""
    height, width = traversable.shape
    starts = _free_cells_from(traversable, 0, 0, 1, 1)
    goals = _free_cells_from(traversable, height - 1, width - 1, -1, -1)
    for start, goal in zip(starts, goals):  # bounded: a few cells of each corner
        if reachable(start, goal):
            return start, goal
    raise MapError('no corner-to-corner pair found on the big map')


def _free_cells_from(traversable, row, col, d_row, d_col, count=16):
    """Up to ``count`` free cells on the anti-diagonals nearest a corner."""
    height, width = traversable.shape
    found = []
    for k in range(height + width - 1):  # bounded: anti-diagonals
        for i in range(max(0, k - width + 1), min(k, height - 1) + 1):
            cell = (row + d_row * i, col + d_col * (k - i))
            if traversable[cell]:
                found.append(cell)
                if len(found) == count:
                    return found
    return found


def scenario_specs(suites, args):
    """The specs of every scenario of the chosen suites, in run order."""
    quick = args.quick
    specs = []
    if 'movingai' in suites:
        folder = pathlib.Path(args.maps) if args.maps else movingai_bench.default_data_dir()
        rows = QUICK_MOVINGAI_ROWS if quick else args.rows
        for s in movingai_bench.find_scenario_sets(folder, None, args.only):
            specs.append({'suite': 'movingai', 'map': str(s.map_path), 'scen': str(s.scen_path),
                          'rows': rows})
    if 'random' in suites:
        specs.append({'suite': 'random', 'side': QUICK_RANDOM_SIDE if quick else RANDOM_SIDE,
                      'density': RANDOM_DENSITY, 'seed': RANDOM_SEED,
                      'repeats': 1 if quick else RANDOM_REPEATS})
        specs.append({'suite': 'random', 'side': QUICK_RANDOM_SIDE if quick else RANDOM_SIDE,
                      'density': RANDOM_DENSITY, 'seed': RANDOM_SEED,
                      'pairs': QUICK_RANDOM_PAIRS if quick else RANDOM_PAIRS})
    if 'nav2' in suites:
        for density in NAV2_DENSITIES:
            specs.append({'suite': 'nav2', 'side': QUICK_NAV2_SIDE if quick else NAV2_SIDE,
                          'density': density, 'seed': NAV2_SEED,
                          'pairs': QUICK_NAV2_PAIRS if quick else args.pairs,
                          'side_buffer': QUICK_NAV2_SIDE_BUFFER if quick else NAV2_SIDE_BUFFER})
    if 'big' in suites:
        specs.append({'suite': 'big', 'side': QUICK_BIG_SIDE if quick else BIG_SIDE,
                      'density': BIG_DENSITY, 'seed': NAV2_SEED, 'pairs': 1, 'side_buffer': 0})
    if 'building' in suites:
        for seed in BUILDING_SEEDS[:1] if quick else BUILDING_SEEDS:
            specs.append({'suite': 'building',
                          'side_m': QUICK_BUILDING_SIDE_M if quick else BuildingSpec().side_m,
                          'seed': seed, 'pairs': 1 if quick else BUILDING_PAIRS,
                          'min_distance_m': (QUICK_BUILDING_MIN_DISTANCE_M if quick
                                             else BUILDING_MIN_DISTANCE_M)})
    return specs


# ---------------------------------------------------------------------------
# Paths
# ---------------------------------------------------------------------------

def path_length_cells(cells):
    """Euclidean length [cells] of a cell path, shape (N, 2)."""
    cells = np.asarray(cells, dtype=float)
    if len(cells) < 2:
        return 0.0
    return float(np.hypot(*np.diff(cells, axis=0).T).sum())


def is_valid_path(cells, start, goal, free, cuts_corners):
    """Whether a cell path is legal on ``free`` under a corner rule.

    Parameters
    ----------
    cells : array_like of int, shape (N, 2)
        ``(row, col)``.
    start, goal : tuple of int
    free : ndarray of bool, shape (H, W)
    cuts_corners : bool
        False: a diagonal step needs both orthogonal neighbours free.

    Returns
    -------
    bool
        Ends as asked, every step one of the 8 moves, every cell after the
        start free, and the corner rule kept.
    """
    cells = np.asarray(cells, dtype=np.int64).reshape(-1, 2)
    if len(cells) == 0 or tuple(cells[0]) != tuple(start) or tuple(cells[-1]) != tuple(goal):
        return False
    height, width = free.shape
    rest = cells[1:]
    if np.any((rest < 0) | (rest >= (height, width))):
        return False
    if not free[rest[:, 0], rest[:, 1]].all():
        return False
    step = np.diff(cells, axis=0)
    if np.any(np.abs(step).max(axis=1, initial=1) != 1):
        return False
    if not cuts_corners and len(step):
        diagonal = (step[:, 0] != 0) & (step[:, 1] != 0)
        src = cells[:-1][diagonal]
        d = step[diagonal]
        if not (free[src[:, 0] + d[:, 0], src[:, 1]].all()
                and free[src[:, 0], src[:, 1] + d[:, 1]].all()):
            return False
    return True


def cutting_optimum(free, start, goal):
    """Shortest Euclidean length [cells] of an 8-connected path that may cut
    corners, or inf.

    Uses tcod's integer A* (costs 10000 / 14142; within 2e-5 of exact) when
    tcod is installed, else scipy's Dijkstra on the cell graph (exact,
    slower).
    """
    try:
        import tcod  # noqa: F401
    except ImportError:
        return _csgraph_optimum(free, start, goal, cut_corners=True)
    cells = _tcod_path(_tcod_graph(free, no_corner_cutting=False), start, goal)
    return math.inf if cells is None else path_length_cells(cells)


def _csgraph_optimum(free, start, goal, cut_corners):
    """Exact shortest 8-connected path length [cells] with scipy, or inf."""
    from scipy.sparse import csr_matrix
    from scipy.sparse.csgraph import dijkstra
    height, width = free.shape
    padded = np.pad(free, 1, constant_values=False)
    rows, cols = np.nonzero(free)
    src, dst, weight = [], [], []
    for dr in (-1, 0, 1):
        for dc in (-1, 0, 1):
            if dr == dc == 0:
                continue
            ok = padded[rows + dr + 1, cols + dc + 1].copy()
            if dr and dc and not cut_corners:
                ok &= padded[rows + dr + 1, cols + 1] & padded[rows + 1, cols + dc + 1]
            src.append(rows[ok] * width + cols[ok])
            dst.append((rows[ok] + dr) * width + cols[ok] + dc)
            weight.append(np.full(int(ok.sum()), math.hypot(dr, dc)))
    graph = csr_matrix((np.concatenate(weight), (np.concatenate(src), np.concatenate(dst))),
                       shape=(height * width, height * width))
    dist = dijkstra(graph, indices=start[0] * width + start[1])
    return float(dist[goal[0] * width + goal[1]])


# ---------------------------------------------------------------------------
# Planner adapters: prepare(free, scenario) once per map, plan(start, goal)
# ---------------------------------------------------------------------------

class _Ours:
    """Our GlobalPlanner; it inflates the raw map itself."""

    def __init__(self, name):
        self.name = name
        self.grid = None
        self.planner = None
        self.last = None  # PlanResult of the last plan

    def refined_is_safe(self):
        """Whether the last refined path touches only cells clear of the inflation.

        Its grid path is checked like every planner's; the any-angle path
        that refinement made of it is checked here: every cell it touches
        must have a clearance above the robot radius
        (:func:`~fusion_planner.core.global_planning.metrics.min_clearance`).
        """
        return self.last.metrics.min_clearance_m > self.planner.config.robot_radius

    def prepare(self, scenario, free):
        config = {
            'dijkstra': PlannerConfig(algorithm='dijkstra', refine=False),
            'astar': PlannerConfig(algorithm='astar', refine=False, jump_points=False),
            'jps': PlannerConfig(algorithm='astar', refine=False),
            'improved': PlannerConfig(algorithm='improved', refine=False),
            'improved_refined': PlannerConfig(algorithm='improved', refine=True),
        }[self.name]
        config = replace(config, robot_radius=scenario.robot_radius)
        self.grid = GridMap(scenario.occupied, scenario.resolution)
        self.planner = GlobalPlanner(self.grid, config)
        self.planner.prepare()

    def plan(self, start, goal):
        grid = self.grid
        result = self.planner.plan(grid.world_of(start), grid.world_of(goal))
        self.last = result
        cells = grid.cell_of(result.grid_path)
        if self.name == 'improved_refined':
            length = metrics.path_length(result.path) / grid.resolution
        else:
            length = metrics.path_length(result.grid_path) / grid.resolution
        return cells, length, result.metrics.expanded


class _Pyastar2d:
    def prepare(self, scenario, free):
        import pyastar2d
        self.solve = pyastar2d.astar_path
        self.weights = np.where(free, 1.0, np.inf).astype(np.float32)

    def plan(self, start, goal):
        path = self.solve(self.weights, start, goal, allow_diagonal=True)
        return (None, None, None) if path is None else (path, path_length_cells(path), None)


def _tcod_graph(free, no_corner_cutting):
    """A tcod CustomGraph of the 8-neighbourhood with an octile heuristic."""
    import tcod
    cost = free.astype(np.int8)
    graph = tcod.path.CustomGraph(free.shape)
    o = TCOD_ORTHOGONAL
    graph.add_edges(edge_map=[[0, o, 0], [o, 0, o], [0, o, 0]], cost=cost)
    padded = np.pad(free, 1, constant_values=False)
    height, width = free.shape
    for dr in (-1, 1):
        for dc in (-1, 1):
            if no_corner_cutting:
                condition = (padded[1 + dr:1 + dr + height, 1:1 + width]
                             & padded[1:1 + height, 1 + dc:1 + dc + width]).astype(np.int8)
                graph.add_edge((dr, dc), TCOD_DIAGONAL, cost=cost, condition=condition)
            else:
                graph.add_edge((dr, dc), TCOD_DIAGONAL, cost=cost)
    graph.set_heuristic(cardinal=TCOD_ORTHOGONAL, diagonal=TCOD_DIAGONAL)
    return graph


def _tcod_path(graph, start, goal):
    """Cells of tcod's path from start to goal, or None."""
    import tcod
    finder = tcod.path.Pathfinder(graph)
    finder.add_root(start)
    path = finder.path_to(goal)
    if len(path) == 0 or tuple(path[0]) != tuple(start):
        return None  # tcod answers an unreachable goal with the goal alone
    return path


class _Tcod:
    def prepare(self, scenario, free):
        self.graph = _tcod_graph(free, no_corner_cutting=True)

    def plan(self, start, goal):
        path = _tcod_path(self.graph, start, goal)
        return (None, None, None) if path is None else (path, path_length_cells(path), None)


class _Pathfinding:
    def prepare(self, scenario, free):
        from pathfinding.core.diagonal_movement import DiagonalMovement
        from pathfinding.core.grid import Grid
        from pathfinding.finder.a_star import AStarFinder
        self.grid = Grid(matrix=free.astype(np.int8))
        self.finder = AStarFinder(diagonal_movement=DiagonalMovement.only_when_no_obstacle)

    def plan(self, start, goal):
        # Nodes carry the search state: the library needs a cleanup per search.
        self.grid.cleanup()
        path, runs = self.finder.find_path(self.grid.node(start[1], start[0]),
                                           self.grid.node(goal[1], goal[0]), self.grid)
        if not path:
            return None, None, runs
        cells = np.array([(node.y, node.x) for node in path])
        return cells, path_length_cells(cells), runs


class _Pmp:
    def prepare(self, scenario, free):
        from python_motion_planning.common import TYPES, Grid
        from python_motion_planning.path_planner.graph_search.a_star import AStar
        height, width = free.shape
        type_map = np.where(free, TYPES.FREE, TYPES.OBSTACLE).astype(np.int8)
        self.map = Grid(bounds=[[0, height], [0, width]], resolution=1.0, type_map=type_map)
        # One planner per map (its constructor recomputes the map's distance
        # field); start and goal are set per search, the library's best case.
        self.planner = AStar(map_=self.map, start=(0, 0), goal=(0, 0))
        warm = Grid(bounds=[[0, 4], [0, 4]], resolution=1.0)
        AStar(map_=warm, start=(0, 0), goal=(3, 3)).plan()  # numba compilation

    def plan(self, start, goal):
        self.planner.start = tuple(start)
        self.planner.goal = tuple(goal)
        path, info = self.planner.plan()
        expanded = len(info.get('expand', ())) if isinstance(info, dict) else None
        if not info.get('success'):
            return None, None, expanded
        cells = np.array(path, dtype=np.int64)
        return cells, path_length_cells(cells), expanded


class _Networkx:
    def prepare(self, scenario, free):
        import networkx
        height, width = free.shape
        self.width = width
        graph = networkx.Graph()
        index = np.arange(height * width).reshape(height, width)
        graph.add_nodes_from(index[free].tolist())
        padded = np.pad(free, 1, constant_values=False)
        for dr, dc in ((0, 1), (1, 0), (1, 1), (1, -1)):  # each undirected edge once
            ok = free & padded[1 + dr:1 + dr + height, 1 + dc:1 + dc + width]
            if dr and dc:
                ok &= padded[1 + dr:1 + dr + height, 1:1 + width]
                ok &= padded[1:1 + height, 1 + dc:1 + dc + width]
            u = index[ok]
            v = u + dr * width + dc
            weight = math.hypot(dr, dc)
            graph.add_weighted_edges_from(zip(u.tolist(), v.tolist(), [weight] * len(u)))
        self.graph = graph
        self.astar = networkx.astar_path
        self.no_path = networkx.NetworkXNoPath

    def plan(self, start, goal):
        width = self.width

        def octile(u, v):
            dy, dx = abs(u // width - v // width), abs(u % width - v % width)
            return dx + dy + (ROOT2 - 2.0) * min(dx, dy)

        try:
            nodes = self.astar(self.graph, start[0] * width + start[1], goal[0] * width + goal[1],
                               heuristic=octile, weight='weight')
        except self.no_path:
            return None, None, None
        cells = np.stack(np.divmod(np.array(nodes), width), axis=1)
        return cells, path_length_cells(cells), None


_ADAPTERS = {'pyastar2d': _Pyastar2d, 'tcod': _Tcod, 'pathfinding': _Pathfinding,
             'pmp': _Pmp, 'networkx': _Networkx}


def make_adapter(name):
    """The adapter of a planner name (ours or a peer)."""
    return _Ours(name) if name in OURS else _ADAPTERS[name]()


#: The module each peer is imported as.
PEER_MODULES = {'pyastar2d': 'pyastar2d', 'tcod': 'tcod', 'pathfinding': 'pathfinding',
                'pmp': 'python_motion_planning', 'networkx': 'networkx'}


# ---------------------------------------------------------------------------
# Running
# ---------------------------------------------------------------------------

def run_scenario(scenario, planners, budget_s, progress=None, unit=1.0):
    """Every planner on every pair of one scenario.

    Parameters
    ----------
    scenario : Scenario
    planners : sequence of str
        Names of :data:`PLANNERS`; peers must be importable.
    budget_s : float
        Planning time per planner after which its remaining pairs are
        skipped [s].
    progress : Progress, optional
    unit : float
        Progress units this scenario is worth.

    Returns
    -------
    rows : list of Row
    extra : dict
        ``inflation_s`` (CPU time of our traversable mask [s]), ``optimal``
        (per pair, no corner cutting), ``cutting_optimal`` (per pair, when a
        cutting peer ran).
    """
    grid = GridMap(scenario.occupied, scenario.resolution)
    c0 = time.process_time()
    free = grid.traversable(scenario.robot_radius)
    inflation_s = time.process_time() - c0
    pairs = scenario.pairs
    optimal = list(scenario.optimal) if scenario.optimal else None
    rows, extra = [], {'inflation_s': inflation_s}
    share = unit / (len(planners) + 1) / max(len(pairs), 1)
    if optimal is None:
        # The no-cutting optimum: our A*-8 (optimal; tested against scipy).
        reference = make_adapter('astar')
        reference.prepare(scenario, free)
        optimal = []
        for start, goal in pairs:
            _, length, _ = reference.plan(start, goal)
            optimal.append(length)
            if progress is not None:
                progress.advance(share, f'{scenario.name}: reference optimum')
    elif progress is not None:
        progress.advance(share * len(pairs))
    extra['optimal'] = optimal
    cutting = None
    for name in planners:
        info = PLANNERS[name]
        row = Row(scenario.suite, scenario.name, name)
        if name == 'networkx' and scenario.occupied.size > NETWORKX_MAX_CELLS:
            row.note = (f'skipped: a graph of {scenario.occupied.size} cells needs several GB '
                        f'(limit {NETWORKX_MAX_CELLS})')
            row.skipped = len(pairs)
            rows.append(row)
            if progress is not None:
                progress.advance(share * len(pairs))
            continue
        adapter = make_adapter(name)
        t0, c0 = time.perf_counter(), time.process_time()
        adapter.prepare(scenario, free)
        row.prep_s = time.process_time() - c0
        row.prep_wall_s = time.perf_counter() - t0
        if info.cuts_corners and cutting is None:
            cutting = [cutting_optimum(free, s, g) for s, g in pairs]
            extra['cutting_optimal'] = cutting
        walls, cpus, ratios, expanded = [], [], [], []
        exact = 0
        spent = 0.0
        for index, (start, goal) in enumerate(pairs):
            if spent > budget_s:
                row.skipped = len(pairs) - index
                row.note = f'time budget {budget_s:g} s spent after {index} pairs'
                if progress is not None:
                    progress.advance(share * row.skipped)
                break
            w0, c0 = time.perf_counter(), time.process_time()
            try:
                cells, length, count = adapter.plan(start, goal)
            except (NoValidPathCouldBeFound, PlannerTimedOut):
                cells, length, count = None, None, None
            wall, cpu = time.perf_counter() - w0, time.process_time() - c0
            spent += wall
            row.pairs += 1
            walls.append(wall)
            cpus.append(cpu)
            if count is not None:
                expanded.append(count)
            if cells is not None:
                row.found += 1
                valid = is_valid_path(cells, start, goal, free, info.cuts_corners)
                if name == 'improved_refined':
                    valid = valid and adapter.refined_is_safe()
                row.valid += valid
                best = cutting[index] if info.cuts_corners else optimal[index]
                ratio = length / best if best > 0 else 1.0
                ratios.append(ratio)
                exact += abs(length - best) <= OPTIMAL_TOLERANCE * max(1.0, best)
            if progress is not None:
                progress.advance(share, f'{scenario.name}: {info.label}')
        if info.optimal and name != 'tcod':
            row.optimal_exact = exact
        row.cpu_ms = [1e3 * c for c in cpus]
        if walls:
            row.time_median_ms = 1e3 * statistics.median(walls)
            row.cpu_median_ms = 1e3 * statistics.median(cpus)
        if ratios:
            row.ratio_median = statistics.median(ratios)
            row.ratio_max = max(ratios)
        if expanded:
            row.expanded_median = statistics.median(expanded)
        rows.append(row)
    if progress is not None:
        progress.advance(0, f'{scenario.name}: done')
    return rows, extra


def memory_probe(spec, planner):
    """Peak RSS [MB] of this process after building a scenario and planning
    its first pair with ``planner`` (None: build the map only)."""
    scenario = build_scenario(spec)
    grid = GridMap(scenario.occupied, scenario.resolution)
    free = grid.traversable(scenario.robot_radius)
    if planner is not None:
        adapter = make_adapter(planner)
        adapter.prepare(scenario, free)
        start, goal = scenario.pairs[0]
        try:
            adapter.plan(start, goal)
        except (NoValidPathCouldBeFound, PlannerTimedOut):
            pass
    return peak_rss_mb()


def peak_rss_mb():
    """Peak resident set size [MB] of this process's own address space.

    ``VmHWM`` of /proc/self/status where it exists: unlike ``ru_maxrss``,
    it is not inherited from the parent across fork and exec. Elsewhere
    ``ru_maxrss`` (kB on Linux).
    """
    try:
        for line in pathlib.Path('/proc/self/status').read_text().splitlines():
            if line.startswith('VmHWM:'):
                return float(line.split()[1]) / 1024.0
    except OSError:
        pass
    import resource  # Unix only
    return resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024.0


def measure_memory(spec, planner, timeout_s):
    """Run :func:`memory_probe` in a fresh interpreter; peak RSS [MB] or None."""
    code = ('import json, sys; from fusion_planner.bench import peers; '
            'print(json.dumps(peers.memory_probe(json.loads(sys.argv[1]), '
            'json.loads(sys.argv[2]))))')
    env = dict(os.environ)
    root = str(pathlib.Path(__file__).resolve().parents[2])
    env['PYTHONPATH'] = root + os.pathsep + env.get('PYTHONPATH', '')
    try:
        done = subprocess.run([sys.executable, '-c', code, json.dumps(spec), json.dumps(planner)],
                              capture_output=True, text=True, timeout=timeout_s, env=env,
                              check=False)
    except subprocess.TimeoutExpired:
        return None
    if done.returncode != 0:
        return None
    return float(done.stdout.strip().splitlines()[-1])


# ---------------------------------------------------------------------------
# Report
# ---------------------------------------------------------------------------

def _fmt(value, spec, missing='-'):
    if value is None or (isinstance(value, float) and math.isnan(value)):
        return missing
    return format(value, spec)


def format_report(header, scenarios, rows, extras, notes, verdicts):
    """The text report: the planners' rules, one table per scenario, the
    targets."""
    lines = [header, '', 'planners (corner rule; cost model; search loop):']
    used = []
    for row in rows:
        if row.planner not in used:
            used.append(row.planner)
    for name in used:
        info = PLANNERS[name]
        rule = 'cuts corners' if info.cuts_corners else 'no corner cutting'
        lines.append(f'  {info.label:<27}{rule:<19}{info.cost_model:<42}{info.language}')
    for note in notes:
        lines.append(f'  note: {note}')
    columns = (f'{"planner":<27}{"pairs":>6}{"found":>6}{"valid":>6}{"exact":>6}'
               f'{"len/opt":>9}{"len/opt":>9}{"time":>10}{"cpu":>10}{"expanded":>10}'
               f'{"prep":>8}{"peak":>8}{"+peak":>8}')
    units = (f'{"":<27}{"":>6}{"":>6}{"":>6}{"":>6}{"median":>9}{"max":>9}{"med [ms]":>10}'
             f'{"med [ms]":>10}{"median":>10}{"cpu [s]":>8}{"[MB]":>8}{"[MB]":>8}')
    for scenario in scenarios:
        extra = extras[scenario.name]
        lines += ['', f'{scenario.suite} / {scenario.name}: {scenario.description}; inflation '
                      f'{extra["inflation_s"]:.3f} s CPU', columns, units]
        for row in (r for r in rows if r.scenario == scenario.name):
            info = PLANNERS[row.planner]
            lines.append(
                f'{info.label:<27}{row.pairs:>6}{row.found:>6}{row.valid:>6}'
                f'{_fmt(row.optimal_exact, "d"):>6}{_fmt(row.ratio_median, ".4f"):>9}'
                f'{_fmt(row.ratio_max, ".4f"):>9}{_fmt(row.time_median_ms, ".1f"):>10}'
                f'{_fmt(row.cpu_median_ms, ".1f"):>10}{_fmt(row.expanded_median, ".0f"):>10}'
                f'{_fmt(row.prep_s, ".3f"):>8}{_fmt(row.peak_rss_mb, ".0f"):>8}'
                f'{_fmt(row.peak_rss_over_map_mb, ".0f"):>8}'
                + (f'  ({row.note})' if row.note else ''))
    if verdicts:
        lines += ['', 'targets (medians of this run; info: no target set on this map):']
        lines += [f'  [{v["status"]}] {v["target"]}: {v["detail"]}' for v in verdicts]
    return '\n'.join(lines)


def evaluate_targets(rows, sides):
    """Verdicts on the speed targets that this run measured.

    Parameters
    ----------
    rows : list of Row
    sides : dict
        Side [cells] of each scenario's (square) map, by scenario name.

    Returns
    -------
    list of dict
        ``target``, ``status`` (``'met'``, ``'NOT met'``, or ``'info'`` for
        the same figures on maps the target was not set on) and ``detail``
        (the numbers and the margin).
    """
    by = {(r.scenario, r.planner): r for r in rows}
    scenarios = []
    suite_of = {}
    for r in rows:
        if r.scenario not in scenarios:
            scenarios.append(r.scenario)
            suite_of[r.scenario] = r.suite
    verdicts = []
    for scenario in (s for s in scenarios if suite_of[s] in ('random', 'movingai', 'building')):
        limit = speed_target(scenario, suite_of[scenario])
        fast = by.get((scenario, 'pyastar2d'))
        tcod = by.get((scenario, 'tcod'))
        for name in ('improved', 'jps', 'astar'):
            ours = by.get((scenario, name))
            label = PLANNERS[name].label
            if ours and ours.found and fast and fast.found:
                ratio = ours.cpu_median_ms / fast.cpu_median_ms
                verdicts.append(_verdict(
                    f'{scenario}: {label} ' + ('vs' if limit is None else f'<= {limit:g}x')
                    + ' pyastar2d (CPU)',
                    None if limit is None else ratio <= limit,
                    f'{ours.cpu_median_ms:.1f} ms vs {fast.cpu_median_ms:.1f} ms = '
                    f'{ratio:.2f}x (wall {ours.time_median_ms:.1f} vs '
                    f'{fast.time_median_ms:.1f} ms)'))
            if ours and ours.found and tcod and tcod.found:
                verdicts.append(_verdict(
                    f'{scenario}: {label} faster than tcod A* (CPU)',
                    None if limit is None else ours.cpu_median_ms < tcod.cpu_median_ms,
                    f'{ours.cpu_median_ms:.1f} ms vs {tcod.cpu_median_ms:.1f} ms = '
                    f'{ours.cpu_median_ms / tcod.cpu_median_ms:.2f}x'))
        ours = by.get((scenario, 'improved'))
        informative = not _random_corner_to_corner(scenario, suite_of[scenario])
        if ours and ours.found:
            verdicts.append(_verdict(
                f'{scenario}: improved A* path <= {TARGET_IMPROVED_LENGTH_RATIO} x optimum',
                None if informative else ours.ratio_max <= TARGET_IMPROVED_LENGTH_RATIO,
                f'ratio {ours.ratio_max:.4f} (margin '
                f'{100 * (TARGET_IMPROVED_LENGTH_RATIO - ours.ratio_max):.2f} points)'))
    for scenario in scenarios:
        astar = by.get((scenario, 'astar'))
        if astar is None or not astar.pairs:
            continue
        slower = []
        compared = []
        for peer in PURE_PYTHON_PEERS:
            other = by.get((scenario, peer))
            if other is None or not other.pairs or not other.cpu_ms:
                continue
            # Like with like: A*-8's median over the pairs the peer ran.
            ours = statistics.median(astar.cpu_ms[:other.pairs])
            theirs = statistics.median(other.cpu_ms)
            compared.append(f'{peer} {theirs:.0f} ms ({theirs / ours:.1f}x A*-8\'s {ours:.0f} ms '
                            f'over {other.pairs} pairs)')
            if ours >= theirs:
                slower.append(peer)
        if compared:
            verdicts.append(_verdict(
                f'{scenario}: A*-8 faster than every pure-Python peer (CPU)', not slower,
                ', '.join(compared) + (f'; slower than {", ".join(slower)}' if slower else '')))
    for scenario in scenarios:
        for name in ('astar', 'jps'):
            row = by.get((scenario, name))
            if row is not None and row.optimal_exact is not None and row.found:
                verdicts.append(_verdict(f'{scenario}: {PLANNERS[name].label} exactly optimal',
                                         row.optimal_exact == row.found,
                                         f'{row.optimal_exact}/{row.found} paths at the optimum'))
    preps = [r for r in rows
             if r.suite == 'nav2' and r.planner in OURS and not math.isnan(r.prep_s)]
    if preps:
        worst = max(preps, key=lambda r: r.prep_s)
        side = sides[worst.scenario]
        verdicts.append(_verdict(
            f'map preparation of a {side} x {side} map < {TARGET_PREP_S} s',
            worst.prep_s < TARGET_PREP_S,
            f'largest {worst.prep_s:.3f} s CPU, {worst.prep_wall_s:.3f} s wall '
            f'({worst.scenario}, {PLANNERS[worst.planner].label}; '
            'inflation, padded grid, move tables)'))
    for r in rows:
        if r.suite == 'big' and r.peak_rss_mb is not None:
            verdicts.append(_verdict(
                f'{r.scenario}: {PLANNERS[r.planner].label} peak memory < '
                f'{TARGET_BIG_MEMORY_MB:.0f} MB',
                r.peak_rss_mb < TARGET_BIG_MEMORY_MB,
                f'{r.peak_rss_mb:.0f} MB ({r.peak_rss_over_map_mb:.0f} MB over the map alone), '
                f'plan {r.time_median_ms / 1e3:.2f} s'))
    return verdicts


def speed_target(scenario, suite):
    """Largest median CPU-time ratio over pyastar2d set for a scenario, or None."""
    if suite == 'random':
        return TARGET_OVER_PYASTAR_RANDOM if _random_corner_to_corner(scenario, suite) else None
    if suite == 'building' or (suite == 'movingai'
                               and any(word in scenario for word in STRUCTURED_MAPS)):
        return TARGET_OVER_PYASTAR_STRUCTURED
    return None


def _random_corner_to_corner(scenario, suite):
    """Whether a scenario is the random map's corner-to-corner pair (the targets' own)."""
    return suite == 'random' and not scenario.endswith(RANDOM_PAIRS_SUFFIX)


def _verdict(target, ok, detail):
    """A verdict; ``ok`` None marks a figure given for information."""
    status = 'info' if ok is None else ('met' if ok else 'NOT met')
    return {'target': target, 'status': status, 'detail': detail}


# ---------------------------------------------------------------------------
# Command line
# ---------------------------------------------------------------------------

def add_arguments(parser):
    """Options of ``fusion-planner bench peers``."""
    parser.add_argument('--suites', nargs='+', choices=SUITES, default=None,
                        metavar='SUITE',
                        help=f'any of {", ".join(SUITES)} (default: '
                             f'{" ".join(DEFAULT_SUITES)}, movingai only when its maps are '
                             f'there; big is the {BIG_SIDE} x {BIG_SIDE} memory run of our '
                             'planners)')
    parser.add_argument('--planners', nargs='+', choices=list(PLANNERS), default=list(PLANNERS),
                        metavar='NAME',
                        help=f'any of {", ".join(PLANNERS)} (default all; the peers need the '
                             'bench extra)')
    parser.add_argument('--maps', metavar='DIR', default=None,
                        help='MovingAI folder (default as for bench movingai)')
    parser.add_argument('--only', nargs='+', metavar='NAME', default=None,
                        help='MovingAI maps whose name contains one of these strings')
    parser.add_argument('--rows', type=int, default=DEFAULT_MOVINGAI_ROWS, metavar='N',
                        help='MovingAI rows per map, sampled over the buckets (default '
                             '%(default)s)')
    parser.add_argument('--pairs', type=int, default=NAV2_PAIRS, metavar='N',
                        help='start/goal pairs per Nav2 map (default %(default)s)')
    parser.add_argument('--budget', type=float, default=DEFAULT_BUDGET_S, metavar='S',
                        help='planning seconds per planner and map before its remaining pairs '
                             'are skipped (default %(default)s)')
    parser.add_argument('--memory', action='store_true',
                        help='measure peak memory per map and planner in fresh processes')
    parser.add_argument('--memory-timeout', type=float, default=900.0, metavar='S',
                        help='time limit of one memory probe (default %(default)s)')
    parser.add_argument('--quick', action='store_true',
                        help=f'small maps and few pairs (random {QUICK_RANDOM_SIDE}, Nav2 '
                             f'{QUICK_NAV2_SIDE} cells x {QUICK_NAV2_PAIRS} pairs, '
                             f'{QUICK_MOVINGAI_ROWS} MovingAI rows): checks that it all runs')
    parser.add_argument('--no-progress', action='store_true',
                        help='do not report progress on stderr')
    parser.add_argument('--json', action='store_true', help='print one JSON object')
    parser.add_argument('--json-out', metavar='FILE', default=None,
                        help='also write the JSON object to FILE')
    parser.add_argument('--plot', metavar='PNG', default=None,
                        help='draw median CPU time per planner and map to PNG (needs matplotlib)')


def run(args):
    """Run the benchmark from parsed options; returns the exit status.

    Returns
    -------
    int
        0 when every planner that ran returned a valid path on every pair
        it tried and the optimal ones were optimal, 1 otherwise.

    Raises
    ------
    MapError, InvalidInput
        Missing MovingAI data (when that suite is asked for with
        ``--suites``), bad options.
    MissingExtra, OutputPathError
        A peer asked for that does not import, ``--plot`` without the
        ``plot`` extra, an output path that cannot be written (all before
        any work).
    """
    if args.rows < 1 or args.pairs < 1:
        raise InvalidInput('--rows and --pairs must be positive')
    if not args.budget > 0:
        raise InvalidInput(f'--budget must be a positive number of seconds, got {args.budget!r}')
    planners = [name for name in PLANNERS if name in args.planners]
    require('bench', 'bench peers',
            modules=[PEER_MODULES[name] for name in planners if name in PEERS],
            alternative='leave the peers out with --planners')
    if args.plot:
        require('plot', 'bench peers --plot')
        prepare_file(args.plot, '--plot')
    if args.json_out:
        prepare_file(args.json_out, '--json-out')
    suites, notes = chosen_suites(args)
    specs = scenario_specs(suites, args)
    progress = None if args.no_progress else Progress(len(specs), 'peers')
    scenarios, rows, extras = [], [], {}
    t0 = time.perf_counter()
    for spec in specs:
        if progress is not None:
            progress.advance(0, f'building {spec["suite"]} map', force=True)
        scenario = build_scenario(spec)
        chosen = planners
        if scenario.suite == 'big':
            chosen = [p for p in planners if p in OURS]
        elif scenario.suite == 'building':
            chosen = [p for p in planners if p in OURS + COMPILED_PEERS]
        scenario_rows, extra = run_scenario(scenario, chosen, args.budget, progress, unit=1.0)
        if args.memory or scenario.suite == 'big':
            spec = dict(spec, pair_cells=[[list(a), list(b)] for a, b in scenario.pairs[:1]])
            base = measure_memory(spec, None, args.memory_timeout)
            for row in scenario_rows:
                if row.pairs == 0:
                    continue
                if progress is not None:
                    progress.advance(0, f'{scenario.name}: memory of {row.planner}', force=True)
                peak = measure_memory(spec, row.planner, args.memory_timeout)
                row.peak_rss_mb = peak
                if peak is not None and base is not None:
                    row.peak_rss_over_map_mb = peak - base
        scenarios.append(scenario)
        rows += scenario_rows
        extras[scenario.name] = extra
    if progress is not None:
        progress.finish()
    elapsed = time.perf_counter() - t0
    if any(s.suite == 'nav2' for s in scenarios):
        notes.append(f'Nav2 maps are generated ({NAV2_OBSTACLE_SIDE_M[0]}-'
                     f'{NAV2_OBSTACLE_SIDE_M[1]} m rectangles), not Nav2\'s own files')
    verdicts = evaluate_targets(rows, {s.name: s.occupied.shape[0] for s in scenarios})
    failed = any(r.valid < r.found or r.found < r.pairs
                 or (r.optimal_exact is not None and r.optimal_exact < r.found) for r in rows)
    report = movingai_bench._strict({
        'suites': suites, 'planners': planners, 'notes': notes, 'elapsed_s': elapsed,
        'machine': machine_summary(),
        'scenarios': [{'suite': s.suite, 'name': s.name, 'description': s.description,
                       'pairs': len(s.pairs), 'optimal': extras[s.name]['optimal'],
                       'inflation_s': extras[s.name]['inflation_s']} for s in scenarios],
        'rows': [asdict(r) for r in rows], 'targets': verdicts})
    if args.json_out:
        pathlib.Path(args.json_out).write_text(json.dumps(report, indent=1) + '\n')
    if args.plot:
        plot_times(rows, [s.name for s in scenarios], args.plot)
    if args.json:
        print(json.dumps(report))
    else:
        header = (f'Peer benchmark: {", ".join(suites)}; {elapsed:.0f} s wall; '
                  f'{machine_summary()}')
        print(format_report(header, scenarios, rows, extras, notes, verdicts))
    return EXIT_FAILED if failed else EXIT_OK


def chosen_suites(args):
    """The suites to run, in :data:`SUITES` order, and notes on those left out.

    Without ``--suites`` (``args.suites`` None) the :data:`DEFAULT_SUITES`
    run, MovingAI only when its maps are there; a MovingAI suite asked for
    by name needs them (:func:`scenario_specs` raises).
    """
    if args.suites is not None:
        return [s for s in SUITES if s in args.suites], []
    suites = list(DEFAULT_SUITES)
    folder = pathlib.Path(args.maps) if args.maps else movingai_bench.default_data_dir()
    if args.maps is None and not folder.is_dir():
        suites.remove('movingai')
        return suites, [f'movingai suite left out: no MovingAI maps in {folder} (see '
                        f'bench movingai --help; --maps DIR or ${movingai_bench.DATA_ENV})']
    return suites, []


def plot_times(rows, scenario_names, path):
    """Bar chart of the median CPU time per planner and map (log scale) to PNG.

    Parameters
    ----------
    rows : list of Row
    scenario_names : list of str
        Maps in drawing order.
    path : str or os.PathLike
        Output PNG.

    """
    import matplotlib
    matplotlib.use('Agg')
    import matplotlib.pyplot as plt
    names = [n for n in PLANNERS if any(r.planner == n and r.pairs for r in rows)]
    by = {(r.scenario, r.planner): r for r in rows}
    fig, ax = plt.subplots(figsize=(max(8.0, 1.1 * len(scenario_names) + 4), 4.8))
    width = 0.8 / max(len(names), 1)
    for k, name in enumerate(names):
        values = [by[(s, name)].cpu_median_ms if (s, name) in by and by[(s, name)].pairs
                  else np.nan for s in scenario_names]
        x = np.arange(len(scenario_names)) + (k - (len(names) - 1) / 2) * width
        ax.bar(x, values, width, label=PLANNERS[name].label)
    ax.set_yscale('log')
    ax.set_xticks(np.arange(len(scenario_names)))
    ax.set_xticklabels(scenario_names, rotation=20, ha='right')
    ax.set_ylabel('median planning CPU time [ms] (log)')
    ax.set_title('fusion-planner bench peers: time per plan, lower is better')
    ax.legend(fontsize=7, ncol=3)
    ax.grid(axis='y', which='both', alpha=0.3)
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)


def machine_summary():
    """One line: CPU model, cores, memory, Python and numpy versions."""
    model = 'unknown CPU'
    try:
        for line in pathlib.Path('/proc/cpuinfo').read_text().splitlines():
            if line.startswith('model name'):
                model = line.split(':', 1)[1].strip()
                break
    except OSError:
        pass
    memory = ''
    try:
        pages = os.sysconf('SC_PHYS_PAGES') * os.sysconf('SC_PAGE_SIZE')
        memory = f', {pages / 2 ** 30:.0f} GB RAM'
    except (ValueError, OSError, AttributeError):
        pass
    return (f'{model}, {os.cpu_count()} cores{memory}, Python {sys.version.split()[0]}, '
            f'numpy {np.__version__}')
