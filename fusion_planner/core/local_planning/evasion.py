"""Evasion of moving obstacles: a short look-ahead check of every field command.

The improved field steers around tracked obstacles at their predicted
positions, but a field only pushes: a robot slowed beside a wall, turning in
place at a local minimum, or facing away from an obstacle that walks at it
(moving obstacles ignore the robot) feels no force that makes it leave in
time. This module checks the command a field controller chose against the
tracked obstacles' predicted motion and replaces it when it leads into
contact, as a velocity-space safety layer (in the spirit of the dynamic
window: D. Fox, W. Burgard and S. Thrun, "The dynamic window approach to
collision avoidance", IEEE Robotics & Automation Magazine 4(1), 1997).

Rollout
    The robot holds a target ``(v, omega)``, reached from the measured
    velocity within ``max_accel`` and ``max_alpha``, one control period at a
    time as the controller's commands will take it (each period's command
    held for the period, the unicycle's chord taken at the period's middle
    heading; positions kept every :data:`ROLLOUT_STEP` over
    :data:`HORIZON`, within millimetres of the simulated robot). Each tracked obstacle goes on
    at its velocity with its radius grown by :data:`UNCERTAINTY_RATE` per
    second of look-ahead (it may turn: a random walk, a bounce, the end of a
    waypoint leg).
Check
    A command is safe when its rollout keeps :data:`MOVING_MARGIN` from
    every grown obstacle, and for the first :data:`TURN_ROUND_HORIZON` of
    it also from each obstacle walking back at its speed (a person ahead may
    turn round; over the whole horizon for a person beside a wall who
    crosses the robot's way, :func:`_walled_crossers`), and from each
    obstacle deflected by another it is about to
    meet (people do not walk through each other: from the moment their
    predicted discs come within :data:`MEETING_MARGIN`, its velocity
    reflected about the line of their centres; :func:`hypotheses`), and
    when its *contact risk* is at
    most :data:`RISK_LIMIT`: over sampled futures in which each obstacle
    keeps its speed and its heading diffuses as the tracker measured
    (``turn_stds``; :data:`TURN_STD` if unknown, and at least that for a
    person in the open, farther than :data:`OPEN_CLEARANCE` from every
    static point;
    :mod:`~fusion_planner.core.local_planning.walker_futures`), the mean
    weight ``exp(-t / RISK_TIME)`` of the first contact (closer than
    :data:`RISK_MARGIN`) at ``t``. The grown disc covers where a person
    going straight may be; the futures cover a person who turns (one at
    0.7 m/s whose heading diffuses by 0.6 rad/sqrt(s) strays 0.24 m
    sideways in a second, one standard deviation; the disc grows by
    0.1 m). The evasion's candidates are judged
    against all three as well. A safe command whose rollout ends in a dead end
    in front of a walking obstacle
    (:mod:`~fusion_planner.core.local_planning.way_out`, past the horizon)
    is replaced all the same when a candidate that leaves a way out is safe.
Evasion
    When the field's command is not safe, a fan of targets (forward speeds
    up to ``max_speed``, reverse ones down to ``-max_reverse_speed`` (at
    most ``max_speed``), turn rates across ``+-max_omega``) and of *pivots*
    (turn on the spot to one of :data:`PIVOT_HEADINGS` headings, then drive
    straight along it at
    one of :data:`PIVOT_SPEED_FRACTIONS` of ``max_speed``: the side-step
    of a robot standing beside a wall, whose every constant arc runs into
    the wall or towards the person) is rolled out the same way and against
    the static points (scan points not on a tracked obstacle): a rollout that
    would come within :data:`STATIC_MARGIN` of them (or closer than now)
    stops there, pinned, and one that would do so within
    :data:`STATIC_HORIZON` is refused. Cornered candidates (see Check) are
    dropped when another keeps clear of the grown obstacles over the whole
    horizon. Only the candidates within :data:`RISK_TOLERANCE` of the
    least contact risk stay; of them, those that do not reverse and
    keep :data:`YIELD_MARGIN` from the obstacles' predicted (not grown)
    motion are preferred when there are any, and of them those that do not
    turn back (lose no ground along the desired direction, or at most
    :data:`TURN_BACK_SLACK` on a brisk arc clear of the grown obstacles: going
    round a person); then the latest predicted
    contact wins, then the least intrusion into the margin (its time
    integral [m s]), then the most progress along the desired direction
    (towards the goal, when the rollouts get as far as it: a robot
    evading beside its goal does not run past it), then the turn rate
    nearest the controller's. An :class:`Evader` (the
    controllers' evasion) keeps a forward target or pivot it chose while
    that is still allowed, as late in contact as the best and within
    :data:`KEEP_INTRUSION` of its intrusion: the rollouts assume the
    choice held, and a robot that switches every period between pivots
    and arcs, or between backing away and driving on, goes nowhere; once
    backing away, it waits again only with :data:`BACKING_YIELD_MARGIN`. It
    is the only place a controller reverses: backing away is sometimes the
    only way out of a person's path, but not into a corner, and not when
    waiting beside them will do.

Frames and units: map frame, metres, seconds, radians throughout.

Examples
--------
>>> import numpy as np
>>> from fusion_planner.core.local_planning.controller_base import FollowerParams
>>> p = FollowerParams(max_speed=0.8)
>>> pose, velocity = np.array([0.0, 0.0, 0.0]), np.zeros(2)
>>> walker = np.array([[1.2, 0.0, -0.35, 0.0, 0.3]])     # walks at the robot
>>> v, omega, evading = evade(pose, velocity, (0.0, 0.0), np.array([1.0, 0.0]),
...                           walker, np.zeros((0, 2)), p)
>>> evading, v >= 0.0, omega != 0.0                        # in the open, it steps aside
(True, True, True)
>>> walls = np.array([[x, y] for x in np.linspace(-2.0, 3.0, 60) for y in (-0.45, 0.45)])
>>> v, omega, evading = evade(pose, velocity, (0.0, 0.0), np.array([1.0, 0.0]),
...                           walker, walls, p)
>>> evading, v <= 0.0, omega != 0.0                        # in a slit, it turns round to leave
(True, True, True)
"""

