"""Artificial potential fields: the classic field and the paper's improved one.

Implements section 2 of the paper ("Robot Path Planning Based on Improved A*
Algorithm and Artificial Potential Field Method"): the attractive field of
eqs. (9)-(10), the classic repulsive field of eqs. (11)-(12) and their sum
(eqs. (13)-(14)), the goal-distance-scaled repulsion of eqs. (15)-(16), the
robot-velocity repulsion of eq. (17) and the adaptive step of eq. (18).
Reference for eqs. (15)-(16): S. S. Ge and Y. J. Cui, "New potential
functions for mobile robot path planning", IEEE Trans. Robotics and
Automation 16(5), 2000.

Conventions
-----------
- Positions are ``(2,)`` float64 [m] in the map frame; obstacles are point
  sets ``(M, 2)`` [m] (laser endpoints, sampled boundaries, the nearest
  surface points of tracked obstacles). Every field is one numpy pass over
  all points; ``M = 0`` gives a zero force.
- Forces are ``(2,)`` float64 vectors in the map frame. Their unit is
  arbitrary (only directions and ratios matter to a follower); the gains
  carry whatever unit makes each equation a force.
- The obstacle distance ``rho(q, q0)`` is measured from the robot's
  **boundary**: ``rho = |q - q0| - robot_radius`` (``robot_radius = 0``
  gives the paper's point robot). It is floored at :data:`MIN_DISTANCE`, so a
  point on or inside the robot gives a large but finite force and never NaN.
  A point exactly at ``q`` has no direction and contributes nothing.
- Each point may carry a weight (default 1): a follower uses it to make a
  sparse sample of a boundary (a tracked person reduced to one point) count
  like a dense one.

Examples
--------
>>> import numpy as np
>>> params = ApfParams(k_att=1.0, k_rep=0.1, rho0=1.0)
>>> q, goal = np.array([0.0, 0.0]), np.array([2.0, 0.0])
>>> attractive_force(q, goal, params).tolist()
[2.0, 0.0]
>>> wall = np.array([[0.0, 0.5], [0.1, 0.5]])
>>> bool(improved_repulsive_force(q, goal, wall, params)[1] < 0)  # pushed away (-y)
True
>>> improved_repulsive_force(goal, goal, wall + [2.0, 0.0], params).tolist()  # at the goal
[0.0, 0.0]
"""

import logging
import math
from dataclasses import dataclass

import numpy as np

from fusion_planner.core.errors import InvalidInput

LOGGER = logging.getLogger(__name__)

#: Smallest obstacle distance rho used in the fields [m]: guards 1/rho and
#: 1/rho^2 against a point on (or inside) the robot.
MIN_DISTANCE = 1e-3

#: Below this length [m] a difference vector has no direction (a point at q,
#: the robot at the goal): its unit vector is taken as zero.
DIRECTION_EPS = 1e-12

#: Cap on the exponent of eq. (17): exp(1/rho - 1/rho0) overflows float64 for
#: rho below ~1.4 mm; beyond this exponent the term is saturated.
MAX_VELOCITY_EXPONENT = 50.0


def _is_number(value):
    return isinstance(value, (int, float, np.floating, np.integer)) \
        and not isinstance(value, bool) and math.isfinite(value)


@dataclass(frozen=True)
class ApfParams:
    """Coefficients of the potential fields, named as in the paper.

    Attributes
    ----------
    k_att : float
        Attraction gain gamma of eqs. (9)-(10) [force/m], > 0.
    k_rep : float
        Repulsion gain k of eqs. (11)-(12) and (15)-(16) [force m^3 for the
        classic field, force m^(3-n) for the improved one], >= 0.
    rho0 : float
        Influence distance rho0 of eqs. (11)-(12), (15)-(17) [m], > 0: points
        farther than this (from the robot boundary) exert no force.
    n : float
        Goal-distance exponent of eqs. (15)-(16), > 0. With ``n > 1`` both
        improved components vanish at the goal; with ``n = 1`` the second
        one stays finite and points at the goal; with ``n < 1`` it grows near
        the goal (still pointing at it).
    mu : float
        Velocity gain mu of eq. (17) [force s/m], >= 0.
    step_alpha, step_beta : float
        Proportional factors alpha and beta of eq. (18) [s/m^2], > 0: the
        step is ``alpha * l0 * d * v`` closer than ``d_min`` and
        ``beta * l0 * d * v`` within ``rho``.
    l0 : float
        Base step l0 of eq. (18) [m], > 0.
    d_min : float
        Minimum robot-obstacle distance d_min of eq. (18) [m], > 0.
    rho : float
        Range of eq. (18) within which obstacles shorten the step [m],
        > ``d_min``.
    robot_radius : float
        Robot radius [m], >= 0; obstacle distances are measured from the
        robot's boundary (0: from its centre, the paper's point robot).

    Raises
    ------
    InvalidInput
        If a coefficient is not a finite number in its range.
    """

    k_att: float = 1.0
    k_rep: float = 0.005
    rho0: float = 1.0
    n: float = 2.0
    mu: float = 0.002
    step_alpha: float = 1.0
    step_beta: float = 1.5
    l0: float = 0.5
    d_min: float = 0.25
    rho: float = 1.0
    robot_radius: float = 0.0

    def __post_init__(self):
        positive = ('k_att', 'rho0', 'n', 'step_alpha', 'step_beta', 'l0', 'd_min', 'rho')
        for name in positive:
            value = getattr(self, name)
            if not (_is_number(value) and value > 0):
                raise InvalidInput(f'ApfParams.{name} must be a finite number > 0, got {value!r}')
        for name in ('k_rep', 'mu', 'robot_radius'):
            value = getattr(self, name)
            if not (_is_number(value) and value >= 0):
                raise InvalidInput(f'ApfParams.{name} must be a finite number >= 0, got {value!r}')
        if self.rho <= self.d_min:
            raise InvalidInput(
                f'ApfParams.rho ({self.rho} m) must exceed d_min ({self.d_min} m)')


