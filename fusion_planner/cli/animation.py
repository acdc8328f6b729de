"""Animated GIFs of closed-loop runs (CLI only).

A frame shows what :func:`fusion_planner.cli.sim_plot.plot_episode` draws,
at one instant: the known map, the unknown static obstacles, the A* plan
with its key nodes, the start and the goal, and, up to that instant, the
driven trajectory, the robot (a disc with a heading tick), the moving
obstacles where they are, and the escape points passed so far. Frames are
rendered on an Agg figure as in :mod:`fusion_planner.cli.plotting` and
written by pillow (no ffmpeg).
"""

import math

import numpy as np

from fusion_planner.cli.plotting import draw_grid, new_figure
from fusion_planner.cli.sim_plot import (
    MOVING_EDGE_COLOUR, MOVING_OBSTACLE_COLOUR, add_legend, draw_endpoints, draw_escapes,
    draw_plan, draw_static_obstacles, draw_trajectory, episode_title)

#: Frames per second of the GIF [1/s].
GIF_FPS = 10
#: Most frames of one GIF; a longer run is subsampled evenly [1].
MAX_FRAMES = 120
#: Resolution of the GIF [dots per inch]: the figure has the picture's size
#: in inches (and so its layout), drawn with fewer pixels.
GIF_DPI = 70
#: Colour of the robot's disc and heading tick.
ROBOT_COLOUR = '#00a0c0'


def frame_indices(samples, max_frames=MAX_FRAMES):
    """Indices of the recorded samples shown as frames.

    Parameters
    ----------
    samples : int
        Recorded instants, > 0.
    max_frames : int
        Most frames, > 1.

    Returns
    -------
    ndarray, int64, shape (F,)
        Every ``step``-th index, ``step = ceil(samples / max_frames)``, and
        always the last one (the end of the run), F <= max_frames + 1.

    Examples
    --------
    >>> frame_indices(10, 4).tolist()
    [0, 3, 6, 9]
    >>> frame_indices(3).tolist()
    [0, 1, 2]
    """
    step = max(1, math.ceil(samples / max_frames))
    indices = np.arange(0, samples, step, dtype=np.int64)
    if indices[-1] != samples - 1:
        indices = np.append(indices, samples - 1)
    return indices


def escape_steps(trajectory, escape_points):
    """Sample index at which each escape point was recorded.

    Parameters
    ----------
    trajectory : ndarray, shape (T, 2) or (T, 3)
        Poses [m], map frame.
    escape_points : ndarray, shape (E, 2)
        Points [m] recorded at poses of the trajectory.

    Returns
    -------
    ndarray, int64, shape (E,)
        For each point, the first sample nearest to it.
    """
    xy = np.asarray(trajectory, dtype=float)[:, :2]
    points = np.asarray(escape_points, dtype=float).reshape(-1, 2)
    distances = np.hypot(xy[None, :, 0] - points[:, None, 0], xy[None, :, 1] - points[:, None, 1])
    return np.argmin(distances, axis=1).astype(np.int64)


