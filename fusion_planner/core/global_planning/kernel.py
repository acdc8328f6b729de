"""The search loops of :mod:`search`, compiled with numba when it is installed.

- :func:`run`: the same best-first loop as the pure-Python one in
  :func:`~fusion_planner.core.global_planning.search.grid_search`, statement
  for statement: the same evaluation ``f = alpha * g + h``, the same ties
  (the open list is ordered by ``(f, h, index)``), the same move order and
  the same partial expansion of the variable neighbourhood, so both return
  the same path and counts. Only the container differs: the open list is a
  binary heap in one numpy array instead of a list of tuples.
- :func:`jump_run`: jump-point search (Harabor and Grastien, AAAI 2011; the
  rules without corner cutting of ICAPS 2014) for A* with the
  8-neighbourhood. It has no separate pure-Python version: without numba
  the same functions run as plain Python.

numba (``pip install numba``; Debian/Ubuntu ``python3-numba``) is optional.
Without it :data:`AVAILABLE` is False and the search runs its pure-Python
loop. numba is imported on the first search, not with this module (the
import alone takes about 0.4 s). The compiled code is cached on disk
(numba's ``cache=True``), so only the first process on a machine pays for
compiling (about 10 s); a later process loads it in about 0.3 s, which
``PaddedGrid.prepare`` spends when a map is prepared rather than at its
first search.

The loops run in slices: they return to Python every so many expansions, so
that the caller polls its deadline and cancellation, and when the heap must
grow.
"""

import math

import numpy as np

from fusion_planner.core import distance_transform


#: Whether the compiled loop can be used.
AVAILABLE = distance_transform.numba_installed()

#: Status codes of :func:`run` (RUNNING: inside a slice only).
FOUND, EXHAUSTED, PAUSED, HEAP_FULL, RUNNING = range(5)

#: Heuristic kinds (the codes of :mod:`search`).
ZERO, MANHATTAN, EUCLIDEAN, OCTILE = range(4)

#: Per-search cell state codes, as in :mod:`search`; STALE and GOAL are
#: :func:`_close`'s answers besides a code.
START_CODE = 127
CLOSED = 128
STALE, GOAL = -1, -2

#: A slice stops for a heap that has fewer free slots than this: one
#: expansion pushes at most 16 moves and one re-queued entry.
HEAP_MARGIN = 18

#: Subtracted from every landmark bound [cells]: the landmark distances
#: are sums in another order than the search's g, so without it rounding
#: could lift a bound a few ulps over the true cost.
LANDMARK_MARGIN = 1e-6

_ROOT2_MINUS_2 = math.sqrt(2.0) - 2.0
ROOT2 = math.sqrt(2.0)

#: The 8 directions of the jump-point search, ``(d_row, d_col)``: the
#: orthogonal then the diagonal moves, as in :func:`neighbourhood.moves`.
DIRECTION_ROWS = np.array([0, 1, 0, -1, 1, 1, -1, -1], np.int64)
DIRECTION_COLS = np.array([1, 0, -1, 0, 1, -1, 1, -1], np.int64)


def _less(f1, h1, k1, f2, h2, k2):
    """Tuple order ``(f1, h1, k1) < (f2, h2, k2)``."""
    if f1 != f2:
        return f1 < f2
    if h1 != h2:
        return h1 < h2
    return k1 < k2


def _push(heap, size, f, h, k):
    """Push ``(f, h, k)`` on the heap of ``size`` entries; return the new size."""
    i = size
    while i > 0:
        parent = (i - 1) >> 1
        if not _less_than_row(f, h, k, heap, parent):
            break
        _copy_row(heap, i, parent)
        i = parent
    _set_row(heap, i, f, h, k)
    return size + 1


def _pop(heap, size):
    """Remove the smallest entry; return its index ``k`` (``size`` > 0)."""
    top = heap[0, 2]
    size -= 1
    f = heap[size, 0]
    h = heap[size, 1]
    k = heap[size, 2]
    i = 0
    while True:
        child = 2 * i + 1
        if child >= size:
            break
        right = child + 1
        if right < size and _less_than_row(heap[right, 0], heap[right, 1], heap[right, 2],
                                           heap, child):
            child = right
        if not _less(heap[child, 0], heap[child, 1], heap[child, 2], f, h, k):
            break
        _copy_row(heap, i, child)
        i = child
    _set_row(heap, i, f, h, k)
    return np.int64(top)


