"""Occupancy grid model: obstacles, clearance, inflation, cell <-> world.

Conventions (REP-103, the same as nav_msgs/OccupancyGrid):

- A grid is an ``(H, W)`` array indexed ``[row, col]``; row 0 is the row at
  the map origin (lowest y in the map frame when the origin yaw is 0), column
  0 the column at the origin. Image files (PGM, PNG, MovingAI ``.map``) store
  the top row first; their loaders flip them (see :mod:`map_files`).
- ``resolution`` is the cell edge in metres; the origin ``(x, y, yaw)`` is the
  pose of the corner of cell ``(0, 0)`` in the map frame [m, m, rad].
- Clearance is the Euclidean distance [m] from a cell centre to the centre of
  the nearest occupied cell (``scipy.ndimage.distance_transform_edt`` with
  ``sampling=resolution``); it is 0 on occupied cells and ``inf`` on a map
  without obstacles. It is computed once per map, on first use.
- A cell is *traversable* for an inflation radius ``r`` [m] when its
  clearance is strictly greater than ``r``: with ``r = 0`` every free cell is
  traversable; with the robot radius, every cell where a disc of that radius
  centred on the cell centre misses all occupied cell centres.
"""

import math

import numpy as np
from scipy import ndimage

from fusion_planner.core.errors import InvalidInput, MapError

#: Default cap on the number of cells of a map (4000 x 4000 fits). Larger
#: maps are refused rather than risking the memory of the process.
DEFAULT_MAX_CELLS = 16_000_000


