"""ROS 2 node wrapping the fusion local planner (paper section 3.3).

The node is an adapter around :func:`fusion_planner.core.local_planning.follow.make_controller`:
it turns the global plan, odometry, laser scans and tracked moving obstacles
into a :class:`~fusion_planner.core.local_planning.follow.Observation`, calls the
controller at a fixed rate on the node clock (sim time under
``use_sim_time``), and publishes the command.

Topics (relative names, so a namespace or a remap applies):

- ``plan`` (nav_msgs/Path; latched or volatile publishers, see
  :class:`~fusion_planner.ros.qos.LatchedOrVolatile`) in: the global plan. Its key nodes become the APF sub-goals: the plan arrives smoothed,
  so they are recovered as the corners its arcs rounded
  (:func:`key_nodes_of`). An *empty* path means "no
  plan": the robot stops. The same plan again (a latched republish) keeps
  the controller's state.
- ``odom`` (nav_msgs/Odometry, header frame = ``odom_frame_id``, best
  effort: reliable and best-effort publishers match; reliable in lockstep) in: pose and measured
  velocity. The robot is controlled in this frame (REP-105: smooth, but
  drifting). The pose is moved ahead along the measured velocity from its
  stamp to the control step (:func:`~fusion_planner.ros.timed_pose.pose_at`),
  which compensates the delay of a message that arrived a step late.
- ``amcl_pose`` (geometry_msgs/PoseWithCovarianceStamped, frame
  ``frame_id``; latched or volatile publishers) in, unless the odometry is
  already in ``frame_id``: the map -> odom correction, from the pose and
  the odometry at the pose's stamp (:class:`~fusion_planner.ros.frames.Localization`).
  Each plan (map frame) is brought into the odom frame with the correction
  of its arrival; later corrections (the odometry's drift since) are applied
  to the robot pose, scans and obstacles the controller sees, so the plan
  and the controller's state stay put. Until the first pose the robot
  stands still (``no_localization``).
- ``scan`` (sensor_msgs/LaserScan, best effort - reliable in lockstep -, frame ``laser_frame_id``,
  mounted at ``laser_x``, ``laser_y``, ``laser_yaw`` on the robot) in:
  obstacle points, placed in the odom frame with the odometry pose of the
  scan's stamp (:meth:`LocalPlannerNode._on_scan`, the one place where
  obstacles come in), and the moving obstacles: a scan tracker
  (:class:`~fusion_planner.ros.scan_tracks.ScanTracks`, map frame, laser
  placed with the map -> odom correction) follows the returns the map does
  not explain and reports the ones that move. A valid scan the tracker
  cannot use (no localization yet, stamped more than ``scan_timeout``
  before the latest odometry, not newer than the last tracked one, without
  beams) is not tracked; why is logged (rate-limited) and kept in the
  diagnostics value ``scan_tracking``.
- ``map`` (nav_msgs/OccupancyGrid, latched or volatile publishers) in: the
  known map the fusion controller replans on, with the obstacles it has
  scanned, when it is stuck (:class:`~fusion_planner.core.local_planning.replanning.GridReplanner`,
  as in the simulation); without a map it recovers without replanning. The
  scan tracker tells people from walls with it too: no scan tracks until it
  arrives.
- ``obstacles`` (visualization_msgs/MarkerArray of id-stable cylinders,
  ``frame_id``) in, optional: moving obstacles tracked elsewhere, brought
  into the odom frame; velocities are estimated from successive positions
  (:class:`~fusion_planner.ros.conversions.ObstacleTracker`). Fused with the
  scan tracks: an obstacle from here replaces a scan track it overlaps.
- ``tracks`` (visualization_msgs/MarkerArray, ``frame_id``) out with each
  tracked scan: the scan tracker's moving tracks, a cylinder and a velocity
  arrow each.
- ``cmd_vel`` (geometry_msgs/Twist, or TwistStamped with
  ``enable_stamped_cmd_vel``, reliable) out, at ``control_rate`` on the node
  clock while a plan is followed. A TwistStamped carries the stamp of the
  odometry the step used (the sensor data it answers), so a simulator can
  tell which step a command belongs to. Idle (no plan, or the plan ended:
  arrived, failed, no path) the node publishes one zero command and then
  nothing, so it does not fight a teleop or keep a twist_mux input alive;
  ``publish_zero_when_idle`` keeps a zero command at ``control_rate``.
- ``local_plan`` (nav_msgs/Path, ``frame_id``) out: the controller's
  short field rollout, computed only while the topic has a subscriber.
- ``controller_outcome`` (diagnostic_msgs/DiagnosticStatus) out, once per
  plan whose run ended: ``reached``, ``no_path`` (replanning proved the goal
  unreachable) or ``controller_failed``, with the plan's stamp
  (:mod:`~fusion_planner.ros.goal_outcome`); also logged once and on
  diagnostics as ``last_outcome``.
- ``/diagnostics`` out: controller status, arrival, failure with its reason,
  stuck events, stale inputs, step timing.

Lockstep (``lockstep``, set by the demo): instead of a timer, the node
computes once per complete set of ``odom``, ``amcl_pose``, ``scan``,
``obstacles`` and ``plan_stamp`` (sensor_msgs/TimeReference) messages with
one stamp (a simulator and a global planner in lockstep publish one of each
per step), handled in that order
(:class:`~fusion_planner.ros.lockstep.StepInputs`), followed by the plan
``plan_stamp`` names (waited for if it has not arrived yet; so is the
``map``, before the first step; at t = 0, the world held until a first
plan, only the inputs are taken), and the node's time is
that stamp: odometry and scans are never stale, the controller's progress and
escape timers run on simulated steps, and the TwistStamped command carries
the stamp the simulator waits for. A run then depends on the messages only,
not on their arrival order or the machine's speed. Idle, the node is silent
as usual, and the simulator holds the world until its ``lockstep_timeout``.

Safety policy (DESIGN.md, Errors): the command is exactly zero with no plan,
on arrival, after a controller failure, when odometry is older than
``odom_timeout``, when the plan's publisher has been gone for longer than
``plan_timeout``, when the node clock jumps backwards (until fresh data
arrives), after an internal error, and - with ``on_stale_scan: stop`` - when
the last scan is older than ``scan_timeout`` (``slow`` caps the speed at
``stale_scan_speed`` instead and keeps steering with the last scan). A
command never exceeds ``max_speed`` or ``max_omega``, whatever the measured
velocity the controller brakes from. Every refused message is one
rate-limited log line and a diagnostics entry; the node never dies on a
message.
"""

