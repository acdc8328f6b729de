"""How long each map cell has been hit without a break by returns the map does not explain.

A person leaves every cell it passes within a second or so; a static object
missing from the map keeps being hit in the same cells for as long as it is
in view. :class:`HitAges` keeps, per cell, when its current run of hits
began, so a tracker can tell an object that stays put (its returns fall in
old cells, however its centre estimate shifts as the view changes) from one
that moves.

Only cells hit recently are stored (sorted flat indices), so the memory
follows what the laser sees, not the map's size. Times are seconds on the
caller's clock; points are metres in the map frame.

Examples
--------
>>> import numpy as np
>>> from fusion_planner.core.grid import GridMap
>>> ages = HitAges(GridMap(np.zeros((20, 20), bool), 0.1), break_s=0.3)
>>> wall = np.array([[1.05, 1.05]])
>>> [round(float(ages.update(wall, t)[0]), 3) for t in (0.0, 0.2, 0.4, 1.0)]   # a break
[0.0, 0.2, 0.4, 0.0]
"""

import numpy as np


class HitAges:
    """Age of each cell's current run of hits.

    Parameters
    ----------
    grid : GridMap
        Its cells are the cells of the memory (points off the map are kept
        in the nearest edge cell).
    break_s : float
        A cell not hit for longer than this [s] starts a new run.
    """

    def __init__(self, grid, break_s):
        self.grid = grid
        self.break_s = float(break_s)
        self._cells = np.zeros(0, np.int64)
        self._first = np.zeros(0)
        self._last = np.zeros(0)

    def update(self, points, now):
        """Record hits at ``points`` (N, 2) at time ``now``; the age [s] of each one's cell."""
        g = np.floor(self.grid.world_to_grid(points)).astype(np.int64)
        cols = np.clip(g[:, 0], 0, self.grid.width - 1)
        rows = np.clip(g[:, 1], 0, self.grid.height - 1)
        flat = rows * self.grid.width + cols
        # forget runs that broke off, then refresh the hit cells and add the new ones
        alive = now - self._last <= self.break_s
        cells, first, last = self._cells[alive], self._first[alive], self._last[alive]
        hit = np.unique(flat)
        pos = np.searchsorted(cells, hit)
        known = pos < len(cells)
        known[known] = cells[pos[known]] == hit[known]
        last[pos[known]] = now
        fresh = hit[~known]
        cells = np.concatenate([cells, fresh])
        first = np.concatenate([first, np.full(len(fresh), float(now))])
        last = np.concatenate([last, np.full(len(fresh), float(now))])
        order = np.argsort(cells, kind='stable')
        self._cells, self._first, self._last = cells[order], first[order], last[order]
        return now - self._first[np.searchsorted(self._cells, flat)]
