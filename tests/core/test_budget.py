"""Memory and work estimated before casting (``core/budget.py``): the counts against
arithmetic and against what is then built, refusals in one line naming the setting,
and default runs allowed."""

import math
import time
from dataclasses import replace

import numpy as np
import pytest

from autoscoop_blender.core import budget, machine, refusal
from autoscoop_blender.core.candidates import build_candidates
from autoscoop_blender.core.errors import InputError
from autoscoop_blender.core.geom import grid_layout
from autoscoop_blender.core.geom.grid import GroundGrid
from autoscoop_blender.core.geom.raycast import BoxCaster
from autoscoop_blender.core.model.sensors import PAPER_CAMERA, ROADSIDE_LIDAR, TRAFFIC_RADAR
from autoscoop_blender.core.problem import Problem, run_estimate
from autoscoop_blender.core.settings import OptimizeSettings
from tests.core.flat import flat_scene
from tests.core.test_grid_held import held_chunks_by_hand
from tests.core.test_lp import drain

GIB = 1 << 30
# A 10 m x 10 m target at the origin, a 4 m x 4 m sensor area 10 m east of it.
TARGET = (0.0, 0.0, 10.0, 10.0)
SENSOR = (20.0, 0.0, 24.0, 4.0)


def hand_scene():
    return flat_scene(target=TARGET, sensor=SENSOR)


def built(problem):
    """The problem's candidate set, built to the end."""
    return drain(build_candidates(problem))


def test_grid_counts_are_arithmetic():
    # Areas' bounds (0, 0)-(24, 10); at g = 0.5 with an 80 m reach the lattice pads
    # 80 + 2 g = 81 m on each side: x from -81 over 24 + 162 m, y over 10 + 162 m.
    est = budget.estimate_grid(hand_scene(), 0.5, 80.0)
    nx, ny = 186 * 2, 172 * 2
    # Tiles of 32 x 32 cells (16 m) from (-81, -81): the 12 x 11 tiles but 15 near the
    # corners whose ground is farther than 80 m from both boxes: (0, 0), (0, 1),
    # (1, 0) at the bottom left (91.9, 81.4, 81.4 m from the target's corner), (0, 9),
    # (0, 10), (1, 10) at the top left, (10, 0), (11, 0), (11, 1) at the bottom right
    # (85.1 m and more from the sensor area), (9, 10), (10, 9), (10, 10), (11, 8),
    # (11, 9), (11, 10) at the top right (80.7 m and more), held in chunks of 64
    # consecutive flat indices (counted on a dense mask).
    assert held_chunks_by_hand(hand_scene(), (-81.0, -81.0, nx, ny), 0.5, 80.0) == 1921
    assert est.grid_cells == 1921 * 64 == 122_944
    assert est.target_points == (10 * 2) ** 2 == 400
    assert est.disk_cells == math.ceil(math.pi * 80**2 / 0.5**2) == 80_425
    # A full evaluation drops every cell in reach and may cast a sight ray to each.
    assert est.rays_per_evaluation == 2 * est.disk_cells
    # The slot table: one int32 per 64 cells of the whole lattice.
    table = math.ceil(nx * ny / 64) * 4
    per_point = budget.TARGET_POINT_BYTES + budget.TARGET_TREE_BYTES
    assert est.grid_bytes == 122_944 * budget.GRID_CELL_BYTES + table + 400 * per_point
    # The reference footprint's flat grid: (2 x 80 + 2 x 2 x 0.5) / 0.5 cells a side.
    assert budget.reference_cells(80.0, 0.5) == 324**2


def test_grid_counts_match_the_grid_built():
    scene = hand_scene()
    for g in (0.5, 1.0, 2.0):
        est = budget.estimate_grid(scene, g, 80.0)
        grid = GroundGrid(scene, BoxCaster(ground_z=0.0), g, reach_m=80.0)
        assert est.grid_cells == grid.held_cells
        assert est.target_points == grid.n_targets
        a = grid.arrays()
        resident = a.dist.nbytes + a.z.nbytes + a.normal.nbytes + grid._target_ordinal.nbytes
        assert resident == est.grid_cells * budget.GRID_CELL_BYTES
        assert a.chunk_offset.nbytes == grid_layout.chunk_count(grid.nx, grid.ny) * 4


