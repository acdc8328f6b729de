"""Simulated world for closed-loop runs: robot, hidden obstacles, people, laser.

The world is the ground truth a local planner is tested against. It holds

- the **known map** (a :class:`~fusion_planner.core.grid.GridMap`, the one
  the global planner sees) whose occupied cells are solid squares;
- **unknown static obstacles**: circles and axis-aligned rectangles in
  metres, in the world but not in the planner's map;
- **moving obstacles**: circles driven by a motion model (constant velocity
  with bounce, a waypoint loop, or a seeded random walk);
- a **round robot** with unicycle kinematics.

Conventions
-----------
- Map frame, SI units (REP-103): positions [m], yaw [rad], speeds [m/s] and
  [rad/s]; arrays ``(N, 2)`` float64.
- The map's outer edge is a wall: the robot and the moving obstacles collide
  with it and laser beams stop on it, so nothing ever leaves the map.
- Laser ranges follow REP-117: ``+inf`` when nothing is hit within
  ``range_max``, ``-inf`` when the hit is closer than ``range_min``; only
  finite ranges give hit points.
- Contacts: the robot cannot enter a static obstacle (known cell, unknown
  circle or rectangle, map edge); a step that would do so is refused (the
  robot keeps its position, may still turn, and its speed drops to zero). A
  moving obstacle ignores the robot and may overlap it. A *contact event* is
  a step in contact (refused step or overlap) that follows a step without
  contact, so pressing against a wall for many steps counts once. A contact
  event with a moving obstacle is *passive* when it begins while the robot
  stands (moved slower than :data:`AT_REST_MPS` in that step) or retreats
  from the obstacle it touches (moved within 60 degrees of straight away
  from it, :data:`RETREAT_COSINE`), and no simple escape begun up to 2 s
  earlier, with the person in sight, would have kept the robot clear of
  everything (:func:`~fusion_planner.core.simulation.contact_blame.could_escape`):
  the people here ignore the robot, and a robot that stands or backs away
  when it could have stepped aside answers for the contact as much as one
  in motion (passive safety: a robot in motion answers for its contacts).
  Every other contact event is *avoidable*: a robot driving across a
  person's way is in motion, not retreating. Each event is kept with how it
  was judged (:attr:`World.contacts`).
- Moving obstacles bounce off the static world (axis-separated reflection of
  their velocity). A bouncing or random-walking one also bounces off the
  other moving obstacles (its velocity reflected about the line of
  centres when its next step would overlap one it approaches): people do
  not walk through each other, and two overlapping discs would be one
  object to a laser. A waypoint walker keeps to its schedule and may
  still overlap another.
- Determinism: all randomness (random walks, scan noise) comes from
  :class:`numpy.random.Generator` streams derived from one seed, so the same
  seed and the same commands give the same run. Motion and noise use
  separate streams: switching noise on does not change how people walk.

Examples
--------
>>> import numpy as np
>>> from fusion_planner.core.grid import GridMap
>>> grid = GridMap(np.zeros((40, 40), bool), resolution=0.1)
>>> world = World(grid, RobotSpec(radius=0.2), start_pose=(1.0, 2.0, 0.0),
...               unknown_obstacles=[Circle((3.0, 2.0), 0.5)],
...               scan_config=ScanConfig(beams=4, fov=2 * np.pi))
>>> scan = world.scan()
>>> scan.angles.round(4).tolist()      # beams start at -fov/2, behind the robot
[-3.1416, -1.5708, 0.0, 1.5708]
>>> scan.ranges.round(6).tolist()      # map edge behind, circle ahead at x = 2.5
[1.0, 2.0, 1.5, 2.0]
>>> world.step(0.5, 0.0, dt=1.0)
False
>>> world.pose.round(6).tolist()
[1.5, 2.0, 0.0]
"""

import logging
import math
from collections import deque
from dataclasses import dataclass, field

import numpy as np

from fusion_planner.core.errors import InvalidInput
from fusion_planner.core.grid import GridMap
from fusion_planner.core.simulation import ray_kernel
from fusion_planner.core.simulation.contact_blame import (ESCAPE_HORIZON_S, ContactEvent, Snapshot,
                                                           could_escape)

LOGGER = logging.getLogger(__name__)

#: A robot that moved slower than this [m/s] in the step a contact began
#: stood still (see the module notes).
AT_REST_MPS = 0.05

#: A robot whose velocity points within 60 degrees of straight away from an
#: obstacle (closing speed at most this times its speed) retreats from it.
RETREAT_COSINE = -0.5

#: Turn rates below this are integrated as a straight line [rad/s].
STRAIGHT_OMEGA_EPS = 1e-9
#: Cap on the search radius of the exact clearance to map cells [m]; beyond
#: it the clearance comes from the map's distance transform (exact to one
#: cell).
CLEARANCE_WINDOW_M = 3.0
#: Two full turns [rad]; a field of view at least 2*pi (minus this slack) is
#: a full circle and its last beam does not repeat the first.
FULL_CIRCLE_SLACK = 1e-9
#: Length of ray [cells] the grid ray cast examines per vectorised pass.
RAY_CHUNK_CELLS = 16.0
#: Stand-in for a zero direction component in the slab test (avoids 0/0).
_TINY = 1e-300

MOTION_MODELS = ('bounce', 'waypoints', 'random_walk')


# -- descriptions (immutable, what a scenario file holds) ---------------------

