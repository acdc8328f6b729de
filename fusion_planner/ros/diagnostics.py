"""Status reporting of the nodes: ``diagnostics`` and rate-limited log lines.

A node never dies on a message (DESIGN.md, Errors): every rejected input is
one clear log line, rate-limited per reason, and a diagnostics entry; a bug
in a callback is logged with its exception text (no traceback spam) and
reported at ERROR level, and the node carries on.

- :class:`RateLimitedLogger`: at most one line per distinct reason key per
  period; the next line of that key says how many were suppressed.
- :class:`DiagnosticsReporter`: publishes ``diagnostic_msgs/DiagnosticArray``
  on the absolute topic ``/diagnostics`` (where diagnostic_aggregator and
  rqt_robot_monitor listen, whatever the node's namespace) with one status
  named after the node's fully qualified name (so namespaced robots differ): level, message,
  and key values (``last_outcome``, ``last_error``, counters, timings the
  node passes). It publishes on every event and, optionally, on a heartbeat
  timer. :meth:`DiagnosticsReporter.guard` wraps a callback so that neither
  a :class:`~fusion_planner.core.errors.PlanningError` nor a bug escapes it.
"""

import threading
import time

from diagnostic_msgs.msg import DiagnosticArray, DiagnosticStatus, KeyValue

from fusion_planner.core.errors import PlanningError

#: Default period [s] within which one reason is logged at most once.
DEFAULT_LOG_PERIOD_S = 5.0
#: Distinct reason keys remembered by the rate limiter [1]; the oldest is
#: forgotten beyond this (bounds memory under fuzzing).
MAX_LOG_KEYS = 256
#: Queue depth of the diagnostics publisher [messages].
DIAGNOSTICS_QUEUE_DEPTH = 10
#: The diagnostics topic: absolute, as in every ROS 2 stack.
DIAGNOSTICS_TOPIC = '/diagnostics'
#: Diagnostic levels, by name.
OK, WARN, ERROR, STALE = (DiagnosticStatus.OK, DiagnosticStatus.WARN,
                          DiagnosticStatus.ERROR, DiagnosticStatus.STALE)
#: Outcome code of a successful request.
SUCCEEDED = 'succeeded'
#: Outcome code of an unexpected exception (a bug) in a callback.
INTERNAL_ERROR = 'internal_error'


class RateLimitedLogger:
    """At most one log line per reason key per period.

    Parameters
    ----------
    logger : rclpy logger or logging.Logger
        Anything with ``warning``/``error``/``info`` methods.
    period_s : float
        Minimum time [s] between two lines of the same key, > 0.
    clock : callable
        Returns the current time [s]; ``time.monotonic`` by default.

    Examples
    --------
    >>> import logging
    >>> limiter = RateLimitedLogger(logging.getLogger('demo'), period_s=10.0)
    >>> limiter.warning('goal/invalid_input', 'goal x is NaN')
    True
    >>> limiter.warning('goal/invalid_input', 'goal y is NaN')
    False
    """

    def __init__(self, logger, period_s=DEFAULT_LOG_PERIOD_S, clock=time.monotonic):
        if not period_s > 0:
            raise ValueError(f'log period must be positive, got {period_s!r}')
        self._logger = logger
        self._period_s = float(period_s)
        self._clock = clock
        self._lock = threading.Lock()
        self._last = {}  # key -> [time of last line, suppressed since]

    def warning(self, key, message):
        """Log ``message`` at WARN unless ``key`` was logged within the period.

        Returns True when a line was written.
        """
        line = self._admit(key, message)
        if line is not None:
            self._logger.warning(line)
        return line is not None

    def error(self, key, message):
        """Log ``message`` at ERROR unless ``key`` was logged within the period.

        Returns True when a line was written.
        """
        line = self._admit(key, message)
        if line is not None:
            self._logger.error(line)
        return line is not None

    def _admit(self, key, message):
        """The line to write for ``key`` now, or None while it is rate-limited.

        (rclpy refuses one call site logging at two severities, hence each
        public method writes from its own line.)
        """
        now = self._clock()
        with self._lock:
            entry = self._last.get(key)
            if entry is not None and now - entry[0] < self._period_s:
                entry[1] += 1
                return None
            suppressed = entry[1] if entry is not None else 0
            self._last.pop(key, None)
            if len(self._last) >= MAX_LOG_KEYS:
                self._last.pop(next(iter(self._last)))
            self._last[key] = [now, 0]
        if suppressed:
            return f'{message} ({suppressed} similar suppressed)'
        return message


