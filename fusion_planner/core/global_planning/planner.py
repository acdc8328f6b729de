"""Global planning in one call: validate, search, refine, measure.

:class:`GlobalPlanner` binds a :class:`~fusion_planner.core.grid.GridMap` and a
:class:`PlannerConfig`; it prepares the inflated search grid once and reuses
it for every plan on that map. :func:`plan_path` is the one-call form.

Examples
--------
>>> import numpy as np
>>> occupied = np.zeros((20, 20), bool); occupied[5:15, 10] = True
>>> result = plan_path(occupied, start=(2.5, 10.5), goal=(17.5, 10.5))
>>> result.path[0].tolist(), result.path[-1].tolist()
([2.5, 10.5], [17.5, 10.5])
>>> bool(result.metrics.length_m < 20.0)
True
"""

import math
import time
from dataclasses import dataclass, field, replace

import numpy as np

from fusion_planner.core import distance_transform
from fusion_planner.core.global_planning import (
    centring, landmarks, metrics, refine, search, straighten)
from fusion_planner.core.errors import (
    GoalOccupied, GoalOutsideMapBounds, InvalidInput, StartOccupied, StartOutsideMapBounds)
from fusion_planner.core.grid import GridMap

ALGORITHMS = ('dijkstra', 'astar', 'improved')

#: When prepared, a map gets its whole clearance map (8 bytes per cell), so
#: that each plan's metrics and refinement read clearances instead of
#: computing them around the path: every map when the compiled distance
#: transform is available (:mod:`~fusion_planner.core.distance_transform`,
#: 0.6 s and 128 MB for 4000 x 4000 cells), else maps of at most this many
#: cells (scipy's transform: about 0.1 s for 1024 x 1024). Larger maps keep
#: the local computation (:meth:`GridMap.clearance_of_cells`).
WHOLE_CLEARANCE_CELLS = 1 << 20

#: A path with its zig-zags folded replaces the refined one when it is at
#: most this fraction longer (see ``PlannerConfig.fewer_turns``).
FOLD_LENGTH_SLACK = 0.03


@dataclass(frozen=True)
class PlannerConfig:
    """Everything that tunes a global plan.

    Attributes
    ----------
    algorithm : str
        ``'dijkstra'``, ``'astar'`` or ``'improved'`` (the paper's improved A*).
    neighbourhood : int
        4, 8 or 16.
    heuristic : str or None
        ``'manhattan'``, ``'euclidean'`` or ``'octile'``; None picks the
        tightest admissible one for the neighbourhood for A*, and the
        Euclidean distance the paper uses (section 1.2) for the improved A*
        (ignored by Dijkstra).
    alpha, beta, gamma : float
        Improved A* weights of eqs. (5)-(8): g weight, h weight, gain of the
        heuristic weight w_n (:func:`~fusion_planner.core.global_planning.search.heuristic_weight`;
        0.2 was tuned on the MovingAI maps and a 1024 x 1024 random map,
        docs/BENCHMARKS.md).
    jump_points : bool
        A* with the 8-neighbourhood searches with jump-point pruning: the
        same optimal cost, far fewer expansions (``expanded`` then counts
        jump points). False expands cell by cell, as the paper's A*.
        Ignored by the other algorithms and neighbourhoods.
    landmarks : bool
        A* with the 4- or 8-neighbourhood takes as its heuristic the larger
        of the usual one and the landmark bounds that :meth:`GlobalPlanner.prepare`
        computes on maps of up to
        :data:`~fusion_planner.core.global_planning.landmarks.MAX_CELLS`
        cells (:mod:`~fusion_planner.core.global_planning.landmarks`): the
        same optimal cost, fewer expansions. False keeps the plain
        heuristic, as the paper's A*. Ignored by the other algorithms.
    refine : bool
        Remove redundant nodes and smooth (section 1.3.3, Table 2).
    centre : bool
        After refining, centre the path in its free corridor up to
        ``robot_radius + safety_distance`` of clearance
        (:func:`~fusion_planner.core.global_planning.centring.centre_path`;
        beyond the paper): the path a local controller can drive at speed.
    fewer_turns : bool
        After centring, fold the path's zig-zags into fewer, longer runs
        (for a robot of radius plus safety distance above 0) where that
        keeps the clearance and lengthens the path by at most
        :data:`FOLD_LENGTH_SLACK`
        (:mod:`~fusion_planner.core.global_planning.straighten`; beyond the
        paper): every corner costs a robot time.
    robot_radius : float
        Robot radius [m]; obstacles are inflated by it for the search.
    safety_distance : float
        Extra distance [m] a shortcut must keep from obstacles (1.3.3).
    path_spacing : float or None
        Spacing [m] of the points of a refined path; None: half a cell.
    max_expansions : int or None
        Search budget in expansions.
    time_limit_s : float or None
        Search budget in wall time [s].
    """

    algorithm: str = 'improved'
    neighbourhood: int = 8
    heuristic: str = None
    alpha: float = 1.0
    beta: float = 1.0
    gamma: float = 0.2
    jump_points: bool = True
    landmarks: bool = True
    refine: bool = True
    centre: bool = True
    fewer_turns: bool = True
    robot_radius: float = 0.0
    safety_distance: float = 0.0
    path_spacing: float = None
    max_expansions: int = None
    time_limit_s: float = None

    def __post_init__(self):
        if self.algorithm not in ALGORITHMS:
            raise InvalidInput(f'algorithm must be one of {ALGORITHMS}, got {self.algorithm!r}')
        for name in ('robot_radius', 'safety_distance'):
            value = getattr(self, name)
            if not (isinstance(value, (int, float)) and math.isfinite(value) and value >= 0):
                raise InvalidInput(f'{name} must be a non-negative number of metres, got {value!r}')
        self.policy()  # validates neighbourhood, heuristic and weights

    def policy(self):
        """The :class:`~fusion_planner.core.global_planning.search.SearchPolicy` of this config."""
        if self.algorithm == 'dijkstra':
            return search.dijkstra(self.neighbourhood)
        if self.algorithm == 'astar':
            return search.astar(self.neighbourhood, self.heuristic,
                                jump_points=self.jump_points and self.neighbourhood == 8,
                                landmarks=self.landmarks and self.neighbourhood in (4, 8))
        return search.improved_astar(
            alpha=self.alpha, beta=self.beta, gamma=self.gamma,
            neighbourhood=self.neighbourhood, heuristic=self.heuristic or 'euclidean')


