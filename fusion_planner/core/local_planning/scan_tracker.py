"""Moving obstacles tracked from laser scans alone.

:class:`ScanTracker` turns a sequence of scans into the moving obstacles a
controller avoids (:attr:`Observation.tracked`):

1. **Map explanation and segmentation** (:mod:`scan_segments`): returns on the
   known map are dropped, the rest cut into object candidates (centre,
   radius) by beam adjacency, range jumps and notches (two people shoulder
   to shoulder). A candidate with returns near two or more confirmed
   tracks' predicted circles (within ``cluster_gap`` of their edges) that
   is more than :data:`MERGE_RATIO` times larger than each of them, or
   wider than ``max_object_radius``, is cut into one part per track
   (:func:`scan_segments.split_among`): two people side by side seen
   nearly in line, or one coming out from behind another, show no notch,
   and the one candidate they make would be taken by one track (swinging
   its velocity) or by none (leaving both to die). Other candidates wider
   than ``max_object_radius`` are static structure and are not tracked.
2. **Prediction**: every track is a constant-velocity Kalman filter (state
   ``x, y, vx, vy``, white-noise acceleration of ``acceleration_std``),
   predicted to the scan's time.
3. **Association**: the squared Mahalanobis distance of each candidate to
   each predicted track, gated at ``gate`` (chi-square, 2 degrees of
   freedom), at ``max_gate_distance``, and by size: a whole candidate more
   than ``size_ratio`` times larger or smaller than a confirmed track (not
   one born partly hidden, step 4, which may be larger than it looked) is a
   merge (a person beside a box or another person) or a split (two who
   walked together part) and is not that track's object; one-to-one by
   the Hungarian method (:func:`scipy.optimize.linear_sum_assignment`).
   Correcting a track with the centre of a merge would swing its velocity
   the wrong way; the track coasts instead, and the candidate starts a
   track of its own.
4. **Update, birth, death**: matched tracks are corrected, except by a
   partly hidden candidate (a nearer return beside it: its centre is
   biased), which only keeps its track alive; unmatched whole candidates
   start tentative tracks (at rest, velocity uncertain); a
   tentative track that misses a scan, or any track unseen for
   ``coast_time``, is dropped. A person may walk for seconds partly hidden
   behind another, or be seen coming out from behind a wall corner for a
   second before they are seen whole: a partly hidden candidate just behind a
   moving track (their angular extents, seen from the laser, within two
   beams), or hidden by a return the map explains
   (:attr:`scan_segments.Segments.behind_map`), and at least
   :data:`HIDDEN_BIRTH_RADIUS` across also starts a track, which such
   candidates then correct, with the hidden part's bias as extra noise
   (:data:`HIDDEN_BIAS_FRACTION` of the track's radius) and the larger of
   the two radii (what is seen is a lower bound). Uncovering a static object
   moves its centre estimate by up to its radius, so a track born partly
   hidden must travel its radius farther than ``min_travel`` to move.
5. **Report**: only tracks that move. A track is *moving* once it has been
   matched ``confirm_hits`` times, has travelled ``min_travel`` from where
   it was born, and its speed is at least ``min_speed``. It stays moving
   until its speed has been below half of ``min_speed`` for ``stop_time``
   (a person turning round passes
   through zero speed), and must then travel again. A static object's
   centre estimate shifts as the view changes, so a track also stops moving
   once most of its returns have fallen in cells hit without a break for
   ``static_age`` (:mod:`hit_ages`) for ``stop_time`` (a person turning
   round walks back over the cells it has just hit),
   unless it has gone farther than ``max_object_radius`` from where it first
   appeared (no change of view moves a centre that far; a slow person keeps
   hitting the same cells for a while). While its returns stay put, a
   track does not start moving (even coasting, unmatched, on the velocity
   a changing view gave it), and a track born on returns that already stay
   put starts as having stayed ``static_age``: a static object whose track
   was lost (its candidate looked wider than ``max_object_radius`` for a
   while) is not reborn as a mover. Everything else (static unknown
   obstacles, people standing still) stays scan points.
6. **Tentative movers**: tracks matched ``confirm_hits`` times that are not
   (yet) moving, whose returns do not stay put, and whose estimated speed
   is at least ``min_speed``, reported apart
   (:attr:`TrackReport.tentative`): a person who has just stepped out from
   behind a corner has a usable velocity estimate long before it has
   travelled ``min_travel``, while a static object's estimate may wander
   for a second as the view changes. A controller checks its commands
   against them without treating them as people. Like a moving track, a
   tentative mover stays one until its speed has been below half of
   ``min_speed`` for ``stop_time``: a person coming out from behind a
   corner at first shows only its front, whose centre estimate stands
   still, or slips back, while more of it comes into view, and its speed
   estimate passes through zero.
7. **Turns**: how much each track turns, its heading diffusion
   [rad / sqrt(s)] (:attr:`TrackReport.turn_stds`), for a controller that
   samples where a person may go (a person walking down a corridor turns
   less than one wandering in a hall). Every ``turn_window`` the direction
   of a track's travel over the window is compared with that over the
   window before (positions, not the filtered velocity, whose direction
   wobbles far more); the squared change, scaled to a diffusion, enters a
   running mean of time constant ``turn_memory``, which starts at
   ``turn_prior``.

Deterministic: the same scans give the same tracks (no randomness; ties in
the assignment are broken by index). Vectorised over beams, candidates and
tracks: one update is a fixed number of numpy calls.

Bad scans are refused with a reason and leave the tracks as they were
(:class:`ScanVerdict`): mismatched or empty arrays, a non-finite pose or
time, a scan not newer than the last one. NaN and infinite ranges are no
returns.

Frames and units: map frame, metres, seconds, radians.

References: Y. Bar-Shalom, X. R. Li and T. Kirubarajan, *Estimation with
Applications to Tracking and Navigation*, Wiley 2001 (ch. 6, the discretised
white-noise acceleration model).

Examples
--------
>>> import numpy as np
>>> from fusion_planner.core.grid import GridMap
>>> from fusion_planner.core.simulation.world import ray_circle_distances
>>> tracker = ScanTracker(GridMap(np.zeros((100, 100), bool), resolution=0.1))
>>> angles = np.linspace(-np.pi, np.pi, 720, endpoint=False)
>>> beams = np.stack([np.cos(angles), np.sin(angles)], axis=1)
>>> origin = np.array([1.0, 5.0, 0.0])
>>> for k in range(15):            # a walker 4 m ahead crossing at 1 m/s
...     centre = np.array([[5.0, 3.5 + 0.1 * k]])
...     ranges = ray_circle_distances(origin[:2], beams, centre, np.array([0.3]))
...     verdict = tracker.update(angles, ranges, origin, time=0.1 * k)
>>> report = tracker.report()
>>> report.tracked.shape, bool(abs(report.tracked[0, 3] - 1.0) < 0.2)
((1, 5), True)
"""

