"""The lp optimizer part by part (``optimize/parts.py``): the same candidates as the
whole ground's, split without loss; a bound that never passes the whole ground's; a
joined plan whose coverage an independent recount confirms; stop and resume."""

from __future__ import annotations

import math
import threading
import time
from collections import Counter
from dataclasses import replace

import numpy as np
import pytest
import shapely
from numpy.typing import NDArray
from scipy import sparse

from autoscoop_blender.core import budget
from autoscoop_blender.core.candidates import (
    CandidateSet,
    PartCandidates,
    build_candidates,
    build_part,
)
from autoscoop_blender.core.coverage.base import place
from autoscoop_blender.core.coverage.targeted import TargetedEvaluator
from autoscoop_blender.core.geom.grid import GroundGrid
from autoscoop_blender.core.model.scene import Area, SceneModel
from autoscoop_blender.core.model.sensors import PAPER_CAMERA, SensorPose
from autoscoop_blender.core.optimize import lp as lp_module
from autoscoop_blender.core.optimize import parts as parts_module
from autoscoop_blender.core.optimize import planner
from autoscoop_blender.core.optimize.base import (
    FixedSensor,
    Solution,
    StopReason,
    fix_candidate,
    newly_covered,
)
from autoscoop_blender.core.optimize.bound import SiteSolution, parts_of
from autoscoop_blender.core.optimize.cover import CoverInstance
from autoscoop_blender.core.optimize.parts import LocalBuilder
from autoscoop_blender.core.problem import Problem
from autoscoop_blender.core.run import Run
from autoscoop_blender.core.settings import OptimizeSettings
from tests.core.flat import box_caster, box_mesh
from tests.core.test_lp import drain

# A road 240 m long with a strip for masts beside it, and a wall that hides a stretch of
# it from the strip's middle: 600 target points at 2 m, three parts of 200.
ROAD = shapely.box(0, -5, 240, 5)
STRIP = shapely.box(0, 8, 240, 12)
WALL = [((110.0, 6.0, 0.0), (130.0, 7.0, 8.0))]
PART_POINTS = 200


def road(k: int | None = None) -> SceneModel:
    vertices, faces = box_mesh(WALL)
    return SceneModel(
        vertices=vertices,
        faces=faces,
        occluders=("Wall",),
        targets=(Area("Road", ROAD, coverage_k=k),),
        sensor_areas=(Area("Strip", STRIP),),
    )


def recount(scene: SceneModel, result) -> NDArray[np.int64]:
    """(N,) sensors covering each target point, each sensor evaluated afresh by the
    plain targeted evaluator on a grid of its own (not the optimizer's cached probe)."""
    caster = box_caster(WALL)()
    grid = GroundGrid(scene, caster, result.cell_m, reach_m=PAPER_CAMERA.range_m)
    ev = TargetedEvaluator(grid, caster)
    counts = np.zeros(grid.n_targets, dtype=np.int64)
    for f in result.sensors:
        x, y = np.array([f.x, f.y]) - result.origin[:2]
        pose = place(grid, x, y, f.height_m, f.pitch_deg, f.yaw_deg)
        counts[ev.evaluate(PAPER_CAMERA, pose).covered] += 1
    return counts


def settings(**kw) -> OptimizeSettings:
    return OptimizeSettings(optimizer="lp", grid_m=2.0, position_step_m=4.0, **kw)


@pytest.fixture
def small_parts(monkeypatch):
    """Parts of ``PART_POINTS`` points (the road: 3 parts) while the test runs."""
    monkeypatch.setattr(budget, "PART_POINTS", PART_POINTS)


def test_the_parts_candidates_are_the_whole_grounds_split_by_point(small_parts):
    """Every (candidate, point) of the whole ground's matrix is in exactly one part's,
    and the parts' shares of a candidate add up to 1 (so its cost is paid once)."""
    problem = Problem(road(), box_caster(WALL)(), PAPER_CAMERA, settings())
    assert problem.estimate.parts == math.ceil(problem.n_targets / PART_POINTS) == 3
    whole = drain(build_candidates(problem))
    key = {
        (int(p), int(o), int(m)): c
        for c, (p, o, m) in enumerate(zip(whole.position, whole.orientation, whole.model))
    }
    split = parts_of(problem.grid.target_xy, 3)
    got = np.zeros(whole.matrix.shape, dtype=np.int32)
    share = np.zeros(len(whole))
    for k in range(3):
        points = np.flatnonzero(split == k)
        part = drain(build_part(problem, points, PAPER_CAMERA.range_m))
        cands = part.cands
        assert cands.matrix.shape[1] == len(points)
        for c in range(len(cands)):
            w = key[(int(cands.position[c]), int(cands.orientation[c]), int(cands.model[c]))]
            got[w, points[cands.matrix[c].indices]] += 1
            share[w] += part.share[c]
        assert set(part.sites.tolist()) == set(cands.position.tolist())
        assert np.all((part.site_share > 0) & (part.site_share <= 1))
    np.testing.assert_array_equal(got, whole.matrix.toarray().astype(np.int32))
    np.testing.assert_allclose(share, 1.0)


def test_a_position_two_parts_reach_is_cast_once_and_builds_the_same(small_parts):
    """The local builder keeps what a position shared with a later part gave: each
    (position, model) is cast once over the three parts, each part's candidates are
    those built afresh, and nothing is kept after the last part."""
    problem = Problem(road(), box_caster(WALL)(), PAPER_CAMERA, settings())
    split = parts_of(problem.grid.target_xy, 3)
    parts = [np.flatnonzero(split == k) for k in range(3)]
    fresh = [drain(build_part(problem, points, PAPER_CAMERA.range_m)) for points in parts]
    near = [set(f.cands.position.tolist()) for f in fresh]
    assert near[0] & near[1] and near[1] & near[2]  # the parts share positions
    calls = []
    real = problem.probe.cover_many

    def counted(model, pose, rots):
        calls.append((pose.x, pose.y))
        return real(model, pose, rots)

    problem.probe.cover_many = counted
    builder = LocalBuilder()
    builder.start(problem, parts, PAPER_CAMERA.range_m)
    for k, want in enumerate(fresh):
        got = drain(builder.build(k))
        for name in ("position", "orientation", "model", "share", "sites", "site_share"):
            a, b = getattr(got, name, None), getattr(want, name, None)
            if a is None:
                a, b = getattr(got.cands, name), getattr(want.cands, name)
            np.testing.assert_array_equal(a, b)
        assert (got.cands.matrix != want.cands.matrix).nnz == 0
        assert got.cands.dominated == want.cands.dominated
        assert got.cands.dominated_nonzeros == want.cands.dominated_nonzeros
    # Every position within range of some point, once (ranges by brute force).
    xy, targets = problem.space.positions, problem.grid.target_xy
    gap = np.hypot(*(xy[:, None, :] - targets[None, :, :]).transpose(2, 0, 1)).min(axis=1)
    assert len(calls) == len(set(calls)) == np.count_nonzero(gap <= PAPER_CAMERA.range_m)
    assert len(builder.shared) == 0


