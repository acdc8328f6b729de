"""ROS 2 node running the headless closed-loop world of a scenario file.

The node is an adapter around :class:`fusion_planner.core.simulation.world.World`: it
loads a scenario (:func:`fusion_planner.core.simulation.scenario.load_scenario`),
integrates the latest velocity command at ``rate`` steps per simulated
second, and publishes what the robot and the planners see. It is the clock
source of the run: the simulated time goes out on ``clock``, and the other
nodes follow it with ``use_sim_time``. ``real_time_factor`` sets how many
simulated seconds pass per wall second (the step timer runs on the steady
clock, whatever ``use_sim_time`` says); it is an upper bound:

- with ``sync_with_controller`` (default), once velocity commands flow a
  step waits while the last command is older than ``max_command_lag`` of
  simulated time, so a controller starved of CPU is not outrun (``0``: one
  step per command, with the controller's rate equal to ``rate``; which
  sensor data a command answers still depends on DDS timing). A controller silent for
  :data:`COMMAND_WAIT_LIMIT_S` of wall time is taken for gone: the world runs
  on and the robot stops after ``cmd_timeout``;
- with ``lockstep`` (the demo sets it; default off) the run no longer
  depends on the machine's speed: every step publishes the whole sensor set
  (odometry, ground truth, ``amcl_pose``, TF, scan, obstacles - a lone
  DELETEALL marker without moving obstacles -, clock; the ``scan_rate`` and
  ``localization_rate`` are not used), all stamped with the
  step's simulated time, and the next step waits until a ``cmd_vel``
  TwistStamped with that stamp (the local planner's answer to that set,
  see :mod:`fusion_planner.ros.lockstep`) has arrived, then goes ahead as
  soon as ``real_time_factor`` allows. A plain Twist cannot be matched to a
  step: it is an error on diagnostics and the log, and the world runs free
  (on the wall clock). A step not answered within ``lockstep_timeout`` of
  wall time is reported and the world runs free until a stamped command
  comes again (the answer to any step: the world then waits for the
  current step's), so nothing ever hangs;
- with ``start_paused`` the world stays at t = 0 (sensors and clock still
  published) until the first plan appears, so moving obstacles do not
  wander off before the robot can start and every run starts alike. The
  sensor set of t = 0 is computed once and republished unchanged.

Topics (relative names, so a namespace or a remap applies):

- ``map`` (nav_msgs/OccupancyGrid, reliable, transient_local) out, once:
  the **known** map, without the scenario's unknown obstacles.
- ``odom`` (nav_msgs/Odometry, reliable) out, every step: wheel odometry
  in ``odom_frame_id`` (child ``robot_frame_id``), starting at the origin
  where the robot stands and drifting from the truth by
  ``odom_scale_error`` of the distance and ``odom_yaw_drift`` of heading
  per metre (:class:`~fusion_planner.ros.robot_sensors.DriftingOdometry`;
  both 0: exact), with the measured velocity.
- ``amcl_pose`` (geometry_msgs/PoseWithCovarianceStamped, reliable,
  transient local, as AMCL publishes it) out at ``localization_rate``: the
  true pose in ``frame_id`` plus Gaussian noise (``localization_noise``,
  ``localization_yaw_noise``), with that covariance.
- ``ground_truth`` (nav_msgs/Odometry, reliable) out, every step: the true
  pose and velocity in ``frame_id``, for tests, metrics and recordings.
- ``/tf`` (tf2_msgs/TFMessage) out when tf2_msgs is importable (a full ROS
  install): ``odom_frame_id`` -> ``robot_frame_id`` every step and
  ``frame_id`` -> ``odom_frame_id`` (the localizer's estimate) with each
  ``amcl_pose``.
- ``scan`` (sensor_msgs/LaserScan, sensor-data QoS - reliable in lockstep -, frame
  ``robot_frame_id``) out at ``scan_rate``: the world's ray-cast scan
  (REP-117: ``+inf`` no return, ``-inf`` too close).
- ``obstacles`` (visualization_msgs/MarkerArray) out with each scan: one
  id-stable cylinder per moving obstacle, ``scale.x`` = diameter.
- ``clock`` (rosgraph_msgs/Clock) out, every step, after the sensors. The
  name is relative: under a namespace it is ``<ns>/clock``, and the nodes
  that run on it need ``-r /clock:=clock`` (rclpy's time source listens on
  ``/clock``), so two simulated robots keep two clocks apart.
- ``cmd_vel`` (geometry_msgs/Twist or TwistStamped, reliable) in: applied until a newer one arrives or
  it is older than ``cmd_timeout`` (then the robot stops). A command with a
  NaN, infinite or huge value is refused and the robot stops. One topic
  carries one type: the node starts with TwistStamped under
  ``enable_stamped_cmd_vel`` (Twist otherwise), then follows the type of the
  publishers it finds on ``cmd_vel`` in other processes (checked every
  :data:`CMD_VEL_TYPE_CHECK_PERIOD_S` of wall time), so a controller with or
  without stamped commands drives it alike. (In one process DDS refuses a
  publisher whose type differs from a subscription's on the same topic: set
  the parameter alike on both nodes there.)
- ``plan`` (nav_msgs/Path, latched or volatile publishers) in, as a signal only: a plan answers the
  goal, and the first non-empty one starts a world held by ``start_paused``;
  a malformed one (wrong frame, NaN points) is refused.
- ``goal_pose`` (geometry_msgs/PoseStamped) out with ``publish_goal``: the
  scenario's goal, once a subscriber (the global planner) is matched,
  re-sent until a ``plan`` answers (at most
  :data:`~fusion_planner.ros.goal_sender.MAX_GOAL_ATTEMPTS`).
- ``diagnostics`` out: collisions (contact events), minimum clearance,
  travelled distance, distance to the goal, simulated time and the real-time
  factor achieved.
"""

