"""Small geometry helpers of the local controllers (map frame, metres, radians).

Angles, point thinning, scan points on or off tracked circles, free travel
ahead, segment clearance, polyline resampling and the braking speed; pure
functions, vectorised over the points.

Examples
--------
>>> import numpy as np
>>> round(wrap_angle(3 * math.pi / 2), 6)
-1.570796
>>> bool(segments_clear(np.zeros(2), np.array([[2.0, 0.0]]), np.array([[1.0, 0.5]]), 0.4)[0])
True
"""

import math

import numpy as np

from fusion_planner.core.local_planning import apf

#: Scan points closer than this [m] to a tracked obstacle's boundary belong
#: to it (they are not static).
TRACKED_POINT_MARGIN = 0.15


def wrap_angle(angle):
    """Wrap an angle to ``[-pi, pi)``.

    Parameters
    ----------
    angle : float
        [rad].

    Returns
    -------
    float
        The same direction [rad] in ``[-pi, pi)``.

    Examples
    --------
    >>> round(wrap_angle(-3 * math.pi / 2), 6)
    1.570796
    """
    return (angle + math.pi) % (2.0 * math.pi) - math.pi


def half_angle_seen(radius, distance):
    """Half the angle [rad] a disc of ``radius`` [m] spans seen from ``distance`` [m] off its centre.

    Element-wise on arrays; ``pi / 2`` from inside the disc.

    Examples
    --------
    >>> round(float(half_angle_seen(1.0, 2.0)), 6)
    0.523599
    """
    return np.arcsin(np.clip(radius / np.maximum(distance, 1e-9), 0.0, 1.0))


def thin_points(points, spacing):
    """Keep one point per ``spacing`` x ``spacing`` square.

    Parameters
    ----------
    points : ndarray, float64, shape (M, 2)
        Points [m], finite.
    spacing : float
        Square edge [m], > 0.

    Returns
    -------
    ndarray, float64, shape (M', 2)
        The first point of each occupied square, in input order, ``M' <= M``.

    Examples
    --------
    >>> thin_points(np.array([[0.01, 0.0], [0.02, 0.0], [0.5, 0.0]]), 0.1).tolist()
    [[0.01, 0.0], [0.5, 0.0]]
    """
    if len(points) < 2:
        return points
    cells = np.floor(points / spacing).astype(np.int64)
    key = cells[:, 0] * np.int64(1 << 31) + cells[:, 1]
    _, first = np.unique(key, return_index=True)
    return points[np.sort(first)]


def held_before(paths, start, blocked):
    """Paths ``(N, T, 2)`` [m] that stop at their last sample before ``blocked`` (``(N,)``).

    A path blocked at its first sample stays at ``start`` [m] (``(2,)``, or
    ``(N, 2)``: one start per path); ``blocked`` equal to ``T`` leaves a path
    as it is.
    """
    last = np.minimum(np.arange(paths.shape[1])[None, :], blocked[:, None] - 1)   # (N, T)
    kept = np.take_along_axis(paths, np.maximum(last, 0)[..., None], axis=1)
    return np.where(last[..., None] >= 0, kept, np.reshape(start, (-1, 1, 2)))


def points_off_circles(points, centres, radii, margin=TRACKED_POINT_MARGIN):
    """The points farther than ``margin`` [m] from every circle's boundary.

    Parameters
    ----------
    points : ndarray, shape (M, 2)
        Points [m] (scan endpoints).
    centres : ndarray, shape (K, 2)
        Circle centres [m] (tracked obstacles).
    radii : ndarray, shape (K,)
        [m].
    margin : float
        [m].

    Returns
    -------
    ndarray, shape (M', 2)
        The static points, in input order.
    """
    if len(centres) == 0 or len(points) == 0:
        return points
    return points[off_circles(points, centres, radii, margin)]


def off_circles(points, centres, radii, margin=TRACKED_POINT_MARGIN):
    """Mask ``(M,)`` of the points farther than ``margin`` [m] from every circle's boundary.

    Same arguments as :func:`points_off_circles`.
    """
    dx = points[:, 0:1] - centres[:, 0]                     # (M, K)
    dy = points[:, 1:2] - centres[:, 1]
    return np.all(dx * dx + dy * dy > (radii + margin)**2, axis=1)


