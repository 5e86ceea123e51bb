"""``python -m headless coverage``: outputs that agree with themselves, bad input that
fails in one line with exit code 2 and writes nothing."""

import csv
import json

import pytest

from autoscoop_blender.core.errors import InputError
from headless.files import write_files
from tests.cli.conftest import SAMPLES, run_headless

FLAT = SAMPLES / "flat_wall.blend"
TWO_SENSORS = {
    "model": "paper_camera",
    "sensors": [
        {"x": -8, "y": 0, "pitch_deg": 40, "yaw_deg": 0},
        {"x": -8, "y": 2, "height_m": 9.0, "pitch_deg": 35, "yaw_deg": 20},
    ],
}


def test_coverage_outputs_agree(tmp_path, sensors_file):
    out, pts = tmp_path / "out.json", tmp_path / "points.csv"
    code, stdout, stderr = run_headless(
        "coverage", FLAT, "--sensors", sensors_file(TWO_SENSORS), "--out", out, "--points-csv", pts
    )
    assert code == 0, stderr
    assert "coverage" in stdout and stderr == ""
    res = json.loads(out.read_text())
    assert res["method"] == "targeted" and res["settings"]["grid_m"] == 1.0
    assert res["target_area_m2"] == pytest.approx(2500.0)
    assert res["target_points"] == 2500
    rows = list(csv.DictReader(pts.open()))
    assert list(rows[0]) == [
        "x", "y", "z", "n_visible", "n_covered", "best_density", "k_needed", "covered",
    ]  # fmt: skip
    assert len(rows) == res["target_points"]
    # k = 1 everywhere: a point counts when one sensor covers it.
    assert {r["k_needed"] for r in rows} == {"1"}
    assert all(r["covered"] == str(int(int(r["n_covered"]) > 0)) for r in rows)
    covered = sum(int(r["n_covered"]) > 0 for r in rows)
    assert res["coverage_fraction"] == pytest.approx(covered / len(rows))
    assert res["covered_m2"] == pytest.approx(covered * 1.0)
    assert all(int(r["n_covered"]) <= int(r["n_visible"]) <= 2 for r in rows)
    s1, s2 = res["sensors"]
    assert (s1["z"], s1["height_m"]) == (7.0, 7.0) and s2["z"] == 9.0
    assert s1["sensor_area"] == "SensorArea_1"
    for s in res["sensors"]:
        assert 0 < s["covered_target_m2"] <= s["footprint_m2"]
    assert res["rays_cast"] == res["rays"]["sight"] + res["rays"]["drop"] > 0
    # Union: at least the best single sensor, at most their sum.
    per = [s["covered_target_m2"] for s in res["sensors"]]
    assert max(per) <= res["covered_m2"] <= sum(per)
    # The map of the layout beside --out: a PNG 1,200 px wide (its IHDR).
    png = (tmp_path / "out.png").read_bytes()
    assert png[:8] == b"\x89PNG\r\n\x1a\n" and int.from_bytes(png[16:20]) == 1200
    assert stdout.rstrip().endswith(f"-> {out}, {tmp_path / 'out.png'}")
    # It is an output like the others: not replaced without --overwrite.
    code, _, stderr = run_headless(
        "coverage", FLAT, "--sensors", sensors_file(TWO_SENSORS), "--out", tmp_path / "b.json",
        "--points-csv", tmp_path / "out.png",
    )  # fmt: skip
    assert code == 2 and "out.png" in stderr and not (tmp_path / "b.json").exists()


def test_min_density_zero_makes_counts_equal(tmp_path, sensors_file):
    pts = tmp_path / "points.csv"
    code, _, stderr = run_headless(
        "coverage", FLAT, "--sensors", sensors_file(TWO_SENSORS), "--out", tmp_path / "o.json",
        "--points-csv", pts, "--min-density", 0,
    )  # fmt: skip
    assert code == 0, stderr
    rows = list(csv.DictReader(pts.open()))
    assert all(r["n_visible"] == r["n_covered"] for r in rows)
    assert any(int(r["n_visible"]) == 2 for r in rows)


def test_pointcloud_method_and_script_entry(tmp_path, sensors_file):
    out = tmp_path / "pc.json"
    code, _, stderr = run_headless(
        "coverage", FLAT, "--sensors", sensors_file(TWO_SENSORS), "--method", "pointcloud",
        "--out", out, script=True,
    )  # fmt: skip
    assert code == 0, stderr
    res = json.loads(out.read_text())
    assert res["method"] == "pointcloud"
    assert res["sensors"][0]["rays_cast"] == 30720


def test_warnings_do_not_stop_the_job(tmp_path, sensors_file, blend_file):
    outside = {
        "model": "paper_camera",
        "sensors": [{"x": 30, "y": 30, "pitch_deg": 40, "yaw_deg": 0}],
    }
    out = tmp_path / "o.json"
    code, _, stderr = run_headless(
        "coverage", FLAT, "--sensors", sensors_file(outside), "--out", out
    )
    assert code == 0
    assert stderr.strip() == "warning: sensor 1 at (30, 30) stands outside every sensor area"
    assert json.loads(out.read_text())["warnings"]

    def empty(b):
        b.curve("Target", [b.rect(0, -25, 50, 25)])
        b.curve("SensorArea", [b.rect(-12, -4, -4, 4)])

    code, _, stderr = run_headless(
        "coverage", blend_file(empty), "--sensors", sensors_file(TWO_SENSORS), "--out", out,
        "--overwrite",
    )  # fmt: skip
    assert code == 0 and "flat nothing" in stderr