def _check_number(owner, name, value, low=0.0, strict=True):
    """Raise InvalidInput unless ``value`` is a finite real number above ``low``."""
    ok = (isinstance(value, (int, float, np.integer, np.floating)) and not isinstance(value, bool)
          and math.isfinite(value) and (value > low if strict else value >= low))
    if not ok:
        relation = '>' if strict else '>='
        raise InvalidInput(f'{owner}.{name} must be a finite number {relation} {low:g}, got {value!r}')


def _check_point(owner, name, value):
    """Raise InvalidInput unless ``value`` is two finite numbers."""
    try:
        point = np.asarray(value, dtype=float)
    except (TypeError, ValueError):
        point = None
    if point is None or point.shape != (2,) or not np.all(np.isfinite(point)):
        raise InvalidInput(f'{owner}.{name} must be two finite numbers (x, y), got {value!r}')


@dataclass(frozen=True)
class Circle:
    """A circular obstacle.

    Attributes
    ----------
    center : tuple of float
        ``(x, y)`` [m], map frame.
    radius : float
        Radius [m], > 0.
    """

    center: tuple
    radius: float

    def __post_init__(self):
        _check_point('Circle', 'center', self.center)
        _check_number('Circle', 'radius', self.radius)


@dataclass(frozen=True)
class Rectangle:
    """An axis-aligned rectangular obstacle.

    Attributes
    ----------
    min, max : tuple of float
        Lower-left and upper-right corners ``(x, y)`` [m], map frame.
    """

    min: tuple
    max: tuple

    def __post_init__(self):
        _check_point('Rectangle', 'min', self.min)
        _check_point('Rectangle', 'max', self.max)
        if not (self.min[0] < self.max[0] and self.min[1] < self.max[1]):
            raise InvalidInput(f'Rectangle needs min < max in x and y, got {self.min} and {self.max}')


@dataclass(frozen=True)
class BounceMotion:
    """Constant velocity, reflected off the map edge and static obstacles.

    Attributes
    ----------
    position : tuple of float
        Start ``(x, y)`` [m].
    velocity : tuple of float
        ``(vx, vy)`` [m/s].
    """

    position: tuple
    velocity: tuple

    def __post_init__(self):
        _check_point('BounceMotion', 'position', self.position)
        _check_point('BounceMotion', 'velocity', self.velocity)


@dataclass(frozen=True)
class WaypointMotion:
    """Endless loop along a closed polyline at constant speed.

    The obstacle starts at the first point and walks ``points[0] ->
    points[1] -> ... -> points[-1] -> points[0]``; two points give a
    back-and-forth walk. Its path is not checked against walls.

    Attributes
    ----------
    points : tuple of tuple of float
        At least two ``(x, y)`` [m].
    speed : float
        [m/s], >= 0.
    """

    points: tuple
    speed: float

    def __post_init__(self):
        if len(self.points) < 2:
            raise InvalidInput(f'WaypointMotion needs at least two points, got {len(self.points)}')
        for point in self.points:
            _check_point('WaypointMotion', 'points', point)
        _check_number('WaypointMotion', 'speed', self.speed, strict=False)


@dataclass(frozen=True)
class RandomWalkMotion:
    """Constant speed with a heading that diffuses; bounces like :class:`BounceMotion`.

    The heading starts uniformly random and changes each step by
    ``turn_std * sqrt(dt) * N(0, 1)`` [rad] (a Wiener process, so the walk
    does not depend on the time step).

    Attributes
    ----------
    position : tuple of float
        Start ``(x, y)`` [m].
    speed : float
        [m/s], >= 0.
    turn_std : float
        Heading diffusion [rad / sqrt(s)], >= 0.
    """

    position: tuple
    speed: float
    turn_std: float

    def __post_init__(self):
        _check_point('RandomWalkMotion', 'position', self.position)
        _check_number('RandomWalkMotion', 'speed', self.speed, strict=False)
        _check_number('RandomWalkMotion', 'turn_std', self.turn_std, strict=False)


@dataclass(frozen=True)
class MovingObstacle:
    """A moving circular obstacle (a person, a cart).

    Attributes
    ----------
    radius : float
        [m], > 0.
    motion : BounceMotion or WaypointMotion or RandomWalkMotion
    """

    radius: float
    motion: object

    def __post_init__(self):
        _check_number('MovingObstacle', 'radius', self.radius)
        if not isinstance(self.motion, (BounceMotion, WaypointMotion, RandomWalkMotion)):
            raise InvalidInput(f'unknown motion model {type(self.motion).__name__}')

    @property
    def model(self):
        """Name of the motion model: one of :data:`MOTION_MODELS`."""
        return {BounceMotion: 'bounce', WaypointMotion: 'waypoints',
                RandomWalkMotion: 'random_walk'}[type(self.motion)]

    def start_position(self):
        """Position ``(2,)`` [m] at time 0."""
        if isinstance(self.motion, WaypointMotion):
            return np.asarray(self.motion.points[0], dtype=float)
        return np.asarray(self.motion.position, dtype=float)

    def top_speed(self):
        """Largest speed [m/s] the model can reach."""
        if isinstance(self.motion, BounceMotion):
            return float(np.hypot(*self.motion.velocity))
        return float(self.motion.speed)


@dataclass(frozen=True)
class RobotSpec:
    """The round robot's body and actuator limits.

    Attributes
    ----------
    radius : float
        [m], > 0.
    max_speed : float
        Largest forward or backward speed [m/s].
    max_accel : float
        Largest change of linear speed [m/s^2].
    max_omega : float
        Largest turn rate [rad/s].
    """

    radius: float
    max_speed: float = 1.0
    max_accel: float = 1.0
    max_omega: float = 2.0

    def __post_init__(self):
        for name in ('radius', 'max_speed', 'max_accel', 'max_omega'):
            _check_number('RobotSpec', name, getattr(self, name))


