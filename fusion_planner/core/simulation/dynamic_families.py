"""Generated scenarios whose difficulty is moving obstacles.

Each family is a function ``seed -> Scenario`` in :data:`DYNAMIC_FAMILIES`
(registered in :data:`~fusion_planner.core.simulation.families.FAMILIES`,
so ``sim --random N --family NAME`` runs them); the same seed gives the
same scenario. All share the robot of the generated
scenarios (radius 0.2 m, top speed 0.8 m/s), a 360-beam laser with 1 cm
range noise, a 0.1 s control period and a 90 s time limit:

``crossing``
    A 14 x 8 m hall; one to three people cross the robot's straight way
    (back and forth between the side walls, 0.4-1.0 m/s), timed to meet the
    robot near their crossing line.
``crowd``
    A 14 x 10 m hall with five to ten people wandering (random walks,
    0.3-0.7 m/s) across the robot's way.
``dense-crowd``
    The hall, start and goal of ``crowd`` with 14 to 18 people: a stress
    test, not one of the families a robot is held to; about ten times as
    many of the robot's contacts as in ``crowd``, so that a change to the
    evasion can be compared on hundreds of runs rather than thousands.
``blind-corner``
    A 2 m wide corridor with a side corridor; a person (0.6-1.0 m/s) steps
    out of the side corridor across the main one when the robot is near its
    mouth. The side corridor's walls hide the person until it steps out.
``fast-obstacle``
    A 14 x 8 m hall; one obstacle as fast as the robot (0.8 m/s) comes
    head-on along the robot's way or crosses it, plus up to one slower
    person.

Frames and units: map frame, metres, seconds, radians.

Examples
--------
>>> s = DYNAMIC_FAMILIES['blind-corner'](3)
>>> s.name, len(s.moving_obstacles)
('blind-corner-3', 1)
"""

import functools

import numpy as np

from fusion_planner.core.errors import InvalidInput
from fusion_planner.core.global_planning.planner import PlannerConfig
from fusion_planner.core.grid import GridMap
from fusion_planner.core.simulation.scenario import (
    DEFAULT_SAFETY_DISTANCE, Limits, Scenario, ScenarioError, check_scenario)
from fusion_planner.core.simulation.world import (
    MovingObstacle, RandomWalkMotion, RobotSpec, ScanConfig, WaypointMotion)

#: The robot, laser and limits of every family.
ROBOT = RobotSpec(radius=0.2, max_speed=0.8, max_accel=1.0, max_omega=2.0)
SCAN = ScanConfig(beams=360, range_max=8.0, noise_std=0.01)
LIMITS = Limits(time_limit_s=90.0, dt=0.1, max_collisions=10)
#: Map cell edge [m].
RESOLUTION = 0.1
#: Speed [m/s] the timing of an encounter assumes for the robot (its
#: average on a straight way).
ROBOT_CRUISE = 0.6
#: Radii [m] of people.
PERSON_RADIUS = (0.2, 0.3)
#: People of a ``dense-crowd`` scenario: from, and up to but not including.
DENSE_CROWD_PEOPLE = (14, 19)
#: Attempts before a family gives up on a seed.
MAX_ATTEMPTS = 50


def hall(width_m, height_m):
    """A walled empty rectangle ``(GridMap)``, origin at its lower-left corner."""
    rows, cols = int(round(height_m / RESOLUTION)), int(round(width_m / RESOLUTION))
    occupied = np.zeros((rows, cols), bool)
    occupied[0, :] = occupied[-1, :] = occupied[:, 0] = occupied[:, -1] = True
    return GridMap(occupied, RESOLUTION)


def scenario_of(family, seed, grid, start, goal, moving):
    """A checked Scenario of a family, or None when its geometry is invalid."""
    scenario = Scenario(
        name=f'{family}-{seed}', grid=grid, robot=ROBOT, start=tuple(map(float, start)),
        goal=tuple(map(float, goal)), moving_obstacles=tuple(moving),
        planner=PlannerConfig(robot_radius=ROBOT.radius, safety_distance=DEFAULT_SAFETY_DISTANCE),
        limits=LIMITS, scan=SCAN, seed=int(seed), description=f'generated family {family}',
        family=family, solvable=True)
    try:
        check_scenario(scenario)
    except ScenarioError:
        return None
    return scenario


