"""The georeference (io/georef.py) and the GIS outputs (sensors.geojson in WGS84,
sensors_local.geojson, plan.gpkg), against numbers worked out here by hand: the
offset's rotation and shift, the meridian arc of the WGS84 ellipsoid, ring
orientation by the shoelace sum, and GDAL (pyogrio) reading the GeoPackage back."""

from __future__ import annotations

import json
import math

import numpy as np
import pyogrio
import pytest
import shapely
from pyproj import CRS, Transformer
from shapely.geometry import Polygon

from autoscoop_blender.core.errors import SceneContractError
from autoscoop_blender.core.evaluate import evaluate_layout
from autoscoop_blender.core.model.sensors import PAPER_CAMERA, SensorSpec
from autoscoop_blender.core.result import MastRecord, Result, SensorRecord
from autoscoop_blender.core.settings import CoverageSettings
from autoscoop_blender.io.georef import (
    Georef,
    check_crs,
    check_offset,
    sensors_geojson_wgs84,
    uncovered_polygons,
)
from autoscoop_blender.io.gpkg import plan_gpkg
from autoscoop_blender.io.reports import gis_files
from tests.core.flat import box_caster, flat_scene

ASTAZERO = (
    "+proj=tmerc +lat_0=57.77527428642261 +lon_0=12.77124408728523 +k=1 +x_0=0 +y_0=0 "
    "+datum=WGS84 +units=m +no_defs"
)
LAT0, LON0 = 57.77527428642261, 12.77124408728523
A, F = 6378137.0, 1 / 298.257223563  # WGS84
E2 = F * (2 - F)


def meridian_m_per_deg(lat_deg: float) -> float:
    """Metres of meridian arc per degree of latitude at ``lat_deg`` (WGS84)."""
    s = math.sin(math.radians(lat_deg))
    return A * (1 - E2) / (1 - E2 * s * s) ** 1.5 * math.pi / 180


def parallel_m_per_deg(lat_deg: float) -> float:
    """Metres along the parallel per degree of longitude at ``lat_deg`` (WGS84)."""
    s = math.sin(math.radians(lat_deg))
    return A / math.sqrt(1 - E2 * s * s) * math.cos(math.radians(lat_deg)) * math.pi / 180


def signed_area(ring: list[list[float]]) -> float:
    """Shoelace sum: positive for a counter-clockwise ring."""
    return 0.5 * sum(x0 * y1 - x1 * y0 for (x0, y0, *_), (x1, y1, *_) in zip(ring[:-1], ring[1:]))


# --- the transform ------------------------------------------------------------------------


def test_tmerc_origin_is_the_projection_centre():
    lon, lat = Georef(ASTAZERO).to_lonlat(np.array([0.0, 0.0]))
    assert lon == pytest.approx(LON0, abs=1e-10) and lat == pytest.approx(LAT0, abs=1e-10)


def test_one_km_north_and_east():
    g = Georef(ASTAZERO)
    (lon_n, lat_n), (lon_e, lat_e) = g.to_lonlat(np.array([[0.0, 1000.0], [1000.0, 0.0]]))
    # Along the central meridian tmerc (k = 1) keeps true scale: 1000 m of meridian arc.
    assert lon_n == pytest.approx(LON0, abs=1e-12)
    dlat = lat_n - LAT0
    assert dlat == pytest.approx(1000 / 111_300, rel=2e-3)  # the brief's round figure
    assert dlat * meridian_m_per_deg(LAT0 + dlat / 2) == pytest.approx(1000.0, abs=0.01)
    # 1 km east: a degree of longitude is N cos(lat) long; the parallel through the
    # origin curves north of the grid line, to y = x^2 tan(lat) / 2N (0.12 m) at x, so
    # the point (x, 0) lies that far south of it.
    assert (lon_e - LON0) * parallel_m_per_deg(LAT0) == pytest.approx(1000.0, abs=0.01)
    bend_m = 1000**2 * math.tan(math.radians(LAT0)) / (2 * 6.39e6)
    assert (lat_e - LAT0) * meridian_m_per_deg(LAT0) == pytest.approx(-bend_m, abs=0.01)


