"""Local controllers: turn a global plan and what the robot senses into (v, omega).

Four controllers share one interface (:class:`Controller`), made by
:func:`make_controller`:

``'fusion'``
    The paper's section 3.3: the key nodes of the A* path are successive
    sub-goals; the improved APF (eqs. (15)-(17)) steers around the sensed
    obstacle points and around tracked moving obstacles **at their predicted
    positions** over a horizon (beyond the paper); the adaptive step of
    eq. (18) limits the speed near obstacles ahead. When stuck it first aims
    at the next key node (the paper's escape), then asks for a new global
    plan around what it has seen (when given a replanner), then follows the
    blocking boundary.
``'apf'``
    The improved field straight to the final goal (no A*); escape by
    boundary following.
``'classic-apf'``
    The classic field of eqs. (9)-(14) straight to the goal, no prediction,
    no escape: it is expected to stop short of a goal beside an obstacle and
    to be caught by traps (the paper's Figure 5). Stuck means failed.
``'astar-track'``
    Pure-pursuit tracking of the global path with no avoidance at all, the
    baseline the paper improves on. Stuck (blocked) means failed.

The command pipeline (:class:`FollowerParams` holds every number):

1. a desired direction: the total force (fields), the path lookahead point
   (tracker) or the boundary tangent (escape);
2. heading control: ``omega`` proportional to the heading error, capped so
   the robot can stop turning in time; forward speed scaled by
   ``cos(error)^2`` (zero beyond 90 degrees: turn in place);
3. speed caps: approach (``v <= approach_gain * distance to goal``), the
   adaptive step of eq. (18), and a braking cap from the free distance
   straight ahead (field controllers only);
4. limits relative to the measured velocity: ``0 <= v <= max_speed``,
   ``|omega| <= max_omega``, ``|dv| <= max_accel * control_period``,
   ``|d omega| <= max_alpha * control_period``. Speed limits win over
   acceleration limits if the measured velocity is already out of range.

What the field sees: the obstacle points, thinned to one per
``point_spacing`` square (so a wall's pull does not depend on the scan's
angular density), plus, for each tracked obstacle, the nearest surface point
of its circle at :data:`PREDICTION_SAMPLES` instants over
``prediction_horizon``, predicted **relative to the robot** going on at its
current velocity, weighted like a sampled half circumference and fading to
:data:`FAR_PREDICTION_WEIGHT`; a predicted (not current) overlap repels as if
:data:`PREDICTED_MIN_GAP` away. The field attracts to a carrot at most
``lookahead`` ahead (``FieldFollower._field_goal``). Fusion sub-goals are the
key nodes in turn; a node is passed when reached (``goal_tolerance``) or when
a later one is visible with ``sight_clearance`` to spare.

Local minima (issue 3, item 2): a field controller keeps the distance to its
current sub-goal over time; **stuck** means a net progress below
``stuck_progress`` over ``stuck_window`` (standing still and oscillating
alike). Each detection counts one ``stuck_event`` and opens (or continues)
an escape episode, whose steps are, in order:

1. fusion only, once per episode: make the next A* key node the sub-goal
   (the paper's escape);
2. fusion with a replanner, up to :data:`MAX_REPLANS_PER_EPISODE` times: a new
   global plan from here around the map and every static point seen so far;
3. boundary following (Bug2-like): keep the blocking boundary on a fixed
   side at ``wall_distance`` until the robot is closer to the sub-goal than
   at every earlier hit by ``stuck_progress`` and the way to it is free.

An episode ends when the robot passes the key node it escaped to or leaves
the boundary. One still open after ``escape_time_limit`` ends in status
``'failed'`` with a reason, which stays until ``reset`` or ``set_path``.
Arrival is only reported within ``goal_tolerance`` of the goal.

Examples
--------
>>> import numpy as np
>>> ctrl = make_controller('fusion', FollowerParams())
>>> ctrl.set_path(np.array([[0.0, 0.0], [3.0, 0.0]]), np.array([[0.0, 0.0], [3.0, 0.0]]))
>>> obs = Observation(pose=np.array([0.0, 0.0, 0.0]), velocity=np.zeros(2),
...                   obstacle_points=np.zeros((0, 2)), tracked=np.zeros((0, 5)), time=0.0)
>>> cmd = ctrl.compute(obs)
>>> cmd.status, cmd.v > 0, abs(cmd.omega) < 1e-9
('moving', True, True)
"""

import collections
import logging
import math
from dataclasses import dataclass, field, replace
from typing import Protocol

import numpy as np

from fusion_planner.core import apf
from fusion_planner.core.apf import ApfParams
from fusion_planner.core.errors import InvalidInput, PlanningError
from fusion_planner.core.grid import GridMap
from fusion_planner.core.planner import GlobalPlanner, PlannerConfig

LOGGER = logging.getLogger(__name__)

#: Names accepted by :func:`make_controller`.
CONTROLLER_NAMES = ('fusion', 'apf', 'classic-apf', 'astar-track')

#: Values of :attr:`Command.status`.
STATUSES = ('moving', 'arrived', 'stuck_escaping', 'failed', 'no_path')

#: Predicted positions per tracked obstacle over the prediction horizon
#: (including the current one).
PREDICTION_SAMPLES = 5

#: Smallest boundary distance [m] at which a predicted (not current) position
#: of a tracked obstacle repels: an overlap predicted seconds ahead must steer
#: the robot, not swamp every other force with a near-infinite one.
PREDICTED_MIN_GAP = 0.1

#: Weight of the last predicted position relative to the current one (linear
#: in between): the farther future is less certain.
FAR_PREDICTION_WEIGHT = 0.5

#: The adaptive step never slows the robot below this fraction of max_speed:
#: eq. (18) gives a zero step at d = 0 and the robot must still be able to
#: leave (the braking cap, not the step, is what prevents contact).
MIN_STEP_FRACTION = 0.25

#: Points within this band [m] beyond the nearest one define the wall normal
#: when following a boundary.
FOLLOW_BAND = 0.25

#: Gain of the clearance correction while following a boundary (1: turn 45
#: degrees toward or away from the wall at a clearance error of one
#: ``wall_distance``).
WALL_GAIN = 1.0

#: Key nodes ahead of the current one tested for visibility on each step.
MAX_VISIBILITY_CHECKS = 4

#: Global replans per escape episode before falling back to boundary following.
MAX_REPLANS_PER_EPISODE = 2

#: Points of the field rollout returned as :attr:`Command.local_plan`.
ROLLOUT_STEPS = 6

#: Longest step [m] of the field rollout.
ROLLOUT_MAX_STEP = 0.2

#: Path points ahead of the current one the tracker searches for the closest.
TRACK_SEARCH_WINDOW = 200