import math

import numpy as np
from scipy.spatial import cKDTree

from fusion_planner.core.local_planning import walker_futures, way_out
from fusion_planner.core.local_planning.local_geometry import held_before, points_off_circles

#: Look-ahead of the check [s]: long enough to turn round (pi / max_omega
#: plus the ramp of max_alpha) before an obstacle at half the robot's top
#: speed closes a metre.
HORIZON = 2.4

#: Time between the rollouts' samples [s] (they are integrated one control
#: period at a time): coarse enough to keep the check cheap. A
#: robot and an obstacle closing at 1.2 m/s (the generated scenarios' top
#: speeds) come 0.24 m closer per step, a third of their smallest combined
#: diameter, so no contact falls between samples.
ROLLOUT_STEP = 0.2

#: Clearance [m] a safe rollout keeps from a (grown) tracked obstacle.
MOVING_MARGIN = 0.1

#: Growth [m/s] of a tracked obstacle's radius per second of look-ahead: the
#: prediction goes on straight, the obstacle may turn.
UNCERTAINTY_RATE = 0.1

#: A person may turn round at any moment (the end of a walk, a change of
#: mind): for this long [s] of the look-ahead every tracked obstacle is also
#: checked walking back at its speed. Long enough for the robot to stop from
#: its top speed; short enough not to hold it far behind a person it follows.
TURN_ROUND_HORIZON = 1.0

#: A tracked obstacle whose heading is within 60 degrees of the robot's
#: desired direction, or of its opposite, walks along the robot's way
#: (cosine of that angle): one the robot may follow or meet head-on.
#: Others cross it (:func:`_walled_crossers`).
ALONG_WAY_COS = 0.5

#: People give way a little before they would touch, and a prediction that
#: has two of them pass within a few centimetres is as likely a meeting: two
#: tracked obstacles whose predicted discs come within this [m] meet
#: (:func:`hypotheses`).
MEETING_MARGIN = 0.1

#: Clearance [m] an evasive rollout must keep from static points (or the
#: present clearance if that is smaller: never closer than now).
STATIC_MARGIN = 0.03

#: An evasive rollout that would come too close to a static point within
#: this time [s] is refused: longer than braking from ``max_speed`` (the
#: check is repeated every step).
STATIC_HORIZON = 1.0

#: Clearance [m] from the obstacles' predicted (not grown) motion that lets an
#: evasion wait or go on forward, rather than back away: a person walking past
#: a robot that has pulled to the side is let pass.
YIELD_MARGIN = 0.02

#: ... and that keeps clear of the grown obstacles for this long [s]: the
#: prediction's uncertainty is not ignored, only not extrapolated so far that
#: backing away always looks safer.
YIELD_SAFE_TIME = 1.0

#: The same clearance [m] for a robot that is backing away: a person's
#: predicted path wobbles by centimetres from one scan to the next, and a
#: robot that switches every period between backing away and waiting beside
#: them neither waits nor gets away.
BACKING_YIELD_MARGIN = 0.07

#: A yielding evasion that keeps clear of the grown obstacles over the whole
#: horizon at :data:`ASIDE_SPEED_FRACTION` of ``max_speed`` or more may lose
#: this much ground [m] along the desired direction: a brisk arc round a
#: person is not turning back (a slow one or a turn on the spot can be).
TURN_BACK_SLACK = 0.15

#: See :data:`TURN_BACK_SLACK`.
ASIDE_SPEED_FRACTION = 0.5

