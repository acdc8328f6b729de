"""ROS 2 node wrapping the improved A* global planner (paper section 1.3).

Topics (relative names, so a namespace or a remap applies):

- ``map`` (nav_msgs/OccupancyGrid; latched or volatile reliable publishers,
  see :class:`~fusion_planner.ros.qos.LatchedOrVolatile`) in:
  converted once per map into a :class:`~fusion_planner.core.grid.GridMap`
  whose inflation and search grid are reused by every plan on it.
- ``goal_pose`` (geometry_msgs/PoseStamped) in: plans from the latest robot
  pose and publishes on ``plan``.
- ``amcl_pose`` (geometry_msgs/PoseWithCovarianceStamped, frame
  ``frame_id``; default ``pose_topic_type: pose_with_covariance``) in: the
  start pose, from the localizer; AMCL's latched pose (reliable, transient
  local) sent before the node joined is taken too. With it, ``odom``
  (nav_msgs/Odometry in ``odom_frame_id``) places scans between the
  localization poses through the map -> odom correction
  (:class:`~fusion_planner.ros.frames.Localization`).
- ``odom`` with ``pose_topic_type: odometry`` in: odometry that is already
  in ``frame_id`` (a localizer's fused output) as the start pose. ``odom`` is
  subscribed best-effort, which matches reliable and best-effort publishers
  alike (reliable in lockstep).
- ``plan`` (nav_msgs/Path, reliable, transient_local) out: the smoothed
  path; an *empty* path when planning for the current goal failed, so a
  follower stops instead of driving an old plan.
- ``plan_markers`` (visualization_msgs/MarkerArray) out: key nodes, and the
  expanded cells when ``publish_expanded`` is set.
- ``scan`` (sensor_msgs/LaserScan, best effort - reliable in lockstep -, frame ``laser_frame_id``,
  mounted at ``laser_x``, ``laser_y``, ``laser_yaw``; with ``use_tf`` its
  frame and the robot pose come from TF) in, with
  ``mark_obstacles``: obstacles the map does not show are learnt from the
  returns (marked once seen for ``obstacle_persistence``, cleared when a
  beam passes through them again; :class:`~fusion_planner.core.global_planning.obstacle_layer.ObstacleLayer`),
  placed with the odometry pose of the scan's stamp. Every plan avoids the
  confirmed ones, and a plan they block is replaced at once.
- ``get_plan`` (nav_msgs/srv/GetPlan): plans between the request's poses
  without touching ``plan``; an empty path on failure.
- ``cancel_goal`` (std_srvs/srv/Trigger): ends the current goal
  (``cancelled``); ``success`` is false when there is none.
- ``controller_outcome`` (diagnostic_msgs/DiagnosticStatus) in: how the
  local planner's run of one of this goal's plans ended.
- ``goal_outcome`` (std_msgs/String, reliable) out: exactly one outcome
  per goal (:mod:`~fusion_planner.ros.goal_outcome`); the goal is then
  forgotten and an empty plan published, so nothing resumes it.
- ``/diagnostics`` out: outcome of each request (``succeeded`` or the
  ``.outcome`` of the core error: ``start_outside_map``, ``goal_occupied``,
  ``no_valid_path``, ``timeout`` ...; ``no_map`` and ``no_start_pose`` while
  waiting), plan time and figures.

Replanning (for the current goal, until it ends) happens on a new goal, on the first start pose after a goal that
was waiting for one, when a confirmed scan obstacle comes within the robot
radius of the rest of the plan, and on a new map that leaves no valid plan
(a new map also forgets the scan obstacles): the current
plan is re-checked against the new map from the robot's position on, and a
path cell that was traversable and is not any more (or a changed map
geometry) triggers a new plan.

Lockstep (``lockstep``, set by the demo): the poses and the scan of one
simulator step are handled together, in a fixed order and on the step's
stamp (:class:`~fusion_planner.ros.lockstep.StepInputs`); a replan they cause
happens right there, synchronously, and goes out on ``plan`` with a stamp of
its own. Every step is then answered on ``plan_stamp``
(sensor_msgs/TimeReference, reliable: header stamp = the step's, ``time_ref``
= the stamp of the plan in force, an empty path before any), and the local
planner in lockstep steers that step with that plan. A plan for a new goal
or map is made when the goal or map arrives and named by the next answer;
while the simulator holds the world at t = 0 (``start_paused``) each repeated
set is answered again. The search's
``planning_time_limit`` stays a wall-time budget: a search that needs
longer on a slower machine is the one thing that can change a run.

Goal tolerance (``goal_tolerance`` for ``goal_pose``, the request's
``tolerance`` for ``get_plan``): when the goal lies in an obstacle or its
inflation, the nearest traversable cell centre within the tolerance that is
connected to the start is used instead (:func:`nearest_free_goal`).
"""

import collections
import functools
import math
from dataclasses import dataclass

import numpy as np
from geometry_msgs.msg import PoseStamped, PoseWithCovarianceStamped
from nav_msgs.msg import OccupancyGrid, Odometry, Path
from nav_msgs.srv import GetPlan
from diagnostic_msgs.msg import DiagnosticStatus
from std_msgs.msg import String
from std_srvs.srv import Trigger
from rclpy.qos import ReliabilityPolicy
from rclpy.time import Time
from scipy import ndimage
from scipy.spatial import cKDTree
from sensor_msgs.msg import LaserScan, TimeReference
from visualization_msgs.msg import Marker, MarkerArray

