"""run_node: a clean stop when a take fails during shutdown, a fault otherwise."""

import os
import pathlib
import signal
import subprocess
import sys

import pytest

rclpy = pytest.importorskip('rclpy')

from rclpy.node import Node  # noqa: E402

from fusion_planner.ros import node_main  # noqa: E402

REPO = pathlib.Path(__file__).resolve().parent.parent


class QuietNode(Node):
    def __init__(self):
        super().__init__('run_node_test')


def spin_that_fails(shut_down_first=False, ctrl_c_first=False):
    def spin(node, ctrl_c):
        if shut_down_first:
            rclpy.shutdown()  # what Ctrl-C does, under a running take
        if ctrl_c_first:  # Ctrl-C inside pybind11's argument conversion, context still up
            try:
                signal.getsignal(signal.SIGINT)(signal.SIGINT, None)
            except KeyboardInterrupt:
                pass
        raise RuntimeError('Unable to convert call argument')
    return spin


def test_an_error_of_a_take_during_shutdown_is_a_clean_stop(monkeypatch):
    monkeypatch.setattr(node_main, 'spin_until_stopped', spin_that_fails(shut_down_first=True))
    assert node_main.run_node(QuietNode, 'run_node_test', []) == 0


def test_an_error_of_a_take_right_after_ctrl_c_is_a_clean_stop(monkeypatch):
    monkeypatch.setattr(node_main, 'spin_until_stopped', spin_that_fails(ctrl_c_first=True))
    before = signal.getsignal(signal.SIGINT)
    assert node_main.run_node(QuietNode, 'run_node_test', []) == 0
    assert signal.getsignal(signal.SIGINT) is before  # the watch put it back


def test_the_same_error_while_running_is_not_hidden(monkeypatch):
    monkeypatch.setattr(node_main, 'spin_until_stopped', spin_that_fails(shut_down_first=False))
    with pytest.raises(RuntimeError):
        node_main.run_node(QuietNode, 'run_node_test', [])
    assert not rclpy.ok()  # run_node shut ROS down on the way out


def test_ctrl_c_while_ros_is_up_stops_the_spin_without_a_keyboard_interrupt(monkeypatch):
    """rclpy's handler shuts the context down; the watch raises nothing where Python is."""
    raised = []

    def spin(node, ctrl_c):
        try:
            signal.getsignal(signal.SIGINT)(signal.SIGINT, None)
        except KeyboardInterrupt:
            raised.append(True)
        rclpy.shutdown()  # what rclpy's own handler does before it chains to the watch
        raise node_main.ExternalShutdownException()

    monkeypatch.setattr(node_main, 'spin_until_stopped', spin)
    assert node_main.run_node(QuietNode, 'run_node_test', []) == 0
    assert raised == []


def test_ctrl_c_that_rclpy_does_not_wake_the_spin_for_still_ends_it():
    """SIGINT seen by the watch alone (rclpy's handler gone): the spin ends within a poll."""
    script = (
        'import os, signal, threading, rclpy.signals\n'
        'from rclpy.node import Node\n'
        'from fusion_planner.ros import node_main\n'
        'class Quiet(Node):\n'
        '    def __init__(self):\n'
        '        super().__init__("ctrl_c_poll_test")\n'
        '        rclpy.signals.uninstall_signal_handlers()  # the watch is all that hears SIGINT\n'
        '        threading.Timer(1.0, os.kill, (os.getpid(), signal.SIGINT)).start()\n'
        'raise SystemExit(node_main.run_node(Quiet, "ctrl_c_poll_test", []))\n')
    env = dict(os.environ)
    env['PYTHONPATH'] = os.pathsep.join(filter(None, [str(REPO), env.get('PYTHONPATH')]))
    done = subprocess.run([sys.executable, '-c', script], capture_output=True, text=True,
                          env=env, timeout=30)
    assert done.returncode == 0, done.stderr[-2000:]
