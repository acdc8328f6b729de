"""Closed-loop test scenarios: the YAML schema, its loader, and random scenarios.

A scenario says what the planner knows (a map file), what it does not (unknown
static obstacles, moving obstacles), where the robot starts and must go, and
how the run is simulated. :func:`load_scenario` reads and validates a file;
:func:`random_scenario` generates one from a seed.

Schema
------
Every length is in metres, every angle in radians, every time in seconds,
map frame. ``point`` is ``[x, y]``. Keys not listed are refused (typos are
errors, not silently ignored).

=================================  ==========  ==========  ==============================================
key                                type        default     meaning
=================================  ==========  ==========  ==============================================
``name``                           str         file stem   label used in reports
``description``                    str         ``''``      free text
``map``                            str         required    map file, relative to the scenario file:
                                                           map_server ``.yaml`` or MovingAI ``.map``
``seed``                           int >= 0    0           seed of random walks and scan noise
``robot.start``                    [x, y, yaw] required    start pose
``robot.radius``                   float > 0   required    robot disc radius
``robot.max_speed``                float > 0   0.8         top linear speed [m/s]
``robot.max_accel``                float > 0   1.0         linear acceleration limit [m/s^2]
``robot.max_omega``                float > 0   2.0         turn-rate limit [rad/s]
``goal``                           point       required    goal position
``unknown_obstacles``              list        ``[]``      static obstacles missing from the map, each
                                                           ``{circle: {center: point, radius: r}}`` or
                                                           ``{rectangle: {min: point, max: point}}``
``moving_obstacles``               list        ``[]``      moving circles, each ``{radius: r, model:
                                                           NAME, ...}`` with the model's keys below
  ``model: bounce``                                        ``position: point, velocity: [vx, vy]``
  ``model: waypoints``                                     ``points: [point, point, ...], speed: v``
                                                           (closed loop, starts at the first point)
  ``model: random_walk``                                   ``position: point, speed: v, turn_std: s``
                                                           (heading diffusion [rad/sqrt(s)])
``planner``                        mapping     ``{}``      :class:`PlannerConfig` fields: ``algorithm``,
                                                           ``neighbourhood``, ``heuristic``, ``alpha``,
                                                           ``beta``, ``gamma``, ``refine``,
                                                           ``robot_radius`` (default ``robot.radius``),
                                                           ``safety_distance`` (default 0.3),
                                                           ``path_spacing``
``limits.time_limit_s``            float > 0   120         give up after this much simulated time
``limits.dt``                      float > 0   0.1         simulation and control period
``limits.max_collisions``          int >= 1    10          stop after this many contact events
``scan.beams``                     int >= 1    360         laser beams
``scan.fov``                       float       2*pi        field of view, (0, 2*pi]
``scan.range_min``                 float >= 0  0.05        shortest valid range
``scan.range_max``                 float > 0   8.0         longest range
``scan.noise_std``                 float >= 0  0.0         Gaussian range noise
``perception``                     str         ``scan``    what the controller is told about moving
                                                           obstacles: ``scan`` (tracked from the
                                                           simulated scans) or ``ideal`` (their true
                                                           states, seen or not)
``follower``                       mapping     ``{}``      overrides of ``FollowerParams`` fields (the
                                                           robot limits and ``control_period`` come from
                                                           ``robot`` and ``limits``)
=================================  ==========  ==========  ==============================================

A file is refused (:class:`ScenarioError`, one sentence naming the file and
the key) when a required key is missing, a value has the wrong type or range,
a key is unknown, a motion model is unknown, the start or the goal is off the
map, the robot disc at the start or at the goal overlaps a known or unknown
obstacle, a moving obstacle starts overlapping the robot or a static
obstacle, or ``robot.max_speed * limits.dt`` exceeds ``robot.radius`` (the
collision check could then miss thin walls).

Examples
--------
>>> s = random_scenario(3)
>>> s.robot.radius > 0 and len(s.moving_obstacles) >= 1
True
>>> all(m.top_speed() < 0.5 * s.robot.max_speed for m in s.moving_obstacles)
True
"""

import dataclasses
import logging
import math
import numbers
import pathlib
import types
from dataclasses import dataclass, field

import numpy as np
import yaml

from fusion_planner.core import map_files
from fusion_planner.core.errors import InvalidInput, PlanningError
from fusion_planner.core.grid import GridMap
from fusion_planner.core.global_planning.planner import GlobalPlanner, PlannerConfig
from fusion_planner.core.simulation.perception import PERCEPTION_MODES
from fusion_planner.core.simulation.world import (
    BounceMotion, Circle, MovingObstacle, RandomWalkMotion, Rectangle, RobotSpec, ScanConfig,
    StaticScene, WaypointMotion, rasterise_obstacles)

LOGGER = logging.getLogger(__name__)

#: Largest scenario file read [bytes]; a scenario is a page of YAML.
MAX_SCENARIO_BYTES = 1 << 20
#: Default safety distance of the planner's redundant-node removal [m].
DEFAULT_SAFETY_DISTANCE = 0.3

