"""Top-view coverage map of a sensor layout as a PNG, in numpy and shapely only.

The picture is the paper's Fig. 4 without the text: target area grey, sensor areas
purple, every sensor footprint a translucent green layer (overlaps get darker), target
points no sensor covers as warning-coloured cells, masts as dark-red discs, a frame and
a scale bar. It has to run inside Blender too, which ships neither matplotlib nor PIL,
so rasterizing and PNG encoding are done here by hand.

Frames and units
----------------
World: metres, X east, Y north (the ``Result``'s frame). Image: pixel rows top to
bottom and columns left to right, north up, the same number of pixels per metre in x
and y. In continuous pixel coordinates ``(col, row)`` pixel ``[r, c]`` covers
``[c, c + 1) x [r, r + 1)``, so its centre is ``(c + 0.5, r + 0.5)``; a world point
``(x, y)`` sits at ``col = (x - x_left) * scale``, ``row = (y_top - y) * scale``.

Drawing order (later on top): background, target fill, sensor-area fill, footprint
layers, footprint outlines, uncovered points, target and sensor-area outlines, masts,
scale bar, frame. The area outlines go over the uncovered cells so the areas stay
readable where the gaps reach their edge.

Scale bar: bottom left, alternating black and white segments of 10 m (100 m when the
bar is longer than 100 m, 1 km beyond 1 km); its length is the largest of 10, 20, 50,
100, 200, ... m that is at most a quarter of the image width. There is no text, so
the segments are what tells the reader the scale.
"""

from __future__ import annotations

import logging
import math
import struct
import time
import zlib
from dataclasses import dataclass

import numpy as np
import shapely
from numpy.typing import NDArray
from shapely.geometry.base import BaseGeometry

from ..core.result import Result

logger = logging.getLogger(__name__)

RGB = tuple[int, int, int]
Canvas = NDArray[np.float32]  # (H, W, 3) colour channels 0..255, blended as floats

BACKGROUND: RGB = (255, 255, 255)
TARGET_FILL: RGB = (217, 217, 217)
TARGET_EDGE: RGB = (90, 90, 90)
SENSOR_AREA_FILL: RGB = (226, 206, 242)
SENSOR_AREA_EDGE: RGB = (118, 56, 163)
FOOTPRINT_FILL: RGB = (30, 160, 60)
FOOTPRINT_ALPHA = 0.25  # per footprint: two overlapping footprints give 1 - 0.75^2
FOOTPRINT_EDGE: RGB = (20, 110, 40)
UNCOVERED: RGB = (240, 70, 20)
MAST_FILL: RGB = (140, 0, 0)
MAST_RIM: RGB = (255, 255, 255)
FRAME: RGB = (40, 40, 40)
SCALE_DARK: RGB = (0, 0, 0)
SCALE_LIGHT: RGB = (255, 255, 255)

AREA_EDGE_PX = 2  # target and sensor-area outlines
FOOTPRINT_EDGE_PX = 1
MAST_RADIUS_PX = 5.0
MAST_RIM_PX = 1.5
SCALE_BAR_THICKNESS_PX = 6
SCALE_BAR_OFFSET_PX = 12  # from the left and bottom image edges
# Boundary samples per pixel of boundary length: 2 leaves no gaps in a 1-px line.
_EDGE_SAMPLES_PER_PX = 2.0

_PNG_SIGNATURE = b"\x89PNG\r\n\x1a\n"
_POLYGON = 3  # shapely type ids
_COLLECTIONS = (4, 5, 6, 7)  # MultiPoint, MultiLineString, MultiPolygon, GeometryCollection


# --------------------------------------------------------------------------- public API


def render_png(result: Result, width_px: int = 1200, margin_m: float = 10.0) -> bytes:
    """Top view of the layout as PNG bytes (8-bit RGB, north up, equal x/y scale).

    The image covers the bounding box of targets, sensor areas, non-empty footprints,
    masts and target points, grown by ``margin_m`` metres on every side; it is
    ``width_px`` pixels wide and as high as the box's aspect ratio gives (at least 1).
    See the module docstring for what is drawn and in which order.
    """
    return encode_png(render_rgb(result, width_px, margin_m))


