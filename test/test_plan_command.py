"""``fusion-planner plan``: the JSON contract, exit codes, --cells, bad input.

Runs the command in-process through ``fusion_planner.cli.main.main``.
"""

import json
import math

import numpy as np
import pytest

from conftest import REPO
from fusion_planner.cli.main import main
from fusion_planner.core.grid import GridMap
from fusion_planner.core.map_files import load_map, save_map_server

PAPER_YAML = str(REPO / 'config' / 'maps' / 'paper.yaml')

JSON_KEYS = {'found', 'length_m', 'expanded', 'key_points', 'turning_deg',
             'min_clearance_m', 'time_s', 'path', 'error'}

#: An asymmetric MovingAI map, top row first. File cell (col 0, row 0) is
#: free, its mirror (col 0, row 3) is blocked, so reading rows the wrong
#: way up puts the start in an obstacle.
TINY_ROWS = (
    '.....',
    '@@@@.',
    '.....',
    '@@@..',
)


def run_cli(capsys, *argv):
    """Run the CLI; return (exit status, stdout, stderr)."""
    try:
        status = main(list(argv))
    except SystemExit as stop:  # argparse errors
        status = stop.code
    out, err = capsys.readouterr()
    return status, out, err


def assert_one_line_error(err):
    assert 'Traceback' not in err
    lines = [line for line in err.splitlines() if line.strip()]
    assert len(lines) == 1, err
    assert lines[0].startswith('error: ')
    assert len(lines[0]) > len('error: ') + 10


@pytest.fixture
def tiny_map(tmp_path):
    path = tmp_path / 'tiny.map'
    path.write_text('type octile\nheight 4\nwidth 5\nmap\n' + '\n'.join(TINY_ROWS) + '\n')
    return path


@pytest.fixture
def tiny_yaml(tmp_path):
    """The same layout as :data:`TINY_ROWS` as a map_server map."""
    occupied = np.array([[ch == '@' for ch in row] for row in TINY_ROWS])[::-1]
    path = tmp_path / 'tiny.yaml'
    save_map_server(GridMap(occupied, 1.0, (0.0, 0.0, 0.0)), path)
    return path


def free_in_file(points, rows=TINY_ROWS):
    """Whether each (x, y) [m] lies in a free character of a 1 m/cell text map."""
    height = len(rows)
    ok = []
    for x, y in points:
        col, file_row = int(math.floor(x)), height - 1 - int(math.floor(y))
        ok.append(0 <= file_row < height and 0 <= col < len(rows[0])
                  and rows[file_row][col] == '.')
    return ok


# -- the JSON contract --------------------------------------------------------

def test_json_has_every_field_with_its_type(capsys):
    status, out, err = run_cli(capsys, 'plan', '--map', PAPER_YAML, '--start', '1.5', '1.5',
                               '--goal', '19.5', '19.5', '--json')
    assert status == 0, err
    doc = json.loads(out)  # exactly one JSON document
    assert set(doc) == JSON_KEYS
    assert doc['found'] is True and doc['error'] is None
    for key in ('length_m', 'turning_deg', 'min_clearance_m', 'time_s'):
        assert isinstance(doc[key], float) and math.isfinite(doc[key]), key
    for key in ('expanded', 'key_points'):
        assert isinstance(doc[key], int) and not isinstance(doc[key], bool), key
    path = np.array(doc['path'])
    assert path.ndim == 2 and path.shape[1] == 2 and len(path) >= 2
    np.testing.assert_allclose(path[0], [1.5, 1.5])
    np.testing.assert_allclose(path[-1], [19.5, 19.5])
    seg = np.hypot(*np.diff(path, axis=0).T).sum()
    assert doc['length_m'] == pytest.approx(seg, rel=1e-9)
    assert doc['length_m'] >= math.hypot(18, 18) - 1e-9
    assert 2 <= doc['key_points'] <= len(path)
    assert doc['expanded'] > 0 and doc['time_s'] > 0 and doc['min_clearance_m'] > 0


