"""The paper-like 20 x 20 map of ``config/maps/paper.yaml`` and its start and goal.

The paper (section 3.1, Figure 3) plans on a 20 x 20 grid whose layout it
does not publish. This module builds a comparable one: block obstacles and
walls that force several turns and a concave pocket facing the start, with
the start near the bottom-left corner and the goal in the top-right corner,
18 cells apart along each axis, as the paper's A*-4 length of 36 cells
(= 18 + 18) implies. One cell is 1 m, so metres equal cells as in the paper.

The map is kept here as text, top row first (as the image stores it), so
that tests and docs can rebuild it and the layout can be read at a glance.
Regenerate the files with::

    python -m fusion_planner.bench.paper_map config/maps/paper.yaml
"""

import argparse
import pathlib
import sys

import numpy as np

from fusion_planner.core.grid import GridMap
from fusion_planner.core.map_files import save_map_server

#: The map as text, top row first (image order): ``#`` obstacle, ``.`` free.
PAPER_MAP_ROWS = (
    '....................',
    '....................',
    '..###........##.....',
    '..###........##.....',
    '.............##.....',
    '.........#####......',
    '.............#......',
    '...#.........#..###.',
    '...#............###.',
    '...#................',
    '...#................',
    '...####....####.....',
    '...........####.....',
    '.......###..........',
    '.......###..........',
    '...#........##......',
    '...#.......###......',
    '...#................',
    '...####.............',
    '...........##.......',
)

#: Cell edge [m]: one cell is one metre, so lengths in metres are in cells.
RESOLUTION_M = 1.0
#: Map origin ``(x, y, yaw)`` [m, m, rad].
ORIGIN = (0.0, 0.0, 0.0)
#: Default start and goal cells ``(row, col)``, grid convention (row 0 at
#: the bottom).
START_CELL = (1, 1)
GOAL_CELL = (19, 19)
#: The same as cell centres ``(x, y)`` [m], map frame.
START_XY = (START_CELL[1] + 0.5, START_CELL[0] + 0.5)
GOAL_XY = (GOAL_CELL[1] + 0.5, GOAL_CELL[0] + 0.5)

#: Where the bundled files live, relative to the repository / share folder.
MAP_RELATIVE_PATH = pathlib.Path('config') / 'maps' / 'paper.yaml'


def build_occupancy():
    """The paper-like map as an occupancy array.

    Returns
    -------
    ndarray, bool, shape (20, 20)
        True on obstacles, indexed ``[row, col]`` with row 0 at the bottom
        (the map origin), i.e. :data:`PAPER_MAP_ROWS` flipped upside down.

    Examples
    --------
    >>> occ = build_occupancy()
    >>> occ.shape, bool(occ[START_CELL]), bool(occ[GOAL_CELL])
    ((20, 20), False, False)
    """
    text_rows = np.array([[ch == '#' for ch in row] for row in PAPER_MAP_ROWS], dtype=bool)
    return np.ascontiguousarray(text_rows[::-1])


def paper_grid():
    """The paper-like map as a :class:`~fusion_planner.core.grid.GridMap`."""
    return GridMap(build_occupancy(), RESOLUTION_M, ORIGIN)


def write_paper_map(yaml_path):
    """Write the paper-like map as a map_server YAML + trinary PGM.

    Parameters
    ----------
    yaml_path : str or os.PathLike
        The YAML to write; the PGM goes beside it with the same stem.

    Returns
    -------
    pathlib.Path
        The PGM written.
    """
    return save_map_server(paper_grid(), yaml_path)


def find_paper_map():
    """Path of the bundled ``paper.yaml``: source tree first, then an install.

    Returns
    -------
    pathlib.Path or None
        None when neither the repository copy nor an installed
        ``share/fusion_planner/config/maps/paper.yaml`` exists.
    """
    here = pathlib.Path(__file__).resolve()
    installed = pathlib.Path('share') / 'fusion_planner' / MAP_RELATIVE_PATH
    # The repository root, then <prefix>/share/fusion_planner of a pip or
    # colcon install (sys.prefix, or an ancestor of site-packages).
    candidates = [here.parents[2] / MAP_RELATIVE_PATH, pathlib.Path(sys.prefix) / installed]
    candidates += [parent / installed for parent in here.parents]
    for candidate in candidates:
        if candidate.is_file():
            return candidate
    return None


def main(argv=None):
    """Regenerate the map files: ``python -m fusion_planner.bench.paper_map [OUT.yaml]``."""
    parser = argparse.ArgumentParser(description='Write the paper-like 20 x 20 map.')
    parser.add_argument('yaml', nargs='?', default=str(MAP_RELATIVE_PATH),
                        help='YAML to write (default %(default)s); the PGM goes beside it')
    args = parser.parse_args(argv)
    write_paper_map(args.yaml)
    return 0


if __name__ == '__main__':
    sys.exit(main())
