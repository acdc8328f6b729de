"""Optimality and search effort on the MovingAI grid benchmark.

Runs every row (or N rows sampled evenly over the difficulty buckets) of
every ``*.map.scen`` file in a folder with A* (8-neighbourhood, octile),
Dijkstra and the improved A*, with robot radius 0, safety distance 0 and no
refinement, and prints per map and algorithm: rows, paths found, rows whose
length equals the file's ``optimal_length`` (A* and Dijkstra), the median,
mean and largest length ratio to the optimum, total and median search time,
median expanded nodes, and the improved A*'s expansions relative to A*'s.

Notes
-----
- Data: N. Sturtevant, "Benchmarks for Grid-Based Pathfinding", IEEE TCIAIG
  4(2):144-148, 2012 (https://www.movingai.com/benchmarks/grids.html, ODC-BY).
  Their ``optimal_length`` is the octile length without corner cutting,
  exactly the 8-neighbourhood cost model of :mod:`fusion_planner.core.global_planning.search`.
- Time is the wall time of :func:`~fusion_planner.core.global_planning.search.grid_search`
  alone (the map is prepared once per map, as a planner bound to one map
  does). Rows run in a shuffled order so that the ETA shown on stderr is
  unbiased; the results do not depend on the order.
- A full run is long in pure Python (about half an hour per algorithm on the
  five maps of ``../shared/benchmarks/movingai``, mostly the maze's 12,120
  rows); ``--jobs`` spreads the rows over processes, ``--rows`` samples.
"""

import concurrent.futures
import json
import math
import os
import pathlib
import random
import statistics
import time
from dataclasses import asdict, dataclass, field, replace

from fusion_planner.cli.progress import Progress
from fusion_planner.core.global_planning import landmarks, search
from fusion_planner.core.errors import (
    InvalidInput, MapError, NoValidPathCouldBeFound, PlannerTimedOut)
from fusion_planner.core.map_files import load_movingai, movingai_cell, read_scenarios
from fusion_planner.core.global_planning.planner import PlannerConfig

EXIT_OK, EXIT_FAILED, EXIT_BAD_INPUT = 0, 1, 2

#: Algorithms of this benchmark, in table order. ``astar`` is A* with the
#: 8-neighbourhood and the octile heuristic, expanding cell by cell;
#: ``jps`` the same with jump-point pruning.
ALGORITHMS = ('astar', 'jps', 'dijkstra', 'improved')
#: The algorithms that must return exactly ``optimal_length``.
OPTIMAL_ALGORITHMS = ('astar', 'jps', 'dijkstra')
#: Labels of the algorithms in the table.
LABELS = {'astar': 'A*-8', 'jps': 'A*-8 jump points', 'dijkstra': 'Dijkstra',
          'improved': 'improved A*'}
#: Largest accepted gap to the file's ``optimal_length`` [cells]; the file
#: rounds to 8 decimals, so 1e-4 leaves room for summation order only.
OPTIMAL_TOLERANCE = 1e-4
#: Where the maps and scenarios are published.
DATA_URL = 'https://www.movingai.com/benchmarks/grids.html'
#: Environment variable that overrides the default data folder.
DATA_ENV = 'FUSION_PLANNER_BENCHMARKS'
#: Seed of the shuffled row order (the order only affects the ETA).
ORDER_SEED = 20120601
#: Rows per task handed to a worker process with ``--jobs`` > 1.
CHUNK_ROWS = 25
#: Failed rows listed in the text report.
MAX_LISTED_FAILURES = 10


@dataclass
class RowOutcome:
    """One algorithm on one scenario row.

    Attributes
    ----------
    found : bool
    length : float
        Path cost [cells]; NaN when not found.
    expanded : int
        Expanded nodes (those of the failed search when not found).
    time_s : float
        Search wall time [s].
    error : str or None
        The error sentence when no path was found.
    """

    found: bool
    length: float
    expanded: int
    time_s: float
    error: str = None


