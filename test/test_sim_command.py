"""Tests of ``fusion-planner sim``: output contract, exit status, one-line errors."""

import json
import os
import pathlib
import subprocess
import sys

import numpy as np
import pytest
import yaml

from fusion_planner.cli.main import main
from fusion_planner.core.grid import GridMap
from fusion_planner.core.map_files import save_map_server

REPO = pathlib.Path(__file__).resolve().parent.parent
SCENARIOS = REPO / 'config' / 'scenarios'
EPISODE_KEYS = {'reached', 'collisions', 'time_s', 'path_length_m', 'min_clearance_m',
                'stuck_events', 'failure'}


def run_cli(capsys, *argv):
    code = main(['sim', *argv])
    out, err = capsys.readouterr()
    return code, out, err


@pytest.fixture
def room(tmp_path):
    occ = np.zeros((60, 80), bool)
    occ[0:20, 40:45] = True
    save_map_server(GridMap(occ, 0.1), tmp_path / 'room.yaml')
    return tmp_path


def scenario_file(folder, **changes):
    doc = {'map': 'room.yaml', 'robot': {'start': [1.0, 1.0, 0.0], 'radius': 0.2},
           'goal': [7.0, 4.0], 'limits': {'time_limit_s': 30.0}}
    for key, value in changes.items():
        if value is None:
            doc.pop(key)
        elif isinstance(value, dict) and isinstance(doc.get(key), dict):
            doc[key] = {**doc[key], **value}
        else:
            doc[key] = value
    path = folder / 'scenario.yaml'
    path.write_text(yaml.safe_dump(doc), encoding='utf-8')
    return path


def test_json_of_a_reached_goal(capsys, room):
    code, out, err = run_cli(capsys, '--scenario', str(scenario_file(room)), '--json')
    report = json.loads(out)
    assert code == 0 and report['reached'] is True
    assert EPISODE_KEYS <= set(report)
    assert report['failure'] is None and report['controller'] == 'fusion'
    assert report['collisions'] == 0 and report['path_length_m'] > 6.0


def test_classic_apf_on_figure_5a_exits_1_with_a_reason(capsys):
    code, out, _ = run_cli(capsys, '--scenario', str(SCENARIOS / 'fig5a.yaml'),
                           '--controller', 'classic-apf', '--json')
    report = json.loads(out)
    assert code == 1
    assert report['reached'] is False and report['failure']


def test_text_summary_and_seed_override(capsys, room):
    code, out, _ = run_cli(capsys, '--scenario', str(scenario_file(room)), '--seed', '9')
    assert code == 0
    assert out.count('\n') == 1 and 'reached' in out and '(seed 9)' in out


def test_plot_is_written(capsys, room, tmp_path):
    png = tmp_path / 'run.png'
    code, _, _ = run_cli(capsys, '--scenario', str(scenario_file(room)), '--plot', str(png))
    assert code == 0
    assert png.read_bytes()[:8] == b'\x89PNG\r\n\x1a\n'


@pytest.mark.parametrize('changes, words', [
    ({'robot': {'start': [1.0, 1.0, 0.0]}}, "missing required key 'robot.radius'"),
    ({'goal': None}, "missing required key 'goal'"),
    ({'robot': {'radius': -0.3}}, "key 'robot.radius' must be positive"),
    ({'robot': {'start': [4.2, 1.0, 0.0], 'radius': 0.2}}, "key 'robot.start'"),
    ({'unknown_obstacles': [{'circle': {'center': [1.0, 1.2], 'radius': 0.3}}]}, "key 'robot.start'"),
    ({'moving_obstacles': [{'radius': 0.2, 'model': 'jump', 'position': [3, 3]}]},
     "unknown motion model 'jump'"),
])
def test_bad_scenario_files_exit_2_with_one_line(capsys, room, changes, words):
    if 'robot' in changes and 'radius' not in changes['robot']:
        path = room / 'scenario.yaml'
        path.write_text(yaml.safe_dump({'map': 'room.yaml', 'robot': changes['robot'],
                                        'goal': [7.0, 4.0]}), encoding='utf-8')
    else:
        path = scenario_file(room, **changes)
    code, out, err = run_cli(capsys, '--scenario', str(path), '--json')
    assert code == 2
    assert out == ''
    assert err.count('\n') == 1 and err.startswith('error: ')
    assert words in err
    assert str(path) in err


