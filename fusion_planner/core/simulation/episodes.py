"""Closed-loop runs: plan once, then sense, decide and move until done.

:func:`run_episode` runs one controller on one
:class:`~fusion_planner.core.simulation.scenario.Scenario`: the global planner plans on
the **known** map only (inflated by ``scenario.planner.robot_radius``), the
controller gets the plan with its ends set to the exact start and goal (or
just ``[start, goal]`` for the pure field controllers), and the loop runs at
the scenario's ``dt``::

    scan -> Observation(scan hit points, tracked obstacles) -> controller.compute
         -> world.step(v, omega)

where the tracked obstacles are what the scan tracker makes of the scans
(perception ``scan``) or the true moving obstacles (``ideal``; see
:mod:`~fusion_planner.core.simulation.perception`)

until the robot arrives (within the goal tolerance *and* the controller
reports ``'arrived'``), the controller reports ``'no_path'`` or
``'failed'``, the contact-event limit is reached, or time runs out.
:func:`run_batch` runs several controllers on the generated scenarios of one
family (:mod:`~fusion_planner.core.simulation.families`) and summarises them
side by side.

Every run ends with one of :data:`OUTCOMES`; failure reasons are
``'<outcome>: <sentence>'``.
"""

import collections
import concurrent.futures
import dataclasses
import logging
import math
import time
from dataclasses import dataclass, field

import numpy as np

from fusion_planner.core.local_planning import follow
from fusion_planner.core.errors import InvalidInput, PlanningError
from fusion_planner.core.global_planning.planner import GlobalPlanner
from fusion_planner.core.simulation.families import FAMILIES, family_scenario
from fusion_planner.core.simulation.perception import PERCEPTION_MODES, check_mode, make_perception
from fusion_planner.core.simulation.scenario import random_scenario
from fusion_planner.core.simulation.world import World

LOGGER = logging.getLogger(__name__)

#: Controllers, in the order reports list them.
CONTROLLERS = follow.CONTROLLER_NAMES
#: Controllers that follow the global plan (the others get ``[start, goal]``).
PLAN_FOLLOWERS = ('fusion', 'dwa', 'astar-track')
#: Slack on the arrival distance check [m] (floating point only).
ARRIVAL_SLACK_M = 1e-9
#: How a run ends: at the goal; the controller's proof (or the planner's)
#: that there is no path; the controller giving up otherwise; the
#: contact-event limit; the time limit.
OUTCOMES = ('reached', 'no_path', 'controller_failed', 'collisions', 'time_limit')
#: Controller status -> outcome, for the statuses that end a run.
_ENDING_STATUS = {'no_path': 'no_path', 'failed': 'controller_failed'}
#: Stand-in for "compute the optimal length" (None means "there is none").
_COMPUTE = object()