def pacer(rng, line_start, line_end, meet, speed, lead_s):
    """A person walking back and forth on a line, at ``meet`` about ``lead_s`` seconds in.

    Returns
    -------
    WaypointMotion
        Starts where walking ``lead_s`` (jittered by +-1.5 s) toward
        ``line_end`` reaches ``meet``, clipped to the line.
    """
    a, b = np.asarray(line_start, float), np.asarray(line_end, float)
    direction = (b - a) / np.hypot(*(b - a))
    lead = max(lead_s + float(rng.uniform(-1.5, 1.5)), 0.0)
    back = min(speed * lead, float(np.hypot(*(np.asarray(meet) - a))))
    begin = np.asarray(meet, float) - direction * back
    return WaypointMotion((tuple(begin), tuple(b), tuple(a)), speed)


def _draw_crossing(rng):
    """One draw of people crossing the robot's way: ``(grid, start, goal, moving)``."""
    grid = hall(14.0, 8.0)
    y0, y1 = rng.uniform(2.5, 5.5, size=2)
    start, goal = (1.2, y0, float(rng.uniform(-0.5, 0.5))), (12.8, y1)
    moving = []
    for x in np.sort(rng.uniform(3.5, 10.5, size=int(rng.integers(1, 4)))):
        speed = float(rng.uniform(0.4, 1.0))
        up = rng.random() < 0.5
        ends = [(x + rng.uniform(-1.5, 1.5), 0.6), (x + rng.uniform(-1.5, 1.5), 7.4)]
        if not up:
            ends.reverse()
        cross_y = y0 + (y1 - y0) * (x - 1.2) / 11.6
        meet = np.array(ends[0]) + (np.array(ends[1]) - ends[0]) * \
            (cross_y - ends[0][1]) / (ends[1][1] - ends[0][1])
        moving.append(MovingObstacle(float(rng.uniform(*PERSON_RADIUS)), pacer(
            rng, ends[0], ends[1], meet, speed, (x - 1.2) / ROBOT_CRUISE)))
    return grid, start, goal, moving


def _draw_crowd(rng):
    """One draw of five to ten wandering people: ``(grid, start, goal, moving)``."""
    grid, start, goal = _crowd_hall(rng)
    moving = []
    # the count is drawn anew on every pass: kept, so each seed keeps its scenario
    while len(moving) < int(rng.integers(5, 11)):
        _add_wanderer(rng, start, goal, moving)
    return grid, start, goal, moving


def _draw_dense_crowd(rng):
    """One draw of 14 to 18 wandering people: ``(grid, start, goal, moving)``.

    The hall, start and goal of the ``crowd`` scenario of the same seed.
    """
    grid, start, goal = _crowd_hall(rng)
    moving = []
    count = int(rng.integers(*DENSE_CROWD_PEOPLE))
    while len(moving) < count:
        _add_wanderer(rng, start, goal, moving)
    return grid, start, goal, moving


def _crowd_hall(rng):
    """The 14 x 10 m hall of the crowds and a start and goal across it: ``(grid, start, goal)``."""
    grid = hall(14.0, 10.0)
    return grid, (1.2, float(rng.uniform(2.0, 8.0)), 0.0), (12.8, float(rng.uniform(2.0, 8.0)))


def _add_wanderer(rng, start, goal, moving):
    """Draw a person on a random walk into ``moving``, unless drawn too close to another.

    None within 2 m of ``start`` or ``goal`` [m], none within 0.3 m of another.
    """
    p = rng.uniform([3.0, 1.0], [11.0, 9.0])
    radius = float(rng.uniform(*PERSON_RADIUS))
    if min(np.hypot(*(p - start[:2])), np.hypot(*(p - goal))) < 2.0 or any(
            np.hypot(*(p - m.motion.position)) < radius + m.radius + 0.3 for m in moving):
        return
    moving.append(MovingObstacle(radius, RandomWalkMotion(
        (float(p[0]), float(p[1])), float(rng.uniform(0.3, 0.7)), float(rng.uniform(0.3, 0.8)))))