class DiagnosticsReporter:
    """A node's status on ``diagnostics``, plus rate-limited logging of problems.

    Parameters
    ----------
    node : rclpy.node.Node
    period_s : float
        Heartbeat period [s] republishing the current status; 0 disables it
        (status then goes out on events only).
    log_period_s : float
        Rate limit [s] of log lines per reason (see :class:`RateLimitedLogger`).
    stamp : callable, optional
        Returns the ``builtin_interfaces/Time`` a status is stamped with;
        default: the node clock's now.

    Notes
    -----
    Values are kept between events, so the latest timing and the last error
    stay visible. Counters ``requests``, ``rejected`` and ``faults`` are kept
    here. All methods are thread-safe.
    """

    def __init__(self, node, period_s=0.0, log_period_s=DEFAULT_LOG_PERIOD_S, stamp=None):
        self._node = node
        self._stamp = stamp or (lambda: node.get_clock().now().to_msg())
        self._pub = node.create_publisher(DiagnosticArray, DIAGNOSTICS_TOPIC,
                                          DIAGNOSTICS_QUEUE_DEPTH)
        self.log = RateLimitedLogger(node.get_logger(), log_period_s)
        self._lock = threading.Lock()
        self._name = node.get_fully_qualified_name()
        self._level = OK
        self._message = 'starting'
        self._values = {'last_outcome': 'none', 'last_error': '',
                        'requests': 0, 'rejected': 0, 'faults': 0}
        self._timer = node.create_timer(period_s, self.publish) if period_s > 0 else None

    @property
    def values(self):
        """A copy of the current key values."""
        with self._lock:
            return dict(self._values)

    def update(self, level, message, **values):
        """Set the status and key values, and publish.

        Parameters
        ----------
        level : bytes
            One of :data:`OK`, :data:`WARN`, :data:`ERROR`, :data:`STALE`.
        message : str
            One sentence.
        **values
            Key values to set (numbers, strings, bools); others are kept.
        """
        with self._lock:
            self._level = level
            self._message = message
            self._values.update(values)
        self.publish()

    def succeeded(self, message, **values):
        """A request succeeded: level OK, ``last_outcome = 'succeeded'``."""
        self._count('requests')
        self.update(OK, message, last_outcome=SUCCEEDED, **values)

    def failed(self, err, what, **values):
        """A request failed with a :class:`PlanningError`: log (rate-limited), WARN.

        Parameters
        ----------
        err : PlanningError
            Its ``outcome`` becomes ``last_outcome``; its text ``last_error``.
        what : str
            What was being done, e.g. ``'goal_pose'``, ``'get_plan'``.
        **values
            Extra key values.
        """
        self._count('requests')
        self._problem(WARN, what, err.outcome, str(err), **values)

    def reject(self, what, err, **values):
        """An input was refused (malformed message): log (rate-limited), WARN, count it."""
        self._count('rejected')
        self._problem(WARN, what, getattr(err, 'outcome', 'invalid_input'), str(err), **values)

    def fault(self, what, err):
        """A bug-level exception in a callback: log its text (rate-limited), ERROR."""
        self._count('faults')
        self._problem(ERROR, what, INTERNAL_ERROR, f'{type(err).__name__}: {err}')

    def guard(self, what, callback, on_error=None):
        """Wrap ``callback`` so that no exception escapes into the executor.

        Parameters
        ----------
        what : str
            Name of the input, used in log lines and diagnostics.
        callback : callable
        on_error : callable, optional
            Called with the callback's arguments after an exception; its
            result is returned (a service callback must return a response).

        Returns
        -------
        callable
            ``PlanningError`` -> :meth:`reject`; any other ``Exception`` ->
            :meth:`fault`, unless the node's context is shut down (Ctrl-C or
            shutdown while the callback ran: its publishers fail, and that
            is the stop, not a fault). ``KeyboardInterrupt`` and
            ``SystemExit`` pass.
        """
        def guarded(*args):
            try:
                return callback(*args)
            except PlanningError as err:
                self.reject(what, err)
            except Exception as err:  # noqa: BLE001 - a node never dies on a message
                if self._node.context.ok():
                    self.fault(what, err)
            return on_error(*args) if on_error is not None else None
        return guarded

    def publish(self):
        """Publish the current status once."""
        with self._lock:
            status = DiagnosticStatus(
                level=self._level, name=self._name, message=self._message,
                hardware_id=self._node.get_name(),
                values=[KeyValue(key=k, value=_text(v)) for k, v in self._values.items()])
        msg = DiagnosticArray()
        msg.header.stamp = self._stamp()
        msg.status = [status]
        self._pub.publish(msg)

    def _count(self, key):
        with self._lock:
            self._values[key] += 1

    def _problem(self, level, what, outcome, text, **values):
        line = one_line(f'{what}: {text}')
        if level == ERROR:
            self.log.error(f'{what}/{outcome}', line)
        else:
            self.log.warning(f'{what}/{outcome}', line)
        self.update(level, line, last_outcome=outcome, last_error=line, **values)


def one_line(text):
    """``text`` with control characters escaped, so that a log line stays one line.

    Error sentences quote message fields (a frame id, a marker namespace),
    which a sender may fill with newlines or escape codes.

    Examples
    --------
    >>> print(one_line('goal is in frame "map\\n[ERROR] fake"'))
    goal is in frame "map\\n[ERROR] fake"
    """
    return ''.join(c if c.isprintable() else repr(c)[1:-1] for c in text)


def _text(value):
    """A key value as text: floats with 6 significant digits."""
    if isinstance(value, float):
        return f'{value:.6g}'
    return str(value)
