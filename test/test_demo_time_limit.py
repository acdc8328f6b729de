"""The demo's reported simulated time: never past the limit, the same in progress and outcome."""

import os
import re
import subprocess
import sys
from types import SimpleNamespace as Msg

import pytest

from conftest import REPO
from fusion_planner.cli import demo_command as demo
from fusion_planner.core.simulation.scenario import load_scenario

DEMO_SCENARIO = REPO / 'config' / 'scenarios' / 'demo.yaml'
#: Wall time limit of a demo subprocess [s].
DEMO_TIMEOUT_S = 180
OUTCOME_TIME = re.compile(r'sim time: (\d+\.\d\d) s')
PROGRESS_TIME = re.compile(r'^ {2}sim +(\d+\.\d\d) s {3}distance to goal', re.M)


def stamp(t):
    return Msg(sec=int(t), nanosec=int(round((t - int(t)) * 1e9)))


def clock(t):
    return Msg(clock=stamp(t))


def odom(t, x, y):
    return Msg(header=Msg(stamp=stamp(t)),
               pose=Msg(pose=Msg(position=Msg(x=x, y=y), orientation=Msg(z=0.0, w=1.0))))


def status(t, name, **values):
    return Msg(header=Msg(stamp=stamp(t)), status=[Msg(
        name=name, values=[Msg(key=k, value=str(v)) for k, v in values.items()])])


@pytest.fixture
def recorder():
    scenario = load_scenario(DEMO_SCENARIO)
    return scenario, demo.RunRecorder(scenario, goal_tolerance=0.15, time_limit_s=3.0)


def test_what_comes_after_the_limit_is_not_part_of_the_run(recorder):
    scenario, rec = recorder
    x0, y0 = scenario.start[:2]
    for t in (1.0, 2.0, 3.0):
        rec.on_clock(clock(t))
        rec.on_ground_truth(odom(t, x0 + t, y0))
        rec.on_diagnostics(status(t, '/simulator', collisions=0, distance_travelled_m=t))
    rec.on_clock(clock(7.7))                       # the simulator ran on meanwhile
    rec.on_ground_truth(odom(7.7, x0 + 7.7, y0))
    rec.on_diagnostics(status(7.7, '/simulator', collisions=2, distance_travelled_m=7.7))
    gx, gy = scenario.goal
    rec.on_ground_truth(odom(7.8, gx, gy))
    rec.on_diagnostics(status(7.8, '/local_planner', status='arrived'))
    assert rec.snapshot()[0] == 3.0
    result = rec.result(False, 'time_limit')
    assert result.time_s == 3.0
    assert result.collisions == 0 and result.path_length_m == 3.0
    assert len(result.trajectory) == 3 and result.trajectory[-1][0] == pytest.approx(x0 + 3.0)
    assert rec.arrived_at is None


def test_an_arrival_freezes_the_reported_time_and_end_freezes_the_run(recorder):
    scenario, rec = recorder
    gx, gy = scenario.goal
    rec.on_clock(clock(2.0))
    rec.on_ground_truth(odom(2.0, gx, gy))
    rec.on_diagnostics(status(2.0, '/local_planner', status='arrived'))
    rec.on_clock(clock(2.5))
    assert rec.snapshot()[0] == 2.0 and rec.result(True, None).time_s == 2.0
    rec.end()
    rec.on_clock(clock(2.9))
    rec.on_diagnostics(status(2.9, '/simulator', collisions=1))
    assert rec.sim_time == 2.5 and rec.collisions() == 0


def test_an_arrival_reported_before_its_true_pose_is_judged_on_the_pose_of_its_time(recorder):
    scenario, rec = recorder
    gx, gy = scenario.goal
    x0, y0 = scenario.start[:2]
    rec.on_ground_truth(odom(1.9, gx - 1.0, gy))
    rec.on_diagnostics(status(2.0, '/local_planner', status='arrived'))  # ahead of its pose
    assert rec.arrived_at is None
    rec.on_ground_truth(odom(2.0, gx, gy))
    assert rec.arrived_at == 2.0
    far = demo.RunRecorder(scenario, goal_tolerance=0.15, time_limit_s=3.0)
    far.on_ground_truth(odom(1.0, x0, y0))
    far.on_diagnostics(status(1.0, '/local_planner', status='arrived'))
    far.on_ground_truth(odom(1.1, gx, gy))  # a later pose does not make that claim true
    assert far.arrived_at is None


def run_demo(tmp_path, *options):
    env = dict(os.environ)
    env['PYTHONPATH'] = os.pathsep.join(filter(None, [str(REPO), env.get('PYTHONPATH')]))
    return subprocess.run(
        [sys.executable, '-m', 'fusion_planner.cli.main', 'demo', '--plot',
         str(tmp_path / 'demo.png'), '--no-plot', '--no-gif', '--no-record', *options],
        capture_output=True, text=True, env=env, timeout=DEMO_TIMEOUT_S, cwd=tmp_path)


def test_demo_time_limit_is_never_exceeded_and_progress_agrees(tmp_path):
    done = run_demo(tmp_path, '--time-limit', '3')
    assert done.returncode == 1, done.stderr[-3000:]
    outcome = done.stdout.strip().splitlines()[-1]
    assert outcome.startswith('arrived: no'), outcome
    reported = float(OUTCOME_TIME.search(outcome).group(1))
    assert 0.0 < reported <= 3.0
    assert 'not reached within 3 s' in done.stderr
    # stderr is a pipe here: whole lines, no carriage returns
    assert '\r' not in done.stderr
    progress = PROGRESS_TIME.findall(done.stderr)
    assert progress and float(progress[-1]) == reported
    assert not list(tmp_path.iterdir())  # --no-plot --no-gif --no-record: nothing written