import math
import dataclasses
from dataclasses import dataclass

import numpy as np
from scipy.optimize import linear_sum_assignment

from fusion_planner.core.errors import InvalidInput
from fusion_planner.core.local_planning.hit_ages import HitAges
from fusion_planner.core.local_planning.local_geometry import half_angle_seen
from fusion_planner.core.local_planning.scan_segments import (
    map_explained_mask, segment_scan, split_among)

#: A candidate with at least this fraction of its returns in old cells stays put.
STATIC_FRACTION = 0.5
#: A candidate with returns near two or more confirmed tracks and more than
#: this many times larger than each of them is their merge, and is cut apart
#: (:func:`scan_segments.split_among`).
MERGE_RATIO = 1.2
#: Cost of a forbidden (gated out) pairing in the assignment; any gated-in
#: cost is below ``gate``.
FORBIDDEN_COST = 1e9
#: A partly hidden candidate behind a moving track or a wall starts a track
#: only from this radius [m] on: a sliver of a few returns beside a walker is
#: as often the edge of whatever stands behind them.
HIDDEN_BIRTH_RADIUS = 0.1
#: Standard deviation of a partly hidden candidate's centre, as a fraction of
#: its track's radius (added to ``measurement_std``).
HIDDEN_BIAS_FRACTION = 0.5


