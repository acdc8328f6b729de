"""Fuzzing of every node input: hypothesis strategies of bad messages, checks, a soak.

Usage::

    python -m fusion_planner.ros.fuzz [--messages N] [--seed S] [--node NAME ...]

Each node is built in this process (never spun) and driven by calling the
callbacks its subscriptions and services hold, which is exactly what the
executor calls, guard included, one message at a time. The messages come
from hypothesis strategies over the message fields: valid ones with odd but
legal fields (REP-117 ranges, empty frames, DELETE markers, empty plans,
stamps anywhere, huge coordinates) and ones with *defects* (NaN or infinite
numbers, zero or non-unit quaternions, wrong frames, bad map geometry, bad
scan increments, bad marker scales or actions, huge commands ...). After
every message:

- no exception reached the guard as a bug (diagnostics ``faults`` unchanged);
- a message with a defect in a field the node reads was refused: counted on
  diagnostics (``rejected``, or a failed request with an ``invalid_*``
  outcome) and logged only through the rate-limited logger, as one line;
  a message without one was not refused as malformed;
- the node's outputs stayed sane: finite plans; finite velocity commands
  within the robot's limits, zero without a plan; a finite simulated robot.

Afterwards each node must still do its job (:meth:`FuzzTarget.still_works`):
the global planner plans a collision-free path to the goal, the local
planner drives a robot to the end of its plan, the simulator applies
commands. The test suite runs 1,000 messages per input
(``test/test_fuzz_inputs.py``); this module's ``main`` is the longer soak.
Needs hypothesis (the ``test`` extra).
"""

if __name__ == '__main__':  # the soak: name a missing extra before the imports below fail
    from fusion_planner.cli.requirements import exit_if_missing
    exit_if_missing(('ros', 'test'), 'python -m fusion_planner.ros.fuzz', 'the soak test')

import argparse
import array
import functools
import math
import sys
import time
import traceback
from collections import namedtuple

import numpy as np
import rclpy
from geometry_msgs.msg import PoseStamped, PoseWithCovarianceStamped, Quaternion, Twist
from hypothesis import HealthCheck, Phase, given, seed, settings
from hypothesis import strategies as st
from diagnostic_msgs.msg import DiagnosticStatus, KeyValue
from nav_msgs.msg import OccupancyGrid, Odometry, Path
from nav_msgs.srv import GetPlan
from rclpy.parameter import Parameter
from rclpy.time import Time
from sensor_msgs.msg import LaserScan
from std_msgs.msg import Header
from std_srvs.srv import Trigger
from visualization_msgs.msg import Marker, MarkerArray

from fusion_planner.core import raster
from fusion_planner.core.grid import GridMap
from fusion_planner.core.local_planning.controller_base import MAX_PATH_LENGTH_M
from fusion_planner.core.simulation.world import integrate_unicycle
from fusion_planner.ros import conversions as conv
from fusion_planner.ros.diagnostics import DEFAULT_LOG_PERIOD_S, RateLimitedLogger
from fusion_planner.ros.goal_outcome import CONTROLLER_OUTCOMES
from fusion_planner.ros.qos import LatchedOrVolatile

#: A message and the names of the defects put into it (empty: a valid message).
Fuzzed = namedtuple('Fuzzed', 'msg defects')
#: What one input's fuzzing did: messages fed, of which refused, wall time [s].
Report = namedtuple('Report', 'node input messages refused seconds')

#: The frames of the nodes under test.
MAP_FRAME, ROBOT_FRAME = 'map', 'base_link'
#: Frame mistakes as they happen (the expected frame itself is left out when drawn), and
#: one that tries to forge a log line.
WRONG_FRAMES = ('odom', 'map', 'base_link', 'map ', '/map', 'Map', 'world', 'laser', '/base_link',
                'map\n[ERROR] [0.0] [forged]: a second line')
NON_FINITE = (math.nan, math.inf, -math.inf)
#: Largest finite float32 (``resolution``, scan fields, ``tolerance``).
FLOAT32_MAX = float(np.finfo(np.float32).max)
#: Diagnostics outcomes that mean "the input was malformed".
REFUSED_OUTCOMES = ('invalid_input', 'invalid_map')
#: At most this many defects are put into one message [1].
MAX_DEFECTS = 3
#: Map-size limit of the fuzzed global planner [cells]: small, so that maps
#: beyond it are cheap to send.
MAX_MAP_CELLS = 4000
#: Default messages per input of the soak [1].
DEFAULT_SOAK_MESSAGES = 10_000
#: Messages generated per hypothesis run [1]; a long soak takes several runs.
CHUNK = 500
#: Characters of a message shown in a failure.
SHOWN_CHARS = 1500
#: Slack on velocity limits [m/s or rad/s].
LIMIT_EPS = 1e-9
#: Services every rclpy (lifecycle) node has (parameters, type descriptions, lifecycle
#: transitions, tested in test_lifecycle.py): not ours.
RCLPY_SERVICE_PACKAGES = ('rcl_interfaces', 'type_description_interfaces', 'lifecycle_msgs')


# -- strategies: numbers, headers, poses ---------------------------------------------
#
# Strategies are built once (module constants, or cached per argument):
# hypothesis validates a strategy on its first draw, which would dominate
# the run if a new one were built for every field of every message.

def _floats32(low, high):
    """float32 values in ``[low, high]`` (bounds rounded to float32)."""
    return st.floats(float(np.float32(low)), float(np.float32(high)), width=32)


def _beyond(limit):
    """A float of either sign whose magnitude lies strictly beyond ``limit``."""
    return st.builds(lambda m, s: m * s, st.floats(limit * 1.001, 1e300),
                     st.sampled_from((1.0, -1.0)))


_ANY = st.floats()
_ANY32 = st.floats(width=32)
_BOOL = st.booleans()
_NON_FINITE = st.sampled_from(NON_FINITE)
_SEED = st.integers(0, 2 ** 32 - 1)
#: A coordinate [m]: near the test maps, else anywhere accepted (far off the maps).
_FAR = st.floats(-conv.MAX_COORDINATE_M, conv.MAX_COORDINATE_M)
_X = st.one_of(st.floats(-1.0, 5.0), _FAR)
_Y = st.one_of(st.floats(-1.0, 4.0), _FAR)
#: A refused coordinate [m]: NaN, infinite, or beyond conv.MAX_COORDINATE_M.
_BAD_COORDINATES = st.one_of(_NON_FINITE, _beyond(conv.MAX_COORDINATE_M))
_NEGATIVE32 = st.one_of(st.sampled_from((0.0, -0.0) + NON_FINITE),
                        _floats32(-FLOAT32_MAX, -1e-30))  # zero, negative or non-finite
