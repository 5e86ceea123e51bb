"""From parsed roads to what a scene needs: road meshes, target and sensor-area rings.

Sampling rule (along s, per lane section, both ends of every section included):
every start of a geometry, lane section, width/border record, laneOffset, elevation
and superelevation record is a station; between two stations the step is the
largest that keeps

- the heading turn per step at most ``MAX_TURN`` = 0.05 rad (a chord polygon of an
  arc, at any lateral offset, then has sin(d)/d - 1 < 0.05 % of the area),
- the chord error of every cubic profile (lateral borders from widths and laneOffset,
  elevation, superelevation times the road's half width), bounded by
  |f''| * h^2 / 8 from the records' coefficients, at most ``CHORD_TOL`` = 5 mm,
- and the step at most ``MAX_STEP`` = 20 m,

so the plan-area error of a lane is a few hundredths of a per cent.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass, field

import numpy as np
import shapely
from numpy.typing import NDArray
from shapely.geometry import MultiPolygon, Polygon
from shapely.geometry.base import BaseGeometry

from ...core.errors import InputError
from .geometry import (
    ReferenceLine,
    eval_polys,
    second_derivative_bound,
    section_borders,
)
from .parse import LaneSection, OpenDriveNetwork, Road

F64 = NDArray[np.float64]

LANE_TYPES = (
    "driving", "stop", "shoulder", "biking", "sidewalk", "border", "restricted",
    "parking", "bidirectional", "median", "special1", "special2", "special3",
    "roadWorks", "tram", "rail", "entry", "exit", "offRamp", "onRamp",
    "connectingRamp", "bus", "taxi", "HOV", "mwyEntry", "mwyExit", "none",
)  # fmt: skip
_CANONICAL = {t.lower(): t for t in LANE_TYPES}

MAX_TURN = 0.05  # rad per sampling step
CHORD_TOL = 0.005  # m, chord error of a cubic profile per step
MAX_STEP = 20.0  # m
NEGATIVE_WIDTH_TOL = 1e-3  # m: widths above -1 mm count as zero (rounding in files)
SHIFT_BEYOND_M = 10_000.0
GROUND_MARGIN_M = 20.0
GROUND_BELOW_M = 0.05
MIN_SENSOR_PART_M2 = 1.0
MIN_TARGET_PART_M2 = 0.01  # slivers from section seams in unions


@dataclass(frozen=True)
class SurfaceMesh:
    name: str
    road_id: str | None
    vertices: NDArray[np.float64]  # (V, 3)
    faces: NDArray[np.int32]  # (F, 3), counter-clockwise seen from above


@dataclass(frozen=True)
class AreaRings:
    name: str
    road_id: str
    lane_types: tuple[str, ...]
    rings: list[NDArray[np.float64]]  # (K, 3) each, closed implicitly, even-odd fill
    area_m2: float


@dataclass(frozen=True)
class ImportedNetwork:
    surfaces: list[SurfaceMesh]
    ground: SurfaceMesh | None
    targets: list[AreaRings]
    sensor_areas: list[AreaRings]
    shift: NDArray[np.float64]
    crs: str | None
    crs_offset: tuple[float, float, float, float]
    warnings: list[str] = field(default_factory=list)
    lane_area_m2: dict[str, float] = field(default_factory=dict)


@dataclass
class _Edge:
    """The outermost surface border of one side of one lane section."""

    side: int
    xy: F64  # (N, 2) plan points
    normal: F64  # (N, 2) unit left normals
    z: F64  # (N,)


@dataclass
class _RoadParts:
    road_id: str
    vertices: F64
    faces: NDArray[np.int32]
    lanes: list[tuple[str, Polygon | MultiPolygon]] = field(default_factory=list)
    edges: list[_Edge] = field(default_factory=list)


def _section_ends(road: Road) -> list[tuple[LaneSection, float, float]]:
    out = []
    for k, sec in enumerate(road.sections):
        end = road.sections[k + 1].s if k + 1 < len(road.sections) else road.length
        end = min(end, road.length)
        if end - sec.s > 1e-6:
            out.append((sec, sec.s, end))
    return out


def _stations(road: Road, ref: ReferenceLine, sec: LaneSection, s0: float, s1: float) -> F64:
    """Sample positions along s in [s0, s1] by the rule in the module docstring."""
    marks = {s0, s1}
    marks |= {g.s for g in road.geometries}
    marks |= {r.s for r in (*road.lane_offsets, *road.elevation, *road.superelevation)}
    for lane in (*sec.left, *sec.right):
        marks |= {sec.s + r.s for r in (*lane.widths, *lane.borders)}
    cuts = np.array(sorted(m for m in marks if s0 <= m <= s1))
    cuts = cuts[np.concatenate([[True], np.diff(cuts) > 1e-9])]
    if cuts[-1] < s1 - 1e-9:
        cuts = np.append(cuts, s1)
    else:
        cuts[-1] = s1
    pieces = [cuts[:1]]
    for a, b in zip(cuts[:-1], cuts[1:], strict=True):
        length = b - a
        m = int(np.clip(np.ceil(length / 0.5), 8, 4000))
        grid = np.linspace(a, b, m + 1)
        turn = float(np.abs(np.diff(np.unwrap(ref.evaluate(grid)[2]))).sum())
        borders, _ = section_borders(road, sec, np.array([a, b]))
        half = max(float(np.abs(v).max()) for v in borders.values()) + 1.0
        bound = second_derivative_bound(road.lane_offsets, a, b, 0.0)
        bound += second_derivative_bound(road.elevation, a, b, 0.0)
        bound += half * second_derivative_bound(road.superelevation, a, b, 0.0)
        for lane in (*sec.left, *sec.right):
            bound += second_derivative_bound(lane.widths or lane.borders, a, b, sec.s)
        n = max(1, math.ceil(length / MAX_STEP), math.ceil(turn / MAX_TURN))
        if bound > 0:
            n = max(n, math.ceil(length / math.sqrt(8.0 * CHORD_TOL / bound)))
        pieces.append(np.linspace(a, b, n + 1)[1:])
    return np.concatenate(pieces)


def _polygonal(geom: BaseGeometry) -> Polygon | MultiPolygon:
    """The polygonal part of a geometry (make_valid may add lines and points)."""
    if isinstance(geom, Polygon | MultiPolygon):
        return geom
    parts = [g for g in getattr(geom, "geoms", []) if isinstance(g, Polygon | MultiPolygon)]
    if not parts:
        return Polygon()
    merged = shapely.union_all(parts)
    return merged if isinstance(merged, Polygon | MultiPolygon) else Polygon()


def _ring_polygon(ring: F64) -> Polygon | MultiPolygon:
    poly = Polygon(ring)
    if not poly.is_valid:
        return _polygonal(shapely.make_valid(poly))
    return poly


def _point(frame: tuple[F64, F64, F64, F64, F64, F64], t: F64) -> F64:
    """3D points at lateral t: t*cos(phi) along the plan normal, elev + t*sin(phi) up."""
    x, y, normal, elev, cphi, sphi = frame
    return np.column_stack(
        [x + normal[:, 0] * t * cphi, y + normal[:, 1] * t * cphi, elev + t * sphi]
    )


def _build_road(road: Road, warnings: list[str]) -> _RoadParts | None:
    rid = road.id
    if not road.sections:
        warnings.append(f"road {rid}: no lane section; road skipped")
        return None
    ref = ReferenceLine(road.geometries)
    verts: list[F64] = []
    faces: list[NDArray[np.int64]] = []
    parts = _RoadParts(rid, np.zeros((0, 3)), np.zeros((0, 3), dtype=np.int32))
    n_verts = 0
    for sec, s0, s1 in _section_ends(road):
        s = _stations(road, ref, sec, s0, s1)
        x, y, h = ref.evaluate(s)
        if not (np.isfinite(x).all() and np.isfinite(y).all()):
            warnings.append(f"road {rid}: the reference line is not finite; road skipped")
            return None
        borders, faults = section_borders(road, sec, s)
        if faults:
            lane_id, why = next(iter(faults.items()))
            warnings.append(
                f"road {rid}: lane {lane_id} in the lane section at s={s0:g} {why}; road skipped"
            )
            return None
        elev = eval_polys(road.elevation, s)
        phi = eval_polys(road.superelevation, s)
        normal = np.column_stack([-np.sin(h), np.cos(h)])
        cphi, sphi = np.cos(phi), np.sin(phi)

        frame = (x, y, normal, elev, cphi, sphi)

        columns: dict[int, int] = {}  # border id -> first vertex index of its column
        outermost = {1: 0, -1: 0}
        n = len(s)
        for lane in (*sec.left, *sec.right):
            side = 1 if lane.id > 0 else -1
            inner_id = lane.id - side
            width = side * (borders[lane.id] - borders[inner_id])
            if lane.type.lower() == "none" or float(width.max()) <= 1e-9:
                continue
            if float(width.min()) < -NEGATIVE_WIDTH_TOL:
                k = int(width.argmin())
                warnings.append(
                    f"road {rid}: lane {lane.id} in the lane section at s={s0:g} has a "
                    f"negative width ({width[k]:.3g} m at s={s[k]:.4g}); lane skipped"
                )
                continue
            for bid in (inner_id, lane.id):
                if bid not in columns:
                    columns[bid] = n_verts
                    verts.append(_point(frame, borders[bid]))
                    n_verts += n
            if abs(lane.id) > abs(outermost[side]):
                outermost[side] = lane.id
            right, left = (inner_id, lane.id) if side > 0 else (lane.id, inner_id)
            a = columns[right] + np.arange(n - 1)
            d = columns[left] + np.arange(n - 1)
            tris = np.concatenate(
                [np.column_stack([a, a + 1, d + 1]), np.column_stack([a, d + 1, d])]
            )
            faces.append(tris)
            rpts = _point(frame, borders[right])[:, :2]
            lpts = _point(frame, borders[left])[:, :2]
            ring = np.concatenate([rpts, lpts[::-1]])
            parts.lanes.append((lane.type, _ring_polygon(ring)))
        if not columns:
            continue
        for side, bid in outermost.items():
            edge = _point(frame, borders[bid])
            parts.edges.append(_Edge(side, edge[:, :2], normal, edge[:, 2]))
    if not verts:
        return parts
    vertices = np.concatenate(verts)
    tri = np.concatenate(faces)
    p = vertices[tri][:, :, :2]
    area2: F64 = (p[:, 1, 0] - p[:, 0, 0]) * (p[:, 2, 1] - p[:, 0, 1]) - (
        p[:, 2, 0] - p[:, 0, 0]
    ) * (p[:, 1, 1] - p[:, 0, 1])
    parts.vertices = vertices
    parts.faces = tri[area2 > 1e-10].astype(np.int32)
    return parts


# 2^-9 m (about 2 mm): multiples of it below 2^14 m (16 km, beyond the 10 km at which
# the import shifts coordinates) are exact in float32's 24-bit mantissa.
FLOAT32_GRID_M = 2.0**-9


def _clean(geom: BaseGeometry, min_part: float, min_hole: float) -> Polygon | MultiPolygon:
    """Valid polygons without parts under ``min_part`` or holes under ``min_hole`` m^2."""
    geom = _polygonal(geom if geom.is_valid else shapely.make_valid(geom))
    polys = list(geom.geoms) if isinstance(geom, MultiPolygon) else [geom]
    kept = []
    for poly in polys:
        if poly.is_empty or poly.area < min_part:
            continue
        holes = [r for r in poly.interiors if Polygon(r).area >= min_hole]
        kept.append(Polygon(poly.exterior, holes))
    if not kept:
        return Polygon()
    # Snapped to a grid that float32 holds exactly (Blender keeps curve points in
    # float32): a ring simple in float64 may otherwise touch itself once rounded.
    out = shapely.set_precision(shapely.union_all(kept), FLOAT32_GRID_M)
    return _polygonal(out)


def _rings(geom: Polygon | MultiPolygon) -> list[F64]:
    """Exteriors counter-clockwise, holes clockwise; first point not repeated."""
    polys = list(geom.geoms) if isinstance(geom, MultiPolygon) else [geom]
    out = []
    for poly in polys:
        if poly.is_empty:
            continue
        poly = shapely.geometry.polygon.orient(poly, 1.0)
        for ring in (poly.exterior, *poly.interiors):
            pts = np.asarray(ring.coords)[:-1, :2]
            if len(pts) >= 3:
                out.append(pts)
    return out


def _surface_z(vertices: F64, faces: NDArray[np.int32], pts: F64) -> F64:
    """Height of the mesh at plan points (the nearest triangle, barycentric)."""
    tri = vertices[faces]
    tree = shapely.STRtree(shapely.polygons(tri[:, :, :2]))
    hit = tree.query_nearest(shapely.points(pts), all_matches=False)
    idx = np.empty(len(pts), dtype=np.int64)
    idx[hit[0]] = hit[1]
    t = tri[idx]
    a, b, c = t[:, 0, :2], t[:, 1, :2], t[:, 2, :2]
    v0, v1, v2 = b - a, c - a, pts - a
    den = v0[:, 0] * v1[:, 1] - v1[:, 0] * v0[:, 1]
    den = np.where(np.abs(den) < 1e-15, 1e-15, den)
    l1 = (v2[:, 0] * v1[:, 1] - v1[:, 0] * v2[:, 1]) / den
    l2 = (v0[:, 0] * v2[:, 1] - v2[:, 0] * v0[:, 1]) / den
    lam = np.clip(np.column_stack([1.0 - l1 - l2, l1, l2]), 0.0, None)
    lam /= np.maximum(lam.sum(axis=1, keepdims=True), 1e-15)
    out: F64 = (lam * t[:, :, 2]).sum(axis=1)
    return out


def _band(parts: _RoadParts, inner: float, outer: float) -> BaseGeometry:
    strips = []
    for e in parts.edges:
        if len(e.xy) < 2:
            continue
        off = e.side * e.normal
        near = e.xy + off * inner
        far = e.xy + off * outer
        strips.append(_ring_polygon(np.concatenate([near, far[::-1]])))
    return shapely.union_all(strips) if strips else Polygon()


def _lane_types(lane_types: Sequence[str]) -> tuple[str, ...]:
    if isinstance(lane_types, str):
        lane_types = [lane_types]
    out: list[str] = []
    for name in lane_types:
        canon = _CANONICAL.get(str(name).strip().lower())
        if canon is None:
            raise InputError(
                f"lane type {name!r} is not an OpenDRIVE lane type "
                f"(one of: {', '.join(LANE_TYPES)})"
            )
        if canon not in out:
            out.append(canon)
    if not out:
        raise InputError("no lane type chosen")
    return tuple(out)


def build_import(
    network: OpenDriveNetwork,
    lane_types: Sequence[str] = ("driving",),
    band: tuple[float, float] = (1.0, 6.0),
    terrain: str = "flat",
) -> ImportedNetwork:
    """Road meshes, targets (chosen lane types) and sensor-area bands of a network."""
    types = _lane_types(lane_types)
    try:
        inner, outer = float(band[0]), float(band[1])
    except (TypeError, ValueError, IndexError):
        raise InputError(f"band {band!r}: give two distances in metres, INNER:OUTER") from None
    if not (math.isfinite(inner) and math.isfinite(outer)) or inner < 0 or outer <= inner:
        raise InputError(
            f"band {inner:g}:{outer:g}: needs 0 <= inner < outer (metres outside the road)"
        )
    if terrain not in ("flat", "none"):
        raise InputError(f"terrain {terrain!r}: must be 'flat' or 'none'")
    wanted = {t.lower() for t in types}
    present = {
        ln.type for r in network.roads for sec in r.sections for ln in (*sec.left, *sec.right)
    }
    if not any(t.lower() in wanted for t in present):
        have = ", ".join(sorted(present)) or "no lanes"
        raise InputError(
            f"{network.path}: no lane of type {', '.join(types)} (the file has: {have})"
        )

    warnings = list(network.warnings)
    built: list[_RoadParts] = []
    for road in network.roads:
        parts = _build_road(road, warnings)
        if parts is not None and len(parts.faces):
            built.append(parts)
    if not built:
        raise InputError(f"{network.path}: no road could be built")

    # Shift far-away coordinates (georeferenced files) near the origin.
    all_xy = np.concatenate([p.vertices[:, :2] for p in built])
    lo, hi = all_xy.min(axis=0), all_xy.max(axis=0)
    shift = np.zeros(3)
    corners = np.array([[lo[0], lo[1]], [lo[0], hi[1]], [hi[0], lo[1]], [hi[0], hi[1]]])
    if float(np.hypot(corners[:, 0], corners[:, 1]).max()) > SHIFT_BEYOND_M:
        shift[:2] = np.round((lo + hi) / 2.0 / 1000.0) * 1000.0
    sx, sy = float(shift[0]), float(shift[1])

    surfaces = [
        SurfaceMesh(f"Road_{p.road_id}", p.road_id, p.vertices - shift, p.faces) for p in built
    ]
    lane_area = {t: 0.0 for t in types}
    surface_polys: list[BaseGeometry] = []
    for p in built:
        for ltype, poly in p.lanes:
            surface_polys.append(poly)
            canon = _CANONICAL.get(ltype.lower())
            if canon in lane_area:
                lane_area[canon] += float(poly.area)
    surface_polys = [shapely.affinity.translate(g, -sx, -sy) for g in surface_polys]
    tree = shapely.STRtree(surface_polys)

    targets: list[AreaRings] = []
    for p in built:
        verts = p.vertices - shift
        for t in types:
            polys = [g for lt, g in p.lanes if lt.lower() == t.lower() and not g.is_empty]
            if not polys:
                continue
            union = shapely.affinity.translate(shapely.union_all(polys), -sx, -sy)
            region = _clean(union, MIN_TARGET_PART_M2, MIN_TARGET_PART_M2)
            rings2 = _rings(region)
            if not rings2:
                continue
            rings = [np.column_stack([r, _surface_z(verts, p.faces, r)]) for r in rings2]
            targets.append(
                AreaRings(f"Target_{t}_road{p.road_id}", p.road_id, (t,), rings, float(region.area))
            )

    z_min = float(min(s.vertices[:, 2].min() for s in surfaces))
    ground_z = z_min - GROUND_BELOW_M
    bands: list[tuple[_RoadParts, Polygon | MultiPolygon]] = []
    for p in built:
        raw = _band(p, inner, outer)
        if raw.is_empty:
            continue
        raw = shapely.affinity.translate(raw, -sx, -sy)
        near = tree.query(raw, predicate="intersects")
        if len(near):
            raw = raw.difference(shapely.union_all([surface_polys[int(k)] for k in near]))
        region = _clean(raw, MIN_SENSOR_PART_M2, MIN_TARGET_PART_M2)
        if not region.is_empty:
            bands.append((p, region))
    sensor_areas = []
    for p, region in bands:
        if terrain == "flat":
            z = ground_z
        else:
            z = float(np.mean(np.concatenate([e.z for e in p.edges]))) - float(shift[2])
        rings = [np.column_stack([r, np.full(len(r), z)]) for r in _rings(region)]
        sensor_areas.append(
            AreaRings(f"SensorArea_road{p.road_id}", p.road_id, (), rings, float(region.area))
        )

    ground = None
    if terrain == "flat":
        xy = [s.vertices[:, :2] for s in surfaces]
        xy += [np.asarray(b.bounds).reshape(2, 2) for _, b in bands]
        pts = np.concatenate(xy)
        (x0, y0), (x1, y1) = pts.min(axis=0) - GROUND_MARGIN_M, pts.max(axis=0) + GROUND_MARGIN_M
        gv = np.array(
            [[x0, y0, ground_z], [x1, y0, ground_z], [x1, y1, ground_z], [x0, y1, ground_z]]
        )
        ground = SurfaceMesh("Ground", None, gv, np.array([[0, 1, 2], [0, 2, 3]], dtype=np.int32))

    ox, oy, oz, oh = network.offset or (0.0, 0.0, 0.0, 0.0)
    c, s_ = math.cos(oh), math.sin(oh)
    crs_offset = (ox + c * sx - s_ * sy, oy + s_ * sx + c * sy, oz + float(shift[2]), oh)
    return ImportedNetwork(
        surfaces=surfaces,
        ground=ground,
        targets=targets,
        sensor_areas=sensor_areas,
        shift=shift,
        crs=network.geo_reference,
        crs_offset=crs_offset,
        warnings=warnings,
        lane_area_m2=lane_area,
    )
