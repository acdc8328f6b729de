"""Plan figures: the saved PNG shows the path and the obstacles where they are."""

import numpy as np
import pytest

from fusion_planner.cli import plotting
from fusion_planner.core.grid import GridMap
from fusion_planner.core.global_planning.planner import GlobalPlanner, PlannerConfig

matplotlib = pytest.importorskip('matplotlib')
from matplotlib.colors import to_rgb  # noqa: E402
from matplotlib.image import imread  # noqa: E402

#: Largest per-channel difference [0..1] for "this pixel has that colour".
COLOUR_TOLERANCE = 0.12
#: Pixels searched around an expected point (antialiasing, rounding).
SEARCH_RADIUS_PX = 2


def _map():
    """A 16 x 12 map with an asymmetric wall, origin off zero."""
    occupied = np.zeros((12, 16), bool)
    occupied[2:10, 7] = True      # a wall with gaps above and below
    occupied[9, 7:12] = True      # a shelf to the right at the top: asymmetric
    return GridMap(occupied, 0.5, (-2.0, 1.0, 0.0))


def _plan(grid):
    planner = GlobalPlanner(grid, PlannerConfig())
    return planner.plan((-1.75, 2.25), (5.25, 5.25), return_expanded=True)


def _pixels(fig, image, points):
    """(row, col) pixel indices of map-frame points in the saved image."""
    ax = fig.axes[0]
    xy = ax.transData.transform(np.asarray(points, float))
    height = image.shape[0]
    scale = image.shape[1] / fig.bbox.width  # saved dpi / figure dpi
    cols = np.round(xy[:, 0] * scale).astype(int)
    rows = np.round(height - xy[:, 1] * scale).astype(int)
    return rows, cols


def _has_colour_near(image, row, col, rgb):
    r0, c0 = max(row - SEARCH_RADIUS_PX, 0), max(col - SEARCH_RADIUS_PX, 0)
    patch = image[r0:row + SEARCH_RADIUS_PX + 1, c0:col + SEARCH_RADIUS_PX + 1, :3]
    return bool((np.abs(patch - np.asarray(rgb)).max(axis=-1) < COLOUR_TOLERANCE).any())


@pytest.fixture(scope='module')
def drawn(tmp_path_factory):
    grid = _map()
    result = _plan(grid)
    png = tmp_path_factory.mktemp('plot') / 'plan.png'
    fig = plotting.plot_plan(result, grid, png)
    return grid, result, fig, imread(png)


def test_plot_plan_writes_a_png(drawn, tmp_path):
    grid, result, _, image = drawn
    assert image.ndim == 3 and image.shape[0] > 100 and image.shape[1] > 100
    png = tmp_path / 'again.png'
    plotting.plot_plan(result, grid, png, title='custom')
    assert png.read_bytes()[:8] == b'\x89PNG\r\n\x1a\n'


def test_path_colour_lies_along_the_path(drawn):
    grid, result, fig, image = drawn
    path = result.path
    # Sample the path densely, away from the start/goal markers drawn on top.
    length = np.concatenate([[0], np.cumsum(np.hypot(*np.diff(path, axis=0).T))])
    s = np.linspace(0.15, 0.85, 40) * length[-1]
    samples = np.stack([np.interp(s, length, path[:, 0]), np.interp(s, length, path[:, 1])], 1)
    rows, cols = _pixels(fig, image, samples)
    blue = to_rgb(plotting.PATH_COLOUR)
    hits = [_has_colour_near(image, r, c, blue) for r, c in zip(rows, cols)]
    assert np.mean(hits) > 0.9


def test_path_colour_is_absent_far_from_the_path(drawn):
    grid, result, fig, image = drawn
    # Free cells far (> 2 m) from the path show no path colour.
    rows, cols = np.nonzero(~grid.occupied)
    centres = grid.world_of(np.stack([rows, cols], 1))
    dist = np.min(np.hypot(centres[:, None, 0] - result.path[None, :, 0],
                           centres[:, None, 1] - result.path[None, :, 1]), axis=1)
    far = centres[dist > 2.0]
    assert len(far) > 10
    pr, pc = _pixels(fig, image, far)
    assert not any(_has_colour_near(image, r, c, to_rgb(plotting.PATH_COLOUR))
                   for r, c in zip(pr, pc))