#: Target speeds of the evasive fan, as fractions of ``max_speed`` (forward)
#: and of :meth:`FollowerParams.reverse_speed` (reverse).
SPEED_FRACTIONS = (-1.0, -0.5, 0.0, 0.25, 0.5, 0.75, 1.0)

#: Target turn rates of the evasive fan, as fractions of ``max_omega``.
TURN_FRACTIONS = (-1.0, -0.4, 0.0, 0.4, 1.0)

#: Headings of the pivot candidates, evenly spaced round the robot.
PIVOT_HEADINGS = 8

#: Straight speeds of the pivot candidates, as fractions of ``max_speed``.
PIVOT_SPEED_FRACTIONS = (0.5, 1.0)

#: A pivot drives on once its heading is off by less than this [rad].
PIVOT_ALIGNED_RAD = 0.3

#: Intrusions closer than this [m s] count as equal (ties go to progress).
INTRUSION_TOLERANCE = 1e-6

#: Progress [m] closer than this counts as equal. Candidates that stand
#: still tie on everything whatever their turn rate; the tie goes to the
#: turn rate nearest the controller's, not to the first of the fan (a spin
#: at ``-max_omega`` toward whoever is passing).
PROGRESS_TOLERANCE = 1e-6

#: Slack [m] of the clearance comparisons (floating point only).
CLEARANCE_EPS = 1e-9

#: A kept evasive choice stays while its intrusion into :data:`MOVING_MARGIN`
#: exceeds the best one's by at most this [m s] (and it is otherwise as
#: good): a commitment, not a new choice every period.
KEEP_INTRUSION = 0.02

#: Heading diffusion [rad / sqrt(s)] of the sampled futures of an obstacle
#: whose own is not known (NaN in ``turn_stds``): a person may turn by about
#: 35 degrees in a second, 50 in two (people wandering in a hall; the scan
#: tracker measures each track's own, ``TrackerParams.turn_prior`` until it
#: has).
TURN_STD = 0.6

#: A person farther than this [m] from every static point is in the open:
#: its sampled futures turn at least :data:`TURN_STD`, whatever the tracker
#: measured. The tracker's estimate runs over the last few seconds (below
#: 0.6 of a walker's true diffusion in 8 % of the samples near the robot)
#: and its heading trails the latest turn; in a corridor (1.2-2 m wide, so
#: within 1 m of a wall) a person's own measured diffusion is kept.
OPEN_CLEARANCE = 1.0

#: Clearance [m] below which a sampled future counts as a contact: the
#: clearance at which a robot may wait beside a person passing it.
RISK_MARGIN = YIELD_MARGIN

#: Time constant [s] of the weight of a sampled contact: one further off
#: can still be evaded.
RISK_TIME = 1.5

#: The field's command is kept only while its contact risk is at most this:
#: one sampled future in twenty touching the robot now.
RISK_LIMIT = 0.05

#: Contact risks closer than this count as equal (less than one of the
#: sampled futures, whose weight is at most 1).
RISK_TOLERANCE = 0.02


def _times():
    """Rollout sample times ``(T,)`` [s]: ``ROLLOUT_STEP`` to ``HORIZON``."""
    return ROLLOUT_STEP * np.arange(1, int(round(HORIZON / ROLLOUT_STEP)) + 1)


def _wall_distance(tracked, walls):
    """Distance [m] ``(K,)`` from each tracked obstacle's centre to the nearest static point.

    ``walls`` (M, 2) [m]; ``inf`` without any.
    """
    if len(walls):
        return cKDTree(walls).query(tracked[:, 0:2])[0]
    return np.full(len(tracked), np.inf)


def _open_turns(turn_stds, wall_distance):
    """``turn_stds`` (K,) [rad/sqrt(s)], at least :data:`TURN_STD` for people in the open.

    A person farther than :data:`OPEN_CLEARANCE` from every static point
    (``wall_distance`` (K,) [m], :func:`_wall_distance`) may turn any way at
    any moment, whatever the tracker measured of its last few seconds; one
    walking down a corridor keeps its own (a person walking straight need
    not hold the robot back).
    """
    return np.where(wall_distance > OPEN_CLEARANCE, np.maximum(turn_stds, TURN_STD), turn_stds)


def _walled_crossers(tracked, desired, wall_distance):
    """Whether each tracked obstacle ``(K,)`` is checked walking back over the whole horizon.

    Those within :data:`OPEN_CLEARANCE` of a static point (``wall_distance``
    (K,) [m], :func:`_wall_distance`) whose heading crosses the robot's way:
    more than 60 degrees off ``desired`` (unit, (2,); zero: no way, none
    cross) and off its opposite (:data:`ALONG_WAY_COS`). Beside a wall a
    person's sampled futures keep the turns measured of them, and walking
    along or across a corridor they mostly go on or turn round; one who
    crossed in front of the robot and turns round walks back along the
    trail the robot would pass behind them on. In the open the sampled
    futures cover turns any way; and a person walking along the robot's way
    is checked walking back for :data:`TURN_ROUND_HORIZON` only, or the
    robot could not follow them.
    """
    if not np.any(desired):
        return np.zeros(len(tracked), bool)
    speed = np.hypot(tracked[:, 2], tracked[:, 3])
    crossing = np.abs(tracked[:, 2:4] @ desired) < ALONG_WAY_COS * speed
    return crossing & (wall_distance <= OPEN_CLEARANCE)


