"""Progress toward the goal, measured continuously: how long since the robot last made some.

A navigation stack gives up on a goal after a while *without progress*, not
after a while since it started: a robot that yields to a person for 20 s and
then drives on has not failed. :class:`ProgressMonitor` keeps the best (least)
remaining distance to the goal seen so far and when it last improved by at
least ``stuck_progress``; a new plan may change what "remaining" means, so
:meth:`ProgressMonitor.rebase` restarts the distance without restarting the
clock (replanning alone is no progress); :meth:`ProgressMonitor.restart`
restarts both, for a caller that grants a new plan the full allowance.

Time in which something else drove the robot farther from the goal (people
it got out of the way of) is not held against it: a robot chased off 5 m
from its goal by a person has the time the chase took to come back, and
does not fail 0.9 m from the goal as it returns.

Examples
--------
>>> monitor = ProgressMonitor(min_progress=0.15)
>>> monitor.update(0.0, 10.0), monitor.update(5.0, 9.95), monitor.update(6.0, 9.8)
(0.0, 5.0, 0.0)
>>> monitor.rebase(12.0); monitor.update(8.0, 12.0)
2.0
>>> monitor.restart(8.0, 12.0); monitor.update(9.0, 12.5)
1.0
>>> monitor.update(10.0, 13.5, pushed=True), monitor.update(11.0, 13.0, pushed=True)
(1.0, 2.0)
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
        self._last = None  # time [s] and remaining distance [m] of the last update

    def update(self, t, remaining, pushed=False):
        """Record the remaining distance [m] at time ``t`` [s]; return the time [s] without progress.

        ``pushed``: the robot was driven out of someone's way since the last
        update; if that took it farther from the goal, the time does not count.
        """
        if self._since is None or t < self._since:  # first call, or the clock went back
            self.restart(t, remaining)
        elif remaining <= self._best - self.min_progress:
            self.restart(t, remaining)
        elif pushed and remaining > self._last[1]:
            self._since = min(self._since + t - self._last[0], t)
        self._last = (t, remaining)
        return t - self._since

    def restart(self, t, remaining):
        """Measure from ``remaining`` [m] at time ``t`` [s] on, as if progress had just been made."""
        self._best = remaining
        self._since = t
        self._last = (t, remaining)

    def rebase(self, remaining):
        """A new plan: measure from ``remaining`` [m] on, keeping the time of the last progress."""
        self._best = remaining
        if self._last is not None:
            self._last = (self._last[0], remaining)
