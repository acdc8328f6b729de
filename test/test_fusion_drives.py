"""The fusion controller drives what the global planner chose, at speed, and ends honestly.

Closed-loop runs in the simulated world on small hand-made maps, one per
claim: a long passage barely wider than the robot, full speed in a corridor,
a person met head-on in a corridor, a goal walled off by an obstacle the map
does not show, and a field of posts crossed at 2 m/s (faster on a plan that
steps once than on the staircase of the same length).
"""

import dataclasses

import numpy as np
import pytest

from fusion_planner.core.global_planning.planner import FOLD_LENGTH_SLACK, GlobalPlanner
from fusion_planner.core.global_planning.straighten import simplify
from fusion_planner.core.grid import GridMap
from fusion_planner.core.simulation.episodes import plan_on_known_map, run_episode
from fusion_planner.core.simulation.scenario import scenario_from_dict

RES = 0.05
RADIUS = 0.2


def scenario(occupied, start, goal, robot=None, unknown=(), moving=(), time_limit=120.0, dt=0.1,
             resolution=RES):
    """A scenario on a hand-made map; the planner inflates by the robot radius only."""
    robot_doc = {'start': list(start), 'radius': RADIUS, 'max_speed': 0.8, 'max_accel': 1.0,
                 'max_omega': 2.0}
    robot_doc.update(robot or {})
    doc = {'robot': robot_doc, 'goal': list(goal), 'unknown_obstacles': list(unknown),
           'moving_obstacles': list(moving),
           'limits': {'time_limit_s': time_limit, 'dt': dt, 'max_collisions': 10},
           'scan': {'beams': 360, 'range_max': 8.0},
           'planner': {'robot_radius': RADIUS}}
    return scenario_from_dict(doc, grid=GridMap(occupied, resolution))


def cells(metres):
    return int(round(metres / RES))


def corridor_map(width, length, height=4.0):
    """A straight corridor along x, centred at y = height / 2, walls everywhere else."""
    occupied = np.ones((cells(height), cells(length)), bool)
    half = width / 2
    occupied[cells(height / 2 - half):cells(height / 2 + half), cells(0.3):cells(length - 0.3)] = False
    return occupied


def speeds(result, dt):
    """Forward speed [m/s] between recorded poses."""
    return np.hypot(*np.diff(result.trajectory[:, :2], axis=0).T) / dt


# -- one notion of drivable: a 0.7 m x 4 m passage, the only way -------------------------

@pytest.mark.parametrize('offset', [0.0, 1.5])
def test_a_long_passage_barely_wider_than_the_robot_is_driven_through(offset):
    """Two rooms joined only by a 0.7 m x 4 m passage; start and goal off its axis or on it."""
    occupied = np.zeros((cells(6.0), cells(14.0)), bool)
    occupied[:, cells(5.0):cells(9.0)] = True
    occupied[cells(3.0 - 0.35):cells(3.0 + 0.35), cells(5.0):cells(9.0)] = False
    s = scenario(occupied, (1.5, 3.0 - offset, 0.0), (12.5, 3.0 + offset), time_limit=60.0)
    result = run_episode(s, 'fusion')
    assert result.reached, result.failure
    assert result.collisions == 0 and result.stuck_events == 0
    assert result.time_s < 1.5 * result.optimal_time_s


# -- speed where it is safe: side walls do not slow the robot -------------------------------

def test_the_straights_of_a_1_3_m_corridor_are_driven_at_90_percent_of_top_speed():
    """An L-shaped 1.3 m corridor: away from the turn, the ends and the ramps, >= 0.9 max_speed."""
    occupied = np.ones((cells(12.0), cells(24.0)), bool)
    half = 0.65
    occupied[cells(2.0 - half):cells(2.0 + half), cells(0.5):cells(21.0 + half)] = False
    occupied[cells(2.0 - half):cells(10.0 + half), cells(21.0 - half):cells(21.0 + half)] = False
    s = scenario(occupied, (1.0, 2.0, 0.0), (21.0, 10.0), time_limit=90.0)
    result = run_episode(s, 'fusion')
    assert result.reached and result.collisions == 0, result.failure
    v = speeds(result, s.limits.dt)
    xy = result.trajectory[1:, :2]
    margin = 2.0   # past the ramp from rest, before the braking for the turn and the goal
    straight = ((xy[:, 0] > 1.0 + margin) & (xy[:, 0] < 21.0 - margin) & (xy[:, 1] < 2.5)) \
        | ((xy[:, 1] > 2.0 + margin) & (xy[:, 1] < 10.0 - margin) & (xy[:, 0] > 20.5))
    assert straight.sum() > 100
    assert np.mean(v[straight]) >= 0.9 * s.robot.max_speed
    assert np.percentile(v[straight], 10) >= 0.85 * s.robot.max_speed


# -- people in corridors: yield, do not retreat ---------------------------------------------

def test_a_person_met_head_on_in_a_1_8_m_corridor_is_let_pass_without_a_long_retreat():
    person = {'radius': 0.3, 'model': 'waypoints', 'points': [[16.0, 2.0], [0.8, 2.0]],
              'speed': 0.35}
    s = scenario(corridor_map(1.8, 24.0), (1.0, 2.0, 0.0), (22.5, 2.0), moving=[person])
    result = run_episode(s, 'fusion')
    assert result.reached and result.collisions == 0, result.failure
    x = result.trajectory[:, 0]
    retreat = np.max(np.maximum.accumulate(x) - x)              # farthest driven back [m]
    assert retreat < 1.0
    assert result.time_s < 1.5 * result.optimal_time_s


