"""One best-first search engine on a grid; algorithms are policies.

Dijkstra, A* with 4-, 8- and 16-neighbourhoods, and the paper's improved A*
share the loop in :func:`grid_search`; they differ only in their
:class:`SearchPolicy`: the neighbourhood table, the heuristic (eqs. 2-4),
the weights of eq. (5), the heuristic weight of eqs. (6)-(8) and the
variable neighbourhood of section 1.3.1.

Costs are in cells (an orthogonal step costs 1, a diagonal sqrt(2)).
Cells are ``(row, col)``. The engine works on a flat, padded copy of the
traversable mask so that a neighbour lookup is one index operation and no
bounds check.

How the loop is kept fast in pure Python (see docs/BENCHMARKS.md):

- the moves that may leave a cell (target free, no corner cut) are a
  per-cell bitmask computed once per map with numpy
  (:meth:`PaddedGrid.allowed_moves`), and each bitmask value has its list of
  moves precomputed (:meth:`PaddedGrid.move_tables`, per goal sector for the
  variable neighbourhood), so the loop visits only legal moves and never
  tests a wall or a corner;
- one byte per cell holds the whole per-search state (never reached, open
  with the move that reached it, closed), so "closed?", "seen?" and the
  parent are one index operation and the path is rebuilt from move codes;
- the costs g live in a flat float array reused across searches on the
  same grid (no per-search allocation of map size);
- the heuristic is computed inline from the row and column offsets, and
  the heuristic weight of eqs. (6)-(8) is one factor per search.

References
----------
P. E. Hart, N. J. Nilsson, B. Raphael, "A Formal Basis for the Heuristic
Determination of Minimum Cost Paths", IEEE TSSC 4(2), 1968.
"""

import heapq
import math
import mmap
import time
from array import array
from dataclasses import dataclass

import numpy as np

from fusion_planner.core.global_planning import kernel, neighbourhood as nbh
from fusion_planner.core.errors import (
    InvalidInput, NoValidPathCouldBeFound, PlannerCancelled, PlannerTimedOut)

HEURISTICS = ('zero', 'manhattan', 'euclidean', 'octile')

#: Border of blocked cells around the padded grid; the 16-neighbourhood
#: reaches two cells away.
_PAD = 2
#: Limits and cancellation are checked at the first expansion and then once
#: per this many expansions (the expansion budget itself is exact).
_CHECK_EVERY = 1024
#: The compiled loop returns to Python to poll them every this many
#: expansions (a few milliseconds).
_COMPILED_SLICE = 1 << 15
#: Initial capacity of the compiled loop's heap arrays (doubled as needed).
_INITIAL_HEAP = 1 << 12

#: Implementations of the loop (:func:`grid_search`'s ``engine``).
ENGINES = ('compiled', 'python')

#: Per-search cell state, one byte per padded cell: 0 never reached;
#: 1..16 reached, the value being 1 + the index of the move (in
#: :func:`neighbourhood.moves` order) that reached it last; the start is
#: :data:`_START_CODE`; :data:`_CLOSED` is or-ed in once a cell is expanded.
_START_CODE = 127
_CLOSED = 128
_CODE_BITS = 127

#: Heuristic kinds as the small integers of :mod:`kernel`.
_ZERO = kernel.ZERO
_HEURISTIC_CODES = {'zero': kernel.ZERO, 'manhattan': kernel.MANHATTAN,
                    'euclidean': kernel.EUCLIDEAN, 'octile': kernel.OCTILE}


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
        Gain of the heuristic weight w_n of eqs. (6)-(8), >= 0; 0 gives
        w_n = 1. See :func:`heuristic_weight`.
    variable_neighbourhood : bool
        Search only the moves heading towards the goal (section 1.3.1),
        widening when they make no progress.
    jump_points : bool
        Jump-point pruning (8-neighbourhood, fixed neighbourhood only): the
        same optimal cost with far fewer expansions where open areas and
        walls alternate. See :func:`grid_search`.
    landmarks : bool
        Take the larger of the heuristic and the grid's landmark bounds
        (:attr:`PaddedGrid.landmarks`, when it has them): exact A* with
        the 4- or 8-neighbourhood only.
    """

    neighbourhood: int = 8
    heuristic: str = 'octile'
    alpha: float = 1.0
    beta: float = 1.0
    gamma: float = 0.0
    variable_neighbourhood: bool = False
    jump_points: bool = False
    landmarks: bool = False

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
        if self.jump_points and (self.neighbourhood != 8 or self.variable_neighbourhood):
            raise InvalidInput('jump points need the fixed 8-neighbourhood')
        if self.landmarks and (self.neighbourhood not in (4, 8) or self.variable_neighbourhood
                               or self.heuristic == 'zero' or self.alpha != self.beta
                               or self.gamma != 0):
            # their costs are 8-moves: knight moves of the 16-neighbourhood are cheaper
            raise InvalidInput('landmarks need the exact A* with the 4- or 8-neighbourhood')


def dijkstra(neighbourhood=8):
    """Policy of Dijkstra's algorithm (no heuristic)."""
    return SearchPolicy(neighbourhood=neighbourhood, heuristic='zero')


