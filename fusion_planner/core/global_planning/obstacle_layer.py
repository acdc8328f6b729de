"""Obstacles a range sensor saw that the map does not show: marking and clearing.

The layer keeps, on the cells of a known :class:`~fusion_planner.core.grid.GridMap`,
the obstacles that laser returns reveal, so a global planner can plan around
an obstacle that closes the way the map left open, and forget it once it is
gone:

- **marking**: a cell holding a return is *seen*; it is *confirmed* (an
  obstacle to plan around) once it has been seen without a break for
  ``persistence_s``. A person walking by leaves a trail of cells, each seen
  too briefly to be confirmed;
- **clearing**: every cell a beam passed through before its return (or up to
  its range when it had none) is free now, and forgets it was seen.

Returns in cells the map already explains (within ``known_margin_cells`` of
an occupied cell, where a hit on a wall's face falls, or of the map's edge,
which bounds every plan as a wall does) are not marked, so a layer never
narrows a door the map shows. Only cells are kept that were
seen, as sorted flat indices: the layer's memory follows what the sensor
saw, not the map's size.

Times are seconds on the caller's clock; points are metres in the map frame.
"""

import math

import numpy as np

from fusion_planner.core.errors import InvalidInput
from fusion_planner.core.global_planning import beam_cells
from fusion_planner.core.grid import GridMap

#: Returns within this many cells of a map obstacle are explained by the map [cells].
DEFAULT_KNOWN_MARGIN_CELLS = 1.5
#: Ray samples per cell edge when clearing [1] (two: no cell a ray crosses
#: by more than half a cell edge is missed).
SAMPLES_PER_CELL = 2


