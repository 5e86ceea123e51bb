"""The scene's georeference: world metres -> its projected CRS -> WGS84, and back.

A scene may name the projected CRS of its metres (``names.CRS_PROP``: a PROJ string,
"EPSG:nnnn" or WKT) and where it sits in it (``names.CRS_OFFSET_PROP`` = (x, y, z, h)).
A scene point p lies at

    (cos h * px - sin h * py + x,  sin h * px + cos h * py + y,  pz + z)

in the CRS: rotated by h about the scene origin, then shifted (OpenDRIVE's header
``<offset>``). ``Georef`` does that and its inverse, and the CRS <-> WGS84 longitude /
latitude step with pyproj (``always_xy``: easting, northing and longitude, latitude in
that order). Heights are not transformed: z stays the CRS's height (pz + z), which is
not a WGS84 ellipsoidal height, so the GeoJSON keeps positions 2D and z as a property.

``sensors_geojson_wgs84`` writes the RFC 7946 document (no ``crs`` member, exteriors
counter-clockwise, holes clockwise, 8 decimals: about 1 mm); ``uncovered_polygons``
gives the uncovered parts of the target as polygons, for the GeoPackage. Nothing here
needs Blender.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from functools import cached_property
from typing import Any

import numpy as np
import shapely
from numpy.typing import NDArray
from shapely.geometry.base import BaseGeometry

from ..core.errors import SceneContractError
from ..core.result import Result

F64 = NDArray[np.float64]

LONLAT_DECIMALS = 8
"""Decimals of longitude and latitude written: 1e-8 deg is 1.1 mm of latitude."""

MAX_OFFSET_M = 1.0e8
"""|x|, |y|, |z| of an offset beyond this are refused (no projected CRS reaches that)."""

NO_OFFSET: tuple[float, float, float, float] = (0.0, 0.0, 0.0, 0.0)


def _one_line(text: str) -> str:
    first = " ".join(str(text).split())
    return first if len(first) <= 160 else first[:157] + "..."


def check_crs(value: Any, where: str, prop: str) -> str | None:
    """The CRS text of a scene's custom property, checked with pyproj; None when the
    property is absent or blank. SceneContractError (one line, naming ``where`` and
    ``prop``) for anything else than a projected CRS in metres that PROJ knows."""
    from pyproj import CRS
    from pyproj.exceptions import CRSError

    if value is None:
        return None
    if not isinstance(value, str):
        raise SceneContractError(
            f"{where}: custom property {prop} must be a string (a PROJ string, "
            f"'EPSG:nnnn' or WKT), got {type(value).__name__}"
        )
    text = value.strip()
    if not text:
        return None
    shown = _one_line(text)
    try:
        crs = CRS.from_user_input(text)
    except CRSError as e:
        reason = _one_line(str(e).split(":")[-1] if ":" in str(e) else str(e))
        raise SceneContractError(
            f"{where}: custom property {prop} = {shown!r} is not a CRS PROJ knows ({reason})"
        ) from None
    if not crs.is_projected:
        raise SceneContractError(
            f"{where}: custom property {prop} = {shown!r} is not a projected CRS (the "
            "scene's metres need one, e.g. a UTM zone or '+proj=tmerc ...')"
        )
    units = {axis.unit_name for axis in crs.axis_info[:2]}
    if not units <= {"metre", "meter"}:
        raise SceneContractError(
            f"{where}: custom property {prop} = {shown!r} is in {', '.join(sorted(units))}, "
            "not metres"
        )
    return text


def check_offset(value: Any, where: str, prop: str) -> tuple[float, float, float, float]:
    """The (x, y, z, hdg) of a scene's custom property (default zeros), or a one-line
    SceneContractError naming ``where`` and ``prop``."""
    if value is None:
        return NO_OFFSET
    try:
        items = list(value)
    except TypeError:
        items = None
    ok = (
        items is not None
        and len(items) == 4
        and all(isinstance(v, (int, float)) and not isinstance(v, bool) for v in items)
    )
    if not ok:
        raise SceneContractError(
            f"{where}: custom property {prop} must be 4 numbers (x, y, z in metres, "
            f"heading in radians), got {_one_line(repr(value))}"
        )
    x, y, z, h = (float(v) for v in items)  # type: ignore[union-attr]
    if not all(math.isfinite(v) for v in (x, y, z, h)):
        raise SceneContractError(f"{where}: custom property {prop} has a value that is not finite")
    if max(abs(x), abs(y), abs(z)) > MAX_OFFSET_M:
        raise SceneContractError(
            f"{where}: custom property {prop} = ({x:g}, {y:g}, {z:g}, {h:g}) lies beyond "
            f"{MAX_OFFSET_M:g} m"
        )
    return (x, y, z, h)


@dataclass(frozen=True)
class Georef:
    """A scene's CRS (as its custom property gives it) and offset (x, y, z, hdg)."""

    crs: str
    offset: tuple[float, float, float, float] = NO_OFFSET

    @cached_property
    def _to_wgs84(self) -> Any:
        from pyproj import CRS, Transformer

        return Transformer.from_crs(CRS.from_user_input(self.crs), "EPSG:4326", always_xy=True)

    @cached_property
    def _from_wgs84(self) -> Any:
        from pyproj import CRS, Transformer

        return Transformer.from_crs("EPSG:4326", CRS.from_user_input(self.crs), always_xy=True)

    @property
    def pyproj_crs(self) -> Any:
        from pyproj import CRS

        return CRS.from_user_input(self.crs)

    def to_crs(self, xyz: F64) -> F64:
        """Scene world metres (N, 2 or 3) -> CRS coordinates (the offset convention)."""
        p = np.asarray(xyz, dtype=float)
        x, y, z, h = self.offset
        c, s = math.cos(h), math.sin(h)
        out = p.copy()
        out[..., 0] = c * p[..., 0] - s * p[..., 1] + x
        out[..., 1] = s * p[..., 0] + c * p[..., 1] + y
        if p.shape[-1] > 2:
            out[..., 2] = p[..., 2] + z
        return out

    def from_crs(self, xyz: F64) -> F64:
        """CRS coordinates (N, 2 or 3) -> scene world metres."""
        p = np.asarray(xyz, dtype=float)
        x, y, z, h = self.offset
        c, s = math.cos(h), math.sin(h)
        dx, dy = p[..., 0] - x, p[..., 1] - y
        out = p.copy()
        out[..., 0] = c * dx + s * dy
        out[..., 1] = -s * dx + c * dy
        if p.shape[-1] > 2:
            out[..., 2] = p[..., 2] - z
        return out

    def to_lonlat(self, xy: F64) -> F64:
        """Scene world metres (N, 2+) -> (N, 2) WGS84 longitude, latitude in degrees."""
        e = self.to_crs(np.asarray(xy, dtype=float)[..., :2])
        lon, lat = self._to_wgs84.transform(e[..., 0], e[..., 1], errcheck=True)
        return np.stack([np.asarray(lon, dtype=float), np.asarray(lat, dtype=float)], axis=-1)

    def from_lonlat(self, lonlat: F64) -> F64:
        """(N, 2) WGS84 longitude, latitude -> (N, 2) scene world metres."""
        q = np.asarray(lonlat, dtype=float)
        e, n = self._from_wgs84.transform(q[..., 0], q[..., 1], errcheck=True)
        crs = np.stack([np.asarray(e, dtype=float), np.asarray(n, dtype=float)], axis=-1)
        return self.from_crs(crs)

    def bearing_deg(self, x: float, y: float, yaw_deg: float) -> float:
        """Clockwise from true north, degrees in [0, 360): the direction of scene yaw
        ``yaw_deg`` (counter-clockwise from scene +X) at scene point (x, y)."""
        from pyproj import Geod

        d = math.radians(yaw_deg)
        a, b = self.to_lonlat(np.array([[x, y], [x + math.cos(d), y + math.sin(d)]]))
        azimuth, _, _ = Geod(ellps="WGS84").inv(a[0], a[1], b[0], b[1])
        return float(azimuth) % 360.0

    def geometry_to_lonlat(self, geom: BaseGeometry) -> BaseGeometry:
        """A 2D geometry in scene world metres in longitude, latitude (RFC 7946 ring
        orientation: exteriors counter-clockwise, holes clockwise)."""
        flat = shapely.force_2d(geom)
        out = shapely.transform(flat, lambda xy: self.to_lonlat(xy))
        return shapely.orient_polygons(out, exterior_cw=False)

    def geometry_to_crs(self, geom: BaseGeometry) -> BaseGeometry:
        """A 2D geometry in scene world metres in the CRS."""
        return shapely.transform(shapely.force_2d(geom), lambda xy: self.to_crs(xy))