def astar(neighbourhood=8, heuristic=None, jump_points=False, landmarks=False):
    """Policy of the classic A* (eq. 1), optionally with jump points (8 only)
    and landmark bounds (4 and 8).

    The default heuristic is the tightest admissible one for the
    neighbourhood: Manhattan for 4, octile for 8, Euclidean for 16.
    """
    if heuristic is None:
        heuristic = {4: 'manhattan', 8: 'octile', 16: 'euclidean'}.get(neighbourhood, 'octile')
    return SearchPolicy(neighbourhood=neighbourhood, heuristic=heuristic,
                        jump_points=jump_points, landmarks=landmarks)


def improved_astar(alpha=1.0, beta=1.0, gamma=0.2, neighbourhood=8, heuristic='euclidean'):
    """Policy of the paper's improved A* (sections 1.3.1 and 1.3.2).

    The defaults are the tuned ones of :class:`~fusion_planner.core.global_planning.planner.PlannerConfig`:
    the Euclidean heuristic the paper uses (section 1.2) and ``gamma = 0.2``.
    """
    return SearchPolicy(neighbourhood=neighbourhood, heuristic=heuristic, alpha=alpha,
                        beta=beta, gamma=gamma, variable_neighbourhood=True)


def heuristic_weight(h, start_distance, gamma):
    """Heuristic weight w_n of eqs. (6)-(8), as this project reads them.

    Parameters
    ----------
    h : float
        Heuristic distance from the node to the goal [cells], >= 0.
    start_distance : float
        Heuristic distance from the start to the goal, S of eq. (6) [cells].
    gamma : float
        Gain, >= 0.

    Returns
    -------
    float
        ``w_n = 1 + gamma`` for every node of a search with
        ``start_distance > 0``; 1 when the start is the goal.

    Notes
    -----
    Printed, eq. (7) is ``w_n = gamma * exp(S) * (1 + h_g / S)``, with h_g
    undefined and exp(S) of a distance in cells overflowing on any real map.
    We read h_g as the heuristic at the goal, 0, which makes the weight one
    factor per search; the unbounded ``exp(S)`` is replaced by the gain, so
    ``w_n = 1 + gamma`` and ``gamma = 0`` gives back eq. (5).

    An earlier reading, ``w_n = 1 + gamma (exp(h / S) - 1)`` (1 at the goal,
    larger far away), was measured and dropped: a weight that falls towards
    the goal makes ``f`` rise along the final approach, so the search floods
    the goal region (128,060 expansions from corner to corner of a
    1024 x 1024 map with 20 % obstacles, against 3,878 for a constant weight
    of 1.2 at a shorter path); docs/BENCHMARKS.md has the table. With a
    constant weight the search is weighted A*: its path costs at most
    ``1 + gamma`` times the optimum (``alpha = beta = 1``).

    ``h`` and ``start_distance`` are kept so that a distance-dependent
    reading can be plugged in without changing callers.

    Examples
    --------
    >>> heuristic_weight(3.0, 10.0, 0.2)
    1.2
    >>> heuristic_weight(0.0, 0.0, 0.2)
    1.0
    """
    if start_distance <= 0:
        return 1.0
    return 1.0 + gamma


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


class _MovesByMask(dict):
    """Lazily filled map: bitmask of legal moves -> tuple of move entries.

    An entry is ``(flat offset, cost, d_row, d_col, code)``; only the moves
    whose index is in ``indices`` and whose bit is set in the mask appear,
    in table order.
    """

    def __init__(self, entries, indices):
        super().__init__()
        self._entries = entries
        self._indices = tuple(indices)

    def __missing__(self, mask):
        moves = tuple(self._entries[i] for i in self._indices if mask >> i & 1)
        self[mask] = moves
        return moves


