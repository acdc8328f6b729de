"""Local planner speed: one control step, its load at 50 Hz, the demo's real-time factor.

Times one step of the fusion controller (``follow.make_controller('fusion')``:
fields, escape logic, command) over a 720-beam scan and 20 tracked moving
obstacles, in a closed loop on a generated scenario, its CPU load at 50 Hz,
and the simulated-over-wall time of ``fusion-planner demo`` (the three ROS
2 nodes in one process, on simulated time).

Notes
-----
- The scene: :func:`~fusion_planner.core.simulation.scenario.random_scenario` of a
  :data:`SIZE_M` m square map with :data:`MOVING_OBSTACLES` moving obstacles,
  a :data:`BEAMS`-beam laser and a control period of 1 / :data:`CONTROL_RATE_HZ`;
  the robot drives it in closed loop (:class:`~fusion_planner.core.simulation.world.World`),
  over consecutive seeds until ``--steps`` control steps were timed, so the
  steps cover driving, avoiding, escaping and arriving.
- The inputs are built as ``local_planner`` builds them (read, not
  imported as a node): the world's scan becomes a ``sensor_msgs/LaserScan``
  (the simulator's ``scan_to_msg``) and then map-frame points
  (``conversions.scan_to_points``) at :data:`SCAN_RATE_HZ`; the moving
  obstacles become a ``MarkerArray`` fed to an ``ObstacleTracker``, which
  estimates their velocities. Without ROS 2 the world's own scan points and
  ideal tracks are used with ``--no-ros`` (noted in the report); otherwise
  ROS 2 (the ``ros`` extra or a sourced install) is checked before the run.
- Timed with the CPU clock of this process (``time.process_time``): the
  *step* is the tracker query, the ``Observation`` and ``compute``, what the
  node's control timer runs besides publishing, with the controller's
  display rollout off as in a node whose ``local_plan`` has no subscriber
  (``--display-plan``: on); *scan* and *track* are the
  conversions of one scan and one marker message. The load is their CPU
  time over the simulated time, i.e. the fraction of one core the local
  planner needs at :data:`CONTROL_RATE_HZ` with scans at
  :data:`SCAN_RATE_HZ` (message transport excluded).
- The demo runs ``fusion-planner demo --real-time-factor F`` in a child
  process, with its default outputs (picture, animation, recording: the
  ``plot`` and ``record`` extras, checked before the run, as ROS 2 is), and
  reads its outcome line: the factor it reached from the first clock tick
  to arrival, and the child's CPU time (start-up and drawing included).
"""

import json
import math
import pathlib
import re
import resource
import statistics
import subprocess
import sys
import tempfile
import time

import numpy as np

from fusion_planner.bench.movingai import _strict
from fusion_planner.bench.peers import machine_summary
from fusion_planner.cli.requirements import require
from fusion_planner.core.local_planning import follow
from fusion_planner.core.errors import InvalidInput, PlanningError
from fusion_planner.core.simulation.scenario import Limits, RandomScenarioConfig, random_scenario
from fusion_planner.core.simulation.episodes import exact_ends, plan_on_known_map
from fusion_planner.core.simulation.world import ScanConfig, World

EXIT_OK, EXIT_FAILED, EXIT_BAD_INPUT = 0, 1, 2

#: The scene of the step benchmark: map edge [m], laser beams, moving
#: obstacles, control and scan rates [Hz], laser range [m] and noise [m],
#: simulated time per episode [s].
SIZE_M = 16.0
BEAMS = 720
MOVING_OBSTACLES = 20
CONTROL_RATE_HZ = 50.0
SCAN_RATE_HZ = 10.0
RANGE_MAX_M = 8.0
RANGE_NOISE_M = 0.01
EPISODE_TIME_S = 60.0
#: Default number of timed control steps, first scenario seed, demo factor.
DEFAULT_STEPS = 2000
DEFAULT_SEED = 1
DEFAULT_DEMO_FACTOR = 100.0
#: Wall time the demo child may take [s].
DEMO_TIMEOUT_S = 600.0
#: Quick mode (tests): timed steps.
QUICK_STEPS = 40
#: Targets: median step [ms], load at 50 Hz [fraction of a core], demo
#: real-time factor.
TARGET_STEP_MS = 1.0
TARGET_LOAD = 0.10
TARGET_DEMO_FACTOR = 10.0
#: Frames of the converted messages (as in config/params.yaml).
MAP_FRAME, ROBOT_FRAME = 'map', 'base_link'
#: The outcome line of ``fusion-planner demo``.
DEMO_OUTCOME = re.compile(
    r'arrived: (?P<arrived>yes|no)\s+sim time: (?P<sim>[\d.]+) s\s+\(wall (?P<wall>[\d.]+) s '
    r'with start-up, (?P<factor>[\d.]+|nan)x real time\)')


