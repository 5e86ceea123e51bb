"""Deterministic sample scenes for AutoSCOOP, built with the pip ``bpy`` module.

Every scene follows the AutoSCOOP scene contract:

* world metres, Z up; every mesh is stored in world coordinates (identity object
  transforms), so a consumer that forgets ``matrix_world`` still sees the truth;
* target areas (roads to watch) are CURVE objects named ``Target...``, sensor
  areas (where masts may stand) are CURVE objects named ``SensorArea_...``; both
  hold closed POLY splines in the XY plane, several splines in one object being
  combined by the even-odd rule (a loop road is an outer plus an inner ring);
* every other visible MESH object occludes: terrain, walls, buildings, trees.
  Occluders live in the ``Environment`` collection, the curves in ``Areas``.

All randomness comes from ``numpy.random.default_rng`` with fixed seeds, so two
runs produce identical geometry.

Run ``./dev.sh samples`` to rebuild the files into ``sample_blends/``
next to the repository root.

One module: the three sample scenes share their terrain, wall, building and tree
builders, and a test compares the committed files with what it builds.
"""

from __future__ import annotations

import math
import pathlib
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field

import bpy
import numpy as np
import shapely
from scipy.interpolate import splev, splprep
from shapely.geometry import LinearRing, LineString, Point, Polygon, box
from shapely.ops import nearest_points, substring, unary_union

from headless.paths import SAMPLES

SAMPLE_DIR = SAMPLES
"""Default output folder: ``sample_blends/`` at the repository root."""

HeightFn = Callable[[np.ndarray, np.ndarray], np.ndarray]
"""Terrain height z [m] as a function of world x, y arrays [m] (vectorised)."""

# --- flat_wall: exact numbers, shared with the tests (world metres) -------------
FLAT_GROUND_HALF = 60.0
"""``Ground`` spans x, y in [-60, 60] at z = 0."""
FLAT_TARGET_RECT = (0.0, -25.0, 50.0, 25.0)
"""``Target_Area`` as (xmin, ymin, xmax, ymax)."""
FLAT_SENSOR_RECT = (-12.0, -4.0, -4.0, 4.0)
"""``SensorArea_1`` as (xmin, ymin, xmax, ymax)."""
FLAT_WALL_BOX = (10.0, -2.0, 0.0, 10.3, 8.0, 3.0)
"""``Wall`` as (xmin, ymin, zmin, xmax, ymax, zmax)."""

# --- two_routes / full_ground: one 250 m x 250 m proving-ground section ---------
TILE_SIZE = 250.0
"""Edge of one proving-ground section [m]; the section spans [0, 250] in x and y."""
TERRAIN_MARGIN = 100.0
"""Terrain extends this far [m] beyond the areas (sensors see ~80 m beyond)."""
TILE_PITCH = 260.0
"""Tile spacing [m] in full_ground; the 10 m gutter keeps tiles' roads apart."""

# Centreline control points (tile-local metres). Route A is a closed handling
# loop whose infield is narrow enough (about 29 m) for masts inside it to see
# both straights; route B is a three-leg serpentine south of it whose legs are
# ~40 m apart, so a mast in a corridor sees both legs. B rises to y ~ 138 at
# x ~ 140 while A dips to y ~ 160: the narrow point, ~8 m between the edges.
_ROUTE_A_CTRL = (
    (48, 165), (100, 163), (140, 160), (195, 164), (230, 185), (195, 206),
    (160, 209), (125, 205), (90, 209), (48, 206), (18, 185),
)  # fmt: skip
_ROUTE_B_CTRL = (
    (-10, 130), (40, 128), (95, 133), (140, 138), (185, 131), (222, 126),
    (238, 112), (226, 96), (190, 92), (140, 96), (90, 90), (45, 92),
    (22, 80), (25, 60), (50, 52), (100, 50), (150, 56), (200, 50), (260, 54),
)  # fmt: skip
_ROUTE_A_WIDTH = 14.0
_ROUTE_B_WIDTH = 14.0


@dataclass(frozen=True)
class _SensorSpec:
    """A sensor strip along one route, on the side of ``near``.

    The strip follows the route centreline for ``length`` metres around the
    point closest to ``near``, keeps ``gap`` metres from the road edge and is
    ``width`` metres wide. ``height_m`` (mast height) is written as a custom
    property when set.
    """

    route: str
    near: tuple[float, float]
    length: float
    gap: float = 4.0
    width: float = 8.0
    height_m: float | None = None


# Six strips, each placed so that it sees two road stretches (the two straights
# of A's infield, or the two legs of a B corridor) plus a hairpin or a loop end
# where it sits near one. 55 m long rather than 40 m: with ~1.2 km of road and
# only six areas, 40 m strips left >10 % of the road beyond 40 m of any area.
_SENSOR_SPECS = (
    _SensorSpec("A", (67, 177), 55.0),
    _SensorSpec("A", (182, 193), 55.0),
    _SensorSpec("B", (47, 105), 55.0),
    _SensorSpec("B", (177, 120), 55.0, height_m=10.0),
    _SensorSpec("B", (57, 65), 55.0),
    _SensorSpec("B", (190, 80), 55.0, height_m=5.0),
)


@dataclass(frozen=True)
class _BuildingSpec:
    """A box building: footprint centre [m], size along its own axes [m], yaw
    [deg, counter-clockwise from +x] and height above the terrain [m]."""

    centre: tuple[float, float]
    size: tuple[float, float]
    yaw_deg: float
    height: float


