"""Reproduce the paper's Tables 1 and 2 on the paper-like 20 x 20 map.

Plans from the bottom-left start to the top-right goal of
``config/maps/paper.yaml`` with Dijkstra, A* (4- and 8-neighbourhood), the
improved A* without refinement and the improved A* with refinement, and
prints for each the columns of the paper's Tables 1-2 (path length in cells,
search nodes, key points, time, total turning angle) beside the paper's
numbers, then the relative changes the paper quotes in section 3.1 beside
ours.

Notes
-----
- Path length is reported in cells (the map has 1 m cells, so cells = m).
- "Search nodes" are the nodes the search expanded (closed). The paper's
  Table 1 heads this column "Key Points"; its values (310, 274, 70, 53)
  are search nodes.
- "Key points" are the ends plus the turning vertices of the raw grid path,
  or the pruned nodes of a refined path. The paper's "22 key points" of the
  improved A* equals the number of steps of its grid path (8 straight + 14
  diagonal for 27.799 = 8 + 14 sqrt 2), so "grid nodes" (cells on the raw
  path) is printed as well.
- Time is the median over ``--repeats`` plans on a prepared map (inflation
  and the padded search grid built once, by a warm-up plan) of the planner's
  own wall time: validation, search and refinement [ms]. The paper's times
  are MATLAB simulation times in seconds, so only relative changes compare.
"""

import json
import math
import pathlib
import statistics
import sys
from dataclasses import asdict, dataclass, replace

from fusion_planner.bench import paper_map
from fusion_planner.cli.output_paths import prepare_folder
from fusion_planner.cli.plotting import plan_title, plot_plan
from fusion_planner.cli.requirements import require
from fusion_planner.core.errors import (
    InvalidInput, MapError, NoValidPathCouldBeFound, PlannerTimedOut)
from fusion_planner.core.map_files import load_map
from fusion_planner.core.global_planning.planner import GlobalPlanner, PlannerConfig

#: Default number of timed plans per algorithm.
DEFAULT_REPEATS = 21

EXIT_OK, EXIT_FAILED, EXIT_BAD_INPUT = 0, 1, 2


@dataclass(frozen=True)
class PaperRow:
    """One row of the paper's Table 1 or 2 (None where the paper gives nothing).

    Attributes
    ----------
    length_cells : float
        Path length [cells].
    search_nodes : int or None
        Search nodes (Table 1's "Key Points" column).
    key_points : int or None
        Key points of the path (Table 2 and the text of section 3.1).
    time_s : float
        MATLAB simulation time [s].
    turning_deg : float
        Total turning angle [deg].
    """

    length_cells: float
    search_nodes: int
    key_points: int
    time_s: float
    turning_deg: float


@dataclass(frozen=True)
class BenchCase:
    """An algorithm of the tables: name, label, planner settings, paper row."""

    name: str
    label: str
    algorithm: str
    neighbourhood: int
    refine: bool
    paper: PaperRow


#: The rows of Tables 1 and 2, in the paper's order.
CASES = (
    BenchCase('dijkstra', 'Dijkstra', 'dijkstra', 8, False,
              PaperRow(27.799, 310, None, 7.004, 585.0)),
    BenchCase('astar4', 'A* 4-neighbourhood', 'astar', 4, False,
              PaperRow(36.0, 274, None, 3.860, 990.0)),
    BenchCase('astar8', 'A* 8-neighbourhood', 'astar', 8, False,
              PaperRow(28.385, 70, None, 1.279, 495.0)),
    BenchCase('improved', 'improved A*', 'improved', 8, False,
              PaperRow(27.799, 53, 22, 1.164, 495.0)),
    BenchCase('improved_refined', 'improved A* + refinement', 'improved', 8, True,
              PaperRow(27.219, None, 10, 1.058, 315.0)),
)

#: Relative changes quoted in the text of section 3.1 [percent]:
#: (case, baseline case, metric, paper's change). Negative is a reduction.
PAPER_CHANGES = (
    ('improved', 'dijkstra', 'search_nodes', -82.9),
    ('improved', 'dijkstra', 'time', -83.42),
    ('improved', 'dijkstra', 'turning_deg', -15.38),
    ('improved', 'astar4', 'length_cells', -22.78),
    ('improved', 'astar4', 'search_nodes', -80.65),
    ('improved', 'astar4', 'time', -69.84),
    ('improved', 'astar4', 'turning_deg', -50.0),
    ('improved', 'astar8', 'length_cells', -2.06),
    ('improved', 'astar8', 'search_nodes', -24.26),
    ('improved', 'astar8', 'time', -8.99),
    ('improved_refined', 'improved', 'length_cells', -2.08),
    ('improved_refined', 'improved', 'key_points', -54.54),
    ('improved_refined', 'improved', 'time', -9.1),
    ('improved_refined', 'improved', 'turning_deg', -36.36),
)

_METRIC_LABELS = {
    'length_cells': 'path length', 'search_nodes': 'search nodes', 'key_points': 'key points',
    'time': 'time', 'turning_deg': 'turning angle'}


