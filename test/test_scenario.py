"""Tests of fusion_planner.core.simulation.scenario: the YAML schema, its validation, random scenarios."""

import math
import pathlib

import numpy as np
import pytest
import yaml

from fusion_planner.core.errors import InvalidInput, MapError
from fusion_planner.core.grid import GridMap
from fusion_planner.core.map_files import save_map_server
from fusion_planner.core.global_planning.planner import GlobalPlanner, PlannerConfig
from fusion_planner.core.simulation.scenario import (
    RandomScenarioConfig, ScenarioError, load_scenario, random_scenario)
from fusion_planner.core.simulation.world import (
    BounceMotion, Circle, RandomWalkMotion, Rectangle, StaticScene, WaypointMotion)

SCENARIOS = pathlib.Path(__file__).resolve().parent.parent / 'config' / 'scenarios'
SHIPPED = ('fig5a', 'fig5b', 'fig5c', 'fig6a', 'fig6b', 'warehouse', 'demo')


def base_doc():
    return {
        'map': 'room.yaml',
        'seed': 3,
        'robot': {'start': [1.0, 1.0, 0.0], 'radius': 0.2, 'max_speed': 0.6},
        'goal': [8.0, 6.0],
        'unknown_obstacles': [{'circle': {'center': [5.0, 3.0], 'radius': 0.4}},
                              {'rectangle': {'min': [6.0, 5.0], 'max': [6.5, 5.5]}}],
        'moving_obstacles': [
            {'radius': 0.25, 'model': 'bounce', 'position': [3.0, 5.0], 'velocity': [0.1, 0.2]},
            {'radius': 0.25, 'model': 'waypoints', 'points': [[2.0, 6.0], [7.0, 6.5]], 'speed': 0.2},
            {'radius': 0.25, 'model': 'random_walk', 'position': [8.0, 2.0], 'speed': 0.2,
             'turn_std': 0.5}],
        'planner': {'safety_distance': 0.2},
        'limits': {'time_limit_s': 30.0, 'dt': 0.1},
        'scan': {'beams': 90, 'range_max': 5.0},
    }


@pytest.fixture
def room(tmp_path):
    """A 10 x 8 m room with a block at x 4-4.5, y 0-2 saved as a map_server map."""
    occ = np.zeros((80, 100), bool)
    occ[0:20, 40:45] = True
    save_map_server(GridMap(occ, 0.1), tmp_path / 'room.yaml')
    return tmp_path


def write(folder, doc, name='s.yaml'):
    path = folder / name
    path.write_text(yaml.safe_dump(doc), encoding='utf-8')
    return path


def error_of(path):
    with pytest.raises(ScenarioError) as info:
        load_scenario(path)
    message = str(info.value)
    assert '\n' not in message
    assert str(path) in message
    return message


# -- valid files -------------------------------------------------------------------

def test_a_full_scenario_loads(room):
    s = load_scenario(write(room, base_doc()))
    assert s.name == 's' and s.seed == 3
    assert s.start == (1.0, 1.0, 0.0) and s.goal == (8.0, 6.0)
    assert s.robot.radius == 0.2 and s.robot.max_speed == 0.6 and s.robot.max_omega == 2.0
    assert [type(o) for o in s.unknown_obstacles] == [Circle, Rectangle]
    motions = [type(m.motion) for m in s.moving_obstacles]
    assert motions == [BounceMotion, WaypointMotion, RandomWalkMotion]
    assert s.planner.robot_radius == 0.2 and s.planner.safety_distance == 0.2
    assert s.limits.time_limit_s == 30.0 and s.limits.max_collisions == 10
    assert s.scan.beams == 90 and s.scan.fov == pytest.approx(2 * math.pi)
    assert s.grid.shape == (80, 100)
    assert pathlib.Path(s.map_path) == (room / 'room.yaml').resolve()
    assert s.perception == 'scan'
    assert load_scenario(write(room, {**base_doc(), 'perception': 'ideal'})).perception == 'ideal'


def test_map_path_is_relative_to_the_scenario_file(room):
    sub = room / 'nested'
    sub.mkdir()
    doc = base_doc()
    doc['map'] = '../room.yaml'
    assert load_scenario(write(sub, doc)).grid.shape == (80, 100)


@pytest.mark.parametrize('name', SHIPPED)
def test_shipped_scenarios_load(name):
    s = load_scenario(SCENARIOS / f'{name}.yaml')
    assert s.name == name
    top = s.robot.max_speed
    assert all(m.top_speed() < 0.5 * top for m in s.moving_obstacles)


def test_true_grid_adds_the_unknown_obstacles(room):
    s = load_scenario(write(room, base_doc()))
    truth = s.true_grid()
    assert truth.occupied.sum() > s.grid.occupied.sum()
    assert truth.occupied[tuple(s.grid.cell_of(np.array([5.0, 3.0])))]
    assert not s.grid.occupied[tuple(s.grid.cell_of(np.array([5.0, 3.0])))]


