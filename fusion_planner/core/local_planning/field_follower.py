"""The field controllers: ``'fusion'``, ``'apf'`` and ``'classic-apf'``.

One class, :class:`FieldFollower`, configured by
:func:`~fusion_planner.core.local_planning.follow.make_controller`: the classic field of
eqs. (9)-(14) or the improved one of eqs. (15)-(17), the final goal or the
A* key nodes as sub-goals (the paper's section 3.3), with or without
prediction of tracked obstacles and escape from local minima. Each step
(:meth:`FieldFollower.compute`):

1. the *scene*: obstacle points thinned to one per ``point_spacing`` square
   (so a wall's pull does not depend on the scan's angular density), plus,
   for each tracked obstacle, the nearest surface point of its circle at
   :data:`PREDICTION_SAMPLES` instants over ``prediction_horizon``;
2. the *sub-goal*: key nodes are passed when reached or when a later one is
   visible with ``sight_clearance`` to spare;
3. the *direction*: the total force at the robot, attracted to a carrot at
   most ``lookahead`` ahead (for fusion, on the route and centred in its free
   band, see :meth:`FieldFollower._shape`), or the boundary tangent while
   escaping (see :mod:`fusion_planner.core.local_planning.escape`);
4. the *command*: heading control under the speed caps (adaptive step of
   eq. (18), approach, braking), then, with prediction, the evasion check of
   :mod:`fusion_planner.core.local_planning.evasion` (against the tracked
   obstacles and the tentative movers), then the velocity and acceleration
   limits, then, for a route follower, the free-arc check of
   :mod:`fusion_planner.core.local_planning.free_arc` on the command as
   limited.

Examples
--------
>>> import numpy as np
>>> from fusion_planner.core.local_planning.controller_base import FollowerParams, Observation
>>> ctrl = FieldFollower(FollowerParams(), field='improved', use_key_nodes=False)
>>> ctrl.set_path(np.array([[0.0, 0.0], [3.0, 0.0]]), np.array([[3.0, 0.0]]))
>>> obs = Observation(pose=np.zeros(3), velocity=np.zeros(2), obstacle_points=np.zeros((0, 2)),
...                   tracked=np.zeros((0, 5)), time=0.0)
>>> cmd = ctrl.compute(obs)
>>> cmd.status, cmd.v > 0
('moving', True)
"""

import logging
import math
from dataclasses import dataclass

import numpy as np

from fusion_planner.core.local_planning import apf, escape, evasion
from fusion_planner.core.local_planning.controller_base import (
    LOCAL_PLAN_POINTS, Command, ControllerBase, WindowHistory, as_path)
from fusion_planner.core.errors import (
    GoalOccupied, InvalidInput, NoValidPathCouldBeFound, PlanningError)
from fusion_planner.core.local_planning.escape import MAX_REPLANS_PER_EPISODE, BoundaryFollow, Episode
from fusion_planner.core.local_planning.free_arc import (
    free_arc_speed, free_arc_turn, turn_round_error)
from fusion_planner.core.local_planning.local_geometry import (
    braking_speed, circle_points, front_gap, off_circles, points_off_circles, segments_clear,
    thin_points, wrap_angle)
from fusion_planner.core.local_planning.progress import ProgressMonitor
from fusion_planner.core.local_planning.replanning import ObstacleMemory
from fusion_planner.core.local_planning.route import Route
from fusion_planner.core.local_planning.speed_policy import (
    ROTATE_FIRST_RAD, braking_path_gap, turn_cap)
from fusion_planner.core.local_planning.yielding import passing_bounds, route_closures

LOGGER = logging.getLogger(__name__)

#: Predicted positions per tracked obstacle over the prediction horizon
#: (including the current one).
PREDICTION_SAMPLES = 5

#: Smallest boundary distance [m] at which a predicted (not current) position
#: of a tracked obstacle repels: an overlap predicted seconds ahead must steer
#: the robot, not swamp every other force with a near-infinite one.
PREDICTED_MIN_GAP = 0.1

#: Weight of the last predicted position relative to the current one (linear
#: in between): the farther future is less certain.
FAR_PREDICTION_WEIGHT = 0.5

#: The adaptive step never slows the robot below this fraction of max_speed:
#: eq. (18) gives a zero step at d = 0 and the robot must still be able to
#: leave (the braking cap, not the step, is what prevents contact).
MIN_STEP_FRACTION = 0.25

#: Key nodes ahead of the current one tested for visibility on each step.
MAX_VISIBILITY_CHECKS = 4

#: Longest step [m] of the field rollout shown as the local plan.
ROLLOUT_MAX_STEP = 0.2

#: A force shorter than this has no direction: the robot stops (a minimum).
FORCE_EPS = 1e-9

#: A route follower this close [m] to a tracked obstacle is giving way: a
#: lack of progress then is no local minimum (the time without progress
#: still counts toward ``escape_time_limit``).
GIVING_WAY_GAP = 0.5

#: Shortest time [s] between two replans asked for because the route is blocked.
BLOCKED_REPLAN_PERIOD = 2.0

#: A route follower held this long [s] without progress toward the goal,
#: with people on its route just ahead, asks for a plan round them (as a
#: navigation stack whose costmap marks a person does); at most this often.
PEOPLE_DETOUR_AFTER = 10.0

#: Replanning outcomes that prove the goal unreachable around what was seen. A
#: goal occupied by what the laser saw (:class:`GoalOccupied`) is not among
#: them: the plan being followed reached it on the map, and a person may be
#: standing on it.
UNREACHABLE = (NoValidPathCouldBeFound,)

#: Below these speeds [m/s, rad/s] the robot counts as stopped.
STOPPED_SPEED = 1e-3
STOPPED_TURN = 1e-2

#: A static point closer to the route than this fraction of the robot radius
#: blocks it (the field pushes the robot off the route around it); a point
#: farther away is beside the route and bounds the band the carrot is
#: centred in (see ``FieldFollower._shape``). The planner
#: checks clearance at cell resolution, so a route may pass a wall's face a
#: little closer than the radius: that wall is still beside the route.
BLOCKING_FRACTION = 0.5

