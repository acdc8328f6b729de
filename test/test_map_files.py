"""Tests of fusion_planner.core.map_files: every way a GridMap is built from outside data."""

import array
import math
import sys

import numpy as np
import pytest
import yaml

from fusion_planner.core import map_files
from fusion_planner.core.errors import MapError
from fusion_planner.core.grid import GridMap
from fusion_planner.core.map_files import (
    ScenarioRow, from_occupancy_values, load_map, load_map_server_yaml, load_movingai,
    movingai_cell, read_scenarios, save_map_server)

#: Shape and passable ('.') cell counts of the benchmark maps, from SOURCES.md.
BENCHMARK_MAPS = {
    'arena2': ((209, 281), 24311, 910),
    'Berlin_0_512': ((512, 512), 196667, 1870),
    'maze512-1-0': ((512, 512), 131071, 12120),
    'random512-10-0': ((512, 512), 235900, 1780),
    '8room_000': ((512, 512), 206642, 2140),
}


# -- helpers -----------------------------------------------------------------

def pgm_p5(pixels, maxval=255, comment=True):
    """Bytes of a binary PGM whose rows are ``pixels`` top row first."""
    pixels = np.asarray(pixels)
    height, width = pixels.shape
    note = b'# test image\n' if comment else b''
    header = b'P5\n' + note + f'{width} {height}\n{maxval}\n'.encode()
    dtype = np.uint8 if maxval <= 255 else np.dtype('>u2')
    return header + pixels.astype(dtype).tobytes()


def pgm_p2(pixels, maxval=255):
    """Bytes of an ASCII PGM, with a comment among the pixel values."""
    pixels = np.asarray(pixels)
    height, width = pixels.shape
    lines = [f'P2\n# ascii\n{width} {height}\n{maxval}']
    for row in pixels:
        lines.append(' '.join(str(int(v)) for v in row) + ' # row')
    return ('\n'.join(lines) + '\n').encode()


def write_yaml(folder, image, name='map.yaml', **fields):
    """A map_server YAML naming ``image``; extra keys override the defaults."""
    doc = {'image': image, 'resolution': 0.5, 'origin': [1.0, -2.0, 0.0], 'negate': 0,
           'occupied_thresh': 0.65, 'free_thresh': 0.25}
    doc.update(fields)
    doc = {k: v for k, v in doc.items() if v is not None}
    path = folder / name
    path.write_text(yaml.safe_dump(doc))
    return path


def image_map(folder, pixels, **fields):
    """Write ``pixels`` as a P5 PGM plus a YAML; return the YAML path."""
    (folder / 'map.pgm').write_bytes(pgm_p5(pixels))
    return write_yaml(folder, 'map.pgm', **fields)


def random_grid(seed, shape=(13, 17)):
    """A GridMap with random obstacles and random unknown cells."""
    rng = np.random.default_rng(seed)
    occupied = rng.random(shape) < 0.3
    unknown = rng.random(shape) < 0.2
    origin = tuple(rng.uniform(-50, 50, 2)) + (float(rng.uniform(-math.pi, math.pi)),)
    resolution = float(rng.choice([0.05, 0.1, 1 / 3, 0.025]))
    return GridMap(occupied, resolution, origin, unknown=unknown)


TINY_MAP_ROWS = ['@..T', '.G.S', 'WO..']   # file rows, top line first


def write_tiny_map(folder, newline='\n', trailing=True, name='tiny.map'):
    """A 4 x 3 MovingAI map with every terrain kind."""
    lines = ['type octile', 'height 3', 'width 4', 'map'] + TINY_MAP_ROWS
    text = newline.join(lines) + (newline if trailing else '')
    path = folder / name
    path.write_bytes(text.encode())
    return path


# -- OccupancyGrid fields ------------------------------------------------------