def render_rgb(result: Result, width_px: int = 1200, margin_m: float = 10.0) -> NDArray[np.uint8]:
    """The picture ``render_png`` encodes, as an (H, W, 3) uint8 array, row 0 = north."""
    t0 = time.perf_counter()
    n_points = len(result.points)
    if len(result.n_covered) != n_points:
        raise ValueError(f"result has {n_points} points but {len(result.n_covered)} n_covered")
    view = View.fit(_world_bounds(result), width_px, margin_m)
    img = np.empty((view.height, view.width, 3), np.float32)
    img[:] = BACKGROUND

    targets = [g for _, g in result.targets]
    areas = [g for _, g in result.sensor_areas]
    footprints = [s.footprint for s in result.sensors if not s.footprint.is_empty]
    for geom in targets:
        fill_polygon(img, view, geom, TARGET_FILL)
    for geom in areas:
        fill_polygon(img, view, geom, SENSOR_AREA_FILL)
    for geom in footprints:
        fill_polygon(img, view, geom, FOOTPRINT_FILL, FOOTPRINT_ALPHA)
    for geom in footprints:
        stroke_polygon(img, view, geom, FOOTPRINT_EDGE, FOOTPRINT_EDGE_PX)

    n_uncovered = 0
    if n_points:  # an empty points array may come without its second axis
        uncovered = result.points[np.asarray(result.n_covered) == 0]
        n_uncovered = len(uncovered)
        fill_cells(img, view, uncovered[:, 0], uncovered[:, 1], result.cell_m, UNCOVERED)

    for geom in targets:
        stroke_polygon(img, view, geom, TARGET_EDGE, AREA_EDGE_PX)
    for geom in areas:
        stroke_polygon(img, view, geom, SENSOR_AREA_EDGE, AREA_EDGE_PX)
    for mast in result.masts:
        draw_disc(img, view, mast.x, mast.y, MAST_RADIUS_PX, MAST_FILL, MAST_RIM, MAST_RIM_PX)
    draw_scale_bar(img, view)
    draw_frame(img, FRAME)

    rgb = np.rint(img).clip(0, 255).astype(np.uint8)
    logger.debug(
        "coverage map %dx%d px, %.3f px/m, %d footprints, %d uncovered of %d points, %.3f s",
        view.width,
        view.height,
        view.scale,
        len(footprints),
        n_uncovered,
        n_points,
        time.perf_counter() - t0,
    )
    return rgb


def encode_png(rgb: NDArray[np.uint8]) -> bytes:
    """PNG bytes of an (H, W, 3) uint8 image: 8-bit truecolour, no interlace, one IDAT,
    filter type 0 (none) on every row; zlib does all the compression work."""
    rgb = np.asarray(rgb)
    if rgb.ndim != 3 or rgb.shape[2] != 3 or rgb.dtype != np.uint8:
        raise ValueError(f"need an (H, W, 3) uint8 array, got {rgb.shape} {rgb.dtype}")
    height, width = rgb.shape[:2]
    if height < 1 or width < 1:
        raise ValueError(f"image must be at least 1 x 1 pixels, got {width} x {height}")
    # Each scanline is prefixed with its filter-type byte (0).
    rows = np.zeros((height, 1 + 3 * width), np.uint8)
    rows[:, 1:] = rgb.reshape(height, 3 * width)
    header = struct.pack(">IIBBBBB", width, height, 8, 2, 0, 0, 0)  # depth 8, colour type 2
    return b"".join(
        (
            _PNG_SIGNATURE,
            _png_chunk(b"IHDR", header),
            _png_chunk(b"IDAT", zlib.compress(rows.tobytes(), 6)),
            _png_chunk(b"IEND", b""),
        )
    )


# ------------------------------------------------------------------------ world <-> pixel


