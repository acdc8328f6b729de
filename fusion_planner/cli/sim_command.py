"""``fusion-planner sim``: closed-loop simulation of one scenario or of a random batch.

Usage::

    fusion-planner sim --scenario FILE [--controller NAME] [--seed N] [--perception MODE]
        [--json] [--plot PNG] [--gif GIF]
    fusion-planner sim --random N [--family F] [--seed S] [--controller NAME ...]
        [--perception MODE ...] [--jobs J] [--json]

Contract:

- ``NAME`` is one of the controllers of
  :data:`~fusion_planner.core.simulation.episodes.CONTROLLERS`. A scenario
  runs ``fusion`` by default; a batch runs all of them side by side unless
  ``--controller`` is given (it may be repeated).
- ``--family F`` (batch only) picks the scenario family, one of ``mixed``
  (the default), ``clutter``, ``corridors``, ``narrow``, ``unreachable``
  (docs/SCENARIOS.md).
- ``MODE`` is what the controller is told about moving obstacles: ``scan``
  (what a tracker makes of the simulated laser scans; hidden people are
  unseen) or ``ideal`` (their true states). A scenario runs the file's
  ``perception`` (default ``scan``); a batch runs both side by side unless
  ``--perception`` is given (it may be repeated).
- ``--seed`` overrides the scenario's world seed (random walks, scan noise);
  for ``--random`` it is the batch seed (default 0): the same seed gives the
  same scenarios and the same results.
- ``--json`` prints one JSON object on stdout. A scenario: ``reached``,
  ``outcome`` (``reached``, ``no_path``, ``controller_failed``,
  ``collisions`` or ``time_limit``), ``collisions``, ``time_s``,
  ``path_length_m``, ``min_clearance_m``, ``stuck_events``, ``failure``
  (null or ``'<outcome>: <sentence>'``) plus ``scenario``, ``family``,
  ``solvable``, ``controller``, ``perception``, ``seed``, ``plan_length_m``,
  ``moving_collisions`` (the contacts a moving obstacle began),
  ``passive_collisions`` (those of them begun while the robot stood or
  retreated and could not have got out of the way),
  ``no_path_proven_at_s``, ``optimal_length_m``, ``optimal_time_s``,
  ``time_ratio`` and ``contacts`` (each contact event: where, how fast the
  robot moved, whom it touched and how it was judged). A batch:
  ``scenarios``, ``family``, ``seed``, ``wall_time_s``, ``controllers``
  (per controller the fields of
  :class:`~fusion_planner.core.simulation.episodes.ControllerSummary`) under
  the first perception, ``by_perception`` (the same per perception, when
  there are several) and
  ``episodes`` (one row per run).
- ``--plot PNG`` (scenario only) draws the run like the paper's Figures 5-6;
  ``--gif GIF`` (scenario only) writes it as an animation. Both need the
  ``plot`` extra; it and the paths are checked before the run
  (:mod:`fusion_planner.cli.requirements`, :mod:`fusion_planner.cli.output_paths`).
- A batch reports its progress with an estimated time to completion on
  stderr.
- Exit status: 0 the goal was reached (a batch: the batch completed), 1 the
  goal was not reached, 2 bad input (unreadable or invalid scenario, unknown
  controller, bad option, missing extra, unwritable output). Errors are one line on stderr, never a traceback.
"""

import contextlib
import json
import logging
import sys

from fusion_planner.cli.output_paths import prepare_file
from fusion_planner.cli.progress import Progress
from fusion_planner.cli.requirements import require
from fusion_planner.core.errors import PlanningError
from fusion_planner.core.simulation.episodes import CONTROLLERS
from fusion_planner.core.simulation.families import FAMILIES
from fusion_planner.core.simulation.perception import PERCEPTION_MODES

EXIT_OK, EXIT_NOT_REACHED, EXIT_BAD_INPUT = 0, 1, 2