@pytest.mark.parametrize("k", [1, 2])
def test_the_part_wise_bound_never_passes_the_whole_grounds(k, monkeypatch):
    """The same road whole and in 3 parts: every part-wise bound (sensors, masts, cost)
    is at most the whole ground's, which is at most the whole plan's; the joined plan
    covers the goal, as a recount with a fresh evaluator says. No plan is rounded
    from the LP, whole or in parts: masts count."""
    s = settings(coverage_k=k, rho=0.9)
    rounded = []
    real = lp_module._lp_plans

    def lp_plans(*args, **kwargs):
        rounded.append(1)
        return real(*args, **kwargs)

    monkeypatch.setattr(lp_module, "_lp_plans", lp_plans)
    whole = Run(road(k), box_caster(WALL), PAPER_CAMERA, s).result()
    monkeypatch.setattr(budget, "PART_POINTS", PART_POINTS)
    run = Run(road(k), box_caster(WALL), PAPER_CAMERA, s)
    assert run.problem.estimate.parts == 3
    parts = run.result()
    assert not rounded
    w, p = whole.metrics, parts.metrics
    assert p["sensors_lower_bound"] <= w["sensors_lower_bound"] <= w["sensors"]
    assert p["masts_lower_bound"] <= w["masts_lower_bound"] <= w["masts"]
    assert p["lower_bound"] <= w["lower_bound"] <= w["cost"]
    assert p["lower_bound"] <= p["cost"]
    assert p["sensors_lower_bound"] >= 1 and "3 parts" in p["bound_scope"]
    counts = recount(road(k), parts)
    np.testing.assert_array_equal(counts, parts.n_covered)
    assert np.count_nonzero(counts >= k) >= math.ceil(0.9 * len(counts))
    assert parts.stop_reason.startswith("Reached the goal")


def _ledger_part(rows: list[list[int]], n_points: int, share: list[float]) -> PartCandidates:
    """Candidates 0.. at positions 0.. (one orientation each, of 2) covering ``rows``."""
    n = len(rows)
    indptr = np.cumsum([0, *map(len, rows)])
    indices = np.concatenate([np.asarray(r, dtype=np.int32) for r in rows])
    matrix = sparse.csr_matrix((np.ones(len(indices), np.float32), indices, indptr), (n, n_points))
    cands = CandidateSet(
        positions=np.zeros((4, 2)),
        angles=(np.zeros((2, 2)),),
        models=(PAPER_CAMERA,),
        position=np.arange(n, dtype=np.int64),
        orientation=np.ones(n, dtype=np.int64),
        model=np.zeros(n, dtype=np.int64),
        matrix=matrix,
    )
    return PartCandidates(cands, np.array(share), np.arange(n), np.ones(n))


def test_the_ledger_hands_on_what_a_parts_line_left_of_a_cost():
    """Candidate 0 covers 2 points in part A, 1 in B and 1 in C (shares 1/2, 1/4, 1/4);
    candidate 1 only A's. A's duals price candidate 0 at 0.2 (of its 0.5) and
    candidate 1 at 1.3 (above its 1): A takes 0.2 and 1. B gets 0.8 x 1/2 of candidate
    0 (more than its share 0.25), its duals take 0.1, and C the 0.7 left: the three
    add up to 1, the candidate's cost. (Figures by hand.)"""
    ledger = parts_module.CostLedger()
    a = _ledger_part([[0, 1], [1, 2]], 3, [0.5, 1.0])
    cost_a = ledger.costs(a, 1.0)
    np.testing.assert_allclose(cost_a, [0.5, 1.0])  # the first part's are its shares
    ledger.take(a, cost_a, a.cands.matrix, [np.array([0.1, 0.1, 1.2])])
    b = _ledger_part([[0]], 2, [0.25])
    cost_b = ledger.costs(b, 1.0)
    np.testing.assert_allclose(cost_b, [0.4])
    ledger.take(b, cost_b, b.cands.matrix, [np.array([0.1, 5.0])])
    c = _ledger_part([[1]], 2, [0.25])
    cost_c = ledger.costs(c, 1.0)
    np.testing.assert_allclose(cost_c, [0.7])
    assert 0.2 + 0.1 + cost_c[0] == pytest.approx(1.0)  # taken by A, by B, C's
    # A part with no line takes nothing: the parts after it share what is left.
    ledger = parts_module.CostLedger()
    ledger.take(a, ledger.costs(a, 1.0), a.cands.matrix, [])
    np.testing.assert_allclose(ledger.costs(b, 1.0), [0.5])


def test_the_ledger_keeps_what_the_highest_of_a_parts_lines_needs():
    """Part A has two lines (its goal's and one below it): the first's duals price
    candidate 0 at 0.2, the second's at 0.3; each line must still hold at A's costs,
    so A keeps 0.3 of its 0.5, and B gets (1 - 0.3) x 1/2 = 0.35 (its point of the two
    the candidate covers in B and C). (Figures by hand.)"""
    ledger = parts_module.CostLedger()
    a = _ledger_part([[0, 1], [1, 2]], 3, [0.5, 1.0])
    cost_a = ledger.costs(a, 1.0)
    lines = [np.array([0.1, 0.1, 1.2]), np.array([0.0, 0.3, 0.0])]
    ledger.take(a, cost_a, a.cands.matrix, lines)
    b = _ledger_part([[0]], 2, [0.25])
    np.testing.assert_allclose(ledger.costs(b, 1.0), [0.35])


