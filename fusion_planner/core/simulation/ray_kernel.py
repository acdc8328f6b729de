"""The simulated laser's grid traversal, compiled with numba when it is installed.

:func:`first_blocked` walks each ray's grid-line crossings in order (the
cell traversal of Amanatides and Woo) and stops at the first that enters a
blocked cell: the same crossings, computed by the same expressions, as the
array version :func:`~fusion_planner.core.simulation.world.ray_grid_distances`
examines chunk by chunk, so both return the same distances to the bit. A
ray stops at its first hit here, where the array version also looks up the
cells of the rest of its chunk: 360 beams on the demo map take 0.02 ms
instead of 0.6 ms.

numba is optional (the ``fast`` extra, see :mod:`fusion_planner.core.compiled`):
without it :func:`first_blocked` answers None and the simulator uses the
array version.
"""

import math

import numpy as np

from fusion_planner.core.compiled import LazyLoop


def first_blocked(occupied, origin, directions, max_distance):
    """Distance along rays to the first occupied cell or the grid edge, compiled.

    Parameters
    ----------
    occupied : ndarray of bool, shape (H, W)
    origin : ndarray, shape (2,)
        ``(col, row)`` of the ray origin, grid units, inside the grid and in
        a free cell (the caller answers the other cases).
    directions : ndarray, shape (n, 2)
        Unit directions in grid coordinates ``(dcol, drow)``.
    max_distance : float
        Ignore hits beyond this distance [cells].

    Returns
    -------
    ndarray, float64, shape (n,) or None
        Distance [cells] at which each ray enters an occupied cell or leaves
        the grid, ``inf`` beyond ``max_distance``. None without numba.
    """
    walk = _WALK.load()
    if walk is None:
        return None
    out = np.empty(len(directions))
    px, py = float(origin[0]), float(origin[1])
    walk(np.ascontiguousarray(occupied, dtype=np.bool_), px, py,
                   float(math.floor(px)), float(math.floor(py)),
                   np.ascontiguousarray(directions, dtype=np.float64), float(max_distance), out)
    return out


def _walk(occupied, px, py, cx, cy, directions, max_distance, out):
    """Per ray, ``out[i]``: the first crossing into a blocked cell [cells], inf past the range.

    A cell is blocked when occupied or outside the grid. The crossings of
    the vertical lines lie at ``x_first + x_delta * k`` (the horizontal ones
    alike), with the array version's expressions.
    """
    height, width = occupied.shape
    for i in range(directions.shape[0]):
        dx, dy = directions[i, 0], directions[i, 1]
        x_step = 1.0 if dx > 0 else -1.0
        y_step = 1.0 if dy > 0 else -1.0
        x_delta = 1.0 / abs(dx) if dx != 0 else math.inf
        y_delta = 1.0 / abs(dy) if dy != 0 else math.inf
        x_first = (cx + 1 - px) / dx if dx > 0 else ((px - cx) / -dx if dx < 0 else math.inf)
        y_first = (cy + 1 - py) / dy if dy > 0 else ((py - cy) / -dy if dy < 0 else math.inf)
        kx, ky = 0.0, 0.0  # crossings passed on each family (floats, as the array version)
        out[i] = math.inf
        while True:
            tx = x_first + x_delta * kx if dx != 0 else math.inf
            ty = y_first + y_delta * ky if dy != 0 else math.inf
            if tx <= ty:
                t = tx
                col = int(cx + x_step * (kx + 1.0))
                row = int(math.floor(py + t * dy))
                kx += 1.0
            else:
                t = ty
                row = int(cy + y_step * (ky + 1.0))
                col = int(math.floor(px + t * dx))
                ky += 1.0
            if not t <= max_distance:
                break
            if col < 0 or col >= width or row < 0 or row >= height or occupied[row, col]:
                out[i] = t
                break


_WALK = LazyLoop(_walk)


def available():
    """Whether the compiled traversal can be used (numba installed and importable)."""
    return _WALK.available