def _bad(tmp_path, *args):
    out = tmp_path / "never.json"
    code, _, stderr = run_headless(*args, "--out", out)
    assert code == 2
    lines = stderr.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith("error: "), stderr
    assert not out.exists()
    return lines[0]


def test_bad_files(tmp_path, sensors_file):
    good = sensors_file(TWO_SENSORS)
    assert "nope.blend: file not found" in _bad(
        tmp_path, "coverage", "nope.blend", "--sensors", good
    )
    assert "missing.json: sensors file not found" in _bad(
        tmp_path, "coverage", FLAT, "--sensors", tmp_path / "missing.json"
    )
    junk = tmp_path / "junk.blend"
    junk.write_text("not a blend")
    assert "junk.blend: not a readable .blend file" in _bad(
        tmp_path, "coverage", junk, "--sensors", good
    )


@pytest.mark.parametrize(
    "sensor, model, message",
    [
        ({"x": 0, "y": 0, "yaw_deg": 0}, "paper_camera", "sensor 1: missing pitch_deg"),
        ({"x": 0, "y": 0, "pitch_deg": float("nan"), "yaw_deg": 0}, "paper_camera", "pitch_deg is nan"),
        ({"x": 0, "y": 0, "pitch_deg": 91, "yaw_deg": 0}, "paper_camera", "not in [-90, 90]"),
        ({"x": 0, "y": 0, "pitch_deg": 40, "yaw_deg": 0}, {"preset": "paper_camera", "pattern": "pinhole", "h_fov_deg": 180}, "h_fov_deg 180.0 must be in (0, 180)"),
        ({"x": 0, "y": 0, "pitch_deg": 40, "yaw_deg": 0}, {"preset": "paper_camera", "range_m": 0}, "range_m 0.0 must be > 0"),
    ],
)  # fmt: skip
def test_bad_sensors(tmp_path, sensors_file, sensor, model, message):
    path = sensors_file({"model": model, "sensors": [sensor]})
    assert message in _bad(tmp_path, "coverage", FLAT, "--sensors", path)


def test_bad_scenes(tmp_path, sensors_file, blend_file):
    good = sensors_file(TWO_SENSORS)

    def no_target(b):
        b.plane("Ground", -9, -9, 9, 9)
        b.curve("SensorArea", [b.rect(0, 0, 1, 1)])

    def no_sensor_area(b):
        b.curve("Target", [b.rect(0, 0, 1, 1)])

    def open_curve(b):
        b.curve("Target_Road", [b.rect(0, 0, 10, 10)], cyclic=False)
        b.curve("SensorArea", [b.rect(-5, 0, -1, 4)])

    def crossing(b):
        b.curve("Target", [b.rect(0, 0, 10, 10)])
        b.curve("SensorArea_X", [[(0, 0), (10, 10), (10, 0), (0, 10)]])

    def tilted(b):
        b.curve("Target_Up", [[(0, 0, 0), (10, 0, 0), (10, 0, 10), (0, 0, 10)]])
        b.curve("SensorArea", [b.rect(-5, 0, -1, 4)])

    def tiny(b):
        b.curve("Target_Speck", [b.rect(0.1, 0.1, 0.3, 0.3)])
        b.curve("SensorArea", [b.rect(-5, 0, -1, 4)])

    cases = [
        (no_target, "no target area"),
        (no_sensor_area, "no sensor area"),
        (open_curve, "Target_Road: curve is open"),
        (crossing, "SensorArea_X: curve crosses itself"),
        (tilted, "Target_Up: curve is not in the XY plane"),
        (tiny, "Target_Speck: target area holds no point of the 1 m grid"),
    ]
    for k, (build, message) in enumerate(cases):
        path = blend_file(build, name=f"bad{k}.blend")
        assert message in _bad(tmp_path, "coverage", path, "--sensors", good)


def test_bad_command_line(tmp_path, sensors_file):
    good = sensors_file(TWO_SENSORS)
    assert "--grid" in _bad(tmp_path, "coverage", FLAT, "--sensors", good, "--grid", "-1")
    assert "--method" in _bad(tmp_path, "coverage", FLAT, "--sensors", good, "--method", "magic")


def test_outputs_are_all_or_nothing(tmp_path):
    first = tmp_path / "first.json"
    blocker = tmp_path / "second.csv"
    blocker.mkdir()  # a directory where a file should go: the rename fails
    with pytest.raises(InputError, match="second.csv: is a directory"):
        write_files({first: "{}", blocker: "x"})
    assert not first.exists()
    assert [p.name for p in tmp_path.iterdir()] == ["second.csv"]