@dataclass(frozen=True)
class View:
    """Maps world metres to image pixels: ``scale`` px per metre, ``(x_left, y_top)`` the
    world position of the image's top-left corner, image ``width`` x ``height`` px."""

    x_left: float
    y_top: float
    scale: float
    width: int
    height: int

    @classmethod
    def fit(cls, bounds: tuple[float, float, float, float], width_px: int, margin_m: float) -> View:
        """The view of world ``bounds`` (xmin, ymin, xmax, ymax) plus ``margin_m`` on each
        side, ``width_px`` wide; the height is rounded, so the box is centred vertically
        and the image may show up to half a pixel more or less at top and bottom."""
        if width_px < 1:
            raise ValueError(f"width_px must be at least 1, got {width_px}")
        if margin_m < 0:
            raise ValueError(f"margin_m must not be negative, got {margin_m}")
        xmin, ymin, xmax, ymax = bounds
        # A single point or nothing at all still needs a finite scale.
        span_x = max(xmax - xmin + 2 * margin_m, 1.0)
        span_y = max(ymax - ymin + 2 * margin_m, 0.0)
        scale = width_px / span_x
        height = max(1, round(span_y * scale))
        return cls(
            x_left=(xmin + xmax) / 2 - span_x / 2,
            y_top=(ymin + ymax) / 2 + height / scale / 2,
            scale=scale,
            width=width_px,
            height=height,
        )

    def to_px(
        self, x: NDArray[np.float64] | float, y: NDArray[np.float64] | float
    ) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
        """Continuous (col, row) pixel coordinates of world points (x, y), any shape."""
        return (np.asarray(x) - self.x_left) * self.scale, (self.y_top - np.asarray(y)) * self.scale

    def pixel_window(self, bounds: tuple[float, float, float, float]) -> tuple[slice, slice]:
        """(rows, cols) slices of the pixels whose centres may lie in world ``bounds``,
        clipped to the image (possibly empty)."""
        xmin, ymin, xmax, ymax = bounds
        c0, r0 = self.to_px(xmin, ymax)
        c1, r1 = self.to_px(xmax, ymin)
        cols = slice(_clip(math.floor(c0), self.width), _clip(math.ceil(c1), self.width))
        rows = slice(_clip(math.floor(r0), self.height), _clip(math.ceil(r1), self.height))
        return rows, cols

    def pixel_centres(
        self, rows: slice, cols: slice
    ) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
        """World x, y of the centres of the pixels in ``rows`` x ``cols``, each (R, C)."""
        xs = self.x_left + (np.arange(cols.start, cols.stop) + 0.5) / self.scale
        ys = self.y_top - (np.arange(rows.start, rows.stop) + 0.5) / self.scale
        grid_x, grid_y = np.meshgrid(xs, ys)
        return grid_x, grid_y


def _clip(i: int, n: int) -> int:
    return min(max(i, 0), n)


def _world_bounds(result: Result) -> tuple[float, float, float, float]:
    """(xmin, ymin, xmax, ymax) in world metres of everything drawn; all zeros if the
    result holds nothing."""
    geoms = [g for _, g in result.targets] + [g for _, g in result.sensor_areas]
    geoms += [s.footprint for s in result.sensors]
    boxes = [g.bounds for g in geoms if not g.is_empty]
    xy = [(m.x, m.y) for m in result.masts]
    if len(result.points):
        pts = np.asarray(result.points)[:, :2]
        # Half a cell each way: the uncovered cells are drawn as squares of cell_m.
        half = result.cell_m / 2
        boxes.append((*(pts.min(axis=0) - half), *(pts.max(axis=0) + half)))
    boxes += [(x, y, x, y) for x, y in xy]
    if not boxes:
        return (0.0, 0.0, 0.0, 0.0)
    b = np.array(boxes, np.float64)
    return (b[:, 0].min(), b[:, 1].min(), b[:, 2].max(), b[:, 3].max())


# ------------------------------------------------------------------------------ drawing


def _polygons(geom: BaseGeometry) -> list[BaseGeometry]:
    """The non-empty Polygons in a Polygon, MultiPolygon or GeometryCollection (lines and
    points in a collection have no area and are dropped)."""
    parts = shapely.get_parts(geom)
    # Collections may nest, and a one-part Multi* is still a Multi*: flatten until none.
    while np.isin(shapely.get_type_id(parts), _COLLECTIONS).any():
        parts = shapely.get_parts(parts)
    keep = (shapely.get_type_id(parts) == _POLYGON) & ~shapely.is_empty(parts)
    return list(parts[keep])


def _blend(target: Canvas, mask: NDArray[np.bool_], colour: RGB, alpha: float) -> None:
    """Paint ``colour`` with opacity ``alpha`` (1 = opaque) over ``target`` where ``mask``."""
    if alpha >= 1.0:
        target[mask] = colour
    else:
        target[mask] = target[mask] * (1.0 - alpha) + np.asarray(colour, np.float32) * alpha