def test_occupancy_values_row_zero_at_origin_no_flip():
    data = [0] * 12
    data[0] = 100          # first value: row 0, col 0, at the origin
    data[11] = 100         # last value: top-right cell
    grid = from_occupancy_values(4, 3, 0.25, (2.0, 3.0, 0.0), data)
    assert grid.shape == (3, 4)
    assert np.argwhere(grid.occupied).tolist() == [[0, 0], [2, 3]]
    assert grid.cell_of(np.array([2.01, 3.01])).tolist() == [0, 0]
    assert grid.cell_of(np.array([2.99, 3.74])).tolist() == [2, 3]


@pytest.mark.parametrize('threshold', [1, 50, 65, 100])
def test_occupancy_threshold_is_inclusive(threshold):
    values = list(range(-1, 101))
    grid = from_occupancy_values(len(values), 1, 1.0, (0, 0, 0), values,
                                 occupied_threshold=threshold)
    expected = np.array([v >= threshold for v in values])
    assert np.array_equal(grid.occupied[0], expected)
    assert grid.unknown[0].tolist() == [v == -1 for v in values]


@pytest.mark.parametrize('unknown_is_occupied', [False, True])
def test_unknown_policy_and_mask(unknown_is_occupied):
    data = [-1, 0, 100, -1, 30, 70]
    grid = from_occupancy_values(3, 2, 1.0, (0, 0, 0), data,
                                 unknown_is_occupied=unknown_is_occupied)
    unknown = np.array(data).reshape(2, 3) == -1
    assert np.array_equal(grid.unknown, unknown)
    assert np.all(grid.occupied[unknown] == unknown_is_occupied)
    known = ~unknown
    assert np.array_equal(grid.occupied[known], (np.array(data).reshape(2, 3) >= 65)[known])


def test_occupancy_data_containers_agree():
    values = [-1, 0, 5, 64, 65, 100, 0, -1]
    as_int8 = np.array(values, dtype=np.int8)
    containers = [values, tuple(values), array.array('b', values), as_int8,
                  as_int8.astype(np.int64).reshape(2, 4), as_int8.astype(float),
                  bytes(as_int8.tobytes()), bytearray(as_int8.tobytes()),
                  memoryview(as_int8.tobytes())]
    grids = [from_occupancy_values(4, 2, 0.1, (0, 0, 0), c) for c in containers]
    for grid in grids[1:]:
        assert np.array_equal(grid.occupied, grids[0].occupied)
        assert np.array_equal(grid.unknown, grids[0].unknown)
    assert grids[0].occupied.sum() == 2 and grids[0].unknown.sum() == 2


def test_occupancy_length_mismatch_names_both_numbers():
    with pytest.raises(MapError, match=r'5 values.*3 x 2 = 6'):
        from_occupancy_values(3, 2, 1.0, (0, 0, 0), [0] * 5)


@pytest.mark.parametrize('bad', [-2, 101, 127, -128, 1000])
def test_occupancy_value_out_of_range(bad):
    with pytest.raises(MapError, match=f'{bad}.*outside'):
        from_occupancy_values(2, 1, 1.0, (0, 0, 0), [0, bad])


@pytest.mark.parametrize('data', [[0, 0.5], ['a', 'b'], [None, 0], [0, float('nan')],
                                  np.array([True, False])])
def test_occupancy_values_must_be_integers(data):
    with pytest.raises(MapError, match='integer'):
        from_occupancy_values(2, 1, 1.0, (0, 0, 0), data)


@pytest.mark.parametrize('width, height', [(0, 3), (3, -1), (2.0, 1), (True, 1), ('3', 1)])
def test_occupancy_bad_size(width, height):
    with pytest.raises(MapError, match='width|height'):
        from_occupancy_values(width, height, 1.0, (0, 0, 0), [0] * 3)


@pytest.mark.parametrize('resolution', [0, -0.1, float('nan'), float('inf'), '0.1', None])
def test_occupancy_bad_resolution(resolution):
    with pytest.raises(MapError, match='resolution'):
        from_occupancy_values(1, 1, resolution, (0, 0, 0), [0])


@pytest.mark.parametrize('origin', [(0, float('nan'), 0), (float('inf'), 0, 0), (0, 0), None,
                                    (0, 0, 0, 0)])