#: Spacing [m] of the tracker's resampled path.
TRACK_SPACING = 0.05

#: A force shorter than this has no direction: the robot stops (a minimum).
FORCE_EPS = 1e-9

#: Period [s] at which static obstacle points are added to the memory used
#: for replanning.
MEMORY_PERIOD = 1.0

#: Cap on the remembered obstacle points (oldest dropped first).
MAX_MEMORY_POINTS = 20000

#: A point within this many cells (cell-centre clearance) of an occupied map
#: cell is explained by the map; the replanner does not add it again.
KNOWN_POINT_CELLS = 1.5

#: Scan points closer than this [m] to a tracked obstacle's boundary belong
#: to it and are not remembered as static.
TRACKED_POINT_MARGIN = 0.15


# -- data -------------------------------------------------------------------------

def _check_number(value, name, strict=True):
    ok = isinstance(value, (int, float, np.floating, np.integer)) and not isinstance(value, bool) \
        and math.isfinite(value) and (value > 0 if strict else value >= 0)
    if not ok:
        relation = '>' if strict else '>='
        raise InvalidInput(
            f'FollowerParams.{name} must be a finite number {relation} 0, got {value!r}')


@dataclass(frozen=True)
class FollowerParams:
    """Everything that tunes a local controller.

    Attributes
    ----------
    apf : ApfParams
        Field coefficients; its ``robot_radius`` is replaced by
        ``robot_radius`` below (the follower's value is authoritative).
    max_speed : float
        Largest forward speed [m/s], > 0 (the controllers never reverse).
    max_accel : float
        Largest change of forward speed [m/s^2], > 0.
    max_omega : float
        Largest turn rate [rad/s], > 0.
    max_alpha : float
        Largest change of turn rate [rad/s^2], > 0.
    goal_tolerance : float
        Arrival radius around the final goal [m], > 0; an intermediate key
        node this close counts as reached.
    lookahead : float
        [m], > 0. Improved fields: the field's goal is a point at most this
        far ahead (see ``FieldFollower._field_goal``), so the ``rho_g^n``
        scaling of eqs. (15)-(16) stays bounded far from the sub-goal.
        Tracker: pure-pursuit lookahead distance.
    control_period : float
        Period of the control loop [s], > 0; acceleration limits allow
        ``max_accel * control_period`` per command.
    stuck_window : float
        Length of the progress window [s], > 0.
    stuck_progress : float
        Net progress toward the sub-goal [m], > 0, that must be made within
        the window.
    escape_time_limit : float
        Longest escape episode [s], > 0, before status ``'failed'``.
    robot_radius : float
        Robot radius [m], >= 0.
    prediction_horizon : float
        How far ahead tracked obstacles are predicted [s], >= 0 (0: only
        their current position, as in the paper).
    heading_gain : float
        Turn rate per radian of heading error [1/s], > 0.
    approach_gain : float
        Speed per metre of distance to the final goal [1/s], > 0.
    safety_distance : float
        Clearance [m], >= 0, kept straight ahead by the braking cap and
        required of a free line when leaving a boundary.
    sight_clearance : float
        Clearance [m], >= 0, the straight line to a later key node must keep
        from every obstacle point for that node to count as visible (fusion);
        wide enough that the field's repulsion does not stall the robot on
        the shortcut.
    wall_distance : float
        Clearance [m], > 0, kept from the boundary while following it.
    point_spacing : float
        Obstacle points are thinned to one per square of this edge [m],
        > 0, before the fields are summed, so the force does not depend on
        the scan's angular density; a tracked obstacle counts as its half
        circumference over this spacing.
    visibility_range : float
        Later key nodes within this distance [m], > 0, are tested for a free
        line of sight (fusion).

    Raises
    ------
    InvalidInput
        If a value is out of range or ``apf`` is not an ApfParams.
    """

    apf: ApfParams = field(default_factory=ApfParams)
    max_speed: float = 1.0
    max_accel: float = 1.0
    max_omega: float = 2.0
    max_alpha: float = 4.0
    goal_tolerance: float = 0.15
    lookahead: float = 1.5
    control_period: float = 0.05
    stuck_window: float = 4.0
    stuck_progress: float = 0.15
    escape_time_limit: float = 60.0
    robot_radius: float = 0.2
    prediction_horizon: float = 2.0
    heading_gain: float = 2.5
    approach_gain: float = 0.8
    safety_distance: float = 0.02
    sight_clearance: float = 0.3
    wall_distance: float = 0.35
    point_spacing: float = 0.1
    visibility_range: float = 4.0

    def __post_init__(self):
        if not isinstance(self.apf, ApfParams):
            raise InvalidInput(
                f'FollowerParams.apf must be an ApfParams, got {type(self.apf).__name__}')
        for name in ('max_speed', 'max_accel', 'max_omega', 'max_alpha', 'goal_tolerance',
                     'lookahead', 'control_period', 'stuck_window', 'stuck_progress',
                     'escape_time_limit', 'heading_gain', 'approach_gain', 'wall_distance',
                     'point_spacing', 'visibility_range'):
            _check_number(getattr(self, name), name)
        for name in ('robot_radius', 'prediction_horizon', 'safety_distance', 'sight_clearance'):
            _check_number(getattr(self, name), name, strict=False)
        if self.apf.robot_radius != self.robot_radius:
            synced = replace(self.apf, robot_radius=float(self.robot_radius))
            object.__setattr__(self, 'apf', synced)