def bench_scenario(seed):
    """The generated scenario of one episode (720 beams, 20 moving obstacles, 50 Hz)."""
    config = RandomScenarioConfig(
        size_m=SIZE_M, moving_range=(MOVING_OBSTACLES, MOVING_OBSTACLES),
        scan=ScanConfig(beams=BEAMS, range_max=RANGE_MAX_M, noise_std=RANGE_NOISE_M),
        limits=Limits(time_limit_s=EPISODE_TIME_S, dt=1.0 / CONTROL_RATE_HZ))
    return random_scenario(seed, config)


class NodeInputs:
    """Scans and obstacles turned into controller inputs as ``local_planner`` does.

    Parameters
    ----------
    scan_config : ScanConfig
    use_ros : bool
        Convert through ROS messages (``sensor_msgs/LaserScan``,
        ``MarkerArray`` and ``ObstacleTracker``); False: take the world's
        points and ideal tracks.

    Attributes
    ----------
    scan_s, track_s : list of float
        CPU time [s] of each scan conversion and each tracker update.
    """

    def __init__(self, scan_config, use_ros):
        self.scan_config = scan_config
        self.use_ros = use_ros
        self.scan_s, self.track_s = [], []
        self.points = np.zeros((0, 2))
        self._tracks = np.zeros((0, 5))
        if use_ros:
            from fusion_planner.ros import conversions
            self._conv = conversions
            self._tracker = conversions.ObstacleTracker(MAP_FRAME)

    def sense(self, world):
        """Take the world's scan and obstacles now (as the node's subscriptions)."""
        scan = world.scan()
        tracked = world.tracked_obstacles()
        if not self.use_ros:
            self.points, self._tracks = scan.points, tracked
            return
        from fusion_planner.ros.simulator import scan_to_msg
        stamp = self._conv.seconds_to_stamp(world.time)
        msg = scan_to_msg(scan, self.scan_config, ROBOT_FRAME, stamp, 1.0 / SCAN_RATE_HZ)
        markers = self._conv.obstacles_to_markers(tracked, MAP_FRAME, stamp,
                                                  ns='moving_obstacles')
        c0 = time.process_time()
        self.points = self._conv.scan_to_points(msg, tuple(world.pose), ROBOT_FRAME, 'scan')
        c1 = time.process_time()
        self._tracker.update(markers, world.time)
        c2 = time.process_time()
        self.scan_s.append(c1 - c0)
        self.track_s.append(c2 - c1)

    def tracked(self, now):
        """Tracked obstacles ``(K, 5)`` at ``now`` [s] (the node's per-step query)."""
        return self._tracker.obstacles(now) if self.use_ros else self._tracks


def key_nodes(path, plan, use_ros):
    """The controller's key nodes of a plan, as the node derives them (or the planner's)."""
    if use_ros:
        from fusion_planner.ros.local_planner import key_nodes_of
        return key_nodes_of(path)
    return plan.key_nodes