def test_a_person_pacing_the_only_corridor_of_the_plan_is_gone_round_by_another():
    """Two rooms joined by a short and a long 0.9 m corridor; a person paces the short one.

    The robot cannot pass the person in 0.9 m; waiting for them would take
    for ever (they walk up and down). After giving way for a while it asks
    for a plan around them and takes the long corridor.
    """
    occupied = np.ones((cells(8.0), cells(12.0)), bool)
    occupied[cells(0.3):cells(7.7), cells(0.3):cells(2.5)] = False     # left room
    occupied[cells(0.3):cells(7.7), cells(9.5):cells(11.7)] = False    # right room
    for y in (4.0, 1.0):                                               # short, long corridor
        occupied[cells(y - 0.45):cells(y + 0.45), cells(2.5):cells(9.5)] = False
    person = {'radius': 0.3, 'model': 'waypoints', 'points': [[9.0, 4.0], [3.0, 4.0]],
              'speed': 0.2}
    s = scenario(occupied, (1.0, 4.0, 0.0), (11.0, 4.0), moving=[person], time_limit=120.0)
    result = run_episode(s, 'fusion')
    assert result.reached and result.collisions == 0, result.failure
    assert result.stuck_events == 0                                # giving way is no local minimum
    assert np.min(result.trajectory[:, 1]) < 1.5                   # through the long corridor


# -- a bounded, honest end ------------------------------------------------------------------

def test_a_goal_walled_off_by_an_unknown_obstacle_ends_no_path_with_the_robot_still():
    box = {'rectangle': {'min': [10.0, 0.5], 'max': [10.4, 3.5]}}    # closes the corridor
    s = scenario(corridor_map(1.3, 20.0), (1.0, 2.0, 0.0), (18.0, 2.0), unknown=[box],
                 time_limit=200.0)
    result = run_episode(s, 'fusion')
    assert result.outcome == 'no_path' and not result.reached
    assert result.no_path_proven_at_s is not None
    assert result.time_s - result.no_path_proven_at_s <= 20.0
    assert result.time_s < 60.0                                 # no minute of wandering
    assert np.allclose(result.trajectory[-2], result.trajectory[-1])   # standing still at the end
    assert result.collisions == 0


# -- clutter at speed ----------------------------------------------------------------------

def post_field(row_gaps, col_gaps, post=3, strip=24, wall=2):
    """Posts of ``post`` cells on a lattice with the given gaps (cells), open strips at both ends."""
    height = 2 * wall + sum(row_gaps) + post * (len(row_gaps) - 1)
    width = 2 * wall + 2 * strip + sum(col_gaps) + post * (len(col_gaps) + 1)
    occupied = np.zeros((height, width), bool)
    occupied[:wall], occupied[-wall:], occupied[:, :wall], occupied[:, -wall:] = (True,) * 4
    rows = wall + np.cumsum(row_gaps[:-1]) + post * np.arange(len(row_gaps) - 1)
    cols = wall + strip + np.concatenate([[0], np.cumsum(col_gaps)]) + post * np.arange(
        len(col_gaps) + 1)
    for r in rows:
        for c in cols:
            occupied[r:r + post, c:c + post] = True
    return occupied


@pytest.mark.parametrize('gaps', [(9, 12), (10, 14)])
def test_a_post_field_is_crossed_at_2_m_s_without_contact(gaps):
    """Posts 0.15 m wide, gaps 0.45-0.7 m (0.05-0.3 m wider than the robot), top speed 2 m/s."""
    narrow, wide = gaps
    row_gaps = [wide, narrow, wide, narrow, narrow, wide, narrow, wide]
    col_gaps = [narrow, wide, narrow, narrow, wide, narrow, wide, narrow, wide]
    occupied = post_field(row_gaps, col_gaps)
    height, width = occupied.shape[0] * RES, occupied.shape[1] * RES
    robot = {'max_speed': 2.0, 'max_accel': 2.0, 'max_omega': 3.0}
    s = scenario(occupied, (0.7, 0.5, 0.0), (width - 0.7, height - 0.5), robot=robot,
                 time_limit=60.0, dt=0.05)
    result = run_episode(s, 'fusion')
    assert result.reached, result.failure
    assert result.collisions == 0 and result.min_clearance_m > 0.0
    assert result.stuck_events == 0
    assert np.max(speeds(result, s.limits.dt)) > 1.0              # it does go fast where it can


def test_a_post_field_plan_steps_once_and_is_driven_faster_than_the_staircase():
    """The plan folded to few turns is crossed sooner than the staircase of the same length."""
    row_gaps = [12, 9, 12, 9, 9, 12, 9, 12]
    col_gaps = [9, 12, 9, 9, 12, 9, 12, 9, 12]
    occupied = post_field(row_gaps, col_gaps)
    height, width = occupied.shape[0] * RES, occupied.shape[1] * RES
    robot = {'max_speed': 2.0, 'max_accel': 2.0, 'max_omega': 3.0}
    s = scenario(occupied, (0.7, 0.5, 0.0), (width - 0.7, height - 0.5), robot=robot,
                 time_limit=60.0, dt=0.05)
    folded = plan_on_known_map(s)
    staircase = GlobalPlanner(s.grid, dataclasses.replace(s.planner, fewer_turns=False)).plan(
        s.start[:2], s.goal)
    assert len(simplify(folded.path)) < len(simplify(staircase.path))
    assert folded.metrics.length_m <= (1.0 + FOLD_LENGTH_SLACK) * staircase.metrics.length_m
    runs = [run_episode(s, 'fusion', record=False, plan=plan) for plan in (folded, staircase)]
    for result in runs:
        assert result.reached and result.collisions == 0, result.failure
    assert runs[0].time_s < runs[1].time_s
