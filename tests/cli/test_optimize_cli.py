"""``python -m headless optimize``: the default run on two_routes, its outputs, an
independent recomputation, the paper-faithful pipeline, checkpoints and resume."""

import csv
import json
import math
import zlib
from dataclasses import replace

import bpy
import pytest

from autoscoop_blender import names
from autoscoop_blender.core.errors import InputError
from autoscoop_blender.core.settings import ESParams, OptimizeSettings
from headless.checkpoint import Checkpoint
from tests.cli.conftest import SAMPLES, run_headless

FLAT = SAMPLES / "flat_wall.blend"
SMALL = """
optimizer = "es"
rho = 0.6
[es]
mu = 8
lam = 4
max_epochs = 4
"""


@pytest.fixture(scope="module")
def default_run(tmp_path_factory):
    out = tmp_path_factory.mktemp("default")
    code, stdout, stderr = run_headless("optimize", "--out-dir", out)
    assert code == 0, stderr
    return out, stdout


def test_default_run_reaches_the_goal(default_run):
    out, stdout = default_run
    res = json.loads((out / "result.json").read_text())
    m = res["metrics"]
    assert m["coverage_fraction"] >= 0.97
    assert res["scene"] == "two_routes.blend" and res["optimizer"] == "lp"
    assert res["method"] == "targeted" and res["seed"] == 0
    for key in (
        "sensors", "masts", "cluster_ratio", "relative_sensor_coverage", "overlap_factor",
        "mean_epochs_per_sensor", "wall_s", "rays_cast",
    ):  # fmt: skip
        assert key in m
    assert m["sensors"] == len(res["sensors"]) and m["masts"] == len(res["masts"])
    assert res["stop_reason"].startswith("Reached the goal") and f"{m['sensors']} sensors" in stdout
    # Where its gap lies: each count's own bound, never above the plan's count.
    assert m["gap"] > 0 and m["masts_lower_bound"] <= m["masts"]
    assert 0 < m["sensors_lower_bound"] <= m["sensors"]
    line = (
        f"no plan on the candidate set has fewer than {m['masts_lower_bound']} masts or fewer "
        f"than {m['sensors_lower_bound']} sensors; this one has {m['masts']} and {m['sensors']}"
    )
    # On its own masts: at least the fewest sensors anywhere, at most the plan's.
    on_masts = m["sensors_on_masts_lower_bound"]
    assert m["sensors_lower_bound"] <= on_masts <= m["sensors"]
    if on_masts == m["sensors"]:
        line += "; none on its masts has fewer sensors: a plan with fewer needs other masts"
    else:
        line += f"; on its masts a plan needs at least {on_masts} sensors"
    assert line in stdout.splitlines()


def test_recomputed_coverage_agrees(default_run, tmp_path):
    out, _ = default_run
    res = json.loads((out / "result.json").read_text())
    check = tmp_path / "check.json"
    code, _, stderr = run_headless(
        "coverage", SAMPLES / "two_routes.blend", "--sensors", out / "result.json", "--out", check
    )
    assert code == 0, stderr
    again = json.loads(check.read_text())
    assert again["coverage_fraction"] == pytest.approx(
        res["metrics"]["coverage_fraction"], abs=1e-6
    )
    per_sensor = [s["covered_target_m2"] for s in again["sensors"]]
    assert per_sensor == [s["target_covered_m2"] for s in res["sensors"]]


def _sight_tree():
    """A BVHTree of every visible mesh of the open file in world metres, built here
    from Blender's own data (not through the product's caster)."""
    from mathutils.bvhtree import BVHTree

    depsgraph = bpy.context.evaluated_depsgraph_get()
    verts, polys = [], []
    for obj in bpy.context.scene.objects:
        if obj.type != "MESH" or not obj.visible_get():
            continue
        ev = obj.evaluated_get(depsgraph)
        mesh = ev.to_mesh()
        mw = ev.matrix_world
        base = len(verts)
        verts.extend(mw @ v.co for v in mesh.vertices)
        polys.extend([base + i for i in p.vertices] for p in mesh.polygons)
        ev.to_mesh_clear()
    return BVHTree.FromPolygons(verts, polys)