def run_episode_timed(scenario, steps, use_ros, display_plan=False):
    """Drive one scenario in closed loop, timing each control step.

    Parameters
    ----------
    scenario : Scenario
    steps : int
        Most control steps to time.
    use_ros : bool
        See :class:`NodeInputs`.
    display_plan : bool
        The controller's ``display_plan`` (the node's: whether ``local_plan``
        has a subscriber).

    Returns
    -------
    step_s : list of float
        CPU time [s] of each control step.
    inputs : NodeInputs
        With the CPU time of each scan and tracker update.
    sim_time : float
        Simulated time driven [s].
    status : str
        The last command's status.

    Raises
    ------
    PlanningError
        When the scenario has no global plan.
    """
    params = scenario.follower_params()
    controller = follow.make_controller(
        'fusion', params, replan=follow.GridReplanner(scenario.grid, scenario.planner))
    controller.display_plan = display_plan
    plan = plan_on_known_map(scenario)
    start, goal = np.asarray(scenario.start, float), np.asarray(scenario.goal, float)
    path, _ = exact_ends(plan.path, plan.key_nodes, start[:2], goal)
    controller.set_path(path, key_nodes(path, plan, use_ros))
    world = World(scenario.grid, scenario.robot, start, scenario.unknown_obstacles,
                  scenario.moving_obstacles, scenario.scan, seed=scenario.seed)
    inputs = NodeInputs(scenario.scan, use_ros)
    per_scan = max(1, round(CONTROL_RATE_HZ / SCAN_RATE_HZ))
    dt = scenario.limits.dt
    step_s = []
    status = ''
    for k in range(steps):  # bounded: the step budget
        if k % per_scan == 0:
            inputs.sense(world)
        c0 = time.process_time()
        obs = follow.Observation(pose=world.pose.copy(), velocity=world.velocity.copy(),
                                 obstacle_points=inputs.points,
                                 tracked=inputs.tracked(world.time), time=world.time)
        command = controller.compute(obs)
        step_s.append(time.process_time() - c0)
        status = command.status
        if status in ('arrived', 'failed', 'no_path'):
            break
        world.step(command.v, command.omega, dt)
    return step_s, inputs, world.time, status


def measure_steps(steps, seed, use_ros, display_plan=False):
    """Time ``steps`` control steps over episodes of consecutive seeds.

    ``display_plan``: see :func:`run_episode_timed`.

    Returns
    -------
    dict
        ``step_ms`` (median, p90, p99, max, mean), ``scan_ms`` and
        ``track_ms`` (medians, None without ROS), ``load`` (fraction of one
        core), ``steps``, ``sim_time_s``, ``episodes`` (seed, steps, final
        status) and the scene.
    """
    step_s, scan_s, track_s, episodes = [], [], [], []
    sim_time = 0.0
    for attempt in range(steps + 1):  # bounded: each episode times at least one step
        if len(step_s) >= steps:
            break
        episode_seed = seed + attempt
        try:
            scenario = bench_scenario(episode_seed)
            timed, inputs, driven, status = run_episode_timed(
                scenario, steps - len(step_s), use_ros, display_plan)
        except PlanningError as err:
            episodes.append({'seed': episode_seed, 'steps': 0, 'status': f'skipped: {err}'})
            continue
        step_s += timed
        scan_s += inputs.scan_s
        track_s += inputs.track_s
        sim_time += len(timed) / CONTROL_RATE_HZ
        episodes.append({'seed': episode_seed, 'steps': len(timed), 'status': status,
                         'sim_time_s': driven})
    ms = np.array(step_s) * 1e3
    load = (sum(step_s) + sum(scan_s) + sum(track_s)) / sim_time if sim_time > 0 else math.nan
    return {
        'steps': len(step_s), 'sim_time_s': sim_time, 'episodes': episodes,
        'step_ms': {'median': float(np.median(ms)), 'p90': float(np.percentile(ms, 90)),
                    'p99': float(np.percentile(ms, 99)), 'max': float(ms.max()),
                    'mean': float(ms.mean())},
        'scan_ms': 1e3 * statistics.median(scan_s) if scan_s else None,
        'track_ms': 1e3 * statistics.median(track_s) if track_s else None,
        'load': load, 'ros_inputs': use_ros, 'display_plan': display_plan,
        'scene': {'beams': BEAMS, 'moving_obstacles': MOVING_OBSTACLES, 'size_m': SIZE_M,
                  'control_rate_hz': CONTROL_RATE_HZ, 'scan_rate_hz': SCAN_RATE_HZ}}


def parse_demo_outcome(text):
    """The figures of ``fusion-planner demo``'s outcome line, or None.

    Examples
    --------
    >>> line = ('arrived: yes   sim time: 22.10 s   (wall 5.0 s with start-up, 5.8x real '
    ...         'time)   path length: 13.36 m   collisions: 0   min clearance: 0.293 m')
    >>> parse_demo_outcome(line)
    {'arrived': True, 'sim_time_s': 22.1, 'wall_s': 5.0, 'factor': 5.8}
    """
    match = DEMO_OUTCOME.search(text)
    if match is None:
        return None
    return {'arrived': match['arrived'] == 'yes', 'sim_time_s': float(match['sim']),
            'wall_s': float(match['wall']), 'factor': float(match['factor'])}


