"""Scenario families: generated worlds that each stress one ability of a local planner.

:func:`family_scenario` builds the scenario of a family from a seed (same
seed, same scenario); docs/SCENARIOS.md describes every family.

``'mixed'``
    Today's :func:`~fusion_planner.core.simulation.scenario.random_scenario`
    (rooms or blocks, unknown boxes near the plan, people), unchanged.
``'clutter'``
    A field of round posts (radius :data:`POST_RADIUS_M`) on a lattice whose
    gaps are 0.05-0.3 m wider than the robot, fully known, crossed at up to
    2 m/s.
``'corridors'``
    A grid of solid blocks separated by 1.2-2 m corridors, with people
    walking the robot's corridors head-on and in its direction.
``'narrow'``
    Two rooms joined by a passage 0.15-0.3 m wider than the robot and up to
    5 m long that the plan runs through; sometimes the only way, sometimes
    with a wide door elsewhere.
``'unreachable'``
    Two rooms joined by one or two openings on the known map, each closed by
    a box missing from the map: the goal is reachable on the known map and
    not in the world.
``'crossing'``, ``'crowd'``, ``'dense-crowd'``, ``'blind-corner'``, ``'fast-obstacle'``
    Moving obstacles are the difficulty
    (:mod:`~fusion_planner.core.simulation.dynamic_families`).

Every scenario passes the loader's checks
(:func:`~fusion_planner.core.simulation.scenario.check_scenario`), plans on
its known map with an inflation of the robot radius, and says whether it
can be solved (:attr:`Scenario.solvable`).

Examples
--------
>>> s = family_scenario('narrow', 4)
>>> s.name, s.family, s.solvable
('narrow-4', 'narrow', True)
>>> family_scenario('unreachable', 4).solvable
False
"""

import math

import numpy as np
from scipy import ndimage

from fusion_planner.core.errors import InvalidInput, PlanningError
from fusion_planner.core.grid import GridMap
from fusion_planner.core.simulation.dynamic_families import DYNAMIC_FAMILIES
from fusion_planner.core.global_planning.planner import GlobalPlanner, PlannerConfig
from fusion_planner.core.simulation.scenario import (
    DEFAULT_SAFETY_DISTANCE, Limits, Scenario, ScenarioError, check_scenario, random_scenario)
from fusion_planner.core.simulation.world import (
    MovingObstacle, Rectangle, RobotSpec, ScanConfig, WaypointMotion, rasterise_obstacles)

#: Family names, in the order reports list them; ``'mixed'`` is the default.
FAMILIES = ('mixed', 'clutter', 'corridors', 'narrow', 'unreachable') + tuple(DYNAMIC_FAMILIES)

#: Bound on the regeneration attempts of one scenario.
MAX_ATTEMPTS = 100
#: Robot of every family but clutter, as in ``'mixed'``.
ROBOT = RobotSpec(radius=0.2, max_speed=0.8, max_accel=1.0, max_omega=2.0)
#: Laser of the families (as in ``'mixed'``; clutter has a denser one).
SCAN = ScanConfig(beams=180, range_max=6.0)
#: Border wall thickness [m].
WALL_M = 0.1

#: Clutter: map resolution [m], post radius [m], robot limits, control period [s],
#: range of the top speed [m/s], extra width of a gap over the robot's
#: diameter [m], lattice rows and columns, open strip at each end [m], laser.
CLUTTER_RESOLUTION = 0.05
POST_RADIUS_M = 0.075
CLUTTER_MAX_ACCEL = 2.0
CLUTTER_MAX_OMEGA = 3.0
CLUTTER_DT = 0.05
CLUTTER_SPEED_RANGE = (1.0, 2.0)
CLUTTER_GAP_EXTRA = (0.05, 0.3)
CLUTTER_ROWS = (6, 10)
CLUTTER_COLUMNS = (8, 14)
CLUTTER_END_STRIP_M = 1.2
CLUTTER_SCAN = ScanConfig(beams=360, range_max=6.0)

#: Corridors: map resolution [m], corridor width [m], blocks along x and y,
#: block edge along x and y [m], people, their radius [m] and speed as a
#: fraction of the robot's top speed, shortest straight stretch of the plan a
#: person walks [m], smallest start-goal distance [m].
CORRIDOR_RESOLUTION = 0.1
CORRIDOR_WIDTH = (1.2, 2.0)
CORRIDOR_BLOCKS_X = (2, 4)
CORRIDOR_BLOCKS_Y = (1, 2)
CORRIDOR_BLOCK_X_M = (3.0, 6.0)
CORRIDOR_BLOCK_Y_M = (2.0, 4.0)
CORRIDOR_WALKERS = (1, 3)
WALKER_RADIUS = (0.2, 0.3)
WALKER_SPEED_FRACTION = (0.2, 0.45)
WALKER_MIN_STRETCH_M = 3.0
CORRIDOR_MIN_START_GOAL_M = 10.0

