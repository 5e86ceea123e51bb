"""The optimization pipeline on small analytic scenes: goal, determinism, resume, honest
stops, metrics; the optimizers behind one protocol; a result that holds no caster."""

import dataclasses
from dataclasses import replace

import numpy as np
import pytest
import shapely

from autoscoop_blender.core.candidates import build_candidates
from autoscoop_blender.core.coverage.reference import reference_footprint_m2
from autoscoop_blender.core.coverage.targeted import TargetedEvaluator
from autoscoop_blender.core.geom.grid import GroundGrid
from autoscoop_blender.core.geom.raycast import BoxCaster
from autoscoop_blender.core.model.scene import Area, SceneModel
from autoscoop_blender.core.model.sensors import PAPER_CAMERA
from autoscoop_blender.core.optimize.base import Solution
from autoscoop_blender.core.optimize.es import EvolutionStrategy
from autoscoop_blender.core.optimize.greedy import Greedy
from autoscoop_blender.core.problem import Problem, orientations
from autoscoop_blender.core.result import Result
from autoscoop_blender.core.run import Run
from autoscoop_blender.core.settings import ESParams, OptimizeSettings
from tests.core.flat import box_caster, box_mesh
from tests.core.test_lp import drain, steps

FAST = OptimizeSettings(optimizer="es", rho=0.9, es=ESParams(mu=12, lam=6, max_epochs=10))
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
    r = Run(scene or road_scene(), box_caster([BOX]), PAPER_CAMERA, settings, **kw)
    return r, r.result()


def poses(result):
    return [(s.x, s.y, s.pitch_deg, s.yaw_deg) for s in result.sensors]


def test_reaches_the_goal_and_reports_consistent_metrics():
    _, res = run()
    m = res.metrics
    assert res.stop_reason.startswith("Reached the goal")
    assert m["coverage_fraction"] >= 0.9
    assert m["coverage_fraction"] == pytest.approx((res.n_covered > 0).mean())
    assert m["sensors"] == len(res.sensors) and m["masts"] == len(res.masts)
    assert m["cluster_ratio"] == pytest.approx(m["masts"] / m["sensors"], abs=1e-4)
    # 1 m grid: one target point per m^2 of the 100 x 14 m road.
    assert len(res.points) == m["target_area_m2"] == 1400
    covered = sum(s.covered_target_m2 for s in res.sensors)
    assert m["overlap_factor"] == pytest.approx(covered / 1400, abs=1e-4)
    assert covered == res.n_covered.sum()  # each sensor's points are counted once each
    # Every sensor is on exactly one mast; masts list their sensors.
    on_masts = sorted(k for mast in res.masts for k in mast.sensors)
    assert on_masts == list(range(1, len(res.sensors) + 1))
    # Heights follow the sensor areas: 9 m on the south strip, the model's 7 m north.
    for s in res.sensors:
        assert s.height_m == (9.0 if s.y < 0 else 7.0)
        assert s.z == s.height_m  # flat ground at z = 0
        assert s.sensor_area == ("SensorArea_S" if s.y < 0 else "SensorArea_N")
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
    assert "cannot be reached" in res.stop_reason
    named = [p for p in res.uncovered if p["target"] == "Target_Far"]
    assert len(named) == 1 and named[0]["m2"] == pytest.approx(600.0)
    assert named[0]["x"] == pytest.approx(415.0) and named[0]["y"] == pytest.approx(410.0)
    # It still covered the road it could see.
    road = res.points[:, 0] <= 100
    assert road.sum() == 1400 and (res.n_covered[road] > 0).mean() > 0.9


def test_max_sensors_caps_the_run():
    _, res = run(settings=replace(FAST, rho=1.0, max_sensors=2))
    assert len(res.sensors) == 2 and "max_sensors" in res.stop_reason


def test_reference_footprint_is_the_papers():
    assert reference_footprint_m2(PAPER_CAMERA) == pytest.approx(1229.95, rel=0.02)


def test_worker_processes_give_the_same_answer():
    """Workers are built from the grid's arrays and a caster factory; they are sent only
    the sensors fixed since their last chunk, and on a resumed run the first chunk
    brings them the replayed ones."""
    records = []
    _, alone = run(on_fixed=records.append)
    assert len(alone.sensors) >= 3
    r, together = run(workers=2)
    assert poses(together) == poses(alone)
    assert together.metrics["coverage_fraction"] == alone.metrics["coverage_fraction"]
    assert together.metrics["evaluations"] == alone.metrics["evaluations"]
    # Each worker casts a position's sight lines once for itself: no fewer in all.
    assert together.metrics["rays_cast"] >= alone.metrics["rays_cast"]
    assert r.optimizer.pool is None  # the workers are gone at the end
    resumed = run(resume=records[:2], workers=2)[1]
    assert poses(resumed) == poses(alone)