@dataclass(frozen=True)
class TrackerParams:
    """Everything that tunes :class:`ScanTracker`.

    Attributes
    ----------
    map_tolerance : float
        A return within this distance [m] of an occupied map cell (at least
        1.5 cells) is explained by the map.
    cluster_gap : float
        Adjacent returns farther apart [m] belong to different objects.
    min_points : int
        Fewer returns than this are not an object.
    split_depth : float
        A run of returns is cut where its range peaks this much [m] above
        both sides (two people side by side).
    max_object_radius : float
        Candidates with a larger radius [m] are static structure.
    measurement_std : float
        Standard deviation [m] of a candidate's centre.
    acceleration_std : float
        Standard deviation [m/s^2] of the white-noise acceleration.
    initial_speed_std : float
        Standard deviation [m/s] of a new track's velocity (it starts at
        rest).
    gate : float
        Largest squared Mahalanobis distance of an association (13.8: 99.9 %
        of a 2-D Gaussian).
    max_gate_distance : float
        Largest distance [m] of an association, whatever the covariance.
    size_ratio : float
        Largest ratio (> 1) of a whole candidate's radius to a confirmed
        track's, either way, that still associates.
    confirm_hits : int
        Matches before a track may be reported.
    coast_time : float
        A track unseen for this long [s] is dropped.
    min_speed : float
        Slowest speed [m/s] of a moving track.
    min_travel : float
        Distance [m] from its birth a track must have travelled to be moving.
    stop_time : float
        A moving track stops moving once its speed has been below half of
        ``min_speed``, or its returns in old cells (see ``static_age``), for
        this long [s].
    radius_smoothing : float
        Weight in (0, 1] of a new radius in a track's running mean.
    static_age : float
        A candidate with most of its returns in cells hit without a break for
        this long [s] stays put: its track is not moving (unless it has gone
        farther than ``max_object_radius`` from where it first appeared).
    hit_break : float
        A cell not hit for longer than this [s] starts a new run of hits.
    max_tracks : int
        Cap on live tracks; the candidates nearest the laser are kept.
    turn_prior : float
        Heading diffusion [rad / sqrt(s)] assumed of a track not yet seen to
        walk straight or turn (see :attr:`TrackReport.turn_stds`).
    turn_window : float
        Interval [s] over which a track's heading change is measured.
    turn_memory : float
        Time constant [s] of the running estimate of its heading diffusion.
    """

    map_tolerance: float = 0.15
    cluster_gap: float = 0.3
    min_points: int = 2
    split_depth: float = 0.15
    max_object_radius: float = 0.6
    measurement_std: float = 0.05
    acceleration_std: float = 1.0
    initial_speed_std: float = 1.5
    gate: float = 13.8
    max_gate_distance: float = 1.0
    size_ratio: float = 1.6
    confirm_hits: int = 3
    coast_time: float = 0.6
    min_speed: float = 0.1
    min_travel: float = 0.25
    stop_time: float = 0.5
    radius_smoothing: float = 0.3
    static_age: float = 1.0
    hit_break: float = 0.3
    max_tracks: int = 100
    turn_prior: float = 0.6
    turn_window: float = 1.0
    turn_memory: float = 2.0

    def __post_init__(self):
        for name in ('map_tolerance', 'cluster_gap', 'split_depth', 'max_object_radius',
                     'measurement_std',
                     'acceleration_std', 'initial_speed_std', 'gate', 'max_gate_distance',
                     'size_ratio',
                     'coast_time', 'radius_smoothing', 'static_age', 'hit_break',
                     'turn_prior', 'turn_window', 'turn_memory'):
            _check_real(name, getattr(self, name), zero_ok=False)
        for name in ('min_speed', 'min_travel', 'stop_time'):
            _check_real(name, getattr(self, name), zero_ok=True)
        for name in ('min_points', 'confirm_hits', 'max_tracks'):
            value = getattr(self, name)
            if isinstance(value, bool) or not isinstance(value, int) or value < 1:
                raise InvalidInput(
                    f'TrackerParams.{name} must be a positive integer, got {value!r}')
        if not self.size_ratio > 1.0:
            raise InvalidInput(f'TrackerParams.size_ratio must be > 1, got {self.size_ratio!r}')


