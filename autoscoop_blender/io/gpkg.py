"""plan.gpkg: the plan as an OGC GeoPackage, in the scene's projected CRS.

A GeoPackage is an SQLite file with three metadata tables (``gpkg_spatial_ref_sys``,
``gpkg_contents``, ``gpkg_geometry_columns``) and one table per layer, each geometry a
blob of a small header ("GP", flags, srs id, envelope) and ISO WKB. Python's own
sqlite3 and shapely's WKB writer are all it takes, so the file is written here without
GDAL (pyogrio's wheel bundles GDAL at 24-33 MB per platform, fiona's 17 MB per Python
and platform; see the README's "Georeference"). The tests read it back with GDAL.

Layers: ``masts`` and ``sensors`` (points), ``footprints`` and ``uncovered``
(multipolygons: the target area no sensor covers, ``georef.uncovered_polygons``). The
CRS is recorded by its EPSG code when PROJ knows one, else as a custom srs (id 100000)
with its WKT.
"""

from __future__ import annotations

import json
import sqlite3
import struct
import tempfile
import time
from collections.abc import Sequence
from pathlib import Path
from typing import Any

import shapely
from shapely.geometry import MultiPolygon, Polygon
from shapely.geometry.base import BaseGeometry

from ..core.result import Result
from .georef import Georef, uncovered_polygons

APPLICATION_ID = 0x47504B47  # "GPKG"
USER_VERSION = 10300  # GeoPackage 1.3
CUSTOM_SRS_ID = 100000

LAYERS = ("masts", "sensors", "footprints", "uncovered")

_CORE_TABLES = """
CREATE TABLE gpkg_spatial_ref_sys (
  srs_name TEXT NOT NULL, srs_id INTEGER NOT NULL PRIMARY KEY,
  organization TEXT NOT NULL, organization_coordsys_id INTEGER NOT NULL,
  definition TEXT NOT NULL, description TEXT);
CREATE TABLE gpkg_contents (
  table_name TEXT NOT NULL PRIMARY KEY, data_type TEXT NOT NULL,
  identifier TEXT UNIQUE, description TEXT DEFAULT '',
  last_change DATETIME NOT NULL DEFAULT (strftime('%Y-%m-%dT%H:%M:%fZ','now')),
  min_x DOUBLE, min_y DOUBLE, max_x DOUBLE, max_y DOUBLE, srs_id INTEGER,
  CONSTRAINT fk_gc_r_srs_id FOREIGN KEY (srs_id) REFERENCES gpkg_spatial_ref_sys(srs_id));
CREATE TABLE gpkg_geometry_columns (
  table_name TEXT NOT NULL, column_name TEXT NOT NULL,
  geometry_type_name TEXT NOT NULL, srs_id INTEGER NOT NULL,
  z TINYINT NOT NULL, m TINYINT NOT NULL,
  CONSTRAINT pk_geom_cols PRIMARY KEY (table_name, column_name),
  CONSTRAINT fk_gc_tn FOREIGN KEY (table_name) REFERENCES gpkg_contents(table_name),
  CONSTRAINT fk_gc_srs FOREIGN KEY (srs_id) REFERENCES gpkg_spatial_ref_sys (srs_id));
"""

# The three rows every GeoPackage holds (the spec's "undefined" systems and WGS84).
_WGS84_WKT = (
    'GEOGCS["WGS 84",DATUM["WGS_1984",SPHEROID["WGS 84",6378137,298.257223563,'
    'AUTHORITY["EPSG","7030"]],AUTHORITY["EPSG","6326"]],PRIMEM["Greenwich",0,'
    'AUTHORITY["EPSG","8901"]],UNIT["degree",0.0174532925199433,AUTHORITY["EPSG","9122"]],'
    'AUTHORITY["EPSG","4326"]]'
)
_DEFAULT_SRS = (
    ("Undefined cartesian SRS", -1, "NONE", -1, "undefined", "undefined cartesian"),
    ("Undefined geographic SRS", 0, "NONE", 0, "undefined", "undefined geographic"),
    ("WGS 84 geodetic", 4326, "EPSG", 4326, _WGS84_WKT, "longitude/latitude WGS 84"),
)


def geometry_blob(geom: BaseGeometry, srs_id: int) -> bytes:
    """A GeoPackage geometry: header (little-endian, xy envelope) and ISO WKB (2D)."""
    if geom.is_empty:
        flags = 0b0001_0001  # empty, no envelope, little-endian
        return b"GP" + bytes([0, flags]) + struct.pack("<i", srs_id) + shapely.to_wkb(geom)
    minx, miny, maxx, maxy = geom.bounds
    flags = 0b0000_0011  # envelope [minx, maxx, miny, maxy], little-endian
    header = b"GP" + bytes([0, flags]) + struct.pack("<i4d", srs_id, minx, maxx, miny, maxy)
    wkb = shapely.to_wkb(geom, output_dimension=2, byte_order=1, flavor="iso")
    return header + wkb


def _multi(geom: BaseGeometry) -> MultiPolygon:
    if isinstance(geom, Polygon):
        return MultiPolygon([geom])
    parts = [g for g in shapely.get_parts(geom) if isinstance(g, Polygon)]
    return MultiPolygon(parts)


