"""The generated building floor: walls, doors, furniture, reachability."""

import numpy as np
import pytest
from scipy import ndimage

from fusion_planner.bench.building_map import BuildingSpec, building_map, far_pairs
from fusion_planner.core.errors import InvalidInput, MapError
from fusion_planner.core.grid import GridMap

#: A small floor: 4 x 4 rooms of 10 m at 0.1 m.
SMALL = BuildingSpec(side_m=40.0, room_m=10.0, resolution=0.1)


@pytest.mark.parametrize('seed', range(5))
def test_every_room_is_reachable_through_doors_for_the_robot(seed):
    occupied = building_map(SMALL, seed)
    traversable = GridMap(occupied, SMALL.resolution).traversable(0.2)
    labels, _ = ndimage.label(traversable)
    room = SMALL.cells(SMALL.room_m)
    # The free ring along the walls of every room, 0.5 m in: all one component.
    inset = SMALL.cells(0.5)
    ring_labels = {int(labels[r * room + inset, c * room + inset])
                   for r in range(4) for c in range(4)}
    assert 0 not in ring_labels and len(ring_labels) == 1


def test_walls_enclose_the_floor_and_doors_have_their_width():
    occupied = building_map(SMALL, 7)
    assert occupied[0].all() and occupied[-1].all()
    assert occupied[:, 0].all() and occupied[:, -1].all()
    room = SMALL.cells(SMALL.room_m)
    door = SMALL.cells(SMALL.door_m)
    wall_row = occupied[room, :]  # an inner wall along a row
    gaps = np.diff(np.flatnonzero(np.diff(np.concatenate([[1], wall_row, [1]]).astype(int))))
    openings = gaps[::2]
    assert len(openings) >= 1 and (openings == door).all()


def test_the_same_seed_gives_the_same_floor_and_another_seed_another():
    a, b, c = building_map(SMALL, 3), building_map(SMALL, 3), building_map(SMALL, 4)
    assert np.array_equal(a, b) and not np.array_equal(a, c)


def test_default_floor_is_4000_cells_of_5_cm():
    spec = BuildingSpec()
    assert spec.cells(spec.side_m) == 4000 and spec.resolution == 0.05


def test_bad_dimensions_are_refused():
    with pytest.raises(InvalidInput):
        building_map(BuildingSpec(side_m=45.0, room_m=10.0, resolution=0.1))
    with pytest.raises(InvalidInput):
        building_map(BuildingSpec(side_m=4.0, room_m=2.0, door_m=1.5, resolution=0.1))


def test_far_pairs_are_far_and_connected():
    occupied = building_map(SMALL, 2)
    traversable = GridMap(occupied, SMALL.resolution).traversable(0.2)
    labels, _ = ndimage.label(traversable)
    pairs = far_pairs(traversable, 5, 200, seed=1)
    assert len(pairs) == 5
    for start, goal in pairs:
        assert np.hypot(start[0] - goal[0], start[1] - goal[1]) >= 200
        assert labels[start] == labels[goal] != 0
    with pytest.raises(MapError):
        far_pairs(traversable, 1, 10_000, seed=1, max_draws=50)
