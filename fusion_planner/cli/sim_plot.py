"""Figures of closed-loop runs, like the paper's Figures 5 and 6 (CLI only).

Colours follow the paper's Figure 6 where it names them: the start blue, the
goal red, static obstacles the map did not show green, moving obstacles
yellow, the driven trajectory red. The A* plan is drawn thin blue with its
key nodes (dashed for the field controllers, which do not use it), escape
points (where the controller started escaping a local minimum) as magenta
crosses. matplotlib is imported inside the functions
(object-oriented API on an Agg canvas, as in :mod:`fusion_planner.cli.plotting`).
"""

import numpy as np

from fusion_planner.cli.plotting import FIGURE_DPI, draw_grid, new_figure
from fusion_planner.core.simulation.episodes import PLAN_FOLLOWERS
from fusion_planner.core.simulation.world import Circle, Rectangle

#: Colours of the layers (paper's Figure 6 where it gives them).
UNKNOWN_OBSTACLE_COLOUR = '#2ca02c'
MOVING_OBSTACLE_COLOUR = '#f0c000'
MOVING_EDGE_COLOUR = '#8a6d00'
TRAJECTORY_COLOUR = '#e00000'
PLAN_COLOUR = '#3060ff'
START_COLOUR = '#0050ff'
GOAL_COLOUR = '#e00000'
ESCAPE_COLOUR = '#d000d0'
#: Opacity of the moving obstacles' start positions (their end is opaque).
START_ALPHA = 0.35


def draw_static_obstacles(ax, obstacles):
    """Draw unknown static obstacles (circles and rectangles) filled green."""
    from matplotlib.patches import Circle as CirclePatch
    from matplotlib.patches import Rectangle as RectanglePatch

    for i, obstacle in enumerate(obstacles):
        label = 'unknown obstacle' if i == 0 else None
        if isinstance(obstacle, Circle):
            patch = CirclePatch(obstacle.center, obstacle.radius, color=UNKNOWN_OBSTACLE_COLOUR,
                                label=label, zorder=2)
        elif isinstance(obstacle, Rectangle):
            (x0, y0), (x1, y1) = obstacle.min, obstacle.max
            patch = RectanglePatch((x0, y0), x1 - x0, y1 - y0, color=UNKNOWN_OBSTACLE_COLOUR,
                                   label=label, zorder=2)
        else:
            continue
        ax.add_patch(patch)


def draw_moving_obstacles(ax, scenario, tracks):
    """Draw moving obstacle tracks (lines), start positions (faint) and end positions (discs).

    Parameters
    ----------
    ax : matplotlib.axes.Axes
    scenario : Scenario
    tracks : ndarray, shape (T, K, 2) or None
        Centres over time [m]; None draws the start positions only.
    """
    from matplotlib.patches import Circle as CirclePatch

    for k, mover in enumerate(scenario.moving_obstacles):
        first = mover.start_position()
        ax.add_patch(CirclePatch(first, mover.radius, facecolor=MOVING_OBSTACLE_COLOUR,
                                 edgecolor=MOVING_EDGE_COLOUR, alpha=START_ALPHA, zorder=3))
        if tracks is None or tracks.shape[0] == 0:
            continue
        track = tracks[:, k, :]
        ax.plot(track[:, 0], track[:, 1], color=MOVING_EDGE_COLOUR, lw=0.8, ls=':',
                label='moving obstacle track' if k == 0 else None, zorder=3)
        ax.add_patch(CirclePatch(track[-1], mover.radius, facecolor=MOVING_OBSTACLE_COLOUR,
                                 edgecolor=MOVING_EDGE_COLOUR, zorder=4,
                                 label='moving obstacle (end)' if k == 0 else None))


def episode_title(scenario, result):
    """One-line title: scenario, controller, outcome and figures."""
    outcome = 'reached' if result.reached else f'NOT reached ({(result.failure or "").split(":")[0]})'
    return (f'{scenario.name} / {result.controller}: {outcome}, {result.time_s:.1f} s, '
            f'{result.path_length_m:.1f} m, {result.collisions} collisions, '
            f'{result.stuck_events} stuck')


