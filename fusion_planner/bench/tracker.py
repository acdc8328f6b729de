"""Scan tracker accuracy and speed: velocity error, delay, false tracks, update time.

Drives the fusion controller with scan perception on generated scenarios of
every family with moving obstacles and compares the tracker's moving tracks with the
simulation's truth at every scan; drives it among static clutter only (no
moving obstacle) to count false tracks; and times one tracker update on a
720-beam scan of 20 moving obstacles.

Notes
-----
- **Matching**: at every scan the reported tracks and the true moving
  obstacles are paired by the Hungarian method on centre distance, pairs
  farther apart than :data:`MATCH_RADIUS_M` excluded. The *velocity error*
  of a pair is the norm of the velocity difference [m/s].
- **Delay**: an obstacle is *seen* at a scan when a return lies within
  :data:`SEEN_MARGIN_M` of its disc. A *sighting* starts at the first scan
  it is seen after :data:`SIGHTING_GAP_S` unseen (or ever); its delay is the
  time from then to the first scan where a track paired with it has a
  velocity error below :data:`USABLE_ERROR_MPS`. Sightings that end (or the
  run ends) first are counted as never usable.
- **False tracks**: distinct track ids reported at a scan where they pair
  with no true moving obstacle, per minute of simulated time. The clutter
  runs are generated scenarios with 3-6 unknown static obstacles and the
  moving obstacles removed.
- **Update time**: CPU time (``time.process_time``) of
  ``ScanTracker.update`` on the scans of :func:`crowd_around_the_robot`
  (:data:`~fusion_planner.bench.local.BEAMS` beams,
  :data:`~fusion_planner.bench.local.MOVING_OBSTACLES` people in view of a
  standing robot, 1 cm noise), next to the simulated laser's own ray cast of
  the same scans (the peer).
"""

import dataclasses
import functools
import json
import time

import numpy as np
from scipy.optimize import linear_sum_assignment

from fusion_planner.bench.dynamic import MOVING_FAMILIES, add_batch_arguments
from fusion_planner.bench.local import BEAMS, MOVING_OBSTACLES, SCAN_RATE_HZ
from fusion_planner.bench.movingai import _strict
from fusion_planner.bench.peers import machine_summary
from fusion_planner.cli.sim_command import quiet_core
from fusion_planner.core.errors import InvalidInput
from fusion_planner.core.local_planning.scan_tracker import ScanTracker
from fusion_planner.core.simulation.episodes import batch_seeds, run_episode
from fusion_planner.core.simulation.families import family_scenario
from fusion_planner.core.simulation.perception import ScanPerception
from fusion_planner.core.simulation.scenario import RandomScenarioConfig, random_scenario
from fusion_planner.core.simulation.dynamic_families import hall
from fusion_planner.core.simulation.world import (
    BounceMotion, MovingObstacle, RobotSpec, ScanConfig, World)

EXIT_OK = 0
#: A track and a true obstacle farther apart than this [m] are not a pair.
MATCH_RADIUS_M = 0.5
#: A return within this distance [m] of an obstacle's disc sees it.
SEEN_MARGIN_M = 0.05
#: Unseen this long [s], an obstacle's next sighting is a new one.
SIGHTING_GAP_S = 1.0
#: A velocity this close [m/s] to the truth is usable.
USABLE_ERROR_MPS = 0.2
#: Unknown static obstacles of the clutter runs.
CLUTTER_RANGE = (3, 6)
#: Default scenarios per family, batch seed, timed updates; quick mode's.
DEFAULT_SCENARIOS = 20
DEFAULT_SEED = 11
DEFAULT_UPDATES = 600
QUICK_SCENARIOS = 1
QUICK_UPDATES = 30
#: Target of the update time [ms].
TARGET_UPDATE_MS = 1.0


class TrackingStats:
    """Tracker output against the truth, scan by scan (see the module notes).

    Attributes
    ----------
    velocity_errors : list of float
        [m/s], one per paired track and scan.
    delays : list of float
        [s], one per sighting that became usable.
    unusable_sightings : int
    false_ids : set of int
        Track ids reported unpaired at some scan (ids are per run; the
        caller collects them per run).
    """

    def __init__(self):
        self.velocity_errors = []
        self.delays = []
        self.unusable_sightings = 0
        self.false_ids = set()
        self._sighting_start = {}
        self._last_seen = {}

    def observe(self, time_s, report, truth, points):
        """Take in one scan: the tracker's report, the true obstacles ``(K, 5)``, the hit points."""
        pairs = _pairs(report.states[:, 0:2], truth[:, 0:2])
        paired_tracks = {i for i, _ in pairs}
        self.false_ids.update(int(report.ids[i]) for i in range(len(report.ids))
                              if i not in paired_tracks)
        error_of = {j: float(np.hypot(*(report.states[i, 2:4] - truth[j, 2:4]))) for i, j in pairs}
        self.velocity_errors.extend(error_of.values())
        for j in range(len(truth)):
            if _seen(truth[j], points):
                if time_s - self._last_seen.get(j, -np.inf) > SIGHTING_GAP_S:
                    self._end_sighting(j)
                    self._sighting_start[j] = time_s
                self._last_seen[j] = time_s
            start = self._sighting_start.get(j)
            if start is not None and error_of.get(j, np.inf) <= USABLE_ERROR_MPS:
                self.delays.append(time_s - start)
                del self._sighting_start[j]

    def finish(self):
        """Count the sightings still waiting for a usable velocity as never usable."""
        for j in list(self._sighting_start):
            self._end_sighting(j)

    def _end_sighting(self, j):
        if self._sighting_start.pop(j, None) is not None:
            self.unusable_sightings += 1