def test_offset_rotates_then_shifts():
    h = math.pi / 6
    g = Georef(ASTAZERO, (1000.0, 2000.0, 50.0, h))
    got = g.to_crs(np.array([[10.0, 0.0, 5.0], [0.0, 10.0, 0.0], [3.0, -4.0, -1.0]]))
    c, s = math.sqrt(3) / 2, 0.5  # cos 30, sin 30
    want = [
        [1000 + 10 * c, 2000 + 10 * s, 55.0],
        [1000 - 10 * s, 2000 + 10 * c, 50.0],
        [1000 + 3 * c + 4 * s, 2000 + 3 * s - 4 * c, 49.0],
    ]
    np.testing.assert_allclose(got, want, atol=1e-9)
    np.testing.assert_allclose(g.from_crs(got), [[10, 0, 5], [0, 10, 0], [3, -4, -1]], atol=1e-9)
    # The WGS84 position is that CRS point's, by a transformer made here.
    ref = Transformer.from_crs(CRS.from_user_input(ASTAZERO), "EPSG:4326", always_xy=True)
    lon, lat = ref.transform(want[0][0], want[0][1])
    np.testing.assert_allclose(g.to_lonlat(np.array([10.0, 0.0])), [lon, lat], atol=1e-11)


def test_bearing_from_true_north():
    g = Georef(ASTAZERO)
    assert g.bearing_deg(0, 0, 90) == pytest.approx(0, abs=1e-6)  # scene +Y is north here
    assert g.bearing_deg(0, 0, 0) == pytest.approx(90, abs=1e-5)
    assert g.bearing_deg(0, 0, 180) == pytest.approx(270, abs=1e-5)
    turned = Georef(ASTAZERO, (0, 0, 0, math.pi / 2))  # scene +X points north
    assert turned.bearing_deg(0, 0, 0) % 360 == pytest.approx(0, abs=1e-5)
    # 50 km east of the central meridian the meridians lean towards it going north, so
    # grid north lies clockwise of true north by the convergence, about dlon * sin(lat).
    lon, _ = g.to_lonlat(np.array([50_000.0, 0.0]))
    gamma = (lon - LON0) * math.sin(math.radians(LAT0))
    assert g.bearing_deg(50_000, 0, 90) == pytest.approx(gamma, abs=0.01)


# --- checks of the scene's properties ----------------------------------------------------


@pytest.mark.parametrize(
    "value",
    [ASTAZERO, "EPSG:32633", CRS.from_epsg(3006).to_wkt(), "  EPSG:3006 "],
)
def test_good_crs_is_taken(value):
    assert check_crs(value, "scene 'S'", "autoscoop_crs") == value.strip()


@pytest.mark.parametrize(
    "value, says",
    [
        ("+proj=nonsense +units=m", "is not a CRS PROJ knows"),
        ("EPSG:999999", "is not a CRS PROJ knows"),
        ("EPSG:4326", "is not a projected CRS"),
        ("EPSG:2263", "not metres"),  # New York Long Island, US feet
        (42, "must be a string"),
    ],
)
def test_bad_crs_is_a_one_line_error_naming_it(value, says):
    with pytest.raises(SceneContractError) as e:
        check_crs(value, "scene 'S'", "autoscoop_crs")
    text = str(e.value)
    assert "\n" not in text and says in text, text
    assert text.startswith("scene 'S': custom property autoscoop_crs"), text
    if isinstance(value, str):
        assert repr(value) in text


def test_no_crs_is_none():
    assert check_crs(None, "s", "p") is None and check_crs("  ", "s", "p") is None


def test_offset_checks():
    assert check_offset(None, "s", "p") == (0.0, 0.0, 0.0, 0.0)
    assert check_offset([1, 2.5, 3, 0.1], "s", "p") == (1.0, 2.5, 3.0, 0.1)
    for bad in ([1, 2, 3], "abcd", [1, 2, 3, float("nan")], [1e9, 0, 0, 0], [1, 2, 3, True]):
        with pytest.raises(SceneContractError, match=r"^s: custom property p ") as e:
            check_offset(bad, "s", "p")
        assert "\n" not in str(e.value)


# --- outputs -------------------------------------------------------------------------------

# A footprint with a hole, drawn clockwise on purpose (RFC 7946 wants it turned).
FOOTPRINT = Polygon(
    [(0, 0), (0, 40), (30, 40), (30, 0)], [[(10, 10), (20, 10), (20, 20), (10, 20)]]
)


