"""REP-105 frames without tf2: map -> odom from a localization pose and odometry.

A planar transform or pose is ``(x, y, yaw)`` [m, m, rad]; ``compose(a, b)``
is ``b`` expressed in ``a``'s parent frame (``T_map_base = compose(T_map_odom,
T_odom_base)``).

:class:`Localization` keeps the timed odometry (``odom`` -> ``base_link``)
and, from each localization pose (``map`` -> ``base_link``, e.g.
``amcl_pose``), the correction ``map`` -> ``odom`` computed with the
odometry *at the localization's stamp*, the way AMCL and robot_localization
publish it on TF. Odometry drifts but is smooth; the correction absorbs the
drift and moves in small steps at the localization rate.

On a full ROS install the same transforms can come from TF instead
(:class:`TfSource`, ``use_tf``).
"""

import collections
import math

import numpy as np
from rclpy.time import Time

from fusion_planner.core.errors import InvalidInput
from fusion_planner.ros.conversions import yaw_of_quaternion
from fusion_planner.ros.timed_pose import pose_at

#: Odometry messages remembered to find the pose at a stamp [1].
ODOM_HISTORY = 512


def compose(a, b):
    """The transform ``a`` followed by ``b`` (``b`` given in ``a``'s child frame).

    Examples
    --------
    >>> compose((1.0, 0.0, math.pi / 2), (1.0, 0.0, 0.0)).round(6).tolist()
    [1.0, 1.0, 1.570796]
    """
    x, y, yaw = a
    c, s = math.cos(yaw), math.sin(yaw)
    return np.array([x + c * b[0] - s * b[1], y + s * b[0] + c * b[1],
                     math.atan2(math.sin(yaw + b[2]), math.cos(yaw + b[2]))])


def inverse(a):
    """The inverse transform of ``a``.

    Examples
    --------
    >>> compose((1.0, 2.0, 0.5), inverse((1.0, 2.0, 0.5))).round(9).tolist()
    [0.0, 0.0, 0.0]
    """
    x, y, yaw = a
    c, s = math.cos(yaw), math.sin(yaw)
    return np.array([-c * x - s * y, s * x - c * y, -yaw])


def map_from_odom(map_pose, odom_pose):
    """The map -> odom transform that puts the robot's ``odom_pose`` at its ``map_pose``."""
    return compose(map_pose, inverse(odom_pose))


def transform_points(transform, points):
    """``(N, 2)`` points [m] given in the child frame of ``transform``, in its parent frame."""
    points = np.asarray(points, dtype=float).reshape(-1, 2)
    x, y, yaw = transform
    c, s = math.cos(yaw), math.sin(yaw)
    return points @ np.array([[c, s], [-s, c]]) + np.array([x, y])


def rotate_vectors(yaw, vectors):
    """``(N, 2)`` vectors (velocities) rotated by ``yaw`` [rad]."""
    c, s = math.cos(yaw), math.sin(yaw)
    return np.asarray(vectors, dtype=float).reshape(-1, 2) @ np.array([[c, s], [-s, c]])


