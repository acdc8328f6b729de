"""Laser returns the known map does not explain, grouped into objects.

One scan becomes a set of :class:`Segments`: the returns that lie on (or
within a tolerance of) an occupied cell of the known map, or on the map's
edge, are explained and dropped; the rest are cut into runs of adjacent beams
whose hit points lie close together (a range jump or an explained or missing
return ends a run). A run is also cut where its range peaks between two
nearer stretches (the notch between two people side by side: a convex object
never shows one). Each run is an object candidate with a centre, a radius
and its angular extent. Given the circles of objects already known (a
tracker's predictions), :func:`split_among` cuts a run that holds returns of
two or more of them into one part per object.

Everything is a fixed number of numpy passes over the beams; nothing loops
over beams or objects (the refit of known circles iterates a fixed
:data:`FIT_ITERATIONS` times).

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
#: Standard deviations [m] of a return about its circle and of a known
#: circle's predicted centre, and Gauss-Newton iterations, in the refit of
#: known circles to the parts of a shared candidate (:func:`split_among`).
RETURN_STD = 0.02
PRIOR_STD = 0.1
FIT_ITERATIONS = 4
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
    behind_map : ndarray, bool, shape (C,)
        Occluded by a return the map explains (not by an unknown object, nor
        by the edge of the view): it may be stepping out from behind a wall
        corner.
    unexplained : ndarray, float64, shape (U, 2)
        Every hit point the map does not explain [m] (candidates or not).
    labels : ndarray, int64, shape (U,)
        The candidate of each of them (-1: in a run too short to be one).
    beam_spacing : float
        Median angle between adjacent beams of the scan [rad] (0 for one
        beam).
    """

    centers: np.ndarray
    radii: np.ndarray
    counts: np.ndarray
    occluded: np.ndarray
    behind_map: np.ndarray
    unexplained: np.ndarray
    labels: np.ndarray
    beam_spacing: float


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
    beam_spacing = float(np.median(np.abs(np.diff(angles)))) if n > 1 else 0.0
    unexplained = points[own]
    if not own.any():
        return _empty(unexplained, beam_spacing)
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
    sight = 0.5 * (points[first] + points[last]) - origin[:2]
    direction = sight / np.maximum(np.hypot(*sight.T), 1e-9)[:, None]
    centers, radii = _circles_seen(origin, 0.5 * count * beam_spacing, nearest, direction)
    before = _nearer_beside(ranges, first - 1, first, gap, full_circle)
    after = _nearer_beside(ranges, last + 1, last, gap, full_circle)
    on_map = valid & ~own
    behind_map = (before & _on_map_beside(on_map, first - 1, full_circle)) \
        | (after & _on_map_beside(on_map, last + 1, full_circle))
    keep = count >= min_points
    renumber = np.where(keep, np.cumsum(keep) - 1, -1)
    return Segments(centers=centers[keep], radii=radii[keep], counts=count[keep],
                    occluded=(before | after)[keep], behind_map=behind_map[keep],
                    unexplained=unexplained,
                    labels=renumber[label[own]], beam_spacing=beam_spacing)


