"""Local minima of the field controllers: escape episodes and boundary following.

A field controller is *stuck* when its distance to the current sub-goal shows
a net progress below ``stuck_progress`` over ``stuck_window`` (standing still
and oscillating alike). Each detection counts one stuck event and opens (or
continues) an escape :class:`Episode`, whose steps
:class:`~fusion_planner.core.local_planning.field_follower.FieldFollower` takes in order:

1. fusion only, once per episode: the next A* key node becomes the sub-goal
   (the paper's escape);
2. fusion with a replanner, up to :data:`MAX_REPLANS_PER_EPISODE` times: a
   new global plan around the map and every static point seen so far;
3. boundary following (Bug2-like, :class:`BoundaryFollow`): keep the blocking
   boundary on a fixed side at ``wall_distance`` until :func:`may_leave`
   says the robot is closer to the sub-goal than at every earlier hit and
   the way to it is free.

An episode ends when the robot passes the key node it escaped to or leaves
the boundary. The run's bound is not the episode's age but the time without
progress toward the goal (:mod:`~fusion_planner.core.local_planning.progress`):
past ``escape_time_limit`` it is a failure; a replan that proves the goal
unreachable ends it in ``'no_path'``.

Examples
--------
>>> import numpy as np
>>> from fusion_planner.core.local_planning.controller_base import FollowerParams
>>> wall = np.column_stack([np.linspace(-1.0, 1.0, 21), np.full(21, 0.5)])   # y = 0.5
>>> follow = BoundaryFollow()
>>> d = follow.direction(np.zeros(2), np.array([2.0, 2.0]), wall, np.ones(21), FollowerParams())
>>> follow.side, bool(d[0] > 0.9)      # along the wall, toward the target's side
(1, True)
"""

import math
from dataclasses import dataclass

import numpy as np

from fusion_planner.core.local_planning import apf
from fusion_planner.core.local_planning.local_geometry import segments_clear

#: Global replans per escape episode before falling back to boundary following.
MAX_REPLANS_PER_EPISODE = 2

#: Points within this band [m] beyond the nearest one define the wall normal
#: when following a boundary.
FOLLOW_BAND = 0.25

#: Gain of the clearance correction while following a boundary (1: turn 45
#: degrees toward or away from the wall at a clearance error of one
#: ``wall_distance``).
WALL_GAIN = 1.0


@dataclass
class Episode:
    """An open escape episode.

    Attributes
    ----------
    start : float
        When it opened [s].
    index : int
        Sub-goal index after the last escape action.
    target_distance : float
        Distance to the sub-goal when it opened [m].
    skipped : bool
        The next key node was made the sub-goal.
    replans : int
        New global plans asked for.
    """

    start: float
    index: int
    target_distance: float
    skipped: bool = False
    replans: int = 0


@dataclass
class BoundaryFollow:
    """Boundary-following state.

    Attributes
    ----------
    side : int
        +1: boundary on the left (the direction is the wall normal turned
        counter-clockwise), -1: on the right, 0: not chosen yet.
    wall_point : ndarray, shape (2,) or None
        Last nearest obstacle point [m].
    """

    side: int = 0
    wall_point: np.ndarray = None

    def direction(self, q, target, points, weights, params):
        """Boundary-following direction, choosing the side on first use.

        The wall normal is the ``1/rho^2``-weighted mean direction from the
        points within :data:`FOLLOW_BAND` of the nearest one to the robot; the
        direction is the tangent on the chosen side, turned toward or away
        from the wall in proportion to the clearance error. With no point
        within ``rho0`` the last nearest point stands for the wall (turning
        round a convex corner). The side is the one whose tangent points more
        toward the target when following starts.

        Parameters
        ----------
        q : ndarray, shape (2,)
            Robot position [m], map frame.
        target : ndarray, shape (2,)
            Current sub-goal [m].
        points : ndarray, shape (M, 2)
            Obstacle points of the field [m].
        weights : ndarray, shape (M,)
            Their weights (see :mod:`fusion_planner.core.local_planning.apf`).
        params : FollowerParams

        Returns
        -------
        ndarray, shape (2,) or None
            Unit vector, map frame; None with no wall known.
        """
        p = params
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
            self.wall_point = points[nearest].copy()
        elif self.wall_point is not None:
            normal = q - self.wall_point
            rho_min = max(math.hypot(normal[0], normal[1]) - p.robot_radius, apf.MIN_DISTANCE)
        else:
            return None
        norm = math.hypot(normal[0], normal[1])
        if norm < apf.DIRECTION_EPS:
            return None
        normal = normal / norm
        ccw = np.array([-normal[1], normal[0]])
        if self.side == 0:
            self.side = 1 if float(ccw @ (target - q)) >= 0.0 else -1
        error = max(-1.0, min(1.0, (rho_min - p.wall_distance) / p.wall_distance))
        direction = self.side * ccw - WALL_GAIN * error * normal
        return direction / math.hypot(direction[0], direction[1])


def may_leave(q, target, best_hit, points, params):
    """Bug2-like leave test of boundary following.

    Parameters
    ----------
    q, target : ndarray, shape (2,)
        Robot and sub-goal positions [m].
    best_hit : float
        Smallest distance to the sub-goal [m] at which following started
        (``inf``: none).
    points : ndarray, shape (M, 2)
        Obstacle points [m].
    params : FollowerParams

    Returns
    -------
    bool
        True when the robot is closer to the target than ``best_hit`` by
        ``stuck_progress`` and the line to it is free for
        ``rho0 + robot_radius`` (or up to the target) with
        ``robot_radius + safety_distance`` to spare.
    """
    p = params
    distance = math.hypot(*(target - q))
    if distance >= best_hit - p.stuck_progress:
        return False
    reach = min(distance, p.apf.rho0 + p.robot_radius)
    if reach <= apf.DIRECTION_EPS:
        return True
    end = q + (target - q) * (reach / distance)
    half = p.robot_radius + p.safety_distance
    return bool(segments_clear(q, end[None, :], points, half)[0])