def hand_result(crs: str | None, offset=(0.0, 0.0, 0.0, 0.0)) -> Result:
    """Two masts, three sensors, a 4 x 3 grid of target points whose left column is
    uncovered (two separated uncovered cells on the right as well)."""
    sensors = tuple(
        SensorRecord(
            n=k + 1, x=x, y=y, z=z + 6.0, height_m=6.0, pitch_deg=20.0, yaw_deg=yaw,
            model=PAPER_CAMERA, mast=mast, fitness=1.0, epochs=1, covered_target_m2=10.0,
            footprint_m2=float(FOOTPRINT.area), footprint=shapely.affinity.translate(FOOTPRINT, x, y),
        )
        for k, (x, y, z, yaw, mast) in enumerate(
            [(100.0, 200.0, 1.5, 30.0, 0), (100.0, 200.0, 1.5, 210.0, 0), (-250.0, 80.0, 0.0, 90.0, 1)]
        )
    )  # fmt: skip
    masts = (
        MastRecord(1, 100.0, 200.0, 1.5, 6.0, (1, 2)),
        MastRecord(2, -250.0, 80.0, 0.0, 6.0, (3,)),
    )
    gx, gy = np.meshgrid(np.arange(4) + 0.5, np.arange(3) + 0.5, indexing="ij")
    points = np.column_stack([gx.ravel(), gy.ravel(), np.zeros(12)])
    covered = np.ones(12, dtype=np.int32)
    covered[points[:, 0] == 0.5] = 0  # the left column: 1 x 3 m
    covered[(points[:, 0] == 3.5) & (points[:, 1] != 1.5)] = 0  # two lone cells
    return Result(
        sensors=sensors, masts=masts,
        targets=(("Target", shapely.box(0, 0, 4, 3)),), sensor_areas=(),
        points=points, n_visible=covered, n_covered=covered, cell_m=1.0,
        scene="hand.blend", crs=crs, crs_offset=offset,
    )  # fmt: skip


OFFSET = (500.0, -300.0, 40.0, math.radians(25.0))


def test_geojson_follows_rfc7946():
    doc = sensors_geojson_wgs84(hand_result(ASTAZERO, OFFSET), Georef(ASTAZERO, OFFSET))
    assert doc["type"] == "FeatureCollection" and "crs" not in doc
    kinds = [f["properties"]["kind"] for f in doc["features"]]
    assert kinds == ["mast"] * 2 + ["sensor"] * 3 + ["footprint"] * 3
    rings_seen = 0
    for f in doc["features"]:
        assert "crs" not in f and "crs" not in f["properties"]
        geom = f["geometry"]
        if geom["type"] == "Point":
            lon, lat = geom["coordinates"]  # 2D: z is a property
            assert -180 <= lon <= 180 and -90 <= lat <= 90
            assert abs(lon - LON0) < 0.01 and abs(lat - LAT0) < 0.01
            assert all(round(v, 8) == v for v in (lon, lat))
            continue
        assert geom["type"] == "Polygon"
        exterior, *holes = geom["coordinates"]
        assert len(holes) == 1
        assert signed_area(exterior) > 0 and signed_area(holes[0]) < 0
        assert exterior[0] == exterior[-1]
        rings_seen += 1
    assert rings_seen == 3
    mast = doc["features"][0]["properties"]
    assert mast["height_m"] == 6.0 and mast["ground_z_m"] == pytest.approx(41.5)
    assert (mast["scene_x"], mast["scene_y"], mast["scene_z"]) == (100.0, 200.0, 1.5)
    sensor = doc["features"][2]["properties"]
    assert sensor["pitch_deg"] == 20.0 and sensor["yaw_deg"] == 30.0 and sensor["height_m"] == 6.0
    assert sensor["model"]["h_fov_deg"] == PAPER_CAMERA.h_fov_deg
    # Scene yaw 30 deg turned by the 25 deg heading: 55 deg from grid east, so about
    # 35 deg clockwise from north (less the small meridian convergence).
    assert sensor["bearing_deg"] == pytest.approx(35.0, abs=0.5)


def test_masts_come_back_within_a_centimetre():
    """The round trip of the issue: masts read from the written sensors.geojson,
    converted back with the CRS (a transformer made here and the offset undone by
    hand), land within 1 cm of their scene positions."""
    result = hand_result(ASTAZERO, OFFSET)
    files, note = gis_files(result)
    assert note is None
    doc = json.loads(files["sensors.geojson"])
    back = Transformer.from_crs("EPSG:4326", CRS.from_user_input(ASTAZERO), always_xy=True)
    x0, y0, _, h = OFFSET
    masts = [f for f in doc["features"] if f["properties"]["kind"] == "mast"]
    assert len(masts) == len(result.masts)
    for f, m in zip(masts, result.masts):
        e, n = back.transform(*f["geometry"]["coordinates"])
        dx, dy = e - x0, n - y0
        x, y = math.cos(h) * dx + math.sin(h) * dy, -math.sin(h) * dx + math.cos(h) * dy
        assert math.hypot(x - m.x, y - m.y) < 0.01, (x, y, m)
        # And by the module's own inverse.
        bx, by = Georef(ASTAZERO, OFFSET).from_lonlat(np.array(f["geometry"]["coordinates"]))
        assert math.hypot(bx - m.x, by - m.y) < 0.01