def test_occupancy_bad_origin(origin):
    with pytest.raises(MapError, match='origin'):
        from_occupancy_values(1, 1, 1.0, origin, [0])


@pytest.mark.parametrize('threshold', [0, 101, float('nan'), True])
def test_occupancy_bad_threshold(threshold):
    with pytest.raises(MapError, match='threshold'):
        from_occupancy_values(1, 1, 1.0, (0, 0, 0), [0], occupied_threshold=threshold)


def test_occupancy_size_limit_checked_before_data():
    # 10^12 cells with no data: the limit must be reported, not the length,
    # and nothing of that size may be allocated.
    with pytest.raises(MapError, match='exceeds the limit'):
        from_occupancy_values(10 ** 6, 10 ** 6, 1.0, (0, 0, 0), [])
    with pytest.raises(MapError, match='exceeds the limit'):
        from_occupancy_values(4, 4, 1.0, (0, 0, 0), [0] * 16, max_cells=15)


# -- map_server: round trips and flips ---------------------------------------

@pytest.mark.parametrize('seed', range(5))
def test_save_load_round_trip_is_exact(tmp_path, seed):
    grid = random_grid(seed)
    image = save_map_server(grid, tmp_path / 'saved.yaml')
    assert image == tmp_path / 'saved.pgm' and image.is_file()
    back = load_map_server_yaml(tmp_path / 'saved.yaml')
    assert np.array_equal(back.occupied, grid.occupied)
    assert back.resolution == grid.resolution
    assert back.origin == grid.origin
    # Unknown cells that were not obstacles survive as unknown.
    assert np.array_equal(back.unknown, grid.unknown & ~grid.occupied)
    pessimistic = load_map(tmp_path / 'saved.yaml', unknown_is_occupied=True)
    assert np.array_equal(pessimistic.occupied, grid.occupied | grid.unknown)


def test_round_trip_from_occupancy_values(tmp_path):
    rng = np.random.default_rng(7)
    values = rng.choice([-1, 0, 20, 64, 65, 90, 100], size=(9, 6))
    grid = from_occupancy_values(6, 9, 0.05, (-3.2, 4.4, 0.0), values.ravel().tolist())
    save_map_server(grid, tmp_path / 'm.yml')
    back = load_map(tmp_path / 'm.yml')
    assert np.array_equal(back.occupied, values >= 65)
    assert np.array_equal(back.unknown, values == -1)


def test_saved_files_follow_map_server_layout(tmp_path):
    occupied = np.zeros((2, 3), bool)
    occupied[1, 0] = True                       # top-left once flipped
    unknown = np.zeros((2, 3), bool)
    unknown[0, 2] = True                        # bottom-right
    save_map_server(GridMap(occupied, 0.1, (0, 0, 0), unknown=unknown), tmp_path / 'a.yaml')
    doc = yaml.safe_load((tmp_path / 'a.yaml').read_text())
    assert doc['image'] == 'a.pgm' and doc['mode'] == 'trinary' and doc['negate'] == 0
    assert doc['occupied_thresh'] == 0.65
    # 205 must fall in the unknown band, as map_server computes it.
    assert doc['free_thresh'] <= (255 - 205) / 255 <= doc['occupied_thresh']
    raw = (tmp_path / 'a.pgm').read_bytes()
    assert raw.startswith(b'P5')
    assert list(raw[-6:]) == [0, 254, 254, 254, 254, 205]


def test_save_refuses_bad_arguments(tmp_path):
    with pytest.raises(MapError, match='GridMap'):
        save_map_server(np.zeros((2, 2), bool), tmp_path / 'x.yaml')
    grid = GridMap(np.zeros((2, 2), bool), 1.0)
    with pytest.raises(MapError, match='pgm'):
        save_map_server(grid, tmp_path / 'x.pgm')
    with pytest.raises(MapError, match='cannot write'):
        save_map_server(grid, tmp_path / 'no_such_folder' / 'x.yaml')


def single_obstacle_top_left(height=5, width=7):
    """Image pixels (top row first): white, one black pixel at the top-left."""
    pixels = np.full((height, width), 254, np.uint8)
    pixels[0, 0] = 0
    return pixels


