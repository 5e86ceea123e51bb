"""The optimization loop on small analytic scenes: goal, determinism, resume, honest
stops, metrics."""

from dataclasses import replace

import numpy as np
import pytest
import shapely

from autoscoop_blender.core.es import ESParams
from autoscoop_blender.core.optimize import (
    OptimizationRun,
    OptimizeSettings,
    reference_footprint_m2,
)
from autoscoop_blender.core.raycast import BoxCaster
from autoscoop_blender.core.scene_model import Area, SceneModel
from autoscoop_blender.core.sensors import PAPER_CAMERA
from tests.core.flat import box_mesh

FAST = OptimizeSettings(rho=0.9, es=ESParams(mu=12, lam=6, max_epochs=10))
BOX = ((30.0, 8.0, 0.0), (34.0, 12.0, 4.0))


def road_scene(extra_targets=()):
    """A 100 m x 14 m road, two sensor strips beside it, one box (a hut) by the road."""
    vertices, faces = box_mesh([BOX])
    return SceneModel(
        vertices=vertices,
        faces=faces,
        occluders=("Hut",),
        targets=(Area("Target_Road", shapely.box(0, -7, 100, 7)), *extra_targets),
        sensor_areas=(
            Area("SensorArea_N", shapely.box(0, 10, 100, 14)),
            Area("SensorArea_S", shapely.box(0, -14, 100, -10), height_m=9.0),
        ),
    )


def run(scene=None, settings=FAST, **kw):
    r = OptimizationRun(
        scene or road_scene(), BoxCaster([BOX], ground_z=0.0), PAPER_CAMERA, settings, **kw
    )
    return r, r.result()


def poses(result):
    return [(s.pose.x, s.pose.y, s.pose.pitch_deg, s.pose.yaw_deg) for s in result.sensors]


def test_reaches_the_goal_and_reports_consistent_metrics():
    _, res = run()
    m = res.metrics
    assert res.stop_reason.startswith("reached rho")
    assert m["coverage_fraction"] >= 0.9
    assert m["coverage_fraction"] == pytest.approx(res.summary.coverage_fraction)
    assert m["sensors"] == len(res.sensors) and m["masts"] == len(res.masts)
    assert m["cluster_ratio"] == pytest.approx(m["masts"] / m["sensors"], abs=1e-4)
    covered = sum(len(c.covered) for c in res.coverages)
    assert m["overlap_factor"] == pytest.approx(covered / res.grid.n_targets, abs=1e-4)
    # Every sensor is on exactly one mast; masts list their sensors.
    on_masts = sorted(k for *_, members in res.masts for k in members)
    assert on_masts == list(range(1, len(res.sensors) + 1))
    # Heights follow the sensor areas: 9 m on the south strip, the model's 7 m north.
    for s in res.sensors:
        assert s.pose.height_m == (9.0 if s.pose.y < 0 else 7.0)
    assert m["rays_cast"] > 0 and m["mean_epochs_per_sensor"] >= 1


def test_same_seed_same_answer_other_seed_other_answer():
    a, b = run()[1], run()[1]
    assert poses(a) == poses(b)
    c = run(settings=replace(FAST, seed=1))[1]
    assert poses(c) != poses(a)


def test_resume_goes_on_exactly_as_before():
    records = []
    full = run(on_fixed=records.append)[1]
    assert len(records) == len(full.sensors) >= 3
    assert [r["n"] for r in records] == list(range(1, len(records) + 1))
    resumed = run(resume=records[:2])[1]
    assert poses(resumed) == poses(full)
    assert resumed.metrics["coverage_fraction"] == full.metrics["coverage_fraction"]


def test_an_unseeable_target_stops_the_run_and_is_named():
    far = Area("Target_Far", shapely.box(400, 400, 430, 420))  # 600 m away
    _, res = run(road_scene([far]), replace(FAST, rho=0.97))
    assert "cannot be seen" in res.stop_reason
    named = [p for p in res.uncovered if p["target"] == "Target_Far"]
    assert len(named) == 1 and named[0]["m2"] == pytest.approx(600.0)
    assert named[0]["x"] == pytest.approx(415.0) and named[0]["y"] == pytest.approx(410.0)
    # It still covered the road it could see.
    road = res.summary.n_covered[res.grid.target_region == 0] > 0
    assert road.mean() > 0.9


