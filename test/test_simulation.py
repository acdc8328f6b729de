"""Closed-loop tests: the paper's claims (Figures 5-6), determinism, batches.

These run the real controllers of fusion_planner.core.local_planning.follow in the simulated
world of fusion_planner.core.simulation.world on the scenarios of config/scenarios.
"""

import dataclasses
import pathlib
import types

import numpy as np
import pytest

from fusion_planner.core.errors import InvalidInput
from fusion_planner.core.grid import GridMap
from fusion_planner.core.simulation.scenario import load_scenario, scenario_from_dict
from fusion_planner.core.local_planning import follow
from fusion_planner.core.local_planning.controller_base import Command, ControllerBase
from fusion_planner.core.simulation.episodes import (
    CONTROLLERS, batch_seeds, run_batch, run_episode, summarise)

SCENARIOS = pathlib.Path(__file__).resolve().parent.parent / 'config' / 'scenarios'

#: Paper section 3.2 / Figure 5: the classic field fails these, the improved one does not.
FIGURE_5 = ('fig5a', 'fig5b', 'fig5c')
#: Paper section 3.3 / Figure 6 and the larger cases: fusion must reach them without contact.
FUSION_CASES = ('fig6a', 'fig6b', 'warehouse', 'demo')


def scenario(name):
    return load_scenario(SCENARIOS / f'{name}.yaml')


@pytest.fixture(scope='module')
def results():
    """Episode results cached per (scenario, controller) for the module."""
    cache = {}

    def get(name, controller):
        key = (name, controller)
        if key not in cache:
            cache[key] = run_episode(scenario(name), controller)
        return cache[key]
    return get


# -- the paper's claims ------------------------------------------------------------------

@pytest.mark.parametrize('name', FIGURE_5)
def test_classic_apf_fails_figure_5(results, name):
    result = results(name, 'classic-apf')
    assert not result.reached
    assert result.failure is not None
    final = result.trajectory[-1, :2]
    assert np.hypot(*(final - np.array(scenario(name).goal))) > 0.15


def test_classic_apf_stops_short_of_the_goal_beside_an_obstacle(results):
    # Figure 5a: the goal-unreachable problem: it stalls on the approach line, near the goal
    result = results('fig5a', 'classic-apf')
    final = result.trajectory[-1, :2]
    goal = np.array(scenario('fig5a').goal)
    assert 0.15 < np.hypot(*(final - goal)) < 1.5
    assert result.collisions == 0


@pytest.mark.parametrize('k_rep', [0.002, 0.02])
def test_figure_5a_does_not_hinge_on_one_repulsion_gain(k_rep):
    # the goal-unreachable problem is a property of the classic field, not of a tuned gain
    s = dataclasses.replace(scenario('fig5a'), follower=types.MappingProxyType({'apf': {'k_rep': k_rep}}))
    assert not run_episode(s, 'classic-apf', record=False).reached
    assert run_episode(s, 'apf', record=False).reached


@pytest.mark.parametrize('controller', ['apf', 'fusion'])
@pytest.mark.parametrize('name', FIGURE_5)
def test_improved_field_and_fusion_reach_figure_5(results, name, controller):
    result = results(name, controller)
    assert result.reached, result.failure
    assert result.collisions == 0
    assert result.failure is None


@pytest.mark.parametrize('name', FUSION_CASES)
def test_fusion_reaches_figure_6_warehouse_and_demo_without_contact(results, name):
    result = results(name, 'fusion')
    assert result.reached, result.failure
    assert result.collisions == 0
    assert result.min_clearance_m > 0


def test_demo_finishes_within_a_minute(results):
    assert results('demo', 'fusion').time_s < 60.0


# -- episode bookkeeping ---------------------------------------------------------------------

def test_episode_records_are_consistent(results):
    s = scenario('fig6b')
    result = results('fig6b', 'fusion')
    traj = result.trajectory
    assert traj.ndim == 2 and traj.shape[1] == 3
    assert result.obstacle_tracks.shape == (len(traj), len(s.moving_obstacles), 2)
    assert np.allclose(traj[0], s.start)
    assert result.path_length_m == pytest.approx(np.hypot(*np.diff(traj[:, :2], axis=0).T).sum())
    assert result.time_s == pytest.approx((len(traj) - 1) * s.limits.dt)
    assert np.allclose(result.plan_path[0], s.start[:2]) and np.allclose(result.plan_path[-1], s.goal)
    assert result.plan_length_m > 0
    summary = result.summary()
    assert set(summary) >= {'reached', 'collisions', 'time_s', 'path_length_m', 'min_clearance_m',
                            'stuck_events', 'failure'}


