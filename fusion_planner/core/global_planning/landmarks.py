"""Landmark lower bounds for the exact A* (the ALT heuristic), prepared once per map.

The octile distance ignores obstacles: on a map of scattered cells it falls
12 % short of the true cost corner to corner (1024 x 1024 cells, 20 %
blocked), and an exact A* must expand every cell whose ``g + h`` is below
the optimum, about 300,000 there. The true costs from a few landmark cells
tighten it: by the triangle inequality ``|d(L, n) - d(L, goal)|`` is a lower
bound on ``d(n, goal)`` for every landmark L, and so is the largest of them
and the octile distance; the bound is consistent, so A* stays exact
(Goldberg and Harrelson, "Computing the Shortest Path: A* Search Meets
Graph Theory", SODA 2005).

It pays where a landmark lies behind the goal or the start as seen from the
other: a goal near a map corner, a room at the end of a building. Between
two cells in the middle of the map it gains little over the octile distance
(docs/BENCHMARKS.md has both). The cost is one Dijkstra search over the
whole map per landmark, plus one to place the first, and 8 bytes per cell
per landmark; so only maps of at most :data:`MAX_CELLS` cells get them.

Landmarks are placed farthest first, in the largest free component: the
first is the cell farthest from its cell nearest the map's centre, each next one the cell farthest
from all landmarks so far (on a square map, the corners first).
"""

import numpy as np
from scipy import ndimage

from fusion_planner.core.global_planning import kernel, search

#: Landmarks per map.
COUNT = 4

#: Largest map [cells] that gets landmarks: five whole-map Dijkstra searches
#: take about 0.7 s CPU and the table 32 MB at this size (1024 x 1024).
MAX_CELLS = 1 << 20


def wanted(shape, policy):
    """Whether a map of ``shape`` (rows, cols) gets landmarks for searches of ``policy``.

    When the policy uses them (``SearchPolicy.landmarks``), the map is
    small enough, and the compiled loop computes them.
    """
    return policy.landmarks and kernel.AVAILABLE and shape[0] * shape[1] <= MAX_CELLS


def distance_table(grid, count=COUNT):
    """Costs from ``count`` landmarks to every padded cell of ``grid``.

    Parameters
    ----------
    grid : search.PaddedGrid
    count : int
        Number of landmarks, >= 1.

    Returns
    -------
    ndarray, float64, shape (padded cells, count)
        Row ``k``: the 8-neighbourhood cost [cells] from each landmark to
        cell ``k``; inf where a landmark does not reach (other components).
        None when the grid has no traversable cell.
    """
    free = np.frombuffer(grid.passable, dtype=np.uint8).reshape(-1, grid.width).astype(bool)
    labels, count_components = ndimage.label(free)  # 4-connected: what 8-moves without corner cutting reach
    if count_components == 0:
        return None
    largest = 1 + np.argmax(np.bincount(labels.ravel())[1:])
    cells = np.flatnonzero(labels.ravel() == largest)
    rows, cols = np.divmod(cells, grid.width)
    centre_row, centre_col = (np.array(free.shape) - 1) / 2
    seed = cells[np.argmin((rows - centre_row) ** 2 + (cols - centre_col) ** 2)]
    nearest = search.exhaustive_distances(grid, seed)
    columns = []
    for _ in range(count):
        landmark = int(np.argmax(np.where(np.isfinite(nearest), nearest, -1.0)))
        distances = search.exhaustive_distances(grid, landmark)
        columns.append(distances)
        nearest = distances if len(columns) == 1 else np.minimum(nearest, distances)
    return np.ascontiguousarray(np.stack(columns, axis=1))