# -- invalid files: one sentence naming the file and the key ------------------------------

@pytest.mark.parametrize('drop, key', [
    (('robot', 'radius'), 'robot.radius'),
    (('robot', 'start'), 'robot.start'),
    (('goal',), 'goal'),
    (('map',), 'map'),
    (('robot',), 'robot'),
])
def test_missing_keys(room, drop, key):
    doc = base_doc()
    target = doc
    for part in drop[:-1]:
        target = target[part]
    del target[drop[-1]]
    message = error_of(write(room, doc))
    assert f"missing required key '{key}'" in message


@pytest.mark.parametrize('edit, key', [
    (lambda d: d['robot'].update(radius=-0.2), 'robot.radius'),
    (lambda d: d['robot'].update(radius='big'), 'robot.radius'),
    (lambda d: d['robot'].update(start=[1.0, 1.0]), 'robot.start'),
    (lambda d: d.update(goal=[1.0, float('nan')]), 'goal'),
    (lambda d: d['unknown_obstacles'][0]['circle'].update(radius=-1.0),
     'unknown_obstacles[0].circle.radius'),
    (lambda d: d['unknown_obstacles'][1]['rectangle'].update(max=[5.0, 5.5]),
     'unknown_obstacles[1].rectangle'),
    (lambda d: d['moving_obstacles'][0].update(radius=0.0), 'moving_obstacles[0].radius'),
    (lambda d: d['moving_obstacles'][1].update(model='teleport'), 'moving_obstacles[1].model'),
    (lambda d: d['moving_obstacles'][2].update(turn_std=-1), 'moving_obstacles[2].turn_std'),
    (lambda d: d['limits'].update(dt=0), 'limits.dt'),
    (lambda d: d['scan'].update(beams=2.5), 'scan.beams'),
    (lambda d: d['scan'].update(range_min=6.0), 'scan.range_min'),
    (lambda d: d.update(colour='red'), 'colour'),
    (lambda d: d['robot'].update(wheels=3), 'robot.wheels'),
    (lambda d: d['planner'].update(algorithm='bfs'), 'planner'),
    (lambda d: d.update(seed=-1), 'seed'),
    (lambda d: d.update(perception='oracle'), 'perception'),
    (lambda d: d.update(perception=1), 'perception'),
    (lambda d: d.update(unknown_obstacles={'circle': 1}), 'unknown_obstacles'),
])
def test_wrong_types_and_values(room, edit, key):
    doc = base_doc()
    edit(doc)
    message = error_of(write(room, doc))
    assert f"key '{key}'" in message


@pytest.mark.parametrize('edit, key', [
    (lambda d: d['robot'].update(start=[4.2, 1.0, 0.0]), 'robot.start'),    # in the known block
    (lambda d: d['robot'].update(start=[4.65, 1.0, 0.0]), 'robot.start'),   # disc overlaps it
    (lambda d: d['robot'].update(start=[5.0, 3.3, 0.0]), 'robot.start'),    # in the unknown circle
    (lambda d: d['robot'].update(start=[0.1, 4.0, 0.0]), 'robot.start'),    # against the map edge
    (lambda d: d.update(goal=[12.0, 4.0]), 'goal'),                          # outside the map
    (lambda d: d.update(goal=[6.2, 5.2]), 'goal'),                           # in the rectangle
    (lambda d: d['moving_obstacles'][0].update(position=[1.2, 1.2]), 'moving_obstacles[0]'),
    (lambda d: d['moving_obstacles'][2].update(position=[4.2, 1.0]), 'moving_obstacles[2]'),
    (lambda d: d['limits'].update(dt=0.5), 'limits.dt'),                    # 0.6 m/s * 0.5 s > 0.2 m
])
def test_geometry_is_checked(room, edit, key):
    doc = base_doc()
    edit(doc)
    message = error_of(write(room, doc))
    assert f"key '{key}'" in message


def test_unreadable_and_malformed_files(room):
    assert 'cannot read' in error_of(room / 'absent.yaml')
    bad = room / 'bad.yaml'
    bad.write_text('robot: [1, 2\n', encoding='utf-8')
    assert 'invalid YAML' in error_of(bad)
    listed = room / 'list.yaml'
    listed.write_text('- 1\n- 2\n', encoding='utf-8')
    assert 'mapping' in error_of(listed)


def test_a_missing_map_file_is_a_map_error(room):
    doc = base_doc()
    doc['map'] = 'nowhere.yaml'
    with pytest.raises(MapError) as info:
        load_scenario(write(room, doc))
    assert 'nowhere.yaml' in str(info.value)