def fill_polygon(
    img: Canvas, view: View, geom: BaseGeometry, colour: RGB, alpha: float = 1.0
) -> None:
    """Fill the pixels whose centres lie inside ``geom`` (world XY; holes stay unfilled).

    Each polygon part is tested over the pixel window of its own bounding box only, with
    a prepared geometry, which keeps large images with many small footprints fast.
    Parts of a valid MultiPolygon do not overlap, so each pixel is blended at most once.
    """
    for poly in _polygons(geom):
        rows, cols = view.pixel_window(poly.bounds)
        if rows.start == rows.stop or cols.start == cols.stop:
            continue
        xs, ys = view.pixel_centres(rows, cols)
        shapely.prepare(poly)
        inside = shapely.contains_xy(poly, xs, ys)
        _blend(img[rows, cols], inside, colour, alpha)


def stroke_polygon(
    img: Canvas, view: View, geom: BaseGeometry, colour: RGB, width_px: int = 1
) -> None:
    """Draw the exterior and interior rings of ``geom`` as lines ``width_px`` pixels wide.

    Every ring segment is sampled at ``_EDGE_SAMPLES_PER_PX`` points per pixel of its
    length (in pixel space) and each sample sets the ``width_px`` x ``width_px`` block of
    pixels centred on it (for width 1: the pixel it falls in).
    """
    polys = _polygons(geom)
    if not polys:
        return
    rings = shapely.get_rings(np.array(polys, dtype=object))
    coords, ring_of = shapely.get_coordinates(rings, return_index=True)
    if len(coords) < 2:
        return
    col, row = view.to_px(coords[:, 0], coords[:, 1])
    p = np.column_stack([col, row])
    same_ring = ring_of[1:] == ring_of[:-1]  # don't join the last point of one ring to the next
    start, delta = p[:-1][same_ring], (p[1:] - p[:-1])[same_ring]
    n_steps = np.maximum(
        1, np.ceil(np.hypot(delta[:, 0], delta[:, 1]) * _EDGE_SAMPLES_PER_PX).astype(np.int64)
    )
    seg = np.repeat(np.arange(len(start)), n_steps + 1)  # samples at t = 0, 1/n, ..., 1
    first = np.repeat(np.cumsum(n_steps + 1) - (n_steps + 1), n_steps + 1)
    t = (np.arange(len(seg)) - first) / n_steps[seg]
    samples = start[seg] + t[:, None] * delta[seg]
    # Shift so a wide line straddles the boundary instead of lying to one side of it.
    corner = np.floor(samples - (width_px - 1) / 2)
    _set_blocks(img, corner[:, 1], corner[:, 0], width_px, colour)


def _set_blocks(
    img: Canvas, rows: NDArray[np.float64], cols: NDArray[np.float64], size: int, colour: RGB
) -> None:
    """Set the ``size`` x ``size`` pixel blocks whose top-left pixels are (rows, cols)."""
    height, width = img.shape[:2]
    r0, c0 = rows.astype(np.int64), cols.astype(np.int64)
    for dr in range(size):
        for dc in range(size):
            r, c = r0 + dr, c0 + dc
            ok = (r >= 0) & (r < height) & (c >= 0) & (c < width)
            img[r[ok], c[ok]] = colour


def fill_cells(
    img: Canvas,
    view: View,
    x: NDArray[np.float64],
    y: NDArray[np.float64],
    cell_m: float,
    colour: RGB,
) -> None:
    """Fill the square cells of side ``cell_m`` centred on world points (x, y), each (N,).

    A cell gets the pixels whose centres it contains, so neighbouring grid cells tile
    without gaps or overlap; a cell smaller than a pixel gets the pixel its centre is in.
    The (N,) rectangles go into a 2-D difference array, so the cost is N + H * W rather
    than N * cell pixels.
    """
    if len(x) == 0:
        return
    height, width = img.shape[:2]
    c_lo, c_hi = _cell_span(view.to_px(x, y)[0], cell_m * view.scale / 2, width)
    r_lo, r_hi = _cell_span(view.to_px(x, y)[1], cell_m * view.scale / 2, height)
    ok = (c_hi > c_lo) & (r_hi > r_lo)
    c_lo, c_hi, r_lo, r_hi = c_lo[ok], c_hi[ok], r_lo[ok], r_hi[ok]
    diff = np.zeros((height + 1, width + 1), np.int32)
    np.add.at(diff, (r_lo, c_lo), 1)
    np.add.at(diff, (r_lo, c_hi), -1)
    np.add.at(diff, (r_hi, c_lo), -1)
    np.add.at(diff, (r_hi, c_hi), 1)
    covered = diff.cumsum(axis=0).cumsum(axis=1)[:height, :width] > 0
    img[covered] = colour


