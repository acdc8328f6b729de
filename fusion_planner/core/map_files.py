"""Every way a :class:`~fusion_planner.core.grid.GridMap` is built from outside data.

Sources:

- ``nav_msgs/OccupancyGrid`` fields (:func:`from_occupancy_values`), without
  importing ROS: the adapters pass ``msg.info.width``, ``msg.data`` ...
- ROS map_server map files: a YAML descriptor and a PGM/PNG image
  (:func:`load_map_server_yaml`, :func:`save_map_server`), with the semantics
  of ``nav2_map_server``'s ``map_io``.
- The MovingAI grid benchmark: ``.map`` files (:func:`load_movingai`) and
  ``.map.scen`` scenario files (:func:`read_scenarios`).

Row conventions. A :class:`GridMap` has row 0 at the map origin (lowest y
when the origin yaw is 0), like ``OccupancyGrid.data``. Image files and
MovingAI maps store the *top* row first, so their loaders flip them: file row
``i`` of an ``H``-row file becomes grid row ``H - 1 - i``
(:func:`movingai_cell`). Occupancy values are not flipped.

Every failure raises :class:`~fusion_planner.core.errors.MapError` with one
sentence naming the file; no ``OSError``, ``yaml.YAMLError``,
``UnicodeDecodeError`` or ``ValueError`` escapes.

References
----------
ROS map_server map format: http://wiki.ros.org/map_server and the Nav2
``nav2_map_server`` package (``map_io``).
N. Sturtevant, "Benchmarks for Grid-Based Pathfinding", IEEE TCIAIG 4(2):
144-148, 2012 (https://www.movingai.com/benchmarks/grids.html).
"""

import io
import logging
import math
import numbers
import operator
import os
import pathlib
import re
import stat
from dataclasses import dataclass

import numpy as np
import yaml

from fusion_planner.core.errors import MapError
from fusion_planner.core.grid import DEFAULT_MAX_CELLS, GridMap

_LOG = logging.getLogger(__name__)

# -- OccupancyGrid values ---------------------------------------------------

#: ``OccupancyGrid.data`` value of an unknown cell.
OCC_UNKNOWN = -1
#: Smallest and largest occupancy probability [percent].
OCC_FREE = 0
OCC_OCCUPIED = 100
#: Default occupied threshold [percent]: a value >= this is an obstacle
#: (the ``occupied_thresh`` 0.65 of map_server files).
DEFAULT_OCCUPIED_THRESHOLD = 65

# -- map_server files ------------------------------------------------------

#: Interpretations of the image named by a map_server YAML.
MAP_SERVER_MODES = ('trinary', 'scale', 'raw')
#: Thresholds map_server uses when the YAML does not give them
#: [occupancy probability, 0..1].
DEFAULT_OCCUPIED_THRESH = 0.65
DEFAULT_FREE_THRESH = 0.25
#: Pixel values of a saved trinary PGM (8-bit, maxval 255).
PGM_OCCUPIED = 0
PGM_FREE = 254
PGM_UNKNOWN = 205
PGM_MAXVAL = 255
#: Thresholds written beside a saved PGM. 205 means occupancy
#: (255 - 205) / 255 = 0.19608; with map_server's usual free_thresh 0.25 it
#: would read back as *free*, so unknown cells would not survive a round trip.
#: 0.196 (ROS 1 map_saver's value) keeps 205 inside the unknown band.
SAVE_OCCUPIED_THRESH = 0.65
SAVE_FREE_THRESH = 0.196
#: Largest map YAML read [bytes]; a descriptor is a few lines.
MAX_YAML_BYTES = 1 << 20
#: Bytes allowed per map cell in an image file (16-bit RGBA, or ASCII PGM
#: with up to five digits and a separator per pixel) plus header slack.
_IMAGE_BYTES_PER_CELL = 8
_HEADER_SLACK_BYTES = 64 * 1024
#: Largest 16-bit sample value.
_MAXVAL_16BIT = 65535

# -- MovingAI files --------------------------------------------------------

#: Terrain characters a MovingAI agent may stand on: ground and swamp.
MOVINGAI_PASSABLE = b'.GS'
#: Cell edge of a MovingAI map [m] (the benchmark is unitless; one cell = 1 m).
MOVINGAI_RESOLUTION = 1.0
#: Header lines before ``map`` (type, height, width) plus a little slack.
_MOVINGAI_MAX_HEADER_LINES = 16
#: Bytes allowed per cell of a ``.map`` (a character, plus CRLF per row).
_MOVINGAI_BYTES_PER_CELL = 3
#: Largest scenario file read [bytes] (the biggest benchmark one is 0.7 MB).
MAX_SCENARIO_BYTES = 256 << 20
#: Number of tab-separated fields of a scenario line.
_SCEN_FIELDS = 9