# -- input checks ---------------------------------------------------------------

def _as_xy(value, name):
    xy = np.asarray(value, dtype=float)
    if xy.shape != (2,) or not np.all(np.isfinite(xy)):
        raise InvalidInput(f'{name} must be a finite (2,) position in metres, got {value!r}')
    return xy


def _as_points(points, name='obstacle_points'):
    pts = np.asarray(points, dtype=float)
    if pts.size == 0:
        return np.zeros((0, 2))
    if pts.ndim != 2 or pts.shape[1] != 2:
        raise InvalidInput(f'{name} must have shape (M, 2), got {pts.shape}')
    if not np.all(np.isfinite(pts)):
        raise InvalidInput(f'{name} must be finite (drop inf/NaN scan points first)')
    return pts


def _as_weights(weights, count):
    if weights is None:
        return None
    w = np.asarray(weights, dtype=float).reshape(-1)
    if w.shape != (count,) or not np.all(np.isfinite(w)) or np.any(w < 0):
        raise InvalidInput(f'weights must be {count} finite non-negative numbers')
    return w


def _geometry(q, points, params):
    """Unit vectors obstacle -> robot, boundary distances rho, and the in-range mask."""
    diff = q - points                                      # (M, 2) obstacle -> robot
    centre_distance = np.hypot(diff[:, 0], diff[:, 1])     # (M,)
    unit = diff / np.maximum(centre_distance, DIRECTION_EPS)[:, None]
    unit[centre_distance < DIRECTION_EPS] = 0.0
    rho = np.maximum(centre_distance - params.robot_radius, MIN_DISTANCE)
    return unit, rho, rho < params.rho0


def _unit(vector):
    norm = math.hypot(vector[0], vector[1])
    if norm < DIRECTION_EPS:
        return np.zeros(2)
    return vector / norm


# -- fields ---------------------------------------------------------------------

def attractive_force(q, goal, params, check=True):
    """Attractive force of the goal, eq. (10).

    Parameters
    ----------
    q, goal : array_like, shape (2,)
        Robot and goal positions [m], map frame.
    params : ApfParams
    check : bool
        Validate the inputs (default). Hot loops that already hold float64
        arrays of the right shapes may pass False.

    Returns
    -------
    ndarray, float64, shape (2,)
        ``k_att * (goal - q)``: the negative gradient of the potential
        ``U_att = 1/2 k_att rho(q, q_g)^2`` of eq. (9); its magnitude is
        ``k_att * rho(q, q_g)`` as eq. (10) states.

    Raises
    ------
    InvalidInput
        If a position is not a finite (2,) vector.
    """
    if check:
        q = _as_xy(q, 'q')
        goal = _as_xy(goal, 'goal')
    return params.k_att * (goal - q)  # eq. (10)


