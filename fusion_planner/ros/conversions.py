"""Every conversion between ROS messages and the core's arrays, validated.

The nodes call these and nothing else to turn a message into core types and
back, so each check lives in one place. Every function validates what it
reads and raises :class:`~fusion_planner.core.errors.InvalidInput` (or
:class:`~fusion_planner.core.errors.MapError` for maps) with one sentence;
no raw ``ValueError``, ``IndexError`` or ``ZeroDivisionError`` escapes.

Conventions:

- Poses are ``(x, y, yaw)`` tuples of float [m, m, rad] in the map frame;
  yaw is in ``(-pi, pi]``. Paths are ``(N, 2)`` float64 arrays [m].
- Magnitudes: a position farther than :data:`MAX_COORDINATE_M` from the
  frame's origin (a pose, a path point, a marker, a map corner, a scan's
  ``range_max``) and a speed or turn rate beyond :data:`MAX_RATE` are refused
  as corrupt, like NaN: no real robot has them, and the planners' arithmetic
  (squared distances, cell indices) would overflow on them.
- Tracked obstacles are ``(K, 5)`` float64 arrays of ``x, y, vx, vy, radius``
  [m, m, m/s, m/s, m], map frame (:data:`OBSTACLE_COLUMNS`).
- Velocity commands are ``(v, omega)``: forward speed [m/s] along the robot's
  x axis and yaw rate [rad/s] (REP-103).
- Frames (:func:`check_frame`): a message whose ``header.frame_id`` differs
  from the expected frame is refused; an *empty* ``frame_id`` is accepted and
  taken to be the expected frame, because many tools (``ros2 topic pub``,
  hand-written test publishers) leave it empty. Comparison is exact: no tf2
  lookup happens here.
- Quaternions (:func:`yaw_of_quaternion`): a zero or non-finite quaternion is
  refused; one whose norm lies within :data:`QUATERNION_NORM_TOLERANCE` of 1
  is normalised; anything further from unit length is refused as corrupt.
- An empty ``nav_msgs/Path`` is how the global planner says "no plan" (it
  publishes one when planning fails so followers stop): :func:`plan_from_msg`
  gives None for it, :func:`path_from_msg` refuses it.
"""

import array
import math

import numpy as np
from builtin_interfaces.msg import Time
from geometry_msgs.msg import Point, Pose, PoseStamped, Quaternion, Twist, TwistStamped
from nav_msgs.msg import OccupancyGrid, Path
from visualization_msgs.msg import Marker, MarkerArray

from fusion_planner.core import map_files, raster
from fusion_planner.core.errors import InvalidInput, MapError
from fusion_planner.core.grid import DEFAULT_MAX_CELLS
from fusion_planner.core.local_planning.controller_base import check_followable

#: A quaternion whose norm differs from 1 by at most this [1] is normalised;
#: a larger difference means a corrupt message and is refused.
QUATERNION_NORM_TOLERANCE = 0.05

#: Nanoseconds per second.
NS_PER_S = 1_000_000_000

#: Largest accepted distance [m] of a position from its frame's origin; UTM
#: coordinates reach ~1e7 m.
MAX_COORDINATE_M = 1e9
#: Largest accepted speed [m/s] or turn rate [rad/s] of odometry or a command.
MAX_RATE = 1e3

#: Column names of a tracked-obstacle array, shape (K, 5).
OBSTACLE_COLUMNS = ('x', 'y', 'vx', 'vy', 'radius')

#: Smallest accepted cylinder diameter [m]; smaller scales (zero included) are
#: refused as uninitialised markers.
MIN_OBSTACLE_DIAMETER_M = 1e-3
#: Default largest accepted cylinder diameter [m]; larger is refused as bogus.
DEFAULT_MAX_OBSTACLE_DIAMETER_M = 50.0
#: Default time [s] after which an obstacle not seen again is forgotten.
DEFAULT_OBSTACLE_TIMEOUT_S = 1.0
#: Default speed [m/s] above which an id's jump is taken for a teleport: the
#: track restarts with zero velocity instead of reporting that speed.
DEFAULT_MAX_OBSTACLE_SPEED_MPS = 10.0
#: Default weight [1] of the previous velocity in the exponential smoothing
#: of estimated obstacle velocities (0: raw finite differences).
DEFAULT_VELOCITY_SMOOTHING = 0.3
#: Default cap on the number of tracks kept [1] (bounds memory on floods).
DEFAULT_MAX_TRACKS = 1000
#: Height [m] of the cylinders drawn by :func:`obstacles_to_markers`.
OBSTACLE_MARKER_HEIGHT_M = 1.0


# -- stamps and frames --------------------------------------------------------

def stamp_to_seconds(stamp):
    """Seconds of a ``builtin_interfaces/Time``.

    Parameters
    ----------
    stamp : builtin_interfaces.msg.Time

    Returns
    -------
    float
        ``sec + nanosec * 1e-9`` [s].

    Examples
    --------
    >>> stamp_to_seconds(seconds_to_stamp(12.25))
    12.25
    """
    return stamp.sec + stamp.nanosec / NS_PER_S