def test_a_parts_lp_prices_each_candidate_at_most_at_what_the_parts_before_left(
    small_parts, monkeypatch
):
    """On the road in 3 parts: each part's sensors LP prices a candidate at no more than
    its cost less what the lines of the parts before took of it (what their duals
    price it at, at most their cost); a part after the first never gets less than its
    share and some candidates get more; and a candidate a part before fixed still
    covers its points in the LP of the part after (a plan of the whole ground may use
    it there)."""
    taken: dict[tuple[int, int, int], float] = {}
    checked: list[int] = []
    fixed_rows: list[NDArray[np.int64]] = []
    costs, take, real = (
        parts_module.CostLedger.costs,
        parts_module.CostLedger.take,
        parts_module.prove_and_plan,
    )

    def keys(part):
        c = part.cands
        return list(zip(c.position.tolist(), c.orientation.tolist(), c.model.tolist()))

    def spy_costs(self, part, unit):
        out = costs(self, part, unit)
        before = np.array([taken.get(key, 0.0) for key in keys(part)])
        assert np.all(out + before <= 1.0 + 1e-9)
        assert np.all(out >= part.share - 1e-12)
        checked.append(int(np.count_nonzero(out > part.share + 1e-6)))
        return out

    def spy_take(self, part, cost, matrix, pis):
        # What the lines' duals price each candidate at, the most of them, by hand.
        priced = np.max([matrix @ pi for pi in pis], axis=0)
        for key, value in zip(keys(part), np.minimum(cost, priced)):
            taken[key] = taken.get(key, 0.0) + float(value)
        return take(self, part, cost, matrix, pis)

    def spy(problem, cands, inst, solution, deadline, stop, part):
        fixed = parts_module.taken_candidates(cands, solution.sensors)
        fixed_rows.append(np.diff(part.lp_inst.matrix.indptr)[fixed])
        return (yield from real(problem, cands, inst, solution, deadline, stop, part))

    monkeypatch.setattr(parts_module.CostLedger, "costs", spy_costs)
    monkeypatch.setattr(parts_module.CostLedger, "take", spy_take)
    monkeypatch.setattr(parts_module, "prove_and_plan", spy)
    Run(road(), box_caster(WALL), PAPER_CAMERA, settings(rho=0.9)).result()
    assert len(checked) == len(fixed_rows) == 3
    assert checked[0] == 0 and checked[1] > 0 and checked[2] > 0
    rows = np.concatenate(fixed_rows)
    assert len(rows) > 0 and np.all(rows > 0)


def test_the_time_left_never_passes_the_runs_limit(small_parts):
    """A run in parts estimates what is left from the parts done so far, but never
    past its own time limit: with 1 s in all and parts that take longer, each
    estimate ends by the deadline (the estimate once the first part is done would
    otherwise be 2 parts' time)."""
    run = Run(road(), box_caster(WALL), PAPER_CAMERA, settings(rho=0.9, time_limit_s=1.0))
    deadline = run.problem.t0 + 1.0
    etas = []
    for p in run.steps():
        if p.eta_s is not None:
            etas.append(p.eta_s)
            assert p.eta_s <= max(0.0, deadline - time.perf_counter()) + 1e-6
    assert etas  # parts were done and estimates given


def test_the_re_plans_time_left_is_the_time_to_the_deadline(small_parts):
    """Once every part is done the re-plan over the seams may go on to the run's
    deadline, so that is what is left (the parts' rate, spent / 7 on Town04's eighth
    part, grew with every second of the re-plan)."""
    run = Run(road(), box_caster(WALL), PAPER_CAMERA, settings(rho=0.9, time_limit_s=600.0))
    limit = planner.time_limit(run.problem.settings, run.problem.estimate.parts)
    deadline = planner.search_deadline(run.problem.t0, limit)
    seams, bounds = [], []
    for p in run.steps():
        if p.stage == "seams":
            seams.append((p.eta_s, deadline - time.perf_counter()))
        if p.parts:
            bounds.append((p.part, p.bound))
    assert seams
    for eta, left in seams:
        assert left - 1.0 <= eta <= left + 1.0
    # Before its first part is solved nothing is proven, and no bound is shown
    # (a "bound 0" proves nothing); from the last part on, one is.
    assert bounds[0] == (1, None) and all(b is None or b > 0 for _, b in bounds)
    assert bounds[-1][0] == 3 and bounds[-1][1] > 0


def test_a_stopped_run_keeps_the_parts_done_and_resume_finishes_it(small_parts):
    """Stopped after its first part's sensors: the plan covers that part; resumed from
    those sensors, the run builds no candidates for the part done and reaches the goal
    with the same sensors first."""
    s = settings(rho=0.9)
    records: list[dict] = []
    run = Run(road(), box_caster(WALL), PAPER_CAMERA, s, on_fixed=records.append)
    built = []
    real = parts_module.build_part

    def spy(problem, points, reach_m, *shared):
        built.append(points)
        return real(problem, points, reach_m, *shared)

    parts_module.build_part = spy
    try:
        for progress in run.steps():
            if progress.phase == "search" and progress.stage == "part done":
                run.stop_early()
        first = run.result()
        assert len(built) == 1  # the second part was never started
        assert "Stopped early" in first.stop_reason
        assert 0 < first.metrics["coverage_fraction"] < 0.9
        assert first.metrics["sensors"] == len(records)
        built.clear()
        resumed = Run(road(), box_caster(WALL), PAPER_CAMERA, s, resume=records).result()
    finally:
        parts_module.build_part = real
    done_part = np.flatnonzero(parts_of(run.problem.grid.target_xy, 3) == 0)
    assert len(built) == 2 and not any(np.array_equal(b, done_part) for b in built)
    assert resumed.stop_reason.startswith("Reached the goal")
    before = [(r["x"], r["y"], r["pitch_deg"], r["yaw_deg"]) for r in records]
    after = [(x.x, x.y, x.pitch_deg, x.yaw_deg) for x in resumed.sensors[: len(before)]]
    origin = resumed.origin
    assert after == [(x + origin[0], y + origin[1], p, yw) for x, y, p, yw in before]