def test_run_counts_match_the_problem_and_its_candidates():
    # On flat, empty ground the candidates cover what the flat-ground profile says:
    # positions exactly, cached rows and matrix nonzeros within 2 %, for each preset.
    scene = flat_scene(target=(0, 0, 60, 14), sensor=(0, 16, 60, 18))
    for model in (PAPER_CAMERA, ROADSIDE_LIDAR, TRAFFIC_RADAR):
        problem = Problem(
            scene, BoxCaster(ground_z=0.0), model, OptimizeSettings(optimizer="greedy")
        )
        est = problem.estimate
        assert est.positions == len(problem.space.positions) == 31 * 2
        assert est.target_points == problem.n_targets == 60 * 14
        # 36 yaws x 6 pitches; a level spinning lidar only one yaw at pitch 0.
        assert est.orientations == (1 + 36 * 5 if model is ROADSIDE_LIDAR else 36 * 6)
        cands = built(problem)
        rows = sum(len(a) for a in problem.probe._answers.values())
        assert est.cache_rows == pytest.approx(rows, rel=0.02), model.kind
        # Rays go only to rows some orientation needs: at most the rows.
        assert problem.probe.extra_rays <= 1.02 * est.candidate_rays
        # The estimate counts every covering candidate, the dominated ones too.
        held = cands.matrix.nnz + cands.dominated_nonzeros
        assert est.nonzeros == pytest.approx(held, rel=0.02), model.kind


def test_estimates_scale_with_the_grid():
    scene = hand_scene()
    fine, coarse = (
        run_estimate(scene, PAPER_CAMERA, OptimizeSettings(grid_m=g)) for g in (0.5, 1.0)
    )
    # Positions every 2 g: a quarter as many per m^2; points per candidate, too.
    assert fine.positions == 25 and coarse.positions == 9
    assert fine.nonzeros == pytest.approx(coarse.nonzeros * 4 * 25 / 9, rel=0.05)
    assert fine.peak_bytes > coarse.peak_bytes


def test_refusal_is_one_line_naming_the_setting_and_a_grid_that_fits():
    t0 = time.perf_counter()
    with pytest.raises(InputError) as err:
        Problem(hand_scene(), BoxCaster(ground_z=0.0), PAPER_CAMERA, OptimizeSettings(grid_m=0.001))
    msg = str(err.value)
    assert time.perf_counter() - t0 < 5
    assert "\n" not in msg
    assert msg.startswith("grid_m = 0.001 needs ") and "ground cells" in msg
    assert "80 m reach" in msg and "the machine has" in msg
    # The fix: a coarser grid, with what it needs.
    hint = msg.split("raise grid_m (--grid; ")[1]
    assert float(hint.split()[0]) > 0.001 and ("GiB" in hint or "MiB" in hint)


def test_grid_alone_is_checked_for_coverage_runs():
    # ``headless coverage`` and the panel's Evaluate build the grid directly.
    with pytest.raises(InputError, match=r"^grid_m = 0.001 needs .* ground cells"):
        GroundGrid(hand_scene(), BoxCaster(ground_z=0.0), 0.001, reach_m=80.0)


def test_refusal_names_the_candidate_matrix_and_other_fixes():
    scene = flat_scene(target=(0, 0, 60, 14), sensor=(0, 16, 60, 18))
    settings = OptimizeSettings()
    est = run_estimate(scene, PAPER_CAMERA, settings)
    assert est.peak_stage == "optimizer"
    small = est.peak_bytes - (16 << 20)  # a machine a little short of it

    def redo(g):
        return run_estimate(scene, PAPER_CAMERA, replace(settings, grid_m=g))

    with pytest.raises(InputError) as err:
        refusal.check(est, redo, memory_bytes=small, resident=0)
    msg = str(err.value)
    assert msg.startswith("the lp optimizer at grid_m = 1 needs a candidate matrix of about ")
    assert "62 mast positions x 216 orientations" in msg
    # The first coarser grid that fits, with what it needs.
    assert "raise grid_m (--grid; 2 needs " in msg
    assert refusal.verdict(redo(2.0), memory_bytes=small, resident=0) is None
    assert msg.endswith("or position_step_m, or use --optimizer es")


