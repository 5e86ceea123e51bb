"""The report's work done ahead (``core/ahead.py``) and the mast grouping's reuse of the
fixed sensors' own coverage: a finish that casts no ray for what it knows, and the
same report as one made afresh."""

import numpy as np
import pytest
import shapely

from autoscoop_blender.core import ahead
from autoscoop_blender.core.ahead import ReportAhead
from autoscoop_blender.core.evaluate import evaluate_layout
from autoscoop_blender.core.model.sensors import PAPER_CAMERA, SensorSpec
from autoscoop_blender.core.optimize.base import FixedSensor
from autoscoop_blender.core.run import Run
from autoscoop_blender.core.settings import CoverageSettings, OptimizeSettings
from tests.core.flat import box_caster
from tests.core.test_optimize import BOX, road_scene

GREEDY = OptimizeSettings(optimizer="greedy", rho=0.9)


def counted(run, name):
    """Wrap ``run.problem.<name>``: each call appends the phase the run was in."""
    calls = []
    real = getattr(run.problem, name)

    def spy(*args, **kw):
        calls.append(run.phase)
        return real(*args, **kw)

    setattr(run.problem, name, spy)
    return calls


def drive(run):
    """Run to the end, keeping ``run.phase`` as the last progress said."""
    run.phase = "start"
    for p in run.steps():
        run.phase = p.phase
    return run.result()


def test_a_run_whose_sensors_were_evaluated_ahead_reports_them_without_a_ray(monkeypatch):
    """With the work ahead free to take all the time, every fixed sensor is made ready
    between progress reports: the report evaluates nothing more, and says what a fresh
    count of the same sensors (``headless coverage``'s path) says."""
    monkeypatch.setattr(ahead, "WARM_SHARE", 1.0)
    run = Run(road_scene(), box_caster([BOX]), PAPER_CAMERA, GREEDY)
    full = counted(run, "evaluate_full")
    res = drive(run)
    assert len(res.sensors) >= 2
    assert full and "report" not in full and "done" not in full
    specs = [
        SensorSpec(PAPER_CAMERA, s.x, s.y, s.height_m, s.pitch_deg, s.yaw_deg) for s in res.sensors
    ]
    fresh = evaluate_layout(road_scene(), box_caster([BOX])(), specs, CoverageSettings())
    assert np.array_equal(res.n_covered, fresh.n_covered)
    for got, want in zip(res.sensors, fresh.sensors):
        assert got.footprint_m2 == want.footprint_m2
        assert got.covered_target_m2 == want.covered_target_m2
        assert shapely.equals(got.footprint, want.footprint)
        assert np.array_equal(got.drape[0], want.drape[0])
        assert got.sensor_area == want.sensor_area


def test_the_masts_take_the_coverage_each_sensor_was_fixed_with():
    """Sensors that stay where they were fixed are not evaluated again to group them
    (on Town04 that cost 6 s of a stopped run's 4.5 s)."""
    run = Run(road_scene(), box_caster([BOX]), PAPER_CAMERA, GREEDY)
    plain = counted(run, "evaluate")
    res = drive(run)
    moved = len(res.sensors) - len({(s.x, s.y) for s in res.sensors})
    assert plain.count("masts") <= moved  # only a moved sensor is evaluated anew


def fixed_at(problem, x, yaw):
    pose = problem.pose(x, 12.0, 30.0, yaw, 0)
    cov = problem.evaluate(pose)
    return FixedSensor(pose, 0.0, 0, 0, cov.covered, cov.covered)


def test_the_work_ahead_follows_the_plan_and_keeps_to_its_share(monkeypatch):
    monkeypatch.setattr(ahead, "WARM_SLICE_S", 0.0)
    run = Run(road_scene(), box_caster([BOX]), PAPER_CAMERA, GREEDY)
    p = run.problem
    a, b = fixed_at(p, 20.0, 270.0), fixed_at(p, 60.0, 250.0)
    work = ReportAhead(p)
    work.warm([a, b], elapsed_s=1e9)  # one sensor a call when the slice is spent
    assert work.ready(a.pose, 0) and not work.ready(b.pose, 0)
    work.warm([b], elapsed_s=1e9)  # a left the plan: forgotten
    assert work.ready(b.pose, 0) and not work.ready(a.pose, 0)
    # Past its share of the run's time, it waits.
    work.warm([a, b], elapsed_s=work.spent_s / ahead.WARM_SHARE / 2)
    assert not work.ready(a.pose, 0)
    # What it hands out is the pose's own evaluation, not a neighbour's.
    cov, pieces = work.get(a.pose, 0)
    assert cov.pose == a.pose and np.array_equal(cov.covered, a.seen)
    assert pieces.footprint.area == pytest.approx(cov.footprint_m2)
    assert pieces.sensor_area == "SensorArea_N"


def test_the_sensors_the_lp_would_fix_are_made_ready_after_those_fixed(monkeypatch):
    """``planned`` (the lp's best plan so far) comes after the fixed sensors, and a
    pose in neither is forgotten; with a slice to spare, several a call."""
    monkeypatch.setattr(ahead, "WARM_SLICE_S", 0.0)
    run = Run(road_scene(), box_caster([BOX]), PAPER_CAMERA, GREEDY)
    p = run.problem
    a, b, c = (fixed_at(p, x, 270.0) for x in (20.0, 40.0, 60.0))
    work = ReportAhead(p)
    work.warm([a], elapsed_s=1e9, planned=[(b.pose, 0)])
    assert work.ready(a.pose, 0) and not work.ready(b.pose, 0)
    work.warm([a], elapsed_s=1e9, planned=[(b.pose, 0)])
    assert work.ready(b.pose, 0)
    work.warm([a], elapsed_s=1e9, planned=[(c.pose, 0)])  # a better plan: b is gone
    assert work.ready(c.pose, 0) and not work.ready(b.pose, 0)
    monkeypatch.setattr(ahead, "WARM_SLICE_S", 1e9)
    fresh = ReportAhead(p)
    fresh.warm([], elapsed_s=1e9, planned=[(s.pose, 0) for s in (a, b, c)])
    assert all(fresh.ready(s.pose, 0) for s in (a, b, c))


def test_an_lp_run_stopped_early_finds_its_best_plan_evaluated_ahead(monkeypatch):
    """The lp fixes its sensors only when its plan is done; the best plan so far is
    made ready while it searches, so a run stopped once it is ready evaluates no
    sensor for its report, and fixes no sensor outside that plan."""
    monkeypatch.setattr(ahead, "WARM_SHARE", 1.0)
    monkeypatch.setattr(ahead, "WARM_SLICE_S", 1e9)
    lp = OptimizeSettings(optimizer="lp", rho=0.9, time_limit_s=120.0)
    run = Run(road_scene(), box_caster([BOX]), PAPER_CAMERA, lp)
    full = counted(run, "evaluate_full")
    held: list = []
    run.phase = "start"
    for progress in run.steps():
        run.phase = progress.phase
        planned = run.solution.ahead
        if not held and progress.best is not None and planned:
            if all(run.ahead.ready(pose, m) for pose, m in planned):
                held = list(planned)
                assert run.stop_early()
    res = run.result()
    assert held, "the lp never held a plan"
    assert res.interrupted is False and "Stopped early" in res.stop_reason
    assert {(f.pose, f.model) for f in run.solution.sensors} <= set(held)
    assert "report" not in full and "done" not in full