_TOP_KEYS = ('name', 'description', 'map', 'seed', 'robot', 'goal', 'unknown_obstacles',
             'moving_obstacles', 'planner', 'limits', 'scan', 'follower', 'perception')
_ROBOT_KEYS = ('start', 'radius', 'max_speed', 'max_accel', 'max_omega')
_LIMIT_KEYS = ('time_limit_s', 'dt', 'max_collisions')
_SCAN_KEYS = ('beams', 'fov', 'range_min', 'range_max', 'noise_std')
_PLANNER_KEYS = ('algorithm', 'neighbourhood', 'heuristic', 'alpha', 'beta', 'gamma', 'refine',
                 'robot_radius', 'safety_distance', 'path_spacing', 'max_expansions',
                 'time_limit_s')
_MODEL_KEYS = {
    'bounce': ('position', 'velocity'),
    'waypoints': ('points', 'speed'),
    'random_walk': ('position', 'speed', 'turn_std'),
}


class ScenarioError(InvalidInput):
    """A scenario file or description is invalid; the message names the file and the key."""

    outcome = 'invalid_scenario'


@dataclass(frozen=True)
class Limits:
    """When a simulated run stops.

    Attributes
    ----------
    time_limit_s : float
        Simulated time budget [s].
    dt : float
        Simulation and control period [s].
    max_collisions : int
        Stop after this many contact events.
    """

    time_limit_s: float = 120.0
    dt: float = 0.1
    max_collisions: int = 10


@dataclass(frozen=True)
class Scenario:
    """A complete closed-loop test case.

    Attributes
    ----------
    name : str
    grid : GridMap
        The known map (what the global planner sees).
    robot : RobotSpec
    start : tuple of float
        ``(x, y, yaw)`` [m, m, rad].
    goal : tuple of float
        ``(x, y)`` [m].
    unknown_obstacles : tuple of Circle or Rectangle
        Static obstacles absent from ``grid``.
    moving_obstacles : tuple of MovingObstacle
    planner : PlannerConfig
    limits : Limits
    scan : ScanConfig
    seed : int
    follower : Mapping
        Overrides of ``FollowerParams`` fields (read-only mapping).
    perception : str
        One of :data:`~fusion_planner.core.simulation.perception.PERCEPTION_MODES`.
    description : str
    source : str or None
        The file it was loaded from.
    map_path : str or None
        The map file (absolute), when loaded from a file.
    family : str or None
        The generator's family (see
        :mod:`~fusion_planner.core.simulation.families`), None for a file.
    solvable : bool or None
        Whether the goal can be reached in the world (a generator knows;
        None for a file).
    """

    name: str
    grid: GridMap
    robot: RobotSpec
    start: tuple
    goal: tuple
    unknown_obstacles: tuple = ()
    moving_obstacles: tuple = ()
    planner: PlannerConfig = field(default_factory=PlannerConfig)
    limits: Limits = field(default_factory=Limits)
    scan: ScanConfig = field(default_factory=ScanConfig)
    seed: int = 0
    follower: types.MappingProxyType = field(default_factory=lambda: types.MappingProxyType({}))
    perception: str = PERCEPTION_MODES[0]
    description: str = ''
    source: str = None
    map_path: str = None
    family: str = None
    solvable: bool = None

    def true_grid(self):
        """The known map with the unknown static obstacles burnt in (GridMap)."""
        circles = [o for o in self.unknown_obstacles if isinstance(o, Circle)]
        rects = [o for o in self.unknown_obstacles if isinstance(o, Rectangle)]
        return rasterise_obstacles(self.grid, circles, rects)

    def follower_params(self):
        """The :class:`~fusion_planner.core.local_planning.follow.FollowerParams` of this scenario.

        The robot's limits and radius and the control period come from
        ``robot`` and ``limits`` (the robot reverses as fast as it drives
        forward). So does the turn-rate ramp: ``max_alpha`` = ``max_accel /
        radius`` [rad/s^2], what a differential drive whose wheels sit at its
        radius reaches with both wheels accelerating fully in opposite
        directions (the simulated robot bounds only speed, acceleration and
        turn rate). ``follower`` overrides any field,
        ``max_alpha`` included (an ``apf`` mapping overrides fields of
        ``ApfParams``).

        Raises
        ------
        InvalidInput
            An override has a bad value.
        """
        from fusion_planner.core.local_planning import apf, follow  # the controllers' modules; imported on use
        overrides = dict(self.follower)
        apf_overrides = overrides.pop('apf', None)
        robot = self.robot
        values = dict(max_speed=robot.max_speed, max_reverse_speed=robot.max_speed,
                      max_accel=robot.max_accel,
                      max_omega=robot.max_omega, max_alpha=robot.max_accel / robot.radius,
                      robot_radius=robot.radius, control_period=self.limits.dt)
        values.update(overrides)
        if apf_overrides is not None:
            if not isinstance(apf_overrides, dict):
                raise InvalidInput('follower.apf must be a mapping of ApfParams fields, '
                                   f'got {apf_overrides!r}')
            try:
                values['apf'] = apf.ApfParams(**apf_overrides)
            except TypeError as err:
                raise InvalidInput(f'follower.apf is invalid: {err}') from None
        try:
            return follow.FollowerParams(**values)
        except TypeError as err:
            raise InvalidInput(f'follower overrides are invalid: {err}') from None

    def static_scene(self):
        """The static world (known cells, unknown circles and rectangles, map edge)."""
        circles = [o for o in self.unknown_obstacles if isinstance(o, Circle)]
        rects = [o for o in self.unknown_obstacles if isinstance(o, Rectangle)]
        return StaticScene(self.grid, circles, rects)


