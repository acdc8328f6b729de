"""Shared pytest fixtures: the benchmark data folder, an rclpy context, the package path."""

import fcntl
import os
import pathlib
import sys

import pytest

REPO = pathlib.Path(__file__).resolve().parent.parent
if str(REPO) not in sys.path:
    sys.path.insert(0, str(REPO))

#: Lock file of the DDS domain id this test process holds (see below).
_DOMAIN_LOCK = None


def _claim_domain_id():
    """Reserve a DDS domain id no other test process on this machine holds.

    Each id has a lock file; the first one this process can lock exclusively
    is its own until the process ends (the OS drops the lock then, even on a
    crash). Ids 1..101 are the ones whose ports never collide.
    """
    lock_dir = pathlib.Path(os.environ.get('TMPDIR', '/tmp'))
    for domain in range(1, 102):
        handle = open(lock_dir / f'fusion_planner_test_domain_{domain}.lock', 'w')
        try:
            fcntl.flock(handle, fcntl.LOCK_EX | fcntl.LOCK_NB)
        except OSError:
            handle.close()
            continue
        global _DOMAIN_LOCK
        _DOMAIN_LOCK = handle  # held for the lifetime of the process
        return domain
    raise RuntimeError('all ROS domain ids 1..101 are taken by other test processes')


# Every test process talks DDS on its own domain and only on this machine, so
# parallel runs (other checkouts, CI, xdist workers) never hear each other.
# Set before any rclpy.init(); node subprocesses inherit it.
os.environ['ROS_DOMAIN_ID'] = str(_claim_domain_id())
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


@pytest.fixture(scope='module')
def context():
    """A fresh rclpy context for one test module (no signal handlers: pytest owns Ctrl-C)."""
    rclpy = pytest.importorskip('rclpy')
    ctx = rclpy.Context()
    rclpy.init(context=ctx, signal_handler_options=rclpy.signals.SignalHandlerOptions.NO)
    yield ctx
    rclpy.try_shutdown(context=ctx)
