"""The compiled distance transform equals scipy's, bit for bit, and loads before it is needed."""

import pathlib
import subprocess
import sys

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from scipy import ndimage

from fusion_planner.core import distance_transform
from fusion_planner.core.grid import GridMap

REPO = pathlib.Path(__file__).resolve().parent.parent

pytestmark = pytest.mark.skipif(not distance_transform.AVAILABLE, reason='numba is not installed')


@st.composite
def maps(draw):
    height, width = draw(st.integers(1, 50)), draw(st.integers(1, 50))
    density = draw(st.floats(0.001, 0.7))
    occupied = np.random.default_rng(draw(st.integers(0, 2**32 - 1))).random((height, width)) \
        < density
    occupied[draw(st.integers(0, height - 1)), draw(st.integers(0, width - 1))] = True
    return occupied


def _scipy_squared(occupied):
    return np.rint(ndimage.distance_transform_edt(~occupied) ** 2)


@settings(max_examples=200, deadline=None)
@given(occupied=maps())
def test_squared_distances_equal_scipy(occupied):
    grid = GridMap(occupied, 1.0)
    column = grid._column_distances()
    far = np.iinfo(np.uint16).max if column.dtype == np.uint16 else 1 << 30
    assert np.array_equal(distance_transform.squared_distances(column, far),
                          _scipy_squared(occupied))
    # The int32 layout of maps whose diagonal exceeds 65535 cells.
    wide = column.astype(np.int32)
    wide[column == far] = 1 << 30
    assert np.array_equal(distance_transform.squared_distances(wide, 1 << 30),
                          _scipy_squared(occupied))


def test_clearance_uses_it_and_keeps_its_values():
    occupied = np.zeros((40, 70), bool)
    occupied[10:30, 35] = True
    occupied[0, 0] = True
    clearance = GridMap(occupied, 0.05).clearance
    expected = np.sqrt(_scipy_squared(occupied)) * 0.05
    assert np.array_equal(clearance, expected)


def test_load_compiled_loops_loads_the_transform_and_the_search_in_a_fresh_process():
    """What a node does while it configures, so that no first map, plan or step stalls."""
    code = (
        'from fusion_planner.core import distance_transform\n'
        'from fusion_planner.core.global_planning import kernel\n'
        'from fusion_planner.core.global_planning.planner import PlannerConfig, '
        'load_compiled_loops\n'
        'assert distance_transform._ROWS._compiled is None and not kernel._compiled\n'
        'load_compiled_loops(PlannerConfig(robot_radius=0.2))\n'
        'print(len(distance_transform._ROWS._compiled.signatures), len(kernel._run.signatures))\n')
    done = subprocess.run([sys.executable, '-c', code], capture_output=True, text=True,
                          timeout=120, cwd=REPO)
    assert done.returncode == 0, done.stderr[-2000:]
    transform_loaded, search_loaded = map(int, done.stdout.split())
    assert transform_loaded >= 1 and search_loaded >= 1