def add_parser(subparsers):
    """Register the ``sim`` sub-command."""
    parser = subparsers.add_parser(
        'sim', help='simulate a controller on a scenario, or a batch of random scenarios',
        description='Closed-loop simulation: the improved A* plans on the known map, a local '
                    'controller drives a simulated robot among unknown and moving obstacles. '
                    'Exit status: 0 reached (batch: completed), 1 not reached, 2 bad input.')
    parser.add_argument('--scenario', metavar='FILE', help='scenario YAML (see docs/SCENARIOS.md)')
    parser.add_argument('--random', type=_count, metavar='N',
                        help='run a batch of N generated scenarios instead')
    parser.add_argument('--controller', action='append', metavar='NAME',
                        help=f'one of {", ".join(CONTROLLERS)}; default fusion for a scenario, '
                             'all of them for a batch; repeat to select several for a batch')
    parser.add_argument('--family', metavar='F',
                        help=f'scenario family of a batch, one of {", ".join(FAMILIES)} '
                             '(default mixed)')
    parser.add_argument('--perception', action='append', choices=PERCEPTION_MODES,
                        help='what the controller knows of moving obstacles: scan (tracked from '
                             'the laser) or ideal (true states); default the scenario\'s (scan), '
                             'both for a batch; repeat to select both for a batch')
    parser.add_argument('--seed', type=_seed, metavar='N',
                        help='world seed of a scenario (default: the file\'s), batch seed (default 0)')
    parser.add_argument('--jobs', type=_count, default=1, metavar='J',
                        help='worker processes for a batch (default 1; results do not depend on it)')
    parser.add_argument('--json', action='store_true', help='print one JSON object')
    parser.add_argument('--plot', metavar='PNG', help='draw the run (scenario only)')
    parser.add_argument('--gif', metavar='GIF', help='animate the run (scenario only)')
    parser.set_defaults(func=run)
    return parser


def run(args):
    """Run ``sim``; returns the exit status."""
    with quiet_core(args):
        return _run(args)


@contextlib.contextmanager
def quiet_core(args):
    """Silence the core's warnings unless ``--verbose``.

    Failures are reported in the results; the core's warnings (the
    controllers' failures) would repeat them.
    """
    core_logger = logging.getLogger('fusion_planner.core')
    level = core_logger.level
    if not getattr(args, 'verbose', False):
        core_logger.setLevel(logging.ERROR)
    try:
        yield
    finally:
        core_logger.setLevel(level)


def _run(args):
    try:
        controllers = _controllers(args)
        if (args.scenario is None) == (args.random is None):
            raise _BadInput('give exactly one of --scenario FILE or --random N')
        if args.random is not None:
            for option, value in (('--plot', args.plot), ('--gif', args.gif)):
                if value:
                    raise _BadInput(
                        f'{option} draws one scenario; it cannot be used with --random')
            return _run_batch(args, controllers)
        if args.family is not None:
            raise _BadInput('--family chooses generated scenarios; it needs --random N')
        if len(controllers) != 1:
            raise _BadInput('a scenario runs one controller; give --controller once')
        if args.perception and len(args.perception) != 1:
            raise _BadInput('a scenario runs one perception; give --perception once')
        _check_outputs(args)
        return _run_scenario(args, controllers[0])
    except (_BadInput, PlanningError) as err:
        print(f'error: {_one_line(err)}', file=sys.stderr)
        return EXIT_BAD_INPUT


class _BadInput(Exception):
    """A bad command line (reported as one line, exit 2)."""


def _controllers(args):
    names = args.controller or (['fusion'] if args.random is None else list(CONTROLLERS))
    for name in names:
        if name not in CONTROLLERS:
            raise _BadInput(f'unknown controller {name!r}; choose one of {", ".join(CONTROLLERS)}')
    return list(dict.fromkeys(names))


def _check_outputs(args):
    """``--plot`` and ``--gif``: the ``plot`` extra and writable paths, before the run."""
    for option, path in (('--plot', args.plot), ('--gif', args.gif)):
        if path:
            require('plot', f'sim {option}')
            prepare_file(path, option)


def _run_scenario(args, controller):
    from fusion_planner.core.simulation.scenario import load_scenario
    from fusion_planner.core.simulation.episodes import run_episode

    scenario = load_scenario(args.scenario)
    perception = args.perception[0] if args.perception else None
    result = run_episode(scenario, controller, seed=args.seed,
                         record=bool(args.plot or args.gif), perception=perception)
    if args.plot:
        try:
            from fusion_planner.cli.sim_plot import plot_episode
            plot_episode(scenario, result, args.plot)
        except (OSError, ValueError) as err:
            raise _BadInput(f'cannot write the plot {args.plot}: {err}') from None
    if args.gif:
        try:
            from fusion_planner.cli.animation import animate_episode
            animate_episode(scenario, result, args.gif, scenario.limits.dt)
        except (OSError, ValueError) as err:
            raise _BadInput(f'cannot write the animation {args.gif}: {err}') from None
    summary = result.summary()
    if args.json:
        print(json.dumps(summary))
    else:
        print(_episode_line(summary))
    return EXIT_OK if result.reached else EXIT_NOT_REACHED


