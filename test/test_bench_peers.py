"""Tests of ``fusion-planner bench peers`` (fusion_planner.bench.peers).

A quick run on tiny maps checks the output structure and that our A*-8
length equals the optimum computed here with scipy's Dijkstra on a graph
built from the move rules alone. No test asserts a time.
"""

import json
import math

import numpy as np
import pytest
from scipy.sparse import csr_matrix
from scipy.sparse.csgraph import dijkstra

from fusion_planner.bench import peers
from fusion_planner.cli.bench_command import TARGETS
from fusion_planner.cli.main import main
from fusion_planner.core.grid import GridMap

#: Slack of length comparisons [cells]: sums of 1 and sqrt 2 in another order.
LENGTH_TOL = 1e-6


def _independent_optimum(free, start, goal, cut_corners=False):
    """Shortest 8-connected path length [cells] by scipy, from the rules:
    a step enters a free cell; a diagonal step without corner cutting also
    needs both cells beside it free."""
    height, width = free.shape
    src, dst, weight = [], [], []
    for r in range(height):
        for c in range(width):
            if not free[r, c]:
                continue
            for dr in (-1, 0, 1):
                for dc in (-1, 0, 1):
                    rr, cc = r + dr, c + dc
                    if (dr, dc) == (0, 0) or not (0 <= rr < height and 0 <= cc < width):
                        continue
                    if not free[rr, cc]:
                        continue
                    if dr and dc and not cut_corners and not (free[rr, c] and free[r, cc]):
                        continue
                    src.append(r * width + c)
                    dst.append(rr * width + cc)
                    weight.append(math.hypot(dr, dc))
    graph = csr_matrix((weight, (src, dst)), shape=(height * width, height * width))
    return float(dijkstra(graph, indices=start[0] * width + start[1])[goal[0] * width + goal[1]])


@pytest.fixture(scope='module')
def quick_random(tmp_path_factory):
    """One quick run of the random suite, as parsed JSON."""
    import contextlib
    import io
    out = io.StringIO()
    with contextlib.redirect_stdout(out):
        status = main(['bench', 'peers', '--quick', '--suites', 'random', '--json',
                       '--no-progress', '--planners', 'dijkstra', 'astar', 'jps', 'improved',
                       'improved_refined', 'pyastar2d', 'tcod', 'pathfinding', 'networkx'])
    return status, json.loads(out.getvalue())


def test_target_is_registered():
    assert TARGETS['peers'] == 'fusion_planner.bench.peers'


def test_quick_run_structure(quick_random):
    status, report = quick_random
    assert status == 0
    assert set(report) >= {'suites', 'planners', 'notes', 'scenarios', 'rows', 'targets',
                           'machine'}
    assert [s['suite'] for s in report['scenarios']] == ['random', 'random']
    side = peers.QUICK_RANDOM_SIDE
    assert [s['name'] for s in report['scenarios']] == [f'random{side}', f'random{side}-pairs']
    ran = {row['planner'] for row in report['rows']}
    assert set(peers.OURS) <= ran
    assert {'pyastar2d', 'tcod', 'pathfinding', 'networkx'} <= ran  # asked for: all ran
    for row in report['rows']:
        assert row['pairs'] == row['found'] == row['valid'] >= 1
        assert row['cpu_median_ms'] >= 0 and row['time_median_ms'] >= 0
        assert row['ratio_median'] <= row['ratio_max']
        if row['planner'] != 'improved_refined':  # refined paths are any-angle
            assert row['ratio_median'] >= 1.0 - LENGTH_TOL
    for verdict in report['targets']:
        assert verdict['status'] in ('met', 'NOT met', 'info') and verdict['detail']


def test_astar_length_equals_an_independent_optimum(quick_random):
    _, report = quick_random
    side = peers.QUICK_RANDOM_SIDE
    free = ~peers.random_map(side, peers.RANDOM_DENSITY, peers.RANDOM_SEED)
    expected = _independent_optimum(free, (0, 0), (side - 1, side - 1))
    assert math.isfinite(expected)
    scenario = report['scenarios'][0]
    assert scenario['optimal'][0] == pytest.approx(expected, abs=LENGTH_TOL)
    rows = {row['planner']: row for row in report['rows'] if row['scenario'] == f'random{side}'}
    for name in ('astar', 'dijkstra'):
        assert rows[name]['ratio_max'] == pytest.approx(1.0, abs=LENGTH_TOL)
        assert rows[name]['optimal_exact'] == rows[name]['found']
    assert rows['improved']['ratio_median'] >= 1.0 - LENGTH_TOL