@dataclass
class PlanMetrics:
    """Figures of one plan (the columns of the paper's Tables 1-2 and more).

    Attributes
    ----------
    length_m : float
        Path length [m].
    expanded : int
        Nodes expanded by the search ("search nodes" of Table 1).
    generated : int
        Nodes ever opened by the search.
    key_points : int
        Key nodes of the path: endpoints and turning points.
    turning_deg : float
        Total absolute heading change along the path [deg].
    min_clearance_m : float
        Smallest clearance [m] of a cell the path touches (cell-centre
        distance to the nearest obstacle cell centre).
    time_s : float
        Wall time of validation, search and refinement [s].
    """

    length_m: float
    expanded: int
    generated: int
    key_points: int
    turning_deg: float
    min_clearance_m: float
    time_s: float


@dataclass
class PlanResult:
    """A global plan.

    Attributes
    ----------
    path : ndarray, float64, shape (N, 2)
        The path [m], map frame, start to goal (refined when configured).
    key_nodes : ndarray, float64, shape (K, 2)
        Key nodes [m]: the pruned nodes of a refined path, or the turning
        points of a raw grid path; the A* sub-goals of the fusion follower.
    grid_path : ndarray, float64, shape (M, 2)
        The raw search path through cell centres [m].
    metrics : PlanMetrics
    expanded_cells : ndarray, int64, shape (E, 2) or None
        ``(row, col)`` of the expanded cells, when requested.
    """

    path: np.ndarray
    key_nodes: np.ndarray
    grid_path: np.ndarray
    metrics: PlanMetrics
    expanded_cells: np.ndarray = field(default=None, repr=False)


