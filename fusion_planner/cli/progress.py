"""Progress lines with an estimated time left, for long command-line work.

One :class:`Progress` per job: the caller says how much work there is and
calls :meth:`Progress.advance` as it gets done; a line with the count, the
elapsed time and the estimated time left goes to stderr. Every progress
output goes through a :class:`StatusLine`: redrawn in place (``\\r``) only
when the stream is a terminal, else one whole line per update, throttled to
one per :data:`LOG_PERIOD_S`, so that a log file stays readable.
:func:`eta_s` is the estimate on its own, for a caller that knows the done
fraction but not a count (the demo's distance to the goal).
"""

import math
import sys
import time

#: Shortest wall time between two lines on a terminal [s].
TTY_PERIOD_S = 0.5
#: Shortest wall time between two lines in a log file (stderr not a terminal) [s].
LOG_PERIOD_S = 30.0
#: Width a terminal line is padded to, so a shorter line hides a longer one [characters].
TTY_WIDTH = 100


def format_duration(seconds):
    """A duration as ``1h02m03s``, ``2m03s`` or ``3s``; ``?`` when unknown.

    Parameters
    ----------
    seconds : float
        Duration [s]; NaN or infinite for an unknown one.

    Returns
    -------
    str

    Examples
    --------
    >>> [format_duration(s) for s in (3723.4, 123, 3, math.nan)]
    ['1h02m03s', '2m03s', '3s', '?']
    """
    if not math.isfinite(seconds):
        return '?'
    seconds = int(round(max(seconds, 0.0)))
    hours, rest = divmod(seconds, 3600)
    minutes, secs = divmod(rest, 60)
    if hours:
        return f'{hours}h{minutes:02d}m{secs:02d}s'
    if minutes:
        return f'{minutes}m{secs:02d}s'
    return f'{secs}s'


def eta_s(elapsed_s, fraction):
    """Time left [s] if the rest goes as fast as the part done so far.

    Parameters
    ----------
    elapsed_s : float
        Wall time spent so far [s].
    fraction : float
        Part of the work done, in [0, 1].

    Returns
    -------
    float
        ``elapsed_s * (1 - fraction) / fraction``; NaN before any work is
        done (``fraction <= 0``), 0 once it is all done.

    Examples
    --------
    >>> eta_s(10.0, 0.25), eta_s(10.0, 1.0)
    (30.0, 0.0)
    """
    if not fraction > 0.0:
        return math.nan
    fraction = min(fraction, 1.0)
    return elapsed_s * (1.0 - fraction) / fraction


class StatusLine:
    """One status line on a stream, throttled: redrawn in place on a terminal, appended in a log.

    Parameters
    ----------
    stream : file, optional
        Where to write; default ``sys.stderr`` as it is at construction.

    Examples
    --------
    >>> import io
    >>> log = io.StringIO()
    >>> line = StatusLine(log)
    >>> line.show('first'), line.show('throttled'), line.show('last', force=True)
    (True, False, True)
    >>> line.close()
    >>> log.getvalue()
    'first\\nlast\\n'
    """

    def __init__(self, stream=None):
        self.stream = sys.stderr if stream is None else stream
        self.tty = bool(getattr(self.stream, 'isatty', lambda: False)())
        self.period_s = TTY_PERIOD_S if self.tty else LOG_PERIOD_S
        self.last = -math.inf
        self.drawn = False

    def show(self, text, force=False, now=None):
        """Write ``text`` if the last line is old enough (or ``force``); returns whether it did.

        ``now`` is the caller's ``time.monotonic()`` reading [s], if it has one.
        """
        now = time.monotonic() if now is None else now
        if not (force or now - self.last >= self.period_s):
            return False
        self.last = now
        if self.tty:
            self.stream.write('\r' + text.ljust(TTY_WIDTH))
        else:
            self.stream.write(text + '\n')
        self.stream.flush()
        self.drawn = True
        return True

    def close(self):
        """End the line on a terminal (a log's lines are already ended)."""
        if self.tty and self.drawn:
            self.stream.write('\n')
            self.stream.flush()
        self.drawn = False


class Progress:
    """Work done / total, elapsed time and time left on a stream, throttled.

    Parameters
    ----------
    total : float
        Work to do, in any unit (rows, scenarios, weighted tasks); > 0.
    label : str
        First word of the line, e.g. ``'movingai'``.
    unit : str, optional
        Name of the unit, e.g. ``'rows'``; when given, the line shows
        ``done/total unit``, else only the percentage (fractional work).
    stream : file, optional
        As for :class:`StatusLine`, which writes the lines.

    Examples
    --------
    >>> import io
    >>> out = io.StringIO()
    >>> progress = Progress(4, 'sim', unit='scenarios', stream=out)
    >>> progress.advance(1, force=True)
    >>> out.getvalue().split(',')[0]
    'sim: 1/4 scenarios (25.0%)'

    Notes
    -----
    A line looks like ``sim: 12/200 scenarios (6.0%) <status>, elapsed 1m02s,
    ETA 16m11s``. The estimate assumes the remaining work goes as fast as the
    work done so far.
    """

    def __init__(self, total, label, unit=None, stream=None):
        if not total > 0:
            raise ValueError(f'total must be positive, got {total!r}')
        self.total = total
        self.label = label
        self.unit = unit
        self.done = 0
        self.status = ''
        self.t0 = time.monotonic()
        self.output = StatusLine(stream)

    def advance(self, amount=1, status=None, force=False):
        """Count ``amount`` more work done and print a line if one is due.

        Parameters
        ----------
        amount : float
            Work done since the last call (0 to only update the status).
        status : str, optional
            Short text shown after the count (e.g. what runs now); kept until
            replaced.
        force : bool
            Print now even if the last line is recent.
        """
        self.done += amount
        if status is not None:
            self.status = status
        now = time.monotonic()
        self.output.show(self.line(now - self.t0), force, now)

    def line(self, elapsed_s):
        """The progress text after ``elapsed_s`` seconds of wall time."""
        fraction = min(self.done / self.total, 1.0)
        count = f'{self.done:g}/{self.total:g} {self.unit} ' if self.unit else ''
        status = f' {self.status}' if self.status else ''
        return (f'{self.label}: {count}({100.0 * fraction:.1f}%){status}, '
                f'elapsed {format_duration(elapsed_s)}, '
                f'ETA {format_duration(eta_s(elapsed_s, fraction))}')

    def finish(self):
        """Print the final line (and end the terminal line)."""
        self.advance(0, force=True)
        self.output.close()
