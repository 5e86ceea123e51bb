"""``./dev.sh bench bound``'s bookkeeping: which scenes it plans, and how a run of some
of them keeps the others' figures. Nothing here plans a scene (the bench takes about an
hour)."""

from __future__ import annotations

import argparse

from tests.conftest import ROOT
from tools import suite
from tools.xodr_bench import FILES, XODR


def test_a_scene_measured_again_replaces_its_rows_and_keeps_the_others():
    before = {
        "date": "2026-11-26",
        "measured": {"b": {"date": "2026-12-01", "machine": "m1"}},
        "scenes": {"a": [{"cost": 1}], "b": [{"cost": 2}], "c": [{"cost": 3}]},
    }
    fresh = {"b": [{"cost": 20}], "d": [{"cost": 40}]}
    merged = suite.merged_bound(before, fresh, "2026-12-07", "m2")
    assert merged["scenes"] == {
        "a": [{"cost": 1}],
        "b": [{"cost": 20}],
        "c": [{"cost": 3}],
        "d": [{"cost": 40}],
    }
    assert list(merged["scenes"]) == ["a", "b", "c", "d"]  # the chart's panels keep their places
    assert merged["measured"] == {
        "a": {"date": "2026-11-26", "machine": None},  # no date of its own: the section's
        "b": {"date": "2026-12-07", "machine": "m2"},
        "c": {"date": "2026-11-26", "machine": None},
        "d": {"date": "2026-12-07", "machine": "m2"},
    }
    assert merged["date"] == "2026-12-07"
    assert before["scenes"]["b"] == [{"cost": 2}]  # the earlier section is not changed


def test_a_whole_run_keeps_nothing_from_before():
    merged = suite.merged_bound(None, {"x": [{"cost": 5}]}, "2026-12-07", "m")
    assert merged["scenes"] == {"x": [{"cost": 5}]}
    assert merged["measured"] == {"x": {"date": "2026-12-07", "machine": "m"}}


def test_the_full_plan_charts_every_opendrive_file_and_k_2_and_quick_only_the_samples():
    full = suite.bound_scenes(suite.FULL)
    for name in FILES:
        assert full[name].source == f"{name}.xodr"
        assert (XODR / full[name].source).is_file()
        assert "lp" in full[name].runs
    assert full["two_routes, coverage_k = 2"].coverage_k == 2
    assert full["full_ground, 3 tiles"].tiles == (1, 2, 3)
    for how in full.values():
        assert set(how.runs) <= set(suite.BOUND_RUNS)
        if not how.source.endswith(".xodr"):
            assert (ROOT / "sample_blends" / f"{how.source}.blend").is_file()
    quick = suite.bound_scenes(suite.QUICK)
    assert list(quick) == ["two_routes", "full_ground, 1 tiles"]


def test_an_unknown_scene_is_refused_before_anything_runs(tmp_path, capsys, monkeypatch):
    def never(*args):
        raise AssertionError("nothing may be measured")

    monkeypatch.setattr(suite, "_in_fresh_process", never)
    args = argparse.Namespace(
        quick=False, out_dir=str(tmp_path), charts_dir=str(tmp_path), scenes="Town01; Town99"
    )
    assert suite.run_bound(args) == 2
    out = capsys.readouterr().err
    assert "no scene 'Town99'" in out and "Town01" in out
    assert not (tmp_path / "results.json").exists()
