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
(:attr:`GridMap.clearance`, as the inflation uses), computed on windows around
the path and interpolated bilinearly between cell centres.

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

#: Path points centred together (one clearance window per piece).
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
    for first in range(1, len(path) - 1, PIECE_POINTS):
        last = min(first + PIECE_POINTS, len(path) - 1)
        _centre_piece(grid, path, first, last, robot_radius, target)
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


def _centre_piece(grid, path, first, last, robot_radius, target):
    """Centre ``path[first:last]`` in place, its neighbours fixed."""
    res = grid.resolution
    margin = int(math.ceil(target / res)) + 2
    cells = grid.world_to_grid(path[first - 1:last + 1])        # (x, y) continuous, cell units
    col0 = max(int(np.floor(cells[:, 0].min())) - margin, 0)
    row0 = max(int(np.floor(cells[:, 1].min())) - margin, 0)
    col1 = min(int(np.ceil(cells[:, 0].max())) + margin + 1, grid.width)
    row1 = min(int(np.ceil(cells[:, 1].max())) + margin + 1, grid.height)
    occupied = grid.occupied[row0:row1, col0:col1]
    if not occupied.any() or min(occupied.shape) < 2:
        return      # nothing to keep away from, or a one-cell-wide map with no room to move
    # clearance of the window's cell centres; beyond the window counts as occupied
    padded = np.pad(~occupied, 1, constant_values=False)
    clearance = ndimage.distance_transform_edt(padded)[1:-1, 1:-1] * res
    grad_row, grad_col = np.gradient(clearance)
    origin = np.array([col0, row0], float)
    yaw = grid.origin[2]
    rotation = np.array([[math.cos(yaw), -math.sin(yaw)], [math.sin(yaw), math.cos(yaw)]])

    def local(pts):
        """Map-frame points [m] as window ``(col, row)`` [cells]."""
        return grid.world_to_grid(pts) - origin

    def sample(field, at):
        """``field`` at window points ``at``, bilinear between cell centres."""
        return ndimage.map_coordinates(field, [at[:, 1] - 0.5, at[:, 0] - 0.5], order=1,
                                       mode='nearest')

    # a point's window position and clearance carry over to the next
    # iteration unless it moves
    here = local(path[first:last])
    before = sample(clearance, here)
    for _ in range(ITERATIONS):
        inner = path[first:last]
        tangent = path[first + 1:last + 1] - path[first - 1:last - 1]
        tangent /= np.maximum(np.hypot(tangent[:, 0], tangent[:, 1]), 1e-12)[:, None]
        normal = np.column_stack([-tangent[:, 1], tangent[:, 0]])
        gradient = np.column_stack([sample(grad_col, here), sample(grad_row, here)]) @ rotation.T
        climb = np.einsum('ij,ij->i', gradient, normal)
        climb = np.where(before < target, np.sign(climb) * np.minimum(np.abs(climb) / res, 1.0),
                         0.0)
        midpoint = 0.5 * (path[first - 1:last - 1] + path[first + 1:last + 1]) - inner
        smooth = SMOOTHING * np.einsum('ij,ij->i', midpoint, normal)
        step = np.clip(climb * STEP_CELLS * res + smooth, -STEP_CELLS * res, STEP_CELLS * res)
        moved = inner + step[:, None] * normal
        there = local(moved)
        after = sample(clearance, there)
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
