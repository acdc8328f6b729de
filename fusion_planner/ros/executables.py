"""Entry points of the node executables: ROS 2 is checked before a node module is imported.

The node modules import rclpy and the message packages at their top, so a
machine without ROS 2 would fail there with a traceback. These entry points
(the console scripts ``global_planner``, ``local_planner`` and
``simulator`` that ``ros2 run`` starts in a colcon install) first check the
``ros`` extra (:mod:`fusion_planner.cli.requirements`); without it they print
one line and exit with status 2, else they run the node's ``main``.
"""

import importlib

from fusion_planner.cli.requirements import exit_if_missing


def run(node, args=None):
    """Run the ``main`` of ``fusion_planner.ros.<node>``; returns its exit status.

    Parameters
    ----------
    node : str
        ``'global_planner'``, ``'local_planner'`` or ``'simulator'``.
    args : list of str, optional
        Command-line arguments (``--ros-args ...``); default ``sys.argv``.

    Raises
    ------
    SystemExit
        Status 2 after one line on stderr when ROS 2 does not import.
    """
    exit_if_missing(('ros',), node, 'the node')
    return importlib.import_module(f'fusion_planner.ros.{node}').main(args)


def global_planner():
    """The ``global_planner`` executable."""
    return run('global_planner')


def local_planner():
    """The ``local_planner`` executable."""
    return run('local_planner')


def simulator():
    """The ``simulator`` executable."""
    return run('simulator')
