"""Figures of plans and maps (the paper's Figures 3-4), for the CLI only.

matplotlib is imported inside the functions, and only its object-oriented
API with the Agg canvas is used (no ``pyplot``, no global backend switch), so
importing this module costs nothing, the core never depends on matplotlib,
and drawing works on a machine without a display.

Colours follow the paper's Figure 3: obstacles black, free space white,
searched (expanded) cells grey, the planned path blue with its key nodes as
small circles on it.
"""

import math

import numpy as np

#: RGB of the map layers, 0..1.
FREE_RGB = (1.0, 1.0, 1.0)
OBSTACLE_RGB = (0.0, 0.0, 0.0)
UNKNOWN_RGB = (0.55, 0.55, 0.55)
EXPANDED_RGB = (0.80, 0.80, 0.80)
#: Colour of the final (refined) path and of its key nodes.
PATH_COLOUR = '#0033ff'
#: Colour of the raw grid path of the search, drawn under the final path.
RAW_PATH_COLOUR = '#ff8c00'
START_COLOUR = '#00a000'
GOAL_COLOUR = '#e00000'
#: Size [inch] of the longer side of a figure.
FIGURE_INCHES = 6.0
#: Resolution of saved figures [dots per inch].
FIGURE_DPI = 100


def new_figure(grid=None, inches=FIGURE_INCHES, dpi=FIGURE_DPI):
    """A matplotlib Figure on an Agg canvas, shaped like the map.

    Parameters
    ----------
    grid : GridMap, optional
        When given, the figure's aspect ratio follows the map's extent.
    inches : float
        Length of the longer side [inch].
    dpi : float
        Resolution of the canvas [dots per inch].

    Returns
    -------
    matplotlib.figure.Figure
        With one Axes (``fig.axes[0]``); save it with ``fig.savefig(path)``.
    """
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure

    width, height = inches, inches
    if grid is not None:
        xmin, xmax, ymin, ymax = grid.bounds()
        ratio = (ymax - ymin) / (xmax - xmin)
        if ratio > 1:
            width = max(inches / ratio, 2.5)
        else:
            height = max(inches * ratio, 2.5)
    fig = Figure(figsize=(width, height), dpi=dpi)
    FigureCanvasAgg(fig)
    fig.add_subplot(1, 1, 1)
    return fig


def draw_grid(ax, grid, expanded_cells=None):
    """Draw a map: obstacles black, unknown grey, free white.

    Parameters
    ----------
    ax : matplotlib.axes.Axes
    grid : GridMap
        The map; drawn in metres in the map frame (the image is rotated by
        the origin yaw when it is not 0).
    expanded_cells : ndarray, int64, shape (E, 2), optional
        ``(row, col)`` of cells to shade light grey (the search nodes of the
        paper's Figure 3).

    Returns
    -------
    matplotlib.image.AxesImage
        The drawn image.

    Notes
    -----
    The image is drawn with ``origin='lower'`` so that row 0 (the row at the
    map origin) is at the bottom, with the extent of the map in metres and an
    equal aspect ratio: one cell is a square of ``resolution`` metres.
    """
    from matplotlib.transforms import Affine2D

    rgb = np.empty(grid.shape + (3,))
    rgb[...] = FREE_RGB
    if expanded_cells is not None and len(expanded_cells):
        cells = np.asarray(expanded_cells, dtype=np.int64).reshape(-1, 2)
        rgb[cells[:, 0], cells[:, 1]] = EXPANDED_RGB
    if grid.unknown is not None:
        rgb[grid.unknown & ~grid.occupied] = UNKNOWN_RGB
    rgb[grid.occupied] = OBSTACLE_RGB
    x0, y0, yaw = grid.origin
    extent = (x0, x0 + grid.width * grid.resolution, y0, y0 + grid.height * grid.resolution)
    image = ax.imshow(rgb, origin='lower', extent=extent, interpolation='nearest', zorder=0)
    if yaw != 0.0:
        image.set_transform(Affine2D().rotate_around(x0, y0, yaw) + ax.transData)
    xmin, xmax, ymin, ymax = grid.bounds()
    ax.set_xlim(xmin, xmax)
    ax.set_ylim(ymin, ymax)
    ax.set_aspect('equal')
    ax.set_xlabel('x [m]')
    ax.set_ylabel('y [m]')
    return image