@dataclass
class Summary:
    """Figures of one algorithm on one map (or on all maps: ``map == 'ALL'``).

    Attributes
    ----------
    map, algorithm : str
    rows, found : int
    exact : int or None
        Rows within :data:`OPTIMAL_TOLERANCE` of ``optimal_length``; None for
        the improved A* (not an optimal algorithm).
    ratio_median, ratio_mean, ratio_max : float
        Path length / ``optimal_length`` over the rows found (rows with
        optimal length 0 count as 1).
    time_total_s, time_median_s : float
        Search wall time [s].
    expanded_median : float
    expansion_ratio : float or None
        Improved A* only: its total expanded nodes over A*-8's, on the rows
        both solved (None when A*-8 did not run).
    expansion_ratio_median : float or None
        Improved A* only: median of the per-row ratio.
    """

    map: str
    algorithm: str
    rows: int
    found: int
    exact: int = None
    ratio_median: float = math.nan
    ratio_mean: float = math.nan
    ratio_max: float = math.nan
    time_total_s: float = 0.0
    time_median_s: float = math.nan
    expanded_median: float = math.nan
    expansion_ratio: float = None
    expansion_ratio_median: float = None


@dataclass
class ScenarioSet:
    """One map and the rows of its scenario file to run.

    Attributes
    ----------
    name : str
        Map file stem, e.g. ``'arena2'``.
    map_path, scen_path : pathlib.Path
    rows : list of ScenarioRow
        The selected rows.
    line_numbers : list of int
        Line of each selected row in the scenario file (1-based).
    """

    name: str
    map_path: pathlib.Path
    scen_path: pathlib.Path
    rows: list = field(default_factory=list)
    line_numbers: list = field(default_factory=list)


def default_data_dir():
    """The folder the benchmark reads when ``--maps`` is not given.

    Returns
    -------
    pathlib.Path
        ``$FUSION_PLANNER_BENCHMARKS`` when set, else
        ``<repository>/../shared/benchmarks/movingai`` (beside a clone).
    """
    if os.environ.get(DATA_ENV):
        return pathlib.Path(os.environ[DATA_ENV])
    repository = pathlib.Path(__file__).resolve().parents[2]
    return repository.parent / 'shared' / 'benchmarks' / 'movingai'


def missing_data(where, alternative=None):
    """The :class:`MapError` of MovingAI data that is not there, saying where to get it.

    Parameters
    ----------
    where : str or os.PathLike
        The missing folder or file.
    alternative : str, optional
        Another way out, e.g. ``'give --quick'``.
    """
    other = f', or {alternative}' if alternative else ''
    return MapError(f'MovingAI benchmark data {where} not found: put the maps and their '
                    f'scenarios (NAME.map, NAME.map.scen from {DATA_URL}) in a folder and give '
                    f'--maps DIR (or set {DATA_ENV}){other}')


