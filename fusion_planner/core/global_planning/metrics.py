"""Path figures: length, turning angle, key points, clearance.

These are the columns of the paper's Tables 1 and 2 (path length, key
points, total turning angle) plus the clearance the project reports as
``min_clearance_m``. Paths are ``(N, 2)`` float64 arrays of ``(x, y)`` [m] in
the map frame.
"""

import numpy as np

from fusion_planner.core import raster

#: Segments shorter than this [m] have no heading and are skipped.
MIN_SEGMENT_LENGTH_M = 1e-12

#: Two consecutive headings whose directions differ by less than this sine
#: [1] (and point the same way) count as collinear.
COLLINEAR_SINE_TOLERANCE = 1e-9


def path_length(path):
    """Total length of a polyline.

    Parameters
    ----------
    path : array_like, shape (N, 2)
        ``(x, y)`` [m], map frame, N >= 1.

    Returns
    -------
    float
        Sum of segment lengths [m]; 0.0 for a single point.

    Raises
    ------
    InvalidInput
        If ``path`` is not a finite ``(N, 2)`` array with N >= 1.

    Examples
    --------
    >>> path_length([[0, 0], [3, 4], [3, 5]])
    6.0
    """
    pts = raster.as_polyline(path)
    return float(np.sum(np.hypot(*np.diff(pts, axis=0).T)))


def _headings(pts):
    """Unit directions of the non-zero-length segments, shape (S, 2)."""
    d = np.diff(pts, axis=0)
    length = np.hypot(d[:, 0], d[:, 1])
    keep = length > MIN_SEGMENT_LENGTH_M
    return d[keep] / length[keep, None], np.flatnonzero(keep)


def turning_angle_deg(path):
    """Total absolute heading change along a polyline.

    Parameters
    ----------
    path : array_like, shape (N, 2)
        ``(x, y)`` [m], map frame, N >= 1.

    Returns
    -------
    float
        Sum over consecutive non-zero-length segments of the absolute
        change of heading, each in [0, 180] [deg] (the paper's "turning
        angle", Tables 1-2).

    Raises
    ------
    InvalidInput
        If ``path`` is not a finite ``(N, 2)`` array with N >= 1.

    Examples
    --------
    >>> turning_angle_deg([[0, 0], [1, 0], [1, 1]])
    90.0
    >>> turning_angle_deg([[0, 0], [1, 0], [1, 0], [2, 0]])
    0.0
    """
    pts = raster.as_polyline(path)
    u, _ = _headings(pts)
    if len(u) < 2:
        return 0.0
    cross = u[:-1, 0] * u[1:, 1] - u[:-1, 1] * u[1:, 0]
    dot = np.sum(u[:-1] * u[1:], axis=1)
    return float(np.degrees(np.sum(np.abs(np.arctan2(cross, dot)))))


def key_point_indices(path):
    """Indices of a polyline's key points: its ends and its turning vertices.

    Parameters
    ----------
    path : array_like, shape (N, 2)
        ``(x, y)`` [m], map frame, N >= 1.

    Returns
    -------
    ndarray, int64, shape (K,)
        Increasing indices: 0, N - 1, and every vertex where the heading of
        the path changes. Collinear vertices and repeated points are dropped
        (a reversal is a change). All indices when N <= 2.

    Raises
    ------
    InvalidInput
        If ``path`` is not a finite ``(N, 2)`` array with N >= 1.

    Notes
    -----
    The count of these is the "key points" of the paper's Table 2 for a raw
    grid path; for a refined path the planner reports its pruned nodes.

    Examples
    --------
    >>> key_point_indices([[0, 0], [1, 0], [2, 0], [2, 1], [2, 2]]).tolist()
    [0, 2, 4]
    """
    pts = raster.as_polyline(path)
    n = len(pts)
    if n <= 2:
        return np.arange(n, dtype=np.int64)
    u, seg = _headings(pts)
    if len(u) < 2:
        return np.array([0, n - 1], dtype=np.int64)
    cross = u[:-1, 0] * u[1:, 1] - u[:-1, 1] * u[1:, 0]
    dot = np.sum(u[:-1] * u[1:], axis=1)
    turns = (np.abs(cross) > COLLINEAR_SINE_TOLERANCE) | (dot < 0)
    # The vertex of a turn is where the later segment starts.
    vertices = seg[1:][turns]
    return np.unique(np.concatenate([[0], vertices, [n - 1]]).astype(np.int64))


def min_clearance(grid, path):
    """Smallest clearance of the cells a path touches: ``min_clearance_m``.

    Parameters
    ----------
    grid : GridMap
    path : array_like, shape (N, 2)
        ``(x, y)`` [m], map frame, N >= 1.

    Returns
    -------
    float
        Minimum of :attr:`GridMap.clearance` over
        :func:`raster.path_cells` [m]; 0.0 if the path touches a cell
        outside the map; ``inf`` on a map without obstacles.

    Raises
    ------
    InvalidInput
        If ``path`` is not a finite ``(N, 2)`` array with N >= 1.

    Notes
    -----
    This is how ``min_clearance_m`` is defined throughout the project. It
    has cell resolution: it is the Euclidean distance from the *centre* of
    a touched cell to the centre of the nearest obstacle cell (the grid's
    EDT), taken over every cell whose closed square the path touches
    (exact supercover, diagonal corners included). It is therefore not the
    continuous distance from the path to the obstacle boundary, which can
    be smaller by up to about one cell. A path is collision-free for a
    robot of radius ``r`` in the sense used by the search exactly when this
    value is ``> r``.

    Examples
    --------
    >>> import numpy as np
    >>> from fusion_planner.core.grid import GridMap
    >>> occupied = np.zeros((5, 5), bool); occupied[2, 4] = True
    >>> grid = GridMap(occupied, resolution=1.0)
    >>> min_clearance(grid, [[0.5, 0.5], [0.5, 4.5]])
    4.0
    """
    pts = raster.as_polyline(path)
    g = grid.world_to_grid(pts)
    ga, gb = (g, g) if len(g) == 1 else (g[:-1], g[1:])
    # The cells of raster.path_cells, with repetitions: no sort needed for a minimum.
    cells, _ = raster.supercover_grid(ga, gb, grid.shape)
    if not grid.contains(cells).all():
        return 0.0
    return float(grid.clearance_of_cells(cells).min())
