"""Coverage-map PNG: the encoder against a decoder written here, and the rendered
picture against pixel positions worked out by hand from the world geometry."""

import struct
import zlib

import numpy as np
import pytest
from shapely.geometry import GeometryCollection, LineString, MultiPolygon, Polygon, box

from autoscoop_blender.core.model.sensors import PAPER_CAMERA
from autoscoop_blender.core.result import MastRecord, Result, SensorRecord
from autoscoop_blender.io import figure as rp

# --------------------------------------------------------------------- a tiny PNG decoder


def decode_png(data: bytes) -> np.ndarray:
    """(H, W, 3) uint8 pixels of an 8-bit RGB, non-interlaced, filter-0-only PNG; checks
    the signature, every chunk's CRC and every row's filter byte on the way."""
    assert data[:8] == b"\x89PNG\r\n\x1a\n"
    pos, chunks = 8, []
    while pos < len(data):
        (length,) = struct.unpack(">I", data[pos : pos + 4])
        kind = data[pos + 4 : pos + 8]
        body = data[pos + 8 : pos + 8 + length]
        (crc,) = struct.unpack(">I", data[pos + 8 + length : pos + 12 + length])
        assert crc == zlib.crc32(kind + body) & 0xFFFFFFFF, kind
        chunks.append((kind, body))
        pos += 12 + length
    assert pos == len(data)
    assert chunks[0][0] == b"IHDR" and chunks[-1] == (b"IEND", b"")
    width, height, depth, colour, compression, filtering, interlace = struct.unpack(
        ">IIBBBBB", chunks[0][1]
    )
    assert (depth, colour, compression, filtering, interlace) == (8, 2, 0, 0, 0)
    raw = zlib.decompress(b"".join(body for kind, body in chunks if kind == b"IDAT"))
    rows = np.frombuffer(raw, np.uint8).reshape(height, 1 + 3 * width)
    assert (rows[:, 0] == 0).all(), "every row must use filter type 0"
    return rows[:, 1:].reshape(height, width, 3)


@pytest.mark.parametrize("shape", [(1, 1), (5, 7), (64, 3), (2, 300)])
def test_encode_png_round_trips_through_an_independent_decoder(shape):
    rgb = np.random.default_rng(1).integers(0, 256, (*shape, 3), dtype=np.uint8)
    decoded = decode_png(rp.encode_png(rgb))
    assert decoded.shape == rgb.shape
    np.testing.assert_array_equal(decoded, rgb)


def test_encode_png_accepts_non_contiguous_views():
    rgb = np.arange(6 * 8 * 3, dtype=np.uint8).reshape(6, 8, 3)[::2, ::-1]
    np.testing.assert_array_equal(decode_png(rp.encode_png(rgb)), rgb)


@pytest.mark.parametrize(
    "bad", [np.zeros((4, 4, 3), np.float32), np.zeros((4, 4), np.uint8), np.zeros((0, 4, 3))]
)
def test_encode_png_rejects_what_is_not_an_rgb_image(bad):
    with pytest.raises(ValueError):
        rp.encode_png(bad)


# ---------------------------------------------------------------------- scene helpers


def _sensor(n: int, footprint, x: float = 0.0, y: float = 0.0) -> SensorRecord:
    return SensorRecord(
        n=n,
        x=x,
        y=y,
        z=7.0,
        height_m=7.0,
        pitch_deg=40.0,
        yaw_deg=0.0,
        model=PAPER_CAMERA,
        mast=0,
        fitness=0.0,
        epochs=0,
        covered_target_m2=0.0,
        footprint_m2=footprint.area,
        footprint=footprint,
    )


def _result(targets, areas=(), footprints=(), masts=(), points=None, covered=None, cell=1.0):
    points = np.zeros((0, 3)) if points is None else points
    covered = np.zeros(len(points), np.int32) if covered is None else covered
    return Result(
        sensors=tuple(_sensor(i, f) for i, f in enumerate(footprints)),
        masts=tuple(MastRecord(i, x, y, 0.0, 7.0, ()) for i, (x, y) in enumerate(masts)),
        targets=tuple((f"target{i}", g) for i, g in enumerate(targets)),
        sensor_areas=tuple((f"area{i}", g) for i, g in enumerate(areas)),
        points=points,
        n_visible=covered,
        n_covered=covered,
        cell_m=cell,
    )