@dataclass(frozen=True)
class Observation:
    """What a controller sees at one instant.

    Attributes
    ----------
    pose : ndarray, float64, shape (3,)
        ``x, y, yaw`` [m, m, rad], map frame; finite.
    velocity : ndarray, float64, shape (2,)
        Measured ``v`` [m/s] and ``omega`` [rad/s], robot frame; finite.
    obstacle_points : ndarray, float64, shape (M, 2)
        Obstacle points [m], map frame (scan endpoints, static or unknown
        obstacles, moving ones too); non-finite rows are ignored.
    tracked : ndarray, float64, shape (K, 5)
        ``x, y, vx, vy, radius`` [m, m, m/s, m/s, m] of tracked moving
        obstacles; may be ``(0, 5)``; non-finite rows are ignored.
    time : float
        [s], finite.

    Raises
    ------
    InvalidInput
        If a shape is wrong, the pose, velocity or time is not finite, or a
        tracked radius is negative.
    """

    pose: np.ndarray
    velocity: np.ndarray
    obstacle_points: np.ndarray
    tracked: np.ndarray
    time: float

    def __post_init__(self):
        pose = np.asarray(self.pose, dtype=float)
        velocity = np.asarray(self.velocity, dtype=float)
        if pose.shape != (3,) or not np.all(np.isfinite(pose)):
            raise InvalidInput(
                f'Observation.pose must be a finite (3,) x, y, yaw, got {self.pose!r}')
        if velocity.shape != (2,) or not np.all(np.isfinite(velocity)):
            raise InvalidInput(
                f'Observation.velocity must be a finite (2,) v, omega, got {self.velocity!r}')
        points = np.asarray(self.obstacle_points, dtype=float)
        points = points.reshape(0, 2) if points.size == 0 else points
        if points.ndim != 2 or points.shape[1] != 2:
            raise InvalidInput(
                f'Observation.obstacle_points must have shape (M, 2), got {points.shape}')
        tracked = np.asarray(self.tracked, dtype=float)
        tracked = tracked.reshape(0, 5) if tracked.size == 0 else tracked
        if tracked.ndim != 2 or tracked.shape[1] != 5:
            raise InvalidInput(f'Observation.tracked must have shape (K, 5), got {tracked.shape}')
        if np.any(tracked[:, 4] < 0):
            raise InvalidInput('Observation.tracked radii must be >= 0')
        if not (isinstance(self.time, (int, float, np.floating)) and math.isfinite(self.time)):
            raise InvalidInput(
                f'Observation.time must be a finite number of seconds, got {self.time!r}')
        object.__setattr__(self, 'pose', pose)
        object.__setattr__(self, 'velocity', velocity)
        object.__setattr__(self, 'obstacle_points', points)
        object.__setattr__(self, 'tracked', tracked)
        object.__setattr__(self, 'time', float(self.time))


@dataclass(frozen=True)
class Command:
    """A velocity command and what the controller is doing.

    Attributes
    ----------
    v : float
        Forward speed [m/s].
    omega : float
        Turn rate [rad/s].
    status : str
        One of :data:`STATUSES`.
    reason : str
        A sentence when ``status`` is ``'failed'`` or ``'no_path'``.
    sub_goal : ndarray, float64, shape (2,) or None
        Current sub-goal [m], map frame.
    local_plan : ndarray, float64, shape (L, 2) or None
        Short rollout of the steering field from the robot [m], for display.
    """

    v: float
    omega: float
    status: str
    reason: str = ''
    sub_goal: np.ndarray = None
    local_plan: np.ndarray = None


class Controller(Protocol):
    """What the simulation runner and the local_planner node call."""

    stuck_events: int

    def set_path(self, path: np.ndarray, key_nodes: np.ndarray) -> None:
        """Take a global plan ``(N, 2)`` [m] and its key nodes ``(K, 2)`` [m]."""

    def reset(self) -> None:
        """Forget the plan and every internal state."""

    def compute(self, obs: Observation) -> Command:
        """One control step."""


# -- geometry helpers -------------------------------------------------------------

def wrap_angle(angle):
    """Wrap an angle to ``[-pi, pi)``.

    Parameters
    ----------
    angle : float
        [rad].

    Returns
    -------
    float
        The same direction [rad] in ``[-pi, pi)``.

    Examples
    --------
    >>> round(wrap_angle(3 * math.pi / 2), 6)
    -1.570796
    """
    return (angle + math.pi) % (2.0 * math.pi) - math.pi


def _as_path(value, name):
    arr = np.asarray(value, dtype=float)
    if arr.ndim != 2 or arr.shape[1] != 2 or len(arr) == 0:
        raise InvalidInput(
            f'{name} must be a non-empty (N, 2) array of metres, got shape {arr.shape}')
    if not np.all(np.isfinite(arr)):
        raise InvalidInput(f'{name} must be finite')
    return arr


def thin_points(points, spacing):
    """Keep one point per ``spacing`` x ``spacing`` square.

    Parameters
    ----------
    points : ndarray, float64, shape (M, 2)
        Points [m], finite.
    spacing : float
        Square edge [m], > 0.

    Returns
    -------
    ndarray, float64, shape (M', 2)
        The first point of each occupied square, in input order, ``M' <= M``.

    Examples
    --------
    >>> thin_points(np.array([[0.01, 0.0], [0.02, 0.0], [0.5, 0.0]]), 0.1).tolist()
    [[0.01, 0.0], [0.5, 0.0]]
    """
    if len(points) < 2:
        return points
    cells = np.floor(points / spacing).astype(np.int64)
    key = cells[:, 0] * np.int64(1 << 31) + cells[:, 1]
    _, first = np.unique(key, return_index=True)
    return points[np.sort(first)]


def _circle_points(q, centres, radii, keep_off=None):
    """Nearest surface point to ``q`` of each circle.

    If ``q`` is inside a circle the point lies just beside ``q``, on the
    centre's side. With ``keep_off`` (``(K,)`` [m]) a point is moved, if need
    be, to at least that distance from ``q`` along the same line.
    """
    diff = q - centres
    dist = np.hypot(diff[:, 0], diff[:, 1])
    unit = diff / np.maximum(dist, apf.DIRECTION_EPS)[:, None]
    reach = np.minimum(radii, dist * (1.0 - 1e-6))
    if keep_off is not None:
        reach = np.minimum(reach, dist - keep_off)
    return centres + unit * reach[:, None]


def _front_gap(pose, centres, radii, clearance):
    """Free travel [m] straight ahead before a disc of ``clearance + radii`` touches a centre."""
    if len(centres) == 0:
        return math.inf
    c, s = math.cos(pose[2]), math.sin(pose[2])
    dx = centres[:, 0] - pose[0]
    dy = centres[:, 1] - pose[1]
    ahead = dx * c + dy * s
    lateral = -dx * s + dy * c
    reach = clearance + radii
    hit = (ahead > 0) & (np.abs(lateral) < reach)
    if not np.any(hit):
        return math.inf
    return float(np.min(ahead[hit] - np.sqrt(reach[hit]**2 - lateral[hit]**2)))


def _segments_clear(q, ends, points, half_width):
    """For each segment q -> ends[i], True when no point lies within half_width of it.

    ``half_width`` is a float or one value per point ``(M,)`` [m].
    """
    if len(points) == 0:
        return np.ones(len(ends), bool)
    half_width = np.reshape(half_width, (-1, 1)) if np.ndim(half_width) else half_width
    seg = ends - q                                            # (C, 2)
    length2 = np.maximum(np.einsum('ij,ij->i', seg, seg), apf.DIRECTION_EPS)
    rel = points - q                                          # (M, 2)
    t = np.clip((rel @ seg.T) / length2, 0.0, 1.0)            # (M, C)
    px = rel[:, 0:1] - t * seg[:, 0]
    py = rel[:, 1:2] - t * seg[:, 1]
    return np.all(px * px + py * py >= half_width**2, axis=0)


