"""``fusion-planner bench node``: a node in a subprocess answers goals on a small floor."""

import contextlib
import io
import json

from fusion_planner.bench import node_latency
from fusion_planner.cli.main import main


def test_small_floor_latency_run():
    out = io.StringIO()
    with contextlib.redirect_stdout(out):
        status = main(['bench', 'node', '--seeds', '3', '--goals', '2', '--side-m', '40',
                       '--min-distance', '15', '--json'])
    assert status == 0
    report = json.loads(out.getvalue())
    (floor,) = report['floors']
    assert floor['map_wait_s'] > 0 and floor['peak_rss_mb'] > 0
    assert len(floor['goals']) == 2
    for goal in floor['goals']:
        assert goal['latency_s'] > 0
        assert goal['path_length_m'] >= goal['distance_m'] - 1e-6


def test_far_goals_are_reachable_and_far():
    from scipy import ndimage
    from fusion_planner.bench.building_map import BuildingSpec, building_map
    from fusion_planner.core.grid import GridMap
    spec = BuildingSpec(side_m=40.0)
    free = GridMap(building_map(spec, 1), spec.resolution).traversable(0.2)
    start, goals = node_latency.far_goals(free, 4, 300, seed=5)
    labels, _ = ndimage.label(free)
    assert len(goals) == 4
    for goal in goals:
        assert labels[goal] == labels[start] != 0
        assert ((goal[0] - start[0]) ** 2 + (goal[1] - start[1]) ** 2) ** 0.5 >= 300


def test_a_node_that_cannot_start_is_one_error_line(monkeypatch, capsys):
    """A parameter the node refuses: it exits at start; the bench says so in one line, exit 1."""
    import argparse
    monkeypatch.setattr(node_latency, 'MAP_TIMEOUT_S', 30.0)
    args = argparse.Namespace(seeds=[3], goals=1, algorithm='no-such-algorithm', side_m=40.0,
                              min_distance=15.0, json=False)
    status = node_latency.run(args)
    err = capsys.readouterr().err
    assert status == 1
    assert err.startswith('error: floor 3: the node did not accept the map')
    assert 'exited with status' in err and 'Traceback' not in err
