"""The ``main()`` shared by the three node executables (ros2/examples shape)."""

import rclpy
from rclpy.executors import ExternalShutdownException

from fusion_planner.core.errors import InvalidInput


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
    rclpy.init(args=args)
    node = None
    try:
        node = node_class()
        rclpy.spin(node)
    except (KeyboardInterrupt, ExternalShutdownException):
        pass
    except InvalidInput as err:
        rclpy.logging.get_logger(node_name).fatal(f'cannot start: {err}')
        return 1
    except RuntimeError:
        # Ctrl-C shuts the context down under a running take (rclpy 7.1 then
        # raises "Unable to convert call argument"); after a shutdown that is
        # the stop we asked for, not a fault.
        if rclpy.ok():
            raise
    finally:
        if node is not None:
            node.destroy_node()
        rclpy.try_shutdown()
    return 0
