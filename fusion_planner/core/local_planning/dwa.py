"""The ``'dwa'`` baseline: the dynamic window approach following the global plan.

A standard local planner from the field (Fox, Burgard and Thrun, "The
dynamic window approach to collision avoidance", IEEE Robotics & Automation
Magazine, 1997), as ROS navigation stacks run it (Nav2's DWB): every control
step

1. **dynamic window**: the velocities reachable within one control period
   ``T`` from the measured ``(v0, omega0)``: ``v`` in ``[v0 - a T, v0 + a
   T]`` within ``[0, max_speed]`` (and no faster than stopping at the goal
   allows), ``omega`` in ``[omega0 - alpha T, omega0 + alpha T]`` within
   ``[-max_omega, max_omega]``; sampled on a :data:`V_SAMPLES` x
   :data:`OMEGA_SAMPLES` grid;
2. **forward simulation**: each ``(v, omega)`` held for :data:`SIM_TIME_S`
   on exact unicycle arcs, :data:`SIM_STEPS` poses; and, for the static
   obstacles, its curve (curvature ``omega / v``) followed for the distance
   the robot covers at top speed in that time, as Fox et al. measure the
   distance to an obstacle on the curvature independently of the speed;
3. **admissible velocities** (Fox's ``v <= sqrt(2 a dist(v, omega))``, with
   the command held for one period first): the robot must be able to brake
   to a stop before the first point of its curve
   closer than ``safety_distance`` to a scan point, and before the first
   pose of its arc that comes that close to a tracked moving obstacle *at
   its predicted position at that time* (scan points on a tracked obstacle
   are left to its prediction);
4. **objective** over the admissible velocities, each term in ``[0, 1]``:
   ``HEADING_WEIGHT * heading + CLEARANCE_WEIGHT * dist + VELOCITY_WEIGHT *
   velocity`` (Fox et al.'s weights 2, 0.2, 0.2), with *heading* ``1 -
   |error| / pi`` toward a carrot on the global path (the path point
   ``lookahead`` ahead of the point nearest the robot: the plan is followed
   as with DWB's PathAlign and GoalAlign critics), taken as Fox et al. take
   it at the pose where the robot would stop (one period at ``(v, omega)``,
   then braking); *dist* the free travel on the curve before the first
   obstacle over the curve's length; *velocity* ``v / max_speed``;
5. the best command wins; when none is admissible the robot brakes.

It stops within ``goal_tolerance`` of the goal (``'arrived'``). Like Nav2's
progress checker (``SimpleProgressChecker``: 0.5 m in 10 s), a robot that
has not moved :data:`PROGRESS_RADIUS_M` from where it last made progress for
:data:`PROGRESS_TIME_S` is stuck, and a stuck DWA has failed: it has no
recovery of its own (a navigation stack would call its recovery behaviours).

Examples
--------
>>> import numpy as np
>>> from fusion_planner.core.local_planning.controller_base import FollowerParams, Observation
>>> dwa = DynamicWindow(FollowerParams(control_period=0.1))
>>> dwa.set_path(np.array([[0.0, 0.0], [3.0, 0.0]]), np.array([[0.0, 0.0], [3.0, 0.0]]))
>>> obs = Observation(pose=np.zeros(3), velocity=np.zeros(2), obstacle_points=np.zeros((0, 2)),
...                   tracked=np.zeros((0, 5)), time=0.0)
>>> cmd = dwa.compute(obs)
>>> cmd.status, round(cmd.v, 3), round(cmd.omega, 3)     # full acceleration, straight on
('moving', 0.1, 0.0)
"""

import math

import numpy as np
from scipy.spatial import cKDTree

from fusion_planner.core.local_planning.controller_base import Command
from fusion_planner.core.local_planning.local_geometry import points_off_circles
from fusion_planner.core.local_planning.path_tracker import TRACK_SPACING, PathTracker

#: Samples of the window: forward speeds and turn rates.
V_SAMPLES = 11
OMEGA_SAMPLES = 21
#: Forward simulation: horizon [s] (DWB's default ``sim_time``), poses per arc
#: (against moving obstacles) and spacing [m] of the points checked along a
#: curve against static ones (between two points the robot's centre is at
#: most half of it from one of them, so a point counts as a contact when its
#: clearance is below the threshold plus half the spacing).
SIM_TIME_S = 1.7
SIM_STEPS = 17
CURVE_SPACING_M = 0.05
#: Weights of the objective's heading, dist and velocity terms (Fox et al.'s
#: alpha, beta, gamma).
HEADING_WEIGHT = 2.0
CLEARANCE_WEIGHT = 0.2
VELOCITY_WEIGHT = 0.2
#: Clearances to points beyond the contact threshold plus this [m] are not
#: computed (reported as ``inf``).
QUERY_SLACK_M = 0.1
#: Progress checker (Nav2's SimpleProgressChecker defaults): radius [m], time [s].
PROGRESS_RADIUS_M = 0.5
PROGRESS_TIME_S = 10.0
#: How far along the path [m] the point nearest the robot is searched for
#: from the last one.
SEARCH_WINDOW_M = 10.0
#: Turn rates below this are simulated as straight lines [rad/s].
STRAIGHT_OMEGA = 1e-9
#: Poses of the chosen arc shown as the local plan (every SIM_STEPS // 4-th).
PLAN_STRIDE = 4