def test_max_sensors_caps_the_run():
    _, res = run(settings=replace(FAST, rho=1.0, max_sensors=2))
    assert len(res.sensors) == 2 and "max_sensors" in res.stop_reason


def test_reference_footprint_is_the_papers():
    assert reference_footprint_m2(PAPER_CAMERA) == pytest.approx(1229.95, rel=0.02)


def test_bad_settings():
    from autoscoop_blender.core.errors import InputError

    with pytest.raises(InputError, match="rho"):
        replace(FAST, rho=1.5).validated()
    with pytest.raises(InputError, match="unknown setting"):
        OptimizeSettings.from_mapping({"rhoo": 0.9}, "c.toml")
    with pytest.raises(InputError, match=r"\[es\]: unknown setting"):
        OptimizeSettings.from_mapping({"es": {"muu": 3}}, "c.toml")
    with pytest.raises(InputError, match="must be a number"):
        OptimizeSettings.from_mapping({"rho": "high"}, "c.toml")
    s = OptimizeSettings.from_mapping({"rho": 0.9, "es": {"mu": 8}}, "c.toml")
    assert s.rho == 0.9 and s.es.mu == 8 and s.es.lam == 20
    assert np.isfinite(s.fitness.band_m)


def test_worker_processes_give_the_same_answer():
    """Workers are sent only the sensors fixed since their last chunk; on a resumed run
    the first chunk brings them the replayed ones."""
    records = []
    _, alone = run(on_fixed=records.append)
    assert len(alone.sensors) >= 3
    r, together = run(workers=2)
    assert poses(together) == poses(alone)
    assert together.metrics["coverage_fraction"] == alone.metrics["coverage_fraction"]
    assert together.metrics["evaluations"] == alone.metrics["evaluations"]
    assert r._pool is None  # the workers are gone at the end
    resumed = run(resume=records[:2], workers=2)[1]
    assert poses(resumed) == poses(alone)


def test_greedy_reaches_the_goal_with_no_more_sensors_than_the_es():
    greedy_settings = replace(FAST, optimizer="greedy")
    _, es = run()
    _, gr = run(settings=greedy_settings)
    assert gr.metrics["coverage_fraction"] >= 0.9 and gr.stop_reason.startswith("reached rho")
    assert gr.metrics["sensors"] <= es.metrics["sensors"]
    # Each fixed sensor's recorded gain is what it added, in order; same answer twice.
    assert [s.fitness for s in gr.sensors] == [float(s.new_points) for s in gr.sensors]
    assert poses(run(settings=greedy_settings)[1]) == poses(gr)


def test_greedy_picks_the_candidate_that_adds_most():
    """The first greedy sensor covers at least as much as any candidate pose (a
    sample of them, evaluated one by one)."""
    from autoscoop_blender.core import greedy

    _, res = run(settings=replace(FAST, optimizer="greedy", rho=0.3))
    first = res.sensors[0].new_points
    angles = greedy.orientations(PAPER_CAMERA.pitch_min_deg, PAPER_CAMERA.pitch_max_deg)
    best = 0
    fresh = OptimizationRun(road_scene(), BoxCaster([BOX], ground_z=0.0), PAPER_CAMERA, FAST)
    for x, y in fresh.space.positions[::7]:
        for p, yw in angles[::5]:
            cov, _ = fresh.evaluate(fresh.pose(x, y, p, yw))
            best = max(best, len(cov.covered))
    assert first >= best


def test_greedy_prefers_a_mast_already_standing_when_it_adds_nearly_as_much():
    from autoscoop_blender.core.greedy import MAST_PREFERENCE, pick_candidate

    best = 100.0
    near = best / (1 + MAST_PREFERENCE) + 1  # on a mast, just inside the preference
    far = best / (1 + MAST_PREFERENCE) - 1  # on a mast, just outside it
    assert pick_candidate(np.array([best, near]), np.array([False, True])) == 1
    assert pick_candidate(np.array([best, far]), np.array([False, True])) == 0
    # Without masts in play it is the plain largest gain, the first on ties.
    assert pick_candidate(np.array([3.0, 7.0, 7.0]), np.zeros(3, bool)) == 1


def test_greedy_needs_the_targeted_method():
    from autoscoop_blender.core.errors import InputError

    with pytest.raises(InputError, match="greedy optimizer needs the targeted method"):
        replace(FAST, optimizer="greedy", method="pointcloud").validated()