_DIGITS = re.compile(rb'\d+')
_PGM_COMMENT = re.compile(rb'#[^\n]*')


@dataclass(frozen=True)
class ScenarioRow:
    """One line of a MovingAI ``.map.scen`` file, in file coordinates.

    Attributes
    ----------
    bucket : int
        Difficulty bucket (``floor(optimal_length / 4)`` in the benchmark).
    map_name : str
        Bare file name of the map, e.g. ``'arena2.map'``.
    width, height : int
        Size of the map [cells].
    start_col, start_row, goal_col, goal_row : int
        Start and goal as in the file: column x and *file* row y (row 0 is
        the top line). Convert with :func:`movingai_cell`.
    optimal_length : float
        Octile length of a shortest path without corner cutting [cells].
    """

    bucket: int
    map_name: str
    width: int
    height: int
    start_col: int
    start_row: int
    goal_col: int
    goal_row: int
    optimal_length: float


# ---------------------------------------------------------------------------
# OccupancyGrid fields
# ---------------------------------------------------------------------------

def from_occupancy_values(width, height, resolution, origin, data,
                          unknown_is_occupied=False,
                          occupied_threshold=DEFAULT_OCCUPIED_THRESHOLD,
                          max_cells=DEFAULT_MAX_CELLS):
    """Build a grid from ``nav_msgs/OccupancyGrid``-style fields.

    Parameters
    ----------
    width, height : int
        Columns and rows, > 0 (``msg.info.width``, ``msg.info.height``).
    resolution : float
        Cell edge [m], finite and > 0.
    origin : sequence of 3 float
        ``(x, y, yaw)`` of the corner of cell ``(0, 0)`` [m, m, rad], map
        frame (``msg.info.origin`` reduced to a planar pose).
    data : list of int, bytes-like, array.array or ndarray
        ``width * height`` occupancy values in row-major order, row 0 at the
        origin (no flip): 0..100 occupancy probability [percent], -1 unknown.
        A ``bytes``/``bytearray``/``memoryview`` is read as int8, as ROS
        serialises ``int8[]`` (byte 255 is -1).
    unknown_is_occupied : bool, optional
        Resolve unknown cells as obstacles (True) or free space (False,
        default). They are kept in ``GridMap.unknown`` either way.
    occupied_threshold : int, optional
        A cell is occupied when its value is >= this, 1..100. Default 65.
    max_cells : int, optional
        Refuse maps with more cells than this, checked before any array is
        allocated.

    Returns
    -------
    GridMap
        ``occupied`` and ``unknown`` of shape ``(height, width)``.

    Raises
    ------
    MapError
        If width or height is not a positive integer, ``len(data)`` differs
        from ``width * height``, the map is larger than ``max_cells``, a value
        lies outside -1..100 or is not an integer, the threshold is outside
        1..100, or the resolution or origin is not finite (or resolution <= 0).

    Examples
    --------
    >>> grid = from_occupancy_values(3, 2, 0.5, (0.0, 0.0, 0.0), [0, 100, -1, 0, 0, 70])
    >>> grid.occupied.astype(int).tolist()
    [[0, 1, 0], [0, 0, 1]]
    >>> grid.unknown.astype(int).tolist()
    [[0, 0, 1], [0, 0, 0]]
    """
    width = _positive_int(width, 'occupancy grid width')
    height = _positive_int(height, 'occupancy grid height')
    threshold = _threshold_percent(occupied_threshold)
    n_cells = width * height
    _check_cell_limit(width, height, max_cells, 'occupancy grid')
    resolution = _check_resolution(resolution, 'occupancy grid')
    origin = _check_origin(origin, 'occupancy grid')
    count = _value_count(data)
    if count != n_cells:
        raise MapError(
            f'occupancy grid data has {count} values but width x height is '
            f'{width} x {height} = {n_cells}')
    values = _occupancy_array(data).reshape(height, width)
    bad = (values < OCC_UNKNOWN) | (values > OCC_OCCUPIED)
    if bad.any():
        row, col = np.argwhere(bad)[0]
        raise MapError(
            f'occupancy value {values[row, col]} at row {row}, column {col} '
            f'is outside -1..100')
    values = values.astype(np.int8)
    unknown = values == OCC_UNKNOWN
    occupied = values >= threshold
    if unknown_is_occupied:
        occupied |= unknown
    return GridMap(occupied, resolution, origin, unknown=unknown, max_cells=max_cells)


def _value_count(data):
    """Count the values in ``data`` without converting it."""
    if isinstance(data, np.ndarray):
        return int(data.size)
    if isinstance(data, memoryview):
        return data.nbytes if data.itemsize == 1 else int(np.prod(data.shape))
    try:
        return len(data)
    except TypeError:
        raise MapError(
            f'occupancy grid data must be a sequence of integers, got {type(data).__name__}'
        ) from None