def _resample(path, spacing):
    """Points every ``spacing`` [m] (at most) along a polyline ``(N, 2)``, corners kept."""
    pieces = [path[:1]]
    for a, b in zip(path[:-1], path[1:]):
        count = int(math.ceil(math.hypot(*(b - a)) / spacing))
        if count > 0:
            pieces.append(a + np.linspace(0.0, 1.0, count + 1)[1:, None] * (b - a))
    return np.vstack(pieces)


def _window_covered(history, now, window):
    """Drop entries older than needed; True when the oldest left is ``window`` [s] old.

    ``history`` is a deque of tuples whose first item is a time [s]; the
    oldest entry kept is the newest one at least ``window`` old (comparing
    against the window this way is immune to rounding of summed time steps).
    """
    while len(history) >= 2 and now - history[1][0] >= window:
        history.popleft()
    return now - history[0][0] >= window


def _braking_speed(gap, accel, period):
    """Largest speed whose travel over one period plus braking fits in ``gap`` [m]."""
    if not math.isfinite(gap):
        return math.inf
    gap = max(gap, 0.0)
    return max(0.0, -accel * period + math.sqrt((accel * period)**2 + 2.0 * accel * gap))


@dataclass
class _Scene:
    """Obstacles of one step, prepared once."""

    field_points: np.ndarray      # (M', 2) thinned points + tracked surface points [m]
    field_velocities: np.ndarray  # (M', 2) [m/s]
    field_weights: np.ndarray     # (M',)
    all_points: np.ndarray        # (M, 2) every finite point (safety checks) [m]
    circle_centres: np.ndarray    # (K, 2) current tracked centres [m]
    circle_radii: np.ndarray      # (K,) [m]
    nearest_ahead: float          # boundary distance to the nearest obstacle ahead [m]


@dataclass
class _Episode:
    """An open escape episode."""

    start: float             # [s]
    index: int               # sub-goal index after the last escape action
    target_distance: float   # distance to the sub-goal when it opened [m]
    skipped: bool = False    # jumped to the next key node
    replans: int = 0         # new global plans asked for


@dataclass
class _Follow:
    """Boundary-following state."""

    side: int = 0                  # +1: boundary on the right, -1: on the left, 0: not chosen
    wall_point: np.ndarray = None  # last nearest obstacle point [m]


# -- shared command shaping ---------------------------------------------------------

class _Base:
    """Plan storage, velocity limits, stop and command shaping shared by the controllers."""

    def __init__(self, params):
        if not isinstance(params, FollowerParams):
            raise InvalidInput('a controller needs a FollowerParams')
        self.params = params
        self.stuck_events = 0
        self._path = None
        self._key_nodes = None
        self._failure = None
        self._clear_state()

    @property
    def goal(self):
        """The final goal ``(2,)`` [m], or None before :meth:`set_path`."""
        return None if self._key_nodes is None else self._key_nodes[-1]

    @property
    def path(self):
        """The global path ``(N, 2)`` [m] being followed (after replanning), or None."""
        return self._path

    def set_path(self, path, key_nodes):
        """Take a global plan.

        Parameters
        ----------
        path : array_like, shape (N, 2)
            Global path [m], map frame, start to goal.
        key_nodes : array_like, shape (K, 2)
            Its key nodes [m]; the last one is the goal. The field
            controllers without A* use only ``key_nodes[-1]``.

        Raises
        ------
        InvalidInput
            If an array is empty, not (N, 2) or not finite.
        """
        self._path = _as_path(path, 'path')
        self._key_nodes = _as_path(key_nodes, 'key_nodes')
        self._clear_state()

    def reset(self):
        """Forget the plan, the stuck history, the failure and the stuck count."""
        self._path = None
        self._key_nodes = None
        self.stuck_events = 0
        self._clear_state()

    def _clear_state(self):
        self._failure = None

    def _limit(self, v_des, omega_des, obs):
        p = self.params
        v0, w0 = obs.velocity
        dv = p.max_accel * p.control_period
        dw = p.max_alpha * p.control_period
        v = min(max(v_des, v0 - dv), v0 + dv)
        w = min(max(omega_des, w0 - dw), w0 + dw)
        v = min(max(v, 0.0), p.max_speed)
        w = min(max(w, -p.max_omega), p.max_omega)
        return float(v), float(w)

    def _stop(self, obs, status, reason='', sub_goal=None):
        """Brake toward (0, 0) within the acceleration limits."""
        v, w = self._limit(0.0, 0.0, obs)
        return Command(v=v, omega=w, status=status, reason=reason, sub_goal=sub_goal,
                       local_plan=obs.pose[None, :2].copy())

    def _fail(self, obs, reason, sub_goal=None):
        self._failure = reason
        LOGGER.warning('controller failed: %s', reason)
        return self._stop(obs, 'failed', reason, sub_goal)

    def _steer(self, heading, v_cap, obs):
        """Heading control toward ``heading`` [rad] with forward speed at most ``v_cap``."""
        p = self.params
        error = wrap_angle(heading - obs.pose[2])
        turn = min(p.heading_gain * abs(error), math.sqrt(2.0 * p.max_alpha * abs(error)),
                   p.max_omega)
        omega = math.copysign(turn, error)
        v = min(p.max_speed, v_cap) * max(0.0, math.cos(error))**2
        return self._limit(v, omega, obs)


# -- field followers ----------------------------------------------------------------

