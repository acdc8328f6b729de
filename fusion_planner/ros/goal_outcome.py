"""How a goal ends: the outcome names and the two topics that carry them.

Every goal the global planner accepts on ``goal_pose`` ends with exactly one
outcome, published once on ``goal_outcome`` (std_msgs/String, reliable, the
outcome word), logged once and set as ``goal_outcome`` on the global
planner's diagnostics:

- ``reached``: the local planner arrived within its goal tolerance;
- ``no_path``: the global planner found no path (or the local planner's
  replanning proved the goal unreachable);
- ``controller_failed``: the local planner gave up (no progress);
- ``cancelled``: the ``cancel_goal`` service (std_srvs/Trigger) was called;
- ``preempted``: a newer goal replaced it.

The local planner tells the global planner how a plan's run ended on
``controller_outcome`` (diagnostic_msgs/DiagnosticStatus, reliable):
``message`` is the outcome (``reached``, ``no_path``,
``controller_failed``), key ``plan_stamp_ns`` the stamp of the plan it ran
(so an outcome of an older plan cannot end a newer goal), key ``reason`` a
sentence. After any outcome the global planner publishes an empty plan:
the robot stops and no node resumes the goal, not even a follower that
starts later and reads the latched ``plan``.
"""

from diagnostic_msgs.msg import DiagnosticStatus, KeyValue

from fusion_planner.core.errors import InvalidInput

#: Every way a goal ends.
GOAL_OUTCOMES = ('reached', 'no_path', 'controller_failed', 'cancelled', 'preempted')
#: The ways the local planner's run of a plan ends.
CONTROLLER_OUTCOMES = ('reached', 'no_path', 'controller_failed')
#: Controller statuses (Command.status) that end a run, and their outcome.
OUTCOME_OF_STATUS = {'arrived': 'reached', 'no_path': 'no_path', 'failed': 'controller_failed'}
#: Topic of the goal outcomes (global planner).
GOAL_OUTCOME_TOPIC = 'goal_outcome'
#: Topic of the run outcomes (local planner -> global planner).
CONTROLLER_OUTCOME_TOPIC = 'controller_outcome'
#: Service that cancels the current goal.
CANCEL_SERVICE = 'cancel_goal'


def controller_outcome_msg(outcome, plan_stamp_ns, reason, node_name):
    """The ``controller_outcome`` message of a run that ended.

    Parameters
    ----------
    outcome : str
        One of :data:`CONTROLLER_OUTCOMES`.
    plan_stamp_ns : int
        Header stamp of the plan that was run [ns].
    reason : str
        One sentence ('' when reached).
    node_name : str
        Fully qualified name of the local planner.

    Returns
    -------
    diagnostic_msgs.msg.DiagnosticStatus
    """
    level = DiagnosticStatus.OK if outcome == 'reached' else DiagnosticStatus.ERROR
    return DiagnosticStatus(level=level, name=node_name, message=outcome,
                            values=[KeyValue(key='plan_stamp_ns', value=str(int(plan_stamp_ns))),
                                    KeyValue(key='reason', value=reason)])


def controller_outcome_from_msg(msg):
    """``(outcome, plan stamp [ns], reason)`` of a ``controller_outcome`` message.

    Raises
    ------
    InvalidInput
        If the outcome is not one of :data:`CONTROLLER_OUTCOMES` or the plan
        stamp is missing or not an integer.
    """
    if msg.message not in CONTROLLER_OUTCOMES:
        raise InvalidInput(f'controller outcome must be one of {", ".join(CONTROLLER_OUTCOMES)}, '
                           f'got {msg.message!r}')
    values = {kv.key: kv.value for kv in msg.values}
    try:
        stamp = int(values['plan_stamp_ns'])
    except (KeyError, ValueError):
        raise InvalidInput('controller outcome without an integer plan_stamp_ns') from None
    return msg.message, stamp, values.get('reason', '')