def test_work_limits():
    scene = hand_scene()
    # A pointcloud pose at 0.05 m: the paper camera's 30,720 rays x 14^2.
    est = run_estimate(
        scene, PAPER_CAMERA, OptimizeSettings(grid_m=0.05, optimizer="es", method="pointcloud")
    )
    assert est.pattern_rays == 30_720 * 14**2
    stage, why = refusal.verdict(est, memory_bytes=1 << 50, resident=0)
    assert stage == "pattern" and "2.0 M rays a pose" in why
    # A full evaluation at 0.01 m: 201 M cells within 80 m.
    est = budget.estimate_grid(scene, 0.01, 80.0)
    stage, why = refusal.verdict(est, memory_bytes=1 << 50, resident=0)
    assert stage == "rays" and "20.0 M rays an evaluation" in why


def test_each_es_worker_holds_its_own_grid_and_cache():
    scene = hand_scene()
    settings = OptimizeSettings(optimizer="es", grid_m=0.5)
    one = run_estimate(scene, PAPER_CAMERA, settings)
    assert "workers" not in dict(one.stages)
    # A worker: the interpreter, then the grid, the cache (well below its 2 GiB cap
    # here) and one evaluation in flight, as this process holds them.
    cache = one.cache_rows * (budget.CACHE_ROW_BYTES + budget.CACHE_ANSWER_BYTES)
    resident = one.grid_bytes + one.positions * budget.POSITION_BYTES
    assert one.stage_bytes("cache") == resident + cache
    in_flight = one.stage_bytes("evaluation") - resident - cache
    disk, sight = one.disk_cells, one.rays_per_evaluation - one.disk_cells
    assert in_flight == (
        disk * budget.EVALUATION_CELL_BYTES
        + min(disk, budget.DROP_BATCH) * budget.DROP_RAY_BYTES
        + sight * budget.SIGHT_RAY_BYTES
    )
    worker = budget.WORKER_BASE_BYTES + one.grid_bytes + cache + in_flight
    for n in (2, 3):
        est = run_estimate(scene, PAPER_CAMERA, settings, workers=n)
        assert est.workers == n
        assert est.stage_bytes("workers") == one.stage_bytes("cache") + n * worker
    # A machine that holds the run with two workers but not with three: the refusal
    # names the workers and the flag.
    two = run_estimate(scene, PAPER_CAMERA, settings, workers=2).peak_bytes
    three = run_estimate(scene, PAPER_CAMERA, settings, workers=3)
    memory = (two + three.peak_bytes) // 2
    assert refusal.verdict(replace(three, workers=2), memory, 0)[0] == "workers"
    with pytest.raises(InputError) as err:
        refusal.check(three, lambda g: three, memory_bytes=memory, resident=0)
    msg = str(err.value)
    assert msg.startswith("the es optimizer at grid_m = 0.5 with 3 worker processes")
    assert msg.endswith("or use fewer workers (--workers)")
    # Greedy and lp have no workers: the count changes nothing.
    greedy = replace(settings, optimizer="greedy")
    assert run_estimate(scene, PAPER_CAMERA, greedy, workers=4).stages == (
        run_estimate(scene, PAPER_CAMERA, greedy).stages
    )


def test_default_runs_pass():
    scene = flat_scene()  # a 200 m x 200 m target around a 2 m x 2 m sensor area
    for optimizer in ("lp", "greedy", "es"):
        settings = OptimizeSettings(optimizer=optimizer)
        problem = Problem(scene, BoxCaster(ground_z=0.0), PAPER_CAMERA, settings)
        est = problem.estimate
        assert refusal.verdict(est) is None
        assert est.peak_bytes < 0.5 * GIB
        assert est.grid_cells == problem.grid.held_cells


def test_a_matrix_that_outgrows_its_estimate_stops_the_build(monkeypatch):
    problem = Problem(
        hand_scene(), BoxCaster(ground_z=0.0), PAPER_CAMERA, OptimizeSettings(optimizer="greedy")
    )
    whole = built(problem).matrix.nnz
    problem.candidates = None  # built again under a limit one short of it
    monkeypatch.setattr(budget, "nonzero_limit", lambda optimizer: whole - 1)
    with pytest.raises(InputError, match=r"outgrew its estimate .* the greedy optimizer: raise"):
        built(problem)


