"""Laser returns the known map does not explain, grouped into objects.

One scan becomes a set of :class:`Segments`: the returns that lie on (or
within a tolerance of) an occupied cell of the known map, or on the map's
edge, are explained and dropped; the rest are cut into runs of adjacent beams
whose hit points lie close together (a range jump or an explained or missing
return ends a run). A run is also cut where its range peaks between two
nearer stretches (the notch between two people side by side: a convex object
never shows one). Each run is an object candidate with a centre, a radius
and its angular extent.

Everything is one numpy pass over the beams; nothing loops over beams or
objects.

Frames and units: hit points and centres in the map frame [m]; beam angles
in the laser frame [rad], counter-clockwise, in scan order.

Examples
--------
>>> import numpy as np
>>> from fusion_planner.core.grid import GridMap
>>> grid = GridMap(np.zeros((100, 100), bool), resolution=0.1)
>>> explained = map_explained_mask(grid, tolerance=0.15)
>>> angles = np.linspace(-0.2, 0.2, 9)
>>> ranges = np.full(9, 3.0)                 # a short arc 3 m ahead
>>> segments = segment_scan(angles, ranges, np.array([2.0, 5.0, 0.0]), grid, explained,
...                         gap=0.3, min_points=2, split_depth=0.15)
>>> len(segments.centers), bool(segments.centers[0, 0] > 4.9)
(1, True)
"""

import math
from dataclasses import dataclass

import numpy as np
from scipy import ndimage
from scipy.signal import find_peaks

#: Cap on the sine of a run's half angle in the circle estimate (a run this
#: wide is far larger than any tracked object anyway).
MAX_HALF_ANGLE_SIN = 0.9
#: Range [m] that stands for "no return" in the notch search: higher than any return.
_WALL = 1e9


@dataclass(frozen=True)
class Segments:
    """Object candidates of one scan.

    Attributes
    ----------
    centers : ndarray, float64, shape (C, 2)
        Estimated centres [m], map frame.
    radii : ndarray, float64, shape (C,)
        Estimated radii [m].
    counts : ndarray, int64, shape (C,)
        Hit points per candidate.
    occluded : ndarray, bool, shape (C,)
        The beam beside its first or last return hit something nearer (by
        more than the gap), or it touches the edge of a partial field of
        view: part of the object may be hidden, so its centre and radius are
        biased.
    unexplained : ndarray, float64, shape (U, 2)
        Every hit point the map does not explain [m] (candidates or not).
    labels : ndarray, int64, shape (U,)
        The candidate of each of them (-1: in a run too short to be one).
    """

    centers: np.ndarray
    radii: np.ndarray
    counts: np.ndarray
    occluded: np.ndarray
    unexplained: np.ndarray
    labels: np.ndarray


def map_explained_mask(grid, tolerance):
    """Cells whose returns the known map explains, with a one-cell frame for the map edge.

    Parameters
    ----------
    grid : GridMap
    tolerance : float
        A cell is explained when its centre lies within this distance [m] of
        an occupied cell's centre; raised to 1.5 cells so that a return on a
        wall's face or corner (in the free cell beside it) is explained.

    Returns
    -------
    ndarray, bool, shape (H + 2, W + 2)
        Indexed ``[row + 1, col + 1]``; the frame (outside the map) is True.
    """
    reach = max(float(tolerance), 1.5 * grid.resolution) / grid.resolution
    framed = np.ones((grid.height + 2, grid.width + 2), bool)
    framed[1:-1, 1:-1] = grid.occupied
    # the map's edge stops beams too: treat the frame as occupied
    distance = ndimage.distance_transform_edt(~framed)
    mask = distance <= reach
    mask.setflags(write=False)
    return mask


def hit_points(angles, ranges, origin):
    """Map-frame hit points of every beam and which of them are returns.

    Parameters
    ----------
    angles, ranges : ndarray, float64, shape (n,)
        Beam angles [rad] in the laser frame and ranges [m]; non-finite or
        non-positive ranges are no return.
    origin : ndarray, shape (3,)
        Laser pose ``(x, y, yaw)`` in the map frame.

    Returns
    -------
    points : ndarray, float64, shape (n, 2)
        NaN where there is no return.
    valid : ndarray, bool, shape (n,)
    """
    with np.errstate(invalid='ignore'):
        valid = np.isfinite(ranges) & (ranges > 0)
    r = np.where(valid, ranges, np.nan)
    world = origin[2] + angles
    points = np.stack([origin[0] + r * np.cos(world), origin[1] + r * np.sin(world)], axis=1)
    return points, valid


def explained_by_map(points, valid, grid, explained_mask):
    """Which returns lie in an explained cell (or outside the map).

    Parameters
    ----------
    points : ndarray, shape (n, 2)
    valid : ndarray, bool, shape (n,)
    grid : GridMap
    explained_mask : ndarray, bool
        From :func:`map_explained_mask`.

    Returns
    -------
    ndarray, bool, shape (n,)
        False where ``valid`` is False.
    """
    g = grid.world_to_grid(np.where(valid[:, None], points, 0.0))
    cols = np.clip(np.floor(g[:, 0]).astype(np.int64) + 1, 0, explained_mask.shape[1] - 1)
    rows = np.clip(np.floor(g[:, 1]).astype(np.int64) + 1, 0, explained_mask.shape[0] - 1)
    return valid & explained_mask[rows, cols]