def _risk(paths, futures, tracked, radius):
    """Contact risk ``(C,)`` of rollouts ``(C, T, 2)`` over the people's sampled ``futures``."""
    reach = radius + tracked[:, 4] + RISK_MARGIN
    return walker_futures.contact_risk(paths, futures, reach, np.exp(-_times() / RISK_TIME))


def _targets(params):
    """The evasive fan ``(C, 2)`` of target ``(v, omega)`` [m/s, rad/s]."""
    fractions = np.array(SPEED_FRACTIONS)
    speeds = fractions * np.where(fractions < 0.0, params.reverse_speed(), params.max_speed)
    turns = np.array(TURN_FRACTIONS) * params.max_omega
    v, w = np.meshgrid(speeds, turns, indexing='ij')
    return np.column_stack([v.ravel(), w.ravel()])


def _control_steps(params):
    """Control periods per rollout step, and their length [s].

    The rollouts follow the robot period by period, as the controller's
    commands will move it (each held for one ``control_period``, the one-step
    limits applied); positions are kept every :data:`ROLLOUT_STEP`.
    """
    count = max(1, int(round(ROLLOUT_STEP / params.control_period)))
    return count, ROLLOUT_STEP / count


def _advance(x, y, yaw, v, omega, period):
    """Unicycle poses after ``period`` [s] at ``v, omega`` held (arrays of equal shape).

    The chord of the arc: its direction is the heading half-way through the
    period (exact for the direction; its length differs from ``v * period``
    by less than 0.2 % while ``|omega| * period <= 0.2``).
    """
    mid = yaw + 0.5 * omega * period
    return x + v * np.cos(mid) * period, y + v * np.sin(mid) * period, yaw + omega * period


def rollout(pose, velocity, targets, params):
    """Robot positions holding each target command, within the acceleration limits.

    Parameters
    ----------
    pose : ndarray, shape (3,)
        ``x, y, yaw`` [m, m, rad], map frame.
    velocity : ndarray, shape (2,)
        Measured ``v, omega`` [m/s, rad/s].
    targets : ndarray, shape (C, 2)
        Target ``v, omega`` [m/s, rad/s].
    params : FollowerParams
        ``max_accel`` and ``max_alpha`` bound the ramps, one
        ``control_period`` at a time.

    Returns
    -------
    ndarray, float64, shape (C, T, 2)
        Positions [m] at ``ROLLOUT_STEP, 2 ROLLOUT_STEP, ..., HORIZON``.
    """
    count, period = _control_steps(params)
    times = period * np.arange(1, len(_times()) * count + 1)   # each command's period ends here
    v0, w0 = velocity
    v = v0 + np.clip(targets[:, :1] - v0, -params.max_accel * times, params.max_accel * times)
    w = w0 + np.clip(targets[:, 1:] - w0, -params.max_alpha * times, params.max_alpha * times)
    start_yaw = pose[2] + (np.cumsum(w, axis=1) - w) * period     # heading as each period starts
    dx, dy, _ = _advance(0.0, 0.0, start_yaw, v, w, period)
    x = pose[0] + np.cumsum(dx, axis=1)
    y = pose[1] + np.cumsum(dy, axis=1)
    return np.stack([x, y], axis=-1)[:, count - 1::count]


def pivot_command(yaw, headings, speeds, params):
    """Target ``(P, 2)`` ``v, omega`` of pivots: turn towards ``headings`` [rad], then drive.

    The turn rate closes the heading error within one
    :data:`ROLLOUT_STEP` (at most ``max_omega``); the speed is ``speeds``
    [m/s] once the error is below :data:`PIVOT_ALIGNED_RAD`, 0 before.
    """
    error = np.angle(np.exp(1j * (headings - yaw)))
    omega = np.clip(error / ROLLOUT_STEP, -params.max_omega, params.max_omega)
    return np.column_stack([np.where(np.abs(error) < PIVOT_ALIGNED_RAD, speeds, 0.0), omega])


def _pivots(yaw, params):
    """Headings [rad] and straight speeds [m/s] ``(P,)`` of the pivot candidates."""
    headings = yaw + np.linspace(0.0, 2.0 * math.pi, PIVOT_HEADINGS, endpoint=False)
    speeds = np.array(PIVOT_SPEED_FRACTIONS) * params.max_speed
    h, v = np.meshgrid(headings, speeds, indexing='ij')
    return h.ravel(), v.ravel()