def draw_plan(ax, result, grid, start=None, goal=None):
    """Draw a plan over a map drawn by :func:`draw_grid`.

    Parameters
    ----------
    ax : matplotlib.axes.Axes
    result : PlanResult or None
        The plan; None draws only the start and goal (a failed plan).
    grid : GridMap
    start, goal : array_like, shape (2,), optional
        ``(x, y)`` [m]; default the ends of ``result.path``.
    """
    if result is not None:
        path = np.asarray(result.path, dtype=float)
        raw = np.asarray(result.grid_path, dtype=float)
        if raw.shape != path.shape or not np.allclose(raw, path):
            ax.plot(raw[:, 0], raw[:, 1], color=RAW_PATH_COLOUR, lw=1.2, ls='--',
                    label='grid path', zorder=2)
        ax.plot(path[:, 0], path[:, 1], color=PATH_COLOUR, lw=2.0, label='path', zorder=3)
        keys = np.asarray(result.key_nodes, dtype=float).reshape(-1, 2)
        marker = max(3.0, min(7.0, 60.0 / math.sqrt(max(grid.width, grid.height))))
        ax.plot(keys[:, 0], keys[:, 1], ls='none', marker='o', ms=marker, mfc='white',
                mec=PATH_COLOUR, mew=1.2, label='key nodes', zorder=4)
        if start is None:
            start = path[0]
        if goal is None:
            goal = path[-1]
    if start is not None:
        ax.plot(*np.asarray(start, float).reshape(2), ls='none', marker='o', ms=9,
                color=START_COLOUR, label='start', zorder=5)
    if goal is not None:
        ax.plot(*np.asarray(goal, float).reshape(2), ls='none', marker='*', ms=13,
                color=GOAL_COLOUR, label='goal', zorder=5)


def plan_title(result, algorithm=None):
    """One-line figure title with the metrics of a plan (Table 1 columns)."""
    head = f'{algorithm}: ' if algorithm else ''
    if result is None:
        return f'{head}no path'
    m = result.metrics
    return (f'{head}{m.length_m:.2f} m, {m.expanded} expanded, {m.key_points} key points, '
            f'{m.turning_deg:.0f} deg')


def plot_plan(result, grid, path_png, title=None, start=None, goal=None):
    """Save a figure of a plan like the paper's Figures 3-4.

    Parameters
    ----------
    result : PlanResult or None
        The plan, planned with ``return_expanded=True`` to show the searched
        cells; None draws the map with the start and goal only.
    grid : GridMap
        The map planned on.
    path_png : str or os.PathLike
        Output file; the format follows the extension (PNG normally).
    title : str, optional
        Figure title; default the plan's metrics.
    start, goal : array_like, shape (2,), optional
        ``(x, y)`` [m]; default the ends of the path.

    Returns
    -------
    matplotlib.figure.Figure
        The saved figure (for tests and further drawing).

    Notes
    -----
    Drawn: obstacles (black), expanded cells (light grey, "searched cells"
    in the legend), the raw grid path of the search (dashed orange, when
    refinement changed it), the final path (blue), its key nodes (small
    circles), the start (green dot) and the goal (red star).
    """
    fig = new_figure(grid)
    ax = fig.axes[0]
    expanded = None if result is None else result.expanded_cells
    draw_grid(ax, grid, expanded_cells=expanded)
    draw_plan(ax, result, grid, start=start, goal=goal)
    ax.set_title(title if title is not None else plan_title(result), fontsize=9)
    handles, _ = ax.get_legend_handles_labels()
    if expanded is not None and len(expanded):
        from matplotlib.patches import Patch
        handles.insert(0, Patch(facecolor=EXPANDED_RGB, edgecolor='none', label='searched cells'))
    ax.legend(handles=handles, loc='upper center', bbox_to_anchor=(0.5, -0.13), ncol=5,
              fontsize=7, frameon=False, handlelength=1.5)
    fig.tight_layout()
    fig.savefig(path_png, dpi=FIGURE_DPI)
    return fig