def test_prune_drops_what_the_seams_made_redundant():
    """Three sensors over points 0-5: the middle one covers only what the others do, so
    it goes; the counts and 'newly' of the two kept are fixed again in order."""
    problem = type("P", (), {"goal": 6})()
    solution = Solution(np.zeros(6, bool))

    def sensor(x, seen):
        seen = np.array(seen, dtype=np.int64)
        return FixedSensor(SensorPose(x, 0, 5, 5, 10, 0), 0.0, 0, 0, seen, seen)

    for f in (sensor(0, [0, 1, 2, 3]), sensor(10, [2, 3]), sensor(20, [3, 4, 5])):
        solution.fix(FixedSensor(f.pose, 0.0, 0, 0, newly_covered(solution, f.seen), f.seen))
    assert parts_module.prune(problem, solution) == 1
    assert [f.pose.x for f in solution.sensors] == [0, 20]
    assert solution.counts.tolist() == [1, 1, 1, 2, 1, 1] and solution.n_covered == 6
    assert solution.sensors[1].newly.tolist() == [4, 5]
    # A sensor that stood already is never dropped, though the goal does not need it.
    standing = FixedSensor(
        SensorPose(30, 0, 5, 5, 10, 0), 0.0, 0, 0, np.zeros(0, np.int64), np.array([0]),
        existing=True,
    )  # fmt: skip
    solution.fix(standing)
    assert parts_module.prune(problem, solution) == 0 and len(solution.sensors) == 3
    # A planned one as redundant goes.
    solution.fix(replace(standing, existing=False, pose=replace(standing.pose, x=40)))
    assert parts_module.prune(problem, solution) == 1
    assert [f.pose.x for f in solution.sensors] == [0, 20, 30]


@pytest.mark.parametrize("whole", [True, False])
def test_a_stop_while_candidates_are_built_drops_the_build(whole, monkeypatch):
    """Stopped while candidates are being built (the whole ground's, or the second
    part's): the build is dropped at once; whole, no plan was made; in parts, the
    first part's plan is kept."""
    if not whole:
        monkeypatch.setattr(budget, "PART_POINTS", PART_POINTS)
    run = Run(road(), box_caster(WALL), PAPER_CAMERA, settings(rho=0.9))
    seen = []
    for progress in run.steps():
        if progress.stage == "candidates" and progress.part in (0, 2):
            seen.append(progress)
            run.stop_early()
    res = run.result()
    assert len(seen) == 1  # no more of the build once stopped
    if whole:
        assert res.stop_reason == StopReason.stopped_before_plan() and not res.sensors
    else:
        assert "Stopped early" in res.stop_reason and res.sensors
        assert 0 < res.metrics["coverage_fraction"] < 0.5


def test_past_the_time_limit_every_part_is_still_planned(small_parts):
    """A limit already spent when the search starts: no LP is solved to its end, yet
    every part is planned (from its greedy plans) and the goal met, with a bound (of
    the duals so far, possibly 0) at most the plan's cost."""
    run = Run(road(), box_caster(WALL), PAPER_CAMERA, settings(rho=0.9, time_limit_s=0.01))
    res = run.result()
    assert res.stop_reason.startswith("Reached the goal") and "Stopped early" in res.stop_reason
    counts = recount(road(), res)
    assert np.count_nonzero(counts >= 1) >= math.ceil(0.9 * len(counts))
    assert 0 <= res.metrics["lower_bound"] <= res.metrics["cost"]


def test_resuming_a_finished_run_prunes_again_to_the_same_plan(small_parts, monkeypatch):
    """A run in parts whose seams left a sensor redundant drops it at the end, but its
    checkpoint holds every sensor as it was fixed: resumed from those records, the run
    drops the same ones and ends with the same plan."""
    s = settings(rho=0.9)
    records: list[dict] = []
    first = Run(road(), box_caster(WALL), PAPER_CAMERA, s, on_fixed=records.append).result()
    if len(records) == len(first.sensors):  # no seam left one over: make one redundant
        real = parts_module.in_gain_order

        calls = []

        def with_a_spare(inst, chosen):  # the first part's plan takes one more sensor
            calls.append(1)
            spare = [c for c in range(inst.matrix.shape[0]) if c not in chosen][: len(calls) == 1]
            return real(inst, list(chosen) + spare)

        monkeypatch.setattr(parts_module, "in_gain_order", with_a_spare)
        records.clear()
        first = Run(road(), box_caster(WALL), PAPER_CAMERA, s, on_fixed=records.append).result()
        monkeypatch.setattr(parts_module, "in_gain_order", real)
    assert len(records) > len(first.sensors)  # the checkpoint holds the dropped ones too
    resumed = Run(road(), box_caster(WALL), PAPER_CAMERA, s, resume=records).result()

    def poses(res):
        return [(f.x, f.y, f.pitch_deg, f.yaw_deg) for f in res.sensors]

    assert poses(resumed) == poses(first)
    assert resumed.metrics["coverage_fraction"] == first.metrics["coverage_fraction"] >= 0.9


def _middle_part():
    """The road's middle part of 3 (nothing covered yet, goal 90 % of its points): its
    cover instance, its candidates and where masts stand."""
    problem = Problem(road(), box_caster(WALL)(), PAPER_CAMERA, settings())
    points = np.flatnonzero(parts_of(problem.grid.target_xy, 3) == 1)
    part = drain(build_part(problem, points, PAPER_CAMERA.range_m))
    no = np.zeros(0, dtype=np.int64)
    inst, _ = parts_module.split_instance(
        part.cands, points, np.zeros(problem.n_targets, bool),
        np.zeros(problem.n_targets, np.int32), problem.need, problem.grid.target_xy, 4, no,
    )  # fmt: skip
    return replace(inst, goal=math.ceil(0.9 * len(points))), part, problem.space.standing