@dataclass(frozen=True)
class ScanConfig:
    """A planar laser at the robot centre, facing the robot's heading.

    Attributes
    ----------
    beams : int
        Number of beams, >= 1.
    fov : float
        Field of view [rad], in (0, 2*pi]; beams span ``[-fov/2, fov/2]``
        about the heading. A full circle spaces beams ``2*pi / beams`` apart
        (no duplicate beam); otherwise the first and last beams lie on the
        edges of the field of view.
    range_min, range_max : float
        Valid range interval [m], ``0 <= range_min < range_max``.
    noise_std : float
        Standard deviation of additive Gaussian range noise [m], >= 0.
    """

    beams: int = 360
    fov: float = 2 * math.pi
    range_min: float = 0.05
    range_max: float = 8.0
    noise_std: float = 0.0

    def __post_init__(self):
        if isinstance(self.beams, bool) or not isinstance(self.beams, (int, np.integer)) \
                or self.beams < 1:
            raise InvalidInput(f'ScanConfig.beams must be a positive integer, got {self.beams!r}')
        _check_number('ScanConfig', 'fov', self.fov)
        if self.fov > 2 * math.pi + FULL_CIRCLE_SLACK:
            raise InvalidInput(f'ScanConfig.fov must be at most 2*pi, got {self.fov!r}')
        _check_number('ScanConfig', 'range_min', self.range_min, strict=False)
        _check_number('ScanConfig', 'range_max', self.range_max, low=self.range_min)
        _check_number('ScanConfig', 'noise_std', self.noise_std, strict=False)

    def angles(self):
        """Beam angles ``(beams,)`` [rad], robot frame, counter-clockwise."""
        full = self.fov >= 2 * math.pi - FULL_CIRCLE_SLACK
        if self.beams == 1:
            return np.zeros(1)
        increment = self.fov / self.beams if full else self.fov / (self.beams - 1)
        return -self.fov / 2 + increment * np.arange(self.beams)


@dataclass(frozen=True)
class LaserScan:
    """One scan.

    Attributes
    ----------
    angles : ndarray, float64, shape (n,)
        Beam angles [rad] in the robot frame.
    ranges : ndarray, float64, shape (n,)
        Measured ranges [m]; ``+inf`` no hit within ``range_max``, ``-inf``
        closer than ``range_min`` (REP-117).
    points : ndarray, float64, shape (M, 2)
        Hit points of the finite ranges [m], map frame.
    origin : ndarray, float64, shape (3,)
        Pose ``(x, y, yaw)`` of the laser when the scan was taken.
    """

    angles: np.ndarray
    ranges: np.ndarray
    points: np.ndarray
    origin: np.ndarray


# -- geometry helpers (vectorised) ---------------------------------------------

def integrate_unicycle(pose, v, omega, dt):
    """Exact unicycle motion over ``dt`` at constant ``(v, omega)``.

    Parameters
    ----------
    pose : array_like, shape (3,)
        ``(x, y, yaw)`` [m, m, rad].
    v : float
        Linear speed [m/s].
    omega : float
        Turn rate [rad/s].
    dt : float
        Duration [s], >= 0.

    Returns
    -------
    ndarray, float64, shape (3,)
        The new pose; yaw wrapped to ``(-pi, pi]``.

    Notes
    -----
    On an arc (``omega != 0``) the robot moves on a circle of radius
    ``v / omega``: ``x' = x + v/omega (sin(yaw + omega dt) - sin yaw)``,
    ``y' = y - v/omega (cos(yaw + omega dt) - cos yaw)``; a straight line
    otherwise.

    Examples
    --------
    >>> integrate_unicycle((0.0, 0.0, 0.0), 1.0, math.pi / 2, 1.0).round(6).tolist()
    [0.63662, 0.63662, 1.570796]
    """
    x, y, yaw = (float(c) for c in pose)
    if abs(omega) < STRAIGHT_OMEGA_EPS:
        x += v * dt * math.cos(yaw)
        y += v * dt * math.sin(yaw)
        new_yaw = yaw
    else:
        new_yaw = yaw + omega * dt
        x += v / omega * (math.sin(new_yaw) - math.sin(yaw))
        y -= v / omega * (math.cos(new_yaw) - math.cos(yaw))
    return np.array([x, y, wrap_angle(new_yaw)])


def wrap_angle(angle):
    """Angle(s) wrapped to ``(-pi, pi]`` [rad]."""
    wrapped = np.mod(np.asarray(angle, dtype=float) + math.pi, 2 * math.pi) - math.pi
    wrapped = np.where(wrapped == -math.pi, math.pi, wrapped)
    return float(wrapped) if np.ndim(wrapped) == 0 else wrapped


def ray_circle_distances(origin, directions, centers, radii):
    """Distance along rays to the first crossing of circles.

    Parameters
    ----------
    origin : ndarray, shape (2,)
        Ray origin [m].
    directions : ndarray, shape (n, 2)
        Unit ray directions.
    centers : ndarray, shape (C, 2)
        Circle centres [m].
    radii : ndarray, shape (C,)
        Circle radii [m].

    Returns
    -------
    ndarray, float64, shape (n,)
        Smallest ``t >= 0`` with ``|origin + t d - c| = r`` over all
        circles; 0 when the origin is inside a circle; ``inf`` when no ray
        meets any circle.
    """
    n = len(directions)
    if len(centers) == 0:
        return np.full(n, np.inf)
    w = origin[None, :] - centers                       # (C, 2)
    b = directions @ w.T                                 # (n, C)
    c = np.einsum('ij,ij->i', w, w) - radii ** 2         # (C,)
    disc = b * b - c[None, :]
    with np.errstate(invalid='ignore'):
        t = -b - np.sqrt(disc)
    t = np.where((disc >= 0) & (t >= 0), t, np.inf)
    t = np.where(c[None, :] <= 0, 0.0, t)                # origin inside
    return t.min(axis=1)