# In A's infield, in both B corridors (between their two sensor strips) and in
# the gap west of the narrow point: each stands between roads and the masts
# that look at them, so it casts shadows that matter.
_BUILDING_SPECS = (
    _BuildingSpec((125.0, 185.0), (22.0, 10.0), 3.0, 10.0),
    _BuildingSpec((112.0, 113.0), (14.0, 10.0), 15.0, 8.0),
    _BuildingSpec((118.0, 73.0), (16.0, 10.0), -12.0, 12.0),
    _BuildingSpec((36.0, 149.0), (12.0, 10.0), 30.0, 7.0),
)

# Relief of the two_routes section: (x0, y0, amplitude, sigma) in metres.
_TWO_ROUTES_BUMPS = (
    (125.0, 250.0, 6.0, 40.0),  # hill north of the loop; A's north straight climbs
    (170.0, 70.0, -3.0, 30.0),  # dip in B's southern corridor
    (25.0, 80.0, 4.0, 30.0),  # knoll inside B's west hairpin
    (235.0, 175.0, 2.5, 45.0),  # gentle rise at A's east end
)

_TREE_SEED = 20240601
_TERRAIN_SEED = 7


# ================================================================================
# Pure geometry (numpy / shapely): no Blender involved
# ================================================================================


@dataclass(frozen=True)
class _Tree:
    """One tree: position [m], canopy radii [m] and heights above ground [m]."""

    x: float
    y: float
    radius: float
    radius_z: float
    trunk_height: float
    canopy_z: float


@dataclass
class _Layout:
    """Everything of one proving-ground section in world XY metres."""

    centrelines: dict[str, tuple[LineString, float]]
    """Route name -> (centreline, road width [m]); route A's line is closed."""
    targets: dict[str, Polygon]
    """Route name -> road polygon (A has a hole: its infield)."""
    sensor_areas: list[Polygon]
    sensor_heights: list[float | None]
    wall: np.ndarray
    """(n, 2) polyline of the wall at the narrow point."""
    buildings: list[tuple[np.ndarray, float]]
    """(4, 2) footprint corners and height above terrain [m]."""
    bounds: Polygon
    """The section's square; trees stay inside it."""
    trees: list[_Tree] = field(default_factory=list)


def _smooth_path(
    ctrl: Sequence[tuple[float, float]], closed: bool, step: float = 1.0
) -> np.ndarray:
    """Sample an interpolating cubic spline through ``ctrl`` every ~``step`` m.

    Returns an (n, 2) array; for a closed path the first point is not repeated.
    """
    pts = np.asarray(ctrl, dtype=float)
    if closed:
        pts = np.vstack([pts, pts[:1]])
    tck, _ = splprep(pts.T, s=0, per=int(closed), k=3)
    x, y = splev(np.linspace(0.0, 1.0, 4000), tck)
    length = float(np.hypot(np.diff(x), np.diff(y)).sum())
    u = np.linspace(0.0, 1.0, max(int(length / step), 8) + 1)
    x, y = splev(u, tck)
    out = np.column_stack([x, y])
    return out[:-1] if closed else out


def _road_polygon(line: LineString | LinearRing, width: float, clip: Polygon) -> Polygon:
    """Buffer a centreline into a road of ``width`` m, clip it and simplify.

    Flat caps make an open road end square where it leaves ``clip``; the 0.2 m
    simplification keeps a few hundred points per ring at most.
    """
    road = line.buffer(width / 2.0, cap_style="flat").intersection(clip)
    road = road.simplify(0.2)
    if not isinstance(road, Polygon):
        raise TypeError(f"road is not a single polygon: {road.geom_type}")
    return road


def _arc(line: LineString, s0: float, s1: float) -> LineString:
    """Piece of ``line`` between arc lengths ``s0`` < ``s1`` [m].

    A closed line wraps around its seam (shapely's ``substring`` would read a
    negative distance as counted from the end instead).
    """
    if not line.is_ring:
        return substring(line, s0, s1)
    coords = np.asarray(line.coords)
    twice = LineString(np.vstack([coords, coords[1:]]))
    start = s0 % line.length
    return substring(twice, start, start + (s1 - s0))


def _sensor_strip(line: LineString, road_width: float, spec: _SensorSpec) -> Polygon:
    """A strip beside ``line`` following it, ``spec.gap`` m off the road edge."""
    s_mid = line.project(Point(spec.near))
    seg = _arc(line, s_mid - spec.length / 2.0, s_mid + spec.length / 2.0)
    p0 = np.array(line.interpolate(s_mid).coords[0])
    p1 = np.array(line.interpolate(s_mid + 1.0).coords[0])
    tangent = p1 - p0
    left = np.array([-tangent[1], tangent[0]])
    side = 1.0 if np.dot(np.asarray(spec.near) - p0, left) > 0.0 else -1.0
    offset = road_width / 2.0 + spec.gap + spec.width / 2.0
    # offset_curve: positive distance = left of the line direction.
    mid = seg.offset_curve(side * offset)
    return mid.buffer(spec.width / 2.0, cap_style="flat").simplify(0.2)


