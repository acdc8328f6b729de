"""Named exceptions of the planning core.

Every failure a caller can act on has its own class, named after Nav2's
planner outcome vocabulary (``StartOutsideMapBounds``, ``GoalOccupied``,
``NoValidPathCouldBeFound``, ``PlannerTimedOut`` ...), so that the ROS adapters
can map each one to a diagnostics outcome without parsing messages.
The message of each exception is one human-readable sentence.
"""


class PlanningError(Exception):
    """Base class of every error raised by the planning core."""

    #: Short outcome code reported on diagnostics and in ``--json`` output.
    outcome = 'planning_error'


class InvalidInput(PlanningError, ValueError):
    """An argument is malformed (NaN coordinate, bad resolution, bad shape)."""

    outcome = 'invalid_input'


class MapError(InvalidInput):
    """A map could not be built or loaded (bad file, bad fields, too large)."""

    outcome = 'invalid_map'


class StartOutsideMapBounds(PlanningError):
    """The start lies outside the map."""

    outcome = 'start_outside_map'


class GoalOutsideMapBounds(PlanningError):
    """The goal lies outside the map."""

    outcome = 'goal_outside_map'


class StartOccupied(PlanningError):
    """The start lies in an obstacle."""

    outcome = 'start_occupied'


class GoalOccupied(PlanningError):
    """The goal lies in an obstacle or in the inflation around one."""

    outcome = 'goal_occupied'


class NoValidPathCouldBeFound(PlanningError):
    """The search exhausted every reachable cell without reaching the goal."""

    outcome = 'no_valid_path'


class PlannerTimedOut(PlanningError):
    """The search hit its expansion or time budget before reaching the goal."""

    outcome = 'timeout'


class PlannerCancelled(PlanningError):
    """The caller's cancel callable asked the search to stop."""

    outcome = 'cancelled'
