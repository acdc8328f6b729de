"""Secondary optimisation of a grid path: redundant nodes, then smoothing.

Section 1.3.3 of the paper removes redundant nodes of the A* path: a node is
deleted when the straight line that would replace it keeps at least the
safety distance from every obstacle. Table 2 then reports a path that is
shorter than the grid-optimal one after "smoothing", so the second step
turns the pruned polyline into an any-angle path with rounded corners.

Safety is judged on cells (see :mod:`raster`): a segment is *safe* when
every cell it touches lies inside the map and has a clearance (cell-centre
distance to the nearest obstacle cell centre) greater than the robot radius
and at least the robot radius plus the safety distance.

The guarantees, for an input path that the search produced on
``grid.traversable(robot_radius)``:

- the output starts and ends at the input's ends, exactly;
- it never touches a cell with clearance ``<= robot_radius`` or outside the
  map unless the input did, and its smallest clearance is at least the
  smaller of the input's and ``robot_radius + safety_distance``;
- it is never longer than the input and never has more key nodes than the
  input has key points (ends and turning vertices).
"""

import logging
import math

import numpy as np

from fusion_planner.core import raster
from fusion_planner.core.global_planning import metrics
from fusion_planner.core.errors import InvalidInput

_LOG = logging.getLogger(__name__)

#: Turns smaller than this [rad] are treated as straight (no curve).
MIN_TURN_RAD = 1e-6
#: Largest heading change [rad] between two chords of a sampled corner arc.
MAX_CHORD_TURN_RAD = math.radians(5.0)
#: How many times the tangent length of a corner is halved before the
#: corner is left sharp.
MAX_SHRINK_STEPS = 6
#: Upper bound on the chords of one corner arc or points of one straight
#: piece, whatever the spacing asked for.
MAX_SAMPLES_PER_PIECE = 100_000
#: Points closer than this [m] are the same point.
SAME_POINT_M = 1e-12
#: Grid lines per axis, from the anchor, that a shortcut probe is first
#: checked over before it is checked whole (see _farthest_safe).
PROBE_PREFIX_CROSSINGS = 8
#: Nodes ahead of every node whose shortcuts are all tested in one batch
#: before the greedy pass (see _window_reach).
WINDOW_NODES = 8
#: A bisection between a safe and an unsafe shortcut end at most this many
#: nodes apart tests every node between them in one batch instead.
DENSE_GAP_NODES = 32


def _is_finite_number(value):
    """True for a real finite number (bool excluded)."""
    if isinstance(value, bool) or not isinstance(value, (int, float, np.integer, np.floating)):
        return False
    return math.isfinite(value)


def _check_distances(robot_radius, safety_distance):
    for name, value in (('robot_radius', robot_radius), ('safety_distance', safety_distance)):
        if not _is_finite_number(value) or value < 0:
            raise InvalidInput(f'{name} must be a non-negative number of metres, got {value!r}')
    return float(robot_radius), float(safety_distance)


def _is_safe(clearance, robot_radius, needed):
    """Elementwise safety test: clearance [m] ``> robot_radius`` and ``>= needed``."""
    return (clearance > robot_radius) & (clearance >= needed)


def segment_is_safe(grid, a, b, robot_radius, safety_distance):
    """Whether a straight segment keeps the safety distance from obstacles.

    Parameters
    ----------
    grid : GridMap
    a, b : array_like, shape (2,)
        Segment ends ``(x, y)`` [m], map frame.
    robot_radius : float
        Robot radius [m], >= 0.
    safety_distance : float
        Extra distance [m] to keep beyond the radius, >= 0 (section 1.3.3).

    Returns
    -------
    bool
        True when every cell the segment touches (:func:`raster.segment_cells`)
        is inside the map and has clearance ``> robot_radius`` and
        ``>= robot_radius + safety_distance``.

    Raises
    ------
    InvalidInput
        If an end is not finite or a distance is negative or not a number.

    Notes
    -----
    This is the test of step 1) of section 1.3.3 ("judge the distance
    between the connection line and the obstacle"), at cell resolution.

    Examples
    --------
    >>> import numpy as np
    >>> from fusion_planner.core.grid import GridMap
    >>> occupied = np.zeros((5, 5), bool); occupied[2, 2] = True
    >>> grid = GridMap(occupied, resolution=1.0)
    >>> segment_is_safe(grid, (0.5, 0.5), (4.5, 0.5), 0.0, 1.5)
    True
    >>> segment_is_safe(grid, (0.5, 0.5), (4.5, 0.5), 0.0, 2.5)
    False
    """
    r, s = _check_distances(robot_radius, safety_distance)
    return bool(_is_safe(raster.segment_clearance(grid, a, b), r, r + s))


