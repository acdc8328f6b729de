"""Exact squared Euclidean distance transform from per-column distances.

:func:`squared_distances` finishes the two-pass distance transform of
Felzenszwalb and Huttenlocher ("Distance Transforms of Sampled Functions",
Theory of Computing 8, 2012): the first pass, the distance to the nearest
occupied cell of the same column, is :meth:`GridMap._column_distances`; the
second takes, per row, the lower envelope of the parabolas
``(c - q)**2 + v(q)**2``. Compiled with numba when it is installed (the
import happens on first use); :data:`AVAILABLE` says whether it is. It needs
a float64 output and a few row-sized arrays, where scipy's
``distance_transform_edt`` holds a feature transform of two int32 per cell
besides (0.45 GB more at the peak on 4000 x 4000 cells).
"""

import numpy as np

from fusion_planner.core.compiled import LazyLoop, numba_installed

#: Whether the compiled transform can be used.
AVAILABLE = numba_installed()


def squared_distances(column_distance, far):
    """Exact squared distances [cells^2] to the nearest occupied cell.

    Parameters
    ----------
    column_distance : ndarray of uint16 or int32, shape (H, W)
        Distance [cells] to the nearest occupied cell of the same column;
        ``far`` where the column has none.
    far : int
        The "no occupied cell in this column" value.

    Returns
    -------
    ndarray, float64, shape (H, W) or None
        Integer-valued squared distances (exact in float64); needs at least
        one occupied cell in the map. None when numba cannot be imported
        (then :data:`AVAILABLE` turns False).
    """
    global AVAILABLE
    rows = _ROWS.load()
    if rows is None:
        AVAILABLE = False
        return None
    out = np.empty(column_distance.shape)
    rows(column_distance, far, out)
    return out


def _lower_envelope_rows(column_distance, far, out):
    """Per row, ``out[r, c] = min over q of (c - q)**2 + v(r, q)**2``."""
    height, width = column_distance.shape
    sites = np.empty(width, np.int64)  # columns of the parabolas of the envelope
    bounds = np.empty(width + 1)  # where each parabola starts to be the lowest
    heights = np.empty(width, np.int64)
    for r in range(height):
        count = 0
        for q in range(width):
            v = np.int64(column_distance[r, q])
            if v == far:
                continue
            fq = v * v
            s = 0.0
            while count > 0:
                p = sites[count - 1]
                # Abscissa where the parabola of q gets below the one of p.
                s = ((fq + q * q) - (heights[count - 1] + p * p)) / (2.0 * (q - p))
                if s > bounds[count - 1]:
                    break
                count -= 1
            if count == 0:
                bounds[0] = -np.inf
            else:
                bounds[count] = s
            sites[count] = q
            heights[count] = fq
            count += 1
        k = 0
        for c in range(width):
            while k + 1 < count and bounds[k + 1] <= c:
                k += 1
            d = c - sites[k]
            out[r, c] = d * d + heights[k]


_ROWS = LazyLoop(_lower_envelope_rows)
