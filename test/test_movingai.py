"""Optimality on the MovingAI grid benchmark (../shared/benchmarks/movingai).

With radius 0, safety distance 0 and no refinement, A* (8-neighbourhood,
octile) and Dijkstra must return exactly each row's ``optimal_length`` (the
octile length without corner cutting, rounded to 8 decimals by the file),
and the improved A* must find a path on every row, never shorter than the
optimum. The rows checked by all three: every row of arena2 (the small
map) and 273 rows spread evenly over the buckets of each 512 x 512 map,
2,002 rows in all. ``fusion-planner bench movingai`` runs every row.
"""

import functools
import statistics

import pytest

from fusion_planner.bench.movingai import OPTIMAL_TOLERANCE, PreparedMap, policies, sample_rows
from fusion_planner.core.map_files import read_scenarios
from fusion_planner.core.global_planning.planner import PlannerConfig

#: Maps of the benchmark folder (file stems).
MAPS = ('arena2', 'Berlin_0_512', 'maze512-1-0', 'random512-10-0', '8room_000')
#: Rows checked per map (None: every row).
ROWS = {'arena2': None, 'Berlin_0_512': 273, 'maze512-1-0': 273, 'random512-10-0': 273,
        '8room_000': 273}
#: Rows checked per map with Dijkstra, the costliest part of this file
#: (about 60% of its time). LIGHT_ROWS here would check 1,456 rows in about
#: 60% less Dijkstra time, below the issue's 2,000 (see MIN_ROWS).
DIJKSTRA_ROWS = ROWS
#: Every third of :data:`ROWS` on the open 512 x 512 maps (91 = 273 / 3).
LIGHT_ROWS = {'arena2': None, 'Berlin_0_512': 91, 'maze512-1-0': 273,
              'random512-10-0': 91, '8room_000': 91}
#: At least this many rows are checked with A*-8 and Dijkstra (the issue).
MIN_ROWS = 2000
#: Loose upper bound on the improved A*'s length ratio to the optimum.
IMPROVED_MAX_RATIO = 1.5
#: Slack for "never shorter than the optimum": the file rounds to 8 decimals.
RATIO_SLACK = 1e-9


@functools.lru_cache(maxsize=None)
def _prepared(folder, name):
    """The map (loaded once per test session) and all its scenario rows."""
    return PreparedMap(folder / f'{name}.map'), read_scenarios(folder / f'{name}.map.scen')


def _rows(folder, name, counts):
    """The selected rows of a map, spread evenly over the buckets."""
    prepared, rows = _prepared(folder, name)
    return prepared, [rows[i] for i in sample_rows(rows, counts[name])]


def _mismatches(prepared, rows, policy):
    """Rows whose length differs from optimal_length, as readable strings."""
    bad = []
    for row in rows:
        outcome = prepared.solve(row, policy)
        if not outcome.found or abs(outcome.length - row.optimal_length) > OPTIMAL_TOLERANCE:
            got = f'{outcome.length:.8f}' if outcome.found else f'no path ({outcome.error})'
            bad.append(f'start {(row.start_col, row.start_row)} '
                       f'goal {(row.goal_col, row.goal_row)} '
                       f'optimal {row.optimal_length:.8f} got {got}')
    return bad


def test_selection_spans_all_maps_and_buckets(benchmark_dir):
    """>= 2,000 rows over all five maps for A*-8 and for Dijkstra, each map
    from its lowest to its highest buckets."""
    totals = {'astar': 0, 'dijkstra': 0}
    for name in MAPS:
        _, all_rows = _prepared(benchmark_dir, name)
        _, rows = _rows(benchmark_dir, name, ROWS)
        _, dijkstra_rows = _rows(benchmark_dir, name, DIJKSTRA_ROWS)
        _, light_rows = _rows(benchmark_dir, name, LIGHT_ROWS)
        totals['astar'] += len(rows)
        totals['dijkstra'] += len(dijkstra_rows)
        buckets = [row.bucket for row in all_rows]
        for selection in (rows, dijkstra_rows, light_rows):
            chosen = [row.bucket for row in selection]
            assert min(chosen) == min(buckets)
            assert max(chosen) >= 0.98 * max(buckets)
            assert len(set(map(id, selection))) == len(selection)
        assert set(map(id, light_rows)) <= set(map(id, rows))
    assert min(totals.values()) >= MIN_ROWS, totals


@pytest.mark.parametrize('algorithm', ('astar', 'jps'))
@pytest.mark.parametrize('name', MAPS)
def test_astar8_returns_optimal_length(benchmark_dir, name, algorithm):
    """Cell by cell and with jump points."""
    prepared, rows = _rows(benchmark_dir, name, ROWS)
    bad = _mismatches(prepared, rows, policies([algorithm])[algorithm])
    assert not bad, (f'A*-8 ({algorithm}) missed optimal_length on {len(bad)}/{len(rows)} rows '
                     f'of {name}: ' + '; '.join(bad[:5]))


@pytest.mark.parametrize('name', MAPS)
def test_dijkstra_returns_optimal_length(benchmark_dir, name):
    prepared, rows = _rows(benchmark_dir, name, DIJKSTRA_ROWS)
    bad = _mismatches(prepared, rows, policies(['dijkstra'])['dijkstra'])
    assert not bad, (f'Dijkstra missed optimal_length on {len(bad)}/{len(rows)} rows of '
                     f'{name}: ' + '; '.join(bad[:5]))


@pytest.mark.parametrize('name', MAPS)
def test_improved_astar_finds_near_optimal_paths(benchmark_dir, name, record_property):
    """The default improved A* (PlannerConfig, no refinement) finds a path on
    every row, never shorter than the optimum; its median and largest length
    ratio are recorded (``-rP`` or the junit XML shows them)."""
    prepared, rows = _rows(benchmark_dir, name, ROWS)
    policy = PlannerConfig(refine=False).policy()
    ratios, missing = [], []
    for row in rows:
        outcome = prepared.solve(row, policy)
        if not outcome.found:
            missing.append(f'start {(row.start_col, row.start_row)} goal '
                           f'{(row.goal_col, row.goal_row)}: {outcome.error}')
            continue
        ratios.append(outcome.length / row.optimal_length if row.optimal_length > 0 else 1.0)
    assert not missing, f'improved A* found no path on {len(missing)} rows of {name}: ' + (
        '; '.join(missing[:5]))
    median, worst = statistics.median(ratios), max(ratios)
    record_property('improved_ratio_median', median)
    record_property('improved_ratio_max', worst)
    print(f'{name}: improved A* on {len(rows)} rows, length ratio median {median:.5f} '
          f'max {worst:.5f}')
    assert min(ratios) >= 1.0 - RATIO_SLACK, 'improved A* returned a path shorter than optimal'
    assert worst <= IMPROVED_MAX_RATIO