def segment_scan(angles, ranges, origin, grid, explained_mask, gap, min_points, split_depth):
    """Cut a scan's unexplained returns into object candidates.

    Parameters
    ----------
    angles, ranges : ndarray, float64, shape (n,)
        In scan order (increasing angle) [rad], [m].
    origin : ndarray, shape (3,)
        Laser pose ``(x, y, yaw)``, map frame.
    grid : GridMap
    explained_mask : ndarray, bool
        From :func:`map_explained_mask`.
    gap : float
        Adjacent returns farther apart than this [m] belong to different
        objects.
    min_points : int
        Runs with fewer returns are dropped (a lone return is not an object).
    split_depth : float
        A run is cut at a beam whose range exceeds the nearest return on
        each side of it within the run by more than this [m] (a notch
        between two objects); far above the range noise, so that noise on
        one object's face does not cut it.

    Returns
    -------
    Segments
        A full-circle scan joins a run that wraps past its last beam to the
        one at its first beam.

    Notes
    -----
    Each run is taken for a circle: seen under the angle ``a`` of its
    ``count`` beams (``count * beam spacing``) with its nearest return at
    range ``rho``, a circle of radius ``r`` centred at range ``d`` has
    ``sin(a / 2) = r / d`` and ``rho = d - r``, so
    ``r = rho sin(a/2) / (1 - sin(a/2))``; its centre lies at ``rho + r``
    along the bearing of the run's middle.
    """
    points, valid = hit_points(angles, ranges, origin)
    own = valid & ~explained_by_map(points, valid, grid, explained_mask)
    n = len(angles)
    unexplained = points[own]
    if not own.any():
        return _empty(unexplained)
    step = np.hypot(*np.diff(points, axis=0).T)
    with np.errstate(invalid='ignore'):
        linked = own[:-1] & own[1:] & (step <= gap)
    linked[_notches(ranges, own, linked, split_depth)] = False
    starts = own.copy()
    starts[1:] &= ~linked
    label = np.cumsum(starts) - 1
    ends = own.copy()
    ends[:-1] &= ~linked
    first = np.flatnonzero(starts)
    last = np.flatnonzero(ends)
    count = last - first + 1
    beam_spacing = float(np.median(np.abs(np.diff(angles)))) if n > 1 else 0.0
    full_circle = n > 1 and abs(angles[-1] - angles[0]) + 1.5 * beam_spacing >= 2 * math.pi
    if full_circle and len(first) > 1 and own[0] and own[-1] \
            and math.hypot(*(points[0] - points[-1])) <= gap:
        # the run at the end continues the one at the start
        first[0] = first[-1]
        count[0] += count[-1]
        first, last, count = first[:-1], last[:-1], count[:-1]
        label = np.where(label == len(first), 0, label)
    nearest = np.full(len(first), np.inf)
    np.minimum.at(nearest, label[own], ranges[own])
    # the circle seen under the run's angle from its nearest return
    half_sin = np.minimum(np.sin(0.5 * count * beam_spacing), MAX_HALF_ANGLE_SIN)
    radii = nearest * half_sin / (1.0 - half_sin)
    sight = 0.5 * (points[first] + points[last]) - origin[:2]
    direction = sight / np.maximum(np.hypot(*sight.T), 1e-9)[:, None]
    centers = origin[:2] + direction * (nearest + radii)[:, None]
    occluded = _nearer_beside(ranges, first - 1, first, gap, full_circle) \
        | _nearer_beside(ranges, last + 1, last, gap, full_circle)
    keep = count >= min_points
    renumber = np.where(keep, np.cumsum(keep) - 1, -1)
    return Segments(centers=centers[keep], radii=radii[keep], counts=count[keep],
                    occluded=occluded[keep], unexplained=unexplained,
                    labels=renumber[label[own]])


def _notches(ranges, own, linked, depth):
    """Beams ``i`` inside runs whose range peaks more than ``depth`` [m] above both sides.

    The peak's prominence is measured within its run: between each pair of
    adjacent beams goes a sample that walls the runs off where they are
    not linked and is the lower of the two ranges where they are (which
    neither makes nor hides a peak).

    Returns
    -------
    ndarray, int64
        The beams; the link from each to the next beam is to be cut.
    """
    n = len(ranges)
    if n < 3:
        return np.zeros(0, np.int64)
    profile = np.full(2 * n - 1, _WALL)
    profile[0::2] = np.where(own, ranges, _WALL)
    profile[1::2] = np.where(linked, np.fmin(ranges[:-1], ranges[1:]), _WALL)
    peaks, _ = find_peaks(profile, prominence=depth)
    beams = peaks[peaks % 2 == 0] // 2
    inside = (beams > 0) & (beams < n - 1)
    beams = beams[inside]
    return beams[linked[beams - 1] & linked[beams]]


def _nearer_beside(ranges, beside, own, gap, full_circle):
    """Whether beam ``beside`` returned nearer than beam ``own`` by more than ``gap``.

    Beyond the ends of a partial field of view the answer is True (unseen).
    """
    n = len(ranges)
    outside = (beside < 0) | (beside >= n)
    beside = np.mod(beside, n)
    with np.errstate(invalid='ignore'):
        nearer = ranges[beside] < ranges[own] - gap
    return nearer | (outside & (not full_circle))


def _empty(unexplained):
    return Segments(centers=np.zeros((0, 2)), radii=np.zeros(0), counts=np.zeros(0, np.int64),
                    occluded=np.zeros(0, bool), unexplained=unexplained,
                    labels=np.full(len(unexplained), -1, np.int64))
