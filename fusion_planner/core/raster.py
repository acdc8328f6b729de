"""Which grid cells a straight segment touches (exact conservative supercover).

A segment's *supercover* is the set of cells whose closed square the segment
touches: every cell it crosses, both cells on either side when it runs along
a grid line, and all four cells around a grid corner it passes through. The
last case is what keeps a shortcut from slipping between two diagonal
obstacle cells. The computation is exact (no point sampling): the segment is
cut at every grid line it crosses, and each cut point and endpoint contributes
the (up to four) cells whose closed squares contain it. Any cell the segment
touches holds such a point on its boundary or contains a whole piece between
two cuts, whose ends are cut points, so nothing is missed.

Points are ``(x, y)`` [m] in the map frame and go through
:meth:`GridMap.world_to_grid`, so rotated map origins work. Cells are
``(row, col)`` int64 and may lie outside the grid; callers treat those as
blocked.

A coordinate within a hair (:data:`ON_LINE_TOLERANCE`, relative) of a grid
line counts as on it, so rounding errors can only add the neighbouring cell,
never drop one: the result is conservative.
"""

import numpy as np

from fusion_planner.core.errors import InvalidInput

#: Relative tolerance [cells per cell of coordinate magnitude] within which
#: a coordinate counts as lying on a grid line (both neighbours included).
ON_LINE_TOLERANCE = 1e-9

#: Segments are clipped to the grid grown by this many cells on each side
#: [cells]; what lies further out is outside the map anyway, and clipping
#: keeps a wild endpoint from producing billions of crossings.
CLIP_MARGIN_CELLS = 2


def as_polyline(points, name='path', min_points=1):
    """Validate a polyline and return it as a float64 ``(N, 2)`` array.

    Parameters
    ----------
    points : array_like, shape (N, 2)
        ``(x, y)`` [m], map frame.
    name : str
        Name used in the error message.
    min_points : int
        Smallest acceptable N.

    Returns
    -------
    ndarray, float64, shape (N, 2)

    Raises
    ------
    InvalidInput
        If the array is not ``(N, 2)`` with ``N >= min_points`` or holds a
        NaN or infinite coordinate.

    Examples
    --------
    >>> as_polyline([[0, 0], [1, 2]]).shape
    (2, 2)
    """
    try:
        arr = np.asarray(points, dtype=float)
    except (TypeError, ValueError):
        raise InvalidInput(f'{name} must be an (N, 2) array of numbers') from None
    if arr.ndim != 2 or arr.shape[1] != 2 or arr.shape[0] < min_points:
        raise InvalidInput(
            f'{name} must be an (N, 2) array with N >= {min_points}, got shape {arr.shape}')
    if not np.all(np.isfinite(arr)):
        raise InvalidInput(f'{name} must hold finite coordinates only')
    return arr


def _as_point(value, name):
    try:
        point = np.asarray(value, dtype=float).reshape(2)
    except (TypeError, ValueError):
        raise InvalidInput(f'{name} must be two numbers (x, y), got {value!r}') from None
    if not np.all(np.isfinite(point)):
        raise InvalidInput(f'{name} must be finite, got {point.tolist()}')
    return point


