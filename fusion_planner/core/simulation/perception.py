"""What a simulated controller is told about the moving obstacles.

Two modes, named in :data:`PERCEPTION_MODES`:

``scan``
    A :class:`~fusion_planner.core.local_planning.scan_tracker.ScanTracker`
    on the known map reads every simulated scan; the controller gets its
    moving tracks only. What the laser does not see (a person behind a wall)
    is not reported, and a person is reported only once the tracker has
    seen it move.
``ideal``
    The oracle: the true position and velocity of every moving obstacle,
    seen or not (:meth:`World.tracked_obstacles`).

Either way the controller also gets every scan hit point.
"""

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
    """

    mode = 'scan'

    def __init__(self, grid):
        self.tracker = ScanTracker(grid)

    def tracked(self, world, scan):
        """``(K, 5)`` ``x, y, vx, vy, radius`` of the moving tracks after ``scan`` (map frame)."""
        self.tracker.update(scan.angles, scan.ranges, scan.origin, world.time)
        return self.tracker.report().tracked


class IdealPerception:
    """Every moving obstacle's true state, visible or not."""

    mode = 'ideal'

    def tracked(self, world, scan):
        """``(K, 5)`` ``x, y, vx, vy, radius`` of every moving obstacle (map frame)."""
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