def test_a_result_holds_no_caster_grid_or_problem():
    """Everything after the optimizer reads plain data: no field of the result, at any
    depth, is a caster, a grid or the problem, so nothing downstream can cast a ray."""
    _, res = run()
    found = []

    def walk(value, path):
        if isinstance(value, (GroundGrid, Problem, BoxCaster)) or hasattr(value, "cast"):
            found.append(path)
        elif dataclasses.is_dataclass(value) and not isinstance(value, type):
            for f in dataclasses.fields(value):
                walk(getattr(value, f.name), f"{path}.{f.name}")
        elif isinstance(value, (list, tuple)):
            for k, v in enumerate(value):
                walk(v, f"{path}[{k}]")
        elif isinstance(value, dict):
            for k, v in value.items():
                walk(v, f"{path}[{k!r}]")

    walk(res, "result")
    assert isinstance(res, Result) and found == []
    # Footprints come draped on the top surface: the hut's roof (z = 4 m) over its
    # plan, the ground (z = 0) everywhere else.
    xyz = np.concatenate([s.drape[0] for s in res.sensors if s.drape is not None])
    (x0, y0, _), (x1, y1, top) = BOX
    on_hut = (xyz[:, 0] > x0) & (xyz[:, 0] < x1) & (xyz[:, 1] > y0) & (xyz[:, 1] < y1)
    off_hut = (xyz[:, 0] < x0) | (xyz[:, 0] > x1) | (xyz[:, 1] < y0) | (xyz[:, 1] > y1)
    assert len(xyz) > 100 and np.all(xyz[off_hut, 2] == 0.0) and np.all(xyz[on_hut, 2] == top)


def test_optimizers_run_on_a_problem_without_a_run():
    """The protocol: an optimizer takes a Problem and a Solution, yields progress and
    returns the solution; it needs nothing of the Run."""
    problem = Problem(road_scene(), BoxCaster([BOX], ground_z=0.0), PAPER_CAMERA, FAST)
    for optimizer in (Greedy(), EvolutionStrategy()):
        solution = Solution(np.zeros(problem.n_targets, dtype=bool))
        returned, progress = steps(optimizer.solve(problem, solution))
        phases = [p.phase for p in progress]
        assert returned is solution and problem.reached(solution.n_covered)
        assert phases.count("fixed") == len(solution.sensors) >= 1
        # The covered points are exactly the union of what the sensors newly covered.
        union = np.zeros(problem.n_targets, dtype=bool)
        for s in solution.sensors:
            assert not union[s.newly].any()
            union[s.newly] = True
        assert np.array_equal(union, solution.covered)


def test_candidate_rows_are_what_each_pose_covers():
    """Each row of the candidate matrix holds exactly the points ``targeted`` covers
    from that candidate's pose (a sample of rows, evaluated one by one afresh)."""
    problem = Problem(road_scene(), BoxCaster([BOX], ground_z=0.0), PAPER_CAMERA, FAST)
    cands = drain(build_candidates(problem))
    angles = orientations(PAPER_CAMERA.pitch_min_deg, PAPER_CAMERA.pitch_max_deg)
    assert len(angles) == 36 * 6 and np.array_equal(cands.angles[0], angles)
    assert cands.matrix.shape == (len(cands), problem.n_targets) and len(cands) > 1000
    fresh = TargetedEvaluator(
        GroundGrid(road_scene(), BoxCaster([BOX], ground_z=0.0), 1.0, reach_m=80.0),
        BoxCaster([BOX], ground_z=0.0),
    )
    for c in range(0, len(cands), 97):
        pose = cands.pose(problem, c)
        expected = np.sort(fresh.evaluate(PAPER_CAMERA, pose).covered)
        assert np.array_equal(cands.matrix[c].indices, expected)


def test_greedy_reaches_the_goal_with_no_more_sensors_than_the_es():
    greedy_settings = replace(FAST, optimizer="greedy")
    _, es = run()
    _, gr = run(settings=greedy_settings)
    assert gr.metrics["coverage_fraction"] >= 0.9 and gr.stop_reason.startswith("Reached the goal")
    assert gr.metrics["sensors"] <= es.metrics["sensors"]
    # Each fixed sensor's recorded gain is what it added, in order: they sum to the
    # points covered before masts were formed (grouping here moves no sensor).
    assert sum(s.fitness for s in gr.sensors) == (gr.n_covered > 0).sum()
    assert poses(run(settings=greedy_settings)[1]) == poses(gr)


def test_greedy_picks_the_candidate_that_adds_most():
    """The first greedy sensor covers at least as much as any candidate pose (a
    sample of them, evaluated one by one)."""
    _, res = run(settings=replace(FAST, optimizer="greedy", rho=0.3))
    first = res.sensors[0].fitness
    angles = orientations(PAPER_CAMERA.pitch_min_deg, PAPER_CAMERA.pitch_max_deg)
    best = 0
    fresh = Problem(road_scene(), BoxCaster([BOX], ground_z=0.0), PAPER_CAMERA, FAST)
    for x, y in fresh.space.positions[::7]:
        for p, yw in angles[::5]:
            best = max(best, len(fresh.evaluate(fresh.pose(x, y, p, yw)).covered))
    assert first >= best > 0


def test_greedy_prefers_a_mast_already_standing_when_it_adds_nearly_as_much():
    from autoscoop_blender.core.optimize.greedy import MAST_PREFERENCE, pick_candidate

    best = 100.0
    on_mast = np.array([False, True])
    for objective, p in MAST_PREFERENCE.items():
        near = best / (1 + p) + 1  # on a mast, just inside the preference
        far = best / (1 + p) - 1  # on a mast, just outside it
        assert pick_candidate(np.array([best, near]), on_mast, objective) == 1
        assert pick_candidate(np.array([best, far]), on_mast, objective) == 0
        # Without masts in play it is the plain largest gain, the first on ties.
        assert pick_candidate(np.array([3.0, 7.0, 7.0]), np.zeros(3, bool), objective) == 1
    # The objective decides: fewer sensors prefer a standing mast less than cost does.
    between = best / (1 + (MAST_PREFERENCE["cost"] + MAST_PREFERENCE["sensors"]) / 2)
    assert pick_candidate(np.array([best, between]), on_mast, "cost") == 1
    assert pick_candidate(np.array([best, between]), on_mast, "sensors") == 0
    assert pick_candidate(np.array([best, between]), on_mast) == 1  # cost, the default
