"""Search neighbourhoods as data tables (paper section 1.2 and 1.3.1).

A move is ``(d_row, d_col, cost, crossed)``: the step in cells, its length
in cells, and the cells (relative to the source) that the straight step
crosses and that must be free besides the target. This is what forbids
corner cutting: a diagonal step needs both orthogonal neighbours free, a
16-neighbourhood (knight) step needs the two cells its segment passes
through free.

The variable neighbourhood of the improved A* (section 1.3.1) keeps only
the moves that head towards the goal: the goal direction angle alpha,
measured from the +x (column) axis, is rounded to one of eight sectors of
45 degrees, and a move is kept when it lies within 90 degrees of that
sector's direction. For the 8-neighbourhood this is 5 of the 8 moves.
"""

import math

ORTHOGONAL = ((0, 1), (1, 0), (0, -1), (-1, 0))
DIAGONAL = ((1, 1), (1, -1), (-1, 1), (-1, -1))
KNIGHT = ((1, 2), (2, 1), (-1, 2), (-2, 1), (1, -2), (2, -1), (-1, -2), (-2, -1))

SUPPORTED = (4, 8, 16)

#: Number of goal-direction sectors of the variable neighbourhood.
SECTORS = 8


def _sign(v):
    return (v > 0) - (v < 0)


def _crossed_cells(dr, dc):
    """Cells besides the target that the straight step (dr, dc) crosses."""
    if abs(dr) == 1 and abs(dc) == 1:
        return ((dr, 0), (0, dc))
    if abs(dr) == 1 and abs(dc) == 2:
        return ((0, _sign(dc)), (dr, _sign(dc)))
    if abs(dr) == 2 and abs(dc) == 1:
        return ((_sign(dr), 0), (_sign(dr), dc))
    return ()


def moves(neighbourhood):
    """The move table of a 4-, 8- or 16-neighbourhood.

    Parameters
    ----------
    neighbourhood : int
        4, 8 or 16.

    Returns
    -------
    list of tuple
        ``(d_row, d_col, cost, crossed)`` with ``cost`` in cells and
        ``crossed`` a tuple of ``(d_row, d_col)`` cells that must be free.

    Raises
    ------
    ValueError
        If ``neighbourhood`` is not 4, 8 or 16.

    Examples
    --------
    >>> [m[:3] for m in moves(4)][:2]
    [(0, 1, 1.0), (1, 0, 1.0)]
    >>> len(moves(8)), len(moves(16))
    (8, 16)
    """
    if neighbourhood not in SUPPORTED:
        raise ValueError(f'neighbourhood must be one of {SUPPORTED}, got {neighbourhood!r}')
    steps = list(ORTHOGONAL)
    if neighbourhood >= 8:
        steps += DIAGONAL
    if neighbourhood == 16:
        steps += KNIGHT
    return [(dr, dc, math.hypot(dr, dc), _crossed_cells(dr, dc)) for dr, dc in steps]


def sector_of(d_row, d_col):
    """Sector index 0..7 of a direction (45-degree sectors, 0 = +column axis)."""
    return round(math.atan2(d_row, d_col) / (math.pi / 4)) % SECTORS


def sector_split(move_table):
    """Split a move table into per-sector forward and remaining moves.

    Parameters
    ----------
    move_table : list of tuple
        As returned by :func:`moves`.

    Returns
    -------
    forward, rest : list of list of int
        For each of the 8 sectors, the indices into ``move_table`` of the
        moves within 90 degrees of the sector direction, and of the others.
    """
    forward, rest = [], []
    for sector in range(SECTORS):
        angle = sector * math.pi / 4
        ux, uy = math.cos(angle), math.sin(angle)
        ahead, behind = [], []
        for index, (dr, dc, _, _) in enumerate(move_table):
            # Small tolerance keeps the perpendicular moves (dot = 0) forward.
            (ahead if dc * ux + dr * uy > -1e-9 else behind).append(index)
        forward.append(ahead)
        rest.append(behind)
    return forward, rest