def _run_batch(args, controllers):
    from fusion_planner.core.simulation.episodes import run_batch

    family = args.family or 'mixed'
    if family not in FAMILIES:
        raise _BadInput(f'unknown family {family!r}; choose one of {", ".join(FAMILIES)}')
    seed = 0 if args.seed is None else args.seed
    reporter = Progress(args.random, 'sim', unit='scenarios')
    batch = run_batch(args.random, seed, controllers=controllers,
                      progress=lambda done, _total: reporter.advance(done - reporter.done),
                      workers=args.jobs, family=family,
                      perceptions=args.perception or PERCEPTION_MODES)
    reporter.finish()
    if args.json:
        print(json.dumps(batch.as_dict()))
    else:
        print(batch_table(batch))
    return EXIT_OK


def _episode_line(s):
    outcome = 'reached' if s['reached'] else f'NOT reached ({s["failure"]})'
    return (f'{s["scenario"]} / {s["controller"]} / {s["perception"]} perception '
            f'(seed {s["seed"]}): {outcome}; '
            f'time {s["time_s"]:.1f} s (x{_num(s["time_ratio"])} the optimal path at top speed), '
            f'path {s["path_length_m"]:.2f} m, '
            f'collisions {s["collisions"]}, min clearance {_num(s["min_clearance_m"], "m")}, '
            f'stuck events {s["stuck_events"]}')


def batch_table(batch, wall_time=False):
    """The side-by-side table of a batch (Markdown, as in docs/ALGORITHM.md).

    Parameters
    ----------
    batch : BatchResult
    wall_time : bool
        Add a column with each controller's wall time [s].
    """
    header = ['controller', 'perception', 'success (solvable)', 'outcomes',
              'contacts (episodes; by moving; avoidable)',
              'runs with stuck', 'time / optimal', 'path / optimal', 'mean min clearance [m]',
              'no_path (unsolvable)', 'max proof-to-end [s]']
    if wall_time:
        header.append('wall time [s]')
    lines = [f'{batch.scenarios} {batch.family} scenarios, seed {batch.seed}, '
             f'{batch.wall_time_s:.0f} s wall time',
             '',
             '| ' + ' | '.join(header) + ' |',
             '|' + '---|' * len(header)]
    summaries = [s for by_name in batch.by_perception.values() for s in by_name.values()]
    for s in summaries:
        cells = [s.controller, s.perception, _rate(s.success_on_solvable, s.solvable_reached, s.solvable_episodes),
                 _outcomes(s.outcomes),
                 f'{s.collisions} ({s.episodes_with_collisions}; {s.moving_collisions}; '
                 f'{s.avoidable_collisions})',
                 _percent(s.stuck_run_fraction), _num(s.mean_time_ratio),
                 _num(s.path_length_over_optimal, digits=3), _num(s.mean_min_clearance_m),
                 _rate(s.no_path_fraction, round(s.no_path_fraction * s.unsolvable_episodes),
                       s.unsolvable_episodes)
                 if s.unsolvable_episodes else '-',
                 _num(s.max_no_path_delay_s, digits=1)]
        if wall_time:
            cells.append(f'{s.wall_time_s:.1f}')
        lines.append('| ' + ' | '.join(cells) + ' |')
    return '\n'.join(lines)


def _rate(fraction, count, total):
    return '-' if fraction is None else f'{100 * fraction:.1f}% ({count}/{total})'


def _percent(fraction):
    return '-' if fraction is None else f'{100 * fraction:.0f}%'


def _outcomes(counts):
    """The outcomes that happened, e.g. ``reached 48, time_limit 2``."""
    return ', '.join(f'{name} {n}' for name, n in counts.items() if n) or '-'


def _num(value, unit='', digits=2):
    if value is None:
        return '-'
    return f'{value:.{digits}f}' + (f' {unit}' if unit else '')


def _one_line(err):
    return ' '.join(str(err).split())


def _int_at_least(low, what):
    """An argparse type: an integer >= ``low``, else a one-line usage error naming ``what``."""
    import argparse

    def parse(text):
        try:
            value = int(text)
        except ValueError:
            value = None
        if value is None or value < low:
            raise argparse.ArgumentTypeError(f'expected {what}, got {text!r}')
        return value
    return parse


_count = _int_at_least(1, 'a positive integer')
_seed = _int_at_least(0, 'a non-negative integer seed')