_STAMP_SEC = st.one_of(st.integers(0, 1000), st.integers(-2 ** 31, 2 ** 31 - 1))
_STAMP_NANOSEC = st.integers(0, 2 ** 32 - 1)


def _make_header(frame_id, sec, nanosec):
    header = Header(frame_id=frame_id)
    header.stamp.sec, header.stamp.nanosec = sec, nanosec
    return header


@functools.cache
def _headers(frame):
    """Headers in ``frame`` (or the empty frame, which means it), stamped anywhere."""
    return st.builds(_make_header, st.sampled_from((frame, '')), _STAMP_SEC, _STAMP_NANOSEC)


@functools.cache
def _wrong_frames(frame):
    """Frames other than ``frame`` (and not empty, which means ``frame``)."""
    return st.sampled_from([f for f in WRONG_FRAMES if f != frame])


@functools.cache
def _defect_sets(names, bad_only):
    """Sorted lists of up to :data:`MAX_DEFECTS` of ``names`` (at least one if ``bad_only``)."""
    return st.builds(sorted, st.sets(st.sampled_from(names), min_size=int(bad_only),
                                     max_size=MAX_DEFECTS))


def _yaw_quaternion(yaw, norm):
    return Quaternion(z=norm * math.sin(yaw / 2), w=norm * math.cos(yaw / 2))


def _tilted_quaternion(q, norm):
    q = np.array(q)
    q = q / np.linalg.norm(q) if np.linalg.norm(q) > 0.1 else np.array([0.0, 0.0, 0.0, 1.0])
    x, y, z, w = (norm * q).tolist()
    return Quaternion(x=x, y=y, z=z, w=w)


#: Rotations, about z or tilted, with a norm within the accepted tolerance of 1.
_QUATERNIONS = st.one_of(
    st.builds(_yaw_quaternion, st.floats(-4.0, 4.0), st.floats(0.96, 1.04)),
    st.builds(_tilted_quaternion, st.tuples(*[st.floats(-1.0, 1.0)] * 4), st.floats(0.96, 1.04)))


def _non_finite_component(name, value):
    q = Quaternion(w=1.0)
    setattr(q, name, value)
    return q


#: Zero, far from unit length, or with a non-finite component.
_BAD_QUATERNIONS = st.one_of(
    st.builds(lambda: Quaternion(w=0.0)),
    st.builds(lambda w: Quaternion(w=w), st.one_of(st.floats(0.0, 0.9), st.floats(1.1, 1e100))),
    st.builds(_non_finite_component, st.sampled_from('xyzw'), _NON_FINITE))

#: Defects of a pose: each one is a reason to refuse it.
POSE_DEFECTS = ('x', 'y', 'orientation', 'frame')


def _stamped_pose(draw, stamped, pose, frame, defects, prefix=''):
    """Fill ``stamped.header`` and ``pose`` (z is not read: it may be anything)."""
    stamped.header = draw(_headers(frame))
    pose.position.x = draw(_BAD_COORDINATES if prefix + 'x' in defects else _X)
    pose.position.y = draw(_BAD_COORDINATES if prefix + 'y' in defects else _Y)
    pose.position.z = draw(_ANY)
    pose.orientation = draw(_BAD_QUATERNIONS if prefix + 'orientation' in defects
                            else _QUATERNIONS)
    if prefix + 'frame' in defects:
        stamped.header.frame_id = draw(_wrong_frames(frame))


@st.composite
def pose_stampeds(draw, frame=MAP_FRAME, bad_only=False):
    """``geometry_msgs/PoseStamped`` messages (goals), as :data:`Fuzzed`."""
    defects = draw(_defect_sets(POSE_DEFECTS, bad_only))
    msg = PoseStamped()
    _stamped_pose(draw, msg, msg.pose, frame, defects)
    return Fuzzed(msg, defects)


#: Defects of a PoseWithCovarianceStamped: those of its pose, a NaN or infinite covariance.
POSE_WITH_COVARIANCE_DEFECTS = POSE_DEFECTS + ('covariance',)
_FINITE = st.floats(allow_nan=False, allow_infinity=False)


@st.composite
def poses_with_covariance(draw, frame=MAP_FRAME, bad_only=False):
    """``geometry_msgs/PoseWithCovarianceStamped`` (AMCL); a non-finite covariance is a defect."""
    defects = draw(_defect_sets(POSE_WITH_COVARIANCE_DEFECTS, bad_only))
    msg = PoseWithCovarianceStamped()
    _stamped_pose(draw, msg, msg.pose.pose, frame, defects)
    msg.pose.covariance[draw(st.integers(0, 35))] = draw(
        _NON_FINITE if 'covariance' in defects else _FINITE)
    return Fuzzed(msg, defects)


#: Defects of an Odometry: those of its pose, and a v or omega that is not
#: finite or beyond conv.MAX_RATE.
ODOMETRY_DEFECTS = POSE_DEFECTS + ('twist',)
_RATES = st.floats(-conv.MAX_RATE, conv.MAX_RATE)
_SPEEDS = st.one_of(st.floats(-1.0, 1.0), _RATES)
_TURN_RATES = st.one_of(st.floats(-2.0, 2.0), _RATES)
_BAD_RATES = st.one_of(_NON_FINITE, _beyond(conv.MAX_RATE))


@st.composite
def odometries(draw, frame=MAP_FRAME, bad_only=False):
    """``nav_msgs/Odometry``: pose, twist (only v and omega are read), covariance (not read)."""
    defects = draw(_defect_sets(ODOMETRY_DEFECTS, bad_only))
    msg = Odometry()
    _stamped_pose(draw, msg, msg.pose.pose, frame, defects)
    msg.child_frame_id = draw(st.sampled_from((ROBOT_FRAME, '', 'odom')))
    msg.pose.covariance[draw(st.integers(0, 35))] = draw(_ANY)
    twist = msg.twist.twist
    twist.linear.x, twist.angular.z = draw(_SPEEDS), draw(_TURN_RATES)
    twist.linear.y = draw(_ANY)
    if 'twist' in defects:
        if draw(_BOOL):
            twist.linear.x = draw(_BAD_RATES)
        else:
            twist.angular.z = draw(_BAD_RATES)
    return Fuzzed(msg, defects)


#: Defects of a GetPlan request: of its start, of its goal, and a bad tolerance.
GET_PLAN_DEFECTS = tuple(f'{end} {d}' for end in ('start', 'goal') for d in POSE_DEFECTS) \
    + ('tolerance',)
_TOLERANCES = st.one_of(st.floats(0.0, 1.0, width=32), st.floats(0.0, FLOAT32_MAX, width=32))
_BAD_TOLERANCES = st.one_of(_NON_FINITE, _floats32(-FLOAT32_MAX, -1e-30))