def pivot_rollout(pose, velocity, headings, speeds, params):
    """Robot positions ``(P, T, 2)`` [m] following each pivot, within the acceleration limits."""
    x = np.full(len(headings), pose[0])
    y = np.full(len(headings), pose[1])
    yaw = np.full(len(headings), pose[2])
    v = np.full(len(headings), velocity[0])
    w = np.full(len(headings), velocity[1])
    count, period = _control_steps(params)
    dv, dw = params.max_accel * period, params.max_alpha * period
    out = []
    for _ in _times():
        for _ in range(count):
            target = pivot_command(yaw, headings, speeds, params)
            v = v + np.clip(target[:, 0] - v, -dv, dv)
            w = w + np.clip(target[:, 1] - w, -dw, dw)
            x, y, yaw = _advance(x, y, yaw, v, w, period)
        out.append(np.column_stack([x, y]))
    return np.stack(out, axis=1)


def obstacle_gaps(paths, tracked, robot_radius, growth=UNCERTAINTY_RATE, since=None,
                  until=None):
    """Gap [m] between each rollout sample and the nearest predicted, grown tracked obstacle.

    Parameters
    ----------
    paths : ndarray, shape (C, T, 2)
        Rollouts from :func:`rollout` [m].
    tracked : ndarray, shape (K, 5)
        ``x, y, vx, vy, radius`` [m, m, m/s, m/s, m], finite, ``K >= 1``.
    robot_radius : float
        [m].
    growth : float
        Growth of the obstacles' radii [m/s] over the look-ahead.
    since, until : ndarray, shape (K,), optional
        Look-ahead [s] from which and up to which each obstacle counts
        (other samples do not see it); default the whole horizon for every
        one.

    Returns
    -------
    ndarray, float64, shape (C, T)
        Distance from the robot's boundary to the nearest obstacle predicted
        at constant velocity, its radius grown by ``growth * t``; negative:
        predicted contact; ``inf`` where none counts.
    """
    times = _times()[:, None]                                                  # (T, 1)
    dx = paths[:, :, 0:1] - (tracked[:, 0] + times * tracked[:, 2])            # (C, T, K)
    dy = paths[:, :, 1:2] - (tracked[:, 1] + times * tracked[:, 3])
    reach = robot_radius + tracked[:, 4] + growth * times                      # (T, K)
    gaps = np.sqrt(dx * dx + dy * dy) - reach
    if since is not None:
        gaps = np.where(times >= since - CLEARANCE_EPS, gaps, math.inf)
    if until is not None:
        gaps = np.where(times <= until + CLEARANCE_EPS, gaps, math.inf)
    return gaps.min(axis=2)


def hypotheses(tracked, others, walking_back=None):
    """Each tracked obstacle as it goes on, as it would walk back, and as another deflects it.

    Parameters
    ----------
    tracked : ndarray, shape (K, 5)
        ``x, y, vx, vy, radius`` of the obstacles near the robot.
    others : ndarray, shape (N, 5)
        Every tracked obstacle (``tracked`` among them), any of which may
        meet one of ``tracked``.
    walking_back : ndarray of bool, shape (K,), optional
        The obstacles checked walking back over the whole horizon, not only
        :data:`TURN_ROUND_HORIZON` (default none).

    Returns
    -------
    movers : ndarray, shape (2K + D, 5)
        ``tracked``; the same rows with the velocity reversed; then each of
        the ``D`` obstacles of ``tracked`` that meets another within the
        horizon, as it goes on after the first such meeting (its velocity
        reflected about the line of their centres, the row's position set
        back so that ``x + t vx`` passes where they meet).
    since, until : ndarray, shape (2K + D,)
        Look-ahead [s] from which and up to which each counts: the whole
        horizon, then up to :data:`TURN_ROUND_HORIZON` (the whole horizon
        where ``walking_back``), then from the meeting.
    """
    meeting, normal = _meetings(tracked, others)
    into = np.sum(tracked[:, 2:4] * normal, axis=1)          # < 0: walking into the other
    deflected = np.flatnonzero((meeting <= HORIZON) & (into < 0.0))
    velocity = tracked[deflected, 2:4]
    after = tracked[deflected].copy()
    after[:, 2:4] = velocity - 2.0 * into[deflected, None] * normal[deflected]
    met = meeting[deflected][:, None]
    after[:, 0:2] += met * (velocity - after[:, 2:4])
    back = tracked.copy()
    back[:, 2:4] *= -1.0
    count = len(tracked)
    back_until = np.full(count, TURN_ROUND_HORIZON)
    if walking_back is not None:
        back_until[walking_back] = HORIZON
    since = np.concatenate([np.zeros(2 * count), meeting[deflected]])
    until = np.concatenate([np.full(count, HORIZON), back_until,
                            np.full(len(deflected), HORIZON)])
    return np.vstack([tracked, back, after]), since, until