class PaddedGrid:
    """A traversable mask flattened with a blocked border, for the engine.

    Build once per map and inflation radius and reuse across searches: the
    legal-move bitmasks and move tables of each neighbourhood are computed
    on first use and kept, and so is the cost array of the search (up to
    8 bytes per padded cell, for the cells searches have reached).

    Parameters
    ----------
    traversable : ndarray of bool, shape (H, W)

    Raises
    ------
    InvalidInput
        If ``traversable`` is not a 2-D array.
    """

    def __init__(self, traversable):
        mask = np.asarray(traversable, dtype=bool)
        if mask.ndim != 2:
            raise InvalidInput(f'a traversable mask must be a 2-D array, got shape {mask.shape}')
        self.shape = mask.shape
        self.width = mask.shape[1] + 2 * _PAD
        padded = np.zeros((mask.shape[0] + 2 * _PAD, self.width), dtype=np.uint8)
        padded[_PAD:-_PAD, _PAD:-_PAD] = mask
        self.passable = bytearray(padded.data)
        self._allowed = {}
        self._tables = {}
        #: Costs from landmark cells to every padded cell, shape (cells,
        #: landmarks) (:func:`landmarks.distance_table`), or None: lower
        #: bounds the exact A* adds to its heuristic (:func:`grid_search`).
        self.landmarks = None
        self._pools = {'d': [], 'q': []}

    def index(self, cell):
        """Flat index of a ``(row, col)`` cell."""
        return (int(cell[0]) + _PAD) * self.width + int(cell[1]) + _PAD

    def cells(self, indices):
        """``(row, col)`` array of flat indices; shape (N, 2), int64."""
        flat = np.fromiter(indices, dtype=np.int64)
        rows, cols = np.divmod(flat, self.width)
        return np.stack([rows - _PAD, cols - _PAD], axis=1)

    def allowed_moves(self, neighbourhood):
        """Bitmask of the legal moves out of every padded cell.

        Parameters
        ----------
        neighbourhood : int
            4, 8 or 16.

        Returns
        -------
        bytes or array.array of 'H', length ``len(self.passable)``
            Bit ``i`` of entry ``j`` is set when move ``i`` of
            :func:`neighbourhood.moves` may be taken from cell ``j``: its
            target and every cell it crosses are traversable. The source
            itself is not checked (a start inside the inflation can be
            left). Entries of the blocked border are meaningless. Cached.
        """
        allowed = self._allowed.get(neighbourhood)
        if allowed is None:
            table = nbh.moves(neighbourhood)
            free = np.frombuffer(self.passable, dtype=np.uint8).astype(bool)
            n = free.size
            reach = _PAD * self.width + _PAD  # largest |flat offset| of any move
            dtype = np.uint8 if len(table) <= 8 else np.uint16
            bits = np.zeros(n, dtype=dtype)
            inner = bits[reach:n - reach]
            for i, (dr, dc, _, crossed) in enumerate(table):
                ok = _shifted(free, dr * self.width + dc, reach).copy()
                for cr, cc in crossed:
                    ok &= _shifted(free, cr * self.width + cc, reach)
                inner |= ok.astype(dtype) << dtype(i)
            allowed = bits.tobytes() if dtype is np.uint8 else array('H', bits.tobytes())
            self._allowed[neighbourhood] = allowed
        return allowed

    def move_tables(self, neighbourhood):
        """Moves by legal-move bitmask: all, and per goal sector forward / rest.

        Parameters
        ----------
        neighbourhood : int
            4, 8 or 16.

        Returns
        -------
        full : mapping of int to tuple
            ``full[mask]``: the entries ``(flat offset, cost, d_row, d_col,
            code)`` of the moves set in ``mask``; ``code`` is 1 + the
            move's index in :func:`neighbourhood.moves`.
        forward, rest : list of mapping of int to tuple
            For each of the 8 goal sectors (:func:`neighbourhood.sector_of`),
            the same restricted to the moves heading towards the goal and to
            the others (:func:`neighbourhood.sector_split`). Filled on first
            use of a mask, then cached.
        offsets : list of int
            Flat offset of each move, by ``code - 1``.
        """
        tables = self._tables.get(neighbourhood)
        if tables is None:
            table = nbh.moves(neighbourhood)
            entries = [(dr * self.width + dc, cost, dr, dc, i + 1)
                       for i, (dr, dc, cost, _) in enumerate(table)]
            forward_idx, rest_idx = nbh.sector_split(table)
            tables = (_MovesByMask(entries, range(len(table))),
                      [_MovesByMask(entries, idx) for idx in forward_idx],
                      [_MovesByMask(entries, idx) for idx in rest_idx],
                      [entry[0] for entry in entries])
            self._tables[neighbourhood] = tables
        return tables

    def allowed_array(self, neighbourhood):
        """:meth:`allowed_moves` as a numpy array (uint8, or uint16 for 16), no copy."""
        allowed = self.allowed_moves(neighbourhood)
        return np.frombuffer(allowed, dtype=np.uint8 if isinstance(allowed, bytes) else np.uint16)

    def kernel_moves(self, neighbourhood):
        """The move table of the compiled loop (see :func:`kernel.run`), cached.

        Returns
        -------
        tuple of ndarray
            ``(offsets, costs, d_rows, d_cols, forward_bits, rest_bits)``:
            per move its flat offset (int64), cost [cells] (float64), row
            and column step (int64); per goal sector the bitmask of its
            forward moves and of the others (int64).
        """
        key = ('kernel', neighbourhood)
        arrays = self._tables.get(key)
        if arrays is None:
            table = nbh.moves(neighbourhood)
            forward_idx, rest_idx = nbh.sector_split(table)
            arrays = (np.array([dr * self.width + dc for dr, dc, _, _ in table], np.int64),
                      np.array([cost for _, _, cost, _ in table], np.float64),
                      np.array([dr for dr, _, _, _ in table], np.int64),
                      np.array([dc for _, dc, _, _ in table], np.int64),
                      np.array([_bits(idx) for idx in forward_idx], np.int64),
                      np.array([_bits(idx) for idx in rest_idx], np.int64))
            self._tables[key] = arrays
        return arrays

    def prepare(self, neighbourhood):
        """Build everything a search with ``neighbourhood`` needs, now.

        The legal-move bitmasks, the move tables of both loops, and the
        compiled loop itself (loaded from numba's cache, or compiled the
        first time on a machine) by a search on a tiny grid.
        """
        self.allowed_moves(neighbourhood)
        self.move_tables(neighbourhood)
        self.kernel_moves(neighbourhood)
        if kernel.AVAILABLE:
            _warm_up(neighbourhood)

    def _take(self, typecode):
        """A per-cell array of padded-grid size (contents undefined).

        ``typecode`` ``'d'`` (float costs) or ``'q'`` (int64 parents).
        Backed by an anonymous memory mapping, so only the pages a search
        writes take memory; give it back with :meth:`_give` for the next
        search on this grid.
        """
        try:
            return self._pools[typecode].pop()
        except IndexError:
            return memoryview(mmap.mmap(-1, 8 * len(self.passable))).cast(typecode)

    def _give(self, values):
        self._pools[values.format].append(values)