def ray_box_distances(origin, directions, mins, maxs):
    """Distance along rays to the first crossing of axis-aligned boxes (slab test).

    Parameters
    ----------
    origin : ndarray, shape (2,)
    directions : ndarray, shape (n, 2)
        Unit ray directions.
    mins, maxs : ndarray, shape (R, 2)
        Box corners [m].

    Returns
    -------
    ndarray, float64, shape (n,)
        Entry distance [m]; 0 when the origin is inside a box; ``inf`` on a
        miss.
    """
    n = len(directions)
    if len(mins) == 0:
        return np.full(n, np.inf)
    d = np.where(directions == 0.0, _TINY, directions)   # (n, 2)
    inv = 1.0 / d
    t1 = (mins[None, :, :] - origin[None, None, :]) * inv[:, None, :]   # (n, R, 2)
    t2 = (maxs[None, :, :] - origin[None, None, :]) * inv[:, None, :]
    t_near = np.minimum(t1, t2).max(axis=2)
    t_far = np.maximum(t1, t2).min(axis=2)
    hit = (t_near <= t_far) & (t_far >= 0)
    t = np.where(hit, np.maximum(t_near, 0.0), np.inf)
    return t.min(axis=1)


def ray_grid_distances(occupied, origin, directions, max_distance, chunk=RAY_CHUNK_CELLS,
                       compiled=True):
    """Distance along rays to the first occupied cell or the grid edge.

    Works in continuous grid coordinates (cell ``(r, c)`` is the unit square
    ``[c, c+1) x [r, r+1)``); the caller converts to metres.

    Parameters
    ----------
    occupied : ndarray of bool, shape (H, W)
    origin : ndarray, shape (2,)
        ``(col, row)`` of the ray origin, grid units.
    directions : ndarray, shape (n, 2)
        Unit directions in grid coordinates ``(dcol, drow)``.
    max_distance : float
        Ignore hits beyond this distance [cells].
    chunk : float, optional
        Length [cells] of ray examined per pass.
    compiled : bool, optional
        Walk the rays with :func:`~fusion_planner.core.simulation.ray_kernel.first_blocked`
        when numba is installed (the same distances, about ten times faster).

    Returns
    -------
    ndarray, float64, shape (n,)
        Distance [cells] at which each ray enters an occupied cell or leaves
        the grid; ``inf`` when that is beyond ``max_distance``; 0 when the
        origin is in an occupied cell or outside the grid.

    Notes
    -----
    Exact cell traversal (as Amanatides & Woo's DDA) done with arrays: a ray
    enters a new cell exactly where it crosses a grid line, and the crossings
    of the vertical lines ``col = c`` lie at ``t = t0x + k / |dcol|`` (the
    horizontal ones alike). Each pass takes, for every live ray, all
    crossings with ``t`` in the next ``chunk`` cells of length, looks the
    entered cells up, and keeps the nearest blocked one; rays that hit drop
    out. The number of passes is bounded by ``max_distance / chunk + 1``.
    """
    height, width = occupied.shape
    n = len(directions)
    px, py = float(origin[0]), float(origin[1])
    cx, cy = math.floor(px), math.floor(py)
    if not (0 <= cx < width and 0 <= cy < height) or occupied[cy, cx]:
        return np.zeros(n)
    t_hit = ray_kernel.first_blocked(occupied, origin, directions, max_distance) \
        if compiled else None
    if t_hit is not None:
        return t_hit
    # per family (crossings of vertical lines: axis 0, horizontal: axis 1)
    start = np.array([px, py])
    cell = np.array([cx, cy])
    with np.errstate(divide='ignore', invalid='ignore'):
        step = np.where(directions > 0, 1, -1)                        # (n, 2)
        t_delta = np.where(directions != 0, 1.0 / np.abs(directions), np.inf)
        t_first = np.where(directions > 0, (cell + 1 - start) / directions,
                           np.where(directions < 0, (start - cell) / -directions, np.inf))
    columns = np.arange(int(math.ceil(chunk)) + 2)
    t_hit = np.full(n, np.inf)
    live = np.arange(n)
    t0 = 0.0
    for _ in range(int(max_distance / chunk) + 2):
        if len(live) == 0 or t0 > max_distance:
            break
        t1 = min(t0 + chunk, max_distance)
        best = np.full(len(live), np.inf)
        for axis in (0, 1):
            other = 1 - axis
            tf, td = t_first[live, axis], t_delta[live, axis]
            finite = np.isfinite(td)
            with np.errstate(invalid='ignore'):   # inf * 0 on rays parallel to the lines
                k0 = np.where(finite, np.maximum(np.ceil((t0 - tf) / td), 0.0), 0.0)
                k = k0[:, None] + columns[None, :]                      # (m, K)
                t = np.where(finite[:, None], tf[:, None] + td[:, None] * k, np.inf)
            in_chunk = (t >= t0) & (t <= t1)
            entered = cell[axis] + step[live, axis][:, None] * (k + 1)  # along axis
            across = np.floor(start[other] + np.where(in_chunk, t, 0.0)
                              * directions[live, other][:, None]).astype(np.int64)
            entered = entered.astype(np.int64)
            ix, iy = (entered, across) if axis == 0 else (across, entered)
            inside = (ix >= 0) & (ix < width) & (iy >= 0) & (iy < height)
            blocked = ~inside
            blocked[inside] = occupied[iy[inside], ix[inside]]
            best = np.minimum(best, np.where(in_chunk & blocked, t, np.inf).min(axis=1))
        done = np.isfinite(best)
        t_hit[live[done]] = best[done]
        live = live[~done]
        t0 = t1
    return t_hit