def sample_rows(rows, count=None):
    """Pick ``count`` rows spread evenly over the difficulty buckets.

    Parameters
    ----------
    rows : sequence of ScenarioRow
    count : int or None
        Rows to keep, > 0; None (or at least ``len(rows)``) keeps all.

    Returns
    -------
    list of int
        Indices into ``rows``, ordered by bucket then file order. Rows are
        taken every ``len(rows) / count`` positions of that order, so every
        part of the difficulty range is represented; the choice is
        deterministic.

    Examples
    --------
    >>> from types import SimpleNamespace
    >>> rows = [SimpleNamespace(bucket=b) for b in (0, 0, 1, 1, 2, 2)]
    >>> sample_rows(rows, 3)
    [0, 2, 4]
    """
    order = sorted(range(len(rows)), key=lambda i: (rows[i].bucket, i))
    if count is None or count >= len(order):
        return order
    if count < 1:
        raise InvalidInput(f'the number of rows to sample must be positive, got {count!r}')
    return [order[i * len(order) // count] for i in range(count)]


def find_scenario_sets(folder, rows_per_map=None, only=None):
    """The maps of a folder with their (sampled) scenario rows.

    Parameters
    ----------
    folder : str or os.PathLike
        Holds ``NAME.map`` and ``NAME.map.scen`` pairs.
    rows_per_map : int or None
        Rows per scenario file (:func:`sample_rows`); None for all.
    only : sequence of str, optional
        Keep the maps whose stem contains one of these strings.

    Returns
    -------
    list of ScenarioSet
        Sorted by map name.

    Raises
    ------
    MapError
        If the folder is missing or holds no scenario file, a scenario's map
        is missing, or a row's size disagrees with its map's header.
    InvalidInput
        If a name of ``only`` matches no map.
    """
    folder = pathlib.Path(folder)
    if not folder.is_dir():
        raise missing_data(folder)
    scen_paths = sorted(folder.glob('*.map.scen'))
    if not scen_paths:
        raise MapError(f'no MovingAI scenario file (*.map.scen) in {folder}')
    sets = []
    for scen_path in scen_paths:
        map_path = scen_path.with_suffix('')  # NAME.map.scen -> NAME.map
        name = map_path.stem
        if only and not any(part in name for part in only):
            continue
        if not map_path.is_file():
            raise MapError(f'scenario file {scen_path} has no map {map_path.name} beside it')
        rows = read_scenarios(scen_path)
        chosen = sample_rows(rows, rows_per_map)
        sets.append(ScenarioSet(name, map_path, scen_path, [rows[i] for i in chosen],
                                [i + 2 for i in chosen]))  # + version line, 1-based
    if only:
        for part in only:
            if not any(part in s.name for s in sets):
                raise InvalidInput(f'--only {part!r} matches no map in {folder}')
    return sets


def policies(algorithms, config=None):
    """Search policies of the benchmark's algorithms.

    Parameters
    ----------
    algorithms : sequence of str
        Names from :data:`ALGORITHMS`.
    config : PlannerConfig, optional
        Settings of the improved A* (default :class:`PlannerConfig`: its
        weights and heuristic) and whether the exact A* uses landmark
        bounds; the neighbourhood is forced to 8, the benchmark's cost
        model.

    Returns
    -------
    dict of str to SearchPolicy
    """
    config = config or PlannerConfig()
    table = {
        'astar': search.astar(8, 'octile', landmarks=config.landmarks),
        'jps': search.astar(8, 'octile', jump_points=True, landmarks=config.landmarks),
        'dijkstra': search.dijkstra(8),
        'improved': replace(config, algorithm='improved', neighbourhood=8).policy(),
    }
    unknown = [name for name in algorithms if name not in table]
    if unknown:
        raise InvalidInput(f'unknown algorithm {unknown[0]!r}; choose from {ALGORITHMS}')
    return {name: table[name] for name in algorithms}


class PreparedMap:
    """A MovingAI map loaded once and its search grid (radius 0).

    The grid gets the landmarks the planner's ``prepare`` gives an exact A*
    on a map of this size (:mod:`~fusion_planner.core.global_planning.landmarks`),
    so the rows check the A* the planner runs; the other policies ignore them.

    Parameters
    ----------
    map_path : str or os.PathLike
    with_landmarks : bool
        False: no landmarks (the A* with its plain heuristic).
    """

    def __init__(self, map_path, with_landmarks=True):
        self.grid = load_movingai(map_path)
        self.padded = search.PaddedGrid(self.grid.traversable(0.0))
        if landmarks.wanted(self.grid.shape, search.astar(8, landmarks=with_landmarks)):
            self.padded.landmarks = landmarks.distance_table(self.padded)

    def solve(self, row, policy):
        """Run one policy on one scenario row.

        Parameters
        ----------
        row : ScenarioRow
        policy : SearchPolicy

        Returns
        -------
        RowOutcome

        Raises
        ------
        MapError
            If the row's map size differs from this map's.
        """
        height, width = self.grid.shape
        if (row.width, row.height) != (width, height):
            raise MapError(f'scenario row for {row.map_name} says {row.width} x {row.height} '
                           f'but the map is {width} x {height}')
        start = movingai_cell(row.start_col, row.start_row, height)
        goal = movingai_cell(row.goal_col, row.goal_row, height)
        t0 = time.perf_counter()
        try:
            found = search.grid_search(self.padded, start, goal, policy)
        except (NoValidPathCouldBeFound, PlannerTimedOut) as err:
            return RowOutcome(False, math.nan, 0, time.perf_counter() - t0, str(err))
        return RowOutcome(True, found.cost, found.expanded, time.perf_counter() - t0)


def _solve_chunk(map_path, rows, algorithms, config):
    """Worker task: every algorithm on some rows of one map.

    Returns a list (per row) of dicts algorithm -> RowOutcome.
    """
    prepared = PreparedMap(map_path, config.landmarks)
    table = policies(algorithms, config)
    return [{name: prepared.solve(row, table[name]) for name in algorithms} for row in rows]


def run_benchmark(sets, algorithms, config=None, jobs=1, progress=None):
    """Run the algorithms on every selected row.

    Parameters
    ----------
    sets : list of ScenarioSet
    algorithms : sequence of str
    config : PlannerConfig, optional
        Weights of the improved A*, and whether A* uses landmarks.
    jobs : int
        Worker processes; 1 runs in this process.
    progress : Progress, optional

    Returns
    -------
    list of list of dict
        ``outcomes[i][k][name]`` is the RowOutcome of algorithm ``name`` on
        row ``k`` of ``sets[i]``.
    """
    if jobs < 1:
        raise InvalidInput(f'--jobs must be at least 1, got {jobs}')
    config = config or PlannerConfig()
    policies(algorithms, config)  # validate names before any work
    outcomes = [[None] * len(s.rows) for s in sets]
    order = [(i, k) for i, s in enumerate(sets) for k in range(len(s.rows))]
    random.Random(ORDER_SEED).shuffle(order)
    if jobs == 1:
        prepared = [PreparedMap(s.map_path, config.landmarks) for s in sets]
        table = policies(algorithms, config)
        for i, k in order:
            row = sets[i].rows[k]
            outcomes[i][k] = {name: prepared[i].solve(row, table[name]) for name in algorithms}
            if progress is not None:
                progress.advance(1)
        return outcomes
    chunks = _chunks(order, len(sets))
    with concurrent.futures.ProcessPoolExecutor(max_workers=jobs) as pool:
        futures = {
            pool.submit(_solve_chunk, sets[i].map_path, [sets[i].rows[k] for k in ks],
                        tuple(algorithms), config): (i, ks)
            for i, ks in chunks}
        for future in concurrent.futures.as_completed(futures):
            i, ks = futures[future]
            for k, outcome in zip(ks, future.result()):
                outcomes[i][k] = outcome
            if progress is not None:
                progress.advance(len(ks))
    return outcomes


def _chunks(order, set_count):
    """Group a shuffled (set, row) order into per-map chunks, order kept."""
    pending = [[] for _ in range(set_count)]
    chunks = []
    for i, k in order:
        pending[i].append(k)
        if len(pending[i]) == CHUNK_ROWS:
            chunks.append((i, pending[i]))
            pending[i] = []
    chunks += [(i, ks) for i, ks in enumerate(pending) if ks]
    return chunks


def summarise(sets, outcomes, algorithms):
    """Per map and algorithm figures, then the same over all maps.

    Parameters
    ----------
    sets : list of ScenarioSet
    outcomes : as returned by :func:`run_benchmark`
    algorithms : sequence of str

    Returns
    -------
    summaries : list of Summary
    failures : list of dict
        One per row where an algorithm found no path or an optimal one
        missed ``optimal_length``: map, line, algorithm, start, goal,
        optimal and found length, error.
    """
    summaries, failures = [], []
    pooled = {name: [] for name in algorithms}
    for scenario_set, per_row in zip(sets, outcomes):
        pairs = list(zip(scenario_set.rows, per_row))
        for name in algorithms:
            summaries.append(_summary(scenario_set.name, name, pairs))
            pooled[name] += pairs
        for line, row, result in zip(scenario_set.line_numbers, scenario_set.rows, per_row):
            for name in algorithms:
                outcome = result[name]
                exact = abs(outcome.length - row.optimal_length) <= OPTIMAL_TOLERANCE
                if outcome.found and (exact or name not in OPTIMAL_ALGORITHMS):
                    continue
                failures.append({
                    'map': scenario_set.name, 'line': line, 'algorithm': name,
                    'start': [row.start_col, row.start_row], 'goal': [row.goal_col, row.goal_row],
                    'optimal_length': row.optimal_length,
                    'length': outcome.length if outcome.found else None,
                    'error': outcome.error})
    if len(sets) > 1:
        summaries += [_summary('ALL', name, pooled[name]) for name in algorithms]
    return summaries, failures


def _summary(map_name, name, pairs):
    """A Summary of one algorithm over (row, outcomes) pairs."""
    outcomes = [(row, result[name]) for row, result in pairs]
    found = [(row, o) for row, o in outcomes if o.found]
    summary = Summary(map=map_name, algorithm=name, rows=len(outcomes), found=len(found))
    if name in OPTIMAL_ALGORITHMS:
        summary.exact = sum(abs(o.length - row.optimal_length) <= OPTIMAL_TOLERANCE
                            for row, o in found)
    times = [o.time_s for _, o in outcomes]
    if times:
        summary.time_total_s = math.fsum(times)
        summary.time_median_s = statistics.median(times)
    if found:
        ratios = [o.length / row.optimal_length if row.optimal_length > 0 else 1.0
                  for row, o in found]
        summary.ratio_median = statistics.median(ratios)
        summary.ratio_mean = statistics.fmean(ratios)
        summary.ratio_max = max(ratios)
        summary.expanded_median = statistics.median(o.expanded for _, o in found)
    if name == 'improved':
        both = [(result['improved'].expanded, result['astar'].expanded) for _, result in pairs
                if 'astar' in result and result['improved'].found and result['astar'].found
                and result['astar'].expanded > 0]
        if both:
            summary.expansion_ratio = sum(i for i, _ in both) / sum(a for _, a in both)
            summary.expansion_ratio_median = statistics.median(i / a for i, a in both)
    return summary


def format_table(summaries, failures, header):
    """The text report: one line per map and algorithm, then failures."""
    lines = [header, '',
             f'{"map":<16}{"algorithm":<13}{"rows":>6}{"found":>7}{"exact":>7}'
             f'{"ratio":>9}{"ratio":>9}{"ratio":>9}{"time":>9}{"time":>9}{"expanded":>10}'
             f'{"exp/A*-8":>10}',
             f'{"":<16}{"":<13}{"":>6}{"":>7}{"":>7}{"median":>9}{"mean":>9}{"max":>9}'
             f'{"tot [s]":>9}{"med[ms]":>9}{"median":>10}{"total":>10}']
    for index, s in enumerate(summaries):
        if s.map == 'ALL' and summaries[index - 1].map != 'ALL':
            lines.append('-' * len(lines[-1]))
        exact = '-' if s.exact is None else str(s.exact)
        exp_ratio = '-' if s.expansion_ratio is None else f'{s.expansion_ratio:.3f}'
        lines.append(
            f'{s.map:<16}{LABELS[s.algorithm]:<13}{s.rows:>6}{s.found:>7}{exact:>7}'
            f'{s.ratio_median:>9.4f}{s.ratio_mean:>9.4f}{s.ratio_max:>9.4f}'
            f'{s.time_total_s:>9.1f}{s.time_median_s * 1e3:>9.1f}{s.expanded_median:>10.0f}'
            f'{exp_ratio:>10}')
    if failures:
        lines += ['', f'{len(failures)} failed row(s) (no path, or not optimal_length):']
        for f in failures[:MAX_LISTED_FAILURES]:
            got = 'no path' if f['length'] is None else f'{f["length"]:.8f}'
            lines.append(f'  {f["map"]} line {f["line"]} {LABELS[f["algorithm"]]}: start '
                         f'{tuple(f["start"])} goal {tuple(f["goal"])} optimal '
                         f'{f["optimal_length"]:.8f} got {got}')
        if len(failures) > MAX_LISTED_FAILURES:
            lines.append(f'  ... and {len(failures) - MAX_LISTED_FAILURES} more (see --json)')
    return '\n'.join(lines)


def _rows_arg(text):
    """``--rows``: a positive integer or ``all``."""
    if text.strip().lower() == 'all':
        return None
    try:
        value = int(text)
    except ValueError:
        value = 0
    if value < 1:
        raise InvalidInput(f'--rows must be a positive integer or "all", got {text!r}')
    return value


def add_arguments(parser):
    """Options of ``fusion-planner bench movingai``."""
    defaults = PlannerConfig()
    parser.add_argument('--maps', metavar='DIR', default=None,
                        help='folder of NAME.map and NAME.map.scen files (default: '
                             f'${DATA_ENV}, else ../shared/benchmarks/movingai beside the '
                             'repository)')
    parser.add_argument('--rows', metavar='N|all', default='all',
                        help='rows per scenario file, sampled evenly over the buckets '
                             '(default all)')
    parser.add_argument('--algorithms', nargs='+', choices=ALGORITHMS, default=list(ALGORITHMS),
                        metavar='NAME',
                        help=f'any of {", ".join(ALGORITHMS)} (default all; astar is the '
                             '8-neighbourhood A* with the octile heuristic)')
    parser.add_argument('--only', nargs='+', metavar='NAME', default=None,
                        help='run only the maps whose name contains one of these strings')
    parser.add_argument('--jobs', type=int, default=1, metavar='N',
                        help='worker processes (default 1)')
    parser.add_argument('--alpha', type=float, default=defaults.alpha,
                        help='improved A*: weight of g, eq. (5) (default %(default)s)')
    parser.add_argument('--beta', type=float, default=defaults.beta,
                        help='improved A*: weight of h, eq. (5) (default %(default)s)')
    parser.add_argument('--gamma', type=float, default=defaults.gamma,
                        help='improved A*: gain of the heuristic weight w_n, eqs. (6)-(8) '
                             '(default %(default)s)')
    parser.add_argument('--no-landmarks', action='store_true',
                        help='A* with its plain octile heuristic, without the landmark bounds '
                             'the planner prepares')
    parser.add_argument('--no-progress', action='store_true',
                        help='do not report progress on stderr')
    parser.add_argument('--json', action='store_true', help='print one JSON object')


def run(args):
    """Run the benchmark from parsed options; returns the exit status.

    Returns
    -------
    int
        0 when every algorithm found a path on every row and A*-8 and
        Dijkstra matched ``optimal_length`` on every row, 1 otherwise.

    Raises
    ------
    MapError, InvalidInput
        Missing data folder or files, bad options (exit 2 through the CLI).
    """
    rows_per_map = _rows_arg(args.rows)
    config = PlannerConfig(alpha=args.alpha, beta=args.beta, gamma=args.gamma, refine=False,
                           landmarks=not args.no_landmarks)
    algorithms = [name for name in ALGORITHMS if name in args.algorithms]
    folder = pathlib.Path(args.maps) if args.maps else default_data_dir()
    sets = find_scenario_sets(folder, rows_per_map, args.only)
    total = sum(len(s.rows) for s in sets)
    progress = None if args.no_progress else Progress(total, 'movingai', unit='rows')
    t0 = time.perf_counter()
    outcomes = run_benchmark(sets, algorithms, config, args.jobs, progress)
    if progress is not None:
        progress.finish()
    elapsed = time.perf_counter() - t0
    summaries, failures = summarise(sets, outcomes, algorithms)
    improved = policies(['improved'], config)['improved']
    if args.json:
        print(json.dumps(_strict({
            'maps_dir': str(folder), 'rows_per_map': rows_per_map or 'all',
            'algorithms': algorithms, 'tolerance': OPTIMAL_TOLERANCE,
            'improved': asdict(improved),
            'elapsed_s': elapsed, 'summaries': [asdict(s) for s in summaries],
            'failures': failures})))
    else:
        header = (f'MovingAI benchmark: {folder}, {total} rows '
                  f'({"all" if rows_per_map is None else rows_per_map} per map), radius 0, no '
                  f'refinement; A* {"with" if config.landmarks else "without"} landmarks; '
                  f'improved A*: {improved.heuristic} heuristic, alpha '
                  f'{improved.alpha:g} beta {improved.beta:g} gamma {improved.gamma:g}; '
                  f'{elapsed:.1f} s wall')
        print(format_table(summaries, failures, header))
    return EXIT_FAILED if failures else EXIT_OK


def _strict(value):
    """``value`` with non-finite floats replaced by None (strict JSON)."""
    if isinstance(value, dict):
        return {key: _strict(item) for key, item in value.items()}
    if isinstance(value, (list, tuple)):
        return [_strict(item) for item in value]
    if isinstance(value, float) and not math.isfinite(value):
        return None
    return value
