"""Send a goal once a planner listens, and again until a plan answers it.

Used by the simulator (its ``publish_goal`` parameter) and by the demo's
monitor when the nodes run in other processes (the monitor then waits to
hear every node before it sends the goal, so the world, held until the first
plan, cannot start before the monitor is matched to the nodes).
"""

import time

from geometry_msgs.msg import PoseStamped

#: Wall time without a plan after which the goal is sent again [s].
GOAL_RETRY_PERIOD_S = 2.0
#: The goal is sent at most this many times [1].
MAX_GOAL_ATTEMPTS = 5
#: Wall time a subscriber must have been matched before the goal is sent [s]
#: (gives the subscriber's side of discovery time to match us back).
GOAL_MATCH_SETTLE_S = 0.3


class GoalSender:
    """Publish one goal pose on a publisher, with discovery settling and retries.

    Parameters
    ----------
    publisher : rclpy.publisher.Publisher
        Of ``geometry_msgs/PoseStamped`` on ``goal_pose``.
    logger : rclpy logger, optional
        Each send is logged (info); None: not logged.
    """

    def __init__(self, publisher, logger=None):
        self._pub = publisher
        self._logger = logger
        self.attempts = 0
        self._sent_at = None     # wall time of the last send
        self._matched_at = None  # wall time the subscriber was first seen
        self.answered = False

    def on_plan(self):
        """A plan arrived: the goal sent (if any) is answered."""
        if self._sent_at is not None:
            self.answered = True

    def poll(self, goal, frame_id, stamp):
        """Send ``goal`` ``(x, y)`` [m] in ``frame_id`` now if it is due.

        Due: not answered, attempts left, a subscriber matched for
        :data:`GOAL_MATCH_SETTLE_S`, and :data:`GOAL_RETRY_PERIOD_S` since
        the last send.
        """
        if self.answered or self.attempts >= MAX_GOAL_ATTEMPTS:
            return
        now = time.monotonic()
        if self._pub.get_subscription_count() == 0:
            self._matched_at = None
            return
        if self._matched_at is None:
            self._matched_at = now
        if now - self._matched_at < GOAL_MATCH_SETTLE_S:
            return
        if self._sent_at is not None and now - self._sent_at < GOAL_RETRY_PERIOD_S:
            return
        msg = PoseStamped()
        msg.header.frame_id = frame_id
        msg.header.stamp = stamp
        msg.pose.position.x = float(goal[0])
        msg.pose.position.y = float(goal[1])
        msg.pose.orientation.w = 1.0
        self._pub.publish(msg)
        self._sent_at = now
        self.attempts += 1
        if self._logger is not None:
            self._logger.info(
                f'goal ({goal[0]:.2f}, {goal[1]:.2f}) published (attempt {self.attempts})')
