"""Build script of fusion_planner (ament_python layout, also pip-installable)."""

import glob
import os

from setuptools import find_packages, setup

PACKAGE = 'fusion_planner'


def share(folder):
    """Install every file of a config sub-folder under share/fusion_planner."""
    return (f'share/{PACKAGE}/{folder}', sorted(f for f in glob.glob(f'{folder}/*') if os.path.isfile(f)))


setup(
    name=PACKAGE,
    version='0.1.0',
    description='Improved A* global planner and improved APF local planner for ROS 2 Jazzy',
    license='Apache-2.0',
    python_requires='>=3.10',
    packages=find_packages(exclude=['test', 'test.*']),
    data_files=[
        ('share/ament_index/resource_index/packages', [f'resource/{PACKAGE}']),
        (f'share/{PACKAGE}', ['package.xml']),
        share('config'),
        share('config/maps'),
        share('config/scenarios'),
    ],
    install_requires=['numpy', 'scipy', 'PyYAML'],
    extras_require={
        # The ROS 2 Jazzy wheels, for machines without a sourced ROS install.
        'ros': ['ros-jazzy-rclpy[fastrtps]', 'ros-jazzy-common-interfaces'],
        # The compiled search loop (about 10x faster; 35 MB + llvmlite 170 MB
        # installed); without it the search runs in pure Python.
        'fast': ['numba'],
        # Pictures and animated GIFs of plans and runs.
        'plot': ['matplotlib', 'pillow'],
        # MCAP recordings of the demo (mcap-ros2-support reads them back).
        'record': ['mcap', 'mcap-ros2-support'],
        'bench': ['pyastar2d', 'tcod', 'pathfinding', 'python-motion-planning', 'networkx'],
        # The suite also runs the benchmarks' quick modes against the small
        # peers (python-motion-planning, with its 3-D viewer stack, stays out).
        'test': ['pytest', 'pytest-timeout', 'hypothesis', 'matplotlib', 'pillow',
                 'mcap', 'mcap-ros2-support', 'colcon-common-extensions',
                 'pyastar2d', 'tcod', 'pathfinding', 'networkx'],
    },
    zip_safe=True,
    entry_points={
        'console_scripts': [
            'fusion-planner = fusion_planner.cli.main:main',
            # checks ROS 2 first (one line, exit 2 without it), then runs the node's main
            'global_planner = fusion_planner.ros.executables:global_planner',
            'local_planner = fusion_planner.ros.executables:local_planner',
            'simulator = fusion_planner.ros.executables:simulator',
        ],
    },
)
