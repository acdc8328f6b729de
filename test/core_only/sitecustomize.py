"""A core-only Python for subprocesses: the optional dependencies do not import.

Put this folder first on ``PYTHONPATH``; Python runs this file at start-up.
Every top-level module named in ``FUSION_PLANNER_BLOCKED`` (comma-separated;
default every module of every extra of setup.py) is then not found, as on a
machine where the extra was never installed: ``importlib.util.find_spec``
gives None and ``import`` raises ``ModuleNotFoundError``.
"""

import os
import sys

#: The top-level modules of the extras ros, fast, plot, record, bench and test.
EXTRAS = ('rclpy', 'rpyutils', 'builtin_interfaces', 'std_msgs', 'geometry_msgs', 'nav_msgs',
          'sensor_msgs', 'visualization_msgs', 'diagnostic_msgs', 'rosgraph_msgs',
          'matplotlib', 'PIL', 'mcap', 'mcap_ros2', 'pyastar2d', 'tcod', 'pathfinding',
          'python_motion_planning', 'networkx', 'pytest', 'hypothesis', 'numba', 'llvmlite')
BLOCKED = frozenset(filter(None, os.environ.get('FUSION_PLANNER_BLOCKED', ','.join(EXTRAS))
                           .split(',')))


class _NotInstalled:
    """Wraps a finder of ``sys.meta_path``: the blocked modules are not found, the rest as before.

    As for a module that is not installed, ``importlib.util.find_spec`` gives
    None and ``import`` raises ``ModuleNotFoundError``.
    """

    def __init__(self, finder):
        self.finder = finder

    def find_spec(self, fullname, path=None, target=None):
        if fullname.partition('.')[0] in BLOCKED:
            return None
        return self.finder.find_spec(fullname, path, target)

    def __getattr__(self, name):  # invalidate_caches and the like
        return getattr(self.finder, name)


for _name in [n for n in sys.modules if n.partition('.')[0] in BLOCKED]:
    del sys.modules[_name]
sys.meta_path[:] = [_NotInstalled(finder) for finder in sys.meta_path]