def _farthest_safe(grid, gpts, i, r, needed, first):
    """Index of a far node reachable from node ``i`` by a safe segment.

    ``gpts`` are the nodes in grid coordinates. ``needed[k]`` is the
    clearance [m] the segment ``i -> i + 1 + k`` must keep. Assumes the
    segment ``i -> i + first`` is safe. Probes ``i + first, i + 2 first,
    i + 4 first, ...`` and the last node in one batch (near the anchor
    first, then whole), takes the farthest safe probe, then bisects towards
    the next (unsafe) probe, two bisection steps per batch, until at most
    :data:`DENSE_GAP_NODES` nodes are left between them, which are tested
    together (the farthest safe one wins). The result ``j >= i + first``
    has a safe segment ``i -> j``.
    """
    n = len(gpts)
    probes = [i + first]
    step = 2 * first
    while i + step < n - 1:  # bounded: step doubles
        probes.append(i + step)
        step *= 2
    if probes[-1] != n - 1:
        probes.append(n - 1)
    probes = np.array(probes)
    starts = np.repeat(gpts[i:i + 1], len(probes), axis=0)
    # First the cells near the anchor only (a subset of each probe's cells):
    # on a cluttered map most long probes fail there already. Only the
    # probes that pass are tested whole, so the outcome is the same.
    needs = needed[probes - i - 1]
    ok = np.ones(len(probes), bool)
    if len(probes) > 1:
        ok[1:] = _is_safe(raster.grid_segments_clearance(
            grid, starts[1:], gpts[probes[1:]], max_crossings=PROBE_PREFIX_CROSSINGS),
            r, needs[1:])
        whole = np.flatnonzero(ok[1:]) + 1
        if len(whole):
            ok[whole] = _is_safe(raster.grid_segments_clearance(
                grid, starts[whole], gpts[probes[whole]]), r, needs[whole])
    best = int(np.flatnonzero(ok)[-1])
    if best == len(probes) - 1:
        return int(probes[best])
    lo, hi = int(probes[best]), int(probes[best + 1])
    while hi - lo > DENSE_GAP_NODES:  # bounded: bisection
        # The midpoint and both possible next midpoints in one batch; the
        # same decisions as plain bisection.
        mid = (lo + hi) // 2
        left, right = (lo + mid) // 2, (mid + hi) // 2
        ends = np.array([mid, left, right])
        clearance = raster.grid_segments_clearance(
            grid, np.repeat(gpts[i:i + 1], 3, axis=0), gpts[ends])
        safe = _is_safe(clearance, r, needed[ends - i - 1])
        if safe[0]:
            lo = mid
            if hi - lo > 1:
                lo, hi = (right, hi) if safe[2] else (lo, right)
        else:
            hi = mid
            if hi - lo > 1:
                lo, hi = (left, hi) if safe[1] else (lo, left)
    if hi - lo <= 1:
        return lo
    # A short gap: every node of it in one batch, the farthest safe one.
    ends = np.arange(lo + 1, hi)
    safe = _is_safe(raster.grid_segments_clearance(
        grid, np.repeat(gpts[i:i + 1], len(ends), axis=0), gpts[ends]), r, needed[ends - i - 1])
    return int(ends[safe][-1]) if safe.any() else lo


