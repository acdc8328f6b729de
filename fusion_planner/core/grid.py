"""Occupancy grid model: obstacles, clearance, inflation, cell <-> world.

Conventions (REP-103, the same as nav_msgs/OccupancyGrid):

- A grid is an ``(H, W)`` array indexed ``[row, col]``; row 0 is the row at
  the map origin (lowest y in the map frame when the origin yaw is 0), column
  0 the column at the origin. Image files (PGM, PNG, MovingAI ``.map``) store
  the top row first; their loaders flip them (see :mod:`map_files`).
- ``resolution`` is the cell edge in metres; the origin ``(x, y, yaw)`` is the
  pose of the corner of cell ``(0, 0)`` in the map frame [m, m, rad].
- Clearance is the Euclidean distance [m] from a cell centre to the centre of
  the nearest occupied cell: ``sqrt(n) * resolution`` with ``n`` the exact
  squared distance in cells; it is 0 on occupied cells and ``inf`` on a map
  without obstacles.
- A cell is *traversable* for an inflation radius ``r`` [m] when its
  clearance is strictly greater than ``r``: with ``r = 0`` every free cell is
  traversable; with the robot radius, every cell where a disc of that radius
  centred on the cell centre misses all occupied cell centres.

What is computed, and when (each at most once per map, on first use): the
whole clearance map (:attr:`GridMap.clearance`, a Euclidean distance
transform: :mod:`distance_transform` from the per-column distances when
numba is installed, else ``scipy.ndimage.distance_transform_edt``) only when
a caller asks for it (``GlobalPlanner.prepare`` does). Planning alone does
not: an inflated mask (:meth:`GridMap.traversable`)
needs the exact distance only up to the radius, which a bounded distance
transform gives in a few vectorised passes; and the clearance of a path's
cells (:meth:`GridMap.clearance_of_cells`) is computed exactly around those
cells alone, from the per-column distances to the nearest obstacle.
"""

import math
import mmap

import numpy as np
from scipy import ndimage

from fusion_planner.core import distance_transform
from fusion_planner.core.errors import InvalidInput, MapError

#: Default cap on the number of cells of a map (4000 x 4000 fits). Larger
#: maps are refused rather than risking the memory of the process.
DEFAULT_MAX_CELLS = 16_000_000