def split_among(segments, origin, centers, radii, reach, min_points, widest, merge_ratio):
    """Cut each candidate that holds returns of two or more known objects into one per object.

    Two people side by side, seen nearly in line from the laser, join into
    one run without a notch (the farther one's visible edge lies within
    ``split_depth`` of its own nearest return), and so does one coming out
    from behind another (the nearer one's edge, then the farther one): one
    candidate too large for either. Known circles (a tracker's predicted
    tracks) cut it apart again.

    Parameters
    ----------
    segments : Segments
        From :func:`segment_scan`.
    origin : ndarray, shape (3,)
        Laser pose ``(x, y, yaw)``, map frame.
    centers : ndarray, shape (K, 2)
        Centres [m] of the known objects, map frame.
    radii : ndarray, shape (K,)
        Their radii [m].
    reach : float
        A return within this distance [m] of a circle's edge may be its object's.
    min_points : int
        Parts with fewer returns are dropped.
    widest : float
        Candidates of a larger radius [m] are too wide to be one object.
    merge_ratio : float
        So are candidates more than this many times larger than every circle
        whose returns they hold: a merge. Only such candidates are cut; a
        person beside a small box, tracked as one object of the box's and the
        person's size, stays one.

    Returns
    -------
    Segments
        A candidate too wide (see ``widest``) with returns within ``reach``
        of two or more circles is
        replaced by one part per circle (the returns nearest that circle's
        edge; returns within reach of none form one more part). A circle's
        part is that circle refitted to its returns (:func:`_refit`: its
        radius kept; partly hidden or not, its centre is unbiased), occluded
        only if the candidate was; every part is behind the map if the
        candidate was; the rest is taken for a circle as in
        :func:`segment_scan`, occluded unless nearest the laser. Other
        candidates are kept as they were, in order, before the parts.
    """
    labelled = np.flatnonzero(segments.labels >= 0)
    count = len(segments.counts)
    if len(centers) < 2 or not len(labelled):
        return segments
    points, label = segments.unexplained[labelled], segments.labels[labelled]
    edge = np.hypot(points[:, None, 0] - centers[:, 0], points[:, None, 1] - centers[:, 1]) - radii
    near = edge <= reach                                                       # (P, K)
    touched = np.zeros((count, len(centers)), bool)
    np.logical_or.at(touched, label, near)
    largest = np.max(np.where(touched, radii, 0.0), axis=1)
    too_wide = segments.radii > np.minimum(widest, merge_ratio * largest)
    shared = (touched.sum(axis=1) >= 2) & too_wide
    inside = shared[label]
    if not inside.any():
        return segments
    cost = np.where(touched[label] & near, edge, np.inf)
    owner = np.where(np.isfinite(cost.min(axis=1)), cost.argmin(axis=1), len(centers))
    # one part per (candidate, circle); len(centers) stands for "no circle"
    keys, part_of = np.unique(label[inside] * (len(centers) + 1) + owner[inside],
                              return_inverse=True)
    parts = len(keys)
    parent = keys // (len(centers) + 1)
    sight = points[inside] - origin[:2]
    ranges = np.hypot(sight[:, 0], sight[:, 1])
    # bearings relative to each part's first return (a part spans far less than pi)
    bearing = np.arctan2(sight[:, 1], sight[:, 0])
    first = np.full(parts, len(bearing))
    np.minimum.at(first, part_of, np.arange(len(bearing)))
    relative = np.angle(np.exp(1j * (bearing - bearing[first][part_of])))
    low, high, nearest = np.full(parts, np.inf), np.full(parts, -np.inf), np.full(parts, np.inf)
    np.minimum.at(low, part_of, relative)
    np.maximum.at(high, part_of, relative)
    np.minimum.at(nearest, part_of, ranges)
    counts = np.bincount(part_of, minlength=parts)
    middle = bearing[first] + 0.5 * (low + high)
    seen_from = np.stack([np.cos(middle), np.sin(middle)], axis=1)
    part_centers, part_radii = _circles_seen(origin, 0.5 * (high - low + segments.beam_spacing),
                                             nearest, seen_from)
    closest = np.full(count, np.inf)
    np.minimum.at(closest, parent, nearest)
    part_occluded = segments.occluded[parent] | (nearest > closest[parent])
    # a part of a known circle: that circle refitted to its returns, hidden or not
    circle = keys % (len(centers) + 1)
    known = circle < len(centers)
    on_known = known[part_of]
    renamed = np.cumsum(known) - 1
    part_centers[known] = _refit(points[inside][on_known], renamed[part_of[on_known]],
                                 centers[circle[known]], radii[circle[known]])
    part_radii[known] = radii[circle[known]]
    part_occluded[known] = segments.occluded[parent[known]]
    kept = np.flatnonzero(~shared)
    keep_part = counts >= min_points
    renumber = np.full(count + parts, -1)
    renumber[kept] = np.arange(len(kept))
    renumber[count + np.flatnonzero(keep_part)] = len(kept) + np.arange(keep_part.sum())
    full = label.copy()
    full[inside] = count + part_of
    labels = segments.labels.copy()
    labels[labelled] = renumber[full]
    return Segments(
        centers=np.vstack([segments.centers[kept], part_centers[keep_part]]),
        radii=np.concatenate([segments.radii[kept], part_radii[keep_part]]),
        counts=np.concatenate([segments.counts[kept], counts[keep_part]]),
        occluded=np.concatenate([segments.occluded[kept], part_occluded[keep_part]]),
        behind_map=np.concatenate([segments.behind_map[kept],
                                   segments.behind_map[parent][keep_part]]),
        unexplained=segments.unexplained, labels=labels, beam_spacing=segments.beam_spacing)


def _circles_seen(origin, half_angle, nearest, direction):
    """Centres ``(C, 2)`` and radii ``(C,)`` [m] of circles seen from the laser.

    Each is seen under twice ``half_angle`` [rad] with its nearest return
    at range ``nearest`` [m], its centre along the unit ``direction``
    ``(C, 2)`` (see :func:`segment_scan`, notes).
    """
    half_sin = np.minimum(np.sin(half_angle), MAX_HALF_ANGLE_SIN)
    radii = nearest * half_sin / (1.0 - half_sin)
    return origin[:2] + direction * (nearest + radii)[:, None], radii


def _refit(points, part_of, start, radius):
    """Centres ``(Q, 2)`` [m] of circles of known ``radius`` (Q,) through each part's returns.

    Gauss-Newton on the returns' distances from the circle (standard
    deviation :data:`RETURN_STD`) and the centre's distance from ``start``
    (:data:`PRIOR_STD`): the few returns of a partly hidden person fix its
    centre along the line of sight, the prediction the rest.
    """
    centre = start.astype(float)
    for _ in range(FIT_ITERATIONS):
        offset = points - centre[part_of]
        distance = np.maximum(np.hypot(offset[:, 0], offset[:, 1]), 1e-9)
        unit = offset / distance[:, None]
        residual = distance - radius[part_of]
        normal = np.tile(np.eye(2) / PRIOR_STD ** 2, (len(centre), 1, 1))
        np.add.at(normal, part_of, unit[:, :, None] * unit[:, None, :] / RETURN_STD ** 2)
        pull = (start - centre) / PRIOR_STD ** 2
        np.add.at(pull, part_of, unit * residual[:, None] / RETURN_STD ** 2)
        centre = centre + np.linalg.solve(normal, pull[:, :, None])[:, :, 0]
    return centre


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


def _on_map_beside(on_map, beside, full_circle):
    """Whether beam ``beside`` returned from the map (False beyond the ends of a partial view)."""
    n = len(on_map)
    in_view = full_circle | ((beside >= 0) & (beside < n))
    return in_view & on_map[np.mod(beside, n)]


def _empty(unexplained, beam_spacing):
    return Segments(centers=np.zeros((0, 2)), radii=np.zeros(0), counts=np.zeros(0, np.int64),
                    occluded=np.zeros(0, bool), behind_map=np.zeros(0, bool),
                    unexplained=unexplained,
                    labels=np.full(len(unexplained), -1, np.int64), beam_spacing=beam_spacing)