# -- loading --------------------------------------------------------------------

def load_scenario(path):
    """Read and validate a scenario file.

    Parameters
    ----------
    path : str or os.PathLike
        A YAML file following the schema of this module.

    Returns
    -------
    Scenario

    Raises
    ------
    ScenarioError
        Unreadable file, invalid YAML, or any violation of the schema (one
        sentence naming the file and the key).
    MapError
        The map file cannot be loaded (raised by
        :func:`~fusion_planner.core.map_files.load_map`).

    Examples
    --------
    >>> import tempfile, os
    >>> with tempfile.TemporaryDirectory() as d:
    ...     p = os.path.join(d, 's.yaml')
    ...     _ = open(p, 'w').write('map: m.yaml\\nrobot: {start: [1, 1, 0]}\\ngoal: [2, 2]\\n')
    ...     try:
    ...         load_scenario(p)
    ...     except ScenarioError as err:
    ...         print(str(err).endswith("missing required key 'robot.radius'"))
    True
    """
    path = pathlib.Path(path)
    try:
        if path.stat().st_size > MAX_SCENARIO_BYTES:
            raise ScenarioError(f'scenario {path}: file is larger than {MAX_SCENARIO_BYTES} bytes')
        text = path.read_text(encoding='utf-8')
    except OSError as err:
        raise ScenarioError(f'scenario {path}: cannot read the file ({err.strerror or err})') from None
    except UnicodeDecodeError:
        raise ScenarioError(f'scenario {path}: the file is not UTF-8 text') from None
    try:
        doc = yaml.safe_load(text)
    except yaml.YAMLError as err:
        mark = getattr(err, 'problem_mark', None)
        where = f' at line {mark.line + 1}' if mark is not None else ''
        raise ScenarioError(f'scenario {path}: invalid YAML{where}') from None
    return scenario_from_dict(doc, source=path)