@st.composite
def get_plan_requests(draw, frame=MAP_FRAME, bad_only=False):
    """``nav_msgs/srv/GetPlan`` requests: start and goal poses and the tolerance [m]."""
    defects = draw(_defect_sets(GET_PLAN_DEFECTS, bad_only))
    request = GetPlan.Request()
    for end in ('start', 'goal'):
        pose = getattr(request, end)
        _stamped_pose(draw, pose, pose.pose, frame, defects, prefix=f'{end} ')
    request.tolerance = draw(_BAD_TOLERANCES if 'tolerance' in defects else _TOLERANCES)
    return Fuzzed(request, defects)


# -- strategies: maps, paths, scans, markers, commands -----------------------------------

#: Defects of an OccupancyGrid: each one is a reason to refuse it.
MAP_DEFECTS = ('data length', 'empty', 'resolution', 'too many cells', 'origin',
               'origin orientation', 'frame', 'values', 'too far')
_SIDES = st.integers(1, 50)
#: Valid resolutions [m] and origins [m]: every map stays within conv.MAX_COORDINATE_M.
_RESOLUTIONS = st.one_of(st.sampled_from((0.05, 0.1, 0.25, 1.0)), _floats32(1e-6, 1e5))
_ORIGINS = st.one_of(st.floats(-20.0, 20.0), st.floats(-1e8, 1e8))
_FAR_ORIGINS = _beyond(conv.MAX_COORDINATE_M)
_FAR_RESOLUTIONS = _floats32(conv.MAX_COORDINATE_M * 1.01, FLOAT32_MAX)
_HUGE_SIDES = st.integers(2 ** 16, 2 ** 32 - 1)
_BAD_OCCUPANCY = st.one_of(st.integers(-128, -2), st.integers(101, 127))
_MAP_KINDS = st.sampled_from(('free', 'sparse', 'random', 'unknown', 'full'))


def _occupancy_values(draw, count):
    """``count`` occupancy values (int8) of a drawn kind: free, sparse, random, unknown, full."""
    rng = np.random.default_rng(draw(_SEED))
    kind = draw(_MAP_KINDS)
    if kind == 'random':
        return rng.integers(-1, 101, count).astype(np.int8)
    fill = {'free': 0, 'sparse': 0, 'unknown': -1, 'full': 100}[kind]
    values = np.full(count, fill, dtype=np.int8)
    if kind == 'sparse':
        values[rng.random(count) < 0.05] = 100
    return values


@st.composite
def occupancy_grids(draw, frame=MAP_FRAME, max_cells=MAX_MAP_CELLS, bad_only=False):
    """``nav_msgs/OccupancyGrid`` maps of up to 50 x 50 cells (valid ones within ``max_cells``)."""
    defects = draw(_defect_sets(MAP_DEFECTS, bad_only))
    msg = OccupancyGrid()
    msg.header = draw(_headers(frame))
    info = msg.info
    width, height = draw(_SIDES), draw(_SIDES)
    count = width * height
    info.resolution = draw(_NEGATIVE32 if 'resolution' in defects else _RESOLUTIONS)
    info.origin.position.x, info.origin.position.y = draw(_ORIGINS), draw(_ORIGINS)
    if 'too far' in defects:  # a corner beyond conv.MAX_COORDINATE_M
        if draw(_BOOL):
            setattr(info.origin.position, draw(st.sampled_from('xy')), draw(_FAR_ORIGINS))
        else:
            info.resolution = draw(_FAR_RESOLUTIONS)
    if 'origin' in defects:
        setattr(info.origin.position, draw(st.sampled_from('xy')), draw(_NON_FINITE))
    info.origin.orientation = draw(_BAD_QUATERNIONS if 'origin orientation' in defects
                                   else _QUATERNIONS)
    if 'empty' in defects:
        width, height, count = (0, height, 0) if draw(_BOOL) else (width, 0, 0)
    if 'too many cells' in defects:
        if draw(_BOOL):  # absurd: the product overflows 32 bits
            width, height = draw(_HUGE_SIDES), draw(_HUGE_SIDES)
        else:  # just beyond the limit, with matching data
            height = max(height, 1)
            width = max_cells // height + draw(st.integers(1, 10))
            count = width * height
    if 'data length' in defects:
        change = draw(_SIDES)
        count = max(count - change, 0) if draw(_BOOL) and count else count + change
    info.width, info.height = width, height
    values = _occupancy_values(draw, count)
    if 'values' in defects and count:
        values[draw(st.integers(0, count - 1))] = draw(_BAD_OCCUPANCY)
    msg.data = array.array('b', values.tobytes())
    if 'frame' in defects:
        msg.header.frame_id = draw(_wrong_frames(frame))
    return Fuzzed(msg, defects)


#: Defects of a Path: a refused point (NaN, infinite, too far), a wrong frame of the
#: path or of one pose, longer than MAX_PATH_LENGTH_M (also whenever its points are).
PATH_DEFECTS = ('point', 'frame', 'pose frame', 'too long')
_PATH_KINDS = st.sampled_from(('line', 'scattered', 'far', 'wild', 'repeated'))


def _path_points(draw, count):
    """``(count, 2)`` points [m]: a line, scattered, far off the map, wild (up to
    conv.MAX_COORDINATE_M), or one repeated."""
    rng = np.random.default_rng(draw(_SEED))
    kind = draw(_PATH_KINDS)
    if kind == 'line':
        return np.linspace((0.5, 0.5), rng.uniform((-1.0, -1.0), (5.0, 4.0)), count)
    if kind == 'scattered':
        return rng.uniform((-1.0, -1.0), (5.0, 4.0), (count, 2))
    if kind == 'far':
        return rng.uniform(-1e4, 1e4, (count, 2))
    if kind == 'wild':
        scale = 10.0 ** rng.uniform(0.0, math.log10(conv.MAX_COORDINATE_M), (count, 2))
        return rng.uniform(-1.0, 1.0, (count, 2)) * scale
    return np.tile(rng.uniform(-1.0, 5.0, 2), (count, 1))


@st.composite
def paths(draw, frame=MAP_FRAME, bad_only=False):
    """``nav_msgs/Path`` plans of 0..40 poses (empty means "stop"); orientations are not read."""
    defects = draw(_defect_sets(PATH_DEFECTS, bad_only))
    msg = Path()
    msg.header = draw(_headers(frame))
    count = draw(st.integers(2 if 'too long' in defects else
                             1 if {'point', 'pose frame'} & set(defects) else 0, 40))
    points = _path_points(draw, count)
    if 'too long' in defects:
        points[-1] = points[0] + (2.0 * MAX_PATH_LENGTH_M, 0.0)
    if 'point' in defects:
        points[draw(st.integers(0, count - 1)), draw(st.integers(0, 1))] = draw(_BAD_COORDINATES)
    pose_frame = draw(st.sampled_from((frame, '')))
    orientation = Quaternion(w=draw(_ANY))
    poses = []
    for x, y in points.tolist():
        pose = PoseStamped()
        pose.header.frame_id = pose_frame
        pose.pose.position.x, pose.pose.position.y = x, y
        pose.pose.orientation = orientation
        poses.append(pose)
    if 'pose frame' in defects:
        poses[draw(st.integers(0, count - 1))].header.frame_id = draw(_wrong_frames(frame))
    msg.poses = poses
    if 'frame' in defects:
        msg.header.frame_id = draw(_wrong_frames(frame))
    if 'point' not in defects and len(points) > 1 and (
            np.sum(np.hypot(*np.diff(points, axis=0).T)) > MAX_PATH_LENGTH_M):
        defects = sorted({*defects, 'too long'})
    return Fuzzed(msg, defects)