def _check_real(name, value, zero_ok):
    """Raise InvalidInput unless ``value`` is a finite real > 0 (>= 0 with ``zero_ok``)."""
    ok = (isinstance(value, (int, float)) and not isinstance(value, bool) and math.isfinite(value)
          and (value >= 0 if zero_ok else value > 0))
    if not ok:
        relation = '>=' if zero_ok else '>'
        raise InvalidInput(f'TrackerParams.{name} must be a finite number {relation} 0, '
                           f'got {value!r}')


@dataclass(frozen=True)
class ScanVerdict:
    """What :meth:`ScanTracker.update` made of a scan.

    Attributes
    ----------
    accepted : bool
        False: the scan was refused and the tracks are unchanged.
    reason : str
        Why it was refused, or a note on an accepted scan ('' when none).
    """

    accepted: bool
    reason: str = ''


@dataclass(frozen=True)
class TrackReport:
    """The moving tracks at one instant.

    Attributes
    ----------
    ids : ndarray, int64, shape (K,)
        Track identities (stable while a track lives, never reused).
    states : ndarray, float64, shape (K, 4)
        ``x, y, vx, vy`` [m, m, m/s, m/s], map frame.
    covariances : ndarray, float64, shape (K, 4, 4)
        Their covariances (same units, squared).
    radii : ndarray, float64, shape (K,)
        [m]: a running mean of the radii of the whole (not partly hidden)
        candidates matched to each track.
    tentative : ndarray, float64, shape (T, 5)
        ``x, y, vx, vy, radius`` of the tentative movers (module notes,
        step 6), same frame and units.
    turn_stds : ndarray, float64, shape (K,)
        Each track's heading diffusion [rad / sqrt(s)] (module notes, step
        7): how much it turns.
    """

    ids: np.ndarray
    states: np.ndarray
    covariances: np.ndarray
    radii: np.ndarray
    tentative: np.ndarray = dataclasses.field(default_factory=lambda: np.zeros((0, 5)))
    turn_stds: np.ndarray = dataclasses.field(default_factory=lambda: np.zeros(0))

    @property
    def tracked(self):
        """``(K, 5)`` rows ``x, y, vx, vy, radius``, as :attr:`Observation.tracked`."""
        return np.column_stack([self.states, self.radii]).reshape(-1, 5)


