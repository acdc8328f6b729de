"""What every local controller shares: parameters, observation, command, command shaping.

:class:`FollowerParams` holds every number of the controllers,
:class:`Observation` what they see at one instant, :class:`Command` what they
answer; :class:`ControllerBase` stores the plan and shapes commands: heading
control, the velocity and acceleration limits, braking to a stop, latched
failure. :class:`WindowHistory` is the sliding time window of the stuck
tests.

Examples
--------
>>> history = WindowHistory(window=1.0, period=0.5)
>>> [history.push(t, t * 10.0) for t in (0.0, 0.5, 1.0, 1.5)]
[None, None, 0.0, 5.0]
"""

import collections
import logging
import math
from dataclasses import dataclass, field, replace
from typing import Protocol

import numpy as np

from fusion_planner.core.local_planning.apf import ApfParams
from fusion_planner.core.errors import InvalidInput
from fusion_planner.core.local_planning.local_geometry import wrap_angle

LOGGER = logging.getLogger(__name__)

#: Longest global path [m] a controller takes (its route is resampled every
#: few centimetres; no map a robot plans on is a hundred kilometres across).
MAX_PATH_LENGTH_M = 100_000.0

#: Values of :attr:`Command.status`.
STATUSES = ('moving', 'arrived', 'stuck_escaping', 'failed', 'no_path')

