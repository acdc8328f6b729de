"""Lockstep inputs: one message of each per-step topic, handed over as a set per stamp.

In lockstep (the ``lockstep`` parameter of the three nodes) the simulator
publishes one sensor set per step, every message stamped with the step's
simulated time, and waits for the local planner's command stamped alike
before the next step. DDS keeps the order of one topic, not across topics:
a node that handled each message as it arrived would see, in one run, the
scan of step k before the odometry of step k and, in the next, after it.
:class:`StepInputs` removes that freedom: it gathers the messages of one
stamp and hands the complete set over in a fixed order, so a node's state
after step k depends on the messages of steps 0..k only, not on their
arrival order or the machine's speed.

The global planner answers every step on :data:`PLAN_STAMP_TOPIC` with the
stamp of its plan in force (each plan has a stamp of its own); the local
planner handles a step once it holds that plan, so a replan caused by the
scan of step k steers the robot from step k on, whatever arrives first.
"""

from fusion_planner.ros.conversions import stamp_to_nanoseconds
from rclpy.qos import ReliabilityPolicy

from fusion_planner.ros.qos import ANY_PUBLISHER_QOS, RELIABLE_QOS, LatchedOrVolatile

#: Stamps whose set is still incomplete kept at most [1]; older ones are
#: dropped (a lost message: that step is never handed over).
MAX_PENDING_STEPS = 8
#: The global planner's per-step answer (sensor_msgs/TimeReference): the
#: header stamp is the step's, ``time_ref`` the stamp of the plan in force
#: after it. Plans themselves go out on ``plan`` only when they change.
PLAN_STAMP_TOPIC = 'plan_stamp'
#: Plans a local planner keeps for the steps that name them [1].
MAX_KEPT_PLANS = 4


def step_stamp_ns(msg):
    """The stamp of a per-step message [ns]: its header's, a MarkerArray's first marker's.

    Returns
    -------
    int or None
        None for a MarkerArray without markers (it names no step).
    """
    if hasattr(msg, 'header'):
        return stamp_to_nanoseconds(msg.header.stamp)
    return stamp_to_nanoseconds(msg.markers[0].header.stamp) if msg.markers else None


def step_input_qos(lockstep):
    """QoS of the ``odom`` and ``scan`` subscriptions.

    Best effort (any publisher matches) when running free; reliable in
    lockstep, where a message lost would leave its step unanswered (the
    simulator's publishers are reliable then).
    """
    return RELIABLE_QOS if lockstep else ANY_PUBLISHER_QOS


def pose_subscription(node, msg_type, topic, callback, lockstep):
    """The ``amcl_pose`` subscription.

    Running free, a :class:`~fusion_planner.ros.qos.LatchedOrVolatile` pair
    (AMCL's latched pose sent before the node joined counts). In lockstep
    every step carries its pose: one reliable subscription, one callback per
    step.
    """
    if lockstep:
        return node.create_subscription(msg_type, topic, callback, RELIABLE_QOS)
    return LatchedOrVolatile(node, msg_type, topic, callback, ReliabilityPolicy.BEST_EFFORT)


class StepInputs:
    """Gather the per-step messages of one stamp; hand over complete sets in a fixed order.

    Parameters
    ----------
    names : sequence of str
        The per-step inputs, in the order their messages are handed over.
    on_step : callable
        ``on_step(stamp_ns, messages)`` with the messages of ``names`` in
        that order, once per stamp, stamps increasing.
    on_repeat : callable, optional
        ``on_repeat(stamp_ns)`` when a message of the last stamp handed over
        arrives again (a simulator holding its world republishes the same
        set); default: ignored.

    Notes
    -----
    A message older than the last set handed over is ignored: its step is
    past. Completing a stamp drops the incomplete sets of older stamps.
    """

    def __init__(self, names, on_step, on_repeat=None):
        self.names = tuple(names)
        self._on_step = on_step
        self._on_repeat = on_repeat
        self._pending = {}  # stamp [ns] -> {name: message}
        self.last_stamp_ns = None  # stamp of the last set handed over [ns]

    def add(self, name, msg):
        """Take a message of input ``name`` (one naming no step is ignored: see step_stamp_ns)."""
        stamp = step_stamp_ns(msg)
        if stamp is None:
            return
        if self.last_stamp_ns is not None and stamp <= self.last_stamp_ns:
            if stamp == self.last_stamp_ns and self._on_repeat is not None:
                self._on_repeat(stamp)
            return
        entry = self._pending.setdefault(stamp, {})
        entry[name] = msg
        if len(entry) < len(self.names):
            while len(self._pending) > MAX_PENDING_STEPS:
                del self._pending[min(self._pending)]
            return
        self._pending = {t: e for t, e in self._pending.items() if t > stamp}
        self.last_stamp_ns = stamp
        self._on_step(stamp, [entry[n] for n in self.names])

    def clear(self):
        """Forget the pending sets and the last stamp (a simulation reset)."""
        self._pending = {}
        self.last_stamp_ns = None