#: Defects of a LaserScan: each one is a reason to refuse it.
SCAN_DEFECTS = ('angle_increment', 'angle_min', 'range limits', 'frame')
_BEAMS = st.integers(0, 400)
_ANGLES = st.one_of(_floats32(-math.pi, math.pi), st.floats(-FLOAT32_MAX, FLOAT32_MAX, width=32))
_INCREMENTS = _floats32(1e-6, 1.0)
_RANGE_MINS = st.floats(0.0, 0.5, width=32)
_RANGE_MAXS = st.floats(1.0, 1e4, width=32)
_ODD_SHARES = st.sampled_from((0.0, 0.1, 0.5, 1.0))
_RANGE_FAULTS = st.sampled_from(('min', 'max', 'order', 'far'))
_FAR_RANGES = _floats32(conv.MAX_COORDINATE_M * 1.01, FLOAT32_MAX)
_BAD_RANGE_MINS = st.sampled_from(NON_FINITE + (-0.1, -FLOAT32_MAX))


def _ranges(draw, count, range_min, range_max):
    """``count`` float32 ranges [m]: valid, mixed with NaN, +-inf, negative, too short or long."""
    rng = np.random.default_rng(draw(_SEED))
    ranges = rng.uniform(range_min, range_max, count)
    odd = np.array([math.nan, math.inf, -math.inf, -1.0, 0.0, range_max * 2.0 + 1.0,
                    range_max, FLOAT32_MAX, 1e-40])
    replace = rng.random(count) < draw(_ODD_SHARES)
    ranges[replace] = rng.choice(odd, int(replace.sum()))
    return array.array('f', ranges.astype(np.float32).tobytes())


@st.composite
def laser_scans(draw, frame=ROBOT_FRAME, bad_only=False):
    """``sensor_msgs/LaserScan`` of 0..400 beams; intensities of any length (never read)."""
    defects = draw(_defect_sets(SCAN_DEFECTS, bad_only))
    msg = LaserScan()
    msg.header = draw(_headers(frame))
    count = draw(_BEAMS)
    msg.angle_min = draw(_NON_FINITE if 'angle_min' in defects else _ANGLES)
    msg.angle_increment = draw(_INCREMENTS) if draw(_BOOL) else 2 * math.pi / max(count, 1)
    if 'angle_increment' in defects:
        msg.angle_increment = draw(_NEGATIVE32)
    msg.angle_max, msg.time_increment, msg.scan_time = draw(_ANY32), draw(_ANY32), draw(_ANY32)
    msg.range_min, msg.range_max = draw(_RANGE_MINS), draw(_RANGE_MAXS)
    msg.ranges = _ranges(draw, count, msg.range_min, msg.range_max)
    intensities = count if draw(_BOOL) else draw(st.integers(0, count + 20))
    msg.intensities = array.array('f', np.ones(intensities, np.float32).tobytes())
    if 'range limits' in defects:
        kind = draw(_RANGE_FAULTS)
        if kind == 'min':
            msg.range_min = draw(_BAD_RANGE_MINS)
        elif kind == 'max':
            msg.range_max = draw(_NON_FINITE)
        elif kind == 'far':
            msg.range_max = draw(_FAR_RANGES)
        else:
            msg.range_max = draw(st.floats(0.0, float(msg.range_min), width=32))
    if 'frame' in defects:
        msg.header.frame_id = draw(_wrong_frames(frame))
    return Fuzzed(msg, defects)


#: Defects of one ADD marker: each one is a reason to refuse that marker.
MARKER_DEFECTS = ('pose', 'scale', 'type', 'action', 'frame')
#: Largest accepted cylinder diameter [m] (the tracker's default).
MAX_DIAMETER = conv.DEFAULT_MAX_OBSTACLE_DIAMETER_M
_NAMESPACES = st.sampled_from(('a', 'b', '', 'c\r\nd'))
_IDS = st.one_of(st.integers(0, 5), st.integers(-2 ** 31, 2 ** 31 - 1))
_ACTIONS = st.sampled_from((Marker.ADD,) * 4 + (Marker.DELETE, Marker.DELETEALL))
_DIAMETERS = st.one_of(st.floats(0.05, 2.0), st.floats(1e-3, MAX_DIAMETER))
_BAD_DIAMETERS = st.one_of(st.sampled_from((0.0, -1.0) + NON_FINITE), st.floats(-1e300, 5e-4),
                           st.floats(MAX_DIAMETER * 1.001, 1e300))
_BAD_TYPES = st.one_of(
    st.sampled_from((Marker.ARROW, Marker.CUBE, Marker.SPHERE, Marker.TEXT_VIEW_FACING)),
    st.integers(-2 ** 31, 2 ** 31 - 1).filter(lambda t: t != Marker.CYLINDER))
_BAD_ACTIONS = st.one_of(st.just(1), st.integers(4, 2 ** 31 - 1), st.integers(-2 ** 31, -1))


def _marker(draw, frame, defects):
    """One cylinder marker: ADD (DELETE or DELETEALL when it carries no defect)."""
    marker = Marker()
    marker.header = draw(_headers(frame))
    marker.ns, marker.id = draw(_NAMESPACES), draw(_IDS)
    marker.type = draw(_BAD_TYPES) if 'type' in defects else Marker.CYLINDER
    marker.action = Marker.ADD if defects else draw(_ACTIONS)
    if 'action' in defects:
        marker.action = draw(_BAD_ACTIONS)
    marker.pose.position.x, marker.pose.position.y = draw(_X), draw(_Y)
    if 'pose' in defects:
        setattr(marker.pose.position, draw(st.sampled_from('xy')), draw(_BAD_COORDINATES))
    marker.pose.orientation.w = draw(_ANY)  # not read
    marker.scale.x = draw(_BAD_DIAMETERS if 'scale' in defects else _DIAMETERS)
    marker.scale.y = draw(_ANY)  # not read
    if 'frame' in defects:
        marker.header.frame_id = draw(_wrong_frames(frame))
    return marker


