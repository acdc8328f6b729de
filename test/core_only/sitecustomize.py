"""A core-only Python for subprocesses: the optional dependencies do not import.

Put this folder first on ``PYTHONPATH``; Python runs this file at start-up.
Every top-level module named in ``FUSION_PLANNER_BLOCKED`` (comma-separated;
default every module of every extra of setup.py) then raises
``ModuleNotFoundError`` on import, as on a machine where the extra was never
installed.
"""

import importlib.abc
import os
import sys

#: The top-level modules of the extras ros, plot, record, bench and test.
EXTRAS = ('rclpy', 'rpyutils', 'builtin_interfaces', 'std_msgs', 'geometry_msgs', 'nav_msgs',
          'sensor_msgs', 'visualization_msgs', 'diagnostic_msgs', 'rosgraph_msgs',
          'matplotlib', 'PIL', 'mcap', 'mcap_ros2', 'pyastar2d', 'tcod', 'pathfinding',
          'python_motion_planning', 'networkx', 'pytest', 'hypothesis')
BLOCKED = frozenset(filter(None, os.environ.get('FUSION_PLANNER_BLOCKED', ','.join(EXTRAS))
                           .split(',')))


class _NotInstalled(importlib.abc.MetaPathFinder):
    """Refuses the blocked modules before any other finder can find them."""

    def find_spec(self, fullname, path=None, target=None):
        if fullname.partition('.')[0] in BLOCKED:
            raise ModuleNotFoundError(f'No module named {fullname!r}', name=fullname)
        return None


for _name in [n for n in sys.modules if n.partition('.')[0] in BLOCKED]:
    del sys.modules[_name]
sys.meta_path.insert(0, _NotInstalled())