def _window_reach(grid, gpts, r, needed):
    """Farthest safe node within :data:`WINDOW_NODES` of every node, in two batches.

    Parameters
    ----------
    grid : GridMap
    gpts : ndarray, float64, shape (N, 2)
        The nodes in grid coordinates, N >= 2.
    r : float
        Robot radius [m].
    needed : ndarray, float64, shape (N - 1, WINDOW_NODES)
        ``needed[i, k - 1]``: the clearance [m] segment ``i -> i + k`` must
        keep (inf past the last node).

    Returns
    -------
    ndarray, int64, shape (N - 1,)
        For node ``i``, with ``w = min(i + WINDOW_NODES, N - 1)`` the end of
        its window: ``-1`` when the segment ``i -> w`` is safe and ``w`` is
        not the last node (the reach lies beyond the window, see
        :func:`_farthest_safe`); else the largest ``j <= w`` with a safe
        segment ``i -> j``, or ``i + 1`` when there is none (the original
        step).

    Notes
    -----
    First every window end is tested (one segment per node): on open maps
    most pass and nothing more is needed. The nodes whose window end is
    unsafe then test every shorter segment of their window in one batch.
    """
    count = len(gpts) - 1
    first = np.arange(count)
    span = np.minimum(first + WINDOW_NODES, count) - first  # window length, >= 1
    ends = first + span
    safe_end = _is_safe(raster.grid_segments_clearance(grid, gpts[first], gpts[ends]),
                        r, needed[first, span - 1])
    reach = np.where(safe_end, np.where(ends == count, ends, -1), first + 1)
    # The shorter segments of the windows whose end is unsafe.
    short = np.flatnonzero(~safe_end & (span > 1))
    k = np.arange(1, WINDOW_NODES)
    node = np.repeat(short, WINDOW_NODES - 1)
    offset = np.tile(k, len(short))
    keep = offset < span[node]
    node, offset = node[keep], offset[keep]
    if len(node):
        safe = _is_safe(raster.grid_segments_clearance(grid, gpts[node], gpts[node + offset]),
                        r, needed[node, offset - 1])
        # The largest safe offset per node.
        farthest = np.zeros(count, np.int64)
        np.maximum.at(farthest, node[safe], offset[safe])
        reach[short] = np.where(farthest[short] > 0, short + farthest[short], short + 1)
    return reach


def _needed_clearance(step_clearance, r, s, tolerate_input_margin, width):
    """Clearance [m] a shortcut from node ``i`` over ``k + 1`` steps must keep.

    Returns shape ``(N - 1, width)`` for the ``N - 1`` steps: ``r + s``,
    or with ``tolerate_input_margin`` the smaller of that and the smallest
    clearance of the input steps ``i .. i + k``; inf past the last step.
    """
    count = len(step_clearance)
    needed = np.full((count, width), np.inf)
    if not tolerate_input_margin:
        for k in range(min(width, count)):  # bounded: the window's columns
            needed[:count - k, k] = r + s
        return needed
    running = np.minimum(step_clearance, r + s)
    needed[:, 0] = running
    for k in range(1, min(width, count)):  # bounded: the window's columns
        running = np.minimum(running[:-1], step_clearance[k:])
        needed[:count - k, k] = running
    return needed


def _prune(grid, pts, r, s, tolerate_input_margin):
    """Greedy redundant-node removal over all of ``pts``; indices kept."""
    n = len(pts)
    gpts = grid.world_to_grid(pts)
    step_clearance = raster.grid_segments_clearance(grid, gpts[:-1], gpts[1:])
    reach = _window_reach(grid, gpts, r,
                          _needed_clearance(step_clearance, r, s, tolerate_input_margin,
                                            WINDOW_NODES))
    kept = [0]
    i = 0
    while i < n - 1:  # bounded: i grows every pass
        if reach[i] >= 0:
            i = int(reach[i])
        else:  # safe to the end of its window: look farther
            if tolerate_input_margin:
                # A shortcut must keep r + s, or as much as the steps it replaces.
                needed = np.minimum(np.minimum.accumulate(step_clearance[i:]), r + s)
            else:
                needed = np.full(n - 1 - i, r + s)
            i = _farthest_safe(grid, gpts, i, r, needed, WINDOW_NODES)
        kept.append(i)
    return np.array(kept)