import math
import os
import pathlib
import sys
import time
from dataclasses import dataclass

import numpy as np
from geometry_msgs.msg import (
    PoseStamped, PoseWithCovarianceStamped, TransformStamped, Twist, TwistStamped)
from nav_msgs.msg import OccupancyGrid, Odometry, Path
from rclpy.clock import Clock, ClockType
from rclpy.qos import ReliabilityPolicy
from rosgraph_msgs.msg import Clock as ClockMsg
from sensor_msgs.msg import LaserScan
from visualization_msgs.msg import MarkerArray

try:  # a full ROS install has tf2_msgs; the wheels do not
    from tf2_msgs.msg import TFMessage
except ImportError:
    TFMessage = None

from fusion_planner.core.errors import InvalidInput
from fusion_planner.core.simulation.scenario import load_scenario
from fusion_planner.core.simulation.world import World
from fusion_planner.ros import conversions as conv
from fusion_planner.ros.diagnostics import ERROR, OK, WARN, DiagnosticsReporter
from fusion_planner.ros.parameters import ParameterHandler, ParameterSpec, float_range
from fusion_planner.ros.frames import map_from_odom
from fusion_planner.ros.goal_sender import GoalSender
from fusion_planner.ros.robot_sensors import DriftingOdometry, NoisyLocalizer
from fusion_planner.ros.qos import (
    LATCHED_QOS, RELIABLE_QOS, SENSOR_QOS, LatchedOrVolatile)
from fusion_planner.ros.lifecycle import AUTOSTART_DESCRIPTION, ManagedNode
from fusion_planner.ros.node_main import run_node

NODE_NAME = 'simulator'
PACKAGE = 'fusion_planner'
#: The bundled scenario, relative to the package's share folder.
DEMO_SCENARIO = pathlib.Path('config') / 'scenarios' / 'demo.yaml'

#: Velocity command types ``cmd_vel`` may carry, by their ROS type name.
CMD_VEL_TYPES = {'geometry_msgs/msg/Twist': Twist, 'geometry_msgs/msg/TwistStamped': TwistStamped}
#: Wall period of the check of the type the ``cmd_vel`` publishers use [s].
CMD_VEL_TYPE_CHECK_PERIOD_S = 0.25
#: A command faster than this many times the robot's limits is refused [1].
MAX_COMMAND_FACTOR = 10.0
#: Wall period of the goal publisher's check [s].
GOAL_CHECK_PERIOD_S = 0.25
#: Slack on comparisons of simulated times [s] (sums of steps are inexact).
TIME_EPS_S = 1e-6
#: Longest wall time the simulation waits for a late command [s]; after it
#: the controller is taken for gone and the simulation runs on (the robot
#: stops after cmd_timeout) until commands flow again.
COMMAND_WAIT_LIMIT_S = 1.0
#: Wall period of the sensor messages while the world is held at t = 0 [s].
PAUSED_PUBLISH_PERIOD_S = 0.1
#: Longest wall period of the lockstep simulator's timer [s] (see
#: SimulatorNode._make_step_timer).
LOCKSTEP_POLL_S = 0.05
#: Ticks of the lockstep pace timer per step's wall time [1]: a command that
#: came early steps the world at most 1/PACE_TICKS_PER_STEP of a step late.
PACE_TICKS_PER_STEP = 4
#: The error of a lockstep simulator that receives an unstamped command.
UNSTAMPED_PROBLEM = (
    'lockstep needs stamped velocity commands: cmd_vel carries geometry_msgs/Twist, which '
    'cannot be matched to a step; set enable_stamped_cmd_vel on the controller (TwistStamped '
    'stamped with the sensor data it answers). Running free on the wall clock')


@dataclass(frozen=True)
class SimulatorParams:
    """Tunables of the simulator node (see :data:`PARAMETER_SPECS`)."""

    scenario: str = ''
    frame_id: str = 'map'
    odom_frame_id: str = 'odom'
    robot_frame_id: str = 'base_link'
    odom_scale_error: float = 0.03
    odom_yaw_drift: float = 0.01
    localization_rate: float = 5.0
    localization_noise: float = 0.02
    localization_yaw_noise: float = 0.01
    rate: float = 20.0
    real_time_factor: float = 1.0
    scan_rate: float = 10.0
    cmd_timeout: float = 0.5
    sync_with_controller: bool = True
    max_command_lag: float = 0.25
    publish_goal: bool = False
    start_paused: bool = False
    enable_stamped_cmd_vel: bool = False
    lockstep: bool = False
    lockstep_timeout: float = 5.0
    diagnostics_period: float = 1.0
    autostart: bool = True

    def __post_init__(self):
        if self.scan_rate > self.rate:
            raise InvalidInput(f'scan_rate ({self.scan_rate:g} Hz) cannot exceed the simulation '
                               f'rate ({self.rate:g} Hz)')


