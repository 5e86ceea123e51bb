"""k-coverage from the command line: the flag's limits in one line, ``headless
coverage`` at k = 1..3 on flat_wall against a layout counted by hand, and a checkpoint
of one k that a run of another refuses."""

import csv
import json
import math

import numpy as np
import pytest

from autoscoop_blender.core.errors import InputError
from autoscoop_blender.core.settings import OptimizeSettings
from headless.checkpoint import Checkpoint
from tests.cli.conftest import SAMPLES, run_headless


@pytest.mark.parametrize(
    ("value", "message"),
    [
        ("0", "coverage_k (--coverage-k) = 0 is out of range: must be in [1, 10]"),
        ("11", "coverage_k (--coverage-k) = 11 is out of range: must be in [1, 10]"),
        ("1.5", "argument --coverage-k: invalid int value: '1.5'"),
    ],
)
def test_coverage_k_outside_1_to_10_is_refused_in_one_line(tmp_path, value, message):
    code, _, stderr = run_headless(
        "optimize", SAMPLES / "flat_wall.blend", "--coverage-k", value, "--out-dir", tmp_path
    )
    assert code != 0
    lines = stderr.strip().splitlines()
    assert len(lines) == 1 and message in lines[0], stderr


def down_camera(x, y, side):
    """A pinhole camera looking straight down at the height where its square
    footprint on flat ground is ``side`` wide (2 h tan 30 deg), no density limit."""
    return {
        "x": x, "y": y, "height_m": side / 2 / math.tan(math.radians(30)),
        "pitch_deg": 90, "yaw_deg": 0,
    }  # fmt: skip


DOWN = {
    "preset": "paper_camera", "pattern": "pinhole", "h_fov_deg": 60, "v_fov_deg": 60,
    "range_m": 40, "pitch_min_deg": 90, "pitch_max_deg": 90, "min_density_per_m2": 0,
}  # fmt: skip


def test_headless_coverage_reports_k_1_to_3_on_flat_wall(tmp_path, sensors_file):
    """On flat_wall's 50 x 50 m target (2,500 points on the 1 m grid), far from the
    wall: squares x 20..40 and x 30..50 (y -10..10) and x 32..38, y -3..3. Once:
    x 20..30 and 40..50 (400 points), twice: x 30..40 (200), of which the 6 x 6
    square three times (36). At k = 2, 200 of 2,500 (8 %) count."""
    sensors = sensors_file(
        {
            "model": DOWN,
            "sensors": [down_camera(30, 0, 20), down_camera(40, 0, 20), down_camera(35, 0, 6)],
        }
    )
    out, points = tmp_path / "out.json", tmp_path / "points.csv"
    code, _, stderr = run_headless(
        "coverage", SAMPLES / "flat_wall.blend", "--sensors", sensors, "--coverage-k", "2",
        "--out", out, "--points-csv", points,
    )  # fmt: skip
    assert code == 0, stderr
    doc = json.loads(out.read_text())
    assert doc["target_points"] == 2500
    assert doc["coverage_k"] == {"setting": 2, "max": 2, "areas": {}}
    assert doc["covered_m2"] == 200.0 and doc["coverage_fraction"] == 0.08
    assert doc["coverage_by_k"] == {
        "1": {"fraction": 0.24, "m2": 600.0},
        "2": {"fraction": 0.08, "m2": 200.0},
        "3": {"fraction": 0.0144, "m2": 36.0},
    }
    with points.open() as f:
        rows = list(csv.DictReader(f))
    n = np.array([int(r["n_covered"]) for r in rows])
    x = np.array([float(r["x"]) for r in rows])
    y = np.array([float(r["y"]) for r in rows])
    twice = (x > 30) & (x < 40) & (np.abs(y) < 10)
    np.testing.assert_array_equal(n >= 2, twice)
    thrice = (np.abs(x - 35) < 3) & (np.abs(y) < 3)
    np.testing.assert_array_equal(n >= 3, thrice)
    # --coverage-k 2 with no area of its own: every point needs 2.
    assert {r["k_needed"] for r in rows} == {"2"}
    np.testing.assert_array_equal([int(r["covered"]) for r in rows], twice.astype(int))


def test_points_csv_gives_each_point_its_areas_k(tmp_path, sensors_file, blend_file):
    """Target_Junction (x 0..15, y 0..10) asks coverage_k = 2, Target_Straight
    (x 15..30) nothing (the setting: 1). Squares x 0..20 and x 10..30 (y 0..10) and
    x 14..20, y 2..8: once at x 0..10 and 20..30, twice at x 10..20, three times in
    the small square. Counted: the Junction's x 10..15 (50 of its 150 points) and all
    150 of the Straight: 200 of 300."""

    def build(b):
        b.plane("Ground", -10, -10, 40, 20)
        junction = b.curve("Target_Junction", [b.rect(0, 0, 15, 10)])
        junction["coverage_k"] = 2
        b.curve("Target_Straight", [b.rect(15, 0, 30, 10)])
        b.curve("SensorArea", [b.rect(-1, -1, 31, 11)])

    sensors = sensors_file(
        {
            "model": DOWN,
            "sensors": [down_camera(10, 5, 20), down_camera(20, 5, 20), down_camera(17, 5, 6)],
        }
    )
    out, points = tmp_path / "out.json", tmp_path / "points.csv"
    code, _, stderr = run_headless(
        "coverage", blend_file(build), "--sensors", sensors, "--out", out, "--points-csv", points
    )
    assert code == 0, stderr
    doc = json.loads(out.read_text())
    assert doc["target_points"] == 300
    assert doc["coverage_k"] == {"setting": 1, "max": 2, "areas": {"Target_Junction": 2}}
    assert doc["covered_m2"] == 200.0
    with points.open() as f:
        rows = list(csv.DictReader(f))
    x = np.array([float(r["x"]) for r in rows])
    y = np.array([float(r["y"]) for r in rows])
    n = np.array([int(r["n_covered"]) for r in rows])
    k = np.array([int(r["k_needed"]) for r in rows])
    covered = np.array([int(r["covered"]) for r in rows])
    junction = x < 15
    np.testing.assert_array_equal(k, np.where(junction, 2, 1))
    # The counts by hand, then covered: n_covered >= k_needed.
    small = (np.abs(x - 17) < 3) & (np.abs(y - 5) < 3)
    np.testing.assert_array_equal(n, np.where((x > 10) & (x < 20), 2, 1) + small)
    np.testing.assert_array_equal(covered, (n >= k).astype(int))
    np.testing.assert_array_equal(covered == 1, ~junction | (x > 10))
    assert covered.sum() == 200


def test_a_checkpoint_of_another_k_is_not_resumed(tmp_path):
    header = {
        "scene": "x.blend",
        "scene_fingerprint": "0123456789abcdef",
        "model": {"name": "cam"},
        "settings": OptimizeSettings(coverage_k=2).to_dict(),
    }
    cp = Checkpoint(tmp_path, header)
    cp.append({"n": 1, "x": 0.0, "y": 0.0, "pitch_deg": 30.0, "yaw_deg": 0.0,
               "fitness": 1.0, "epochs": 0, "evaluations": 0})  # fmt: skip
    assert len(Checkpoint(tmp_path, header).resume()) == 1
    other = dict(header, settings=OptimizeSettings(coverage_k=1).to_dict())
    with pytest.raises(InputError, match="different settings"):
        Checkpoint(tmp_path, other).resume()