def test_escape_points_are_where_escapes_started(results):
    result = results('fig5b', 'apf')
    assert result.stuck_events >= 1
    assert len(result.escape_points) >= 1
    # each escape point lies on the trajectory
    for point in result.escape_points:
        assert np.min(np.hypot(*(result.trajectory[:, :2] - point).T)) < 1e-9


def test_same_seed_same_trajectory():
    s = scenario('demo')       # scan noise and a random walk: both seeded
    a = run_episode(s, 'fusion')
    b = run_episode(s, 'fusion')
    assert np.array_equal(a.trajectory, b.trajectory)
    assert np.array_equal(a.obstacle_tracks, b.obstacle_tracks)
    c = run_episode(s, 'fusion', seed=s.seed + 1)
    assert not np.array_equal(a.obstacle_tracks, c.obstacle_tracks[:len(a.obstacle_tracks)]) \
        or len(a.obstacle_tracks) != len(c.obstacle_tracks)


def test_unknown_controller_is_refused():
    with pytest.raises(InvalidInput):
        run_episode(scenario('fig5a'), 'teleport')


def _corridor(unknown=(), time_limit=60.0, max_collisions=10):
    occ = np.zeros((40, 100), bool)
    doc = {'robot': {'start': [1.0, 2.0, 0.0], 'radius': 0.2}, 'goal': [9.0, 2.0],
           'unknown_obstacles': list(unknown),
           'limits': {'time_limit_s': time_limit, 'max_collisions': max_collisions},
           'scan': {'beams': 180, 'range_max': 6.0}}
    return scenario_from_dict(doc, grid=GridMap(occ, 0.1))


def test_a_path_tracker_hits_what_the_map_did_not_show_and_fusion_does_not():
    s = _corridor([{'circle': {'center': [5.0, 2.0], 'radius': 0.4}}])
    tracked = run_episode(s, 'astar-track', record=False)
    assert tracked.collisions >= 1 and not tracked.reached
    contacts = tracked.summary()['contacts']          # each one, where and against what
    assert len(contacts) == tracked.collisions
    assert all(c['person'] is None and c['escape'] is None and 4.0 < c['x_m'] < 5.0
               for c in contacts)
    fused = run_episode(s, 'fusion', record=False)
    assert fused.reached and fused.collisions == 0 and fused.summary()['contacts'] == []


def test_time_and_collision_limits_end_an_episode():
    slow = run_episode(_corridor(time_limit=2.0), 'fusion', record=False)
    assert not slow.reached and slow.failure.startswith('time_limit')
    assert slow.outcome == 'time_limit'
    assert slow.time_s == pytest.approx(2.0)
    bumped = run_episode(_corridor([{'circle': {'center': [5.0, 2.0], 'radius': 0.4}}], max_collisions=1),
                         'astar-track', record=False)
    assert not bumped.reached and bumped.outcome == 'collisions'
    assert bumped.collisions == 1


class _Ending(ControllerBase):
    """Drives straight ahead, then ends with ``status`` at 1 s; proves no path at 0.5 s."""

    status = 'failed'

    def compute(self, obs):
        if obs.time >= 0.5 - 1e-9 and self.no_path_proven_at is None and self.status == 'no_path':
            self.no_path_proven_at = obs.time
        if obs.time >= 1.0 - 1e-9:
            return self._stop(obs, self.status, 'it is over')
        return Command(0.3, 0.0, 'moving')


@pytest.mark.parametrize('status, outcome, proven', [
    ('no_path', 'no_path', 0.5), ('failed', 'controller_failed', None)])
def test_a_controller_ending_maps_to_its_outcome_and_the_proof_time_is_kept(
        monkeypatch, status, outcome, proven):
    monkeypatch.setattr(_Ending, 'status', status)
    monkeypatch.setattr(follow, 'make_controller', lambda name, params, replan=None: _Ending(params))
    result = run_episode(_corridor(), 'fusion', record=False)
    assert result.outcome == outcome and result.failure == f'{outcome}: it is over'
    assert result.no_path_proven_at_s == (None if proven is None else pytest.approx(proven))
    assert result.time_s == pytest.approx(1.0) and not result.reached
    assert result.summary()['outcome'] == outcome


def test_a_reached_goal_reports_its_time_over_the_optimal_time():
    result = run_episode(_corridor(), 'fusion', record=False)
    assert result.outcome == 'reached' and result.failure is None
    assert result.optimal_length_m == pytest.approx(8.0, abs=0.05)
    assert result.optimal_time_s == pytest.approx(result.optimal_length_m / 0.8)
    assert result.time_ratio == pytest.approx(result.time_s / result.optimal_time_s)
    assert result.time_ratio > 1.0
    assert result.summary()['time_ratio'] == pytest.approx(result.time_ratio, abs=1e-3)