from fusion_planner.core import raster
from fusion_planner.core.errors import GoalOccupied, InvalidInput, PlanningError
from fusion_planner.core.grid import DEFAULT_MAX_CELLS
from fusion_planner.core.grid import GridMap
from fusion_planner.core.map_files import DEFAULT_OCCUPIED_THRESHOLD
from fusion_planner.core.global_planning.obstacle_layer import ObstacleLayer
from fusion_planner.core.global_planning.planner import (
    ALGORITHMS, GlobalPlanner, PlannerConfig, load_compiled_loops)
from fusion_planner.ros import conversions as conv
from fusion_planner.ros.diagnostics import OK, WARN, DiagnosticsReporter
from fusion_planner.ros.lifecycle import AUTOSTART_DESCRIPTION, ManagedNode
from fusion_planner.ros.goal_outcome import (
    CANCEL_SERVICE, CONTROLLER_OUTCOME_TOPIC, GOAL_OUTCOME_TOPIC, controller_outcome_from_msg)
from fusion_planner.ros.parameters import ParameterHandler, ParameterSpec, float_range, int_range
from fusion_planner.ros.qos import LATCHED_QOS, RELIABLE_QOS, LatchedOrVolatile
from fusion_planner.ros import frames
from fusion_planner.ros.frames import Localization
from fusion_planner.ros.lockstep import (
    PLAN_STAMP_TOPIC, StepInputs, pose_subscription, step_input_qos)
from fusion_planner.ros.timed_pose import pose_at
from fusion_planner.ros.node_main import run_node

NODE_NAME = 'global_planner'

#: ``pose_topic_type`` values and the topic each one subscribes.
POSE_TOPICS = {'odometry': 'odom', 'pose_with_covariance': 'amcl_pose'}


#: Largest tolerance search radius [cells]; a larger tolerance is clipped to
#: it so the search window stays (2 * 500 + 1)^2 cells at most.
MAX_TOLERANCE_CELLS = 500
#: Expanded cells drawn at most [1]; more are subsampled evenly.
MAX_EXPANDED_MARKER_POINTS = 100_000
#: Diameter of the key-node spheres [m].
KEY_NODE_MARKER_SIZE_M = 0.15
#: Poses remembered to place scans at their own time [1].
POSE_HISTORY = 50
#: Longest time a pose is moved ahead along its velocity to a scan's stamp [s].
POSE_EXTRAPOLATION_S = 0.5
#: A node-clock step backwards larger than this [s] is a clock reset.
CLOCK_JUMP_TOLERANCE_S = 1e-3
#: Period of the robot pose lookup in TF with ``use_tf`` [s].
TF_POSE_PERIOD_S = 0.1


@dataclass(frozen=True)
class GlobalPlannerParams:
    """Tunables of the global planner node (see :data:`PARAMETER_SPECS`)."""

    frame_id: str = 'map'
    pose_topic_type: str = 'pose_with_covariance'
    odom_frame_id: str = 'odom'
    algorithm: str = 'improved'
    neighbourhood: int = 8
    alpha: float = 1.0
    beta: float = 1.0
    gamma: float = PlannerConfig.gamma
    refine: bool = True
    robot_radius: float = 0.2
    safety_distance: float = 0.05
    unknown_is_occupied: bool = True
    occupied_threshold: int = DEFAULT_OCCUPIED_THRESHOLD
    max_map_cells: int = DEFAULT_MAX_CELLS
    planning_time_limit: float = 10.0
    goal_tolerance: float = 0.5
    publish_expanded: bool = False
    mark_obstacles: bool = True
    laser_frame_id: str = 'base_link'
    use_tf: bool = False
    robot_frame_id: str = 'base_link'
    laser_x: float = 0.0
    laser_y: float = 0.0
    laser_yaw: float = 0.0
    obstacle_persistence: float = 1.0
    obstacle_mark_range: float = 3.0
    obstacle_clear_range: float = 4.0
    obstacle_update_period: float = 0.2
    lockstep: bool = False
    diagnostics_period: float = 1.0
    autostart: bool = True

    def __post_init__(self):
        self.planner_config()  # the core validates algorithm, weights, radii
        if self.lockstep and self.use_tf:
            raise InvalidInput('lockstep takes the poses and scans of each step from their '
                               'topics: it cannot be combined with use_tf')

    def planner_config(self):
        """The :class:`PlannerConfig` these parameters describe."""
        return PlannerConfig(
            algorithm=self.algorithm, neighbourhood=self.neighbourhood,
            alpha=self.alpha, beta=self.beta, gamma=self.gamma, refine=self.refine,
            robot_radius=self.robot_radius, safety_distance=self.safety_distance,
            time_limit_s=self.planning_time_limit)

    def map_options(self):
        """The fields that decide how an OccupancyGrid becomes a GridMap."""
        return (self.frame_id, self.unknown_is_occupied, self.occupied_threshold,
                self.max_map_cells)

    def obstacle_layer(self, grid):
        """A new :class:`ObstacleLayer` on ``grid``, or None without ``mark_obstacles``."""
        if not self.mark_obstacles:
            return None
        return ObstacleLayer(grid, self.obstacle_persistence, self.obstacle_mark_range,
                             self.obstacle_clear_range)


