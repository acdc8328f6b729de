"""One best-first search engine on a grid; algorithms are policies.

Dijkstra, A* with 4-, 8- and 16-neighbourhoods, and the paper's improved A*
share the loop in :func:`grid_search`; they differ only in their
:class:`SearchPolicy`: the neighbourhood table, the heuristic (eqs. 2-4),
the weights of eq. (5), the distance-dependent heuristic weight of eqs.
(6)-(8) and the variable neighbourhood of section 1.3.1.

Costs are in cells (an orthogonal step costs 1, a diagonal sqrt(2)).
Cells are ``(row, col)``. The engine works on a flat, padded copy of the
traversable mask so that a neighbour lookup is one index operation and no
bounds check.

References
----------
P. E. Hart, N. J. Nilsson, B. Raphael, "A Formal Basis for the Heuristic
Determination of Minimum Cost Paths", IEEE TSSC 4(2), 1968.
"""

import heapq
import math
import time
from dataclasses import dataclass

import numpy as np

from fusion_planner.core import neighbourhood as nbh
from fusion_planner.core.errors import (
    InvalidInput, NoValidPathCouldBeFound, PlannerCancelled, PlannerTimedOut)

HEURISTICS = ('zero', 'manhattan', 'euclidean', 'octile')

#: Border of blocked cells around the padded grid; the 16-neighbourhood
#: reaches two cells away.
_PAD = 2
#: Limits and cancellation are checked once per this many expansions.
_CHECK_EVERY = 1024


@dataclass(frozen=True)
class SearchPolicy:
    """What distinguishes one best-first algorithm from another.

    Attributes
    ----------
    neighbourhood : int
        4, 8 or 16 (section 1.2).
    heuristic : str
        ``'zero'`` (Dijkstra), ``'manhattan'`` (eq. 2), ``'euclidean'``
        (eq. 3) or ``'octile'`` (eq. 4, printed as "Chebyshev" in the paper).
    alpha, beta : float
        Weights of g and h in eq. (5) / eq. (8); > 0.
    gamma : float
        Gain of the distance-dependent heuristic weight w_n of eqs. (6)-(8),
        >= 0; 0 gives w_n = 1. See :func:`heuristic_weight`.
    variable_neighbourhood : bool
        Search only the moves heading towards the goal (section 1.3.1),
        widening when they make no progress.
    """

    neighbourhood: int = 8
    heuristic: str = 'octile'
    alpha: float = 1.0
    beta: float = 1.0
    gamma: float = 0.0
    variable_neighbourhood: bool = False

    def __post_init__(self):
        if self.neighbourhood not in nbh.SUPPORTED:
            raise InvalidInput(f'neighbourhood must be one of {nbh.SUPPORTED}, got {self.neighbourhood!r}')
        if self.heuristic not in HEURISTICS:
            raise InvalidInput(f'heuristic must be one of {HEURISTICS}, got {self.heuristic!r}')
        for name in ('alpha', 'beta'):
            value = getattr(self, name)
            if not (isinstance(value, (int, float)) and math.isfinite(value) and value > 0):
                raise InvalidInput(f'{name} must be a positive number, got {value!r}')
        if not (isinstance(self.gamma, (int, float)) and math.isfinite(self.gamma) and self.gamma >= 0):
            raise InvalidInput(f'gamma must be a non-negative number, got {self.gamma!r}')


def dijkstra(neighbourhood=8):
    """Policy of Dijkstra's algorithm (no heuristic)."""
    return SearchPolicy(neighbourhood=neighbourhood, heuristic='zero')


def astar(neighbourhood=8, heuristic=None):
    """Policy of the classic A* (eq. 1).

    The default heuristic is the tightest admissible one for the
    neighbourhood: Manhattan for 4, octile for 8, Euclidean for 16.
    """
    if heuristic is None:
        heuristic = {4: 'manhattan', 8: 'octile', 16: 'euclidean'}.get(neighbourhood, 'octile')
    return SearchPolicy(neighbourhood=neighbourhood, heuristic=heuristic)


def improved_astar(alpha=1.0, beta=1.0, gamma=0.1, neighbourhood=8, heuristic='octile'):
    """Policy of the paper's improved A* (sections 1.3.1 and 1.3.2)."""
    return SearchPolicy(neighbourhood=neighbourhood, heuristic=heuristic, alpha=alpha,
                        beta=beta, gamma=gamma, variable_neighbourhood=True)


def heuristic_weight(h, start_distance, gamma):
    """Distance-dependent heuristic weight w_n, our reading of eqs. (6)-(8).

    Parameters
    ----------
    h : float
        Heuristic distance from the node to the goal [cells].
    start_distance : float
        Heuristic distance from the start to the goal, S of eq. (6) [cells].
    gamma : float
        Gain, >= 0.

    Returns
    -------
    float
        ``w_n = 1 + gamma * (exp(r) - 1)`` with ``r = h / S``: 1 at the goal
        (plain A* close to the goal, where precision matters) rising to
        ``1 + gamma * (e - 1)`` at the start distance (greedy far away, where
        speed matters). Using r instead of the raw distance of the printed
        formula keeps the exponential bounded on any map size.

    Examples
    --------
    >>> heuristic_weight(0.0, 10.0, 1.0)
    1.0
    >>> round(heuristic_weight(10.0, 10.0, 1.0), 4)
    2.7183
    """
    if start_distance <= 0:
        return 1.0
    return 1.0 + gamma * (math.exp(h / start_distance) - 1.0)


