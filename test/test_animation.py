"""Animated GIFs of runs: frames read back show the run as it unfolds.

The hand-made run of test_sim_plot is animated; the GIF is read back with
pillow: the robot is where the trajectory is at each frame's instant, the
driven line grows behind it, the moving obstacle moves along its track, and
the escape cross appears once the escape has happened.
"""

import numpy as np
import pytest

from fusion_planner.cli import animation, sim_plot
from fusion_planner.cli.main import main
from test_sim_plot import MOVER_TO, colour_near, hand_made_run, share_near, write_room_scenario

pytest.importorskip('matplotlib')
Image = pytest.importorskip('PIL.Image')

#: Frames asked of the hand-made run (of test_sim_plot.SAMPLES samples).
MAX_FRAMES = 10


def read_gif(path):
    """Every frame of a GIF as an (H, W, 3) float array in [0, 1], and its duration [ms]."""
    with Image.open(path) as gif:
        frames = []
        for i in range(gif.n_frames):
            gif.seek(i)
            frames.append(np.asarray(gif.convert('RGB'), dtype=float) / 255.0)
        return frames, gif.info['duration']


@pytest.fixture(scope='module')
def animated(tmp_path_factory):
    folder = tmp_path_factory.mktemp('animation')
    scenario = write_room_scenario(folder)
    result = hand_made_run(scenario)
    fig = animation.animate_episode(scenario, result, folder / 'run.gif', scenario.limits.dt,
                                    max_frames=MAX_FRAMES)
    frames, duration = read_gif(folder / 'run.gif')
    return scenario, result, fig, frames, duration


def test_frame_indices_cover_the_run_evenly():
    for samples in (1, 2, 9, 10, 11, 101, 1234):
        idx = animation.frame_indices(samples, MAX_FRAMES)
        assert idx[0] == 0 and idx[-1] == samples - 1
        assert len(idx) <= MAX_FRAMES + 1 and np.all(np.diff(idx) > 0)
        assert len(set(np.diff(idx[:-1]).tolist())) <= 1  # even steps but for the last


def test_gif_has_one_frame_per_index_at_the_frame_rate(animated):
    scenario, result, fig, frames, duration = animated
    assert len(frames) == len(animation.frame_indices(len(result.trajectory), MAX_FRAMES))
    assert duration == round(1000 / animation.GIF_FPS)
    assert frames[0].shape[:2] == (round(fig.bbox.height), round(fig.bbox.width))


def test_robot_follows_the_trajectory(animated):
    scenario, result, fig, frames, _ = animated
    indices = animation.frame_indices(len(result.trajectory), MAX_FRAMES)
    for frame, i in zip(frames, indices):
        here = result.trajectory[i, :2]
        assert colour_near(frame, fig, here, animation.ROBOT_COLOUR), i
        later = result.trajectory[-1, :2] if i < len(result.trajectory) // 2 else \
            result.trajectory[0, :2]
        assert not colour_near(frame, fig, later, animation.ROBOT_COLOUR), i


def test_driven_line_grows_behind_the_robot(animated):
    scenario, result, fig, frames, _ = animated
    middle = len(frames) // 2
    i = animation.frame_indices(len(result.trajectory), MAX_FRAMES)[middle]
    ahead = result.trajectory[i + 10:-10, :2]
    behind = result.trajectory[5:i - 5, :2]
    assert share_near(frames[middle], fig, behind, sim_plot.TRAJECTORY_COLOUR) > 0.9
    assert share_near(frames[middle], fig, ahead, sim_plot.TRAJECTORY_COLOUR) == 0.0
    assert share_near(frames[-1], fig, ahead, sim_plot.TRAJECTORY_COLOUR) > 0.9


def test_moving_obstacle_and_escape_appear_in_time(animated):
    scenario, result, fig, frames, _ = animated
    start, end = result.obstacle_tracks[0, 0], result.obstacle_tracks[-1, 0]
    assert colour_near(frames[0], fig, start, sim_plot.MOVING_OBSTACLE_COLOUR)
    assert not colour_near(frames[0], fig, MOVER_TO, sim_plot.MOVING_OBSTACLE_COLOUR)
    assert colour_near(frames[-1], fig, end, sim_plot.MOVING_OBSTACLE_COLOUR)
    escape = result.escape_points[0]
    indices = animation.frame_indices(len(result.trajectory), MAX_FRAMES)
    steps = animation.escape_steps(result.trajectory, result.escape_points)
    for frame, i in zip(frames, indices):
        assert colour_near(frame, fig, escape, sim_plot.ESCAPE_COLOUR) == (i >= steps[0]), i


def test_a_run_without_trajectory_or_with_other_track_times_is_refused(tmp_path):
    scenario = write_room_scenario(tmp_path)
    result = hand_made_run(scenario)
    result.obstacle_tracks = result.obstacle_tracks[::2]
    with pytest.raises(ValueError, match='sampled'):
        animation.animate_episode(scenario, result, tmp_path / 'x.gif', 0.1)
    result.trajectory = None
    with pytest.raises(ValueError, match='no recorded trajectory'):
        animation.animate_episode(scenario, result, tmp_path / 'x.gif', 0.1)
    assert not (tmp_path / 'x.gif').exists()


def test_sim_command_writes_a_gif_and_refuses_it_for_a_batch(tmp_path, capsys):
    write_room_scenario(tmp_path)
    gif = tmp_path / 'run.gif'
    code = main(['sim', '--scenario', str(tmp_path / 'room_scenario.yaml'), '--gif', str(gif)])
    assert code in (0, 1)  # the gif is written either way
    frames, _ = read_gif(gif)
    assert len(frames) > 2
    assert main(['sim', '--random', '2', '--gif', str(tmp_path / 'batch.gif')]) == 2
    assert '--gif' in capsys.readouterr().err
