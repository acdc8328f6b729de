"""The route a plan follower drives: the global path as a dense polyline with arc lengths.

The fusion controller follows the global plan through a :class:`Route`: the
path resampled every :data:`ROUTE_SPACING` metres, the robot's *station*
(arc length of its projection, which only moves forward), the carrot ahead
of it, the tangent there, the sharpest turn ahead, and where obstacle points
lie with respect to it (on it or beside it, on which side). Map frame, metres and radians throughout.

Examples
--------
>>> import numpy as np
>>> route = Route(np.array([[0.0, 0.0], [4.0, 0.0], [4.0, 3.0]]))
>>> round(route.length, 3), round(route.project(np.array([1.0, 0.2])), 3)
(7.0, 1.0)
>>> route.point_at(5.0).round(6).tolist()
[4.0, 1.0]
>>> points = np.array([[2.0, 0.05], [2.0, -0.5]])
>>> distance, index = route.nearest(points, 1.0, 3.0)
>>> route.signed_offsets(points, distance, index).round(2).tolist()
[0.05, -0.5]
"""

import math

import numpy as np

from fusion_planner.core.local_planning.controller_base import check_followable
from fusion_planner.core.local_planning.local_geometry import resample, wrap_angle

#: Spacing [m] of the route's points (its projection error is a few tenths of
#: a millimetre at this spacing).
ROUTE_SPACING = 0.05

#: How far [m] ahead of the station the projection searches: the robot never
#: moves this far in one control period, and a route that comes back near
#: itself later is not mistaken for the part being driven.
PROJECTION_WINDOW = 2.0

#: Arc length [m] over which the heading change ahead is measured (a sharp
#: polyline corner and a tight arc alike turn this much within it).
TURN_BASE = 0.3