def test_local_geojson_keeps_scene_metres():
    files, _ = gis_files(hand_result(ASTAZERO, OFFSET))
    local = json.loads(files["sensors_local.geojson"])
    masts = [f for f in local["features"] if f["properties"]["kind"] == "mast"]
    assert [f["geometry"]["coordinates"] for f in masts] == [
        [100.0, 200.0, 1.5],
        [-250.0, 80.0, 0.0],
    ]
    footprints = [f for f in local["features"] if f["properties"]["kind"] == "footprint"]
    assert shapely.geometry.shape(footprints[0]["geometry"]).area == pytest.approx(FOOTPRINT.area)


def test_no_crs_writes_only_the_local_file_and_says_so():
    files, note = gis_files(hand_result(None))
    assert list(files) == ["sensors_local.geojson"]
    assert note is not None and "autoscoop_crs" in note and "hand.blend" in note
    assert "sensors_local.geojson" in note and "\n" not in note


def test_uncovered_patches_are_the_uncovered_cells():
    parts = uncovered_polygons(hand_result(None))
    assert [round(p.area, 9) for p in parts] == [3.0, 1.0, 1.0]
    assert parts[0].bounds == (0.0, 0.0, 1.0, 3.0)
    assert sorted(p.bounds for p in parts[1:]) == [(3.0, 0.0, 4.0, 1.0), (3.0, 2.0, 4.0, 3.0)]


def test_uncovered_patches_are_clipped_to_the_target():
    result = hand_result(None)
    clipped = Result(**{**result.__dict__, "targets": (("T", shapely.box(0.25, 0, 4, 3)),)})
    assert uncovered_polygons(clipped)[0].bounds == (0.25, 0.0, 1.0, 3.0)


@pytest.mark.parametrize("crs, epsg", [(ASTAZERO, None), ("EPSG:32633", 32633)])
def test_geopackage_reads_back_with_gdal(tmp_path, crs, epsg):
    result = hand_result(crs, OFFSET)
    georef = Georef(crs, OFFSET)
    path = tmp_path / "plan.gpkg"
    path.write_bytes(plan_gpkg(result, georef))
    layers = {name: kind for name, kind in pyogrio.list_layers(path)}
    assert layers == {
        "masts": "Point", "sensors": "Point", "footprints": "MultiPolygon",
        "uncovered": "MultiPolygon",
    }  # fmt: skip
    counts = {name: pyogrio.read_info(path, layer=name)["features"] for name in layers}
    assert counts == {"masts": 2, "sensors": 3, "footprints": 3, "uncovered": 3}
    info = pyogrio.read_info(path, layer="masts")
    assert CRS.from_user_input(info["crs"]).equals(CRS.from_user_input(crs))
    if epsg is not None:
        assert info["crs"] == f"EPSG:{epsg}"
    _, _, geometry, fields = pyogrio.raw.read(path, layer="masts")
    xy = np.array([shapely.from_wkb(g).coords[0] for g in geometry])
    x0, y0, z0, h = OFFSET
    c, s = math.cos(h), math.sin(h)
    want = [[c * 100 - s * 200 + x0, s * 100 + c * 200 + y0], [c * -250 - s * 80 + x0, s * -250 + c * 80 + y0]]  # fmt: skip
    np.testing.assert_allclose(xy, want, atol=1e-6)
    names = list(pyogrio.read_info(path, layer="masts")["fields"])
    assert list(fields[names.index("ground_z_m")]) == [41.5, 40.0]
    _, _, geometry, _ = pyogrio.raw.read(path, layer="uncovered")
    areas = sorted(shapely.from_wkb(g).area for g in geometry)
    assert areas == pytest.approx([1.0, 1.0, 3.0])  # a rotation keeps areas


def test_evaluated_layout_carries_the_scene_crs():
    from dataclasses import replace

    scene = replace(flat_scene(target=(-20, -20, 20, 20)), crs=ASTAZERO, crs_offset=OFFSET)
    spec = SensorSpec(PAPER_CAMERA, 0.0, 0.0, 6.0, 30.0, 0.0)
    result = evaluate_layout(scene, box_caster()(), [spec], CoverageSettings(grid_m=2.0))
    assert result.crs == ASTAZERO and result.crs_offset == OFFSET
    files, note = gis_files(result)
    assert note is None and sorted(files) == [
        "plan.gpkg",
        "sensors.geojson",
        "sensors_local.geojson",
    ]
