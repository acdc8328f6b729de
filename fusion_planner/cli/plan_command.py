"""``fusion-planner plan``: plan once on a map file and report or draw the result.

Usage::

    fusion-planner plan --map FILE --start X Y --goal X Y [--cells]
        [--algorithm dijkstra|astar|improved] [--neighbourhood 4|8|16]
        [--no-refine] [--robot-radius M] [--safety-distance M]
        [--json] [--plot PNG]

This is a contract other tools rely on:

- ``FILE`` is a map_server ``.yaml`` (with its PGM/PNG image) or a MovingAI
  ``.map``.
- Without ``--cells``, X Y are metres in the map frame. With ``--cells`` they
  are integer cell indices, column then row, row 0 being the first row of
  the file as stored (the top image row; the first line after ``map`` in a
  MovingAI file), exactly as in MovingAI ``.scen`` files. The cell's centre
  is planned from / to.
- ``--json`` prints exactly one JSON object on stdout, also on failure:
  ``found`` (bool), ``length_m``, ``expanded``, ``key_points``,
  ``turning_deg``, ``min_clearance_m``, ``time_s`` (numbers, null when no
  path; ``min_clearance_m`` is also null on a map without obstacles, where
  it is infinite), ``path`` (list of ``[x, y]`` [m], map frame; empty when
  no path) and ``error`` (null, or one sentence).
- Exit status: 0 a path was found, 1 no path exists (or the search budget
  ran out), 2 bad input (unreadable map, start or goal outside the map or in
  an obstacle, NaN, bad options, a ``--plot`` file that cannot be written,
  the ``plot`` extra missing). ``--plot`` is checked before planning (see
  :mod:`fusion_planner.cli.output_paths` and
  :mod:`fusion_planner.cli.requirements`). Errors are one line on stderr,
  never a traceback.
- Defaults: the improved A*, the 8-neighbourhood, refinement on, and a
  robot radius and safety distance of 0 m for every map file (map files
  carry no robot; give ``--robot-radius`` / ``--safety-distance`` for a real
  robot). Unknown cells of map_server maps are free.
"""

import argparse
import json
import math
import sys

from fusion_planner.cli.output_paths import prepare_file
from fusion_planner.cli.plotting import plan_title, plot_plan
from fusion_planner.cli.requirements import require
from fusion_planner.core.errors import (
    GoalOutsideMapBounds, InvalidInput, NoValidPathCouldBeFound, PlannerTimedOut,
    PlanningError, StartOutsideMapBounds)
from fusion_planner.core.map_files import load_map, movingai_cell
from fusion_planner.core.global_planning.planner import ALGORITHMS, GlobalPlanner, PlannerConfig

EXIT_OK, EXIT_NO_PATH, EXIT_BAD_INPUT = 0, 1, 2

#: Suffix of MovingAI map files (their cells follow ``.scen`` coordinates).
MOVINGAI_SUFFIX = '.map'

_ALGORITHM_NAMES = {'dijkstra': 'Dijkstra', 'astar': 'A*', 'improved': 'improved A*'}