def test_json_on_no_path_is_exit_1_with_found_false(capsys, tmp_path):
    walled = tmp_path / 'walled.map'
    walled.write_text('type octile\nheight 3\nwidth 5\nmap\n..@..\n..@..\n..@..\n')
    status, out, err = run_cli(capsys, 'plan', '--map', str(walled), '--start', '0.5', '0.5',
                               '--goal', '4.5', '0.5', '--json')
    assert status == 1
    doc = json.loads(out)
    assert set(doc) == JSON_KEYS
    assert doc['found'] is False and doc['path'] == []
    assert isinstance(doc['error'], str) and doc['error']
    assert doc['length_m'] is None
    assert_one_line_error(err)


def test_human_summary_without_json(capsys):
    status, out, err = run_cli(capsys, 'plan', '--map', PAPER_YAML, '--start', '1.5', '1.5',
                               '--goal', '19.5', '19.5', '--algorithm', 'astar',
                               '--neighbourhood', '4', '--no-refine')
    assert status == 0 and err == ''
    assert 'path found' in out and 'm' in out
    with pytest.raises(json.JSONDecodeError):
        json.loads(out)
    # A*-4 on 1 m cells: a Manhattan path, at least 18 + 18 m.
    length = float(out.split('length ')[1].split(' m')[0])
    assert length >= 36.0 - 1e-9


@pytest.mark.parametrize('algorithm,neighbourhood', [
    ('dijkstra', '8'), ('astar', '4'), ('astar', '16'), ('improved', '8'), ('improved', '16')])
def test_every_algorithm_reaches_the_goal_on_free_cells(capsys, algorithm, neighbourhood):
    status, out, _ = run_cli(capsys, 'plan', '--map', PAPER_YAML, '--start', '1.5', '1.5',
                             '--goal', '19.5', '19.5', '--algorithm', algorithm,
                             '--neighbourhood', neighbourhood, '--json')
    assert status == 0
    path = np.array(json.loads(out)['path'])
    grid = load_map(PAPER_YAML)
    cells = grid.cell_of(path)
    assert grid.contains(cells).all()
    assert not grid.occupied[cells[:, 0], cells[:, 1]].any()


def test_robot_radius_keeps_the_path_away(capsys):
    status, out, _ = run_cli(capsys, 'plan', '--map', PAPER_YAML, '--start', '1.5', '1.5',
                             '--goal', '19.5', '19.5', '--robot-radius', '0.9', '--json')
    assert status == 0
    assert json.loads(out)['min_clearance_m'] > 0.9


# -- --cells: MovingAI .scen convention ---------------------------------------

def test_cells_on_movingai_map_count_rows_from_the_top(capsys, tiny_map):
    status, out, err = run_cli(capsys, 'plan', '--map', str(tiny_map), '--cells',
                               '--start', '0', '0', '--goal', '0', '2', '--json', '--no-refine')
    assert status == 0, err
    doc = json.loads(out)
    path = np.array(doc['path'])
    # File row 0 is the top row: y = H - 0.5 = 3.5; file row 2 is y = 1.5.
    np.testing.assert_allclose(path[0], [0.5, 3.5])
    np.testing.assert_allclose(path[-1], [0.5, 1.5])
    assert all(free_in_file(path))
    # The wall forces the way round its open end at column 4.
    assert path[:, 0].max() == pytest.approx(4.5)
    assert doc['length_m'] >= 8.0 - 1e-9


def test_cells_on_yaml_map_use_the_same_convention(capsys, tiny_map, tiny_yaml):
    docs = []
    for path in (tiny_map, tiny_yaml):
        status, out, err = run_cli(capsys, 'plan', '--map', str(path), '--cells', '--start',
                                   '0', '0', '--goal', '0', '2', '--json', '--no-refine')
        assert status == 0, err
        docs.append(json.loads(out))
    np.testing.assert_allclose(docs[0]['path'], docs[1]['path'])
    assert docs[0]['length_m'] == pytest.approx(docs[1]['length_m'])


