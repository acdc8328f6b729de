"""Tests of fusion_planner.ros.diagnostics: rate-limited logs, status, guards."""

import pytest
import rclpy
from rclpy.context import Context
from rclpy.node import Node

from fusion_planner.core.errors import GoalOccupied, InvalidInput
from fusion_planner.ros import diagnostics
from fusion_planner.ros.diagnostics import DiagnosticsReporter, RateLimitedLogger


class FakeLogger:
    def __init__(self):
        self.lines = []

    def warning(self, text):
        self.lines.append(('warn', text))

    def error(self, text):
        self.lines.append(('error', text))


class FakeClock:
    def __init__(self):
        self.t = 0.0

    def __call__(self):
        return self.t


def test_one_line_per_reason_per_period_with_suppressed_count():
    log, clock = FakeLogger(), FakeClock()
    limiter = RateLimitedLogger(log, period_s=5.0, clock=clock)
    assert limiter.warning('goal/nan', 'goal x is NaN')
    for _ in range(9):
        assert not limiter.warning('goal/nan', 'goal x is NaN')
    assert limiter.error('map/bad', 'map data too short')  # another key is independent
    clock.t = 5.0
    assert limiter.warning('goal/nan', 'goal y is NaN')
    assert log.lines == [('warn', 'goal x is NaN'), ('error', 'map data too short'),
                         ('warn', 'goal y is NaN (9 similar suppressed)')]


def test_limiter_memory_is_bounded():
    limiter = RateLimitedLogger(FakeLogger(), clock=FakeClock())
    for k in range(3 * diagnostics.MAX_LOG_KEYS):
        limiter.warning(f'key{k}', 'x')
    assert len(limiter._last) <= diagnostics.MAX_LOG_KEYS


@pytest.fixture
def node():
    ctx = Context()
    rclpy.init(context=ctx)
    n = Node('diag_test', context=ctx)
    yield n
    n.destroy_node()
    rclpy.shutdown(context=ctx)


def test_guard_turns_errors_into_counts_and_outcomes(node):
    reporter = DiagnosticsReporter(node)

    def refuse(msg):
        raise GoalOccupied('goal (1, 2) is inside an obstacle')

    def bug(msg):
        return {}['missing']

    assert reporter.guard('goal_pose', refuse)(None) is None
    values = reporter.values
    assert values['rejected'] == 1 and values['last_outcome'] == 'goal_occupied'
    assert 'inside an obstacle' in values['last_error']
    assert reporter.guard('odom', bug, on_error=lambda msg: 'fallback')(None) == 'fallback'
    values = reporter.values
    assert values['faults'] == 1 and values['last_outcome'] == diagnostics.INTERNAL_ERROR
    assert 'KeyError' in values['last_error']
    reporter.failed(InvalidInput('bad tolerance'), 'get_plan')
    reporter.succeeded('plan found', plan_time_s=0.01)
    values = reporter.values
    assert values['requests'] == 2 and values['last_outcome'] == diagnostics.SUCCEEDED
    assert values['plan_time_s'] == 0.01
    with pytest.raises(KeyboardInterrupt):
        reporter.guard('x', lambda: (_ for _ in ()).throw(KeyboardInterrupt()))()


def test_an_error_after_the_context_is_shut_down_is_the_stop_not_a_fault():
    """Ctrl-C shuts the context down under a running callback: its publish then fails."""
    ctx = Context()
    rclpy.init(context=ctx)
    n = Node('diag_stop_test', context=ctx)
    reporter = DiagnosticsReporter(n)
    rclpy.shutdown(context=ctx)

    def publish_after_shutdown():
        raise RuntimeError("Failed to publish: publisher's context is invalid")

    guarded = reporter.guard('step', publish_after_shutdown, on_error=lambda: 'stopped')
    assert guarded() == 'stopped'
    assert reporter.values['faults'] == 0
    n.destroy_node()