#: People keep this far [m] from the start and the goal when they spawn.
SPAWN_CLEARANCE_M = 2.0
#: A person keeps at least this gap [m] to the wall on its side, and leaves
#: this much room [m] on the other side (the robot's diameter plus 0.15 m).
WALKER_WALL_GAP_M = 0.05
PASSING_ROOM_M = 2 * ROBOT.radius + 0.15

#: Narrow: map resolution [m], passage width over the robot's diameter [m],
#: passage length [m], room depth on each side [m], map height [m], width of
#: the optional wide door [m], chance that the passage is the only way.
NARROW_RESOLUTION = 0.05
NARROW_EXTRA = (0.15, 0.3)
NARROW_LENGTH_M = (0.3, 5.0)
ROOM_DEPTH_M = (3.0, 5.0)
NARROW_HEIGHT_M = (7.0, 10.0)
WIDE_DOOR_M = (1.2, 1.6)
NARROW_ONLY_WAY_CHANCE = 0.5

#: Unreachable: map resolution [m], thickness of the dividing wall (a door or
#: a corridor) [m], openings, their width [m], blocking box depth [m] and how
#: far it reaches into the wall beside the opening [m].
UNREACHABLE_RESOLUTION = 0.1
DIVIDER_M = (0.3, 6.0)
OPENINGS = (1, 2)
OPENING_M = (0.8, 1.8)
BLOCKER_DEPTH_M = (0.3, 0.6)
BLOCKER_OVERLAP_M = 0.1

#: Time limits [s] per family (``'mixed'`` keeps its own).
TIME_LIMIT_S = {'clutter': 60.0, 'corridors': 150.0, 'narrow': 90.0, 'unreachable': 120.0}


def family_scenario(family, seed):
    """Generate the scenario of a family.

    Parameters
    ----------
    family : str
        One of :data:`FAMILIES`.
    seed : int
        Non-negative; same family and seed, same scenario.

    Returns
    -------
    Scenario
        ``name`` is ``'<family>-<seed>'`` (``'random-<seed>'`` for mixed),
        ``family`` and ``solvable`` are set, the map is in memory.

    Raises
    ------
    InvalidInput
        Unknown family, or no valid scenario within :data:`MAX_ATTEMPTS`.
    """
    if family not in FAMILIES:
        raise InvalidInput(f'unknown scenario family {family!r}; choose one of {", ".join(FAMILIES)}')
    if family == 'mixed':
        return random_scenario(seed)
    if family in DYNAMIC_FAMILIES:
        return DYNAMIC_FAMILIES[family](seed)
    build = {'clutter': _clutter, 'corridors': _corridors, 'narrow': _narrow,
             'unreachable': _unreachable}[family]
    rng = np.random.default_rng(np.random.SeedSequence(int(seed)))
    for _ in range(MAX_ATTEMPTS):
        scenario = build(rng, int(seed))
        if scenario is None:
            continue
        try:
            check_scenario(scenario)
        except ScenarioError:
            continue
        return scenario
    raise InvalidInput(f'no valid {family} scenario found for seed {seed} in {MAX_ATTEMPTS} attempts')


# -- shared pieces -----------------------------------------------------------------

def _cells(metres, resolution):
    return int(round(metres / resolution))


def _walled(rows, cols, resolution):
    """An empty occupancy array with a border wall :data:`WALL_M` thick."""
    occ = np.zeros((rows, cols), bool)
    w = max(1, _cells(WALL_M, resolution))
    occ[:w, :] = occ[-w:, :] = occ[:, :w] = occ[:, -w:] = True
    return occ


def _planner(robot):
    """The families' planner: the known map inflated by the robot radius only."""
    return PlannerConfig(robot_radius=robot.radius, safety_distance=DEFAULT_SAFETY_DISTANCE)


def _plan(grid, robot, start, goal):
    """The known-map plan, or None."""
    try:
        return GlobalPlanner(grid, _planner(robot)).plan(start[:2], goal)
    except PlanningError:
        return None