#: Every parameter of the node; config/params.yaml lists the same names.
PARAMETER_SPECS = (
    ParameterSpec('scenario', '',
                  "scenario file (the core's YAML schema); '' loads the bundled "
                  'config/scenarios/demo.yaml', read_only=True),
    ParameterSpec('frame_id', 'map',
                  'map frame: of the map, amcl_pose, ground_truth and obstacles', read_only=True),
    ParameterSpec('odom_frame_id', 'odom', 'frame of the wheel odometry (REP-105 odom)',
                  read_only=True),
    ParameterSpec('robot_frame_id', 'base_link', 'robot frame: child of odom, frame of the scan',
                  read_only=True),
    ParameterSpec('odom_scale_error', 0.03,
                  'odometry distance error per metre travelled; 0 with odom_yaw_drift 0: exact '
                  'odometry [1]', float_range(-0.5, 0.5), read_only=True),
    ParameterSpec('odom_yaw_drift', 0.01, 'odometry heading error gained per metre travelled '
                  '[rad/m]', float_range(-1.0, 1.0), read_only=True),
    ParameterSpec('localization_rate', 5.0, 'amcl_pose messages per simulated second [Hz]',
                  float_range(0.1, 100.0), read_only=True),
    ParameterSpec('localization_noise', 0.02, 'standard deviation of x and y of amcl_pose [m]',
                  float_range(0.0, 10.0), read_only=True),
    ParameterSpec('localization_yaw_noise', 0.01, 'standard deviation of the heading of '
                  'amcl_pose [rad]', float_range(0.0, 3.0), read_only=True),
    ParameterSpec('rate', 20.0, 'integration steps per simulated second [Hz]',
                  float_range(1.0, 1000.0), read_only=True),
    ParameterSpec('real_time_factor', 1.0,
                  'simulated seconds per wall second (10: ten times faster than real time) [1]',
                  float_range(0.01, 1000.0)),
    ParameterSpec('scan_rate', 10.0, 'laser scans (and obstacle markers) per simulated second [Hz]',
                  float_range(0.1, 1000.0)),
    ParameterSpec('cmd_timeout', 0.5,
                  'a velocity command older than this (simulated time) stops the robot [s]',
                  float_range(0.01, 60.0)),
    ParameterSpec('sync_with_controller', True,
                  'once cmd_vel commands flow, a step waits (up to 1 s of wall time) while the '
                  'last command is older than max_command_lag, so a busy controller is not '
                  'outrun at a high real_time_factor'),
    ParameterSpec('max_command_lag', 0.25,
                  'largest age of the last command, in simulated time, at which a step goes '
                  "ahead with sync_with_controller; keep it at least the controller's period; "
                  '0: one step per command (controller rate = rate; for a run that repeats '
                  'exactly, use lockstep) [s]',
                  float_range(0.0, 60.0)),
    ParameterSpec('publish_goal', False,
                  "publish the scenario's goal on goal_pose once a subscriber is matched"),
    ParameterSpec('start_paused', False,
                  'hold the world at t = 0 (robot and moving obstacles still, sensors and clock '
                  'still published) until the first non-empty plan appears on plan, so every '
                  'run starts when the robot can move', read_only=True),
    ParameterSpec('enable_stamped_cmd_vel', False,
                  'subscribe cmd_vel as TwistStamped at start-up (Twist otherwise); either way the '
                  'node then follows the type of the cmd_vel publishers it finds', read_only=True),
    ParameterSpec('lockstep', False,
                  'publish the whole sensor set every step and step on only when the cmd_vel '
                  "TwistStamped stamped with that set's time has arrived: the same scenario "
                  'gives the same run at any real_time_factor (needs stamped commands)',
                  read_only=True),
    ParameterSpec('lockstep_timeout', 5.0,
                  'with lockstep: wall time a step waits for its command before the world runs '
                  'free (reported) until the controller answers a step again [s]',
                  float_range(0.01, 600.0)),
    ParameterSpec('diagnostics_period', 1.0, 'wall period of the diagnostics status [s]',
                  float_range(0.05, 60.0), read_only=True),
    ParameterSpec('autostart', True, AUTOSTART_DESCRIPTION, read_only=True),
)