def _occupancy_array(data):
    """Convert occupancy values to a flat integer or integral-float array."""
    if isinstance(data, (bytes, bytearray)) or (
            isinstance(data, memoryview) and data.format in ('b', 'B', 'c')):
        return np.frombuffer(data, dtype=np.int8)
    try:
        values = np.asarray(data).ravel()
    except (TypeError, ValueError):
        raise MapError('occupancy grid data must be a sequence of integers') from None
    if values.dtype.kind in 'iu':
        return values
    if values.dtype.kind == 'f':
        if not np.all(np.isfinite(values)) or np.any(values != np.round(values)):
            raise MapError('occupancy grid data must hold integers, got non-integral numbers')
        return values
    raise MapError(
        f'occupancy grid data must hold integers, got values of type {values.dtype}')


def _threshold_percent(value):
    """Validate an occupied threshold in percent (1..100)."""
    if isinstance(value, bool) or not isinstance(value, numbers.Real) \
            or not math.isfinite(value) or not OCC_FREE < value <= OCC_OCCUPIED:
        raise MapError(f'occupied threshold must be a number in 1..100, got {value!r}')
    return value


# ---------------------------------------------------------------------------
# map_server YAML + image
# ---------------------------------------------------------------------------

def load_map_server_yaml(path, unknown_is_occupied=False, max_cells=DEFAULT_MAX_CELLS):
    """Load a ROS map_server map: a YAML descriptor and the image it names.

    Parameters
    ----------
    path : str or os.PathLike
        The ``.yaml`` file. Keys: ``image`` (path, relative to the YAML's
        folder unless absolute), ``resolution`` [m/cell], ``origin``
        ``[x, y, yaw]`` [m, m, rad] of the lower-left pixel's corner, and
        optionally ``negate`` (0/1, default 0), ``occupied_thresh`` (default
        0.65), ``free_thresh`` (default 0.25) and ``mode`` (``trinary``
        default, ``scale`` or ``raw``).
    unknown_is_occupied : bool, optional
        Resolve unknown pixels as obstacles (True) or free (False, default);
        they are kept in ``GridMap.unknown`` either way.
    max_cells : int, optional
        Refuse images with more pixels than this (checked from the header,
        before the pixels are decoded).

    Returns
    -------
    GridMap
        Row 0 is the image's *bottom* row (the image is flipped).

    Raises
    ------
    MapError
        If the YAML is missing, unreadable, not valid YAML, or lacks
        ``image``, ``resolution`` or ``origin``; if a value is out of range;
        if the image is missing, truncated, malformed or in a format that
        needs Pillow when Pillow is not installed; or if the map is too large.

    Notes
    -----
    The semantics are those of ``nav2_map_server``'s ``map_io``. A pixel's
    shade ``s`` in [0, 1] is its value over the image's maximum (colour
    channels averaged, alpha ignored). Its occupancy probability is
    ``p = 1 - s`` (``p = s`` when ``negate``):

    - ``trinary``: occupied if ``p > occupied_thresh``, free if
      ``p < free_thresh``, unknown otherwise.
    - ``scale``: the same for a boolean grid (map_server scales the in-between
      band to 1..99; here it stays unknown).
    - ``raw``: the pixel value ``round(255 s)`` is the occupancy in percent
      (``negate`` is ignored, as in Nav2); values above 100 are unknown, and
      ``p = value / 100`` is banded with the thresholds as above.

    Images: PGM (P2 ASCII and P5 binary, 8- or 16-bit) is read by a small
    parser here; PNG and other formats need Pillow.
    """
    path = _as_path(path, 'map YAML')
    doc = _read_yaml(path)
    image = doc.get('image')
    if image is None:
        raise MapError(f'map YAML {path} has no "image" key naming the map image')
    if not isinstance(image, str) or not image.strip():
        raise MapError(f'map YAML {path} has an "image" that is not a file name: {image!r}')
    for key in ('resolution', 'origin'):
        if key not in doc:
            raise MapError(f'map YAML {path} has no "{key}" key')
    resolution = _check_resolution(doc['resolution'], f'map YAML {path}')
    origin = _check_origin(doc['origin'], f'map YAML {path}')
    negate = _yaml_negate(doc.get('negate', 0), path)
    occupied_thresh = _yaml_probability(doc, 'occupied_thresh', DEFAULT_OCCUPIED_THRESH, path)
    free_thresh = _yaml_probability(doc, 'free_thresh', DEFAULT_FREE_THRESH, path)
    if free_thresh > occupied_thresh:
        raise MapError(
            f'map YAML {path} has free_thresh {free_thresh} above '
            f'occupied_thresh {occupied_thresh}')
    mode = doc.get('mode', 'trinary')
    if not isinstance(mode, str) or mode.lower() not in MAP_SERVER_MODES:
        raise MapError(
            f'map YAML {path} has mode {mode!r}; expected one of {", ".join(MAP_SERVER_MODES)}')
    image_path = pathlib.Path(image)
    if not image_path.is_absolute():
        image_path = path.parent / image_path
    gray, maxval = _read_image(image_path, max_cells, named_by=path)
    occupied, unknown = _classify_pixels(
        gray, maxval, negate, mode.lower(), occupied_thresh, free_thresh)
    if unknown_is_occupied:
        occupied |= unknown
    # Image rows run top-down; grid rows run up from the origin.
    grid = GridMap(occupied[::-1], resolution, origin, unknown=unknown[::-1].copy(),
                   max_cells=max_cells)
    _LOG.debug('loaded map %s: %d x %d cells at %.3f m', path, grid.width, grid.height,
               grid.resolution)
    return grid


