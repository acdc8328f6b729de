"""ObstacleLayer: scan returns marked after a persistence time, cleared by beams through them."""

import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from fusion_planner.core.errors import InvalidInput
from fusion_planner.core.grid import GridMap
from fusion_planner.core.global_planning import beam_cells
from fusion_planner.core.global_planning.obstacle_layer import ObstacleLayer
from fusion_planner.core.simulation.world import Rectangle, StaticScene

RESOLUTION = 0.1  # [m]
BEAMS = 360
ANGLES = np.linspace(-math.pi, math.pi, BEAMS, endpoint=False)
DIRECTIONS = np.column_stack([np.cos(ANGLES), np.sin(ANGLES)])
RANGE_MAX = 6.0  # [m]


def room():
    """6 m x 4 m, walls on the map edge only."""
    occupied = np.zeros((40, 60), bool)
    occupied[0, :] = occupied[-1, :] = occupied[:, 0] = occupied[:, -1] = True
    return GridMap(occupied, RESOLUTION)


def beams(grid, origin, rectangles=()):
    """``(ends, hit)`` of a 360-beam scan from ``origin`` in ``grid`` plus rectangles."""
    ranges = StaticScene(grid, rectangles=rectangles).cast(np.asarray(origin), DIRECTIONS, RANGE_MAX)
    hit = ranges < RANGE_MAX
    ranges = np.minimum(ranges, RANGE_MAX)
    return np.asarray(origin) + DIRECTIONS * ranges[:, None], hit


BOX = Rectangle(min=(3.0, 1.5), max=(3.4, 2.5))


def box_cells(grid, box=BOX):
    """Cells whose centre lies inside the box."""
    centres = grid.world_of(np.indices(grid.shape).reshape(2, -1).T)
    inside = ((centres[:, 0] > box.min[0]) & (centres[:, 0] < box.max[0])
              & (centres[:, 1] > box.min[1]) & (centres[:, 1] < box.max[1]))
    return {tuple(c) for c in np.indices(grid.shape).reshape(2, -1).T[inside]}


def test_a_static_box_is_confirmed_after_the_persistence_time_and_only_then():
    grid = room()
    layer = ObstacleLayer(grid, persistence_s=1.0, mark_range=3.0)
    ends, hit = beams(grid, (1.0, 2.0), [BOX])
    changes = [layer.update((1.0, 2.0), ends, hit, now=t) for t in np.arange(0.0, 1.01, 0.1)]
    assert changes[:-1] == [False] * 10 and changes[-1] is True
    confirmed = {tuple(c) for c in layer.confirmed_cells()}
    # Every confirmed cell touches the box's face towards the sensor ...
    centres = grid.world_of(np.array(sorted(confirmed)))
    assert np.all(np.abs(centres[:, 0] - BOX.min[0]) <= RESOLUTION)
    assert np.all((centres[:, 1] > BOX.min[1] - RESOLUTION) & (centres[:, 1] < BOX.max[1] + RESOLUTION))
    # ... and the face is covered: every row of the box has its confirmed cell.
    assert len({r for r, _ in confirmed}) >= round((BOX.max[1] - BOX.min[1]) / RESOLUTION)
    # The room's walls are the map's: never marked.
    assert not (confirmed & {tuple(c) for c in np.argwhere(grid.occupied)})


def test_the_box_gone_the_beams_clear_it():
    grid = room()
    layer = ObstacleLayer(grid, persistence_s=0.0)
    ends, hit = beams(grid, (1.0, 2.0), [BOX])
    assert layer.update((1.0, 2.0), ends, hit, now=0.0)
    assert len(layer.confirmed_cells())
    ends, hit = beams(grid, (1.0, 2.0))
    assert layer.update((1.0, 2.0), ends, hit, now=0.1)
    assert len(layer.confirmed_cells()) == 0 and len(layer) == 0
    assert np.array_equal(layer.occupied(), grid.occupied)


def test_a_walking_person_leaves_no_obstacle():
    grid = room()
    layer = ObstacleLayer(grid, persistence_s=1.0)
    # 0.3 m wide at 0.5 m/s: each cell of its face is covered for 0.8 s at most
    for step in range(60):  # 3 s at 20 Hz across the sensor's view
        t = step * 0.05
        person = Rectangle(min=(3.0, 0.5 + 0.5 * t), max=(3.3, 0.8 + 0.5 * t))
        ends, hit = beams(grid, (1.0, 2.0), [person])
        assert not layer.update((1.0, 2.0), ends, hit, now=t), f'confirmed at {t:.2f} s'
    assert len(layer.confirmed_cells()) == 0