def classic_repulsive_force(q, obstacle_points, params, weights=None, check=True):
    """Classic repulsive force of a set of obstacle points, eq. (12) summed.

    Parameters
    ----------
    q : array_like, shape (2,)
        Robot position [m], map frame.
    obstacle_points : array_like, shape (M, 2)
        Obstacle points [m], map frame, finite; ``M = 0`` allowed.
    params : ApfParams
    weights : array_like, shape (M,), optional
        Non-negative weight of each point (default 1).
    check : bool
        Validate the inputs (default); see :func:`attractive_force`.

    Returns
    -------
    ndarray, float64, shape (2,)
        Sum over the points closer than ``rho0`` of
        ``k (1/rho - 1/rho0) / rho^2`` along the obstacle -> robot direction
        (the gradient of rho); zero beyond ``rho0``.

    Raises
    ------
    InvalidInput
        If ``q`` or the points are malformed or not finite.

    Notes
    -----
    The total classic force is eq. (14):
    ``attractive_force(...) + classic_repulsive_force(...)``. Near a goal
    that lies within ``rho0`` of an obstacle this repulsion does not vanish,
    which is the goal-unreachable problem of section 2.1.4.
    """
    if check:
        q = _as_xy(q, 'q')
        obstacle_points = _as_points(obstacle_points)
        weights = _as_weights(weights, len(obstacle_points))
    points, w = obstacle_points, weights
    if len(points) == 0:
        return np.zeros(2)
    unit, rho, near = _geometry(q, points, params)
    inverse = 1.0 / rho - 1.0 / params.rho0
    magnitude = np.where(near, params.k_rep * inverse / rho**2, 0.0)  # eq. (12)
    if w is not None:
        magnitude = magnitude * w
    return magnitude @ unit


def improved_repulsive_force(q, goal, obstacle_points, params, weights=None, check=True):
    """Goal-distance-scaled repulsion of eqs. (15)-(16), summed over points.

    Parameters
    ----------
    q, goal : array_like, shape (2,)
        Robot and goal positions [m], map frame.
    obstacle_points : array_like, shape (M, 2)
        Obstacle points [m], map frame, finite; ``M = 0`` allowed.
    params : ApfParams
    weights : array_like, shape (M,), optional
        Non-negative weight of each point (default 1).
    check : bool
        Validate the inputs (default); see :func:`attractive_force`.

    Returns
    -------
    ndarray, float64, shape (2,)
        ``F_rep1 + F_rep2`` summed over the points closer than ``rho0``:

        - ``F_rep1 = k (1/rho - 1/rho0) rho_g^n / rho^2`` along the
          obstacle -> robot direction (eq. (15));
        - ``F_rep2 = n/2 k (1/rho - 1/rho0)^2 rho_g^(n-1)`` along the
          robot -> goal direction (eq. (16)),

        with ``rho_g = |q - goal|``. Zero beyond ``rho0`` and, for
        ``n > 1``, zero at the goal.

    Raises
    ------
    InvalidInput
        If a position or the points are malformed or not finite.

    Notes
    -----
    Multiplying the classic potential by ``rho_g^n`` makes the goal the
    minimum of the total potential even with obstacles within ``rho0`` of it;
    eqs. (15)-(16) are the two parts of its negative gradient (the second
    comes from differentiating ``rho_g^n``, hence it points at the goal).
    ``rho_g^(n-1)`` is evaluated with ``rho_g`` floored at
    :data:`MIN_DISTANCE`; at the goal itself the direction is undefined and
    ``F_rep2`` is zero.
    """
    if check:
        q = _as_xy(q, 'q')
        goal = _as_xy(goal, 'goal')
        obstacle_points = _as_points(obstacle_points)
        weights = _as_weights(weights, len(obstacle_points))
    points, w = obstacle_points, weights
    if len(points) == 0:
        return np.zeros(2)
    unit, rho, near = _geometry(q, points, params)
    if not np.any(near):
        return np.zeros(2)
    to_goal = goal - q
    rho_g = math.hypot(to_goal[0], to_goal[1])
    goal_unit = _unit(to_goal)
    inverse = np.where(near, 1.0 / rho - 1.0 / params.rho0, 0.0)
    if w is not None:
        inverse_w = inverse * w
    else:
        inverse_w = inverse
    k, n = params.k_rep, params.n
    rep1 = k * rho_g**n * (inverse_w / rho**2)                        # eq. (15)
    rep2 = 0.5 * n * k * max(rho_g, MIN_DISTANCE)**(n - 1) * (inverse_w * inverse)  # eq. (16)
    return rep1 @ unit + float(np.sum(rep2)) * goal_unit