def stamp_to_nanoseconds(stamp):
    """Integer nanoseconds of a ``builtin_interfaces/Time`` (exact, unlike seconds).

    Examples
    --------
    >>> stamp_to_nanoseconds(seconds_to_stamp(1.5))
    1500000000
    """
    return stamp.sec * NS_PER_S + stamp.nanosec


def seconds_to_stamp(seconds):
    """A ``builtin_interfaces/Time`` for a time in seconds.

    Parameters
    ----------
    seconds : float
        Time [s], finite and >= 0.

    Returns
    -------
    builtin_interfaces.msg.Time

    Raises
    ------
    InvalidInput
        If ``seconds`` is negative, NaN, infinite or beyond the int32 range
        of ``Time.sec``.

    Examples
    --------
    >>> seconds_to_stamp(1.5)
    builtin_interfaces.msg.Time(sec=1, nanosec=500000000)
    """
    value = _finite(seconds, 'a time stamp')
    if value < 0 or value >= 2 ** 31:
        raise InvalidInput(f'a time stamp must lie in [0, 2^31) s, got {value!r}')
    total_ns = round(value * NS_PER_S)
    return Time(sec=total_ns // NS_PER_S, nanosec=total_ns % NS_PER_S)


def check_frame(frame_id, expected, what):
    """Refuse a frame other than the expected one.

    Parameters
    ----------
    frame_id : str
        The message's ``header.frame_id``.
    expected : str
        The frame the node works in (its ``frame_id`` parameter).
    what : str
        Name of the message for the error sentence, e.g. ``'goal'``.

    Returns
    -------
    str
        ``expected`` (an empty ``frame_id`` is taken to mean it).

    Raises
    ------
    InvalidInput
        If ``frame_id`` is non-empty and differs from ``expected``.

    Notes
    -----
    No transform is looked up (the test wheels have no tf2): a pose in
    another frame cannot be used and is refused with a clear message.

    Examples
    --------
    >>> check_frame('', 'map', 'goal')
    'map'
    """
    if frame_id and frame_id != expected:
        raise InvalidInput(f"{what} is in frame '{frame_id}' but this node works in '{expected}'")
    return expected


# -- poses and quaternions ----------------------------------------------------

def yaw_of_quaternion(q, what='orientation'):
    """Yaw of a ``geometry_msgs/Quaternion`` (rotation about z).

    Parameters
    ----------
    q : geometry_msgs.msg.Quaternion
    what : str
        Name used in the error sentence.

    Returns
    -------
    float
        Yaw [rad] in ``[-pi, pi]``; roll and pitch are discarded.

    Raises
    ------
    InvalidInput
        If a component is NaN or infinite, the quaternion is zero, or its
        norm differs from 1 by more than :data:`QUATERNION_NORM_TOLERANCE`.

    Notes
    -----
    ``yaw = atan2(2 (w z + x y), 1 - 2 (y^2 + z^2))`` on the normalised
    quaternion.

    Examples
    --------
    >>> round(yaw_of_quaternion(quaternion_of_yaw(1.0)), 12)
    1.0
    """
    x, y, z, w = (_finite(v, what) for v in (q.x, q.y, q.z, q.w))
    norm = math.sqrt(x * x + y * y + z * z + w * w)
    if norm == 0.0:
        raise InvalidInput(f'{what} is the zero quaternion, which is no rotation')
    if abs(norm - 1.0) > QUATERNION_NORM_TOLERANCE:
        raise InvalidInput(
            f'{what} quaternion has norm {norm:.4g}, too far from 1 to be normalised')
    x, y, z, w = x / norm, y / norm, z / norm, w / norm
    return math.atan2(2.0 * (w * z + x * y), 1.0 - 2.0 * (y * y + z * z))


def quaternion_of_yaw(yaw):
    """A ``geometry_msgs/Quaternion`` rotating by ``yaw`` [rad] about z."""
    half = 0.5 * float(yaw)
    return Quaternion(x=0.0, y=0.0, z=math.sin(half), w=math.cos(half))


def xy_yaw_to_pose(pose):
    """A ``geometry_msgs/Pose`` of ``(x, y, yaw)`` [m, m, rad] (z = 0)."""
    msg = Pose()
    msg.position.x, msg.position.y = float(pose[0]), float(pose[1])
    msg.orientation = quaternion_of_yaw(pose[2])
    return msg


def pose_to_xy_yaw(pose, what='pose'):
    """Planar pose of a ``geometry_msgs/Pose``.

    Parameters
    ----------
    pose : geometry_msgs.msg.Pose
    what : str
        Name used in the error sentence.

    Returns
    -------
    tuple of float
        ``(x, y, yaw)`` [m, m, rad]; z is ignored.

    Raises
    ------
    InvalidInput
        If x or y is NaN, infinite or beyond :data:`MAX_COORDINATE_M`, or the
        orientation is refused by :func:`yaw_of_quaternion`.
    """
    x = _finite(pose.position.x, f'{what} x', MAX_COORDINATE_M)
    y = _finite(pose.position.y, f'{what} y', MAX_COORDINATE_M)
    return x, y, yaw_of_quaternion(pose.orientation, f'{what} orientation')


def pose_stamped_to_xy_yaw(msg, frame_id, what='pose'):
    """Planar pose of a ``geometry_msgs/PoseStamped`` in ``frame_id``.

    Parameters
    ----------
    msg : geometry_msgs.msg.PoseStamped
    frame_id : str
        Expected frame (see :func:`check_frame`).
    what : str
        Name used in the error sentence.

    Returns
    -------
    tuple of float
        ``(x, y, yaw)`` [m, m, rad].

    Raises
    ------
    InvalidInput
        Wrong frame, non-finite position, bad quaternion.
    """
    check_frame(msg.header.frame_id, frame_id, what)
    return pose_to_xy_yaw(msg.pose, what)


def pose_with_covariance_to_xy_yaw(msg, frame_id, what='pose'):
    """Planar pose of a ``geometry_msgs/PoseWithCovarianceStamped`` (e.g. AMCL).

    Parameters, returns and errors as :func:`pose_stamped_to_xy_yaw`; a
    covariance with a NaN or infinite entry (a localizer that lost track) is
    refused too (InvalidInput).
    """
    check_frame(msg.header.frame_id, frame_id, what)
    if not all(math.isfinite(value) for value in msg.pose.covariance):
        raise InvalidInput(f'{what} covariance has a NaN or infinite entry')
    return pose_to_xy_yaw(msg.pose.pose, what)


def odometry_to_xy_yaw(msg, frame_id, what='odometry'):
    """Planar pose of a ``nav_msgs/Odometry`` whose header frame is ``frame_id``.

    Parameters, returns and errors as :func:`pose_stamped_to_xy_yaw`; the
    pose covariance and ``child_frame_id`` are not used.
    """
    check_frame(msg.header.frame_id, frame_id, what)
    return pose_to_xy_yaw(msg.pose.pose, what)


def odometry_to_velocity(msg, what='odometry'):
    """Forward speed and yaw rate of a ``nav_msgs/Odometry``.

    Parameters
    ----------
    msg : nav_msgs.msg.Odometry
        Twist in the robot frame (``child_frame_id``), as REP-105 has it.
    what : str
        Name used in the error sentence.

    Returns
    -------
    tuple of float
        ``(v, omega)`` [m/s, rad/s]: ``twist.linear.x`` and ``twist.angular.z``.

    Raises
    ------
    InvalidInput
        If either is NaN, infinite or beyond :data:`MAX_RATE`.
    """
    return twist_to_velocity(msg.twist.twist, what)


# -- velocity commands --------------------------------------------------------

def twist_to_velocity(msg, what='twist'):
    """``(v, omega)`` of a ``geometry_msgs/Twist`` or ``TwistStamped``.

    Parameters
    ----------
    msg : geometry_msgs.msg.Twist or geometry_msgs.msg.TwistStamped
    what : str
        Name used in the error sentence.

    Returns
    -------
    tuple of float
        ``(linear.x, angular.z)`` [m/s, rad/s]; other components are ignored
        (a unicycle cannot follow them).

    Raises
    ------
    InvalidInput
        If either value is NaN, infinite or beyond :data:`MAX_RATE`.
        Saturation to the robot's limits is the caller's job.
    """
    twist = msg.twist if isinstance(msg, TwistStamped) else msg
    return (_finite(twist.linear.x, f'{what} linear.x', MAX_RATE),
            _finite(twist.angular.z, f'{what} angular.z', MAX_RATE))


def velocity_to_twist(v, omega):
    """A ``geometry_msgs/Twist`` for a forward speed [m/s] and yaw rate [rad/s].

    Raises
    ------
    InvalidInput
        If either value is NaN or infinite (a command must never carry one).
    """
    msg = Twist()
    msg.linear.x = _finite(v, 'linear velocity')
    msg.angular.z = _finite(omega, 'angular velocity')
    return msg


def velocity_to_twist_stamped(v, omega, frame_id, stamp):
    """A ``geometry_msgs/TwistStamped`` (robot frame ``frame_id``) at ``stamp``.

    Raises
    ------
    InvalidInput
        If either value is NaN or infinite.
    """
    msg = TwistStamped()
    msg.header.frame_id = frame_id
    msg.header.stamp = stamp
    msg.twist = velocity_to_twist(v, omega)
    return msg


# -- maps ---------------------------------------------------------------------

def occupancy_grid_to_grid_map(msg, frame_id, unknown_is_occupied=False,
                               occupied_threshold=map_files.DEFAULT_OCCUPIED_THRESHOLD,
                               max_cells=DEFAULT_MAX_CELLS):
    """A :class:`~fusion_planner.core.grid.GridMap` from a ``nav_msgs/OccupancyGrid``.

    Parameters
    ----------
    msg : nav_msgs.msg.OccupancyGrid
    frame_id : str
        Expected frame (see :func:`check_frame`).
    unknown_is_occupied : bool
        Treat unknown cells (-1) as obstacles.
    occupied_threshold : int
        A value >= this [percent] is an obstacle, 1..100.
    max_cells : int
        Refuse maps with more cells, before any array is allocated.

    Returns
    -------
    GridMap
        ``(height, width)`` grid, row 0 at ``info.origin`` (no flip); the
        origin yaw comes from the origin quaternion.

    Raises
    ------
    MapError
        Wrong frame, bad quaternion, non-finite origin, bad resolution, data
        length other than width x height, too many cells, values outside
        -1..100, a corner farther than :data:`MAX_COORDINATE_M` from the
        frame's origin.

    Notes
    -----
    ``msg.data`` is read through the buffer protocol (no per-cell Python
    work). The origin's z, roll and pitch are ignored.
    """
    try:
        check_frame(msg.header.frame_id, frame_id, 'map')
        origin_yaw = yaw_of_quaternion(msg.info.origin.orientation, 'map origin orientation')
    except InvalidInput as err:
        raise MapError(str(err)) from None
    info = msg.info
    origin = (info.origin.position.x, info.origin.position.y, origin_yaw)
    data = msg.data
    if isinstance(data, array.array):
        data = np.frombuffer(data, dtype=np.int8) if data.itemsize == 1 else np.asarray(data)
    # The message stores the resolution as float32 (0.1 arrives as
    # 0.100000001); rounding to float32's 7 significant digits gives back
    # the sender's value, so a point on a cell border stays in its cell.
    resolution = float(f'{info.resolution:.7g}')
    grid = map_files.from_occupancy_values(
        info.width, info.height, resolution, origin, data,
        unknown_is_occupied=unknown_is_occupied, occupied_threshold=occupied_threshold,
        max_cells=max_cells)
    with np.errstate(over='ignore', invalid='ignore'):
        reach = float(np.max(np.abs(grid.bounds())))
    if not reach <= MAX_COORDINATE_M:  # also when it overflowed
        raise MapError(f'map reaches {reach:.3g} m from the origin of its frame, beyond '
                       f'{MAX_COORDINATE_M:g} m: bogus origin or resolution')
    return grid


def grid_map_to_occupancy_grid(grid, frame_id, stamp):
    """A ``nav_msgs/OccupancyGrid`` of a :class:`GridMap` (e.g. the simulator's map).

    Parameters
    ----------
    grid : GridMap
    frame_id : str
        ``header.frame_id``.
    stamp : builtin_interfaces.msg.Time
        ``header.stamp`` and ``info.map_load_time``.

    Returns
    -------
    nav_msgs.msg.OccupancyGrid
        ``data`` holds 100 for occupied cells, -1 for unknown cells that are
        not occupied, 0 otherwise (``map_files.OCC_*``), row-major, row 0 at
        the origin.
    """
    values = np.where(grid.occupied, map_files.OCC_OCCUPIED, map_files.OCC_FREE).astype(np.int8)
    if grid.unknown is not None:
        values[grid.unknown & ~grid.occupied] = map_files.OCC_UNKNOWN
    msg = OccupancyGrid()
    msg.header.frame_id = frame_id
    msg.header.stamp = stamp
    msg.info.map_load_time = stamp
    msg.info.resolution = grid.resolution
    msg.info.width = grid.width
    msg.info.height = grid.height
    msg.info.origin.position.x = grid.origin[0]
    msg.info.origin.position.y = grid.origin[1]
    msg.info.origin.orientation = quaternion_of_yaw(grid.origin[2])
    msg.data = array.array('b', values.tobytes())
    return msg


# -- paths --------------------------------------------------------------------

def path_headings(path, final_yaw=None):
    """Heading [rad] of each point of a path, from its segment directions.

    Parameters
    ----------
    path : ndarray, float64, shape (N, 2)
        ``(x, y)`` [m], finite, N >= 1.
    final_yaw : float, optional
        Heading of the last point (e.g. the goal's); default the direction
        of the last segment of non-zero length.

    Returns
    -------
    ndarray, float64, shape (N,)
        Point ``i`` faces towards point ``i + 1``. A zero-length segment keeps
        the previous heading (0 before any segment has a direction).
    """
    n = len(path)
    headings = np.zeros(n)
    if n > 1:
        d = np.diff(path, axis=0)
        moving = np.hypot(d[:, 0], d[:, 1]) > 0
        seg_yaw = np.arctan2(d[:, 1], d[:, 0])
        # Carry the last moving segment's heading across zero-length ones.
        last_moving = np.maximum.accumulate(np.where(moving, np.arange(n - 1), -1))
        first = np.flatnonzero(moving)
        fill = seg_yaw[first[0]] if len(first) else 0.0
        headings[:-1] = np.where(last_moving >= 0, seg_yaw[np.maximum(last_moving, 0)], fill)
        headings[-1] = headings[-2]
    if final_yaw is not None:
        headings[-1] = _finite(final_yaw, 'final yaw')
    return headings


def path_to_msg(path, frame_id, stamp, final_yaw=None):
    """A ``nav_msgs/Path`` of an ``(N, 2)`` path, each pose facing along the path.

    Parameters
    ----------
    path : array_like, shape (N, 2)
        ``(x, y)`` [m], map frame, finite, N >= 1.
    frame_id : str
        Frame of the path and of every pose.
    stamp : builtin_interfaces.msg.Time
    final_yaw : float, optional
        Orientation [rad] of the last pose; see :func:`path_headings`.

    Returns
    -------
    nav_msgs.msg.Path

    Raises
    ------
    InvalidInput
        If the path is empty, not ``(N, 2)`` or not finite.

    Examples
    --------
    >>> msg = path_to_msg([[0.0, 0.0], [1.0, 0.0]], 'map', seconds_to_stamp(0.0))
    >>> len(msg.poses), msg.poses[1].pose.position.x
    (2, 1.0)
    """
    pts = raster.as_polyline(path, 'path')
    headings = path_headings(pts, final_yaw)
    half = 0.5 * headings
    qz, qw = np.sin(half).tolist(), np.cos(half).tolist()
    msg = Path()
    msg.header.frame_id = frame_id
    msg.header.stamp = stamp
    poses = []
    for (x, y), z, w in zip(pts.tolist(), qz, qw):
        # Filling the default pose in place: a long plan has 10,000 poses,
        # and each message built and type-checked costs microseconds.
        pose = PoseStamped(check_fields=False)
        pose.header = msg.header
        position, orientation = pose.pose.position, pose.pose.orientation
        position.x = x
        position.y = y
        orientation.z = z
        orientation.w = w
        poses.append(pose)
    msg.poses = poses
    return msg


def path_from_msg(msg, frame_id, what='path'):
    """The ``(N, 2)`` points of a ``nav_msgs/Path``.

    Parameters
    ----------
    msg : nav_msgs.msg.Path
    frame_id : str
        Expected frame of the path (see :func:`check_frame`); the frames of
        the individual poses are checked the same way.
    what : str
        Name used in the error sentence.

    Returns
    -------
    ndarray, float64, shape (N, 2)
        ``(x, y)`` [m], map frame, N >= 1. Orientations are not used.

    Raises
    ------
    InvalidInput
        Empty path (see :func:`plan_from_msg` when empty means "stop"),
        wrong frame, NaN or infinite coordinates or ones beyond
        :data:`MAX_COORDINATE_M`.
    """
    check_frame(msg.header.frame_id, frame_id, what)
    if len(msg.poses) == 0:
        raise InvalidInput(f'{what} is empty')
    for pose in msg.poses:
        if pose.header.frame_id:
            check_frame(pose.header.frame_id, frame_id, f'a pose of {what}')
    pts = raster.as_polyline(
        [(p.pose.position.x, p.pose.position.y) for p in msg.poses], what)
    if np.abs(pts).max() > MAX_COORDINATE_M:
        raise InvalidInput(f'{what} has a point beyond +-{MAX_COORDINATE_M:g} m: corrupt')
    return pts


def plan_from_msg(msg, frame_id, what='plan'):
    """The points of a global plan, or None for the empty plan that means "stop".

    Parameters
    ----------
    msg : nav_msgs.msg.Path
    frame_id : str
        Expected frame (see :func:`check_frame`), checked for an empty plan too.
    what : str
        Name used in the error sentence.

    Returns
    -------
    ndarray, float64, shape (N, 2) or None
        As :func:`path_from_msg`; None when ``msg`` has no poses.

    Raises
    ------
    InvalidInput
        Wrong frame, NaN or infinite coordinates, or longer than
        :data:`~fusion_planner.core.local_planning.controller_base.MAX_PATH_LENGTH_M`.
    """
    if len(msg.poses) == 0:
        check_frame(msg.header.frame_id, frame_id, what)
        return None
    return check_followable(path_from_msg(msg, frame_id, what), what)


# -- scans --------------------------------------------------------------------

def scan_to_points(msg, robot_pose, frame_id=None, what='scan'):
    """Map-frame endpoints ``(M, 2)`` [m] of the returns of a ``sensor_msgs/LaserScan``.

    The ends of :func:`scan_to_rays` that are returns: ranges that are
    finite and lie in ``[range_min, range_max)``. Same parameters and errors.
    """
    ends, hit = scan_to_rays(msg, robot_pose, frame_id, what)
    return ends[hit]


def check_scan_header(msg, frame_id=None, what='scan'):
    """The beam geometry of a ``sensor_msgs/LaserScan``, checked; its ranges are not read.

    Returns
    -------
    angle_min, angle_increment, range_min, range_max : float
        [rad, rad, m, m].

    Raises
    ------
    InvalidInput
        Non-finite ``angle_min``; ``angle_increment`` not a positive finite
        number; ``range_min``/``range_max`` not finite, ``range_min < 0``,
        ``range_max <= range_min`` or ``range_max`` beyond
        :data:`MAX_COORDINATE_M`; a frame other than ``frame_id`` (when given).
    """
    if frame_id is not None:
        check_frame(msg.header.frame_id, frame_id, what)
    angle_min = _finite(msg.angle_min, f'{what} angle_min')
    increment = _finite(msg.angle_increment, f'{what} angle_increment')
    if increment <= 0:
        raise InvalidInput(f'{what} angle_increment must be positive, got {increment!r}')
    range_min = _finite(msg.range_min, f'{what} range_min')
    range_max = _finite(msg.range_max, f'{what} range_max', MAX_COORDINATE_M)
    if range_min < 0 or range_max <= range_min:
        raise InvalidInput(
            f'{what} range limits must satisfy 0 <= range_min < range_max, '
            f'got [{range_min!r}, {range_max!r}]')
    return angle_min, increment, range_min, range_max


def scan_to_rays(msg, robot_pose, frame_id=None, what='scan'):
    """Where each usable beam of a ``sensor_msgs/LaserScan`` ended, in the map frame.

    Parameters
    ----------
    msg : sensor_msgs.msg.LaserScan
        Beams in the robot frame (the sensor at the robot's origin facing
        forward; no tf2 lookup).
    robot_pose : tuple of float
        ``(x, y, yaw)`` [m, m, rad] of the robot in the map frame.
    frame_id : str, optional
        When given, the scan's frame must be this (or empty).
    what : str
        Name used in the error sentence.

    Returns
    -------
    ends : ndarray, float64, shape (M, 2)
        ``(x, y)`` [m], map frame: the return of a beam with a range in
        ``[range_min, range_max)``, or the point at ``range_max`` of a beam
        with no return (``+inf`` by REP-117, or a range at or beyond
        ``range_max``). NaN, ``-inf`` and too-short ranges are dropped, as
        is a beam whose end overflows.
    hit : ndarray, bool, shape (M,)
        Whether the beam ended on a return.

    Raises
    ------
    InvalidInput
        Non-finite pose or ``angle_min``; ``angle_increment`` not a positive
        finite number; ``range_min``/``range_max`` not finite,
        ``range_min < 0``, ``range_max <= range_min`` or ``range_max`` beyond
        :data:`MAX_COORDINATE_M`; ``ranges`` not a flat sequence; wrong frame.

    Notes
    -----
    Beam ``i`` points at ``angle_min + i * angle_increment`` in the robot
    frame. ``intensities`` is never read, so a length that disagrees with
    ``ranges`` does no harm. Vectorised: no Python loop over beams.
    """
    angle_min, increment, range_min, range_max = check_scan_header(msg, frame_id, what)
    x, y, yaw = (_finite(v, f'robot pose for {what}') for v in robot_pose)
    ranges = np.asarray(msg.ranges, dtype=float)
    if ranges.ndim != 1:
        raise InvalidInput(f'{what} ranges must be a flat sequence of numbers')
    with np.errstate(invalid='ignore'):
        usable = ~np.isnan(ranges) & (ranges >= range_min)   # drops NaN, -inf, too short
        hit_all = usable & (ranges < range_max)
    index = np.flatnonzero(usable)
    hit = hit_all[index]
    r = np.where(hit, ranges[index], range_max)
    with np.errstate(invalid='ignore', over='ignore'):
        angles = yaw + angle_min + index * increment
        ends = np.column_stack([x + r * np.cos(angles), y + r * np.sin(angles)])
    # Absurd angle or pose magnitudes can overflow: such beams are dropped too.
    finite = np.isfinite(ends).all(axis=1)
    return ends[finite], hit[finite]


# -- obstacles ----------------------------------------------------------------

class ObstacleTracker:
    """Tracked cylinders from ``visualization_msgs/MarkerArray`` messages.

    Each marker ``(ns, id)`` is one obstacle; its velocity is estimated from
    successive positions of the same id. Markers not refreshed within the
    timeout are forgotten.

    Parameters
    ----------
    frame_id : str
        Frame the markers must be in (see :func:`check_frame`).
    timeout_s : float
        Forget a track not updated for longer than this [s], > 0.
    max_speed : float
        Estimated speeds above this [m/s] are taken for a teleport (the same
        id reused elsewhere): the track restarts with zero velocity.
    smoothing : float
        Weight of the previous velocity in exponential smoothing, in [0, 1).
    max_diameter : float
        Largest accepted ``scale.x`` [m].
    max_tracks : int
        Markers that would add a track beyond this many are refused.

    Notes
    -----
    Per marker: ``ADD``/``MODIFY`` (same value) creates or updates a track,
    ``DELETE`` removes ``(ns, id)``, ``DELETEALL`` removes every track; markers
    are processed in array order, as RViz does. Only ``CYLINDER`` markers are
    obstacles; other types are refused. ``scale.x`` is the diameter; the
    orientation is ignored (a vertical cylinder). A marker with a NaN,
    infinite or too distant position (:data:`MAX_COORDINATE_M`), a NaN, zero,
    negative or huge scale, or a wrong frame is
    refused on its own; the rest of the array is still used. Velocities use
    the markers' header stamps when set (sim time), else the receive time.

    Examples
    --------
    >>> tracker = ObstacleTracker('map')
    >>> msg = obstacles_to_markers(np.array([[1.0, 2.0, 0.0, 0.0, 0.5]]), 'map',
    ...                            seconds_to_stamp(1.0))
    >>> obstacles, rejected = tracker.update(msg, now_s=1.0)
    >>> obstacles.tolist(), rejected
    ([[1.0, 2.0, 0.0, 0.0, 0.5]], [])
    """

    def __init__(self, frame_id, timeout_s=DEFAULT_OBSTACLE_TIMEOUT_S,
                 max_speed=DEFAULT_MAX_OBSTACLE_SPEED_MPS,
                 smoothing=DEFAULT_VELOCITY_SMOOTHING,
                 max_diameter=DEFAULT_MAX_OBSTACLE_DIAMETER_M,
                 max_tracks=DEFAULT_MAX_TRACKS):
        if not (_is_number(timeout_s) and timeout_s > 0):
            raise InvalidInput(
                f'obstacle timeout must be a positive number of seconds, got {timeout_s!r}')
        if not (_is_number(max_speed) and max_speed > 0):
            raise InvalidInput(f'obstacle max speed must be a positive number, got {max_speed!r}')
        if not (_is_number(smoothing) and 0 <= smoothing < 1):
            raise InvalidInput(f'velocity smoothing must lie in [0, 1), got {smoothing!r}')
        if not (_is_number(max_diameter) and max_diameter > MIN_OBSTACLE_DIAMETER_M):
            raise InvalidInput(
                f'max obstacle diameter must exceed {MIN_OBSTACLE_DIAMETER_M} m, got {max_diameter!r}')
        if isinstance(max_tracks, bool) or not isinstance(max_tracks, int) or max_tracks < 1:
            raise InvalidInput(f'max tracks must be a positive integer, got {max_tracks!r}')
        self.frame_id = frame_id
        self.timeout_s = float(timeout_s)
        self.max_speed = float(max_speed)
        self.smoothing = float(smoothing)
        self.max_diameter = float(max_diameter)
        self.max_tracks = max_tracks
        # (ns, id) -> [x, y, vx, vy, radius, stamp_s, seen_s]
        self._tracks = {}

    def __len__(self):
        return len(self._tracks)

    def clear(self):
        """Forget every track (e.g. after a clock reset)."""
        self._tracks.clear()

    def update(self, msg, now_s):
        """Apply one ``MarkerArray`` and return the live obstacles.

        Parameters
        ----------
        msg : visualization_msgs.msg.MarkerArray
        now_s : float
            Receive time [s] on the node's clock (finite).

        Returns
        -------
        obstacles : ndarray, float64, shape (K, 5)
            ``x, y, vx, vy, radius`` [m, m, m/s, m/s, m], map frame.
        rejected : list of str
            One sentence per refused marker (empty when all were used).

        Raises
        ------
        InvalidInput
            If ``now_s`` is not finite.
        """
        now_s = _finite(now_s, 'receive time')
        rejected = []
        for marker in msg.markers:
            try:
                self._apply(marker, now_s)
            except InvalidInput as err:
                rejected.append(str(err))
        return self.obstacles(now_s), rejected

    def obstacles(self, now_s):
        """Live obstacles at ``now_s`` [s]: ``(K, 5)`` float64; stale tracks dropped.

        Each position is moved ahead along its estimated velocity from the
        stamp of its last marker to ``now_s`` (at most ``timeout_s``): markers
        come at the sensor's rate and late, and a person at 0.4 m/s seen
        0.1 s ago is 4 cm further on. A ``now_s`` earlier than a track's last
        sighting (clock reset) keeps the track where it was seen;
        :meth:`clear` is the caller's choice on a reset.
        """
        stale = [key for key, t in self._tracks.items() if now_s - t[6] > self.timeout_s]
        for key in stale:
            del self._tracks[key]
        if not self._tracks:
            return np.zeros((0, len(OBSTACLE_COLUMNS)))
        tracks = np.array([t[:6] for t in self._tracks.values()], dtype=float)
        age = np.clip(now_s - tracks[:, 5], 0.0, self.timeout_s)
        tracks[:, :2] += tracks[:, 2:4] * age[:, None]
        return tracks[:, :5]

    def _apply(self, marker, now_s):
        name = f"marker '{marker.ns}'/{marker.id}"
        if marker.action == Marker.DELETEALL:
            self._tracks.clear()
            return
        if marker.action == Marker.DELETE:
            self._tracks.pop((marker.ns, marker.id), None)
            return
        if marker.action != Marker.ADD:
            raise InvalidInput(f'{name} has unknown action {marker.action}')
        if marker.type != Marker.CYLINDER:
            raise InvalidInput(f'{name} is of type {marker.type}, not a cylinder')
        check_frame(marker.header.frame_id, self.frame_id, name)
        x = _finite(marker.pose.position.x, f'{name} x', MAX_COORDINATE_M)
        y = _finite(marker.pose.position.y, f'{name} y', MAX_COORDINATE_M)
        diameter = _finite(marker.scale.x, f'{name} scale.x')
        if not MIN_OBSTACLE_DIAMETER_M <= diameter <= self.max_diameter:
            raise InvalidInput(
                f'{name} diameter {diameter!r} m lies outside '
                f'[{MIN_OBSTACLE_DIAMETER_M}, {self.max_diameter}] m')
        stamp_s = stamp_to_seconds(marker.header.stamp)
        if stamp_s <= 0:
            stamp_s = now_s
        key = (marker.ns, marker.id)
        track = self._tracks.get(key)
        if track is None:
            if len(self._tracks) >= self.max_tracks:
                raise InvalidInput(f'{name} refused: already tracking {self.max_tracks} obstacles')
            self._tracks[key] = [x, y, 0.0, 0.0, diameter / 2, stamp_s, now_s]
            return
        dt = stamp_s - track[5]
        if dt > 0:
            vx = (x - track[0]) / dt
            vy = (y - track[1]) / dt
            if math.hypot(vx, vy) > self.max_speed:
                vx = vy = 0.0
            else:
                s = self.smoothing
                vx = s * track[2] + (1 - s) * vx
                vy = s * track[3] + (1 - s) * vy
        elif dt < 0:
            vx = vy = 0.0  # time went backwards: restart the estimate
        else:
            vx, vy = track[2], track[3]  # same stamp again: keep the estimate
        self._tracks[key] = [x, y, vx, vy, diameter / 2, stamp_s, now_s]


def obstacles_to_markers(obstacles, frame_id, stamp, ns='obstacles', ids=None,
                         height=OBSTACLE_MARKER_HEIGHT_M):
    """A ``MarkerArray`` of cylinders for ``(K, 5)`` obstacles (id-stable).

    Parameters
    ----------
    obstacles : array_like, shape (K, 5)
        ``x, y, vx, vy, radius`` [m, m, m/s, m/s, m], map frame, finite,
        radius > 0. Velocities are not drawn.
    frame_id : str
    stamp : builtin_interfaces.msg.Time
    ns : str
        Marker namespace.
    ids : sequence of int, optional
        Marker id of each row; default ``0..K-1``. Keep them stable over time
        so that :class:`ObstacleTracker` can estimate velocities.
    height : float
        Cylinder height [m] (drawing only).

    Returns
    -------
    visualization_msgs.msg.MarkerArray
        One ``ADD`` cylinder per row, ``scale.x = scale.y = 2 * radius``.
        No ``DELETEALL`` is sent (it would reset the receivers' tracks).

    Raises
    ------
    InvalidInput
        Wrong shape, non-finite values, radius <= 0, or ``ids`` of the wrong
        length.
    """
    try:
        obs = np.asarray(obstacles, dtype=float).reshape(-1, len(OBSTACLE_COLUMNS))
    except (TypeError, ValueError):
        raise InvalidInput('obstacles must be a (K, 5) array of numbers') from None
    if not np.all(np.isfinite(obs)) or np.any(obs[:, 4] <= 0):
        raise InvalidInput('obstacles must be finite with positive radii')
    ids = list(range(len(obs))) if ids is None else [int(i) for i in ids]
    if len(ids) != len(obs):
        raise InvalidInput(f'got {len(ids)} marker ids for {len(obs)} obstacles')
    out = MarkerArray()
    for (x, y, _vx, _vy, radius), marker_id in zip(obs.tolist(), ids):
        marker = Marker()
        marker.header.frame_id = frame_id
        marker.header.stamp = stamp
        marker.ns = ns
        marker.id = marker_id
        marker.type = Marker.CYLINDER
        marker.action = Marker.ADD
        marker.pose.position.x = x
        marker.pose.position.y = y
        marker.pose.position.z = height / 2
        marker.pose.orientation.w = 1.0
        marker.scale.x = marker.scale.y = 2 * radius
        marker.scale.z = float(height)
        marker.color.r, marker.color.g, marker.color.b, marker.color.a = 0.9, 0.3, 0.1, 0.8
        out.markers.append(marker)
    return out


def points_marker(points, frame_id, stamp, ns, marker_type=Marker.SPHERE_LIST, scale=0.1,
                  rgba=(0.1, 0.4, 0.9, 1.0), marker_id=0):
    """One list marker (``SPHERE_LIST``, ``CUBE_LIST``, ``POINTS``, ``LINE_STRIP``) of points.

    Parameters
    ----------
    points : array_like, shape (N, 2)
        ``(x, y)`` [m], finite.
    frame_id : str
    stamp : builtin_interfaces.msg.Time
    ns : str
        Marker namespace.
    marker_type : int
        A list type of ``visualization_msgs/Marker``.
    scale : float
        Point size (or line width) [m].
    rgba : tuple of float
        Colour, each in [0, 1].
    marker_id : int

    Returns
    -------
    visualization_msgs.msg.Marker
        An ``ADD`` marker (N may be 0).

    Raises
    ------
    InvalidInput
        If ``points`` is not a finite ``(N, 2)`` array.
    """
    pts = raster.as_polyline(points, ns) if np.size(points) else np.zeros((0, 2))
    marker = Marker()
    marker.header.frame_id = frame_id
    marker.header.stamp = stamp
    marker.ns = ns
    marker.id = marker_id
    marker.type = marker_type
    marker.action = Marker.ADD
    marker.pose.orientation.w = 1.0
    marker.scale.x = marker.scale.y = marker.scale.z = float(scale)
    marker.color.r, marker.color.g, marker.color.b, marker.color.a = (float(c) for c in rgba)
    marker.points = [Point(x=x, y=y, z=0.0) for x, y in pts.tolist()]
    return marker


def delete_all_marker(frame_id, stamp):
    """A ``DELETEALL`` marker, to put first in an array that redraws everything."""
    marker = Marker()
    marker.header.frame_id = frame_id
    marker.header.stamp = stamp
    marker.action = Marker.DELETEALL
    return marker


# -- helpers ------------------------------------------------------------------

def _is_number(value):
    return not isinstance(value, bool) and isinstance(value, (int, float)) and math.isfinite(value)


def _finite(value, what, limit=None):
    """``value`` as a finite float (within ``[-limit, limit]`` if given), else InvalidInput."""
    try:
        number = float(value)
    except (TypeError, ValueError):
        raise InvalidInput(f'{what} must be a number, got {value!r}') from None
    if isinstance(value, bool) or not math.isfinite(number):
        raise InvalidInput(f'{what} must be a finite number, got {value!r}')
    if limit is not None and abs(number) > limit:
        raise InvalidInput(f'{what} {number:.3g} lies beyond +-{limit:g}: corrupt')
    return number