# The road's grid is 2 m: one point in 2 x 2 cells of it, as a run samples.
CELL_M = 4.0


def test_a_masts_lp_on_a_sample_proves_most_of_its_value_on_every_point(small_parts):
    """A part's masts LP is solved on one point per 4 m square, and the dual steps
    from its duals prove a line over every point: at the part's goal at most the LP
    over every point (solved by the simplex) and at least 95 % of it."""
    inst, part, standing = _middle_part()
    seen = []
    real = parts_module.cover_lp

    def spy(lp_inst, *args, **kwargs):
        seen.append(lp_inst.n_points)
        return (yield from real(lp_inst, *args, **kwargs))

    with pytest.MonkeyPatch.context() as mp:
        mp.setattr(parts_module, "cover_lp", spy)
        lp = drain(parts_module.site_line(inst, part, standing, CELL_M, None, None))
    squares = np.unique(np.floor(inst.xy / CELL_M), axis=0)
    assert seen == [len(squares)] and len(squares) < inst.n_points / 3
    value = drain(real(*_site_lp_args(inst, part, standing))).value
    assert 0.95 * value <= lp.line[0] * inst.goal - lp.line[1] <= value + 1e-6
    assert len(lp.used) > 0 and lp.center is not None


def test_a_masts_lp_cut_short_still_proves_most_of_its_value(small_parts, monkeypatch):
    """A part's masts LP whose interior point solve gives nothing (cut by its limit):
    the dual steps from nothing still prove a line, at most the LP's value and at
    least 90 % of it at the part's goal, and the plans look at a greedy cover's sites."""
    inst, part, standing = _middle_part()
    value = drain(parts_module.cover_lp(*_site_lp_args(inst, part, standing))).value
    real = parts_module.cover_lp

    def nothing(*args, **kwargs):
        lp = yield from real(*args, **kwargs)
        return replace(lp, x=np.zeros(0), pi=None)

    monkeypatch.setattr(parts_module, "cover_lp", nothing)
    cut = drain(parts_module.site_line(inst, part, standing, CELL_M, None, None))
    assert 0.9 * value <= cut.line[0] * inst.goal - cut.line[1] <= value + 1e-6
    assert len(cut.used) > 0


def test_a_masts_lp_past_its_deadline_takes_the_fewest_dual_steps(small_parts, monkeypatch):
    """Past the part's deadline the steps end after ``DualPolish.MIN_STEPS``, with a
    line that still holds; with time (none, or ``steps_until`` later), all
    ``SITE_POLISH_STEPS`` (or until no step helps)."""
    inst, part, standing = _middle_part()
    value = drain(parts_module.cover_lp(*_site_lp_args(inst, part, standing))).value
    taken = []
    real_walk = parts_module.DualPolish.walk

    def walk(self, pi, sigma, target, steps=None):
        taken.append(self)
        return real_walk(self, pi, sigma, target, steps)

    monkeypatch.setattr(parts_module.DualPolish, "walk", walk)
    late = drain(
        parts_module.site_line(inst, part, standing, CELL_M, time.perf_counter() - 1.0, None)
    )
    assert taken[-1].steps == parts_module.DualPolish.MIN_STEPS
    assert late.line[0] * inst.goal - late.line[1] <= value + 1e-6
    drain(parts_module.site_line(inst, part, standing, CELL_M, None, None))
    assert taken[-1].steps > parts_module.DualPolish.MIN_STEPS
    # The part's time spent, the run's not: the steps go on to ``steps_until``.
    past, later = time.perf_counter() - 1.0, time.perf_counter() + 600.0
    drain(parts_module.site_line(inst, part, standing, CELL_M, past, None, later))
    assert taken[-1].steps > parts_module.DualPolish.MIN_STEPS


def test_spread_duals_shares_each_sample_dual_among_its_square():
    """Squares of 2, 1 and 3 points with sample duals 4, 3 and 6: 2 each, 3, 2 each."""
    square = np.array([0, 2, 0, 1, 2, 2])
    out = parts_module.spread_duals(np.array([4.0, 3.0, 6.0]), square)
    assert out.tolist() == [2.0, 2.0, 2.0, 3.0, 2.0, 2.0]


def _site_lp_args(inst, part, standing):
    """The masts LP of ``site_line``, solved to its end (the simplex)."""
    col = np.searchsorted(part.sites, part.cands.position)
    pick = sparse.csr_matrix(
        (np.ones(len(col)), (col, np.arange(len(col)))), shape=(len(part.sites), len(col))
    )
    sites = (pick @ inst.matrix.astype(np.float64)).tocsr()
    sites.data[:] = 1.0
    cost = np.where(standing[part.sites], 0.0, part.site_share)
    every = np.arange(len(part.sites), dtype=np.int64)
    return CoverInstance(sites, inst.goal, need=inst.k), cost, every, every, 50, False


def test_the_masts_lps_lines_hold_at_other_goals(small_parts):
    """A part's masts LP gives lines at its goal and at the goals either side (all it
    can cover, and as far below): at each of those goals every line is at most the LP
    solved there to its end (what the lines add to the whole's bound: test_bound)."""
    inst, part, standing = _middle_part()
    lp = drain(parts_module.site_line(inst, part, standing, CELL_M, None, None))
    reach = parts_module.coverable(inst)
    lines = [lp.line, *drain(parts_module.either_side(lp, reach, None, None))]
    # Past the run's deadline: one step each, lines that hold all the same.
    late = drain(parts_module.either_side(lp, reach, time.perf_counter() - 1.0, None))
    assert len(lines) == 3 and len(late) == 2 and reach > inst.goal
    lines += late
    for goal in (inst.goal, reach, 2 * inst.goal - reach):
        at = replace(inst, goal=goal)
        value = drain(parts_module.cover_lp(*_site_lp_args(at, part, standing))).value
        for a, b in lines:
            assert a * goal - b <= value + 1e-6


