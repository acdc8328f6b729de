"""Tests of fusion_planner.core.raster: the exact conservative supercover."""

from fractions import Fraction

import numpy as np
import pytest

from fusion_planner.core import raster
from fusion_planner.core.errors import InvalidInput
from fusion_planner.core.grid import GridMap


def _cells(array):
    return {tuple(int(v) for v in cell) for cell in np.asarray(array).reshape(-1, 2)}


def _touches_exactly(a, b, row, col):
    """Whether segment a-b meets the closed square of cell (row, col).

    Liang-Barsky clipping against the box in exact rational arithmetic;
    a and b are grid coordinates (col, row).
    """
    ax, ay = Fraction(a[0]), Fraction(a[1])
    dx, dy = Fraction(b[0]) - ax, Fraction(b[1]) - ay
    t0, t1 = Fraction(0), Fraction(1)
    for start, delta, lo in ((ax, dx, col), (ay, dy, row)):
        hi = lo + 1
        if delta == 0:
            if start < lo or start > hi:
                return False
            continue
        ta, tb = (lo - start) / delta, (hi - start) / delta
        t0, t1 = max(t0, min(ta, tb)), min(t1, max(ta, tb))
    return t0 <= t1


def _reference(a, b):
    """All cells whose closed square meets a-b, by testing every candidate."""
    lo = np.floor(np.minimum(a, b)).astype(int) - 1
    hi = np.floor(np.maximum(a, b)).astype(int) + 1
    return {(row, col)
            for row in range(lo[1], hi[1] + 1)
            for col in range(lo[0], hi[0] + 1)
            if _touches_exactly(a, b, row, col)}


def _sampled(a, b, samples=4001):
    """Cells of points densely sampled on a-b (a subset of the supercover)."""
    t = np.linspace(0.0, 1.0, samples)[:, None]
    p = np.asarray(a) + t * (np.asarray(b) - np.asarray(a))
    return _cells(np.floor(p[:, ::-1]).astype(int))


@pytest.fixture
def unit_grid():
    return GridMap(np.zeros((6, 6), bool), resolution=1.0)


def test_horizontal_through_centres(unit_grid):
    cells = raster.segment_cells(unit_grid, (0.5, 2.5), (3.5, 2.5))
    assert _cells(cells) == {(2, c) for c in range(4)}


def test_vertical_through_centres(unit_grid):
    cells = raster.segment_cells(unit_grid, (4.5, 0.5), (4.5, 3.5))
    assert _cells(cells) == {(r, 4) for r in range(4)}


@pytest.mark.parametrize('a, b', [((0.5, 0.5), (2.5, 2.5)), ((2.5, 2.5), (0.5, 0.5))])
def test_diagonal_through_corners_takes_both_neighbours(unit_grid, a, b):
    cells = _cells(raster.segment_cells(unit_grid, a, b))
    assert cells == {(0, 0), (0, 1), (1, 0), (1, 1), (1, 2), (2, 1), (2, 2)}


def test_anti_diagonal_through_corners(unit_grid):
    cells = _cells(raster.segment_cells(unit_grid, (0.5, 2.5), (2.5, 0.5)))
    assert cells == {(2, 0), (2, 1), (1, 0), (1, 1), (1, 2), (0, 1), (0, 2)}


def test_segment_along_grid_line_takes_both_sides(unit_grid):
    cells = _cells(raster.segment_cells(unit_grid, (0.5, 2.0), (2.5, 2.0)))
    assert cells == {(r, c) for r in (1, 2) for c in (0, 1, 2)}


def test_zero_length_segment(unit_grid):
    assert _cells(raster.segment_cells(unit_grid, (1.5, 2.5), (1.5, 2.5))) == {(2, 1)}
    corner = _cells(raster.segment_cells(unit_grid, (2.0, 3.0), (2.0, 3.0)))
    assert corner == {(2, 1), (2, 2), (3, 1), (3, 2)}


def test_no_gap_between_diagonal_obstacles():
    occupied = np.zeros((4, 4), bool)
    occupied[0, 1] = occupied[1, 0] = True
    grid = GridMap(occupied, resolution=1.0)
    assert raster.segment_clearance(grid, (0.5, 0.5), (1.5, 1.5)) == 0.0
    assert raster.segment_clearance(grid, (0.5, 0.5), (3.5, 3.5)) == 0.0


def test_outside_cells_are_included_and_make_clearance_zero(unit_grid):
    cells = raster.segment_cells(unit_grid, (0.5, 0.5), (-1.5, 0.5))
    assert not unit_grid.contains(cells).all()
    assert raster.segment_clearance(unit_grid, (0.5, 0.5), (-1.5, 0.5)) == 0.0
    assert raster.segment_clearance(unit_grid, (0.5, 0.5), (5.5, 5.5)) == np.inf


