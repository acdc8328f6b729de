"""The local planner's moving obstacles from its own laser: scans in, tracks and markers out.

:class:`ScanTracks` holds a :class:`~fusion_planner.core.local_planning.scan_tracker.ScanTracker`
on the known map (from the ``map`` topic) and feeds it the ``scan``
messages, each placed with the robot pose of its own stamp. Its moving
tracks are fused with the obstacles of the optional ``obstacles`` topic
(:func:`fuse`) and drawn as a MarkerArray (:func:`tracks_to_markers`):
a cylinder per track and an arrow of its velocity.

Frames: the map frame (``frame_id``) for tracks and markers; the scan is in
the robot frame with the laser at the robot's origin (as
:func:`~fusion_planner.ros.conversions.scan_to_rays` assumes).
"""

import numpy as np
from geometry_msgs.msg import Point
from visualization_msgs.msg import Marker, MarkerArray

from fusion_planner.core.local_planning.scan_tracker import ScanTracker, ScanVerdict
from fusion_planner.ros import conversions as conv

#: Length of a velocity arrow: where the track will be this much later [s].
ARROW_TIME_S = 1.0
#: Arrow shaft diameter and head diameter and length [m].
ARROW_SCALE = (0.05, 0.12, 0.15)
#: Colours of track cylinders and arrows (r, g, b, a).
TRACK_RGBA = (0.9, 0.1, 0.8, 0.6)
ARROW_RGBA = (0.9, 0.1, 0.8, 1.0)


class ScanTracks:
    """Scan tracking on the current map (see the module notes).

    Parameters
    ----------
    frame_id : str
        The map frame.
    """

    def __init__(self, frame_id):
        self.frame_id = frame_id
        self._tracker = None

    @property
    def has_map(self):
        """Whether a map arrived (tracking needs one)."""
        return self._tracker is not None

    def set_map(self, grid):
        """Track on a new known map (forgets every track)."""
        self._tracker = ScanTracker(grid)

    def update(self, msg, robot_pose, stamp_s):
        """Take in one ``sensor_msgs/LaserScan`` taken at ``robot_pose`` ``(x, y, yaw)``.

        Returns
        -------
        ScanVerdict
            Refused without a map, or as the tracker refuses it (out of
            order, bad values); NaN, infinite and out-of-range ranges are no
            returns.
        """
        if self._tracker is None:
            return ScanVerdict(False, 'no map yet: scans are not tracked')
        ranges = np.asarray(msg.ranges, dtype=float).reshape(-1)
        angles = msg.angle_min + msg.angle_increment * np.arange(len(ranges))
        with np.errstate(invalid='ignore'):
            returns = (ranges >= msg.range_min) & (ranges < msg.range_max)
        return self._tracker.update(angles, np.where(returns, ranges, np.nan), robot_pose, stamp_s)

    def movers(self, now_s):
        """The moving tracks and the tentative movers, predicted to ``now_s`` [s].

        Returns
        -------
        tracked, tentative : ndarray, shape (K, 5) and (T, 5)
            ``x, y, vx, vy, radius`` (map frame) of the moving tracks and of
            the objects that seem to move but are not confirmed yet.
        turn_stds : ndarray, shape (K,)
            How much each moving track turns [rad / sqrt(s)].
        """
        if self._tracker is None:
            return np.zeros((0, 5)), np.zeros((0, 5)), np.zeros(0)
        report = self._tracker.report(now_s)
        return report.tracked, report.tentative, report.turn_stds

    def report(self):
        """The tracker's TrackReport (None without a map)."""
        return None if self._tracker is None else self._tracker.report()

    def clear(self):
        """Forget every track (a clock reset)."""
        if self._tracker is not None:
            self._tracker.reset()


def fuse(scan_tracks, external, scan_turn_stds):
    """Scan tracks and externally tracked obstacles as one ``(K, 5)`` array.

    An external obstacle (from the ``obstacles`` topic) wins over a scan
    track that overlaps it (centres closer than the sum of the radii): both
    are the same object, seen by a better-placed tracker.

    Returns the obstacles and how much each turns ``(K,)`` [rad / sqrt(s)]:
    ``scan_turn_stds`` for the scan tracks, NaN (unknown) for the external
    ones.

    Examples
    --------
    >>> scan = np.array([[1.0, 0.0, 0.5, 0.0, 0.3], [5.0, 0.0, 0.0, 0.5, 0.3]])
    >>> tracked, turns = fuse(scan, np.array([[1.2, 0.0, 0.4, 0.0, 0.25]]), np.array([0.2, 0.4]))
    >>> tracked[:, 0].tolist(), turns.tolist()
    ([1.2, 5.0], [nan, 0.4])
    """
    external = external.reshape(-1, 5)
    unknown = np.full(len(external), np.nan)
    if not len(external) or not len(scan_tracks):
        return (np.vstack([external, scan_tracks.reshape(-1, 5)]),
                np.concatenate([unknown, scan_turn_stds]))
    gap = np.hypot(*(scan_tracks[:, None, 0:2] - external[None, :, 0:2]).transpose(2, 0, 1))
    overlap = (gap < scan_tracks[:, None, 4] + external[None, :, 4]).any(axis=1)
    return (np.vstack([external, scan_tracks[~overlap]]),
            np.concatenate([unknown, scan_turn_stds[~overlap]]))


def tracks_to_markers(report, frame_id, stamp):
    """A MarkerArray of the moving tracks: cylinders and velocity arrows.

    Parameters
    ----------
    report : TrackReport or None
    frame_id : str
    stamp : builtin_interfaces.msg.Time

    Returns
    -------
    visualization_msgs.msg.MarkerArray
        A ``DELETEALL`` first (tracks come and go), then per track a
        cylinder (namespace ``tracks``, id = track id) and an arrow
        (namespace ``track_velocities``) from its centre to where it will be
        after :data:`ARROW_TIME_S`.
    """
    out = MarkerArray()
    out.markers.append(conv.delete_all_marker(frame_id, stamp))
    if report is None or not len(report.ids):
        return out
    tracked = report.tracked
    cylinders = conv.obstacles_to_markers(tracked, frame_id, stamp, ns='tracks',
                                          ids=report.ids.tolist())
    for marker in cylinders.markers:
        marker.color.r, marker.color.g, marker.color.b, marker.color.a = TRACK_RGBA
    out.markers.extend(cylinders.markers)
    ends = tracked[:, 0:2] + ARROW_TIME_S * tracked[:, 2:4]
    for track_id, (x, y), (ex, ey) in zip(report.ids.tolist(), tracked[:, 0:2].tolist(),
                                          ends.tolist()):
        arrow = Marker()
        arrow.header.frame_id = frame_id
        arrow.header.stamp = stamp
        arrow.ns = 'track_velocities'
        arrow.id = track_id
        arrow.type = Marker.ARROW
        arrow.action = Marker.ADD
        arrow.pose.orientation.w = 1.0
        arrow.points = [Point(x=x, y=y, z=0.0), Point(x=ex, y=ey, z=0.0)]
        arrow.scale.x, arrow.scale.y, arrow.scale.z = ARROW_SCALE
        arrow.color.r, arrow.color.g, arrow.color.b, arrow.color.a = ARROW_RGBA
        out.markers.append(arrow)
    return out
