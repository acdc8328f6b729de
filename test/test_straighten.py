"""Folding a plan's zig-zags: fewer turns, the same clearance, hardly longer."""

import dataclasses

import numpy as np
import pytest

from fusion_planner.core import raster
from fusion_planner.core.global_planning.planner import (
    FOLD_LENGTH_SLACK, GlobalPlanner, PlannerConfig)
from fusion_planner.core.global_planning.straighten import fewer_turns, simplify
from fusion_planner.core.grid import GridMap
from fusion_planner.core.simulation.families import family_scenario

RES = 0.1


def test_a_staircase_in_the_open_becomes_one_step():
    stairs = np.array([[0.5, 0.5], [1.5, 0.5], [1.5, 1.5], [2.5, 1.5], [2.5, 2.5], [3.5, 2.5],
                       [3.5, 3.5]])
    folded = fewer_turns(GridMap(np.zeros((50, 50), bool), RES), stairs, 0.2, 0.05)
    np.testing.assert_allclose(folded, [[0.5, 0.5], [3.5, 0.5], [3.5, 3.5]], atol=1e-9)


def test_a_zig_zag_round_a_block_is_not_folded_through_it():
    occupied = np.zeros((50, 50), bool)
    occupied[:30, 18:40] = True                      # the block the L would cross
    stairs = np.array([[0.5, 0.5], [1.5, 0.5], [1.5, 3.5], [4.5, 3.5], [4.5, 4.5]])
    assert fewer_turns(GridMap(occupied, RES), stairs, 0.2, 0.05) is None


def test_a_straight_or_short_path_has_nothing_to_fold():
    grid = GridMap(np.zeros((20, 20), bool), RES)
    line = np.column_stack([np.linspace(0.2, 1.8, 33), np.full(33, 1.0)])
    assert fewer_turns(grid, line, 0.2, 0.05) is None
    assert len(simplify(line)) == 2


@pytest.mark.parametrize('seed', [3, 11, 29])
def test_a_post_field_plan_turns_less_keeps_its_clearance_and_is_hardly_longer(seed):
    s = family_scenario('clutter', seed)
    unfolded = GlobalPlanner(s.grid, dataclasses.replace(s.planner, fewer_turns=False)).plan(
        s.start[:2], s.goal)
    folded = GlobalPlanner(s.grid, s.planner).plan(s.start[:2], s.goal)
    assert len(simplify(folded.path)) <= len(simplify(unfolded.path))
    assert folded.metrics.length_m <= (1.0 + FOLD_LENGTH_SLACK) * unfolded.metrics.length_m
    needed = min(s.planner.robot_radius + s.planner.safety_distance,
                 unfolded.metrics.min_clearance_m)
    clearance = raster.segments_clearance(s.grid, folded.path[:-1], folded.path[1:])
    assert clearance.min() >= needed - 1e-9
    np.testing.assert_allclose(folded.path[[0, -1]], unfolded.path[[0, -1]])


def test_a_point_robot_keeps_the_paper_s_path():
    s = family_scenario('clutter', 3)
    point = PlannerConfig()                           # radius and safety distance 0
    a = GlobalPlanner(s.grid, point).plan(s.start[:2], s.goal)
    b = GlobalPlanner(s.grid, dataclasses.replace(point, fewer_turns=False)).plan(
        s.start[:2], s.goal)
    np.testing.assert_array_equal(a.path, b.path)
    np.testing.assert_array_equal(a.key_nodes, b.key_nodes)