def _clip(ga, gb, shape):
    """Clip grid-coordinate segments to the grid grown by the margin.

    Returns the clipped ends and a mask of the segments that meet the box
    at all (the others lie wholly outside it).
    """
    lo = np.array([-CLIP_MARGIN_CELLS, -CLIP_MARGIN_CELLS], float)
    hi = np.array([shape[1] + CLIP_MARGIN_CELLS, shape[0] + CLIP_MARGIN_CELLS], float)
    if len(ga) and min(ga.min(), gb.min()) >= lo[0] and (np.maximum(ga, gb) <= hi).all():
        return ga, gb, np.ones(len(ga), bool)  # every end inside: nothing to clip
    d = gb - ga
    t0 = np.zeros(len(ga))
    t1 = np.ones(len(ga))
    meets = np.ones(len(ga), bool)
    for axis in (0, 1):  # Liang-Barsky
        still = d[:, axis] == 0
        meets &= ~still | ((ga[:, axis] >= lo[axis]) & (ga[:, axis] <= hi[axis]))
        with np.errstate(divide='ignore', invalid='ignore'):
            ta = (lo[axis] - ga[:, axis]) / d[:, axis]
            tb = (hi[axis] - ga[:, axis]) / d[:, axis]
        t0 = np.where(still, t0, np.maximum(t0, np.minimum(ta, tb)))
        t1 = np.where(still, t1, np.minimum(t1, np.maximum(ta, tb)))
    meets &= t0 <= t1
    ca = ga + t0[:, None] * d
    cb = ga + t1[:, None] * d
    # Unclipped ends stay bit-exact.
    ca = np.where((t0 == 0)[:, None], ga, ca)
    cb = np.where((t1 == 1)[:, None], gb, cb)
    return ca, cb, meets


def _cells_of_points(p):
    """Cells ``(row, col)`` whose closed squares contain grid points ``(col, row)``.

    Returns shape (4 * N, 2); duplicates where a point is not on a line.
    """
    nearest = np.rint(p)
    on_line = np.abs(p - nearest) <= ON_LINE_TOLERANCE * (1.0 + np.abs(p))
    high = np.where(on_line, nearest, np.floor(p))
    low = np.where(on_line, nearest - 1.0, high)
    rows = np.concatenate([low[:, 1], high[:, 1], low[:, 1], high[:, 1]])
    cols = np.concatenate([low[:, 0], low[:, 0], high[:, 0], high[:, 0]])
    return np.stack([rows, cols], axis=1).astype(np.int64)


def supercover_grid(ga, gb, shape):
    """Supercover of many segments given in continuous grid coordinates.

    Parameters
    ----------
    ga, gb : ndarray, float64, shape (M, 2)
        Segment ends ``(col, row)`` in cell units (as returned by
        :meth:`GridMap.world_to_grid`).
    shape : tuple of int
        ``(H, W)`` of the grid, for the clipping margin.

    Returns
    -------
    cells : ndarray, int64, shape (K, 2)
        ``(row, col)`` of touched cells, with repetitions.
    owner : ndarray, int64, shape (K,)
        Index of the segment each cell belongs to; every segment owns at
        least one cell.

    Notes
    -----
    Parts of a segment farther than :data:`CLIP_MARGIN_CELLS` outside the
    grid are clipped away; such a segment still owns outside cells (on the
    clip boundary), which is all a caller needs to see that it leaves the
    map. A segment wholly outside the clip box owns the cell(s) of its first
    end.
    """
    points, owners = _supercover_points(ga, gb, shape)
    p = np.concatenate(points)
    owner = np.concatenate(owners)
    return _cells_of_points(p), np.tile(owner, 4)


def _supercover_points(ga, gb, shape, max_crossings=None):
    """The cut points and ends of many segments, in groups.

    Returns two lists of the same length: arrays of grid points ``(col,
    row)`` shape (P, 2), and the owning segment of each point, shape (P,),
    non-decreasing within each group (the first group is the clipped starts,
    the second the clipped ends, then the crossings of each axis).

    With ``max_crossings``, only the crossings of at most that many grid
    lines per axis are kept, those nearest the start: the same points (the
    same arithmetic) as without the limit, so their cells are a subset of
    the segment's supercover.
    """
    ga = np.asarray(ga, dtype=float).reshape(-1, 2)
    gb = np.asarray(gb, dtype=float).reshape(-1, 2)
    m = len(ga)
    ca, cb, meets = _clip(ga, gb, shape)
    ca = np.where(meets[:, None], ca, ga)
    cb = np.where(meets[:, None], cb, ga)
    d = cb - ca
    lo = np.minimum(ca, cb)
    hi = np.maximum(ca, cb)
    first = np.floor(lo) + 1.0  # first integer line strictly above lo
    count = np.maximum(np.ceil(hi) - first, 0.0).astype(np.int64)  # lines strictly inside
    every = np.arange(m)
    points = [ca, cb]
    owners = [every, every]
    for axis in (0, 1):
        n = count[:, axis]
        skip = np.zeros(m, np.int64)
        if max_crossings is not None:
            # Keep the lines nearest the start: the lowest ones when the
            # segment runs up this axis, the highest ones when it runs down.
            kept = np.minimum(n, max_crossings)
            skip = np.where(d[:, axis] < 0, n - kept, 0)
            n = kept
        total = int(n.sum())
        if total == 0:
            continue
        seg = np.repeat(every, n)
        local = np.arange(total) - np.repeat(np.cumsum(n) - n, n) + skip[seg]
        k = first[seg, axis] + local
        t = (k - ca[seg, axis]) / d[seg, axis]
        p = ca[seg] + t[:, None] * d[seg]
        p[:, axis] = k  # exactly on the line it crosses
        points.append(p)
        owners.append(seg)
    return points, owners


