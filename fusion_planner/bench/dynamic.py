"""Closed loop among moving obstacles: scan perception against the ideal oracle.

Runs the fusion controller on generated scenarios of every family with
moving obstacles (:data:`MOVING_FAMILIES`),
each once with ``scan`` perception (the scan tracker) and once with
``ideal`` perception (true obstacle states), and reports per family and
perception the success rate, the contacts and which of them the robot could
have avoided, and the mean time of the successful runs.

Notes
-----
- Scenario seeds are ``batch_seeds(N, seed)`` of each family: a new
  ``--seed`` gives scenarios the controller was never tuned on.
- **Avoidable contacts**: every contact event that is not *passive* (a
  moving obstacle walking into a robot that stood still or retreated from
  it, when no simple escape begun up to 2 s earlier with the person in
  sight would have kept the robot clear;
  :class:`~fusion_planner.core.simulation.world.World` tells them apart as
  each contact begins, see its module notes): then the person walked into
  a robot that could not get away (people here ignore it). A robot driving
  across a person's way is in motion, not retreating, and one that stood
  where it could have stepped aside answers for the contact too.
"""

import concurrent.futures
import json

import numpy as np

from fusion_planner.bench.movingai import _strict
from fusion_planner.bench.peers import machine_summary
from fusion_planner.cli.progress import Progress
from fusion_planner.cli.sim_command import quiet_core
from fusion_planner.core.errors import InvalidInput
from fusion_planner.core.simulation.dynamic_families import DYNAMIC_FAMILIES, STRESS_FAMILIES
from fusion_planner.core.simulation.episodes import batch_seeds, run_episode
from fusion_planner.core.simulation.families import family_scenario
from fusion_planner.core.simulation.perception import PERCEPTION_MODES

EXIT_OK = 0
#: The scenario families whose difficulty includes moving obstacles (the stress
#: tests aside, which run only when asked for).
MOVING_FAMILIES = ('mixed', 'corridors') + tuple(f for f in DYNAMIC_FAMILIES
                                                 if f not in STRESS_FAMILIES)
#: Default scenarios per family and batch seed; quick mode's scenarios.
DEFAULT_SCENARIOS = 50
DEFAULT_SEED = 101
QUICK_SCENARIOS = 1


def run_one(family, scenario_seed):
    """Both perceptions on one scenario of a family; one row per perception."""
    scenario = family_scenario(family, scenario_seed)
    rows = []
    for mode in PERCEPTION_MODES:
        result = run_episode(scenario, 'fusion', record=False, perception=mode)
        rows.append({'family': family, 'perception': mode, 'scenario': scenario.name,
                     'reached': bool(result.reached), 'collisions': result.collisions,
                     'avoidable': result.collisions - result.passive_collisions,
                     'time_s': float(result.time_s), 'failure': result.failure})
    return rows


def run_families(n, seed, families, workers=1, progress=None):
    """Every family's ``n`` scenarios under both perceptions; the episode rows."""
    tasks = [(family, s) for family in families for s in batch_seeds(n, seed)]
    rows = []
    if workers == 1:
        for done, task in enumerate(tasks, start=1):
            rows += run_one(*task)
            if progress is not None:
                progress(done)
    else:
        with concurrent.futures.ProcessPoolExecutor(max_workers=workers) as pool:
            futures = [pool.submit(run_one, *task) for task in tasks]
            for done, future in enumerate(concurrent.futures.as_completed(futures), start=1):
                rows += future.result()
                if progress is not None:
                    progress(done)
    order = {(f, s): i for i, (f, s) in enumerate(tasks)}
    rows.sort(key=lambda r: (order[(r['family'], int(r['scenario'].rsplit('-', 1)[1]))],
                             PERCEPTION_MODES.index(r['perception'])))
    return rows