def test_drops_in_batches_give_the_same_surface(monkeypatch):
    scene = flat_scene(boxes=[((3.0, 3.0, 0.0), (5.0, 6.0, 2.0))])
    caster = BoxCaster([((3.0, 3.0, 0.0), (5.0, 6.0, 2.0))], ground_z=0.0)
    grid = GroundGrid(scene, caster, 1.0, reach_m=10.0)
    xy = np.random.default_rng(0).uniform(-20, 20, (1000, 2))
    whole = grid.drop(xy)
    monkeypatch.setattr(budget, "DROP_BATCH", 64)
    parts = grid.drop(xy)
    assert np.array_equal(whole[0], parts[0]) and np.array_equal(whole[1], parts[1])


def test_machine_figures():
    assert machine.machine_memory_bytes() > 256 << 20
    assert machine.resident_bytes() >= 0
    assert refusal.count_text(46.6e9) == "46.6 G" and refusal.count_text(512) == "512"
    assert refusal.bytes_text(43 * GIB) == "43.0 GiB" and refusal.bytes_text(310 << 20) == "310 MiB"


def test_a_camera_with_a_resolution_keeps_8_more_bytes_a_cached_row():
    from autoscoop_blender.core.model.sensors import CCTV_CAMERA

    settings = OptimizeSettings(optimizer="es", grid_m=0.5)
    plain = replace(CCTV_CAMERA, resolution_px=None, min_px_per_m=0.0)
    a = run_estimate(hand_scene(), CCTV_CAMERA, settings)
    b = run_estimate(hand_scene(), plain, settings)
    assert a.cache_rows == b.cache_rows > 0
    assert a.stage_bytes("cache") - b.stage_bytes("cache") == 8 * a.cache_rows


def test_lp_in_parts_holds_one_parts_matrix(monkeypatch):
    """The lp optimizer plans 840 points in parts of at most 300 (3 parts), or of at
    most a third of the nonzeros: its candidate and optimizer stages hold the largest
    part's matrix (a third, with ``PART_IMBALANCE`` room), not the whole's; so does
    greedy, but with a bound (the whole ground's LP), which holds the whole matrix."""
    scene = flat_scene(target=(0, 0, 60, 14), sensor=(0, 16, 60, 18))
    lp = OptimizeSettings(optimizer="lp")
    whole = run_estimate(scene, PAPER_CAMERA, lp)
    monkeypatch.setattr(budget, "PART_POINTS", 300)
    parts = run_estimate(scene, PAPER_CAMERA, lp)
    assert whole.parts == 1 and parts.parts == math.ceil(840 / 300) == 3
    assert parts.nonzeros == whole.nonzeros  # the whole ground's, as the split needs
    held = int(whole.nonzeros / 3 * budget.PART_IMBALANCE)
    per = budget.NONZERO_OPTIMIZER_BYTES["lp"]
    assert whole.stage_bytes("optimizer") - parts.stage_bytes("optimizer") == (
        (whole.nonzeros - held) * per
    )
    assert parts.stage_bytes("optimizer") < whole.stage_bytes("optimizer")
    greedy = run_estimate(scene, PAPER_CAMERA, replace(lp, optimizer="greedy"))
    bounded = run_estimate(scene, PAPER_CAMERA, replace(lp, optimizer="greedy", bound=True))
    assert greedy.parts == 3 and bounded.parts == 1
    assert bounded.stage_bytes("optimizer") - greedy.stage_bytes("optimizer") == (
        (whole.nonzeros - held) * budget.NONZERO_OPTIMIZER_BYTES["greedy"]
    )
    monkeypatch.setattr(budget, "PART_POINTS", 10_000)
    monkeypatch.setattr(budget, "PART_NONZEROS", math.ceil(whole.nonzeros / 4))
    assert run_estimate(scene, PAPER_CAMERA, lp).parts == 4
    # The problem is split as estimated: the estimate's memory is the run's.
    problem = Problem(scene, BoxCaster(ground_z=0.0), PAPER_CAMERA, lp)
    assert problem.estimate.parts == 4