def _bits(indices):
    """Bitmask with the bits of ``indices`` set."""
    return sum(1 << i for i in indices)


def _warm_up(neighbourhood):
    """Load the compiled loops for a neighbourhood (and the jump points for 8)
    by one search each on a 3 x 3 grid."""
    tiny = PaddedGrid(np.ones((3, 3), bool))
    policies = [astar(neighbourhood), improved_astar(neighbourhood=neighbourhood)]
    if neighbourhood == 8:
        policies.append(astar(8, jump_points=True))
    for policy in policies:
        grid_search(tiny, (0, 0), (2, 2), policy)


def _shifted(values, offset, reach):
    """``values[j + offset]`` for the inner range ``reach <= j < n - reach``."""
    n = values.size
    return values[reach + offset:n - reach + offset]


def _sector(d_row, d_col):
    """:func:`neighbourhood.sector_of` for integer offsets, without trigonometry."""
    return kernel.goal_sector(-d_row, -d_col)


def grid_search(grid, start, goal, policy, max_expansions=None, time_limit_s=None,
                cancel=None, return_expanded=False, engine=None):
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
        Stop with :class:`PlannerTimedOut` when this many nodes have been
        expanded without reaching the goal.
    time_limit_s : float, optional
        Stop with :class:`PlannerTimedOut` after this much wall time [s].
    cancel : callable, optional
        Polled at the first expansion and then every 1024 expansions (every
        :data:`_COMPILED_SLICE` with the compiled loop); returning True stops
        the search with :class:`PlannerCancelled`.
    return_expanded : bool
        Fill :attr:`SearchResult.expanded_cells`.
    engine : str, optional
        ``'compiled'`` (the loop of :mod:`kernel`, needs numba) or
        ``'python'``; both return the same result. Default: compiled when
        numba is installed.

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
    ``w_n`` from :func:`heuristic_weight` (1 unless ``policy.gamma > 0``).
    Ties in f go to the node with the smaller heuristic term (nearer the
    goal), which keeps A* from expanding whole plateaus of equal f on open
    maps. A node's g is never revised after it is closed, so with weights
    > 1 the path is within the largest weight of the optimum (weighted A*);
    with ``alpha = beta = 1`` and ``gamma = 0`` and an admissible heuristic
    it is optimal.

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
    if engine is None:
        engine = 'compiled' if kernel.AVAILABLE else 'python'
    if engine not in ENGINES:
        raise InvalidInput(f'engine must be one of {ENGINES}, got {engine!r}')
    if engine == 'compiled' and not kernel.AVAILABLE:
        raise InvalidInput('the compiled search needs numba, which is not installed')
    width = grid.width
    kind = _HEURISTIC_CODES[policy.heuristic]
    s = grid.index(start)
    t = grid.index(goal)
    goal_row, goal_col = divmod(t, width)
    start_row, start_col = divmod(s, width)
    if kind == _ZERO:
        weight = 0.0
    else:
        start_distance = _heuristic(kind, start_row - goal_row, start_col - goal_col)
        weight = policy.beta * heuristic_weight(start_distance, start_distance, policy.gamma)
    limits = _Limits(max_expansions, time_limit_s, cancel)
    state = bytearray(len(grid.passable))
    g = grid._take('d')
    try:
        state[s] = _START_CODE
        g[s] = 0.0
        h0 = weight * _heuristic(kind, start_row - goal_row, start_col - goal_col)
        if policy.jump_points:
            loop = _jump_loop
        else:
            loop = _compiled_loop if engine == 'compiled' else _python_loop
        chain, expanded, generated = loop(grid, policy, s, t, kind, weight, h0, state, g,
                                          limits)
        if chain is None:
            raise NoValidPathCouldBeFound(
                f'no path from cell {tuple(start)} to cell {tuple(goal)} '
                f'({expanded} cells expanded)')
        cost = g[t]
    finally:
        grid._give(g)
    expanded_cells = None
    if return_expanded:
        closed = np.flatnonzero(np.frombuffer(state, dtype=np.uint8) & _CLOSED)
        expanded_cells = grid.cells(closed)
    return SearchResult(cells=grid.cells(chain), cost=cost, expanded=expanded,
                        generated=generated, expanded_cells=expanded_cells)