def test_coverage_agrees_with_brute_force_rays(default_run, tmp_path):
    """An independent path: for 400 random target points of the plan's own points CSV,
    each sensor's verdict worked out here from its pose and model - range, the angular
    FoV, line of sight by a ray cast on a BVHTree of the scene's meshes, the pattern's
    density on the surface there - and counted. The README holds targeted exact at the
    grid's resolution and its points within 1 % of a reference: so must this be."""
    import math

    import numpy as np
    from mathutils import Vector

    out, _ = default_run
    res = json.loads((out / "result.json").read_text())
    points = tmp_path / "points.csv"
    code, _, stderr = run_headless(
        "coverage", SAMPLES / "two_routes.blend", "--sensors", out / "result.json",
        "--out", tmp_path / "c.json", "--points-csv", points,
    )  # fmt: skip
    assert code == 0, stderr
    rows = np.array(
        [[float(r[k]) for k in ("x", "y", "z", "n_covered")] for r in csv.DictReader(points.open())]
    )
    rng = np.random.default_rng(7)
    sample = rows[rng.choice(len(rows), 400, replace=False)]
    bpy.ops.wm.open_mainfile(filepath=str(SAMPLES / "two_routes.blend"))
    tree = _sight_tree()
    model = res["model"]
    half_h, half_v = math.radians(model["h_fov_deg"]) / 2, math.radians(model["v_fov_deg"]) / 2
    n_rays = model["rays_h"] * model["rays_v"]
    counts = np.zeros(len(sample), dtype=int)
    for k, (x, y, z, _) in enumerate(sample):
        # The point on the surface, found here (the file's z is rounded to 1 mm).
        point, normal, _, _ = tree.ray_cast(Vector((x, y, z + 0.5)), Vector((0, 0, -1)), 1.0)
        assert point is not None and abs(point.z - z) < 0.01
        normal = normal.normalized()
        for s in res["sensors"]:
            eye = Vector((s["x"], s["y"], s["z"]))
            d = point - eye
            r = d.length
            if r > model["range_m"]:
                continue
            d = d / r
            p, w = math.radians(s["pitch_deg"]), math.radians(s["yaw_deg"])
            forward = Vector((math.cos(p) * math.cos(w), math.cos(p) * math.sin(w), -math.sin(p)))
            left = Vector((-math.sin(w), math.cos(w), 0.0))
            up = forward.cross(left)
            azimuth = math.atan2(d.dot(left), d.dot(forward))
            elevation = math.asin(max(-1.0, min(1.0, d.dot(up))))
            if abs(azimuth) > half_h or abs(elevation) > half_v:
                continue
            if tree.ray_cast(eye, d, r - 0.01)[0] is not None:
                continue  # something stands between
            per_sr = n_rays / (4 * half_h * half_v * math.cos(elevation))
            density = per_sr * abs(d.dot(normal)) / (r * r * max(abs(normal.z), 1e-3))
            counts[k] += density >= model["min_density_per_m2"]
    differ = counts != sample[:, 3].astype(int)
    assert differ.mean() <= 0.01, sample[differ]
    assert (counts > 0).mean() >= 0.9  # the sample is mostly covered ground: a real test


