"""Keeping to one side for people on the route: where a route follower passes or yields.

A person walking along a corridor the route runs through is in the robot's
way for many metres; pushed by the field and by the evasion check alone, the
robot backs away in front of them (it was herded 11 m in a 1.8 m corridor).
People do better: each keeps to one side and they pass. :func:`passing_bounds`
picks, for the tracked obstacles near the route within :data:`YIELD_RANGE`
ahead that walk along it (head-on or the same way, not across: a person
crossing is avoided by the field at their predicted positions), the side with more free width between them and the walls (and keeps
that side while they stay), and returns how far across the route the robot
may then go: the carrot is shifted into that gap, and the evasion check lets
the robot wait there while the person passes
(see :mod:`~fusion_planner.core.local_planning.evasion`).

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
        robot fits there.

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
    if len(tracked) == 0:
        return math.inf, math.inf, 0
    centres, radii = tracked[:, 0:2], tracked[:, 4]
    distance, index = route.nearest(centres, route.station - r, route.station + YIELD_RANGE)
    offsets = route.signed_offsets(centres, distance, index)
    # beside the searched piece, not beyond either end of it
    ahead = (index > route.index_at(route.station - r)) \
        & (index < route.index_at(route.station + YIELD_RANGE))
    reach = r + radii + PASSING_MARGIN
    tangent = route.tangents(index)
    along = np.abs(tangent[:, 0] * tracked[:, 2] + tangent[:, 1] * tracked[:, 3])
    across = np.abs(tangent[:, 0] * tracked[:, 3] - tangent[:, 1] * tracked[:, 2])
    on_route = ahead & (np.abs(offsets) < reach) & (across <= along)
    if not np.any(on_route):
        return math.inf, math.inf, 0
    offsets, reach = offsets[on_route], reach[on_route]
    # the room the robot's centre has between the people and the walls on either side
    free_left = (wall_left - r) - float(np.max(offsets + reach))
    free_right = (wall_right - r) + float(np.min(offsets - reach))
    side = previous_side
    if side == 0 or min(free_left if side > 0 else free_right, 0.0) < 0.0:
        side = 1 if free_left > free_right else -1
    if max(free_left, free_right) < 0.0:
        return math.inf, math.inf, 0  # no room on either side: the field and the evasion decide
    if side > 0:
        return math.inf, -float(np.max(offsets + reach)), side
    return float(np.min(offsets - reach)), math.inf, side