def _python_loop(grid, policy, s, t, kind, weight, h0, state, g, limits):
    """The search loop in pure Python; see :func:`grid_search`.

    Returns ``(path, expanded, generated)``, the path a list of flat
    indices from start to goal or None; fills ``state`` and ``g``.
    """
    width = grid.width
    goal_row, goal_col = divmod(t, width)
    allowed = grid.allowed_moves(policy.neighbourhood)
    full, forward, rest, _ = grid.move_tables(policy.neighbourhood)
    variable = policy.variable_neighbourhood
    alpha = float(policy.alpha)
    push, pop = heapq.heappush, heapq.heappop
    closed_bit = _CLOSED
    goal_sector = kernel.goal_sector
    heuristic_term = kernel.heuristic_term
    table, goal_distances = _landmark_bounds(grid, policy, t)
    use_landmarks = goal_distances.size > 0
    landmark_term = kernel.landmark_term
    heap = [(h0, h0, s)]
    generated = 1
    expanded = 0
    next_check = 1  # poll the limits at the first expansion
    found = False
    while heap:
        j = pop(heap)[2]
        if j >= 0:
            code = state[j]
            if code & closed_bit:
                continue  # a stale entry of a node already expanded
            if j == t:
                found = True
                break
            state[j] = code | closed_bit
            expanded += 1
            if expanded >= next_check:
                limits.check(expanded)
                next_check = min(expanded + _CHECK_EVERY, limits.budget)
            widened = not variable
        else:
            # Second pass of a reduced expansion: its remaining moves.
            j = ~j
            widened = True
        row, col = divmod(j, width)
        d_row = row - goal_row
        d_col = col - goal_col
        mask = allowed[j]
        if variable:
            sector = goal_sector(d_row, d_col)
            moves = rest[sector][mask] if widened else forward[sector][mask]
        else:
            moves = full[mask]
        gj = g[j]
        probe = False
        while True:  # at most three passes: forward, probe, rest
            opened = False
            best_f = math.inf
            best_h = 0.0
            for offset, cost, dr, dc, move_code in moves:
                k = j + offset
                state_k = state[k]
                if state_k & closed_bit:
                    continue
                ng = gj + cost
                if state_k and ng >= g[k]:
                    continue
                hk = heuristic_term(kind, weight, d_row + dr, d_col + dc)  # eqs. 2-4, 8
                if use_landmarks:
                    hk = max(hk, weight * landmark_term(table, goal_distances, k))
                f = alpha * ng + hk
                if probe:
                    if f < best_f:
                        best_f = f
                        best_h = hk
                    continue
                if not state_k:
                    generated += 1
                g[k] = ng
                state[k] = move_code
                push(heap, (f, hk, k))
                opened = True
            if probe:
                # Re-queue the node at the best f its remaining moves
                # would give, so they are tried exactly when A* would
                # need them; when that entry would come up next anyway,
                # widen now instead.
                if best_f == math.inf:
                    break
                entry = (best_f, best_h, ~j)
                if heap and heap[0] < entry:
                    push(heap, entry)
                    break
                moves = rest[sector][mask]
                probe = False
                continue
            if widened:
                break
            widened = True
            moves = rest[sector][mask]
            # No progress ahead: widen at once; else only measure the rest.
            probe = opened
    return _traced(grid, policy, state, t) if found else None, expanded, generated