@st.composite
def marker_arrays(draw, frame=MAP_FRAME, bad_only=False):
    """``visualization_msgs/MarkerArray`` of 0..12 tracked cylinders; each defect goes
    into one ADD marker (the others are used, so the array is refused in part)."""
    defects = draw(_defect_sets(MARKER_DEFECTS, bad_only))
    count = draw(st.integers(1 if defects else 0, 12))
    owner = {name: draw(st.integers(0, count - 1)) for name in defects}
    markers = [_marker(draw, frame, [d for d in defects if owner[d] == i]) for i in range(count)]
    return Fuzzed(MarkerArray(markers=markers), defects)


#: Defects of a velocity command.
TWIST_DEFECTS = ('non-finite', 'too fast')


@functools.cache
def _command_values(limit):
    """Values within ``[-limit, limit]`` (accepted) and beyond it (refused)."""
    return st.floats(-limit, limit), _beyond(limit)


@st.composite
def twists(draw, speed_limit, omega_limit, bad_only=False):
    """``geometry_msgs/Twist`` commands; ``|v| <= speed_limit`` [m/s] and
    ``|omega| <= omega_limit`` [rad/s] are accepted. Only linear.x and angular.z are read."""
    defects = draw(_defect_sets(TWIST_DEFECTS, bad_only))
    speeds, too_fast = _command_values(speed_limit)
    turn_rates, too_quick = _command_values(omega_limit)
    msg = Twist()
    msg.linear.x, msg.angular.z = draw(speeds), draw(turn_rates)
    msg.linear.y, msg.linear.z, msg.angular.x = draw(_ANY), draw(_ANY), draw(_ANY)
    if 'non-finite' in defects:
        if draw(_BOOL):
            msg.linear.x = draw(_NON_FINITE)
        else:
            msg.angular.z = draw(_NON_FINITE)
    if 'too fast' in defects:
        if draw(_BOOL):
            msg.linear.x = draw(too_fast)
        else:
            msg.angular.z = draw(too_quick)
    return Fuzzed(msg, defects)


#: Defects of a controller outcome: an unknown outcome word, a missing or
#: non-integer plan stamp.
CONTROLLER_OUTCOME_DEFECTS = ('outcome', 'plan stamp')
_TEXT = st.text(max_size=20)


@st.composite
def controller_outcomes(draw, bad_only=False):
    """``diagnostic_msgs/DiagnosticStatus`` on ``controller_outcome``, as :data:`Fuzzed`."""
    defects = draw(_defect_sets(CONTROLLER_OUTCOME_DEFECTS, bad_only))
    outcome = draw(st.sampled_from(CONTROLLER_OUTCOMES))
    if 'outcome' in defects:
        outcome = draw(_TEXT.filter(lambda text: text not in CONTROLLER_OUTCOMES))
    values = [KeyValue(key='reason', value=draw(_TEXT))]
    if 'plan stamp' not in defects:
        values.append(KeyValue(key='plan_stamp_ns', value=str(draw(st.integers(0, 2 ** 63)))))
    elif draw(_BOOL):
        values.append(KeyValue(key='plan_stamp_ns', value=draw(_TEXT.filter(_not_integer))))
    return Fuzzed(DiagnosticStatus(level=draw(st.sampled_from((b'\x00', b'\x02'))),
                                   name=draw(_TEXT), message=outcome, values=values), defects)


def _not_integer(text):
    try:
        int(text)
    except ValueError:
        return True
    return False


#: Inputs without fields (a Trigger request): every message is valid.
FIELDLESS_INPUTS = ('cancel_goal',)


def triggers(bad_only=False):
    """``std_srvs/Trigger`` requests (no fields, so no defects; ``bad_only`` is ignored)."""
    return st.just(Fuzzed(Trigger.Request(), []))


def generate(strategy, count, seed_value=0):
    """Yield ``count`` examples of ``strategy``, the same ones for the same seed.

    Parameters
    ----------
    strategy : hypothesis strategy
    count : int
        Examples wanted.
    seed_value : int
        Seed of the generation.

    Notes
    -----
    Hypothesis generates (no shrinking, no example database) in runs of
    :data:`CHUNK` examples, each run seeded from ``seed_value``.
    """
    produced, run = 0, 0
    while produced < count:
        batch = []
        wanted = min(CHUNK, count - produced)

        @settings(max_examples=wanted, database=None, deadline=None, phases=[Phase.generate],
                  suppress_health_check=list(HealthCheck))
        @seed(seed_value * 1_000_003 + run)
        @given(strategy)
        def collect(example):
            batch.append(example)

        collect()
        if not batch:
            raise RuntimeError('hypothesis generated no example')
        yield from batch[:wanted]
        produced += min(len(batch), wanted)
        run += 1


# -- targets --------------------------------------------------------------------------

class LogRecorder:
    """Stands in for a node's logger: keeps ``(severity, text)`` lines, prints nothing."""

    def __init__(self):
        self.lines = []

    def info(self, text):
        self.lines.append(('info', text))

    def warning(self, text):
        self.lines.append(('warning', text))

    def error(self, text):
        self.lines.append(('error', text))


class _PublisherStandIn:
    """Stands in for a publisher: keeps what is published."""

    def __init__(self):
        self.messages = []

    def publish(self, msg):
        self.messages.append(msg)


