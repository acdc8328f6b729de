"""Centring a path in its free corridor: clearance where there is room, the middle where not.

The search inflates obstacles by the robot radius only, and the refinement
keeps ``safety_distance`` only where the search path itself kept it: a plan
may graze a door post, run along one wall of a passage, or thread a post
field a few millimetres from every post. A local controller needs room for
its tracking error, so :func:`centre_path` moves each point of a refined path
across the path, up the clearance gradient, until it has
``robot_radius + safety_distance`` of clearance or stands on the ridge of the
corridor (its middle), smoothing as it goes (an elastic band). No point ever
loses clearance it had, nor is moved where a point of the path could not be:
the path stays inside the cells the search found free. This runs after the
search, on the path only; the search's inner loop is untouched.

The clearance is the map's distance from cell centres to occupied cell centres
(:attr:`GridMap.clearance`, as the inflation uses), interpolated bilinearly
between cell centres. When the map's whole clearance is prepared (the
planner's ``prepare``), the whole path is one band read from it; otherwise
pieces of :data:`PIECE_POINTS` points are centred one after the other, each
on the clearance of a window around it.

Examples
--------
>>> import numpy as np
>>> from fusion_planner.core.grid import GridMap
>>> occupied = np.zeros((20, 60), bool); occupied[:, :2] = occupied[:, -2:] = True
>>> occupied[:2, :] = occupied[-2:, :] = True            # a 1.6 m wide corridor
>>> grid = GridMap(occupied, 0.1)
>>> path = np.column_stack([np.linspace(0.5, 5.5, 51), np.full(51, 0.45)])   # along a wall
>>> centred = centre_path(grid, path, robot_radius=0.2, safety_distance=0.3)
>>> bool(np.all(grid.clearance_at(centred[5:-5]) >= grid.clearance_at(path[5:-5])))
True
>>> round(float(np.median(centred[:, 1])), 1)            # moved off the wall
0.7
"""

import math

import numpy as np
from scipy import ndimage

from fusion_planner.core import raster

#: Path points centred together when the clearance is computed on windows
#: (one window per piece).
PIECE_POINTS = 400

#: Iterations of the elastic band.
ITERATIONS = 60

#: Largest move of a point per iteration, in cells.
STEP_CELLS = 0.25

#: Weight of the smoothing pull toward the neighbours' midpoint, per iteration.
SMOOTHING = 0.3


def centre_path(grid, path, robot_radius, safety_distance):
    """Centre a path in its free corridor up to ``robot_radius + safety_distance`` of clearance.

    Parameters
    ----------
    grid : GridMap
    path : ndarray, float64, shape (N, 2)
        A refined path [m], map frame, points at most a cell apart.
    robot_radius, safety_distance : float
        [m], >= 0.

    Returns
    -------
    ndarray, float64, shape (N, 2)
        The path with its end points unchanged and every other point moved
        across the path: up the clearance while it has less than
        ``robot_radius + safety_distance``, and toward its neighbours'
        midpoint, never losing clearance below that sum and never into a
        cell of clearance ``<= robot_radius``; the path itself when the sum
        is 0.
    """
    path = np.array(path, dtype=float, copy=True)
    if len(path) < 3:
        return path
    target = robot_radius + safety_distance
    if target <= 0.0:
        return path
    original = path.copy()
    if grid.clearance_ready:
        if not math.isinf(grid.clearance.flat[0]):  # inf everywhere: nothing occupied
            _centre_piece(grid, path, 1, len(path) - 1, robot_radius, target,
                          grid.clearance, (0, 0))
    else:
        for first in range(1, len(path) - 1, PIECE_POINTS):
            last = min(first + PIECE_POINTS, len(path) - 1)
            window = _window_clearance(grid, path[first - 1:last + 1], target)
            if window is not None:
                _centre_piece(grid, path, first, last, robot_radius, target, *window)
    return _without_new_contacts(grid, original, path, robot_radius)


def _without_new_contacts(grid, original, centred, robot_radius):
    """Put back the moved ends of every segment that now touches a cell the robot cannot be in.

    The band checks points only; two points in free cells can still span a
    segment across an obstacle's corner. Putting a point back can make its
    other segment bad, so this repeats; it ends at the latest with the
    original segments.
    """
    moved = np.any(centred != original, axis=1)
    while True:
        clear = raster.segments_clearance(grid, centred[:-1], centred[1:])
        bad = np.flatnonzero(clear <= robot_radius)
        ends = np.zeros(len(centred), bool)
        ends[bad] = ends[bad + 1] = True
        ends &= moved
        if not ends.any():
            return centred
        centred[ends] = original[ends]
        moved &= ~ends