class GlobalPlanner:
    """Improved-A* (or classic) global planner bound to one map.

    Parameters
    ----------
    grid : GridMap
    config : PlannerConfig, optional

    Notes
    -----
    Inflation and the padded search grid are built on the first plan and
    reused while the map and the robot radius stay the same.
    """

    def __init__(self, grid, config=None):
        if not isinstance(grid, GridMap):
            raise InvalidInput('the planner needs a GridMap')
        self.grid = grid
        self.config = config or PlannerConfig()
        self._padded = None
        self._padded_radius = None

    def reconfigure(self, **changes):
        """Replace configuration fields (validated); keeps the map preparation."""
        self.config = replace(self.config, **changes)

    def prepare(self):
        """Prepare the map for the current configuration now; return the time taken [s].

        Builds what the first plan would otherwise build: the inflated
        traversable mask, the padded search grid, its move tables for the
        configured neighbourhood, and loads the compiled search loop
        (:meth:`~fusion_planner.core.global_planning.search.PaddedGrid.prepare`);
        the whole clearance map (see :data:`WHOLE_CLEARANCE_CELLS`); and for
        the exact A* on maps of up to
        :data:`~fusion_planner.core.global_planning.landmarks.MAX_CELLS`
        cells, the landmark distances that tighten its heuristic (see
        ``PlannerConfig.landmarks``). Plans without a preparation search
        without landmarks.
        Plans on an unchanged map and radius reuse them, so a caller that
        prepares when the map arrives keeps the plans' time to the search.
        Cheap when already prepared.
        """
        t0 = time.perf_counter()
        if distance_transform.AVAILABLE or self.grid.occupied.size <= WHOLE_CLEARANCE_CELLS:
            self.grid.clearance  # computed once and kept by the map
        padded = self._search_grid()
        padded.prepare(self.config.neighbourhood)
        if padded.landmarks is None and landmarks.wanted(self.grid.shape, self.config.policy()):
            padded.landmarks = landmarks.distance_table(padded)
        return time.perf_counter() - t0

    def _search_grid(self):
        radius = self.config.robot_radius
        if self._padded is None or self._padded_radius != radius:
            self._padded = search.PaddedGrid(self.grid.traversable(radius))
            self._padded_radius = radius
        return self._padded

    def plan(self, start, goal, cancel=None, return_expanded=False):
        """Plan from ``start`` to ``goal``.

        Parameters
        ----------
        start, goal : array_like, shape (2,)
            ``(x, y)`` [m], map frame.
        cancel : callable, optional
            Polled during the search; True stops it.
        return_expanded : bool
            Keep the expanded cells (for drawing).

        Returns
        -------
        PlanResult

        Raises
        ------
        InvalidInput
            NaN or infinite coordinates.
        StartOutsideMapBounds, GoalOutsideMapBounds
        StartOccupied
            The start is in an obstacle (a start inside the inflation only is
            accepted, so a robot pushed close to a wall can still get away).
        GoalOccupied
            The goal is in an obstacle or its inflation.
        NoValidPathCouldBeFound, PlannerTimedOut, PlannerCancelled
            From the search.
        """
        t0 = time.perf_counter()
        cfg = self.config
        grid = self.grid
        start_cell, goal_cell = self.cells_of(start, goal)
        padded = self._search_grid()
        found = search.grid_search(
            padded, start_cell, goal_cell, cfg.policy(),
            max_expansions=cfg.max_expansions, time_limit_s=cfg.time_limit_s,
            cancel=cancel, return_expanded=return_expanded)
        grid_path = grid.world_of(found.cells)
        if cfg.refine and len(grid_path) > 2:
            # Where the search path itself runs inside the safety margin (it
            # hugs the inflation), shortcuts may keep the margin it had.
            key_nodes = refine.prune_redundant(
                grid, grid_path, cfg.robot_radius, cfg.safety_distance,
                tolerate_input_margin=True)
            spacing = cfg.path_spacing or grid.resolution / 2
            path = refine.smooth_path(
                grid, key_nodes, cfg.robot_radius, cfg.safety_distance, spacing)
            if cfg.centre:
                path = centring.centre_path(grid, path, cfg.robot_radius, cfg.safety_distance)
            if cfg.fewer_turns:
                path, key_nodes = self._fewer_turns(path, key_nodes, spacing)
        else:
            key_nodes = grid_path[metrics.key_point_indices(grid_path)]
            path = grid_path
        elapsed = time.perf_counter() - t0
        plan_metrics = PlanMetrics(
            length_m=metrics.path_length(path),
            expanded=found.expanded,
            generated=found.generated,
            key_points=len(key_nodes),
            turning_deg=metrics.turning_angle_deg(path),
            min_clearance_m=metrics.min_clearance(grid, path),
            time_s=elapsed)
        return PlanResult(path=path, key_nodes=key_nodes, grid_path=grid_path,
                          metrics=plan_metrics, expanded_cells=found.expanded_cells)

    def _fewer_turns(self, path, key_nodes, spacing):
        """A refined path with its zig-zags folded, and its vertices as key nodes; or the inputs.

        See :mod:`~fusion_planner.core.global_planning.straighten`. The
        folded path is rounded and sampled like the first one (its runs were
        chosen for clearance, it is not centred again) and replaces it only
        when it is at most :data:`FOLD_LENGTH_SLACK` longer. A point robot
        (``robot_radius + safety_distance`` of 0, the paper's tables) keeps
        the path as the paper refines it, as with the centring.
        """
        cfg = self.config
        if cfg.robot_radius + cfg.safety_distance <= 0.0:
            return path, key_nodes
        vertices = straighten.fewer_turns(self.grid, path, cfg.robot_radius, cfg.safety_distance)
        if vertices is None:
            return path, key_nodes
        folded = refine.smooth_path(self.grid, vertices, cfg.robot_radius, cfg.safety_distance,
                                    spacing)
        if cfg.centre:
            folded = centring.centre_path(self.grid, folded, cfg.robot_radius, cfg.safety_distance)
        if metrics.path_length(folded) > (1.0 + FOLD_LENGTH_SLACK) * metrics.path_length(path):
            return path, key_nodes
        return folded, vertices

    def cells_of(self, start, goal):
        """Validate start and goal [m]; return their ``(row, col)`` cells.

        Raises the same errors as :meth:`plan` for bad endpoints.
        """
        grid = self.grid
        start_cell = tuple(int(v) for v in grid.cell_of(_point(start, 'start')))
        goal_cell = tuple(int(v) for v in grid.cell_of(_point(goal, 'goal')))
        if not grid.contains(start_cell):
            raise StartOutsideMapBounds(f'start {_fmt(start)} is outside the map')
        if not grid.contains(goal_cell):
            raise GoalOutsideMapBounds(f'goal {_fmt(goal)} is outside the map')
        if grid.occupied[start_cell]:
            raise StartOccupied(f'start {_fmt(start)} is inside an obstacle')
        if grid.occupied[goal_cell]:
            raise GoalOccupied(f'goal {_fmt(goal)} is inside an obstacle')
        if not grid.traversable(self.config.robot_radius)[goal_cell]:
            raise GoalOccupied(
                f'goal {_fmt(goal)} is closer to an obstacle than the robot radius '
                f'{self.config.robot_radius:g} m')
        return start_cell, goal_cell