class FuzzTarget:
    """A node driven by direct callback calls; subclasses set it up and check it.

    Parameters
    ----------
    node : rclpy.node.Node
        One of the package's nodes (it has a ``_diagnostics`` reporter).

    Attributes
    ----------
    inputs : dict
        ``{name: (message or service type, callable)}``: every subscription
        (by topic base name; rclpy's ``/clock`` left out) and every service
        of the node's own interface. A service callable takes the request
        and returns the response.
    direct, limited : LogRecorder
        Lines the node logged directly, and through its rate limiter.
    tracebacks : list of str
        Tracebacks of the bugs the node's callback guard caught.
    """

    def __init__(self, node):
        self.node = node
        self.direct, self.limited = LogRecorder(), LogRecorder()
        node.get_logger = lambda: self.direct
        reporter = node._diagnostics
        reporter.log = RateLimitedLogger(self.limited, DEFAULT_LOG_PERIOD_S)
        self.tracebacks = []  # of the bugs the guard caught, for the failure report
        report_fault = reporter.fault

        def fault(what, err):
            self.tracebacks.append(traceback.format_exc())
            report_fault(what, err)
        reporter.fault = fault
        self.inputs = {}
        for sub in node.subscriptions:
            if sub.topic_name != '/clock':
                # Past the duplicate filter of a topic subscribed twice: every
                # fuzzed message must reach the node's own callback.
                owner = getattr(getattr(sub.callback, 'func', None), '__self__', None)
                callback = owner.callback if isinstance(owner, LatchedOrVolatile) else sub.callback
                self.inputs[sub.topic_name.rsplit('/', 1)[-1]] = (sub.msg_type, callback)
        for srv in node.services:
            if not srv.srv_type.__module__.startswith(RCLPY_SERVICE_PACKAGES):
                self.inputs[srv.service_name.rsplit('/', 1)[-1]] = (
                    srv.srv_type, lambda request, cb=srv.callback, t=srv.srv_type:
                    cb(request, t.Response()))

    def strategy(self, name, bad_only=False):
        """The hypothesis strategy of input ``name``.

        Raises
        ------
        KeyError
            If the input's type has no strategy (a new input: add one).
        """
        factories = {OccupancyGrid: occupancy_grids, PoseStamped: pose_stampeds,
                     DiagnosticStatus: controller_outcomes, Trigger: triggers,
                     PoseWithCovarianceStamped: poses_with_covariance, Odometry: odometries,
                     Path: paths, MarkerArray: marker_arrays, GetPlan: get_plan_requests,
                     LaserScan: lambda bad_only: laser_scans(ROBOT_FRAME, bad_only)}
        return factories[self.inputs[name][0]](bad_only=bad_only)

    def diagnostics(self):
        """The node's diagnostics key values now."""
        return self.node._diagnostics.values

    def deliver(self, name, msg):
        """Call input ``name``'s callback with ``msg``; returns what it returns."""
        return self.inputs[name][1](msg)

    def prepare(self):
        """Give the node fresh valid inputs before a fuzzed message (default: nothing)."""

    def check_after(self, name, fuzzed, result):
        """Check the node's outputs after ``fuzzed`` went to ``name``; AssertionError if bad."""

    def still_works(self):
        """Check that the node still does its job; AssertionError if not."""
        raise NotImplementedError

    def close(self):
        self.node.destroy_node()

    def check_quiet_step(self, step):
        """Run ``step()`` (a timer callback); no fault and no refusal may come of it."""
        before = self.diagnostics()
        step()
        after = self.diagnostics()
        for key in ('faults', 'rejected'):
            assert after[key] == before[key], f'{key} in a timer step: {after["last_error"]}'


def _shown(fuzzed):
    text = repr(fuzzed.msg)
    return text if len(text) <= SHOWN_CHARS else text[:SHOWN_CHARS] + '...'


def _check_refusal(target, name, fuzzed, before, after, logged):
    """The per-message promises: no fault; refused exactly when defective; quiet."""
    where = f'{target.node.get_name()}/{name}'
    assert after['faults'] == before['faults'], \
        f'{where}: a bug surfaced on {_shown(fuzzed)}\n{target.tracebacks[-1]}'
    refused = after['rejected'] > before['rejected'] or (
        after['requests'] > before['requests'] and after['last_outcome'] in REFUSED_OUTCOMES)
    defective = bool(fuzzed.defects)
    assert refused == defective, (
        f'{where}: defects {fuzzed.defects} but refused={refused} '
        f'({after["last_error"]!r}) on {_shown(fuzzed)}')
    if refused:
        loud = [line for line in logged if line[0] != 'info']
        assert not loud, f'{where}: refusal logged past the rate limiter: {loud}'
        line = after['last_error']  # as logged
        assert line.startswith(name) and line.isprintable(), f'{where}: not one line: {line!r}'
    return refused


def fuzz_input(target, name, messages, seed_value=0, bad_only=False):
    """Feed ``messages`` fuzzed messages to input ``name`` of ``target``, checking each.

    Parameters
    ----------
    target : FuzzTarget
    name : str
        A key of ``target.inputs``.
    messages : int
    seed_value : int
        Seed of the generation (the same seed gives the same messages).
    bad_only : bool
        Only messages with at least one defect.

    Returns
    -------
    Report

    Raises
    ------
    AssertionError
        On the first broken promise (see the module docstring), naming the
        message.
    """
    started = time.monotonic()
    refused = count = 0
    for fuzzed in generate(target.strategy(name, bad_only), messages, seed_value):
        target.prepare()
        before, mark = target.diagnostics(), len(target.direct.lines)
        result = target.deliver(name, fuzzed.msg)
        refused += _check_refusal(target, name, fuzzed, before, target.diagnostics(),
                                  target.direct.lines[mark:])
        try:
            target.check_after(name, fuzzed, result)
        except AssertionError as err:
            raise AssertionError(f'{target.node.get_name()}/{name}: {err}; after '
                                 f'{_shown(fuzzed)}') from None
        count += 1
    for severity, text in target.direct.lines + target.limited.lines:
        assert '\n' not in text and 'Traceback' not in text, (severity, text)
    return Report(target.node.get_name(), name, count, refused, time.monotonic() - started)


def wall_map():
    """4 m x 3 m at 0.1 m; a wall at x = 2.0-2.1 m from y = 0.5 m to 2.5 m, gaps below and above."""
    occupied = np.zeros((30, 40), dtype=bool)
    occupied[5:25, 20] = True
    return GridMap(occupied, 0.1)


class GlobalPlannerTarget(FuzzTarget):
    """The global planner on :func:`wall_map`, start and goal on either side of the wall.

    Parameters
    ----------
    context : rclpy.Context
    pose_topic_type : str
        ``'odometry'`` or ``'pose_with_covariance'``.
    """

    START, GOAL = (0.55, 1.55), (3.45, 1.55)
    ROBOT_RADIUS = 0.1

    def __init__(self, context, pose_topic_type='odometry'):
        from fusion_planner.ros.global_planner import GlobalPlannerNode

        super().__init__(GlobalPlannerNode(context=context, parameter_overrides=[
            Parameter('robot_radius', value=self.ROBOT_RADIUS),
            Parameter('max_map_cells', value=MAX_MAP_CELLS),
            Parameter('pose_topic_type', value=pose_topic_type),
            Parameter('diagnostics_period', value=0.0)]))
        self.grid = wall_map()
        self.pose_name = 'odom' if pose_topic_type == 'odometry' else 'amcl_pose'
        self.node._plan_pub = self.plans = _PublisherStandIn()
        self.prepare()

    def _pose_msg(self, xy):
        msg = Odometry() if self.pose_name == 'odom' else PoseWithCovarianceStamped()
        msg.header.frame_id = MAP_FRAME
        msg.pose.pose.position.x, msg.pose.pose.position.y = xy
        msg.pose.pose.orientation.w = 1.0
        return msg

    def prepare(self):
        """The wall map (a no-op when it is current) and the robot at the start."""
        self.deliver('map', conv.grid_map_to_occupancy_grid(
            self.grid, MAP_FRAME, conv.seconds_to_stamp(0.0)))
        self.deliver(self.pose_name, self._pose_msg(self.START))

    def check_after(self, name, fuzzed, result):
        plan = self.node._plan
        assert plan is None or np.all(np.isfinite(plan)), plan
        if name == 'get_plan':
            assert isinstance(result, GetPlan.Response), result
            points = [(p.pose.position.x, p.pose.position.y) for p in result.plan.poses]
            assert np.all(np.isfinite(points)), points
            assert not (fuzzed.defects and points), f'planned despite {fuzzed.defects}'

    def still_works(self):
        """A new goal gives a collision-free plan from the start to it, and get_plan one too.

        A scan without returns first clears what fuzzed scans marked (when the
        node marks obstacles from scans).
        """
        self.prepare()
        if 'scan' in self.inputs:
            self.deliver('scan', _scan_without_returns(conv.seconds_to_stamp(0.0)))
        self.deliver('goal_pose', _pose_stamped(self.GOAL))
        assert self.diagnostics()['last_outcome'] == 'succeeded', self.diagnostics()
        self._check_path(conv.path_from_msg(self.plans.messages[-1], MAP_FRAME))
        request = GetPlan.Request(start=_pose_stamped(self.START), goal=_pose_stamped(self.GOAL))
        self._check_path(conv.path_from_msg(self.deliver('get_plan', request).plan, MAP_FRAME))

    def _check_path(self, path):
        assert math.dist(path[0], self.START) <= self.grid.resolution, path[0]
        assert math.dist(path[-1], self.GOAL) <= self.grid.resolution, path[-1]
        cells = raster.path_cells(self.grid, path)
        assert self.grid.contains(cells).all()
        assert self.grid.clearance[cells[:, 0], cells[:, 1]].min() >= self.ROBOT_RADIUS - 1e-6