def test_returns_beyond_the_mark_range_clear_but_do_not_mark():
    grid = room()
    layer = ObstacleLayer(grid, persistence_s=0.0, mark_range=1.5)
    ends, hit = beams(grid, (1.0, 2.0), [BOX])  # the box is 2 m away
    assert not layer.update((1.0, 2.0), ends, hit, now=0.0)
    assert len(layer) == 0


def test_occupied_adds_the_confirmed_cells_to_the_map():
    grid = room()
    layer = ObstacleLayer(grid, persistence_s=0.0)
    ends, hit = beams(grid, (1.0, 2.0), [BOX])
    layer.update((1.0, 2.0), ends, hit, now=0.0)
    occupied = layer.occupied()
    cells = layer.confirmed_cells()
    assert occupied[cells[:, 0], cells[:, 1]].all()
    assert occupied.sum() == grid.occupied.sum() + len(cells)
    assert not grid.occupied[cells[:, 0], cells[:, 1]].any()


def test_a_clock_reset_forgets_everything():
    grid = room()
    layer = ObstacleLayer(grid, persistence_s=0.0)
    ends, hit = beams(grid, (1.0, 2.0), [BOX])
    layer.update((1.0, 2.0), ends, hit, now=10.0)
    assert len(layer.confirmed_cells())
    far_ends, no_hit = beams(grid, (1.0, 2.0))
    layer.update((1.0, 2.0), far_ends[:0], no_hit[:0], now=1.0)  # back in time, empty scan
    assert len(layer) == 0


@settings(max_examples=200, deadline=None)
@given(x=st.floats(0.3, 5.7), y=st.floats(0.3, 3.7),
       bad=st.sampled_from([math.nan, math.inf, -math.inf]), beam=st.integers(0, BEAMS - 1))
def test_non_finite_beam_ends_are_ignored_and_every_mark_is_a_return(x, y, bad, beam):
    grid = room()
    layer = ObstacleLayer(grid, persistence_s=0.0, mark_range=10.0, known_margin_cells=0.0)
    ends, hit = beams(grid, (x, y), [BOX])
    ends[beam] = bad
    layer.update((x, y), ends, hit, now=0.0)
    finite = np.isfinite(ends).all(axis=1)
    returned = {tuple(c) for c in grid.cell_of(ends[finite & hit])}
    assert {tuple(c) for c in layer.confirmed_cells()} <= returned


@pytest.mark.parametrize('kwargs', [
    {'persistence_s': -1.0}, {'mark_range': 0.0}, {'clear_range': math.nan},
    {'known_margin_cells': -0.5}, {'persistence_s': 'soon'}])
def test_bad_settings_are_refused(kwargs):
    with pytest.raises(InvalidInput):
        ObstacleLayer(room(), **kwargs)


def test_bad_updates_are_refused():
    layer = ObstacleLayer(room())
    with pytest.raises(InvalidInput):
        layer.update((math.nan, 1.0), np.zeros((1, 2)), [True], now=0.0)
    with pytest.raises(InvalidInput):
        layer.update((1.0, 1.0), np.zeros((2, 2)), [True], now=0.0)
    with pytest.raises(InvalidInput):
        layer.update((1.0, 1.0), np.zeros((1, 2)), [True], now=math.inf)
    with pytest.raises(InvalidInput):
        ObstacleLayer(np.zeros((3, 3), bool))


@pytest.mark.skipif(not beam_cells.available(), reason='needs numba (the fast extra)')
@settings(max_examples=40, deadline=None)
@given(seed=st.integers(0, 10_000), yaw=st.sampled_from([0.0, 0.7, -math.pi / 2]))
def test_compiled_clearing_finds_the_cells_of_the_array_version(seed, yaw):
    # beams leaving the grid, ending on the origin (length zero), with and without returns
    rng = np.random.default_rng(seed)
    grid = GridMap(np.zeros((40, 60), bool), RESOLUTION, origin=(-1.0, 0.5, yaw))
    layer = ObstacleLayer(grid, clear_range=rng.uniform(0.5, 5.0))
    origin = grid.world_of(np.array([rng.integers(0, 40), rng.integers(0, 60)])) \
        + rng.uniform(-0.05, 0.05, 2)
    lengths = rng.uniform(0.0, 8.0, BEAMS)
    lengths[rng.random(BEAMS) < 0.05] = 0.0
    ends = origin + DIRECTIONS * lengths[:, None]
    hit = rng.random(BEAMS) < 0.5
    compiled = layer._cleared_cells(origin, ends, hit)
    arrays = layer._cleared_cells(origin, ends, hit, compiled=False)
    assert len(arrays) and np.array_equal(compiled, arrays), seed
