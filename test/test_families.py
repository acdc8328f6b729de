"""Tests of fusion_planner.core.simulation.families: validity, determinism, each family's geometry.

The geometry is measured on the generated maps themselves (runs of free
cells, blobs of occupied cells), not read back from the generator.
"""

import numpy as np
import pytest

from fusion_planner.core.errors import InvalidInput, PlanningError
from fusion_planner.core.global_planning.planner import GlobalPlanner, PlannerConfig
from fusion_planner.core.simulation.families import (
    FAMILIES, POST_RADIUS_M, family_scenario, post_centres)
from fusion_planner.core.simulation.scenario import check_scenario
from fusion_planner.core.simulation.world import StaticScene

SEEDS = (0, 1, 2, 3, 4, 5)
GENERATED = tuple(f for f in FAMILIES if f != 'mixed')
ROBOT_DIAMETER = 0.4
#: Rounding slack of lengths measured in cells [m].
EPS = 1e-6


def free_runs(line):
    """Lengths [cells] of the runs of free cells of a 1-D occupancy line bounded by occupied cells."""
    edges = np.flatnonzero(np.diff(np.concatenate([[1], line.astype(int), [1]])))
    starts, ends = edges[::2], edges[1::2]
    return [(int(a), int(b)) for a, b in zip(starts, ends) if a > 0 and b < len(line)]


@pytest.mark.parametrize('family', GENERATED)
def test_every_scenario_is_valid_labelled_and_plans_on_its_known_map(family):
    for seed in SEEDS[:3]:
        s = family_scenario(family, seed)
        check_scenario(s)
        assert s.name == f'{family}-{seed}' and s.family == family
        assert s.solvable is (family != 'unreachable')
        assert s.planner.robot_radius == s.robot.radius
        GlobalPlanner(s.grid, s.planner).plan(s.start[:2], s.goal)
        assert s.robot.max_speed * s.limits.dt <= s.robot.radius


@pytest.mark.parametrize('family', FAMILIES)
def test_same_seed_same_scenario_other_seed_other_scenario(family):
    a, b, c = family_scenario(family, 7), family_scenario(family, 7), family_scenario(family, 8)
    assert np.array_equal(a.grid.occupied, b.grid.occupied)
    assert (a.start, a.goal, a.unknown_obstacles, a.moving_obstacles, a.robot) == \
        (b.start, b.goal, b.unknown_obstacles, b.moving_obstacles, b.robot)
    assert a.start != c.start


def test_mixed_is_the_random_scenario_of_before():
    from fusion_planner.core.simulation.scenario import random_scenario
    s = family_scenario('mixed', 3)
    assert s.name == 'random-3' and s.family == 'mixed' and s.solvable
    assert np.array_equal(s.grid.occupied, random_scenario(3).grid.occupied)


def test_unknown_family_is_refused():
    with pytest.raises(InvalidInput, match='unknown scenario family'):
        family_scenario('maze', 1)


@pytest.mark.parametrize('seed', SEEDS)
def test_clutter_posts_are_round_small_and_their_gaps_a_little_wider_than_the_robot(seed):
    s = family_scenario('clutter', seed)
    robot = s.robot
    assert (robot.radius, robot.max_accel, robot.max_omega, s.limits.dt) == (0.2, 2.0, 3.0, 0.05)
    assert 1.0 <= robot.max_speed <= 2.0
    assert s.unknown_obstacles == () and s.moving_obstacles == ()     # the map is all there is
    centres = post_centres(s.grid)
    assert len(centres) >= 48
    # each post is 3 x 3 cells of 0.05 m: 2 * POST_RADIUS_M across
    border = np.ones(s.grid.shape, bool)
    border[2:-2, 2:-2] = False
    assert s.grid.occupied.sum() - border.sum() == 9 * len(centres)
    assert 3 * s.grid.resolution == pytest.approx(2 * POST_RADIUS_M)
    # gaps between neighbouring posts (and the outer rows and walls) along both axes
    xs, ys = np.unique(centres[:, 0].round(6)), np.unique(centres[:, 1].round(6))
    height = s.grid.shape[0] * s.grid.resolution
    row_gaps = np.diff(np.concatenate([[0.1 - POST_RADIUS_M], ys, [height - 0.1 + POST_RADIUS_M]]))
    gaps = np.concatenate([np.diff(xs), row_gaps]) - 2 * POST_RADIUS_M
    assert gaps.min() >= ROBOT_DIAMETER + 0.05 - EPS and gaps.max() <= ROBOT_DIAMETER + 0.3 + EPS
    assert len(xs) * len(ys) == len(centres)                            # a full lattice