class FieldFollower(_Base):
    """APF-based controller: ``'fusion'``, ``'apf'`` or ``'classic-apf'``.

    Parameters
    ----------
    params : FollowerParams
    field : {'improved', 'classic'}
        Eqs. (15)-(17) or eqs. (9)-(14).
    use_key_nodes : bool
        Key nodes as successive sub-goals (fusion) or only the final goal.
    escape : bool
        Escape local minima (next key node, replanning, boundary following);
        without it a stuck robot fails at once.
    predict : bool
        Avoid tracked obstacles at their predicted positions over
        ``prediction_horizon`` (otherwise only where they are now).
    replan : callable, optional
        ``replan(start, goal, obstacle_points) -> (path, key_nodes)``: a new
        global plan from ``start`` (2,) to ``goal`` (2,) [m] that also avoids
        the remembered static obstacle points ``(M, 2)`` [m]; raises
        :class:`~fusion_planner.core.errors.PlanningError` when there is
        none. :class:`GridReplanner` is one. Used only with key nodes.

    Attributes
    ----------
    stuck_events : int
        Local-minimum detections since the last :meth:`reset`.
    replans : int
        Successful replans since the last :meth:`reset`.

    Raises
    ------
    InvalidInput
        If ``params`` is not a FollowerParams, ``field`` is unknown or
        ``replan`` is not callable.
    """

    def __init__(self, params, field='improved', use_key_nodes=True, escape=True, predict=True,
                 replan=None):
        if field not in ('improved', 'classic'):
            raise InvalidInput(f"field must be 'improved' or 'classic', got {field!r}")
        if replan is not None and not callable(replan):
            raise InvalidInput(
                'replan must be a callable (start, goal, obstacle_points) -> (path, key_nodes)')
        self.field = field
        self.use_key_nodes = use_key_nodes
        self.escape = escape
        self.predict = predict
        self._replan = replan if use_key_nodes else None
        self._forget()
        super().__init__(params)

    def reset(self):
        """Forget the plan, the stuck history, the failure, the counts and the obstacle memory."""
        super().reset()
        self._forget()

    def _forget(self):
        self.replans = 0
        self._memory = np.zeros((0, 2))
        self._memory_time = -math.inf

    def _clear_state(self):
        super()._clear_state()
        p = self.params
        self._index = 0
        self._anchor = None  # start [m] of the segment leading to the current key node
        self._history = collections.deque(
            maxlen=int(math.ceil(4.0 * p.stuck_window / p.control_period)) + 16)
        self._episode = None
        self._follow = None
        self._best_hit = {}
        self._last_time = None

    # .. obstacles ....................................................................

    def _scene(self, obs):
        """Thin the points, predict the tracked obstacles, find the nearest obstacle ahead."""
        p = self.params
        q = obs.pose[:2]
        points = obs.obstacle_points
        if len(points) and not np.all(np.isfinite(points)):
            points = points[np.all(np.isfinite(points), axis=1)]
        tracked = obs.tracked
        if len(tracked) and not np.all(np.isfinite(tracked)):
            tracked = tracked[np.all(np.isfinite(tracked), axis=1)]
        own = obs.velocity[0] * np.array([math.cos(obs.pose[2]), math.sin(obs.pose[2])])
        thinned = thin_points(points, p.point_spacing)
        if len(thinned):
            # only points within rho0 of the robot or of its rollout exert a force
            reach = p.robot_radius + p.apf.rho0 + ROLLOUT_STEPS * ROLLOUT_MAX_STEP
            d = thinned - q
            thinned = thinned[np.einsum('ij,ij->i', d, d) < reach * reach]
        centres, velocities, radii = tracked[:, 0:2], tracked[:, 2:4], tracked[:, 4]
        field_points, field_velocities = thinned, np.zeros_like(thinned)
        field_weights = np.ones(len(thinned))
        if len(tracked):
            # predicted relative to the robot going on at its current velocity:
            # what matters is where the obstacle will be with respect to the robot
            horizon = p.prediction_horizon if self.predict else 0.0
            samples = PREDICTION_SAMPLES if horizon > 0 else 1
            times = np.linspace(0.0, horizon, samples)                          # (S,)
            relative = velocities - own
            future = centres[None, :, :] + times[:, None, None] * relative[None, :, :]
            future_radii = np.tile(radii, samples)
            # a predicted overlap is not a contact yet: its repulsion is capped
            # as if the obstacle were PREDICTED_MIN_GAP away
            keep_off = np.where(np.repeat(times, len(tracked)) > 0.0,
                                p.robot_radius + PREDICTED_MIN_GAP, 0.0)
            surface = _circle_points(q, future.reshape(-1, 2), future_radii, keep_off)
            arc = np.maximum(math.pi * future_radii / p.point_spacing, 1.0)
            fraction = times / horizon if horizon > 0 else times
            decay = 1.0 - (1.0 - FAR_PREDICTION_WEIGHT) * fraction
            field_points = np.vstack([thinned, surface])
            field_velocities = np.vstack([field_velocities, np.tile(velocities, (samples, 1))])
            field_weights = np.concatenate([field_weights, arc * np.repeat(decay, len(tracked))])
        # the adaptive step looks only ahead: slowing down for an obstacle behind
        # (a person catching up) would only let it run into the robot
        heading = np.array([math.cos(obs.pose[2]), math.sin(obs.pose[2])])
        nearest = math.inf
        if len(thinned):
            d = thinned - q
            ahead = d @ heading > 0.0
            if np.any(ahead):
                nearest = math.sqrt(float(np.min(np.einsum('ij,ij->i', d[ahead], d[ahead])))) \
                    - p.robot_radius
        if len(tracked):
            d = centres - q
            ahead = d @ heading > -radii
            if np.any(ahead):
                gap = np.hypot(d[ahead, 0], d[ahead, 1]) - radii[ahead] - p.robot_radius
                nearest = min(nearest, float(np.min(gap)))
        return _Scene(field_points, field_velocities, field_weights, points, centres, radii,
                      nearest)

    def _remember(self, obs, scene, force=False):
        """Add this step's static points to the replanning memory (once per MEMORY_PERIOD)."""
        if self._replan is None or not (force or obs.time - self._memory_time >= MEMORY_PERIOD):
            return
        self._memory_time = obs.time
        points = scene.all_points
        if len(scene.circle_centres) and len(points):
            diff = points[:, None, :] - scene.circle_centres[None, :, :]
            gap = np.hypot(diff[..., 0], diff[..., 1]) - scene.circle_radii[None, :]
            points = points[np.all(gap > TRACKED_POINT_MARGIN, axis=1)]
        if len(points) == 0:
            return
        merged = thin_points(np.vstack([points, self._memory]), self.params.point_spacing)
        self._memory = merged[-MAX_MEMORY_POINTS:]

    # .. fields .......................................................................

    def _field_goal(self, q, target):
        """The goal the field attracts to (a carrot), given the current sub-goal.

        Classic field: the sub-goal itself (eqs. (9)-(14) as written).
        Improved field with key nodes: the point ``lookahead`` beyond the
        robot's projection on the segment from the previous key node (or from
        where this sub-goal was chosen) to the sub-goal, never past the
        sub-goal; segments between key nodes are collision-free on the map,
        so a robot pushed off one returns to it instead of cutting a corner.
        Improved field without key nodes: the point ``lookahead`` ahead on
        the straight line to the sub-goal. Either way ``rho_g`` of
        eqs. (15)-(16) stays bounded far from the goal and vanishes at it.
        """
        lookahead = self.params.lookahead
        if self.field == 'classic':
            return target
        if self.use_key_nodes and self._anchor is not None:
            segment = target - self._anchor
            length = math.hypot(segment[0], segment[1])
            if length > apf.DIRECTION_EPS:
                along = float((q - self._anchor) @ segment) / length
                reach = min(max(along, 0.0) + lookahead, length)
                return self._anchor + segment * (reach / length)
        offset = target - q
        dist = math.hypot(offset[0], offset[1])
        if dist <= lookahead:
            return target
        return q + offset * (lookahead / dist)

    def _force(self, q, target, scene, robot_velocity):
        """Total force at ``q``: eq. (14) (classic field) or eqs. (10) + (15)-(17) (improved)."""
        ap = self.params.apf
        goal = self._field_goal(q, target)
        force = apf.attractive_force(q, goal, ap, check=False)                      # eq. (10)
        if self.field == 'classic':
            return force + apf.classic_repulsive_force(                            # eq. (14)
                q, scene.field_points, ap, scene.field_weights, check=False)
        force = force + apf.improved_repulsive_force(                              # eqs. (15)-(16)
            q, goal, scene.field_points, ap, scene.field_weights, check=False)
        if robot_velocity is not None:
            force = force + apf.velocity_repulsion(                                 # eq. (17)
                q, robot_velocity, scene.field_points, scene.field_velocities, ap,
                scene.field_weights, check=False)
        return force

    def _rollout(self, q, target, scene, first_direction):
        """Field rollout from ``q`` with the adaptive step (for display)."""
        p = self.params
        plan = [q.copy()]
        point = q.copy()
        direction = first_direction
        for _ in range(ROLLOUT_STEPS):
            if direction is None:
                break
            if len(scene.field_points):
                d = scene.field_points - point
                near = math.sqrt(float(np.min(np.einsum('ij,ij->i', d, d)))) - p.robot_radius
            else:
                near = math.inf
            step = apf.adaptive_step(near, p.max_speed, p.apf)                     # eq. (18)
            step = min(max(step, MIN_STEP_FRACTION * p.apf.l0), ROLLOUT_MAX_STEP)
            remaining = math.hypot(*(target - point))
            point = point + direction * min(step, remaining)
            plan.append(point)
            if remaining <= step:
                break
            force = self._force(point, target, scene, None)
            norm = math.hypot(force[0], force[1])
            direction = force / norm if norm > FORCE_EPS else None
        return np.array(plan)

    # .. sub-goals ....................................................................

    def _advance_sub_goal(self, q, scene):
        """Pass key nodes reached (within goal_tolerance) or behind a visible later one.

        A later key node (up to :data:`MAX_VISIBILITY_CHECKS` ahead, within
        ``visibility_range``) is visible when no obstacle point lies within
        ``robot_radius + sight_clearance`` of the straight line to it; the
        farthest visible one becomes the sub-goal. A key node is never passed
        merely for being near: cutting a corner toward one that is not
        visible would drive into the corner.
        """
        if not self.use_key_nodes:
            self._index = len(self._key_nodes) - 1
            return
        p = self.params
        last = len(self._key_nodes) - 1
        for _ in range(len(self._key_nodes)):  # bounded: each pass advances or stops
            if self._index >= last:
                break
            if math.hypot(*(self._key_nodes[self._index] - q)) > p.goal_tolerance:
                break
            self._anchor = self._key_nodes[self._index].copy()
            self._index += 1
        if self._index >= last:
            return
        later = np.arange(self._index + 1, min(last, self._index + MAX_VISIBILITY_CHECKS) + 1)
        ends = self._key_nodes[later]
        in_range = np.hypot(ends[:, 0] - q[0], ends[:, 1] - q[1]) <= p.visibility_range
        if not np.any(in_range):
            return
        half = p.robot_radius + p.sight_clearance
        clear = _segments_clear(q, ends[in_range], scene.all_points, half)
        if len(scene.circle_centres):
            clear &= _segments_clear(q, ends[in_range], scene.circle_centres,
                                     half + scene.circle_radii)
        if np.any(clear):
            self._index = int(later[in_range][np.nonzero(clear)[0][-1]])
            self._anchor = q.copy()

    # .. stuck detection and escape ...................................................

    def _no_progress(self, t, distance):
        """Record the distance to the sub-goal; True when the window shows no net progress."""
        p = self.params
        self._history.append((t, distance))
        if not _window_covered(self._history, t, p.stuck_window):
            return False
        return self._history[0][1] - distance < p.stuck_progress

    def _on_stuck(self, obs, q, target_distance, scene):
        """Count the event and take the next escape step; returns a failure reason or None."""
        p = self.params
        self.stuck_events += 1
        self._history.clear()
        where = f'({q[0]:.2f}, {q[1]:.2f})'
        if not self.escape:
            return (f'stuck in a local minimum of the {self.field} potential field at {where} '
                    f'(net progress below {p.stuck_progress} m in {p.stuck_window} s) '
                    'and this controller has no escape')
        if self._episode is None:
            self._episode = _Episode(obs.time, self._index, target_distance)
        episode = self._episode
        LOGGER.info('local minimum at %s (event %d); escaping', where, self.stuck_events)
        if self.use_key_nodes and not episode.skipped and self._index < len(self._key_nodes) - 1:
            self._index += 1  # the paper's escape: aim at the next A* key node
            self._anchor = q.copy()
            episode.skipped = True
            episode.index = self._index
            return None
        if self._replan is not None and episode.replans < MAX_REPLANS_PER_EPISODE:
            episode.replans += 1
            if self._replan_now(obs, q, scene):
                episode.index = self._index
                return None
        key = self._index
        self._best_hit[key] = min(self._best_hit.get(key, math.inf), target_distance)
        self._follow = _Follow()
        return None

    def _replan_now(self, obs, q, scene):
        """Ask for a global plan around everything seen so far; True on success."""
        self._remember(obs, scene, force=True)
        goal = self._key_nodes[-1].copy()
        try:
            path, key_nodes = self._replan(q.copy(), goal, self._memory.copy())
            path = _as_path(path, 'replanned path')
            key_nodes = _as_path(key_nodes, 'replanned key_nodes')
        except PlanningError as err:
            LOGGER.info('replanning from (%.2f, %.2f) failed: %s', q[0], q[1], err)
            return False
        self._path, self._key_nodes = path, key_nodes
        self._index = 0
        self._anchor = q.copy()
        self._best_hit = {}
        self._history.clear()
        self._advance_sub_goal(q, scene)
        self.replans += 1
        LOGGER.info('replanned around %d remembered obstacle points', len(self._memory))
        return True

    def _follow_direction(self, q, target, scene):
        """Boundary-following direction (unit vector), choosing the side on first use.

        The wall normal is the ``1/rho^2``-weighted mean direction from the
        points within :data:`FOLLOW_BAND` of the nearest one to the robot; the
        direction is the tangent on the chosen side, turned toward or away from
        the wall in proportion to the clearance error. With no point within
        ``rho0`` the last nearest point stands for the wall (turning round a
        convex corner). The side is the one whose tangent points more toward
        the sub-goal when following starts.
        """
        p = self.params
        points, weights = scene.field_points, scene.field_weights
        follow = self._follow
        in_range = np.zeros(0, bool)
        if len(points):
            diff = q - points
            dist = np.hypot(diff[:, 0], diff[:, 1])
            rho = np.maximum(dist - p.robot_radius, apf.MIN_DISTANCE)
            nearest = int(np.argmin(rho))
            in_range = rho < p.apf.rho0
        if np.any(in_range):
            rho_min = float(rho[nearest])
            band = in_range & (rho <= rho_min + FOLLOW_BAND)
            unit = diff[band] / np.maximum(dist[band], apf.DIRECTION_EPS)[:, None]
            normal = (weights[band] / rho[band]**2) @ unit
            follow.wall_point = points[nearest].copy()
        elif follow.wall_point is not None:
            normal = q - follow.wall_point
            rho_min = max(math.hypot(normal[0], normal[1]) - p.robot_radius, apf.MIN_DISTANCE)
        else:
            return None
        norm = math.hypot(normal[0], normal[1])
        if norm < apf.DIRECTION_EPS:
            return None
        normal = normal / norm
        ccw = np.array([-normal[1], normal[0]])
        if follow.side == 0:
            follow.side = 1 if float(ccw @ (target - q)) >= 0.0 else -1
        error = max(-1.0, min(1.0, (rho_min - p.wall_distance) / p.wall_distance))
        direction = follow.side * ccw - WALL_GAIN * error * normal
        return direction / math.hypot(direction[0], direction[1])

    def _may_leave(self, q, target, scene):
        """Bug2-like leave test: closer than every earlier hit, and a free line to the target."""
        p = self.params
        distance = math.hypot(*(target - q))
        if distance >= self._best_hit.get(self._index, math.inf) - p.stuck_progress:
            return False
        reach = min(distance, p.apf.rho0 + p.robot_radius)
        if reach <= apf.DIRECTION_EPS:
            return True
        end = q + (target - q) * (reach / distance)
        half = p.robot_radius + p.safety_distance
        return bool(_segments_clear(q, end[None, :], scene.field_points, half)[0])

    # .. main step .....................................................................

    def compute(self, obs):
        """One control step.

        Parameters
        ----------
        obs : Observation

        Returns
        -------
        Command
            ``'no_path'`` before a plan; ``'arrived'`` inside the goal
            tolerance (braking to rest); ``'failed'`` after an escape timed out
            (or at the first minimum without escape), until a new path or a
            reset; otherwise ``'moving'``, or ``'stuck_escaping'`` while an
            escape episode is open.

        Raises
        ------
        InvalidInput
            If ``obs`` is not an Observation.
        """
        if not isinstance(obs, Observation):
            raise InvalidInput('compute needs an Observation')
        p = self.params
        if self._key_nodes is None:
            return self._stop(obs, 'no_path', 'no global plan has been set')
        if self._failure is not None:
            return self._stop(obs, 'failed', self._failure)
        if self._last_time is not None and obs.time < self._last_time:
            self._history.clear()  # the clock went back (simulation reset)
        self._last_time = obs.time
        q = obs.pose[:2]
        goal = self._key_nodes[-1]
        goal_distance = math.hypot(*(goal - q))
        if goal_distance <= p.goal_tolerance:
            return self._stop(obs, 'arrived', sub_goal=goal.copy())
        scene = self._scene(obs)
        self._remember(obs, scene)

        before = self._index
        self._advance_sub_goal(q, scene)
        if self._index != before:
            self._history.clear()
            self._follow = None
            if self._episode is not None and self._index > self._episode.index:
                self._episode = None  # passed the key node we escaped to
        target = self._key_nodes[self._index]
        target_distance = math.hypot(*(target - q))

        if self._episode is not None and obs.time - self._episode.start > p.escape_time_limit:
            reason = (f'still stuck after {p.escape_time_limit:g} s of escape near '
                      f'({q[0]:.2f}, {q[1]:.2f}), {goal_distance:.2f} m from the goal')
            return self._fail(obs, reason, target.copy())

        direction = None
        if self._follow is not None:
            if self._may_leave(q, target, scene):
                self._follow = None
                self._history.clear()
            else:
                direction = self._follow_direction(q, target, scene)
                if direction is None:  # nothing around: head for the sub-goal
                    direction = (target - q) / max(target_distance, apf.DIRECTION_EPS)
        if self._follow is None:
            episode = self._episode
            if (episode is not None and not episode.skipped and episode.replans == 0
                    and target_distance < episode.target_distance - p.stuck_progress):
                self._episode = None  # progress again after boundary following
            if self._no_progress(obs.time, target_distance):
                reason = self._on_stuck(obs, q, target_distance, scene)
                if reason is not None:
                    return self._fail(obs, reason, target.copy())
                target = self._key_nodes[self._index]
                target_distance = math.hypot(*(target - q))
                if self._follow is not None:
                    direction = self._follow_direction(q, target, scene)

        yaw = obs.pose[2]
        if self._follow is None:
            robot_velocity = obs.velocity[0] * np.array([math.cos(yaw), math.sin(yaw)])
            force = self._force(q, target, scene,
                                robot_velocity if self.field == 'improved' else None)
            norm = math.hypot(force[0], force[1])
            direction = force / norm if norm > FORCE_EPS else None
            plan = self._rollout(q, target, scene, direction)
        elif direction is not None:
            plan = np.vstack([q, q + p.apf.l0 * direction])
        else:
            plan = q[None, :].copy()

        status = 'stuck_escaping' if self._episode is not None else 'moving'
        if direction is None:  # an exact minimum: stop; the stuck detector takes over
            v, w = self._limit(0.0, 0.0, obs)
            return Command(v, w, status, sub_goal=target.copy(), local_plan=plan)
        step = apf.adaptive_step(scene.nearest_ahead, p.max_speed, p.apf)             # eq. (18)
        v_cap = min(p.max_speed * min(1.0, max(MIN_STEP_FRACTION, step / p.apf.l0)),
                    p.approach_gain * goal_distance)
        clearance = p.robot_radius + p.safety_distance
        gap = min(
            _front_gap(obs.pose, scene.all_points, np.zeros(len(scene.all_points)), clearance),
            _front_gap(obs.pose, scene.circle_centres, scene.circle_radii, clearance))
        v_cap = min(v_cap, _braking_speed(gap, p.max_accel, p.control_period))
        v, w = self._steer(math.atan2(direction[1], direction[0]), v_cap, obs)
        return Command(v, w, status, sub_goal=target.copy(), local_plan=plan)