def grid_segments_clearance(grid, ga, gb, max_crossings=None):
    """:func:`segments_clearance` for segments in continuous grid coordinates.

    Parameters
    ----------
    grid : GridMap
    ga, gb : ndarray, float64, shape (M, 2)
        Segment ends ``(col, row)`` in cell units
        (:meth:`GridMap.world_to_grid`), finite; not validated.
    max_crossings : int, optional
        Look only at the cells of both ends and of the first
        ``max_crossings`` grid lines crossed per axis from the start: a
        subset of the supercover, so the result is an upper bound of the
        segment's clearance, exact when the segment crosses no more lines.
        A cheap test that rules long segments out.

    Returns
    -------
    ndarray, float64, shape (M,)
        Smallest :attr:`GridMap.clearance` over each segment's supercover
        (or its subset); 0.0 where a touched cell lies outside the grid.

    Notes
    -----
    For callers that test many segments of one polyline (refinement): the
    conversion to grid coordinates is done once. The minimum is taken
    without sorting: each cut point's four cells first, then each group of
    points (owners already in order) per segment.
    """
    m = len(ga)
    out = np.full(m, np.inf)
    if m == 0:
        return out
    points, owners = _supercover_points(ga, gb, grid.shape, max_crossings)
    cells = _cells_of_points(np.concatenate(points))
    rows, cols = cells[:, 0], cells[:, 1]
    height, width = grid.shape
    inside = (rows >= 0) & (rows < height) & (cols >= 0) & (cols < width)
    values = np.zeros(len(cells))
    values[inside] = grid.clearance_of_cells(cells[inside])
    per_point = values.reshape(4, -1).min(axis=0)
    start = 0
    for index, owner in enumerate(owners):  # bounded: at most four groups
        group = per_point[start:start + len(owner)]
        start += len(owner)
        if index < 2:
            np.minimum(out, group, out=out)  # starts or ends: one per segment, in order
            continue
        firsts = np.flatnonzero(np.concatenate([[True], owner[1:] != owner[:-1]]))
        segments = owner[firsts]
        out[segments] = np.minimum(out[segments], np.minimum.reduceat(group, firsts))
    return out


def segment_cells(grid, a, b):
    """Cells a straight segment touches (conservative supercover).

    Parameters
    ----------
    grid : GridMap
    a, b : array_like, shape (2,)
        Segment ends ``(x, y)`` [m], map frame; ``a == b`` is allowed.

    Returns
    -------
    ndarray, int64, shape (n, 2)
        Unique ``(row, col)`` of every cell whose closed square the segment
        touches, sorted; cells outside the grid included.

    Raises
    ------
    InvalidInput
        If an end is not two finite numbers.

    Notes
    -----
    Exact, not sampled: see the module docstring. A segment through a cell
    corner returns all four cells around the corner; one along a grid line
    returns the cells on both sides.

    Examples
    --------
    >>> import numpy as np
    >>> from fusion_planner.core.grid import GridMap
    >>> grid = GridMap(np.zeros((4, 4), bool), resolution=1.0)
    >>> segment_cells(grid, (0.5, 0.5), (2.5, 0.5)).tolist()
    [[0, 0], [0, 1], [0, 2]]
    >>> segment_cells(grid, (0.5, 0.5), (1.5, 1.5)).tolist()
    [[0, 0], [0, 1], [1, 0], [1, 1]]
    """
    ga = grid.world_to_grid(_as_point(a, 'segment start'))[None, :]
    gb = grid.world_to_grid(_as_point(b, 'segment end'))[None, :]
    cells, _ = supercover_grid(ga, gb, grid.shape)
    return np.unique(cells, axis=0)


