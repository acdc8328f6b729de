"""Tests of ``fusion-planner bench movingai`` (fusion_planner.bench.movingai)."""

import json
from types import SimpleNamespace

import pytest

from fusion_planner.bench import movingai
from fusion_planner.cli.main import main
from fusion_planner.core.errors import InvalidInput

#: A 5 x 4 map: in file coordinates (x right, y down) the cells (1, 1) and
#: (2, 1) are walls, and (0, 3) is a wall.
TINY_MAP = 'type octile\nheight 4\nwidth 5\nmap\n.....\n.@@..\n.....\n@....\n'

#: (start x, start y, goal x, goal y, optimal length) of the tiny map. The
#: third row needs three steps: the diagonal (0, 1) -> (1, 2) would cut the
#: corner of the wall at (1, 1).
TINY_ROWS = ((0, 0, 4, 0, 4.0), (0, 2, 4, 2, 4.0), (0, 0, 1, 2, 3.0), (4, 3, 4, 3, 0.0))


def _write_folder(folder, rows=TINY_ROWS, name='tiny'):
    (folder / f'{name}.map').write_text(TINY_MAP)
    lines = ['version 1'] + [
        f'0\t{name}.map\t5\t4\t{sx}\t{sy}\t{gx}\t{gy}\t{length:.8f}'
        for sx, sy, gx, gy, length in rows]
    (folder / f'{name}.map.scen').write_text('\n'.join(lines) + '\n')
    return folder


def _run(capsys, *argv):
    status = main(['bench', 'movingai', *argv])
    out, err = capsys.readouterr()
    return status, out, err


# -- sampling ----------------------------------------------------------------

def _buckets(*counts):
    return [SimpleNamespace(bucket=b) for b, n in enumerate(counts) for _ in range(n)]


def test_sample_rows_spreads_over_the_buckets_deterministically():
    rows = _buckets(*([10] * 50))
    chosen = movingai.sample_rows(rows, 25)
    assert len(chosen) == len(set(chosen)) == 25
    assert chosen == movingai.sample_rows(rows, 25)
    assert sorted({rows[i].bucket for i in chosen}) == list(range(0, 50, 2))


def test_sample_rows_orders_by_bucket_and_keeps_all_when_asked():
    rows = [SimpleNamespace(bucket=b) for b in (2, 0, 1, 0)]
    assert movingai.sample_rows(rows) == [1, 3, 2, 0]
    assert movingai.sample_rows(rows, 10) == [1, 3, 2, 0]
    with pytest.raises(InvalidInput):
        movingai.sample_rows(rows, 0)


# -- the command ---------------------------------------------------------------

def test_tiny_folder_all_algorithms_exact(tmp_path, capsys):
    folder = _write_folder(tmp_path)
    status, out, err = _run(capsys, '--maps', str(folder), '--json', '--no-progress')
    assert status == 0, err
    report = json.loads(out)
    by_algorithm = {s['algorithm']: s for s in report['summaries']}
    assert set(by_algorithm) == {'astar', 'dijkstra', 'improved'}
    for name in ('astar', 'dijkstra'):
        assert by_algorithm[name]['rows'] == by_algorithm[name]['exact'] == len(TINY_ROWS)
        assert by_algorithm[name]['ratio_max'] == pytest.approx(1.0)
    improved = by_algorithm['improved']
    assert improved['found'] == len(TINY_ROWS) and improved['exact'] is None
    assert improved['ratio_median'] >= 1.0 - 1e-12
    assert improved['expansion_ratio'] > 0
    assert report['failures'] == []


def test_a_wrong_optimal_length_fails_the_run(tmp_path, capsys):
    rows = TINY_ROWS + ((0, 0, 1, 2, 1.0 + 2 ** 0.5),)  # the corner-cutting length
    folder = _write_folder(tmp_path, rows)
    status, out, _ = _run(capsys, '--maps', str(folder), '--algorithms', 'astar', '--no-progress')
    assert status == 1
    assert 'failed row' in out and 'line 6' in out
    assert 'got 3.00000000' in out


def test_text_table_and_progress(tmp_path, capsys):
    folder = _write_folder(tmp_path)
    _write_folder(tmp_path, name='other')
    status, out, err = _run(capsys, '--maps', str(folder), '--rows', '2')
    assert status == 0
    for word in ('tiny', 'other', 'ALL', 'A*-8', 'Dijkstra', 'improved A*', 'exp/A*-8'):
        assert word in out
    assert '4/4 rows' in err and 'ETA' in err


def test_only_and_rows_select(tmp_path, capsys):
    _write_folder(tmp_path)
    _write_folder(tmp_path, name='other')
    status, out, _ = _run(capsys, '--maps', str(tmp_path), '--only', 'oth', '--rows', '3',
                          '--algorithms', 'improved', '--json', '--no-progress')
    assert status == 0
    summaries = json.loads(out)['summaries']
    assert [(s['map'], s['algorithm'], s['rows']) for s in summaries] == [
        ('other', 'improved', 3)]


def test_parallel_jobs_give_the_same_results(tmp_path, capsys):
    folder = _write_folder(tmp_path)
    outputs = []
    for jobs in ('1', '2'):
        status, out, _ = _run(capsys, '--maps', str(folder), '--json', '--no-progress',
                              '--jobs', jobs)
        assert status == 0
        outputs.append([{k: v for k, v in s.items() if not k.startswith('time')}
                        for s in json.loads(out)['summaries']])
    assert outputs[0] == outputs[1]


@pytest.mark.parametrize('argv, message', [
    (('--maps', '/nonexistent/movingai'), 'not found'),
    (('--rows', '0'), '--rows'),
    (('--rows', 'many'), '--rows'),
    (('--only', 'no-such-map'), 'matches no map'),
    (('--jobs', '0'), '--jobs'),
])
def test_bad_input_exits_2_with_one_line(tmp_path, capsys, argv, message):
    _write_folder(tmp_path)
    if argv[0] != '--maps':
        argv = ('--maps', str(tmp_path)) + argv
    status, _, err = _run(capsys, *argv, '--no-progress')
    assert status == 2
    assert message in err and 'Traceback' not in err
    assert len(err.strip().splitlines()) == 1


def test_missing_default_folder_says_where_to_get_the_data(monkeypatch, tmp_path, capsys):
    monkeypatch.setenv(movingai.DATA_ENV, str(tmp_path / 'absent'))
    status, _, err = _run(capsys, '--no-progress')
    assert status == 2 and len(err.strip().splitlines()) == 1
    assert movingai.DATA_URL in err and str(tmp_path / 'absent') in err
    assert '--maps DIR' in err and movingai.DATA_ENV in err


def test_missing_map_beside_a_scenario_file(tmp_path, capsys):
    _write_folder(tmp_path)
    (tmp_path / 'tiny.map').unlink()
    status, _, err = _run(capsys, '--maps', str(tmp_path), '--no-progress')
    assert status == 2 and 'tiny.map' in err


def test_bench_refine_without_the_maps_says_where_to_get_them(monkeypatch, tmp_path, capsys):
    monkeypatch.setenv(movingai.DATA_ENV, str(tmp_path / 'absent'))
    status = main(['bench', 'refine', '--repeats', '1'])
    out, err = capsys.readouterr()
    assert status == 2 and out == ''  # refused before refining anything
    assert len(err.strip().splitlines()) == 1
    assert movingai.DATA_URL in err and '--quick' in err