# -- path tracker (baseline) ----------------------------------------------------------

class PathTracker(_Base):
    """Pure-pursuit tracking of the global path with no obstacle avoidance.

    The paper's baseline ("A* cannot avoid dynamic obstacles"): obstacles in
    the observation are ignored. Blocked (moving less than ``stuck_progress``
    within ``stuck_window``) means failed.

    Parameters
    ----------
    params : FollowerParams
    """

    def _clear_state(self):
        super()._clear_state()
        p = self.params
        self._progress = 0
        self._history = collections.deque(
            maxlen=int(math.ceil(4.0 * p.stuck_window / p.control_period)) + 16)

    def set_path(self, path, key_nodes):
        """Take a global plan (see :meth:`FieldFollower.set_path`); the path is tracked.

        The path is resampled every :data:`TRACK_SPACING` metres (a plan may
        be just its corners) and ends at ``key_nodes[-1]``.
        """
        super().set_path(path, key_nodes)
        path = self._path
        if math.hypot(*(path[-1] - self._key_nodes[-1])) > 1e-9:
            path = np.vstack([path, self._key_nodes[-1]])
        self._dense = _resample(path, TRACK_SPACING)

    def compute(self, obs):
        """One control step (see :meth:`FieldFollower.compute`)."""
        if not isinstance(obs, Observation):
            raise InvalidInput('compute needs an Observation')
        p = self.params
        if self._key_nodes is None:
            return self._stop(obs, 'no_path', 'no global plan has been set')
        if self._failure is not None:
            return self._stop(obs, 'failed', self._failure)
        q = obs.pose[:2]
        goal = self._key_nodes[-1]
        goal_distance = math.hypot(*(goal - q))
        if goal_distance <= p.goal_tolerance:
            return self._stop(obs, 'arrived', sub_goal=goal.copy())
        window = self._dense[self._progress:self._progress + TRACK_SEARCH_WINDOW]
        self._progress += int(np.argmin(np.hypot(window[:, 0] - q[0], window[:, 1] - q[1])))
        ahead = self._dense[self._progress:]
        far = np.nonzero(np.hypot(ahead[:, 0] - q[0], ahead[:, 1] - q[1]) >= p.lookahead)[0]
        carrot = ahead[far[0]] if len(far) else goal
        self._history.append((obs.time, q.copy()))
        if _window_covered(self._history, obs.time, p.stuck_window):
            if math.hypot(*(q - self._history[0][1])) < p.stuck_progress:
                self.stuck_events += 1
                return self._fail(obs, f'blocked at ({q[0]:.2f}, {q[1]:.2f}): moved less than '
                                       f'{p.stuck_progress:g} m in {p.stuck_window:g} s, and path '
                                       'tracking has no obstacle avoidance', carrot.copy())
        offset = carrot - q
        v, w = self._steer(math.atan2(offset[1], offset[0]), p.approach_gain * goal_distance, obs)
        plan = np.vstack([q, ahead[:ROLLOUT_STEPS * 4:4]])
        return Command(v, w, 'moving', sub_goal=carrot.copy(), local_plan=plan)