def test_cutting_optimum_matches_scipy():
    free = ~peers.random_map(24, 0.3, 5)
    expected = _independent_optimum(free, (0, 0), (23, 23), cut_corners=True)
    got = peers.cutting_optimum(free, (0, 0), (23, 23))
    assert got == pytest.approx(expected, rel=2e-5)
    assert got <= _independent_optimum(free, (0, 0), (23, 23)) + LENGTH_TOL


def test_a_missing_peer_stops_the_run_before_it_starts(monkeypatch, capsys):
    monkeypatch.setitem(peers.PEER_MODULES, 'pyastar2d', 'fusion_planner_no_such_peer')
    status = main(['bench', 'peers', '--quick', '--suites', 'random', '--no-progress',
                   '--planners', 'astar', 'pyastar2d'])
    out, err = capsys.readouterr()
    assert status == 2 and out == ''
    assert err.count('\n') == 1 and "pip install 'fusion_planner[bench]'" in err
    assert 'fusion_planner_no_such_peer' in err and '--planners' in err


def test_without_movingai_maps_the_default_suites_run_the_others(monkeypatch, tmp_path, capsys):
    monkeypatch.setenv(peers.movingai_bench.DATA_ENV, str(tmp_path / 'absent'))
    status = main(['bench', 'peers', '--quick', '--no-progress', '--json', '--planners', 'astar'])
    report = json.loads(capsys.readouterr().out)
    assert status == 0
    assert report['suites'] == ['random', 'nav2']
    assert any('movingai suite left out' in note and str(tmp_path / 'absent') in note
               for note in report['notes'])


def test_movingai_asked_for_by_name_without_maps_is_bad_input(monkeypatch, tmp_path, capsys):
    monkeypatch.setenv(peers.movingai_bench.DATA_ENV, str(tmp_path / 'absent'))
    status = main(['bench', 'peers', '--quick', '--no-progress', '--suites', 'movingai',
                   '--planners', 'astar'])
    out, err = capsys.readouterr()
    assert status == 2 and out == ''
    assert err.count('\n') == 1 and 'movingai.com' in err


def test_valid_path_checks_the_corner_rule():
    free = np.ones((3, 3), bool)
    free[0, 1] = False
    diagonal = [(0, 0), (1, 1)]
    assert not peers.is_valid_path(diagonal, (0, 0), (1, 1), free, cuts_corners=False)
    assert peers.is_valid_path(diagonal, (0, 0), (1, 1), free, cuts_corners=True)
    assert peers.is_valid_path([(0, 0), (1, 0), (1, 1)], (0, 0), (1, 1), free, False)
    assert not peers.is_valid_path([(0, 0), (0, 1)], (0, 0), (0, 1), free, True)  # blocked
    assert not peers.is_valid_path([(0, 0), (2, 2)], (0, 0), (2, 2), free, True)  # a jump
    assert not peers.is_valid_path([(0, 0), (1, 0)], (0, 0), (1, 1), free, True)  # wrong end


def test_nav2_pairs_follow_the_protocol():
    side, resolution = 120, 0.05
    occupied = peers.nav2_map(side, 0.15, resolution, 33)
    assert 0.15 <= occupied.mean() < 0.25
    traversable = GridMap(occupied, resolution).traversable(peers.NAV2_ROBOT_RADIUS)
    buffer = 10
    pairs = peers.nav2_pairs(traversable, 5, resolution, 33, buffer, 3.0,
                             reachable=lambda start, goal: True)
    assert len(pairs) == 5
    for start, goal in pairs:
        assert traversable[start] and traversable[goal]
        assert math.dist(start, goal) * resolution > 3.0
        for cell in (start, goal):
            assert all(buffer <= v <= side - buffer for v in cell)


def test_quick_building_run_has_our_planners_and_the_compiled_peers_only():
    import contextlib
    import io
    out = io.StringIO()
    with contextlib.redirect_stdout(out):
        status = main(['bench', 'peers', '--quick', '--suites', 'building', '--json',
                       '--no-progress', '--planners', 'astar', 'improved', 'pyastar2d', 'tcod',
                       'pathfinding'])
    report = json.loads(out.getvalue())
    assert status == 0
    assert [s['suite'] for s in report['scenarios']] == ['building']
    ran = {row['planner'] for row in report['rows']}
    assert 'pathfinding' not in ran and {'astar', 'improved'} <= ran
    for row in report['rows']:
        assert row['pairs'] == row['found'] == row['valid'] == 1
    rows = {row['planner']: row for row in report['rows']}
    assert rows['astar']['optimal_exact'] == 1
    targets = [v['target'] for v in report['targets']]
    assert any('A*-8 <= 2x pyastar2d' in t for t in targets if 'pyastar2d' in ran)
