"""Keeping to one side for people on the route: where a route follower passes or yields.

A person walking along a corridor the route runs through is in the robot's
way for many metres; pushed by the field and by the evasion check alone, the
robot backs away in front of them (it was herded 11 m in a 1.8 m corridor).
People do better: each keeps to one side and they pass. :func:`passing_bounds`
picks, for the tracked obstacles near the route within :data:`YIELD_RANGE`
ahead that walk along it (head-on or the same way, not across: a person
crossing is avoided by the field at their predicted positions), the side with more free width between them and the walls (and keeps
that side while they stay and the robot fits there: a switch crosses the
person's way), and returns how far across the route the robot
may then go: the carrot is shifted into that gap, and the evasion check lets
the robot wait there while the person passes
(see :mod:`~fusion_planner.core.local_planning.evasion`). A person walking up
and down the only corridor of the route would hold the robot for ever:
:func:`route_closures` closes the route at them for a replan round them.

Offsets are signed distances across the route [m], positive on its left.

Examples
--------
>>> import numpy as np
>>> from fusion_planner.core.local_planning.controller_base import FollowerParams
>>> from fusion_planner.core.local_planning.route import Route
>>> route = Route(np.array([[0.0, 0.0], [10.0, 0.0]]))
>>> person = np.array([[3.0, 0.1, -0.35, 0.0, 0.3]])          # slightly left, head-on
>>> left, right, side = passing_bounds(route, person, 0.9, 0.9, FollowerParams(), 0)
>>> side, round(left, 2), right                                  # pass on its right
(-1, -0.5, inf)
"""

import math

import numpy as np

#: Tracked obstacles up to this far ahead along the route [m] are passed on one side.
YIELD_RANGE = 6.0

#: Room [m] kept between the robot and a person it passes.
PASSING_MARGIN = 0.1

#: The route is closed at the people walking along it up to this far ahead
#: [m]: those the robot gives way to, not one who has yet to come near.
CLOSURE_RANGE = 2.0

#: A route closure stops this many point spacings short of a static point:
#: a laser's returns on a wall lie about a spacing apart.
WALL_STOP = 1.5


def passing_bounds(route, tracked, wall_left, wall_right, params, previous_side):
    """The bounds across the route that the people on it ahead set, and the side to keep.

    Parameters
    ----------
    route : Route
        With its station at the robot.
    tracked : ndarray, shape (K, 5)
        ``x, y, vx, vy, radius`` of the tracked obstacles [m, m/s].
    wall_left, wall_right : float
        Distance [m] from the route to the nearest static point beside it on
        its left and right (``inf``: none).
    params : FollowerParams
    previous_side : int
        The side kept on the last step (+1 left of the people, -1 right of
        them, 0 none): kept while people are still on the route and the
        robot fits there, if need be without :data:`PASSING_MARGIN`.

    Returns
    -------
    room_left, room_right : float
        Largest offset to the left and to the right [m] the robot's centre
        may take to keep :data:`PASSING_MARGIN` from the people (``inf``:
        unbounded); either may be negative (that side of the route is taken).
    side : int
        The side now kept; 0 when nobody is on the route ahead, or when the
        robot fits on neither side of them (then it has no bounds).
    """
    r = params.robot_radius
    on_route, offsets, _ = _on_route_ahead(route, tracked, r, route.station)
    if not np.any(on_route):
        return math.inf, math.inf, 0
    offsets, reach = offsets[on_route], (r + tracked[:, 4] + PASSING_MARGIN)[on_route]
    # the room the robot's centre has between the people and the walls on either side
    free_left = (wall_left - r) - float(np.max(offsets + reach))
    free_right = (wall_right - r) + float(np.min(offsets - reach))
    side = previous_side
    # a side is kept while the robot fits there without the margin: giving it up
    # means crossing the person's way, not worth it for a few centimetres of
    # tracker noise
    if side == 0 or (free_left if side > 0 else free_right) < -PASSING_MARGIN:
        side = 1 if free_left > free_right else -1
    if max(free_left, free_right) < 0.0:
        return math.inf, math.inf, 0  # no room on either side: the field and the evasion decide
    if side > 0:
        return math.inf, -float(np.max(offsets + reach)), side
    return float(np.min(offsets - reach)), math.inf, side


