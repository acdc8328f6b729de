"""Tests of ``fusion-planner bench local`` (fusion_planner.bench.local).

A quick run checks the report's structure and the parsing of the demo's
outcome line. No test asserts a time.
"""

import json

import pytest

from fusion_planner.bench import local
from fusion_planner.cli.bench_command import TARGETS
from fusion_planner.cli.main import main
from fusion_planner.cli.requirements import missing


def test_target_is_registered():
    assert TARGETS['local'] == 'fusion_planner.bench.local'


@pytest.mark.parametrize('inputs', [['--no-ros'], []])
def test_quick_run_structure(capsys, inputs):
    if not inputs and missing('ros', 'bench local') is not None:
        pytest.skip('ROS 2 not importable')
    status = main(['bench', 'local', '--quick', '--json', *inputs])
    report = json.loads(capsys.readouterr().out)
    assert status == 0
    steps = report['steps']
    assert steps['steps'] == local.QUICK_STEPS
    assert steps['ros_inputs'] == (not inputs)
    assert steps['scene']['beams'] == 720 and steps['scene']['moving_obstacles'] == 20
    ms = steps['step_ms']
    assert 0 <= ms['median'] <= ms['p90'] <= ms['p99'] <= ms['max']
    assert steps['load'] > 0
    assert (steps['scan_ms'] is None) == bool(inputs)
    assert report['demo'] is None  # --quick skips the demo
    assert [v['status'] in ('met', 'NOT met') for v in report['targets']] == [True, True]


def test_scene_has_the_asked_sensor_and_obstacles():
    scenario = local.bench_scenario(local.DEFAULT_SEED)
    assert scenario.scan.beams == local.BEAMS
    assert len(scenario.moving_obstacles) == local.MOVING_OBSTACLES
    assert scenario.follower_params().control_period == pytest.approx(1 / local.CONTROL_RATE_HZ)


def test_demo_outcome_is_parsed():
    line = ('arrived: no   sim time: 60.00 s   (wall 12.5 s with start-up, 4.9x real time)   '
            'path length: 3.00 m   collisions: 1   min clearance: n/a')
    assert local.parse_demo_outcome('progress\n' + line + '\n') == {
        'arrived': False, 'sim_time_s': 60.0, 'wall_s': 12.5, 'factor': 4.9}
    assert local.parse_demo_outcome('error: ROS 2 is not importable') is None


def test_demo_verdicts():
    demo = {'requested': 100.0, 'arrived': True, 'sim_time_s': 20.0, 'wall_s': 1.5,
            'factor': 12.0, 'cpu_s': 2.0}
    verdicts = local.evaluate_targets(None, demo)
    assert [v['status'] for v in verdicts] == ['met']
    failed = local.evaluate_targets(None, {'requested': 100.0, 'error': 'exit 2: no ROS'})
    assert failed[0]['status'] == 'NOT met' and 'no ROS' in failed[0]['detail']