def test_cells_equal_the_metres_of_their_centres(capsys, tiny_map):
    status, out_cells, _ = run_cli(capsys, 'plan', '--map', str(tiny_map), '--cells',
                                   '--start', '0', '2', '--goal', '4', '3', '--json')
    assert status == 0
    status, out_m, _ = run_cli(capsys, 'plan', '--map', str(tiny_map), '--start', '0.5', '1.5',
                               '--goal', '4.5', '0.5', '--json')
    assert status == 0
    np.testing.assert_allclose(json.loads(out_cells)['path'], json.loads(out_m)['path'])


def test_cells_flip_puts_mirror_start_in_the_obstacle(capsys, tiny_map):
    # File (col 0, row 3) is '@': refusing it proves rows count from the top.
    status, out, err = run_cli(capsys, 'plan', '--map', str(tiny_map), '--cells',
                               '--start', '0', '3', '--goal', '0', '0')
    assert status == 2
    assert 'start' in err and 'obstacle' in err
    assert_one_line_error(err)


# -- bad input: exit 2, one line, no traceback --------------------------------

def _bad_cases(tmp_path, tiny_map):
    no_image = tmp_path / 'no_image.yaml'
    no_image.write_text('resolution: 1.0\norigin: [0, 0, 0]\n')
    pgm = tmp_path / 'ok.pgm'
    pgm.write_bytes(b'P5\n2 2\n255\n' + bytes([254, 254, 254, 254]))
    zero_res = tmp_path / 'zero_res.yaml'
    zero_res.write_text('image: ok.pgm\nresolution: 0\norigin: [0, 0, 0]\n')
    neg_res = tmp_path / 'neg_res.yaml'
    neg_res.write_text('image: ok.pgm\nresolution: -0.05\norigin: [0, 0, 0]\n')
    garbage = tmp_path / 'garbage.map'
    garbage.write_bytes(bytes(range(256)) * 4)
    bad_yaml = tmp_path / 'bad.yaml'
    bad_yaml.write_text('image: [unclosed\n')
    missing_image = tmp_path / 'missing_image.yaml'
    missing_image.write_text('image: nowhere.pgm\nresolution: 1.0\norigin: [0, 0, 0]\n')
    folder = tmp_path / 'folder.yaml'
    folder.mkdir()
    text = tmp_path / 'map.txt'
    text.write_text('hello')
    m = str(tiny_map)
    ok = ('--start', '0.5', '3.5', '--goal', '4.5', '0.5')
    return {
        'start outside map': ['--map', m, '--start', '-3', '1', '--goal', '4.5', '0.5'],
        'goal outside map': ['--map', m, '--start', '0.5', '3.5', '--goal', '50', '50'],
        'start in obstacle': ['--map', m, '--start', '0.5', '2.5', '--goal', '4.5', '0.5'],
        'goal in obstacle': ['--map', m, '--start', '0.5', '3.5', '--goal', '0.5', '0.5'],
        'NaN start': ['--map', m, '--start', 'nan', '3', '--goal', '4.5', '0.5'],
        'NaN goal': ['--map', m, '--start', '0.5', '3.5', '--goal', '4.5', 'NaN'],
        'infinite goal': ['--map', m, '--start', '0.5', '3.5', '--goal', 'inf', '0.5'],
        'cells not integer': ['--map', m, '--cells', '--start', '0.5', '0', '--goal', '4', '3'],
        'cells NaN': ['--map', m, '--cells', '--start', 'nan', '0', '--goal', '4', '3'],
        'cells outside': ['--map', m, '--cells', '--start', '0', '0', '--goal', '5', '0'],
        'cells negative': ['--map', m, '--cells', '--start', '0', '-1', '--goal', '4', '3'],
        'missing file': ['--map', str(tmp_path / 'nope.yaml'), *ok],
        'missing .map file': ['--map', str(tmp_path / 'nope.map'), *ok],
        'directory as map': ['--map', str(folder), *ok],
        'unreadable binary map': ['--map', str(garbage), *ok],
        'invalid YAML': ['--map', str(bad_yaml), *ok],
        'YAML without image': ['--map', str(no_image), *ok],
        'image file missing': ['--map', str(missing_image), *ok],
        'zero resolution': ['--map', str(zero_res), *ok],
        'negative resolution': ['--map', str(neg_res), *ok],
        'unsupported extension': ['--map', str(text), *ok],
        'negative robot radius': ['--map', m, *ok, '--robot-radius', '-1'],
        'NaN safety distance': ['--map', m, *ok, '--safety-distance', 'nan'],
        'goal inside inflation': ['--map', m, '--start', '0.5', '3.5', '--goal', '3.5', '0.5',
                                  '--robot-radius', '1.0'],
    }