def prune_redundant(grid, points, robot_radius, safety_distance, tolerate_input_margin=False):
    """Remove redundant nodes of a grid path (paper section 1.3.3).

    Parameters
    ----------
    grid : GridMap
    points : array_like, shape (N, 2)
        The search path through cell centres ``(x, y)`` [m], map frame,
        N >= 1; traversable for ``robot_radius`` but possibly closer to
        obstacles than the safety distance.
    robot_radius : float
        Robot radius [m], >= 0.
    safety_distance : float
        Distance [m] beyond the radius a shortcut must keep, >= 0.
    tolerate_input_margin : bool
        False (the paper's rule): a shortcut must keep
        ``robot_radius + safety_distance``. True: where the input path
        itself runs closer than that, a shortcut need only keep the
        smallest clearance of the input steps it replaces (still
        ``> robot_radius``). See Notes.

    Returns
    -------
    ndarray, float64, shape (K, 2)
        The kept nodes, a subsequence of ``points`` with the first and last
        always kept and no collinear interior node; ``K`` is at most the
        number of key points (:func:`metrics.key_point_indices`) of the
        input.

    Raises
    ------
    InvalidInput
        If ``points`` is not a finite ``(N, 2)`` array or a distance is
        negative.

    Notes
    -----
    The paper's rule (1.3.3): of three consecutive nodes, join the first
    to the third; keep the middle one only when that line passes closer to
    an obstacle than the safety distance (:func:`segment_is_safe` is false).
    Applied greedily, from an anchor node the path jumps to the farthest
    later node reachable by a safe segment, keeps it and repeats from
    there. The reach of every node within its next :data:`WINDOW_NODES`
    nodes is found first, for all nodes at once in two vectorised batches
    (:func:`_window_reach`): on a cluttered map most jumps are that short,
    so the greedy pass costs no segment test of its own. Only an anchor
    whose whole window is reachable looks farther, by doubling then
    bisection (O(log N) segment tests). This replaced a per-anchor search
    whose cost was a handful of small numpy batches per kept node (57 ms
    for the 759-node path of 8room_000's longest row, now 13 ms;
    docs/BENCHMARKS.md). When no segment from a node is safe, not even the
    step to the next node (the search path runs inside the safety
    distance), that next node is kept, so the original step is used and the
    result is never less safe than the input. Collinear kept nodes are then
    dropped (the joined segment touches the same cells). If this leaves
    more nodes than the input has key points, the same procedure is run on
    the input's key points alone, which cannot.

    A search path on an inflated grid hugs the inflation, so with a
    positive safety distance many of its nodes lie inside the margin and
    no segment starting there can be safe: the paper's rule then keeps
    almost every key point. ``tolerate_input_margin=True`` relaxes the
    rule only there (the needed clearance of a shortcut over nodes
    ``i..j`` is ``min(robot_radius + safety_distance, c_ij)`` with
    ``c_ij`` the smallest clearance of the input steps ``i..j``); the
    smallest clearance of the result stays at least
    ``min(input clearance, robot_radius + safety_distance)`` either way.

    Examples
    --------
    >>> import numpy as np
    >>> from fusion_planner.core.grid import GridMap
    >>> grid = GridMap(np.zeros((4, 4), bool), resolution=1.0)
    >>> stairs = [[0.5, 0.5], [1.5, 0.5], [1.5, 1.5], [2.5, 1.5], [2.5, 2.5]]
    >>> prune_redundant(grid, stairs, 0.0, 0.0).tolist()
    [[0.5, 0.5], [2.5, 2.5]]
    """
    pts = raster.as_polyline(points, 'points')
    r, s = _check_distances(robot_radius, safety_distance)
    if len(pts) <= 2:
        return pts.copy()
    pruned = pts[_prune(grid, pts, r, s, tolerate_input_margin)]
    pruned = pruned[metrics.key_point_indices(pruned)]
    key = pts[metrics.key_point_indices(pts)]
    if len(pruned) > len(key):
        _LOG.debug('pruning all %d nodes kept %d > %d key points; pruning the key points',
                   len(pts), len(pruned), len(key))
        pruned = key[_prune(grid, key, r, s, tolerate_input_margin)]
        pruned = pruned[metrics.key_point_indices(pruned)]
    return pruned