def _window_clearance(grid, points, target):
    """Clearance [m] of the cells around ``points`` and the window's ``(col0, row0)``.

    Beyond the window counts as occupied; the window reaches a few cells
    farther than ``target`` from every point, so the clearances the band
    reads are exact. None when there is nothing to keep away from, or on a
    one-cell-wide map with no room to move.
    """
    res = grid.resolution
    margin = int(math.ceil(target / res)) + 2
    cells = grid.world_to_grid(points)                          # (x, y) continuous, cell units
    col0 = max(int(np.floor(cells[:, 0].min())) - margin, 0)
    row0 = max(int(np.floor(cells[:, 1].min())) - margin, 0)
    col1 = min(int(np.ceil(cells[:, 0].max())) + margin + 1, grid.width)
    row1 = min(int(np.ceil(cells[:, 1].max())) + margin + 1, grid.height)
    occupied = grid.occupied[row0:row1, col0:col1]
    if not occupied.any() or min(occupied.shape) < 2:
        return None
    padded = np.pad(~occupied, 1, constant_values=False)
    return ndimage.distance_transform_edt(padded)[1:-1, 1:-1] * res, (col0, row0)


def _bilinear(clearance, at):
    """Clearance at ``at`` and its gradient along columns and rows [m per cell].

    ``at``: ``(col, row)`` [cells] from the corner of ``clearance``. Bilinear
    between cell centres, edge values beyond the edges (scipy's
    ``map_coordinates(order=1, mode='nearest')``); the gradient is the
    bilinear interpolation of the central differences (``np.gradient``
    inside), read from the 12 cells around each point without a gradient
    map.
    """
    height, width = clearance.shape
    flat = clearance.ravel()
    col = at[:, 0] - 0.5
    row = at[:, 1] - 0.5
    col0 = np.floor(col)
    row0 = np.floor(row)
    fc = col - col0
    fr = row - row0
    col0 = col0.astype(np.int64)
    row0 = row0.astype(np.int64)
    rows = {d: np.clip(row0 + d, 0, height - 1) * width for d in (-1, 0, 1, 2)}
    cols = {d: np.clip(col0 + d, 0, width - 1) for d in (-1, 0, 1, 2)}
    shifts = ((0, 0), (0, 1), (0, -1), (1, 0), (-1, 0))   # the value, then the differences
    corners = {(r + dr, c + dc) for r, c in shifts for dr in (0, 1) for dc in (0, 1)}
    cells = {(r, c): flat[rows[r] + cols[c]] for r, c in corners}   # 12 cells, each read once

    def mix(r, c):
        """Bilinear value with the four corners shifted by ``(r, c)`` cells."""
        top = cells[r, c] + fc * (cells[r, c + 1] - cells[r, c])
        bottom = cells[r + 1, c] + fc * (cells[r + 1, c + 1] - cells[r + 1, c])
        return top + fr * (bottom - top)

    value, right, left, down, up = (mix(r, c) for r, c in shifts)
    return value, 0.5 * (right - left), 0.5 * (down - up)


def _centre_piece(grid, path, first, last, robot_radius, target, clearance, corner):
    """Centre ``path[first:last]`` in place, its neighbours fixed.

    ``clearance`` [m] holds the cells from ``corner = (col0, row0)`` on and
    covers every cell the piece can reach.
    """
    res = grid.resolution
    origin = np.array(corner, float)
    yaw = grid.origin[2]
    rotation = np.array([[math.cos(yaw), -math.sin(yaw)], [math.sin(yaw), math.cos(yaw)]])

    def local(pts):
        """Map-frame points [m] as ``(col, row)`` [cells] from the corner."""
        return grid.world_to_grid(pts) - origin

    # a point's position, clearance and gradient carry over to the next
    # iteration unless it moves
    here = local(path[first:last])
    before, grad_col, grad_row = _bilinear(clearance, here)
    for _ in range(ITERATIONS):
        inner = path[first:last]
        tangent = path[first + 1:last + 1] - path[first - 1:last - 1]
        tangent /= np.maximum(np.hypot(tangent[:, 0], tangent[:, 1]), 1e-12)[:, None]
        normal = np.column_stack([-tangent[:, 1], tangent[:, 0]])
        gradient = np.column_stack([grad_col, grad_row]) @ rotation.T
        climb = np.einsum('ij,ij->i', gradient, normal)
        climb = np.where(before < target, np.sign(climb) * np.minimum(np.abs(climb) / res, 1.0),
                         0.0)
        midpoint = 0.5 * (path[first - 1:last - 1] + path[first + 1:last + 1]) - inner
        smooth = SMOOTHING * np.einsum('ij,ij->i', midpoint, normal)
        step = np.clip(climb * STEP_CELLS * res + smooth, -STEP_CELLS * res, STEP_CELLS * res)
        moved = inner + step[:, None] * normal
        there = local(moved)
        after, moved_col, moved_row = _bilinear(clearance, there)
        cells = np.floor(there).astype(np.int64)
        inside = np.all((cells >= 0) & (cells < [clearance.shape[1], clearance.shape[0]]), axis=1)
        cell_clearance = np.zeros(len(moved))
        cell_clearance[inside] = clearance[cells[inside, 1], cells[inside, 0]]
        keep = (after >= np.minimum(before, target)) & (cell_clearance > robot_radius)
        if not np.any(keep):
            break
        path[first:last][keep] = moved[keep]
        here[keep] = there[keep]
        before[keep] = after[keep]
        grad_col[keep] = moved_col[keep]
        grad_row[keep] = moved_row[keep]