import functools
import math
import threading
import time
from dataclasses import field as dataclass_field
from dataclasses import fields, make_dataclass

import numpy as np
from diagnostic_msgs.msg import DiagnosticStatus
from geometry_msgs.msg import PoseWithCovarianceStamped, Twist, TwistStamped
from nav_msgs.msg import OccupancyGrid, Odometry, Path
from rclpy.qos import ReliabilityPolicy
from rclpy.time import Time
from sensor_msgs.msg import LaserScan, TimeReference
from visualization_msgs.msg import MarkerArray

from fusion_planner.core.local_planning import apf, follow
from fusion_planner.core.errors import InvalidInput, PlanningError
from fusion_planner.core.global_planning.planner import PlannerConfig, load_compiled_loops
from fusion_planner.core.grid import DEFAULT_MAX_CELLS
from fusion_planner.core.local_planning.replanning import GridReplanner
from fusion_planner.core.local_planning.scan_tracker import ScanVerdict
from fusion_planner.ros import conversions as conv
from fusion_planner.ros.diagnostics import ERROR, OK, WARN, DiagnosticsReporter, one_line
from fusion_planner.ros.lifecycle import AUTOSTART_DESCRIPTION, ManagedNode
from fusion_planner.ros.goal_outcome import (
    CONTROLLER_OUTCOME_TOPIC, OUTCOME_OF_STATUS, controller_outcome_msg)
from fusion_planner.ros.parameters import ParameterHandler, ParameterSpec, float_range, int_range
from fusion_planner.ros.scan_tracks import ScanTracks, fuse, tracks_to_markers
from fusion_planner.ros.qos import RELIABLE_QOS, LatchedOrVolatile
from fusion_planner.ros import frames
from fusion_planner.ros.frames import Localization
from fusion_planner.ros.lockstep import (
    MAX_KEPT_PLANS, PLAN_STAMP_TOPIC, StepInputs, pose_subscription, step_input_qos)
from fusion_planner.ros.timed_pose import pose_at
from fusion_planner.ros.node_main import run_node

NODE_NAME = 'local_planner'

#: Prefix of the parameters that fill :class:`~fusion_planner.core.local_planning.apf.ApfParams`.
APF_PREFIX = 'apf_'
#: A node-clock step backwards larger than this [s] is a clock reset.
CLOCK_JUMP_TOLERANCE_S = 1e-3
#: Default heading change [rad] above which a plan vertex turns (key nodes).
DEFAULT_KEY_NODE_MIN_TURN_RAD = 0.01
#: Sine of the angle under which two segments count as parallel [1].
PARALLEL_SINE = 1e-6
#: Statuses after which the command is exactly zero.
STOPPED_STATUSES = ('arrived', 'failed', 'no_path')

#: The node's own parameters: ``(name, default, description, range, read_only, choices)``.
NODE_PARAMETERS = (
    ('frame_id', 'map', 'map frame: of the plan, map, amcl_pose and obstacles', None, True, ()),
    ('odom_frame_id', 'odom', 'frame of the odometry, in which the robot is controlled; equal '
     'to frame_id: odometry already in the map frame, no amcl_pose needed', None, True, ()),
    ('laser_frame_id', 'base_link', 'frame of the scan', None, True, ()),
    ('use_tf', False, 'take map -> odom and the laser pose from TF (needs tf2_ros, a full ROS '
     'install) instead of amcl_pose and the laser_* parameters', None, True, ()),
    ('laser_x', 0.0, 'laser position ahead of the robot centre, robot frame [m]',
     float_range(-10.0, 10.0), True, ()),
    ('laser_y', 0.0, 'laser position left of the robot centre, robot frame [m]',
     float_range(-10.0, 10.0), True, ()),
    ('laser_yaw', 0.0, 'laser heading in the robot frame [rad]',
     float_range(-math.pi, math.pi), True, ()),
    ('robot_frame_id', 'base_link', 'robot frame: child of the odometry, frame of a TwistStamped '
     'command',
     None, True, ()),
    ('controller', 'fusion',
     "local controller: 'fusion' (A* key nodes + improved APF, the paper's method), "
     "'apf', 'classic-apf' or 'astar-track'", None, False, follow.CONTROLLER_NAMES),
    ('control_rate', 20.0,
     'rate of cmd_vel on the node clock; the follower period is its inverse [Hz]',
     float_range(1.0, 200.0), False, ()),
    ('enable_stamped_cmd_vel', False,
     "publish geometry_msgs/TwistStamped instead of Twist on cmd_vel (Nav2's name)",
     None, True, ()),
    ('use_stamped_twist', False, 'deprecated alias of enable_stamped_cmd_vel: true also '
     'enables it (with a warning)', None, True, ()),
    ('lockstep', False,
     'compute on each complete per-step set of odom, amcl_pose, scan, obstacles and '
     'plan_stamp (one stamp, from a simulator and a global planner in lockstep) instead of on '
     "a timer, on the set's stamp: a run then does not depend on the machine's speed; needs "
     'enable_stamped_cmd_vel', None, True, ()),
    ('publish_zero_when_idle', False,
     'keep publishing a zero cmd_vel at control_rate while idle (no plan, or the plan ended); '
     'false: one zero command, then silence', None, False, ()),
    ('odom_timeout', 0.5, 'older odometry stops the robot [s]', float_range(0.01, 60.0), False, ()),
    ('scan_timeout', 0.5, 'an older scan is stale (see on_stale_scan) [s]',
     float_range(0.01, 60.0), False, ()),
    ('on_stale_scan', 'stop',
     "with a stale scan: 'stop' the robot or 'slow' it to stale_scan_speed",
     None, False, ('stop', 'slow')),
    ('stale_scan_speed', 0.1, "speed cap with a stale scan and on_stale_scan 'slow' [m/s]",
     float_range(0.0, 10.0), False, ()),
    ('key_node_min_turn', DEFAULT_KEY_NODE_MIN_TURN_RAD,
     'a plan vertex turning by more than this belongs to a rounded corner; each corner '
     'becomes one key node (APF sub-goal) [rad]', float_range(0.0, 1.0), False, ()),
    ('plan_timeout', 1.0, 'drop the plan (stop) when no publisher of plan has been seen for this '
     'long; 0 disables [s]', float_range(0.0, 600.0), False, ()),
    ('obstacle_timeout', conv.DEFAULT_OBSTACLE_TIMEOUT_S,
     'forget a tracked obstacle not seen for this long [s]', float_range(0.01, 60.0), True, ()),
    ('max_map_cells', DEFAULT_MAX_CELLS, 'maps with more cells are refused [cells]',
     int_range(1, 400_000_000), True, ()),
    ('diagnostics_period', 1.0,
     'period of the diagnostics heartbeat on the node clock; 0: events only [s]',
     float_range(0.0, 60.0), True, ()),
    ('autostart', True, AUTOSTART_DESCRIPTION, None, True, ()),
)