#: Column distance [cells] standing for "no occupied cell in this column";
#: its square exceeds any squared distance inside an accepted map.
_FAR_CELLS = 1 << 30
#: Inflation radii up to this many cells use the bounded distance transform
#: (one pass per cell of radius); larger ones the whole clearance map.
MAX_BOUNDED_RADIUS_CELLS = 24
#: A local clearance query switches to the whole clearance map when its next
#: widening would read more than this many times the map's cell count.
LOCAL_QUERY_MAX_WORK = 2
#: Maps of at most this many cells compute the whole clearance map on the
#: first clearance query (a few milliseconds), larger ones work locally.
SMALL_MAP_CELLS = 1 << 16
#: Largest number of values one local clearance gather reads at once.
_GATHER_CHUNK = 1 << 22
#: Columns processed at once by the per-column distance pass (bounds its
#: temporary arrays to a few bytes per cell of such a block).
_COLUMN_BLOCK = 512


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
            raise MapError(
                f'map resolution must be a positive number of metres, got {resolution!r}')
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
        self._column_distance = None
        self._cell_squared = None  # flat cache of local queries: squared distance + 1, 0 unknown
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
        out = np.subtract(pts, self.origin[:2])
        if self.origin[2] != 0.0:
            dx, dy = out[..., 0].copy(), out[..., 1].copy()
            out[..., 0] = self._cos * dx + self._sin * dy
            out[..., 1] = self._cos * dy - self._sin * dx
        out /= self.resolution
        return out

    def grid_to_world(self, grid_points):
        """Map-frame points of continuous grid coordinates ``(col, row)``."""
        out = np.multiply(grid_points, self.resolution, dtype=float)
        if self.origin[2] != 0.0:
            gx, gy = out[..., 0].copy(), out[..., 1].copy()
            out[..., 0] = self._cos * gx - self._sin * gy
            out[..., 1] = self._sin * gx + self._cos * gy
        out += self.origin[:2]
        return out

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
            ``sqrt(n) * resolution`` with ``n`` the squared distance in
            cells; 0 on occupied cells; ``inf`` everywhere when nothing is
            occupied. Computed on first use (a whole-map distance transform)
            and kept; read-only.
        """
        if self._clearance is None:
            if self.occupied.any():
                unit = None
                if distance_transform.AVAILABLE:
                    column = self._column_distances()
                    far = np.iinfo(np.uint16).max if column.dtype == np.uint16 else _FAR_CELLS
                    unit = distance_transform.squared_distances(column, far)
                if unit is None:
                    unit = ndimage.distance_transform_edt(~self.occupied)
                    # Back to exact integer squared distances, so every clearance
                    # of this class is the same float expression of one integer.
                    np.square(unit, out=unit)
                    np.rint(unit, out=unit)
                np.sqrt(unit, out=unit)
                edt = np.multiply(unit, self.resolution, out=unit)
            else:
                edt = np.full(self.shape, np.inf)
            edt.setflags(write=False)
            self._clearance = edt
        return self._clearance

    @property
    def clearance_ready(self):
        """Whether :attr:`clearance` has been computed (reading it is then free)."""
        return self._clearance is not None

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

        Notes
        -----
        Exactly :attr:`clearance` ``> inflation_radius``, but without the
        whole clearance map unless it was computed already or the radius is
        more than :data:`MAX_BOUNDED_RADIUS_CELLS` cells: a cell is blocked
        when an occupied cell lies within the radius, and only distances up
        to the radius need to be exact (:func:`_bounded_squared_distance`).
        """
        if not _is_finite_number(inflation_radius) or inflation_radius < 0:
            raise InvalidInput(
                'inflation radius must be a non-negative number of metres, '
                f'got {inflation_radius!r}')
        key = float(inflation_radius)
        mask = self._traversable.get(key)
        if mask is None:
            if key == 0.0:
                mask = ~self.occupied
            elif self._clearance is not None or not self.occupied.any():
                mask = self.clearance > key
            else:
                threshold = _smallest_squared_distance_beyond(key, self.resolution)
                reach = math.isqrt(threshold - 1) if threshold > 0 else 0
                if reach > MAX_BOUNDED_RADIUS_CELLS:
                    mask = self.clearance > key
                else:
                    squared = _bounded_squared_distance(self._column_distances(), reach)
                    mask = squared >= threshold
            mask.setflags(write=False)
            self._traversable[key] = mask
        return mask

    def clearance_of_cells(self, cells):
        """Clearance [m] of given cells, computed around them only.

        Parameters
        ----------
        cells : array_like of int, shape (N, 2)
            ``(row, col)``, every one inside the grid.

        Returns
        -------
        ndarray, float64, shape (N,)
            The same values as ``clearance[rows, cols]``, bit for bit.

        Raises
        ------
        InvalidInput
            If a cell lies outside the grid or the array is not (N, 2).

        Notes
        -----
        On a map of at most :data:`SMALL_MAP_CELLS` cells the whole
        clearance map is computed (once) and read. Otherwise the distance of
        cell ``(r, c)`` is ``min over c' of v(r, c')**2 +
        (c - c')**2`` with ``v`` the distance to the nearest occupied cell
        in the same column (one vectorised pass per map, kept): the columns
        ``c'`` are widened around each cell, doubling, until no farther
        column can give less. A query that would read more than
        :data:`LOCAL_QUERY_MAX_WORK` times the map computes the whole map
        instead. Each cell is computed once per map: results are kept.
        """
        cells = np.asarray(cells)
        if cells.ndim != 2 or cells.shape[1] != 2:
            raise InvalidInput(f'cells must be an (N, 2) array, got shape {cells.shape}')
        if len(cells) == 0:
            return np.zeros(0)
        rows = cells[:, 0].astype(np.intp)
        cols = cells[:, 1].astype(np.intp)
        height, width = self.shape
        if rows.min() < 0 or rows.max() >= height or cols.min() < 0 or cols.max() >= width:
            raise InvalidInput('clearance_of_cells needs cells inside the grid')
        if self._clearance is None and self.occupied.size <= SMALL_MAP_CELLS:
            self.clearance  # computes and keeps the whole map
        if self._clearance is not None:
            return self._clearance[rows, cols]
        if not self.occupied.any():
            return np.full(len(cells), np.inf)
        if self._cell_squared is None:
            # An anonymous mapping: zero (unknown) pages take no memory until
            # a query writes them, wherever its cells lie on the map.
            self._cell_squared = np.frombuffer(mmap.mmap(-1, 8 * self.occupied.size),
                                               dtype=np.int64)
        flat = rows * width + cols
        stored = self._cell_squared[flat]
        unknown = stored == 0
        if unknown.any():
            missing = np.unique(flat[unknown])
            squared = self._local_squared_distance(*np.divmod(missing, width))
            if squared is None:  # cheaper as a whole map
                return self.clearance[rows, cols]
            self._cell_squared[missing] = squared + 1
            stored = self._cell_squared[flat]
        return np.sqrt((stored - 1).astype(float)) * self.resolution

    def _column_distances(self):
        """Distance [cells] to the nearest occupied cell of the same column.

        (H, W); where the column has none, a value whose square exceeds any
        squared distance inside the map: 65535 in uint16 when the map's
        diagonal is shorter, else :data:`_FAR_CELLS` in int32. Kept.
        """
        if self._column_distance is None:
            height, width = self.shape
            far = np.iinfo(np.uint16).max
            if height ** 2 + width ** 2 < far ** 2:
                # Half the memory; "no obstacle in this column" stays farther
                # than any distance inside the map.
                distance = np.empty(self.shape, np.uint16)
            else:
                distance, far = np.empty(self.shape, np.int32), _FAR_CELLS
            rows = np.arange(height, dtype=np.int32)[:, None]
            for lo in range(0, width, _COLUMN_BLOCK):  # bounded: blocks of columns
                occupied = self.occupied[:, lo:lo + _COLUMN_BLOCK]
                # Index of the last occupied cell at or above each cell ...
                above = np.where(occupied, rows, np.int32(-_FAR_CELLS))
                np.maximum.accumulate(above, axis=0, out=above)
                # ... and of the first at or below (on the flipped block).
                below = np.where(occupied[::-1], rows[::-1], np.int32(height + _FAR_CELLS))
                np.minimum.accumulate(below, axis=0, out=below)
                below = below[::-1]
                np.subtract(rows, above, out=above)
                np.subtract(below, rows, out=below)
                np.minimum(above, below, out=above)
                np.minimum(above, far, out=above)
                distance[:, lo:lo + _COLUMN_BLOCK] = above
            distance.setflags(write=False)
            self._column_distance = distance
        return self._column_distance

    def _local_squared_distance(self, rows, cols):
        """Exact squared distances [cells^2] of unique cells, or None when a
        whole-map transform is cheaper (see :meth:`clearance_of_cells`)."""
        column = self._column_distances()
        width = self.width
        best = column[rows, cols].astype(np.int64) ** 2
        pending = np.flatnonzero(best > 1)  # exact once best <= (reach + 1)**2
        reach = 0
        while pending.size and reach < width - 1:  # bounded: reach doubles
            wider = min(max(2 * reach, 4), width - 1)
            if pending.size * 2 * (wider - reach) > LOCAL_QUERY_MAX_WORK * self.occupied.size:
                return None
            steps = np.arange(reach + 1, wider + 1)
            offsets = np.concatenate([steps, -steps])
            extra = np.concatenate([steps * steps, steps * steps])
            chunk = max(1, _GATHER_CHUNK // offsets.size)
            for lo in range(0, pending.size, chunk):  # bounded: chunks of pending
                part = pending[lo:lo + chunk]
                at = cols[part][:, None] + offsets[None, :]
                outside = (at < 0) | (at >= width)
                np.clip(at, 0, width - 1, out=at)
                values = column[rows[part][:, None], at].astype(np.int64)
                values *= values
                values += extra
                values[outside] = np.iinfo(np.int64).max
                best[part] = np.minimum(best[part], values.min(axis=1))
            reach = wider
            pending = pending[best[pending] > (reach + 1) ** 2]
        return best

    def clearance_at(self, points):
        """Clearance [m] of the cells containing map-frame points.

        Points outside the map get 0 (nothing is known to be free there).
        Computed around the points only (:meth:`clearance_of_cells`).

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
        out[inside] = self.clearance_of_cells(rc)
        return out


def _smallest_squared_distance_beyond(radius, resolution):
    """Smallest integer ``n`` with ``sqrt(n) * resolution > radius``.

    The same float expression as :attr:`GridMap.clearance`, so that a
    threshold on squared cell distances agrees with ``clearance > radius``
    bit for bit.
    """
    n = int(math.floor((radius / resolution) ** 2))
    n = max(n - 2, 0)
    for _ in range(8):  # bounded: n starts within two of the answer
        if math.sqrt(n) * resolution > radius:
            break
        n += 1
    while n > 0 and math.sqrt(n - 1) * resolution > radius:  # bounded: n decreases
        n -= 1
    return n


def _bounded_squared_distance(column_distance, reach):
    """Squared distances [cells^2] to the nearest occupied cell, exact up to
    ``reach**2`` and larger than ``reach**2`` wherever the exact value is.

    Parameters
    ----------
    column_distance : ndarray of uint16 or int32, shape (H, W)
        Distance to the nearest occupied cell of the same column.
    reach : int
        Largest column offset considered [cells], >= 0.

    Returns
    -------
    ndarray, int16 or int32, shape (H, W)

    Notes
    -----
    ``min over |dc| <= reach of v(r, c + dc)**2 + dc**2``: an occupied cell
    within distance ``reach`` lies at most ``reach`` columns away, so such
    distances are exact; the others only grow. 2 * reach vectorised passes.
    """
    # Squares stay below 2 (reach + 1)**2: 16 bits suffice for any bounded reach.
    dtype = np.int16 if 2 * (reach + 1) ** 2 < np.iinfo(np.int16).max else np.int32
    capped = np.empty(column_distance.shape, dtype)
    np.minimum(column_distance, reach + 1, out=capped, casting='unsafe')
    capped *= capped
    squared = capped.copy()
    scratch = np.empty_like(capped)
    for dc in range(1, reach + 1):  # bounded: reach passes
        shifted = np.add(capped[:, :-dc], dc * dc, out=scratch[:, :-dc])
        np.minimum(squared[:, dc:], shifted, out=squared[:, dc:])
        shifted = np.add(capped[:, dc:], dc * dc, out=scratch[:, dc:])
        np.minimum(squared[:, :-dc], shifted, out=squared[:, :-dc])
    return squared


def _is_finite_number(value):
    """True for a real finite number (bool excluded)."""
    if isinstance(value, bool):
        return False
    try:
        return math.isfinite(float(value))
    except (TypeError, ValueError):
        return False