def rasterise_obstacles(grid, circles=(), rectangles=()):
    """The known map with unknown static obstacles burnt in (the true static map).

    A cell becomes occupied when an obstacle overlaps its square (a
    conservative raster: the true free space is a superset of the result's).

    Parameters
    ----------
    grid : GridMap
    circles : sequence of Circle
    rectangles : sequence of Rectangle

    Returns
    -------
    GridMap
        Same geometry as ``grid``.
    """
    occupied = np.array(grid.occupied, copy=True)
    res = grid.resolution
    centers = grid.world_of(np.indices(grid.shape).reshape(2, -1).T).reshape(*grid.shape, 2)
    half = res / 2
    for circle in circles:
        c = np.asarray(circle.center, dtype=float)
        # distance from the circle centre to each (axis-aligned) cell square
        ddx = np.maximum(np.abs(centers[..., 0] - c[0]) - half, 0.0)
        ddy = np.maximum(np.abs(centers[..., 1] - c[1]) - half, 0.0)
        occupied |= np.hypot(ddx, ddy) < circle.radius
    for rect in rectangles:
        lo, hi = np.asarray(rect.min, float), np.asarray(rect.max, float)
        occupied |= ((centers[..., 0] + half > lo[0]) & (centers[..., 0] - half < hi[0])
                     & (centers[..., 1] + half > lo[1]) & (centers[..., 1] - half < hi[1]))
    return GridMap(occupied, res, grid.origin)


# -- the static world -----------------------------------------------------------

class StaticScene:
    """Everything that does not move: map cells, unknown circles and rectangles, map edge.

    Parameters
    ----------
    grid : GridMap
        The known map; occupied cells are solid squares.
    circles : sequence of Circle
    rectangles : sequence of Rectangle
    """

    def __init__(self, grid, circles=(), rectangles=()):
        self.grid = grid
        self.circles = tuple(circles)
        self.rectangles = tuple(rectangles)
        self.circle_centers = np.array([c.center for c in self.circles], float).reshape(-1, 2)
        self.circle_radii = np.array([c.radius for c in self.circles], float)
        self.rect_mins = np.array([r.min for r in self.rectangles], float).reshape(-1, 2)
        self.rect_maxs = np.array([r.max for r in self.rectangles], float).reshape(-1, 2)

    def distance(self, point, horizon):
        """Distance [m] from a point to the nearest static obstacle surface.

        Parameters
        ----------
        point : array_like, shape (2,)
            ``(x, y)`` [m], map frame.
        horizon : float
            Map cells are searched exactly within this radius [m]; a larger
            result is exact for circles, rectangles and the map edge and
            within one cell for map cells.

        Returns
        -------
        float
            >= 0; 0 when the point lies inside an obstacle or off the map.
        """
        p = np.asarray(point, dtype=float)
        best = self._edge_distance(p)
        if best <= 0.0:
            return 0.0
        best = min(best, self._cell_distance(p, horizon))
        if len(self.circles):
            d = np.hypot(*(self.circle_centers - p).T) - self.circle_radii
            best = min(best, float(np.maximum(d, 0.0).min()))
        if len(self.rectangles):
            gap = np.maximum(np.maximum(self.rect_mins - p, p - self.rect_maxs), 0.0)
            best = min(best, float(np.hypot(gap[:, 0], gap[:, 1]).min()))
        return max(best, 0.0)

    def disc_collides(self, center, radius):
        """Whether a disc overlaps a static obstacle or crosses the map edge."""
        return self.distance(center, radius) < radius

    def _edge_distance(self, p):
        """Distance [m] from a point inside the map to its edge; 0 outside."""
        g = self.grid.world_to_grid(p)
        h, w = self.grid.shape
        inside_margin = min(g[0], w - g[0], g[1], h - g[1])
        return max(inside_margin, 0.0) * self.grid.resolution

    def _cell_distance(self, p, horizon):
        """Distance [m] to the nearest occupied cell square (exact within ``horizon``)."""
        grid = self.grid
        res = grid.resolution
        g = grid.world_to_grid(p)
        row, col = int(math.floor(g[1])), int(math.floor(g[0]))
        edt = float(grid.clearance[row, col]) if grid.contains((row, col)) else 0.0
        if not math.isfinite(edt):
            return math.inf
        # The square nearest to p has its centre within edt + 1.5 cells of p
        # (half a diagonal from p to its cell centre, half a diagonal from a
        # square to its centre), so a window of that reach holds it.
        full_reach = edt + 1.5 * res
        reach = min(max(horizon, 0.0), full_reach, CLEARANCE_WINDOW_M)
        half = reach / res
        r0, r1 = max(int(math.floor(g[1] - half)), 0), min(int(math.floor(g[1] + half)), grid.height - 1)
        c0, c1 = max(int(math.floor(g[0] - half)), 0), min(int(math.floor(g[0] + half)), grid.width - 1)
        rows, cols = np.nonzero(grid.occupied[r0:r1 + 1, c0:c1 + 1])
        nearest = math.inf
        if len(rows):
            ddx = np.maximum(np.abs(cols + c0 + 0.5 - g[0]) - 0.5, 0.0)
            ddy = np.maximum(np.abs(rows + r0 + 0.5 - g[1]) - 0.5, 0.0)
            nearest = float(np.hypot(ddx, ddy).min()) * res
        if nearest <= reach or reach >= full_reach:
            return nearest
        # every square outside the window is at least `reach` away
        return min(nearest, max(reach, edt - res * math.sqrt(0.5)))

    def cast(self, origin, directions, max_range):
        """Ranges [m] from ``origin`` along unit ``directions`` (n, 2) to the first static hit."""
        grid = self.grid
        g0 = grid.world_to_grid(origin)
        # rotate directions into the grid frame (the map origin may have a yaw)
        c, s = math.cos(grid.origin[2]), math.sin(grid.origin[2])
        dirs_g = np.stack([c * directions[:, 0] + s * directions[:, 1],
                           -s * directions[:, 0] + c * directions[:, 1]], axis=1)
        t = ray_grid_distances(grid.occupied, g0, dirs_g, max_range / grid.resolution)
        t = t * grid.resolution
        t = np.minimum(t, ray_circle_distances(origin, directions, self.circle_centers, self.circle_radii))
        return np.minimum(t, ray_box_distances(origin, directions, self.rect_mins, self.rect_maxs))