def scenario_from_dict(doc, source=None, grid=None):
    """Build and validate a scenario from a parsed YAML mapping.

    Parameters
    ----------
    doc : dict
        The document (see the module schema).
    source : path-like, optional
        The file it came from: names it in errors and anchors the relative
        ``map`` path.
    grid : GridMap, optional
        Use this map instead of loading ``doc['map']`` (then ``map`` is
        optional).

    Returns
    -------
    Scenario

    Raises
    ------
    ScenarioError, MapError
    """
    r = _Reader(source)
    r.mapping(doc, '')
    r.known_keys(doc, _TOP_KEYS, '')
    map_name = r.string(doc, 'map', required=grid is None)
    name = r.string(doc, 'name', default=pathlib.Path(source).stem if source else 'scenario')
    description = r.string(doc, 'description', default='')
    seed = r.integer(doc, 'seed', default=0, minimum=0)

    robot_doc = r.section(doc, 'robot', required=True)
    r.known_keys(robot_doc, _ROBOT_KEYS, 'robot')
    start = r.vector(robot_doc, 'start', 3, 'robot.', required=True)
    robot = RobotSpec(
        radius=r.number(robot_doc, 'radius', 'robot.', required=True, positive=True),
        max_speed=r.number(robot_doc, 'max_speed', 'robot.', default=0.8, positive=True),
        max_accel=r.number(robot_doc, 'max_accel', 'robot.', default=1.0, positive=True),
        max_omega=r.number(robot_doc, 'max_omega', 'robot.', default=2.0, positive=True))
    goal = r.vector(doc, 'goal', 2, '', required=True)

    unknown = tuple(r.static_obstacle(item, f'unknown_obstacles[{i}]')
                    for i, item in enumerate(r.sequence(doc, 'unknown_obstacles')))
    moving = tuple(r.moving_obstacle(item, f'moving_obstacles[{i}]')
                   for i, item in enumerate(r.sequence(doc, 'moving_obstacles')))

    limits_doc = r.section(doc, 'limits')
    r.known_keys(limits_doc, _LIMIT_KEYS, 'limits')
    limits = Limits(
        time_limit_s=r.number(limits_doc, 'time_limit_s', 'limits.', default=120.0, positive=True),
        dt=r.number(limits_doc, 'dt', 'limits.', default=0.1, positive=True),
        max_collisions=r.integer(limits_doc, 'max_collisions', 'limits.', default=10, minimum=1))

    scan_doc = r.section(doc, 'scan')
    r.known_keys(scan_doc, _SCAN_KEYS, 'scan')
    range_min = r.number(scan_doc, 'range_min', 'scan.', default=0.05, minimum=0.0)
    range_max = r.number(scan_doc, 'range_max', 'scan.', default=8.0, positive=True)
    if range_min >= range_max:
        r.fail('scan.range_min', f'must be smaller than scan.range_max ({range_max:g})')
    scan = ScanConfig(
        beams=r.integer(scan_doc, 'beams', 'scan.', default=360, minimum=1),
        fov=r.number(scan_doc, 'fov', 'scan.', default=2 * math.pi, positive=True,
                     maximum=2 * math.pi + 1e-9),
        range_min=range_min, range_max=range_max,
        noise_std=r.number(scan_doc, 'noise_std', 'scan.', default=0.0, minimum=0.0))

    planner_doc = dict(r.section(doc, 'planner'))
    r.known_keys(planner_doc, _PLANNER_KEYS, 'planner')
    planner_doc.setdefault('robot_radius', robot.radius)
    planner_doc.setdefault('safety_distance', DEFAULT_SAFETY_DISTANCE)
    try:
        planner = PlannerConfig(**planner_doc)
    except (InvalidInput, TypeError) as err:
        r.fail('planner', f'is invalid: {_sentence(err)}')

    follower = r.section(doc, 'follower')
    r.known_keys(follower, _follower_fields(), 'follower')
    perception = r.string(doc, 'perception', default=PERCEPTION_MODES[0])
    if perception not in PERCEPTION_MODES:
        r.fail('perception', f'must be one of {", ".join(PERCEPTION_MODES)}, got {perception!r}')

    map_path = None
    if grid is None:   # the map is loaded last: schema errors are reported first
        base = pathlib.Path(source).parent if source is not None else pathlib.Path('.')
        map_path = (base / map_name).resolve()
        grid = map_files.load_map(map_path)

    scenario = Scenario(
        name=name, grid=grid, robot=robot, start=tuple(start), goal=tuple(goal),
        unknown_obstacles=unknown, moving_obstacles=moving, planner=planner, limits=limits,
        scan=scan, seed=seed, follower=types.MappingProxyType(dict(follower)),
        perception=perception, description=description, source=None if source is None else str(source),
        map_path=None if map_path is None else str(map_path))
    check_scenario(scenario, r)
    return scenario


def check_scenario(scenario, reader=None):
    """Check the geometry of a scenario: endpoints on the map and clear, sane speeds.

    Parameters
    ----------
    scenario : Scenario
    reader : optional
        Internal: names the source file in errors.

    Raises
    ------
    ScenarioError
        The start or goal is off the map or the robot there overlaps an
        obstacle; a moving obstacle starts overlapping the robot, a static
        obstacle or nothing of the map; one step at top speed is longer than
        the robot radius.
    """
    r = reader or _Reader(scenario.source)
    grid, robot = scenario.grid, scenario.robot
    scene = scenario.static_scene()
    start = np.asarray(scenario.start[:2], float)
    goal = np.asarray(scenario.goal, float)
    for key, point in (('robot.start', start), ('goal', goal)):
        if not grid.contains(grid.cell_of(point)):
            r.fail(key, f'{_fmt(point)} is outside the map')
        if scene.disc_collides(point, robot.radius):
            r.fail(key, f'{_fmt(point)} puts the robot (radius {robot.radius:g} m) inside an obstacle '
                        'or against the map edge')
    for i, mover in enumerate(scenario.moving_obstacles):
        p = mover.start_position()
        key = f'moving_obstacles[{i}]'
        if not grid.contains(grid.cell_of(p)):
            r.fail(key, f'starts at {_fmt(p)}, outside the map')
        if np.hypot(*(p - start)) < mover.radius + robot.radius:
            r.fail(key, f'starts at {_fmt(p)}, overlapping the robot')
        if not isinstance(mover.motion, WaypointMotion) and scene.disc_collides(p, mover.radius):
            r.fail(key, f'starts at {_fmt(p)}, inside a static obstacle')
    if scenario.follower:
        try:
            scenario.follower_params()
        except InvalidInput as err:
            r.fail('follower', f'is invalid: {_sentence(err)}')
    if robot.max_speed * scenario.limits.dt > robot.radius:
        r.fail('limits.dt', f'{scenario.limits.dt:g} s lets the robot move more than its radius '
                            'in one step at robot.max_speed')


def _follower_fields():
    """Names of the FollowerParams fields (the ``follower`` overrides)."""
    from fusion_planner.core.local_planning import follow  # the controllers' module; imported on use
    return tuple(f.name for f in dataclasses.fields(follow.FollowerParams))