BAD_CASE_NAMES = [
    'start outside map', 'goal outside map', 'start in obstacle', 'goal in obstacle',
    'NaN start', 'NaN goal', 'infinite goal', 'cells not integer', 'cells NaN', 'cells outside',
    'cells negative', 'missing file', 'missing .map file', 'directory as map',
    'unreadable binary map', 'invalid YAML', 'YAML without image', 'image file missing',
    'zero resolution', 'negative resolution', 'unsupported extension', 'negative robot radius',
    'NaN safety distance', 'goal inside inflation']


@pytest.mark.parametrize('case', BAD_CASE_NAMES)
def test_bad_input_is_exit_2_with_one_line(capsys, tmp_path, tiny_map, case):
    argv = _bad_cases(tmp_path, tiny_map)[case]
    status, out, err = run_cli(capsys, 'plan', *argv)
    assert status == 2, (case, out, err)
    assert out == ''
    assert_one_line_error(err)


@pytest.mark.parametrize('case', ['NaN start', 'YAML without image', 'cells outside',
                                  'missing file'])
def test_bad_input_with_json_still_prints_one_object(capsys, tmp_path, tiny_map, case):
    argv = _bad_cases(tmp_path, tiny_map)[case]
    status, out, err = run_cli(capsys, 'plan', *argv, '--json')
    assert status == 2
    doc = json.loads(out)
    assert set(doc) == JSON_KEYS
    assert doc['found'] is False and doc['path'] == []
    assert isinstance(doc['error'], str) and doc['error'] in err
    assert_one_line_error(err)


@pytest.mark.parametrize('argv', [
    ['--start', '1'],
    ['--start', 'abc', '1', '--goal', '2', '2'],
    ['--start', '1', '1', '--goal', '2', '2', '--algorithm', 'bfs'],
    ['--start', '1', '1', '--goal', '2', '2', '--neighbourhood', '6'],
])
def test_argument_errors_are_exit_2_without_traceback(capsys, tiny_map, argv):
    status, _, err = run_cli(capsys, 'plan', '--map', str(tiny_map), *argv)
    assert status == 2
    assert 'Traceback' not in err and 'error:' in err


# -- --plot -------------------------------------------------------------------

def test_plot_writes_a_png(capsys, tmp_path):
    png = tmp_path / 'plan.png'
    status, _, err = run_cli(capsys, 'plan', '--map', PAPER_YAML, '--start', '1.5', '1.5',
                             '--goal', '19.5', '19.5', '--plot', str(png))
    assert status == 0, err
    assert png.read_bytes()[:8] == b'\x89PNG\r\n\x1a\n'


def test_plot_into_a_missing_folder_creates_it(capsys, tmp_path):
    png = tmp_path / 'no' / 'such' / 'plan.png'
    status, _, err = run_cli(capsys, 'plan', '--map', PAPER_YAML, '--start', '1.5', '1.5',
                             '--goal', '19.5', '19.5', '--plot', str(png))
    assert status == 0, err
    assert png.read_bytes()[:8] == b'\x89PNG\r\n\x1a\n'


def test_plot_below_a_file_is_refused_before_planning(capsys, tmp_path):
    (tmp_path / 'taken').write_text('a file')
    status, out, err = run_cli(capsys, 'plan', '--map', PAPER_YAML, '--start', '1.5', '1.5',
                               '--goal', '19.5', '19.5', '--plot',
                               str(tmp_path / 'taken' / 'plan.png'))
    assert status == 2 and out == ''  # nothing planned
    assert_one_line_error(err)
    assert 'is not a folder' in err