class ScanTracker:
    """Tracks moving obstacles through laser scans (see the module notes).

    Parameters
    ----------
    grid : GridMap
        The known map; returns on it are not objects.
    params : TrackerParams, optional

    Attributes
    ----------
    time : float or None
        Time [s] of the last accepted scan.
    """

    def __init__(self, grid, params=None):
        self.grid = grid
        self.params = params or TrackerParams()
        self._explained = map_explained_mask(grid, self.params.map_tolerance)
        self._ages = HitAges(grid, self.params.hit_break)
        self._measurement_cov = np.eye(2) * self.params.measurement_std ** 2
        self.time = None
        self._next_id = 0
        self._ids = np.zeros(0, np.int64)
        self._x = np.zeros((0, 4))
        self._p = np.zeros((0, 4, 4))
        self._radius = np.zeros(0)
        self._hits = np.zeros(0, np.int64)
        self._last_seen = np.zeros(0)
        self._birth = np.zeros((0, 2))     # where each track must travel min_travel from [m]
        self._origin = np.zeros((0, 2))    # where each track first appeared [m]
        self._moving = np.zeros(0, bool)
        self._tentative = np.zeros(0, bool)  # a tentative mover (module notes, step 6)
        self._slow_since = np.zeros(0)     # since when a track is below half min_speed [s]
        self._stays = np.zeros(0, bool)    # its returns stayed put at its last match (step 5)
        self._born_hidden = np.zeros(0, bool)  # born partly hidden (step 4)
        self._staying_since = np.zeros(0)  # since when they have [s] (inf: they have not)
        self._turn_var = np.zeros(0)       # heading diffusion estimate [rad^2 / s]
        self._anchors = np.zeros((0, 2, 2))  # positions at the last two window ends [m]
        self._anchor_time = np.zeros(0)    # time of the later one [s]

    def update(self, angles, ranges, origin, time):
        """Take in one scan.

        Parameters
        ----------
        angles : array_like, shape (n,)
            Beam angles [rad], laser frame, increasing.
        ranges : array_like, shape (n,)
            Ranges [m]; NaN, ``inf`` and non-positive values are no return.
        origin : array_like, shape (3,)
            Laser pose ``(x, y, yaw)`` in the map frame when the scan was
            taken.
        time : float
            Scan time [s].

        Returns
        -------
        ScanVerdict
        """
        scan = _checked_scan(angles, ranges, origin, time)
        if isinstance(scan, ScanVerdict):
            return scan
        angles, ranges, origin = scan
        if self.time is not None and not time > self.time:
            return ScanVerdict(False, f'scan at {time:.3f} s is not newer than the last one '
                                      f'({self.time:.3f} s)')
        dt = 0.0 if self.time is None else time - self.time
        self.time = float(time)
        self._predict(dt)
        p = self.params
        segments = segment_scan(angles, ranges, origin, self.grid, self._explained,
                                p.cluster_gap, p.min_points, p.split_depth)
        confirmed = self._hits >= p.confirm_hits
        segments = split_among(segments, origin, self._x[confirmed, 0:2],
                               self._radius[confirmed], p.cluster_gap, p.min_points,
                               p.max_object_radius, MERGE_RATIO)
        staying = self._staying(segments)
        objects = segments.radii <= p.max_object_radius
        centers, radii = segments.centers[objects], segments.radii[objects]
        occluded, staying = segments.occluded[objects], staying[objects]
        # partly hidden behind a mover or a wall corner: they may start a track (step 4)
        behind = segments.behind_map[objects]          # a copy; implies occluded
        behind[occluded] |= self._behind_movers(centers[occluded], radii[occluded], origin[:2],
                                                segments.beam_spacing)
        track_of = self._associate(centers, np.where(occluded, np.nan, radii))
        matched = track_of >= 0
        whole = matched & ~occluded
        self._correct(track_of[whole], centers[whole], radii[whole])
        # a track born partly hidden follows such glimpses of it
        glimpsed = matched & behind
        glimpsed[glimpsed] = self._born_hidden[track_of[glimpsed]]
        tracks = track_of[glimpsed]
        self._correct(tracks, centers[glimpsed], np.maximum(self._radius[tracks], radii[glimpsed]),
                      (HIDDEN_BIAS_FRACTION * self._radius[tracks]) ** 2)
        self._measure_turns(track_of[whole])
        # any other partly hidden object's centre is too biased: its track coasts, but lives on
        self._last_seen[track_of[matched & occluded]] = self.time
        # an object whose returns stay in the same cells is not moving, whatever
        # its centre estimate does as the view changes; it must travel again,
        # unless it is farther from where it first appeared than any change of
        # view moves a centre (a slow person keeps hitting the same cells)
        seen = track_of[matched]
        held = staying[matched] & (np.hypot(*(self._x[seen, 0:2] - self._origin[seen]).T)
                                   <= p.max_object_radius)
        self._stays[seen] = held
        self._staying_since[seen] = np.where(held, np.minimum(self._staying_since[seen],
                                                              self.time), np.inf)
        still = seen[held & (self.time - self._staying_since[seen] >= p.stop_time)]
        self._moving[still] = False
        self._birth[still] = self._x[still, 0:2]
        self._drop_lost()
        born = ~matched & (~occluded | (behind & (radii >= HIDDEN_BIRTH_RADIUS)))
        self._give_birth(centers[born], radii[born], staying[born], occluded[born], origin[:2])
        self._mark_moving()
        note = '' if np.isfinite(ranges).any() else 'no returns'
        return ScanVerdict(True, note)

    def report(self, time=None):
        """The moving tracks and the tentative movers, optionally predicted ahead.

        Parameters
        ----------
        time : float, optional
            Predict positions (constant velocity) to this time [s]; default
            the last scan's time.

        Returns
        -------
        TrackReport
        """
        keep = self._moving
        ahead = 0.0
        if time is not None and self.time is not None and math.isfinite(time):
            ahead = time - self.time
        states = self._x.copy()
        states[:, 0:2] += states[:, 2:4] * ahead
        tentative = self._tentative & ~self._stays
        return TrackReport(ids=self._ids[keep].copy(), states=states[keep],
                           covariances=self._p[keep].copy(), radii=self._radius[keep].copy(),
                           tentative=np.column_stack([states[tentative],
                                                      self._radius[tentative]]).reshape(-1, 5),
                           turn_stds=np.sqrt(self._turn_var[keep]))

    @property
    def live_tracks(self):
        """Number of tracks alive, moving or not (the work of an update)."""
        return len(self._ids)

    def reset(self):
        """Forget every track (e.g. after a clock jump)."""
        self.__init__(self.grid, self.params)

    # -- filter steps -------------------------------------------------------------

    def _staying(self, segments):
        """Whether most of each candidate's returns fall in cells hit for ``static_age``."""
        if not len(segments.unexplained):
            return np.zeros(0, bool)
        old = self._ages.update(segments.unexplained, self.time) >= self.params.static_age
        labelled = segments.labels >= 0
        old_count = np.bincount(segments.labels[labelled], weights=old[labelled],
                                minlength=len(segments.counts))
        return old_count >= STATIC_FRACTION * segments.counts

    def _behind_movers(self, centers, radii, laser, beam_spacing):
        """Whether each candidate (N, 2) [m] lies just behind a moving track, seen from ``laser``.

        Behind: farther from the laser than the track's centre, with the two
        discs' angular extents (``radii`` (N,) [m], the track's radius) within
        two beams (``beam_spacing`` [rad]) of each other.
        """
        movers = self._moving
        if not len(centers) or not movers.any():
            return np.zeros(len(centers), bool)
        sight = centers - laser
        far = np.hypot(sight[:, 0], sight[:, 1])
        mover_sight = self._x[movers, 0:2] - laser
        near = np.hypot(mover_sight[:, 0], mover_sight[:, 1])
        half_width = half_angle_seen(radii, far)
        mover_half_width = half_angle_seen(self._radius[movers], near)
        bearing = np.arctan2(sight[:, 1], sight[:, 0])
        mover_bearing = np.arctan2(mover_sight[:, 1], mover_sight[:, 0])
        apart = np.abs(np.angle(np.exp(1j * (bearing[:, None] - mover_bearing[None, :]))))
        touching = apart <= half_width[:, None] + mover_half_width[None, :] + 2.0 * beam_spacing
        return np.any(touching & (near[None, :] < far[:, None]), axis=1)

    def _predict(self, dt):
        if dt <= 0 or not len(self._x):
            return
        f = np.eye(4)
        f[0, 2] = f[1, 3] = dt
        q = self.params.acceleration_std ** 2
        block = q * np.array([[dt ** 3 / 3, dt ** 2 / 2], [dt ** 2 / 2, dt]])
        noise = np.zeros((4, 4))
        noise[np.ix_([0, 2], [0, 2])] = block
        noise[np.ix_([1, 3], [1, 3])] = block
        self._x = self._x @ f.T
        self._p = f @ self._p @ f.T + noise

    def _associate(self, centers, radii):
        """Track index of each candidate (-1: none), by gated Hungarian assignment.

        ``radii`` (C,) [m] are the candidates' radii, NaN for partly hidden
        ones (their size says nothing).
        """
        track_of = np.full(len(centers), -1, np.int64)
        if not len(centers) or not len(self._x):
            return track_of
        p = self.params
        innovation = centers[None, :, :] - self._x[:, None, 0:2]            # (K, C, 2)
        s = self._p[:, 0:2, 0:2] + self._measurement_cov                     # (K, 2, 2)
        s_inv = np.linalg.inv(s)
        mahalanobis = np.einsum('kci,kij,kcj->kc', innovation, s_inv, innovation)
        distance = np.hypot(innovation[..., 0], innovation[..., 1])
        ratio = radii[None, :] / self._radius[:, None]                          # (K, C)
        with np.errstate(invalid='ignore'):  # NaN: a partly hidden candidate, any size
            resized = (ratio > p.size_ratio) | (ratio < 1.0 / p.size_ratio)
        resized &= ((self._hits >= p.confirm_hits) & ~self._born_hidden)[:, None]
        allowed = (mahalanobis <= p.gate) & (distance <= p.max_gate_distance) & ~resized
        cost = np.where(allowed, mahalanobis, FORBIDDEN_COST)
        rows, cols = linear_sum_assignment(cost)
        ok = allowed[rows, cols]
        track_of[cols[ok]] = rows[ok]
        return track_of

    def _correct(self, tracks, centers, radii, extra_variance=0.0):
        """Kalman-correct ``tracks`` with ``centers``, whose variance [m^2] is
        ``measurement_std`` squared plus ``extra_variance`` (scalar or per track)."""
        if not len(tracks):
            return
        x, p = self._x[tracks], self._p[tracks]
        extra = np.broadcast_to(extra_variance, (len(tracks),))[:, None, None] * np.eye(2)
        s = p[:, 0:2, 0:2] + self._measurement_cov + extra
        gain = p[:, :, 0:2] @ np.linalg.inv(s)                                 # (m, 4, 2)
        x = x + np.einsum('mij,mj->mi', gain, centers - x[:, 0:2])
        p = p - gain @ p[:, 0:2, :]
        self._x[tracks] = x
        self._p[tracks] = 0.5 * (p + np.swapaxes(p, 1, 2))
        weight = self.params.radius_smoothing
        self._radius[tracks] += weight * (radii - self._radius[tracks])
        self._hits[tracks] += 1
        self._last_seen[tracks] = self.time

    def _measure_turns(self, tracks):
        """Update the heading diffusion of ``tracks`` just corrected (module notes, step 7).

        The heading is measured from the track's positions, not its velocity
        (whose direction is far noisier): the direction of its travel over
        one ``turn_window`` against that over the window before. For a
        heading that diffuses by ``s`` [rad / sqrt(s)], the difference of
        its means over two windows of ``w`` [s] has variance ``2 w s^2 / 3``.
        """
        p = self.params
        now = self._x[tracks, 0:2]
        window = self.time - self._anchor_time[tracks]
        due = window >= p.turn_window
        tracks, now, window = tracks[due], now[due], window[due]
        before = self._anchors[tracks, 1] - self._anchors[tracks, 0]
        after = now - self._anchors[tracks, 1]
        least = p.min_speed * window
        walked = (np.hypot(*before.T) >= least) & (np.hypot(*after.T) >= least)
        turned = np.angle(np.exp(1j * (np.arctan2(after[:, 1], after[:, 0])
                                       - np.arctan2(before[:, 1], before[:, 0]))))
        done = tracks[walked]
        var = self._turn_var[done]
        weight = np.minimum(window[walked] / p.turn_memory, 1.0)
        sample = 1.5 * turned[walked] ** 2 / window[walked]
        self._turn_var[done] = var + weight * (sample - var)
        self._anchors[tracks, 0] = self._anchors[tracks, 1]
        self._anchors[tracks, 1] = now
        self._anchor_time[tracks] = self.time

    def _drop_lost(self):
        unseen = self._last_seen < self.time
        tentative = self._hits < self.params.confirm_hits
        lost = (unseen & tentative) | (self.time - self._last_seen > self.params.coast_time)
        if lost.any():
            self._keep(~lost)

    def _give_birth(self, centers, radii, staying, hidden, laser):
        """Start tentative tracks on ``centers`` (N, 2) [m] of ``radii`` (N,) [m].

        ``hidden`` (N,): partly hidden candidates (step 4 of the module notes).

        ``staying`` (N,): whose returns fall in old cells; such a candidate
        has been where it is for at least ``static_age``, so its track starts
        as having stayed that long (a static object whose track was lost,
        e.g. while its candidate looked wider than ``max_object_radius``, is
        not reborn as a mover when the changing view shifts its centre).
        """
        room = self.params.max_tracks - len(self._x)
        if room <= 0 or not len(centers):
            return
        if len(centers) > room:
            nearest = np.sort(np.argsort(np.hypot(*(centers - laser).T), kind='stable')[:room])
            centers, radii = centers[nearest], radii[nearest]
            staying, hidden = staying[nearest], hidden[nearest]
        n = len(centers)
        x = np.zeros((n, 4))
        x[:, 0:2] = centers
        p = np.zeros((n, 4, 4))
        p[:, 0, 0] = p[:, 1, 1] = self.params.measurement_std ** 2
        p[:, 2, 2] = p[:, 3, 3] = self.params.initial_speed_std ** 2
        self._ids = np.concatenate([self._ids, self._next_id + np.arange(n)])
        self._next_id += n
        self._x = np.concatenate([self._x, x])
        self._p = np.concatenate([self._p, p])
        self._radius = np.concatenate([self._radius, radii])
        self._hits = np.concatenate([self._hits, np.ones(n, np.int64)])
        self._last_seen = np.concatenate([self._last_seen, np.full(n, self.time)])
        self._birth = np.concatenate([self._birth, centers])
        self._origin = np.concatenate([self._origin, centers])
        self._moving = np.concatenate([self._moving, np.zeros(n, bool)])
        self._tentative = np.concatenate([self._tentative, np.zeros(n, bool)])
        self._slow_since = np.concatenate([self._slow_since, np.full(n, self.time)])
        self._stays = np.concatenate([self._stays, staying])
        self._born_hidden = np.concatenate([self._born_hidden, hidden])
        self._staying_since = np.concatenate(
            [self._staying_since, np.where(staying, self.time - self.params.static_age, np.inf)])
        self._turn_var = np.concatenate([self._turn_var, np.full(n, self.params.turn_prior ** 2)])
        self._anchors = np.concatenate([self._anchors, np.repeat(centers[:, None], 2, axis=1)])
        self._anchor_time = np.concatenate([self._anchor_time, np.full(n, self.time)])

    def _mark_moving(self):
        p = self.params
        speed = np.hypot(self._x[:, 2], self._x[:, 3])
        travelled = np.hypot(*(self._x[:, 0:2] - self._birth).T)
        # returns that stayed put at the last match hold a track back, even one
        # coasting on a velocity that a changing view gave it
        travel = p.min_travel + np.where(self._born_hidden, self._radius, 0.0)
        starts = ((self._hits >= p.confirm_hits) & (travelled >= travel)
                  & (speed >= p.min_speed) & ~self._stays)
        slow = speed < 0.5 * p.min_speed
        self._slow_since = np.where(slow, np.minimum(self._slow_since, self.time), np.inf)
        settled = slow & (self.time - self._slow_since >= p.stop_time)
        stops = self._moving & settled
        # a stopped track must travel again from where it stopped
        self._birth[stops] = self._x[stops, 0:2]
        self._moving = (self._moving & ~stops) | starts
        self._tentative = ((self._hits >= p.confirm_hits) & ~self._moving
                           & ((speed >= p.min_speed) | (self._tentative & ~settled)))

    def _keep(self, mask):
        self._ids, self._x, self._p = self._ids[mask], self._x[mask], self._p[mask]
        self._radius, self._hits = self._radius[mask], self._hits[mask]
        self._last_seen, self._birth = self._last_seen[mask], self._birth[mask]
        self._origin = self._origin[mask]
        self._moving, self._tentative = self._moving[mask], self._tentative[mask]
        self._slow_since = self._slow_since[mask]
        self._stays = self._stays[mask]
        self._born_hidden = self._born_hidden[mask]
        self._staying_since = self._staying_since[mask]
        self._turn_var = self._turn_var[mask]
        self._anchors, self._anchor_time = self._anchors[mask], self._anchor_time[mask]


def _checked_scan(angles, ranges, origin, time):
    """``(angles, ranges, origin)`` as float arrays, or the ScanVerdict refusing them."""
    try:
        angles = np.asarray(angles, dtype=float).reshape(-1)
        ranges = np.asarray(ranges, dtype=float).reshape(-1)
        origin = np.asarray(origin, dtype=float).reshape(-1)
        time = float(time)
    except (TypeError, ValueError) as err:
        return ScanVerdict(False, f'scan is not numeric: {err}')
    if not len(angles) or len(angles) != len(ranges):
        return ScanVerdict(False, f'scan needs as many ranges as angles (>= 1), got '
                                  f'{len(ranges)} ranges and {len(angles)} angles')
    if not np.all(np.isfinite(angles)):
        return ScanVerdict(False, 'scan angles must be finite')
    if origin.shape != (3,) or not np.all(np.isfinite(origin)):
        return ScanVerdict(False, f'laser pose must be three finite numbers, got {origin.tolist()}')
    if not math.isfinite(time):
        return ScanVerdict(False, f'scan time must be finite, got {time!r}')
    return angles, ranges, origin