def _pose_stamped(xy):
    msg = PoseStamped()
    msg.header.frame_id = MAP_FRAME
    msg.pose.position.x, msg.pose.position.y = xy
    msg.pose.orientation.w = 1.0
    return msg


def _scan_without_returns(stamp):
    """A 360-degree scan of 90 beams, range 8 m, that saw nothing."""
    scan = LaserScan()
    scan.header.frame_id = ROBOT_FRAME
    scan.header.stamp = stamp
    scan.angle_min, scan.angle_increment = -math.pi, math.pi / 45
    scan.range_min, scan.range_max = 0.05, 8.0
    scan.ranges = [math.inf] * 90
    return scan


class LocalPlannerTarget(FuzzTarget):
    """The local planner on simulated time, driving a kinematic robot along an L-shaped plan.

    Each fuzzed message comes after fresh odometry of the robot and an empty
    scan, and is followed by one control step whose command moves the robot.
    Every :data:`MISSION_MESSAGES` messages the robot starts again.
    """

    PLAN = ((0.5, 0.5), (3.0, 0.5), (3.0, 2.5))
    START = (0.5, 0.5, 0.0)
    MISSION_MESSAGES = 150
    #: Control steps allowed for the final mission [1].
    MISSION_STEPS = 600

    def __init__(self, context):
        from fusion_planner.ros.local_planner import LocalPlannerNode

        super().__init__(LocalPlannerNode(context=context, parameter_overrides=[
            Parameter('use_sim_time', value=True), Parameter('diagnostics_period', value=0.0),
            Parameter('max_map_cells', value=MAX_MAP_CELLS),
            Parameter('odom_frame_id', value=MAP_FRAME),  # odometry in the map frame
            Parameter('plan_timeout', value=0.0)]))  # no plan publisher here: never time out
        node = self.node
        self.dt = 1.0 / node.get_parameter('control_rate').value
        self.max_speed = node.get_parameter('max_speed').value
        self.max_omega = node.get_parameter('max_omega').value
        self.commands = node._cmd_pub = _PublisherStandIn()
        self.plan_msg = conv.path_to_msg(list(self.PLAN), MAP_FRAME, conv.seconds_to_stamp(0.0))
        self.now = 1.0
        self.messages = 0
        self._start_mission()

    def _advance(self, seconds):
        self.now += seconds
        self.node.get_clock().set_ros_time_override(Time(nanoseconds=round(self.now * 1e9)))

    def _start_mission(self):
        self.pose, self.velocity = np.array(self.START), np.zeros(2)
        empty = Path()
        empty.header.frame_id = MAP_FRAME
        self.deliver('plan', empty)
        self.deliver('plan', self.plan_msg)

    def _sense(self):
        """Odometry of the robot and an empty scan, stamped now."""
        stamp = conv.seconds_to_stamp(self.now)
        odom = Odometry()
        odom.header.frame_id = MAP_FRAME
        odom.header.stamp = stamp
        odom.pose.pose.position.x, odom.pose.pose.position.y = self.pose[:2].tolist()
        odom.pose.pose.orientation = conv.quaternion_of_yaw(self.pose[2])
        odom.twist.twist.linear.x, odom.twist.twist.angular.z = self.velocity.tolist()
        self.deliver('odom', odom)
        self.deliver('scan', _scan_without_returns(stamp))

    def prepare(self):
        self.messages += 1
        if self.messages % self.MISSION_MESSAGES == 0:
            self._start_mission()
        self._advance(self.dt)
        self.deliver('plan', self.plan_msg)  # a no-op while it is the current plan
        self._sense()

    def check_after(self, name, fuzzed, result):
        self._control_step()

    def _control_step(self):
        """One control step; its command must be finite, within limits, zero without a plan."""
        self.check_quiet_step(self.node._timer.callback)
        command = self.commands.messages[-1]
        v, omega = command.linear.x, command.angular.z
        assert math.isfinite(v) and math.isfinite(omega), (v, omega)
        assert abs(v) <= self.max_speed + LIMIT_EPS and abs(omega) <= self.max_omega + LIMIT_EPS, \
            f'command ({v!r} m/s, {omega!r} rad/s) beyond the limits'
        if self.node._plan is None:
            assert v == omega == 0.0, (v, omega)
        self.velocity = np.array([v, omega])
        self.pose = integrate_unicycle(self.pose, v, omega, self.dt)

    def still_works(self):
        """Once stale obstacles are forgotten, a new mission ends at the plan's end."""
        self._advance(self.node.get_parameter('obstacle_timeout').value + 1.0)
        self._start_mission()
        for _ in range(self.MISSION_STEPS):
            self._advance(self.dt)
            self._sense()
            self._control_step()
            if self.node._status == 'arrived':
                break
        tolerance = self.node.get_parameter('goal_tolerance').value
        distance = math.dist(self.pose[:2], self.PLAN[-1])
        assert self.node._status == 'arrived' and distance <= tolerance + 0.05, \
            f'status {self.node._status}, {distance:.2f} m from the goal'