def test_output_files(default_run):
    out, _ = default_run
    res = json.loads((out / "result.json").read_text())
    rows = list(csv.DictReader((out / "sensors.csv").open()))
    assert list(rows[0]) == [
        "n", "x", "y", "z", "height_m", "pitch_deg", "yaw_deg", "bearing_deg", "fitness",
        "target_covered_m2", "mast", "existing", "kind",
    ]  # fmt: skip
    assert len(rows) == len(res["sensors"])
    assert res["notes"] == []  # two_routes' buildings, walls and trees stand up
    for row, s in zip(rows, res["sensors"]):
        # The mast's height above the ground, and the view's compass bearing: the
        # direction (cos yaw, sin yaw) measured clockwise from +Y (north).
        assert float(row["height_m"]) == pytest.approx(s["height_m"], abs=1e-3)
        assert float(row["z"]) - float(row["height_m"]) == pytest.approx(
            res["masts"][s["mast"] - 1]["z_ground"], abs=0.05
        )
        yaw = math.radians(s["yaw_deg"])
        north = math.degrees(math.atan2(math.cos(yaw), math.sin(yaw))) % 360.0
        assert min(abs(float(row["bearing_deg"]) - north), 360 - abs(
            float(row["bearing_deg"]) - north)) == pytest.approx(0.0, abs=1e-3)  # fmt: skip
    assert {r["existing"] for r in rows} == {"0"}  # a plan from scratch: all new
    assert {r["kind"] for r in rows} == {res["model"]["kind"]}  # one model: its kind
    for row, s in zip(rows, res["sensors"]):
        assert float(row["x"]) == pytest.approx(s["x"], abs=1e-3)
        assert int(row["mast"]) == s["mast"]
    # two_routes names no CRS: the scene's metres only, and a note says so.
    assert not (out / "sensors.geojson").exists() and not (out / "plan.gpkg").exists()
    geo = json.loads((out / "sensors_local.geojson").read_text())
    kinds = [f["properties"]["kind"] for f in geo["features"]]
    assert kinds.count("mast") == len(res["masts"]) and kinds.count("footprint") == len(rows)
    assert kinds.count("sensor") == len(rows)
    mast = next(f for f in geo["features"] if f["properties"]["kind"] == "mast")
    first = res["masts"][0]
    want = [first["x"], first["y"], first["z_ground"]]
    assert mast["geometry"]["coordinates"] == pytest.approx(want, abs=1e-4)  # z: 4 decimals
    png = (out / "coverage.png").read_bytes()
    assert png[:8] == b"\x89PNG\r\n\x1a\n" and zlib.crc32(png[12:29]) == int.from_bytes(png[29:33])
    lines = (out / "checkpoint.jsonl").read_text().splitlines()
    assert len(lines) == 1 + len(rows)

    bpy.ops.wm.open_mainfile(filepath=str(out / "result.blend"))
    results = bpy.data.collections[names.RESULTS_COLLECTION]
    cameras = [o for o in results.all_objects if o.type == "CAMERA"]
    assert len(cameras) == len(rows)
    # The user's objects came through unchanged.
    assert "Terrain" in bpy.data.objects and "Target_RouteA" in bpy.data.objects


def test_pointcloud_pipeline_end_to_end(tmp_path):
    cfg = tmp_path / "tiny.toml"
    cfg.write_text('optimizer = "es"\nrho = 0.3\n[es]\nmu = 4\nlam = 2\nmax_epochs = 2\n')
    out = tmp_path / "pc"
    code, _, stderr = run_headless(
        "optimize", FLAT, "--method", "pointcloud", "--config", cfg, "--out-dir", out
    )
    assert code == 0, stderr
    res = json.loads((out / "result.json").read_text())
    assert res["method"] == "pointcloud" and res["metrics"]["coverage_fraction"] >= 0.3
    # Every sensor costs the whole pattern per evaluation.
    assert res["metrics"]["rays_cast"] >= 30720 * res["metrics"]["evaluations"]


def test_resume_after_an_interruption(tmp_path):
    cfg = tmp_path / "small.toml"
    cfg.write_text(SMALL)
    out = tmp_path / "run"
    code, _, stderr = run_headless("optimize", FLAT, "--config", cfg, "--out-dir", out)
    assert code == 0, stderr
    whole = (out / "sensors.csv").read_text()
    lines = (out / "checkpoint.jsonl").read_text().splitlines()
    assert len(lines) >= 3
    # As if the run had been cut off after the first sensor, mid-write of the next:
    # no result file written yet.
    (out / "checkpoint.jsonl").write_text(lines[0] + "\n" + lines[1] + "\n" + lines[2][:20])
    for name in ("result.json", "sensors.csv", "coverage.png", "result.blend"):
        (out / name).unlink()
    (out / "sensors_local.geojson").unlink()
    code, _, stderr = run_headless("optimize", FLAT, "--config", cfg, "--out-dir", out, "--resume")
    assert code == 0, stderr
    assert "resuming after 1 fixed sensor" in stderr
    assert (out / "sensors.csv").read_text() == whole

    code, _, stderr = run_headless(
        "optimize", FLAT, "--config", cfg, "--out-dir", out, "--resume", "--seed", "5",
        "--overwrite",
    )  # fmt: skip
    assert code == 2 and "different settings" in stderr