#: Points of :attr:`Command.local_plan` (the display rollout).
LOCAL_PLAN_POINTS = 6


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
        Largest forward speed [m/s], > 0.
    max_reverse_speed : float
        Largest reverse speed [m/s], >= 0 (0: never reverse), capped by
        ``max_speed`` (:meth:`reverse_speed`). The controllers reverse only
        to evade a moving obstacle: backing away from a person who walks at
        the robot gets clear only when it is faster than the person.
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
        Longest time without progress toward the goal [s], > 0, before
        status ``'failed'`` (see
        :mod:`~fusion_planner.core.local_planning.progress`; a field
        controller without escape fails at its first local minimum; the
        first plan round people for a goal restarts this time, and time in
        which the evasion drove the robot farther from the goal does not
        count).
    robot_radius : float
        Robot radius [m], >= 0.
    prediction_horizon : float
        How far ahead tracked obstacles are predicted [s], >= 0 (0: only
        their current position, as in the paper).
    heading_gain : float
        Turn rate per radian of heading error [1/s], > 0.
    route_heading_gain : float
        The same for a route follower (fusion) [1/s], > 0, at most
        ``1 / (4 control_period)`` (:meth:`route_gain`): a route between
        posts leaves the robot a few centimetres on either side, and a slow
        heading response lets it swing across them.
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
    max_reverse_speed: float = 1.0
    max_accel: float = 1.0
    max_omega: float = 2.0
    max_alpha: float = 4.0
    goal_tolerance: float = 0.15
    lookahead: float = 1.5
    control_period: float = 0.05
    stuck_window: float = 4.0
    stuck_progress: float = 0.15
    escape_time_limit: float = 30.0
    robot_radius: float = 0.2
    prediction_horizon: float = 2.0
    heading_gain: float = 2.5
    route_heading_gain: float = 5.0
    approach_gain: float = 0.8
    safety_distance: float = 0.02
    sight_clearance: float = 0.3
    wall_distance: float = 0.35
    point_spacing: float = 0.1
    visibility_range: float = 4.0

    def reverse_speed(self):
        """The fastest reverse speed [m/s]: ``max_reverse_speed``, at most ``max_speed``."""
        return min(self.max_reverse_speed, self.max_speed)

    def route_gain(self):
        """The route follower's heading gain [1/s]: at most ``0.25 / control_period``.

        ``route_heading_gain``, bounded because a proportional heading loop
        whose command acts one period late (``e[n+1] = e[n] - gain * period *
        e[n-1]``) is critically damped at ``gain * period = 1/4`` and
        oscillates above it.
        """
        return min(self.route_heading_gain, 0.25 / self.control_period)

    def __post_init__(self):
        if not isinstance(self.apf, ApfParams):
            raise InvalidInput(
                f'FollowerParams.apf must be an ApfParams, got {type(self.apf).__name__}')
        for name in ('max_speed', 'max_accel', 'max_omega', 'max_alpha', 'goal_tolerance',
                     'lookahead', 'control_period', 'stuck_window', 'stuck_progress',
                     'escape_time_limit', 'heading_gain', 'route_heading_gain', 'approach_gain',
                     'wall_distance', 'point_spacing', 'visibility_range'):
            _check_number(getattr(self, name), name)
        for name in ('max_reverse_speed', 'robot_radius', 'prediction_horizon', 'safety_distance',
                     'sight_clearance'):
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
    tentative : ndarray, float64, shape (T, 5), optional
        The same for objects that seem to move but are not confirmed as
        moving (a scan tracker's tentative movers); default none. A
        controller checks its commands against their predicted motion but
        does not treat them as people.
    turn_stds : ndarray, float64, shape (K,), optional
        How much each tracked obstacle turns: its heading diffusion
        [rad / sqrt(s)] (a scan tracker's estimate); NaN or none: unknown.
    commanded : ndarray, float64, shape (2,), optional
        The ``v`` [m/s] and ``omega`` [rad/s] last commanded to the robot;
        none: unknown. Braking is bounded from it when it is nearer
        standstill than the measured speed (see :meth:`ControllerBase._limit`).

    Raises
    ------
    InvalidInput
        If a shape is wrong, the pose, velocity or time is not finite, or a
        tracked radius or a turn std is negative.
    """

    pose: np.ndarray
    velocity: np.ndarray
    obstacle_points: np.ndarray
    tracked: np.ndarray
    time: float
    tentative: np.ndarray = None
    turn_stds: np.ndarray = None
    commanded: np.ndarray = None

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
        tracked = _circles(self.tracked, 'tracked')
        tentative = _circles(np.zeros((0, 5)) if self.tentative is None else self.tentative,
                             'tentative')
        turn_stds = np.full(len(tracked), np.nan) if self.turn_stds is None \
            else np.asarray(self.turn_stds, dtype=float)
        if turn_stds.shape != (len(tracked),) or np.any(turn_stds < 0):
            raise InvalidInput(f'Observation.turn_stds must be (K,) = ({len(tracked)},) values '
                               f'>= 0 or NaN, got {self.turn_stds!r}')
        commanded = None if self.commanded is None else np.asarray(self.commanded, dtype=float)
        if commanded is not None and (commanded.shape != (2,)
                                      or not np.all(np.isfinite(commanded))):
            raise InvalidInput(f'Observation.commanded must be a finite (2,) v, omega or None, '
                               f'got {self.commanded!r}')
        if not (isinstance(self.time, (int, float, np.floating)) and math.isfinite(self.time)):
            raise InvalidInput(
                f'Observation.time must be a finite number of seconds, got {self.time!r}')
        object.__setattr__(self, 'pose', pose)
        object.__setattr__(self, 'velocity', velocity)
        object.__setattr__(self, 'obstacle_points', points)
        object.__setattr__(self, 'tracked', tracked)
        object.__setattr__(self, 'tentative', tentative)
        object.__setattr__(self, 'turn_stds', turn_stds)
        object.__setattr__(self, 'commanded', commanded)
        object.__setattr__(self, 'time', float(self.time))


def _circles(rows, name):
    """``rows`` as a ``(K, 5)`` float array of ``x, y, vx, vy, radius``, checked."""
    circles = np.asarray(rows, dtype=float)
    circles = circles.reshape(0, 5) if circles.size == 0 else circles
    if circles.ndim != 2 or circles.shape[1] != 5:
        raise InvalidInput(f'Observation.{name} must have shape (K, 5), got {circles.shape}')
    if np.any(circles[:, 4] < 0):
        raise InvalidInput(f'Observation.{name} radii must be >= 0')
    return circles


@dataclass(frozen=True)
class Command:
    """A velocity command and what the controller is doing.

    Attributes
    ----------
    v : float
        Forward speed [m/s], robot frame; negative (reverse) only while
        evading a moving obstacle.
    omega : float
        Turn rate [rad/s].
    status : str
        One of :data:`STATUSES`.
    reason : str
        A sentence when ``status`` is ``'failed'`` or ``'no_path'``.
    sub_goal : ndarray, float64, shape (2,) or None
        Current sub-goal [m], map frame.
    local_plan : ndarray, float64, shape (L, 2) or None
        Short rollout of the steering field from the robot [m], for display;
        None from a controller whose ``display_plan`` is off.
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
    no_path_proven_at: float
    display_plan: bool

    def set_path(self, path: np.ndarray, key_nodes: np.ndarray) -> None:
        """Take a global plan ``(N, 2)`` [m] and its key nodes ``(K, 2)`` [m]."""

    def reset(self) -> None:
        """Forget the plan and every internal state."""

    def compute(self, obs: Observation) -> Command:
        """One control step."""


# -- shared command shaping ---------------------------------------------------------

def check_followable(points, what):
    """``points`` (N, 2) [m], finite, if no longer than :data:`MAX_PATH_LENGTH_M`.

    Raises
    ------
    InvalidInput
        Naming ``what``, if the polyline is longer (it is resampled every few
        centimetres by the controllers).
    """
    length = float(np.sum(np.hypot(*np.diff(points, axis=0).T))) if len(points) > 1 else 0.0
    if not length <= MAX_PATH_LENGTH_M:
        raise InvalidInput(f'{what}: a path of {length:.3g} m is longer than the '
                           f'{MAX_PATH_LENGTH_M:.0f} m a robot follows')
    return points


def as_path(value, name):
    """``value`` as a non-empty, finite ``(N, 2)`` float64 array [m].

    Raises
    ------
    InvalidInput
        Naming ``name``, if the shape is wrong or a value is not finite.
    """
    arr = np.asarray(value, dtype=float)
    if arr.ndim != 2 or arr.shape[1] != 2 or len(arr) == 0:
        raise InvalidInput(
            f'{name} must be a non-empty (N, 2) array of metres, got shape {arr.shape}')
    if not np.all(np.isfinite(arr)):
        raise InvalidInput(f'{name} must be finite')
    return arr


class WindowHistory:
    """Values over a sliding time window: what a value was ``window`` seconds ago.

    Parameters
    ----------
    window : float
        [s], > 0.
    period : float
        Expected time between pushes [s], > 0 (sizes the buffer).
    """

    def __init__(self, window, period):
        self.window = window
        self._entries = collections.deque(maxlen=int(math.ceil(4.0 * window / period)) + 16)

    def clear(self):
        """Forget every value."""
        self._entries.clear()

    def push(self, t, value):
        """Record ``value`` at time ``t`` [s]; return the value of ``window`` ago, or None.

        The value returned is the newest one at least ``window`` old
        (comparing against the window this way is immune to rounding of
        summed time steps); None while the history does not span the window.
        """
        entries = self._entries
        entries.append((t, value))
        while len(entries) >= 2 and t - entries[1][0] >= self.window:
            entries.popleft()
        return entries[0][1] if t - entries[0][0] >= self.window else None


class ControllerBase:
    """Plan storage, velocity limits, stop and command shaping shared by the controllers.

    Parameters
    ----------
    params : FollowerParams

    Attributes
    ----------
    stuck_events : int
        Local-minimum detections since the last reset.
    no_path_proven_at : float or None
        Observation time [s] at which a replan proved the goal unreachable,
        None until then (and after a reset).
    display_plan : bool
        Whether commands carry a :attr:`Command.local_plan` (default True).
        Nothing the controller does depends on it; the field followers'
        display rollout is about a quarter of their step, so a user with
        nobody to show it to turns it off (the local_planner node while
        ``local_plan`` has no subscriber, the simulation always).

    Raises
    ------
    InvalidInput
        If ``params`` is not a FollowerParams.
    """

    def __init__(self, params):
        if not isinstance(params, FollowerParams):
            raise InvalidInput('a controller needs a FollowerParams')
        self.params = params
        self.stuck_events = 0
        self.no_path_proven_at = None
        self.display_plan = True
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
            If an array is empty, not (N, 2) or not finite, or the path is
            longer than :data:`MAX_PATH_LENGTH_M`.
        """
        self._path = check_followable(as_path(path, 'path'), 'path')
        self._path_box = (self._path.min(axis=0), self._path.max(axis=0))
        self._key_nodes = as_path(key_nodes, 'key_nodes')
        self._clear_state()

    def reset(self):
        """Forget the plan, the stuck history, the failure, the stuck count and the proof."""
        self._path = None
        self._key_nodes = None
        self.stuck_events = 0
        self.no_path_proven_at = None
        self._clear_state()

    def _clear_state(self):
        self._failure = None

    def _limit(self, v_des, omega_des, obs, v_min=0.0):
        """The command nearest ``(v_des, omega_des)`` [m/s, rad/s] within the limits.

        Acceleration limits from the measured velocity, then
        ``v_min <= v <= max_speed`` and ``|omega| <= max_omega``; a reverse
        motion (an evasion, see :mod:`fusion_planner.core.local_planning.evasion`) below
        ``v_min`` is braked at ``max_accel``, and never commanded faster than
        ``max_speed`` whatever the measured velocity says.

        Braking starts from the commanded speed (``obs.commanded``) when
        that is nearer standstill than the measured one: wheel odometry
        that overstates the speed (a wheel-radius error of 5 % is 0.04 m/s
        at 0.8 m/s, most of the 0.05 m/s a period may shed) would otherwise
        hold the brakes back; the robot's own limits bound what it does
        (Nav2's velocity smoother limits from the last command by default
        for the same reason).
        """
        p = self.params
        v0, w0 = obs.velocity
        dv = p.max_accel * p.control_period
        dw = p.max_alpha * p.control_period
        brake_from = v0
        if obs.commanded is not None:
            brake_from = min(max(obs.commanded[0], 0.0), v0) if v0 >= 0.0 \
                else max(min(obs.commanded[0], 0.0), v0)
        if v0 >= 0.0:
            v = min(max(v_des, brake_from - dv), v0 + dv)
        else:
            v = min(max(v_des, v0 - dv), brake_from + dv)
        w = min(max(omega_des, w0 - dw), w0 + dw)
        v = min(max(v, min(v_min, v0 + dv), -p.max_speed), p.max_speed)
        w = min(max(w, -p.max_omega), p.max_omega)
        return float(v), float(w)

    def _checked_stop(self, obs):
        """Validate ``obs``; the stop command when there is no path or a failure, else None.

        Raises
        ------
        InvalidInput
            If ``obs`` is not an Observation.
        """
        if not isinstance(obs, Observation):
            raise InvalidInput('compute needs an Observation')
        if self._key_nodes is None:
            return self._stop(obs, 'no_path', 'no global plan has been set')
        if self._failure is not None:
            return self._stop(obs, 'failed', self._failure)
        lower, upper = self._path_box
        off = math.hypot(*np.maximum(np.maximum(lower - obs.pose[:2], obs.pose[:2] - upper), 0.0))
        if off > MAX_PATH_LENGTH_M:   # no route back can be followed (or resampled)
            return self._fail(obs, f'the robot is {off:.3g} m away from its plan')
        return None

    def _stop(self, obs, status, reason='', sub_goal=None):
        """Brake toward (0, 0) within the acceleration limits."""
        v, w = self._limit(0.0, 0.0, obs)
        return Command(v=v, omega=w, status=status, reason=reason, sub_goal=sub_goal,
                       local_plan=obs.pose[None, :2].copy() if self.display_plan else None)

    def _fail(self, obs, reason, sub_goal=None):
        """Latch the failure ``reason`` (until a new path or a reset) and brake."""
        self._failure = reason
        LOGGER.warning('controller failed: %s', reason)
        return self._stop(obs, 'failed', reason, sub_goal)

    def _steer(self, heading, v_cap, obs, gain=None, error=None):
        """Heading control toward ``heading`` [rad] with forward speed at most ``v_cap``.

        ``gain`` [1/s] is the turn rate per radian of heading error
        (default ``heading_gain``); ``error`` [rad] the heading error to turn
        through (default ``heading`` less the yaw, wrapped; beyond pi to
        turn the long way round). Returns the target ``(v, omega)``
        [m/s, rad/s], not yet within the one-step limits (:meth:`_limit`):
        a check of where the command leads (the evasion) must roll out what
        the robot is steered towards, not one step of the ramp to it.
        """
        p = self.params
        gain = p.heading_gain if gain is None else gain
        error = wrap_angle(heading - obs.pose[2]) if error is None else error
        turn = min(gain * abs(error), math.sqrt(2.0 * p.max_alpha * abs(error)),
                   p.max_omega)
        omega = math.copysign(turn, error)
        v = min(p.max_speed, v_cap) * max(0.0, math.cos(error))**2
        return v, omega
