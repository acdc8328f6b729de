"""Progress toward the goal, measured continuously: how long since the robot last made some.

A navigation stack gives up on a goal after a while *without progress*, not
after a while since it started: a robot that yields to a person for 20 s and
then drives on has not failed. :class:`ProgressMonitor` keeps the best (least)
remaining distance to the goal seen so far and when it last improved by at
least ``stuck_progress``; a new plan may change what "remaining" means, so
:meth:`ProgressMonitor.rebase` restarts the distance without restarting the
clock (replanning alone is no progress); :meth:`ProgressMonitor.restart`
restarts both, for a caller that grants a new plan the full allowance.

Examples
--------
>>> monitor = ProgressMonitor(min_progress=0.15)
>>> monitor.update(0.0, 10.0), monitor.update(5.0, 9.95), monitor.update(6.0, 9.8)
(0.0, 5.0, 0.0)
>>> monitor.rebase(12.0); monitor.update(8.0, 12.0)
2.0
>>> monitor.restart(8.0, 12.0); monitor.update(9.0, 12.5)
1.0
"""

import math


class ProgressMonitor:
    """Time since the remaining distance to the goal last shrank by ``min_progress``.

    Parameters
    ----------
    min_progress : float
        [m], > 0: an improvement of the best remaining distance by at least
        this much is progress.
    """

    def __init__(self, min_progress):
        self.min_progress = min_progress
        self._best = math.inf
        self._since = None

    def update(self, t, remaining):
        """Record the remaining distance [m] at time ``t`` [s]; return the time [s] without progress."""
        if self._since is None or t < self._since:  # first call, or the clock went back
            self._since = t
            self._best = remaining
        elif remaining <= self._best - self.min_progress:
            self._best = remaining
            self._since = t
        return t - self._since

    def restart(self, t, remaining):
        """Measure from ``remaining`` [m] at time ``t`` [s] on, as if progress had just been made."""
        self._best = remaining
        self._since = t

    def rebase(self, remaining):
        """A new plan: measure from ``remaining`` [m] on, keeping the time of the last progress."""
        self._best = remaining