def test_clutter_gaps_vary_across_seeds():
    widths = set()
    for seed in SEEDS:
        xs = np.unique(post_centres(family_scenario('clutter', seed).grid)[:, 0].round(6))
        widths |= set(np.round(np.diff(xs) - 2 * POST_RADIUS_M, 2))
    assert min(widths) == pytest.approx(0.45) and max(widths) == pytest.approx(0.7)


@pytest.mark.parametrize('seed', SEEDS)
def test_corridors_are_1_2_to_2_m_wide_and_people_walk_them(seed):
    s = family_scenario('corridors', seed)
    occ, res = s.grid.occupied, s.grid.resolution
    widths = []
    for lines in (occ[2:-2, :], occ[:, 2:-2].T):   # rows, then columns, inside the border
        for line in lines:
            if line[2:-2].any():                     # the line crosses blocks: corridor sections
                widths += [(b - a) * res for a, b in free_runs(line)]
    assert widths and min(widths) >= 1.2 - EPS and max(widths) <= 2.0 + EPS
    assert 1 <= len(s.moving_obstacles) <= 3
    scene = StaticScene(s.grid)
    for mover in s.moving_obstacles:
        a, b = (np.asarray(p) for p in mover.motion.points)
        assert np.count_nonzero(a != b) == 1                # along one corridor axis
        assert np.hypot(*(a - b)) >= 3.0 - EPS
        assert not any(scene.disc_collides(a + t * (b - a), mover.radius) for t in np.linspace(0, 1, 30))
        assert mover.top_speed() < 0.5 * s.robot.max_speed


def test_the_first_corridor_walker_comes_head_on():
    for seed in SEEDS:
        s = family_scenario('corridors', seed)
        path = GlobalPlanner(s.grid, s.planner).plan(s.start[:2], s.goal).grid_path
        arc = np.concatenate([[0], np.cumsum(np.hypot(*np.diff(path, axis=0).T))])

        def along(p):
            return arc[np.argmin(np.hypot(*(path - p).T))]
        first, toward = (np.asarray(p) for p in s.moving_obstacles[0].motion.points)
        assert along(first) > along(toward) + 2.0


@pytest.mark.parametrize('seed', SEEDS)
def test_narrow_passage_is_a_little_wider_than_the_robot_at_most_5_m_long_and_planned(seed):
    s = family_scenario('narrow', seed)
    occ, res = s.grid.occupied, s.grid.resolution
    wall_columns = 2 + np.flatnonzero(occ[2:-2, 2:-2].mean(axis=0) > 0.5)
    assert 0 < len(wall_columns) * res <= 5.0 + EPS
    column = occ[:, wall_columns[len(wall_columns) // 2]]
    runs = free_runs(column)
    narrow = [(a, b) for a, b in runs if (b - a) * res < 1.0]
    assert len(narrow) == 1 and len(runs) <= 2
    (a, b), = narrow
    assert ROBOT_DIAMETER + 0.15 - EPS <= (b - a) * res <= ROBOT_DIAMETER + 0.3 + EPS
    for other in runs:
        if other != (a, b):
            assert (other[1] - other[0]) * res >= 1.2 - EPS
    path = GlobalPlanner(s.grid, s.planner).plan(s.start[:2], s.goal).grid_path
    x0, x1 = wall_columns[0] * res, (wall_columns[-1] + 1) * res
    inside = path[(path[:, 0] > x0) & (path[:, 0] < x1)]
    assert len(inside) and np.all((inside[:, 1] > a * res) & (inside[:, 1] < b * res))


def test_narrow_passage_is_sometimes_the_only_way():
    only = []
    for seed in range(12):
        occ = family_scenario('narrow', seed).grid.occupied
        wall_columns = 2 + np.flatnonzero(occ[2:-2, 2:-2].mean(axis=0) > 0.5)
        only.append(len(free_runs(occ[:, wall_columns[0]])) == 1)
    assert any(only) and not all(only)


@pytest.mark.parametrize('seed', SEEDS + (871017754,))  # a box as thick as its wall
def test_unreachable_goal_is_open_on_the_known_map_and_closed_in_the_world(seed):
    s = family_scenario('unreachable', seed)
    assert s.unknown_obstacles and s.moving_obstacles == ()
    GlobalPlanner(s.grid, s.planner).plan(s.start[:2], s.goal)
    with pytest.raises(PlanningError):   # not even a point fits through on the true map
        GlobalPlanner(s.true_grid(), PlannerConfig(robot_radius=0.0)).plan(s.start[:2], s.goal)
    scene = StaticScene(s.grid)
    for box in s.unknown_obstacles:       # each box reaches into the wall on both sides
        x = (box.min[0] + box.max[0]) / 2
        assert scene.distance((x, box.min[1]), 1.0) == 0.0
        assert scene.distance((x, box.max[1]), 1.0) == 0.0