def _scenario(family, seed, grid, robot, start, goal, solvable, description, dt=0.1,
              scan=SCAN, unknown=(), moving=()):
    return Scenario(
        name=f'{family}-{seed}', grid=grid, robot=robot,
        start=(float(start[0]), float(start[1]), float(start[2])),
        goal=(float(goal[0]), float(goal[1])), unknown_obstacles=tuple(unknown),
        moving_obstacles=tuple(moving), planner=_planner(robot),
        limits=Limits(time_limit_s=TIME_LIMIT_S[family], dt=dt, max_collisions=10),
        scan=scan, seed=seed, description=description, family=family, solvable=solvable)


def _yaw(rng):
    return float(rng.uniform(-math.pi, math.pi))


# -- clutter -----------------------------------------------------------------------

def _clutter(rng, seed):
    """Round posts on a lattice between an open start strip and an open goal strip."""
    res = CLUTTER_RESOLUTION
    wall = _cells(WALL_M, res)
    post = _cells(2 * POST_RADIUS_M, res)  # drawn as post x post cells centred on a cell
    robot = RobotSpec(radius=ROBOT.radius,
                      max_speed=round(float(rng.uniform(*CLUTTER_SPEED_RANGE)), 1),
                      max_accel=CLUTTER_MAX_ACCEL, max_omega=CLUTTER_MAX_OMEGA)
    gap_lo = _cells(2 * robot.radius + CLUTTER_GAP_EXTRA[0], res)
    gap_hi = _cells(2 * robot.radius + CLUTTER_GAP_EXTRA[1], res)
    n_rows = int(rng.integers(CLUTTER_ROWS[0], CLUTTER_ROWS[1] + 1))
    n_cols = int(rng.integers(CLUTTER_COLUMNS[0], CLUTTER_COLUMNS[1] + 1))
    row_gaps = rng.integers(gap_lo, gap_hi + 1, size=n_rows + 1)  # walls included
    col_gaps = rng.integers(gap_lo, gap_hi + 1, size=n_cols - 1)
    strip = _cells(CLUTTER_END_STRIP_M, res)
    height = 2 * wall + int(row_gaps.sum()) + n_rows * post
    width = 2 * wall + 2 * strip + int(col_gaps.sum()) + n_cols * post
    occ = _walled(height, width, res)
    row_starts = wall + np.cumsum(row_gaps[:-1]) + post * np.arange(n_rows)
    col_starts = wall + strip + np.concatenate([[0], np.cumsum(col_gaps)]) + post * np.arange(n_cols)
    for r in row_starts:
        for c in col_starts:
            occ[r:r + post, c:c + post] = True
    grid = GridMap(occ, res)
    x_start = (wall + strip / 2) * res
    y_lo, y_hi = wall * res + 2 * robot.radius, (height - wall) * res - 2 * robot.radius
    start = (x_start, float(rng.uniform(y_lo, y_hi)), _yaw(rng))
    goal = (width * res - x_start, float(rng.uniform(y_lo, y_hi)))
    if _plan(grid, robot, start, goal) is None:
        return None
    gaps = np.concatenate([row_gaps, col_gaps]) * res
    return _scenario('clutter', seed, grid, robot, start, goal, True,
                     f'{n_rows} x {n_cols} posts, gaps {gaps.min():.2f}-{gaps.max():.2f} m, '
                     f'top speed {robot.max_speed:g} m/s', dt=CLUTTER_DT, scan=CLUTTER_SCAN)


def post_centres(grid):
    """Centres [m] of the posts of a clutter map: its interior blobs of occupied cells.

    Parameters
    ----------
    grid : GridMap
        A map made by the clutter family.

    Returns
    -------
    ndarray, float64, shape (P, 2)
    """
    wall = max(1, _cells(WALL_M, grid.resolution))
    inner = np.array(grid.occupied, copy=True)
    inner[:wall, :] = inner[-wall:, :] = inner[:, :wall] = inner[:, -wall:] = False
    labels, count = ndimage.label(inner)
    centres = ndimage.center_of_mass(inner, labels, range(1, count + 1))
    return grid.world_of(np.asarray(centres, float).reshape(-1, 2)) if count else np.zeros((0, 2))


# -- corridors ---------------------------------------------------------------------