def test_far_endpoint_is_clipped_but_still_leaves_the_map(unit_grid):
    cells = raster.segment_cells(unit_grid, (0.5, 0.5), (1e12, 0.5))
    inside = cells[unit_grid.contains(cells)]
    assert _cells(inside) == {(0, c) for c in range(6)}
    assert len(cells) < 20
    far = raster.segment_cells(unit_grid, (-1e9, -1e9), (-1e9 + 1, -1e9))
    assert len(far) >= 1 and not unit_grid.contains(far).any()


def test_world_frame_scaling_and_rotation():
    """The same segment in cells gives the same cells on any map frame."""
    rng = np.random.default_rng(7)
    plain = GridMap(np.zeros((10, 10), bool), resolution=1.0)
    for origin in ((-3.0, 2.0, 0.0), (1.0, -4.0, 0.7)):
        grid = GridMap(np.zeros((10, 10), bool), resolution=0.25, origin=origin)
        for _ in range(20):
            g = rng.uniform(0, 10, size=(2, 2))
            a, b = grid.grid_to_world(g)
            assert _cells(raster.segment_cells(grid, a, b)) == \
                _cells(raster.segment_cells(plain, g[0], g[1]))


def test_matches_exact_reference_on_random_segments(unit_grid):
    rng = np.random.default_rng(42)
    for _ in range(150):
        a, b = rng.uniform(-1.0, 7.0, size=(2, 2))
        cells = _cells(raster.segment_cells(unit_grid, a, b))
        assert cells == _reference(a, b)
        assert _sampled(a, b) <= cells


def test_matches_exact_reference_on_lattice_segments(unit_grid):
    """Ends on half-cell lattice points hit corners and lines often."""
    rng = np.random.default_rng(3)
    for _ in range(150):
        a, b = rng.integers(-2, 14, size=(2, 2)) / 2.0
        cells = _cells(raster.segment_cells(unit_grid, a, b))
        assert cells == _reference(a, b), (a, b)
        assert _sampled(a, b) <= cells


def test_symmetric_in_its_ends(unit_grid):
    rng = np.random.default_rng(5)
    for _ in range(50):
        a, b = rng.integers(0, 12, size=(2, 2)) / 2.0
        assert _cells(raster.segment_cells(unit_grid, a, b)) == \
            _cells(raster.segment_cells(unit_grid, b, a))


def test_path_cells_is_union_of_segments(unit_grid):
    rng = np.random.default_rng(11)
    path = rng.uniform(0.0, 6.0, size=(8, 2))
    union = set()
    for a, b in zip(path[:-1], path[1:]):
        union |= _cells(raster.segment_cells(unit_grid, a, b))
    cells = raster.path_cells(unit_grid, path)
    assert _cells(cells) == union
    assert len(cells) == len(union)  # unique rows


def test_path_cells_of_one_point(unit_grid):
    assert _cells(raster.path_cells(unit_grid, [[2.5, 3.5]])) == {(3, 2)}


def test_segments_clearance_matches_single_calls():
    rng = np.random.default_rng(2)
    occupied = rng.random((12, 12)) < 0.2
    grid = GridMap(occupied, resolution=0.5)
    starts = rng.uniform(-0.5, 6.5, size=(30, 2))
    ends = rng.uniform(-0.5, 6.5, size=(30, 2))
    batch = raster.segments_clearance(grid, starts, ends)
    single = [raster.segment_clearance(grid, a, b) for a, b in zip(starts, ends)]
    assert np.array_equal(batch, single)
    for a, b, value in zip(starts, ends, single):
        cells = raster.segment_cells(grid, a, b)
        if grid.contains(cells).all():
            assert value == grid.clearance[cells[:, 0], cells[:, 1]].min()
        else:
            assert value == 0.0


@pytest.mark.parametrize('a, b', [((np.nan, 0.0), (1.0, 1.0)), ((0.0, 0.0), (np.inf, 1.0)),
                                  ((0.0,), (1.0, 1.0))])
def test_bad_points_raise(unit_grid, a, b):
    with pytest.raises(InvalidInput):
        raster.segment_cells(unit_grid, a, b)


def test_bad_path_raises(unit_grid):
    with pytest.raises(InvalidInput):
        raster.path_cells(unit_grid, np.zeros((0, 2)))
    with pytest.raises(InvalidInput):
        raster.path_cells(unit_grid, np.zeros((3, 3)))


def test_long_segment_is_fast():
    grid = GridMap(np.zeros((2000, 2000), bool), resolution=0.05)
    cells = raster.segment_cells(grid, (0.01, 0.02), (99.97, 99.3))
    assert len(cells) >= 2000
    assert grid.contains(cells).all()