def _blend(under, over, alpha=rp.FOOTPRINT_ALPHA):
    return (1 - alpha) * np.asarray(under, float) + alpha * np.asarray(over, float)


# ------------------------------------------------------------- the hand-made test field
#
# Target 100 m x 20 m at (0..100, 0..20); sensor area (40..50, 25..35) with the mast at
# (45, 30); one footprint over the left half (0..50, 0..20). Target points on a 1 m
# grid (centres 0.5 .. 99.5), covered left of x = 50. World box (0, 0)-(100, 35) plus
# 10 m margin is 120 m x 55 m; at 1200 px that is 10 px/m and 550 px high, so the pixel
# holding world (x, y) is row floor((45 - y) * 10), column floor((x + 10) * 10).


def _px(x: float, y: float) -> tuple[int, int]:
    return int(np.floor((45 - y) * 10)), int(np.floor((x + 10) * 10))


@pytest.fixture(scope="module")
def field() -> np.ndarray:
    gx, gy = np.meshgrid(np.arange(100) + 0.5, np.arange(20) + 0.5)
    points = np.column_stack([gx.ravel(), gy.ravel(), np.zeros(gx.size)])
    covered = (points[:, 0] < 50).astype(np.int32)
    result = _result(
        targets=[box(0, 0, 100, 20)],
        areas=[box(40, 25, 50, 35)],
        footprints=[box(0, 0, 50, 20)],
        masts=[(45.0, 30.0)],
        points=points,
        covered=covered,
    )
    return decode_png(rp.render_png(result, width_px=1200, margin_m=10.0))


def test_image_size_follows_the_world_box(field):
    height, width, _ = field.shape
    assert width == 1200
    assert abs(height - 1200 * 55 / 120) <= 1
    assert height == 550


def test_uncovered_half_is_the_warning_colour(field):
    for x, y in [(75.25, 10.25), (50.25, 0.25), (99.25, 19.75), (60.0, 5.0)]:
        assert tuple(field[_px(x, y)]) == rp.UNCOVERED, (x, y)


def test_covered_half_is_grey_under_one_green_layer(field):
    # 0.75 * 217 + 0.25 * (30, 160, 60) = (170.25, 202.75, 177.75) -> (170, 203, 178)
    assert tuple(_blend(rp.TARGET_FILL, rp.FOOTPRINT_FILL).round()) == (170, 203, 178)
    for x, y in [(25.25, 10.25), (1.25, 1.25), (49.25, 18.75)]:
        r, g, b = (int(v) for v in field[_px(x, y)])
        assert (r, g, b) == (170, 203, 178), (x, y)
        assert g > r and g > b  # greenish


def test_mast_is_a_dark_red_disc_with_a_white_rim(field):
    row, col = _px(45.0, 30.0)  # (150, 550): the pixel whose corner is the mast
    assert tuple(field[row, col]) == rp.MAST_FILL
    # Pixel centres (col + 0.5, row + 0.5) against radius 5 px and a 1.5 px rim:
    assert tuple(field[row, col - 4]) == rp.MAST_FILL  # hypot(3.5, 0.5) = 3.54 px away
    assert tuple(field[row, col + 5]) == rp.MAST_RIM  # 5.52 px
    assert tuple(field[row, col + 8]) == rp.SENSOR_AREA_FILL  # 8.51 px


def test_sensor_area_is_light_purple_with_a_purple_outline(field):
    assert tuple(field[_px(42.0, 33.0)]) == rp.SENSOR_AREA_FILL
    # Left edge x = 40 is pixel boundary 500; the 2 px line takes columns 499 and 500.
    row = _px(42.0, 28.0)[0]
    assert tuple(field[row, 499]) == rp.SENSOR_AREA_EDGE
    assert tuple(field[row, 500]) == rp.SENSOR_AREA_EDGE
    assert tuple(field[row, 497]) == rp.BACKGROUND
    assert tuple(field[row, 502]) == rp.SENSOR_AREA_FILL