def _corridors(rng, seed):
    """Solid blocks in a grid, 1.2-2 m corridors between them, people walking the plan's corridors."""
    res = CORRIDOR_RESOLUTION
    wall = _cells(WALL_M, res)
    robot = ROBOT
    nbx = int(rng.integers(CORRIDOR_BLOCKS_X[0], CORRIDOR_BLOCKS_X[1] + 1))
    nby = int(rng.integers(CORRIDOR_BLOCKS_Y[0], CORRIDOR_BLOCKS_Y[1] + 1))
    widths_lo, widths_hi = _cells(CORRIDOR_WIDTH[0], res), _cells(CORRIDOR_WIDTH[1], res)
    corr_x = rng.integers(widths_lo, widths_hi + 1, size=nbx + 1)  # vertical corridors
    corr_y = rng.integers(widths_lo, widths_hi + 1, size=nby + 1)  # horizontal corridors
    block_x = np.array([_cells(v, res) for v in rng.uniform(*CORRIDOR_BLOCK_X_M, size=nbx)])
    block_y = np.array([_cells(v, res) for v in rng.uniform(*CORRIDOR_BLOCK_Y_M, size=nby)])
    x_edges, y_edges = _edges(wall, corr_x, block_x), _edges(wall, corr_y, block_y)
    width = int(x_edges[-1] + corr_x[-1] + wall)
    height = int(y_edges[-1] + corr_y[-1] + wall)
    occ = _walled(height, width, res)
    for i in range(nbx):
        for j in range(nby):
            c0, r0 = x_edges[2 * i + 1], y_edges[2 * j + 1]
            occ[r0:r0 + block_y[j], c0:c0 + block_x[i]] = True
    grid = GridMap(occ, res)
    # corridor strips [m]: (axis, low edge, high edge); axis 0 runs along x
    strips = [(0, y_edges[2 * j] * res, (y_edges[2 * j] + corr_y[j]) * res) for j in range(nby + 1)]
    strips += [(1, x_edges[2 * i] * res, (x_edges[2 * i] + corr_x[i]) * res) for i in range(nbx + 1)]
    start, goal = _corridor_ends(rng, strips, width * res, height * res, robot)
    if start is None:
        return None
    plan = _plan(grid, robot, start, goal)
    if plan is None:
        return None
    walkers = _walkers(rng, strips, plan.grid_path, np.asarray(start[:2]), np.asarray(goal), robot)
    if not walkers:
        return None
    return _scenario('corridors', seed, grid, robot, start, goal, True,
                     f'{nbx} x {nby} blocks, corridors {min(corr_x.min(), corr_y.min()) * res:.1f}-'
                     f'{max(corr_x.max(), corr_y.max()) * res:.1f} m wide, {len(walkers)} people',
                     moving=walkers)


def _edges(wall, corridors, blocks):
    """First cells of corridor 0, block 0, corridor 1, block 1, ..., the last corridor.

    Parameters
    ----------
    wall : int
        Border wall [cells].
    corridors : ndarray of int, shape (n + 1,)
        Corridor widths [cells].
    blocks : ndarray of int, shape (n,)
        Block widths [cells].

    Returns
    -------
    ndarray of int, shape (2 n + 1,)
    """
    widths = np.ravel(np.column_stack([corridors[:-1], blocks]))
    return wall + np.concatenate([[0], np.cumsum(widths)])


def _corridor_point(rng, strip, extent, robot):
    """A point inside a corridor strip, away from its side walls and the map's ends."""
    axis, lo, hi = strip
    along = float(rng.uniform(WALL_M + 2 * robot.radius, extent[axis] - WALL_M - 2 * robot.radius))
    across = float(rng.uniform(lo + 2 * robot.radius, hi - 2 * robot.radius))
    return np.array([along, across] if axis == 0 else [across, along])


def _corridor_ends(rng, strips, width_m, height_m, robot):
    """A start pose and a goal far apart in the corridors, or (None, None)."""
    extent = (width_m, height_m)
    for _ in range(50):
        a = _corridor_point(rng, strips[int(rng.integers(len(strips)))], extent, robot)
        b = _corridor_point(rng, strips[int(rng.integers(len(strips)))], extent, robot)
        if math.hypot(*(a - b)) >= CORRIDOR_MIN_START_GOAL_M:
            return (a[0], a[1], _yaw(rng)), (b[0], b[1])
    return None, None


