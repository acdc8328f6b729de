"""Replanning for the fusion escape: remembered obstacle points and a grid replanner.

:class:`ObstacleMemory` keeps the static obstacle points the robot has seen
(scan points not on a tracked obstacle, thinned), added at most once per
:data:`MEMORY_PERIOD`; :class:`GridReplanner` plans around the known map
with them burnt in. Together they are the ``replan`` step of the escape (see
:mod:`fusion_planner.core.local_planning.escape`).

Examples
--------
>>> import numpy as np
>>> memory = ObstacleMemory(spacing=0.1)
>>> memory.add(0.0, np.array([[1.0, 1.0], [1.01, 1.0]]))
>>> memory.due(0.5), memory.due(1.0), len(memory.points)
(False, True, 1)
"""

import math
from dataclasses import replace

import numpy as np

from fusion_planner.core.errors import (
    GoalOccupied, InvalidInput, NoValidPathCouldBeFound, StartOccupied)
from fusion_planner.core.grid import GridMap
from fusion_planner.core.local_planning.local_geometry import thin_points
from fusion_planner.core.global_planning.planner import GlobalPlanner, PlannerConfig

#: Period [s] at which static obstacle points are added to the memory.
MEMORY_PERIOD = 1.0

#: Cap on the remembered obstacle points (oldest dropped first).
MAX_MEMORY_POINTS = 20000

#: A point within this many cells (cell-centre clearance) of an occupied map
#: cell is explained by the map; the replanner does not add it again.
KNOWN_POINT_CELLS = 1.5


class ObstacleMemory:
    """Static obstacle points seen so far, thinned to one per ``spacing`` square.

    Parameters
    ----------
    spacing : float
        Thinning square edge [m], > 0.

    Attributes
    ----------
    points : ndarray, float64, shape (M, 2)
        Remembered points [m], map frame, newest first; at most
        :data:`MAX_MEMORY_POINTS`.
    """

    def __init__(self, spacing):
        self.spacing = spacing
        self.points = np.zeros((0, 2))
        self._time = -math.inf

    def due(self, t):
        """Whether :data:`MEMORY_PERIOD` has passed at time ``t`` [s] since the last addition."""
        return t - self._time >= MEMORY_PERIOD

    def add(self, t, points):
        """Remember static ``points`` ``(M, 2)`` [m] seen at time ``t`` [s]."""
        self._time = t
        if len(points) == 0:
            return
        merged = thin_points(np.vstack([points, self.points]), self.spacing)
        self.points = merged[:MAX_MEMORY_POINTS]


class GridReplanner:
    """Global replanning on the known map with remembered obstacle points added.

    A ``replan`` callable for
    :class:`~fusion_planner.core.local_planning.field_follower.FieldFollower`: the points (obstacles
    the robot has seen) are burnt into a copy of the map as occupied cells,
    then :class:`~fusion_planner.core.global_planning.planner.GlobalPlanner` plans as usual
    (inflation, improved A*, refinement).

    Parameters
    ----------
    grid : GridMap
        The known map.
    config : PlannerConfig, optional
        Planner configuration (its ``robot_radius`` inflates the new cells
        too).
    robot_radius : float, optional
        The robot's own radius [m], when the configuration inflates by more
        (a comfort margin): a plan that fails with the margin is tried again
        with the radius alone before the goal counts as unreachable, so a
        gap the robot fits through is not taken for a wall.

    Raises
    ------
    InvalidInput
        If ``grid`` is not a GridMap, ``config`` not a PlannerConfig, or
        ``robot_radius`` not a finite number >= 0.
    """

    def __init__(self, grid, config=None, robot_radius=None):
        if not isinstance(grid, GridMap):
            raise InvalidInput('GridReplanner needs a GridMap')
        if config is not None and not isinstance(config, PlannerConfig):
            raise InvalidInput('GridReplanner config must be a PlannerConfig')
        if robot_radius is not None and not (
                isinstance(robot_radius, (int, float)) and math.isfinite(robot_radius)
                and robot_radius >= 0):
            raise InvalidInput(f'robot_radius must be a number of metres >= 0, got {robot_radius!r}')
        self.grid = grid
        self.config = config or PlannerConfig()
        self.robot_radius = robot_radius

    def __call__(self, start, goal, obstacle_points):
        """Plan from ``start`` to ``goal`` [m] around the map and ``obstacle_points`` (M, 2) [m].

        Points within ``robot_radius`` plus one cell of the start or the goal
        are left out: the robot stands there, so they cannot be static
        obstacles (a person passing by, noise). So are points the map already
        explains (within :data:`KNOWN_POINT_CELLS` cells of an occupied
        cell): a laser hit on a wall's face may fall in the free cell beside
        it, and burning that cell in would narrow every door by a cell.

        Returns
        -------
        path : ndarray, float64, shape (N, 2)
        key_nodes : ndarray, float64, shape (K, 2)

        Raises
        ------
        PlanningError
            Any planner outcome (no path, start or goal blocked ...); no
            path and a blocked goal only when they hold for ``robot_radius``
            too, and not when the start itself lies within that radius of an
            obstacle (then :class:`StartOccupied`: a robot wedged in a gap
            proves nothing about the goal).
        """
        grid = self.grid
        start = np.asarray(start, dtype=float)
        goal = np.asarray(goal, dtype=float)
        points = np.asarray(obstacle_points, dtype=float).reshape(-1, 2)
        points = points[np.all(np.isfinite(points), axis=1)]
        occupied = grid.occupied.copy()
        if len(points):
            keep_clear = self.config.robot_radius + grid.resolution
            keep = ((np.hypot(*(points - start).T) > keep_clear)
                    & (np.hypot(*(points - goal).T) > keep_clear)
                    & (grid.clearance_at(points) > KNOWN_POINT_CELLS * grid.resolution))
            cells = grid.cell_of(points[keep])
            cells = cells[grid.contains(cells)]
            occupied[cells[:, 0], cells[:, 1]] = True
        known = GridMap(occupied, grid.resolution, grid.origin)
        try:
            plan = GlobalPlanner(known, self.config).plan(start, goal)
        except (NoValidPathCouldBeFound, GoalOccupied):
            radius = self.config.robot_radius if self.robot_radius is None \
                else min(self.robot_radius, self.config.robot_radius)
            if known.clearance_at(start[None, :])[0] <= radius:
                # wedged: the search cannot leave the start, which proves nothing
                raise StartOccupied(
                    f'the robot at ({start[0]:.2f}, {start[1]:.2f}) stands within {radius:g} m '
                    'of an obstacle: no plan can leave from here') from None
            if radius >= self.config.robot_radius:
                raise
            plan = GlobalPlanner(known, replace(self.config, robot_radius=radius)).plan(start, goal)
        return plan.path, plan.key_nodes
