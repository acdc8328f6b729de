"""QoS profiles of the nodes, and subscriptions that accept latched and volatile publishers.

DDS matches a subscription to a publisher only when the subscription asks
for no more than the publisher offers: a reliable subscription refuses a
best-effort publisher, a transient-local one refuses a volatile publisher.
And only a *reliable, transient-local* subscription receives the message a
latched publisher (map_server, AMCL, our global planner) sent before it
joined; a volatile one, or a best-effort one, gets only later messages.

So a topic that may come from either kind of publisher (``map``, ``plan``,
``amcl_pose``) is subscribed twice by :class:`LatchedOrVolatile`: reliable +
transient-local (the latched history) and volatile (every live publisher).
A live message of a latched publisher arrives on both; the second copy is
dropped.

Publishers follow the ROS conventions: reliable everywhere (stock QoS, as
Nav2 and RViz subscribe), transient-local for the latched topics, and
best-effort sensor-data QoS for the laser scan only (what laser drivers and
Nav2's costmaps use).
"""

import collections
import functools

from rclpy.event_handler import SubscriptionEventCallbacks
from rclpy.qos import DurabilityPolicy, QoSProfile, ReliabilityPolicy, qos_profile_sensor_data

#: Latched topics (``map``, ``plan``, ``amcl_pose``) as published: reliable, transient local.
LATCHED_QOS = QoSProfile(depth=1, reliability=ReliabilityPolicy.RELIABLE,
                         durability=DurabilityPolicy.TRANSIENT_LOCAL)
#: Every other published topic: stock QoS (reliable, volatile, depth 10).
RELIABLE_QOS = QoSProfile(depth=10, reliability=ReliabilityPolicy.RELIABLE)
#: The laser scan, as drivers publish it: best effort, volatile.
SENSOR_QOS = qos_profile_sensor_data
#: Streams a node reads that any publisher may offer (``odom``, ``scan``,
#: ``cmd_vel`` of a teleop): best effort matches reliable and best-effort
#: publishers alike.
ANY_PUBLISHER_QOS = qos_profile_sensor_data
#: Copies of recent messages remembered to recognise the second copy [1].
DUPLICATE_WINDOW = 4


class LatchedOrVolatile:
    """A subscription that takes a topic from latched and volatile publishers.

    Parameters
    ----------
    node : rclpy.node.Node
    msg_type : type
    topic : str
    callback : callable
        Called once per distinct message (kept as ``callback``).
    volatile_reliability : ReliabilityPolicy
        Of the volatile subscription: RELIABLE (``map``, ``plan``, whose
        publishers are reliable and whose loss matters) or BEST_EFFORT
        (``amcl_pose``: also accepts best-effort pose publishers).
    depth : int
        Queue depth of each subscription [messages].

    Notes
    -----
    A message equal (header included) to one of the last
    :data:`DUPLICATE_WINDOW` messages the *other* subscription passed on,
    and not yet paired, is that message's second copy and is dropped; the
    copies may arrive in any order. A publisher that sends the same message
    twice is heard twice.
    """

    def __init__(self, node, msg_type, topic, callback, volatile_reliability, depth=1):
        self.callback = callback
        latched = QoSProfile(depth=depth, reliability=ReliabilityPolicy.RELIABLE,
                             durability=DurabilityPolicy.TRANSIENT_LOCAL)
        volatile = QoSProfile(depth=depth, reliability=volatile_reliability,
                              durability=DurabilityPolicy.VOLATILE)
        # Messages each subscription passed on whose copy the other has not seen yet.
        self._unpaired = (collections.deque(maxlen=DUPLICATE_WINDOW),
                          collections.deque(maxlen=DUPLICATE_WINDOW))
        # A volatile publisher is incompatible with the latched side only: the
        # volatile side hears it, so rclpy's "incompatible QoS" warning is noise there.
        quiet = SubscriptionEventCallbacks(incompatible_qos=lambda event: None)
        self._subscriptions = [
            node.create_subscription(msg_type, topic, functools.partial(self._on_message, side),
                                     qos, event_callbacks=events)
            for side, (qos, events) in enumerate(((latched, quiet), (volatile, None)))]

    def _on_message(self, side, msg):
        other = self._unpaired[1 - side]
        for seen in other:
            if msg == seen:
                other.remove(seen)
                return
        self._unpaired[side].append(msg)
        self.callback(msg)

    def get_publisher_count(self):
        """Publishers of the topic this subscription hears (the larger of its two counts)."""
        return max(sub.get_publisher_count() for sub in self._subscriptions)

    def destroy(self, node):
        """Destroy both subscriptions of ``node``."""
        for sub in self._subscriptions:
            node.destroy_subscription(sub)
        self._subscriptions = []