class DynamicWindow(PathTracker):
    """Dynamic window approach on a carrot of the global path.

    It takes the plan as the path tracker does (resampled every
    ``TRACK_SPACING`` metres, the index of the point nearest the robot kept
    and only moved forward), and chooses its commands as above.

    Parameters
    ----------
    params : FollowerParams
        Uses the robot's limits (``max_speed``, ``max_accel``, ``max_omega``,
        ``max_alpha``), ``robot_radius``, ``control_period``,
        ``safety_distance``, ``lookahead`` and ``goal_tolerance``.
    """

    def _clear_state(self):
        super()._clear_state()
        self._anchor = None          # (position (2,), time [s]) of the last progress

    def compute(self, obs):
        """One control step.

        Parameters
        ----------
        obs : Observation

        Returns
        -------
        Command
            As the tracker's (``'no_path'``, ``'arrived'``), but
            ``'failed'`` once the progress checker trips (until a new path or
            a reset), and ``'moving'`` along the chosen arc (``local_plan``)
            toward the carrot (``sub_goal``).

        Raises
        ------
        InvalidInput
            If ``obs`` is not an Observation.
        """
        stop, goal_distance = self._stop_or_arrive(obs)
        if stop is not None:
            return stop
        p = self.params
        q = obs.pose[:2]
        goal = self._key_nodes[-1]
        if self._no_progress(q, obs.time):
            self.stuck_events += 1
            return self._fail(obs, f'no progress at ({q[0]:.2f}, {q[1]:.2f}): moved less than '
                                   f'{PROGRESS_RADIUS_M:g} m in {PROGRESS_TIME_S:g} s, and the '
                                   'dynamic window approach has no recovery')
        window = self._window(obs, goal_distance)
        v = window[:, 0]
        poses, free = self._free_travel(obs, window)
        # held for one period, then braked (Fox's next interval; also covers the
        # discrete braking of a loop that holds each command for a period)
        admissible = v * p.control_period + v * v / (2.0 * p.max_accel) <= free
        if not np.any(admissible):
            v_brake, w_brake = self._limit(0.0, 0.0, obs)
            return Command(v_brake, w_brake, 'moving', sub_goal=goal.copy(),
                           local_plan=q[None, :].copy() if self.display_plan else None)
        # Fox's heading is taken where the robot would stop: after one period at
        # (v, omega), then braking (as far as holding the speed v / (2 a) longer)
        stops = rollout(obs.pose, v, window[:, 1],
                        (p.control_period + v / (2.0 * p.max_accel))[:, None])[:, 0]
        length = p.max_speed * SIM_TIME_S
        carrot = self._carrot(q)
        score = self._score(window, stops, carrot, np.minimum(free, length) / length)
        best = int(np.argmax(np.where(admissible, score, -np.inf)))
        v_best, w_best = self._limit(float(v[best]), float(window[best, 1]), obs)
        plan = np.vstack([q, poses[best, PLAN_STRIDE - 1::PLAN_STRIDE, :2]]) \
            if self.display_plan else None
        return Command(v_best, w_best, 'moving', sub_goal=carrot.copy(), local_plan=plan)

    # -- the steps -------------------------------------------------------------------

    def _no_progress(self, q, t):
        """Whether the robot has stayed within the progress radius for too long."""
        if self._anchor is None or math.hypot(*(q - self._anchor[0])) >= PROGRESS_RADIUS_M:
            self._anchor = (q.copy(), t)
            return False
        return t - self._anchor[1] > PROGRESS_TIME_S

    def _free_travel(self, obs, window):
        """Free travel [m] of every arc before its first contact, and its poses.

        Returns
        -------
        poses : ndarray, shape (S, SIM_STEPS, 3)
            The arcs held for :data:`SIM_TIME_S`.
        free : ndarray, shape (S,)
            Travel [m] to the last point before the first contact: on the
            speed-independent curve for the static points, on the timed arc
            for the tracked obstacles; ``inf`` without contact.
        """
        p = self.params
        q, v = obs.pose[:2], window[:, 0]
        points, tracked = self._obstacles(obs)
        # a robot already closer than the safety distance may keep its distance
        now = float(self._clearances(q[None, None, :], np.zeros(1), points, tracked)[0, 0])
        threshold = min(p.safety_distance, now)
        length = p.max_speed * SIM_TIME_S
        lengths = np.linspace(0.0, length, int(math.ceil(length / CURVE_SPACING_M)) + 1)[1:]
        along = curves(obs.pose, window, lengths, p.max_accel * p.control_period)
        static_free = free_travel(self._clearances(along, lengths, points, ()), lengths,
                                  threshold + CURVE_SPACING_M / 2)
        times = SIM_TIME_S / SIM_STEPS * np.arange(1, SIM_STEPS + 1)
        poses = rollout(obs.pose, v, window[:, 1], times)
        moving_free_s = free_travel(self._clearances(poses[..., :2], times, (), tracked), times,
                                    threshold)
        hit = np.isfinite(moving_free_s)
        moving_free = np.full(len(v), np.inf)
        moving_free[hit] = v[hit] * moving_free_s[hit]
        return poses, np.minimum(static_free, moving_free)

    def _window(self, obs, goal_distance):
        """The sampled dynamic window, shape ``(V_SAMPLES * OMEGA_SAMPLES, 2)`` of ``(v, omega)``."""
        p = self.params
        v0, w0 = obs.velocity
        dv, dw = p.max_accel * p.control_period, p.max_alpha * p.control_period
        v_stop_at_goal = math.sqrt(2.0 * p.max_accel * goal_distance)
        v_lo = min(max(v0 - dv, 0.0), p.max_speed)
        v_hi = max(min(v0 + dv, p.max_speed, v_stop_at_goal), v_lo)   # reachable, always
        w_lo, w_hi = max(w0 - dw, -p.max_omega), min(w0 + dw, p.max_omega)
        if w_lo > w_hi:                 # measured beyond the limit: the nearest reachable rate
            w_lo = w_hi = min(max(w0, -p.max_omega), p.max_omega)
        vs = np.linspace(v_lo, v_hi, V_SAMPLES)
        ws = np.unique(np.concatenate([np.linspace(w_lo, w_hi, OMEGA_SAMPLES),
                                       [0.0] if w_lo <= 0.0 <= w_hi else []]))
        v, w = np.meshgrid(vs, ws, indexing='ij')
        return np.column_stack([v.ravel(), w.ravel()])

    @staticmethod
    def _obstacles(obs):
        """The finite scan points off the tracked obstacles ``(M, 2)`` and the finite tracks ``(T, 5)``."""
        tracked = obs.tracked[np.all(np.isfinite(obs.tracked), axis=1)]
        points = obs.obstacle_points[np.all(np.isfinite(obs.obstacle_points), axis=1)]
        return points_off_circles(points, tracked[:, :2], tracked[:, 4]), tracked

    def _clearances(self, positions, times, points, tracked):
        """Clearance [m] of the robot's disc at positions ``(S, K, 2)`` reached at ``times`` ``(K,)`` [s].

        ``points`` ``(M, 2)`` are static; ``tracked`` ``(T, 5)`` rows ``x, y,
        vx, vy, radius`` are moved along their velocity to each time. Either
        may be empty. Returns ``(S, K)``; beyond the safety distance plus
        :data:`QUERY_SLACK_M` a clearance to points is ``inf`` (its exact
        value does not matter).
        """
        p = self.params
        shape = positions.shape[:2]
        distance = np.full(shape, np.inf)
        if len(points):
            reach = p.robot_radius + p.safety_distance + CURVE_SPACING_M + QUERY_SLACK_M
            distance, _ = cKDTree(points).query(positions.reshape(-1, 2), distance_upper_bound=reach)
            distance = distance.reshape(shape)
        if len(tracked):
            centres = tracked[None, :, :2] + times[:, None, None] * tracked[None, :, 2:4]  # (K, T, 2)
            offset = positions[:, :, None, :] - centres[None]                             # (S, K, T, 2)
            gaps = np.hypot(offset[..., 0], offset[..., 1]) - tracked[:, 4]
            distance = np.minimum(distance, gaps.min(axis=2))
        return distance - p.robot_radius

    def _carrot(self, q):
        """The path point ``lookahead`` [m] along the path from the point nearest ``q``.

        The nearest point is searched :data:`SEARCH_WINDOW_M` ahead of the
        last one (it never moves back).
        """
        dense = self._dense
        window = dense[self._closest:self._closest + int(SEARCH_WINDOW_M / TRACK_SPACING)]
        self._closest += int(np.argmin(np.hypot(*(window - q).T)))
        ahead = int(round(self.params.lookahead / TRACK_SPACING))
        return dense[min(self._closest + ahead, len(dense) - 1)]

    def _score(self, window, stops, carrot, dist):
        """The objective of every arc (higher is better).

        Parameters
        ----------
        window : ndarray, shape (S, 2)
            ``(v, omega)`` of the arcs.
        stops : ndarray, shape (S, 3)
            Where each arc would bring the robot to rest ``x, y, yaw``.
        carrot : ndarray, shape (2,)
            [m], map frame.
        dist : ndarray, shape (S,)
            Free travel over the curve's length, in [0, 1].

        Returns
        -------
        ndarray, shape (S,)
        """
        p = self.params
        bearing = np.arctan2(carrot[1] - stops[:, 1], carrot[0] - stops[:, 0])
        error = np.abs((bearing - stops[:, 2] + math.pi) % (2.0 * math.pi) - math.pi)
        heading = 1.0 - error / math.pi
        velocity = window[:, 0] / p.max_speed
        return HEADING_WEIGHT * heading + CLEARANCE_WEIGHT * dist + VELOCITY_WEIGHT * velocity

