"""What a simulated controller is told about the moving obstacles.

Two modes, named in :data:`PERCEPTION_MODES`:

``scan``
    A :class:`~fusion_planner.core.local_planning.scan_tracker.ScanTracker`
    on the known map reads every simulated scan; the controller gets its
    moving tracks, and apart from them its tentative movers (objects that
    seem to move but have not travelled far enough to be sure). What the
    laser does not see (a person behind a wall) is not reported, and a
    person is reported as moving only once the tracker has seen it move.
``ideal``
    The oracle: the true position and velocity of every moving obstacle,
    seen or not (:meth:`World.tracked_obstacles`).

Either way the controller also gets every scan hit point.
"""

import numpy as np

from fusion_planner.core.errors import InvalidInput
from fusion_planner.core.local_planning.scan_tracker import ScanTracker

#: Perception modes, the default first.
PERCEPTION_MODES = ('scan', 'ideal')


class ScanPerception:
    """Moving obstacles as a scan tracker makes them out.

    Parameters
    ----------
    grid : GridMap
        The known map (returns on it are not objects).

    Attributes
    ----------
    tracker : ScanTracker
    tentative : ndarray, shape (T, 5)
        ``x, y, vx, vy, radius`` of the tentative movers after the last
        :meth:`tracked` (map frame).
    turn_stds : ndarray, shape (K,)
        The tracker's estimate of how much each moving track turns
        [rad / sqrt(s)], after the last :meth:`tracked`.
    """

    mode = 'scan'

    def __init__(self, grid):
        self.tracker = ScanTracker(grid)
        self.tentative = np.zeros((0, 5))
        self.turn_stds = np.zeros(0)

    def tracked(self, world, scan):
        """``(K, 5)`` ``x, y, vx, vy, radius`` of the moving tracks after ``scan`` (map frame)."""
        self.tracker.update(scan.angles, scan.ranges, scan.origin, world.time)
        report = self.tracker.report()
        self.tentative = report.tentative
        self.turn_stds = report.turn_stds
        return report.tracked


class IdealPerception:
    """Every moving obstacle's true state, visible or not.

    Attributes
    ----------
    tentative : ndarray, shape (0, 5)
        None: the oracle is sure of every obstacle.
    turn_stds : ndarray, shape (K,)
        How much each one turns [rad / sqrt(s)], from its motion
        (:meth:`World.turn_stds`), after the last :meth:`tracked`.
    """

    mode = 'ideal'
    tentative = np.zeros((0, 5))

    def __init__(self):
        self.turn_stds = np.zeros(0)

    def tracked(self, world, scan):
        """``(K, 5)`` ``x, y, vx, vy, radius`` of every moving obstacle (map frame)."""
        self.turn_stds = world.turn_stds()
        return world.tracked_obstacles()


def make_perception(mode, grid):
    """The perception of a mode.

    Parameters
    ----------
    mode : str
        One of :data:`PERCEPTION_MODES`.
    grid : GridMap
        The known map.

    Returns
    -------
    ScanPerception or IdealPerception

    Raises
    ------
    InvalidInput
        Unknown mode.
    """
    check_mode(mode)
    return ScanPerception(grid) if mode == 'scan' else IdealPerception()


def check_mode(mode):
    """Raise InvalidInput unless ``mode`` is one of :data:`PERCEPTION_MODES`."""
    if mode not in PERCEPTION_MODES:
        raise InvalidInput(
            f'unknown perception {mode!r}; choose one of {", ".join(PERCEPTION_MODES)}')
