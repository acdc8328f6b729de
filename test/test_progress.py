"""Progress lines: counts, percentages, elapsed time and the time left."""

import io
import math

import pytest

from fusion_planner.cli import progress as progress_module
from fusion_planner.cli.progress import Progress, eta_s, format_duration


class Tty(io.StringIO):
    def isatty(self):
        return True


def test_durations_and_estimates():
    assert [format_duration(s) for s in (0, 59.4, 60, 3599, 3600, 86399)] == \
        ['0s', '59s', '1m00s', '59m59s', '1h00m00s', '23h59m59s']
    assert format_duration(math.inf) == format_duration(math.nan) == '?'
    assert eta_s(30.0, 0.75) == pytest.approx(10.0)
    assert math.isnan(eta_s(5.0, 0.0)) and eta_s(5.0, 1.5) == 0.0


def test_log_lines_are_throttled_and_the_last_one_is_complete(monkeypatch):
    clock = iter([0.0, 1.0, 2.0, 100.0, 101.0])
    monkeypatch.setattr(progress_module.time, 'monotonic', lambda: next(clock))
    stream = io.StringIO()
    job = Progress(8, 'movingai', unit='rows', stream=stream)   # t0 = 0
    job.advance(2)                                              # first line, t = 1
    job.advance(2)                                              # t = 2: throttled
    job.advance(2, status='map arena')                          # t = 100: due
    job.finish()                                                # t = 101: forced
    lines = stream.getvalue().splitlines()
    assert lines == [
        'movingai: 2/8 rows (25.0%), elapsed 1s, ETA 3s',
        'movingai: 6/8 rows (75.0%) map arena, elapsed 1m40s, ETA 33s',
        'movingai: 6/8 rows (75.0%) map arena, elapsed 1m41s, ETA 34s']


def test_terminal_line_is_rewritten_in_place_and_fractions_show_percent():
    stream = Tty()
    job = Progress(2.5, 'peers', stream=stream)
    job.advance(1.25, force=True)
    job.finish()
    text = stream.getvalue()
    assert text.startswith('\rpeers: (50.0%), elapsed') and text.endswith('\n')
    assert text.count('\r') == 2 and 'ETA' in text
    with pytest.raises(ValueError, match='positive'):
        Progress(0, 'empty')


def test_status_lines_in_a_log_are_whole_lines_at_the_log_rate(monkeypatch):
    clock = iter([0.0, 0.25, 10.0, progress_module.LOG_PERIOD_S + 0.1, 40.0])
    monkeypatch.setattr(progress_module.time, 'monotonic', lambda: next(clock))
    log = io.StringIO()
    line = progress_module.StatusLine(log)
    shown = [line.show(f'sim {t} s') for t in (0, 1, 2, 3)] + [line.show('final', force=True)]
    line.close()
    assert shown == [True, False, False, True, True]
    assert log.getvalue() == 'sim 0 s\nsim 3 s\nfinal\n'
    assert '\r' not in log.getvalue()


def test_status_line_on_a_terminal_is_redrawn_in_place_and_ended_once():
    tty = Tty()
    line = progress_module.StatusLine(tty)
    line.show('first', force=True)
    line.show('second', force=True)
    line.close()
    line.close()
    text = tty.getvalue()
    assert text.count('\r') == 2 and text.count('\n') == 1 and text.endswith('\n')
    assert text.split('\r')[2].rstrip() == 'second'