@dataclass
class EpisodeResult:
    """The outcome of one closed-loop run.

    Attributes
    ----------
    scenario : str
        Scenario name.
    controller : str
    seed : int
        Seed of the world (random walks, scan noise).
    perception : str
        What the controller was told of the moving obstacles (one of
        :data:`PERCEPTION_MODES`).
    reached : bool
        Arrived within the goal tolerance with status ``'arrived'``.
    collisions : int
        Contact events (a contact that lasts several steps counts once).
    moving_collisions : int
        Those of them that began with a moving obstacle overlapping the robot
        (rather than the robot driving into a static obstacle).
    passive_collisions : int
        Those of them that a moving obstacle began while the robot stood or
        retreated from it and could not have got out of its way
        (:attr:`World.passive_contact_events`); the others the robot could
        have avoided.
    time_s : float
        Simulated time at the end [s].
    path_length_m : float
        Length of the driven trajectory [m].
    min_clearance_m : float
        Smallest distance [m] between the robot's boundary and any obstacle
        over the run (0 on contact; NaN when nothing was simulated).
    stuck_events : int
        Local-minimum detections reported by the controller.
    outcome : str
        One of :data:`OUTCOMES`.
    failure : str or None
        ``'<outcome>: <sentence>'`` when not reached.
    plan_length_m : float or None
        Length of the global plan on the known map [m] (None: no plan).
    no_path_proven_at_s : float or None
        Simulated time [s] at which the controller proved the goal
        unreachable (its ``no_path_proven_at``), None when it did not.
    optimal_length_m : float or None
        Length of the plan on the true static map [m] (see
        :func:`optimal_length`); None when there is none.
    optimal_time_s : float or None
        ``optimal_length_m / robot.max_speed`` [s].
    family : str or None
        The scenario's family.
    solvable : bool or None
        Whether the scenario can be solved (None: not known).
    trajectory : ndarray, float64, shape (T, 3) or None
        Robot poses ``(x, y, yaw)`` at ``t = 0, dt, ..., time_s``
        (``record=True`` only).
    obstacle_tracks : ndarray, float64, shape (T, K, 2) or None
        Moving obstacle centres at the same instants (``record=True`` only).
    plan_path : ndarray, float64, shape (N, 2) or None
        The global plan.
    key_nodes : ndarray, float64, shape (M, 2) or None
        Its key nodes.
    escape_points : ndarray, float64, shape (E, 2)
        Positions where the controller's status became ``'stuck_escaping'``.
    contacts : tuple of ContactEvent
        Every contact event, oldest first: where, how fast the robot moved,
        whom it touched and how the contact was judged
        (:class:`~fusion_planner.core.simulation.contact_blame.ContactEvent`).
    """

    scenario: str
    controller: str
    seed: int
    reached: bool
    collisions: int
    time_s: float
    path_length_m: float
    min_clearance_m: float
    stuck_events: int
    moving_collisions: int = 0
    passive_collisions: int = 0
    perception: str = PERCEPTION_MODES[0]
    outcome: str = 'reached'
    failure: str = None
    plan_length_m: float = None
    no_path_proven_at_s: float = None
    optimal_length_m: float = None
    optimal_time_s: float = None
    family: str = None
    solvable: bool = None
    trajectory: np.ndarray = field(default=None, repr=False)
    obstacle_tracks: np.ndarray = field(default=None, repr=False)
    plan_path: np.ndarray = field(default=None, repr=False)
    key_nodes: np.ndarray = field(default=None, repr=False)
    escape_points: np.ndarray = field(default_factory=lambda: np.zeros((0, 2)), repr=False)
    contacts: tuple = ()

    @property
    def time_ratio(self):
        """``time_s / optimal_time_s`` of a reached goal, else None."""
        if not self.reached or not self.optimal_time_s:
            return None
        return self.time_s / self.optimal_time_s

    def summary(self):
        """The JSON-ready figures of the run plus identification.

        Returns
        -------
        dict
            ``reached``, ``outcome``, ``collisions``, ``time_s``,
            ``path_length_m``, ``min_clearance_m``, ``stuck_events``,
            ``failure`` (None or a reason), ``scenario``, ``family``,
            ``solvable``, ``controller``, ``perception``, ``seed``, ``plan_length_m``,
            ``moving_collisions``, ``passive_collisions``, ``no_path_proven_at_s``,
            ``optimal_length_m``, ``optimal_time_s``, ``time_ratio``, and
            ``contacts`` (one
            :meth:`~fusion_planner.core.simulation.contact_blame.ContactEvent.summary` per
            contact event).
        """
        return {
            'scenario': self.scenario,
            'family': self.family,
            'solvable': self.solvable,
            'controller': self.controller,
            'perception': self.perception,
            'seed': self.seed,
            'reached': bool(self.reached),
            'outcome': self.outcome,
            'collisions': int(self.collisions),
            'moving_collisions': int(self.moving_collisions),
            'passive_collisions': int(self.passive_collisions),
            'time_s': round(float(self.time_s), 3),
            'path_length_m': round(float(self.path_length_m), 3),
            'min_clearance_m': (round(float(self.min_clearance_m), 3)
                                if math.isfinite(self.min_clearance_m) else None),
            'stuck_events': int(self.stuck_events),
            'failure': self.failure,
            'plan_length_m': _rounded(self.plan_length_m),
            'no_path_proven_at_s': _rounded(self.no_path_proven_at_s),
            'optimal_length_m': _rounded(self.optimal_length_m),
            'optimal_time_s': _rounded(self.optimal_time_s),
            'time_ratio': _rounded(self.time_ratio),
            'contacts': [event.summary() for event in self.contacts],
        }