def summarise(rows, families):
    """Per family and perception: episodes, success rate, contacts, avoidable ones, mean time."""
    out = []
    for family in families:
        for mode in PERCEPTION_MODES:
            mine = [r for r in rows if r['family'] == family and r['perception'] == mode]
            ok = [r for r in mine if r['reached']]
            out.append({
                'family': family, 'perception': mode, 'episodes': len(mine),
                'reached': len(ok), 'success_rate': len(ok) / len(mine) if mine else None,
                'collisions': sum(r['collisions'] for r in mine),
                'avoidable_collisions': sum(r['avoidable'] for r in mine),
                'mean_time_s': float(np.mean([r['time_s'] for r in ok])) if ok else None,
                'failures': [(r['scenario'], r['failure']) for r in mine if not r['reached']]})
    return out


def format_report(summary, n, seed):
    """The Markdown table."""
    lines = [f'Fusion among moving obstacles, scan perception against ideal; {n} scenarios per '
             f'family, seed {seed}; {machine_summary()}', '',
             '| family | perception | success | contacts (avoidable) | mean time [s] |',
             '|---|---|---|---|---|']
    for s in summary:
        time_s = '-' if s['mean_time_s'] is None else f'{s["mean_time_s"]:.1f}'
        lines.append(f'| {s["family"]} | {s["perception"]} | {100 * s["success_rate"]:.1f}% '
                     f'({s["reached"]}/{s["episodes"]}) | {s["collisions"]} '
                     f'({s["avoidable_collisions"]}) | {time_s} |')
    failures = [f'  {s["perception"]}: {name}: {reason}'
                for s in summary for name, reason in s['failures']]
    if failures:
        lines += ['', 'not reached:'] + failures
    return '\n'.join(lines)


def add_batch_arguments(parser, default_scenarios, default_seed, quick_help):
    """``--scenarios``, ``--seed``, ``--quick``, ``--json`` of a benchmark over families."""
    parser.add_argument('--scenarios', type=int, default=default_scenarios, metavar='N',
                        help='scenarios per family (default %(default)s)')
    parser.add_argument('--seed', type=int, default=default_seed,
                        help='batch seed of the scenarios (default %(default)s)')
    parser.add_argument('--quick', action='store_true', help=quick_help)
    parser.add_argument('--json', action='store_true', help='print one JSON object')


def add_arguments(parser):
    """Options of ``fusion-planner bench dynamic``."""
    add_batch_arguments(parser, DEFAULT_SCENARIOS, DEFAULT_SEED,
                        f'{QUICK_SCENARIOS} scenario per family')
    parser.add_argument('--family', action='append', metavar='NAME',
                        help=f'one of {", ".join(MOVING_FAMILIES + STRESS_FAMILIES)}; repeat '
                             'for several (default all but the stress tests)')
    parser.add_argument('--jobs', type=int, default=1, metavar='J',
                        help='worker processes (default 1; results do not depend on it)')


def run(args):
    """Run every family under both perceptions and print the table; 0 when it ran.

    Raises
    ------
    InvalidInput
        Unknown family, or a non-positive count.
    """
    n = QUICK_SCENARIOS if args.quick else args.scenarios
    families = args.family or list(MOVING_FAMILIES)
    known = MOVING_FAMILIES + STRESS_FAMILIES
    unknown = [f for f in families if f not in known]
    if unknown or n < 1 or args.jobs < 1:
        raise InvalidInput(f'need known families ({", ".join(known)}), positive '
                           f'--scenarios and --jobs; got {families}, {n}, {args.jobs}')
    reporter = Progress(n * len(families), 'bench dynamic', unit='scenarios')
    with quiet_core(args):
        rows = run_families(n, args.seed, families, args.jobs,
                            progress=lambda done: reporter.advance(done - reporter.done))
    reporter.finish()
    summary = summarise(rows, families)
    if args.json:
        print(json.dumps(_strict({'machine': machine_summary(), 'scenarios': n, 'seed': args.seed,
                                  'summary': summary, 'episodes': rows})))
    else:
        print(format_report(summary, n, args.seed))
    return EXIT_OK