def test_follower_overrides_are_checked_against_the_controller_params(room):
    doc = base_doc()
    doc['follower'] = {'lookahead': 1.0}
    assert load_scenario(write(room, doc)).follower['lookahead'] == 1.0
    doc['follower'] = {'look_ahead': 1.0}
    assert "key 'follower.look_ahead'" in error_of(write(room, doc))


def test_scenario_errors_are_invalid_input():
    assert issubclass(ScenarioError, InvalidInput)


# -- random scenarios -------------------------------------------------------------------------

@pytest.mark.parametrize('seed', [0, 1, 2, 17, 12345])
def test_random_scenarios_keep_their_promises(seed):
    s = random_scenario(seed)
    cfg = RandomScenarioConfig()
    start, goal = np.array(s.start[:2]), np.array(s.goal)
    assert np.hypot(*(goal - start)) >= cfg.min_start_goal_m
    assert cfg.unknown_range[0] <= len(s.unknown_obstacles) <= cfg.unknown_range[1]
    assert cfg.moving_range[0] <= len(s.moving_obstacles) <= cfg.moving_range[1]
    for mover in s.moving_obstacles:
        assert mover.top_speed() < 0.5 * s.robot.max_speed
        p = mover.start_position()
        assert np.hypot(*(p - start)) >= cfg.spawn_clearance_m
        assert np.hypot(*(p - goal)) >= cfg.spawn_clearance_m
    scene = s.static_scene()
    assert not scene.disc_collides(start, s.robot.radius)
    assert not scene.disc_collides(goal, s.robot.radius)
    # connected on the true map, for the robot plus the passage margin
    passage = s.robot.radius + cfg.passage_margin_m
    known = GlobalPlanner(s.grid, PlannerConfig(robot_radius=passage)).plan(start, goal)
    true = GlobalPlanner(s.true_grid(), PlannerConfig(robot_radius=passage)).plan(start, goal)
    assert true.metrics.length_m <= cfg.max_detour_ratio * known.metrics.length_m + 1e-9
    # the detour is local: every point of it stays near the known plan
    a, b = known.path[:-1], known.path[1:]
    for p in true.path:
        t = np.clip(np.einsum('ij,ij->i', p - a, b - a) / np.maximum(np.einsum('ij,ij->i', b - a, b - a),
                                                                     1e-18), 0, 1)
        assert np.min(np.hypot(*(p - (a + t[:, None] * (b - a))).T)) <= cfg.max_detour_offset_m + 1e-9
    # the scenario's planner keeps a margin beyond the robot radius
    assert s.planner.robot_radius == pytest.approx(s.robot.radius + cfg.plan_inflation_margin_m)


def test_random_scenarios_are_reproducible_and_differ_by_seed():
    a, b, c = random_scenario(8), random_scenario(8), random_scenario(9)
    assert np.array_equal(a.grid.occupied, b.grid.occupied)
    assert a.start == b.start and a.goal == b.goal
    assert a.unknown_obstacles == b.unknown_obstacles and a.moving_obstacles == b.moving_obstacles
    assert not (np.array_equal(a.grid.occupied, c.grid.occupied) and a.start == c.start)


def test_random_config_refuses_fast_obstacles():
    with pytest.raises(InvalidInput):
        RandomScenarioConfig(moving_speed_fraction=(0.2, 0.6))


def test_some_unknown_obstacles_sit_on_the_plan():
    near = 0
    for seed in range(10):
        s = random_scenario(seed)
        plan = GlobalPlanner(s.grid, s.planner).plan(s.start[:2], s.goal)
        scene = StaticScene(s.grid, [o for o in s.unknown_obstacles if isinstance(o, Circle)],
                            [o for o in s.unknown_obstacles if isinstance(o, Rectangle)])
        blocked = any(scene.disc_collides(p, s.robot.radius) for p in plan.path)
        near += blocked
    assert near >= 5        # most generated plans run into something the map did not show


def test_follower_override_values_are_checked_at_load_time(room):
    doc = base_doc()
    doc['follower'] = {'goal_tolerance': -1.0}
    assert "key 'follower' is invalid" in error_of(write(room, doc))
    doc['follower'] = {'apf': {'k_rep': 0.05}}
    params = load_scenario(write(room, doc)).follower_params()
    assert params.apf.k_rep == 0.05 and params.robot_radius == 0.2 and params.max_speed == 0.6
    doc['follower'] = {'apf': {'k_repulsion': 0.05}}
    assert "key 'follower' is invalid" in error_of(write(room, doc))


def test_the_turn_ramp_follows_from_the_robot_unless_overridden(room):
    doc = base_doc()
    doc['robot'].update(max_accel=2.0, radius=0.25)
    assert load_scenario(write(room, doc)).follower_params().max_alpha == pytest.approx(8.0)
    doc['follower'] = {'max_alpha': 3.0}
    assert load_scenario(write(room, doc)).follower_params().max_alpha == 3.0
