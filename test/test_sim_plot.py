"""Figures of runs: the saved picture shows each layer where it is in the map.

A hand-made run (a trajectory below, the plan above, one escape, one moving
obstacle) on a room with a wall is drawn, and the PNG is read back: the
trajectory is red along the trajectory, the plan blue along the plan, the
escape a magenta cross at the escape point, the unknown obstacle green, the
moving obstacle yellow where it ended, and the wall black.
"""

import numpy as np
import pytest
import yaml

from fusion_planner.cli import sim_plot
from fusion_planner.core.grid import GridMap
from fusion_planner.core.map_files import save_map_server
from fusion_planner.core.simulation.scenario import load_scenario
from fusion_planner.core.simulation.episodes import EpisodeResult

matplotlib = pytest.importorskip('matplotlib')
from matplotlib.colors import to_rgb  # noqa: E402
from matplotlib.image import imread  # noqa: E402

#: Largest per-channel difference [0..1] for "this pixel has that colour".
COLOUR_TOLERANCE = 0.12
#: Pixels searched around an expected point (antialiasing, rounding).
SEARCH_RADIUS_PX = 2
#: Samples of the hand-made trajectory.
SAMPLES = 101
#: Sample at which the hand-made run starts an escape.
ESCAPE_SAMPLE = 60
#: The wall of the room: x from 5.9 to 6.1 m, y from 0 to 3 m.
WALL_CELLS = (slice(0, 30), slice(59, 61))
UNKNOWN_CENTRE = (3.0, 6.0)
MOVER_FROM, MOVER_TO = (9.0, 1.0), (9.0, 5.0)


def write_room_scenario(folder):
    """A 12 m x 8 m room at 0.1 m with a wall, one unknown and one moving obstacle."""
    occupied = np.zeros((80, 120), bool)
    occupied[WALL_CELLS] = True
    save_map_server(GridMap(occupied, 0.1), folder / 'room.yaml')
    doc = {'name': 'room', 'map': 'room.yaml',
           'robot': {'start': [1.0, 1.0, 0.0], 'radius': 0.25}, 'goal': [11.0, 7.0],
           'unknown_obstacles': [{'circle': {'center': list(UNKNOWN_CENTRE), 'radius': 0.4}}],
           'moving_obstacles': [{'radius': 0.3, 'model': 'waypoints',
                                 'points': [list(MOVER_FROM), list(MOVER_TO)], 'speed': 0.4}]}
    path = folder / 'room_scenario.yaml'
    path.write_text(yaml.safe_dump(doc), encoding='utf-8')
    return load_scenario(path)


def polyline(points, samples):
    """``samples`` points evenly spaced along a polyline, shape (samples, 2)."""
    points = np.asarray(points, float)
    length = np.concatenate([[0.0], np.cumsum(np.hypot(*np.diff(points, axis=0).T))])
    s = np.linspace(0.0, length[-1], samples)
    return np.stack([np.interp(s, length, points[:, 0]), np.interp(s, length, points[:, 1])], 1)


def hand_made_run(scenario):
    """An EpisodeResult: the trajectory passes below the wall's end, the plan above it."""
    xy = polyline([scenario.start[:2], (6.0, 3.8), scenario.goal], SAMPLES)
    step = np.diff(xy, axis=0)
    step = np.vstack([step, step[-1]])
    trajectory = np.column_stack([xy, np.arctan2(step[:, 1], step[:, 0])])
    tracks = polyline([MOVER_FROM, MOVER_TO], SAMPLES)[:, None, :]
    plan = np.array([scenario.start[:2], (3.5, 5.0), (8.0, 7.2), scenario.goal])
    return EpisodeResult(
        scenario='room', controller='fusion', seed=0, reached=True, collisions=0,
        time_s=(SAMPLES - 1) * scenario.limits.dt, path_length_m=14.0, min_clearance_m=0.3,
        stuck_events=1, trajectory=trajectory, obstacle_tracks=tracks, plan_path=plan,
        key_nodes=plan[1:-1], escape_points=xy[ESCAPE_SAMPLE][None, :])


