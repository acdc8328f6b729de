"""The robot pose at a given time from timed odometry (no tf2 buffer here)."""

import numpy as np

from fusion_planner.core.simulation.world import integrate_unicycle


def pose_at(history, t, max_gap):
    """The robot pose at time ``t`` from timed odometry.

    Parameters
    ----------
    history : sequence of tuple
        ``(stamp [s], pose (3,) x, y, yaw [m, m, rad], velocity (2,) v, omega
        [m/s, rad/s])``, oldest first, non-empty.
    t : float
        Time [s] on the odometry's clock.
    max_gap : float
        Longest time [s] the pose is predicted ahead of a message.

    Returns
    -------
    ndarray, float64, shape (3,)
        The pose of the latest message stamped at or before ``t`` (the oldest
        one if all are later), moved ahead to ``t`` along its measured
        velocity (unicycle) when ``0 < t - stamp <= max_gap``.

    Notes
    -----
    This compensates the delay between a control step and the odometry it
    uses (messages of another process or thread may arrive a step late), and
    places a scan with the pose of its own time rather than the latest one.

    Examples
    --------
    >>> pose_at([(1.0, np.zeros(3), np.array([0.5, 0.0]))], 1.2, 0.5).round(3).tolist()
    [0.1, 0.0, 0.0]
    """
    chosen = history[0]
    for entry in reversed(history):
        if entry[0] <= t:
            chosen = entry
            break
    stamp, pose, velocity = chosen
    gap = t - stamp
    if 0.0 < gap <= max_gap:
        return integrate_unicycle(pose, velocity[0], velocity[1], gap)
    return np.array(pose, dtype=float)