def velocity_repulsion(q, robot_velocity_xy, obstacle_points, obstacle_velocities, params,
                       weights=None, check=True):
    """Velocity-dependent repulsion of eq. (17), summed over points.

    Parameters
    ----------
    q : array_like, shape (2,)
        Robot position [m], map frame.
    robot_velocity_xy : array_like, shape (2,)
        Robot velocity [m/s], map frame.
    obstacle_points : array_like, shape (M, 2)
        Obstacle points [m], map frame, finite; ``M = 0`` allowed.
    obstacle_velocities : array_like, shape (M, 2) or None
        Velocity of each point [m/s], map frame; None for static points.
    params : ApfParams
    weights : array_like, shape (M,), optional
        Non-negative weight of each point (default 1).
    check : bool
        Validate the inputs (default); see :func:`attractive_force`.

    Returns
    -------
    ndarray, float64, shape (2,)
        Sum over the points closer than ``rho0`` of
        ``mu * v * exp(1/rho - 1/rho0)`` along the obstacle -> robot
        direction, where ``v`` is the closing speed.

    Raises
    ------
    InvalidInput
        If an argument is malformed or not finite.

    Notes
    -----
    Eq. (17) writes ``v`` as "the velocity of the robot" and gives no
    direction. We read ``v`` as the **closing speed**
    ``max(0, (v_robot - v_obstacle) . u)`` with ``u`` the unit vector robot
    -> obstacle, and apply the force along obstacle -> robot: a robot moving
    away from (or parallel to) an obstacle feels nothing, one closing in on
    it (or being approached by a moving one) is pushed back harder the faster
    they close. For static points this is the robot's speed toward the point.
    As written, eq. (17) jumps from ``mu v`` to 0 at ``rho0``; we keep that.
    The exponent is capped at :data:`MAX_VELOCITY_EXPONENT` so the force
    stays finite.
    """
    if check:
        q = _as_xy(q, 'q')
        robot_velocity_xy = _as_xy(robot_velocity_xy, 'robot_velocity_xy')
        obstacle_points = _as_points(obstacle_points)
        weights = _as_weights(weights, len(obstacle_points))
        if obstacle_velocities is not None:
            obstacle_velocities = _as_points(obstacle_velocities, 'obstacle_velocities')
            if obstacle_velocities.shape != obstacle_points.shape:
                raise InvalidInput(
                    f'obstacle_velocities must match obstacle_points {obstacle_points.shape}, '
                    f'got {obstacle_velocities.shape}')
    points, w = obstacle_points, weights
    if len(points) == 0:
        return np.zeros(2)
    if obstacle_velocities is None:
        relative = np.broadcast_to(robot_velocity_xy, points.shape)
    else:
        relative = robot_velocity_xy - obstacle_velocities
    unit, rho, near = _geometry(q, points, params)
    closing = np.maximum(-np.einsum('ij,ij->i', relative, unit), 0.0)  # unit is obstacle -> robot
    exponent = np.minimum(1.0 / rho - 1.0 / params.rho0, MAX_VELOCITY_EXPONENT)
    magnitude = np.where(near, params.mu * closing * np.exp(exponent), 0.0)  # eq. (17)
    if w is not None:
        magnitude = magnitude * w
    return magnitude @ unit


def adaptive_step(d_obstacle, speed, params):
    """Adaptive step length of eq. (18).

    Parameters
    ----------
    d_obstacle : float or array_like
        Distance d from the robot to the nearest obstacle [m] (from the
        robot boundary, like rho); negative values count as 0, ``inf`` when
        there is none.
    speed : float or array_like
        Robot speed v [m/s]; its magnitude is used.
    params : ApfParams

    Returns
    -------
    float or ndarray
        Step length l [m]: ``alpha * l0 * d * v`` when ``d < d_min``,
        ``beta * l0 * d * v`` when ``d_min <= d < rho``, ``l0`` otherwise.

    Raises
    ------
    InvalidInput
        If ``d_obstacle`` is NaN or ``speed`` is not finite.

    Notes
    -----
    Eq. (18) leaves the boundary ``d = rho`` to neither branch; we give it the
    base step. ``alpha`` and ``beta`` carry the unit [s/m^2] that makes
    ``alpha * d * v`` dimensionless. The equation is used as written: it is
    not continuous at ``d_min`` or ``rho`` unless the factors are chosen so,
    and it may exceed ``l0`` when ``beta * d * v > 1`` (a follower clips it).

    Examples
    --------
    >>> p = ApfParams(step_alpha=1.0, step_beta=2.0, l0=0.5, d_min=0.2, rho=1.0)
    >>> [float(adaptive_step(d, 0.5, p)) for d in (0.1, 0.5, 3.0)]
    [0.025, 0.25, 0.5]
    """
    d = np.asarray(d_obstacle, dtype=float)
    v = np.abs(np.asarray(speed, dtype=float))
    if np.any(np.isnan(d)):
        raise InvalidInput('d_obstacle must not be NaN')
    if not np.all(np.isfinite(v)):
        raise InvalidInput('speed must be finite')
    d = np.maximum(d, 0.0)
    scaled = np.where(np.isfinite(d), d, 0.0) * v * params.l0
    step = np.where(d < params.d_min, params.step_alpha * scaled,          # eq. (18), d < d_min
                    np.where(d < params.rho, params.step_beta * scaled,   # eq. (18), d < rho
                             params.l0))                                  # eq. (18), d > rho
    if step.ndim == 0:
        return float(step)
    return step
