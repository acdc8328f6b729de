"""package.xml declares every ROS package the code imports (rosdep installs only those)."""

import ast
import pathlib
import xml.etree.ElementTree as ET

REPO = pathlib.Path(__file__).resolve().parent.parent
#: Python module of a ROS package -> the package name rosdep knows (they differ for a few).
ROS_PACKAGE_OF_MODULE = {'tf2_ros': 'tf2_ros_py'}
#: Modules of ROS packages that are not message or service packages.
ROS_MODULES = ('rclpy', 'rcl_interfaces', 'ament_index_python', 'tf2_ros')


def imported_ros_packages():
    """ROS package names imported anywhere in fusion_planner/, by file."""
    found = {}
    for path in (REPO / 'fusion_planner').rglob('*.py'):
        for node in ast.walk(ast.parse(path.read_text())):
            if isinstance(node, ast.Import):
                names = [alias.name for alias in node.names]
            elif isinstance(node, ast.ImportFrom) and node.level == 0:
                names = [node.module]
            else:
                continue
            for name in names:
                top = name.split('.')[0]
                if top in ROS_MODULES or top.endswith(('_msgs', '_srvs')):
                    found.setdefault(ROS_PACKAGE_OF_MODULE.get(top, top), path.name)
    return found


def test_every_imported_ros_package_is_an_exec_depend():
    root = ET.parse(REPO / 'package.xml').getroot()
    declared = {e.text for e in root.iter('exec_depend')}
    missing = {pkg: where for pkg, where in imported_ros_packages().items() if pkg not in declared}
    assert not missing, f'imported but not in package.xml: {missing}'
    assert {'rclpy', 'rcl_interfaces', 'ament_index_python'} <= set(imported_ros_packages())
