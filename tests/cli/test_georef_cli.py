"""``headless optimize`` on a georeferenced scene: sensors.geojson in WGS84, the local
file, plan.gpkg; without a CRS the local file only and a note; a bad CRS refused in one
line before anything is written (issue 15)."""

from __future__ import annotations

import json
import math

import bpy
import numpy as np
import pyogrio
import pytest
from pyproj import CRS, Transformer

from autoscoop_blender import names
from tests.cli.conftest import SAMPLES, run_headless

FLAT = SAMPLES / "flat_wall.blend"
UTM33 = "EPSG:32633"
OFFSET = (370_000.0, 6_400_000.0, 12.0, math.radians(-10.0))
SMALL = 'optimizer = "es"\nrho = 0.6\n[es]\nmu = 8\nlam = 4\nmax_epochs = 4\n'


def georeferenced_copy(path, crs, offset=None):
    """flat_wall.blend with the scene's georeference properties set, saved at ``path``."""
    bpy.ops.wm.open_mainfile(filepath=str(FLAT))
    scene = bpy.context.scene
    scene[names.CRS_PROP] = crs
    if offset is not None:
        scene[names.CRS_OFFSET_PROP] = offset
    bpy.ops.wm.save_as_mainfile(filepath=str(path), copy=True)
    return path


@pytest.fixture(scope="module")
def geo_run(tmp_path_factory):
    tmp = tmp_path_factory.mktemp("geo")
    scene = georeferenced_copy(tmp / "flat_utm.blend", UTM33, OFFSET)
    cfg = tmp / "small.toml"
    cfg.write_text(SMALL)
    out = tmp / "out"
    code, _, stderr = run_headless("optimize", scene, "--config", cfg, "--out-dir", out)
    assert code == 0, stderr
    return out, stderr


def test_georeferenced_run_writes_wgs84_local_and_gpkg(geo_run):
    out, stderr = geo_run
    assert "no georeference" not in stderr
    res = json.loads((out / "result.json").read_text())
    geo = json.loads((out / "sensors.geojson").read_text())
    local = json.loads((out / "sensors_local.geojson").read_text())
    assert "crs" not in geo
    masts = [f for f in geo["features"] if f["properties"]["kind"] == "mast"]
    assert len(masts) == len(res["masts"]) >= 1
    # Back to the scene with a transformer made here and the offset undone by hand.
    back = Transformer.from_crs("EPSG:4326", UTM33, always_xy=True)
    x0, y0, z0, h = OFFSET
    for f, m in zip(masts, res["masts"]):
        lon, lat = f["geometry"]["coordinates"]
        # UTM 33N: 130 km west of 15 E (about 2.2 deg at 57.7 N), 6,400 km north
        assert 12.6 < lon < 13.0 and 57.5 < lat < 58.0
        e, n = back.transform(lon, lat)
        x = math.cos(h) * (e - x0) + math.sin(h) * (n - y0)
        y = -math.sin(h) * (e - x0) + math.cos(h) * (n - y0)
        assert math.hypot(x - m["x"], y - m["y"]) < 0.01
        assert f["properties"]["ground_z_m"] == pytest.approx(m["z_ground"] + z0, abs=1e-3)
    local_masts = [f for f in local["features"] if f["properties"]["kind"] == "mast"]
    assert [f["geometry"]["coordinates"][:2] for f in local_masts] == [
        [m["x"], m["y"]] for m in res["masts"]
    ]
    gpkg = out / "plan.gpkg"
    layers = dict(pyogrio.list_layers(gpkg))
    assert set(layers) == {"masts", "sensors", "footprints", "uncovered"}
    info = pyogrio.read_info(gpkg, layer="sensors")
    assert info["features"] == len(res["sensors"]) and info["crs"] == UTM33
    _, _, geometry, _ = pyogrio.raw.read(gpkg, layer="masts")
    assert len(geometry) == len(res["masts"])
    patches = pyogrio.read_info(gpkg, layer="uncovered")["features"]
    assert patches == len(res["uncovered"])


def test_no_crs_writes_the_local_file_only_and_says_so(tmp_path):
    cfg = tmp_path / "small.toml"
    cfg.write_text(SMALL)
    out = tmp_path / "out"
    out.mkdir()
    # An earlier georeferenced run's files would not be this plan's: replacing that
    # run's results (--overwrite), they go.
    (out / "sensors.geojson").write_text("{}")
    (out / "plan.gpkg").write_bytes(b"old")
    code, _, stderr = run_headless("optimize", FLAT, "--config", cfg, "--out-dir", out)
    assert code == 2 and "plan.gpkg: exist already; --overwrite replaces them" in stderr
    code, _, stderr = run_headless(
        "optimize", FLAT, "--config", cfg, "--out-dir", out, "--overwrite"
    )
    assert code == 0, stderr
    notes = [ln for ln in stderr.splitlines() if ln.startswith("note:")]
    assert any(names.CRS_PROP in ln and "sensors_local.geojson" in ln for ln in notes), stderr
    assert (out / "sensors_local.geojson").is_file()
    assert not (out / "sensors.geojson").exists() and not (out / "plan.gpkg").exists()


@pytest.mark.parametrize(
    "crs, offset, says",
    [
        ("+proj=tmerc +lat_0=nope", None, names.CRS_PROP),
        ("EPSG:4326", None, "not a projected CRS"),
        (UTM33, [1.0, 2.0], names.CRS_OFFSET_PROP),
    ],
)
def test_bad_georeference_is_one_line_before_any_output(tmp_path, crs, offset, says):
    scene = georeferenced_copy(tmp_path / "bad.blend", crs, offset)
    out = tmp_path / "out"
    code, stdout, stderr = run_headless("optimize", scene, "--out-dir", out)
    assert code == 2, stderr
    lines = stderr.strip().splitlines()
    assert len(lines) == 1 and says in lines[0] and "bad.blend" in lines[0], stderr
    assert not out.exists()


def test_offset_array_reads_as_given(tmp_path):
    """A Blender float-array property comes through as the four numbers."""
    from autoscoop_blender.scene.extract import extract_scene

    georeferenced_copy(tmp_path / "g.blend", UTM33, OFFSET)
    bpy.ops.wm.open_mainfile(filepath=str(tmp_path / "g.blend"))
    model = extract_scene()
    assert model.crs == UTM33
    np.testing.assert_allclose(model.crs_offset, OFFSET)
    assert CRS.from_user_input(model.crs).to_epsg() == 32633