#: Description and range of each :class:`~fusion_planner.core.local_planning.follow.FollowerParams`
#: field declared as a parameter of the same name. ``apf`` (below) and
#: ``control_period`` (``1 / control_rate``) are not declared.
FOLLOWER_PARAMETERS = {
    'max_speed': ('largest forward speed [m/s]', float_range(0.01, 10.0)),
    'max_reverse_speed': ('largest reverse speed, at most max_speed; the controllers reverse '
                          'only to evade a moving obstacle; 0: never [m/s]',
                          float_range(0.0, 10.0)),
    'max_accel': ('largest change of speed [m/s^2]', float_range(0.01, 20.0)),
    'max_omega': ('largest turn rate [rad/s]', float_range(0.01, 20.0)),
    'max_alpha': ('largest change of turn rate [rad/s^2]', float_range(0.01, 100.0)),
    'goal_tolerance': ("arrival radius around the plan's end [m]", float_range(0.01, 10.0)),
    'lookahead': ('field goal at most this far ahead of the robot; pure-pursuit lookahead [m]',
                  float_range(0.05, 20.0)),
    'stuck_window': ('window of the local-minimum progress test [s]', float_range(0.1, 120.0)),
    'stuck_progress': ('net progress needed within stuck_window [m]', float_range(0.001, 10.0)),
    'escape_time_limit': ('longest time without progress toward the goal before failing [s]',
                          float_range(0.1, 3600.0)),
    'robot_radius': ('robot radius; obstacle distances are from its boundary [m]',
                     float_range(0.0, 10.0)),
    'prediction_horizon': ('how far ahead tracked obstacles are predicted; 0: current positions '
                           'only [s]', float_range(0.0, 30.0)),
    'heading_gain': ('turn rate per radian of heading error [1/s]', float_range(0.01, 50.0)),
    'route_heading_gain': ('turn rate per radian of heading error of the route follower '
                           '(fusion), at most 1 / (4 control periods) [1/s]',
                           float_range(0.01, 50.0)),
    'approach_gain': ('speed cap per metre of distance to the goal [1/s]', float_range(0.01, 50.0)),
    'safety_distance': ('clearance kept straight ahead and required of a free line of sight [m]',
                        float_range(0.0, 10.0)),
    'sight_clearance': ('clearance the straight line to a later key node must keep from every '
                        'obstacle point for that node to count as visible [m]',
                        float_range(0.0, 10.0)),
    'wall_distance': ('clearance kept while following a boundary to escape [m]',
                      float_range(0.01, 10.0)),
    'point_spacing': ('obstacle points are thinned to one per square of this edge [m]',
                      float_range(0.01, 5.0)),
    'visibility_range': ('later key nodes within this distance are tested for a free line of '
                         'sight [m]', float_range(0.01, 100.0)),
}

#: Description and range of each :class:`~fusion_planner.core.local_planning.apf.ApfParams`
#: field, declared as ``apf_<field>``; its ``robot_radius`` is ``robot_radius``.
APF_PARAMETERS = {
    'k_att': ('attraction gain, eqs. (9)-(10) [force/m]', float_range(1e-6, 1e6)),
    'k_rep': ('repulsion gain k, eqs. (11)-(12), (15)-(16)', float_range(0.0, 1e6)),
    'rho0': ('influence distance rho0 of the repulsion [m]', float_range(0.01, 100.0)),
    'n': ('goal-distance exponent n, eqs. (15)-(16) [1]', float_range(0.01, 10.0)),
    'mu': ('velocity repulsion gain mu, eq. (17) [force s/m]', float_range(0.0, 1e6)),
    'step_alpha': ('adaptive step factor alpha closer than d_min, eq. (18) [s/m^2]',
                   float_range(1e-6, 1e3)),
    'step_beta': ('adaptive step factor beta within rho, eq. (18) [s/m^2]', float_range(1e-6, 1e3)),
    'l0': ('base step l0, eq. (18) [m]', float_range(1e-3, 10.0)),
    'd_min': ('minimum robot-obstacle distance d_min, eq. (18) [m]', float_range(1e-3, 10.0)),
    'rho': ('range within which obstacles shorten the step, eq. (18); > apf_d_min [m]',
            float_range(1e-3, 100.0)),
}

#: Range of a core field missing from the tables above (kept declarable).
UNDOCUMENTED_RANGE = float_range(0.0, 1e6)
#: Core fields never declared as parameters.
_FOLLOWER_SKIPPED = ('apf', 'control_period')
_APF_SKIPPED = ('robot_radius',)


def _core_specs(core_type, table, prefix, skipped):
    """ParameterSpecs of the fields of a core dataclass (defaults from the core)."""
    defaults = core_type()
    specs = []
    for f in fields(core_type):
        if f.name in skipped:
            continue
        description, value_range = table.get(
            f.name, (f'{core_type.__name__}.{f.name} (see its documentation)', UNDOCUMENTED_RANGE))
        specs.append(ParameterSpec(prefix + f.name, float(getattr(defaults, f.name)),
                                   description, value_range))
    return specs


#: Every parameter of the node; config/params.yaml lists the same names.
PARAMETER_SPECS = tuple(
    [ParameterSpec(name, default, description, value_range, read_only, choices)
     for name, default, description, value_range, read_only, choices in NODE_PARAMETERS]
    + _core_specs(follow.FollowerParams, FOLLOWER_PARAMETERS, '', _FOLLOWER_SKIPPED)
    + _core_specs(apf.ApfParams, APF_PARAMETERS, APF_PREFIX, _APF_SKIPPED))


def _check(params):
    """``__post_init__`` of :class:`LocalPlannerParams`: the core validates the values."""
    if params.controller not in follow.CONTROLLER_NAMES:
        raise InvalidInput(f'controller must be one of {follow.CONTROLLER_NAMES}, '
                           f'got {params.controller!r}')
    if params.lockstep and not (params.enable_stamped_cmd_vel or params.use_stamped_twist):
        raise InvalidInput('lockstep needs enable_stamped_cmd_vel: the simulator matches each '
                           'command to the sensor set it answers by its stamp, which a Twist '
                           'does not carry')
    params.follower_params()