class ObstacleLayer:
    """Sensor obstacles on the cells of a known map.

    Parameters
    ----------
    grid : GridMap
        The known map; the layer uses its cells and never changes it.
    persistence_s : float, optional
        Time [s] a cell must be seen without a break before it is confirmed,
        >= 0.
    mark_range : float, optional
        Returns farther than this from the sensor [m] are not marked (their
        position is the least certain); they still clear the cells before
        them. > 0.
    clear_range : float, optional
        Beams clear cells up to this distance [m] from the sensor, > 0.
    known_margin_cells : float, optional
        Returns within this many cells of an occupied map cell or of the
        map's edge are not marked, >= 0.

    Raises
    ------
    InvalidInput
        If ``grid`` is not a GridMap or a number is out of range.

    Examples
    --------
    >>> import numpy as np
    >>> from fusion_planner.core.grid import GridMap
    >>> layer = ObstacleLayer(GridMap(np.zeros((20, 20), bool), 0.1), persistence_s=0.5)
    >>> origin, hit = np.array([0.25, 1.05]), np.array([[1.55, 1.05]])
    >>> layer.update(origin, hit, np.array([True]), now=0.0)
    False
    >>> layer.update(origin, hit, np.array([True]), now=0.5)
    True
    >>> layer.confirmed_cells(0.5).tolist()
    [[10, 15]]
    """

    def __init__(self, grid, persistence_s=1.0, mark_range=3.0, clear_range=4.0,
                 known_margin_cells=DEFAULT_KNOWN_MARGIN_CELLS):
        if not isinstance(grid, GridMap):
            raise InvalidInput('ObstacleLayer needs a GridMap')
        for name, value, low_ok in (('persistence_s', persistence_s, True),
                                    ('mark_range', mark_range, False),
                                    ('clear_range', clear_range, False),
                                    ('known_margin_cells', known_margin_cells, True)):
            if not (isinstance(value, (int, float)) and math.isfinite(value)
                    and (value >= 0 if low_ok else value > 0)):
                raise InvalidInput(f'ObstacleLayer {name} must be a '
                                   f'{"non-negative" if low_ok else "positive"} number, got {value!r}')
        self.grid = grid
        self.persistence_s = float(persistence_s)
        self.mark_range = float(mark_range)
        self.clear_range = float(clear_range)
        self.known_margin_cells = float(known_margin_cells)
        self._seen = np.empty(0, dtype=np.int64)   # flat cell indices, sorted
        self._since = np.empty(0, dtype=float)     # first time of each unbroken sighting [s]
        self._confirmed = np.empty(0, dtype=np.int64)
        self._last_time = -math.inf

    def __len__(self):
        """Number of cells seen (confirmed or not)."""
        return len(self._seen)

    def reset(self):
        """Forget everything (e.g. after the clock jumped back)."""
        self._seen = np.empty(0, dtype=np.int64)
        self._since = np.empty(0, dtype=float)
        self._confirmed = np.empty(0, dtype=np.int64)
        self._last_time = -math.inf

    def update(self, origin, ends, hit, now):
        """Clear along the beams, mark their returns; whether the confirmed set changed.

        Parameters
        ----------
        origin : array_like, shape (2,)
            Sensor position ``(x, y)`` [m], map frame.
        ends : array_like, shape (N, 2)
            Where each beam ended [m], map frame: its return, or a point at
            its maximum range when it had none. Non-finite rows are ignored.
        hit : array_like of bool, shape (N,)
            Whether the beam ended on a return.
        now : float
            Time of the scan [s]. A time before the previous update resets
            the layer first (a clock reset).

        Returns
        -------
        bool
            Whether :meth:`confirmed_cells` at ``now`` differs from before.

        Raises
        ------
        InvalidInput
            If the shapes disagree or ``origin``/``now`` are not finite.
        """
        origin = np.asarray(origin, dtype=float).reshape(-1)
        ends = np.asarray(ends, dtype=float).reshape(-1, 2)
        hit = np.asarray(hit, dtype=bool).reshape(-1)
        if origin.shape != (2,) or not np.all(np.isfinite(origin)):
            raise InvalidInput(f'sensor origin must be two finite numbers, got {origin!r}')
        if len(hit) != len(ends):
            raise InvalidInput(f'{len(ends)} beam ends but {len(hit)} hit flags')
        if not math.isfinite(now):
            raise InvalidInput(f'scan time must be finite, got {now!r}')
        if now < self._last_time:
            self.reset()
        self._last_time = now
        finite = np.all(np.isfinite(ends), axis=1)
        ends, hit = ends[finite], hit[finite]
        marked = self._marked_cells(origin, ends[hit])
        cleared = self._cleared_cells(origin, ends, hit)
        # a return seen now wins over a beam grazing the same cell
        gone = np.isin(self._seen, cleared) & ~np.isin(self._seen, marked)
        self._seen, self._since = self._seen[~gone], self._since[~gone]
        new = np.setdiff1d(marked, self._seen, assume_unique=True)
        if len(new):
            seen = np.concatenate([self._seen, new])
            since = np.concatenate([self._since, np.full(len(new), float(now))])
            order = np.argsort(seen, kind='stable')
            self._seen, self._since = seen[order], since[order]
        confirmed = self._seen[now - self._since >= self.persistence_s]
        changed = not np.array_equal(confirmed, self._confirmed)
        self._confirmed = confirmed
        return changed

    def confirmed_cells(self, now=None):
        """``(row, col)`` of the confirmed cells, int64 (K, 2), sorted.

        Parameters
        ----------
        now : float, optional
            Evaluate persistence at this time [s]; default: the last update.
        """
        flat = self._confirmed if now is None else \
            self._seen[now - self._since >= self.persistence_s]
        return np.column_stack(np.unravel_index(flat, self.grid.shape)).astype(np.int64)

    def occupied(self):
        """The map's occupied cells plus the confirmed ones: bool (H, W), a new array."""
        occupied = np.array(self.grid.occupied, copy=True)
        occupied.ravel()[self._confirmed] = True
        return occupied

    # -- geometry ----------------------------------------------------------------

    def _flat_inside(self, points):
        """Sorted unique flat indices of the cells holding ``points`` that lie in the grid."""
        cells = self.grid.cell_of(points) if len(points) else np.empty((0, 2), np.int64)
        cells = cells[self.grid.contains(cells)]
        return _sorted_unique(cells[:, 0] * self.grid.width + cells[:, 1])

    def _marked_cells(self, origin, returns):
        """Cells of the returns within ``mark_range`` that the map does not explain."""
        if len(returns):
            returns = returns[np.hypot(*(returns - origin).T) <= self.mark_range]
        flat = self._flat_inside(returns)
        if len(flat):
            cells = np.column_stack(np.unravel_index(flat, self.grid.shape))
            # local distance transforms: no whole-map clearance for a few returns
            clearance = self.grid.clearance_of_cells(cells)
            edge = np.minimum(cells + 0.5, np.array(self.grid.shape) - cells - 0.5).min(axis=1)
            margin = self.known_margin_cells
            flat = flat[(clearance > margin * self.grid.resolution) & (edge > margin)]
        return flat

    def _cleared_cells(self, origin, ends, hit, compiled=True):
        """Cells the beams crossed: up to half a cell before a return, else to the range.

        The beams are sampled every half cell; ``compiled`` takes the cells
        of the samples with :mod:`beam_cells` when numba is installed (the
        same cells).
        """
        if not len(ends):
            return np.empty(0, dtype=np.int64)
        offset = ends - origin
        length = np.hypot(offset[:, 0], offset[:, 1])
        step = self.grid.resolution / SAMPLES_PER_CELL
        reach = np.minimum(np.where(hit, length - self.grid.resolution / 2, length),
                           self.clear_range)
        counts = np.maximum(np.floor(reach / step).astype(np.int64) + 1, 0)
        counts[(reach < 0) | (length == 0)] = 0  # a beam of length zero has no direction
        unit = np.divide(offset, length[:, None], out=np.zeros_like(offset),
                         where=length[:, None] > 0)
        flat = beam_cells.sampled_cells(self.grid, origin, unit, counts, step) \
            if compiled else None
        if flat is not None:
            return _sorted_unique(flat)
        beam = np.repeat(np.arange(len(ends)), counts)
        first = np.cumsum(counts) - counts
        along = (np.arange(len(beam)) - first[beam]) * step
        return self._flat_inside(origin + unit[beam] * along[:, None])


def _sorted_unique(flat):
    """The sorted distinct values of int64 ``flat``.

    A mask over the span of the values sorts and dedups in one pass, where
    ``np.unique`` sorts all of them (a scan's samples repeat each cell a few
    times).
    """
    if not len(flat):
        return flat
    low = flat.min()
    mask = np.zeros(flat.max() - low + 1, dtype=bool)
    mask[flat - low] = True
    return np.flatnonzero(mask) + low