def _stretches(strips, path, start, goal):
    """Straight stretches of a dense path inside corridor strips.

    Returns
    -------
    list of tuple
        ``(strip, first point, last point)`` of each maximal run of path
        points inside one strip, away from the start and goal, at least
        :data:`WALKER_MIN_STRETCH_M` long along the corridor, in the
        direction of travel.
    """
    keep = (np.hypot(*(path - start).T) >= SPAWN_CLEARANCE_M) & \
        (np.hypot(*(path - goal).T) >= SPAWN_CLEARANCE_M)
    out = []
    for strip in strips:
        axis, lo, hi = strip
        inside = keep & (path[:, 1 - axis] > lo) & (path[:, 1 - axis] < hi)
        edges = np.flatnonzero(np.diff(np.concatenate([[0], inside.astype(int), [0]])))
        for first, end in zip(edges[::2], edges[1::2]):
            a, b = path[first], path[end - 1]
            if abs(b[axis] - a[axis]) >= WALKER_MIN_STRETCH_M:
                out.append((strip, a, b))
    return out


def _walkers(rng, strips, path, start, goal, robot):
    """People walking back and forth along the plan's corridors, one per stretch.

    The first walks the longest stretch head-on; each keeps to one side of
    its corridor and leaves :data:`PASSING_ROOM_M` free on the other.
    """
    stretches = _stretches(strips, path, start, goal)
    if not stretches:
        return []
    lengths = [abs(b - a)[strip[0]] for strip, a, b in stretches]
    longest = int(np.argmax(lengths))
    others = [i for i in rng.permutation(len(stretches)) if i != longest]
    count = int(rng.integers(CORRIDOR_WALKERS[0], CORRIDOR_WALKERS[1] + 1))
    walkers = []
    for k, index in enumerate(([longest] + others)[:count]):
        (axis, lo, hi), a, b = stretches[index]
        radius = float(rng.uniform(*WALKER_RADIUS))
        speed = float(rng.uniform(*WALKER_SPEED_FRACTION)) * robot.max_speed
        slack = (hi - lo) - 2 * radius - PASSING_ROOM_M
        if slack < WALKER_WALL_GAP_M:
            continue
        near_wall = float(rng.uniform(WALKER_WALL_GAP_M, slack)) + radius
        across = lo + near_wall if rng.random() < 0.5 else hi - near_wall
        near, far = float(a[axis]), float(b[axis])
        head_on = k == 0 or rng.random() < 0.5
        ends = (far, near) if head_on else (near, far)
        points = tuple((e, across) if axis == 0 else (across, e) for e in ends)
        walkers.append(MovingObstacle(radius, WaypointMotion(points, speed)))
    return walkers


# -- narrow ------------------------------------------------------------------------

def _narrow(rng, seed):
    """Two rooms, a thick wall between them, a narrow passage through it the plan takes."""
    res = NARROW_RESOLUTION
    robot = ROBOT
    length = _cells(float(rng.uniform(*NARROW_LENGTH_M)), res)
    rooms = [_cells(float(rng.uniform(*ROOM_DEPTH_M)), res) for _ in range(2)]
    height = _cells(float(rng.uniform(*NARROW_HEIGHT_M)), res)
    width = rooms[0] + length + rooms[1]
    occ = _walled(height, width, res)
    c0 = rooms[0]
    occ[:, c0:c0 + length] = True
    passage = _cells(2 * robot.radius + float(rng.uniform(*NARROW_EXTRA)), res)
    margin = _cells(1.0, res)
    p0 = int(rng.integers(margin, height - margin - passage))
    occ[p0:p0 + passage, c0:c0 + length] = False
    only_way = rng.random() < NARROW_ONLY_WAY_CHANCE
    if not only_way:
        door = _cells(float(rng.uniform(*WIDE_DOOR_M)), res)
        spots = [d for d in range(margin, height - margin - door)
                 if d + door + margin < p0 or d > p0 + passage + margin]
        if not spots:
            return None
        d0 = spots[int(rng.integers(len(spots)))]
        occ[d0:d0 + door, c0:c0 + length] = False
    grid = GridMap(occ, res)
    passage_y = (p0 + passage / 2) * res
    spread = 2.0
    y_lo, y_hi = WALL_M + 2 * robot.radius, height * res - WALL_M - 2 * robot.radius
    start = (float(rng.uniform(WALL_M + 2 * robot.radius, c0 * res - 2 * robot.radius)),
             float(np.clip(passage_y + rng.uniform(-spread, spread), y_lo, y_hi)), _yaw(rng))
    goal = (float(rng.uniform((c0 + length) * res + 2 * robot.radius,
                              width * res - WALL_M - 2 * robot.radius)),
            float(np.clip(passage_y + rng.uniform(-spread, spread), y_lo, y_hi)))
    plan = _plan(grid, robot, start, goal)
    if plan is None:
        return None
    path = plan.grid_path
    in_wall = (path[:, 0] > c0 * res) & (path[:, 0] < (c0 + length) * res)
    if not np.all(np.abs(path[in_wall, 1] - passage_y) < passage * res / 2):
        return None  # the plan takes the wide door
    return _scenario('narrow', seed, grid, robot, start, goal, True,
                     f'passage {passage * res:.2f} m wide and {length * res:.2f} m long, '
                     + ('the only way' if only_way else 'a wide door elsewhere'))