def path_cells(grid, path):
    """Unique cells touched by all segments of a polyline.

    Parameters
    ----------
    grid : GridMap
    path : array_like, shape (N, 2)
        ``(x, y)`` [m], map frame, N >= 1.

    Returns
    -------
    ndarray, int64, shape (n, 2)
        Unique ``(row, col)``, sorted; cells outside the grid included. For
        N == 1, the cell containing the point (the two or four cells sharing
        it when the point lies exactly on a cell edge or corner).

    Raises
    ------
    InvalidInput
        If ``path`` is not a finite ``(N, 2)`` array with N >= 1.

    Examples
    --------
    >>> import numpy as np
    >>> from fusion_planner.core.grid import GridMap
    >>> grid = GridMap(np.zeros((4, 4), bool), resolution=1.0)
    >>> path_cells(grid, [[0.5, 0.5], [0.5, 1.5], [1.5, 1.5]]).tolist()
    [[0, 0], [1, 0], [1, 1]]
    """
    pts = as_polyline(path)
    g = grid.world_to_grid(pts)
    if len(g) == 1:
        ga, gb = g, g
    else:
        ga, gb = g[:-1], g[1:]
    cells, _ = supercover_grid(ga, gb, grid.shape)
    return np.unique(cells, axis=0)


def segments_clearance(grid, starts, ends):
    """Smallest clearance [m] along each of many segments.

    Parameters
    ----------
    grid : GridMap
    starts, ends : array_like, shape (M, 2)
        Segment ends ``(x, y)`` [m], map frame.

    Returns
    -------
    ndarray, float64, shape (M,)
        For each segment, the minimum of :attr:`GridMap.clearance` over its
        :func:`segment_cells`; 0.0 when any of them lies outside the grid;
        ``inf`` on a map without obstacles.

    Raises
    ------
    InvalidInput
        If the arrays are not finite ``(M, 2)`` arrays of equal length.
    """
    a = as_polyline(starts, 'segment starts', min_points=0)
    b = as_polyline(ends, 'segment ends', min_points=0)
    if a.shape != b.shape:
        raise InvalidInput(f'segment starts and ends differ in shape: {a.shape} vs {b.shape}')
    if len(a) == 0:
        return np.full(0, np.inf)
    return grid_segments_clearance(grid, grid.world_to_grid(a), grid.world_to_grid(b))


def segment_clearance(grid, a, b):
    """Smallest clearance [m] of the cells a segment touches.

    Parameters
    ----------
    grid : GridMap
    a, b : array_like, shape (2,)
        Segment ends ``(x, y)`` [m], map frame.

    Returns
    -------
    float
        Minimum of :attr:`GridMap.clearance` over :func:`segment_cells`
        (cell-centre distance to the nearest obstacle cell centre); 0.0 if
        any touched cell lies outside the grid; ``inf`` on a map without
        obstacles.

    Examples
    --------
    >>> import numpy as np
    >>> from fusion_planner.core.grid import GridMap
    >>> occupied = np.zeros((5, 5), bool); occupied[4, 4] = True
    >>> grid = GridMap(occupied, resolution=1.0)
    >>> segment_clearance(grid, (0.5, 4.5), (2.5, 4.5))  # cells (4, 0)-(4, 2)
    2.0
    >>> segment_clearance(grid, (0.5, 0.5), (-0.5, 0.5))
    0.0
    """
    a = _as_point(a, 'segment start')
    b = _as_point(b, 'segment end')
    return float(segments_clearance(grid, a[None, :], b[None, :])[0])