def test_obstacles_are_dark_where_obstacles_are(drawn):
    grid, result, fig, image = drawn
    rows, cols = np.nonzero(grid.occupied)
    centres = grid.world_of(np.stack([rows, cols], 1))
    pr, pc = _pixels(fig, image, centres)
    assert (image[pr, pc, :3].max(axis=-1) < 0.15).all()
    # ... and free cells away from anything drawn are light.
    rows, cols = np.nonzero(~grid.occupied)
    free = grid.world_of(np.stack([rows, cols], 1))
    dist = np.min(np.hypot(free[:, None, 0] - result.path[None, :, 0],
                           free[:, None, 1] - result.path[None, :, 1]), axis=1)
    pr, pc = _pixels(fig, image, free[dist > 1.0])
    assert (image[pr, pc, :3].min(axis=-1) > 0.7).all()


def test_expanded_cells_are_grey(drawn):
    grid, result, fig, image = drawn
    cells = result.expanded_cells
    centres = grid.world_of(cells)
    dist = np.min(np.hypot(centres[:, None, 0] - result.path[None, :, 0],
                           centres[:, None, 1] - result.path[None, :, 1]), axis=1)
    away = centres[dist > 0.6]
    if len(away) == 0:
        pytest.skip('every expanded cell lies under the path')
    pr, pc = _pixels(fig, image, away)
    expected = np.broadcast_to(plotting.EXPANDED_RGB, (len(away), 3))
    np.testing.assert_allclose(image[pr, pc, :3], expected, atol=0.05)


def test_legend_names_the_searched_cells_in_their_grey(drawn):
    _, _, fig, _ = drawn
    legend = fig.axes[0].get_legend()
    entries = dict(zip([t.get_text() for t in legend.get_texts()], legend.legend_handles))
    assert {'searched cells', 'path', 'key nodes', 'start', 'goal'} <= set(entries)
    np.testing.assert_allclose(entries['searched cells'].get_facecolor()[:3],
                               plotting.EXPANDED_RGB)


def test_no_searched_cells_entry_without_searched_cells(tmp_path):
    grid = _map()
    result = GlobalPlanner(grid, PlannerConfig()).plan((-1.75, 2.25), (5.25, 5.25))
    fig = plotting.plot_plan(result, grid, tmp_path / 'plan.png')
    labels = [t.get_text() for t in fig.axes[0].get_legend().get_texts()]
    assert 'searched cells' not in labels and 'path' in labels


def test_draw_grid_uses_metres_origin_and_unknown_grey(tmp_path):
    occupied = np.zeros((4, 6), bool)
    occupied[0, 0] = True
    unknown = np.zeros_like(occupied)
    unknown[3, 5] = True
    grid = GridMap(occupied, 0.25, (3.0, -1.0, 0.0), unknown=unknown)
    fig = plotting.new_figure(grid)
    ax = fig.axes[0]
    plotting.draw_grid(ax, grid)
    assert ax.get_xlim() == pytest.approx((3.0, 4.5))
    assert ax.get_ylim() == pytest.approx((-1.0, 0.0))
    png = tmp_path / 'grid.png'
    fig.savefig(png)
    image = imread(png)
    pr, pc = _pixels(fig, image, grid.world_of(np.array([[0, 0], [3, 5], [1, 2]])))
    colours = image[pr, pc, :3]
    np.testing.assert_allclose(colours[0], plotting.OBSTACLE_RGB, atol=0.05)
    np.testing.assert_allclose(colours[1], plotting.UNKNOWN_RGB, atol=0.05)
    np.testing.assert_allclose(colours[2], plotting.FREE_RGB, atol=0.05)


def test_failed_plan_draws_map_and_endpoints(tmp_path):
    grid = _map()
    png = tmp_path / 'failed.png'
    plotting.plot_plan(None, grid, png, start=(-1.75, 2.25), goal=(5.25, 5.25))
    assert imread(png).shape[0] > 100


def test_rotated_map_draws(tmp_path):
    grid = GridMap(np.eye(5, dtype=bool), 1.0, (0.0, 0.0, 0.5))
    result = GlobalPlanner(grid, PlannerConfig()).plan((0.3, 2.5), (0.5, 5.5))
    plotting.plot_plan(result, grid, tmp_path / 'rotated.png')
    assert (tmp_path / 'rotated.png').stat().st_size > 0
