"""Controllers on every scenario family: success, contacts, stuck runs, time, honest ends.

Runs N generated scenarios of each family (docs/SCENARIOS.md) with every
controller side by side and prints one Markdown table per family: success
on the solvable scenarios, the outcomes, contact events, the fraction of
runs with a stuck episode, the time over the optimal time, on unsolvable
scenarios the fraction ending ``no_path`` and the largest time from the
proof of unreachability to the end, and each controller's wall time.

Notes
-----
- The batch of a family is :func:`~fusion_planner.core.simulation.episodes.run_batch`
  with the same seed for every family (each family turns a seed into its
  own scenario); ``--jobs`` does not change the results, only the wall
  time.
- Wall time is summed over a controller's episodes in whichever process
  ran them; with ``--jobs`` above 1 the processes share the machine's
  cores, so compare wall times within one run only.
"""

import json

from fusion_planner.cli.progress import Progress
from fusion_planner.cli.sim_command import batch_table, quiet_core
from fusion_planner.core.errors import InvalidInput
from fusion_planner.core.simulation.dynamic_families import STRESS_FAMILIES
from fusion_planner.core.simulation.episodes import CONTROLLERS, run_batch
from fusion_planner.core.simulation.families import FAMILIES

EXIT_OK = 0
#: Default scenarios per family and batch seed.
DEFAULT_SCENARIOS = 50
DEFAULT_SEED = 0


def add_arguments(parser):
    """Options of ``fusion-planner bench families``."""
    parser.add_argument('--scenarios', type=int, default=DEFAULT_SCENARIOS, metavar='N',
                        help='scenarios per family (default %(default)s)')
    parser.add_argument('--seed', type=int, default=DEFAULT_SEED, metavar='S',
                        help='batch seed (default %(default)s)')
    parser.add_argument('--family', action='append', metavar='F',
                        help=f'one of {", ".join(FAMILIES)}; repeat for several (default all but '
                             f'the stress tests {", ".join(STRESS_FAMILIES)})')
    parser.add_argument('--controller', action='append', metavar='NAME',
                        help=f'one of {", ".join(CONTROLLERS)}; repeat for several (default all)')
    parser.add_argument('--jobs', type=int, default=1, metavar='J',
                        help='worker processes (default 1; results do not depend on it)')
    parser.add_argument('--json', action='store_true', help='print one JSON object')


def run(args):
    """Run the benchmark; returns the exit status (0).

    Raises
    ------
    InvalidInput
        A count below 1, a negative seed, an unknown family or controller.
    """
    for option, value, low in (('--scenarios', args.scenarios, 1), ('--jobs', args.jobs, 1),
                               ('--seed', args.seed, 0)):
        if value < low:
            raise InvalidInput(f'{option} must be at least {low}, got {value}')
    families = _chosen(args.family or [f for f in FAMILIES if f not in STRESS_FAMILIES],
                       FAMILIES, 'family')
    controllers = _chosen(args.controller, CONTROLLERS, 'controller')
    progress = Progress(args.scenarios * len(families), 'bench families', unit='scenarios')
    batches = []
    with quiet_core(args):
        for family in families:
            # run_batch reports after each scenario: one more done
            batches.append(run_batch(
                args.scenarios, args.seed, controllers=controllers, workers=args.jobs,
                family=family,
                progress=lambda _done, _total, family=family: progress.advance(1, status=family)))
    progress.finish()
    if args.json:
        print(json.dumps({'scenarios_per_family': args.scenarios, 'seed': args.seed,
                          'families': {b.family: b.as_dict() for b in batches}}))
    else:
        print('\n\n'.join(batch_table(b, wall_time=True) for b in batches))
    return EXIT_OK


def _chosen(names, known, what):
    """The names asked for (all of ``known`` when none), checked, without repeats."""
    names = list(dict.fromkeys(names or known))
    for name in names:
        if name not in known:
            raise InvalidInput(f'unknown {what} {name!r}; choose one of {", ".join(known)}')
    return names
