"""Managed (lifecycle) nodes: what the three nodes share of the ROS 2 node lifecycle.

A :class:`ManagedNode` is an ``rclpy.lifecycle.LifecycleNode``, so
``ros2 lifecycle set`` and nav2_lifecycle_manager drive it through the
standard ``~/change_state`` service:

- *unconfigured*: parameters declared, nothing else; diagnostics report it;
- ``configure``: the node creates its publishers, subscriptions, timers and
  services (:meth:`ManagedNode.configure`) with fresh state, so latched
  inputs (``map``, ``plan``) arrive again after a cleanup;
- ``activate``: the lifecycle publishers publish, timers act
  (:attr:`ManagedNode.active`); inputs are taken in either state;
- ``deactivate``: the node stops acting (the local planner sends one zero
  command first);
- ``cleanup``: everything ``configure`` created is destroyed and the state
  forgotten.

With the ``autostart`` parameter (default true) the node configures and
activates itself at start-up, so ``ros2 run`` alone gives a working node. A
transition that is not valid from the current state (``activate`` twice,
``cleanup`` while active) is refused with one log line and ``success:
false``; rclpy would otherwise let its error escape the service callback and
stop the node.
"""

from lifecycle_msgs.srv import ChangeState
from rclpy._rclpy_pybind11 import RCLError
from rclpy.lifecycle import LifecycleNode, LifecyclePublisher, TransitionCallbackReturn

from fusion_planner.core.errors import InvalidInput
from fusion_planner.ros.diagnostics import one_line

#: Description of the ``autostart`` parameter every managed node declares.
AUTOSTART_DESCRIPTION = ('configure and activate at start-up (false: wait for a lifecycle manager '
                         'or `ros2 lifecycle set`)')


class ManagedNode(LifecycleNode):
    """A lifecycle node whose configured entities come and go with configure and cleanup.

    Subclasses implement :meth:`configure` and may extend :meth:`activate`,
    :meth:`deactivate` and :meth:`cleanup`; they call :meth:`start` at the
    end of their ``__init__``.

    Parameters
    ----------
    node_name : str
    **kwargs
        Passed to ``rclpy.lifecycle.LifecycleNode``.
    """

    def __init__(self, node_name, **kwargs):
        super().__init__(node_name, **kwargs)
        self._active = False
        self._base_entities = None  # what the node had before its first configure
        for service in self.services:
            if service.srv_type is ChangeState:
                service.callback = self._refusing_invalid(service.callback)

    @property
    def active(self):
        """Whether the node is in the active state (timers act, publishers publish)."""
        return self._active

    def start(self, autostart):
        """Configure and activate now when ``autostart``; a failed configure leaves it unconfigured."""
        if autostart and self.trigger_configure() == TransitionCallbackReturn.SUCCESS:
            self.trigger_activate()

    # -- hooks of the subclasses ----------------------------------------------------

    def configure(self):
        """Create publishers, subscriptions, timers and services with fresh state.

        Raises
        ------
        InvalidInput
            The node cannot be configured; the transition fails (logged).
        """
        raise NotImplementedError

    def activate(self):
        """Called once the node is active."""

    def deactivate(self):
        """Called before the node becomes inactive (its publishers still publish)."""

    def cleanup(self):
        """Called after the configured entities were destroyed: forget the state."""

    # -- transitions ------------------------------------------------------------------

    def on_configure(self, state):
        if self._base_entities is None:
            self._base_entities = self._entities()
        try:
            self.configure()
        except InvalidInput as err:
            self.get_logger().error(f'configure failed: {err}')
            self._destroy_configured()
            return TransitionCallbackReturn.FAILURE
        self.get_logger().info('configured')
        return super().on_configure(state)

    def on_activate(self, state):
        result = super().on_activate(state)
        self._active = True
        self.activate()
        self.get_logger().info('active')
        return result

    def on_deactivate(self, state):
        self.deactivate()
        self._active = False
        self.get_logger().info('inactive')
        return super().on_deactivate(state)

    def on_cleanup(self, state):
        self._destroy_configured()
        self.cleanup()
        self.get_logger().info('cleaned up')
        return super().on_cleanup(state)

    def on_shutdown(self, state):
        self._active = False
        return super().on_shutdown(state)

    # -- helpers ------------------------------------------------------------------------

    def _entities(self):
        return {*self.publishers, *self.subscriptions, *self.timers, *self.services,
                *self.clients}

    def _destroy_configured(self):
        """Destroy every entity created since the first configure began."""
        for entity in self._entities() - (self._base_entities or set()):
            if isinstance(entity, LifecyclePublisher):
                self.destroy_lifecycle_publisher(entity)
            elif entity in set(self.publishers):
                self.destroy_publisher(entity)
            elif entity in set(self.subscriptions):
                self.destroy_subscription(entity)
            elif entity in set(self.timers):
                self.destroy_timer(entity)
            elif entity in set(self.services):
                self.destroy_service(entity)
            else:
                self.destroy_client(entity)

    def _refusing_invalid(self, change_state):
        """``change_state`` that answers an invalid transition with ``success: false``."""
        def guarded(request, response):
            try:
                return change_state(request, response)
            except RCLError as err:
                current = self._state_machine.current_state[1]
                asked = request.transition.label or f'id {request.transition.id}'
                self.get_logger().warning(one_line(
                    f'lifecycle transition {asked} refused in state {current!r}: {err}'))
                response.success = False
                return response
        return guarded