#: Clearance [m] from the points beside the route that the carrot keeps where
#: there is room; in a passage narrower than twice this (plus the robot) the
#: carrot is centred.
KEEP_CLEARANCE = 0.12

#: A static point this close [m] to the robot's boundary is grazed: the
#: route follower's direction is turned away from it (the field direction plus
#: the unit vector away from the point), since the band steers but a robot
#: already grazing a post may only get off it by turning away.
NEAR_GAP = 0.01

#: Gap [m] the band keeps from the points beside the route even where it is
#: narrow (the carrot is centred in what is left).
MIN_WALL_GAP = 0.03

#: Shortest carrot distance [m] along the route (see ``FieldFollower._shape``).
MIN_LOOKAHEAD = 0.2

#: Slack [m] below the robot's present clearance that the line to the carrot
#: may keep (floating point and the discretisation of the band only).
CLEARANCE_SLACK = 1e-3


@dataclass
class _Scene:
    """Obstacles of one step, prepared once."""

    field_points: np.ndarray      # (M', 2) thinned points + tracked surface points [m]
    field_velocities: np.ndarray  # (M', 2) [m/s]
    field_weights: np.ndarray     # (M',)
    all_points: np.ndarray        # (M, 2) every finite point (safety checks) [m]
    tracked: np.ndarray           # (K, 5) finite tracked obstacles x, y, vx, vy, radius
    tentative: np.ndarray         # (T, 5) finite tentative movers, the same
    turn_stds: np.ndarray         # (K,) their heading diffusion [rad/sqrt(s)], NaN: unknown
    nearest_ahead: float          # boundary distance to the nearest obstacle ahead [m]
                                  # (not measured for a route follower)
    repelling: tuple = None       # route followers: (points, velocities, weights) that repel
    carrot: np.ndarray = None     # (2,) the route follower's field goal [m]
    graze: np.ndarray = None      # (2,) unit vector away from a static point grazed, or None
    blocking: np.ndarray = None   # (B, 2) static points on the route ahead [m]

    @property
    def circle_centres(self):
        """Current centres ``(K, 2)`` [m] of the tracked obstacles."""
        return self.tracked[:, 0:2]

    @property
    def circle_radii(self):
        """Radii ``(K,)`` [m] of the tracked obstacles."""
        return self.tracked[:, 4]


