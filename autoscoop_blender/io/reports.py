"""Report files of a result: result.json, the coverage job's JSON, sensors.csv,
sensors_local.geojson and the per-point CSV.

Everything is read from a ``core.result.Result``; nothing here computes coverage.
All coordinates are the scene's world coordinates (metres). sensors_local.geojson
carries them as they are; the georeferenced outputs (sensors.geojson in WGS84,
plan.gpkg in the scene's CRS) are ``io.georef`` and ``io.gpkg``.
"""

from __future__ import annotations

import csv
import io
import json
import platform
from typing import Any

import numpy as np
import shapely

from .. import names
from ..core.result import Result

RESULT_SCHEMA = "autoscoop.result/1"
VERSION = "0.1.0"

SENSORS_CSV_HEADER = (
    "n",
    "x",
    "y",
    "z",
    "height_m",
    "pitch_deg",
    "yaw_deg",
    "bearing_deg",
    "fitness",
    "target_covered_m2",
    "mast",
    "existing",
    "kind",
)


def versions() -> dict[str, str]:
    """Versions of AutoSCOOP and of the libraries behind a result."""
    import scipy

    return {
        "autoscoop": VERSION,
        "python": platform.python_version(),
        "numpy": np.__version__,
        "scipy": scipy.__version__,
        "shapely": shapely.__version__,
    }


def result_dict(result: Result, extra_versions: dict[str, str] | None = None) -> dict[str, Any]:
    """The result.json document of an optimization.

    Its ``model`` and ``sensors`` keys form a valid sensors file, so
    ``headless coverage SCENE --sensors result.json`` recomputes the coverage. A
    mixed pack's plan also lists ``models`` (each with its ``sensor_cost``), and each
    sensor its ``model``. ``interrupted``: true when the run was interrupted and
    stopped early, with the best plan it had.
    """
    settings = result.settings
    assert result.model is not None, "an optimization has one model"
    mixed = result.pack is not None
    doc = {
        "schema": RESULT_SCHEMA,
        "scene": result.scene,
        "targets_fingerprint": result.targets_fingerprint,
        "optimizer": settings.optimizer,
        "method": settings.method,
        "seed": settings.seed,
        "settings": settings.to_dict(),
        "model": result.model.to_dict(),
        "versions": {**versions(), **(extra_versions or {})},
        "metrics": result.metrics,
        "stop_reason": result.stop_reason,
        "interrupted": result.interrupted,
        "notes": list(result.notes),
        "uncovered": list(result.uncovered),
        "no_mast_sites": excluded_list(result),
        "sensors": [
            {
                "n": s.n,
                "x": s.x,
                "y": s.y,
                "z": round(s.z, 4),
                "height_m": s.height_m,
                "pitch_deg": s.pitch_deg,
                "yaw_deg": s.yaw_deg,
                "mast": s.mast + 1,
                "fitness": round(s.fitness, 3),
                "epochs": s.epochs,
                "target_covered_m2": s.covered_target_m2,
                "footprint_m2": round(s.footprint_m2, 2),
                "existing": s.existing,
                **({"model": s.model.to_dict()} if mixed else {}),
            }
            for s in result.sensors
        ],
        "masts": [
            {
                "n": m.n,
                "x": m.x,
                "y": m.y,
                "z_ground": round(m.z_ground, 4),
                "height_m": m.height_m,
                "sensors": list(m.sensors),
                "existing": m.existing,
            }
            for m in result.masts
        ],
        "origin": [float(v) for v in result.origin],
    }
    if result.pack is not None:
        doc["models"] = result.pack.to_list(settings.sensor_cost)
    return doc


def coverage_dict(result: Result) -> dict[str, Any]:
    """The ``headless coverage`` document (OUT.json) of an evaluated layout."""
    m = result.metrics
    return {
        "scene": result.scene,
        "method": result.settings.method,
        "settings": result.settings.to_dict(),
        "target_area_m2": m["target_area_m2"],
        "target_polygon_m2": result.target_polygon_m2,
        "target_points": len(result.points),
        "covered_m2": m["covered_m2"],
        "coverage_fraction": m["coverage_fraction"],
        "coverage_k": _k_in_effect(result),
        "coverage_by_k": m.get("coverage_by_k"),
        "sensors": [
            {
                "n": s.n,
                "x": round(s.x, 4),
                "y": round(s.y, 4),
                "z": round(s.z, 4),
                "height_m": s.height_m,
                "pitch_deg": s.pitch_deg,
                "yaw_deg": s.yaw_deg,
                "model": s.model.to_dict(),
                "sensor_area": s.sensor_area,
                "covered_target_m2": s.covered_target_m2,
                "footprint_m2": round(s.footprint_m2, 3),
                "mast": s.mast + 1,
                "rays_cast": s.rays,
            }
            for s in result.sensors
        ],
        "metrics": m,
        "rays_cast": m["rays_cast"],
        "rays": dict(result.rays),
        "wall_s": m["wall_s"],
        "origin": [float(v) for v in result.origin],
        "warnings": list(result.warnings),
        "notes": list(result.notes),
        "no_mast_sites": excluded_list(result),
    }


def excluded_list(result: Result) -> list[dict[str, Any]]:
    """Where the sensor areas offer no mast site, and why: area, cause, m^2."""
    return [{"area": e.area, "cause": e.cause, "m2": round(e.m2, 2)} for e in result.excluded]