def _rounded(value, digits=3):
    """``value`` rounded for JSON, None kept."""
    return None if value is None else round(float(value), digits)


def follower_params(scenario):
    """The controllers' parameters of a scenario (see :meth:`Scenario.follower_params`)."""
    return scenario.follower_params()


def plan_on_known_map(scenario):
    """Plan from the scenario's start to its goal on the known map.

    Returns
    -------
    PlanResult

    Raises
    ------
    PlanningError
        From :meth:`GlobalPlanner.plan`.
    """
    return GlobalPlanner(scenario.grid, scenario.planner).plan(scenario.start[:2], scenario.goal)


def exact_ends(path, key_nodes, start, goal):
    """A plan whose first point is exactly ``start`` and last point exactly ``goal``.

    The planner's path runs between the centres of the start and goal cells,
    up to half a diagonal cell away from the requested points; the follower
    must aim at the real goal.

    Parameters
    ----------
    path : ndarray, shape (N, 2)
    key_nodes : ndarray, shape (K, 2)
    start, goal : ndarray, shape (2,)

    Returns
    -------
    tuple of ndarray
        Copies of ``path`` and ``key_nodes`` with their ends replaced.
    """
    path = np.array(path, dtype=float, copy=True)
    key_nodes = np.array(key_nodes, dtype=float, copy=True)
    path[0], path[-1] = start, goal
    if len(key_nodes):
        key_nodes[-1] = goal
        if len(key_nodes) > 1:
            key_nodes[0] = start
    return path, key_nodes


def optimal_length(scenario):
    """Length [m] of the global plan on the *true* static map, or None when there is none.

    The true map is the known map with the unknown static obstacles burnt in
    (:meth:`Scenario.true_grid`); moving obstacles are ignored. It is the
    reference of the "path length over optimal" ratio, planned without
    folding zig-zags (``PlannerConfig.fewer_turns``, which may lengthen a
    path a little for fewer corners): the shortest path the planner finds.
    """
    try:
        plan = GlobalPlanner(scenario.true_grid(),
                             dataclasses.replace(scenario.planner, fewer_turns=False)).plan(
            scenario.start[:2], scenario.goal)
    except PlanningError as err:
        LOGGER.info('no plan on the true map of %s: %s', scenario.name, err)
        return None
    return float(plan.metrics.length_m)