def draw_plan(ax, result):
    """Draw the A* plan and its key nodes of a run (nothing when it has none).

    Parameters
    ----------
    ax : matplotlib.axes.Axes
    result : EpisodeResult
        Its ``plan_path`` (N, 2) and ``key_nodes`` (K, 2) [m, map frame];
        the plan is dashed for a controller that does not follow it.
    """
    if result.plan_path is None:
        return
    plan = np.asarray(result.plan_path)
    followed = result.controller in PLAN_FOLLOWERS
    ax.plot(plan[:, 0], plan[:, 1], color=PLAN_COLOUR, lw=1.2, ls='-' if followed else '--',
            label='A* plan' if followed else 'A* plan (not used)', zorder=5)
    if result.key_nodes is not None and len(result.key_nodes):
        keys = np.asarray(result.key_nodes)
        ax.plot(keys[:, 0], keys[:, 1], ls='none', marker='o', ms=4, mfc='white',
                mec=PLAN_COLOUR, mew=1.0, label='key nodes', zorder=5)


def draw_trajectory(ax, trajectory):
    """Draw the driven trajectory; returns the line (``set_data`` animates it).

    Parameters
    ----------
    ax : matplotlib.axes.Axes
    trajectory : ndarray, shape (T, 2) or (T, 3)
        Poses ``(x, y[, yaw])`` [m, m, rad], map frame.

    Returns
    -------
    matplotlib.lines.Line2D
    """
    traj = np.asarray(trajectory, dtype=float).reshape(-1, np.shape(trajectory)[-1])
    (line,) = ax.plot(traj[:, 0], traj[:, 1], color=TRAJECTORY_COLOUR, lw=1.8,
                      label='trajectory', zorder=6)
    return line


def draw_escapes(ax, points):
    """Mark where the controller began escaping a local minimum (magenta crosses).

    Parameters
    ----------
    ax : matplotlib.axes.Axes
    points : ndarray, shape (E, 2)
        Escape points [m], map frame; E may be 0 (the label is kept, so the
        legend of an animation that meets its first escape later is stable).

    Returns
    -------
    matplotlib.lines.Line2D
    """
    points = np.asarray(points, dtype=float).reshape(-1, 2)
    (line,) = ax.plot(points[:, 0], points[:, 1], ls='none', marker='x', ms=8, mew=2,
                      color=ESCAPE_COLOUR, label='escape', zorder=7)
    return line


def draw_endpoints(ax, scenario):
    """Draw the start (blue) and goal (red) of a scenario."""
    ax.plot(scenario.start[0], scenario.start[1], ls='none', marker='o', ms=9,
            color=START_COLOUR, label='start', zorder=8)
    ax.plot(scenario.goal[0], scenario.goal[1], ls='none', marker='o', ms=9,
            color=GOAL_COLOUR, label='goal', zorder=8)


def add_legend(ax):
    """The legend below the map, as in every figure of a run."""
    ax.legend(loc='upper center', bbox_to_anchor=(0.5, -0.12), ncol=4, fontsize=7,
              frameon=False, handlelength=1.5)


def plot_episode(scenario, result, path_png, title=None):
    """Save a figure of one run.

    Parameters
    ----------
    scenario : Scenario
    result : EpisodeResult
        Recorded with ``record=True``.
    path_png : str or os.PathLike
        Output file (format from the extension).
    title : str, optional
        Default :func:`episode_title`.

    Returns
    -------
    matplotlib.figure.Figure

    Notes
    -----
    Drawn: the known map (black), unknown static obstacles (green), the
    moving obstacles' tracks with their start (faint) and end positions
    (yellow), the A* plan with its key nodes (blue), the driven trajectory
    (red), the escape points (magenta crosses), the start and the goal.
    """
    fig = new_figure(scenario.grid)
    ax = fig.axes[0]
    draw_grid(ax, scenario.grid)
    draw_static_obstacles(ax, scenario.unknown_obstacles)
    draw_moving_obstacles(ax, scenario, result.obstacle_tracks)
    draw_plan(ax, result)
    if result.trajectory is not None and len(result.trajectory):
        draw_trajectory(ax, result.trajectory)
    if len(result.escape_points):
        draw_escapes(ax, result.escape_points)
    draw_endpoints(ax, scenario)
    ax.set_title(title if title is not None else episode_title(scenario, result), fontsize=8)
    add_legend(ax)
    fig.tight_layout()
    fig.savefig(path_png, dpi=FIGURE_DPI)
    return fig