def test_target_outline_is_drawn_over_the_uncovered_cells(field):
    row = _px(95.0, 10.0)[0]
    # Right edge x = 100 is pixel boundary 1100: columns 1099 and 1100 are the outline.
    assert tuple(field[row, 1099]) == rp.TARGET_EDGE
    assert tuple(field[row, 1100]) == rp.TARGET_EDGE
    assert tuple(field[row, 1098]) == rp.UNCOVERED
    assert tuple(field[row, 1102]) == rp.BACKGROUND


def test_outside_everything_is_white_and_the_border_is_the_frame(field):
    for x, y in [(105.0, 40.0), (-5.0, 40.0), (70.0, 30.0), (30.0, -5.0)]:
        assert tuple(field[_px(x, y)]) == rp.BACKGROUND, (x, y)
    for row, col in [(0, 0), (0, 600), (549, 1199), (275, 0), (275, 1199), (549, 600)]:
        assert tuple(field[row, col]) == rp.FRAME


def test_scale_bar_is_20_m_in_two_10_m_segments(field):
    # 120 m wide: the largest round length <= 30 m is 20 m = 200 px, from column 12;
    # rows 532..537 (6 px, 12 px above the bottom); its middle row reads dark for the
    # first 10 m (100 px), light for the second, closed by the dark outline.
    assert rp.scale_bar_m(120.0) == (20.0, 10.0)
    row = field[535]
    dark = np.all(row == rp.SCALE_DARK, axis=1)
    assert dark[12:112].all()
    assert np.all(row[112:211] == rp.SCALE_LIGHT)
    assert dark[211] and not dark[212] and not dark[11]
    assert np.all(field[531, 12:212] == rp.BACKGROUND)
    assert np.all(field[532, 12:212] == rp.SCALE_DARK)


@pytest.mark.parametrize(
    "width_m, expected",
    [(40.0, (10.0, 10.0)), (120.0, (20.0, 10.0)), (400.0, (100.0, 10.0)), (900.0, (200.0, 100.0)),
     (5000.0, (1000.0, 100.0)), (9000.0, (2000.0, 1000.0))],
)  # fmt: skip
def test_scale_bar_lengths(width_m, expected):
    assert rp.scale_bar_m(width_m) == expected


# ------------------------------------------------------- holes, empties, overlaps, cells
#
# Target 40 m x 40 m at the origin, margin 10 m, 600 px: 10 px/m, 600 px high; the pixel
# holding world (x, y) is row floor((50 - y) * 10), column floor((x + 10) * 10).


def _px60(x: float, y: float) -> tuple[int, int]:
    return int(np.floor((50 - y) * 10)), int(np.floor((x + 10) * 10))


def test_empty_footprint_is_skipped_and_a_hole_stays_uncoloured():
    holed = Polygon(box(0, 0, 40, 40).exterior.coords, [box(15, 15, 25, 25).exterior.coords])
    result = _result(targets=[box(0, 0, 40, 40)], footprints=[Polygon(), holed])
    img = decode_png(rp.render_png(result, width_px=600))
    assert img.shape == (600, 600, 3)
    assert tuple(img[_px60(20.0, 20.0)]) == rp.TARGET_FILL  # in the hole: no green
    assert tuple(img[_px60(5.0, 5.0)]) == tuple(_blend(rp.TARGET_FILL, rp.FOOTPRINT_FILL).round())
    # The hole's edge x = 15 is pixel boundary 250: the 1 px outline is column 250.
    row = _px60(15.0, 20.0)[0]
    assert tuple(img[row, 250]) == rp.FOOTPRINT_EDGE
    assert tuple(img[row, 252]) == rp.TARGET_FILL
    assert tuple(img[row, 248]) != rp.TARGET_FILL
    # The hole's outline is the border of the pixel square [250, 350] x [250, 350]:
    # 4 * 101 - 4 = 400 pixels; the outer ring's line lies under the 2 px target outline
    # (columns/rows 99-100 and 499-500), and nothing joins the two rings.
    edge = np.all(img == rp.FOOTPRINT_EDGE, axis=2)
    assert edge.sum() == 400
    assert edge[250, 250:351].all() and edge[350, 250:351].all() and edge[250:351, 250].all()


