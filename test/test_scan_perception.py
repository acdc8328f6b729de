"""Scan perception in the closed loop: dynamic families, hidden people, passive contacts."""

import numpy as np
import pytest

from fusion_planner.bench.tracker import TrackingStats
from fusion_planner.core.errors import InvalidInput
from fusion_planner.core.local_planning.hit_ages import HitAges
from fusion_planner.core.local_planning.scan_tracker import TrackReport
from fusion_planner.core.simulation.dynamic_families import DYNAMIC_FAMILIES
from fusion_planner.core.simulation.families import FAMILIES, family_scenario
from fusion_planner.core.simulation.episodes import run_episode
from fusion_planner.core.simulation.perception import (
    IdealPerception, ScanPerception, make_perception)
from fusion_planner.core.grid import GridMap
from fusion_planner.core.simulation.world import BounceMotion, MovingObstacle, RobotSpec, World


@pytest.mark.parametrize('family', sorted(DYNAMIC_FAMILIES))
def test_families_are_valid_reproducible_and_differ_by_seed(family):
    make = DYNAMIC_FAMILIES[family]
    a, b, c = make(5), make(5), make(6)
    assert a.name == f'{family}-5' and a.moving_obstacles == b.moving_obstacles
    assert a.moving_obstacles != c.moving_obstacles or a.goal != c.goal
    assert a.perception == 'scan'
    assert max(m.top_speed() for m in a.moving_obstacles) >= 0.3
    assert family in FAMILIES and family_scenario(family, 5).moving_obstacles == a.moving_obstacles
    assert a.family == family and a.solvable is True


def test_a_dense_crowd_is_the_crowd_of_its_seed_with_14_to_18_people():
    counts = set()
    for seed in range(30):
        crowd, dense = DYNAMIC_FAMILIES['crowd'](seed), DYNAMIC_FAMILIES['dense-crowd'](seed)
        assert (dense.start, dense.goal) == (crowd.start, crowd.goal)
        assert np.array_equal(dense.grid.occupied, crowd.grid.occupied)
        counts.add(len(dense.moving_obstacles))
        assert len(dense.moving_obstacles) > len(crowd.moving_obstacles)
    assert counts <= set(range(14, 19)) and len(counts) > 1


def test_fast_obstacles_are_as_fast_as_the_robot():
    for seed in range(5):
        scenario = DYNAMIC_FAMILIES['fast-obstacle'](seed)
        assert scenario.moving_obstacles[0].top_speed() == scenario.robot.max_speed


def test_the_person_round_the_blind_corner_is_unseen_by_scan_perception_only():
    scenario = DYNAMIC_FAMILIES['blind-corner'](3)
    world = World(scenario.grid, scenario.robot, scenario.start, (), scenario.moving_obstacles,
                  scenario.scan, seed=0)
    scan_perception, ideal = ScanPerception(scenario.grid), IdealPerception()
    for _ in range(5):
        scan = world.scan()
        hidden = scan_perception.tracked(world, scan)
        oracle = ideal.tracked(world, scan)
        world.step(0.0, 0.0, scenario.limits.dt)
    assert len(hidden) == 0 and len(oracle) == 1


@pytest.mark.parametrize('family, seed', [('blind-corner', 3), ('fast-obstacle', 4),
                                          ('crossing', 7)])
def test_closed_loop_with_scan_perception_only(family, seed):
    scenario = DYNAMIC_FAMILIES[family](seed)
    assert scenario.perception == 'scan'
    result = run_episode(scenario, 'fusion', record=True)
    assert result.perception == 'scan'
    assert result.reached, result.failure
    assert result.collisions == 0
    # the people did come close: the run was an encounter, not a stroll
    gaps = np.hypot(*(result.obstacle_tracks - result.trajectory[:, None, 0:2])
                    .transpose(2, 0, 1)).min()
    assert gaps < 2.0


def test_unknown_perception_is_refused():
    scenario = DYNAMIC_FAMILIES['crossing'](1)
    with pytest.raises(InvalidInput, match='perception'):
        run_episode(scenario, 'fusion', perception='telepathy')
    with pytest.raises(InvalidInput, match='perception'):
        make_perception('oracle', scenario.grid)


