"""Without an optional extra, every command, option and executable says so in one line.

Each case runs in a subprocess whose Python cannot import the extras (the
``test/core_only`` start-up hook makes their modules raise
``ModuleNotFoundError``, as on a machine where only the core was installed):
the answer must be one line on stderr naming the extra to install, exit
status 2, no traceback, and no work done (nothing on stdout, no file
written).
"""

import os
import pathlib
import subprocess
import sys

import pytest

from conftest import REPO

CORE_ONLY_HOOK = pathlib.Path(__file__).resolve().parent / 'core_only'
PAPER_MAP = str(REPO / 'config' / 'maps' / 'paper.yaml')
FIG5A = str(REPO / 'config' / 'scenarios' / 'fig5a.yaml')
PLAN = ['plan', '--map', PAPER_MAP, '--start', '1.5', '1.5', '--goal', '19.5', '19.5']
#: Wall time limit of one subprocess [s].
TIMEOUT_S = 120
ROS_FIX = "pip install 'fusion_planner[ros]'"


def run_core_only(args, cwd, blocked=None):
    """Run ``python *args`` where the extras (or only the modules ``blocked``) are missing."""
    env = dict(os.environ)
    env['PYTHONPATH'] = os.pathsep.join([str(CORE_ONLY_HOOK), str(REPO)])
    env.pop('FUSION_PLANNER_BLOCKED', None)
    if blocked is not None:
        env['FUSION_PLANNER_BLOCKED'] = ','.join(blocked)
    return subprocess.run([sys.executable, *args], capture_output=True, text=True, cwd=cwd,
                          env=env, timeout=TIMEOUT_S)


def cli(*argv):
    return ['-m', 'fusion_planner.cli.main', *argv]


def executable(node):
    """What the console script of a node runs (setup.py's entry point)."""
    return ['-c', f'import sys; from fusion_planner.ros.executables import {node}; '
                  f'sys.exit({node}())']


#: The node executables (console scripts, started by ``ros2 run``).
NODES = ('global_planner', 'local_planner', 'simulator')
#: (command line, extra named in the answer); OUT is replaced by an output folder.
CASES = [
    (cli(*PLAN, '--plot', 'OUT/plan.png'), 'plot'),
    (cli(*PLAN, '--json', '--plot', 'OUT/plan.png'), 'plot'),
    (cli('sim', '--scenario', FIG5A, '--plot', 'OUT/run.png'), 'plot'),
    (cli('sim', '--scenario', FIG5A, '--gif', 'OUT/run.gif'), 'plot'),
    (cli('bench', 'paper', '--plot', 'OUT'), 'plot'),
    (cli('bench', 'peers', '--quick'), 'bench'),
    (cli('bench', 'peers', '--quick', '--planners', 'astar', 'tcod'), 'bench'),
    (cli('bench', 'peers', '--quick', '--planners', 'astar', '--plot', 'OUT/peers.png'), 'plot'),
    (cli('bench', 'local', '--quick'), 'ros'),
    (cli('bench', 'local', '--no-ros'), 'ros'),  # the demo run needs ROS 2
    (cli('demo', '--plot', 'OUT/demo.png'), 'ros'),
    (cli('demo', '--processes', '--no-plot', '--no-gif', '--no-record', '--plot', 'OUT/d.png'),
     'ros'),
    (['-m', 'fusion_planner.ros.fuzz', '--messages', '10'], 'ros'),
]


def assert_refused(done, extra, out_dir):
    lines = done.stderr.splitlines()
    assert done.returncode == 2, done.stderr[-2000:]
    assert len(lines) == 1, done.stderr[-2000:]
    assert 'error: ' in lines[0] and 'Traceback' not in done.stderr
    fix = ROS_FIX if extra == 'ros' else f"pip install 'fusion_planner[{extra}]'"
    assert f'needs the {extra} extra' in lines[0] and fix in lines[0], lines[0]
    assert done.stdout == ''  # no work done, not even a plan printed
    assert not out_dir.exists()  # nothing written, no folder made


def case_id(args):
    """The words of a command line that tell the cases apart."""
    return ' '.join(a for a in args if a not in ('-m', 'fusion_planner.cli.main')
                    and '/' not in a and 'OUT' not in a)


@pytest.mark.parametrize('args, extra', [pytest.param(*case, id=case_id(case[0])) for case in CASES]
                         + [pytest.param(executable(node), 'ros', id=node) for node in NODES])
def test_core_only_refuses_in_one_line_naming_the_extra(tmp_path, args, extra):
    out_dir = tmp_path / 'out'
    args = [a.replace('OUT', str(out_dir)) for a in args]
    assert_refused(run_core_only(args, tmp_path), extra, out_dir)


def test_ros_messages_missing_with_rclpy_present_is_the_same_line(tmp_path):
    done = run_core_only(executable('simulator'), tmp_path, blocked=['geometry_msgs'])
    assert_refused(done, 'ros', tmp_path / 'out')
    assert "No module named 'geometry_msgs" in done.stderr


@pytest.mark.parametrize('blocked, extra, options', [
    (['matplotlib'], 'plot', []),
    (['PIL'], 'plot', ['--no-plot']),         # the animation still needs the extra
    (['mcap'], 'record', ['--no-plot', '--no-gif']),
])
def test_demo_checks_the_extras_of_its_outputs_before_it_starts(tmp_path, blocked, extra,
                                                                  options):
    out_dir = tmp_path / 'out'
    done = run_core_only(cli('demo', '--plot', str(out_dir / 'demo.png'), *options), tmp_path,
                         blocked=blocked)
    assert_refused(done, extra, out_dir)
    assert '--no-' in done.stderr  # and how to do without


@pytest.mark.parametrize('blocked, extra', [(['matplotlib'], 'plot'), (['mcap_ros2'], 'record')])
def test_bench_local_checks_the_extras_of_its_demo_run(tmp_path, blocked, extra):
    done = run_core_only(cli('bench', 'local', '--no-ros'), tmp_path, blocked=blocked)
    assert_refused(done, extra, tmp_path / 'out')
    assert '--no-demo' in done.stderr


def test_soak_without_the_test_extra(tmp_path):
    done = run_core_only(['-m', 'fusion_planner.ros.fuzz'], tmp_path, blocked=['hypothesis'])
    assert_refused(done, 'test', tmp_path / 'out')


@pytest.mark.parametrize('argv', [
    [*PLAN, '--json'],
    ['sim', '--scenario', FIG5A, '--json'],
    ['bench', 'paper', '--json', '--repeats', '1'],
    ['bench', 'peers', '--quick', '--no-progress', '--suites', 'random', '--planners', 'astar'],
])
def test_what_needs_no_extra_runs_core_only(tmp_path, argv):
    done = run_core_only(cli(*argv), tmp_path)
    assert done.returncode == 0, done.stderr[-2000:]
    assert done.stdout and 'Traceback' not in done.stderr


@pytest.mark.parametrize('argv', [[], ['plan'], ['sim'], ['demo'], ['bench'], ['bench', 'peers'],
                                  ['bench', 'local'], ['bench', 'movingai']])
def test_help_works_core_only(tmp_path, argv):
    done = run_core_only(cli(*argv, '--help'), tmp_path)
    assert done.returncode == 0, done.stderr[-2000:]
    assert done.stdout.startswith('usage: fusion-planner')


def test_the_node_console_scripts_check_ros_first():
    """setup.py's node executables are the checking entry points (ros2 run starts them)."""
    text = (REPO / 'setup.py').read_text()
    for node in NODES:
        assert f"'{node} = fusion_planner.ros.executables:{node}'" in text