#: Every parameter of the node; config/params.yaml lists the same names.
PARAMETER_SPECS = (
    ParameterSpec('frame_id', 'map', 'frame of the map, poses and plan', read_only=True),
    ParameterSpec('pose_topic_type', 'pose_with_covariance',
                  "source of the start pose: 'pose_with_covariance' (a localizer's "
                  "PoseWithCovarianceStamped on amcl_pose) or 'odometry' (nav_msgs/Odometry on "
                  'odom, already in frame_id)', read_only=True, choices=tuple(POSE_TOPICS)),
    ParameterSpec('odom_frame_id', 'odom',
                  'frame of the odometry that places scans between amcl_pose messages',
                  read_only=True),
    ParameterSpec('algorithm', 'improved',
                  "search algorithm: 'dijkstra', 'astar' (with the 8-neighbourhood: jump points, "
                  "optimal) or 'improved' (the paper's improved A*)",
                  choices=ALGORITHMS),
    ParameterSpec('neighbourhood', 8, 'search neighbourhood [cells]: 4, 8 or 16',
                  int_range(4, 16, 4)),
    ParameterSpec('alpha', 1.0, 'weight of the path cost g, eq. (5) [1]', float_range(0.01, 100.0)),
    ParameterSpec('beta', 1.0, 'weight of the heuristic h, eq. (5) [1]', float_range(0.01, 100.0)),
    ParameterSpec('gamma', PlannerConfig.gamma,
                  'gain of the distance-dependent heuristic weight, eqs. (6)-(8) [1]',
                  float_range(0.0, 100.0)),
    ParameterSpec('refine', True, 'remove redundant nodes and smooth the path (section 1.3.3)'),
    ParameterSpec('robot_radius', 0.2, 'robot radius; obstacles are inflated by it [m]',
                  float_range(0.0, 10.0)),
    ParameterSpec('safety_distance', 0.05,
                  'extra distance a shortcut keeps from obstacles (section 1.3.3) [m]',
                  float_range(0.0, 10.0)),
    ParameterSpec('unknown_is_occupied', True, 'treat unknown map cells (-1) as obstacles'),
    ParameterSpec('occupied_threshold', DEFAULT_OCCUPIED_THRESHOLD,
                  'a map value at or above this is an obstacle [percent]', int_range(1, 100)),
    ParameterSpec('max_map_cells', DEFAULT_MAX_CELLS,
                  'maps with more cells are refused [cells]', int_range(1, 400_000_000)),
    ParameterSpec('planning_time_limit', 10.0, 'wall-time budget of one search [s]',
                  float_range(0.001, 600.0)),
    ParameterSpec('goal_tolerance', 0.5,
                  'a goal_pose in an obstacle moves to the nearest free cell within this [m]',
                  float_range(0.0, 100.0)),
    ParameterSpec('publish_expanded', False, 'draw the expanded cells on plan_markers'),
    ParameterSpec('mark_obstacles', True,
                  'learn obstacles the map does not show from scan and plan around them',
                  read_only=True),
    ParameterSpec('laser_frame_id', 'base_link', 'frame of the scan', read_only=True),
    ParameterSpec('use_tf', False,
                  'take the robot pose (map -> robot_frame_id) and the laser pose from TF (needs '
                  'tf2_ros, a full ROS install) instead of amcl_pose or odom and the laser_* '
                  'parameters', read_only=True),
    ParameterSpec('robot_frame_id', 'base_link', 'robot frame, looked up in TF with use_tf',
                  read_only=True),
    ParameterSpec('laser_x', 0.0, 'laser position ahead of the robot centre, robot frame [m]',
                  float_range(-10.0, 10.0), read_only=True),
    ParameterSpec('laser_y', 0.0, 'laser position left of the robot centre, robot frame [m]',
                  float_range(-10.0, 10.0), read_only=True),
    ParameterSpec('laser_yaw', 0.0, 'laser heading in the robot frame [rad]',
                  float_range(-math.pi, math.pi), read_only=True),
    ParameterSpec('obstacle_persistence', 1.0,
                  'a scan return must stay in its cell this long to become an obstacle [s]',
                  float_range(0.0, 60.0), read_only=True),
    ParameterSpec('obstacle_mark_range', 3.0, 'scan returns farther than this are not marked [m]',
                  float_range(0.1, 100.0), read_only=True),
    ParameterSpec('obstacle_clear_range', 4.0, 'beams clear the cells they cross up to this [m]',
                  float_range(0.1, 100.0), read_only=True),
    ParameterSpec('obstacle_update_period', 0.2,
                  'scans closer in time than this to the last one used are skipped [s]',
                  float_range(0.0, 10.0)),
    ParameterSpec('lockstep', False,
                  "handle each step's amcl_pose, odom and scan together (one stamp, from a "
                  'simulator in lockstep), on its stamp, and name the plan in force after each '
                  'step on plan_stamp, so a local planner in lockstep steers each step with the '
                  'plan made on it', read_only=True),
    ParameterSpec('diagnostics_period', 1.0,
                  'period of the diagnostics heartbeat; 0 publishes on events only [s]',
                  float_range(0.0, 60.0), read_only=True),
    ParameterSpec('autostart', True, AUTOSTART_DESCRIPTION, read_only=True),
)


