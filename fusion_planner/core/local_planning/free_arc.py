"""The last check of a route follower's command: is its arc free for the stopping distance?

The route follower's speed caps look along the route and straight ahead
(:mod:`~fusion_planner.core.local_planning.speed_policy`), and the points
beside the route do not repel. A robot turning onto the route (or round a
person it has not yet recognised as one) sweeps neither: its disc follows
the arc of its command. :func:`free_arc_speed` bounds the forward (or
reverse) speed so that the robot, on the arc of the command's turn rate at
that speed, can stop within it without coming closer than ``safety_distance`` to
any scan point, whatever the point is (a wall, an unknown box, a person not
yet tracked as moving).

When the robot cannot brake to that speed within one control period,
:func:`free_arc_turn` picks, among the turn rates it can reach, one whose
arc it can stop on. A robot told to turn round while still moving turns
the long way round when only that way's arc is free
(:func:`turn_round_error`).

Stopping on the arc is a manoeuvre the robot can always make: braking at
``max_accel`` while the turn rate falls in proportion to the speed keeps the
curvature. The stopping distance from speed ``u`` is
``u^2 / (2 max_accel) + |u| control_period`` (one period passes before the
next command).

A robot that is already closer than ``safety_distance`` to a point (in a
passage only a little wider than itself) may drive on at its present
clearance less :data:`~fusion_planner.core.local_planning.speed_policy.PASSING_SLACK`,
never below
:data:`~fusion_planner.core.local_planning.speed_policy.PASSING_FLOOR`
(nor below the present clearance when that is already less).

Frames and units: map frame, metres, seconds, radians.

Examples
--------
>>> import numpy as np
>>> from fusion_planner.core.local_planning.controller_base import FollowerParams
>>> p = FollowerParams(max_speed=1.0, max_accel=1.0)
>>> pose = np.array([0.0, 0.0, 0.0])
>>> free_arc_speed(pose, 1.0, 0.0, np.array([[5.0, 0.0]]), p)     # far ahead: free
1.0
>>> free_arc_speed(pose, 1.0, 0.0, np.array([[0.6, 0.0]]), p) < 1.0  # too close to stop
True
>>> free_arc_speed(pose, 1.0, 2.0, np.array([[0.6, 0.0]]), p)     # the arc turns away
1.0
"""

import math

import numpy as np
from scipy.spatial import cKDTree

from fusion_planner.core.local_planning.speed_policy import PASSING_FLOOR, PASSING_SLACK

#: Fractions of the commanded speed tried, fastest first.
SPEED_FRACTIONS = np.linspace(1.0, 0.0, 11)

#: Spacing [m] of the robot positions checked along an arc: a point between
#: two of them comes at most ``spacing^2 / (8 radius)`` (under 0.3 mm for a
#: 0.2 m robot) closer than at either.
SAMPLE_SPACING = 0.02

#: Curvatures [1/m] below this are straight lines.
STRAIGHT_CURVATURE = 1e-6

#: Turn rates tried by :func:`free_arc_turn` across the range it is given.
TURN_SAMPLES = 9


def stopping_distance(speed, params):
    """Distance [m] to stop from ``speed`` [m/s] at ``max_accel``, plus one period's travel."""
    speed = np.abs(speed)
    return speed**2 / (2.0 * params.max_accel) + speed * params.control_period


def arc_points(pose, curvature, lengths):
    """Positions ``(..., 2)`` [m] after signed arc lengths ``lengths`` at ``curvature`` [1/m]."""
    yaw = pose[2]
    turned = curvature * lengths
    straight = np.abs(curvature) < STRAIGHT_CURVATURE
    safe = np.where(straight, 1.0, curvature)
    dx = np.where(straight, lengths * math.cos(yaw), (np.sin(yaw + turned) - math.sin(yaw)) / safe)
    dy = np.where(straight, lengths * math.sin(yaw), (math.cos(yaw) - np.cos(yaw + turned)) / safe)
    return pose[:2] + np.stack([dx, dy], axis=-1)