def _draw_blind_corner(rng):
    """One draw of a person out of a side corridor: ``(grid, start, goal, moving)``."""
    rows, cols = 90, 140
    occupied = np.ones((rows, cols), bool)
    main_lo, main_hi = 35, 55                             # main corridor y = 3.5 .. 5.5 m
    occupied[main_lo:main_hi, 1:-1] = False
    side_x = float(rng.uniform(5.0, 10.0))
    side_w = float(rng.uniform(1.2, 2.0))
    c0, c1 = int(side_x / RESOLUTION), int((side_x + side_w) / RESOLUTION)
    north = rng.random() < 0.5
    if north:
        occupied[main_hi:rows - 1, c0:c1] = False
    else:
        occupied[1:main_lo, c0:c1] = False
    grid = GridMap(occupied, RESOLUTION)
    start = (1.0, float(rng.uniform(4.0, 5.0)), float(rng.uniform(-0.3, 0.3)))
    goal = (13.0, float(rng.uniform(4.0, 5.0)))
    x = side_x + side_w / 2
    deep, far = (8.5, 3.8) if north else (0.5, 5.2)
    speed = float(rng.uniform(0.6, 1.0))
    meet = (x, 4.5)
    person = MovingObstacle(float(rng.uniform(*PERSON_RADIUS)), pacer(
        rng, (x, deep), (x, far), meet, speed, (x - start[0]) / ROBOT_CRUISE))
    return grid, start, goal, [person]


def _draw_fast_obstacle(rng):
    """One draw of an obstacle as fast as the robot: ``(grid, start, goal, moving)``."""
    grid = hall(14.0, 8.0)
    y = float(rng.uniform(2.5, 5.5))
    start, goal = (1.2, y, 0.0), (12.8, y + float(rng.uniform(-1.0, 1.0)))
    radius = float(rng.uniform(0.25, 0.35))
    if rng.random() < 0.5:
        offset = float(rng.uniform(-0.4, 0.4))
        motion = pacer(rng, (13.0, y + offset), (1.0, y + offset), (7.0, y + offset),
                       ROBOT.max_speed, 5.8 / (ROBOT_CRUISE + ROBOT.max_speed))
    else:
        x = float(rng.uniform(4.0, 10.0))
        motion = pacer(rng, (x, 0.6), (x, 7.4), (x, y), ROBOT.max_speed,
                       (x - 1.2) / ROBOT_CRUISE)
    moving = [MovingObstacle(radius, motion)]
    if rng.random() < 0.5:
        x = float(rng.uniform(4.0, 10.0))
        moving.append(MovingObstacle(float(rng.uniform(*PERSON_RADIUS)), pacer(
            rng, (x, 7.4), (x, 0.6), (x, y), float(rng.uniform(0.3, 0.6)),
            (x - 1.2) / ROBOT_CRUISE)))
    return grid, start, goal, moving


def generate(family, seed):
    """The scenario of a dynamic family for a seed.

    Parameters
    ----------
    family : str
        A key of :data:`DYNAMIC_FAMILIES`.
    seed : int

    Returns
    -------
    Scenario

    Raises
    ------
    InvalidInput
        No valid scenario within :data:`MAX_ATTEMPTS` draws.
    """
    salt, draw = _DRAWS[family]
    rng = np.random.default_rng(np.random.SeedSequence([int(seed), salt]))
    for _ in range(MAX_ATTEMPTS):
        scenario = scenario_of(family, seed, *draw(rng))
        if scenario is not None:
            return scenario
    raise InvalidInput(f'no {family} scenario for seed {seed}')


#: Family name -> (seed salt, draw of one attempt).
_DRAWS = {
    'crossing': (1, _draw_crossing),
    'crowd': (2, _draw_crowd),
    'dense-crowd': (2, _draw_dense_crowd),   # the salt of crowd: the same start and goal
    'blind-corner': (3, _draw_blind_corner),
    'fast-obstacle': (4, _draw_fast_obstacle),
}

#: Family name -> generator ``seed -> Scenario``.
DYNAMIC_FAMILIES = {name: functools.partial(generate, name) for name in _DRAWS}

#: Stress tests: families a benchmark runs only when asked for by name.
STRESS_FAMILIES = ('dense-crowd',)