# -- moving obstacles -------------------------------------------------------------

@dataclass
class _Mover:
    """Mutable state of one moving obstacle."""

    spec: MovingObstacle
    position: np.ndarray
    velocity: np.ndarray
    heading: float = 0.0
    waypoints: np.ndarray = field(default=None, repr=False)
    cumulative: np.ndarray = field(default=None, repr=False)


class World:
    """The simulated world: one robot among static and moving obstacles.

    Parameters
    ----------
    grid : GridMap
        The known map.
    robot : RobotSpec
    start_pose : array_like, shape (3,)
        ``(x, y, yaw)`` [m, m, rad].
    unknown_obstacles : sequence of Circle or Rectangle, optional
    moving_obstacles : sequence of MovingObstacle, optional
    scan_config : ScanConfig, optional
    seed : int, optional
        Seed of the random walks and the scan noise.

    Raises
    ------
    InvalidInput
        Bad argument types or values (non-finite pose, unknown obstacle
        kind).

    Attributes
    ----------
    pose : ndarray, shape (3,)
        Robot pose ``(x, y, yaw)``.
    velocity : ndarray, shape (2,)
        Robot ``(v, omega)`` actually applied in the last step.
    time : float
        Simulated time [s].
    contact_events : int
        Number of contact events so far (see the module notes).
    moving_contact_events : int
        Those of them that began with a moving obstacle overlapping the robot
        (not with a refused step into a static obstacle).
    passive_contact_events : int
        Those of them that were passive (see the module notes).
    contacts : list of ContactEvent
        Every contact event so far, oldest first, with how it was judged.
    in_contact : bool
        Whether the last step ended in contact.
    """

    def __init__(self, grid, robot, start_pose, unknown_obstacles=(), moving_obstacles=(),
                 scan_config=None, seed=0):
        if not isinstance(grid, GridMap):
            raise InvalidInput('the world needs a GridMap as its known map')
        pose = np.asarray(start_pose, dtype=float).reshape(-1)
        if pose.shape != (3,) or not np.all(np.isfinite(pose)):
            raise InvalidInput(f'start pose must be three finite numbers (x, y, yaw), got {start_pose!r}')
        circles, rects = [], []
        for obstacle in unknown_obstacles:
            if isinstance(obstacle, Circle):
                circles.append(obstacle)
            elif isinstance(obstacle, Rectangle):
                rects.append(obstacle)
            else:
                raise InvalidInput(f'unknown static obstacle kind {type(obstacle).__name__}')
        self.robot = robot
        self.static = StaticScene(grid, circles, rects)
        self.scan_config = scan_config or ScanConfig()
        self._angles = self.scan_config.angles()
        seeds = np.random.SeedSequence(seed).spawn(2)
        self._motion_rng = np.random.default_rng(seeds[0])
        self._noise_rng = np.random.default_rng(seeds[1])
        self.pose = pose.copy()
        self.pose[2] = wrap_angle(self.pose[2])
        self.velocity = np.zeros(2)
        self.time = 0.0
        self.contact_events = 0
        self.moving_contact_events = 0
        self.passive_contact_events = 0
        self.contacts = []
        self.in_contact = False
        self._movers = [self._make_mover(spec) for spec in moving_obstacles]
        self._mover_radii = np.array([m.spec.radius for m in self._movers], float)
        self._history = deque()
        self._remember()

    # -- state queries ------------------------------------------------------

    @property
    def grid(self):
        """The known map."""
        return self.static.grid

    def obstacle_positions(self):
        """Centres ``(K, 2)`` [m] of the moving obstacles."""
        return np.array([m.position for m in self._movers], float).reshape(-1, 2)

    def tracked_obstacles(self):
        """What an ideal tracker reports about the moving obstacles.

        Returns
        -------
        ndarray, float64, shape (K, 5)
            ``x, y, vx, vy, radius`` [m, m, m/s, m/s, m], map frame; ``(0, 5)``
            without moving obstacles.
        """
        if not self._movers:
            return np.zeros((0, 5))
        return np.array([[*m.position, *m.velocity, m.spec.radius] for m in self._movers], float)

    def turn_stds(self):
        """How much each moving obstacle turns, as an ideal tracker would know it.

        Returns
        -------
        ndarray, float64, shape (K,)
            Heading diffusion [rad / sqrt(s)]: a random walk's ``turn_std``,
            0 for the other motions (their turns, bounces and the ends of
            their legs are not a diffusion).
        """
        return np.array([m.spec.motion.turn_std if isinstance(m.spec.motion, RandomWalkMotion)
                         else 0.0 for m in self._movers], float)

    def clearance(self):
        """Distance [m] from the robot's boundary to the nearest obstacle of any kind.

        Returns
        -------
        float
            0 when touching or overlapping something.
        """
        p = self.pose[:2]
        r = self.robot.radius
        best = self.static.distance(p, CLEARANCE_WINDOW_M) - r
        for mover in self._movers:
            best = min(best, float(np.hypot(*(mover.position - p))) - mover.spec.radius - r)
        return max(best, 0.0)

    def in_collision(self, pose=None):
        """Whether the robot disc at ``pose`` (default: now) overlaps any obstacle."""
        p = self.pose[:2] if pose is None else np.asarray(pose, float)[:2]
        r = self.robot.radius
        if self.static.disc_collides(p, r):
            return True
        return self._overlaps_mover(p, r)

    def _overlaps_mover(self, p, r):
        return any(np.hypot(*(m.position - p)) < m.spec.radius + r for m in self._movers)

    def _judge_contact(self, before, dt, refused_speed):
        """The record of a contact event that began in the last step (see the module notes).

        ``before`` (2,) [m] is where the robot was a step ``dt`` [s] ago;
        ``refused_speed`` [m/s] is the speed of a step refused at a static
        obstacle, None when the step was taken. A contact with people is
        with the moving obstacle nearest to overlapping the robot now.
        """
        velocity = (self.pose[:2] - before) / dt
        speed = math.hypot(velocity[0], velocity[1])
        where = (float(self.pose[0]), float(self.pose[1]))
        if refused_speed is not None:
            return ContactEvent(self.time, where, refused_speed)
        gaps = [math.hypot(*(m.position - self.pose[:2])) - m.spec.radius for m in self._movers]
        touched = int(np.argmin(gaps))
        approach = None
        if speed >= AT_REST_MPS:
            towards = self._movers[touched].position - self.pose[:2]
            approach = float(velocity @ towards) / max(math.hypot(towards[0], towards[1]),
                                                       1e-9) / speed
        escape = could_escape(self.static, self.robot, self._mover_radii, list(self._history),
                              touched)
        retreating = approach is None or approach <= RETREAT_COSINE
        return ContactEvent(self.time, where, speed, person=touched, approach=approach,
                            escape=escape, passive=retreating and not escape)

    def _remember(self):
        """Record the state after a step; keep what an escape may start from."""
        self._history.append(Snapshot(
            time=self.time, pose=self.pose.copy(), speed=float(self.velocity[0]),
            people=self.obstacle_positions(),
            people_velocity=np.array([m.velocity for m in self._movers], float).reshape(-1, 2)))
        while self._history[0].time < self.time - ESCAPE_HORIZON_S - 1e-9:
            self._history.popleft()

    # -- sensing ----------------------------------------------------------------

    def scan(self):
        """A laser scan from the robot's pose.

        Returns
        -------
        LaserScan
            Ranges per REP-117 (``inf`` no hit, ``-inf`` too close) and the
            map-frame hit points of the valid ranges.

        Notes
        -----
        Map cells are traversed exactly (DDA); unknown circles, rectangles and
        moving obstacles are intersected analytically; all beams at once.
        """
        cfg = self.scan_config
        x, y, yaw = self.pose
        world_angles = yaw + self._angles
        directions = np.stack([np.cos(world_angles), np.sin(world_angles)], axis=1)
        origin = np.array([x, y])
        ranges = self.static.cast(origin, directions, cfg.range_max)
        if self._movers:
            centers = self.obstacle_positions()
            radii = np.array([m.spec.radius for m in self._movers])
            ranges = np.minimum(ranges, ray_circle_distances(origin, directions, centers, radii))
        if cfg.noise_std > 0:
            noise = self._noise_rng.normal(0.0, cfg.noise_std, size=len(ranges))
            finite = np.isfinite(ranges)
            ranges = np.where(finite, ranges + noise, ranges)
        ranges = np.where(ranges > cfg.range_max, np.inf, ranges)
        ranges = np.where(ranges < cfg.range_min, -np.inf, ranges)
        valid = np.isfinite(ranges)
        points = origin + directions[valid] * ranges[valid, None]
        return LaserScan(angles=self._angles.copy(), ranges=ranges, points=points,
                         origin=self.pose.copy())

    # -- time stepping --------------------------------------------------------------

    def step(self, v, omega, dt):
        """Advance the world by ``dt``: obstacles move, then the robot.

        Parameters
        ----------
        v : float
            Commanded linear speed [m/s]; clipped to ``max_speed`` and to the
            acceleration limit ``max_accel * dt`` from the current speed.
        omega : float
            Commanded turn rate [rad/s]; clipped to ``max_omega``.
        dt : float
            Time step [s], > 0.

        Returns
        -------
        bool
            True when a new contact event began in this step.

        Raises
        ------
        InvalidInput
            Non-finite command or non-positive ``dt``.
        """
        if not (math.isfinite(v) and math.isfinite(omega)):
            raise InvalidInput(f'command must be finite, got v={v!r}, omega={omega!r}')
        if not (math.isfinite(dt) and dt > 0):
            raise InvalidInput(f'time step must be a positive number of seconds, got {dt!r}')
        spec = self.robot
        v_prev = self.velocity[0]
        v = float(np.clip(v, -spec.max_speed, spec.max_speed))
        v = float(np.clip(v, v_prev - spec.max_accel * dt, v_prev + spec.max_accel * dt))
        omega = float(np.clip(omega, -spec.max_omega, spec.max_omega))
        for mover in self._movers:
            self._move(mover, dt)
        new_pose = integrate_unicycle(self.pose, v, omega, dt)
        before = self.pose[:2].copy()
        blocked = self.static.disc_collides(new_pose[:2], spec.radius)
        if blocked:
            # a bump: the robot stays where it was, turning is still possible
            self.pose = np.array([self.pose[0], self.pose[1], new_pose[2]])
            self.velocity = np.array([0.0, omega])
        else:
            self.pose = new_pose
            self.velocity = np.array([v, omega])
        self.time += dt
        self._remember()
        contact = blocked or self._overlaps_mover(self.pose[:2], spec.radius)
        started = contact and not self.in_contact
        if started:
            event = self._judge_contact(before, dt, abs(v) if blocked else None)
            self.contacts.append(event)
            self.contact_events += 1
            self.moving_contact_events += int(not blocked)
            self.passive_contact_events += int(event.passive)
            LOGGER.debug('contact at t=%.2f s, pose %s', self.time, self.pose.round(3).tolist())
        self.in_contact = contact
        return started

    def _make_mover(self, spec):
        motion = spec.motion
        if isinstance(motion, BounceMotion):
            return _Mover(spec, np.array(motion.position, float), np.array(motion.velocity, float))
        if isinstance(motion, RandomWalkMotion):
            heading = float(self._motion_rng.uniform(-math.pi, math.pi))
            velocity = motion.speed * np.array([math.cos(heading), math.sin(heading)])
            return _Mover(spec, np.array(motion.position, float), velocity, heading=heading)
        if isinstance(motion, WaypointMotion):
            pts = np.asarray(motion.points, float)
            loop = np.vstack([pts, pts[:1]])
            seg = np.hypot(*np.diff(loop, axis=0).T)
            cumulative = np.concatenate([[0.0], np.cumsum(seg)])
            mover = _Mover(spec, pts[0].copy(), np.zeros(2), waypoints=loop, cumulative=cumulative)
            self._place_on_loop(mover, 0.0)
            return mover
        raise InvalidInput(f'unknown motion model {type(motion).__name__}')

    def _move(self, mover, dt):
        motion = mover.spec.motion
        if isinstance(motion, WaypointMotion):
            self._place_on_loop(mover, self.time + dt)
            return
        if isinstance(motion, RandomWalkMotion):
            mover.heading += motion.turn_std * math.sqrt(dt) * float(self._motion_rng.normal())
            mover.velocity = motion.speed * np.array([math.cos(mover.heading), math.sin(mover.heading)])
        self._give_way(mover, dt)
        self._bounce(mover, dt)
        if isinstance(motion, RandomWalkMotion):
            mover.heading = math.atan2(mover.velocity[1], mover.velocity[0])

    def _give_way(self, mover, dt):
        """Reflect ``mover``'s velocity off each other mover its next step would overlap."""
        for other in self._movers:
            if other is mover:
                continue
            away = mover.position - other.position
            distance = math.hypot(away[0], away[1])
            reach = mover.spec.radius + other.spec.radius
            ahead = mover.position + mover.velocity * dt - other.position
            approaching = float(mover.velocity @ away) < 0.0
            if distance > 0.0 and approaching and math.hypot(ahead[0], ahead[1]) < reach:
                normal = away / distance
                mover.velocity = mover.velocity - 2.0 * float(mover.velocity @ normal) * normal

    def _bounce(self, mover, dt):
        """Move at constant velocity; reflect the velocity components that would hit."""
        radius = mover.spec.radius
        p, vel = mover.position, mover.velocity.copy()
        collides = self.static.disc_collides
        if not collides(p + vel * dt, radius):
            mover.position = p + vel * dt
            return
        hit_x = collides(p + np.array([vel[0] * dt, 0.0]), radius)
        hit_y = collides(p + np.array([0.0, vel[1] * dt]), radius)
        if hit_x:
            vel[0] = -vel[0]
        if hit_y:
            vel[1] = -vel[1]
        if not (hit_x or hit_y):   # a corner: only the diagonal move hits
            vel = -vel
        mover.velocity = vel
        candidate = p + vel * dt
        if not collides(candidate, radius):
            mover.position = candidate

    def _place_on_loop(self, mover, t):
        motion = mover.spec.motion
        total = mover.cumulative[-1]
        if total <= 0 or motion.speed == 0:
            mover.position = mover.waypoints[0].copy()
            mover.velocity = np.zeros(2)
            return
        s = (motion.speed * t) % total
        i = int(np.searchsorted(mover.cumulative, s, side='right') - 1)
        i = min(max(i, 0), len(mover.cumulative) - 2)
        a, b = mover.waypoints[i], mover.waypoints[i + 1]
        seg = mover.cumulative[i + 1] - mover.cumulative[i]
        direction = (b - a) / seg if seg > 0 else np.zeros(2)
        mover.position = a + direction * (s - mover.cumulative[i])
        mover.velocity = direction * motion.speed
