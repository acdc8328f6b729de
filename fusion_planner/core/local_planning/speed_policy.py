"""How fast a route follower may go: for what lies in its braking path and the turn ahead.

The adaptive step of eq. (18) slows the robot by the distance ``d`` to the
nearest obstacle; taken over every obstacle around, side walls count too, and
a 0.4 m robot in a 1.3 m corridor crawls at a third of its top speed. A route
follower (fusion) instead measures ``d`` along its **braking path**: the
route ahead, as far as the robot needs to stop from ``max_speed``, swept by
the robot's disc plus ``safety_distance``, and the straight line ahead
(see :func:`braking_path_gap`). Side walls the route runs between are not in
it. On top of that the speed is capped so that the robot can brake to the
speed of the sharpest turn ahead in time (:func:`turn_cap`), and a robot
heading more than :data:`ROTATE_FIRST_RAD` off its direction turns on the
spot first.

Examples
--------
>>> import numpy as np
>>> from fusion_planner.core.local_planning.controller_base import FollowerParams
>>> from fusion_planner.core.local_planning.route import Route
>>> p = FollowerParams(max_speed=1.0, max_accel=1.0, max_omega=2.0)
>>> straight = Route(np.array([[0.0, 0.0], [10.0, 0.0]]))
>>> turn_cap(straight, 0.0, p) >= 1.0
True
>>> corner = Route(np.array([[0.0, 0.0], [0.5, 0.0], [0.5, 5.0]]))
>>> bool(turn_cap(corner, 0.0, p) < 1.0)
True
"""

import math

import numpy as np

from fusion_planner.core.local_planning.local_geometry import front_gap
from fusion_planner.core.local_planning.route import TURN_BASE

#: Fraction of ``max_omega`` a turn on the route may take at the capped
#: speed; the rest is left to heading corrections.
TURN_OMEGA_FRACTION = 0.8

#: Lateral acceleration allowed in a turn, as a fraction of ``max_accel``.
LATERAL_ACCEL_FRACTION = 1.0

#: Fraction of ``TURN_BASE`` the turn rate may take to build up at ``max_alpha``.
RAMP_FRACTION = 1.0

#: A route follower whose heading is off the direction it should drive by
#: more than this [rad] turns on the spot before it drives on (as Nav2's
#: rotation shim controller, whose default threshold this is): turning
#: while driving at such an error swings the robot sideways off its route,
#: more than the gaps of a post field leave room for.
ROTATE_FIRST_RAD = math.pi / 4

#: Heading changes [rad] over ``TURN_BASE`` below this are straight.
STRAIGHT_TURN = 1e-3

#: The straight braking check asks for the robot's present clearance less
#: this [m] when that is below ``safety_distance``: a robot already that
#: close to a post beside it may drive on past it, not closer.
PASSING_SLACK = 1e-3

#: ... but not below this clearance [m] (nor below the present one when it
#: is already less): creeping along a wall a millimetre closer each step
#: would end in contact.
PASSING_FLOOR = 5e-3


def braking_distance(params):
    """Distance [m] to stop from ``max_speed`` at ``max_accel``, plus one period's travel."""
    p = params
    return p.max_speed**2 / (2.0 * p.max_accel) + p.max_speed * p.control_period


def turn_speed(turns, params):
    """Speed [m/s] at which heading changes ``turns`` [rad] over ``TURN_BASE`` can be driven.

    Bounded by the turn rate (``TURN_OMEGA_FRACTION * max_omega``), the
    lateral acceleration (``LATERAL_ACCEL_FRACTION * max_accel``) and the
    turn-rate ramp: reaching the turn rate ``v * curvature`` at
    ``max_alpha`` takes ``v^2 curvature / max_alpha`` metres, at most
    ``RAMP_FRACTION * TURN_BASE``.
    """
    p = params
    curvature = np.maximum(np.asarray(turns, dtype=float), STRAIGHT_TURN) / TURN_BASE
    by_rate = TURN_OMEGA_FRACTION * p.max_omega / curvature
    by_accel = np.sqrt(LATERAL_ACCEL_FRACTION * p.max_accel / curvature)
    by_ramp = np.sqrt(RAMP_FRACTION * TURN_BASE * p.max_alpha / curvature)
    return np.minimum(np.minimum(np.minimum(by_rate, by_accel), by_ramp), p.max_speed)


def turn_cap(route, station, params):
    """Largest speed [m/s] from which the turns ahead can be braked for in time.

    Parameters
    ----------
    route : Route
    station : float
        The robot's arc length on it [m].
    params : FollowerParams

    Returns
    -------
    float
        ``min over stations ahead of sqrt(turn_speed^2 + 2 max_accel s)``,
        ``s`` the distance to the station; ``max_speed`` when the route is
        straight within the braking distance.
    """
    p = params
    distances, turns = route.sharpest_turns(station, station + braking_distance(p) + TURN_BASE)
    if len(turns) == 0:
        return p.max_speed
    allowed = np.sqrt(turn_speed(turns, p)**2 + 2.0 * p.max_accel * np.maximum(distances, 0.0))
    return float(min(p.max_speed, np.min(allowed)))


def braking_path_gap(pose, route, station, points, blocking, circles, params):
    """Free travel [m] in the braking path: along the route and straight ahead.

    Parameters
    ----------
    pose : ndarray, shape (3,)
        ``x, y, yaw`` [m, m, rad].
    route : Route
    station : float
        The robot's arc length on the route [m].
    points : ndarray, shape (M, 2)
        Obstacle points [m].
    blocking : ndarray, shape (B, 2)
        Those of them that lie on the route (the others are beside it: the
        follower keeps its distance from them by moving across the route).
    circles : ndarray, shape (K, 3)
        Tracked obstacles ``x, y, radius`` [m].
    params : FollowerParams

    Returns
    -------
    float
        The smaller of the arc length to the first route point whose disc of
        ``robot_radius + safety_distance`` reaches a blocking point or a
        circle (at least the straight distance to that point: a robot off
        its route, down a side corridor, gets there no sooner), and the
        free straight travel (:func:`front_gap`) of that
        disc among the tracked circles and of a disc no wider than the
        robot's present clearance among all points; ``inf`` when nothing is
        in the way.
    """
    p = params
    clearance = p.robot_radius + p.safety_distance
    end = station + braking_distance(p)
    along = min(route.along_to_first(blocking, station, end, clearance),
                route.along_to_first(circles[:, 0:2], station, end, clearance + circles[:, 2]))
    if math.isfinite(along):
        along = max(along, math.hypot(*(route.point_at(station + along) - pose[:2])))
    passing = clearance
    if len(points):
        # driving on past a point at the clearance the robot already has is no contact
        d = points - pose[:2]
        now = math.sqrt(float(np.min(np.einsum('ij,ij->i', d, d))))
        floor = min(now, p.robot_radius + PASSING_FLOOR)
        passing = min(clearance, max(now - PASSING_SLACK, floor))
    straight = min(front_gap(pose, points, np.zeros(len(points)), passing),
                   front_gap(pose, circles[:, 0:2], circles[:, 2], clearance))
    return min(along, straight)