def add_parser(subparsers):
    """Register the ``plan`` sub-command."""
    parser = subparsers.add_parser(
        'plan', help='plan a path on a map file',
        description='Plan one global path on a map_server .yaml or MovingAI .map file '
                    'and print its metrics (or JSON), optionally drawing it. Exit status: '
                    '0 path found, 1 no path, 2 bad input.')
    parser.add_argument('--map', required=True, metavar='FILE',
                        help='map_server .yaml (with its image) or MovingAI .map')
    parser.add_argument('--start', required=True, nargs=2, type=_number, metavar=('X', 'Y'),
                        help='start: metres in the map frame, or cells with --cells')
    parser.add_argument('--goal', required=True, nargs=2, type=_number, metavar=('X', 'Y'),
                        help='goal: metres in the map frame, or cells with --cells')
    parser.add_argument('--cells', action='store_true',
                        help='X Y are integer cells: column, then row counted from the first '
                             'row of the file as stored (top image row), as in MovingAI .scen')
    parser.add_argument('--algorithm', choices=ALGORITHMS, default='improved',
                        help='search algorithm (default: %(default)s, the paper\'s improved A*)')
    parser.add_argument('--neighbourhood', type=int, choices=(4, 8, 16), default=8,
                        help='search neighbourhood (default: %(default)s)')
    parser.add_argument('--no-refine', action='store_true',
                        help='keep the raw grid path (no redundant-node removal or smoothing)')
    parser.add_argument('--robot-radius', type=_number, default=0.0, metavar='M',
                        help='robot radius [m]; obstacles are inflated by it (default 0)')
    parser.add_argument('--safety-distance', type=_number, default=0.0, metavar='M',
                        help='extra distance [m] a refined path keeps from obstacles (default 0)')
    parser.add_argument('--json', action='store_true',
                        help='print one JSON object with the result instead of a summary')
    parser.add_argument('--plot', metavar='PNG',
                        help='draw the map, searched cells, path and key nodes into PNG')
    parser.set_defaults(func=run)
    return parser


def run(args):
    """Run ``plan``; returns the exit status (0 found, 1 no path, 2 bad input).

    Raises
    ------
    MissingExtra, OutputPathError
        ``--plot`` without the ``plot`` extra or into a path that cannot be
        written (before any planning).
    """
    if args.plot:
        require('plot', 'plan --plot')
        prepare_file(args.plot, '--plot')
    grid = start = goal = result = None
    error = None
    try:
        grid = load_map(args.map)
        start, goal = endpoints(args, grid)
        config = PlannerConfig(
            algorithm=args.algorithm, neighbourhood=args.neighbourhood,
            refine=not args.no_refine, robot_radius=args.robot_radius,
            safety_distance=args.safety_distance)
        result = GlobalPlanner(grid, config).plan(start, goal, return_expanded=bool(args.plot))
        status = EXIT_OK
    except (NoValidPathCouldBeFound, PlannerTimedOut) as err:
        status, error = EXIT_NO_PATH, str(err)
    except PlanningError as err:
        status, error = EXIT_BAD_INPUT, str(err)

    if args.plot and grid is not None:
        plot_error = _plot(args, result, grid, start, goal)
        if plot_error is not None:
            status = EXIT_BAD_INPUT
            error = plot_error if error is None else f'{error}; {plot_error}'

    if args.json:
        print(json.dumps(result_json(result, error)))
    elif result is not None:
        print(summary(result, args))
    if error is not None:
        print(f'error: {error}', file=sys.stderr)
    return status


def endpoints(args, grid):
    """Start and goal ``(x, y)`` [m] from the parsed options.

    Parameters
    ----------
    args : argparse.Namespace
        With ``start``, ``goal`` (two floats each), ``cells`` and ``map``.
    grid : GridMap
        The loaded map.

    Returns
    -------
    start, goal : tuple of float
        Map-frame points [m]; with ``--cells`` the centres of the cells.

    Raises
    ------
    InvalidInput
        With ``--cells``, a coordinate that is not an integer.
    StartOutsideMapBounds, GoalOutsideMapBounds
        With ``--cells``, a cell outside the map.
    """
    if not args.cells:
        return tuple(args.start), tuple(args.goal)
    movingai = str(args.map).lower().endswith(MOVINGAI_SUFFIX)
    start = cell_centre(grid, args.start, 'start', StartOutsideMapBounds, movingai)
    goal = cell_centre(grid, args.goal, 'goal', GoalOutsideMapBounds, movingai)
    return start, goal