def _less_than_row(f, h, k, heap, row):
    """``(f, h, k) < heap[row]`` in tuple order."""
    return _less(f, h, k, heap[row, 0], heap[row, 1], heap[row, 2])


def _copy_row(heap, dst, src):
    """``heap[dst] = heap[src]``."""
    heap[dst, 0] = heap[src, 0]
    heap[dst, 1] = heap[src, 1]
    heap[dst, 2] = heap[src, 2]


def _set_row(heap, row, f, h, k):
    """``heap[row] = (f, h, k)``."""
    heap[row, 0] = f
    heap[row, 1] = h
    heap[row, 2] = k


def _stop(size, expanded, pause_at, capacity):
    """Why a slice stops before its next pop, or :data:`RUNNING`.

    A slice that reached ``pause_at`` pauses even with an empty heap, so that
    an exhausted expansion budget is reported as such, as the pure-Python
    loop does.
    """
    if expanded >= pause_at:
        return PAUSED
    if size == 0:
        return EXHAUSTED
    if size + HEAP_MARGIN > capacity:
        return HEAP_FULL
    return RUNNING


def _close(state, j, goal):
    """Close popped node ``j`` and return its state code before closing, or
    :data:`STALE` (already closed: a stale heap entry) or :data:`GOAL` (the
    goal, left open)."""
    code = state[j]
    if code & CLOSED:
        return STALE
    if j == goal:
        return GOAL
    state[j] = code | CLOSED
    return code


def _heuristic_term(kind, weight, y, x):
    """``beta * w_n * h`` of an offset ``(y, x)`` to the goal [cells]."""
    if kind == EUCLIDEAN:
        return weight * math.sqrt(x * x + y * y)
    if kind == OCTILE:
        if y < 0:
            y = -y
        if x < 0:
            x = -x
        return weight * (x + y + _ROOT2_MINUS_2 * (x if x < y else y))
    if kind == ZERO:
        return 0.0
    return weight * (abs(y) + abs(x))


def _landmark_term(table, goal_distances, k):
    """Lower bound on the cost from cell ``k`` to the goal from landmark distances [cells].

    ``max |d(L, k) - d(L, goal)|`` over the landmarks L (triangle
    inequality), less :data:`LANDMARK_MARGIN`; landmarks that do not reach
    ``k`` or the goal are skipped. 0 without landmarks.
    """
    best = 0.0
    for i in range(goal_distances.shape[0]):
        d = table[k, i]
        to_goal = goal_distances[i]
        if d == math.inf or to_goal == math.inf:
            continue
        d -= to_goal
        if d < 0.0:
            d = -d
        if d > best:
            best = d
    return best - LANDMARK_MARGIN if best > LANDMARK_MARGIN else 0.0


def _goal_sector(d_row, d_col):
    """Sector (:func:`neighbourhood.sector_of`) of the direction from a cell
    to the goal, ``d`` = cell - goal, in integers without trigonometry.

    The direction is near an axis when it lies within 22.5 degrees of it,
    i.e. ``|minor| < tan(22.5 deg) |major|``, tested exactly as
    ``(|minor| + |major|)**2 < 2 major**2`` (tan 22.5 deg = sqrt 2 - 1).
    """
    a_row = -d_row if d_row < 0 else d_row
    a_col = -d_col if d_col < 0 else d_col
    square = (a_row + a_col) * (a_row + a_col)
    if square < 2 * a_col * a_col:
        return 4 if d_col > 0 else 0
    if square < 2 * a_row * a_row:
        return 6 if d_row > 0 else 2
    if d_row < 0:
        return 1 if d_col < 0 else 3
    if d_row == 0:
        return 0
    return 7 if d_col < 0 else 5