def _two_masts_one_can_carry():
    """The road's problem, its whole-ground candidates, and two candidates ``a`` at
    the mast position P = (60, 8) and ``b`` at Q = (64, 8) such that a and another
    candidate at P cover at least what a and b do together, ``goal``, and no single
    candidate at P or Q does: so on {P, Q} the cheapest plan is one mast with two
    sensors (3 + 2 = 5), where a and b cost 3 + 3 + 2 = 8. Searched on the matrix,
    without the code under test."""
    problem = Problem(road(), box_caster(WALL)(), PAPER_CAMERA, settings())
    cands = drain(build_candidates(problem))
    sites = [problem.space.index_of(x, 8.0) for x in (60.0, 64.0)]
    rows = {s: np.flatnonzero(cands.position == s) for s in sites}
    dense = {s: cands.matrix[rows[s]].toarray() > 0 for s in sites}
    single = max(int(d.sum(axis=1).max()) for d in dense.values())
    at_p = dense[sites[0]]
    partner = (at_p[:, None, :] | at_p[None, :, :]).sum(axis=2).max(axis=1)  # a and one at P
    both = (at_p[:, None, :] | dense[sites[1]][None, :, :]).sum(axis=2)
    fits = (both > single) & (both <= partner[:, None])
    i, j = np.unravel_index(np.argmax(np.where(fits, both, -1)), both.shape)
    assert fits[i, j]
    return problem, cands, int(rows[sites[0]][i]), int(rows[sites[1]][j]), int(both[i, j])


def test_a_parts_plans_look_at_the_masts_lp_and_the_fewest_masts_sites():
    """The sets a part's plans look for masts at, each with the masts of the parts
    before (site 4): the fewest masts' MILP's (1, 2), the masts LP's (5, 7), the
    fewest masts' LP's (1, 2, 9) and a moved sample's (2, 3); without the fewest
    masts, the masts LP's alone. The fewest masts are solved first (the masts LP's
    steps wait for the main thread while the sensors LP works)."""
    empty = CoverInstance(sparse.csr_matrix((0, 0)), 0)
    order = []

    def masts_lp():
        order.append("masts LP")
        return parts_module.SiteLP((0.0, 0.0), 1, np.array([5, 7]), empty, np.zeros(0), None)
        yield  # generators, like the real ones

    def fewest():
        order.append("fewest")
        yield None
        order.append("fewest ends")
        return SiteSolution(3, np.array([1, 2]), np.array([1, 2, 9]), (np.array([2, 3]),))

    found = {}
    got = drain(parts_module.part_sites(masts_lp(), np.array([4]), found, fewest()))
    assert order == ["fewest", "fewest ends", "masts LP"]
    assert [s.tolist() for s in got.site_sets()] == [
        [1, 2, 4], [4, 5, 7], [1, 2, 4, 9], [2, 3, 4]
    ]  # fmt: skip
    assert got.bound == 0 and found["lp"].used.tolist() == [5, 7]
    alone = drain(parts_module.part_sites(masts_lp(), np.array([4]), {}))
    assert [s.tolist() for s in alone.site_sets()] == [[4, 5, 7]]


def test_the_fewest_masts_of_a_part_count_the_standing_free_and_take_their_share():
    """Points 0..2; site 0 sees 0, site 1 sees 1 and 2, site 2 sees 0 and 2. With no
    mast standing the fewest are sites 1 and either other (2); with site 2 standing
    (free), one new mast, site 1 (site 2 covers 0 and 2, then 1 needs site 1). The
    MILP may take 40 % of the part's time left: 4 s of 10, on one point in 2 x 2 cells
    of the grid: point 3, 1 m from point 0 in the same 2 m square, is left out."""
    rows = [[0, 3], [1, 2], [0, 2, 3]]
    inst = CoverInstance(
        sparse.csr_matrix(
            (np.ones(7, np.float32), np.concatenate(rows), [0, 2, 4, 7]), shape=(3, 4)
        ),
        4,
        xy=np.array([[0.0, 0.0], [10.0, 0.0], [20.0, 0.0], [1.0, 0.0]]),
    )
    site_of = np.arange(3, dtype=np.int64)
    free = drain(parts_module.fewest_masts(inst, site_of, np.zeros(3, bool), 1.0, None, None))
    assert free.bound == 2 and len(free.sites) == 2 and 1 in free.sites
    standing = np.array([False, False, True])
    one = drain(parts_module.fewest_masts(inst, site_of, standing, 1.0, None, None))
    assert one.bound == 1 and 1 in one.sites and 0 not in one.sites
    seen = []
    real = parts_module.site_cover

    def spy(inst, site_of, n_sites, deadline, *args):
        seen.append((deadline - time.perf_counter(), inst.n_points, inst.goal))
        return (yield from real(inst, site_of, n_sites, deadline, *args))

    with pytest.MonkeyPatch.context() as mp:
        mp.setattr(parts_module, "site_cover", spy)
        drain(
            parts_module.fewest_masts(inst, site_of, standing, 1.0, time.perf_counter() + 10, None)
        )
    assert parts_module.FEWEST_SHARE == 0.4 and seen[0][0] == pytest.approx(4.0, abs=0.2)
    assert parts_module.SAMPLE_CELLS == 2 and seen[0][1:] == (3, 3)
    # Then the samples moved by half a square (1 m) in x, in y and in both, within the
    # same 4 s: moved in x, x = 0 and 1 fall in [-1, 1) and [1, 3), so all 4 points
    # stay; moved in y alone, the same 3 as before.
    assert parts_module.SAMPLE_OFFSETS == ((0.5, 0.0), (0.0, 0.5), (0.5, 0.5))
    assert [n for _, n, _ in seen[1:]] == [4, 3, 4]
    # Each for at most as long as the first took (milliseconds here) or 1 s.
    assert all(0.0 < left <= 1.0 for left, _, _ in seen[1:])
    # Each sample's set is one more set for the plans: here each is site 1 and the
    # standing site 2 (a mast there costs nothing).
    assert [s.tolist() for s in one.more] == [[1, 2], [1, 2], [1, 2]]
    # No time left after the first sample: no moved one.
    seen.clear()
    with pytest.MonkeyPatch.context() as mp:
        mp.setattr(parts_module, "site_cover", spy)
        now = time.perf_counter()
        late = drain(parts_module.fewest_masts(inst, site_of, standing, 1.0, now, None))
    assert len(seen) == 1 and late.more == ()