class _Reader:
    """Typed access to a parsed YAML document with errors naming file and key."""

    def __init__(self, source):
        self.source = source

    def fail(self, key, problem):
        where = f'scenario {self.source}' if self.source is not None else 'scenario'
        raise ScenarioError(f"{where}: key '{key}' {problem}")

    def missing(self, key):
        where = f'scenario {self.source}' if self.source is not None else 'scenario'
        raise ScenarioError(f"{where}: missing required key '{key}'")

    def mapping(self, value, key):
        if not isinstance(value, dict):
            where = f'scenario {self.source}' if self.source is not None else 'scenario'
            if key == '':
                raise ScenarioError(f'{where}: the document must be a YAML mapping of keys')
            self.fail(key, f'must be a mapping, got {_kind(value)}')
        return value

    def known_keys(self, doc, allowed, prefix):
        for key in doc:
            if key not in allowed:
                full = f'{prefix}.{key}' if prefix else str(key)
                self.fail(full, f'is unknown (allowed here: {", ".join(allowed)})')

    def section(self, doc, key, required=False):
        if key not in doc or doc[key] is None:
            if required:
                self.missing(key)
            return {}
        return self.mapping(doc[key], key)

    def sequence(self, doc, key):
        value = doc.get(key)
        if value is None:
            return []
        if not isinstance(value, list):
            self.fail(key, f'must be a list, got {_kind(value)}')
        return value

    def _get(self, doc, name, prefix, required, default):
        full = prefix + name
        if name not in doc or doc[name] is None:
            if required:
                self.missing(full)
            return full, default, False
        return full, doc[name], True

    def string(self, doc, name, prefix='', required=False, default=None):
        full, value, given = self._get(doc, name, prefix, required, default)
        if given and not isinstance(value, str):
            self.fail(full, f'must be a string, got {_kind(value)}')
        return value

    def number(self, doc, name, prefix='', required=False, default=None, positive=False,
               minimum=None, maximum=None):
        full, value, given = self._get(doc, name, prefix, required, default)
        if not given:
            return default
        if isinstance(value, bool) or not isinstance(value, numbers.Real) \
                or not math.isfinite(float(value)):
            self.fail(full, f'must be a finite number, got {_kind(value)}')
        value = float(value)
        if positive and value <= 0:
            self.fail(full, f'must be positive, got {value:g}')
        if minimum is not None and value < minimum:
            self.fail(full, f'must be at least {minimum:g}, got {value:g}')
        if maximum is not None and value > maximum:
            self.fail(full, f'must be at most {maximum:g}, got {value:g}')
        return value

    def integer(self, doc, name, prefix='', required=False, default=None, minimum=None):
        full, value, given = self._get(doc, name, prefix, required, default)
        if not given:
            return default
        if isinstance(value, bool) or not isinstance(value, numbers.Integral):
            self.fail(full, f'must be an integer, got {_kind(value)}')
        if minimum is not None and value < minimum:
            self.fail(full, f'must be at least {minimum}, got {value}')
        return int(value)

    def vector(self, doc, name, size, prefix='', required=False, default=None):
        full, value, given = self._get(doc, name, prefix, required, default)
        if not given:
            return default
        if (not isinstance(value, list) or len(value) != size
                or not all(isinstance(v, numbers.Real) and not isinstance(v, bool)
                           and math.isfinite(float(v)) for v in value)):
            self.fail(full, f'must be a list of {size} finite numbers, got {_kind(value)}')
        return tuple(float(v) for v in value)

    def static_obstacle(self, item, key):
        self.mapping(item, key)
        if len(item) != 1 or next(iter(item)) not in ('circle', 'rectangle'):
            self.fail(key, "must be {circle: {...}} or {rectangle: {...}}")
        kind, body = next(iter(item.items()))
        full = f'{key}.{kind}'
        self.mapping(body, full)
        if kind == 'circle':
            self.known_keys(body, ('center', 'radius'), full)
            return Circle(self.vector(body, 'center', 2, full + '.', required=True),
                          self.number(body, 'radius', full + '.', required=True, positive=True))
        self.known_keys(body, ('min', 'max'), full)
        lo = self.vector(body, 'min', 2, full + '.', required=True)
        hi = self.vector(body, 'max', 2, full + '.', required=True)
        if not (lo[0] < hi[0] and lo[1] < hi[1]):
            self.fail(full, f'needs min < max in x and y, got min {list(lo)} and max {list(hi)}')
        return Rectangle(lo, hi)

    def moving_obstacle(self, item, key):
        self.mapping(item, key)
        model = self.string(item, 'model', key + '.', required=True)
        if model not in _MODEL_KEYS:
            self.fail(f'{key}.model', f'names an unknown motion model {model!r} '
                                      f'(known: {", ".join(_MODEL_KEYS)})')
        self.known_keys(item, ('radius', 'model') + _MODEL_KEYS[model], key)
        radius = self.number(item, 'radius', key + '.', required=True, positive=True)
        p = key + '.'
        if model == 'bounce':
            motion = BounceMotion(self.vector(item, 'position', 2, p, required=True),
                                  self.vector(item, 'velocity', 2, p, required=True))
        elif model == 'waypoints':
            points = item.get('points')
            if not isinstance(points, list) or len(points) < 2:
                self.fail(p + 'points', 'must be a list of at least two points [x, y]')
            pts = tuple(self.vector({'points': pt}, 'points', 2, p) for pt in points)
            motion = WaypointMotion(pts, self.number(item, 'speed', p, required=True, minimum=0.0))
        else:
            motion = RandomWalkMotion(self.vector(item, 'position', 2, p, required=True),
                                      self.number(item, 'speed', p, required=True, minimum=0.0),
                                      self.number(item, 'turn_std', p, required=True, minimum=0.0))
        return MovingObstacle(radius, motion)