def test_hit_ages_grow_on_a_wall_and_stay_young_on_a_walker():
    scenario = DYNAMIC_FAMILIES['crossing'](1)
    ages = HitAges(scenario.grid, break_s=0.3)
    for k in range(20):
        t = 0.1 * k
        wall_age = ages.update(np.array([[5.05, 5.05]]), t)
        walker_age = ages.update(np.array([[8.05, 1.0 + 0.5 * t]]), t)
    assert wall_age[0] == pytest.approx(1.9)
    assert walker_age[0] < 0.3


def _corridor(width_m, closed_behind):
    """A 8 x 4 m map (0.1 m cells) walled off except a corridor along y = 2 m."""
    occupied = np.ones((40, 80), bool)
    half = int(round(width_m / 0.2))
    occupied[20 - half:20 + half, (15 if closed_behind else 0):] = False
    return GridMap(occupied, resolution=0.1)


OPEN = GridMap(np.zeros((40, 80), bool), resolution=0.1)


@pytest.mark.parametrize('grid, robot_v, person, approach, escape, passive', [
    # standing at the end of a dead-end corridor too narrow to pass: nowhere to go
    (_corridor(0.6, True), 0.0, ((4.0, 2.0), (-0.6, 0.0)), None, False, True),
    # backing away down a corridor from a person faster than the robot can drive
    (_corridor(0.6, False), -0.3, ((3.0, 2.0), (-1.5, 0.0)), -1.0, False, True),
    # standing in the open while a person walks at it from 2.5 m: it could step aside
    (OPEN, 0.0, ((5.0, 2.0), (-0.6, 0.0)), None, True, False),
    # creeping on ahead of a slow person overtaking from behind, room to either side
    (OPEN, 0.1, ((0.6, 2.0), (0.5, 0.0)), -1.0, True, False),
    # driving into a person standing in the way
    (OPEN, 0.5, ((3.0, 2.0), (0.0, 0.0)), 1.0, True, False),
    # driving on at a person walking at it
    (OPEN, 0.3, ((3.0, 2.0), (-0.6, 0.0)), 1.0, True, False),
])
def test_contacts_with_people_are_passive_only_when_the_robot_could_not_get_away(
        grid, robot_v, person, approach, escape, passive):
    walker = MovingObstacle(0.25, BounceMotion(*person))
    world = World(grid, RobotSpec(radius=0.2, max_accel=10.0), np.array([2.0, 2.0, 0.0]),
                  moving_obstacles=[walker])
    while world.contact_events == 0 and world.time < 6.0:
        world.step(robot_v, 0.0, 0.05)
    assert world.contact_events == world.moving_contact_events == 1
    assert world.passive_contact_events == int(passive)
    (event,) = world.contacts                       # the record says why
    assert event.person == 0 and event.escape == escape and event.passive == passive
    assert event.robot_speed_mps == pytest.approx(abs(robot_v))
    assert event.approach == (None if approach is None else pytest.approx(approach))


def test_tracking_stats_pair_tracks_with_the_truth_and_time_the_delay():
    stats = TrackingStats()
    truth = np.array([[1.0, 0.0, 1.0, 0.0, 0.3]])
    seen = np.array([[0.7, 0.0]])
    empty = TrackReport(np.zeros(0, np.int64), np.zeros((0, 4)), np.zeros((0, 4, 4)), np.zeros(0))
    stats.observe(0.0, empty, truth, seen)
    good = TrackReport(np.array([4]), np.array([[1.1, 0.0, 0.9, 0.0]]), np.zeros((1, 4, 4)),
                       np.array([0.3]))
    stats.observe(0.5, good, truth, seen)
    ghost = TrackReport(np.array([9]), np.array([[5.0, 5.0, 0.5, 0.0]]), np.zeros((1, 4, 4)),
                        np.array([0.3]))
    stats.observe(0.6, ghost, truth, seen)
    stats.finish()
    assert stats.delays == [0.5]
    assert stats.velocity_errors == [pytest.approx(0.1)]
    assert stats.false_ids == {9} and stats.unusable_sightings == 0