@dataclass
class SearchResult:
    """Outcome of :func:`grid_search`.

    Attributes
    ----------
    cells : ndarray, int64, shape (N, 2)
        ``(row, col)`` of the path from start to goal, both included.
    cost : float
        Path cost [cells].
    expanded : int
        Number of nodes expanded (closed).
    generated : int
        Number of nodes ever opened (given a g value), the start included.
    expanded_cells : ndarray, int64, shape (M, 2) or None
        The expanded cells, when requested.
    """

    cells: np.ndarray
    cost: float
    expanded: int
    generated: int
    expanded_cells: np.ndarray = None


class PaddedGrid:
    """A traversable mask flattened with a blocked border, for the engine.

    Build once per map and inflation radius and reuse across searches.

    Parameters
    ----------
    traversable : ndarray of bool, shape (H, W)
    """

    def __init__(self, traversable):
        mask = np.asarray(traversable, dtype=bool)
        self.shape = mask.shape
        self.width = mask.shape[1] + 2 * _PAD
        padded = np.zeros((mask.shape[0] + 2 * _PAD, self.width), dtype=np.uint8)
        padded[_PAD:-_PAD, _PAD:-_PAD] = mask
        self.passable = bytearray(padded.tobytes())

    def index(self, cell):
        """Flat index of a ``(row, col)`` cell."""
        return (int(cell[0]) + _PAD) * self.width + int(cell[1]) + _PAD

    def cells(self, indices):
        """``(row, col)`` array of flat indices; shape (N, 2), int64."""
        flat = np.fromiter(indices, dtype=np.int64)
        rows, cols = np.divmod(flat, self.width)
        return np.stack([rows - _PAD, cols - _PAD], axis=1)


def _heuristic_term(policy, goal_row, goal_col, width, start_index):
    """The weighted heuristic term ``beta * h * w_n`` of eq. (8), as f(index)."""
    kind = policy.heuristic
    if kind == 'zero':
        return lambda index: 0.0
    root2_minus_2 = math.sqrt(2.0) - 2.0

    def h(index):
        row, col = divmod(index, width)
        dx = abs(col - goal_col)
        dy = abs(row - goal_row)
        if kind == 'octile':  # eq. (4)
            return dx + dy + root2_minus_2 * (dx if dx < dy else dy)
        if kind == 'euclidean':  # eq. (3)
            return math.sqrt(dx * dx + dy * dy)
        return dx + dy  # eq. (2)

    beta, gamma = policy.beta, policy.gamma
    if gamma == 0.0:
        return lambda index: beta * h(index)
    start_distance = h(start_index)  # S of eq. (6)

    def weighted(index):
        hn = h(index)
        return beta * hn * heuristic_weight(hn, start_distance, gamma)
    return weighted