def test_bad_optimize_input(tmp_path):
    bad = tmp_path / "bad.toml"
    bad.write_text("rhoo = 0.9\n")
    code, _, stderr = run_headless("optimize", FLAT, "--config", bad, "--out-dir", tmp_path / "o")
    assert code == 2 and stderr.strip() == "error: bad.toml: unknown setting(s) rhoo"
    code, _, stderr = run_headless("optimize", FLAT, "--resume", "--out-dir", tmp_path / "none")
    assert code == 2 and "no checkpoint to resume from" in stderr
    assert not (tmp_path / "o" / "result.json").exists()


def test_greedy_optimizer_from_the_command_line(tmp_path):
    cfg = tmp_path / "goal.toml"
    cfg.write_text("rho = 0.6\n")
    out = tmp_path / "greedy"
    code, _, stderr = run_headless(
        "optimize", FLAT, "--optimizer", "greedy", "--config", cfg, "--out-dir", out
    )
    assert code == 0, stderr
    res = json.loads((out / "result.json").read_text())
    assert res["optimizer"] == "greedy" and res["settings"]["optimizer"] == "greedy"
    assert res["metrics"]["coverage_fraction"] >= 0.6
    code, _, stderr = run_headless(
        "optimize", FLAT, "--optimizer", "greedy", "--method", "pointcloud", "--out-dir", out
    )
    assert code == 2 and "greedy optimizer needs the targeted method" in stderr


def test_flags_set_what_a_config_file_sets(tmp_path):
    """--rho, --model and a nested knob (--es-mu) on the command line give the run a
    config file with the same keys gives, and override that file."""
    cfg = tmp_path / "lidar.toml"
    cfg.write_text('model = "roadside_lidar"\nrho = 0.5\n[es]\nmu = 5\n')
    runs = {}
    for name, args in (
        ("file", ("--config", cfg)),
        ("flags", ("--model", "roadside_lidar", "--rho", "0.5", "--es-mu", "5")),
        ("both", ("--config", cfg, "--rho", "0.4", "--model", "paper_camera")),
    ):
        out = tmp_path / name
        code, _, stderr = run_headless(
            "optimize", FLAT, "--optimizer", "greedy", *args, "--out-dir", out
        )
        assert code == 0, stderr
        runs[name] = json.loads((out / "result.json").read_text())
    assert runs["file"]["model"] == runs["flags"]["model"]
    assert runs["file"]["model"]["kind"] == "lidar"
    assert runs["file"]["settings"] == runs["flags"]["settings"]
    assert runs["flags"]["settings"]["rho"] == 0.5 and runs["flags"]["settings"]["es"]["mu"] == 5
    assert runs["file"]["sensors"] == runs["flags"]["sensors"]
    assert runs["both"]["settings"]["rho"] == 0.4 and runs["both"]["model"]["kind"] == "camera"


def test_checkpoint_from_before_a_setting_existed_resumes_as_its_default(tmp_path):
    """The header's settings are read through the schema: a key missing from an older
    checkpoint, at the top or in a table, reads as its default."""
    header = {
        "scene_fingerprint": "f",
        "model": {"kind": "camera"},
        "settings": OptimizeSettings().to_dict(),
    }
    old_settings = OptimizeSettings().to_dict()
    del old_settings["optimizer"], old_settings["es"]["decay"]  # not settings back then
    record = {"n": 1, "x": 0.5, "y": 1.0, "pitch_deg": 20.0, "yaw_deg": 0.0, "fitness": 0.1,
              "epochs": 2, "evaluations": 9}  # fmt: skip
    Checkpoint(tmp_path, dict(header, settings=old_settings)).append(record)
    assert Checkpoint(tmp_path, header).resume() == [record]
    # A run asking for another optimizer, or another decay, is not the one recorded.
    for other in (
        replace(OptimizeSettings(), optimizer="greedy"),
        OptimizeSettings(es=ESParams(decay=0.9)),
    ):
        with pytest.raises(InputError, match="different settings"):
            Checkpoint(tmp_path, dict(header, settings=other.to_dict())).resume()