class Route:
    """A polyline with arc lengths and a station that only moves forward.

    Parameters
    ----------
    polyline : ndarray, shape (N, 2)
        The route [m], map frame, N >= 1, finite.

    Attributes
    ----------
    points : ndarray, shape (P, 2)
        The resampled route [m].
    arc : ndarray, shape (P,)
        Arc length [m] of each point from the first.
    station : float
        Arc length [m] of the robot's last projection.

    Raises
    ------
    InvalidInput
        If the polyline is longer than
        :data:`~fusion_planner.core.local_planning.controller_base.MAX_PATH_LENGTH_M`.
    """

    def __init__(self, polyline):
        polyline = check_followable(np.asarray(polyline, dtype=float), 'route')
        self.points = resample(polyline, ROUTE_SPACING)
        steps = np.hypot(*np.diff(self.points, axis=0).T)
        self.arc = np.concatenate([[0.0], np.cumsum(steps)])
        headings = np.arctan2(*np.diff(self.points, axis=0).T[::-1]) if len(steps) else np.zeros(0)
        self._headings = np.concatenate([headings, headings[-1:]]) if len(steps) else np.zeros(1)
        self._index = 0
        self.station = 0.0

    @property
    def length(self):
        """Total arc length [m]."""
        return float(self.arc[-1])

    @property
    def remaining(self):
        """Arc length [m] from the station to the end."""
        return self.length - self.station

    def project(self, q):
        """Move the station to the nearest route point within the window ahead; return it [m].

        Parameters
        ----------
        q : ndarray, shape (2,)
            Robot position [m].
        """
        end = int(np.searchsorted(self.arc, self.station + PROJECTION_WINDOW, side='right'))
        window = self.points[self._index:max(end, self._index + 1)]
        self._index += int(np.argmin(np.hypot(window[:, 0] - q[0], window[:, 1] - q[1])))
        self.station = float(self.arc[self._index])
        return self.station

    def index_at(self, s):
        """Index of the last route point at or before arc length ``s`` [m] (clipped)."""
        return int(min(max(np.searchsorted(self.arc, s, side='right') - 1, 0), len(self.arc) - 1))

    def point_at(self, s):
        """The route point [m] at arc length ``s`` (clipped to the route), interpolated."""
        i = self.index_at(s)
        if i >= len(self.arc) - 1:
            return self.points[-1].copy()
        a, b = self.points[i], self.points[i + 1]
        step = self.arc[i + 1] - self.arc[i]
        t = 0.0 if step <= 0.0 else (min(max(s, 0.0), self.length) - self.arc[i]) / step
        return a + t * (b - a)

    def tangents(self, index):
        """Unit tangents ``(M, 2)`` of the route at its points ``index`` (M,)."""
        heading = self._headings[index]
        return np.column_stack([np.cos(heading), np.sin(heading)])

    def tangent_at(self, s):
        """Unit tangent ``(2,)`` of the route at arc length ``s``."""
        heading = self._headings[self.index_at(s)]
        return np.array([math.cos(heading), math.sin(heading)])

    def arc_of(self, point, start=0.0):
        """Arc length [m] of the route point nearest ``point`` at or after ``start`` [m]."""
        i = self.index_at(start)
        d = self.points[i:] - point
        return float(self.arc[i + int(np.argmin(np.einsum('ij,ij->i', d, d)))])

    def sharpest_turns(self, s_from, s_to):
        """Heading changes [rad] over :data:`TURN_BASE` at stations from ``s_from`` to ``s_to``.

        Returns
        -------
        distances : ndarray, shape (T,)
            Arc length [m] from ``s_from`` to each station.
        turns : ndarray, shape (T,)
            Absolute heading change [rad] over the next ``TURN_BASE`` metres
            of route after each station (0 at the end of the route).
        """
        i, j = self.index_at(s_from), self.index_at(s_to)
        stride = max(1, int(round(TURN_BASE / ROUTE_SPACING)))
        ahead = np.minimum(np.arange(i, j + 1) + stride, len(self._headings) - 1)
        now = np.arange(i, j + 1)
        # the last heading is repeated, so the route's end turns by nothing
        turns = np.abs(wrap_angle(self._headings[ahead] - self._headings[now]))
        return self.arc[now] - s_from, turns

    def normal_at(self, s):
        """Unit normal ``(2,)`` of the route at arc length ``s``, pointing to its left."""
        t = self.tangent_at(s)
        return np.array([-t[1], t[0]])

    def nearest(self, points, s_from, s_to):
        """The nearest route point between two arc lengths, for each point.

        Parameters
        ----------
        points : ndarray, shape (M, 2)
            [m].
        s_from, s_to : float
            Arc lengths [m] of the piece of route searched.

        Returns
        -------
        distance : ndarray, shape (M,)
            Distance [m] to the nearest point of the piece.
        index : ndarray of int, shape (M,)
            Its index in :attr:`points`.
        """
        if len(points) == 0:
            return np.zeros(0), np.zeros(0, np.int64)
        i = self.index_at(s_from)
        piece = self.points[i:self.index_at(s_to) + 1]
        dx = points[:, 0:1] - piece[:, 0]
        dy = points[:, 1:2] - piece[:, 1]
        squared = dx * dx + dy * dy
        nearest = np.argmin(squared, axis=1)
        return np.sqrt(squared[np.arange(len(points)), nearest]), i + nearest

    def signed_offsets(self, points, distance, index):
        """Signed distances [m] of points from their nearest route points (+ on the left).

        ``distance`` and ``index`` are what :meth:`nearest` returned for
        ``points``.
        """
        tangent = self.tangents(index)
        rel = points - self.points[index]
        across = tangent[:, 0] * rel[:, 1] - tangent[:, 1] * rel[:, 0]
        return np.copysign(distance, across)

    def along_to_first(self, points, s_from, s_to, half_width):
        """Arc length [m] from ``s_from`` to the first route point within ``half_width`` of a point.

        ``half_width`` [m] is one value or one per point; ``inf`` when no
        point comes that close to the route between ``s_from`` and ``s_to``.
        """
        if len(points) == 0:
            return math.inf
        i = self.index_at(s_from)
        piece = self.points[i:self.index_at(s_to) + 1]
        dx = piece[:, 0:1] - points[:, 0]
        dy = piece[:, 1:2] - points[:, 1]
        hit = np.nonzero(np.any(dx * dx + dy * dy < np.square(half_width), axis=1))[0]
        return math.inf if len(hit) == 0 else float(self.arc[i + hit[0]] - s_from)