class MeasuredPerception(ScanPerception):
    """Scan perception that also feeds a :class:`TrackingStats`."""

    def __init__(self, grid, stats):
        super().__init__(grid)
        self.stats = stats

    def tracked(self, world, scan):
        """The scan perception's tracks; the stats observe them against the truth."""
        tracked = super().tracked(world, scan)
        self.stats.observe(world.time, self.tracker.report(), world.tracked_obstacles(),
                           scan.points)
        return tracked


def _pairs(tracks, truth):
    """Hungarian pairs ``(track index, truth index)`` closer than MATCH_RADIUS_M."""
    if not len(tracks) or not len(truth):
        return []
    distance = np.hypot(*(tracks[:, None, :] - truth[None, :, :]).transpose(2, 0, 1))
    rows, cols = linear_sum_assignment(np.minimum(distance, 2 * MATCH_RADIUS_M))
    return [(int(i), int(j)) for i, j in zip(rows, cols) if distance[i, j] <= MATCH_RADIUS_M]


def _seen(obstacle, points):
    if not len(points):
        return False
    gap = np.hypot(*(points - obstacle[0:2]).T) - obstacle[4]
    return bool(gap.min() <= SEEN_MARGIN_M)


def measure_family(name, generator, n, seed):
    """Drive fusion with scan perception on ``n`` scenarios of a family.

    Returns
    -------
    dict
        ``velocity_error`` and ``delay_s`` (median, p95, count),
        ``unusable_sightings``, ``false_tracks_per_min``, ``sim_time_s``,
        ``scenarios``.
    """
    errors, delays, unusable, false_tracks, sim_time = [], [], 0, 0, 0.0
    for scenario_seed in batch_seeds(n, seed):
        scenario = generator(scenario_seed)
        stats = TrackingStats()
        result = run_episode(scenario, 'fusion', record=False,
                             perception=MeasuredPerception(scenario.grid, stats))
        stats.finish()
        errors += stats.velocity_errors
        delays += stats.delays
        unusable += stats.unusable_sightings
        false_tracks += len(stats.false_ids)
        sim_time += result.time_s
    return {'family': name, 'scenarios': n, 'sim_time_s': sim_time,
            'velocity_error': _spread(errors), 'delay_s': _spread(delays),
            'unusable_sightings': unusable,
            'false_tracks_per_min': 60.0 * false_tracks / sim_time if sim_time > 0 else None}


def clutter_scenario(scenario_seed):
    """A generated scenario with 3-6 unknown static obstacles and no moving one."""
    scenario = random_scenario(scenario_seed, RandomScenarioConfig(unknown_range=CLUTTER_RANGE))
    return dataclasses.replace(scenario, name=f'clutter-{scenario_seed}', moving_obstacles=())


def crowd_around_the_robot(seed):
    """The timing scene: a standing robot with a 720-beam laser among 20 people in view.

    A walled 20 x 20 m hall at 0.1 m, the robot in its middle; the people
    (radius 0.2-0.3 m, 0.3-1.0 m/s, bouncing) start 1.5-7 m from it, apart
    from one another.

    Returns
    -------
    grid : GridMap
    world : World
    """
    rng = np.random.default_rng(np.random.SeedSequence([int(seed), 7]))
    grid = hall(20.0, 20.0)
    centre = np.array([10.0, 10.0])
    people = []
    while len(people) < MOVING_OBSTACLES:
        distance, bearing = rng.uniform(1.5, 7.0), rng.uniform(-np.pi, np.pi)
        p = centre + distance * np.array([np.cos(bearing), np.sin(bearing)])
        radius, speed, heading = rng.uniform(0.2, 0.3), rng.uniform(0.3, 1.0), \
            rng.uniform(-np.pi, np.pi)
        if any(np.hypot(*(p - q.motion.position)) < radius + q.radius + 0.3 for q in people):
            continue
        people.append(MovingObstacle(float(radius), BounceMotion(
            (float(p[0]), float(p[1])),
            (float(speed * np.cos(heading)), float(speed * np.sin(heading))))))
    world = World(grid, RobotSpec(radius=0.2), (10.0, 10.0, 0.0), moving_obstacles=people,
                  scan_config=ScanConfig(beams=BEAMS, range_max=8.0, noise_std=0.01), seed=seed)
    return grid, world


