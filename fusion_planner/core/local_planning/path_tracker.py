"""The ``'astar-track'`` baseline: pure-pursuit tracking of the global path, no avoidance.

The paper's baseline ("A* cannot avoid dynamic obstacles"): the obstacles in
the observation are ignored; blocked (moving less than ``stuck_progress``
within ``stuck_window``) means failed.

Examples
--------
>>> import numpy as np
>>> from fusion_planner.core.local_planning.controller_base import FollowerParams, Observation
>>> tracker = PathTracker(FollowerParams())
>>> tracker.set_path(np.array([[0.0, 0.0], [3.0, 0.0]]), np.array([[0.0, 0.0], [3.0, 0.0]]))
>>> obs = Observation(pose=np.zeros(3), velocity=np.zeros(2), obstacle_points=np.zeros((0, 2)),
...                   tracked=np.zeros((0, 5)), time=0.0)
>>> tracker.compute(obs).sub_goal.tolist()            # the carrot, lookahead ahead
[1.5, 0.0]
"""

import math

import numpy as np

from fusion_planner.core.local_planning.controller_base import (
    LOCAL_PLAN_POINTS, Command, ControllerBase, WindowHistory)
from fusion_planner.core.local_planning.local_geometry import resample

#: Path points ahead of the current one the tracker searches for the closest.
TRACK_SEARCH_WINDOW = 200

#: Spacing [m] of the tracker's resampled path.
TRACK_SPACING = 0.05

#: Stride between the resampled path points shown as the local plan.
PLAN_STRIDE = 4


class PathTracker(ControllerBase):
    """Pure-pursuit tracking of the global path with no obstacle avoidance.

    The paper's baseline ("A* cannot avoid dynamic obstacles"): obstacles in
    the observation are ignored. Blocked (moving less than ``stuck_progress``
    within ``stuck_window``) means failed.

    Parameters
    ----------
    params : FollowerParams
    """

    def _clear_state(self):
        super()._clear_state()
        p = self.params
        self._closest = 0  # index of the closest resampled path point so far
        self._positions = WindowHistory(p.stuck_window, p.control_period)

    def set_path(self, path, key_nodes):
        """Take a global plan (see :meth:`ControllerBase.set_path`); the path is tracked.

        The path is resampled every :data:`TRACK_SPACING` metres (a plan may
        be just its corners) and ends at ``key_nodes[-1]``.
        """
        super().set_path(path, key_nodes)
        path = self._path
        if math.hypot(*(path[-1] - self._key_nodes[-1])) > 1e-9:
            path = np.vstack([path, self._key_nodes[-1]])
        self._dense = resample(path, TRACK_SPACING)

    def _stop_or_arrive(self, obs):
        """The stop command (no plan, failure, or inside the goal tolerance), else None.

        Returns
        -------
        command : Command or None
        goal_distance : float
            From the robot to the goal [m] (NaN with a stop for no plan or a
            failure).
        """
        stop = self._checked_stop(obs)
        if stop is not None:
            return stop, math.nan
        goal = self._key_nodes[-1]
        goal_distance = math.hypot(*(goal - obs.pose[:2]))
        if goal_distance <= self.params.goal_tolerance:
            return self._stop(obs, 'arrived', sub_goal=goal.copy()), goal_distance
        return None, goal_distance

    def compute(self, obs):
        """One control step.

        Parameters
        ----------
        obs : Observation
            Only the pose, velocity and time are used.

        Returns
        -------
        Command
            ``'no_path'`` before a plan; ``'arrived'`` inside the goal
            tolerance (braking to rest); ``'failed'`` once blocked, until a
            new path or a reset; otherwise ``'moving'`` toward the carrot
            (``sub_goal``), the path point ``lookahead`` ahead.

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
        window = self._dense[self._closest:self._closest + TRACK_SEARCH_WINDOW]
        self._closest += int(np.argmin(np.hypot(window[:, 0] - q[0], window[:, 1] - q[1])))
        ahead = self._dense[self._closest:]
        far = np.nonzero(np.hypot(ahead[:, 0] - q[0], ahead[:, 1] - q[1]) >= p.lookahead)[0]
        carrot = ahead[far[0]] if len(far) else goal
        before = self._positions.push(obs.time, q.copy())
        if before is not None and math.hypot(*(q - before)) < p.stuck_progress:
            self.stuck_events += 1
            return self._fail(obs, f'blocked at ({q[0]:.2f}, {q[1]:.2f}): moved less than '
                                   f'{p.stuck_progress:g} m in {p.stuck_window:g} s, and path '
                                   'tracking has no obstacle avoidance', carrot.copy())
        offset = carrot - q
        v, w = self._limit(*self._steer(math.atan2(offset[1], offset[0]),
                                        p.approach_gain * goal_distance, obs), obs)
        plan = np.vstack([q, ahead[:LOCAL_PLAN_POINTS * PLAN_STRIDE:PLAN_STRIDE]]) \
            if self.display_plan else None
        return Command(v, w, 'moving', sub_goal=carrot.copy(), local_plan=plan)
