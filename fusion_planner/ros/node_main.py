"""The ``main()`` shared by the three node executables (ros2/examples shape)."""

import signal

import rclpy
from rclpy.executors import ExternalShutdownException

from fusion_planner.core.errors import InvalidInput

#: How often [s] the spin's wait times out to look for a Ctrl-C (see :func:`spin_until_stopped`).
CTRL_C_POLL_S = 0.25


def run_node(node_class, node_name, args=None):
    """Spin one node until Ctrl-C or shutdown.

    Parameters
    ----------
    node_class : type
        A ``rclpy.node.Node`` subclass constructible without arguments.
    node_name : str
        Logger name for a start-up failure.
    args : list of str, optional
        Command-line arguments (``--ros-args ...``).

    Returns
    -------
    int
        0 on a clean stop, 1 when the node refused its start-up parameters
        (one fatal log line, no traceback).
    """
    ctrl_c = _CtrlCWatch()
    rclpy.init(args=args)  # rclpy's signal handler chains to the watch's
    ctrl_c.ros_up = True
    node = None
    try:
        node = node_class()
        spin_until_stopped(node, ctrl_c)
    except (KeyboardInterrupt, ExternalShutdownException):
        pass
    except InvalidInput as err:
        rclpy.logging.get_logger(node_name).fatal(f'cannot start: {err}')
        return 1
    except RuntimeError:
        # A take that Ctrl-C or a shutdown interrupts fails with a
        # RuntimeError (rclpy 7.1: "Unable to convert call argument"). After
        # a Ctrl-C or a shutdown that is the stop we asked for, not a fault.
        if rclpy.ok() and not ctrl_c.seen:
            raise
    finally:
        ctrl_c.restore()
        if node is not None:
            node.destroy_node()
        rclpy.try_shutdown()
    return 0


def spin_until_stopped(node, ctrl_c):
    """Spin ``node`` in the global executor until ROS shuts down or ``ctrl_c`` saw SIGINT.

    rclpy's SIGINT handler shuts the context down and wakes the executor's
    wait. Once in CI a node slept on in that wait after SIGINT until it was
    killed, so the wait also times out every :data:`CTRL_C_POLL_S`: Python
    then runs the handler chained to rclpy's (``ctrl_c``), and the loop ends.
    """
    executor = rclpy.get_global_executor()
    executor.add_node(node)
    try:
        while rclpy.ok() and not ctrl_c.seen:
            executor.spin_once(timeout_sec=CTRL_C_POLL_S)
    finally:
        executor.remove_node(node)


class _CtrlCWatch:
    """Remembers that SIGINT arrived; raises KeyboardInterrupt only before ROS is up.

    Installed before ``rclpy.init`` so that rclpy's own handler (which shuts
    the context down and wakes the executor) chains to it instead of being
    replaced by it. Once ROS is up (``ros_up``), that shutdown is what ends
    the spin (``ExternalShutdownException``), or ``seen`` at the spin's next
    poll. A KeyboardInterrupt raised as well lands wherever Python happens
    to be: inside a ctypes callback of numba's compiler during a node's
    first step it is printed as a traceback and ignored, inside pybind11's
    argument conversion it becomes a RuntimeError.
    """

    def __init__(self):
        self.seen = False
        self.ros_up = False
        self._previous = signal.signal(signal.SIGINT, self._on_sigint)

    def _on_sigint(self, signum, frame):
        self.seen = True
        if not self.ros_up:
            signal.default_int_handler(signum, frame)

    def restore(self):
        """Put back the handler that was there before."""
        signal.signal(signal.SIGINT, self._previous)
