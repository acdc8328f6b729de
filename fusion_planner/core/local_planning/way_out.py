"""Whether a robot ahead of a walking person can still get out of their way.

The evasion looks :data:`~fusion_planner.core.local_planning.evasion.HORIZON`
ahead and picks the escape that meets a person latest. Running ahead of a
person who walks into a side corridor keeps clear for the whole horizon, and
so does the field's push away from them, but a side corridor may be a dead
end: the person walks on, the robot runs out of room and is touched against
the wall. This module looks past the horizon: a robot that ends its escape
in front of a person, inside the band their body sweeps as they walk on, is
*cornered* when it can reach no place beside that band, in the free space
the static scan points leave (a pocket as wide as the person), before the
person gets there.

Band
    For a tracked obstacle walking at :data:`MIN_WALKING_SPEED` or more,
    predicted at the end of the escape at ``X`` with unit heading ``u``: the
    points within ``w = radius + robot_radius + PASSING_ROOM`` across ``u``
    of the line ``X + a u``, widening by :data:`BAND_SPREAD` per metre the
    person walks from now (the error of a track's heading). A robot centre
    in it and less than ``radius + robot_radius`` behind the person is in
    the way (ahead of them, or beside them too close); one outside it is
    passed, one farther behind follows.
Room
    The band and the samples just beside it, on a grid of :data:`CELL` [m]
    aligned with ``u``, from ``w`` behind the person to :data:`RUN_ON_TIME`
    of the robot's top speed beyond the robot; a sample is free when the
    robot's disc fits there: no static point within ``robot_radius`` of it,
    and the scan saw through the disc (:class:`_Room`).
Race
    The robot at ``a0`` along the band can reach the stretch of it it gets
    to before the person does: going back towards them it meets them at
    ``(a0 s + w v) / (v + s)`` (or where it is, when that is already
    within their reach), running ahead of a faster person it is caught at
    ``(a0 s - w v) / (s - v)`` (``s`` the person's speed, ``v`` the
    robot's top speed, ``w`` the band's half width).
Verdict
    The free samples of that stretch connected to the robot's end
    (8-neighbours) reach the samples beside the band (a way out), or the
    far end of the sampled band (room to keep going): not cornered.
    Otherwise cornered.

Only the scan counts: the known map is not used, other people do not
block (each sweeps a band of its own), and what the scan has not seen is
no room.

Frames and units: map frame, metres, seconds.

Examples
--------
>>> import numpy as np
>>> from fusion_planner.core.local_planning.controller_base import FollowerParams
>>> p = FollowerParams(max_speed=0.8)
>>> walls = np.array([[x, y] for y in np.arange(-3.0, 0.01, 0.05) for x in (-0.65, 0.65)]
...                  + [[x, -3.0] for x in np.arange(-0.65, 0.66, 0.05)])
>>> person = np.array([[0.0, 0.5, 0.0, -0.6, 0.3]])          # walks down a dead-end pocket
>>> ends = np.array([[0.0, -1.0], [0.0, 1.5]])               # ahead of them, behind them
>>> cornered(np.array([0.0, 1.0]), ends, 0.0, person, walls, p).tolist()
[True, False]
"""

import math

import numpy as np
from scipy import ndimage
from scipy.spatial import cKDTree

from fusion_planner.core.local_planning.local_geometry import half_angle_seen, points_off_circles

#: Sample spacing of the band [m].
CELL = 0.1

#: Slower tracked obstacles [m/s] sweep no band: a person standing or turning
#: round has no direction to be out of the way of.
MIN_WALKING_SPEED = 0.2

#: Room [m] a robot beside the band keeps from the person passing: also the
#: error of a track's position.
PASSING_ROOM = 0.2

#: Widening of the band [m] per metre the person walks from now: the error of a
#: track's heading (about 4.5 degrees).
BAND_SPREAD = 0.08

#: A band free this long [s] at the robot's top speed beyond the robot's end is
#: room to keep going: the robot is not cornered.
RUN_ON_TIME = 5.0

#: Bearing bins of the scan's free space seen from the robot: one per degree
#: (as fine as the simulated laser; a finer scan fills each bin with its nearest
#: return).
BEARING_BINS = 360

