"""Smoke tests of ``fusion-planner bench tracker`` and ``bench dynamic`` (figures not checked)."""

import json

import pytest

from fusion_planner.cli.main import main


def test_tracker_bench_reports_every_figure(capsys):
    code = main(['bench', 'tracker', '--quick', '--json'])
    report = json.loads(capsys.readouterr().out)
    assert code == 0
    assert [f['family'] for f in report['families']] == [
        'mixed', 'corridors', 'crossing', 'crowd', 'blind-corner', 'fast-obstacle']
    for row in report['families'] + [report['clutter']]:
        assert {'velocity_error', 'delay_s', 'unusable_sightings',
                'false_tracks_per_min'} <= set(row)
    timing = report['update_time']
    assert timing['updates'] == 30 and timing['update_ms']['median'] > 0
    assert timing['scene'] == {'beams': 720, 'moving_obstacles': 20, 'seed': 11}


def test_dynamic_bench_compares_both_perceptions(capsys):
    code = main(['bench', 'dynamic', '--quick', '--family', 'crossing'])
    out = capsys.readouterr().out
    assert code == 0
    assert '| crossing | scan |' in out and '| crossing | ideal |' in out


@pytest.mark.parametrize('argv, words', [
    (['dynamic', '--family', 'maze'], 'known families'),
    (['dynamic', '--scenarios', '0'], 'positive'),
    (['tracker', '--updates', '0'], 'positive'),
])
def test_bad_options_exit_2_with_one_line(capsys, argv, words):
    code = main(['bench', *argv])
    out, err = capsys.readouterr()
    assert code == 2 and out == '' and words in err and err.count('\n') == 1