def cell_centre(grid, col_row, name, outside_error, movingai):
    """Centre [m] of a cell given as (column, file row), file row 0 on top.

    Parameters
    ----------
    grid : GridMap
    col_row : sequence of 2 float
        Column and row as typed; the row counts from the first row of the
        file as stored (the top image row), as in MovingAI ``.scen`` files.
    name : str
        ``'start'`` or ``'goal'``, for messages.
    outside_error : type
        Exception raised when the cell is outside the map.
    movingai : bool
        The map is a MovingAI ``.map`` (converted with
        :func:`~fusion_planner.core.map_files.movingai_cell`); otherwise an
        image map, whose top row is grid row ``H - 1`` as well.

    Returns
    -------
    tuple of float
        ``(x, y)`` [m], map frame.
    """
    col, file_row = col_row
    if not all(math.isfinite(v) and v == int(v) for v in (col, file_row)):
        raise InvalidInput(
            f'with --cells the {name} must be two integer cell indices (column row), '
            f'got {_fmt_number(col)} {_fmt_number(file_row)}')
    col, file_row = int(col), int(file_row)
    if not (0 <= col < grid.width and 0 <= file_row < grid.height):
        raise outside_error(
            f'{name} cell (column {col}, row {file_row}) is outside the map of '
            f'{grid.width} x {grid.height} cells')
    if movingai:
        row, col = movingai_cell(col, file_row, grid.height)
    else:
        row = grid.height - 1 - file_row  # image rows run top-down
    x, y = grid.world_of((row, col))
    return float(x), float(y)


def result_json(result, error=None):
    """The ``--json`` object of a plan (or of a failure when ``result`` is None).

    Parameters
    ----------
    result : PlanResult or None
    error : str or None
        One sentence, or None.

    Returns
    -------
    dict
        Keys ``found``, ``length_m``, ``expanded``, ``key_points``,
        ``turning_deg``, ``min_clearance_m``, ``time_s``, ``path``, ``error``;
        only finite numbers or None, so that the JSON is strict.
    """
    if result is None:
        return {'found': False, 'length_m': None, 'expanded': None, 'key_points': None,
                'turning_deg': None, 'min_clearance_m': None, 'time_s': None,
                'path': [], 'error': error}
    m = result.metrics
    return {
        'found': True,
        'length_m': _finite(m.length_m),
        'expanded': int(m.expanded),
        'key_points': int(m.key_points),
        'turning_deg': _finite(m.turning_deg),
        'min_clearance_m': _finite(m.min_clearance_m),
        'time_s': _finite(m.time_s),
        'path': [[float(x), float(y)] for x, y in result.path],
        'error': error,
    }


def summary(result, args):
    """Short human-readable report of a plan (a few lines)."""
    m = result.metrics
    clearance = 'no obstacles' if not math.isfinite(m.min_clearance_m) \
        else f'{m.min_clearance_m:.3f} m'
    refined = 'raw grid path' if args.no_refine else 'refined'
    start, goal = result.path[0], result.path[-1]
    return '\n'.join([
        f'path found: ({start[0]:.3f}, {start[1]:.3f}) -> ({goal[0]:.3f}, {goal[1]:.3f}) m',
        f'  length {m.length_m:.3f} m, {len(result.path)} points, {m.key_points} key points, '
        f'turning {m.turning_deg:.1f} deg',
        f'  min clearance {clearance}, {m.expanded} cells expanded, '
        f'{m.time_s * 1e3:.2f} ms',
        f'  {_ALGORITHM_NAMES[args.algorithm]}, {args.neighbourhood}-neighbourhood, {refined}',
    ])


def _plot(args, result, grid, start, goal):
    """Draw the plan (or the failed request) into ``args.plot``; error text or None."""
    title = plan_title(result, _ALGORITHM_NAMES[args.algorithm])
    try:
        plot_plan(result, grid, args.plot, title=title, start=start, goal=goal)
    except (OSError, ValueError) as err:
        reason = getattr(err, 'strerror', None) or ' '.join(str(err).split())
        return f'cannot write plot {args.plot}: {reason}'
    return None


def _number(text):
    """argparse type: a float ('nan' and 'inf' pass here and are refused later)."""
    try:
        return float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f'not a number: {text!r}') from None


def _finite(value):
    value = float(value)
    return value if math.isfinite(value) else None


def _fmt_number(value):
    return f'{value:g}'