def _compiled_loop(grid, policy, s, t, kind, weight, h0, state, g, limits):
    """The search loop of :mod:`kernel`, run in slices; see :func:`grid_search`.

    Returns as :func:`_python_loop`.
    """
    allowed = grid.allowed_array(policy.neighbourhood)
    moves = grid.kernel_moves(policy.neighbourhood)
    state_array = np.frombuffer(state, dtype=np.uint8)
    g_array = np.frombuffer(g, dtype=np.float64)

    bounds = _landmark_bounds(grid, policy, t)

    def run_slice(heap, counts, pause_at):
        return kernel.run(allowed, moves, grid.width, t, kind, float(policy.alpha), weight,
                          policy.variable_neighbourhood, bounds, state_array, g_array, heap,
                          counts, pause_at)

    found, expanded, generated = _in_slices(run_slice, s, h0, limits)
    return _traced(grid, policy, state, t) if found else None, expanded, generated


def _jump_loop(grid, policy, s, t, kind, weight, h0, state, g, limits):
    """Jump-point search (:func:`kernel.jump_run`), run in slices.

    Returns as :func:`_python_loop`; the path is filled in between the
    jump points, cell by cell.
    """
    free = np.frombuffer(grid.passable, dtype=np.uint8)
    state_array = np.frombuffer(state, dtype=np.uint8)
    g_array = np.frombuffer(g, dtype=np.float64)
    parent = grid._take('q')
    parent_array = np.frombuffer(parent, dtype=np.int64)

    bounds = _landmark_bounds(grid, policy, t)

    def run_slice(heap, counts, pause_at):
        return kernel.jump_run(free, grid.width, t, kind, float(policy.alpha), weight, bounds,
                               state_array, g_array, parent_array, heap, counts, pause_at)

    try:
        found, expanded, generated = _in_slices(run_slice, s, h0, limits)
        path = None
        if found:
            jumps = [t]
            while jumps[-1] != s:  # bounded: parents lead back to the start
                jumps.append(parent[jumps[-1]])
            path = _filled(jumps[::-1], grid.width)
        return path, expanded, generated
    finally:
        grid._give(parent)


#: :func:`_landmark_bounds` of a search without landmarks.
_NO_LANDMARKS = (np.empty((1, 0)), np.empty(0))


