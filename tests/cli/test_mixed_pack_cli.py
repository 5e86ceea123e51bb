"""``headless optimize`` with a mixed pack (``models`` in the config): every output
names each sensor's model, the cost counts each at its own, and the result
recomputes with ``headless coverage`` (issue 16 point 3)."""

import csv
import json

import pytest

from tests.cli.conftest import SAMPLES, run_headless


def test_a_pack_plan_lists_its_models_and_recomputes(tmp_path):
    cfg = tmp_path / "pack.toml"
    # flat_wall's wall hides part of its target: 65 % is within reach.
    cfg.write_text(
        'optimizer = "greedy"\nrho = 0.65\n'
        'models = ["paper_camera", {preset = "roadside_lidar", sensor_cost = 0.5}]\n'
    )
    out = tmp_path / "plan"
    code, _, stderr = run_headless(
        "optimize", SAMPLES / "flat_wall.blend", "--config", cfg, "--out-dir", out
    )
    assert code == 0, stderr
    doc = json.loads((out / "result.json").read_text())
    assert [(m["kind"], m["sensor_cost"]) for m in doc["models"]] == [
        ("camera", 1.0),
        ("lidar", 0.5),
    ]
    kinds = [s["model"]["kind"] for s in doc["sensors"]]
    assert "lidar" in kinds  # at half a camera's cost a lidar sees far more
    m = doc["metrics"]
    assert m["cost"] == pytest.approx(3 * m["masts"] + sum(1.0 if k == "camera" else 0.5
                                                           for k in kinds))  # fmt: skip
    with open(out / "sensors.csv", newline="") as f:
        assert [r["kind"] for r in csv.DictReader(f)] == kinds
    # result.json is a sensors file with a model per sensor: the same coverage again.
    code, _, stderr = run_headless(
        "coverage", SAMPLES / "flat_wall.blend", "--sensors", out / "result.json",
        "--out", tmp_path / "again.json",
    )  # fmt: skip
    assert code == 0, stderr
    again = json.loads((tmp_path / "again.json").read_text())
    assert again["coverage_fraction"] == pytest.approx(m["coverage_fraction"], abs=1e-6)
    assert [s["model"]["kind"] for s in again["sensors"]] == kinds


def test_the_es_refuses_a_pack_in_one_line(tmp_path):
    cfg = tmp_path / "pack.toml"
    cfg.write_text('optimizer = "es"\nmodels = ["paper_camera", "traffic_radar"]\n')
    code, _, stderr = run_headless(
        "optimize", SAMPLES / "flat_wall.blend", "--config", cfg, "--out-dir", tmp_path / "o"
    )
    assert code != 0
    assert "es optimizer plans one sensor model" in stderr
    assert len(stderr.strip().splitlines()) == 1 and "Traceback" not in stderr
    assert not (tmp_path / "o").exists()  # refused before the output folder is made
