"""Large maps over real DDS: a 4000 x 4000 OccupancyGrid is planned on; a too large one is refused.

The peak memory of planning on such a map is a benchmark figure, not
asserted here.
"""

import numpy as np
import pytest
from rclpy.parameter import Parameter

from fusion_planner.core.grid import GridMap
from fusion_planner.ros import conversions as conv
from test_global_planner_node import Harness, map_msg, odom_msg

SIDE = 4000  # [cells]
RESOLUTION = 0.05  # [m]
#: Seconds a 16-million-cell map may take to cross DDS and be prepared [s].
LARGE_MAP_WAIT_S = 120.0


def shelves(side=SIDE):
    """A warehouse: rows of 2 m x 15 m shelves every 10 m x 20 m (at 0.05 m)."""
    occupied = np.zeros((side, side), bool)
    for row in range(100, side - 100, 200):
        for col in range(100, side - 400, 400):
            occupied[row:row + 40, col:col + 300] = True
    return GridMap(occupied, RESOLUTION)


@pytest.fixture
def harness(context):
    h = Harness(context, overrides=[Parameter('planning_time_limit', value=60.0)])
    yield h
    h.close()


def test_a_4000_by_4000_map_is_accepted_and_planned_on(harness):
    grid = shelves()
    harness.map_pub.publish(map_msg(grid))
    assert harness.spin_until(lambda: harness.planner._map_msg is not None, LARGE_MAP_WAIT_S)
    start, goal = (1.0, 1.0), (60.0, 48.0)
    harness.odom_pub.publish(odom_msg(*start))
    assert harness.spin_until(lambda: harness.planner._start is not None)
    assert harness.send_goal(*goal), 'no plan on the large map'
    path = conv.path_from_msg(harness.plans[-1], 'map')
    assert np.hypot(*(path[0] - start)) < 0.1 and np.hypot(*(path[-1] - goal)) < 0.1
    cells = grid.cell_of(path)
    assert not grid.occupied[cells[:, 0], cells[:, 1]].any()


def test_a_map_beyond_the_cell_limit_is_refused_and_the_last_map_kept(context):
    h = Harness(context, overrides=[Parameter('max_map_cells', value=1_000_000)])
    try:
        h.setup_world()  # the small wall map
        kept = h.planner._map_msg
        h.map_pub.publish(map_msg(GridMap(np.zeros((1001, 1000), bool), RESOLUTION)))
        assert h.spin_until(lambda: 'exceeds the limit of 1000000 cells'
                            in h.diag_values().get('last_error', ''), LARGE_MAP_WAIT_S)
        assert h.planner._map_msg is kept
        assert h.send_goal(7.0, 3.0), 'the kept map no longer plans'
    finally:
        h.close()