def _narrow_point_wall(
    b_line: LineString,
    b_width: float,
    a_road: Polygon,
    length: tuple[float, float] = (30.0, 60.0),
) -> np.ndarray:
    """Polyline [m] midway between road B's edge and road A where they are closest.

    The wall covers the stretch of B whose edge gap to A is within 4 m of the
    minimum, clamped to ``length`` (min, max) metres and centred on the minimum.
    """
    s = np.arange(0.0, b_line.length, 1.0)
    pts = shapely.line_interpolate_point(b_line, s)
    gap = shapely.distance(a_road, pts) - b_width / 2.0
    i_min = int(np.argmin(gap))
    lo, hi = i_min, i_min
    while lo > 0 and gap[lo - 1] <= gap[i_min] + 4.0:
        lo -= 1
    while hi < len(s) - 1 and gap[hi + 1] <= gap[i_min] + 4.0:
        hi += 1
    half = np.clip((s[hi] - s[lo]) / 2.0, length[0] / 2.0, length[1] / 2.0)
    sel = np.abs(s - s[i_min]) <= half
    mids = []
    for p, g in zip(pts[sel], gap[sel], strict=True):
        q = nearest_points(a_road, p)[0]
        pq = np.array(p.coords[0]) - np.array(q.coords[0])
        mids.append(np.array(q.coords[0]) + pq / np.linalg.norm(pq) * (g / 2.0))
    # Nearest points hop between polygon vertices: smooth the 1 m samples with a
    # 9 m moving average (ends kept), then keep a vertex every ~4 m.
    mids_arr = np.asarray(mids)
    kernel = np.ones(9) / 9.0
    smooth = mids_arr.copy()
    for k in range(2):
        smooth[4:-4, k] = np.convolve(mids_arr[:, k], kernel, mode="valid")
    line = LineString(smooth)
    n_seg = max(round(line.length / 4.0), 1)
    return np.array(
        [line.interpolate(f, normalized=True).coords[0] for f in np.linspace(0, 1, n_seg + 1)]
    )


def _two_routes_layout() -> _Layout:
    """The two_routes section in tile-local metres ([0, 250] x [0, 250])."""
    clip = box(0.0, 0.0, TILE_SIZE, TILE_SIZE)
    a_pts = _smooth_path(_ROUTE_A_CTRL, closed=True)
    b_pts = _smooth_path(_ROUTE_B_CTRL, closed=False)
    a_line = LineString(np.vstack([a_pts, a_pts[:1]]))
    b_line = LineString(b_pts)
    targets = {
        "A": _road_polygon(LinearRing(a_pts), _ROUTE_A_WIDTH, clip),
        "B": _road_polygon(b_line, _ROUTE_B_WIDTH, clip),
    }
    centrelines = {"A": (a_line, _ROUTE_A_WIDTH), "B": (b_line, _ROUTE_B_WIDTH)}
    areas = [
        _sensor_strip(centrelines[sp.route][0], centrelines[sp.route][1], sp)
        for sp in _SENSOR_SPECS
    ]
    wall = _narrow_point_wall(b_line, _ROUTE_B_WIDTH, targets["A"])
    buildings = [(_rect_corners(b), b.height) for b in _BUILDING_SPECS]
    return _Layout(
        centrelines=centrelines,
        targets=targets,
        sensor_areas=areas,
        sensor_heights=[sp.height_m for sp in _SENSOR_SPECS],
        wall=wall,
        buildings=buildings,
        bounds=clip,
    )


def _rect_corners(spec: _BuildingSpec) -> np.ndarray:
    """(4, 2) counter-clockwise corners [m] of a building footprint."""
    hx, hy = spec.size[0] / 2.0, spec.size[1] / 2.0
    local = np.array([[-hx, -hy], [hx, -hy], [hx, hy], [-hx, hy]])
    c, s = math.cos(math.radians(spec.yaw_deg)), math.sin(math.radians(spec.yaw_deg))
    return local @ np.array([[c, s], [-s, c]]) + np.asarray(spec.centre)


def _tile_transform(
    quarter_turns: int, mirror: bool, origin: tuple[float, float]
) -> Callable[[np.ndarray], np.ndarray]:
    """Map tile-local XY [m] to world XY [m]: mirror x, rotate about the tile
    centre by ``quarter_turns`` x 90 deg, then translate by ``origin``."""
    c = TILE_SIZE / 2.0
    ang = quarter_turns * math.pi / 2.0
    rot = np.array([[math.cos(ang), -math.sin(ang)], [math.sin(ang), math.cos(ang)]])
    rot = np.round(rot)  # exact quarter turns: keep coordinates bit-stable

    def apply(xy: np.ndarray) -> np.ndarray:
        p = np.array(xy, dtype=float).reshape(-1, 2)
        if mirror:
            p[:, 0] = TILE_SIZE - p[:, 0]
        return (p - c) @ rot.T + c + np.asarray(origin)

    return apply


def _transform_layout(layout: _Layout, xf: Callable[[np.ndarray], np.ndarray]) -> _Layout:
    """Apply a rigid (possibly mirroring) XY map to every part of a layout."""

    def geom(g: shapely.Geometry) -> shapely.Geometry:
        return shapely.transform(g, xf)

    return _Layout(
        centrelines={k: (geom(line), w) for k, (line, w) in layout.centrelines.items()},
        targets={k: geom(p) for k, p in layout.targets.items()},
        sensor_areas=[geom(p) for p in layout.sensor_areas],
        sensor_heights=list(layout.sensor_heights),
        wall=xf(layout.wall),
        buildings=[(xf(c), h) for c, h in layout.buildings],
        bounds=geom(layout.bounds),
    )