def measure_update_time(updates, seed):
    """CPU time of tracker updates and of the simulated laser on the same scans.

    Returns
    -------
    dict
        ``update_ms`` and ``scan_ms`` (median, p95), ``updates``, the
        medians of the moving obstacles ``seen`` per scan, of the ``live``
        tracks (moving or not) and of the moving ``tracks`` reported, the
        scene.
    """
    grid, world = crowd_around_the_robot(seed)
    tracker = ScanTracker(grid)
    update_s, scan_s, tracks, live, seen = [], [], [], [], []
    period = 1.0 / SCAN_RATE_HZ
    for _ in range(updates):
        c0 = time.process_time()
        scan = world.scan()
        c1 = time.process_time()
        tracker.update(scan.angles, scan.ranges, scan.origin, world.time)
        c2 = time.process_time()
        scan_s.append(c1 - c0)
        update_s.append(c2 - c1)
        tracks.append(len(tracker.report().ids))
        live.append(tracker.live_tracks)
        seen.append(sum(_seen(obstacle, scan.points) for obstacle in world.tracked_obstacles()))
        world.step(0.0, 0.0, period)
    return {'updates': updates, 'update_ms': _spread(1e3 * np.array(update_s)),
            'scan_ms': _spread(1e3 * np.array(scan_s)), 'tracks': float(np.median(tracks)),
            'live': float(np.median(live)), 'seen': float(np.median(seen)),
            'scene': {'beams': BEAMS, 'moving_obstacles': MOVING_OBSTACLES, 'seed': seed}}


def _spread(values):
    values = np.asarray(values, float)
    if not len(values):
        return {'median': None, 'p95': None, 'count': 0}
    return {'median': float(np.median(values)), 'p95': float(np.percentile(values, 95)),
            'count': int(len(values))}


def format_report(families, clutter, timing):
    """The text report."""
    lines = [f'Scan tracker benchmark; {machine_summary()}', '',
             '| scenes | scenarios | velocity error median / p95 [m/s] | '
             'delay to a usable velocity median / p95 [s] (sightings; never usable) | '
             'false tracks per minute |',
             '|---|---|---|---|---|']
    for row in families + [clutter]:
        v, d = row['velocity_error'], row['delay_s']
        lines.append(
            f'| {row["family"]} | {row["scenarios"]} | {_pair(v)} | '
            f'{_pair(d)} ({d["count"] + row["unusable_sightings"]}; {row["unusable_sightings"]}) | '
            f'{row["false_tracks_per_min"]:.2f} |')
    u, s = timing['update_ms'], timing['scan_ms']
    lines += ['', f'update time, {BEAMS} beams, {MOVING_OBSTACLES} moving obstacles '
                  f'({timing["updates"]} updates; medians: {timing["seen"]:.0f} obstacles seen, '
                  f'{timing["live"]:.0f} live tracks, {timing["tracks"]:.0f} moving tracks):',
              f'  tracker update: median {u["median"]:.3f} ms, p95 {u["p95"]:.3f} ms '
              f'= {u["median"] / TARGET_UPDATE_MS:.2f}x the {TARGET_UPDATE_MS:g} ms target',
              f'  simulated laser (peer): median {s["median"]:.3f} ms, p95 {s["p95"]:.3f} ms; '
              f'tracker / laser = {u["median"] / s["median"]:.2f}']
    return '\n'.join(lines)


def _pair(spread):
    if spread['median'] is None:
        return '-'
    return f'{spread["median"]:.3f} / {spread["p95"]:.3f}'


def add_arguments(parser):
    """Options of ``fusion-planner bench tracker``."""
    add_batch_arguments(parser, DEFAULT_SCENARIOS, DEFAULT_SEED,
                        f'{QUICK_SCENARIOS} scenario per family, {QUICK_UPDATES} updates')
    parser.add_argument('--updates', type=int, default=DEFAULT_UPDATES, metavar='N',
                        help='timed tracker updates (default %(default)s)')


def run(args):
    """Measure the tracker on every family, on clutter and on the clock; 0 when it ran.

    Raises
    ------
    InvalidInput
        A non-positive count.
    """
    n = QUICK_SCENARIOS if args.quick else args.scenarios
    updates = QUICK_UPDATES if args.quick else args.updates
    if n < 1 or updates < 1:
        raise InvalidInput(f'--scenarios and --updates must be positive, got {n} and {updates}')
    with quiet_core(args):
        families = [measure_family(name, functools.partial(family_scenario, name), n, args.seed)
                    for name in MOVING_FAMILIES]
        clutter = measure_family('static clutter', clutter_scenario, n, args.seed)
    timing = measure_update_time(updates, args.seed)
    if args.json:
        print(json.dumps(_strict({'machine': machine_summary(), 'families': families,
                                  'clutter': clutter, 'update_time': timing})))
    else:
        print(format_report(families, clutter, timing))
    return EXIT_OK