def route_closures(route, q, tracked, points, params, spacing):
    """Points closing the route at the people walking along it just ahead, for a replan round them.

    For each person walking along the route (as in :func:`passing_bounds`)
    whose nearest route point lies between their radius plus the robot's
    plus :data:`PASSING_MARGIN` and :data:`CLOSURE_RANGE` ahead of the
    robot, a line across the route through that point: the corridor they
    walk is closed there, as a navigation stack's costmap closes a
    corridor a person fills, while the robot's own place stays free.
    "Ahead" counts from the route point nearest the robot, not from its
    station: a person walking at the robot may have pushed it back behind
    its station. Each line reaches a robot diameter and the passing margin
    past the person on both sides of the route, and stops
    :data:`WALL_STOP` spacings short of the first static point on either
    side, so that it never closes a neighbouring corridor beyond a wall.

    Parameters
    ----------
    route : Route
    q : ndarray, shape (2,)
        Robot position [m].
    tracked : ndarray, shape (K, 5)
        ``x, y, vx, vy, radius`` of the tracked obstacles [m, m/s].
    points : ndarray, shape (M, 2)
        Static obstacle points [m] (walls).
    params : FollowerParams
    spacing : float
        Spacing [m] of the points along each line, > 0.

    Returns
    -------
    ndarray, float64, shape (C, 2)
        [m], map frame; empty when nobody walks the route far enough ahead.
    """
    r = params.robot_radius
    here = float(route.arc[route.nearest(q[None, :], 0.0, route.station)[1][0]])
    on_route, offsets, index = _on_route_ahead(route, tracked, r, here)
    radii = tracked[:, 4]
    ahead = route.arc[index] - here
    room = (ahead >= radii + r + PASSING_MARGIN) & (ahead <= CLOSURE_RANGE)
    lines = []
    for i in np.nonzero(on_route & room)[0]:
        half = abs(offsets[i]) + radii[i] + PASSING_MARGIN + 2.0 * r
        across = spacing * np.arange(1, int(math.ceil(half / spacing)) + 1)
        tangent = route.tangents(index[i:i + 1])[0]
        normal = np.array([-tangent[1], tangent[0]])
        centre = route.points[index[i]]
        for side in (normal, -normal):
            line = centre + across[:, None] * side
            if len(points):
                gaps = np.min(np.hypot(line[:, 0:1] - points[:, 0], line[:, 1:2] - points[:, 1]),
                              axis=1)
                line = line[:_first_true(gaps < WALL_STOP * spacing)]
            lines.append(line)
        lines.append(centre[None, :])
    return np.vstack(lines) if lines else np.zeros((0, 2))


def _first_true(mask):
    """Index of the first True of ``mask`` (N,), or N."""
    hits = np.nonzero(mask)[0]
    return int(hits[0]) if len(hits) else len(mask)


def _on_route_ahead(route, tracked, robot_radius, station):
    """Which tracked obstacles walk along the route within :data:`YIELD_RANGE` ahead of ``station`` [m].

    Head-on or the same way (not across), nearer the route than the robot's
    radius, theirs and :data:`PASSING_MARGIN`. Returns the mask (K,), their
    signed offsets from the route (K,) [m] and their nearest route points'
    indices (K,).
    """
    r = robot_radius
    if len(tracked) == 0:
        return np.zeros(0, bool), np.zeros(0), np.zeros(0, np.int64)
    centres, radii = tracked[:, 0:2], tracked[:, 4]
    distance, index = route.nearest(centres, station - r, station + YIELD_RANGE)
    offsets = route.signed_offsets(centres, distance, index)
    # beside the searched piece, not beyond either end of it
    ahead = (index > route.index_at(station - r)) & (index < route.index_at(station + YIELD_RANGE))
    reach = r + radii + PASSING_MARGIN
    tangent = route.tangents(index)
    along = np.abs(tangent[:, 0] * tracked[:, 2] + tangent[:, 1] * tracked[:, 3])
    across = np.abs(tangent[:, 0] * tracked[:, 3] - tangent[:, 1] * tracked[:, 2])
    return ahead & (np.abs(offsets) < reach) & (across <= along), offsets, index