def test_rejoin_moves_a_sensor_to_the_other_mast_and_closes_one():
    """A plan of two sensors on two masts, where one mast can carry both (above): the
    re-plan over the whole ground ends at cost 5 (one mast, two sensors), and an
    independent evaluator counts at least the goal covered."""
    problem, cands, a, b, goal = _two_masts_one_can_carry()
    problem.goal = goal
    solution = Solution(np.zeros(problem.n_targets, bool), need=problem.need.copy())
    for c in (a, b):
        fix_candidate(problem, solution, cands, c)
    assert solution.n_covered >= goal
    before, after, on_masts = drain(parts_module.rejoin(problem, solution, None, None))
    assert (before, after) == (8.0, 5.0)
    assert len(solution.sensors) == 2
    # The fewest sensors on the two masts: at most the 2 planned; at least the goal
    # over what the best of their candidates covers (no sensor covers more).
    at_masts = np.isin(cands.position, cands.position[[a, b]])
    most = int(np.diff(cands.matrix.indptr)[at_masts].max())
    assert goal / most - 1e-5 <= on_masts <= 2.0 + 1e-6 and goal > most
    assert len({(f.pose.x, f.pose.y) for f in solution.sensors}) == 1
    caster = box_caster(WALL)()
    ev = TargetedEvaluator(problem.grid, caster)
    counts = np.zeros(problem.n_targets, dtype=np.int64)
    for f in solution.sensors:
        counts[ev.evaluate(PAPER_CAMERA, f.pose).covered] += 1
    assert np.count_nonzero(counts) >= goal


def _three_masts():
    """``_two_masts_one_can_carry``'s a at P and b at Q fixed, and the candidate at
    R = (200, 8) that covers the most, which sees none of their points; the goal is
    what the three cover."""
    problem, cands, a, b, _ = _two_masts_one_can_carry()
    far = np.flatnonzero(cands.position == problem.space.index_of(200.0, 8.0))
    r = int(far[np.argmax(np.diff(cands.matrix.indptr)[far])])
    near = cands.matrix[[a, b]].indices
    assert not np.isin(cands.matrix[r].indices, near).any()
    solution = Solution(np.zeros(problem.n_targets, bool), need=problem.need.copy())
    for c in (a, b, r):
        fix_candidate(problem, solution, cands, c)
    problem.goal = solution.n_covered
    return problem, cands, solution


def test_plan_cost_of_counts_as_each_objective():
    """Three sensors on three masts: cost 3 x 3 + 3 = 12; with a mast standing at P
    already, 2 new masts: 9; 3 sensors; 2 masts (and the sensors as a tie-break)."""
    problem, _, solution = _three_masts()
    assert parts_module.plan_cost_of(problem, solution.sensors) == 12.0
    problem.space.standing[problem.space.index_of(60.0, 8.0)] = True
    assert parts_module.plan_cost_of(problem, solution.sensors) == 9.0
    problem.settings = replace(problem.settings, objective="sensors")
    assert parts_module.plan_cost_of(problem, solution.sensors) == 3.0
    problem.settings = replace(problem.settings, objective="masts")
    assert parts_module.plan_cost_of(problem, solution.sensors) == pytest.approx(2.0, abs=1e-5)


def test_rejoin_by_windows_keeps_the_sensors_outside_each(monkeypatch):
    """The two masts of ``_two_masts_one_can_carry`` and a third sensor on a mast at
    R = (200, 8), seeing none of their points; at most 2 masts a window, so {P, Q}
    and {R}: the first window's re-plan puts two sensors on one mast with R's sensor
    counted as it stands, the second cannot do better than one mast and one sensor.
    Cost 3 x 3 + 3 = 12 before, 3 x 2 + 3 = 9 after; R's sensor keeps its pose; an
    independent evaluator counts the goal covered."""
    problem, cands, solution = _three_masts()
    at_r = solution.sensors[2].pose
    monkeypatch.setattr(parts_module, "REJOIN_MASTS", 2)
    before, after, on_masts = drain(parts_module.rejoin_windows(problem, solution, None, None))
    assert (before, after, on_masts) == (12.0, 9.0, 0.0)  # by windows: no bound on its masts
    assert at_r in [f.pose for f in solution.sensors] and len(solution.sensors) == 3
    assert len({(f.pose.x, f.pose.y) for f in solution.sensors}) == 2
    ev = TargetedEvaluator(problem.grid, box_caster(WALL)())
    counts = np.zeros(problem.n_targets, dtype=np.int64)
    for f in solution.sensors:
        counts[ev.evaluate(PAPER_CAMERA, f.pose).covered] += 1
    assert np.count_nonzero(counts) >= problem.goal


def test_rejoin_keeps_the_plan_when_the_fresh_count_falls_short(monkeypatch):
    """The cheaper plan's sensors, evaluated afresh, short of the goal (made so here):
    the plan stays as it was, sensor for sensor."""
    problem, cands, a, b, goal = _two_masts_one_can_carry()
    problem.goal = goal
    solution = Solution(np.zeros(problem.n_targets, bool), need=problem.need.copy())
    for c in (a, b):
        fix_candidate(problem, solution, cands, c)
    poses = [f.pose for f in solution.sensors]
    reached = problem.reached
    monkeypatch.setattr(problem, "reached", lambda n: n >= goal + 1)
    assert drain(parts_module.rejoin(problem, solution, None, None))[:2] == (8.0, 8.0)
    assert [f.pose for f in solution.sensors] == poses and reached(solution.n_covered)