def _run(allowed, offsets, costs, d_rows, d_cols, forward_bits, rest_bits, width, goal,
         kind, alpha, weight, variable, table, goal_distances, state, g, heap, counts,
         pause_at):
    """Run the loop until the goal, an empty heap, ``pause_at`` expansions or a full heap.

    ``counts`` holds ``[heap size, expanded, generated]`` and is updated in
    place; returns a status code.
    """
    goal_row = goal // width
    goal_col = goal % width
    size = counts[0]
    expanded = counts[1]
    generated = counts[2]
    capacity = heap.shape[0]
    n_moves = offsets.shape[0]
    use_landmarks = goal_distances.shape[0] > 0
    all_bits = (1 << n_moves) - 1
    while True:
        status = _stop(size, expanded, pause_at, capacity)
        if status != RUNNING:
            break
        j = _pop(heap, size)
        size -= 1
        if j >= 0:
            code = _close(state, j, goal)
            if code == STALE:
                continue
            if code == GOAL:
                status = FOUND
                break
            expanded += 1
            widened = not variable
        else:
            j = ~j
            widened = True
        row = j // width
        col = j - row * width
        d_row = row - goal_row
        d_col = col - goal_col
        mask = np.int64(allowed[j])
        sector = 0
        if variable:
            sector = _goal_sector(d_row, d_col)
            bits = mask & (rest_bits[sector] if widened else forward_bits[sector])
        else:
            bits = mask & all_bits
        gj = g[j]
        probe = False
        while True:  # at most three passes: forward, probe, rest
            opened = False
            best_f = math.inf
            best_h = 0.0
            for i in range(n_moves):
                if not (bits >> i) & 1:
                    continue
                k = j + offsets[i]
                state_k = state[k]
                if state_k & CLOSED:
                    continue
                ng = gj + costs[i]
                if state_k and ng >= g[k]:
                    continue
                hk = _heuristic_term(kind, weight, d_row + d_rows[i], d_col + d_cols[i])
                if use_landmarks:
                    hk = max(hk, weight * _landmark_term(table, goal_distances, k))
                f = alpha * ng + hk
                if probe:
                    if f < best_f:
                        best_f = f
                        best_h = hk
                    continue
                if not state_k:
                    generated += 1
                g[k] = ng
                state[k] = i + 1
                size = _push(heap, size, f, hk, k)
                opened = True
            if probe:
                if best_f == math.inf:
                    break
                if size > 0 and _less(heap[0, 0], heap[0, 1], heap[0, 2], best_f, best_h, ~j):
                    size = _push(heap, size, best_f, best_h, ~j)
                    break
                bits = mask & rest_bits[sector]
                probe = False
                continue
            if widened:
                break
            widened = True
            bits = mask & rest_bits[sector]
            probe = opened
    counts[0] = size
    counts[1] = expanded
    counts[2] = generated
    return status



def _jump_straight(free, k, step, side_a, side_b, goal):
    """Jump from cell ``k`` along an axis step; ``(jump point, steps)`` or ``(-1, 0)``.

    Stops at the goal, or at a cell with a forced neighbour: a side cell
    that is free while the side cell behind it is blocked (without corner
    cutting, only such a side is not reached at least as cheaply by a
    diagonal step taken earlier). Stops with -1 at a blocked cell.
    """
    n = 0
    while True:
        k += step
        n += 1
        if not free[k]:
            return -1, 0
        if k == goal:
            return k, n
        if (free[k + side_a] and not free[k - step + side_a]) or \
                (free[k + side_b] and not free[k - step + side_b]):
            return k, n


def _jump_diagonal(free, k, step_row, step_col, goal):
    """Jump from ``k`` along the diagonal ``step_row + step_col`` (flat offsets).

    A diagonal step needs both cells it passes between free. Stops at the
    goal or where a straight jump along either component finds a jump point.
    """
    step = step_row + step_col
    n = 0
    while True:
        if not (free[k + step] and free[k + step_row] and free[k + step_col]):
            return -1, 0
        k += step
        n += 1
        if k == goal:
            return k, n
        if _jump_straight(free, k, step_col, step_row, -step_row, goal)[0] >= 0 or \
                _jump_straight(free, k, step_row, step_col, -step_col, goal)[0] >= 0:
            return k, n