def _sample_line(p, q, spacing):
    """Points from ``p`` (included) towards ``q`` (excluded), ~spacing apart."""
    length = math.hypot(q[0] - p[0], q[1] - p[1])
    if length <= SAME_POINT_M:
        return np.empty((0, 2))
    count = min(max(math.ceil(length / spacing), 1), MAX_SAMPLES_PER_PIECE)
    t = np.arange(count) / count
    return p + t[:, None] * (q - p)


def _corner_arc(q0, u_in, turn, sign, tangent, spacing):
    """Circular arc tangent to both legs, from ``q0`` over ``turn`` [rad].

    Returns the sampled arc, shape (m + 1, 2), first point ``q0``.
    """
    radius = tangent / math.tan(turn / 2)
    normal = sign * np.array([-u_in[1], u_in[0]])  # towards the inside of the turn
    centre = q0 + radius * normal
    chords = max(math.ceil(radius * turn / spacing), math.ceil(turn / MAX_CHORD_TURN_RAD), 1)
    chords = min(chords, MAX_SAMPLES_PER_PIECE)
    phi = sign * turn * np.arange(chords + 1) / chords
    v0 = q0 - centre
    cos, sin = np.cos(phi), np.sin(phi)
    arc = centre + np.stack([cos * v0[0] - sin * v0[1], sin * v0[0] + cos * v0[1]], axis=1)
    arc[0] = q0
    return arc


def _round_corners(grid, pts, r, s, spacing):
    """The verified rounded corner at every interior node of ``pts``.

    Returns, per interior node ``pts[i]`` (i = 1 .. n - 2), points from the
    arc start to the arc end (both included), or ``pts[i]`` alone when the
    corner stays sharp. Each corner is tried with its largest tangent length,
    then halved, as in the Notes of :func:`smooth_path`; all corners still
    being tried are checked together, one batch of segments per attempt.
    """
    count = len(pts) - 2
    result = [pts[i + 1][None, :] for i in range(count)]
    shape = []  # (corner, p, u_in, u_out, turn, sign) of the corners that turn
    tangent = []
    for c in range(count):  # bounded: one pass over the corners
        a, p, b = pts[c], pts[c + 1], pts[c + 2]
        len_in = math.hypot(*(p - a))
        len_out = math.hypot(*(b - p))
        u_in = (p - a) / len_in
        u_out = (b - p) / len_out
        cross = u_in[0] * u_out[1] - u_in[1] * u_out[0]
        turn = math.atan2(abs(cross), float(np.dot(u_in, u_out)))
        if turn < MIN_TURN_RAD or turn > math.pi - MIN_TURN_RAD:
            continue
        shape.append((c, p, u_in, u_out, turn, 1.0 if cross > 0 else -1.0))
        tangent.append(0.5 * min(len_in, len_out))
    pending = list(range(len(shape)))
    for _ in range(MAX_SHRINK_STEPS + 1):  # bounded: halving
        if not pending:
            break
        arcs, leg_starts, leg_ends = [], [], []
        for k in pending:
            c, p, u_in, u_out, turn, sign = shape[k]
            q0 = p - tangent[k] * u_in
            q2 = p + tangent[k] * u_out
            arc = _corner_arc(q0, u_in, turn, sign, tangent[k], spacing)
            arc[-1] = q2
            arcs.append(arc)
            leg_starts += [q0, p]
            leg_ends += [p, q2]
        # The legs and every chord of every arc in one batch; the smallest
        # clearance of an arc is that of its chords (metrics.min_clearance).
        sizes = np.array([len(arc) - 1 for arc in arcs])
        starts = np.concatenate([leg_starts] + [arc[:-1] for arc in arcs])
        ends = np.concatenate([leg_ends] + [arc[1:] for arc in arcs])
        clearance = raster.segments_clearance(grid, starts, ends)
        legs, chords = clearance[:len(leg_starts)], clearance[len(leg_starts):]
        got = np.minimum.reduceat(chords, np.concatenate([[0], np.cumsum(sizes)[:-1]]))
        still = []
        for index, k in enumerate(pending):
            need = min(float(min(legs[2 * index], legs[2 * index + 1])), r + s)
            if got[index] > r and got[index] >= need:
                result[shape[k][0]] = arcs[index]
            else:
                tangent[k] *= 0.5
                still.append(k)
        pending = still
    for k in pending:
        p = shape[k][1]
        _LOG.debug('corner at (%.3f, %.3f) left sharp: no arc keeps the clearance', p[0], p[1])
    return result