class GridMap:
    """A static occupancy grid with lazily computed clearance.

    Parameters
    ----------
    occupied : array_like of bool, shape (H, W)
        True where a cell is an obstacle (unknown cells already resolved by
        the caller's policy).
    resolution : float
        Cell edge [m], finite and > 0.
    origin : tuple of float, optional
        ``(x, y, yaw)`` of the corner of cell ``(0, 0)`` in the map frame
        [m, m, rad]. Default ``(0, 0, 0)``.
    unknown : array_like of bool, shape (H, W), optional
        Cells whose state was unknown in the source (kept for drawing only).
    max_cells : int, optional
        Refuse maps with more than this many cells.

    Raises
    ------
    MapError
        If the array is not 2-D and non-empty, the resolution is not a
        positive finite number, the origin is not finite, or the map has more
        than ``max_cells`` cells.

    Examples
    --------
    >>> import numpy as np
    >>> grid = GridMap(np.zeros((3, 4), bool), resolution=0.5, origin=(1.0, 2.0, 0.0))
    >>> grid.shape
    (3, 4)
    >>> grid.cell_of(np.array([[1.6, 2.1]])).tolist()
    [[0, 1]]
    >>> grid.world_of(np.array([[0, 1]])).tolist()
    [[1.75, 2.25]]
    """

    def __init__(self, occupied, resolution, origin=(0.0, 0.0, 0.0),
                 unknown=None, max_cells=DEFAULT_MAX_CELLS):
        occupied = np.asarray(occupied)
        if occupied.ndim != 2 or occupied.size == 0:
            raise MapError(
                f'a map must be a non-empty 2-D array, got shape {occupied.shape}')
        if occupied.size > max_cells:
            raise MapError(
                f'map of {occupied.shape[1]} x {occupied.shape[0]} cells exceeds '
                f'the limit of {max_cells} cells')
        if not _is_finite_number(resolution) or resolution <= 0:
            raise MapError(f'map resolution must be a positive number of metres, got {resolution!r}')
        if len(origin) != 3 or not all(_is_finite_number(v) for v in origin):
            raise MapError(f'map origin must be three finite numbers (x, y, yaw), got {origin!r}')
        self.occupied = np.ascontiguousarray(occupied, dtype=bool)
        self.occupied.setflags(write=False)
        self.resolution = float(resolution)
        self.origin = tuple(float(v) for v in origin)
        self.unknown = None if unknown is None else np.asarray(unknown, dtype=bool)
        self._cos = math.cos(self.origin[2])
        self._sin = math.sin(self.origin[2])
        self._clearance = None
        self._traversable = {}

    # -- shape and geometry -------------------------------------------------

    @property
    def shape(self):
        """``(H, W)``: rows, columns."""
        return self.occupied.shape

    @property
    def height(self):
        """Number of rows H."""
        return self.occupied.shape[0]

    @property
    def width(self):
        """Number of columns W."""
        return self.occupied.shape[1]

    def world_to_grid(self, points):
        """Continuous grid coordinates of map-frame points.

        Parameters
        ----------
        points : array_like, shape (N, 2) or (2,)
            ``(x, y)`` [m], map frame.

        Returns
        -------
        ndarray, float64, same shape
            ``(col, row)`` in cell units: cell ``(r, c)`` covers
            ``c <= col < c + 1``, ``r <= row < r + 1``.
        """
        pts = np.asarray(points, dtype=float)
        dx = pts[..., 0] - self.origin[0]
        dy = pts[..., 1] - self.origin[1]
        col = (self._cos * dx + self._sin * dy) / self.resolution
        row = (-self._sin * dx + self._cos * dy) / self.resolution
        return np.stack([col, row], axis=-1)

    def grid_to_world(self, grid_points):
        """Map-frame points of continuous grid coordinates ``(col, row)``."""
        g = np.asarray(grid_points, dtype=float) * self.resolution
        x = self.origin[0] + self._cos * g[..., 0] - self._sin * g[..., 1]
        y = self.origin[1] + self._sin * g[..., 0] + self._cos * g[..., 1]
        return np.stack([x, y], axis=-1)

    def cell_of(self, points):
        """Cells ``(row, col)`` containing map-frame points.

        Parameters
        ----------
        points : array_like, shape (N, 2) or (2,)
            ``(x, y)`` [m], map frame. Must be finite.

        Returns
        -------
        ndarray, int64, same shape
            ``(row, col)``; may lie outside the grid (see :meth:`contains`).

        Raises
        ------
        InvalidInput
            If any coordinate is NaN or infinite.
        """
        pts = np.asarray(points, dtype=float)
        if not np.all(np.isfinite(pts)):
            raise InvalidInput(f'coordinates must be finite numbers, got {pts.tolist()}')
        g = np.floor(self.world_to_grid(pts)).astype(np.int64)
        return g[..., ::-1]

    def world_of(self, cells):
        """Map-frame centres [m] of cells ``(row, col)``, shape (N, 2) or (2,)."""
        c = np.asarray(cells, dtype=float)
        return self.grid_to_world(c[..., ::-1] + 0.5)

    def contains(self, cells):
        """Whether cells ``(row, col)`` lie inside the grid; bool array."""
        c = np.asarray(cells)
        return ((c[..., 0] >= 0) & (c[..., 0] < self.height)
                & (c[..., 1] >= 0) & (c[..., 1] < self.width))

    def bounds(self):
        """``(xmin, xmax, ymin, ymax)`` [m] of the map's footprint, map frame."""
        corners = self.grid_to_world(np.array(
            [[0, 0], [self.width, 0], [0, self.height], [self.width, self.height]], float))
        return (corners[:, 0].min(), corners[:, 0].max(),
                corners[:, 1].min(), corners[:, 1].max())

    # -- clearance and inflation --------------------------------------------

    @property
    def clearance(self):
        """Distance [m] from each cell centre to the nearest occupied cell centre.

        Returns
        -------
        ndarray, float64, shape (H, W)
            0 on occupied cells; ``inf`` everywhere when nothing is occupied.
        """
        if self._clearance is None:
            if self.occupied.any():
                edt = ndimage.distance_transform_edt(~self.occupied, sampling=self.resolution)
            else:
                edt = np.full(self.shape, np.inf)
            edt.setflags(write=False)
            self._clearance = edt
        return self._clearance

    def traversable(self, inflation_radius=0.0):
        """Cells a robot centre may occupy, for an inflation radius [m].

        Parameters
        ----------
        inflation_radius : float
            Robot radius plus any margin [m], >= 0.

        Returns
        -------
        ndarray, bool, shape (H, W)
            ``clearance > inflation_radius``; cached per radius.
        """
        if not _is_finite_number(inflation_radius) or inflation_radius < 0:
            raise InvalidInput(
                f'inflation radius must be a non-negative number of metres, got {inflation_radius!r}')
        key = float(inflation_radius)
        mask = self._traversable.get(key)
        if mask is None:
            if key == 0.0:
                mask = ~self.occupied
            else:
                mask = self.clearance > key
            mask.setflags(write=False)
            self._traversable[key] = mask
        return mask

    def clearance_at(self, points):
        """Clearance [m] of the cells containing map-frame points.

        Points outside the map get 0 (nothing is known to be free there).

        Parameters
        ----------
        points : array_like, shape (N, 2)
            ``(x, y)`` [m], map frame.

        Returns
        -------
        ndarray, float64, shape (N,)
        """
        cells = self.cell_of(np.atleast_2d(points))
        inside = self.contains(cells)
        out = np.zeros(len(cells))
        rc = cells[inside]
        out[inside] = self.clearance[rc[:, 0], rc[:, 1]]
        return out


def _is_finite_number(value):
    """True for a real finite number (bool excluded)."""
    if isinstance(value, bool):
        return False
    try:
        return math.isfinite(float(value))
    except (TypeError, ValueError):
        return False