def _jump_run(free, width, goal, kind, alpha, weight, table, goal_distances, state, g, parent,
              heap, counts, pause_at):
    """Jump-point search (8-neighbourhood, no corner cutting) until a stop.

    The same contract as :func:`_run`, on the traversable bytes ``free``;
    ``state`` holds the direction (1..8, :data:`DIRECTIONS` order) that
    reached a jump point, ``parent`` its predecessor jump point.
    """
    goal_row = goal // width
    goal_col = goal % width
    size = counts[0]
    expanded = counts[1]
    generated = counts[2]
    capacity = heap.shape[0]
    use_landmarks = goal_distances.shape[0] > 0
    while True:
        status = _stop(size, expanded, pause_at, capacity)
        if status != RUNNING:
            break
        j = _pop(heap, size)
        size -= 1
        code = _close(state, j, goal)
        if code == STALE:
            continue
        if code == GOAL:
            status = FOUND
            break
        expanded += 1
        row = j // width
        col = j - row * width
        gj = g[j]
        for d in range(8):
            d_row = DIRECTION_ROWS[d]
            d_col = DIRECTION_COLS[d]
            if code != START_CODE and not _natural_or_forced(
                    free, j, width, DIRECTION_ROWS[code - 1], DIRECTION_COLS[code - 1],
                    d_row, d_col):
                continue
            if d_row != 0 and d_col != 0:
                k, n = _jump_diagonal(free, j, d_row * width, d_col, goal)
                cost = n * ROOT2
            elif d_row != 0:
                k, n = _jump_straight(free, j, d_row * width, 1, -1, goal)
                cost = n * 1.0
            else:
                k, n = _jump_straight(free, j, d_col, width, -width, goal)
                cost = n * 1.0
            if k < 0:
                continue
            state_k = state[k]
            if state_k & CLOSED:
                continue
            ng = gj + cost
            if state_k and ng >= g[k]:
                continue
            hk = _heuristic_term(kind, weight, row + n * d_row - goal_row,
                                 col + n * d_col - goal_col)
            if use_landmarks:
                hk = max(hk, weight * _landmark_term(table, goal_distances, k))
            if not state_k:
                generated += 1
            g[k] = ng
            state[k] = d + 1
            parent[k] = j
            size = _push(heap, size, alpha * ng + hk, hk, k)
    counts[0] = size
    counts[1] = expanded
    counts[2] = generated
    return status


def _natural_or_forced(free, j, width, in_row, in_col, d_row, d_col):
    """Whether direction ``(d_row, d_col)`` is searched from a jump point
    reached along ``(in_row, in_col)``.

    After a diagonal: its two components and itself. After a straight
    move: itself, and towards a side whose cell is free while the side cell
    behind is blocked, that side and the diagonal ahead on it.
    """
    if in_row != 0 and in_col != 0:
        return (d_row == in_row and d_col == in_col) or (d_row == in_row and d_col == 0) \
            or (d_row == 0 and d_col == in_col)
    if d_row == in_row and d_col == in_col:
        return True
    # Straight arrival: the side is the component across the arrival axis.
    side_row = d_row if in_row == 0 else 0
    side_col = d_col if in_col == 0 else 0
    if side_row == 0 and side_col == 0:
        return False  # backwards
    if (d_row != 0 and d_col != 0) and not (d_row == in_row or d_col == in_col):
        return False  # the diagonal behind
    side = side_row * width + side_col
    behind = in_row * width + in_col
    return bool(free[j + side]) and not free[j - behind + side]

#: :func:`_goal_sector`, :func:`_heuristic_term` and :func:`_landmark_term` as plain Python, for the
#: pure-Python loop.
goal_sector = _goal_sector
heuristic_term = _heuristic_term
landmark_term = _landmark_term

#: Whether :func:`_compile` has run.
_compiled = False