@dataclass
class BenchRow:
    """Our measurement of one case.

    Attributes
    ----------
    name, label : str
    length_cells : float
        Path length [cells].
    length_m : float
        Path length [m].
    search_nodes : int
        Expanded nodes.
    generated : int
        Nodes ever opened.
    key_points : int
    grid_nodes : int
        Cells on the raw grid path, ends included.
    time_ms : float
        Median planning time [ms].
    turning_deg : float
    min_clearance_m : float
    """

    name: str
    label: str
    length_cells: float
    length_m: float
    search_nodes: int
    generated: int
    key_points: int
    grid_nodes: int
    time_ms: float
    turning_deg: float
    min_clearance_m: float


def add_arguments(parser):
    """Options of ``fusion-planner bench paper``."""
    parser.add_argument('--map', metavar='FILE', default=None,
                        help='map file (default: the bundled config/maps/paper.yaml)')
    parser.add_argument('--start', nargs=2, type=float, metavar=('X', 'Y'),
                        default=paper_map.START_XY, help='start [m] (default %(default)s)')
    parser.add_argument('--goal', nargs=2, type=float, metavar=('X', 'Y'),
                        default=paper_map.GOAL_XY, help='goal [m] (default %(default)s)')
    parser.add_argument('--repeats', type=int, default=DEFAULT_REPEATS, metavar='N',
                        help='timed plans per algorithm; the median is reported '
                             '(default %(default)s)')
    defaults = PlannerConfig()
    parser.add_argument('--alpha', type=float, default=defaults.alpha,
                        help='improved A*: weight of g, eq. (5) (default %(default)s)')
    parser.add_argument('--beta', type=float, default=defaults.beta,
                        help='improved A*: weight of h, eq. (5) (default %(default)s)')
    parser.add_argument('--gamma', type=float, default=defaults.gamma,
                        help='improved A*: gain of the heuristic weight w_n, eqs. (6)-(8) '
                             '(default %(default)s)')
    parser.add_argument('--robot-radius', type=float, default=0.0, metavar='M',
                        help='robot radius [m] (default 0, a point robot as in the paper)')
    parser.add_argument('--safety-distance', type=float, default=0.0, metavar='M',
                        help='safety distance [m] of redundant-node removal (default 0)')
    parser.add_argument('--json', action='store_true', help='print one JSON object')
    parser.add_argument('--plot', metavar='DIR',
                        help='write one figure per algorithm into DIR (paper_<name>.png)')


def run(args):
    """Run the benchmark from parsed options; returns the exit status.

    Raises
    ------
    MissingExtra, OutputPathError
        ``--plot`` without the ``plot`` extra or into a folder that cannot
        be written (before any planning).
    """
    if args.repeats < 1:
        print('error: --repeats must be at least 1', file=sys.stderr)
        return EXIT_BAD_INPUT
    if args.plot:
        require('plot', 'bench paper --plot')
        prepare_folder(args.plot, '--plot')
    map_path = args.map or paper_map.find_paper_map()
    if map_path is None:
        raise MapError('the bundled map config/maps/paper.yaml was not found; give --map')
    grid = load_map(map_path)
    base = PlannerConfig(alpha=args.alpha, beta=args.beta, gamma=args.gamma,
                         robot_radius=args.robot_radius, safety_distance=args.safety_distance)
    try:
        rows, results = measure(grid, args.start, args.goal, base, args.repeats)
    except (NoValidPathCouldBeFound, PlannerTimedOut) as err:
        print(f'error: {err}', file=sys.stderr)
        return EXIT_FAILED
    changes = relative_changes(rows)
    if args.plot:
        _plot_all(grid, results, pathlib.Path(args.plot))
    if args.json:
        print(json.dumps(_strict({
            'map': str(map_path), 'start': list(args.start), 'goal': list(args.goal),
            'repeats': args.repeats, 'config': asdict(base),
            'rows': [dict(asdict(row), paper=asdict(case.paper))
                     for row, case in zip(rows, CASES)],
            'changes': changes})))
    else:
        print(format_report(rows, changes, map_path, args))
    return EXIT_OK