def run_episode(scenario, controller_name, seed=None, record=True, plan=None,
                optimal_length_m=_COMPUTE, perception=None):
    """Run one controller on one scenario.

    Parameters
    ----------
    scenario : Scenario
    controller_name : str
        One of :data:`CONTROLLERS`.
    seed : int, optional
        World seed; default ``scenario.seed``.
    record : bool
        Keep the trajectory, obstacle tracks and plan in the result.
    plan : PlanResult, optional
        A plan already made on the known map (saves re-planning when several
        controllers run on the same scenario).
    optimal_length_m : float or None, optional
        The scenario's :func:`optimal_length` when already known (None:
        there is none); computed when not given.
    perception : str or ScanPerception or IdealPerception, optional
        One of :data:`PERCEPTION_MODES` (default ``scenario.perception``),
        or a perception object to use (and inspect afterwards).

    Returns
    -------
    EpisodeResult

    Raises
    ------
    InvalidInput
        Unknown controller name or perception, or invalid follower overrides.

    Examples
    --------
    >>> from fusion_planner.core.simulation.scenario import random_scenario
    >>> result = run_episode(random_scenario(5), 'fusion', record=False)
    >>> result.collisions >= 0 and result.time_s > 0
    True
    """
    if controller_name not in CONTROLLERS:
        raise InvalidInput(
            f'unknown controller {controller_name!r}; choose one of {", ".join(CONTROLLERS)}')
    perception = scenario.perception if perception is None else perception
    if isinstance(perception, str):
        perceive = make_perception(perception, scenario.grid)
    else:
        perceive, perception = perception, perception.mode
    params = follower_params(scenario)
    # Fusion may replan on the known map plus the obstacles it has seen when
    # its escape toward the next key node fails (see follow.GridReplanner).
    controller = follow.make_controller(
        controller_name, params,
        replan=follow.GridReplanner(scenario.grid, scenario.planner, robot_radius=scenario.robot.radius))
    controller.display_plan = False  # nothing here shows it
    seed = scenario.seed if seed is None else int(seed)
    start = np.asarray(scenario.start, float)
    goal = np.asarray(scenario.goal, float)
    limits = scenario.limits
    if optimal_length_m is _COMPUTE:
        optimal_length_m = optimal_length(scenario)
    reference = dict(
        scenario=scenario.name, controller=controller_name, seed=seed, perception=perception,
        family=scenario.family, solvable=scenario.solvable, optimal_length_m=optimal_length_m,
        optimal_time_s=(None if optimal_length_m is None
                        else optimal_length_m / scenario.robot.max_speed))

    plan_path = key_nodes = None
    plan_length = None
    if plan is None:
        try:
            plan = plan_on_known_map(scenario)
        except PlanningError as err:
            LOGGER.info('%s: no global plan: %s', scenario.name, err)
            if controller_name in PLAN_FOLLOWERS:
                return EpisodeResult(
                    reached=False, collisions=0, time_s=0.0, path_length_m=0.0,
                    min_clearance_m=math.nan, stuck_events=0, outcome='no_path',
                    failure=f'no_path: {err}', no_path_proven_at_s=0.0, **reference)
    if plan is not None:
        plan_path, key_nodes = exact_ends(plan.path, plan.key_nodes, start[:2], goal)
        plan_length = float(plan.metrics.length_m)
    if controller_name in PLAN_FOLLOWERS:
        controller.set_path(plan_path, key_nodes)
    else:
        controller.set_path(np.vstack([start[:2], goal]), goal[None, :])

    world = World(scenario.grid, scenario.robot, start, scenario.unknown_obstacles,
                  scenario.moving_obstacles, scenario.scan, seed=seed)
    trajectory, tracks, escapes = [], [], []
    path_length = 0.0
    min_clearance = world.clearance()
    reached, outcome, failure = False, 'reached', None
    previous_status = None
    max_steps = int(math.ceil(limits.time_limit_s / limits.dt - 1e-9))
    steps = 0
    for _ in range(max_steps):
        scan = world.scan()
        tracked = perceive.tracked(world, scan)
        obs = follow.Observation(pose=world.pose.copy(), velocity=world.velocity.copy(),
                                 obstacle_points=scan.points, tracked=tracked,
                                 time=world.time, tentative=perceive.tentative,
                                 turn_stds=perceive.turn_stds)
        command = controller.compute(obs)
        if record:
            trajectory.append(world.pose.copy())
            tracks.append(world.obstacle_positions())
        if command.status == 'stuck_escaping' and previous_status != 'stuck_escaping':
            escapes.append(world.pose[:2].copy())
        previous_status = command.status
        if command.status == 'arrived' and \
                np.hypot(*(world.pose[:2] - goal)) <= params.goal_tolerance + ARRIVAL_SLACK_M:
            reached = True
            break
        if command.status in _ENDING_STATUS:
            outcome = _ENDING_STATUS[command.status]
            failure = f'{outcome}: {command.reason or command.status}'
            break
        before = world.pose[:2].copy()
        world.step(command.v, command.omega, limits.dt)
        steps += 1
        path_length += float(np.hypot(*(world.pose[:2] - before)))
        min_clearance = min(min_clearance, world.clearance())
        if world.contact_events >= limits.max_collisions:
            outcome = 'collisions'
            failure = f'collisions: stopped after {world.contact_events} contact events'
            break
    else:
        outcome = 'time_limit'
        failure = f'time_limit: the goal was not reached within {limits.time_limit_s:g} s'
    if record and steps == len(trajectory):
        # the loop ended after a step (limits): record where that step ended
        trajectory.append(world.pose.copy())
        tracks.append(world.obstacle_positions())
    k = len(scenario.moving_obstacles)
    proven_at = getattr(controller, 'no_path_proven_at', None)
    return EpisodeResult(
        reached=reached, collisions=world.contact_events, time_s=world.time,
        path_length_m=path_length, min_clearance_m=min_clearance,
        stuck_events=int(getattr(controller, 'stuck_events', 0)),
        moving_collisions=world.moving_contact_events,
        passive_collisions=world.passive_contact_events, outcome=outcome,
        failure=failure, plan_length_m=plan_length,
        no_path_proven_at_s=None if proven_at is None else float(proven_at), **reference,
        trajectory=np.array(trajectory).reshape(-1, 3) if record else None,
        obstacle_tracks=np.array(tracks).reshape(len(tracks), k, 2) if record else None,
        plan_path=plan_path if record else None, key_nodes=key_nodes if record else None,
        escape_points=np.array(escapes).reshape(-1, 2), contacts=tuple(world.contacts))