class SimulatorTarget(FuzzTarget):
    """The simulator on the bundled demo scenario, free-running (no controller to wait for).

    Each fuzzed message is followed by one simulation step.
    """

    def __init__(self, context):
        from fusion_planner.ros.simulator import MAX_COMMAND_FACTOR, SimulatorNode

        super().__init__(SimulatorNode(context=context, parameter_overrides=[
            Parameter('sync_with_controller', value=False)]))
        robot = self.node.scenario.robot
        self.robot = robot
        self.limits = (MAX_COMMAND_FACTOR * robot.max_speed, MAX_COMMAND_FACTOR * robot.max_omega)

    def strategy(self, name, bad_only=False):
        if self.inputs[name][0] is Twist:
            return twists(*self.limits, bad_only=bad_only)
        return super().strategy(name, bad_only)

    def check_after(self, name, fuzzed, result):
        if name == 'cmd_vel' and fuzzed.defects:
            assert self.node._command == (0.0, 0.0), self.node._command
        self._step()

    def _step(self):
        """One simulation step; the robot stays finite and within its limits."""
        self.check_quiet_step(self.node._step_timer.callback)
        world = self.node.world
        assert np.all(np.isfinite(world.pose)), world.pose
        assert abs(world.velocity[0]) <= self.robot.max_speed + LIMIT_EPS, world.velocity
        assert abs(world.velocity[1]) <= self.robot.max_omega + LIMIT_EPS, world.velocity

    def still_works(self):
        """A good command turns the robot and drives it (unless it is pressed to a wall)."""
        command = Twist()
        command.linear.x, command.angular.z = 0.2, 0.5
        started = self.node.world.time
        for _ in range(10):
            self.deliver('cmd_vel', command)
            self._step()
        world = self.node.world
        assert world.time > started
        assert world.velocity[1] == 0.5, world.velocity
        assert world.velocity[0] > 0.0 or world.in_contact, world.velocity


# -- over DDS -------------------------------------------------------------------------

#: Longest wait [s] for a node to count one published bad message.
REFUSAL_WAIT_S = 2.0


def publish_refused(publisher, fuzzed, refused_count, wait_until):
    """Publish bad messages one at a time, each once the node counted the last refused.

    Parameters
    ----------
    publisher : rclpy.publisher.Publisher
    fuzzed : iterable of Fuzzed
    refused_count : callable
        The node's count of refused messages now, e.g. its diagnostics' ``rejected``.
    wait_until : callable
        ``wait_until(condition, timeout_s)``: spins (or sleeps while another
        thread spins) until ``condition()`` holds or the timeout passes;
        returns ``condition()``.

    Returns
    -------
    int
        How many were counted refused within :data:`REFUSAL_WAIT_S` each (a
        best-effort message may be lost on the way).
    """
    refused = 0
    for item in fuzzed:
        before = refused_count()
        publisher.publish(item.msg)
        refused += bool(wait_until(lambda: refused_count() > before, REFUSAL_WAIT_S))
    return refused


def publish_all_refused(inputs, count, refused_count, wait_until):
    """:func:`publish_refused` of ``count`` bad messages on each ``(publisher, strategy)``.

    Returns
    -------
    dict
        ``{topic name: messages counted refused}``.
    """
    return {publisher.topic_name: publish_refused(publisher, generate(strategy, count),
                                                  refused_count, wait_until)
            for publisher, strategy in inputs}


def allowed_problem_lines(reasons, elapsed_s):
    """Most WARN/ERROR lines a node may print in ``elapsed_s`` [s]: one per reason per log period."""
    return reasons * (elapsed_s // DEFAULT_LOG_PERIOD_S + 1)


def problem_lines(text, node):
    """The WARN, ERROR and FATAL lines of ``node``'s logger in captured console ``text``."""
    tag = f'[{node.get_logger().name}]'
    return [line for line in text.splitlines()
            if tag in line and line.startswith(('[WARN]', '[ERROR]', '[FATAL]'))]


#: The fuzzed nodes: ``{name: (target factory, inputs to fuzz, None for all)}``. The
#: global planner takes its pose from ``amcl_pose`` only by parameter, hence a second
#: target for that input.
TARGETS = {
    'global_planner': (GlobalPlannerTarget, None),
    'global_planner_amcl': (functools.partial(GlobalPlannerTarget,
                                              pose_topic_type='pose_with_covariance'),
                            ('amcl_pose',)),
    'local_planner': (LocalPlannerTarget, None),
    'simulator': (SimulatorTarget, None),
}


# -- soak ------------------------------------------------------------------------------

def fuzz_target(context, name, messages, seed_value, out=None):
    """Fuzz the inputs of ``TARGETS[name]``, then check the node still works.

    Parameters
    ----------
    context : rclpy.Context
    name : str
        A key of :data:`TARGETS`.
    messages : int
        Messages per input.
    seed_value : int
    out : file, optional
        Gets one progress line per input.

    Returns
    -------
    list of Report

    Raises
    ------
    AssertionError
        On the first broken promise.
    """
    factory, inputs = TARGETS[name]
    target = factory(context)
    reports = []
    try:
        for input_name in inputs or sorted(target.inputs):
            report = fuzz_input(target, input_name, messages, seed_value)
            reports.append(report)
            if out is not None:
                print(f'{name}/{input_name}: {report.messages} messages, {report.refused} '
                      f'refused, {report.seconds:.1f} s', file=out, flush=True)
        target.still_works()
    finally:
        target.close()
    return reports


def main(argv=None):
    """Run the soak; exit status 0 when every promise held, 1 otherwise."""
    parser = argparse.ArgumentParser(
        prog='python -m fusion_planner.ros.fuzz',
        description='Feed every node input hypothesis-generated valid and malformed messages, '
                    'check each is used or refused cleanly, then check each node still works.')
    parser.add_argument('--messages', type=int, default=DEFAULT_SOAK_MESSAGES, metavar='N',
                        help='messages per input (default: %(default)s)')
    parser.add_argument('--seed', type=int, default=None, metavar='S',
                        help='seed of the messages (default: from the clock; printed)')
    parser.add_argument('--node', action='append', choices=sorted(TARGETS), dest='nodes',
                        help='fuzz only this target (repeatable; default: all)')
    args = parser.parse_args(argv)
    seed_value = int(time.time()) if args.seed is None else args.seed
    print(f'fuzz soak: {args.messages} messages per input, seed {seed_value}', flush=True)
    context = rclpy.Context()
    rclpy.init(context=context, signal_handler_options=rclpy.signals.SignalHandlerOptions.NO)
    try:
        for name in args.nodes or TARGETS:
            fuzz_target(context, name, args.messages, seed_value, sys.stdout)
            print(f'{name}: still works', flush=True)
    except AssertionError as err:
        print(f'FAILED: {err}', file=sys.stderr)
        return 1
    finally:
        rclpy.try_shutdown(context=context)
    return 0


if __name__ == '__main__':
    raise SystemExit(main())