def _cell_span(
    centre_px: NDArray[np.float64], half_px: float, n: int
) -> tuple[NDArray[np.int64], NDArray[np.int64]]:
    """[lo, hi) pixel index range along one axis of cells centred at ``centre_px`` with
    half-size ``half_px`` (pixels whose centre k + 0.5 lies in [c - h, c + h)),
    at least the pixel holding the centre, clipped to [0, n]."""
    # Rounded before ceil: the shared edge of two neighbouring cells, computed from each
    # centre, may differ by an ulp across an integer and leave a one-pixel seam.
    lo = np.ceil(np.round(centre_px - half_px - 0.5, 6)).astype(np.int64)
    hi = np.ceil(np.round(centre_px + half_px - 0.5, 6)).astype(np.int64)
    tiny = hi <= lo
    lo[tiny] = np.floor(centre_px[tiny]).astype(np.int64)
    hi[tiny] = lo[tiny] + 1
    return np.clip(lo, 0, n), np.clip(hi, 0, n)


def draw_disc(
    img: Canvas,
    view: View,
    x: float,
    y: float,
    radius_px: float,
    fill: RGB,
    rim: RGB,
    rim_px: float,
) -> None:
    """A disc of ``radius_px`` pixels at world (x, y), with a ring ``rim_px`` wide
    around it; sized in pixels so masts stay visible at any scale."""
    height, width = img.shape[:2]
    col, row = view.to_px(x, y)
    outer = radius_px + rim_px
    r0, r1 = _clip(math.floor(row - outer), height), _clip(math.ceil(row + outer) + 1, height)
    c0, c1 = _clip(math.floor(col - outer), width), _clip(math.ceil(col + outer) + 1, width)
    if r0 == r1 or c0 == c1:
        return
    dr = np.arange(r0, r1)[:, None] + 0.5 - row
    dc = np.arange(c0, c1)[None, :] + 0.5 - col
    dist = np.hypot(dr, dc)
    window = img[r0:r1, c0:c1]
    window[dist <= outer] = rim
    window[dist <= radius_px] = fill


def scale_bar_m(world_width_m: float) -> tuple[float, float]:
    """(bar length, segment length) in metres for an image ``world_width_m`` wide: the
    largest of 10, 20, 50, 100, 200, ... m not over a quarter of the width (at least
    10 m), cut into 10 m segments, 100 m beyond 100 m, 1 km beyond 1 km, and so on."""
    length = 10.0
    for decade in range(1, 9):
        for mantissa in (1, 2, 5):
            candidate = mantissa * 10.0**decade
            if candidate <= world_width_m / 4:
                length = candidate
    segment = 10.0 ** max(1, math.ceil(math.log10(length) - 1e-9) - 1)
    return length, segment


def draw_scale_bar(img: Canvas, view: View) -> None:
    """Scale bar at the bottom left (see ``scale_bar_m``): alternating dark and light
    segments inside a one-pixel dark outline; skipped if it does not fit in the image."""
    height, width = img.shape[:2]
    length_m, segment_m = scale_bar_m(width / view.scale)
    length_px = round(length_m * view.scale)
    r1 = height - SCALE_BAR_OFFSET_PX
    r0 = r1 - SCALE_BAR_THICKNESS_PX
    c0 = SCALE_BAR_OFFSET_PX
    if r0 < 0 or c0 + length_px > width or length_px < 2:
        return
    # Segment index of every bar column, from the metres it stands for.
    metres = (np.arange(length_px) + 0.5) / view.scale
    dark = (np.floor(metres / segment_m).astype(np.int64) % 2) == 0
    img[r0:r1, c0 : c0 + length_px] = np.where(dark[:, None], SCALE_DARK, SCALE_LIGHT)
    bar = img[r0:r1, c0 : c0 + length_px]
    bar[[0, -1], :] = SCALE_DARK
    bar[:, [0, -1]] = SCALE_DARK


def draw_frame(img: Canvas, colour: RGB) -> None:
    """A one-pixel border around the whole image."""
    img[[0, -1], :] = colour
    img[:, [0, -1]] = colour


# ---------------------------------------------------------------------------------- PNG


def _png_chunk(kind: bytes, data: bytes) -> bytes:
    """length, type, data, CRC-32 of type + data (all big-endian)."""
    crc = zlib.crc32(kind + data) & 0xFFFFFFFF
    return struct.pack(">I", len(data)) + kind + data + struct.pack(">I", crc)