def measure(grid, start, goal, base_config=None, repeats=DEFAULT_REPEATS, cases=CASES):
    """Plan every case and measure the table columns.

    Parameters
    ----------
    grid : GridMap
    start, goal : array_like, shape (2,)
        ``(x, y)`` [m], map frame.
    base_config : PlannerConfig, optional
        Shared settings (weights, radius, safety distance); each case sets
        ``algorithm``, ``neighbourhood`` and ``refine``.
    repeats : int
        Timed plans per case (after one warm-up plan).
    cases : sequence of BenchCase

    Returns
    -------
    rows : list of BenchRow
    results : dict of str to PlanResult
        The warm-up plan of each case, with its expanded cells (for figures).

    Raises
    ------
    PlanningError
        Bad endpoints, or no path.
    """
    base_config = base_config or PlannerConfig()
    rows, results = [], {}
    for case in cases:
        # The paper's A* expands cell by cell with its plain heuristic: no
        # jump points or landmarks in its tables.
        config = replace(base_config, algorithm=case.algorithm,
                         neighbourhood=case.neighbourhood, refine=case.refine,
                         jump_points=False, landmarks=False)
        planner = GlobalPlanner(grid, config)
        result = planner.plan(start, goal, return_expanded=True)  # warm-up + figure
        times = [planner.plan(start, goal).metrics.time_s for _ in range(repeats)]
        m = result.metrics
        rows.append(BenchRow(
            name=case.name, label=case.label, length_cells=m.length_m / grid.resolution,
            length_m=m.length_m, search_nodes=m.expanded, generated=m.generated,
            key_points=m.key_points, grid_nodes=len(result.grid_path),
            time_ms=statistics.median(times) * 1e3, turning_deg=m.turning_deg,
            min_clearance_m=m.min_clearance_m))
        results[case.name] = result
    return rows, results


def relative_changes(rows):
    """Our relative changes for each change the paper quotes.

    Parameters
    ----------
    rows : list of BenchRow

    Returns
    -------
    list of dict
        ``case``, ``baseline``, ``metric``, ``paper_pct`` and ``ours_pct``
        (``100 * (case - baseline) / baseline``; None when the baseline is 0).
    """
    by_name = {row.name: row for row in rows}
    out = []
    for case, baseline, metric, paper_pct in PAPER_CHANGES:
        if case not in by_name or baseline not in by_name:
            continue
        attribute = 'time_ms' if metric == 'time' else metric
        new = getattr(by_name[case], attribute)
        old = getattr(by_name[baseline], attribute)
        ours = 100.0 * (new - old) / old if old else None
        out.append({'case': case, 'baseline': baseline, 'metric': metric,
                    'paper_pct': paper_pct, 'ours_pct': ours})
    return out


def format_report(rows, changes, map_path, args):
    """The text report: our table beside the paper's, then the changes."""
    cases = {case.name: case for case in CASES}
    lines = [
        f'map {map_path}, start ({args.start[0]:g}, {args.start[1]:g}) m, goal '
        f'({args.goal[0]:g}, {args.goal[1]:g}) m, robot radius {args.robot_radius:g} m, '
        f'safety distance {args.safety_distance:g} m',
        f'improved A*: alpha {args.alpha:g}, beta {args.beta:g}, gamma {args.gamma:g}; '
        f'time = median of {args.repeats} plans',
        '',
        f'{"algorithm":<26}{"length":>8}{"search":>8}{"key":>5}{"grid":>6}{"time":>8}'
        f'{"turning":>9}   | paper:{"length":>8}{"search":>8}{"key":>5}{"time":>7}{"turning":>9}',
        f'{"":<26}{"[cells]":>8}{"nodes":>8}{"pts":>5}{"nodes":>6}{"[ms]":>8}{"[deg]":>9}'
        f'   |       {"[cells]":>8}{"nodes":>8}{"pts":>5}{"[s]":>7}{"[deg]":>9}',
    ]
    for row in rows:
        p = cases[row.name].paper
        lines.append(
            f'{row.label:<26}{row.length_cells:>8.3f}{row.search_nodes:>8d}{row.key_points:>5d}'
            f'{row.grid_nodes:>6d}{row.time_ms:>8.3f}{row.turning_deg:>9.1f}   |       '
            f'{p.length_cells:>8.3f}{_opt(p.search_nodes):>8}{_opt(p.key_points):>5}'
            f'{p.time_s:>7.3f}{p.turning_deg:>9.1f}')
    lines += ['', 'relative changes quoted in section 3.1 (negative = reduction):',
              f'{"":<56}{"paper":>9}{"ours":>9}']
    for change in changes:
        what = (f'{cases[change["case"]].label} vs {cases[change["baseline"]].label}: '
                f'{_METRIC_LABELS[change["metric"]]}')
        ours = '-' if change['ours_pct'] is None else f'{change["ours_pct"]:+.1f}%'
        lines.append(f'{what:<56}{change["paper_pct"]:>+8.2f}%{ours:>9}')
    return '\n'.join(lines)


def _plot_all(grid, results, folder):
    """One figure per case: ``folder/paper_<name>.png``."""
    labels = {case.name: case.label for case in CASES}
    try:
        for name, result in results.items():
            plot_plan(result, grid, folder / f'paper_{name}.png',
                      title=plan_title(result, labels[name]))
    except OSError as err:
        raise InvalidInput(f'cannot write figures into {folder}: {err.strerror or err}') from None


def _opt(value):
    return '-' if value is None else str(value)


def _strict(value):
    """``value`` with non-finite floats replaced by None (strict JSON)."""
    if isinstance(value, dict):
        return {key: _strict(item) for key, item in value.items()}
    if isinstance(value, (list, tuple)):
        return [_strict(item) for item in value]
    if isinstance(value, float) and not math.isfinite(value):
        return None
    return value
