"""A real ``colcon build`` of the package gives the layout ``ros2 run`` needs.

The package is copied into ``<tmp>/src`` (so the build never writes into the
source tree), built with colcon, and the install space is checked: the ament
index marker, package.xml, the config files, and one executable per node in
``lib/fusion_planner``. Then the installed simulator is started the way
``ros2 run fusion_planner simulator`` would start it (environment of
``install/setup.bash``): it must find the bundled scenario through the ament
index, accept the installed params file, and stop cleanly on SIGINT.
"""

import importlib.util
import os
import pathlib
import shutil
import signal
import subprocess
import sys
import time

import pytest

REPO = pathlib.Path(__file__).resolve().parent.parent
PACKAGE = 'fusion_planner'
#: What a source checkout of the package holds that the build needs.
PACKAGE_CONTENT = ('package.xml', 'setup.py', 'setup.cfg', 'resource', 'fusion_planner', 'config')
EXECUTABLES = ('global_planner', 'local_planner', 'simulator')
#: Wall time limits [s].
BUILD_TIMEOUT_S = 300
NODE_START_TIMEOUT_S = 30
NODE_STOP_TIMEOUT_S = 10


@pytest.fixture(scope='module')
def install(tmp_path_factory):
    """Build the package with colcon into a temporary workspace; returns the install prefix."""
    if importlib.util.find_spec('colcon_core') is None:
        pytest.skip('colcon is not importable here (pip install colcon-common-extensions) '
                    'so the colcon install layout cannot be checked')
    workspace = tmp_path_factory.mktemp('ws')
    source = workspace / 'src' / PACKAGE
    source.mkdir(parents=True)
    for name in PACKAGE_CONTENT:
        origin = REPO / name
        if origin.is_dir():
            shutil.copytree(origin, source / name,
                            ignore=shutil.ignore_patterns('__pycache__', '*.pyc', '*.egg-info'))
        else:
            shutil.copy2(origin, source / name)
    run_colcon = 'import sys; from colcon_core.command import main; sys.exit(main())'
    cmd = [sys.executable, '-c', run_colcon, 'build', '--base-paths', 'src',
           '--build-base', 'build', '--install-base', 'install',
           '--event-handlers', 'console_direct-']
    done = subprocess.run(cmd, cwd=workspace, capture_output=True, text=True,
                          timeout=BUILD_TIMEOUT_S)
    assert done.returncode == 0, \
        f'colcon build failed:\n{done.stdout[-3000:]}\n{done.stderr[-3000:]}'
    prefix = workspace / 'install' / PACKAGE  # colcon's default isolated layout
    assert prefix.is_dir(), sorted(p.name for p in (workspace / 'install').iterdir())
    return prefix


def test_ament_index_marker_and_package_xml(install):
    assert (install / 'share' / 'ament_index' / 'resource_index' / 'packages' / PACKAGE).is_file()
    installed = install / 'share' / PACKAGE / 'package.xml'
    assert installed.read_text() == (REPO / 'package.xml').read_text()


def test_config_params_and_scenarios_are_installed(install):
    config = install / 'share' / PACKAGE / 'config'
    assert (config / 'params.yaml').read_text() == (REPO / 'config' / 'params.yaml').read_text()
    scenarios = sorted(p.name for p in (config / 'scenarios').glob('*.yaml'))
    assert 'demo.yaml' in scenarios
    assert scenarios == sorted(p.name for p in (REPO / 'config' / 'scenarios').glob('*.yaml'))
    # Scenario files name their maps relative to themselves: those must be installed too.
    from fusion_planner.core.simulation.scenario import load_scenario
    scenario = load_scenario(config / 'scenarios' / 'demo.yaml')
    assert pathlib.Path(scenario.map_path).is_relative_to(config)


@pytest.mark.parametrize('name', EXECUTABLES)
def test_one_executable_per_node_in_lib(install, name):
    exe = install / 'lib' / PACKAGE / name
    assert exe.is_file(), sorted(p.name for p in (install / 'lib' / PACKAGE).iterdir())
    assert os.access(exe, os.X_OK)


def test_installed_simulator_runs_like_ros2_run_and_stops_on_sigint(install, tmp_path):
    site = next((install / 'lib').glob('python3*/site-packages'))
    env = dict(os.environ)
    # What `source install/setup.bash` adds for this package.
    env['AMENT_PREFIX_PATH'] = os.pathsep.join(
        filter(None, [str(install), env.get('AMENT_PREFIX_PATH')]))
    env['PYTHONPATH'] = os.pathsep.join(filter(None, [str(site), env.get('PYTHONPATH')]))
    params = install / 'share' / PACKAGE / 'config' / 'params.yaml'
    log_path = tmp_path / 'simulator.log'
    with open(log_path, 'wb') as log:
        proc = subprocess.Popen([str(install / 'lib' / PACKAGE / 'simulator'), '--ros-args',
                                 '--params-file', str(params)],
                                stdout=log, stderr=subprocess.STDOUT, env=env, cwd=tmp_path)
    try:
        deadline = time.monotonic() + NODE_START_TIMEOUT_S
        while time.monotonic() < deadline and 'loaded from' not in log_path.read_text() \
                and proc.poll() is None:
            time.sleep(0.1)
        text = log_path.read_text()
        assert 'loaded from' in text, text[-3000:]
        # The default scenario came from the install found through the ament index.
        expected = install / 'share' / PACKAGE / 'config' / 'scenarios' / 'demo.yaml'
        assert f'loaded from {expected}' in text, text[-3000:]
    finally:
        if proc.poll() is None:
            proc.send_signal(signal.SIGINT)
        try:
            code = proc.wait(timeout=NODE_STOP_TIMEOUT_S)
        except subprocess.TimeoutExpired:
            proc.kill()
            code = 'killed'
    text = log_path.read_text()
    assert code == 0, text[-3000:]
    assert 'Traceback' not in text, text[-3000:]


@pytest.mark.parametrize('name', EXECUTABLES)
def test_installed_executable_without_ros_says_so_in_one_line(install, tmp_path, name):
    """``ros2 run fusion_planner <node>`` on a Python where ROS 2 does not import."""
    site = next((install / 'lib').glob('python3*/site-packages'))
    env = dict(os.environ)
    env['AMENT_PREFIX_PATH'] = os.pathsep.join(
        filter(None, [str(install), env.get('AMENT_PREFIX_PATH')]))
    env['PYTHONPATH'] = os.pathsep.join([str(REPO / 'test' / 'core_only'), str(site)])
    env.pop('FUSION_PLANNER_BLOCKED', None)
    done = subprocess.run([str(install / 'lib' / PACKAGE / name), '--ros-args'],
                          capture_output=True, text=True, env=env, cwd=tmp_path,
                          timeout=NODE_START_TIMEOUT_S)
    assert done.returncode == 2, done.stderr[-3000:]
    assert done.stderr.count('\n') == 1 and 'Traceback' not in done.stderr
    assert done.stderr.startswith(f'{name}: error: ') and 'ros' in done.stderr