def _place_trees(layout: _Layout, rng: np.random.Generator, count: int) -> None:
    """Scatter ``count`` trees beside the roads of ``layout`` (in place).

    A canopy keeps >= 1 m horizontal clearance from every road, stays off the
    sensor areas, buildings and the wall, does not touch another canopy and
    stays inside the section. Candidates are drawn along the centrelines at a
    random side and distance, so trees line the roads.
    """
    roads = unary_union(list(layout.targets.values()))
    sensors = unary_union(layout.sensor_areas)
    blocks = unary_union([Polygon(c) for c, _ in layout.buildings])
    wall = LineString(layout.wall)
    inner = layout.bounds
    names = sorted(layout.centrelines)
    lengths = np.array([layout.centrelines[n][0].length for n in names])
    trees: list[_Tree] = []
    for _ in range(20000):
        if len(trees) == count:
            break
        name = names[rng.choice(len(names), p=lengths / lengths.sum())]
        line, width = layout.centrelines[name]
        s = rng.uniform(0.0, line.length)
        r = rng.uniform(2.5, 4.0)
        off = width / 2.0 + r + 1.0 + rng.uniform(0.5, 4.0)
        side = rng.choice((-1.0, 1.0))
        trunk_h = rng.uniform(3.2, 4.0)
        r_z = r * rng.uniform(0.9, 1.0)
        # Canopy centre 5-7 m up but low enough that the trunk reaches into it.
        canopy_z = rng.uniform(5.0, min(7.0, trunk_h - 0.3 + r_z))
        p0 = np.array(line.interpolate(s).coords[0])
        p1 = np.array(line.interpolate(min(s + 1.0, line.length)).coords[0])
        if s + 1.0 > line.length:
            p0, p1 = np.array(line.interpolate(s - 1.0).coords[0]), p0
        t = (p1 - p0) / np.linalg.norm(p1 - p0)
        x, y = p0 + side * off * np.array([-t[1], t[0]])
        pt = Point(x, y)
        if not inner.contains(pt) or inner.exterior.distance(pt) < r:
            continue
        if roads.distance(pt) < r + 1.0 or sensors.distance(pt) < r + 0.5:
            continue
        if blocks.distance(pt) < r + 1.0 or wall.distance(pt) < r + 0.5:
            continue
        if any(math.hypot(x - o.x, y - o.y) < r + o.radius + 0.5 for o in trees):
            continue
        trees.append(_Tree(float(x), float(y), r, r_z, trunk_h, canopy_z))
    if len(trees) < count:
        raise RuntimeError(f"placed only {len(trees)} of {count} trees")
    layout.trees = trees


def _check_layout(layout: _Layout) -> None:
    """Fail loudly if a layout breaks the scene contract's spacing rules."""
    roads = unary_union(list(layout.targets.values()))
    for i, area in enumerate(layout.sensor_areas, start=1):
        d = area.distance(roads)
        if not 2.0 <= d <= 6.0:
            raise ValueError(f"sensor area {i} is {d:.2f} m from the nearest road")
        for corners, _ in layout.buildings:
            if area.distance(Polygon(corners)) < 2.0:
                raise ValueError(f"sensor area {i} is too close to a building")
    for corners, _ in layout.buildings:
        if Polygon(corners).distance(roads) < 3.0:
            raise ValueError("a building stands closer than 3 m to a road")
    if LineString(layout.wall).distance(roads) < 2.0:
        raise ValueError("the wall is closer than 2 m to a road")


def _gaussian_relief(bumps: np.ndarray) -> HeightFn:
    """Height function: a sum of isotropic Gaussians (x0, y0, amplitude, sigma)."""
    b = np.asarray(bumps, dtype=float).reshape(-1, 4)

    def height(x: np.ndarray, y: np.ndarray) -> np.ndarray:
        x = np.asarray(x, dtype=float)[..., None]
        y = np.asarray(y, dtype=float)[..., None]
        r2 = (x - b[:, 0]) ** 2 + (y - b[:, 1]) ** 2
        return (b[:, 2] * np.exp(-r2 / (2.0 * b[:, 3] ** 2))).sum(axis=-1)

    return height


def _axis(
    lo: float, hi: float, inner: tuple[float, float], fine: float, coarse: float
) -> np.ndarray:
    """Grid coordinates [m] from ``lo`` to ``hi``: ``fine`` spacing inside
    ``inner`` (lo, hi), ``coarse`` outside. A rectilinear grid built from two
    such axes is conforming (no T-junctions) whatever the spacings."""
    left = np.arange(lo, inner[0], coarse)
    mid = np.linspace(inner[0], inner[1], round((inner[1] - inner[0]) / fine) + 1)
    right = np.arange(hi, inner[1], -coarse)[::-1]
    return np.concatenate([left, mid, right[right > inner[1] + 1e-9]])


# ================================================================================
# Mesh construction (numpy): vertices in world metres, faces as index tuples
# ================================================================================


def _orient_ring_ccw(ring: np.ndarray) -> np.ndarray:
    """Return the (n, 2) ring ordered counter-clockwise seen from +z."""
    x, y = ring[:, 0], ring[:, 1]
    signed = np.dot(x, np.roll(y, -1)) - np.dot(y, np.roll(x, -1))
    return ring if signed > 0.0 else ring[::-1]


def _prism(
    ring: np.ndarray, z_bottom: float, z_top: float
) -> tuple[np.ndarray, list[tuple[int, ...]]]:
    """Closed prism over a simple XY polygon ring, outward normals.

    ``ring`` is (n, 2) without a repeated first point; a 4-point ring gives the
    classic 8-vertex, 6-quad box.
    """
    ring = _orient_ring_ccw(np.asarray(ring, dtype=float))
    n = len(ring)
    verts = np.vstack(
        [
            np.column_stack([ring, np.full(n, z_bottom)]),
            np.column_stack([ring, np.full(n, z_top)]),
        ]
    )
    faces: list[tuple[int, ...]] = [tuple(range(n - 1, -1, -1)), tuple(range(n, 2 * n))]
    # Ring is CCW, so (b_i, b_i+1, t_i+1, t_i) faces outwards (to its right).
    faces += [(i, (i + 1) % n, n + (i + 1) % n, n + i) for i in range(n)]
    return verts, faces