def pixels(fig, image, points):
    """(row, col) pixel indices of map-frame points [m] in a saved image of ``fig``."""
    xy = fig.axes[0].transData.transform(np.asarray(points, float).reshape(-1, 2))
    scale = image.shape[1] / fig.bbox.width  # saved dpi / figure dpi
    cols = np.round(xy[:, 0] * scale).astype(int)
    rows = np.round(image.shape[0] - xy[:, 1] * scale).astype(int)
    return rows, cols


def colour_near(image, fig, point, colour):
    """Whether ``colour`` (any matplotlib colour) is drawn within a few pixels of ``point``."""
    (row,), (col,) = pixels(fig, image, point)
    r0, c0 = max(row - SEARCH_RADIUS_PX, 0), max(col - SEARCH_RADIUS_PX, 0)
    patch = image[r0:row + SEARCH_RADIUS_PX + 1, c0:col + SEARCH_RADIUS_PX + 1, :3]
    return bool((np.abs(patch - np.asarray(to_rgb(colour))).max(axis=-1) < COLOUR_TOLERANCE).any())


def share_near(image, fig, points, colour):
    """Share of ``points`` with ``colour`` drawn near them."""
    return float(np.mean([colour_near(image, fig, p, colour) for p in points]))


def away_from(points, others, distance):
    """The points farther than ``distance`` [m] from every point of ``others``."""
    others = np.asarray(others, float).reshape(-1, 2)
    gaps = np.hypot(points[:, None, 0] - others[None, :, 0],
                    points[:, None, 1] - others[None, :, 1])
    return points[gaps.min(axis=1) > distance]


@pytest.fixture(scope='module')
def drawn(tmp_path_factory):
    folder = tmp_path_factory.mktemp('sim_plot')
    scenario = write_room_scenario(folder)
    result = hand_made_run(scenario)
    fig = sim_plot.plot_episode(scenario, result, folder / 'run.png')
    return scenario, result, fig, imread(folder / 'run.png')


def markers_of(scenario, result):
    """Where markers sit on top of the lines (start, goal, key nodes, escape, obstacles)."""
    return np.vstack([scenario.start[:2], scenario.goal, result.key_nodes, result.escape_points,
                      UNKNOWN_CENTRE, result.obstacle_tracks[[0, -1], 0]])


def test_trajectory_is_red_along_the_trajectory_only(drawn):
    scenario, result, fig, image = drawn
    along = away_from(result.trajectory[5:-5, :2], markers_of(scenario, result), 0.5)
    assert share_near(image, fig, along, sim_plot.TRAJECTORY_COLOUR) > 0.9
    plan_only = away_from(polyline(result.plan_path, 200), result.trajectory[:, :2], 1.0)
    assert len(plan_only) > 20
    assert share_near(image, fig, plan_only, sim_plot.TRAJECTORY_COLOUR) == 0.0


def test_plan_is_blue_along_the_plan(drawn):
    scenario, result, fig, image = drawn
    plan = away_from(polyline(result.plan_path, 200),
                     np.vstack([markers_of(scenario, result), result.trajectory[:, :2]]), 0.5)
    assert len(plan) > 20
    assert share_near(image, fig, plan, sim_plot.PLAN_COLOUR) > 0.9


def test_escape_obstacles_and_wall_are_where_they_are(drawn):
    scenario, result, fig, image = drawn
    assert colour_near(image, fig, result.escape_points[0], sim_plot.ESCAPE_COLOUR)
    assert not colour_near(image, fig, result.trajectory[20, :2], sim_plot.ESCAPE_COLOUR)
    assert colour_near(image, fig, UNKNOWN_CENTRE, sim_plot.UNKNOWN_OBSTACLE_COLOUR)
    assert colour_near(image, fig, MOVER_TO, sim_plot.MOVING_OBSTACLE_COLOUR)
    wall = scenario.grid.world_of(np.argwhere(scenario.grid.occupied))
    rows, cols = pixels(fig, image, wall[::7])
    assert (image[rows, cols, :3].max(axis=-1) < 0.15).all()