# -- batches -----------------------------------------------------------------------

@dataclass
class ControllerSummary:
    """Side-by-side figures of one controller over a batch.

    Attributes
    ----------
    controller : str
    perception : str
        One of :data:`PERCEPTION_MODES`.
    episodes : int
    reached : int
    success_rate : float
        ``reached / episodes``.
    solvable_episodes : int
        Episodes on scenarios known to be solvable.
    solvable_reached : int
    success_on_solvable : float or None
        ``solvable_reached / solvable_episodes`` (None: no solvable ones).
    outcomes : dict of str to int
        How many episodes ended with each of :data:`OUTCOMES`.
    collisions : int
        Contact events over all episodes.
    moving_collisions : int
        Those that began with a moving obstacle overlapping the robot.
    avoidable_collisions : int
        Those that were not passive (a moving obstacle walking into a robot
        that stood or retreated and could not get away;
        :attr:`EpisodeResult.passive_collisions`).
    episodes_with_collisions : int
    mean_time_s : float or None
        Mean simulated time of the successful episodes [s].
    mean_time_ratio : float or None
        Mean of time / optimal time (the optimal path at ``max_speed``) over
        the successful episodes.
    path_length_over_optimal : float or None
        Mean of driven length / optimal length (plan on the true static map)
        over the successful episodes.
    mean_min_clearance_m : float or None
        Mean of the episodes' smallest clearance [m].
    stuck_events : int
    stuck_run_fraction : float or None
        Fraction of the episodes with at least one stuck event.
    unsolvable_episodes : int
        Episodes on scenarios known to be unsolvable.
    no_path_fraction : float or None
        Fraction of those that ended ``no_path``.
    max_no_path_delay_s : float or None
        Largest time from the controller's proof of unreachability to the
        end of the run [s], over the episodes with a proof.
    wall_time_s : float
        Wall time spent in this controller's episodes [s].
    failures : list of tuple
        ``(scenario name, reason)`` of every episode not reached.
    """

    controller: str
    perception: str = PERCEPTION_MODES[0]
    episodes: int = 0
    reached: int = 0
    success_rate: float = 0.0
    solvable_episodes: int = 0
    solvable_reached: int = 0
    success_on_solvable: float = None
    outcomes: dict = field(default_factory=lambda: dict.fromkeys(OUTCOMES, 0))
    collisions: int = 0
    moving_collisions: int = 0
    avoidable_collisions: int = 0
    episodes_with_collisions: int = 0
    mean_time_s: float = None
    mean_time_ratio: float = None
    path_length_over_optimal: float = None
    mean_min_clearance_m: float = None
    stuck_events: int = 0
    stuck_run_fraction: float = None
    unsolvable_episodes: int = 0
    no_path_fraction: float = None
    max_no_path_delay_s: float = None
    wall_time_s: float = 0.0
    failures: list = field(default_factory=list)

    def as_dict(self):
        """JSON-ready form (numbers rounded)."""
        out = dataclasses.asdict(self)
        for key in ('success_rate', 'success_on_solvable', 'mean_time_s', 'mean_time_ratio',
                    'path_length_over_optimal', 'mean_min_clearance_m', 'stuck_run_fraction',
                    'no_path_fraction', 'max_no_path_delay_s', 'wall_time_s'):
            if out[key] is not None:
                out[key] = round(float(out[key]), 4)
        out['failures'] = [{'scenario': s, 'reason': r} for s, r in self.failures]
        return out


