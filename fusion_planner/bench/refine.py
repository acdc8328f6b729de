"""Refinement speed: redundant-node removal and smoothing of search paths.

Plans an A*-8 path (no refinement) on a few maps, then times
:func:`~fusion_planner.core.global_planning.refine.prune_redundant` (with the planner's
``tolerate_input_margin=True``), :func:`~fusion_planner.core.global_planning.refine.smooth_path`
and :func:`~fusion_planner.core.global_planning.metrics.min_clearance` of the result, the
steps :meth:`GlobalPlanner.plan` adds after the search.

Notes
-----
- Maps and pairs: the paper's 20 x 20 map (its start and goal), the last
  (longest) row of the MovingAI ``8room_000`` and ``maze512-1-0``
  scenarios, the 1024 x 1024 map with 20 % random cells (corner to corner,
  as ``bench peers``), and a 2000 x 2000 map of Nav2's kind (20 %
  rectangles, 0.05 m cells, robot radius 0.22 m, safety distance 0.1 m,
  between free cells near opposite corners).
- Medians over ``--repeats`` runs of the CPU time of this process
  (``time.process_time``) [ms].
"""

import json
import pathlib
import statistics
import time

from fusion_planner.bench import paper_map, peers
from fusion_planner.bench.movingai import _strict, default_data_dir, missing_data
from fusion_planner.core.global_planning import metrics, refine
from fusion_planner.core.errors import InvalidInput, NoValidPathCouldBeFound
from fusion_planner.core.grid import GridMap
from fusion_planner.core.map_files import load_movingai, movingai_cell, read_scenarios
from fusion_planner.core.global_planning.planner import GlobalPlanner, PlannerConfig

EXIT_OK, EXIT_FAILED, EXIT_BAD_INPUT = 0, 1, 2

#: Default number of timed runs per path.
DEFAULT_REPEATS = 7
#: MovingAI maps of the benchmark.
MOVINGAI_MAPS = ('8room_000', 'maze512-1-0')
#: Safety distance of the Nav2-kind case [m].
NAV2_SAFETY_M = 0.1


def cases(maps_dir, quick=False):
    """The ``(name, grid, start, goal, robot radius, safety distance)`` of each path.

    Start and goal are ``(x, y)`` [m]. ``quick`` keeps the paper map and a
    200 x 200 Nav2-kind map.
    """
    found = [('paper 20x20', paper_map.paper_grid(), paper_map.START_XY, paper_map.GOAL_XY,
              0.0, 0.0)]
    if not quick:
        for name in MOVINGAI_MAPS:
            grid = load_movingai(maps_dir / f'{name}.map')
            row = read_scenarios(maps_dir / f'{name}.map.scen')[-1]
            height = grid.shape[0]
            start = grid.world_of(movingai_cell(row.start_col, row.start_row, height))
            goal = grid.world_of(movingai_cell(row.goal_col, row.goal_row, height))
            found.append((name, grid, start, goal, 0.0, 0.0))
        side = peers.RANDOM_SIDE
        grid = GridMap(peers.random_map(side, peers.RANDOM_DENSITY, peers.RANDOM_SEED), 1.0)
        found.append((f'random{side}', grid, grid.world_of((0, 0)),
                      grid.world_of((side - 1, side - 1)), 0.0, 0.0))
    side = peers.QUICK_BIG_SIDE if quick else peers.NAV2_SIDE
    grid = GridMap(peers.nav2_map(side, peers.BIG_DENSITY, peers.NAV2_RESOLUTION,
                                  peers.NAV2_SEED), peers.NAV2_RESOLUTION)
    planner = GlobalPlanner(grid, PlannerConfig(algorithm='astar', refine=False,
                                                robot_radius=peers.NAV2_ROBOT_RADIUS))

    def reachable(start, goal):
        try:
            planner.plan(grid.world_of(start), grid.world_of(goal))
        except NoValidPathCouldBeFound:
            return False
        return True

    start, goal = peers._corner_pair(grid.traversable(peers.NAV2_ROBOT_RADIUS), reachable)
    found.append((f'nav2-{side}', grid, grid.world_of(start), grid.world_of(goal),
                  peers.NAV2_ROBOT_RADIUS, NAV2_SAFETY_M))
    return found