def save_map_server(grid, yaml_path):
    """Write a grid as a map_server map: a trinary PGM beside a YAML.

    Parameters
    ----------
    grid : GridMap
        The map to save.
    yaml_path : str or os.PathLike
        The YAML to write; the image goes beside it with the same stem and
        the suffix ``.pgm``, named in the YAML by its bare file name.

    Returns
    -------
    pathlib.Path
        The PGM file written.

    Raises
    ------
    MapError
        If ``grid`` is not a GridMap, the YAML path ends in ``.pgm``, or a
        file cannot be written.

    Notes
    -----
    The PGM is binary (P5, maxval 255), top row first: occupied cells 0,
    free cells 254, unknown cells that are not occupied 205. The YAML says
    ``mode: trinary``, ``negate: 0``, ``occupied_thresh: 0.65`` and
    ``free_thresh: 0.196`` (so that 205 reads back as unknown; see
    :data:`SAVE_FREE_THRESH`). Resolution and origin are written with full
    float precision, so :func:`load_map_server_yaml` gives back the same
    ``occupied``, ``resolution`` and ``origin``.

    Examples
    --------
    >>> import numpy as np, tempfile, os
    >>> g = GridMap(np.eye(3, dtype=bool), 0.05, (-1.0, 2.0, 0.0))
    >>> with tempfile.TemporaryDirectory() as d:
    ...     _ = save_map_server(g, os.path.join(d, 'm.yaml'))
    ...     back = load_map_server_yaml(os.path.join(d, 'm.yaml'))
    >>> bool((back.occupied == g.occupied).all()), back.resolution, back.origin
    (True, 0.05, (-1.0, 2.0, 0.0))
    """
    if not isinstance(grid, GridMap):
        raise MapError(f'save_map_server needs a GridMap, got {type(grid).__name__}')
    yaml_path = _as_path(yaml_path, 'map YAML')
    image_path = yaml_path.with_suffix('.pgm')
    if image_path == yaml_path:
        raise MapError(f'map YAML path {yaml_path} must not end in .pgm, the image suffix')
    pixels = np.full(grid.shape, PGM_FREE, dtype=np.uint8)
    if grid.unknown is not None:
        pixels[grid.unknown] = PGM_UNKNOWN
    pixels[grid.occupied] = PGM_OCCUPIED
    header = f'P5\n# fusion_planner trinary map\n{grid.width} {grid.height}\n{PGM_MAXVAL}\n'
    doc = {
        'image': image_path.name,
        'mode': 'trinary',
        'resolution': grid.resolution,
        'origin': list(grid.origin),
        'negate': 0,
        'occupied_thresh': SAVE_OCCUPIED_THRESH,
        'free_thresh': SAVE_FREE_THRESH,
    }
    try:
        with open(image_path, 'wb') as out:
            out.write(header.encode('ascii'))
            out.write(np.ascontiguousarray(pixels[::-1]).tobytes())
        with open(yaml_path, 'w', encoding='utf-8') as out:
            yaml.safe_dump(doc, out, default_flow_style=None, sort_keys=False)
    except OSError as err:
        raise MapError(
            f'cannot write map {yaml_path}: {err.strerror or err}') from None
    return image_path


def _read_yaml(path):
    """Read a map YAML and return its top-level mapping."""
    raw = _read_bytes(path, 'map YAML', MAX_YAML_BYTES)
    try:
        text = raw.decode('utf-8')
    except UnicodeDecodeError:
        raise MapError(f'map YAML {path} is not UTF-8 text') from None
    try:
        doc = yaml.safe_load(text)
    except yaml.YAMLError as err:
        where = getattr(err, 'problem_mark', None)
        at = f' at line {where.line + 1}' if where is not None else ''
        problem = getattr(err, 'problem', None) or 'invalid syntax'
        raise MapError(f'map YAML {path} does not parse{at}: {problem}') from None
    if not isinstance(doc, dict):
        raise MapError(
            f'map YAML {path} must be a mapping with keys image, resolution and origin, '
            f'got {type(doc).__name__}')
    return doc