class Localization:
    """Timed odometry and the map -> odom correction of the latest localization pose.

    Parameters
    ----------
    max_gap : float
        Longest time [s] an odometry pose is moved ahead along its velocity
        to reach a stamp (see :func:`~fusion_planner.ros.timed_pose.pose_at`).
    same_frame : bool
        The odometry is already in the map frame: the correction is the
        identity and no localization pose is needed.
    """

    def __init__(self, max_gap, same_frame=False):
        self.max_gap = float(max_gap)
        self.same_frame = bool(same_frame)
        self.odometry = collections.deque(maxlen=ODOM_HISTORY)  # (stamp, pose, velocity)
        self.map_from_odom = np.zeros(3) if same_frame else None
        self.pending = None  # (stamp, pose) of a localization that came before any odometry

    def clear(self):
        """Forget odometry and correction (a clock reset)."""
        self.odometry.clear()
        self.map_from_odom = np.zeros(3) if self.same_frame else None
        self.pending = None

    def add_odometry(self, stamp, pose, velocity):
        """Odometry: ``stamp`` [s], ``pose`` (3,) in odom, ``velocity`` (v, omega).

        Returns True when a localization pose kept for want of odometry
        (see :meth:`add_localization`) has now made the correction.
        """
        if self.odometry and stamp < self.odometry[-1][0]:
            self.odometry.clear()  # stamps went back (a simulation reset)
        self.odometry.append((stamp, np.array(pose, dtype=float),
                              np.array(velocity, dtype=float)))
        if self.pending is None:
            return False
        kept, self.pending = self.pending, None
        return self.add_localization(*kept)

    def add_localization(self, stamp, pose):
        """A map-frame pose of the robot at ``stamp`` [s]; False when it cannot be paired now.

        A pose that comes before any odometry (AMCL's latched pose is
        delivered as soon as the subscription matches) is kept and paired
        with the first odometry (:meth:`add_odometry`). A pose older
        than the whole odometry history pairs with the oldest odometry:
        right for the first one (the latched pose of a robot that has not
        moved yet), off by the distance driven in between for a late one,
        which is left unused once there is a correction.
        """
        if self.same_frame:
            return False
        if not self.odometry:
            self.pending = (stamp, np.array(pose, dtype=float))
            return False
        if 0 < stamp < self.odometry[0][0] and self.map_from_odom is not None:
            return False
        odom_pose = self.odom_pose_at(stamp) if stamp > 0 else self.odometry[-1][1]
        self.map_from_odom = map_from_odom(pose, odom_pose)
        return True

    def odom_pose_at(self, t):
        """The odometry pose at ``t`` [s] (odom frame); needs odometry."""
        return pose_at(self.odometry, t, self.max_gap)

    def map_pose_at(self, t):
        """The robot pose at ``t`` [s] in the map frame, or None without a correction."""
        if self.map_from_odom is None or not self.odometry:
            return None
        return compose(self.map_from_odom, self.odom_pose_at(t))


class TfSource:
    """Planar transforms from a tf2 buffer (``tf2_ros.Buffer`` or anything with its interface).

    Parameters
    ----------
    buffer : object
        With ``can_transform(target, source, time)`` and
        ``lookup_transform(target, source, time)`` returning a
        ``geometry_msgs/TransformStamped``, as ``tf2_ros.Buffer`` has them.
    listener : object, optional
        The ``tf2_ros.TransformListener`` filling the buffer (kept alive here).
    """

    def __init__(self, buffer, listener=None):
        self.buffer = buffer
        self.listener = listener

    def planar(self, target, source):
        """The latest ``source`` -> ``target`` transform as ``(x, y, yaw)``, or None if unknown.

        Raises
        ------
        InvalidInput
            If the transform holds a NaN or a bad quaternion.
        """
        latest = Time()
        if not self.buffer.can_transform(target, source, latest):
            return None
        transform = self.buffer.lookup_transform(target, source, latest).transform
        what = f'transform {source} -> {target}'
        x, y = transform.translation.x, transform.translation.y
        if not (math.isfinite(x) and math.isfinite(y)):
            raise InvalidInput(f'{what} has a NaN or infinite translation')
        return np.array([x, y, yaw_of_quaternion(transform.rotation, what)])


    def scan_pose(self, target, scan_frame):
        """The pose of a scan's frame in ``target`` (latest); InvalidInput when TF has none."""
        pose = self.planar(target, scan_frame)
        if pose is None:
            raise InvalidInput(f'scan is in frame {scan_frame!r}, which TF does not connect to '
                               f'{target!r}')
        return pose


def make_tf_source(node):
    """A :class:`TfSource` on a ``tf2_ros.Buffer`` filled by a listener on ``node``.

    Raises
    ------
    InvalidInput
        If tf2_ros is not importable (the Python wheels have no tf2).
    """
    try:
        import tf2_ros
    except ImportError:
        raise InvalidInput('use_tf needs tf2_ros, which is not installed here') from None
    buffer = tf2_ros.Buffer()
    return TfSource(buffer, tf2_ros.TransformListener(buffer, node))