def measure_demo(factor, timeout_s=DEMO_TIMEOUT_S):
    """Run ``fusion-planner demo`` in a child process; its figures or an error.

    Returns
    -------
    dict
        ``requested`` factor, and either ``error`` or the fields of
        :func:`parse_demo_outcome` plus ``cpu_s`` (the child's user + system
        time, start-up included).
    """
    result = {'requested': factor}
    root = str(pathlib.Path(__file__).resolve().parents[2])
    with tempfile.TemporaryDirectory() as folder:
        cmd = [sys.executable, '-c', 'import sys; from fusion_planner.cli.main import main; '
               'sys.exit(main(sys.argv[1:]))', 'demo', '--real-time-factor', f'{factor:g}',
               '--plot', str(pathlib.Path(folder) / 'demo.png')]
        before = resource.getrusage(resource.RUSAGE_CHILDREN)
        try:
            done = subprocess.run(cmd, capture_output=True, text=True, timeout=timeout_s,
                                  cwd=root, check=False)
        except subprocess.TimeoutExpired:
            return dict(result, error=f'no outcome within {timeout_s:g} s')
        after = resource.getrusage(resource.RUSAGE_CHILDREN)
    outcome = parse_demo_outcome(done.stdout)
    if outcome is None:
        tail = (done.stderr.strip().splitlines() or ['no output'])[-1]
        return dict(result, error=f'exit {done.returncode}: {tail}')
    cpu = (after.ru_utime - before.ru_utime) + (after.ru_stime - before.ru_stime)
    return dict(result, cpu_s=cpu, **outcome)


def evaluate_targets(steps, demo):
    """Verdicts on the local-planner targets (see peers.evaluate_targets)."""
    verdicts = []
    if steps is not None:
        median = steps['step_ms']['median']
        verdicts.append(_verdict(
            f'local-planner step < {TARGET_STEP_MS:g} ms ({BEAMS} beams, {MOVING_OBSTACLES} '
            'tracked obstacles, median CPU)', median < TARGET_STEP_MS,
            f'{median:.3f} ms = {median / TARGET_STEP_MS:.2f}x the target '
            f'(p99 {steps["step_ms"]["p99"]:.3f} ms, max {steps["step_ms"]["max"]:.3f} ms)'))
        load = steps['load']
        verdicts.append(_verdict(
            f'local planner at {CONTROL_RATE_HZ:g} Hz < {100 * TARGET_LOAD:.0f} % of one core',
            load < TARGET_LOAD, f'{100 * load:.1f} % (steps, scans and tracks)'))
    if demo is not None:
        if 'error' in demo:
            verdicts.append(_verdict(f'demo >= {TARGET_DEMO_FACTOR:g}x real time', False,
                                     demo['error']))
        else:
            verdicts.append(_verdict(
                f'demo >= {TARGET_DEMO_FACTOR:g}x real time (three nodes, one process)',
                demo['factor'] >= TARGET_DEMO_FACTOR,
                f'{demo["factor"]:.1f}x of {demo["requested"]:g}x asked '
                f'({demo["sim_time_s"]:.1f} s simulated, wall {demo["wall_s"]:.1f} s and CPU '
                f'{demo["cpu_s"]:.1f} s with start-up; arrived: '
                f'{"yes" if demo["arrived"] else "no"})'))
    return verdicts


def _verdict(target, ok, detail):
    return {'target': target, 'status': 'met' if ok else 'NOT met', 'detail': detail}