def smooth_path(grid, key_nodes, robot_radius, safety_distance, spacing):
    """Round the corners of a pruned path and sample it evenly.

    Parameters
    ----------
    grid : GridMap
    key_nodes : array_like, shape (K, 2)
        Pruned polyline ``(x, y)`` [m], map frame, K >= 1 (the output of
        :func:`prune_redundant`).
    robot_radius : float
        Robot radius [m], >= 0.
    safety_distance : float
        Safety distance [m] beyond the radius, >= 0.
    spacing : float
        Target distance [m] between consecutive output points, > 0.

    Returns
    -------
    ndarray, float64, shape (M, 2)
        The smoothed path [m], map frame; first and last points are exactly
        ``key_nodes[0]`` and ``key_nodes[-1]``; points are at most
        ``spacing`` apart (arcs may be sampled more densely, so that no two
        chords differ in heading by more than 5 degrees).

    Raises
    ------
    InvalidInput
        If ``key_nodes`` is not a finite ``(K, 2)`` array, a distance is
        negative or ``spacing`` is not a positive number.

    Notes
    -----
    Our reading of the "smoothing" of Table 2 (section 3.1): each interior
    corner is replaced by the circular arc tangent to both legs at distance
    ``d`` from the corner (radius ``d / tan(theta / 2)`` for a turn of
    ``theta``), with ``d`` at most half of each leg so that neighbouring
    arcs never overlap. A circular arc was chosen over a Bezier curve for
    its constant curvature (the robot turns at one rate through a corner).
    An arc is always shorter than the two leg pieces it replaces and turns
    by the same total angle, so smoothing never lengthens the path nor adds
    turning. Each arc, as the sampled polyline that is returned, is checked
    with :mod:`raster`: it must touch only map cells with clearance
    ``> robot_radius`` and no less than the smaller of the clearance of the
    leg pieces it replaces and ``robot_radius + safety_distance``;
    otherwise ``d`` is halved, at most 6 times, and then the corner is
    left sharp. Straight pieces lie on the pruned segments, so they touch
    no new cell.

    Examples
    --------
    >>> import numpy as np
    >>> from fusion_planner.core.grid import GridMap
    >>> grid = GridMap(np.zeros((10, 10), bool), resolution=1.0)
    >>> path = smooth_path(grid, [[0.5, 0.5], [8.5, 0.5], [8.5, 8.5]], 0.0, 0.0, 0.5)
    >>> path[0].tolist(), path[-1].tolist()
    ([0.5, 0.5], [8.5, 8.5])
    >>> bool(np.hypot(*np.diff(path, axis=0).T).max() <= 0.5 + 1e-9)
    True
    """
    nodes = raster.as_polyline(key_nodes, 'key nodes')
    r, s = _check_distances(robot_radius, safety_distance)
    if not _is_finite_number(spacing) or spacing <= 0:
        raise InvalidInput(f'spacing must be a positive number of metres, got {spacing!r}')
    spacing = float(spacing)
    steps = np.hypot(*np.diff(nodes, axis=0).T)
    pts = nodes[np.concatenate([[True], steps > SAME_POINT_M])]
    if len(pts) == 1:
        return nodes[[0, -1]] if len(nodes) > 1 else nodes.copy()
    pts[-1] = nodes[-1]
    pieces = []
    start = pts[0]
    for arc in _round_corners(grid, pts, r, s, spacing):  # bounded: one per corner
        pieces.append(_sample_line(start, arc[0], spacing))
        pieces.append(arc[:-1])
        start = arc[-1]
    pieces.append(_sample_line(start, pts[-1], spacing))
    pieces.append(pts[-1:])
    path = np.concatenate(pieces)
    path = path[np.concatenate([[True], np.hypot(*np.diff(path, axis=0).T) > SAME_POINT_M])]
    path[-1] = nodes[-1]
    return path