class FieldFollower(ControllerBase):
    """APF-based controller: ``'fusion'``, ``'apf'`` or ``'classic-apf'``.

    Parameters
    ----------
    params : FollowerParams
    field : {'improved', 'classic'}
        Eqs. (15)-(17) or eqs. (9)-(14).
    use_key_nodes : bool
        Key nodes as successive sub-goals (fusion) or only the final goal.
    escape : bool
        Escape local minima (next key node, replanning, boundary following);
        without it a stuck robot fails at once.
    predict : bool
        Avoid tracked obstacles at their predicted positions over
        ``prediction_horizon`` and check every command against their
        predicted motion (:mod:`fusion_planner.core.local_planning.evasion`); otherwise the
        field sees them only where they are now.
    replan : callable, optional
        ``replan(start, goal, obstacle_points) -> (path, key_nodes)``: a new
        global plan from ``start`` (2,) to ``goal`` (2,) [m] that also avoids
        the remembered static obstacle points ``(M, 2)`` [m]; raises
        :class:`~fusion_planner.core.errors.PlanningError` when there is
        none. :class:`~fusion_planner.core.local_planning.replanning.GridReplanner` is one.
        Used only with key nodes.

    Attributes
    ----------
    stuck_events : int
        Local-minimum detections since the last :meth:`reset`.
    replans : int
        Successful replans since the last :meth:`reset`.

    Raises
    ------
    InvalidInput
        If ``params`` is not a FollowerParams, ``field`` is unknown or
        ``replan`` is not callable.
    """

    def __init__(self, params, field='improved', use_key_nodes=True, escape=True, predict=True,
                 replan=None):
        if field not in ('improved', 'classic'):
            raise InvalidInput(f"field must be 'improved' or 'classic', got {field!r}")
        if replan is not None and not callable(replan):
            raise InvalidInput(
                'replan must be a callable (start, goal, obstacle_points) -> (path, key_nodes)')
        self.field = field
        self.use_key_nodes = use_key_nodes
        self.escape = escape
        self.predict = predict
        self._replan = replan if use_key_nodes else None
        super().__init__(params)
        self._forget()

    def reset(self):
        """Forget the plan, the stuck history, the failure, the counts and the obstacle memory."""
        super().reset()
        self._forget()

    def _forget(self):
        self.replans = 0
        self._memory = ObstacleMemory(self.params.point_spacing)

    def _clear_state(self):
        super()._clear_state()
        p = self.params
        self._index = 0
        self._progress = WindowHistory(p.stuck_window, p.control_period)  # sub-goal distances
        self._episode = None
        self._follow = None
        self._best_hit = {}
        self._last_time = None
        self._monitor = ProgressMonitor(p.stuck_progress)
        self._unreachable = None  # why the goal cannot be reached, once a replan proved it
        self._passing_side = 0    # side kept for the people on the route (see yielding)
        self._evader = evasion.Evader()  # keeps its evasive choice while it stays good
        self._last_replan = -math.inf  # when a new plan was last asked for [s]
        self._last_detour = -math.inf  # when a plan round people was last asked for [s]
        self._detour_taken = False     # a plan round people has had its fresh allowance
        self._goal_blocked = None      # why the last replan found the goal occupied
        self._plan_route = self._route = None
        if self.use_key_nodes and self._path is not None:
            self._set_plan_route()

    # .. the route (key-node followers) ..............................................

    def _set_plan_route(self):
        """Make the global path the route, and place the key nodes on it."""
        path = self._path
        if math.hypot(*(path[-1] - self._key_nodes[-1])) > 0.0:
            path = np.vstack([path, self._key_nodes[-1]])
        self._plan_route = self._route = Route(path)
        arcs, s = [], 0.0
        for node in self._key_nodes:
            s = self._plan_route.arc_of(node, start=s)
            arcs.append(s)
        self._plan_node_arcs = self._node_arcs = np.array(arcs)

    def _route_from(self, q, index):
        """Drive from ``q`` straight to key node ``index``'s place on the plan, then along it."""
        plan = self._plan_route
        first = plan.index_at(self._plan_node_arcs[index])
        joint = plan.points[first]
        self._route = Route(np.vstack([q, plan.points[first:]]))
        self._node_arcs = self._plan_node_arcs - plan.arc[first] + math.hypot(*(joint - q))
        self._monitor.rebase(self._remaining(q))

    def _remaining(self, q):
        """Distance [m] still to go: along the route (plus the way back to it), else straight."""
        route = self._route
        if route is None:
            return math.hypot(*(self._key_nodes[-1] - q))
        return route.remaining + math.hypot(*(q - route.point_at(route.station)))

    # .. obstacles ....................................................................

    def _scene(self, obs):
        """Thin the points, predict the tracked obstacles, find the nearest obstacle ahead."""
        p = self.params
        q = obs.pose[:2]
        points = obs.obstacle_points
        if len(points) and not np.all(np.isfinite(points)):
            points = points[np.all(np.isfinite(points), axis=1)]
        finite = np.all(np.isfinite(obs.tracked), axis=1)
        tracked, turn_stds = obs.tracked[finite], obs.turn_stds[finite]
        tentative = _finite_rows(obs.tentative)
        thinned = thin_points(points, p.point_spacing)
        if len(thinned):
            # only points within rho0 of the robot or of its rollout exert a force
            reach = p.robot_radius + p.apf.rho0 + LOCAL_PLAN_POINTS * ROLLOUT_MAX_STEP
            d = thinned - q
            thinned = thinned[np.einsum('ij,ij->i', d, d) < reach * reach]
        surface, velocities, weights = self._tracked_field(obs, tracked)
        return _Scene(field_points=np.vstack([thinned, surface]),
                      field_velocities=np.vstack([np.zeros_like(thinned), velocities]),
                      field_weights=np.concatenate([np.ones(len(thinned)), weights]),
                      all_points=points, tracked=tracked, tentative=tentative,
                      turn_stds=turn_stds,
                      nearest_ahead=(math.inf if self._route is not None  # braking path instead
                                     else self._nearest_ahead(obs.pose, thinned, tracked)))

    def _tracked_field(self, obs, tracked):
        """Field points of the tracked obstacles: nearest surface points at predicted positions.

        Predicted relative to the robot going on at its current velocity
        (what matters is where the obstacle will be with respect to the
        robot) at :data:`PREDICTION_SAMPLES` instants over
        ``prediction_horizon`` (only now without prediction); each weighs
        its half circumference over ``point_spacing``, fading to
        :data:`FAR_PREDICTION_WEIGHT`. A predicted (not current) overlap is
        not a contact yet: it repels as if :data:`PREDICTED_MIN_GAP` away.

        Returns
        -------
        points : ndarray, shape (S * K, 2)
            [m], map frame.
        velocities : ndarray, shape (S * K, 2)
            The obstacles' velocities [m/s].
        weights : ndarray, shape (S * K,)
        """
        p = self.params
        if len(tracked) == 0:
            return np.zeros((0, 2)), np.zeros((0, 2)), np.zeros(0)
        q, yaw = obs.pose[:2], obs.pose[2]
        centres, velocities, radii = tracked[:, 0:2], tracked[:, 2:4], tracked[:, 4]
        own = obs.velocity[0] * np.array([math.cos(yaw), math.sin(yaw)])
        horizon = p.prediction_horizon if self.predict else 0.0
        samples = PREDICTION_SAMPLES if horizon > 0 else 1
        times = np.linspace(0.0, horizon, samples)                              # (S,)
        future = centres[None, :, :] + times[:, None, None] * (velocities - own)[None, :, :]
        future_radii = np.tile(radii, samples)
        keep_off = np.where(np.repeat(times, len(tracked)) > 0.0,
                            p.robot_radius + PREDICTED_MIN_GAP, 0.0)
        surface = circle_points(q, future.reshape(-1, 2), future_radii, keep_off)
        arc = np.maximum(math.pi * future_radii / p.point_spacing, 1.0)
        fraction = times / horizon if horizon > 0 else times
        decay = 1.0 - (1.0 - FAR_PREDICTION_WEIGHT) * fraction
        return surface, np.tile(velocities, (samples, 1)), arc * np.repeat(decay, len(tracked))

    def _nearest_ahead(self, pose, points, tracked):
        """Boundary distance [m] to the nearest obstacle ahead (``inf``: none).

        The adaptive step looks only ahead: slowing down for an obstacle
        behind (a person catching up) would only let it run into the robot.
        """
        p = self.params
        q = pose[:2]
        heading = np.array([math.cos(pose[2]), math.sin(pose[2])])
        nearest = math.inf
        if len(points):
            d = points - q
            ahead = d @ heading > 0.0
            if np.any(ahead):
                nearest = math.sqrt(float(np.min(np.einsum('ij,ij->i', d[ahead], d[ahead])))) \
                    - p.robot_radius
        if len(tracked):
            d = tracked[:, 0:2] - q
            radii = tracked[:, 4]
            ahead = d @ heading > -radii
            if np.any(ahead):
                gap = np.hypot(d[ahead, 0], d[ahead, 1]) - radii[ahead] - p.robot_radius
                nearest = min(nearest, float(np.min(gap)))
        return nearest

    def _remember(self, obs, scene, force=False):
        """Add this step's static points to the replanning memory (when due, or ``force``)."""
        if self._replan is None or not (force or self._memory.due(obs.time)):
            return
        self._memory.add(obs.time, points_off_circles(scene.all_points, scene.circle_centres,
                                                      scene.circle_radii))

    # .. fields .......................................................................

    def _field_goal(self, q, target):
        """The goal the field attracts to (a carrot), given the current sub-goal.

        Classic field: the sub-goal itself (eqs. (9)-(14) as written).
        Improved field with key nodes: see :meth:`_shape` (the route's
        carrot). Improved field without key nodes: the point ``lookahead`` ahead on
        the straight line to the sub-goal. Either way ``rho_g`` of
        eqs. (15)-(16) stays bounded far from the goal and vanishes at it.
        """
        lookahead = self.params.lookahead
        if self.field == 'classic':
            return target
        offset = target - q
        dist = math.hypot(offset[0], offset[1])
        if dist <= lookahead:
            return target
        return q + offset * (lookahead / dist)

    def _force(self, q, target, scene, robot_velocity):
        """Total force at ``q``: eq. (14) (classic field) or eqs. (10) + (15)-(17) (improved).

        A route follower's field is shaped by its route (:meth:`_shape`):
        the static points beside the route do not repel, they shift the
        carrot it attracts to; points on the route and tracked obstacles
        repel as in the paper.
        """
        ap = self.params.apf
        goal = self._field_goal(q, target) if scene.carrot is None else scene.carrot
        force = apf.attractive_force(q, goal, ap, check=False)                      # eq. (10)
        if self.field == 'classic':
            return force + apf.classic_repulsive_force(                            # eq. (14)
                q, scene.field_points, ap, scene.field_weights, check=False)
        points, velocities, weights = scene.repelling or (
            scene.field_points, scene.field_velocities, scene.field_weights)
        force = force + apf.improved_repulsive_force(                              # eqs. (15)-(16)
            q, goal, points, ap, weights, check=False)
        if robot_velocity is not None:
            force = force + apf.velocity_repulsion(                                 # eq. (17)
                q, robot_velocity, points, velocities, ap, weights, check=False)
        return force

    def _rollout(self, q, target, scene, first_direction):
        """Field rollout from ``q`` with the adaptive step (for display)."""
        p = self.params
        plan = [q.copy()]
        point = q.copy()
        direction = first_direction
        for _ in range(LOCAL_PLAN_POINTS):
            if direction is None:
                break
            if len(scene.field_points):
                d = scene.field_points - point
                near = math.sqrt(float(np.min(np.einsum('ij,ij->i', d, d)))) - p.robot_radius
            else:
                near = math.inf
            step = apf.adaptive_step(near, p.max_speed, p.apf)                     # eq. (18)
            step = min(max(step, MIN_STEP_FRACTION * p.apf.l0), ROLLOUT_MAX_STEP)
            remaining = math.hypot(*(target - point))
            point = point + direction * min(step, remaining)
            plan.append(point)
            if remaining <= step:
                break
            force = self._force(point, target, scene, None)
            norm = math.hypot(force[0], force[1])
            direction = force / norm if norm > FORCE_EPS else None
        return np.array(plan)

    # .. sub-goals ....................................................................

    def _advance_sub_goal(self, q, scene):
        """Pass key nodes reached (within goal_tolerance) or behind a visible later one.

        A later key node (up to :data:`MAX_VISIBILITY_CHECKS` ahead, within
        ``visibility_range``) is visible when no obstacle point lies within
        ``robot_radius + sight_clearance`` of the straight line to it; the
        farthest visible one becomes the sub-goal. A key node is never passed
        merely for being near: cutting a corner toward one that is not
        visible would drive into the corner.
        """
        if not self.use_key_nodes:
            self._index = len(self._key_nodes) - 1
            return
        p = self.params
        last = len(self._key_nodes) - 1
        station = self._route.station
        for _ in range(len(self._key_nodes)):  # bounded: each pass advances or stops
            if self._index >= last:
                break
            if math.hypot(*(self._key_nodes[self._index] - q)) > p.goal_tolerance \
                    and self._node_arcs[self._index] > station + p.goal_tolerance:
                break
            self._index += 1
        if self._index >= last:
            return
        later = np.arange(self._index + 1, min(last, self._index + MAX_VISIBILITY_CHECKS) + 1)
        ends = self._key_nodes[later]
        in_range = np.hypot(ends[:, 0] - q[0], ends[:, 1] - q[1]) <= p.visibility_range
        if not np.any(in_range):
            return
        half = p.robot_radius + p.sight_clearance
        clear = segments_clear(q, ends[in_range], scene.all_points, half)
        if len(scene.circle_centres):
            clear &= segments_clear(q, ends[in_range], scene.circle_centres,
                                    half + scene.circle_radii)
        if np.any(clear):
            self._index = int(later[in_range][np.nonzero(clear)[0][-1]])
            self._route_from(q, self._index)

    # .. stuck detection and escape ...................................................

    def _on_stuck(self, obs, q, target_distance, scene):
        """Count the event and take the next escape step; returns a failure reason or None."""
        p = self.params
        self.stuck_events += 1
        self._progress.clear()
        where = f'({q[0]:.2f}, {q[1]:.2f})'
        if not self.escape:
            return (f'stuck in a local minimum of the {self.field} potential field at {where} '
                    f'(net progress below {p.stuck_progress} m in {p.stuck_window} s) '
                    'and this controller has no escape')
        if self._episode is None:
            self._episode = Episode(obs.time, self._index, target_distance)
        episode = self._episode
        LOGGER.info('local minimum at %s (event %d); escaping', where, self.stuck_events)
        if self.use_key_nodes and not episode.skipped and self._index < len(self._key_nodes) - 1:
            self._index += 1  # the paper's escape: aim at the next A* key node
            self._route_from(q, self._index)
            episode.skipped = True
            episode.index = self._index
            return None
        if self._replan is not None and episode.replans < MAX_REPLANS_PER_EPISODE:
            episode.replans += 1
            if self._replan_now(obs, q, scene):
                episode.index = self._index
                return None
            if self._unreachable is not None:
                return None
        key = self._index
        straight = math.hypot(*(self._key_nodes[key] - q))  # what may_leave compares against
        self._best_hit[key] = min(self._best_hit.get(key, math.inf), straight)
        self._follow = BoundaryFollow()
        return None

    def _route_blocked(self, obs, scene):
        """Whether to replan now: static points the map did not show block the route just ahead.

        Like a navigation stack whose path is blocked, fusion with a
        replanner asks for a new plan as soon as a static point lies on the
        route within ``lookahead`` ahead, instead of waiting to be stuck in
        front of it; at most once per :data:`BLOCKED_REPLAN_PERIOD`, and not
        while escaping.
        """
        p = self.params
        route = self._route
        if (self._replan is None or self._follow is not None or self._episode is not None
                or len(scene.blocking) == 0
                or obs.time - self._last_replan < BLOCKED_REPLAN_PERIOD):
            return False
        ahead = route.along_to_first(scene.blocking, route.station, route.station + p.lookahead,
                                     p.robot_radius + p.safety_distance)
        return math.isfinite(ahead)

    def _detour_round_people(self, obs, q, scene, stalled):
        """Plan round the people on the route just ahead after a while without progress; True on a new plan.

        A person walking up and down the corridor the route runs through
        can hold the robot for as long as they like; after
        :data:`PEOPLE_DETOUR_AFTER` without progress (``stalled`` [s]),
        with people on the route ahead, the robot asks for a plan with the
        route closed at them
        (:func:`~fusion_planner.core.local_planning.yielding.route_closures`),
        and takes it if there is one (another corridor) that it drives at
        ``max_speed`` in no more time than it has already waited beyond the
        route it has; at most once per that time, and not while following a
        boundary. An escape episode may be open (a robot waiting a little
        too far from the person to count as giving way is "stuck"): its
        steps are for static minima, and its replans round the walls find
        the same corridor, so they neither wait for nor delay this plan,
        and the new plan ends the episode.

        The first such plan for a goal restarts the clock of
        ``escape_time_limit``: the person who held the robot may herd it
        back while it turns to the other corridor, and the time spent
        waiting for them was not the robot's to make up. Later ones do not,
        so a robot sent back and forth between corridors that people hold
        still gives up.
        """
        if (self._replan is None or self._follow is not None
                or stalled < PEOPLE_DETOUR_AFTER
                or obs.time - self._last_detour < PEOPLE_DETOUR_AFTER):
            return False
        walls = points_off_circles(scene.all_points, scene.circle_centres, scene.circle_radii)
        closures = route_closures(self._route, q, scene.tracked, walls, self.params,
                                  self.params.point_spacing)
        if len(closures) == 0:
            return False
        self._last_detour = obs.time
        longest = self._remaining(q) + self.params.max_speed * stalled
        if not self._replan_now(obs, q, scene, people=closures, longest=longest):
            return False
        self._episode = None
        if not self._detour_taken:
            self._detour_taken = True
            self._monitor.restart(obs.time, self._remaining(q))
        return True

    def _replan_now(self, obs, q, scene, people=None, longest=math.inf):
        """Ask for a global plan around everything seen so far; True on success.

        ``people`` (M, 2) [m] are points closing the route at people, for
        this plan only; people move, so a plan that fails for them proves
        nothing. A plan longer than ``longest`` [m] is not taken.
        """
        self._last_replan = obs.time
        self._remember(obs, scene, force=True)
        goal = self._key_nodes[-1].copy()
        points = self._memory.points.copy()
        if people is not None:
            points = np.vstack([points, people])
        try:
            path, key_nodes = self._replan(q.copy(), goal, points)
            path = as_path(path, 'replanned path')
            key_nodes = as_path(key_nodes, 'replanned key_nodes')
        except PlanningError as err:
            LOGGER.info('replanning from (%.2f, %.2f) failed: %s', q[0], q[1], err)
            self._goal_blocked = str(err) if isinstance(err, GoalOccupied) else None
            if isinstance(err, UNREACHABLE) and people is None:
                self._unreachable = (f'the goal is unreachable around the obstacles seen '
                                     f'(replanned from ({q[0]:.2f}, {q[1]:.2f})): {err}')
                if self.no_path_proven_at is None:
                    self.no_path_proven_at = obs.time
            return False
        length = float(np.sum(np.hypot(*np.diff(path, axis=0).T)))
        if length > longest:
            LOGGER.info('a plan of %.1f m round the people is longer than %.1f m; waiting on',
                        length, longest)
            return False
        self._goal_blocked = None
        # the planner ends at the goal's cell centre; the goal stays the one asked for
        self._path = np.vstack([path[:-1], goal])
        self._key_nodes = np.vstack([key_nodes[:-1], goal])
        self._index = 0
        self._set_plan_route()
        self._route.project(q)
        self._monitor.rebase(self._remaining(q))
        self._best_hit = {}
        self._progress.clear()
        self._advance_sub_goal(q, scene)
        self.replans += 1
        LOGGER.info('replanned around %d remembered obstacle points', len(self._memory.points))
        return True

    # .. main step .....................................................................

    def compute(self, obs):
        """One control step.

        Parameters
        ----------
        obs : Observation

        Returns
        -------
        Command
            ``'no_path'`` before a plan, or once a replan proved the goal
            unreachable and the robot stands still; ``'arrived'`` inside the
            goal tolerance (braking to rest); ``'failed'`` after
            ``escape_time_limit`` without progress toward the goal (or at the
            first minimum without escape), until a new path or a reset;
            otherwise ``'moving'``, or ``'stuck_escaping'`` while an escape
            episode is open or the robot brakes for a proven ``'no_path'``.

        Raises
        ------
        InvalidInput
            If ``obs`` is not an Observation.
        """
        stop = self._checked_stop(obs)
        if stop is not None:
            return stop
        if self._unreachable is not None:
            return self._stop_unreachable(obs)
        p = self.params
        if self._last_time is not None and obs.time < self._last_time:
            self._progress.clear()  # the clock went back (simulation reset)
        self._last_time = obs.time
        q = obs.pose[:2]
        goal_distance = math.hypot(*(self._key_nodes[-1] - q))
        if goal_distance <= p.goal_tolerance:
            return self._stop(obs, 'arrived', sub_goal=self._key_nodes[-1].copy())
        scene = self._scene(obs)
        self._remember(obs, scene)
        if self._route is not None:
            self._route.project(q)
        self._update_sub_goal(q, scene)
        target = self._key_nodes[self._index]
        stalled = self._monitor.update(obs.time, self._remaining(q),  # [s] without progress
                                       pushed=self._evader.evading)
        if stalled > p.escape_time_limit:
            reason = (f'stuck: no progress toward the goal for {p.escape_time_limit:g} s, near '
                      f'({q[0]:.2f}, {q[1]:.2f}), {goal_distance:.2f} m from the goal')
            if self._goal_blocked is not None:
                reason += f' (the last replan: {self._goal_blocked})'
            return self._fail(obs, reason, target.copy())
        direction, reason = self._escape_direction(obs, scene)
        if reason is not None:
            return self._fail(obs, reason, target.copy())
        if self._route is not None:
            self._shape(scene, q)
            if self._route_blocked(obs, scene) and self._replan_now(obs, q, scene):
                self._shape(scene, q)  # around what blocked the old route
            elif self._detour_round_people(obs, q, scene, stalled):
                self._shape(scene, q)
        if self._unreachable is not None:
            return self._stop_unreachable(obs)
        target = self._key_nodes[self._index]  # an escape step or a replan may have changed it
        plan = None
        if self._follow is None:
            yaw = obs.pose[2]
            robot_velocity = obs.velocity[0] * np.array([math.cos(yaw), math.sin(yaw)])
            force = self._force(q, target, scene,
                                robot_velocity if self.field == 'improved' else None)
            if scene.graze is not None:
                force = force / max(math.hypot(force[0], force[1]), FORCE_EPS) + scene.graze
            norm = math.hypot(force[0], force[1])
            direction = force / norm if norm > FORCE_EPS else None
            if self.display_plan:
                plan = self._rollout(q, target, scene, direction)
        elif self.display_plan:
            plan = q[None, :].copy() if direction is None \
                else np.vstack([q, q + p.apf.l0 * direction])
        status = 'stuck_escaping' if self._episode is not None else 'moving'
        if direction is None:  # an exact minimum: stop; the stuck detector takes over
            v, w = self._evade(obs, scene, (0.0, 0.0), target - q, goal_distance)
        else:
            command = self._field_command(obs, scene, direction, goal_distance)
            v, w = self._evade(obs, scene, command, direction, goal_distance)
        return Command(v, w, status, sub_goal=target.copy(), local_plan=plan)

    def _target_distance(self, q):
        """Distance [m] to the sub-goal: along the route for a route follower, else straight."""
        target = self._key_nodes[self._index]
        route = self._route
        if route is None:
            return math.hypot(*(target - q))
        off = math.hypot(*(q - route.point_at(route.station)))
        return max(self._node_arcs[self._index] - route.station, 0.0) + off

    def _shape(self, scene, q):
        """Shape the field by the route: split the static points, place the carrot.

        A static point within :data:`BLOCKING_FRACTION` of the robot radius
        of the route ahead blocks it and repels as in the paper (within the
        whole radius where the points on either side leave the robot no room
        to pass: the route is closed there, see :meth:`_route_fits`); the
        others lie beside the route and repel nothing (a passage's walls
        would hold the robot back at its entrance, and their steep, opposed
        pushes make it weave inside); one within :data:`NEAR_GAP` of the
        robot is grazed. They bound the free band about the route from the
        robot's station to the carrot, the route point ``lookahead`` ahead;
        the carrot is shifted across the route to keep
        :data:`KEEP_CLEARANCE` from them where the band is wide enough, to
        the band's middle where it is not. Where the straight line to the
        carrot would graze a point beside the route (cutting a corner the
        route goes round), the lookahead is halved, down to
        :data:`MIN_LOOKAHEAD`; the line need not keep more clearance than
        the robot has now. A robot more than its radius off the route
        (pushed aside by people) whose every such line grazes a point heads
        for its station first, when the line to that is free: round a
        wall's end, the route ahead is reached by going back onto it.
        People on the route ahead narrow the band to the side of them the
        robot keeps to (:mod:`~fusion_planner.core.local_planning.yielding`);
        while it keeps to a side, the tracked obstacles do not repel either.
        """
        p = self.params
        route = self._route
        station = route.station
        window = (station - p.robot_radius, station + p.lookahead + p.robot_radius)
        blocking = BLOCKING_FRACTION * p.robot_radius
        # the band and the braking path are measured on every static scan point, not the
        # thinned ones of the field: a post's corner a few centimetres away matters here
        points = scene.all_points
        d = points - q
        reach = math.hypot(*(route.point_at(station) - q)) + p.lookahead + 2.0 * p.robot_radius
        points = points[np.einsum('ij,ij->i', d, d) <= reach * reach]
        points = points_off_circles(points, scene.circle_centres, scene.circle_radii)
        distance, index = route.nearest(points, *window)
        if not self._route_fits(route.signed_offsets(points, distance, index), index):
            blocking = p.robot_radius  # what narrows the route below the robot blocks it
        on_route = distance < blocking
        if len(points):
            away = q - points
            reach = np.hypot(away[:, 0], away[:, 1])
            nearest = int(np.argmin(reach))
            if reach[nearest] - p.robot_radius < NEAR_GAP:
                scene.graze = away[nearest] / max(reach[nearest], FORCE_EPS)
        scene.blocking = points[on_route]
        side = points[~on_route]
        offsets = route.signed_offsets(side, distance[~on_route], index[~on_route])
        side_index = index[~on_route]
        half_width = p.robot_radius + p.safety_distance
        if len(side):
            # never demand more clearance of the line than the robot has now
            nearest = math.sqrt(float(np.min(np.einsum('ij,ij->i', side - q, side - q))))
            half_width = min(half_width, nearest - CLEARANCE_SLACK)
        wall_left = np.min(offsets[offsets > 0], initial=math.inf)
        wall_right = np.min(-offsets[offsets < 0], initial=math.inf)
        *people, self._passing_side = passing_bounds(route, scene.tracked, wall_left, wall_right,
                                                     p, self._passing_side)
        # which points of the field repel; people being passed bound the band, like
        # walls, and the evasion check keeps them safe
        static = len(scene.field_points) - len(scene.tracked) * (
            PREDICTION_SAMPLES if self.predict and p.prediction_horizon > 0 else 1)
        field = scene.field_points[:static]
        on_people = ~off_circles(field, scene.circle_centres, scene.circle_radii)
        beside = route.nearest(field, *window)[0] >= blocking
        passing = self._passing_side != 0
        # people behind the robot along the route (passed, or following) do not repel:
        # pushing the robot away from them pushes it into the walls; the evasion check stays
        tangent = route.tangent_at(station)
        behind = (field - q) @ tangent < 0.0
        people_behind = (scene.circle_centres - q) @ tangent < -scene.circle_radii
        samples = (len(scene.field_points) - static) // max(len(scene.tracked), 1)
        beside = np.concatenate([np.where(on_people, passing | behind, beside),
                                 passing | np.tile(people_behind, samples)])
        scene.repelling = (scene.field_points[~beside], scene.field_velocities[~beside],
                           scene.field_weights[~beside])
        carrot = self._centred_carrots(offsets, side_index, np.array([p.lookahead]), people)[0]
        if p.lookahead > MIN_LOOKAHEAD and not segments_clear(q, carrot[None, :], side,
                                                              half_width)[0]:
            halvings = int(math.ceil(math.log2(p.lookahead / MIN_LOOKAHEAD)))
            shorter = np.maximum(p.lookahead * 0.5**np.arange(1, halvings + 1), MIN_LOOKAHEAD)
            carrots = self._centred_carrots(offsets, side_index, np.append(shorter, 0.0),
                                            people)
            clear = segments_clear(q, carrots, side, half_width)
            if np.any(clear[:-1]):
                carrot = carrots[int(np.argmax(clear[:-1]))]
            elif clear[-1] and math.hypot(*(carrots[-1] - q)) > p.robot_radius:
                carrot = carrots[-1]  # off the route, the way ahead hidden by a corner: back on first
            else:
                carrot = carrots[-2]
        scene.carrot = carrot

    def _route_fits(self, offsets, index):
        """Whether the robot fits between the points on either side of the route ahead.

        ``offsets`` [m] are the signed distances of the static points from
        the route, ``index`` their nearest route points; only those beside
        the route between the robot's station and ``lookahead`` ahead count.
        """
        p = self.params
        route = self._route
        inside = (index > route.index_at(route.station)) \
            & (index < route.index_at(route.station + p.lookahead))
        left = np.min(offsets[inside & (offsets > 0)], initial=math.inf)
        right = np.min(-offsets[inside & (offsets < 0)], initial=math.inf)
        return left + right >= 2.0 * p.robot_radius

    def _centred_carrots(self, offsets, index, lookaheads, people):
        """The route points ``lookaheads`` (C,) [m] ahead, each shifted across the free band to it.

        ``offsets`` [m] are the signed distances of the points beside the
        route from their nearest route points, ``index`` the indices of
        those; only points beside the route between the robot's station
        (less a radius) and a carrot bound its band. ``people`` are the
        bounds ``(room_left, room_right)`` [m] of
        :func:`~fusion_planner.core.local_planning.yielding.passing_bounds`.
        Returns ``(C, 2)`` [m].
        """
        p = self.params
        route = self._route
        ends = route.station + lookaheads
        last = np.array([route.index_at(end) for end in ends])
        inside = (index > route.index_at(route.station - p.robot_radius)) \
            & (index < last[:, None])                                       # (C, M)
        left = np.where(inside & (offsets > 0), offsets, math.inf)
        right = np.where(inside & (offsets < 0), -offsets, math.inf)
        wall = p.robot_radius + MIN_WALL_GAP
        room_left = np.minimum(np.min(left, axis=1, initial=math.inf) - wall, people[0])
        room_right = np.minimum(np.min(right, axis=1, initial=math.inf) - wall, people[1])
        with np.errstate(invalid='ignore'):  # inf - inf where no point bounds either side
            middle = 0.5 * (room_left - room_right)
        keep = np.minimum(np.maximum(0.0, KEEP_CLEARANCE - room_right), room_left - KEEP_CLEARANCE)
        shift = np.where(room_left + room_right < 2.0 * KEEP_CLEARANCE, middle, keep)
        return np.array([route.point_at(end) + d * route.normal_at(end)
                         for end, d in zip(ends, shift)])

    def _stop_unreachable(self, obs):
        """Brake once the goal is proven unreachable; ``'no_path'`` when the robot stands still."""
        v, omega = obs.velocity
        stopped = abs(v) <= STOPPED_SPEED and abs(omega) <= STOPPED_TURN
        return self._stop(obs, 'no_path' if stopped else 'stuck_escaping', self._unreachable)

    def _update_sub_goal(self, q, scene):
        """Advance the sub-goal; a new one resets the progress window and boundary following."""
        before = self._index
        self._advance_sub_goal(q, scene)
        if self._index != before:
            self._progress.clear()
            self._follow = None
            if self._episode is not None and self._index > self._episode.index:
                self._episode = None  # passed the key node we escaped to

    def _escape_direction(self, obs, scene):
        """Boundary following and the stuck test: ``(direction, failure reason)``.

        ``direction`` is the boundary-following direction (unit vector) while
        following, else None (the field steers); ``reason`` is a failure
        sentence when stuck without escape, else None.
        """
        p = self.params
        q = obs.pose[:2]
        target = self._key_nodes[self._index]
        target_distance = self._target_distance(q)
        if self._follow is not None:
            best_hit = self._best_hit.get(self._index, math.inf)
            if not escape.may_leave(q, target, best_hit, scene.field_points, p):
                direction = self._follow.direction(q, target, scene.field_points,
                                                   scene.field_weights, p)
                if direction is None:  # nothing around: head for the sub-goal
                    direction = (target - q) / max(math.hypot(*(target - q)), apf.DIRECTION_EPS)
                return direction, None
            self._follow = None
            self._progress.clear()
            if self._route is not None:
                self._route_from(q, self._index)
        episode = self._episode
        if (episode is not None and not episode.skipped and episode.replans == 0
                and target_distance < episode.target_distance - p.stuck_progress):
            self._episode = None  # progress again after boundary following
        if self._waiting_for_people(q, scene):
            self._progress.clear()  # giving way is not a local minimum (time still counts)
            return None, None
        before = self._progress.push(obs.time, target_distance)
        if before is None or before - target_distance >= p.stuck_progress:
            return None, None
        reason = self._on_stuck(obs, q, target_distance, scene)
        if reason is not None or self._follow is None:
            return None, reason
        target = self._key_nodes[self._index]
        return self._follow.direction(q, target, scene.field_points, scene.field_weights, p), None

    def _waiting_for_people(self, q, scene):
        """Whether a route follower is giving way: keeping to a side, or a person close by."""
        if self._route is None or len(scene.tracked) == 0:
            return False
        if self._passing_side != 0:
            return True
        gaps = np.hypot(*(scene.circle_centres - q).T) - scene.circle_radii - self.params.robot_radius
        return bool(np.min(gaps) < GIVING_WAY_GAP)

    def _field_command(self, obs, scene, direction, goal_distance):
        """Heading control along ``direction`` under the speed caps: the target ``(v, omega)``.

        Caps: the adaptive step of eq. (18) (floored at
        :data:`MIN_STEP_FRACTION` of ``max_speed``), the approach cap
        ``approach_gain * goal_distance``, and braking within the free
        distance straight ahead; a route follower measures that distance
        along its braking path, brakes for the turns ahead, and turns on the
        spot while its heading is off by more than
        :data:`~fusion_planner.core.local_planning.speed_policy.ROTATE_FIRST_RAD`.
        """
        p = self.params
        points = scene.all_points
        circles = np.column_stack([scene.circle_centres, scene.circle_radii])
        if self._passing_side != 0:
            circles = circles[:0]  # keeping to one side of them: the evasion check keeps them safe
        on_route = self._route is not None and self._follow is None
        if on_route:
            gap = braking_path_gap(obs.pose, self._route, self._route.station, points,
                                   scene.blocking, circles, p)
            nearest = gap
        else:
            clearance = p.robot_radius + p.safety_distance
            gap = min(front_gap(obs.pose, points, np.zeros(len(points)), clearance),
                      front_gap(obs.pose, scene.circle_centres, scene.circle_radii, clearance))
            nearest = scene.nearest_ahead
        step = apf.adaptive_step(nearest, p.max_speed, p.apf)                         # eq. (18)
        approach = p.approach_gain * goal_distance
        if on_route:  # brake for the goal as late as for anything else in the way
            approach = max(approach, braking_speed(goal_distance, p.max_accel,
                                                   p.control_period))
        v_cap = min(p.max_speed * min(1.0, max(MIN_STEP_FRACTION, step / p.apf.l0)),
                    approach, braking_speed(gap, p.max_accel, p.control_period))
        heading = math.atan2(direction[1], direction[0])
        error = wrap_angle(heading - obs.pose[2])
        if on_route:
            v_cap = min(v_cap, turn_cap(self._route, self._route.station, p))
            if abs(error) > ROTATE_FIRST_RAD:
                v_cap = 0.0  # turn toward the route on the spot first
                error = turn_round_error(obs.pose, obs.velocity[0], error, points, p)
        return self._steer(heading, v_cap, obs, error=error,
                           gain=p.route_gain() if self._route is not None else None)

    def _evade(self, obs, scene, command, desired, goal_distance):
        """``command`` within the limits, or an evasive one if it runs into a moving obstacle.

        Only with prediction (see :mod:`fusion_planner.core.local_planning.evasion`),
        against the tracked obstacles and the tentative movers (a person
        not yet confirmed as moving is still checked against where it
        walks); ``desired`` (2,) is the direction the controller wants to go,
        ``goal_distance`` [m] how far (the evasion does not run past the goal).
        Then, for a route follower, the free-arc check (:meth:`_on_free_arc`).
        """
        movers = np.vstack([scene.tracked, scene.tentative])
        v_min = 0.0
        if self.predict and len(movers):
            norm = math.hypot(desired[0], desired[1])
            desired = desired / norm if norm > FORCE_EPS else np.zeros(2)
            turn_stds = np.concatenate([scene.turn_stds, np.full(len(scene.tentative), np.nan)])
            command = self._evader.evade(obs.pose, obs.velocity, command, desired, movers,
                                         scene.all_points, self.params, turn_stds,
                                         goal_distance)[:2]
            v_min = -self.params.reverse_speed()
        else:
            self._evader.forget()
        v, omega = self._limit(command[0], command[1], obs, v_min=v_min)
        return self._on_free_arc(obs, scene, v, omega, v_min)

    def _on_free_arc(self, obs, scene, v, omega, v_min):
        """A route follower's command ``(v, omega)``, slowed so that it can stop on its arc.

        Whatever the route following made of the scan points (beside the
        route, a person not yet tracked), the robot must be able to stop
        on the arc of the command it will drive (within the limits) clear
        of every one of them
        (:func:`~fusion_planner.core.local_planning.free_arc.free_arc_speed`),
        as far as ``max_accel`` lets it brake now; when that is not enough,
        the turn rate (within ``max_alpha``) is chosen for a free arc. The
        field followers of the paper go unchecked.
        """
        if self._route is None:
            return v, omega
        p = self.params
        safe = free_arc_speed(obs.pose, v, omega, scene.all_points, p)
        if safe == v:
            return v, omega
        reachable, _ = self._limit(safe, omega, obs, v_min=v_min)
        if abs(reachable) > abs(safe):  # it cannot brake enough on this arc: steer for a free one
            w0, dw = obs.velocity[1], p.max_alpha * p.control_period
            turns = (max(w0 - dw, -p.max_omega), min(w0 + dw, p.max_omega))
            omega = free_arc_turn(obs.pose, reachable, turns, omega, scene.all_points, p)
        return self._limit(safe, omega, obs, v_min=v_min)


def _finite_rows(rows):
    """The rows of ``rows`` (N, C) without a non-finite entry."""
    if len(rows) and not np.all(np.isfinite(rows)):
        return rows[np.all(np.isfinite(rows), axis=1)]
    return rows