def _srs_row(georef: Georef) -> tuple[str, int, str, int, str, str]:
    from pyproj.enums import WktVersion

    crs = georef.pyproj_crs
    code = crs.to_epsg(min_confidence=100)
    wkt = crs.to_wkt(WktVersion.WKT1_GDAL) or crs.to_wkt()
    name = crs.name or "scene CRS"
    if code is not None and code not in (4326, 0, -1):
        return (name, code, "EPSG", code, wkt, georef.crs)
    return (name, CUSTOM_SRS_ID, "NONE", CUSTOM_SRS_ID, wkt, georef.crs)


def _layer(
    db: sqlite3.Connection,
    name: str,
    geometry_type: str,
    srs_id: int,
    columns: Sequence[tuple[str, str]],
    rows: Sequence[tuple[BaseGeometry, Sequence[Any]]],
    description: str,
) -> None:
    cols = "".join(f", {c} {t}" for c, t in columns)
    db.execute(
        f"CREATE TABLE {name} (fid INTEGER PRIMARY KEY AUTOINCREMENT, geom {geometry_type}{cols})"
    )
    marks = ", ".join("?" * (len(columns) + 1))
    names = ", ".join(["geom", *(c for c, _ in columns)])
    for geom, values in rows:
        db.execute(
            f"INSERT INTO {name} ({names}) VALUES ({marks})", (geometry_blob(geom, srs_id), *values)
        )
    bounds = shapely.total_bounds([g for g, _ in rows]) if rows else [None] * 4
    stamp = time.strftime("%Y-%m-%dT%H:%M:%S.000Z", time.gmtime())
    db.execute(
        "INSERT INTO gpkg_contents (table_name, data_type, identifier, description, last_change,"
        " min_x, min_y, max_x, max_y, srs_id) VALUES (?, 'features', ?, ?, ?, ?, ?, ?, ?, ?)",
        (
            name,
            name,
            description,
            stamp,
            *(None if b is None else float(b) for b in bounds),
            srs_id,
        ),
    )
    db.execute(
        "INSERT INTO gpkg_geometry_columns VALUES (?, 'geom', ?, ?, 0, 0)",
        (name, geometry_type, srs_id),
    )


def plan_gpkg(result: Result, georef: Georef) -> bytes:
    """The bytes of plan.gpkg: masts, sensors, footprints and uncovered patches in the
    scene's CRS (see the module docstring)."""
    srs = _srs_row(georef)
    srs_id = srs[1]
    dz = georef.offset[2]

    def point(x: float, y: float) -> BaseGeometry:
        return georef.geometry_to_crs(shapely.Point(x, y))

    masts = [
        (point(m.x, m.y),
         (m.n, m.height_m, round(m.z_ground + dz, 4), ",".join(map(str, m.sensors)), m.x, m.y))
        for m in result.masts
    ]  # fmt: skip
    sensors = [
        (point(s.x, s.y),
         (s.n, s.mast + 1, s.height_m, round(s.z + dz, 4), round(s.pitch_deg, 3),
          round(s.yaw_deg, 3), round(georef.bearing_deg(s.x, s.y, s.yaw_deg), 3),
          json.dumps(s.model.to_dict()), s.covered_target_m2, s.x, s.y))
        for s in result.sensors
    ]  # fmt: skip
    footprints = [
        (_multi(georef.geometry_to_crs(s.footprint)),
         (s.n, s.mast + 1, s.covered_target_m2, round(s.footprint_m2, 2)))
        for s in result.sensors
        if not s.footprint.is_empty
    ]  # fmt: skip
    uncovered = [
        (_multi(georef.geometry_to_crs(p)), (k + 1, round(float(p.area), 2)))
        for k, p in enumerate(uncovered_polygons(result))
    ]
    with tempfile.TemporaryDirectory(prefix="autoscoop-gpkg-") as tmp:
        path = Path(tmp) / "plan.gpkg"
        db = sqlite3.connect(path)
        try:
            db.execute(f"PRAGMA application_id = {APPLICATION_ID}")
            db.execute(f"PRAGMA user_version = {USER_VERSION}")
            db.executescript(_CORE_TABLES)
            db.executemany("INSERT INTO gpkg_spatial_ref_sys VALUES (?, ?, ?, ?, ?, ?)",
                           [*_DEFAULT_SRS, srs])  # fmt: skip
            _layer(db, "masts", "POINT", srs_id,
                   [("mast", "INTEGER"), ("height_m", "REAL"), ("ground_z_m", "REAL"),
                    ("sensors", "TEXT"), ("scene_x", "REAL"), ("scene_y", "REAL")],
                   masts, "masts: foot of each mast")  # fmt: skip
            _layer(db, "sensors", "POINT", srs_id,
                   [("sensor", "INTEGER"), ("mast", "INTEGER"), ("height_m", "REAL"),
                    ("z_m", "REAL"), ("pitch_deg", "REAL"), ("yaw_deg", "REAL"),
                    ("bearing_deg", "REAL"), ("model", "TEXT"), ("target_covered_m2", "REAL"),
                    ("scene_x", "REAL"), ("scene_y", "REAL")],
                   sensors, "sensors: pose of each sensor")  # fmt: skip
            _layer(db, "footprints", "MULTIPOLYGON", srs_id,
                   [("sensor", "INTEGER"), ("mast", "INTEGER"), ("target_covered_m2", "REAL"),
                    ("footprint_m2", "REAL")],
                   footprints, "footprints: ground each sensor covers")  # fmt: skip
            _layer(db, "uncovered", "MULTIPOLYGON", srs_id,
                   [("patch", "INTEGER"), ("area_m2", "REAL")],
                   uncovered, "uncovered: target area no sensor covers")  # fmt: skip
            db.commit()
        finally:
            db.close()
        return path.read_bytes()
