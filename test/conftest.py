"""Shared pytest fixtures: the benchmark data folder, an rclpy context, the package path."""

import os
import pathlib
import sys

import pytest

REPO = pathlib.Path(__file__).resolve().parent.parent
if str(REPO) not in sys.path:
    sys.path.insert(0, str(REPO))

from fusion_planner.ros.domain import claim_private_domain  # noqa: E402 (after the path)

# Every test process talks DDS on its own domain and only on this machine, so
# parallel runs (other checkouts, CI, xdist workers) never hear each other.
# Set before any rclpy.init(); node subprocesses inherit it.
claim_private_domain()

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