def _kind(value):
    """Short description of a YAML value for error messages."""
    if value is None:
        return 'nothing'
    text = repr(value)
    return text if len(text) <= 40 else f'a {type(value).__name__}'


def _sentence(err):
    """An exception's message without a trailing period."""
    return str(err).rstrip('.')


def _fmt(point):
    return '(' + ', '.join(f'{float(v):.3f}' for v in point) + ')'


# -- random scenarios ------------------------------------------------------------

@dataclass(frozen=True)
class RandomScenarioConfig:
    """How :func:`random_scenario` builds a scenario.

    Attributes
    ----------
    size_m : float
        Edge of the square map [m].
    resolution : float
        Cell edge [m].
    robot : RobotSpec
    min_start_goal_m : float
        Smallest straight-line distance between start and goal [m].
    unknown_range : tuple of int
        Inclusive range of the number of unknown static obstacles.
    moving_range : tuple of int
        Inclusive range of the number of moving obstacles.
    moving_speed_fraction : tuple of float
        Range of moving-obstacle speeds as a fraction of the robot's top
        speed; the upper end must stay below 0.5.
    moving_radius : tuple of float
        Range of moving-obstacle radii [m].
    spawn_clearance_m : float
        No obstacle spawns closer than this to the start or the goal [m].
    passage_margin_m : float
        Start and goal must stay connected on the true map for a disc of
        ``robot.radius + passage_margin_m``.
    max_detour_ratio : float
        Unknown obstacles may lengthen the plan (made for the disc above) by
        at most this factor ...
    max_detour_offset_m : float
        ... and the plan around them must stay within this distance [m] of
        the plan on the known map: they force local detours, they do not
        close the passage the plan uses (that would need global re-planning,
        which the paper's fusion does not do).
    plan_inflation_margin_m : float
        The scenario's planner inflates the known map by ``robot.radius`` plus
        this margin, so that plans keep out of slits barely wider than the
        robot (as an inflation layer does).
    limits : Limits
    scan : ScanConfig
    max_attempts : int
        Bound on the regeneration attempts.
    """

    size_m: float = 12.0
    resolution: float = 0.1
    robot: RobotSpec = RobotSpec(radius=0.2, max_speed=0.8, max_accel=1.0, max_omega=2.0)
    min_start_goal_m: float = 6.0
    unknown_range: tuple = (1, 3)
    moving_range: tuple = (1, 3)
    moving_speed_fraction: tuple = (0.2, 0.45)
    moving_radius: tuple = (0.2, 0.3)
    spawn_clearance_m: float = 1.5
    passage_margin_m: float = 0.3
    max_detour_ratio: float = 1.5
    max_detour_offset_m: float = 1.5
    plan_inflation_margin_m: float = 0.15
    limits: Limits = Limits(time_limit_s=90.0, dt=0.1, max_collisions=10)
    scan: ScanConfig = ScanConfig(beams=180, range_max=6.0)
    max_attempts: int = 200

    def __post_init__(self):
        if not self.moving_speed_fraction[1] < 0.5:
            raise InvalidInput(
                'moving obstacles must stay slower than half the robot top speed '
                f'(moving_speed_fraction upper end < 0.5), got {self.moving_speed_fraction}')