def test_no_plan_on_the_known_map_is_a_failure_not_an_error():
    occ = np.zeros((40, 100), bool)
    occ[:, 50] = True                      # a wall across the room
    doc = {'robot': {'start': [1.0, 2.0, 0.0], 'radius': 0.2}, 'goal': [9.0, 2.0]}
    s = scenario_from_dict(doc, grid=GridMap(occ, 0.1))
    result = run_episode(s, 'fusion')
    assert not result.reached and result.failure.startswith('no_path')
    assert result.outcome == 'no_path' and result.optimal_length_m is None


# -- batches -----------------------------------------------------------------------------------

def test_batch_seeds_are_distinct_and_reproducible():
    a = batch_seeds(50, 7)
    assert a == batch_seeds(50, 7) and len(set(a)) == 50
    assert a != batch_seeds(50, 8)


def test_batch_summary_counts():
    rows = [
        {'controller': 'x', 'scenario': 'a', 'reached': True, 'collisions': 0, 'time_s': 10.0,
         'path_length_m': 11.0, 'optimal_length_m': 10.0, 'min_clearance_m': 0.3, 'stuck_events': 1,
         'failure': None},
        {'controller': 'x', 'scenario': 'b', 'reached': False, 'collisions': 2, 'time_s': 90.0,
         'path_length_m': 5.0, 'optimal_length_m': 10.0, 'min_clearance_m': 0.0, 'stuck_events': 0,
         'failure': 'time_limit: late'},
    ]
    s = summarise('x', rows)
    assert s.success_rate == 0.5 and s.collisions == 2 and s.episodes_with_collisions == 1
    assert s.mean_time_s == 10.0 and s.path_length_over_optimal == pytest.approx(1.1)
    assert s.failures == [('b', 'time_limit: late')]


def test_batch_summary_of_outcomes_solvable_runs_and_proofs():
    def row(name, solvable, outcome, stuck=0, ratio=None, proven=None, time_s=20.0):
        return {'controller': 'x', 'scenario': name, 'solvable': solvable, 'outcome': outcome,
                'reached': outcome == 'reached', 'collisions': 0, 'time_s': time_s,
                'path_length_m': 1.0, 'optimal_length_m': 1.0, 'min_clearance_m': 0.2,
                'stuck_events': stuck, 'failure': None if outcome == 'reached' else f'{outcome}: x',
                'time_ratio': ratio, 'no_path_proven_at_s': proven, 'wall_time_s': 0.5}
    rows = [row('a', True, 'reached', ratio=1.2), row('b', True, 'reached', stuck=2, ratio=1.6),
            row('c', True, 'time_limit'), row('d', False, 'no_path', stuck=1, proven=8.0),
            row('e', False, 'controller_failed', proven=1.0, time_s=61.0)]
    s = summarise('x', rows)
    assert (s.solvable_episodes, s.solvable_reached) == (3, 2)
    assert s.success_on_solvable == pytest.approx(2 / 3)
    assert s.outcomes == {'reached': 2, 'no_path': 1, 'controller_failed': 1, 'collisions': 0,
                          'time_limit': 1}
    assert s.stuck_run_fraction == pytest.approx(0.4)
    assert s.mean_time_ratio == pytest.approx(1.4)
    assert s.unsolvable_episodes == 2 and s.no_path_fraction == 0.5
    assert s.max_no_path_delay_s == pytest.approx(60.0)
    assert s.wall_time_s == pytest.approx(2.5)


def test_batches_do_not_depend_on_the_worker_count():
    one = run_batch(2, 5, controllers=['astar-track', 'classic-apf'], workers=1)
    two = run_batch(2, 5, controllers=['astar-track', 'classic-apf'], workers=2)

    def results(batch):
        return [{k: v for k, v in row.items() if k != 'wall_time_s'} for row in batch.episodes]
    assert results(one) == results(two)
    assert set(one.controllers) == {'astar-track', 'classic-apf'}


def test_batch_refuses_bad_arguments():
    with pytest.raises(InvalidInput):
        run_batch(0, 1)
    with pytest.raises(InvalidInput):
        run_batch(1, 1, controllers=['fusion', 'teleport'])
    with pytest.raises(InvalidInput, match='family'):
        run_batch(1, 1, family='maze')


def test_a_family_batch_labels_its_rows():
    batch = run_batch(1, 3, controllers=['astar-track'], family='unreachable')
    assert batch.family == 'unreachable' and batch.as_dict()['family'] == 'unreachable'
    row, = batch.episodes
    assert row['family'] == 'unreachable' and row['solvable'] is False
    assert row['optimal_length_m'] is None and row['wall_time_s'] > 0
    assert batch.controllers['astar-track'].unsolvable_episodes == 1


def test_all_controllers_are_known():
    assert set(CONTROLLERS) == {'fusion', 'apf', 'classic-apf', 'dwa', 'astar-track'}
