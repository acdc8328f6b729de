"""Smoke test of ``fusion-planner bench families`` (its figures are not checked here)."""

import json

import pytest

from fusion_planner.cli.main import main


def test_one_scenario_per_family_gives_a_table_per_family(capsys):
    code = main(['bench', 'families', '--scenarios', '1', '--family', 'narrow', '--family',
                 'unreachable', '--controller', 'astar-track'])
    out, err = capsys.readouterr()
    assert code == 0
    assert '1 narrow scenarios' in out and '1 unreachable scenarios' in out
    assert out.count('| astar-track |') == 2 and 'wall time [s]' in out
    assert '2/2 scenarios' in err


def test_json_holds_every_family_asked_for(capsys):
    code = main(['bench', 'families', '--scenarios', '1', '--seed', '3', '--family', 'unreachable',
                 '--controller', 'classic-apf', '--json'])
    report = json.loads(capsys.readouterr().out)
    assert code == 0 and report['seed'] == 3 and list(report['families']) == ['unreachable']
    summary = report['families']['unreachable']['controllers']['classic-apf']
    assert summary['unsolvable_episodes'] == 1 and summary['wall_time_s'] > 0


def test_the_stress_tests_run_only_when_asked_for(monkeypatch, capsys):
    from fusion_planner.bench import families as bench_families
    from fusion_planner.core.simulation.families import FAMILIES
    one = bench_families.run_batch(1, 3, controllers=['astar-track'], family='unreachable')
    asked = []

    def record(n, seed, family, **_options):
        asked.append(family)
        return one

    monkeypatch.setattr(bench_families, 'run_batch', record)
    assert main(['bench', 'families', '--scenarios', '1', '--controller', 'astar-track']) == 0
    assert asked == [f for f in FAMILIES if f != 'dense-crowd']
    asked.clear()
    assert main(['bench', 'families', '--scenarios', '1', '--family', 'dense-crowd']) == 0
    assert asked == ['dense-crowd']
    capsys.readouterr()


@pytest.mark.parametrize('argv, words', [
    (['--scenarios', '0'], '--scenarios'),
    (['--family', 'maze'], 'unknown family'),
    (['--controller', 'teleport'], 'unknown controller'),
])
def test_bad_options_exit_2_with_one_line(capsys, argv, words):
    code = main(['bench', 'families', *argv])
    out, err = capsys.readouterr()
    assert code == 2 and out == '' and words in err and err.count('\n') == 1