def _k_in_effect(result: Result) -> dict[str, Any]:
    """The k the coverage figures were counted at: the settings' ``coverage_k``, the
    largest any point needs, and the target areas that ask their own (name: k)."""
    k = int(getattr(result.settings, "coverage_k", 1) or 1)
    need = result.need
    return {
        "setting": k,
        "max": int(np.max(need)) if need is not None and len(need) else k,
        "areas": dict(result.area_k),
    }


POINTS_HEADER = ("x", "y", "z", "n_visible", "n_covered", "best_density", "k_needed", "covered")


def point_rows(result: Result) -> list[tuple[float, float, float, int, int, float, int, int]]:
    """One row per target point (``POINTS_HEADER``): world x, y, z, the sensors that
    see it and that cover it, the best density among those (points/m^2), the sensors
    it needs to count as covered (its k: its target area's ``coverage_k`` or the
    setting's) and whether it does (1: n_covered >= k_needed, else 0)."""
    best = result.best_density if result.best_density is not None else np.zeros(len(result.points))
    return [
        (
            round(float(x), 3),
            round(float(y), 3),
            round(float(z), 3),
            int(v),
            int(c),
            round(float(b), 4),
            int(k),
            int(c >= k),
        )
        for (x, y, z), v, c, b, k in zip(
            result.points, result.n_visible, result.n_covered, best, result.k_need
        )
    ]


def bearing(yaw_deg: float) -> float:
    """A yaw (deg, counter-clockwise from the scene's +X) as a compass bearing (deg,
    clockwise from the scene's +Y, its grid north), in [0, 360)."""
    return (90.0 - yaw_deg) % 360.0


def sensors_csv(result: Result) -> str:
    """The paper's Table III columns, one row per sensor, with its height above the
    ground beside z and its compass bearing beside yaw (``bearing``), plus its mast
    (1-based), whether it stood already (1) or is new (0), and its model's kind
    (camera, lidar, radar)."""
    buf = io.StringIO()
    w = csv.writer(buf, lineterminator="\n")
    w.writerow(SENSORS_CSV_HEADER)
    for s in result.sensors:
        w.writerow(
            [
                s.n,
                f"{s.x:.3f}",
                f"{s.y:.3f}",
                f"{s.z:.3f}",
                f"{s.height_m:.3f}",
                f"{s.pitch_deg:.3f}",
                f"{s.yaw_deg:.3f}",
                f"{bearing(s.yaw_deg):.3f}",
                f"{s.fitness:.1f}",
                f"{s.covered_target_m2:.0f}",
                s.mast + 1,
                int(s.existing),
                s.model.kind,
            ]
        )
    return buf.getvalue()


def sensors_geojson(result: Result) -> dict[str, Any]:
    """sensors_local.geojson: masts and sensors as points, sensor footprints as
    (multi)polygons, in the scene's world metres (no CRS)."""
    features: list[dict[str, Any]] = []
    for m in result.masts:
        features.append(
            {
                "type": "Feature",
                "geometry": {"type": "Point", "coordinates": [m.x, m.y, m.z_ground]},
                "properties": {
                    "kind": "mast",
                    "mast": m.n,
                    "height_m": m.height_m,
                    "sensors": list(m.sensors),
                    "existing": m.existing,
                },
            }
        )
    for s in result.sensors:
        features.append(
            {
                "type": "Feature",
                "geometry": {"type": "Point", "coordinates": [s.x, s.y, round(s.z, 4)]},
                "properties": {
                    "kind": "sensor",
                    "sensor": s.n,
                    "mast": s.mast + 1,
                    "height_m": s.height_m,
                    "pitch_deg": round(s.pitch_deg, 3),
                    "yaw_deg": round(s.yaw_deg, 3),
                    "model": s.model.to_dict(),
                    "existing": s.existing,
                },
            }
        )
    for s in result.sensors:
        if s.footprint.is_empty:
            continue
        features.append(
            {
                "type": "Feature",
                "geometry": shapely.geometry.mapping(shapely.set_precision(s.footprint, 0.01)),
                "properties": {
                    "kind": "footprint",
                    "sensor": s.n,
                    "mast": s.mast + 1,
                    "pitch_deg": round(s.pitch_deg, 3),
                    "yaw_deg": round(s.yaw_deg, 3),
                    "height_m": s.height_m,
                    "target_covered_m2": s.covered_target_m2,
                    "footprint_m2": round(s.footprint_m2, 2),
                },
            }
        )
    return {"type": "FeatureCollection", "features": features}


def gis_files(result: Result) -> tuple[dict[str, str | bytes], str | None]:
    """The GIS outputs of a result by file name, and a note when it has no CRS.

    Always sensors_local.geojson (world metres); with the scene's CRS also
    sensors.geojson (RFC 7946, WGS84) and plan.gpkg (the scene's CRS).
    """
    from .georef import georef_of, sensors_geojson_wgs84
    from .gpkg import plan_gpkg

    files: dict[str, str | bytes] = {"sensors_local.geojson": _json(sensors_geojson(result))}
    georef = georef_of(result)
    if georef is None:
        note = (
            f"{result.scene or 'the scene'}: no georeference (scene custom property "
            f"{names.CRS_PROP}): wrote sensors_local.geojson in the scene's metres only, no "
            "sensors.geojson (WGS84) or plan.gpkg"
        )
        return files, note
    files["sensors.geojson"] = _json(sensors_geojson_wgs84(result, georef))
    files["plan.gpkg"] = plan_gpkg(result, georef)
    return files, None


def _json(doc: dict[str, Any]) -> str:
    return json.dumps(doc, indent=2, allow_nan=False) + "\n"