@dataclass
class BatchResult:
    """A batch: its parameters, per-controller summaries and every episode.

    Attributes
    ----------
    scenarios : int
    seed : int
    controllers : dict of str to ControllerSummary
        Under the first perception of the batch.
    episodes : list of dict
        :meth:`EpisodeResult.summary` of every episode plus ``wall_time_s``.
    wall_time_s : float
    family : str
        The scenario family (see :data:`FAMILIES`).
    by_perception : dict of str to dict of str to ControllerSummary
        The summaries under every perception of the batch, first one first.
    """

    scenarios: int
    seed: int
    controllers: dict
    episodes: list
    wall_time_s: float
    family: str = 'mixed'
    by_perception: dict = field(default_factory=dict)

    def as_dict(self):
        """JSON-ready form; ``by_perception`` only when the batch compared perceptions."""
        out = {
            'scenarios': self.scenarios,
            'family': self.family,
            'seed': self.seed,
            'wall_time_s': round(self.wall_time_s, 2),
            'controllers': {name: s.as_dict() for name, s in self.controllers.items()},
            'episodes': self.episodes,
        }
        if len(self.by_perception) > 1:
            out['by_perception'] = {
                mode: {name: s.as_dict() for name, s in summaries.items()}
                for mode, summaries in self.by_perception.items()}
        return out


def batch_seeds(n, seed):
    """The scenario seeds of a batch: ``n`` distinct non-negative ints from ``seed``."""
    children = np.random.SeedSequence(int(seed)).spawn(int(n))
    return [int(child.generate_state(1)[0]) for child in children]


def generate(family, seed, config=None):
    """The generated scenario of a family and seed.

    Parameters
    ----------
    family : str
        One of :data:`FAMILIES`.
    seed : int
    config : RandomScenarioConfig, optional
        Only for ``'mixed'`` (:func:`random_scenario`).

    Raises
    ------
    InvalidInput
        Unknown family, a config for another family, or no valid scenario.
    """
    if family == 'mixed':
        return random_scenario(seed, config)
    if config is not None:
        raise InvalidInput(f'a RandomScenarioConfig applies to the mixed family only, not {family!r}')
    return family_scenario(family, seed)


def run_scenario_set(scenario_seed, controllers, config=None, family='mixed',
                     perceptions=PERCEPTION_MODES[:1]):
    """Generate one scenario of a family and run every controller on it under every perception.

    Returns
    -------
    list of dict
        One :meth:`EpisodeResult.summary` per perception and controller,
        each with ``wall_time_s`` (wall time of that episode).
    """
    scenario = generate(family, scenario_seed, config)
    optimal = optimal_length(scenario)
    try:
        plan = plan_on_known_map(scenario)
    except PlanningError:
        plan = None
    rows = []
    for mode in perceptions:
        for name in controllers:
            t0 = time.perf_counter()
            result = run_episode(scenario, name, record=False, plan=plan,
                                 optimal_length_m=optimal, perception=mode)
            row = result.summary()
            row['wall_time_s'] = round(time.perf_counter() - t0, 4)
            rows.append(row)
    return rows