@pytest.mark.parametrize('argv, words', [
    (['--scenario', 'SCEN', '--controller', 'teleport'], 'unknown controller'),
    (['--scenario', '/no/such/file.yaml'], 'cannot read'),
    ([], 'exactly one of'),
    (['--scenario', 'SCEN', '--random', '2'], 'exactly one of'),
    (['--random', '2', '--plot', 'x.png'], '--plot'),
    (['--scenario', 'SCEN', '--controller', 'fusion', '--controller', 'apf'], 'once'),
    (['--scenario', 'SCEN', '--family', 'clutter'], 'needs --random'),
    (['--random', '1', '--family', 'maze'], 'unknown family'),
])
def test_bad_command_lines_exit_2_with_one_line(capsys, argv, words):
    argv = [str(SCENARIOS / 'fig5a.yaml') if a == 'SCEN' else a for a in argv]
    code, out, err = run_cli(capsys, *argv)
    assert code == 2 and out == ''
    assert err.count('\n') == 1 and words in err


def test_a_bad_file_never_prints_a_traceback(room):
    path = scenario_file(room, robot={'radius': -1.0})
    env = {**os.environ, 'PYTHONPATH': str(REPO)}
    command = [sys.executable, '-m', 'fusion_planner.cli.main', 'sim', '--scenario', str(path)]
    proc = subprocess.run(command, capture_output=True, text=True, env=env, timeout=120)
    assert proc.returncode == 2
    assert 'Traceback' not in proc.stderr
    assert proc.stderr.count('\n') == 1


def test_batch_json_and_progress(capsys):
    code, out, err = run_cli(capsys, '--random', '2', '--seed', '4', '--controller', 'astar-track',
                             '--controller', 'classic-apf', '--json')
    report = json.loads(out)
    assert code == 0
    assert report['scenarios'] == 2 and report['seed'] == 4
    assert set(report['controllers']) == {'astar-track', 'classic-apf'}
    for summary in report['controllers'].values():
        assert {'success_rate', 'collisions', 'mean_time_s'} <= set(summary)
        assert 0.0 <= summary['success_rate'] <= 1.0
    assert len(report['episodes']) == 4
    assert 'ETA' in err and '2/2' in err


def test_batch_table_lists_every_controller(capsys):
    code, out, _ = run_cli(capsys, '--random', '1', '--seed', '3')
    assert code == 0
    for name in ('fusion', 'apf', 'classic-apf', 'dwa', 'astar-track'):
        assert f'| {name} |' in out


def test_a_family_batch_in_json_and_in_the_table(capsys):
    code, out, _ = run_cli(capsys, '--random', '1', '--family', 'narrow', '--controller',
                           'astar-track', '--json')
    report = json.loads(out)
    assert code == 0 and report['family'] == 'narrow'
    row, = report['episodes']
    assert row['family'] == 'narrow' and row['solvable'] is True
    assert row['outcome'] in ('reached', 'no_path', 'controller_failed', 'collisions', 'time_limit')
    summary = report['controllers']['astar-track']
    assert {'success_on_solvable', 'outcomes', 'stuck_run_fraction', 'mean_time_ratio',
            'no_path_fraction', 'max_no_path_delay_s'} <= set(summary)
    code, out, _ = run_cli(capsys, '--random', '1', '--family', 'narrow', '--controller', 'astar-track')
    assert code == 0 and '1 narrow scenarios' in out and '| astar-track |' in out