def random_scenario(seed, config=None):
    """Generate a scenario: a random map, hidden static obstacles, moving obstacles.

    Parameters
    ----------
    seed : int
        Same seed, same scenario.
    config : RandomScenarioConfig, optional

    Returns
    -------
    Scenario
        ``name`` is ``'random-<seed>'``; the map is in memory (``map_path``
        None). The start and the goal are connected on the true map (known
        map plus unknown obstacles) for a disc of the robot radius plus a
        margin, checked with :class:`GlobalPlanner`; no obstacle spawns near
        them; every moving obstacle is slower than half the robot's top
        speed.

    Raises
    ------
    InvalidInput
        When no valid scenario was found within ``config.max_attempts``.

    Notes
    -----
    The map is one of two layouts, chosen by the seed: *rooms* (a 2 x 2 or
    3 x 2 grid of rooms whose walls have doorways at least 1.2 m wide) or
    *blocks* (scattered rectangular blocks). Some unknown obstacles are put
    on the planned path so that the local planner must leave it; each keeps
    the start and goal connected for a disc of ``robot.radius +
    passage_margin_m``, lengthens that disc's plan by at most
    ``max_detour_ratio`` and moves it by at most ``max_detour_offset_m``
    (a local detour, not a closed passage).
    """
    cfg = config or RandomScenarioConfig()
    rng = np.random.default_rng(np.random.SeedSequence(int(seed)))
    for _ in range(cfg.max_attempts):
        scenario = _try_random(rng, int(seed), cfg)
        if scenario is not None:
            return scenario
    raise InvalidInput(f'no valid random scenario found for seed {seed} in {cfg.max_attempts} attempts')


def _try_random(rng, seed, cfg):
    """One attempt of :func:`random_scenario`; None when the draw is unusable."""
    grid = _random_map(rng, cfg)
    robot = cfg.robot
    passage = robot.radius + cfg.passage_margin_m
    known_free = grid.traversable(passage + 0.05)
    free_cells = np.argwhere(known_free)
    if len(free_cells) < 2:
        return None
    picked = rng.choice(len(free_cells), size=min(60, len(free_cells)), replace=False)
    points = grid.world_of(free_cells[picked])
    pairs = [(a, b) for a in points[:30] for b in points[30:]
             if np.hypot(*(a - b)) >= cfg.min_start_goal_m]
    if not pairs:
        return None
    start_xy, goal = pairs[int(rng.integers(len(pairs)))]
    try:
        plan = GlobalPlanner(grid, PlannerConfig(robot_radius=passage)).plan(start_xy, goal)
    except PlanningError:
        return None
    yaw = float(rng.uniform(-math.pi, math.pi))
    start = (float(start_xy[0]), float(start_xy[1]), yaw)
    goal = (float(goal[0]), float(goal[1]))
    unknown = _random_unknown(rng, cfg, grid, plan, start_xy, np.asarray(goal), passage)
    if unknown is None:
        return None
    circles = [o for o in unknown if isinstance(o, Circle)]
    rects = [o for o in unknown if isinstance(o, Rectangle)]
    scene = StaticScene(grid, circles, rects)
    moving = _random_moving(rng, cfg, grid, scene, start_xy, np.asarray(goal))
    if moving is None:
        return None
    scenario = Scenario(
        name=f'random-{seed}', grid=grid, robot=robot, start=start, goal=goal,
        unknown_obstacles=tuple(unknown), moving_obstacles=tuple(moving),
        planner=PlannerConfig(robot_radius=robot.radius + cfg.plan_inflation_margin_m,
                              safety_distance=DEFAULT_SAFETY_DISTANCE),
        limits=cfg.limits, scan=cfg.scan, seed=seed,
        description='generated by random_scenario', family='mixed', solvable=True)
    try:
        check_scenario(scenario)
    except ScenarioError:
        return None
    return scenario


def _random_map(rng, cfg):
    """A square map with a border wall and either rooms or blocks inside."""
    n = int(round(cfg.size_m / cfg.resolution))
    occ = np.zeros((n, n), bool)
    wall = max(1, int(round(0.1 / cfg.resolution)))
    occ[:wall, :] = occ[-wall:, :] = occ[:, :wall] = occ[:, -wall:] = True

    def cells(metres):
        return max(1, int(round(metres / cfg.resolution)))

    if rng.random() < 0.5:
        # rooms: interior walls on a coarse grid, each wall segment with a doorway
        nx, ny = int(rng.integers(2, 4)), 2
        xs = np.linspace(0, n, nx + 1).astype(int)[1:-1]
        ys = np.linspace(0, n, ny + 1).astype(int)[1:-1]
        door = cells(float(rng.uniform(1.2, 1.8)))
        for x in xs:
            occ[:, x:x + wall] = True
            bounds = np.concatenate([[0], ys, [n]])
            for lo, hi in zip(bounds[:-1], bounds[1:]):
                d0 = int(rng.integers(lo + wall + 1, max(hi - door - wall - 1, lo + wall + 2)))
                occ[d0:d0 + door, x:x + wall] = False
        for y in ys:
            occ[y:y + wall, :] = True
            bounds = np.concatenate([[0], xs, [n]])
            for lo, hi in zip(bounds[:-1], bounds[1:]):
                d0 = int(rng.integers(lo + wall + 1, max(hi - door - wall - 1, lo + wall + 2)))
                occ[y:y + wall, d0:d0 + door] = False
        occ[:wall, :] = occ[-wall:, :] = occ[:, :wall] = occ[:, -wall:] = True
    else:
        for _ in range(int(rng.integers(5, 10))):
            w, h = cells(float(rng.uniform(0.6, 2.5))), cells(float(rng.uniform(0.6, 2.5)))
            r0, c0 = int(rng.integers(wall, n - h - wall)), int(rng.integers(wall, n - w - wall))
            occ[r0:r0 + h, c0:c0 + w] = True
    return GridMap(occ, cfg.resolution)