def nearest_free_goal(grid, traversable, goal, tolerance, components=None, start_cell=None):
    """The traversable cell centre nearest to ``goal`` within ``tolerance``.

    Parameters
    ----------
    grid : GridMap
    traversable : ndarray, bool, shape (H, W)
        Cells the robot centre may occupy (``grid.traversable(radius)``).
    goal : array_like, shape (2,)
        ``(x, y)`` [m], map frame, inside the map.
    tolerance : float
        Largest distance [m] the goal may move, >= 0; searched over at most
        :data:`MAX_TOLERANCE_CELLS` cells around the goal.
    components : ndarray, int, shape (H, W), optional
        4-connected component labels of ``traversable`` (0 = blocked). With
        ``start_cell``, only cells of the start's component are candidates,
        so the new goal is reachable.
    start_cell : tuple of int, optional
        ``(row, col)`` of the start.

    Returns
    -------
    ndarray, float64, shape (2,) or None
        The cell centre [m], map frame; None when no candidate lies within
        the tolerance.

    Notes
    -----
    Vectorised over a square window of cells around the goal: distances are
    measured between the goal and cell centres in grid units (cells are
    square, so the map's rotation does not matter). Components are
    4-connected because the search never cuts corners: a diagonal or knight
    step needs the cells it crosses free, so it connects nothing that
    orthogonal steps do not.
    """
    col_f, row_f = grid.world_to_grid(np.asarray(goal, dtype=float))
    reach = min(int(math.ceil(tolerance / grid.resolution)) + 1, MAX_TOLERANCE_CELLS)
    r0, c0 = int(math.floor(row_f)), int(math.floor(col_f))
    rows = slice(max(r0 - reach, 0), min(r0 + reach + 1, grid.height))
    cols = slice(max(c0 - reach, 0), min(c0 + reach + 1, grid.width))
    rr = np.arange(rows.start, rows.stop)[:, None]
    cc = np.arange(cols.start, cols.stop)[None, :]
    dist = grid.resolution * np.hypot(rr + 0.5 - row_f, cc + 0.5 - col_f)
    ok = traversable[rows, cols] & (dist <= tolerance)
    if components is not None and start_cell is not None:
        label = components[start_cell]
        if label > 0:
            ok &= components[rows, cols] == label
    if not ok.any():
        return None
    flat = np.flatnonzero(ok.ravel())
    best = flat[np.argmin(dist.ravel()[flat])]
    r, c = divmod(int(best), ok.shape[1])
    return grid.world_of(np.array([rows.start + r, cols.start + c]))