def _meetings(tracked, others):
    """When [s] each of ``tracked`` (K, 5) first meets one of ``others`` (N, 5), and the normal.

    Both go on at constant velocity; they meet when their discs come within
    :data:`MEETING_MARGIN` while closing (``inf`` when never, 0 when they
    already are). The normal
    ``(K, 2)`` is the unit vector from the other's centre to this one's then.
    An obstacle does not meet itself (nor a row of ``others`` at its centre).
    """
    offset = tracked[:, None, 0:2] - others[None, :, 0:2]                     # (K, N, 2)
    closing = tracked[:, None, 2:4] - others[None, :, 2:4]
    reach = tracked[:, None, 4] + others[None, :, 4] + MEETING_MARGIN
    a = np.sum(closing * closing, axis=-1)
    b = np.sum(offset * closing, axis=-1)
    c = np.sum(offset * offset, axis=-1) - reach ** 2
    distinct = np.sum(offset * offset, axis=-1) > CLEARANCE_EPS
    with np.errstate(invalid='ignore', divide='ignore'):
        root = (-b - np.sqrt(b * b - a * c)) / a
    time = np.where(c <= 0.0, 0.0, root)
    meets = distinct & (b < 0.0) & np.isfinite(time) & (time >= 0.0)
    time = np.where(meets, time, np.inf)
    first = np.argmin(time, axis=1)
    rows = np.arange(len(tracked))
    when = time[rows, first]
    apart = offset[rows, first] + np.where(np.isfinite(when), when, 0.0)[:, None] \
        * closing[rows, first]
    length = np.maximum(np.hypot(apart[:, 0], apart[:, 1]), CLEARANCE_EPS)
    return when, apart / length[:, None]


def static_clearance(q, paths, walls, robot_radius):
    """Present clearance and clearance along each rollout to the static points [m].

    Parameters
    ----------
    q : ndarray, shape (2,)
        Robot position now [m].
    paths : ndarray, shape (C, T, 2)
        Rollouts [m].
    walls : ndarray, shape (M, 2)
        Static obstacle points [m] (the sensed points off the tracked
        obstacles, :func:`~fusion_planner.core.local_planning.local_geometry.points_off_circles`);
        only those the rollouts can reach count.
    robot_radius : float
        [m].

    Returns
    -------
    now : float
        Distance [m] from the robot's boundary to the nearest static point
        within reach now (``inf``: none).
    along : ndarray, shape (C, T)
        The same at each rollout sample [m] (``inf``: none).
    """
    travel = paths - q
    reach = math.sqrt(float(np.max(np.einsum('ijk,ijk->ij', travel, travel)))) \
        + robot_radius + STATIC_MARGIN
    d = walls - q
    points = walls[np.einsum('ij,ij->i', d, d) <= reach * reach]
    if len(points) == 0:
        return math.inf, np.full(paths.shape[:2], math.inf)
    tree = cKDTree(points)
    now = float(tree.query(q)[0]) - robot_radius
    nearest = tree.query(paths.reshape(-1, 2))[0].reshape(paths.shape[:2])
    return now, nearest - robot_radius


def _first(mask):
    """Index of the first True along the last axis of ``mask`` (C, T); T where none."""
    return np.where(mask.any(axis=1), mask.argmax(axis=1), mask.shape[1])


def _relevant(q, tracked, params):
    """Whether each tracked obstacle ``(K,)`` can come within the margin during the horizon."""
    gap = np.hypot(*(tracked[:, 0:2] - q).T) - tracked[:, 4] - params.robot_radius
    closing = params.max_speed + np.hypot(*tracked[:, 2:4].T) + UNCERTAINTY_RATE
    return gap - MOVING_MARGIN < closing * HORIZON


def _cornered(q, paths, tracked, points, params):
    """Whether each rollout ``(C, T, 2)`` from ``q`` (2,) ends in a dead end before a walker.

    See :func:`~fusion_planner.core.local_planning.way_out.cornered`.
    """
    return way_out.cornered(q, paths[:, -1], HORIZON, tracked, points, params)


def _with_way_out(allowed, q, paths, gaps, tracked, points, params):
    """``allowed`` without the cornered rollouts; None when none of the rest is safe.

    A rollout ahead of a person into a dead end is a contact put off past
    the horizon: it gives way to one that leaves the robot a way out
    (:func:`_cornered`) when one keeps clear of the grown obstacles for the
    whole horizon (``gaps`` ``(C, T)`` [m] all >= 0). A robot already
    cornered, whose only ways out squeeze past the person, keeps choosing
    by the latest contact.
    """
    free = allowed & ~_cornered(q, paths, tracked, points, params)
    if np.any(free & np.all(gaps >= 0.0, axis=1)):
        return free
    return None