def share_file(relative):
    """A file of the package's share folder.

    Parameters
    ----------
    relative : str or os.PathLike
        Path inside ``share/fusion_planner``, e.g. ``'config/params.yaml'``.

    Returns
    -------
    pathlib.Path
        The file of the install found by ament_index_python (a colcon
        workspace), else of the Python prefix (a pip install), else of the
        source tree. It may not exist (the source tree's path is returned
        then); whoever opens it reports that.
    """
    candidates = []
    try:
        from ament_index_python.packages import get_package_share_directory
        candidates.append(pathlib.Path(get_package_share_directory(PACKAGE)))
    except (ImportError, LookupError, KeyError, OSError, ValueError):
        pass  # not in an ament workspace
    candidates.append(pathlib.Path(sys.prefix) / 'share' / PACKAGE)
    candidates.append(pathlib.Path(__file__).resolve().parents[2])
    for folder in candidates:
        if (folder / relative).is_file():
            return folder / relative
    return candidates[-1] / relative


def default_scenario_path():
    """The bundled demo scenario, ``share/fusion_planner/config/scenarios/demo.yaml``.

    Returns
    -------
    pathlib.Path
        See :func:`share_file`.
    """
    return share_file(DEMO_SCENARIO)


def odometry_msg(pose, velocity, frame_id, child_frame_id, stamp):
    """A ``nav_msgs/Odometry`` of ``(x, y, yaw)`` in ``frame_id`` and ``(v, omega)``."""
    msg = Odometry()
    msg.header.frame_id = frame_id
    msg.header.stamp = stamp
    msg.child_frame_id = child_frame_id
    msg.pose.pose = conv.xy_yaw_to_pose(pose)
    msg.twist.twist.linear.x = float(velocity[0])
    msg.twist.twist.angular.z = float(velocity[1])
    return msg


def scan_to_msg(scan, config, frame_id, stamp, scan_period):
    """A ``sensor_msgs/LaserScan`` of a world scan.

    Parameters
    ----------
    scan : fusion_planner.core.simulation.world.LaserScan
        Beam angles (n,) [rad], robot frame, increasing; ranges (n,) [m].
    config : fusion_planner.core.simulation.world.ScanConfig
    frame_id : str
        The robot frame (the laser sits at the robot centre).
    stamp : builtin_interfaces.msg.Time
    scan_period : float
        Time between scans [s] (``scan_time``).

    Returns
    -------
    sensor_msgs.msg.LaserScan
        ``angle_min`` the first beam, ``angle_increment`` the beam spacing
        (the field of view for a single beam), ranges as float32 with
        ``+inf``/``-inf`` kept (REP-117).
    """
    msg = LaserScan()
    msg.header.frame_id = frame_id
    msg.header.stamp = stamp
    angles = scan.angles
    msg.angle_min = float(angles[0])
    msg.angle_max = float(angles[-1])
    msg.angle_increment = float(angles[1] - angles[0]) if len(angles) > 1 else float(config.fov)
    msg.time_increment = 0.0
    msg.scan_time = float(scan_period)
    msg.range_min = float(config.range_min)
    msg.range_max = float(config.range_max)
    msg.ranges = scan.ranges.astype(np.float32)
    return msg