def _landmark_bounds(grid, policy, t):
    """``(table, goal distances)`` of the grid's landmarks for a search to ``t``.

    Only an exact A* with the 4- or 8-neighbourhood uses them (their
    distances are 8-neighbourhood costs, a lower bound for both; the
    16-neighbourhood's knight moves are cheaper than two 8-moves); and only
    the landmarks that reach the goal.
    """
    table = grid.landmarks
    if (table is None or policy.heuristic == 'zero' or policy.variable_neighbourhood
            or policy.neighbourhood not in (4, 8)):
        return _NO_LANDMARKS
    return table, table[t]


def exhaustive_distances(grid, source):
    """Cost [cells] from ``source`` to every padded cell (8-neighbourhood, no corner cutting).

    Dijkstra's algorithm run to exhaustion with the compiled loop (needs
    :data:`kernel.AVAILABLE`). Returns float64 of padded-grid size, inf
    where ``source`` does not reach.
    """
    state = np.zeros(len(grid.passable), np.uint8)
    g = np.empty(len(grid.passable))
    state[source] = _START_CODE
    g[source] = 0.0
    allowed = grid.allowed_array(8)
    moves = grid.kernel_moves(8)

    def run_slice(heap, counts, pause_at):
        return kernel.run(allowed, moves, grid.width, -1, kernel.ZERO, 1.0, 0.0, False,
                          _NO_LANDMARKS, state, g, heap, counts, pause_at)

    _in_slices(run_slice, source, 0.0, _Limits(None, None, None))
    g[state == 0] = np.inf
    return g


def _in_slices(run_slice, s, h0, limits):
    """Run a compiled loop from start ``s`` in slices, polling the limits between.

    ``run_slice(heap, counts, pause_at)`` advances the search (see
    :func:`kernel.run`). Returns ``(found, expanded, generated)``.
    """
    heap = np.empty((_INITIAL_HEAP, 3))
    heap[0] = (h0, h0, s)
    counts = np.array([1, 0, 1], dtype=np.int64)  # heap size, expanded, generated
    limits.check(0)
    while True:
        status = run_slice(heap, counts, min(counts[1] + _COMPILED_SLICE, limits.budget))
        if status == kernel.HEAP_FULL:
            heap = np.concatenate([heap, np.empty_like(heap)])
        elif status == kernel.PAUSED:
            limits.check(int(counts[1]))
        else:
            return status == kernel.FOUND, int(counts[1]), int(counts[2])


def _filled(jumps, width):
    """Flat indices of every cell on straight or diagonal runs between jump points."""
    path = [jumps[0]]
    for a, b in zip(jumps, jumps[1:]):
        (ra, ca), (rb, cb) = divmod(a, width), divmod(b, width)
        steps = max(abs(rb - ra), abs(cb - ca))
        step = ((rb > ra) - (rb < ra)) * width + (cb > ca) - (cb < ca)
        path.extend(range(a + step, b + step, step) if steps else ())
    return path


def _traced(grid, policy, state, t):
    """The path to ``t`` rebuilt from the move codes in ``state``, start first."""
    offsets = grid.move_tables(policy.neighbourhood)[3]
    chain = [t]
    j = t
    for _ in range(len(state)):  # bounded: a path visits each cell once
        code = state[j] & _CODE_BITS
        if code == _START_CODE:
            break
        j -= offsets[code - 1]
        chain.append(j)
    chain.reverse()
    return chain


def _heuristic(kind, d_row, d_col):
    """Unweighted heuristic [cells] of an offset to the goal (eqs. 2-4)."""
    return kernel.heuristic_term(kind, 1.0, d_row, d_col)


class _Limits:
    """The stop conditions of one search: expansion budget, deadline, caller.

    Parameters
    ----------
    max_expansions : int or None
    time_limit_s : float or None
        Wall time [s] from now.
    cancel : callable or None
    """

    def __init__(self, max_expansions, time_limit_s, cancel):
        self.budget = math.inf if max_expansions is None else max_expansions
        self.time_limit_s = time_limit_s
        self.deadline = None if time_limit_s is None else time.monotonic() + time_limit_s
        self.cancel = cancel

    def check(self, expanded):
        """Raise when the budget, the deadline or the caller says stop."""
        if expanded >= self.budget:
            raise PlannerTimedOut(
                f'search stopped after {expanded} expansions without reaching the goal')
        if self.deadline is not None and time.monotonic() > self.deadline:
            raise PlannerTimedOut(
                f'search stopped after {self.time_limit_s:g} s without reaching the goal')
        if self.cancel is not None and self.cancel():
            raise PlannerCancelled('search cancelled by the caller')