def grid_search(grid, start, goal, policy, max_expansions=None, time_limit_s=None,
                cancel=None, return_expanded=False):
    """Best-first search from ``start`` to ``goal`` on a padded grid.

    Parameters
    ----------
    grid : PaddedGrid
        Traversable cells. The start cell is searched from even when it is
        not traversable (a robot inside the inflation must still get out).
    start, goal : tuple of int
        ``(row, col)`` inside the grid; the goal must be traversable.
    policy : SearchPolicy
    max_expansions : int, optional
        Stop with :class:`PlannerTimedOut` after this many expansions.
    time_limit_s : float, optional
        Stop with :class:`PlannerTimedOut` after this much wall time [s].
    cancel : callable, optional
        Polled every 1024 expansions; returning True stops the search with
        :class:`PlannerCancelled`.
    return_expanded : bool
        Fill :attr:`SearchResult.expanded_cells`.

    Returns
    -------
    SearchResult

    Raises
    ------
    NoValidPathCouldBeFound
        If every cell reachable from the start was expanded.
    PlannerTimedOut, PlannerCancelled
        As above.

    Notes
    -----
    The evaluation is ``f = alpha * g + beta * h * w_n`` (eqs. 5 and 8), with
    ``w_n = 1`` unless ``policy.gamma > 0``. Ties in f go to the node with the
    smaller heuristic term (nearer the goal), which keeps A* from expanding
    whole plateaus of equal f on open maps. A node's g is never revised
    after it is closed, so with weights > 1 the path is within the largest
    weight of the optimum (weighted A*); with ``alpha = beta = 1`` and
    ``gamma = 0`` and an admissible heuristic it is optimal.

    With the variable neighbourhood (section 1.3.1) a node is first expanded
    with the moves heading towards the goal only. When none of them opens or
    improves a node it is widened at once to the full neighbourhood;
    otherwise the node is queued again with the best f its remaining moves
    would give, and widened when that entry comes up (the idea of partial
    expansion A*, Yoshizumi et al., AAAI 2000). So the remaining moves are
    tried exactly when the search would need them: the search stays complete
    and finds the same path as with the full neighbourhood, while the
    nodes it never needs sideways or backwards are not generated.

    Examples
    --------
    >>> import numpy as np
    >>> free = np.ones((3, 3), bool); free[1, 1] = False
    >>> result = grid_search(PaddedGrid(free), (0, 0), (2, 2), astar(8))
    >>> result.cells.tolist(), round(result.cost, 3)
    ([[0, 0], [0, 1], [0, 2], [1, 2], [2, 2]], 4.0)
    """
    width = grid.width
    passable = grid.passable
    table = nbh.moves(policy.neighbourhood)
    # (flat offset, cost, crossed offset a, crossed offset b); an orthogonal
    # move "crosses" its own source twice, so the check is branch-free.
    flat_moves = []
    for dr, dc, cost, crossed in table:
        a, b = (crossed + ((0, 0), (0, 0)))[:2]
        flat_moves.append((dr * width + dc, cost, a[0] * width + a[1], b[0] * width + b[1]))
    if policy.variable_neighbourhood:
        forward, rest = nbh.sector_split(table)
        forward_moves = [[flat_moves[i] for i in idx] for idx in forward]
        rest_moves = [[flat_moves[i] for i in idx] for idx in rest]

    s = grid.index(start)
    t = grid.index(goal)
    goal_row, goal_col = divmod(t, width)
    term = _heuristic_term(policy, goal_row, goal_col, width, s)
    alpha = policy.alpha
    variable = policy.variable_neighbourhood
    deadline = None if time_limit_s is None else time.monotonic() + time_limit_s

    g = {s: 0.0}
    parent = {s: -1}
    closed = set()
    h0 = term(s)
    heap = [(h0, h0, s, False)]
    push, pop = heapq.heappush, heapq.heappop
    expanded = 0
    found = False
    while heap:
        f, _, j, is_deferred = pop(heap)
        if is_deferred:
            # Second pass of a reduced expansion: its remaining moves.
            row, col = divmod(j, width)
            candidates = rest_moves[nbh.sector_of(goal_row - row, goal_col - col)]
        else:
            if j in closed:
                continue
            if j == t:
                found = True
                break
            closed.add(j)
            expanded += 1
            if expanded % _CHECK_EVERY == 0:
                if max_expansions is not None and expanded >= max_expansions:
                    raise PlannerTimedOut(
                        f'search stopped after {expanded} expansions without reaching the goal')
                if deadline is not None and time.monotonic() > deadline:
                    raise PlannerTimedOut(
                        f'search stopped after {time_limit_s:g} s without reaching the goal')
                if cancel is not None and cancel():
                    raise PlannerCancelled('search cancelled by the caller')
            if variable:
                row, col = divmod(j, width)
                sector = nbh.sector_of(goal_row - row, goal_col - col)
                candidates = forward_moves[sector]
            else:
                candidates = flat_moves
        gj = g[j]
        while True:
            opened = False
            for offset, cost, a, b in candidates:
                k = j + offset
                if not passable[k] or k in closed or not (passable[j + a] and passable[j + b]):
                    continue
                ng = gj + cost
                if ng < g.get(k, math.inf):
                    g[k] = ng
                    parent[k] = j
                    hk = term(k)
                    push(heap, (alpha * ng + hk, hk, k, False))
                    opened = True
            if not variable or is_deferred or candidates is rest_moves[sector]:
                break
            if opened:
                # Re-queue the node at the best f its remaining moves would
                # give, so they are tried exactly when A* would need them.
                best_f, best_h = math.inf, 0.0
                for offset, cost, a, b in rest_moves[sector]:
                    k = j + offset
                    if not passable[k] or k in closed or not (passable[j + a] and passable[j + b]):
                        continue
                    ng = gj + cost
                    if ng < g.get(k, math.inf):
                        hk = term(k)
                        if alpha * ng + hk < best_f:
                            best_f, best_h = alpha * ng + hk, hk
                if best_f < math.inf:
                    push(heap, (best_f, best_h, j, True))
                break
            candidates = rest_moves[sector]  # widen at once: no progress ahead
    if not found:
        raise NoValidPathCouldBeFound(
            f'no path from cell {tuple(start)} to cell {tuple(goal)} '
            f'({expanded} cells expanded)')

    chain = []
    j = t
    while j != -1:
        chain.append(j)
        j = parent[j]
    chain.reverse()
    return SearchResult(
        cells=grid.cells(chain), cost=g[t], expanded=expanded, generated=len(g),
        expanded_cells=grid.cells(closed) if return_expanded else None)