def _follower_params(params):
    """The :class:`~fusion_planner.core.local_planning.follow.FollowerParams` these values describe.

    The control period is ``1 / control_rate``; the APF robot radius is
    ``robot_radius``.
    """
    apf_values = {f.name: getattr(params, APF_PREFIX + f.name) for f in fields(apf.ApfParams)
                  if f.name not in _APF_SKIPPED}
    follower_values = {f.name: getattr(params, f.name) for f in fields(follow.FollowerParams)
                       if f.name not in _FOLLOWER_SKIPPED}
    return follow.FollowerParams(apf=apf.ApfParams(**apf_values),
                                 control_period=1.0 / params.control_rate, **follower_values)


#: Tunables of the local planner node: one frozen field per entry of
#: :data:`PARAMETER_SPECS` (the node's own, then every FollowerParams field,
#: then every ApfParams field as ``apf_<name>``), built from the core
#: dataclasses so the node follows them. ``follower_params()`` gives the
#: FollowerParams; construction raises InvalidInput on values the core refuses.
LocalPlannerParams = make_dataclass(
    'LocalPlannerParams',
    [(spec.name, type(spec.default), dataclass_field(default=spec.default))
     for spec in PARAMETER_SPECS],
    frozen=True,
    namespace={'__post_init__': _check, 'follower_params': _follower_params,
               '__module__': __name__})


@np.errstate(over='ignore', invalid='ignore')  # overflow on absurd coordinates is handled
def key_nodes_of(path, min_turn=DEFAULT_KEY_NODE_MIN_TURN_RAD):
    """Key nodes of a global plan: its ends and the corners its smoothing rounded.

    The global planner removes redundant nodes and rounds each remaining
    corner with an arc (paper section 1.3.3); the key nodes, the APF
    sub-goals of the fusion (section 3.3), are those corners. Each run of
    consecutive vertices that turn by more than ``min_turn`` (an arc, or a
    single vertex of an unsmoothed path) gives one key node: the
    intersection of the straight segments entering and leaving the run,
    i.e. the corner the arc replaced.

    Parameters
    ----------
    path : ndarray, float64, shape (N, 2)
        ``(x, y)`` [m], map frame, finite, N >= 1.
    min_turn : float
        Heading change [rad] above which a vertex turns, >= 0; smaller
        changes (sampling noise on a straight run) are ignored.

    Returns
    -------
    ndarray, float64, shape (K, 2)
        The first point, one corner per turning run, the last point (the
        goal). A corner is replaced by the run's middle vertex when the
        two segments are (anti)parallel, the intersection lies farther
        from the run than the run is long (a turn close to 180 degrees), or
        it overflows (absurd coordinates): key nodes are always finite.

    Notes
    -----
    Repeated points are dropped first. Vectorised headings; one pass over
    the runs (at most N).

    Examples
    --------
    A straight run, a rounded right-angle corner at (2, 0), a straight run:

    >>> arc = [[2.0 - 0.3 + 0.3 * np.sin(a), 0.3 - 0.3 * np.cos(a)]
    ...        for a in np.linspace(0.0, np.pi / 2, 5)]
    >>> path = np.array([[0.0, 0.0], [1.0, 0.0]] + arc + [[2.0, 1.0], [2.0, 2.0]])
    >>> key_nodes_of(path).round(6).tolist()
    [[0.0, 0.0], [2.0, 0.0], [2.0, 2.0]]
    """
    keep = np.ones(len(path), dtype=bool)
    keep[1:] = np.any(np.diff(path, axis=0) != 0.0, axis=1)
    pts = path[keep]
    n = len(pts)
    if n <= 2:
        return pts if n == 2 or len(path) == 1 else np.vstack([pts, pts])
    seg = np.diff(pts, axis=0)                                   # (n - 1, 2)
    heading = np.arctan2(seg[:, 1], seg[:, 0])
    turn = (np.diff(heading) + math.pi) % (2.0 * math.pi) - math.pi  # at vertices 1..n-2
    turning = np.flatnonzero(np.abs(turn) > min_turn) + 1
    nodes = [pts[0]]
    if len(turning):
        runs = np.split(turning, np.flatnonzero(np.diff(turning) > 1) + 1)
        for run in runs:  # bounded: at most n - 2 runs
            nodes.append(_corner(pts, run[0], run[-1]))
    nodes.append(pts[-1])
    return np.array(nodes)


