"""``headless optimize --existing FILE.json``: sensors that stand already are kept as
given, flagged in every output, and the plan adds no more than one from scratch."""

import csv
import json

from tests.cli.conftest import SAMPLES, run_headless


def _goal(tmp_path):
    """flat_wall's wall hides part of its target from its sensor area: 70 % is what
    any plan there can reach, so the goal is set below it."""
    cfg = tmp_path / "goal.toml"
    cfg.write_text('optimizer = "greedy"\nrho = 0.65\n')
    return ("--config", cfg)


def _optimize(out, *extra):
    code, _, stderr = run_headless(
        "optimize", SAMPLES / "flat_wall.blend", *_goal(out.parent), "--out-dir", out, *extra
    )
    assert code == 0, stderr
    return json.loads((out / "result.json").read_text())


def test_existing_sensors_are_kept_flagged_and_added_to(tmp_path, sensors_file):
    scratch = _optimize(tmp_path / "scratch")
    # Two sensors of the plan from scratch, as a sensors file: they stand already.
    given = [
        {k: s[k] for k in ("x", "y", "height_m", "pitch_deg", "yaw_deg")}
        for s in scratch["sensors"][:2]
    ]
    existing = sensors_file({"model": scratch["model"], "sensors": given})
    doc = _optimize(tmp_path / "plan", "--existing", existing)

    kept = [s for s in doc["sensors"] if s["existing"]]
    assert [(s["x"], s["y"], s["z"], s["pitch_deg"], s["yaw_deg"]) for s in kept] == [
        (s["x"], s["y"], s["z"], s["pitch_deg"], s["yaw_deg"]) for s in scratch["sensors"][:2]
    ]
    new = [s for s in doc["sensors"] if not s["existing"]]
    assert doc["metrics"]["coverage_fraction"] >= 0.65
    assert len(new) <= len(scratch["sensors"])
    assert doc["metrics"]["existing_sensors"] == 2
    # Every output says which ones stood already.
    rows = list(csv.DictReader((tmp_path / "plan" / "sensors.csv").open()))
    assert [r["existing"] for r in rows] == ["1" if s["existing"] else "0" for s in doc["sensors"]]
    geo = json.loads((tmp_path / "plan" / "sensors_local.geojson").read_text())
    props = [f["properties"] for f in geo["features"]]
    flags = [p["existing"] for p in props if p["kind"] == "sensor"]
    assert flags == [s["existing"] for s in doc["sensors"]]
    assert sum(m["existing"] for m in doc["masts"]) == doc["metrics"]["existing_masts"] >= 1


def test_a_checkpoint_made_without_them_is_refused(tmp_path, sensors_file):
    out = tmp_path / "plan"
    scratch = _optimize(out)
    given = [{k: scratch["sensors"][0][k] for k in ("x", "y", "height_m", "pitch_deg", "yaw_deg")}]
    existing = sensors_file({"model": scratch["model"], "sensors": given})
    code, _, stderr = run_headless(
        "optimize", SAMPLES / "flat_wall.blend", *_goal(tmp_path), "--out-dir", out,
        "--existing", existing, "--resume", "--overwrite",
    )  # fmt: skip
    assert code != 0
    assert "made with different existing sensors; run without --resume" in stderr


def test_masts_with_free_slots_from_the_file(tmp_path, sensors_file):
    """A file of masts alone (no sensor): each is a site where a new sensor adds no
    mast, so the plan's masts there are flagged and cost nothing."""
    scratch = _optimize(tmp_path / "scratch")
    sites = [{"x": m["x"], "y": m["y"]} for m in scratch["masts"][:2]]
    existing = sensors_file({"model": scratch["model"], "sensors": [], "masts": sites})
    doc = _optimize(tmp_path / "plan", "--existing", existing)
    assert doc["metrics"]["existing_sensors"] == 0
    standing = [m for m in doc["masts"] if m["existing"]]
    assert {(m["x"], m["y"]) for m in standing} <= {(s["x"], s["y"]) for s in sites}
    assert doc["metrics"]["existing_masts"] == len(standing) >= 1
    # greedy's cost counts only the masts it added.
    new_masts = len(doc["masts"]) - len(standing)
    settings = doc["settings"]
    assert doc["metrics"]["cost"] == (
        settings["mast_cost"] * new_masts + settings["sensor_cost"] * len(doc["sensors"])
    )


def test_a_mast_entry_without_y_is_refused_in_one_line(tmp_path, sensors_file):
    existing = sensors_file({"sensors": [], "masts": [{"x": 1.0}]}, name="masts.json")
    code, _, stderr = run_headless(
        "optimize", SAMPLES / "flat_wall.blend", "--existing", existing, "--out-dir", tmp_path
    )
    assert code == 2
    assert stderr.strip() == "error: masts.json: mast 1: missing y"


def test_another_grounds_plan_is_warned_of_and_still_counted(tmp_path, blend_file):
    """A result.json planned for other target areas (its targets_fingerprint), and
    sensors standing outside every sensor area: each a warning, as coverage gives."""
    plan = tmp_path / "plan"
    scratch = _optimize(plan)
    code, _, same = run_headless(
        "optimize", SAMPLES / "flat_wall.blend", *_goal(tmp_path), "--out-dir",
        tmp_path / "again", "--existing", plan / "result.json",
    )  # fmt: skip
    assert code == 0 and "--existing" not in same, same

    def moved(b):  # flat_wall's areas, the target 10 m further east: another ground
        b.curve("Target_Area", [b.rect(10, -25, 60, 25)])
        b.curve("SensorArea_1", [b.rect(-12, -4, -4, 4)])
        b.plane("Ground", -60, -60, 80, 60)

    other = blend_file(moved)
    code, _, stderr = run_headless(
        "optimize", other, *_goal(tmp_path), "--out-dir", tmp_path / "other",
        "--existing", plan / "result.json",
    )  # fmt: skip
    warned = [line for line in stderr.splitlines() if line.startswith("warning: --existing")]
    assert warned == [
        f"warning: --existing {plan / 'result.json'}: planned for other target areas than "
        "scene.blend's (its targets_fingerprint differs): is it this ground's plan?"
    ], stderr
    assert code in (0, 3)
    doc = json.loads((tmp_path / "other" / "result.json").read_text())
    assert doc["metrics"]["existing_sensors"] == len(scratch["sensors"])

    code, _, stderr = run_headless(
        "optimize", SAMPLES / "flat_wall.blend", *_goal(tmp_path), "--out-dir",
        tmp_path / "far", "--existing", SAMPLES / "two_routes_sensors.json",
    )  # fmt: skip
    assert (
        f"warning: --existing {SAMPLES / 'two_routes_sensors.json'}: 18 of its 18 sensor(s) "
        "stand outside every sensor area of flat_wall.blend; they are counted as standing "
        "all the same"
    ) in stderr.splitlines(), stderr