def _yaml_negate(value, path):
    """``negate`` as a bool (0/1 or true/false)."""
    if isinstance(value, bool):
        return value
    if isinstance(value, numbers.Integral) and value in (0, 1):
        return bool(value)
    raise MapError(f'map YAML {path} has negate {value!r}; expected 0 or 1')


def _yaml_probability(doc, key, default, path):
    """Read a threshold in [0, 1] from the YAML, or return its default."""
    value = doc.get(key, default)
    if isinstance(value, bool) or not isinstance(value, numbers.Real) \
            or not math.isfinite(value) or not 0.0 <= value <= 1.0:
        raise MapError(f'map YAML {path} has {key} {value!r}; expected a number in [0, 1]')
    return float(value)


def _classify_pixels(gray, maxval, negate, mode, occupied_thresh, free_thresh):
    """Band pixels into occupied and unknown masks, top row first."""
    if mode == 'raw':
        value = np.rint(gray * (PGM_MAXVAL / maxval))
        out_of_range = value > OCC_OCCUPIED
        prob = value / OCC_OCCUPIED
    else:
        # (maxval - v) / maxval rather than 1 - v / maxval: exact for 8-bit.
        prob = gray / maxval if negate else (maxval - gray) / maxval
        out_of_range = np.zeros(gray.shape, dtype=bool)
    occupied = (prob > occupied_thresh) & ~out_of_range
    free = (prob < free_thresh) & ~out_of_range
    unknown = ~(occupied | free)
    return occupied, unknown


# -- images ----------------------------------------------------------------

def _read_image(path, max_cells, named_by):
    """Read gray levels ``(H, W)`` float64 (top row first) and the maximum value."""
    limit = max_cells * _IMAGE_BYTES_PER_CELL + _HEADER_SLACK_BYTES
    raw = _read_bytes(path, 'map image', limit, named_by=named_by)
    if raw[:2] in (b'P2', b'P5'):
        return _parse_pgm(raw, path, max_cells)
    return _decode_with_pillow(raw, path, max_cells)


def _parse_pgm(raw, path, max_cells):
    """Decode a P2 (ASCII) or P5 (binary) PGM, 8- or 16-bit."""
    binary = raw[:2] == b'P5'
    pos = 2
    fields = []
    for name in ('width', 'height', 'maximum value'):
        value, pos = _pgm_header_number(raw, pos, name, path)
        fields.append(value)
    width, height, maxval = fields
    if width == 0 or height == 0:
        raise MapError(f'PGM image {path} has an empty size {width} x {height}')
    if not 0 < maxval <= _MAXVAL_16BIT:
        raise MapError(f'PGM image {path} has maximum value {maxval}; expected 1..65535')
    _check_cell_limit(width, height, max_cells, f'PGM image {path}')
    n_pixels = width * height
    if binary:
        if pos >= len(raw) or not raw[pos:pos + 1].isspace():
            raise MapError(f'PGM image {path} is truncated or has a bad header: '
                           f'no whitespace before the pixel data')
        start = pos + 1
        dtype = np.dtype(np.uint8) if maxval <= PGM_MAXVAL else np.dtype('>u2')
        need = n_pixels * dtype.itemsize
        have = len(raw) - start
        if have < need:
            raise MapError(f'PGM image {path} is truncated: {width} x {height} pixels need '
                           f'{need} bytes of data, found {have}')
        pixels = np.frombuffer(raw, dtype=dtype, count=n_pixels, offset=start)
    else:
        tokens = _PGM_COMMENT.sub(b'', raw[pos:]).split()
        if len(tokens) < n_pixels:
            raise MapError(f'PGM image {path} is truncated: {width} x {height} pixels '
                           f'but only {len(tokens)} values')
        try:
            pixels = np.array(tokens[:n_pixels]).astype(np.int64)
        except ValueError:
            raise MapError(f'PGM image {path} has a pixel value that is not a number') from None
    pixels = pixels.reshape(height, width)
    if pixels.min() < 0 or pixels.max() > maxval:
        raise MapError(f'PGM image {path} has pixel values outside 0..{maxval}')
    return pixels.astype(np.float64), maxval


def _pgm_header_number(raw, pos, name, path):
    """Read the next decimal number of a PGM header after whitespace and comments."""
    end = len(raw)
    while pos < end:  # advances at least one byte per pass
        char = raw[pos:pos + 1]
        if char.isspace():
            pos += 1
        elif char == b'#':
            newline = raw.find(b'\n', pos)
            pos = end if newline < 0 else newline + 1
        else:
            break
    match = _DIGITS.match(raw, pos)
    if match is None:
        raise MapError(f'PGM image {path} has a bad header: no {name} at byte {pos}')
    return int(match.group()), match.end()