def _corner(pts, first, last):
    """Corner of the turning run ``pts[first..last]`` (see :func:`key_nodes_of`)."""
    a, da = pts[first], pts[first] - pts[first - 1]      # entering segment
    b, db = pts[last], pts[last + 1] - pts[last]         # leaving segment
    middle = pts[(first + last) // 2]
    cross = da[0] * db[1] - da[1] * db[0]
    scale = math.hypot(*da) * math.hypot(*db)
    if abs(cross) <= PARALLEL_SINE * scale:
        return middle.copy()
    t = ((b[0] - a[0]) * db[1] - (b[1] - a[1]) * db[0]) / cross
    corner = a + t * da
    run_length = float(np.sum(np.hypot(*np.diff(pts[first:last + 1], axis=0).T))) \
        + math.hypot(*da) + math.hypot(*db)
    # Also the middle vertex when the corner is not finite (overflow on absurd coordinates).
    if not math.hypot(*(corner - middle)) <= run_length:
        return middle.copy()
    return corner


class LocalPlannerNode(ManagedNode):
    """The local planner node (see the module docstring for its interface).

    A lifecycle node (:class:`~fusion_planner.ros.lifecycle.ManagedNode`):
    it commands only while active; deactivating it sends one zero command
    and then nothing.

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

    Notes
    -----
    Callbacks run in the node's default (mutually exclusive) callback group;
    a lock also guards the state against parameter changes made from another
    thread.
    """

    def __init__(self, node_name=NODE_NAME, tf_buffer=None, **kwargs):
        super().__init__(node_name, **kwargs)
        self._tf_buffer = tf_buffer  # with use_tf: this buffer instead of a tf2_ros one
        self._tf = None
        self._lock = threading.RLock()
        self._params = ParameterHandler(self, LocalPlannerParams, PARAMETER_SPECS,
                                        on_change=self._on_parameters_changed)
        params = self._params.current
        self._frame_id = params.frame_id
        self._robot_frame_id = params.robot_frame_id
        # lockstep: the node's time, from 0 on the stamp of the set in hand [ns]
        self._step_time_ns = 0 if params.lockstep else None
        self._diagnostics = DiagnosticsReporter(self, params.diagnostics_period,
                                                stamp=self._stamp)
        self._stamped = params.enable_stamped_cmd_vel or params.use_stamped_twist
        if params.use_stamped_twist:
            self.get_logger().warning('use_stamped_twist is deprecated: '
                                      'set enable_stamped_cmd_vel instead')
        self._timer = None
        self._reset_state()
        self._diagnostics.update(WARN, 'unconfigured')
        self.start(params.autostart)

    def _reset_state(self):
        """Forget every input and the controller's state."""
        params = self._params.current
        self._replanner = None     # GridReplanner on the latest map
        self._controller = follow.make_controller(params.controller, params.follower_params(),
                                                  replan=self._replan)
        self._tracker = conv.ObstacleTracker(params.frame_id, timeout_s=params.obstacle_timeout)
        self._scan_tracks = ScanTracks(params.frame_id)
        self._tracking_note = ''   # why the last scan was not tracked ('' when it was)
        self._plan_map = None      # (N, 2) the plan as received, map frame [m]
        self._plan = None          # (N, 2) that plan in the odom frame, being followed [m]
        self._plan_correction = None  # the map -> odom correction it was brought over with
        self._localization = Localization(params.odom_timeout,
                                          same_frame=params.odom_frame_id == params.frame_id)
        self._plan_stamp_ns = 0    # header stamp of that plan [ns]
        self._outcome_sent = False  # the run of that plan ended and was reported
        self._odom = None          # latest Odometry as (stamp [s], pose (3,), velocity (2,))
        self._odom_received = None  # node-clock time it arrived [s]
        self._odom_stamp = None    # its header stamp
        self._scan = None          # (points (M, 2), receive time [s])
        self._last_tick = None     # node-clock time of the last control step [s]
        self._plan_orphaned_since = None  # node-clock time the plan's publisher vanished [s]
        self._status = None        # last reported status
        self._level, self._message = WARN, 'waiting for a plan'  # last reported status line
        self._stuck_events = 0
        self._step_ms_max = 0.0
        self._timing = [0.0, 0, None]  # [sum of step times [ms], steps, window start [s]]
        self._idle_stop_sent = False  # the one zero command of an idle spell went out
        self._last_command = None  # (v, omega) last published [m/s, rad/s]
        self._plans = {}  # lockstep: the latest plans by stamp [ns]
        self._waiting_step = None  # lockstep: (stamp [ns], messages) of a step awaiting its plan
        self._plan_in_force = None  # lockstep: stamp of the plan last handed over [ns]

    def configure(self):
        """Fresh state; the publishers, subscriptions and the control timer."""
        with self._lock:
            self._reset_state()
        params = self._params.current
        load_s = load_compiled_loops(PlannerConfig(robot_radius=params.robot_radius))
        self.get_logger().debug(f'compiled loops of the replanner loaded in {load_s:.3f} s')
        if params.use_tf:
            self._tf = frames.TfSource(self._tf_buffer) if self._tf_buffer is not None \
                else frames.make_tf_source(self)
        guard = self._diagnostics.guard
        twist_type = TwistStamped if self._stamped else Twist
        self._cmd_pub = self.create_lifecycle_publisher(twist_type, 'cmd_vel', RELIABLE_QOS)
        self._local_plan_pub = self.create_lifecycle_publisher(Path, 'local_plan', RELIABLE_QOS)
        self._tracks_pub = self.create_lifecycle_publisher(MarkerArray, 'tracks', RELIABLE_QOS)
        # Per-step inputs, in the order a lockstep set hands them over: the
        # odometry first (it places the pose and the scan). The plan comes
        # last, after the set (see _on_step_inputs).
        self._input_handlers = {'odom': self._on_odometry, 'amcl_pose': self._on_localization,
                                'scan': self._on_scan, 'obstacles': self._on_obstacles}
        if self._localization.same_frame or self._tf is not None:
            del self._input_handlers['amcl_pose']
        handlers = dict(self._input_handlers, plan=self._on_plan)
        if params.lockstep:
            self._inputs = StepInputs([*self._input_handlers, PLAN_STAMP_TOPIC],
                                      self._on_step_inputs)
            handlers = {name: functools.partial(self._inputs.add, name) for name in handlers}
            handlers['plan'] = self._keep_plan
            self.create_subscription(TimeReference, PLAN_STAMP_TOPIC, guard(
                PLAN_STAMP_TOPIC, functools.partial(self._inputs.add, PLAN_STAMP_TOPIC)),
                RELIABLE_QOS)
        self._plan_sub = LatchedOrVolatile(self, Path, 'plan', guard('plan', handlers['plan']),
                                           ReliabilityPolicy.RELIABLE)
        sensor_qos = step_input_qos(params.lockstep)
        self.create_subscription(Odometry, 'odom', guard('odom', handlers['odom']), sensor_qos)
        self.create_subscription(LaserScan, 'scan', guard('scan', handlers['scan']), sensor_qos)
        self.create_subscription(MarkerArray, 'obstacles', guard('obstacles',
                                                                 handlers['obstacles']),
                                 RELIABLE_QOS)
        self._map_sub = LatchedOrVolatile(self, OccupancyGrid, 'map', guard('map', self._on_map),
                                          ReliabilityPolicy.RELIABLE)
        if 'amcl_pose' in handlers:
            self._pose_sub = pose_subscription(self, PoseWithCovarianceStamped, 'amcl_pose',
                                               guard('amcl_pose', handlers['amcl_pose']),
                                               params.lockstep)
        self._outcome_pub = self.create_lifecycle_publisher(
            DiagnosticStatus, CONTROLLER_OUTCOME_TOPIC, RELIABLE_QOS)
        if not params.lockstep:
            self._timer = self.create_timer(
                1.0 / params.control_rate, guard('control', self._on_timer,
                                                 on_error=self._on_fault))
        self._diagnostics.update(WARN, 'waiting for a plan', status='no_path', arrived=False,
                                 stuck_events=0, controller=params.controller)

    def deactivate(self):
        """Stop the robot with one zero command before the publishers go quiet."""
        with self._lock:
            self._publish_command(0.0, 0.0)
            self._idle_stop_sent = True
        self._update(WARN, 'inactive', status='inactive')

    def cleanup(self):
        """The timer went with the other entities; the TF listener goes too."""
        self._timer = None
        self._tf = None

    # -- inputs ---------------------------------------------------------------

    def _on_plan(self, msg):
        """Take a new global plan; an empty one means stop."""
        path = conv.plan_from_msg(msg, self._frame_id, 'plan')
        with self._lock:
            if path is None:
                if self._plan_map is not None:
                    self.get_logger().info('empty plan received: stopping')
                self._drop_plan()
                return
            if self._plan_map is not None and self._plan_map.shape == path.shape \
                    and np.array_equal(self._plan_map, path):
                return  # the same plan again (a latched republish): keep the state
            self._plan_map = path
            self._plan = None
            self._bring_plan_over()
            self._plan_stamp_ns = conv.stamp_to_nanoseconds(msg.header.stamp)
            self._outcome_sent = False
            self._plan_orphaned_since = None
            self._status = None
            self.get_logger().info(
                f'new plan of {len(path)} points to ({path[-1, 0]:.2f}, {path[-1, 1]:.2f})')

    def _on_map(self, msg):
        """Replan on this map from now on (unknown cells count as obstacles)."""
        params = self._params.current
        grid = conv.occupancy_grid_to_grid_map(msg, self._frame_id, unknown_is_occupied=True,
                                               max_cells=params.max_map_cells)
        config = PlannerConfig(robot_radius=params.robot_radius)
        with self._lock:
            self._replanner = GridReplanner(grid, config)
            self._scan_tracks.set_map(grid)
        if self._waiting_step is not None:  # lockstep: a step that waited for the map
            self._on_step_inputs(*self._waiting_step)

    def _replan(self, start, goal, obstacle_points):
        """The controller's replanner: the map plus the scanned obstacles (see GridReplanner).

        The controller works in the plan's frame (odom as corrected when the
        plan arrived), the map is in the map frame: the request and the new
        plan go through that correction.
        """
        correction = self._plan_correction
        if self._replanner is None or correction is None:
            # no search was made: the goal is not proven unreachable, the robot carries on
            raise PlanningError('no map or no localization received: cannot replan')
        to_map = functools.partial(frames.transform_points, correction)
        to_odom = functools.partial(frames.transform_points, frames.inverse(correction))
        path, key_nodes = self._replanner(to_map(start)[0], to_map(goal)[0],
                                          to_map(obstacle_points))
        return to_odom(path), to_odom(key_nodes)

    def _on_odometry(self, msg):
        params = self._params.current
        pose = conv.odometry_to_xy_yaw(msg, params.odom_frame_id, 'odometry')
        velocity = conv.odometry_to_velocity(msg, 'odometry')
        stamp = conv.stamp_to_seconds(msg.header.stamp)
        with self._lock:
            self._odom = (stamp, np.array(pose), np.array(velocity))
            self._odom_stamp = msg.header.stamp  # exact, for a TwistStamped answering it
            self._odom_received = self._now_s()
            if self._localization.add_odometry(*self._odom):
                self._bring_plan_over()  # with the localization that came first

    def _on_localization(self, msg):
        """A map-frame pose: the map -> odom correction at its stamp."""
        pose = conv.pose_with_covariance_to_xy_yaw(msg, self._frame_id, 'amcl_pose')
        with self._lock:
            if self._localization.add_localization(conv.stamp_to_seconds(msg.header.stamp), pose):
                self._bring_plan_over()

    def _bring_plan_over(self):
        """Bring a new map plan into the odom frame with the current correction.

        The controller keeps this frame (the odom frame as corrected when the
        plan arrived) for the whole plan: a later correction moves the robot
        pose, scans and obstacles it is given (:meth:`_to_plan_frame`), never
        the plan, so the controller's progress and escape state carry on.
        """
        correction = self._localization.map_from_odom
        if self._plan_map is None or self._plan is not None or correction is None:
            return
        self._plan_correction = correction
        self._plan = frames.transform_points(frames.inverse(correction), self._plan_map)
        self._controller.set_path(
            self._plan, key_nodes_of(self._plan, self._params.current.key_node_min_turn))

    def _correction_from_tf(self, params):
        """With ``use_tf``: the latest map -> odom from TF instead of amcl_pose."""
        correction = self._tf.planar(self._frame_id, params.odom_frame_id)
        if correction is not None:
            self._localization.map_from_odom = correction
            self._bring_plan_over()

    def _to_plan_frame(self):
        """The transform from the odom frame now to the plan's frame (identity without drift).

        ``inverse(correction at the plan) o correction now``: what odometry
        drifted since the plan was brought over.
        """
        return frames.compose(frames.inverse(self._plan_correction),
                              self._localization.map_from_odom)

    def _on_scan(self, msg):
        """Scan returns as obstacle points in the odom frame (the one place obstacles come in)."""
        params = self._params.current
        with self._lock:
            if self._odom is None:
                return  # cannot place the beams before the first pose
            stamp = conv.stamp_to_seconds(msg.header.stamp)
            if stamp > 0:
                pose = self._localization.odom_pose_at(stamp)
            else:  # an unstamped scan: take it as current
                pose = self._odom[1]
            frame, mount = params.laser_frame_id, (params.laser_x, params.laser_y, params.laser_yaw)
            if self._tf is not None:
                frame = msg.header.frame_id
                mount = self._tf.scan_pose(params.robot_frame_id, frame)
            laser = frames.compose(pose, mount)
            points = conv.scan_to_points(msg, tuple(laser), frame, 'scan')
            self._scan = (points, self._now_s())
            self._track_scan(msg, laser, stamp if stamp > 0 else self._odom[0])

    def _track_scan(self, msg, laser, stamp):
        """Feed a scan taken from ``laser`` (odom frame) to the scan tracker; publish its tracks."""
        if not self._scan_tracks.has_map:
            return
        lag = self._odom[0] - stamp
        timeout = self._params.current.scan_timeout
        correction = self._localization.map_from_odom
        if correction is None:
            verdict = ScanVerdict(False, 'no localization yet: scans are not tracked')
        elif lag > timeout:
            verdict = ScanVerdict(False, f'scan stamped {lag:.2f} s before the latest odometry '
                                         f'(scan_timeout {timeout:g} s): not tracked')
        else:
            verdict = self._scan_tracks.update(msg, frames.compose(correction, laser), stamp)
        self._note_tracking(verdict.reason if not verdict.accepted else '')
        if not verdict.accepted:
            return
        if self._tracks_pub.get_subscription_count() > 0:
            self._tracks_pub.publish(tracks_to_markers(self._scan_tracks.report(),
                                                       self._frame_id, self._stamp()))

    def _note_tracking(self, reason):
        """Say (once per change, rate-limited) why a valid scan was not tracked ('' when it was)."""
        if reason == self._tracking_note:
            return
        self._tracking_note = reason
        if reason:
            self._diagnostics.log.warning('scan/not_tracked', one_line(f'scan: {reason}'))
        self._diagnostics.update(self._level, self._message, scan_tracking=reason or 'tracking')

    def _on_obstacles(self, msg):
        with self._lock:
            _, rejected = self._tracker.update(msg, self._now_s())
        if rejected:
            self._diagnostics.reject(
                'obstacles',
                InvalidInput(f'{len(rejected)} marker(s) refused, first: {rejected[0]}'))

    def _keep_plan(self, msg):
        """Lockstep: keep a plan until a step names it; run the step that waited for it."""
        self._plans[conv.stamp_to_nanoseconds(msg.header.stamp)] = msg
        while len(self._plans) > MAX_KEPT_PLANS:
            del self._plans[min(self._plans)]
        if self._waiting_step is not None:
            self._on_step_inputs(*self._waiting_step)

    def _on_step_inputs(self, stamp_ns, messages):
        """Lockstep: take a step's set in order, the plan it names, then run one control step.

        The set ends with the global planner's ``plan_stamp``: the stamp of the
        plan in force after that step. The step waits here until that plan has
        arrived on ``plan`` (another topic, so possibly later), and until the
        map has (latched, so its arrival time varies; the scan tracker and
        the replanner work on it).
        """
        plan_stamp = conv.stamp_to_nanoseconds(messages[-1].time_ref)
        if plan_stamp not in self._plans or self._replanner is None:
            self._waiting_step = (stamp_ns, messages)
            return
        self._waiting_step = None
        self._step_time_ns = stamp_ns
        guard = self._diagnostics.guard
        for name, msg in zip(self._inputs.names, messages[:-1]):
            # a refused message is reported and the step goes on without it
            guard(name, self._input_handlers[name])(msg)
        if stamp_ns == 0:
            # The world held at t = 0 until the first plan: which plan the
            # global planner named first then depends on when the goal came.
            return
        if plan_stamp != self._plan_in_force:
            self._plan_in_force = plan_stamp
            guard('plan', self._on_plan)(self._plans[plan_stamp])
        guard('control', self._on_timer, on_error=self._on_fault)()

    def _on_parameters_changed(self, old, new):
        """Apply an accepted run-time parameter change."""
        with self._lock:
            if new.controller != old.controller or new.key_node_min_turn != old.key_node_min_turn:
                self._controller = follow.make_controller(new.controller, new.follower_params(),
                                                          replan=self._replan)
                if self._plan is not None:
                    self._controller.set_path(self._plan,
                                              key_nodes_of(self._plan, new.key_node_min_turn))
                self._status = None
            else:
                self._controller.params = new.follower_params()
            if new.control_rate != old.control_rate and self._timer is not None:
                self.destroy_timer(self._timer)
                self._timer = self.create_timer(
                    1.0 / new.control_rate,
                    self._diagnostics.guard('control', self._on_timer, on_error=self._on_fault))
        self.get_logger().info(
            'parameters changed: ' + ', '.join(
                f'{f.name}={getattr(new, f.name)!r}' for f in fields(new)
                if getattr(new, f.name) != getattr(old, f.name)))

    # -- control loop ---------------------------------------------------------

    def _on_timer(self):
        """One control step: check inputs, run the controller, publish."""
        if not self.active:
            return
        started = time.perf_counter()
        with self._lock:
            now = self._now_s()
            params = self._params.current
            if self._last_tick is not None and now < self._last_tick - CLOCK_JUMP_TOLERANCE_S:
                self._on_clock_reset(now)
            self._last_tick = now
            if self._tf is not None:
                self._correction_from_tf(params)
            stop_reason = self._stop_reason(now, params)
            if stop_reason is not None:
                status, message = stop_reason
                self._publish_command(0.0, 0.0, idle=self._plan_map is None)
                self._report(status, message, WARN if status != 'no_path' else OK)
                return
            drift = self._to_plan_frame()
            pose = frames.compose(drift, pose_at((self._odom,), now, params.odom_timeout))
            velocity = self._odom[2]
            scan_stale = self._scan is None or now - self._scan[1] > params.scan_timeout
            points = np.zeros((0, 2)) if self._scan is None \
                else frames.transform_points(drift, self._scan[0])
            scan_tracked, tentative, scan_turns = self._scan_tracks.movers(now)
            tracked, turn_stds = fuse(scan_tracked, self._tracker.obstacles(now), scan_turns)
            obs = follow.Observation(
                pose=pose, velocity=velocity, obstacle_points=points,
                tracked=self._in_plan_frame(tracked), time=now,
                tentative=self._in_plan_frame(tentative), turn_stds=turn_stds,
                commanded=self._last_command)
            self._controller.display_plan = self._local_plan_pub.get_subscription_count() > 0
            command = self._controller.compute(obs)
            # The robot's limits hold whatever the controller asks: it speeds up from the
            # measured velocity, which an odometry glitch can put beyond them.
            v = min(max(command.v, -params.max_speed), params.max_speed)
            omega = min(max(command.omega, -params.max_omega), params.max_omega)
            if command.status in STOPPED_STATUSES:
                v = omega = 0.0
            elif scan_stale:
                v = min(v, params.stale_scan_speed)
            self._publish_command(v, omega, idle=command.status in STOPPED_STATUSES)
            if command.local_plan is not None and len(command.local_plan):
                self._local_plan_pub.publish(conv.path_to_msg(
                    frames.transform_points(self._plan_correction, command.local_plan),
                    self._frame_id, self._stamp()))
            step_ms = (time.perf_counter() - started) * 1e3
            self._step_ms_max = max(self._step_ms_max, step_ms)
            self._report_command(command, pose, step_ms, scan_stale)
            self._report_timing(now, step_ms, params.diagnostics_period)

    def _stop_reason(self, now, params):
        """``(status, sentence)`` when the robot must stand still, else None."""
        if self._plan_map is not None and params.plan_timeout > 0:
            if self._plan_sub.get_publisher_count() > 0:
                self._plan_orphaned_since = None
            elif self._plan_orphaned_since is None:
                self._plan_orphaned_since = now
            elif now - self._plan_orphaned_since > params.plan_timeout:
                self.get_logger().warning(
                    f'the plan publisher has been gone for more than {params.plan_timeout:g} s: '
                    'dropping the plan')
                self._drop_plan()
        if self._plan_map is None:
            return 'no_path', 'no plan: standing still'
        if self._odom is None:
            return 'stale_odom', 'no odometry received: standing still'
        if self._plan is None:
            return 'no_localization', ('no localization pose (amcl_pose) yet: cannot bring the '
                                       'plan into the odom frame; standing still')
        age = now - self._odom_received
        if age > params.odom_timeout:
            return 'stale_odom', (f'odometry is {age:.2f} s old '
                                  f'(odom_timeout {params.odom_timeout:g} s)')
        if params.on_stale_scan == 'stop':
            if self._scan is None:
                return 'stale_scan', 'no scan received: standing still'
            age = now - self._scan[1]
            if age > params.scan_timeout:
                return 'stale_scan', (f'scan is {age:.2f} s old '
                                      f'(scan_timeout {params.scan_timeout:g} s)')
        return None

    def _on_clock_reset(self, now):
        """The node clock went backwards (a simulation reset): forget timed inputs."""
        self.get_logger().warning(
            f'clock jumped back from {self._last_tick:.3f} s to {now:.3f} s: '
            'waiting for fresh data')
        self._odom = None
        self._localization.clear()
        self._plan = None  # brought over again with the next correction
        self._scan = None
        self._tracker.clear()
        self._scan_tracks.clear()
        self._plan_orphaned_since = None

    def _on_fault(self):
        """After an internal error in a control step: stop the robot."""
        try:
            self._publish_command(0.0, 0.0)
        except Exception as err:  # noqa: BLE001 - last line of defence, never raise
            self.get_logger().error(f'could not publish the stop command: {err}')

    def _in_plan_frame(self, tracked):
        """Moving obstacles ``(K, 5)`` x, y, vx, vy, r from the map frame to the plan's frame."""
        if len(tracked) and not self._localization.same_frame:
            to_odom = frames.inverse(self._plan_correction)
            tracked = tracked.copy()
            tracked[:, 0:2] = frames.transform_points(to_odom, tracked[:, 0:2])
            tracked[:, 2:4] = frames.rotate_vectors(to_odom[2], tracked[:, 2:4])
        return tracked

    def _drop_plan(self):
        self._plan_map = None
        self._plan = None
        self._plan_orphaned_since = None
        self._controller.reset()
        self._stuck_events = 0

    # -- outputs --------------------------------------------------------------

    def _publish_command(self, v, omega, idle=False):
        """Publish a command; idle, only the first zero unless ``publish_zero_when_idle``."""
        if idle and self._idle_stop_sent and not self._params.current.publish_zero_when_idle:
            return
        self._idle_stop_sent = idle
        self._last_command = (v, omega)
        if self._stamped:
            stamp = self._odom_stamp if self._odom is not None else self._stamp()
            msg = conv.velocity_to_twist_stamped(v, omega, self._robot_frame_id, stamp)
        else:
            msg = conv.velocity_to_twist(v, omega)
        self._cmd_pub.publish(msg)

    def _report_command(self, command, pose, step_ms, scan_stale):
        """Diagnostics on a status change or a new stuck event."""
        stuck = int(getattr(self._controller, 'stuck_events', 0))
        if stuck > self._stuck_events:
            self._stuck_events = stuck
            self.get_logger().info(
                f'local minimum detected at ({pose[0]:.2f}, {pose[1]:.2f}) '
                f'(stuck event {stuck}): escaping')
            self._status = None  # report it below
        goal = self._plan[-1]
        distance = float(math.hypot(goal[0] - pose[0], goal[1] - pose[1]))
        status = command.status
        if status == 'moving' and scan_stale:
            status = 'slow_stale_scan'
        if status == self._status:
            return
        values = dict(status=status, arrived=status == 'arrived', stuck_events=stuck,
                      controller=self._params.current.controller,
                      distance_to_goal_m=distance, step_ms=step_ms, step_ms_max=self._step_ms_max)
        if status in OUTCOME_OF_STATUS:
            self._publish_outcome(OUTCOME_OF_STATUS[status], command.reason)
        if status == 'arrived':
            self.get_logger().info(f'arrived at ({pose[0]:.2f}, {pose[1]:.2f}), '
                                   f'{distance:.3f} m from the goal')
            self._diagnostics.succeeded('arrived at the goal', last_error='', **values)
            self._update(OK, 'arrived at the goal', last_outcome='reached')
        elif status in ('failed', 'no_path'):
            outcome = OUTCOME_OF_STATUS[status]
            self.get_logger().error(f'local planner ended: {outcome}: {command.reason}')
            self._update(ERROR, f'{outcome}: {command.reason}', last_outcome=outcome,
                         last_error=command.reason, **values)
        elif status == 'slow_stale_scan':
            self._update(WARN, 'scan is stale: slowing down', **values)
        else:
            self._update(OK if status == 'moving' else WARN, status, **values)
        self._status = status

    def _publish_outcome(self, outcome, reason):
        """Tell the global planner, once per plan, how its run ended."""
        if self._outcome_sent:
            return
        self._outcome_sent = True
        self._outcome_pub.publish(controller_outcome_msg(
            outcome, self._plan_stamp_ns, reason, self.get_fully_qualified_name()))

    def _report(self, status, message, level):
        """Diagnostics (and a log line for a stop) once per status change."""
        if status == self._status:
            return
        if status != 'no_path':
            self.get_logger().warning(f'stopping: {message}')
        self._update(level, message, status=status, arrived=False)
        self._status = status

    def _report_timing(self, now, step_ms, period):
        """Mean and largest control-step time on diagnostics, once per ``period`` [s]."""
        timing = self._timing
        timing[0] += step_ms
        timing[1] += 1
        if timing[2] is None or now < timing[2]:
            timing[2] = now
        if period > 0 and now - timing[2] >= period:
            self._update(self._level, self._message, step_ms=step_ms,
                         step_ms_mean=timing[0] / timing[1], step_ms_max=self._step_ms_max)
            self._timing = [0.0, 0, now]

    def _update(self, level, message, **values):
        """Publish a status on diagnostics and remember its level and message."""
        self._level, self._message = level, message
        self._diagnostics.update(level, message, **values)

    def _now_ns(self):
        """The node's time [ns]: the node clock's, in lockstep the stamp of the set in hand."""
        if self._step_time_ns is not None:
            return self._step_time_ns
        return self.get_clock().now().nanoseconds

    def _now_s(self):
        return self._now_ns() / conv.NS_PER_S

    def _stamp(self):
        return Time(nanoseconds=self._now_ns()).to_msg()


def main(args=None):
    """Run the local planner node until Ctrl-C or shutdown; returns the exit code."""
    return run_node(LocalPlannerNode, NODE_NAME, args)


if __name__ == '__main__':
    raise SystemExit(main())