def assert_top_left_obstacle(grid, height=5, width=7):
    """The image's top-left pixel is grid cell (H-1, 0), found from its world point."""
    assert grid.shape == (height, width)
    assert np.argwhere(grid.occupied).tolist() == [[height - 1, 0]]
    x0, y0, _ = grid.origin
    point = np.array([x0 + 0.5 * grid.resolution, y0 + (height - 0.5) * grid.resolution])
    assert grid.cell_of(point).tolist() == [height - 1, 0]
    assert grid.clearance_at(point[None])[0] == 0.0


@pytest.mark.parametrize('encoding', ['p5', 'p2', 'p5_16bit', 'p2_16bit'])
def test_pgm_top_left_pixel_is_top_grid_row(tmp_path, encoding):
    pixels = single_obstacle_top_left()
    if encoding.endswith('16bit'):
        data = (pgm_p5 if encoding.startswith('p5') else pgm_p2)(
            pixels.astype(np.int64) * 257, maxval=65535)
    else:
        data = (pgm_p5 if encoding == 'p5' else pgm_p2)(pixels)
    (tmp_path / 'map.pgm').write_bytes(data)
    grid = load_map(write_yaml(tmp_path, 'map.pgm'))
    assert_top_left_obstacle(grid)
    assert grid.resolution == 0.5 and grid.origin == (1.0, -2.0, 0.0)


def test_image_path_absolute_and_relative(tmp_path):
    (tmp_path / 'img').mkdir()
    (tmp_path / 'img' / 'm.pgm').write_bytes(pgm_p5(single_obstacle_top_left()))
    assert_top_left_obstacle(load_map(write_yaml(tmp_path, 'img/m.pgm')))
    other = tmp_path / 'elsewhere'
    other.mkdir()
    assert_top_left_obstacle(load_map(write_yaml(other, str(tmp_path / 'img' / 'm.pgm'))))


def occupancy_of(value, negate=False):
    """map_server's occupancy probability of an 8-bit gray value."""
    return value / 255 if negate else (255 - value) / 255


@pytest.mark.parametrize('mode', ['trinary', 'scale', None])
@pytest.mark.parametrize('negate', [0, 1])
def test_trinary_and_scale_bands(tmp_path, mode, negate):
    values = np.arange(256).reshape(1, 256)
    path = image_map(tmp_path, values, mode=mode, negate=negate,
                     occupied_thresh=0.6, free_thresh=0.3)
    grid = load_map(path)
    p = np.array([occupancy_of(v, negate) for v in range(256)])
    assert np.array_equal(grid.occupied[0], p > 0.6)
    assert np.array_equal(grid.unknown[0], (p >= 0.3) & (p <= 0.6))
    assert grid.unknown.any() and grid.occupied.any() and (~grid.occupied).any()
    pessimistic = load_map(path, unknown_is_occupied=True)
    assert np.array_equal(pessimistic.occupied[0], p >= 0.3)