def _decode_with_pillow(raw, path, max_cells):
    """Decode a non-PGM image with Pillow (channels averaged, alpha dropped)."""
    try:
        from PIL import Image
    except ImportError:
        raise MapError(f'map image {path} is not a PGM; reading PNG and other image formats '
                       f'needs pillow (pip install pillow)') from None
    try:
        img = Image.open(io.BytesIO(raw))
        width, height = img.size
    except Exception as err:  # Pillow raises many types for bad data
        raise MapError(f'map image {path} is not a readable image: {_one_line(err)}') from None
    with img:
        _check_cell_limit(width, height, max_cells, f'map image {path}')
        try:
            gray, maxval = _pillow_gray(img, path)
        except MapError:
            raise
        except Exception as err:  # truncated or corrupt data found while decoding
            raise MapError(f'map image {path} cannot be decoded: {_one_line(err)}') from None
    if gray.min() < 0 or gray.max() > maxval:
        raise MapError(f'map image {path} has pixel values outside 0..{maxval}')
    return gray, maxval


def _pillow_gray(img, path):
    """Return the gray levels and maximum value of a Pillow image."""
    mode = img.mode
    if mode == 'I' or mode.startswith('I;16'):
        maxval = _MAXVAL_16BIT
    elif mode == 'F':
        raise MapError(f'map image {path} has floating-point pixels, which are not supported')
    else:
        maxval = PGM_MAXVAL
        if mode in ('P', 'PA'):
            img = img.convert('RGBA')  # a palette may carry transparency
        elif mode not in ('L', 'LA', 'La', 'RGB', 'RGBA', 'RGBa', 'RGBX'):
            img = img.convert('RGB')  # 1-bit, CMYK, YCbCr ...
    pixels = np.asarray(img)
    if pixels.ndim == 3:
        keep = [i for i, band in enumerate(img.getbands()) if band not in ('A', 'a', 'X')]
        gray = pixels[..., keep].astype(np.float64).mean(axis=-1)
    else:
        gray = pixels.astype(np.float64)
    return gray, maxval


# ---------------------------------------------------------------------------
# MovingAI benchmark
# ---------------------------------------------------------------------------

def load_movingai(path, max_cells=DEFAULT_MAX_CELLS):
    r"""Load a MovingAI ``.map`` grid.

    Parameters
    ----------
    path : str or os.PathLike
        The ``.map`` file: header ``type octile``, ``height H``,
        ``width W``, ``map``, then H rows of W characters (``\r`` stripped).
    max_cells : int, optional
        Refuse maps with more cells than this (checked from the header).

    Returns
    -------
    GridMap
        Resolution 1 m, origin ``(0, 0, 0)``; ``.``, ``G`` and ``S`` are free,
        every other character an obstacle. The file's first row is the grid's
        top row ``H - 1`` (see :func:`movingai_cell`).

    Raises
    ------
    MapError
        If the file is missing or unreadable, the header is bad, the number
        of rows differs from H, a row's length differs from W, or the map is
        larger than ``max_cells``.

    Examples
    --------
    >>> import tempfile, os
    >>> with tempfile.TemporaryDirectory() as d:
    ...     name = os.path.join(d, 'tiny.map')
    ...     with open(name, 'w') as f:
    ...         _ = f.write('type octile\nheight 2\nwidth 3\nmap\n@..\n...\n')
    ...     grid = load_movingai(name)
    >>> grid.occupied.astype(int).tolist()
    [[0, 0, 0], [1, 0, 0]]
    """
    path = _as_path(path, 'MovingAI map')
    limit = max_cells * _MOVINGAI_BYTES_PER_CELL + _HEADER_SLACK_BYTES
    lines = _read_bytes(path, 'MovingAI map', limit).split(b'\n')
    header = {}
    map_line = None
    for index in range(min(len(lines), _MOVINGAI_MAX_HEADER_LINES)):
        text = _ascii_line(lines[index], path, index)
        if text == 'map':
            map_line = index
            break
        parts = text.split()
        if len(parts) != 2:
            raise MapError(f'MovingAI map {path} line {index + 1}: expected "key value" in '
                           f'the header, got {text!r}')
        header[parts[0].lower()] = parts[1]
    if map_line is None:
        raise MapError(f'MovingAI map {path} has a bad header: no "map" line after '
                       f'type, height and width')
    if header.get('type') != 'octile':
        raise MapError(f'MovingAI map {path} has a bad header: type is '
                       f'{header.get("type")!r}, expected "octile"')
    height = _header_size(header, 'height', path)
    width = _header_size(header, 'width', path)
    _check_cell_limit(width, height, max_cells, f'MovingAI map {path}')
    rows = [line.rstrip(b'\r') for line in lines[map_line + 1:]]
    while rows and not rows[-1].strip():  # trailing blank lines; shrinks each pass
        rows.pop()
    if len(rows) != height:
        raise MapError(f'MovingAI map {path} declares height {height} but has '
                       f'{len(rows)} grid rows')
    for index, row in enumerate(rows):
        if len(row) != width:
            raise MapError(f'MovingAI map {path} line {map_line + 2 + index} has '
                           f'{len(row)} characters, expected width {width}')
    cells = np.frombuffer(b''.join(rows), dtype=np.uint8).reshape(height, width)
    passable = np.isin(cells, np.frombuffer(MOVINGAI_PASSABLE, dtype=np.uint8))
    # File row 0 is the top row: grid row = H - 1 - file row.
    return GridMap(~passable[::-1], MOVINGAI_RESOLUTION, (0.0, 0.0, 0.0),
                   max_cells=max_cells)