class Evader:
    """The evasion of one controller: :func:`evade` that keeps its forward choices.

    Attributes
    ----------
    kept : tuple or None
        The forward evasive choice of the last call, ``('arc', v, omega)``
        or ``('pivot', heading, speed)`` [m/s, rad/s, rad]; None when the
        last call did not evade, backed away, or there was none.
    backing : bool
        The last call backed away: waiting or going on needs
        :data:`BACKING_YIELD_MARGIN` again, not :data:`YIELD_MARGIN`.
    evading : bool
        The last call replaced the command.
    """

    def __init__(self):
        self.forget()

    def forget(self):
        """Drop the kept choice and the backing (the evasion did not run this period)."""
        self.kept = None
        self.backing = False
        self.evading = False

    def evade(self, pose, velocity, command, desired, tracked, points, params, turn_stds=None,
              reach=math.inf):
        """:func:`evade`, keeping the last forward choice while it is as good as the best."""
        v, omega, evading, chosen = _evade(pose, velocity, command, desired, tracked, points,
                                           params, turn_stds, self.kept, self.backing, reach)
        forward = chosen is not None and (chosen[0] == 'pivot' or chosen[1] >= 0.0)
        self.kept = chosen if evading and forward else None
        self.backing = evading and not forward
        self.evading = evading
        return v, omega, evading


def evade(pose, velocity, command, desired, tracked, points, params, turn_stds=None,
          reach=math.inf):
    """Keep a command when it is safe; otherwise the best evasive one.

    Parameters
    ----------
    pose : ndarray, shape (3,)
        ``x, y, yaw`` [m, m, rad], map frame.
    velocity : ndarray, shape (2,)
        Measured ``v, omega`` [m/s, rad/s].
    command : tuple of float
        The controller's ``v, omega`` [m/s, rad/s].
    desired : ndarray, shape (2,)
        Unit vector the controller wants to go along (progress measure, and
        the way people beside walls may cross: :func:`_walled_crossers`).
    tracked : ndarray, shape (K, 5)
        Tracked obstacles ``x, y, vx, vy, radius``, finite; ``K >= 0``.
    points : ndarray, shape (M, 2)
        Sensed obstacle points [m], finite; those within
        :data:`~fusion_planner.core.local_planning.local_geometry.TRACKED_POINT_MARGIN` of a
        tracked obstacle are not static and are left out.
    params : FollowerParams
    turn_stds : ndarray, shape (K,), optional
        Heading diffusion [rad / sqrt(s)] of each tracked obstacle; NaN or
        none: :data:`TURN_STD`.
    reach : float, optional
        How far [m] the controller wants to go along ``desired`` (its goal's
        distance): once the rollouts get that far, progress is measured
        towards that point (:func:`_progress`), not along ``desired``.

    Returns
    -------
    v, omega : float
        Target command [m/s, rad/s] (the caller applies the one-step limits;
        ``v`` may be negative, down to ``-params.reverse_speed()``).
    evading : bool
        True when ``command`` was replaced.

    Notes
    -----
    A candidate that would come closer to a static point than allowed stops
    there in its rollout (it is pinned, and an obstacle may still walk into
    it); one that would do so within :data:`STATIC_HORIZON` is refused
    unless every candidate would. One that ends cornered in front of a
    walking obstacle (:func:`_cornered`) is dropped when another keeps clear
    of the grown obstacles over the whole horizon; a safe command
    that ends cornered is kept only when no such other is left. Of the
    rest, only those within :data:`RISK_TOLERANCE` of the least contact
    risk stay. When some of them do not reverse
    and keep :data:`YIELD_MARGIN` from the obstacles' predicted (not grown)
    motion and clear of the grown ones for :data:`YIELD_SAFE_TIME`, the
    choice is among those, and among those of them that do not
    lose ground along ``desired`` (or little, going round the person: see
    :data:`TURN_BACK_SLACK`) if there are any: the robot yields (waits,
    or goes on beside the person) instead of backing away or turning back. The choice is
    lexicographic: the latest predicted contact with a (grown) tracked
    obstacle, then the least intrusion into :data:`MOVING_MARGIN`, then the
    most progress along ``desired`` (towards the point ``reach`` ahead once
    a rollout gets that far), then the turn rate nearest ``command``'s (a
    robot that waits keeps its heading rather than spin).
    """
    return _evade(pose, velocity, command, desired, tracked, points, params, turn_stds,
                  None, reach=reach)[:3]


def _progress(travel, desired, reach):
    """Progress [m] ``(C,)`` of rollouts that end ``travel`` ``(C, 2)`` [m] from the robot.

    Along ``desired`` (unit, or zero: no direction); but when some rollout
    gets as far as the point ``reach`` [m] ahead along it, towards that
    point: a robot evading beside its goal gains nothing by running past it
    or beside it, and would have to come back.
    """
    if not np.any(desired) or reach > np.max(np.hypot(*travel.T)):
        return travel @ desired
    return reach - np.hypot(*(reach * desired - travel).T)