def georef_of(result: Result) -> Georef | None:
    """The result's georeference, or None when its scene named no CRS."""
    if result.crs is None:
        return None
    return Georef(result.crs, result.crs_offset)


def _lonlat(point: F64) -> list[float]:
    return [round(float(v), LONLAT_DECIMALS) for v in point]


def _rounded(geom: BaseGeometry) -> BaseGeometry:
    """Longitude, latitude rounded to ``LONLAT_DECIMALS`` (orientation kept)."""
    return shapely.transform(geom, lambda xy: np.round(xy, LONLAT_DECIMALS))


def sensors_geojson_wgs84(result: Result, georef: Georef) -> dict[str, Any]:
    """sensors.geojson as RFC 7946 asks: masts and sensors as points, footprints as
    (multi)polygons, in WGS84 longitude, latitude; properties keep the scene's values
    (``scene_x``, ``scene_y``, ``scene_z``; footprint areas in scene m^2)."""
    features: list[dict[str, Any]] = []
    for m in result.masts:
        features.append(
            {
                "type": "Feature",
                "geometry": {
                    "type": "Point",
                    "coordinates": _lonlat(georef.to_lonlat(np.array([m.x, m.y]))),
                },
                "properties": {
                    "kind": "mast",
                    "mast": m.n,
                    "height_m": m.height_m,
                    "ground_z_m": round(m.z_ground + georef.offset[2], 4),
                    "sensors": list(m.sensors),
                    "existing": m.existing,
                    "scene_x": m.x,
                    "scene_y": m.y,
                    "scene_z": round(m.z_ground, 4),
                },
            }
        )
    for s in result.sensors:
        features.append(
            {
                "type": "Feature",
                "geometry": {
                    "type": "Point",
                    "coordinates": _lonlat(georef.to_lonlat(np.array([s.x, s.y]))),
                },
                "properties": {
                    "kind": "sensor",
                    "sensor": s.n,
                    "mast": s.mast + 1,
                    "height_m": s.height_m,
                    "z_m": round(s.z + georef.offset[2], 4),
                    "pitch_deg": round(s.pitch_deg, 3),
                    "yaw_deg": round(s.yaw_deg, 3),
                    "bearing_deg": round(georef.bearing_deg(s.x, s.y, s.yaw_deg), 3),
                    "existing": s.existing,
                    "model": s.model.to_dict(),
                    "scene_x": s.x,
                    "scene_y": s.y,
                    "scene_z": round(s.z, 4),
                },
            }
        )
    for s in result.sensors:
        if s.footprint.is_empty:
            continue
        local = shapely.set_precision(s.footprint, 0.01)
        geom = _rounded(georef.geometry_to_lonlat(local))
        features.append(
            {
                "type": "Feature",
                "geometry": shapely.geometry.mapping(geom),
                "properties": {
                    "kind": "footprint",
                    "sensor": s.n,
                    "mast": s.mast + 1,
                    "target_covered_m2": s.covered_target_m2,
                    "footprint_m2": round(s.footprint_m2, 2),
                },
            }
        )
    return {
        "type": "FeatureCollection",
        # A foreign member (RFC 7946 section 6.1): how to get back to the scene.
        "georeference": {"scene_crs": georef.crs, "scene_offset": list(georef.offset)},
        "features": features,
    }


def uncovered_polygons(result: Result) -> list[BaseGeometry]:
    """The uncovered parts of the target in scene world metres: the union of the
    uncovered target cells (squares of ``cell_m`` about each target point no sensor
    covers), clipped to the target areas, one Polygon per connected part, largest
    first."""
    points = np.asarray(result.points, dtype=float)
    mask = np.asarray(result.n_covered) == 0
    if len(points) == 0 or not mask.any():
        return []
    g = result.cell_m
    ref = points[0, :2]
    # Lattice indices, so neighbouring squares share their edges bit for bit.
    ij = np.round((points[mask, :2] - ref) / g)
    lo = ref + (ij - 0.5) * g
    hi = ref + (ij + 0.5) * g
    squares = shapely.box(lo[:, 0], lo[:, 1], hi[:, 0], hi[:, 1])
    union = shapely.coverage_union_all(squares)
    targets = shapely.union_all([geom for _, geom in result.targets])
    if not targets.is_empty:
        union = shapely.intersection(union, targets)
    parts = [p for p in shapely.get_parts(union) if p.geom_type == "Polygon" and p.area > 0]
    parts.sort(key=lambda p: -p.area)
    return parts
