"""A generated building floor: rooms behind walls with doors, and furniture.

The benchmark of a building-scale map (``fusion-planner bench peers --suites
building``) and the node latency script plan on it. The floor is a square of
rooms of equal size behind walls; the doors between rooms form a random
spanning tree of the rooms (so every room is reachable, usually by a detour)
plus a share of extra doors, and each room holds a few rectangular pieces of
furniture kept off its walls, so that the free ring along the walls connects
its doors.

With the defaults the map is 4000 x 4000 cells of 0.05 m (200 m square),
10 x 10 rooms of 20 m, doors of 1.5 m, walls of 0.2 m.

Examples
--------
>>> floor = building_map(BuildingSpec(side_m=10.0, room_m=5.0), seed=1)
>>> floor.shape
(200, 200)
>>> bool(floor[0].all() and floor[:, 0].all())  # the outer wall
True
"""

from dataclasses import dataclass

import numpy as np
from scipy import ndimage

from fusion_planner.core.errors import InvalidInput, MapError


@dataclass(frozen=True)
class BuildingSpec:
    """Dimensions of a generated building floor.

    Attributes
    ----------
    side_m : float
        Edge of the square floor [m]; a multiple of ``room_m``.
    room_m : float
        Edge of a square room, walls included [m].
    door_m : float
        Door width [m].
    wall_m : float
        Wall thickness [m].
    resolution : float
        Cell edge [m].
    extra_doors : float
        Share of the walls between rooms that get a door besides the
        spanning tree's, in [0, 1].
    furniture_per_room : tuple of int
        Least and most pieces of furniture per room.
    furniture_m : tuple of float
        Least and largest side of a piece [m].
    furniture_margin_m : float
        Free band kept between furniture and the walls [m].
    """

    side_m: float = 200.0
    room_m: float = 20.0
    door_m: float = 1.5
    wall_m: float = 0.2
    resolution: float = 0.05
    extra_doors: float = 0.3
    furniture_per_room: tuple = (3, 8)
    furniture_m: tuple = (0.5, 2.5)
    furniture_margin_m: float = 1.0

    def cells(self, metres):
        """A length [m] in whole cells (at least one)."""
        return max(1, int(round(metres / self.resolution)))


def building_map(spec=BuildingSpec(), seed=0):
    """Generate a building floor.

    Parameters
    ----------
    spec : BuildingSpec
    seed : int

    Returns
    -------
    ndarray of bool, shape (N, N)
        True where occupied; ``N = side_m / resolution``; row 0 at the
        origin.

    Raises
    ------
    InvalidInput
        If the floor is not a whole number of rooms, or a room is too small
        for its door and margins.
    """
    side = spec.cells(spec.side_m)
    room = spec.cells(spec.room_m)
    wall = spec.cells(spec.wall_m)
    door = spec.cells(spec.door_m)
    margin = spec.cells(spec.furniture_margin_m)
    rooms = side // room
    if rooms * room != side or rooms < 1:
        raise InvalidInput(f'a floor of {spec.side_m} m is not a whole number of '
                           f'{spec.room_m} m rooms')
    if room < door + 2 * (wall + margin):
        raise InvalidInput(f'rooms of {spec.room_m} m are too small for doors of {spec.door_m} m')
    rng = np.random.default_rng(seed)
    occupied = np.zeros((side, side), bool)
    for k in range(rooms + 1):  # walls on every room boundary, the outer ones inside the map
        at = min(k * room, side - wall)
        occupied[at:at + wall, :] = True
        occupied[:, at:at + wall] = True
    for (r0, c0), (r1, c1) in _doors(rooms, spec.extra_doors, rng):
        # A door through the wall between room (r0, c0) and its neighbour.
        lo = wall + margin
        offset = int(rng.integers(lo, room - lo - door + 1))
        if r1 != r0:  # wall along a row
            row = r1 * room
            col = c0 * room + offset
            occupied[row:row + wall, col:col + door] = False
        else:
            col = c1 * room
            row = r0 * room + offset
            occupied[row:row + door, col:col + wall] = False
    lo_piece, hi_piece = (spec.cells(v) for v in spec.furniture_m)
    inner_lo = wall + margin
    for r in range(rooms):
        for c in range(rooms):
            count = int(rng.integers(spec.furniture_per_room[0], spec.furniture_per_room[1] + 1))
            for _ in range(count):
                h, w = (int(v) for v in rng.integers(lo_piece, hi_piece + 1, size=2))
                row = r * room + int(rng.integers(inner_lo, room - margin - h + 1))
                col = c * room + int(rng.integers(inner_lo, room - margin - w + 1))
                occupied[row:row + h, col:col + w] = True
    return occupied


def _doors(rooms, extra_share, rng):
    """Pairs of adjacent rooms ``((r, c), (r', c'))`` that get a door.

    A random spanning tree (randomised depth-first search) connects every
    room; ``extra_share`` of the remaining walls between rooms get a door too.
    """
    visited = np.zeros((rooms, rooms), bool)
    stack = [(0, 0)]
    visited[0, 0] = True
    tree = set()
    while stack:  # bounded: each room is pushed once
        r, c = stack[-1]
        options = [(r + dr, c + dc) for dr, dc in ((0, 1), (1, 0), (0, -1), (-1, 0))
                   if 0 <= r + dr < rooms and 0 <= c + dc < rooms and not visited[r + dr, c + dc]]
        if not options:
            stack.pop()
            continue
        nxt = options[int(rng.integers(len(options)))]
        visited[nxt] = True
        tree.add(tuple(sorted(((r, c), nxt))))
        stack.append(nxt)
    walls = [((r, c), (r + dr, c + dc)) for r in range(rooms) for c in range(rooms)
             for dr, dc in ((0, 1), (1, 0)) if r + dr < rooms and c + dc < rooms]
    extra = [pair for pair in walls if pair not in tree and rng.random() < extra_share]
    return sorted(tree) + extra


def far_pairs(traversable, count, min_distance_cells, seed, max_draws=100_000):
    """Start/goal cells in the same free component, far apart.

    Parameters
    ----------
    traversable : ndarray of bool, shape (H, W)
        Cells a robot centre may occupy.
    count : int
        Number of pairs to return.
    min_distance_cells : float
        Least straight-line distance between start and goal [cells].
    seed : int
    max_draws : int
        Draws before giving up.

    Returns
    -------
    list of tuple
        ``((row, col), (row, col))`` pairs.

    Raises
    ------
    MapError
        If ``count`` pairs are not found in ``max_draws`` draws.
    """
    # 4-connected: without corner cutting, exactly what 8-moves can reach.
    labels, _ = ndimage.label(traversable)
    largest = np.bincount(labels.ravel())[1:].argmax() + 1
    rows, cols = np.nonzero(labels == largest)
    rng = np.random.default_rng(seed)
    pairs = []
    for _ in range(max_draws):  # bounded
        i, j = rng.integers(len(rows), size=2)
        if np.hypot(rows[i] - rows[j], cols[i] - cols[j]) >= min_distance_cells:
            pairs.append(((int(rows[i]), int(cols[i])), (int(rows[j]), int(cols[j]))))
            if len(pairs) == count:
                return pairs
    raise MapError(f'only {len(pairs)} of {count} far start/goal pairs found')