def test_rejoin_keeps_a_standing_sensor_and_its_mast_free():
    """A sensor that stood already (at P, free) and a planned one at Q: the planned
    one moves to P's free mast (cost 8 - 3 = 5 before, 1 after: one sensor, no new
    mast), and the standing one stays as it was."""
    problem, cands, a, b, goal = _two_masts_one_can_carry()
    problem.goal = goal
    solution = Solution(np.zeros(problem.n_targets, bool), need=problem.need.copy())
    fixed = fix_candidate(problem, solution, cands, a)
    solution.sensors[0] = replace(fixed, existing=True)
    problem.space.standing[cands.position[a]] = True
    fix_candidate(problem, solution, cands, b)
    before, after, on_masts = drain(parts_module.rejoin(problem, solution, None, None))
    assert (before, after) == (4.0, 1.0)
    assert 0.0 < on_masts <= 1.0 + 1e-6  # the one planned sensor, on either mast
    assert solution.sensors[0].existing and solution.sensors[0].pose == fixed.pose
    assert {(f.pose.x, f.pose.y) for f in solution.sensors} == {(60.0, 8.0)}


def test_rejoin_stopped_keeps_the_plan():
    """Esc or Ctrl-C (the stop set) while the re-plan's MILP works: the plan stays."""
    problem, cands, a, b, goal = _two_masts_one_can_carry()
    problem.goal = goal
    solution = Solution(np.zeros(problem.n_targets, bool), need=problem.need.copy())
    for c in (a, b):
        fix_candidate(problem, solution, cands, c)
    poses = [f.pose for f in solution.sensors]
    stop = threading.Event()
    stop.set()
    # (nothing proven on its masts either)
    assert drain(parts_module.rejoin(problem, solution, None, stop)) == (8.0, 8.0, 0.0)
    assert [f.pose for f in solution.sensors] == poses


def test_the_parts_leave_the_replan_its_share_of_the_time(small_parts, monkeypatch):
    """With a deadline 100 s away, every part's plan must end by 75 s (the re-plan
    over the whole ground keeps ``REJOIN_SHARE``, 25 %), and the re-plan itself is
    given the run's deadline."""
    problem = Problem(road(), box_caster(WALL)(), PAPER_CAMERA, settings(rho=0.9))
    solution = Solution(np.zeros(problem.n_targets, bool), need=problem.need.copy())
    asked: dict[str, list[float]] = {"parts": [], "rejoin": []}
    plan, replan = parts_module.prove_and_plan, parts_module.rejoin

    def parts_plan(*args):
        asked["parts"].append(args[4])
        return plan(*args)

    def rejoin(problem, solution, deadline, stop):
        asked["rejoin"].append(deadline)
        return replan(problem, solution, deadline, stop)

    monkeypatch.setattr(parts_module, "prove_and_plan", parts_plan)
    monkeypatch.setattr(parts_module, "rejoin", rejoin)
    t0 = time.perf_counter()
    deadline = t0 + 100.0
    drain(parts_module.solve_in_parts(problem, solution, 3, deadline, threading.Event()))
    assert len(asked["parts"]) == 3 and asked["rejoin"] == [deadline]
    assert all(d <= t0 + 75.0 + 0.5 for d in asked["parts"])
    assert problem.reached(solution.n_covered)


@pytest.mark.parametrize("seed", range(10))
def test_cheapest_counts_is_the_least_cost_of_whole_counts(seed):
    """A bound on the cost rises to the cheapest mast_cost x m + sensor_cost x s at
    or above it with s, m at least their own bounds: brute force over a box of counts.
    By hand: 10.5 with masts at 3, sensors at 2, one of each at least: 3 + 2 x 4,
    9 + 2 x 1 and 6 + 2 x 3 give 11, 6 + 2 x 2 = 10 is short."""
    assert parts_module.cheapest_counts(10.5, 1, 1, 2.0, 3.0) == 11.0
    rng = np.random.default_rng(seed)
    mast_cost, sensor_cost = (float(c) for c in rng.integers(1, 6, 2))
    sensors, masts = (int(c) for c in rng.integers(0, 8, 2))
    total = float(rng.uniform(0, 60))
    brute = min(
        mast_cost * m + sensor_cost * s
        for m in range(masts, 80)
        for s in range(sensors, 80)
        if mast_cost * m + sensor_cost * s >= total
    )
    assert parts_module.cheapest_counts(total, sensors, masts, sensor_cost, mast_cost) == brute


def test_a_parts_solve_leaves_time_for_the_builds_after_it():
    """900 s to the parts' end, a quarter of it this part's: 225 s with no build
    measured yet; builds of 20 and 40 s so far reserve 3 x 30 s for the three parts
    after it, so (900 - 90) / 4 = 202.5 s; with parts so far 10 and 20 s past their
    deadlines, 3 x (30 + 15) s: (900 - 135) / 4 = 191.25 s; a reserve beyond the
    time left leaves none; no limit stays none."""
    deadline = parts_module.solve_deadline
    assert deadline(100.0, 1000.0, 0.25, [], 3) == 325.0
    assert deadline(100.0, 1000.0, 0.25, [20.0, 40.0], 3) == 302.5
    assert deadline(100.0, 1000.0, 0.25, [20.0, 40.0], 3, [10.0, 20.0]) == 291.25
    assert deadline(100.0, 1000.0, 0.25, [20.0, 40.0], 0) == 325.0
    assert deadline(100.0, 150.0, 0.5, [100.0], 2) == 100.0
    assert deadline(100.0, None, 0.5, [100.0], 2) is None


@pytest.mark.parametrize("cap", [1, 2])
def test_the_parts_plans_keep_the_cap_on_masts_the_parts_before_stood(
    small_parts, monkeypatch, cap
):
    """A part may put its sensors on a mast a part before stood (at no mast cost), but
    only as many as the cap leaves there: counted from the joined plan as the seams'
    re-plan receives it (before that re-plan could repair anything), no mast carries
    more than ``cap`` sensors; nor does the final plan."""
    seen = []
    real = parts_module.rejoin_windows

    def spy(problem, solution, *args):
        xy = [(f.pose.x, f.pose.y) for f in solution.sensors if not f.existing]
        seen.append(max(Counter(xy).values()))
        return (yield from real(problem, solution, *args))

    monkeypatch.setattr(parts_module, "rejoin_windows", spy)
    s = settings(rho=0.9, max_sensors_per_mast=cap)
    result = Run(road(), box_caster(WALL), PAPER_CAMERA, s).result()
    assert len(seen) == 1 and seen[0] <= cap
    assert max(Counter((f.x, f.y) for f in result.sensors).values()) <= cap