def animate_episode(scenario, result, path_gif, dt, fps=GIF_FPS, max_frames=MAX_FRAMES):
    """Save an animated GIF of one run.

    Parameters
    ----------
    scenario : Scenario
    result : EpisodeResult
        With ``trajectory`` (T, 3) and ``obstacle_tracks`` (T, K, 2) sampled
        at the same instants (``run_episode(..., record=True)``).
    path_gif : str or os.PathLike
        Output file.
    dt : float
        Simulated time between two samples [s].
    fps : int
        Frames per second of the GIF.
    max_frames : int
        Most frames; a longer run is subsampled (:func:`frame_indices`).

    Returns
    -------
    matplotlib.figure.Figure
        The figure as in the last frame; its ``transData`` maps metres to
        the GIF's pixels (the GIF is drawn at the figure's dpi).

    Raises
    ------
    ValueError
        If the run has no trajectory, or its obstacle tracks are not sampled
        like it.

    Notes
    -----
    One frame shows ``ceil(T / max_frames) * dt`` seconds of simulated time;
    the title gives the time of the frame and the speed-up of the playback
    over simulated time. The map, the obstacles the robot does not move and
    the legend are rendered once; each frame redraws only the moving
    artists over a copy of that background (matplotlib's blitting), then
    pillow writes the frames as one looping GIF.
    """
    from matplotlib.patches import Circle as CirclePatch
    from PIL import Image

    if result.trajectory is None or not len(result.trajectory):
        raise ValueError('the run has no recorded trajectory to animate')
    trajectory = np.asarray(result.trajectory, dtype=float)
    tracks = result.obstacle_tracks
    movers = scenario.moving_obstacles if tracks is not None else ()
    if tracks is not None and len(tracks) != len(trajectory):
        raise ValueError(f'{len(tracks)} obstacle samples for {len(trajectory)} poses: '
                         'the tracks must be sampled at the poses\' instants')
    frames = frame_indices(len(trajectory), max_frames)
    step = frames[1] - frames[0] if len(frames) > 1 else 1
    escapes = np.asarray(result.escape_points, dtype=float).reshape(-1, 2)
    escaped_at = escape_steps(trajectory, escapes)

    fig = new_figure(scenario.grid, dpi=GIF_DPI)
    ax = fig.axes[0]
    draw_grid(ax, scenario.grid)
    draw_static_obstacles(ax, scenario.unknown_obstacles)
    draw_plan(ax, result)
    draw_endpoints(ax, scenario)
    moving = [draw_trajectory(ax, trajectory[:1]), draw_escapes(ax, escapes[:0])]
    for k, mover in enumerate(movers):
        moving.append(ax.add_patch(CirclePatch(
            tracks[0, k], mover.radius, facecolor=MOVING_OBSTACLE_COLOUR,
            edgecolor=MOVING_EDGE_COLOUR, zorder=4,
            label='moving obstacle' if k == 0 else None)))
    radius = scenario.robot.radius
    moving.append(ax.add_patch(CirclePatch(trajectory[0, :2], radius, facecolor=ROBOT_COLOUR,
                                           edgecolor='black', lw=0.5, zorder=9, label='robot')))
    moving.append(ax.plot([], [], color='black', lw=1.0, zorder=10)[0])
    driven, escape_marks, *mover_patches, robot, heading = moving
    add_legend(ax)
    ax.set_title(episode_title(scenario, result), fontsize=7)
    fig.tight_layout()
    moving.append(ax.title)
    for artist in moving:
        artist.set_animated(True)  # left out of the background
    canvas = fig.canvas
    canvas.draw()
    background = canvas.copy_from_bbox(fig.bbox)
    speed_up = step * dt * fps

    images = []
    for i in frames:
        x, y, yaw = trajectory[i]
        driven.set_data(trajectory[:i + 1, 0], trajectory[:i + 1, 1])
        passed = escapes[escaped_at <= i]
        escape_marks.set_data(passed[:, 0], passed[:, 1])
        for k, patch in enumerate(mover_patches):
            patch.set_center(tracks[i, k])
        robot.set_center((x, y))
        heading.set_data([x, x + radius * math.cos(yaw)], [y, y + radius * math.sin(yaw)])
        ax.set_title(episode_title(scenario, result) if i == frames[-1] else
                     f'{scenario.name} / {result.controller}: t = {i * dt:5.1f} s '
                     f'(playback x{speed_up:.1f})', fontsize=7)
        canvas.restore_region(background)
        for artist in moving:
            ax.draw_artist(artist)
        rgb = np.asarray(canvas.buffer_rgba())[..., :3]
        images.append(Image.fromarray(rgb).quantize(
            method=Image.Quantize.FASTOCTREE, dither=Image.Dither.NONE))
    images[0].save(path_gif, format='GIF', save_all=True, append_images=images[1:],
                   duration=round(1000 / fps), loop=0)
    return fig