@pytest.mark.parametrize('maxval', [255, 65535])
def test_raw_mode_uses_pixel_as_occupancy(tmp_path, maxval):
    values = np.arange(256).reshape(1, 256)
    # A 16-bit image is scaled to 0..255 first, as map_server does.
    (tmp_path / 'map.pgm').write_bytes(pgm_p5(values * (maxval // 255), maxval=maxval))
    grid = load_map(write_yaml(tmp_path, 'map.pgm', mode='raw', negate=1))   # negate ignored
    v = np.arange(256)
    assert np.array_equal(grid.unknown[0], (v > 100) | ((v >= 25) & (v <= 65)))
    assert np.array_equal(grid.occupied[0], (v > 65) & (v <= 100))


def test_default_thresholds_and_mode(tmp_path):
    pixels = np.array([[0, 80, 205, 254]])   # p = 1, 0.686, 0.196, 0.004
    path = image_map(tmp_path, pixels, occupied_thresh=None, free_thresh=None, negate=None)
    grid = load_map(path)
    assert grid.occupied[0].tolist() == [True, True, False, False]
    assert grid.unknown[0].tolist() == [False, False, False, False]   # 205 -> 0.196 < 0.25


def test_png_through_pillow(tmp_path):
    image_module = pytest.importorskip('PIL.Image')
    pixels = single_obstacle_top_left()
    for mode, layers in [('L', pixels), ('RGB', np.dstack([pixels] * 3)),
                         ('RGBA', np.dstack([pixels] * 3 + [np.zeros_like(pixels)]))]:
        image_module.fromarray(layers, mode=mode).save(tmp_path / f'{mode}.png')
        grid = load_map(write_yaml(tmp_path, f'{mode}.png'))
        assert_top_left_obstacle(grid)
        assert not grid.unknown.any()       # a transparent alpha is not averaged in
    wide = (pixels.astype(np.uint16) * 257)
    image_module.fromarray(wide).save(tmp_path / 'wide.png')
    assert_top_left_obstacle(load_map(write_yaml(tmp_path, 'wide.png')))


def test_colour_channels_are_averaged(tmp_path):
    image_module = pytest.importorskip('PIL.Image')
    rgb = np.array([[[255, 0, 0], [255, 255, 0], [255, 255, 255], [0, 0, 0]]], np.uint8)
    image_module.fromarray(rgb, mode='RGB').save(tmp_path / 'c.png')
    grid = load_map(write_yaml(tmp_path, 'c.png'))
    p = (255 - rgb.mean(axis=-1)[0]) / 255          # 0.667, 0.333, 0, 1
    assert np.array_equal(grid.occupied[0], p > 0.65)
    assert np.array_equal(grid.unknown[0], (p >= 0.25) & (p <= 0.65))


def test_png_without_pillow_is_a_map_error(tmp_path, monkeypatch):
    (tmp_path / 'm.png').write_bytes(b'\x89PNG\r\n\x1a\n' + b'\0' * 32)
    monkeypatch.setitem(sys.modules, 'PIL', None)
    with pytest.raises(MapError, match='pillow'):
        load_map(write_yaml(tmp_path, 'm.png'))


# -- map_server: bad input -----------------------------------------------------

def test_missing_yaml(tmp_path):
    with pytest.raises(MapError, match='nothere.yaml.*does not exist'):
        load_map(tmp_path / 'nothere.yaml')


def test_yaml_is_directory(tmp_path):
    (tmp_path / 'd.yaml').mkdir()
    with pytest.raises(MapError, match='directory'):
        load_map(tmp_path / 'd.yaml')


def test_unreadable_file(tmp_path, monkeypatch):
    path = write_yaml(tmp_path, 'm.pgm')

    def refuse(*_args, **_kwargs):
        raise PermissionError(13, 'Permission denied')
    monkeypatch.setattr(map_files, 'open', refuse, raising=False)
    with pytest.raises(MapError, match='cannot read.*Permission denied'):
        load_map(path)


@pytest.mark.parametrize('text, word', [
    ('image: [unclosed\n', 'does not parse'),
    ('just a string\n', 'mapping'),
    ('', 'mapping'),
    ('resolution: 0.1\norigin: [0, 0, 0]\n', '"image"'),
    ('image: m.pgm\norigin: [0, 0, 0]\n', '"resolution"'),
    ('image: m.pgm\nresolution: 0.1\n', '"origin"'),
    ('image: 5\nresolution: 0.1\norigin: [0, 0, 0]\n', 'image'),
    ('image: m.pgm\nresolution: 0\norigin: [0, 0, 0]\n', 'resolution'),
    ('image: m.pgm\nresolution: -1\norigin: [0, 0, 0]\n', 'resolution'),
    ('image: m.pgm\nresolution: .nan\norigin: [0, 0, 0]\n', 'resolution'),
    ('image: m.pgm\nresolution: 0.1\norigin: [0, .inf, 0]\n', 'origin'),
    ('image: m.pgm\nresolution: 0.1\norigin: [0, 0]\n', 'origin'),
    ('image: m.pgm\nresolution: 0.1\norigin: [0, 0, 0]\nnegate: 2\n', 'negate'),
    ('image: m.pgm\nresolution: 0.1\norigin: [0, 0, 0]\nmode: fancy\n', 'mode'),
    ('image: m.pgm\nresolution: 0.1\norigin: [0, 0, 0]\nfree_thresh: 1.5\n', 'free_thresh'),
    ('image: m.pgm\nresolution: 0.1\norigin: [0, 0, 0]\nfree_thresh: 0.9\n', 'above'),
])
def test_bad_yaml(tmp_path, text, word):
    (tmp_path / 'm.pgm').write_bytes(pgm_p5(np.zeros((2, 2))))
    (tmp_path / 'bad.yaml').write_text(text)
    with pytest.raises(MapError, match=word) as info:
        load_map(tmp_path / 'bad.yaml')
    assert 'bad.yaml' in str(info.value)


def test_yaml_not_utf8(tmp_path):
    (tmp_path / 'bin.yaml').write_bytes(b'image: \xff\xfe\n')
    with pytest.raises(MapError, match='UTF-8'):
        load_map(tmp_path / 'bin.yaml')


def test_image_missing(tmp_path):
    with pytest.raises(MapError, match=r'gone\.pgm.*named by.*map\.yaml.*does not exist'):
        load_map(write_yaml(tmp_path, 'gone.pgm'))


@pytest.mark.parametrize('data, word', [
    (b'P5\n4 4\n255\n' + b'\0' * 10, 'truncated'),
    (b'P5\n4 4\n65535\n' + b'\0' * 31, 'truncated'),
    (b'P2\n3 2\n255\n1 2 3 4 5\n', 'truncated'),
    (b'P2\n2 1\n255\n1 x\n', 'not a number'),
    (b'P2\n2 1\n100\n1 200\n', 'outside'),
    (b'P5\n2 x\n255\n\0\0', 'header'),
    (b'P5\n2 2', 'header'),
    (b'P5\n0 2\n255\n', 'empty'),
    (b'P5\n2 1\n70000\n\0\0\0\0', 'maximum value'),
    (b'P5\n2 1\n255\n', 'truncated'),
    (b'this is not an image at all', 'not a readable image'),
    (b'', 'not a readable image'),
])
def test_bad_image(tmp_path, data, word):
    (tmp_path / 'img.pgm').write_bytes(data)
    with pytest.raises(MapError, match=word) as info:
        load_map(write_yaml(tmp_path, 'img.pgm'))
    assert 'img.pgm' in str(info.value)


def test_truncated_png(tmp_path):
    image_module = pytest.importorskip('PIL.Image')
    rng = np.random.default_rng(1)
    image_module.fromarray(rng.integers(0, 255, (64, 64), dtype=np.uint8)).save(tmp_path / 'f.png')
    data = (tmp_path / 'f.png').read_bytes()
    (tmp_path / 't.png').write_bytes(data[:len(data) // 2])
    with pytest.raises(MapError, match='t.png'):
        load_map(write_yaml(tmp_path, 't.png'))


def test_oversized_image(tmp_path):
    path = image_map(tmp_path, np.zeros((10, 10)))
    with pytest.raises(MapError, match='exceeds the limit'):
        load_map(path, max_cells=99)
    assert load_map(path, max_cells=100).shape == (10, 10)


def test_oversized_png(tmp_path):
    image_module = pytest.importorskip('PIL.Image')
    image_module.fromarray(np.zeros((10, 10), np.uint8)).save(tmp_path / 'big.png')
    with pytest.raises(MapError, match='exceeds the limit'):
        load_map(write_yaml(tmp_path, 'big.png'), max_cells=50)


@pytest.mark.parametrize('cut', range(0, 40, 3))
def test_truncated_files_only_raise_map_error(tmp_path, cut):
    """Any prefix of a valid map file either loads or raises MapError."""
    (tmp_path / 'm.pgm').write_bytes(pgm_p5(np.full((3, 5), 254))[:cut])
    (tmp_path / 'a.pgm').write_bytes(pgm_p2(np.full((3, 5), 254))[:cut])
    good_map = write_tiny_map(tmp_path).read_bytes()
    (tmp_path / 'cut.map').write_bytes(good_map[:cut])
    yaml_text = (write_yaml(tmp_path, 'm.pgm').read_bytes())
    (tmp_path / 'cut.yaml').write_bytes(yaml_text[:cut])
    for name in ['map.yaml', 'cut.map', 'cut.yaml']:
        try:
            load_map(tmp_path / name)
        except MapError:
            pass
    try:
        load_map(write_yaml(tmp_path, 'a.pgm', name='ascii.yaml'))
    except MapError:
        pass


# -- MovingAI ----------------------------------------------------------------

@pytest.mark.parametrize('newline, trailing', [('\n', True), ('\r\n', True), ('\r\n', False),
                                               ('\n', False)])
def test_movingai_tiny_map_and_cell_conversion(tmp_path, newline, trailing):
    grid = load_movingai(write_tiny_map(tmp_path, newline, trailing))
    height, width = len(TINY_MAP_ROWS), len(TINY_MAP_ROWS[0])
    assert grid.shape == (height, width)
    assert grid.resolution == 1.0 and grid.origin == (0.0, 0.0, 0.0)
    for file_row, line in enumerate(TINY_MAP_ROWS):
        for col, char in enumerate(line):
            cell = movingai_cell(col, file_row, height)
            assert grid.occupied[cell] == (char not in '.GS'), (col, file_row, char)
    # The first file row is the top of the map: it has the largest y.
    top_left = movingai_cell(0, 0, height)
    assert top_left == (height - 1, 0)
    assert grid.cell_of(np.array([0.5, height - 0.5])).tolist() == list(top_left)


def test_movingai_cell_round_trips_and_checks():
    for height in (1, 2, 9):
        rows = [movingai_cell(3, y, height)[0] for y in range(height)]
        assert sorted(rows) == list(range(height))
        assert all(height - 1 - r == y for y, r in enumerate(rows))
    for args in [(0, 3, 3), (0, -1, 3), (-1, 0, 3), (0, 0, 0), (0.5, 0, 3), (0, True, 3)]:
        with pytest.raises(MapError, match='MovingAI'):
            movingai_cell(*args)


@pytest.mark.parametrize('text, word', [
    ('type octile\nheight 2\nwidth 2\n..\n..\n', 'header'),          # no "map" line
    ('type grid\nheight 2\nwidth 2\nmap\n..\n..\n', 'octile'),
    ('type octile\nheight two\nwidth 2\nmap\n..\n..\n', 'height'),
    ('type octile\nheight 2\nwidth 0\nmap\n..\n..\n', 'width'),
    ('type octile\nheight 2\nmap\n..\n..\n', 'width'),
    ('type octile height 2\nwidth 2\nmap\n..\n..\n', 'key value'),
    ('type octile\nheight 3\nwidth 2\nmap\n..\n..\n', 'height 3 but has 2'),
    ('type octile\nheight 1\nwidth 2\nmap\n..\n..\n', 'height 1 but has 2'),
    ('type octile\nheight 2\nwidth 2\nmap\n..\n...\n', 'line 6 has 3 characters'),
    ('type octile\nheight 2\nwidth 2\nmap\n..\n\n..\n', 'height 2 but has 3'),
    ('', 'header'),
])
def test_bad_movingai(tmp_path, text, word):
    (tmp_path / 'bad.map').write_text(text)
    with pytest.raises(MapError, match=word) as info:
        load_map(tmp_path / 'bad.map')
    assert 'bad.map' in str(info.value)


def test_movingai_non_ascii_header_and_limits(tmp_path):
    (tmp_path / 'u.map').write_bytes(b'type \xff\nheight 1\nwidth 1\nmap\n.\n')
    with pytest.raises(MapError, match='ASCII'):
        load_movingai(tmp_path / 'u.map')
    path = write_tiny_map(tmp_path)
    with pytest.raises(MapError, match='exceeds the limit'):
        load_movingai(path, max_cells=11)
    assert load_movingai(path, max_cells=12).shape == (3, 4)
    with pytest.raises(MapError, match='does not exist'):
        load_movingai(tmp_path / 'absent.map')
    (tmp_path / 'dir.map').mkdir()
    with pytest.raises(MapError, match='directory'):
        load_movingai(tmp_path / 'dir.map')


def test_load_map_unknown_extension(tmp_path):
    (tmp_path / 'm.pgm').write_bytes(pgm_p5(np.zeros((2, 2))))
    with pytest.raises(MapError, match=r'\.yaml.*\.map'):
        load_map(tmp_path / 'm.pgm')
    with pytest.raises(MapError, match='path'):
        load_map(None)


SCEN_TEXT = ('version 1\n'
             '0\ttiny.map\t4\t3\t1\t0\t2\t2\t2.41421356\n'
             '1\ttiny.map\t4\t3\t2\t1\t3\t2\t4.00000000\n')


def test_read_scenarios_tiny(tmp_path):
    (tmp_path / 'tiny.map.scen').write_text(SCEN_TEXT)
    rows = read_scenarios(tmp_path / 'tiny.map.scen')
    assert rows[0] == ScenarioRow(0, 'tiny.map', 4, 3, 1, 0, 2, 2, 2.41421356)
    assert len(rows) == 2
    grid = load_movingai(write_tiny_map(tmp_path))
    for row in rows:
        assert not grid.occupied[movingai_cell(row.start_col, row.start_row, row.height)]
        assert not grid.occupied[movingai_cell(row.goal_col, row.goal_row, row.height)]


@pytest.mark.parametrize('text, word', [
    ('0\ttiny.map\t4\t3\t1\t0\t2\t2\t2.4\n', 'version'),
    ('version 1\n0\ttiny.map\t4\t3\t1\t0\t2\t2\n', '8 fields'),
    ('version 1\n0\ttiny.map\t4\t3\tx\t0\t2\t2\t2.4\n', 'not a number'),
    ('version 1\n0\ttiny.map\t4\t3\t1\t3\t2\t2\t2.4\n', 'outside'),
    ('version 1\n0\ttiny.map\t4\t3\t1\t0\t2\t2\tnan\n', 'length'),
])
def test_bad_scenarios(tmp_path, text, word):
    (tmp_path / 'bad.scen').write_text(text)
    with pytest.raises(MapError, match=word):
        read_scenarios(tmp_path / 'bad.scen')
    with pytest.raises(MapError, match='does not exist'):
        read_scenarios(tmp_path / 'absent.scen')


@pytest.mark.parametrize('name', sorted(BENCHMARK_MAPS))
def test_benchmark_maps(benchmark_dir, name):
    shape, passable, n_rows = BENCHMARK_MAPS[name]
    grid = load_map(benchmark_dir / f'{name}.map')
    assert grid.shape == shape
    assert int((~grid.occupied).sum()) == passable
    rows = read_scenarios(benchmark_dir / f'{name}.map.scen')
    assert len(rows) == n_rows
    assert {row.map_name for row in rows} == {f'{name}.map'}
    assert all((row.height, row.width) == shape for row in rows)
    assert all(row.bucket == math.floor(row.optimal_length / 4) for row in rows)
    starts = np.array([movingai_cell(r.start_col, r.start_row, r.height) for r in rows])
    goals = np.array([movingai_cell(r.goal_col, r.goal_row, r.height) for r in rows])
    assert not grid.occupied[starts[:, 0], starts[:, 1]].any()
    assert not grid.occupied[goals[:, 0], goals[:, 1]].any()


def test_benchmark_map_saved_and_reloaded(benchmark_dir, tmp_path):
    grid = load_map(benchmark_dir / 'arena2.map')
    save_map_server(grid, tmp_path / 'arena2.yaml')
    back = load_map(tmp_path / 'arena2.yaml')
    assert np.array_equal(back.occupied, grid.occupied)
    assert (back.resolution, back.origin) == (grid.resolution, grid.origin)