def measure(grid, start, goal, radius, safety, repeats):
    """Figures of refining one A*-8 path; a dict of counts and median CPU times [ms]."""
    planner = GlobalPlanner(grid, PlannerConfig(algorithm='astar', refine=False,
                                                robot_radius=radius, safety_distance=safety))
    raw = planner.plan(start, goal).grid_path
    spacing = grid.resolution / 2
    prune_s, smooth_s, clearance_s = [], [], []
    for _ in range(repeats):  # bounded
        c0 = time.process_time()
        nodes = refine.prune_redundant(grid, raw, radius, safety, tolerate_input_margin=True)
        c1 = time.process_time()
        path = refine.smooth_path(grid, nodes, radius, safety, spacing)
        c2 = time.process_time()
        clearance = metrics.min_clearance(grid, path)
        c3 = time.process_time()
        prune_s.append(c1 - c0)
        smooth_s.append(c2 - c1)
        clearance_s.append(c3 - c2)
    return {'nodes': len(raw), 'key_points': len(metrics.key_point_indices(raw)),
            'kept': len(nodes), 'points': len(path),
            'length_ratio': metrics.path_length(path) / metrics.path_length(raw),
            'min_clearance_m': clearance,
            'prune_ms': 1e3 * statistics.median(prune_s),
            'smooth_ms': 1e3 * statistics.median(smooth_s),
            'clearance_ms': 1e3 * statistics.median(clearance_s)}


def format_table(rows, header):
    """The text table: one line per path."""
    lines = [header, '',
             f'{"path":<16}{"nodes":>7}{"keys":>7}{"kept":>6}{"points":>8}{"len/raw":>9}'
             f'{"prune":>9}{"smooth":>9}{"clear.":>9}',
             f'{"":<16}{"":>7}{"":>7}{"":>6}{"":>8}{"":>9}{"[ms]":>9}{"[ms]":>9}{"[ms]":>9}']
    for name, r in rows:
        lines.append(f'{name:<16}{r["nodes"]:>7}{r["key_points"]:>7}{r["kept"]:>6}'
                     f'{r["points"]:>8}{r["length_ratio"]:>9.4f}{r["prune_ms"]:>9.2f}'
                     f'{r["smooth_ms"]:>9.2f}{r["clearance_ms"]:>9.2f}')
    return '\n'.join(lines)


def add_arguments(parser):
    """Options of ``fusion-planner bench refine``."""
    parser.add_argument('--maps', metavar='DIR', default=None,
                        help='MovingAI folder (default as for bench movingai)')
    parser.add_argument('--repeats', type=int, default=DEFAULT_REPEATS, metavar='N',
                        help='timed runs per path (default %(default)s)')
    parser.add_argument('--quick', action='store_true',
                        help='the paper map and a small Nav2-kind map only')
    parser.add_argument('--json', action='store_true', help='print one JSON object')


def run(args):
    """Run the benchmark; returns the exit status (0).

    Raises
    ------
    InvalidInput, MapError
        Bad options, missing MovingAI data (checked before any work).
    """
    if args.repeats < 1:
        raise InvalidInput(f'--repeats must be positive, got {args.repeats}')
    maps_dir = pathlib.Path(args.maps) if args.maps else default_data_dir()
    if not args.quick:
        for name in MOVINGAI_MAPS:
            for path in (maps_dir / f'{name}.map', maps_dir / f'{name}.map.scen'):
                if not path.is_file():
                    raise missing_data(path, alternative='give --quick (no MovingAI paths)')
    rows = [(name, measure(grid, start, goal, radius, safety, args.repeats))
            for name, grid, start, goal, radius, safety in cases(maps_dir, args.quick)]
    if args.json:
        print(json.dumps(_strict({'machine': peers.machine_summary(),
                                  'rows': [dict(r, path=name) for name, r in rows]})))
    else:
        print(format_table(rows, f'Refinement of A*-8 paths (median CPU of {args.repeats} runs); '
                                 f'{peers.machine_summary()}'))
    return EXIT_OK
