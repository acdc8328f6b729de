"""Shared pytest fixtures: the benchmark data folder and the package path."""

import os
import pathlib
import sys

import pytest

REPO = pathlib.Path(__file__).resolve().parent.parent
if str(REPO) not in sys.path:
    sys.path.insert(0, str(REPO))

# Every test process talks DDS on its own domain and only on this machine, so
# parallel runs (xdist workers, other checkouts, CI) never hear each other.
# Set before any rclpy.init(); node subprocesses inherit it.
# Derived from the pid of each test process (each xdist worker has its own).
os.environ['ROS_DOMAIN_ID'] = str(1 + os.getpid() % 100)
os.environ['ROS_AUTOMATIC_DISCOVERY_RANGE'] = 'LOCALHOST'
os.environ.pop('ROS_LOCALHOST_ONLY', None)

#: MovingAI benchmark data lives beside the clone (CI), never inside it.
BENCHMARK_DIR = pathlib.Path(
    os.environ.get('FUSION_PLANNER_BENCHMARKS', REPO.parent / 'shared' / 'benchmarks' / 'movingai'))


@pytest.fixture(scope='session')
def benchmark_dir():
    """Folder of the MovingAI maps and scenarios; skips when it is absent."""
    if not BENCHMARK_DIR.is_dir():
        pytest.skip(f'MovingAI benchmark data not found at {BENCHMARK_DIR} '
                    '(it sits in ../shared/benchmarks beside a CI clone)')
    return BENCHMARK_DIR