def run_batch(n, seed, controllers=CONTROLLERS, config=None, progress=None, workers=1,
              family='mixed', perceptions=PERCEPTION_MODES[:1]):
    """Run controllers side by side on ``n`` generated scenarios of one family.

    Parameters
    ----------
    n : int
        Number of scenarios, >= 1.
    seed : int
        Batch seed; scenario ``i`` uses ``batch_seeds(n, seed)[i]``.
    controllers : sequence of str
        Names from :data:`CONTROLLERS`.
    config : RandomScenarioConfig, optional
        For the ``'mixed'`` family only.
    progress : callable, optional
        ``progress(done, total)`` after each scenario (all controllers).
    workers : int
        Worker processes (1: run in this process). Results do not depend on
        it.
    family : str
        One of :data:`FAMILIES`.
    perceptions : sequence of str
        Modes from :data:`PERCEPTION_MODES`; every controller runs under
        each.

    Returns
    -------
    BatchResult

    Raises
    ------
    InvalidInput
        ``n < 1``, unknown controller, family or perception, bad worker count.
    """
    if isinstance(n, bool) or not isinstance(n, int) or n < 1:
        raise InvalidInput(f'the batch size must be a positive integer, got {n!r}')
    if isinstance(workers, bool) or not isinstance(workers, int) or workers < 1:
        raise InvalidInput(f'workers must be a positive integer, got {workers!r}')
    if family not in FAMILIES:
        raise InvalidInput(f'unknown scenario family {family!r}; choose one of {", ".join(FAMILIES)}')
    controllers = tuple(controllers)
    for name in controllers:
        if name not in CONTROLLERS:
            raise InvalidInput(f'unknown controller {name!r}; choose one of {", ".join(CONTROLLERS)}')
    perceptions = tuple(dict.fromkeys(perceptions))
    if not perceptions:
        raise InvalidInput('a batch needs at least one perception')
    for mode in perceptions:
        check_mode(mode)
    seeds = batch_seeds(n, seed)
    t0 = time.perf_counter()
    per_scenario = [None] * n
    if workers == 1:
        for i, s in enumerate(seeds):
            per_scenario[i] = run_scenario_set(s, controllers, config, family, perceptions)
            if progress is not None:
                progress(i + 1, n)
    else:
        with concurrent.futures.ProcessPoolExecutor(max_workers=workers) as pool:
            futures = {pool.submit(run_scenario_set, s, controllers, config, family, perceptions): i
                       for i, s in enumerate(seeds)}
            for done, future in enumerate(concurrent.futures.as_completed(futures), start=1):
                per_scenario[futures[future]] = future.result()
                if progress is not None:
                    progress(done, n)
    episodes = [row for rows in per_scenario for row in rows]
    by_perception = {
        mode: {name: summarise(name, [e for e in episodes if e['controller'] == name
                                      and e['perception'] == mode], mode)
               for name in controllers}
        for mode in perceptions}
    return BatchResult(scenarios=n, seed=int(seed), controllers=by_perception[perceptions[0]],
                       episodes=episodes, wall_time_s=time.perf_counter() - t0, family=family,
                       by_perception=by_perception)


def _mean(values):
    """Mean of a list, None when empty."""
    return float(np.mean(values)) if values else None


def summarise(controller, rows, perception=PERCEPTION_MODES[0]):
    """A :class:`ControllerSummary` from episode summary rows of one controller and perception."""
    out = ControllerSummary(controller=controller, perception=perception, episodes=len(rows))
    if not rows:
        return out
    ok = [r for r in rows if r['reached']]
    out.reached = len(ok)
    out.success_rate = len(ok) / len(rows)
    solvable = [r for r in rows if r.get('solvable')]
    out.solvable_episodes = len(solvable)
    out.solvable_reached = sum(1 for r in solvable if r['reached'])
    if solvable:
        out.success_on_solvable = out.solvable_reached / len(solvable)
    counts = collections.Counter(r.get('outcome', 'reached' if r['reached'] else None) for r in rows)
    out.outcomes = {name: counts.get(name, 0) for name in OUTCOMES}
    out.collisions = sum(r['collisions'] for r in rows)
    out.moving_collisions = sum(r.get('moving_collisions', 0) for r in rows)
    out.avoidable_collisions = out.collisions - sum(r.get('passive_collisions', 0) for r in rows)
    out.episodes_with_collisions = sum(1 for r in rows if r['collisions'] > 0)
    out.stuck_events = sum(r['stuck_events'] for r in rows)
    out.stuck_run_fraction = sum(1 for r in rows if r['stuck_events'] > 0) / len(rows)
    out.mean_time_s = _mean([r['time_s'] for r in ok])
    out.mean_time_ratio = _mean([r['time_ratio'] for r in ok if r.get('time_ratio') is not None])
    out.path_length_over_optimal = _mean([r['path_length_m'] / r['optimal_length_m'] for r in ok
                                          if r.get('optimal_length_m')])
    out.mean_min_clearance_m = _mean([r['min_clearance_m'] for r in rows
                                      if r['min_clearance_m'] is not None
                                      and math.isfinite(r['min_clearance_m'])])
    unsolvable = [r for r in rows if r.get('solvable') is False]
    out.unsolvable_episodes = len(unsolvable)
    if unsolvable:
        out.no_path_fraction = sum(1 for r in unsolvable if r['outcome'] == 'no_path') / len(unsolvable)
    delays = [r['time_s'] - r['no_path_proven_at_s'] for r in rows
              if r.get('no_path_proven_at_s') is not None]
    out.max_no_path_delay_s = max(delays) if delays else None
    out.wall_time_s = float(sum(r.get('wall_time_s', 0.0) for r in rows))
    out.failures = [(r['scenario'], r['failure']) for r in rows if not r['reached']]
    return out
