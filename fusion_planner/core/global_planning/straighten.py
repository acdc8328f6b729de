"""Fewer turns at the same length: a staircase through a post field becomes one step.

Among the shortest paths through a lattice of posts (or a grid of
corridors) there are many of the same length: every staircase between two
points is as long as every other. The search and the centring pick one that
steps at almost every post, and a robot with a bounded turn rate and turn
acceleration loses a second or more at every corner. :func:`fewer_turns`
looks at four successive runs of the simplified path that zig-zag (the
first parallel to the third, the second to the fourth) and replaces them by
two: along the first run's line, then along the fourth's, meeting where the
two lines cross (the corner is searched within :data:`CORNER_SEARCH_M` of
that crossing for the most clearance). A replacement is taken only when it
is at most :data:`LENGTH_SLACK` longer than the four runs and keeps, on
every cell it touches, the smaller of ``robot_radius + safety_distance`` and
the smallest clearance the path already had; so the path stays as drivable
as it was. Map frame, metres.

Examples
--------
>>> import numpy as np
>>> from fusion_planner.core.grid import GridMap
>>> stairs = np.array([[0.5, 0.5], [1.5, 0.5], [1.5, 1.5], [2.5, 1.5], [2.5, 2.5], [3.5, 2.5]])
>>> fewer = fewer_turns(GridMap(np.zeros((40, 40), bool), 0.1), stairs, 0.2, 0.05)
>>> fewer.round(6).tolist()
[[0.5, 0.5], [2.5, 0.5], [2.5, 2.5], [3.5, 2.5]]
"""

import math

import numpy as np

from fusion_planner.core import raster

#: Largest distance [m] of a point of a run from the simplified line that
#: stands for it (the centred path wavers by a few centimetres in a passage).
SIMPLIFY_TOLERANCE_M = 0.08

#: Runs whose directions differ by less than this [rad] are parallel.
PARALLEL_RAD = 0.1

#: The new corner is searched on a square grid of this half-width [m] ...
CORNER_SEARCH_M = 0.1

#: ... and this spacing [m] around the crossing of the two lines.
CORNER_STEP_M = 0.01

#: A fold may be this fraction longer than the four runs it replaces: the
#: simplified runs stand for a wavering centred path, and their lines meet
#: a few centimetres off the middle of the crossing.
LENGTH_SLACK = 0.01


def simplify(path, tolerance=SIMPLIFY_TOLERANCE_M):
    """Douglas-Peucker: the vertices of ``path`` (N, 2) [m] within ``tolerance`` [m] of it.

    Returns ``(K, 2)`` [m] with the ends kept.
    """
    keep = np.zeros(len(path), bool)
    keep[0] = keep[-1] = True
    stack = [(0, len(path) - 1)]
    while stack:
        i, j = stack.pop()
        if j - i < 2:
            continue
        a, chord = path[i], path[j] - path[i]
        rel = path[i + 1:j] - a
        length = math.hypot(chord[0], chord[1])
        if length > 0.0:
            off = np.abs(chord[0] * rel[:, 1] - chord[1] * rel[:, 0]) / length
        else:
            off = np.hypot(rel[:, 0], rel[:, 1])
        k = i + 1 + int(np.argmax(off))
        if off[k - i - 1] > tolerance:
            keep[k] = True
            stack += [(i, k), (k, j)]
    return path[keep]


def _parallel(u, v):
    """Whether two runs (2,) [m] point the same way within :data:`PARALLEL_RAD`."""
    norm = math.hypot(u[0], u[1]) * math.hypot(v[0], v[1])
    return norm > 0.0 and float(u @ v) / norm > math.cos(PARALLEL_RAD)


def _crossing(p, u, q, w):
    """Where the line through ``p`` along ``u`` meets the one through ``q`` along ``w``, or None."""
    det = u[0] * w[1] - u[1] * w[0]
    if abs(det) < 1e-12:
        return None
    t = ((q[0] - p[0]) * w[1] - (q[1] - p[1]) * w[0]) / det
    return p + t * u


def _better_corner(grid, a, b, runs, needed, robot_radius):
    """The corner of a two-run replacement of ``runs`` (4, 2) from ``a`` to ``b``, or None.

    The most-clearance corner near the crossing of the first and the last
    run's lines among those whose two runs are at most :data:`LENGTH_SLACK`
    longer than ``runs`` and keep ``needed`` [m] of clearance (more than
    ``robot_radius``).
    """
    crossing = _crossing(a, runs[0], b, runs[3])
    if crossing is None:
        return None
    steps = np.arange(-CORNER_SEARCH_M, CORNER_SEARCH_M + CORNER_STEP_M / 2, CORNER_STEP_M)
    corners = crossing + np.stack(np.meshgrid(steps, steps), axis=-1).reshape(-1, 2)
    # nearest the crossing first: of equal clearances, the first is taken
    corners = corners[np.argsort(np.hypot(*(corners - crossing).T), kind='stable')]
    length = np.hypot(*(corners - a).T) + np.hypot(*(b - corners).T)
    corners = corners[length <= (1.0 + LENGTH_SLACK) * np.sum(np.hypot(*runs.T))]
    if len(corners) == 0:
        return None
    clearance = np.minimum(
        raster.segments_clearance(grid, np.broadcast_to(a, corners.shape), corners),
        raster.segments_clearance(grid, corners, np.broadcast_to(b, corners.shape)))
    best = int(np.argmax(clearance))
    if clearance[best] < needed or clearance[best] <= robot_radius:
        return None
    return corners[best]


def fewer_turns(grid, path, robot_radius, safety_distance):
    """The vertices of a path with zig-zags of four runs folded into two.

    Parameters
    ----------
    grid : GridMap
    path : ndarray, float64, shape (N, 2)
        A planned path [m], map frame (dense points).
    robot_radius, safety_distance : float
        [m], >= 0.

    Returns
    -------
    ndarray, float64, shape (K, 2) or None
        The simplified path's vertices [m] (ends exact), with every zig-zag
        folded that can be (see the module's description); at most as long
        as the simplified path, never closer to an obstacle than the
        smaller of ``robot_radius + safety_distance`` and the path's own
        smallest clearance. None when there was nothing to fold.
    """
    path = np.asarray(path, dtype=float)
    vertices = simplify(path)
    if len(vertices) < 5:
        return None
    own = float(np.min(raster.segments_clearance(grid, path[:-1], path[1:])))
    needed = min(robot_radius + safety_distance, own)
    i, folded = 0, False
    while i + 4 < len(vertices):
        runs = np.diff(vertices[i:i + 5], axis=0)
        corner = None
        if _parallel(runs[0], runs[2]) and _parallel(runs[1], runs[3]) \
                and not _parallel(runs[0], runs[1]):
            corner = _better_corner(grid, vertices[i], vertices[i + 4], runs, needed, robot_radius)
        if corner is None:
            i += 1
            continue
        vertices = np.vstack([vertices[:i + 1], corner, vertices[i + 4:]])
        folded = True
        i = max(i - 3, 0)  # the new corner may start or end another zig-zag
    return vertices if folded else None