def _ribbon_wall(
    line: np.ndarray, thickness: float, z_bottom: np.ndarray, z_top: np.ndarray
) -> tuple[np.ndarray, list[tuple[int, ...]]]:
    """Closed wall mesh along an (n, 2) polyline, per-vertex base and top z [m].

    The sides are offset by +-thickness/2 along the mitred vertex normals.
    Vertex blocks: left-bottom, right-bottom, left-top, right-top (n each).
    """
    line = np.asarray(line, dtype=float)
    n = len(line)
    seg = np.diff(line, axis=0)
    seg /= np.linalg.norm(seg, axis=1)[:, None]
    seg_n = np.column_stack([-seg[:, 1], seg[:, 0]])  # left normals per segment
    normals = np.vstack([seg_n[:1], seg_n[:-1] + seg_n[1:], seg_n[-1:]])
    normals /= np.linalg.norm(normals, axis=1)[:, None]
    # Mitre: stretch so both sides stay thickness/2 from each adjacent segment.
    cos_half = np.ones(n)
    cos_half[1:-1] = np.einsum("ij,ij->i", normals[1:-1], seg_n[1:])
    half = thickness / 2.0 / cos_half
    left = line + normals * half[:, None]
    right = line - normals * half[:, None]
    verts = np.vstack(
        [
            np.column_stack([left, z_bottom]),
            np.column_stack([right, z_bottom]),
            np.column_stack([left, z_top]),
            np.column_stack([right, z_top]),
        ]
    )
    lb, rb, lt, rt = 0, n, 2 * n, 3 * n
    faces: list[tuple[int, ...]] = []
    for i in range(n - 1):
        j = i + 1
        faces.append((lt + i, rt + i, rt + j, lt + j))  # top, +z
        faces.append((lb + i, lb + j, rb + j, rb + i))  # bottom, -z
        faces.append((lb + i, lt + i, lt + j, lb + j))  # left side
        faces.append((rb + i, rb + j, rt + j, rt + i))  # right side
    faces.append((lb, rb, rt, lt))  # start cap
    e = n - 1
    faces.append((lb + e, lt + e, rt + e, rb + e))  # end cap
    return verts, faces


def _subdivide_on_sphere(
    pts: list[np.ndarray], faces: list[tuple[int, int, int]]
) -> list[tuple[int, int, int]]:
    """Split each triangle in four; new unit-sphere vertices are appended to pts."""
    cache: dict[tuple[int, int], int] = {}

    def midpoint(a: int, b: int) -> int:
        key = (min(a, b), max(a, b))
        if key not in cache:
            m = pts[a] + pts[b]
            pts.append(m / np.linalg.norm(m))
            cache[key] = len(pts) - 1
        return cache[key]

    out = []
    for a, b, c in faces:
        ab, bc, ca = midpoint(a, b), midpoint(b, c), midpoint(c, a)
        out += [(a, ab, ca), (b, bc, ab), (c, ca, bc), (ab, bc, ca)]
    return out


def _icosphere(
    centre: Sequence[float], radius: float, radius_z: float, subdivisions: int = 1
) -> tuple[np.ndarray, list[tuple[int, ...]]]:
    """Low-poly closed ellipsoid (icosphere) with outward normals.

    One subdivision gives 42 vertices and 80 triangles: round enough for a
    canopy shadow and cheap in the file.
    """
    g = (1.0 + 5.0**0.5) / 2.0
    verts = [
        (-1, g, 0), (1, g, 0), (-1, -g, 0), (1, -g, 0),
        (0, -1, g), (0, 1, g), (0, -1, -g), (0, 1, -g),
        (g, 0, -1), (g, 0, 1), (-g, 0, -1), (-g, 0, 1),
    ]  # fmt: skip
    faces = [
        (0, 11, 5), (0, 5, 1), (0, 1, 7), (0, 7, 10), (0, 10, 11),
        (1, 5, 9), (5, 11, 4), (11, 10, 2), (10, 7, 6), (7, 1, 8),
        (3, 9, 4), (3, 4, 2), (3, 2, 6), (3, 6, 8), (3, 8, 9),
        (4, 9, 5), (2, 4, 11), (6, 2, 10), (8, 6, 7), (9, 8, 1),
    ]  # fmt: skip
    pts = [np.array(v, dtype=float) / np.linalg.norm(v) for v in verts]
    for _ in range(subdivisions):
        faces = _subdivide_on_sphere(pts, faces)
    unit = np.array(pts)
    # The sphere is convex: orient each triangle so its normal points outwards.
    oriented = []
    for f in faces:
        a, b, c = unit[list(f)]
        outward = np.dot(np.cross(b - a, c - a), a + b + c) > 0.0
        oriented.append(f if outward else (f[0], f[2], f[1]))
    scaled = unit * np.array([radius, radius, radius_z]) + np.asarray(centre)
    return scaled, oriented


def _signed_volume(verts: np.ndarray, faces: Sequence[Sequence[int]]) -> float:
    """Enclosed volume [m^3] by the divergence theorem; > 0 for outward normals."""
    vol = 0.0
    for f in faces:
        a = verts[f[0]]
        for k in range(1, len(f) - 1):
            vol += float(np.dot(a, np.cross(verts[f[k]], verts[f[k + 1]])))
    return vol / 6.0