def _compile():
    """Replace the loop's functions by numba's compiled ones, once per process.

    numba is imported here, on the first search, not with this module. The
    helpers are replaced first: numba binds the globals a function calls
    when it compiles that function.
    """
    global AVAILABLE, _compiled, _less, _less_than_row, _copy_row, _set_row, _push, _pop
    global _stop, _close, _heuristic_term, _landmark_term, _goal_sector, _run
    global _jump_straight, _jump_diagonal, _natural_or_forced, _jump_run
    if _compiled or not AVAILABLE:
        return
    try:
        import numba
    except ImportError:  # installed but broken (e.g. a mismatched llvmlite)
        AVAILABLE = False  # this call runs as plain Python, later ones the Python loop
        return
    _less = numba.njit(cache=True, inline='always')(_less)
    _less_than_row = numba.njit(cache=True, inline='always')(_less_than_row)
    _copy_row = numba.njit(cache=True, inline='always')(_copy_row)
    _set_row = numba.njit(cache=True, inline='always')(_set_row)
    _push = numba.njit(cache=True)(_push)
    _pop = numba.njit(cache=True)(_pop)
    _stop = numba.njit(cache=True, inline='always')(_stop)
    _close = numba.njit(cache=True, inline='always')(_close)
    _heuristic_term = numba.njit(cache=True, inline='always')(_heuristic_term)
    _landmark_term = numba.njit(cache=True, inline='always')(_landmark_term)
    _goal_sector = numba.njit(cache=True, inline='always')(_goal_sector)
    _run = numba.njit(cache=True, nogil=True)(_run)
    _jump_straight = numba.njit(cache=True)(_jump_straight)
    _jump_diagonal = numba.njit(cache=True)(_jump_diagonal)
    _natural_or_forced = numba.njit(cache=True, inline='always')(_natural_or_forced)
    _jump_run = numba.njit(cache=True, nogil=True)(_jump_run)
    _compiled = True


def run(allowed, moves, width, goal, kind, alpha, weight, variable, landmarks, state, g, heap,
        counts, pause_at):
    """Advance a search by one slice (compiled; needs :data:`AVAILABLE`).

    Parameters
    ----------
    allowed : ndarray of uint8 or uint16
        Legal-move bitmask of every padded cell (``PaddedGrid.allowed_moves``).
    moves : tuple of ndarray
        ``(offsets, costs, d_rows, d_cols, forward_bits, rest_bits)``: the
        flat offset, cost [cells] and row/column step of each move, and per
        goal sector the bitmask of the forward moves and of the others.
    width : int
        Padded row length [cells].
    goal : int
        Flat index of the goal.
    kind : int
        Heuristic kind (:data:`ZERO`, :data:`MANHATTAN`, ...).
    alpha, weight : float
        Weight of g, and ``beta * w_n``, the weight of h.
    variable : bool
        Variable neighbourhood (partial expansion).
    state : ndarray of uint8
        Per-cell search state, updated in place.
    g : ndarray of float64
        Per-cell cost [cells], updated in place.
    heap : ndarray of float64, shape (capacity, 3)
        The open list, rows ``(f, h, index)`` (an index is exact in a
        float64), updated in place.
    counts : ndarray of int64, shape (3,)
        ``[heap size, expanded, generated]``, updated in place.
    pause_at : int
        Return once this many nodes have been expanded.

    Returns
    -------
    int
        :data:`FOUND`, :data:`EXHAUSTED`, :data:`PAUSED` or :data:`HEAP_FULL`
        (grow the heap arrays and call again).
    """
    _compile()
    offsets, costs, d_rows, d_cols, forward_bits, rest_bits = moves
    table, goal_distances = landmarks
    return _run(allowed, offsets, costs, d_rows, d_cols, forward_bits, rest_bits, width, goal,
                kind, alpha, weight, variable, table, goal_distances, state, g, heap, counts,
                pause_at)


def jump_run(free, width, goal, kind, alpha, weight, landmarks, state, g, parent, heap, counts,
             pause_at):
    """Advance a jump-point search by one slice.

    Compiled with numba when :data:`AVAILABLE`, plain Python otherwise (the
    same code, slower).

    Parameters
    ----------
    free : ndarray of uint8
        Traversable padded cells (``PaddedGrid.passable``); the border is
        blocked, so jumps stop inside.
    parent : ndarray of int64
        Per-cell predecessor jump point, updated in place.
    width, goal, kind, alpha, weight, state, g, heap, counts, pause_at
        As for :func:`run`; ``state`` holds 1 + the direction that reached a
        jump point instead of a move code.

    Returns
    -------
    int
        A status code as for :func:`run`.
    """
    _compile()
    table, goal_distances = landmarks
    return _jump_run(free, width, goal, kind, alpha, weight, table, goal_distances, state, g,
                     parent, heap, counts, pause_at)