# -- replanning -------------------------------------------------------------------------

class GridReplanner:
    """Global replanning on the known map with remembered obstacle points added.

    A ``replan`` callable for :class:`FieldFollower`: the points (obstacles
    the robot has seen) are burnt into a copy of the map as occupied cells,
    then :class:`~fusion_planner.core.planner.GlobalPlanner` plans as usual
    (inflation, improved A*, refinement).

    Parameters
    ----------
    grid : GridMap
        The known map.
    config : PlannerConfig, optional
        Planner configuration (its ``robot_radius`` inflates the new cells
        too).

    Raises
    ------
    InvalidInput
        If ``grid`` is not a GridMap or ``config`` not a PlannerConfig.
    """

    def __init__(self, grid, config=None):
        if not isinstance(grid, GridMap):
            raise InvalidInput('GridReplanner needs a GridMap')
        if config is not None and not isinstance(config, PlannerConfig):
            raise InvalidInput('GridReplanner config must be a PlannerConfig')
        self.grid = grid
        self.config = config or PlannerConfig()

    def __call__(self, start, goal, obstacle_points):
        """Plan from ``start`` to ``goal`` [m] around the map and ``obstacle_points`` (M, 2) [m].

        Points within ``robot_radius`` plus one cell of the start or the goal
        are left out: the robot stands there, so they cannot be static
        obstacles (a person passing by, noise). So are points the map already
        explains (within :data:`KNOWN_POINT_CELLS` cells of an occupied
        cell): a laser hit on a wall's face may fall in the free cell beside
        it, and burning that cell in would narrow every door by a cell.

        Returns
        -------
        path : ndarray, float64, shape (N, 2)
        key_nodes : ndarray, float64, shape (K, 2)

        Raises
        ------
        PlanningError
            Any planner outcome (no path, start or goal blocked ...).
        """
        grid = self.grid
        start = np.asarray(start, dtype=float)
        goal = np.asarray(goal, dtype=float)
        points = np.asarray(obstacle_points, dtype=float).reshape(-1, 2)
        points = points[np.all(np.isfinite(points), axis=1)]
        occupied = grid.occupied.copy()
        if len(points):
            keep_clear = self.config.robot_radius + grid.resolution
            keep = ((np.hypot(*(points - start).T) > keep_clear)
                    & (np.hypot(*(points - goal).T) > keep_clear)
                    & (grid.clearance_at(points) > KNOWN_POINT_CELLS * grid.resolution))
            cells = grid.cell_of(points[keep])
            cells = cells[grid.contains(cells)]
            occupied[cells[:, 0], cells[:, 1]] = True
        known = GridMap(occupied, grid.resolution, grid.origin)
        plan = GlobalPlanner(known, self.config).plan(start, goal)
        return plan.path, plan.key_nodes


def make_controller(name, params, replan=None):
    """Build a controller by name.

    Parameters
    ----------
    name : str
        One of :data:`CONTROLLER_NAMES`.
    params : FollowerParams
    replan : callable, optional
        Global replanner for the ``'fusion'`` escape (see
        :class:`FieldFollower`, :class:`GridReplanner`); ignored by the
        other controllers.

    Returns
    -------
    Controller

    Raises
    ------
    InvalidInput
        If the name is unknown or ``params`` is not a FollowerParams.
    """
    if name == 'fusion':
        return FieldFollower(params, field='improved', use_key_nodes=True, escape=True,
                             replan=replan)
    if name == 'apf':
        return FieldFollower(params, field='improved', use_key_nodes=False, escape=True)
    if name == 'classic-apf':
        return FieldFollower(params, field='classic', use_key_nodes=False, escape=False,
                             predict=False)
    if name == 'astar-track':
        return PathTracker(params)
    raise InvalidInput(f'unknown controller {name!r}; choose one of {", ".join(CONTROLLER_NAMES)}')