def _random_unknown(rng, cfg, grid, plan, start, goal, passage):
    """Unknown static obstacles, some on the path; None when they block the way."""
    count = int(rng.integers(cfg.unknown_range[0], cfg.unknown_range[1] + 1))
    path = plan.path
    longest = cfg.max_detour_ratio * plan.metrics.length_m
    chosen = []
    for i in range(count * 10):
        if len(chosen) == count:
            break
        if i % 2 == 0 and len(path) > 2:
            center = path[int(rng.integers(len(path) // 5, len(path) * 4 // 5 + 1))]
            center = center + rng.normal(0.0, 0.15, size=2)
        else:
            xmin, xmax, ymin, ymax = grid.bounds()
            center = rng.uniform([xmin, ymin], [xmax, ymax])
        size = float(rng.uniform(0.2, 0.5))
        margin = cfg.spawn_clearance_m
        if np.hypot(*(center - start)) < margin + size or np.hypot(*(center - goal)) < margin + size:
            continue
        if rng.random() < 0.5:
            candidate = Circle((float(center[0]), float(center[1])), size)
        else:
            half = rng.uniform(0.15, size, size=2)
            candidate = Rectangle((float(center[0] - half[0]), float(center[1] - half[1])),
                                  (float(center[0] + half[0]), float(center[1] + half[1])))
        trial = chosen + [candidate]
        truth = rasterise_obstacles(grid, [o for o in trial if isinstance(o, Circle)],
                                    [o for o in trial if isinstance(o, Rectangle)])
        try:
            detour = GlobalPlanner(truth, PlannerConfig(robot_radius=passage)).plan(start, goal)
        except PlanningError:
            continue
        if detour.metrics.length_m > longest or \
                _max_offset(detour.path, path) > cfg.max_detour_offset_m:
            continue
        chosen.append(candidate)
    return chosen if len(chosen) >= cfg.unknown_range[0] else None


def _random_moving(rng, cfg, grid, scene, start, goal):
    """Moving obstacles away from the start and goal; None when none fit."""
    count = int(rng.integers(cfg.moving_range[0], cfg.moving_range[1] + 1))
    top = cfg.robot.max_speed
    free = np.argwhere(grid.traversable(cfg.moving_radius[1] + 0.1))
    moving = []
    for _ in range(count * 20):
        if len(moving) == count or len(free) == 0:
            break
        radius = float(rng.uniform(*cfg.moving_radius))
        speed = float(rng.uniform(*cfg.moving_speed_fraction)) * top
        p = grid.world_of(free[int(rng.integers(len(free)))])
        if (np.hypot(*(p - start)) < cfg.spawn_clearance_m + radius
                or np.hypot(*(p - goal)) < cfg.spawn_clearance_m + radius
                or scene.disc_collides(p, radius)):
            continue
        kind = rng.choice(3)
        if kind == 0:
            heading = float(rng.uniform(-math.pi, math.pi))
            motion = BounceMotion((float(p[0]), float(p[1])),
                                  (speed * math.cos(heading), speed * math.sin(heading)))
        elif kind == 1:
            motion = RandomWalkMotion((float(p[0]), float(p[1])), speed, float(rng.uniform(0.3, 1.0)))
        else:
            q = grid.world_of(free[int(rng.integers(len(free)))])
            if not _segment_clear(scene, p, q, radius) or np.hypot(*(q - p)) < 1.0:
                continue
            motion = WaypointMotion(((float(p[0]), float(p[1])), (float(q[0]), float(q[1]))), speed)
        moving.append(MovingObstacle(radius, motion))
    return moving if moving else None


def _max_offset(points, polyline):
    """Largest distance [m] from ``points`` (N, 2) to a polyline (M, 2), vectorised."""
    a, b = polyline[:-1], polyline[1:]
    ab = b - a                                                    # (S, 2)
    length2 = np.maximum(np.einsum('ij,ij->i', ab, ab), 1e-18)
    ap = points[:, None, :] - a[None, :, :]                       # (N, S, 2)
    t = np.clip(np.einsum('nsk,sk->ns', ap, ab) / length2, 0.0, 1.0)
    nearest = a[None, :, :] + t[..., None] * ab[None, :, :]
    distance = np.hypot(*(points[:, None, :] - nearest).transpose(2, 0, 1))
    return float(distance.min(axis=1).max())


def _segment_clear(scene, a, b, radius):
    """Whether a disc of ``radius`` sweeping from ``a`` to ``b`` stays clear of static obstacles."""
    length = float(np.hypot(*(b - a)))
    samples = max(2, int(length / (scene.grid.resolution / 2)) + 1)
    return not any(scene.disc_collides(a + (b - a) * s, radius) for s in np.linspace(0, 1, samples))