def _heightfield_arrays(
    xs: np.ndarray, ys: np.ndarray, height: HeightFn
) -> tuple[np.ndarray, np.ndarray]:
    """Grid vertices (nx*ny, 3) and upward-facing quads (m, 4) of a heightfield."""
    gx, gy = np.meshgrid(xs, ys)  # row index = y, column index = x
    verts = np.column_stack([gx.ravel(), gy.ravel(), height(gx, gy).ravel()])
    idx = np.arange(len(xs) * len(ys)).reshape(len(ys), len(xs))
    # (x, y) -> (x+1, y) -> (x+1, y+1) -> (x, y+1) is CCW from above: normal +z.
    faces = np.column_stack(
        [
            idx[:-1, :-1].ravel(),
            idx[:-1, 1:].ravel(),
            idx[1:, 1:].ravel(),
            idx[1:, :-1].ravel(),
        ]
    )
    return verts, faces


# ================================================================================
# Blender objects
# ================================================================================


def _reset() -> None:
    """Start from an empty factory scene (no objects, default metric units)."""
    bpy.ops.wm.read_factory_settings(use_empty=True)


def _collection(name: str) -> bpy.types.Collection:
    """Create a collection linked to the scene's master collection."""
    col = bpy.data.collections.new(name)
    bpy.context.scene.collection.children.link(col)
    return col


def _add_mesh(
    name: str,
    verts: np.ndarray,
    faces: Sequence[Sequence[int]] | np.ndarray,
    collection: bpy.types.Collection,
) -> bpy.types.Object:
    """Mesh object with world-space ``verts`` [m] and identity transform."""
    mesh = bpy.data.meshes.new(name)
    mesh.from_pydata(np.asarray(verts, dtype=float).tolist(), [], [list(f) for f in faces])
    if mesh.validate():
        raise ValueError(f"mesh {name!r} needed repairs: builder bug")
    mesh.update()
    obj = bpy.data.objects.new(name, mesh)
    collection.objects.link(obj)
    return obj


def _add_closed_mesh(
    name: str,
    mesh_data: tuple[np.ndarray, Sequence[Sequence[int]]],
    collection: bpy.types.Collection,
) -> bpy.types.Object:
    """Like :func:`_add_mesh` for a watertight solid; flips inside-out input."""
    verts, faces = mesh_data
    if _signed_volume(verts, faces) < 0.0:
        faces = [tuple(reversed(f)) for f in faces]
    return _add_mesh(name, verts, faces, collection)


def _add_area_curve(
    name: str,
    rings: Sequence[np.ndarray],
    z: float,
    collection: bpy.types.Collection,
) -> bpy.types.Object:
    """CURVE object with one closed POLY spline per XY ring [m].

    The points lie at local z = 0 and the object sits at height ``z`` [m] so it
    floats just above the terrain in the viewport; only XY carries meaning.
    """
    curve = bpy.data.curves.new(name, "CURVE")
    # 3D, no bevel: a 2D curve would be filled, and the fill would evaluate to
    # faces that a scene ray cast could mistake for an occluder.
    curve.dimensions = "3D"
    for ring in rings:
        ring = np.asarray(ring, dtype=float)
        if np.allclose(ring[0], ring[-1]):
            ring = ring[:-1]  # shapely repeats the first point; Blender closes itself
        spline = curve.splines.new("POLY")
        spline.points.add(len(ring) - 1)
        co = np.column_stack([ring, np.zeros(len(ring)), np.ones(len(ring))])
        spline.points.foreach_set("co", co.ravel())
        spline.use_cyclic_u = True
    obj = bpy.data.objects.new(name, curve)
    obj.location = (0.0, 0.0, z)
    collection.objects.link(obj)
    return obj


def _polygon_rings(poly: Polygon) -> list[np.ndarray]:
    """Exterior and hole rings of a polygon as (n, 2) arrays (even-odd input)."""
    return [np.asarray(poly.exterior.coords)] + [np.asarray(r.coords) for r in poly.interiors]


def _add_heightfield(
    name: str,
    xs: np.ndarray,
    ys: np.ndarray,
    height: HeightFn,
    collection: bpy.types.Collection,
) -> bpy.types.Object:
    """Terrain: one open grid mesh over the rectilinear grid ``xs`` x ``ys`` [m]."""
    verts, faces = _heightfield_arrays(xs, ys, height)
    return _add_mesh(name, verts, faces, collection)


def _add_box(
    name: str,
    corners: np.ndarray,
    z_bottom: float,
    z_top: float,
    collection: bpy.types.Collection,
) -> bpy.types.Object:
    """Box (8 vertices, 6 quads) over a 4-corner XY footprint [m]."""
    return _add_closed_mesh(name, _prism(corners, z_bottom, z_top), collection)


def _add_tree(prefix: str, tree: _Tree, height: HeightFn, collection: bpy.types.Collection) -> None:
    """Trunk (hexagonal prism, 0.4 m across) and canopy (icosphere) on the terrain."""
    ground = float(height(np.array(tree.x), np.array(tree.y)))
    ang = np.arange(6) * (math.pi / 3.0)
    ring = np.column_stack([tree.x + 0.2 * np.cos(ang), tree.y + 0.2 * np.sin(ang)])
    # Sink the trunk 0.3 m so no sliver of light passes under it on a slope.
    trunk = _prism(ring, ground - 0.3, ground + tree.trunk_height)
    _add_closed_mesh(f"{prefix}_Trunk", trunk, collection)
    centre = (tree.x, tree.y, ground + tree.canopy_z)
    canopy = _icosphere(centre, tree.radius, tree.radius_z)
    _add_closed_mesh(f"{prefix}_Canopy", canopy, collection)


def _footprint_heights(height: HeightFn, ring: np.ndarray) -> np.ndarray:
    """Terrain z [m] sampled over a footprint: its corners and a 2 m interior grid."""
    poly = Polygon(ring)
    x0, y0, x1, y1 = poly.bounds
    gx, gy = np.meshgrid(np.arange(x0, x1 + 2.0, 2.0), np.arange(y0, y1 + 2.0, 2.0))
    inside = shapely.contains_xy(poly, gx.ravel(), gy.ravel())
    xs = np.concatenate([ring[:, 0], gx.ravel()[inside]])
    ys = np.concatenate([ring[:, 1], gy.ravel()[inside]])
    return height(xs, ys)