def load_compiled_loops(config=None):
    """Load the compiled loops a planner of ``config`` runs, now; return the time taken [s].

    By preparing a planner on a 3 x 3 map: the distance transform and the
    search loop get loaded (numba imported, the machine code read from its
    cache or compiled). That takes about 0.4 s, up to 1.7 s on a busy
    machine, which the first map, plan or control step would otherwise
    stall for (the simulator waits 1 s for a command); a node does it while it
    configures, as Nav2's nodes do their heavy set-up. Quick without numba
    and once loaded.
    """
    occupied = np.zeros((3, 3), dtype=bool)
    occupied[0, 0] = True
    return GlobalPlanner(GridMap(occupied, resolution=1.0), config or PlannerConfig()).prepare()


def plan_path(occupancy, start, goal, resolution=1.0, origin=(0.0, 0.0, 0.0), config=None,
              **config_fields):
    """Plan on an occupancy array or a loaded map in one call.

    Parameters
    ----------
    occupancy : GridMap or array_like of bool, shape (H, W)
        A map, or True where a cell is an obstacle (row 0 at the origin).
    start, goal : array_like, shape (2,)
        ``(x, y)`` [m], map frame.
    resolution : float
        Cell edge [m] when ``occupancy`` is an array.
    origin : tuple of float
        ``(x, y, yaw)`` of the map origin when ``occupancy`` is an array.
    config : PlannerConfig, optional
    **config_fields
        Overrides of :class:`PlannerConfig` fields, e.g. ``algorithm='astar'``.

    Returns
    -------
    PlanResult

    Raises
    ------
    PlanningError
        Any of the errors of :meth:`GlobalPlanner.plan`.
    """
    grid = occupancy if isinstance(occupancy, GridMap) else GridMap(occupancy, resolution, origin)
    config = replace(config or PlannerConfig(), **config_fields)
    return GlobalPlanner(grid, config).plan(start, goal)


def _point(value, name):
    try:
        point = np.asarray(value, dtype=float).reshape(2)
    except (TypeError, ValueError):
        raise InvalidInput(f'{name} must be two numbers (x, y), got {value!r}') from None
    if not np.all(np.isfinite(point)):
        raise InvalidInput(f'{name} must be finite, got {point.tolist()}')
    return point


def _fmt(point):
    x, y = np.asarray(point, dtype=float).reshape(2)
    return f'({x:.3f}, {y:.3f})'
