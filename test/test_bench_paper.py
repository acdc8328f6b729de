"""``fusion-planner bench paper``: runs, and its figures agree with each other."""

import json
import math

import numpy as np
import pytest

from conftest import REPO
from fusion_planner.bench import paper, paper_map
from fusion_planner.cli.bench_command import TARGETS
from fusion_planner.cli.main import main
from fusion_planner.core.map_files import load_map
from fusion_planner.core.global_planning.planner import PlannerConfig

PAPER_YAML = REPO / 'config' / 'maps' / 'paper.yaml'


@pytest.fixture(scope='module')
def rows():
    grid = paper_map.paper_grid()
    measured, _ = paper.measure(grid, paper_map.START_XY, paper_map.GOAL_XY,
                                PlannerConfig(), repeats=1)
    return {row.name: row for row in measured}


def test_bundled_map_matches_its_generator():
    grid = load_map(PAPER_YAML)
    assert grid.shape == (20, 20) and grid.resolution == 1.0
    assert np.array_equal(grid.occupied, paper_map.build_occupancy())
    assert not grid.occupied[paper_map.START_CELL] and not grid.occupied[paper_map.GOAL_CELL]
    assert paper_map.find_paper_map() is not None


def test_docs_show_the_bundled_map():
    text = (REPO / 'docs' / 'ALGORITHM.md').read_text()
    block = text.split('<!-- paper-map')[1].split('```')[1].strip().splitlines()
    assert [line.replace('S', '.').replace('G', '.') for line in block] == \
        list(paper_map.PAPER_MAP_ROWS)
    start_row, start_col = paper_map.START_CELL
    goal_row, goal_col = paper_map.GOAL_CELL
    assert block[19 - start_row][start_col] == 'S' and block[19 - goal_row][goal_col] == 'G'


def test_every_case_is_measured(rows):
    assert list(rows) == [case.name for case in paper.CASES]
    for row in rows.values():
        assert row.length_cells > 0 and row.search_nodes > 0 and row.time_ms > 0
        assert 2 <= row.key_points <= row.grid_nodes


def test_optimal_planners_agree(rows):
    # Dijkstra and A*-8 (octile, admissible) both return the 8-connected optimum.
    assert rows['astar8'].length_cells == pytest.approx(rows['dijkstra'].length_cells, abs=1e-9)
    assert rows['astar8'].search_nodes < rows['dijkstra'].search_nodes
    # A*-4 is a 4-connected optimum: at least the Manhattan distance 18 + 18.
    assert rows['astar4'].length_cells >= 36.0 - 1e-9
    # Nothing beats the straight line.
    for row in rows.values():
        assert row.length_cells >= 18 * math.sqrt(2) - 1e-9


def test_improved_astar_claims(rows):
    # Fewer expansions than A*-8 at a length within 2 % of optimal (section 3.1).
    assert rows['improved'].search_nodes < rows['astar8'].search_nodes
    assert rows['improved'].length_cells <= 1.02 * rows['dijkstra'].length_cells + 1e-9


def test_refinement_claims(rows):
    raw, refined = rows['improved'], rows['improved_refined']
    assert refined.key_points < raw.key_points
    assert refined.turning_deg <= raw.turning_deg + 1e-9
    assert refined.length_cells <= raw.length_cells + 1e-9
    assert refined.search_nodes == raw.search_nodes  # refinement does not search
    assert refined.min_clearance_m > 0


def test_relative_changes_follow_the_rows(rows):
    changes = paper.relative_changes(list(rows.values()))
    assert len(changes) == len(paper.PAPER_CHANGES)
    for change in changes:
        new = rows[change['case']]
        old = rows[change['baseline']]
        attribute = 'time_ms' if change['metric'] == 'time' else change['metric']
        before, after = getattr(old, attribute), getattr(new, attribute)
        expected = 100 * (after - before) / before
        assert change['ours_pct'] == pytest.approx(expected)


def test_cli_json_and_plots(capsys, tmp_path):
    status = main(['bench', 'paper', '--repeats', '1', '--json', '--plot', str(tmp_path / 'figs')])
    out, err = capsys.readouterr()
    assert status == 0, err
    doc = json.loads(out)
    assert [row['name'] for row in doc['rows']] == [case.name for case in paper.CASES]
    for row in doc['rows']:
        assert set(row['paper']) == {'length_cells', 'search_nodes', 'key_points', 'time_s',
                                     'turning_deg'}
    assert {c['metric'] for c in doc['changes']} >= {'search_nodes', 'turning_deg', 'key_points'}
    figures = sorted(p.name for p in (tmp_path / 'figs').iterdir())
    assert figures == sorted(f'paper_{case.name}.png' for case in paper.CASES)


def test_cli_text_table(capsys):
    status = main(['bench', 'paper', '--repeats', '1'])
    out, _ = capsys.readouterr()
    assert status == 0
    for case in paper.CASES:
        assert case.label in out
    assert '-24.26%' in out  # the paper's improved-vs-A*-8 expansion change, quoted


def test_cli_no_path_is_exit_1(capsys, tmp_path):
    walled = tmp_path / 'walled.map'
    walled.write_text('type octile\nheight 3\nwidth 5\nmap\n..@..\n..@..\n..@..\n')
    status = main(['bench', 'paper', '--map', str(walled), '--start', '0.5', '0.5',
                   '--goal', '4.5', '0.5', '--repeats', '1'])
    _, err = capsys.readouterr()
    assert status == 1
    assert err.startswith('error: ') and 'Traceback' not in err


def test_cli_bad_input_is_exit_2(capsys, tmp_path):
    status = main(['bench', 'paper', '--map', str(tmp_path / 'nope.yaml'), '--repeats', '1'])
    _, err = capsys.readouterr()
    assert status == 2 and 'Traceback' not in err
    status = main(['bench', 'paper', '--repeats', '0'])
    _, err = capsys.readouterr()
    assert status == 2 and 'Traceback' not in err


def test_targets_registry_is_importable():
    import importlib

    for module_name in TARGETS.values():
        module = importlib.import_module(module_name)
        assert callable(module.add_arguments) and callable(module.run)