class SimulatorNode(ManagedNode):
    """The simulator node (see the module docstring for its interface).

    A lifecycle node (:class:`~fusion_planner.ros.lifecycle.ManagedNode`):
    configuring builds a fresh world from the scenario (loaded once, at
    construction); the world steps only while active.

    Parameters
    ----------
    node_name : str
    **kwargs
        Passed to :class:`rclpy.node.Node` (``context``, ``namespace``,
        ``parameter_overrides``, ``cli_args`` ...).

    Raises
    ------
    InvalidInput
        Bad start-up parameters, or a scenario file that cannot be loaded
        (:class:`~fusion_planner.core.simulation.scenario.ScenarioError`,
        :class:`~fusion_planner.core.errors.MapError`).

    Attributes
    ----------
    scenario : Scenario
    world : World
        The simulated world; read it only from the executor's thread or
        after spinning stopped.
    """

    def __init__(self, node_name=NODE_NAME, **kwargs):
        super().__init__(node_name, **kwargs)
        self._params = ParameterHandler(self, SimulatorParams, PARAMETER_SPECS,
                                        on_change=self._on_parameters_changed)
        params = self._params.current
        path = params.scenario or str(default_scenario_path())
        self.scenario = load_scenario(os.path.expanduser(path))
        s = self.scenario
        if s.robot.max_speed / params.rate > s.robot.radius:
            raise InvalidInput(
                f'rate {params.rate:g} Hz lets the robot move more than its radius '
                f'({s.robot.radius:g} m) in one step at {s.robot.max_speed:g} m/s: '
                'contacts with thin walls could be missed; raise rate')
        self._scenario_path = path
        self._frame_id = params.frame_id
        self._odom_frame_id = params.odom_frame_id
        self._robot_frame_id = params.robot_frame_id
        self._dt = 1.0 / params.rate
        self._goal = np.asarray(s.goal, dtype=float)
        self._steady = Clock(clock_type=ClockType.STEADY_TIME)
        self._step_timer = None
        self._diagnostics = DiagnosticsReporter(self, 0.0)
        self._diagnostics.update(WARN, 'unconfigured')
        self.start(params.autostart)

    def configure(self):
        """A fresh world; the publishers, subscriptions and timers."""
        params = self._params.current
        s = self.scenario
        self.world = World(s.grid, s.robot, s.start, s.unknown_obstacles, s.moving_obstacles,
                           s.scan, seed=s.seed)
        self._odometry_model = DriftingOdometry(params.odom_scale_error, params.odom_yaw_drift)
        self._localizer = NoisyLocalizer(params.localization_noise,
                                         params.localization_yaw_noise, s.seed)
        self._next_localization_time = 0.0
        self._command = (0.0, 0.0)
        self._command_time = -math.inf  # simulated time of the last command [s]
        self._commands_flow = False  # a controller is sending commands (see max_command_lag)
        self._waiting_since = None   # wall time the simulation began waiting for one [s]
        self._next_scan_time = 0.0
        # lockstep state
        self._lockstep_engaged = params.lockstep  # steps wait for their command
        self._step_answered = True  # the command answering the current step has arrived
        self._step_published_wall = -math.inf  # wall time the current step went out [s]
        self._lockstep_problem = ''  # why the world runs free despite lockstep ('' none)
        self._held_messages = None  # the sensor set of t = 0 while held
        self.min_clearance = self.world.clearance()
        self.distance_travelled = 0.0
        self._rtf_mark = (time.monotonic(), 0.0)  # (wall, sim) at the last status
        self._rtf = 0.0
        # goal publishing state
        self._paused = params.start_paused  # held at t = 0 until the first plan
        self._paused_published = -math.inf  # wall time of the last sensors while held [s]

        guard = self._diagnostics.guard
        publisher = self.create_lifecycle_publisher
        self._map_pub = publisher(OccupancyGrid, 'map', LATCHED_QOS)
        self._odom_pub = publisher(Odometry, 'odom', RELIABLE_QOS)
        self._truth_pub = publisher(Odometry, 'ground_truth', RELIABLE_QOS)
        self._localization_pub = publisher(PoseWithCovarianceStamped, 'amcl_pose', LATCHED_QOS)
        self._tf_pub = publisher(TFMessage, '/tf', RELIABLE_QOS) if TFMessage else None
        # lockstep: a lost scan would leave its step unanswered
        self._scan_pub = publisher(LaserScan, 'scan', RELIABLE_QOS if params.lockstep
                                   else SENSOR_QOS)
        self._obstacles_pub = publisher(MarkerArray, 'obstacles', RELIABLE_QOS)
        self._clock_pub = publisher(ClockMsg, 'clock', RELIABLE_QOS)
        self._goal_sender = GoalSender(publisher(PoseStamped, 'goal_pose', RELIABLE_QOS),
                                       self.get_logger())
        self._cmd_vel_sub = self.create_subscription(
            TwistStamped if params.enable_stamped_cmd_vel else Twist, 'cmd_vel',
            guard('cmd_vel', self._on_cmd_vel_then_step), RELIABLE_QOS)
        self._plan_sub = LatchedOrVolatile(self, Path, 'plan', guard('plan', self._on_plan),
                                           ReliabilityPolicy.RELIABLE)
        self.create_timer(CMD_VEL_TYPE_CHECK_PERIOD_S,
                          guard('cmd_vel type', self._match_cmd_vel_type), clock=self._steady)
        self._step_timer = self._make_step_timer(params)
        self._pace_timer = self._make_pace_timer(params)  # lockstep: an early answer's step
        self.create_timer(GOAL_CHECK_PERIOD_S, guard('goal', self._on_goal_timer),
                          clock=self._steady)
        self.create_timer(params.diagnostics_period, guard('status', self._publish_status),
                          clock=self._steady)
        self.get_logger().info(
            f"scenario '{s.name}' loaded from {self._scenario_path}: map {s.grid.width} x "
            f'{s.grid.height} cells, {len(s.unknown_obstacles)} unknown and '
            f'{len(s.moving_obstacles)} moving obstacles, '
            f'goal ({self._goal[0]:.2f}, {self._goal[1]:.2f})')

    def activate(self):
        """Publish the known map (latched) and start stepping."""
        self._map_pub.publish(conv.grid_map_to_occupancy_grid(
            self.scenario.grid, self._frame_id, conv.seconds_to_stamp(0.0)))
        self._diagnostics.update(OK, 'running', collisions=0)

    def deactivate(self):
        self._diagnostics.update(WARN, 'inactive: the world is held')

    def cleanup(self):
        """The timers went with the other entities."""
        self._step_timer = None
        self._pace_timer = None

    # -- inputs ---------------------------------------------------------------

    def _on_cmd_vel(self, msg):
        """Take a velocity command; a bad one stops the robot and is reported."""
        robot = self.scenario.robot
        self._command_time = self.world.time
        self._commands_flow = True
        if self._params.current.lockstep:
            self._note_step_answer(msg)
        try:
            v, omega = conv.twist_to_velocity(msg, 'cmd_vel')
            if abs(v) > MAX_COMMAND_FACTOR * robot.max_speed \
                    or abs(omega) > MAX_COMMAND_FACTOR * robot.max_omega:
                raise InvalidInput(
                    f'cmd_vel ({v:.3g} m/s, {omega:.3g} rad/s) exceeds '
                    f'{MAX_COMMAND_FACTOR:g} times '
                    f'the robot limits ({robot.max_speed:g} m/s, {robot.max_omega:g} rad/s)')
        except InvalidInput:
            self._command = (0.0, 0.0)  # refused: the robot stops for this command
            raise
        self._command = (v, omega)

    def _on_cmd_vel_then_step(self, msg):
        """Take a command; in lockstep, step when it answers the step (and the pace allows)."""
        try:
            self._on_cmd_vel(msg)
        finally:
            params = self._params.current
            if params.lockstep and self._lockstep_engaged and self.active \
                    and self._step_answered and not self._paused:
                self._step_when_due(params)

    def _note_step_answer(self, msg):
        """Lockstep: whether ``msg`` answers the current step (its stamp is the step's).

        While the world runs free (after a timeout), an answer to an earlier
        step engages the lockstep again: the world then waits for the
        current step's answer.
        """
        if not hasattr(msg, 'header'):
            if self._lockstep_problem != UNSTAMPED_PROBLEM:
                self._lockstep_problem = UNSTAMPED_PROBLEM
                self.get_logger().error(UNSTAMPED_PROBLEM)
                self._diagnostics.update(ERROR, UNSTAMPED_PROBLEM, lockstep='off')
            self._set_engaged(False)
            return
        stamp_ns, step_ns = conv.stamp_to_nanoseconds(msg.header.stamp), self._step_stamp_ns()
        if stamp_ns == step_ns:
            self._step_answered = True
        elif self._lockstep_engaged or stamp_ns > step_ns:
            return  # not an answer to this step: applied, not matched
        # Running free, any answer shows the controller is back. Waiting for
        # one stamped with the current step would never end: the free world
        # moves on faster than an answer can come back.
        if not self._lockstep_engaged:
            self._set_engaged(True)
            self._lockstep_problem = ''
            self.get_logger().info('lockstep: the controller answers the steps again')

    def _step_stamp_ns(self):
        """Stamp of the current step's sensor set [ns]."""
        return conv.stamp_to_nanoseconds(conv.seconds_to_stamp(self.world.time))

    def _match_cmd_vel_type(self):
        """Subscribe ``cmd_vel`` with the message type its publishers use."""
        topic = self.resolve_topic_name('cmd_vel')
        types = {info.topic_type for info in self.get_publishers_info_by_topic(topic)}
        known = [CMD_VEL_TYPES[name] for name in sorted(types) if name in CMD_VEL_TYPES]
        if len(known) != 1 or known[0] is self._cmd_vel_sub.msg_type:
            if len(known) > 1:
                self._diagnostics.log.warning(
                    'cmd_vel/types', f'cmd_vel has Twist and TwistStamped publishers: '
                                     f'listening to {self._cmd_vel_sub.msg_type.__name__} only')
            return
        self.destroy_subscription(self._cmd_vel_sub)
        self._cmd_vel_sub = self.create_subscription(
            known[0], 'cmd_vel', self._diagnostics.guard('cmd_vel', self._on_cmd_vel_then_step),
            RELIABLE_QOS)
        self.get_logger().info(f'cmd_vel is published as {known[0].__name__}: listening to that')

    def _on_plan(self, msg):
        """A plan answers the goal; the first non-empty one starts a paused world."""
        path = conv.plan_from_msg(msg, self._frame_id, 'plan')  # refuses one nobody can follow
        self._goal_sender.on_plan()
        if self._paused and path is not None:
            self._paused = False
            self._command = (0.0, 0.0)  # the first step leaves the robot at rest
            self._step_answered = True
            if self._params.current.lockstep:
                self._step_when_due(self._params.current)
            self.get_logger().info('first plan received: the world starts moving')

    def _on_parameters_changed(self, old, new):
        if new.real_time_factor != old.real_time_factor and self._step_timer is not None:
            self.destroy_timer(self._step_timer)
            self._step_timer = self._make_step_timer(new)
            self.destroy_timer(self._pace_timer)
            self._pace_timer = self._make_pace_timer(new)
        self.get_logger().info(f'parameters changed: real_time_factor={new.real_time_factor:g}, '
                               f'scan_rate={new.scan_rate:g} Hz, '
                               f'cmd_timeout={new.cmd_timeout:g} s, '
                               f'publish_goal={new.publish_goal}')

    # -- simulation -------------------------------------------------------------

    def _wall_period(self, params):
        """Wall time of one step at ``real_time_factor`` [s]."""
        return self._dt / params.real_time_factor

    def _make_step_timer(self, params):
        """The timer that steps a free-running world; in lockstep it only watches.

        In lockstep the commands step the world (:meth:`_step_when_due`): the
        timer publishes the held world and notices an unanswered step, at
        most every :data:`LOCKSTEP_POLL_S`.
        """
        period = self._wall_period(params)
        if params.lockstep and self._lockstep_engaged:
            period = max(period, LOCKSTEP_POLL_S)
        return self.create_timer(period,
                                 self._diagnostics.guard('step', self._on_step_timer),
                                 clock=self._steady)

    def _make_pace_timer(self, params):
        """A timer of a fraction of a step's wall time, cancelled until an early answer."""
        timer = self.create_timer(self._wall_period(params) / PACE_TICKS_PER_STEP,
                                  self._diagnostics.guard('step', self._on_pace_timer),
                                  clock=self._steady)
        timer.cancel()
        return timer

    def _on_step_timer(self):
        """Step when the world may move: not held, not waiting for the controller."""
        if not self.active:
            return
        params = self._params.current
        if self._paused:
            now = time.monotonic()
            if now - self._paused_published >= PAUSED_PUBLISH_PERIOD_S:
                self._paused_published = now
                if self._held_messages is None:
                    self._held_messages = self._sensor_messages(params, force_scan=True)
                self._publish(self._held_messages)
            return
        if params.lockstep and self._lockstep_engaged:
            if self._step_answered:  # the first step; the others follow their commands
                self._step_when_due(params)
                return
            self._check_step_timeout(params)
            if self._lockstep_engaged:
                return
        elif not params.lockstep and self._command_late(params):
            return
        self.step()

    def step(self):
        """Advance the world by one step and publish clock, odometry and (when due) the scan."""
        params = self._params.current
        world = self.world
        v, omega = self._command
        if world.time - self._command_time > params.cmd_timeout:
            v = omega = 0.0
        before = world.pose[:2].copy()
        contact = world.step(v, omega, self._dt)
        self._odometry_model.step(world.velocity[0], world.velocity[1], self._dt)
        if contact:
            what = _contact_kind(world.contacts[-1])
            self._diagnostics.update(
                WARN, f'collision {world.contact_events} ({what}) at t = {world.time:.2f} s, '
                      f'robot at ({world.pose[0]:.2f}, {world.pose[1]:.2f})',
                collisions=world.contact_events)
            self.get_logger().warning(
                f'collision (contact event {world.contact_events}, {what}) at '
                f't = {world.time:.2f} s, robot at ({world.pose[0]:.2f}, {world.pose[1]:.2f}) '
                f'heading {world.pose[2]:.2f} rad, speed {world.velocity[0]:.2f} m/s')
        self.distance_travelled += float(np.hypot(*(world.pose[:2] - before)))
        self.min_clearance = min(self.min_clearance, world.clearance())
        self._step_answered = False
        self._step_published_wall = time.monotonic()
        self._publish(self._sensor_messages(params))

    def _publish(self, messages):
        for publisher, msg in messages:
            publisher.publish(msg)

    def _sensor_messages(self, params, force_scan=False):
        """``(publisher, message)`` of a step: odometry, scan and obstacles when due, clock.

        In lockstep the localization pose and the scan are due every step.
        """
        world = self.world
        stamp = conv.seconds_to_stamp(world.time)
        # Sensors first, the clock last: a node whose timer wakes on the new
        # time has (most likely) already received the data of that time.
        odometry = self._odometry_model
        messages = [
            (self._odom_pub, odometry_msg(odometry.pose, odometry.velocity, self._odom_frame_id,
                                          self._robot_frame_id, stamp)),
            (self._truth_pub, odometry_msg(world.pose, world.velocity, self._frame_id,
                                           self._robot_frame_id, stamp))]
        transforms = [(self._odom_frame_id, odometry.pose)]
        if params.lockstep or world.time + TIME_EPS_S >= self._next_localization_time:
            self._next_localization_time = world.time + 1.0 / params.localization_rate
            estimate = self._localizer.estimate(world.pose)
            messages.append((self._localization_pub, self._localization_msg(estimate, stamp)))
            transforms.append((self._frame_id, map_from_odom(estimate, odometry.pose)))
        if self._tf_pub is not None:
            messages.append((self._tf_pub, self._tf_msg(transforms, stamp)))
        if params.lockstep or force_scan or world.time + TIME_EPS_S >= self._next_scan_time:
            period = self._dt if params.lockstep else 1.0 / params.scan_rate
            self._next_scan_time = world.time + period
            messages.append((self._scan_pub, scan_to_msg(world.scan(), self.scenario.scan,
                                                         self._robot_frame_id, stamp, period)))
            tracked = world.tracked_obstacles()
            if len(tracked):
                messages.append((self._obstacles_pub, conv.obstacles_to_markers(
                    tracked, self._frame_id, stamp, ns='moving_obstacles')))
            elif params.lockstep:  # every step has its set: "no moving obstacles", stamped
                messages.append((self._obstacles_pub, MarkerArray(
                    markers=[conv.delete_all_marker(self._frame_id, stamp)])))
        messages.append((self._clock_pub, ClockMsg(clock=stamp)))
        return messages

    def _check_step_timeout(self, params):
        """Lockstep: run free (reported) when the current step waited too long for its command."""
        if self._step_answered \
                or time.monotonic() - self._step_published_wall < params.lockstep_timeout:
            return
        self._set_engaged(False)
        self._lockstep_problem = (
            f'lockstep: no cmd_vel stamped {self.world.time:.3f} s (the sensor set it answers) '
            f'within {params.lockstep_timeout:g} s of wall time: running free until the '
            'controller answers a step again (the robot stops after cmd_timeout)')
        self.get_logger().warning(self._lockstep_problem)
        self._diagnostics.update(WARN, self._lockstep_problem, lockstep='timed out')

    def _set_engaged(self, engaged):
        """Lockstep: whether the steps wait for their commands; the step timer follows."""
        if engaged == self._lockstep_engaged:
            return
        self._lockstep_engaged = engaged
        if self._step_timer is not None:
            self.destroy_timer(self._step_timer)
            self._step_timer = self._make_step_timer(self._params.current)

    def _step_due(self, params):
        """Whether a step's wall time at ``real_time_factor`` has passed since the last one."""
        return time.monotonic() >= self._step_published_wall + self._wall_period(params)

    def _step_when_due(self, params):
        """Lockstep, the step answered: step now, or when its wall time has come."""
        if self._step_due(params):
            self.step()
        elif self._pace_timer.is_canceled():
            self._pace_timer.reset()

    def _on_pace_timer(self):
        """Step an early-answered step once its wall time has come."""
        params = self._params.current
        if not self._step_due(params):
            return
        self._pace_timer.cancel()
        if self.active and self._step_answered and not self._paused:
            self.step()

    def _command_late(self, params):
        """Whether this step waits for the controller's next command (see max_command_lag)."""
        lag = self.world.time - self._command_time
        if not params.sync_with_controller or not self._commands_flow \
                or lag <= params.max_command_lag + TIME_EPS_S:
            self._waiting_since = None
            return False
        now = time.monotonic()
        if self._waiting_since is None:
            self._waiting_since = now
        if now - self._waiting_since < COMMAND_WAIT_LIMIT_S:
            return True
        self.get_logger().warning(
            f'no cmd_vel for {COMMAND_WAIT_LIMIT_S:g} s of wall time: running on without the '
            'controller (the robot stops after cmd_timeout)')
        self._commands_flow = False
        self._waiting_since = None
        return False

    def _localization_msg(self, pose, stamp):
        msg = PoseWithCovarianceStamped()
        msg.header.frame_id = self._frame_id
        msg.header.stamp = stamp
        msg.pose.pose = conv.xy_yaw_to_pose(pose)
        msg.pose.covariance = self._localizer.covariance()
        return msg

    def _tf_msg(self, transforms, stamp):
        """TFMessage of ``(parent frame, (x, y, yaw))`` pairs: odom -> base_link, map -> odom."""
        children = {self._odom_frame_id: self._robot_frame_id,
                    self._frame_id: self._odom_frame_id}
        msg = TFMessage()
        for parent, (x, y, yaw) in transforms:
            t = TransformStamped()
            t.header.frame_id, t.header.stamp = parent, stamp
            t.child_frame_id = children[parent]
            t.transform.translation.x, t.transform.translation.y = float(x), float(y)
            t.transform.rotation = conv.quaternion_of_yaw(yaw)
            msg.transforms.append(t)
        return msg

    # -- goal and status ----------------------------------------------------------

    def _on_goal_timer(self):
        """Send the scenario's goal once the planner listens; re-send until a plan answers."""
        if self.active and self._params.current.publish_goal:
            self._goal_sender.poll(self._goal, self._frame_id,
                                   conv.seconds_to_stamp(self.world.time))

    def _publish_status(self):
        """Diagnostics heartbeat: collisions, clearance, distances, achieved speed."""
        if not self.active:
            return  # the lifecycle transitions report themselves
        world = self.world
        wall, sim = time.monotonic(), world.time
        if wall > self._rtf_mark[0]:
            self._rtf = (sim - self._rtf_mark[1]) / (wall - self._rtf_mark[0])
        self._rtf_mark = (wall, sim)
        collisions = world.contact_events
        level = OK if collisions == 0 and not self._lockstep_problem else WARN
        if self._lockstep_problem == UNSTAMPED_PROBLEM:
            level = ERROR
        lockstep = 'off' if not self._params.current.lockstep \
            else 'on' if self._lockstep_engaged else self._lockstep_problem
        self._diagnostics.update(
            level, f'{collisions} collision(s), t = {sim:.1f} s',
            lockstep=lockstep,
            collisions=collisions, sim_time_s=sim, min_clearance_m=self.min_clearance,
            distance_travelled_m=self.distance_travelled,
            distance_to_goal_m=float(np.hypot(*(world.pose[:2] - self._goal))),
            real_time_factor=self._rtf, x=float(world.pose[0]), y=float(world.pose[1]))


def _contact_kind(event):
    """What a contact event (a ContactEvent) touched and how it was judged, in words for the log."""
    if event.person is None:
        return 'with a wall or static obstacle'
    if event.passive:
        return f'with moving obstacle {event.person}, passive: the robot could not have escaped'
    why = 'an escape existed' if event.escape else 'the robot was not standing or retreating'
    return f'with moving obstacle {event.person}, avoidable: {why}'


def main(args=None):
    """Run the simulator node until Ctrl-C or shutdown; returns the exit code."""
    return run_node(SimulatorNode, NODE_NAME, args)


if __name__ == '__main__':
    raise SystemExit(main())