def free_arc_speed(pose, v, omega, points, params):
    """Largest speed, at most ``|v|`` and with its sign, whose arc is free to stop on.

    Parameters
    ----------
    pose : ndarray, shape (3,)
        ``x, y, yaw`` [m, m, rad].
    v, omega : float
        The command [m/s, rad/s]; a speed ``u`` tried drives the arc of
        curvature ``omega / u`` (the turn rate is kept).
    points : ndarray, shape (M, 2)
        Scan points [m], finite.
    params : FollowerParams
        ``robot_radius``, ``safety_distance``, ``max_accel``,
        ``control_period``.

    Returns
    -------
    float
        ``v`` when its arc is free, else the largest of
        :data:`SPEED_FRACTIONS` of it that is (0 when none is) [m/s].
    """
    p = params
    if v == 0.0 or len(points) == 0:
        return v
    q = pose[:2]
    longest = float(stopping_distance(v, p))
    d = points - q
    reach = longest + p.robot_radius + p.safety_distance
    points = points[np.einsum('ij,ij->i', d, d) <= reach * reach]
    if len(points) == 0:
        return v
    tree = cKDTree(points)
    now = float(tree.query(q)[0]) - p.robot_radius
    required = min(p.safety_distance, max(now - PASSING_SLACK, min(now, PASSING_FLOOR)))
    speeds = v * SPEED_FRACTIONS[:-1]                                            # (C,)
    samples = max(int(math.ceil(longest / SAMPLE_SPACING)), 1)
    # signed arc lengths: every speed's own stopping distance, in as many steps
    lengths = math.copysign(1.0, v) * stopping_distance(speeds, p)[:, None] \
        * np.linspace(0.0, 1.0, samples + 1)[1:]                               # (C, S)
    positions = arc_points(pose, (omega / speeds)[:, None], lengths)
    gaps = tree.query(positions.reshape(-1, 2))[0].reshape(lengths.shape) - p.robot_radius
    free = np.all(gaps >= required, axis=1)
    return float(speeds[np.argmax(free)]) if np.any(free) else 0.0


def free_arc_turn(pose, v, turns, omega, points, params):
    """The turn rate, among ``turns``, on whose arc the robot at speed ``v`` can stop clear.

    For a robot that cannot brake enough to stop on the arc it wants
    (:func:`free_arc_speed` asks for less than it can reach this step):
    steering may still leave it a free arc.

    Parameters
    ----------
    pose : ndarray, shape (3,)
    v : float
        The speed it will have [m/s].
    turns : tuple of float
        ``(low, high)`` [rad/s]: the turn rates it can reach this step.
    omega : float
        The turn rate it wants [rad/s].
    points : ndarray, shape (M, 2)
    params : FollowerParams

    Returns
    -------
    float
        Of :data:`TURN_SAMPLES` turn rates across ``turns`` (and
        ``omega`` clipped to them), the one nearest ``omega`` whose arc is
        free at ``v``, or, when none is, the one that allows the highest
        speed [rad/s].
    """
    candidates = np.append(np.linspace(turns[0], turns[1], TURN_SAMPLES),
                           min(max(omega, turns[0]), turns[1]))
    allowed = np.array([abs(free_arc_speed(pose, v, w, points, params)) for w in candidates])
    free = allowed >= abs(v)
    if np.any(free):
        return float(candidates[free][np.argmin(np.abs(candidates[free] - omega))])
    return float(candidates[np.argmax(allowed)])


def turn_round_error(pose, speed, error, points, params):
    """The heading error [rad] to turn through when turning round while still moving forward.

    Beyond 90 degrees either way round is at most twice as long as the
    other, and a robot that brakes while it turns sweeps an arc that curls
    to the side it turns to: after a new plan that reverses its way beside
    a wall, the shorter way round may turn it into the wall faster than it
    can brake (:func:`free_arc_turn` then has only turn rates within
    ``max_alpha`` of the present one to choose from). Such a robot turns
    the long way round when the arc of the short one, at its speed and
    ``max_omega``, is not free to stop on and the long one's is.

    Parameters
    ----------
    pose : ndarray, shape (3,)
        ``x, y, yaw`` [m, m, rad].
    speed : float
        Measured forward speed [m/s].
    error : float
        Heading error [rad], wrapped to ``[-pi, pi)``.
    points : ndarray, shape (M, 2)
        Scan points [m], finite.
    params : FollowerParams

    Returns
    -------
    float
        ``error``, or ``error -+ 2 pi`` (the long way round).
    """
    if abs(error) <= math.pi / 2 or speed <= 0.0 or len(points) == 0:
        return error
    short = math.copysign(params.max_omega, error)
    if free_arc_speed(pose, speed, short, points, params) >= speed \
            or free_arc_speed(pose, speed, -short, points, params) < speed:
        return error
    return error - math.copysign(2.0 * math.pi, error)