# -- arcs ---------------------------------------------------------------------------

def rollout(pose, v, omega, times):
    """Poses on constant-velocity unicycle arcs.

    Parameters
    ----------
    pose : ndarray, shape (3,)
        Start ``x, y, yaw`` [m, m, rad], map frame.
    v, omega : ndarray, shape (S,)
        Forward speeds [m/s] and turn rates [rad/s].
    times : ndarray, shape (K,) or (S, K)
        [s] after the start, common or per arc.

    Returns
    -------
    ndarray, float64, shape (S, K, 3)
        ``x, y, yaw`` on the exact arcs (straight lines for
        ``|omega| < STRAIGHT_OMEGA``).

    Examples
    --------
    >>> rollout(np.zeros(3), np.array([1.0]), np.array([math.pi / 2]), np.array([1.0])).round(6)
    array([[[0.63662 , 0.63662 , 1.570796]]])
    """
    x0, y0, yaw0 = pose
    v, w, t = v[:, None], omega[:, None], np.atleast_2d(times)
    yaw = yaw0 + w * t
    turning = np.abs(w) >= STRAIGHT_OMEGA
    safe_w = np.where(turning, w, 1.0)
    x = np.where(turning, x0 + v / safe_w * (np.sin(yaw) - math.sin(yaw0)),
                 x0 + v * t * math.cos(yaw0))
    y = np.where(turning, y0 - v / safe_w * (np.cos(yaw) - math.cos(yaw0)),
                 y0 + v * t * math.sin(yaw0))
    return np.stack([x, y, np.broadcast_to(yaw, x.shape)], axis=-1)