def format_report(steps, demo, verdicts, notes):
    """The text report."""
    lines = [f'Local planner benchmark; {machine_summary()}']
    lines += [f'  note: {note}' for note in notes]
    if steps is not None:
        s = steps['step_ms']
        lines += ['', f'control step of the fusion controller: {steps["steps"]} steps, '
                      f'{steps["sim_time_s"]:.1f} s simulated at {CONTROL_RATE_HZ:g} Hz, '
                      f'{BEAMS} beams at {SCAN_RATE_HZ:g} Hz, {MOVING_OBSTACLES} tracked obstacles, '
                      f'display rollout {"on" if steps["display_plan"] else "off"}',
                  f'{"CPU [ms]":<26}{"median":>9}{"p90":>9}{"p99":>9}{"max":>9}{"mean":>9}',
                  f'{"step (obs + compute)":<26}{s["median"]:>9.3f}{s["p90"]:>9.3f}'
                  f'{s["p99"]:>9.3f}{s["max"]:>9.3f}{s["mean"]:>9.3f}']
        for name, key in (('scan -> points', 'scan_ms'), ('tracker update', 'track_ms')):
            if steps[key] is not None:
                lines.append(f'{name:<26}{steps[key]:>9.3f}')
        lines.append(f'load at {CONTROL_RATE_HZ:g} Hz: {100 * steps["load"]:.1f} % of one core')
        lines.append('episodes: ' + ', '.join(
            f'seed {e["seed"]} {e["steps"]} steps ({e["status"]})' for e in steps['episodes']))
    if demo is not None:
        lines += ['', 'demo (three nodes in one process, simulated time):']
        if 'error' in demo:
            lines.append(f'  failed: {demo["error"]}')
        else:
            lines.append(f'  asked {demo["requested"]:g}x, reached {demo["factor"]:.1f}x; '
                         f'{demo["sim_time_s"]:.1f} s simulated, wall {demo["wall_s"]:.1f} s, '
                         f'child CPU {demo["cpu_s"]:.1f} s (start-up included); arrived '
                         f'{"yes" if demo["arrived"] else "no"}')
    lines += ['', 'targets:']
    lines += [f'  [{v["status"]}] {v["target"]}: {v["detail"]}' for v in verdicts]
    return '\n'.join(lines)


def add_arguments(parser):
    """Options of ``fusion-planner bench local``."""
    parser.add_argument('--steps', type=int, default=DEFAULT_STEPS, metavar='N',
                        help='control steps to time (default %(default)s)')
    parser.add_argument('--seed', type=int, default=DEFAULT_SEED,
                        help='first scenario seed (default %(default)s)')
    parser.add_argument('--demo-factor', type=float, default=DEFAULT_DEMO_FACTOR, metavar='F',
                        help='real-time factor asked of the demo (default %(default)s)')
    parser.add_argument('--no-demo', action='store_true', help='skip the demo run')
    parser.add_argument('--no-ros', action='store_true',
                        help='feed the controller the world\'s points and ideal tracks instead '
                             'of converted ROS messages')
    parser.add_argument('--display-plan', action='store_true',
                        help='time the step with the display rollout (local_plan) on, as in a '
                             'node whose local_plan has a subscriber')
    parser.add_argument('--quick', action='store_true',
                        help=f'{QUICK_STEPS} steps and no demo: checks that it all runs')
    parser.add_argument('--json', action='store_true', help='print one JSON object')


def run(args):
    """Run the benchmark; 0 when it ran (whatever the verdicts), 1 when the demo failed.

    Raises
    ------
    InvalidInput
        Bad options.
    MissingExtra
        ROS 2 not importable, unless ``--no-ros`` and no demo run; for the
        demo run, the ``plot`` or ``record`` extra missing (before any
        work).
    """
    steps_wanted = QUICK_STEPS if args.quick else args.steps
    if steps_wanted < 1:
        raise InvalidInput(f'--steps must be positive, got {steps_wanted}')
    if not (args.demo_factor > 0 and math.isfinite(args.demo_factor)):
        raise InvalidInput(f'--demo-factor must be a positive number, got {args.demo_factor!r}')
    run_demo = not (args.quick or args.no_demo)
    if run_demo or not args.no_ros:
        require('ros', 'bench local', alternative='give --no-ros --no-demo')
    if run_demo:
        for extra in ('plot', 'record'):  # the demo writes its default outputs
            require(extra, 'bench local (its demo run)', alternative='give --no-demo')
    notes = []
    if args.no_ros:
        notes.append('inputs from the world, not from ROS messages: asked (--no-ros)')
    steps = measure_steps(steps_wanted, args.seed, use_ros=not args.no_ros,
                          display_plan=args.display_plan)
    demo = measure_demo(args.demo_factor) if run_demo else None
    verdicts = evaluate_targets(steps, demo)
    if args.json:
        print(json.dumps(_strict({'machine': machine_summary(), 'notes': notes, 'steps': steps,
                                  'demo': demo, 'targets': verdicts})))
    else:
        print(format_report(steps, demo, verdicts, notes))
    return EXIT_FAILED if demo is not None and 'error' in demo else EXIT_OK