def _add_layout_objects(
    layout: _Layout,
    height: HeightFn,
    tag: str,
    area_z: float,
    env: bpy.types.Collection,
    areas: bpy.types.Collection,
) -> None:
    """Create all objects of one section. ``tag`` ("" or "T03") goes into names."""
    pre = f"_{tag}" if tag else ""
    for route, poly in sorted(layout.targets.items()):
        _add_area_curve(f"Target{pre}_Route{route}", _polygon_rings(poly), area_z, areas)
    for i, (poly, h) in enumerate(
        zip(layout.sensor_areas, layout.sensor_heights, strict=True), start=1
    ):
        obj = _add_area_curve(f"SensorArea{pre}_{i}", _polygon_rings(poly), area_z, areas)
        if h is not None:
            obj["height_m"] = float(h)
    for i, (corners, h) in enumerate(layout.buildings, start=1):
        z = _footprint_heights(height, corners)
        # Base 0.5 m below the lowest ground point: no gap on a slope.
        _add_box(f"Building{pre}_{i}", corners, z.min() - 0.5, z.mean() + h, env)
    ground = height(layout.wall[:, 0], layout.wall[:, 1])
    wall = _ribbon_wall(layout.wall, 0.3, ground - 0.4, ground + 3.0)
    _add_closed_mesh(f"Wall{pre}_NarrowPoint", wall, env)
    for i, tree in enumerate(layout.trees, start=1):
        _add_tree(f"Tree{pre}_{i:02d}", tree, height, env)


def _frame_viewports(centre: tuple[float, float, float], size: float) -> None:
    """Aim the stored 3D views at the scene so a person opening the file sees it."""
    for screen in bpy.data.screens:
        for area in screen.areas:
            for space in area.spaces:
                if space.type != "VIEW_3D":
                    continue
                space.clip_start = 0.1
                space.clip_end = max(1000.0, 4.0 * size)
                space.region_3d.view_location = centre
                space.region_3d.view_distance = 1.2 * size


def _save(path: pathlib.Path) -> pathlib.Path:
    """Save the current file compressed (zstd) and return its path."""
    path.parent.mkdir(parents=True, exist_ok=True)
    bpy.context.preferences.filepaths.save_version = 0  # no .blend1 backups
    bpy.ops.wm.save_as_mainfile(filepath=str(path), compress=True)
    return path


# ================================================================================
# Scenes
# ================================================================================


def build_flat_wall(out_dir: pathlib.Path = SAMPLE_DIR) -> pathlib.Path:
    """``flat_wall.blend``: one wall on flat ground, small enough to check by hand.

    * ``Ground``: the plane z = 0 over x, y in [-60, 60] m (a single quad);
    * ``Target_Area``: the rectangle x in [0, 50], y in [-25, 25] m;
    * ``SensorArea_1``: the rectangle x in [-12, -4], y in [-4, 4] m;
    * ``Wall``: the box x in [10.0, 10.3], y in [-2, 8], z in [0, 3] m.

    The numbers are the module constants ``FLAT_*``; tests derive the analytic
    shadow of the wall from them.
    """
    _reset()
    env, areas = _collection("Environment"), _collection("Areas")
    g = FLAT_GROUND_HALF
    ground = np.array([[-g, -g, 0.0], [g, -g, 0.0], [g, g, 0.0], [-g, g, 0.0]])
    _add_mesh("Ground", ground, [(0, 1, 2, 3)], env)
    x0, y0, z0, x1, y1, z1 = FLAT_WALL_BOX
    wall = np.array([[x0, y0], [x1, y0], [x1, y1], [x0, y1]])
    _add_box("Wall", wall, z0, z1, env)
    for name, (ax, ay, bx, by) in (
        ("Target_Area", FLAT_TARGET_RECT),
        ("SensorArea_1", FLAT_SENSOR_RECT),
    ):
        ring = np.array([[ax, ay], [bx, ay], [bx, by], [ax, by]])
        _add_area_curve(name, [ring], 0.05, areas)
    _frame_viewports((10.0, 0.0, 0.0), 2.0 * g)
    return _save(out_dir / "flat_wall.blend")