def movingai_cell(col, file_row, height):
    """Grid cell ``(row, col)`` of a MovingAI / ``.scen`` cell ``(x, y)``.

    Parameters
    ----------
    col : int
        MovingAI x, the column, >= 0.
    file_row : int
        MovingAI y, the row counted from the file's top line, 0..height-1.
    height : int
        Number of rows H of the map, > 0.

    Returns
    -------
    tuple of int
        ``(H - 1 - file_row, col)``, the cell of :func:`load_movingai`'s grid.

    Raises
    ------
    MapError
        If an argument is not an integer or the cell lies outside the rows.

    Examples
    --------
    >>> movingai_cell(4, 0, 10)
    (9, 4)
    """
    col = _int_arg(col, 'MovingAI column')
    file_row = _int_arg(file_row, 'MovingAI row')
    height = _positive_int(height, 'MovingAI map height')
    if col < 0 or not 0 <= file_row < height:
        raise MapError(f'MovingAI cell (x={col}, y={file_row}) lies outside a map of '
                       f'height {height}')
    return height - 1 - file_row, col


def read_scenarios(path):
    """Read a MovingAI ``.map.scen`` scenario file.

    Parameters
    ----------
    path : str or os.PathLike
        First line ``version 1`` (any version number is accepted), then one
        line per scenario with nine tab-separated fields: bucket, map, width,
        height, start x, start y, goal x, goal y, optimal length.

    Returns
    -------
    list of ScenarioRow
        In file order, in file coordinates (y counted from the top line).

    Raises
    ------
    MapError
        If the file is missing or unreadable, lacks the version line, or a
        line has the wrong number of fields, a field that does not parse, or
        a start or goal outside its map.
    """
    path = _as_path(path, 'MovingAI scenario file')
    raw = _read_bytes(path, 'MovingAI scenario file', MAX_SCENARIO_BYTES)
    try:
        lines = raw.decode('utf-8').split('\n')
    except UnicodeDecodeError:
        raise MapError(f'MovingAI scenario file {path} is not UTF-8 text') from None
    first = lines[0].strip().split()
    if len(first) != 2 or first[0] != 'version' or not _is_number_text(first[1]):
        raise MapError(f'MovingAI scenario file {path} does not start with a "version" line')
    rows = []
    for index in range(1, len(lines)):
        line = lines[index].rstrip('\r')
        if line.strip():
            rows.append(_scenario_row(line, path, index + 1))
    return rows


def _scenario_row(line, path, line_number):
    """Parse one scenario line."""
    fields = [field.strip() for field in line.split('\t')]
    if len(fields) != _SCEN_FIELDS:
        fields = line.split()
    if len(fields) != _SCEN_FIELDS:
        raise MapError(f'MovingAI scenario file {path} line {line_number} has '
                       f'{len(fields)} fields, expected {_SCEN_FIELDS}')
    try:
        bucket, width, height, start_col, start_row, goal_col, goal_row = (
            int(fields[i]) for i in (0, 2, 3, 4, 5, 6, 7))
        optimal_length = float(fields[8])
    except ValueError:
        raise MapError(f'MovingAI scenario file {path} line {line_number} has a field '
                       f'that is not a number') from None
    inside = (width > 0 and height > 0 and 0 <= start_col < width and 0 <= goal_col < width
              and 0 <= start_row < height and 0 <= goal_row < height)
    if not inside or not math.isfinite(optimal_length) or optimal_length < 0:
        raise MapError(f'MovingAI scenario file {path} line {line_number} has a start or '
                       f'goal outside its {width} x {height} map or a bad length')
    return ScenarioRow(bucket, fields[1], width, height, start_col, start_row,
                       goal_col, goal_row, optimal_length)


def _header_size(header, key, path):
    """Read a positive integer from a MovingAI header."""
    text = header.get(key)
    if text is None or not text.isdigit() or int(text) == 0:
        raise MapError(f'MovingAI map {path} has a bad header: {key} is {text!r}, '
                       f'expected a positive integer')
    return int(text)