#: Neighbours of a sample that connect free space (8-neighbourhood).
_NEIGHBOURS = np.ones((3, 3), bool)


def cornered(q, ends, time, tracked, points, params):
    """Whether each robot end position lies in a dead end in front of a walking person.

    Parameters
    ----------
    q : ndarray, shape (2,)
        The robot's position now [m]: where the scan was taken from.
    ends : ndarray, shape (C, 2)
        Robot positions [m] at the end of the look-ahead.
    time : float
        The look-ahead [s]: when the robot is at ``ends``.
    tracked : ndarray, shape (K, 5)
        ``x, y, vx, vy, radius`` [m, m, m/s, m/s, m] of the tracked
        obstacles now; they go on at their velocity.
    points : ndarray, shape (M, 2)
        The scan's hit points [m]; all of them hide what lies behind them,
        those farther than
        :data:`~fusion_planner.core.local_planning.local_geometry.TRACKED_POINT_MARGIN`
        from every tracked obstacle are static.
    params : FollowerParams
        ``robot_radius`` and ``max_speed``.

    Returns
    -------
    ndarray of bool, shape (C,)
        True where some walking obstacle would drive the robot into a dead
        end (see the module notes).
    """
    result = np.zeros(len(ends), bool)
    walking = tracked[np.hypot(tracked[:, 2], tracked[:, 3]) >= MIN_WALKING_SPEED]
    bands = [_Band(mover, time, params) for mover in walking]
    in_way = [band.holds(ends) for band in bands]
    if not np.any(in_way):
        return result
    static = points_off_circles(points, tracked[:, 0:2], tracked[:, 4])
    if len(static) == 0:
        return result  # open ground: a way out everywhere
    room = _Room(q, points, static, params.robot_radius)
    for band, mask in zip(bands, in_way):
        if np.any(mask):
            result[mask] |= _cornered_by(ends[mask], band, room, params)
    return result


class _Room:
    """Where the robot's disc fits, as far as one scan shows.

    A centre fits when no static point lies within ``radius`` of it and the
    scan saw through the disc: every bearing of :data:`BEARING_BINS` the
    disc covers from ``q`` has its nearest return beyond the centre
    (a wall seen at a grazing angle leaves its returns far apart; what it
    hides is not room).
    """

    def __init__(self, q, points, static, radius):
        self.q = q
        self.radius = radius
        self.tree = cKDTree(static)
        rel = points - q
        bins = _bearing_bins(np.arctan2(rel[:, 1], rel[:, 0]))
        nearest = np.full(BEARING_BINS, math.inf)                 # per bearing bin [m]
        np.minimum.at(nearest, bins, np.hypot(rel[:, 0], rel[:, 1]))
        # nearest return over 2**k bins from each bin on (wrapping), for every k:
        # the minimum over any run of bins is then that of two overlapping powers of two
        levels = [nearest]
        while 2 ** len(levels) <= BEARING_BINS:
            levels.append(np.minimum(levels[-1], np.roll(levels[-1], -2 ** (len(levels) - 1))))
        self.run_minima = np.stack(levels)                       # (K, BEARING_BINS)

    def fits(self, centres):
        """Mask ``(N,)`` of the centres ``(N, 2)`` [m] where the robot's disc fits."""
        clear = self.tree.query(centres, distance_upper_bound=self.radius)[0] > self.radius
        rel = centres - self.q
        distance = np.hypot(rel[:, 0], rel[:, 1])
        half = half_angle_seen(self.radius, distance)
        spans = np.maximum(np.ceil(half / (2.0 * math.pi / BEARING_BINS)).astype(int), 1)
        bins = _bearing_bins(np.arctan2(rel[:, 1], rel[:, 0]))
        length = np.minimum(2 * spans + 1, BEARING_BINS)     # bins the disc covers
        level = np.floor(np.log2(length)).astype(int)
        first = (bins - spans) % BEARING_BINS
        last = (first + length - 2 ** level) % BEARING_BINS
        nearest = np.minimum(self.run_minima[level, first], self.run_minima[level, last])
        return clear & (nearest > distance)


def _bearing_bins(bearings):
    """Bin index ``(N,)`` of bearings [rad]."""
    return np.floor((bearings + math.pi) / (2.0 * math.pi) * BEARING_BINS).astype(int) \
        % BEARING_BINS


