"""Optional dependencies: checked before any work, reported as one line naming the extra.

Every command, option and executable that needs an optional library asks
:func:`require` (or :func:`missing`) for the extra of ``setup.py`` that
provides it before it starts; when a module of that extra does not import,
the user reads one line that says what to install, and the command exits
with status 2 (bad input) without a traceback.
"""

import importlib
import sys

from fusion_planner.core.errors import InvalidInput

#: The modules each extra of setup.py provides, as they are imported. ``ros``
#: covers rclpy and every message package the nodes and the demo use.
EXTRA_MODULES = {
    'ros': ('rclpy', 'builtin_interfaces.msg', 'std_msgs.msg', 'geometry_msgs.msg',
            'nav_msgs.msg', 'sensor_msgs.msg', 'visualization_msgs.msg', 'diagnostic_msgs.msg',
            'rosgraph_msgs.msg'),
    'plot': ('matplotlib', 'PIL'),
    'record': ('mcap', 'mcap_ros2'),
    'bench': ('pyastar2d', 'tcod', 'pathfinding', 'python_motion_planning', 'networkx'),
    'test': ('pytest', 'hypothesis'),
}

#: Exit status of a missing extra (bad input, as every command's).
EXIT_BAD_INPUT = 2

#: How to get the ROS 2 libraries: a sourced install, or the wheels of the extra.
ROS_HINT = ("source a ROS 2 Jazzy install (. /opt/ros/jazzy/setup.bash) "
            "or pip install 'fusion_planner[ros]'")


class MissingExtra(InvalidInput):
    """An optional dependency that a command needs does not import (exit 2, one line)."""

    outcome = 'missing_extra'


def missing(extra, purpose, modules=None, alternative=None):
    """The one-line complaint about a missing optional dependency, or None.

    Parameters
    ----------
    extra : str
        A key of :data:`EXTRA_MODULES` (an extra of setup.py).
    purpose : str
        What needs it, as the user asked for it (``'plan --plot'``).
    modules : sequence of str, optional
        The modules to import; default all of the extra's.
    alternative : str, optional
        Another way out, e.g. ``'give --no-plot'``.

    Returns
    -------
    str or None
        None when every module imports, else one sentence naming the
        module that failed and what to install.

    Examples
    --------
    >>> missing('plot', 'plan --plot', modules=('math',)) is None
    True
    """
    for name in EXTRA_MODULES[extra] if modules is None else modules:
        try:
            importlib.import_module(name)
        except ImportError as err:
            reason = ' '.join(str(err).split()) or type(err).__name__
            fix = ROS_HINT if extra == 'ros' else f"pip install 'fusion_planner[{extra}]'"
            other = f', or {alternative}' if alternative else ''
            return f'{purpose} needs the {extra} extra ({reason}): {fix}{other}'
    return None


def require(extra, purpose, modules=None, alternative=None):
    """Raise :class:`MissingExtra` unless :func:`missing` finds nothing.

    Parameters
    ----------
    extra, purpose, modules, alternative
        As for :func:`missing`.

    Raises
    ------
    MissingExtra
        With the one-line complaint.
    """
    problem = missing(extra, purpose, modules, alternative)
    if problem is not None:
        raise MissingExtra(problem)


def exit_if_missing(extras, program, purpose=None):
    """For a program without the command line's error handling: one line and exit 2.

    Parameters
    ----------
    extras : sequence of str
        Extras the program needs, checked in order.
    program : str
        Its name, first on the line.
    purpose : str, optional
        What needs the extras (default ``program``).

    Raises
    ------
    SystemExit
        With status :data:`EXIT_BAD_INPUT` after the line on stderr, when an
        extra is missing.
    """
    for extra in extras:
        problem = missing(extra, purpose or program)
        if problem is not None:
            print(f'{program}: error: {problem}', file=sys.stderr)
            raise SystemExit(EXIT_BAD_INPUT)