class GlobalPlannerNode(ManagedNode):
    """The global planner node (see the module docstring for its interface).

    A lifecycle node (:class:`~fusion_planner.ros.lifecycle.ManagedNode`):
    inactive, it refuses goals and plans; deactivating it cancels the
    current goal.

    Parameters
    ----------
    node_name : str
    **kwargs
        Passed to :class:`rclpy.node.Node` (``context``, ``namespace``,
        ``parameter_overrides``, ``cli_args`` ...).

    Raises
    ------
    InvalidInput
        If the start-up parameters are out of range or inconsistent.
    """

    def __init__(self, node_name=NODE_NAME, tf_buffer=None, **kwargs):
        super().__init__(node_name, **kwargs)
        self._tf_buffer = tf_buffer  # with use_tf: this buffer instead of a tf2_ros one
        self._tf = None
        self._params = ParameterHandler(self, GlobalPlannerParams, PARAMETER_SPECS)
        params = self._params.current
        self._frame_id = params.frame_id
        # lockstep: the node's time, from 0 on the stamp of the last step's set [ns]
        self._step_time_ns = 0 if params.lockstep else None
        self._diagnostics = DiagnosticsReporter(self, params.diagnostics_period,
                                                stamp=self._now)
        self._diagnostics.update(WARN, 'unconfigured')
        self.start(params.autostart)

    def configure(self):
        """Fresh state; the publishers, subscriptions and services."""
        params = self._params.current
        load_s = load_compiled_loops(params.planner_config())
        self.get_logger().debug(f'compiled loops of the planner loaded in {load_s:.3f} s')
        # Map state: the accepted message (kept to rebuild on a parameter
        # change), the options it was converted with, its planner.
        self._map_msg = None
        self._map_options = None
        self._planner = None
        self._components = None  # (radius, labels) of the traversable mask
        self._start = None  # (x, y, yaw) [m, m, rad]
        self._goal = None  # (x, y, yaw) of the current goal_pose goal, None once it ended
        self._goal_plan_stamps = set()  # stamps of the plans published for it [ns]
        self._waiting = False  # the current goal waits for a map or a start pose
        self._plan = None  # (N, 2) published plan, None when none is valid
        self._layer = None  # ObstacleLayer of the scans on the current map
        self._marked_planner = None  # planner on the map plus confirmed scan obstacles
        self._poses = collections.deque(maxlen=POSE_HISTORY)  # (stamp, pose, velocity)
        self._localization = Localization(POSE_EXTRAPOLATION_S)
        self._last_now = -math.inf  # latest node-clock time seen [s]
        self._plan_stamp_ns = None  # stamp of the last plan or empty path published [ns]
        self._waiting_step = None  # lockstep: (stamp [ns], messages) of a step awaiting the map
        self._layer_updated = -math.inf  # node-clock time of the last scan used [s]

        guard = self._diagnostics.guard
        self._plan_pub = self.create_lifecycle_publisher(Path, 'plan', LATCHED_QOS)
        self._markers_pub = self.create_lifecycle_publisher(MarkerArray, 'plan_markers',
                                                            RELIABLE_QOS)
        self._map_sub = LatchedOrVolatile(self, OccupancyGrid, 'map', guard('map', self._on_map),
                                          ReliabilityPolicy.RELIABLE)
        self.create_subscription(PoseStamped, 'goal_pose', guard('goal_pose', self._on_goal),
                                 RELIABLE_QOS)
        if params.use_tf:
            self._tf = frames.TfSource(self._tf_buffer) if self._tf_buffer is not None \
                else frames.make_tf_source(self)
            self.create_timer(TF_POSE_PERIOD_S, guard('tf', self._on_tf_timer))
        self._input_handlers = self._step_input_handlers(params)
        handlers = self._input_handlers
        if params.lockstep:
            self._plan_stamp_pub = self.create_lifecycle_publisher(
                TimeReference, PLAN_STAMP_TOPIC, RELIABLE_QOS)
            self._inputs = StepInputs(handlers, self._on_step_inputs, self._answer_step)
            handlers = {name: functools.partial(self._inputs.add, name) for name in handlers}
        if 'odom' in handlers:
            self.create_subscription(Odometry, 'odom', guard('odom', handlers['odom']),
                                     step_input_qos(params.lockstep))
        if 'amcl_pose' in handlers:
            self._pose_sub = pose_subscription(
                self, PoseWithCovarianceStamped, POSE_TOPICS['pose_with_covariance'],
                guard('amcl_pose', handlers['amcl_pose']), params.lockstep)
        if 'scan' in handlers:
            self.create_subscription(LaserScan, 'scan', guard('scan', handlers['scan']),
                                     step_input_qos(params.lockstep))
        self.create_service(GetPlan, 'get_plan',
                            guard('get_plan', self._on_get_plan, on_error=self._empty_response))
        self._outcome_pub = self.create_lifecycle_publisher(String, GOAL_OUTCOME_TOPIC,
                                                            RELIABLE_QOS)
        self.create_subscription(DiagnosticStatus, CONTROLLER_OUTCOME_TOPIC,
                                 guard('controller_outcome', self._on_controller_outcome),
                                 RELIABLE_QOS)
        self.create_service(Trigger, CANCEL_SERVICE,
                            guard('cancel_goal', self._on_cancel, on_error=self._cancel_refused))
        self._diagnostics.update(WARN, 'waiting for a map', last_outcome='no_map')

    def cleanup(self):
        """The TF listener goes with the other entities."""
        self._tf = None

    def deactivate(self):
        """The current goal ends ``cancelled`` while the publishers still publish."""
        if self._goal is not None:
            self._end_goal('cancelled', 'the node was deactivated')
        self._diagnostics.update(WARN, 'inactive')

    def _step_input_handlers(self, params):
        """The pose and scan inputs and their callbacks, in the order a lockstep set is handled.

        Odometry first (it places scans between localization poses), the scan
        last (it is placed with both). None with ``use_tf`` (poses from TF).
        """
        handlers = {}
        from_topics = not params.use_tf  # else the poses come from the TF timer
        if from_topics and params.pose_topic_type == 'odometry':
            handlers['odom'] = self._on_odometry
        elif from_topics:
            if params.mark_obstacles:
                handlers['odom'] = self._on_wheel_odometry
            handlers['amcl_pose'] = self._on_pose_with_covariance
        if params.mark_obstacles:
            handlers['scan'] = self._on_scan
        return handlers

    # -- callbacks ------------------------------------------------------------

    def _on_step_inputs(self, stamp_ns, messages):
        """Lockstep: take a step's set in order on its stamp, then answer with the plan.

        The first step waits for the map (latched, so its arrival time
        varies): scans count from the same step in every run.
        """
        if self._map_msg is None:
            self._waiting_step = (stamp_ns, messages)
            return
        self._waiting_step = None
        self._step_time_ns = stamp_ns
        guard = self._diagnostics.guard
        for name, msg in zip(self._inputs.names, messages):
            # a refused message is reported and the step goes on without it
            guard(name, self._input_handlers[name])(msg)
        self._answer_step(stamp_ns)

    def _answer_step(self, stamp_ns):
        """Lockstep: name the plan in force (an empty path before any) on ``plan_stamp``."""
        if self._waiting_step is not None:
            return  # that step is not handled yet
        if self._plan_stamp_ns is None:
            self._publish_plan(self._empty_path())
        msg = TimeReference(source=self.get_fully_qualified_name())
        msg.header.stamp = Time(nanoseconds=stamp_ns).to_msg()
        msg.time_ref = Time(nanoseconds=self._plan_stamp_ns).to_msg()
        self._plan_stamp_pub.publish(msg)

    def _publish_plan(self, msg):
        """Publish a plan or an empty path; in lockstep each with a stamp of its own.

        Two plans of one step (a goal and a map in the same step) are told
        apart by the later one's stamp being a nanosecond later.
        """
        stamp_ns = conv.stamp_to_nanoseconds(msg.header.stamp)
        if self._params.current.lockstep and self._plan_stamp_ns is not None:
            stamp_ns = max(stamp_ns, self._plan_stamp_ns + 1)
            msg.header.stamp = Time(nanoseconds=stamp_ns).to_msg()
        self._plan_stamp_ns = stamp_ns
        if msg.poses:
            self._goal_plan_stamps.add(stamp_ns)
        self._plan_pub.publish(msg)

    def _on_map(self, msg):
        """Accept a new map; replan when the current plan does not survive it."""
        if self._same_map(msg):
            return
        old = self._planner
        params = self._params.current
        prepare_s = self._load_map(msg, params)
        self.get_logger().info(
            f'map {msg.info.width} x {msg.info.height} cells at {msg.info.resolution:g} m accepted, '
            f'prepared for planning in {prepare_s:.3f} s')
        if self._waiting_step is not None:
            self._on_step_inputs(*self._waiting_step)
        if self._goal is None:
            self._diagnostics.update(WARN, 'map accepted; waiting for a goal',
                                     map_cells=msg.info.width * msg.info.height)
            return
        if self._plan is None or not self._plan_survives(old, params.robot_radius):
            self._replan('map')

    def _on_goal(self, msg):
        """Plan to a new goal; one still active ends ``preempted``.

        The active goal's pose again (a sender's retry, whatever its stamp)
        is the same goal: it is planned for anew and goes on.
        """
        goal = conv.pose_stamped_to_xy_yaw(msg, self._frame_id, 'goal')
        if not self.active:
            self._diagnostics.log.warning('goal_pose/inactive',
                                          'goal_pose ignored: the node is inactive')
            return
        if self._goal is not None and tuple(goal) == tuple(self._goal):
            self.get_logger().info('the active goal received again: replanning for it')
        elif self._goal is not None:
            self._end_goal('preempted', 'a newer goal arrived', stop=False)
        self._goal = goal
        self._check_clock()
        self._replan('goal_pose')

    def _on_cancel(self, request, response):
        """Serve ``cancel_goal``: the current goal ends ``cancelled``, the robot stops."""
        if self._goal is None:
            response.success, response.message = False, 'no goal to cancel'
            return response
        self._end_goal('cancelled', 'cancel_goal was called')
        response.success, response.message = True, 'goal cancelled'
        return response

    def _cancel_refused(self, request, response):
        response.success, response.message = False, 'cancel failed: see the diagnostics'
        return response

    def _on_controller_outcome(self, msg):
        """End the goal when the local planner's run of one of its plans ended."""
        outcome, plan_stamp, reason = controller_outcome_from_msg(msg)
        if self._goal is None or plan_stamp not in self._goal_plan_stamps:
            return  # the run of an older goal's plan
        self._end_goal(outcome, reason)

    def _end_goal(self, outcome, reason, stop=True):
        """Publish, log and report the current goal's one outcome, then forget the goal.

        With ``stop`` an empty plan goes out, so a follower stops and a late
        one does not drive the latched old plan.
        """
        goal = self._goal
        self._goal = None
        self._goal_plan_stamps.clear()
        self._waiting = False
        if stop:
            self._plan = None
            self._publish_plan(self._empty_path())
        self._outcome_pub.publish(String(data=outcome))
        line = f'goal ({goal[0]:.2f}, {goal[1]:.2f}) ended: {outcome}' + (
            f' ({reason})' if reason else '')
        if outcome in ('reached', 'cancelled', 'preempted'):
            self.get_logger().info(line)
        else:
            self.get_logger().warning(line)
        self._diagnostics.update(OK if outcome == 'reached' else WARN, line, goal_outcome=outcome)

    def _on_odometry(self, msg):
        pose = conv.odometry_to_xy_yaw(msg, self._frame_id, 'odometry')
        self._set_start(pose, msg.header.stamp, conv.odometry_to_velocity(msg, 'odometry'))

    def _on_pose_with_covariance(self, msg):
        pose = conv.pose_with_covariance_to_xy_yaw(msg, self._frame_id, 'amcl_pose')
        self._localization.add_localization(conv.stamp_to_seconds(msg.header.stamp), pose)
        self._set_start(pose, msg.header.stamp, (0.0, 0.0))

    def _on_wheel_odometry(self, msg):
        """Odometry in the odom frame: places scans between localization poses."""
        pose = conv.odometry_to_xy_yaw(msg, self._params.current.odom_frame_id, 'odom')
        self._localization.add_odometry(conv.stamp_to_seconds(msg.header.stamp), pose,
                                        conv.odometry_to_velocity(msg, 'odom'))

    def _set_start(self, pose, stamp, velocity):
        self._check_clock()
        self._start = pose
        t = conv.stamp_to_seconds(stamp)
        if self._poses and t < self._poses[-1][0]:
            self._poses.clear()  # stamps went back (a simulation reset)
        self._poses.append((t, np.array(pose), np.array(velocity, dtype=float)))
        if self._waiting and self._map_msg is not None:
            self._replan('start pose')

    def _on_scan(self, msg):
        """Mark and clear scan obstacles; replan when they block the plan."""
        self._check_clock()
        if self._layer is None or not self._poses:
            return  # no map to mark on, or no pose to place the beams with
        params = self._params.current
        frame = msg.header.frame_id if self._tf is not None else params.laser_frame_id
        conv.check_scan_header(msg, frame, 'scan')  # a bad scan is refused even when not used
        now = self._now_s()
        if now - self._layer_updated < params.obstacle_update_period:
            return  # persistence is measured in seconds: every scan is not needed
        stamp = conv.stamp_to_seconds(msg.header.stamp)
        if self._tf is not None:
            laser = self._tf.scan_pose(params.frame_id, frame)
            pose = self._poses[-1][1]
        else:
            pose = self._localization.map_pose_at(stamp) if stamp > 0 else None
            if pose is None:
                pose = pose_at(self._poses, stamp, POSE_EXTRAPOLATION_S) if stamp > 0 \
                    else self._poses[-1][1]
            laser = frames.compose(pose, (params.laser_x, params.laser_y, params.laser_yaw))
        ends, hit = conv.scan_to_rays(msg, tuple(laser), frame, 'scan')
        self._layer_updated = now
        if not self._layer.update(pose[:2], ends, hit, now):
            return
        self._marked_planner = None
        self._components = None
        if self._plan is not None and self._goal is not None and self._plan_blocked():
            self.get_logger().info('scan obstacles block the plan: replanning')
            self._replan('scan obstacle')

    def _on_get_plan(self, request, response):
        """Serve nav_msgs/srv/GetPlan; the published plan is left alone."""
        response.plan = self._empty_path()
        if not self.active:
            self._diagnostics.log.warning('get_plan/inactive',
                                          'get_plan answered empty: the node is inactive')
            return response
        try:
            start = conv.pose_stamped_to_xy_yaw(request.start, self._frame_id, 'start')
            goal = conv.pose_stamped_to_xy_yaw(request.goal, self._frame_id, 'goal')
            tolerance = float(request.tolerance)
            if not (math.isfinite(tolerance) and tolerance >= 0):
                raise InvalidInput(
                    f'tolerance must be a non-negative number of metres, got {tolerance!r}')
            if self._ensure_planner() is None:
                self._diagnostics.update(WARN, 'get_plan: no map received yet',
                                         last_outcome='no_map')
                return response
            result, used_goal = self._plan_to(start, goal, tolerance)
        except PlanningError as err:
            self._diagnostics.failed(err, 'get_plan')
            return response
        response.plan = conv.path_to_msg(result.path, self._frame_id, self._now(), goal[2])
        self._report_success('get_plan', result, goal, used_goal)
        return response

    def _check_clock(self):
        """After the node clock jumped back (a simulation reset), forget timed state.

        The start pose and the scan obstacles belong to the old timeline: the
        next plan waits for fresh odometry rather than start from where the
        robot was before the reset.
        """
        now = self._now_s()
        if now < self._last_now - CLOCK_JUMP_TOLERANCE_S:
            self.get_logger().warning(
                f'clock jumped back from {self._last_now:.3f} s to {now:.3f} s: '
                'waiting for a fresh start pose')
            self._start = None
            self._poses.clear()
            self._localization.clear()
            self._layer_updated = -math.inf
            if self._layer is not None:
                self._layer.reset()
                self._marked_planner = None
                self._components = None
        self._last_now = now

    # -- planning ---------------------------------------------------------------

    def _on_tf_timer(self):
        """With ``use_tf``: the robot pose from TF; a goal waiting for it is planned."""
        params = self._params.current
        pose = self._tf.planar(params.frame_id, params.robot_frame_id)
        if pose is not None:
            self._set_start(pose, self.get_clock().now().to_msg(), (0.0, 0.0))

    def _replan(self, trigger):
        """Plan from the robot to the current goal; publish the plan or an empty one."""
        if self._ensure_planner() is None:
            self._waiting = True
            self._diagnostics.update(WARN, f'{trigger}: waiting for a map', last_outcome='no_map')
            return
        if self._start is None:
            self._waiting = True
            self._diagnostics.update(WARN, f'{trigger}: waiting for a start pose',
                                     last_outcome='no_start_pose')
            return
        self._waiting = False
        goal = self._goal
        try:
            result, used_goal = self._plan_to(
                self._start, goal, self._params.current.goal_tolerance)
        except Exception as err:  # noqa: BLE001 - re-raised below unless a planning outcome
            if not isinstance(err, PlanningError):
                self._plan = None
                self._publish_plan(self._empty_path())  # followers stop
                raise  # a bug: the callback guard logs it and reports a fault
            self._diagnostics.failed(err, trigger)
            self._end_goal('no_path', f'{err.outcome}: {err}')
            return
        self._plan = result.path
        self._publish_plan(conv.path_to_msg(result.path, self._frame_id, self._now(), goal[2]))
        self._markers_pub.publish(self._markers(result))
        self._report_success(trigger, result, goal, used_goal)

    def _plan_to(self, start, goal, tolerance):
        """Plan with goal tolerance; returns ``(PlanResult, goal used (2,))``."""
        planner = self._ensure_planner()
        goal_xy = np.array(goal[:2])
        try:
            planner.cells_of(start[:2], goal_xy)
        except GoalOccupied:
            if tolerance <= 0:
                raise
            goal_xy = self._free_goal_near(planner, start, goal_xy, tolerance)
        result = planner.plan(start[:2], goal_xy,
                              return_expanded=self._params.current.publish_expanded)
        return result, goal_xy

    def _free_goal_near(self, planner, start, goal_xy, tolerance):
        grid = planner.grid
        radius = planner.config.robot_radius
        traversable = grid.traversable(radius)
        if self._components is None or self._components[0] != radius:
            self._components = (radius, ndimage.label(traversable)[0])
        start_cell = tuple(int(v) for v in grid.cell_of(np.array(start[:2])))
        found = nearest_free_goal(grid, traversable, goal_xy, tolerance,
                                  self._components[1], start_cell)
        if found is None:
            raise GoalOccupied(
                f'goal ({goal_xy[0]:.3f}, {goal_xy[1]:.3f}) is in an obstacle and no reachable '
                f'free cell lies within the tolerance of {tolerance:g} m')
        return found

    def _ensure_planner(self):
        """The planner on the current map and scan obstacles with the current parameters.

        None without a map. Applies parameter changes lazily, in the
        executor's thread: map options rebuild the grid from the kept
        message, the rest reconfigure the planner (keeping the map
        preparation). With confirmed scan obstacles, the planner works on a
        copy of the map with them burnt in, prepared once per change.
        """
        if self._map_msg is None:
            return None
        params = self._params.current
        if params.map_options() != self._map_options:
            self._load_map(self._map_msg, params)
        config = params.planner_config()
        if self._planner.config != config:
            self._planner.config = config
        if self._layer is None or not len(self._layer.confirmed_cells()):
            return self._planner
        if self._marked_planner is None:
            grid = self._planner.grid
            marked = GridMap(self._layer.occupied(), grid.resolution, grid.origin)
            self._marked_planner = GlobalPlanner(marked, config)
        elif self._marked_planner.config != config:
            self._marked_planner.config = config
        return self._marked_planner

    def _load_map(self, msg, params):
        """Convert, cache and prepare a map; return the preparation time [s].

        The preparation (inflation, search grid, compiled search loop) is
        done here, once per map, so that plans pay for the search alone.
        MapError leaves the previous map in place.
        """
        try:
            grid = conv.occupancy_grid_to_grid_map(
                msg, self._frame_id, params.unknown_is_occupied,
                params.occupied_threshold, params.max_map_cells)
        except PlanningError:
            if msg is self._map_msg:  # the kept map no longer passes: drop it
                self._map_msg = self._planner = None
            raise
        self._map_msg = msg
        self._map_options = params.map_options()
        self._planner = GlobalPlanner(grid, params.planner_config())
        self._layer = params.obstacle_layer(grid)
        self._marked_planner = None
        self._components = None
        return self._planner.prepare()

    def _same_map(self, msg):
        """Whether ``msg`` repeats the current map (e.g. a latched republish)."""
        old = self._map_msg
        if old is None:
            return False
        a, b = old.info, msg.info
        if (old.header.frame_id, a.width, a.height, a.resolution, a.origin, len(old.data)) != \
                (msg.header.frame_id, b.width, b.height, b.resolution, b.origin, len(msg.data)):
            return False
        return bool(np.array_equal(np.frombuffer(old.data, np.int8), np.frombuffer(msg.data, np.int8)))

    def _plan_blocked(self):
        """Whether a confirmed scan obstacle lies within the robot radius of the rest of the plan.

        Cell-centre distances, as the planner's inflation measures them.
        """
        confirmed = self._layer.confirmed_cells()
        if not len(confirmed):
            return False
        grid = self._planner.grid
        cells = raster.path_cells(grid, self._remaining_plan())
        reach = self._params.current.robot_radius / grid.resolution
        distance, _ = cKDTree(confirmed).query(cells, distance_upper_bound=reach + 1e-9)
        return bool(np.isfinite(distance).any())

    def _remaining_plan(self):
        """The current plan from its point nearest the robot on."""
        path = self._plan
        if self._start is not None and len(path) > 1:
            nearest = int(np.argmin(np.hypot(*(path - np.array(self._start[:2])).T)))
            path = path[nearest:]
        return path

    def _plan_survives(self, old_planner, radius):
        """Whether the rest of the current plan is still traversable on the new map.

        A cell that was not traversable on the old map either (e.g. a start in
        the inflation) does not count against the plan.
        """
        new_grid = self._planner.grid
        cells = raster.path_cells(new_grid, self._remaining_plan())
        ok = _traversable_at(new_grid, cells, radius)
        if ok.all():
            return True
        old_grid = None if old_planner is None else old_planner.grid
        if old_grid is None or old_grid.shape != new_grid.shape \
                or old_grid.resolution != new_grid.resolution or old_grid.origin != new_grid.origin:
            return False
        was_ok = _traversable_at(old_grid, cells, radius)
        return not np.any(was_ok & ~ok)

    # -- output -----------------------------------------------------------------

    def _report_success(self, what, result, goal, used_goal):
        m = result.metrics
        moved = float(np.hypot(used_goal[0] - goal[0], used_goal[1] - goal[1]))
        self._diagnostics.succeeded(
            f'{what}: plan of {m.length_m:.2f} m in {m.time_s * 1e3:.1f} ms',
            last_error='', plan_time_s=m.time_s, path_length_m=m.length_m,
            expanded=m.expanded, key_points=m.key_points, min_clearance_m=m.min_clearance_m,
            goal_moved_m=moved, scan_obstacle_cells=self._scan_obstacle_cells())

    def _scan_obstacle_cells(self):
        """Confirmed scan obstacle cells the plans avoid [1]."""
        return 0 if self._layer is None else len(self._layer.confirmed_cells())

    def _markers(self, result):
        stamp = self._now()
        markers = [conv.delete_all_marker(self._frame_id, stamp),
                   conv.points_marker(result.key_nodes, self._frame_id, stamp, 'key_nodes',
                                      Marker.SPHERE_LIST, KEY_NODE_MARKER_SIZE_M)]
        cells = result.expanded_cells
        if cells is not None and len(cells):
            step = max(1, -(-len(cells) // MAX_EXPANDED_MARKER_POINTS))
            grid = self._planner.grid
            markers.append(conv.points_marker(
                grid.world_of(cells[::step]), self._frame_id, stamp, 'expanded',
                Marker.CUBE_LIST, grid.resolution, rgba=(0.9, 0.8, 0.2, 0.4)))
        return MarkerArray(markers=markers)

    def _empty_path(self):
        msg = Path()
        msg.header.frame_id = self._frame_id
        msg.header.stamp = self._now()
        return msg

    def _empty_response(self, request, response):
        response.plan = self._empty_path()
        return response

    def _now_ns(self):
        """The node's time [ns]: the node clock's, in lockstep the stamp of the last step."""
        if self._step_time_ns is not None:
            return self._step_time_ns
        return self.get_clock().now().nanoseconds

    def _now(self):
        return Time(nanoseconds=self._now_ns()).to_msg()

    def _now_s(self):
        return self._now_ns() * 1e-9


def _traversable_at(grid, cells, radius):
    """Bool per ``(row, col)``: inside the grid and traversable for ``radius``."""
    inside = grid.contains(cells)
    ok = np.zeros(len(cells), dtype=bool)
    rc = cells[inside]
    ok[inside] = grid.traversable(radius)[rc[:, 0], rc[:, 1]]
    return ok


def main(args=None):
    """Run the global planner node until Ctrl-C or shutdown; returns the exit code."""
    return run_node(GlobalPlannerNode, NODE_NAME, args)


if __name__ == '__main__':
    raise SystemExit(main())