def _ascii_line(line, path, index):
    """Decode a header line as stripped ASCII text."""
    try:
        return line.decode('ascii').strip()
    except UnicodeDecodeError:
        raise MapError(f'MovingAI map {path} has a bad header: line {index + 1} is not '
                       f'ASCII text') from None


def _is_number_text(text):
    """Tell whether ``text`` parses as a finite float."""
    try:
        return math.isfinite(float(text))
    except ValueError:
        return False


# ---------------------------------------------------------------------------
# dispatch
# ---------------------------------------------------------------------------

def load_map(path, unknown_is_occupied=False, max_cells=DEFAULT_MAX_CELLS):
    """Load a map file, choosing the reader by its extension.

    Parameters
    ----------
    path : str or os.PathLike
        ``.yaml`` / ``.yml``: a map_server map (:func:`load_map_server_yaml`);
        ``.map``: a MovingAI map (:func:`load_movingai`).
    unknown_is_occupied : bool, optional
        Policy for unknown cells of map_server maps (MovingAI has none).
    max_cells : int, optional
        Refuse maps with more cells than this.

    Returns
    -------
    GridMap

    Raises
    ------
    MapError
        If the extension is not supported, or the reader fails.
    """
    path = _as_path(path, 'map file')
    suffix = path.suffix.lower()
    if suffix in ('.yaml', '.yml'):
        return load_map_server_yaml(path, unknown_is_occupied=unknown_is_occupied,
                                    max_cells=max_cells)
    if suffix == '.map':
        return load_movingai(path, max_cells=max_cells)
    raise MapError(f'cannot load map {path}: supported map files are map_server '
                   f'.yaml/.yml and MovingAI .map')


# ---------------------------------------------------------------------------
# shared checks
# ---------------------------------------------------------------------------

def _as_path(path, what):
    """Convert ``path`` to a pathlib.Path, or raise MapError."""
    try:
        return pathlib.Path(path)
    except TypeError:
        raise MapError(
            f'{what} path must be a string or path, got {type(path).__name__}') from None


def _read_bytes(path, what, max_bytes, named_by=None):
    """Read a whole file, raising MapError for every way reading fails."""
    path = pathlib.Path(path)
    by = f' (named by {named_by})' if named_by is not None else ''
    try:
        info = os.stat(path)
    except FileNotFoundError:
        raise MapError(f'{what} {path}{by} does not exist') from None
    except OSError as err:
        raise MapError(f'cannot read {what} {path}{by}: {err.strerror or err}') from None
    if stat.S_ISDIR(info.st_mode):
        raise MapError(f'{what} {path}{by} is a directory, not a file')
    if info.st_size > max_bytes:
        raise MapError(f'{what} {path}{by} has {info.st_size} bytes, which exceeds the limit '
                       f'of {max_bytes} bytes for the configured map size')
    try:
        with open(path, 'rb') as stream:
            return stream.read(max_bytes + 1)
    except OSError as err:
        raise MapError(f'cannot read {what} {path}{by}: {err.strerror or err}') from None


def _check_cell_limit(width, height, max_cells, what):
    """Raise MapError when ``width * height`` exceeds ``max_cells``."""
    if width * height > max_cells:
        raise MapError(f'{what} of {width} x {height} cells exceeds the limit of '
                       f'{max_cells} cells')


def _check_resolution(value, what):
    """Validate a finite resolution > 0 [m]; return it as float."""
    if isinstance(value, bool) or not isinstance(value, numbers.Real) \
            or not math.isfinite(value) or value <= 0:
        raise MapError(f'{what} resolution must be a positive number of metres, got {value!r}')
    return float(value)


def _check_origin(value, what):
    """Validate a finite ``(x, y, yaw)``; return it as a tuple of float."""
    ok = isinstance(value, (list, tuple, np.ndarray)) and len(value) == 3 and all(
        not isinstance(v, bool) and isinstance(v, numbers.Real) and math.isfinite(v)
        for v in value)
    if not ok:
        shown = value.tolist() if isinstance(value, np.ndarray) else value
        raise MapError(f'{what} origin must be three finite numbers [x, y, yaw], got {shown!r}')
    return tuple(float(v) for v in value)


def _positive_int(value, what):
    """Validate a positive integer (bool and float refused)."""
    number = _int_arg(value, what)
    if number <= 0:
        raise MapError(f'{what} must be a positive integer, got {value!r}')
    return number


def _int_arg(value, what):
    """Validate an integer (bool and float refused)."""
    if isinstance(value, bool):
        raise MapError(f'{what} must be an integer, got {value!r}')
    try:
        return operator.index(value)
    except TypeError:
        raise MapError(f'{what} must be an integer, got {value!r}') from None


def _one_line(err):
    """Fold an exception's message onto one line."""
    return ' '.join(str(err).split()) or type(err).__name__