def circle_points(q, centres, radii, keep_off=None):
    """Nearest surface point to ``q`` of each circle.

    Parameters
    ----------
    q : ndarray, shape (2,)
        [m].
    centres : ndarray, shape (K, 2)
        [m].
    radii : ndarray, shape (K,)
        [m].
    keep_off : ndarray, shape (K,), optional
        A point is moved, if need be, to at least this distance [m] from
        ``q`` along the same line.

    Returns
    -------
    ndarray, shape (K, 2)
        [m]. If ``q`` is inside a circle the point lies just beside ``q``,
        on the centre's side.
    """
    diff = q - centres
    dist = np.hypot(diff[:, 0], diff[:, 1])
    unit = diff / np.maximum(dist, apf.DIRECTION_EPS)[:, None]
    reach = np.minimum(radii, dist * (1.0 - 1e-6))
    if keep_off is not None:
        reach = np.minimum(reach, dist - keep_off)
    return centres + unit * reach[:, None]


def front_gap(pose, centres, radii, clearance):
    """Free travel [m] straight ahead before a disc of ``clearance + radii`` touches a centre.

    Parameters
    ----------
    pose : ndarray, shape (3,)
        ``x, y, yaw`` [m, m, rad].
    centres : ndarray, shape (K, 2)
        [m]; points are circles of radius 0.
    radii : ndarray, shape (K,)
        [m].
    clearance : float
        Robot radius plus the clearance to keep [m].

    Returns
    -------
    float
        [m], ``inf`` when nothing lies ahead; negative when already closer.
    """
    if len(centres) == 0:
        return math.inf
    c, s = math.cos(pose[2]), math.sin(pose[2])
    dx = centres[:, 0] - pose[0]
    dy = centres[:, 1] - pose[1]
    ahead = dx * c + dy * s
    lateral = -dx * s + dy * c
    reach = clearance + radii
    hit = (ahead > 0) & (np.abs(lateral) < reach)
    if not np.any(hit):
        return math.inf
    return float(np.min(ahead[hit] - np.sqrt(reach[hit]**2 - lateral[hit]**2)))


def segments_clear(q, ends, points, half_width):
    """For each segment ``q -> ends[i]``, True when no point lies within ``half_width`` of it.

    Parameters
    ----------
    q : ndarray, shape (2,)
        Common start [m].
    ends : ndarray, shape (C, 2)
        Segment ends [m].
    points : ndarray, shape (M, 2)
        [m].
    half_width : float or ndarray, shape (M,)
        [m], one value or one per point.

    Returns
    -------
    ndarray of bool, shape (C,)
    """
    if len(points) == 0:
        return np.ones(len(ends), bool)
    half_width = np.reshape(half_width, (-1, 1)) if np.ndim(half_width) else half_width
    seg = ends - q                                            # (C, 2)
    length2 = np.maximum(np.einsum('ij,ij->i', seg, seg), apf.DIRECTION_EPS)
    rel = points - q                                          # (M, 2)
    t = np.clip((rel @ seg.T) / length2, 0.0, 1.0)            # (M, C)
    px = rel[:, 0:1] - t * seg[:, 0]
    py = rel[:, 1:2] - t * seg[:, 1]
    return np.all(px * px + py * py >= half_width**2, axis=0)


def resample(path, spacing):
    """Points every ``spacing`` [m] (at most) along a polyline ``(N, 2)`` [m], corners kept."""
    pieces = [path[:1]]
    for a, b in zip(path[:-1], path[1:]):
        count = int(math.ceil(math.hypot(*(b - a)) / spacing))
        if count > 0:
            pieces.append(a + np.linspace(0.0, 1.0, count + 1)[1:, None] * (b - a))
    return np.vstack(pieces)


def braking_speed(gap, accel, period):
    """Largest speed [m/s] whose travel over one period plus braking fits in a gap.

    Parameters
    ----------
    gap : float
        Free travel [m]; ``inf`` gives ``inf``.
    accel : float
        Braking deceleration [m/s^2], > 0.
    period : float
        Control period [s], >= 0: the speed is held that long before braking.

    Returns
    -------
    float
        [m/s], >= 0.

    Examples
    --------
    >>> braking_speed(math.inf, 1.0, 0.1)
    inf
    >>> round(braking_speed(0.5, 1.0, 0.0), 6)
    1.0
    """
    if not math.isfinite(gap):
        return math.inf
    gap = max(gap, 0.0)
    return max(0.0, -accel * period + math.sqrt((accel * period)**2 + 2.0 * accel * gap))