# -- unreachable -------------------------------------------------------------------

def _unreachable(rng, seed):
    """Two rooms joined by one or two openings, every opening closed by an unknown box."""
    res = UNREACHABLE_RESOLUTION
    robot = ROBOT
    thickness = _cells(float(rng.uniform(*DIVIDER_M)), res)
    rooms = [_cells(float(rng.uniform(*ROOM_DEPTH_M)), res) for _ in range(2)]
    height = _cells(float(rng.uniform(*NARROW_HEIGHT_M)), res)
    width = rooms[0] + thickness + rooms[1]
    occ = _walled(height, width, res)
    c0 = rooms[0]
    occ[:, c0:c0 + thickness] = True
    margin = _cells(1.0, res)
    blockers, openings = [], []
    for _ in range(int(rng.integers(OPENINGS[0], OPENINGS[1] + 1))):
        size = _cells(float(rng.uniform(*OPENING_M)), res)
        spots = [o for o in range(margin, height - margin - size)
                 if not any(o < b + margin and a < o + size + margin for a, b in openings)]
        if not spots:
            break
        o0 = spots[int(rng.integers(len(spots)))]
        openings.append((o0, o0 + size))
        occ[o0:o0 + size, c0:c0 + thickness] = False
        depth = min(float(rng.uniform(*BLOCKER_DEPTH_M)), thickness * res)
        # An offset into the wall, not two absolute bounds: when the box fills the
        # wall's thickness, rounding would put the upper bound below the lower.
        x0 = c0 * res + float(rng.uniform(0.0, thickness * res - depth))
        blockers.append(Rectangle((x0, o0 * res - BLOCKER_OVERLAP_M),
                                  (x0 + depth, (o0 + size) * res + BLOCKER_OVERLAP_M)))
    grid = GridMap(occ, res)
    y_lo, y_hi = WALL_M + 2 * robot.radius, height * res - WALL_M - 2 * robot.radius
    start = (float(rng.uniform(WALL_M + 2 * robot.radius, c0 * res - 2 * robot.radius)),
             float(rng.uniform(y_lo, y_hi)), _yaw(rng))
    goal = (float(rng.uniform((c0 + thickness) * res + 2 * robot.radius,
                              width * res - WALL_M - 2 * robot.radius)),
            float(rng.uniform(y_lo, y_hi)))
    if _plan(grid, robot, start, goal) is None or not blocked_in_world(grid, blockers, start, goal):
        return None
    return _scenario('unreachable', seed, grid, robot, start, goal, False,
                     f'{len(openings)} opening(s) in a {thickness * res:.1f} m wall, '
                     'each closed by a box missing from the map', unknown=blockers)


def blocked_in_world(grid, rectangles, start, goal):
    """Whether unknown boxes separate ``start`` from ``goal`` even for a point robot.

    Each box is shrunk by one cell before it is burnt into the map, so every
    cell it marks lies inside the real box; the free cells are then joined
    8-connected (corner contacts count as openings). A separation there is a
    separation in the world.

    Parameters
    ----------
    grid : GridMap
        The known map.
    rectangles : sequence of Rectangle
    start, goal : array_like
        ``(x, y, ...)`` [m].

    Returns
    -------
    bool
    """
    res = grid.resolution
    inner = [Rectangle((r.min[0] + res, r.min[1] + res), (r.max[0] - res, r.max[1] - res))
             for r in rectangles if r.max[0] - r.min[0] > 2 * res and r.max[1] - r.min[1] > 2 * res]
    truth = rasterise_obstacles(grid, (), inner)
    labels, _ = ndimage.label(~truth.occupied, structure=np.ones((3, 3), int))
    a = labels[tuple(grid.cell_of(np.asarray(start[:2], float)))]
    b = labels[tuple(grid.cell_of(np.asarray(goal[:2], float)))]
    return a == 0 or b == 0 or a != b