def _evade(pose, velocity, command, desired, tracked, points, params, turn_stds, kept,
           backing=False, reach=math.inf):
    """:func:`evade` with a kept choice and the last call's backing (see :class:`Evader`).

    Also returns the choice made.
    """
    q = pose[:2]
    relevant = _relevant(q, tracked, params)
    everyone, tracked = tracked, tracked[relevant]
    if len(tracked) == 0:
        return command[0], command[1], False, None
    turn_stds = np.full(len(relevant), np.nan) if turn_stds is None \
        else np.asarray(turn_stds, float)
    turn_stds = np.where(np.isfinite(turn_stds), turn_stds, TURN_STD)[relevant]
    walls = points_off_circles(points, tracked[:, 0:2], tracked[:, 4])
    wall_distance = _wall_distance(tracked, walls)
    movers, since, until = hypotheses(tracked, everyone,
                                      _walled_crossers(tracked, desired, wall_distance))
    turns = _open_turns(turn_stds, wall_distance)
    futures = walker_futures.sample_futures(tracked, _times(), turns, walls)
    nominal = np.array([command], dtype=float)
    radius = params.robot_radius
    ahead = rollout(pose, velocity, nominal, params)
    safe = np.min(obstacle_gaps(ahead, movers, radius, since=since, until=until)) \
        >= MOVING_MARGIN and _risk(ahead, futures, tracked, radius)[0] <= RISK_LIMIT
    if safe and not _cornered(q, ahead, tracked, points, params)[0]:
        return command[0], command[1], False, None
    fan = np.vstack([nominal, _targets(params)])
    headings, speeds = _pivots(pose[2], params)
    if kept is not None and kept[0] == 'arc':
        fan = np.vstack([fan, kept[1:]])
    elif kept is not None:
        headings, speeds = np.append(headings, kept[1]), np.append(speeds, kept[2])
    targets = np.vstack([fan, pivot_command(pose[2], headings, speeds, params)])
    paths = np.concatenate([rollout(pose, velocity, fan, params),
                            pivot_rollout(pose, velocity, headings, speeds, params)])
    kept_index = None if kept is None else (len(fan) - 1 if kept[0] == 'arc' else len(targets) - 1)
    now, along = static_clearance(q, paths, walls, radius)
    blocked = _first(along < min(STATIC_MARGIN, now) - CLEARANCE_EPS)          # (C,)
    allowed = blocked >= int(round(STATIC_HORIZON / ROLLOUT_STEP))
    if not np.any(allowed):
        allowed = blocked == np.max(blocked)
    paths = held_before(paths, q, blocked)
    gaps = obstacle_gaps(paths, movers, radius, since=since, until=until)
    progress = _progress(paths[:, -1] - q, desired, reach)
    soon = int(round(YIELD_SAFE_TIME / ROLLOUT_STEP))
    with_way_out = _with_way_out(allowed, q, paths, gaps, tracked, points, params)
    if with_way_out is None and safe:
        return command[0], command[1], False, None  # cornered, but nothing better is safe
    if with_way_out is not None:
        allowed = with_way_out
    risk = _risk(paths, futures, tracked, radius)
    allowed &= risk <= np.min(risk[allowed]) + RISK_TOLERANCE
    margin = BACKING_YIELD_MARGIN if backing else YIELD_MARGIN
    yielding = (targets[:, 0] >= 0.0) & allowed & np.all(gaps[:, :soon] >= 0.0, axis=1) \
        & np.all(obstacle_gaps(paths, movers, radius, growth=0.0, since=since,
                                   until=until) >= margin, axis=1)
    contact = _first(gaps < 0.0)
    if np.any(yielding):
        allowed = yielding
        brisk = targets[:, 0] >= ASIDE_SPEED_FRACTION * params.max_speed
        aside = brisk & (contact == gaps.shape[1]) & (progress >= -TURN_BACK_SLACK)
        onward = yielding & ((progress >= 0.0) | aside)
        if np.any(onward):
            allowed = onward  # wait or go on; do not turn back
    intrusion = np.maximum(MOVING_MARGIN - gaps, 0.0).sum(axis=1) * ROLLOUT_STEP
    best = allowed & (contact == np.max(contact[allowed]))
    if kept_index is not None and best[kept_index] \
            and intrusion[kept_index] <= np.min(intrusion[best]) + KEEP_INTRUSION:
        choice = kept_index
    else:
        best &= intrusion <= np.min(intrusion[best]) + INTRUSION_TOLERANCE
        best &= progress >= np.max(progress[best]) - PROGRESS_TOLERANCE
        choice = int(np.argmin(np.where(best, np.abs(targets[:, 1] - command[1]), np.inf)))
    if choice < len(fan):
        chosen = ('arc', float(targets[choice, 0]), float(targets[choice, 1]))
    else:
        pivot = choice - len(fan)
        chosen = ('pivot', float(headings[pivot]), float(speeds[pivot]))
    return float(targets[choice, 0]), float(targets[choice, 1]), True, chosen