def test_overlapping_footprints_darken_and_multipart_footprints_fill_every_part():
    two = MultiPolygon([box(0, 32, 5, 37), box(35, 32, 40, 37)])
    nested = GeometryCollection(
        [MultiPolygon([box(15, 32, 20, 37)]), LineString([(0, 0), (40, 40)])]
    )
    result = _result(
        targets=[box(0, 0, 40, 40)],
        footprints=[box(0, 0, 30, 30), box(10, 0, 40, 30), two, nested],
    )
    img = decode_png(rp.render_png(result, width_px=600))
    one = _blend(rp.TARGET_FILL, rp.FOOTPRINT_FILL)
    # 0.5625 * 217 + 0.4375 * (30, 160, 60) = (135.19, 192.06, 148.31)
    assert tuple(_blend(one, rp.FOOTPRINT_FILL).round()) == (135, 192, 148)
    assert tuple(img[_px60(20.0, 20.0)]) == (135, 192, 148)
    assert tuple(img[_px60(5.0, 20.0)]) == tuple(one.round())
    assert tuple(img[_px60(35.0, 20.0)]) == tuple(one.round())
    for x in (2.5, 17.5, 37.5):
        assert tuple(img[_px60(x, 34.5)]) == tuple(one.round()), x
    assert tuple(img[_px60(10.0, 34.5)]) == rp.TARGET_FILL


def test_uncovered_cells_tile_without_seams_at_a_fractional_scale():
    # 0.7 m cells at 777 / (21 + 20) = 18.95 px/m: 13.27 px per cell, so cell edges fall
    # inside pixels; 30 x 10 cells must still be one solid 21 m x 7 m rectangle.
    cell = 0.7
    gx, gy = np.meshgrid((np.arange(30) + 0.5) * cell, (np.arange(10) + 0.5) * cell)
    points = np.column_stack([gx.ravel(), gy.ravel(), np.zeros(gx.size)])
    img = rp.render_rgb(_result(targets=[], points=points, cell=cell), width_px=777)
    scale = 777 / 41.0
    red = np.all(img == rp.UNCOVERED, axis=2)
    rows, cols = np.flatnonzero(red.any(axis=1)), np.flatnonzero(red.any(axis=0))
    assert red[rows[0] : rows[-1] + 1, cols[0] : cols[-1] + 1].all()
    assert red.sum() == len(rows) * len(cols)
    assert abs(len(cols) - 21 * scale) <= 1 and abs(len(rows) - 7 * scale) <= 1
    assert cols[0] == np.ceil(10 * scale - 0.5)  # first pixel centre right of x = 0


def test_a_cell_smaller_than_a_pixel_still_gets_its_pixel():
    # 0.1 px cells whose centres (300.2, 299.8) px are not near a pixel centre.
    points = np.array([[20.02, 20.02, 0.0]])
    result = _result(targets=[box(0, 0, 40, 40)], points=points, cell=0.01)
    img = rp.render_rgb(result, width_px=600)
    red = np.all(img == rp.UNCOVERED, axis=2)
    assert np.argwhere(red).tolist() == [[299, 300]] == [list(_px60(20.02, 20.02))]


def test_an_empty_placement_renders_a_framed_blank():
    img = rp.render_rgb(_result(targets=[]), width_px=50, margin_m=0.0)
    assert img.shape == (1, 50, 3)
    assert np.all(img == rp.FRAME)
    no_axis = _result(targets=[], points=np.zeros(0), covered=np.zeros(0, np.int32))
    img = rp.render_rgb(no_axis, width_px=50, margin_m=10.0)
    assert img.shape == (50, 50, 3)
    assert np.all(img[1:30, 1:-1] == rp.BACKGROUND)  # the scale bar is below row 30


def test_points_and_counts_must_match():
    result = _result(
        targets=[box(0, 0, 1, 1)], points=np.zeros((3, 3)), covered=np.zeros(2, np.int32)
    )
    with pytest.raises(ValueError):
        rp.render_png(result)