class _Band:
    """The band a walking obstacle sweeps ahead of it from the end of the look-ahead.

    Attributes
    ----------
    origin, heading, normal : ndarray, shape (2,)
        The obstacle's predicted centre [m] and unit heading and left normal.
    speed : float
        [m/s].
    touch : float
        Radius plus robot radius [m].
    half_width : float
        Half width [m] at the origin: :attr:`touch`, :data:`PASSING_ROOM`
        and :data:`BAND_SPREAD` of the distance walked to it.
    """

    def __init__(self, mover, time, params):
        self.speed = math.hypot(mover[2], mover[3])
        self.heading = mover[2:4] / self.speed
        self.normal = np.array([-self.heading[1], self.heading[0]])
        self.origin = mover[0:2] + time * mover[2:4]
        self.touch = mover[4] + params.robot_radius
        self.half_width = self.touch + PASSING_ROOM + BAND_SPREAD * self.speed * time

    def coordinates(self, points):
        """Along and across ``(N,)`` [m] of ``points`` ``(N, 2)`` in the band's frame."""
        rel = points - self.origin
        return rel @ self.heading, rel @ self.normal

    def holds(self, ends):
        """Mask ``(C,)`` of the ends ``(C, 2)`` in the way: inside the band, ahead or beside.

        Beside: less than :attr:`touch` behind the person's centre (a robot
        following farther behind is not in their way).
        """
        along, across = self.coordinates(ends)
        return (along > -self.touch) & (np.abs(across) < self.half_width)


def _cornered_by(ends, band, room, params):
    """For ends ``(C, 2)`` inside ``band`` (a :class:`_Band`): cornered ``(C,)`` (module notes)."""
    speed, half_width, v = band.speed, band.half_width, params.max_speed
    along, across = band.coordinates(ends)
    far = float(np.max(along)) + v * RUN_ON_TIME
    first = -int(math.ceil(half_width / CELL))
    rows = np.arange(first, int(math.ceil(far / CELL)) + 1) * CELL             # (R,)
    widths = half_width + BAND_SPREAD * np.maximum(rows, 0.0)                   # (R,)
    edge = int(math.ceil(widths[-1] / CELL))
    cols = np.arange(-edge, edge + 1) * CELL                                    # (W,)
    samples = band.origin + rows[:, None, None] * band.heading \
        + cols[None, :, None] * band.normal
    free = room.fits(samples.reshape(-1, 2)).reshape(len(rows), len(cols))
    beside = np.abs(cols)[None, :] >= widths[:, None] - 1e-9                    # (R, W)
    met = np.minimum((along * speed + half_width * v) / (v + speed), along)
    caught = np.full(len(ends), math.inf) if v >= speed else \
        (along * speed - half_width * v) / (speed - v)
    out = np.zeros(len(ends), bool)
    stretches = {}  # labelled free samples per stretch of rows the robot can reach
    for i in range(len(ends)):
        stretch = (int(np.searchsorted(rows, met[i] - 1e-9)),
                   int(np.searchsorted(rows, caught[i] + 1e-9)))
        if stretch not in stretches:
            reach = free.copy()
            reach[:stretch[0]] = reach[stretch[1]:] = False
            stretches[stretch] = reach, ndimage.label(reach, structure=_NEIGHBOURS)[0]
        reach, labels = stretches[stretch]
        start = _start_cell(reach, along[i] / CELL - first, across[i] / CELL + edge)
        if start is None:
            continue
        region = labels == labels[start]
        out[i] = not (np.any(region & beside) or np.any(region[-1]))
    return out


def _start_cell(reach, row, col):
    """The free sample ``(row, col)`` nearest the fractional indices, within one cell; or None."""
    r0, c0 = int(round(row)), int(round(col))
    best, best_d = None, math.inf
    for r in range(r0 - 1, r0 + 2):
        for c in range(c0 - 1, c0 + 2):
            if 0 <= r < reach.shape[0] and 0 <= c < reach.shape[1] and reach[r, c]:
                d = (r - row)**2 + (c - col)**2
                if d < best_d:
                    best, best_d = (r, c), d
    return best