def curves(pose, window, lengths, creep):
    """Points along the curve of each ``(v, omega)``, independent of the speed.

    Parameters
    ----------
    pose : ndarray, shape (3,)
        Start ``x, y, yaw`` [m, m, rad].
    window : ndarray, shape (S, 2)
        ``(v, omega)`` [m/s, rad/s], ``v >= 0``.
    lengths : ndarray, shape (K,)
        Arc lengths [m] of the points.
    creep : float
        Speeds below this [m/s] (> 0) bend as if at this speed: a creeping
        arc would otherwise curl on the spot and look free of obstacles
        (it stops within ``creep`` times a period or so, well before its
        first point).

    Returns
    -------
    ndarray, shape (S, K, 2)
        For ``v > 0`` the arc of curvature ``omega / max(v, creep)``; for a
        turn in place, the straight line the robot faces after turning for
        :data:`SIM_TIME_S` (where it will go next).
    """
    v, omega = window[:, 0], window[:, 1]
    moving = v > 0.0
    arcs = rollout(pose, moving.astype(float), omega / np.maximum(v, creep), lengths)[..., :2]
    facing = pose[2] + omega * SIM_TIME_S
    ahead = pose[:2] + lengths[None, :, None] * np.stack([np.cos(facing), np.sin(facing)], -1)[:, None]
    return np.where(moving[:, None, None], arcs, ahead)


def free_travel(clearance, along, threshold):
    """How far along each arc the last sample before its first contact lies.

    Parameters
    ----------
    clearance : ndarray, shape (S, K)
        Clearance [m] at the samples of each arc.
    along : ndarray, shape (K,)
        Increasing positions of the samples (arc length [m] or time [s]).
    threshold : float
        A sample with less clearance [m] is a contact.

    Returns
    -------
    ndarray, shape (S,)
        ``along`` of the last sample before the first contact (0 when the
        first sample is one), ``inf`` for an arc without contact.

    Examples
    --------
    >>> free_travel(np.array([[0.5, 0.4], [0.5, -0.1], [-0.1, 0.3]]), np.array([0.5, 1.0]), 0.0)
    array([inf, 0.5, 0. ])
    """
    contact = clearance < threshold
    first = contact.argmax(axis=1)
    free = np.concatenate([[0.0], along])[first]
    return np.where(contact.any(axis=1), free, np.inf)