def build_two_routes(out_dir: pathlib.Path = SAMPLE_DIR) -> pathlib.Path:
    """``two_routes.blend``: a 250 m x 250 m proving-ground section.

    Layout (x, y in [0, 250] m; terrain over [-100, 350] m on a 2.5 m grid inside
    the section and 10 m outside; relief from -3 m to +6 m: a hill north of the
    loop, a dip in B's southern corridor, a knoll in B's west hairpin):

    * ``Target_RouteA``: a 14 m wide closed handling loop in the north
      (x 11..237, y 152..217, centreline 457 m), outer plus inner ring; its
      infield is ~29 m wide;
    * ``Target_RouteB``: a 14 m wide serpentine (centreline 747 m) with three
      east-west legs at y ~ 132, 93, 53 joined by an east and a west hairpin,
      entering at the west edge and leaving at the east edge;
    * the narrow point: at x ~ 140, B rises and A dips until their edges are
      7.9 m apart; ``Wall_NarrowPoint`` (0.3 m thick, 3 m above the ground,
      ~50 m long) follows the middle of that gap;
    * ``SensorArea_1..6``: 55 m x 8 m strips 4 m off a road edge (2,655 m^2 in
      all): two in A's infield and two in each of B's corridors, so each sees
      two road stretches; ``SensorArea_4`` has ``height_m`` 10, ``SensorArea_6``
      has 5, the others none (the tool's default mast height applies);
    * ``Building_1..4`` (7-12 m tall) in A's infield, in both B corridors and
      west of the narrow point, and 24 trees (``Tree_NN_Trunk`` and
      ``Tree_NN_Canopy``) beside the roads.

    Measured total target area (union of both routes): 16,556 m^2 (A 6,392 m^2,
    B 10,164 m^2). From masts 7 m (or ``height_m``) above the sensor areas, 97 %
    of the road lies within 40 m of an area and ~96 % is also in line of sight;
    the rest is behind the buildings and on A's south straight by the wall.
    """
    _reset()
    env, areas = _collection("Environment"), _collection("Areas")
    layout = _two_routes_layout()
    _place_trees(layout, np.random.default_rng(_TREE_SEED), 24)
    _check_layout(layout)
    height = _gaussian_relief(np.array(_TWO_ROUTES_BUMPS))
    axis = _axis(-TERRAIN_MARGIN, TILE_SIZE + TERRAIN_MARGIN, (0.0, TILE_SIZE), 2.5, 10.0)
    terrain = _add_heightfield("Terrain", axis, axis, height, env)
    area_z = _max_z(terrain) + 1.0
    _add_layout_objects(layout, height, "", area_z, env, areas)
    c = TILE_SIZE / 2.0
    _frame_viewports((c, c, 0.0), TILE_SIZE)
    return _save(out_dir / "two_routes.blend")


# Tile variants of full_ground, row-major from the south-west corner:
# (quarter turns, mirror) so neighbouring tiles differ.
_FULL_GROUND_TILES = (
    (0, False), (1, True), (2, False),
    (3, True), (2, True), (0, True),
    (1, False), (3, False), (0, False),
    (2, True), (1, True), (3, False),
)  # fmt: skip
_FULL_GROUND_COLS = 3


def build_full_ground(out_dir: pathlib.Path = SAMPLE_DIR) -> pathlib.Path:
    """``full_ground.blend``: twelve two_routes sections for scaling work.

    Tiles ``T01..T12`` are laid out 3 columns x 4 rows at a 260 m pitch (x in
    [0, 770], y in [0, 1030] m), each mirrored and/or rotated by quarter turns
    and with its own tree seed. Object names carry the tile tag, e.g.
    ``Target_T03_RouteA``, ``SensorArea_T03_2``, ``Tree_T03_05_Canopy``. One
    terrain heightfield (5 m grid inside, 10 m in the 100 m margin) with random
    relief (seeded Gaussians, about -2.5..+6 m) lies under everything.

    Measured total target area: 198,673 m^2, 12 x that of two_routes (the tiles
    are copies of its roads and do not touch each other).
    """
    _reset()
    env, areas = _collection("Environment"), _collection("Areas")
    rows = math.ceil(len(_FULL_GROUND_TILES) / _FULL_GROUND_COLS)
    width = _FULL_GROUND_COLS * TILE_PITCH - (TILE_PITCH - TILE_SIZE)
    depth = rows * TILE_PITCH - (TILE_PITCH - TILE_SIZE)
    height = _gaussian_relief(_random_bumps(width, depth, 30))
    m = TERRAIN_MARGIN
    xs = _axis(-m, width + m, (0.0, width), 5.0, 10.0)
    ys = _axis(-m, depth + m, (0.0, depth), 5.0, 10.0)
    terrain = _add_heightfield("Terrain", xs, ys, height, env)
    area_z = _max_z(terrain) + 1.0
    base = _two_routes_layout()
    for i, (turns, mirror) in enumerate(_FULL_GROUND_TILES):
        row, col = divmod(i, _FULL_GROUND_COLS)
        origin = (col * TILE_PITCH, row * TILE_PITCH)
        layout = _transform_layout(base, _tile_transform(turns, mirror, origin))
        rng = np.random.default_rng(_TREE_SEED + 1 + i)
        _place_trees(layout, rng, int(rng.integers(18, 27)))
        _check_layout(layout)
        _add_layout_objects(layout, height, f"T{i + 1:02d}", area_z, env, areas)
    _frame_viewports((width / 2.0, depth / 2.0, 0.0), max(width, depth))
    return _save(out_dir / "full_ground.blend")


def _random_bumps(width: float, depth: float, count: int) -> np.ndarray:
    """Seeded Gaussian bumps (x0, y0, amplitude, sigma) [m] over a ground.

    Sigmas of 35-70 m keep slopes around 10 % at most: rolling land, no cliffs.
    """
    rng = np.random.default_rng(_TERRAIN_SEED)
    return np.column_stack(
        [
            rng.uniform(-50.0, width + 50.0, count),
            rng.uniform(-50.0, depth + 50.0, count),
            rng.uniform(-3.0, 6.0, count),
            rng.uniform(35.0, 70.0, count),
        ]
    )


def _max_z(obj: bpy.types.Object) -> float:
    """Highest vertex z [m] of a mesh object (identity transform assumed)."""
    co = np.empty(len(obj.data.vertices) * 3)
    obj.data.vertices.foreach_get("co", co)
    return float(co[2::3].max())


def build_all(out_dir: pathlib.Path) -> list[pathlib.Path]:
    """Rebuild every sample scene into out_dir (created if needed).

    Returns the paths written: flat_wall, two_routes, full_ground.
    """
    out_dir = pathlib.Path(out_dir)
    out_dir.mkdir(parents=True, exist_ok=True)
    return [build(out_dir) for build in (build_flat_wall, build_two_routes, build_full_ground)]
