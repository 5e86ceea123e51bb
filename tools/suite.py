"""``./dev.sh bench [--quick]``: speed against accuracy, optimizer runs,
stability across seeds, scaling, and the default pipeline against the paper's.

Writes ``bench/results.json``, ``docs/img/speed_accuracy.png`` and ``docs/img/optimize.png``
(``bench/quick/...`` with ``--quick``).

The reference for accuracy is ``targeted`` on a 0.25 m grid at the exact pose (no
position lattice, no cropping); it is checked first against the analytic shadow of
``flat_wall``'s wall. For every method and knob, each pose is scored by

* point disagreement: the fraction of the reference's target points (0.25 m) whose
  covered / not-covered verdict differs from the method's coverage map there (the
  verdict of the method's grid cell holding the point, or, for ``pointcloud``, whether
  the point lies in its alpha shape);
* footprint error: |footprint m^2 - reference footprint m^2| / reference.

Time is seconds per pose evaluation as the optimizer calls it (target points plus the
fitness band; for the cached method, amortised over the orientations an ES tries at
each position, measured by replaying that many).

One module: its sections share the plan (``FULL``, ``QUICK``), the runner in a fresh
process and the results file they all write into.
"""

from __future__ import annotations

import argparse
import json
import math
import multiprocessing
import os
import resource
import sys
import tempfile
import time
from concurrent.futures import ProcessPoolExecutor
from dataclasses import dataclass, replace
from datetime import date
from pathlib import Path
from typing import Any

import numpy as np
import shapely
from scipy.spatial import cKDTree

from autoscoop_blender.core.coverage.base import footprint_polygon, place
from autoscoop_blender.core.coverage.cached import CachedTargetedEvaluator
from autoscoop_blender.core.coverage.pointcloud import PointcloudEvaluator, auto_oversample
from autoscoop_blender.core.coverage.targeted import TargetedEvaluator
from autoscoop_blender.core.evaluate import evaluate_layout
from autoscoop_blender.core.geom.grid import GroundGrid
from autoscoop_blender.core.model.scene import SceneModel, random_points
from autoscoop_blender.core.model.sensors import PAPER_CAMERA, SensorPose
from autoscoop_blender.core.run import Run
from autoscoop_blender.core.settings import CoverageSettings, FitnessParams, OptimizeSettings
from autoscoop_blender.io.reports import result_dict
from autoscoop_blender.io.sensor_file import parse_sensors
from headless.files import json_text, load_scene
from headless.paths import SAMPLES
from tools.machine import machine_line

REFERENCE_GRID_M = 0.25
BAND_M = FitnessParams().band_m
MODEL = PAPER_CAMERA


@dataclass(frozen=True)
class Plan:
    """How much to measure: --quick keeps the whole suite to a few minutes."""

    poses: int
    pointcloud_oversample: tuple[int, ...]
    alphas: tuple[float, ...]
    grids: tuple[float, ...]
    quantizations: tuple[float, ...]
    orientations_per_position: int
    seeds: int
    scaling_tiles: tuple[int, ...]
    bound_tiles: int


QUICK = Plan(4, (1, 2), (0.5, 1.0, 2.0), (2.0, 1.0, 0.5), (1.0, 2.0, 4.0), 32, 3, (1, 2), 1)
FULL = Plan(
    12, (1, 2, 3), (0.5, 1.0, 2.0), (2.0, 1.0, 0.5), (1.0, 2.0, 4.0), 64, 10, (1, 3, 6, 12), 3
)


def run(args: argparse.Namespace) -> int:
    plan = QUICK if args.quick else FULL
    # The quick run has its own folder, so it never overwrites the full figures.
    out = Path(args.out_dir) / ("quick" if args.quick else "")
    out.mkdir(parents=True, exist_ok=True)
    results: dict[str, Any] = {
        "date": date.today().isoformat(),
        "machine": machine_line(),
        "quick": bool(args.quick),
        "reference": {
            "method": "targeted",
            "grid_m": REFERENCE_GRID_M,
            "positions": "exact (no lattice), no cropping",
            "analytic_check": reference_check(),
        },
        "defaults": derived_defaults(),
    }
    print(f"reference check: {results['reference']['analytic_check']}")
    results["speed_accuracy"] = {
        name: speed_accuracy(SAMPLES / f"{name}.blend", plan, seed=args.seed)
        for name in ("two_routes", "full_ground")
    }
    runs = optimize_runs(plan, args.seed)
    results["optimize"] = runs
    results["stability"] = stability([r for r in runs if r["config"] == "es"])
    results["bound"] = bound_section(plan)
    results["scaling"] = scaling(plan, args.seed)
    results["default_vs_paper"] = default_vs_paper(Path(args.paper_dir), args.seed, out)
    (out / "results.json").write_text(json_text(results))

    from tools.charts import bound_chart, optimize_chart, speed_accuracy_chart

    charts = charts_dir(args, out)
    speed_accuracy_chart(results, charts / "speed_accuracy.png")
    optimize_chart(results, charts / "optimize.png")
    bound_chart(results, charts / "bound.png")
    print(f"wrote {out / 'results.json'} and the charts in {charts}")
    return 0


def run_bound(args: argparse.Namespace) -> int:
    """Only the bound section (objective against time, with the lower bound), written
    into the existing ``results.json``, and its chart; with ``--scenes``, only those
    scenes, the others' figures kept."""
    plan = QUICK if args.quick else FULL
    out = Path(args.out_dir) / ("quick" if args.quick else "")
    out.mkdir(parents=True, exist_ok=True)
    path = out / "results.json"
    results = json.loads(path.read_text()) if path.is_file() else {}
    only = tuple(n.strip() for n in (args.scenes or "").split(";") if n.strip())
    scenes = bound_scenes(plan)
    unknown = sorted(set(only) - set(scenes))
    if unknown:
        print(f"error: bench bound --scenes: no scene {unknown[0]!r}; the scenes: "
              + "; ".join(scenes), file=sys.stderr)  # fmt: skip
        return 2
    results["bound"] = bound_section(plan, only, results.get("bound"))
    results.setdefault("date", date.today().isoformat())
    results.setdefault("machine", machine_line())
    path.write_text(json_text(results))
    from tools.charts import bound_chart

    chart = charts_dir(args, out) / "bound.png"
    bound_chart(results, chart)
    print(f"wrote the bound section of {path} and {chart}")
    return 0


def charts_dir(args: argparse.Namespace, out: Path) -> Path:
    """Where the charts go: the docs' pictures (``--charts-dir``, docs/img/, where the
    benchmarks page shows them), or beside a quick run's figures."""
    charts = out if args.quick else Path(args.charts_dir)
    charts.mkdir(parents=True, exist_ok=True)
    return charts


def run_scaling(args: argparse.Namespace) -> int:
    """Only the scaling section, written into the existing ``results.json`` (its own
    date): on a shared machine, the one section that takes a quarter of an hour can be
    measured again when nothing else runs."""
    plan = QUICK if args.quick else FULL
    out = Path(args.out_dir) / ("quick" if args.quick else "")
    out.mkdir(parents=True, exist_ok=True)
    path = out / "results.json"
    results = json.loads(path.read_text()) if path.is_file() else {}
    results["scaling"] = scaling(plan, args.seed)
    path.write_text(json_text(results))
    print(f"wrote the scaling section of {path}")
    return 0


def derived_defaults() -> dict[str, Any]:
    """The knobs' defaults as derived for the paper camera on the 1 m grid."""
    settings = OptimizeSettings()
    return {
        "method": settings.method,
        "grid_m": settings.grid_m,
        "position_step_m": settings.position_step_m or 2 * settings.grid_m,
        "pointcloud_oversample": auto_oversample(MODEL, settings.grid_m),
        "alpha": settings.alpha,
        "crop_to_range_m": MODEL.range_m,
        "fitness_band_m": round(BAND_M, 2),
    }


# --- reference -------------------------------------------------------------------


def reference_check() -> dict[str, float]:
    """The reference's hidden area behind flat_wall's wall against the analytic one."""
    import bpy

    from autoscoop_blender.scene.extract import extract_scene
    from autoscoop_blender.scene.factory import BVHFactory
    from headless.files import open_blend
    from tools.samples import FLAT_WALL_BOX

    open_blend(str(SAMPLES / "flat_wall.blend"))
    model = replace(MODEL, min_density_per_m2=0.0)
    seen = []
    for ignore in (False, True):
        bpy.data.objects["Wall"]["autoscoop_ignore"] = ignore
        scene = extract_scene()
        caster = BVHFactory.of(scene)()
        grid = GroundGrid(scene, caster, REFERENCE_GRID_M, reach_m=model.range_m)
        pose = place(grid, -8.0, 0.0, 7.0, 40.0, 0.0)
        seen.append(
            len(TargetedEvaluator(grid, caster).evaluate(model, pose).covered) * grid.cell_area
        )
    x0, y0, z0, x1, y1, z1 = FLAT_WALL_BOX
    s = np.array([-8.0, 0.0, 7.0])
    corners = np.array([[x, y, z] for x in (x0, x1) for y in (y0, y1) for z in (z0, z1)])
    proj = s[:2] + (corners[:, :2] - s[:2]) * (s[2] / (s[2] - corners[:, 2:3]))
    analytic = shapely.MultiPoint(proj).convex_hull.area - (x1 - x0) * (y1 - y0)
    measured = seen[1] - seen[0]
    return {
        "analytic_hidden_m2": round(analytic, 3),
        "reference_hidden_m2": round(measured, 3),
        "relative_error": round(abs(measured - analytic) / analytic, 5),
    }


def _poses(
    scene: SceneModel, grid: GroundGrid, n: int, rng: np.random.Generator
) -> list[SensorPose]:
    """Poses spread over the sensor areas, each looking towards nearby target points
    (an optimizer's candidates look at roads, not away from them)."""
    poses = []
    target_xy = grid.target_xy
    areas = scene.sensor_areas
    while len(poses) < n:
        area = areas[len(poses) % len(areas)]
        ((x, y),) = random_points(area.geometry, 1, rng)
        near = target_xy[np.hypot(*(target_xy - (x, y)).T) < 40.0]
        if len(near) == 0:
            continue
        cx, cy = near.mean(axis=0)
        yaw = math.degrees(math.atan2(cy - y, cx - x)) + rng.normal(0, 20.0)
        pitch = rng.uniform(MODEL.pitch_min_deg, 45.0)
        poses.append(SensorPose(float(x), float(y), 0.0, MODEL.mount_height_m, pitch, yaw % 360))
    return poses


def _at(
    grid: GroundGrid, pose: SensorPose, x: float | None = None, y: float | None = None
) -> SensorPose:
    x = pose.x if x is None else x
    y = pose.y if y is None else y
    return place(grid, x, y, pose.height_m, pose.pitch_deg, pose.yaw_deg)


# --- speed against accuracy ------------------------------------------------------------


def speed_accuracy(path: Path, plan: Plan, seed: int) -> list[dict[str, Any]]:
    """One row per (series, knob value): seconds per pose and both errors (mean)."""
    from autoscoop_blender.scene.factory import BVHFactory

    print(f"speed/accuracy on {path.name} ({plan.poses} poses)")
    full_scene, make_full = load_scene(str(path))
    full_caster = make_full()
    scene = full_scene.cropped(MODEL.range_m)
    caster = BVHFactory.of(scene)()
    ref_grid = GroundGrid(full_scene, full_caster, REFERENCE_GRID_M, reach_m=MODEL.range_m)
    rng = np.random.default_rng(seed)
    poses = _poses(scene, ref_grid, plan.poses, rng)
    reference = []
    for pose in poses:
        cov = TargetedEvaluator(ref_grid, full_caster).evaluate(
            MODEL, _at(ref_grid, pose), outside_band_m=math.inf
        )
        mask = np.zeros(ref_grid.n_targets, dtype=bool)
        mask[cov.covered] = True
        reference.append((mask, cov.footprint_m2))

    rows: list[dict[str, Any]] = []
    grids = {g: GroundGrid(scene, caster, g, reach_m=MODEL.range_m) for g in plan.grids}
    defaults = derived_defaults()

    def score(series, knob, value, evaluate, timing, default=False, note=""):
        dis, fp = [], []
        for pose, (ref_mask, ref_fp) in zip(poses, reference):
            verdict, footprint = evaluate(pose)
            dis.append(float((verdict != ref_mask).mean()))
            fp.append(abs(footprint - ref_fp) / max(ref_fp, 1e-9))
        row = {
            "series": series,
            "knob": knob,
            "value": value,
            "s_per_pose": timing,
            "point_disagreement": float(np.mean(dis)),
            "footprint_error": float(np.mean(fp)),
            "default": default,
        }
        if note:
            row["note"] = note
        rows.append(row)
        print(
            f"  {series:<18}{knob}={value!s:<6}{timing * 1e3:9.2f} ms/pose  "
            f"disagree {row['point_disagreement']:.3%}  footprint {row['footprint_error']:.2%}"
        )

    # targeted at several grid spacings (direct: a ray per point that can count)
    for g, grid in grids.items():
        ev = TargetedEvaluator(grid, caster)
        timing = _time(lambda p, ev=ev, grid=grid: ev.evaluate(MODEL, _at(grid, p), BAND_M), poses)

        def verdicts(pose, ev=ev, grid=grid):
            cov = ev.evaluate(MODEL, _at(grid, pose), outside_band_m=math.inf)
            return _cell_verdicts(grid, cov.covered, ref_grid), cov.footprint_m2

        score("targeted", "grid_m", g, verdicts, timing)

    # cached targeted at several position lattices (grid 1 m)
    grid = grids[1.0]
    for q in plan.quantizations:
        timing = _time_cached(grid, caster, poses, q, plan.orientations_per_position, rng)

        def snapped(pose, q=q):
            x, y = round(pose.x / q) * q, round(pose.y / q) * q
            cov = TargetedEvaluator(grid, caster).evaluate(
                MODEL, _at(grid, pose, x, y), outside_band_m=math.inf
            )
            return _cell_verdicts(grid, cov.covered, ref_grid), cov.footprint_m2

        score(
            "cached targeted", "position_step_m", q, snapped, timing,
            default=q == defaults["position_step_m"],
        )  # fmt: skip

    # pointcloud at several ray counts and alpha values (grid 1 m)
    for os_ in plan.pointcloud_oversample:
        for alpha in plan.alphas if os_ == 1 else (1.0,):
            ev = PointcloudEvaluator(grid, caster, oversample=os_, alpha=alpha)
            n = 2 if os_ > 1 else len(poses)  # oversampled patterns are slow: time a few
            timing = _time(lambda p, ev=ev: ev.evaluate(MODEL, _at(grid, p), BAND_M), poses[:n])

            def inside(pose, ev=ev):
                cov = ev.evaluate(MODEL, _at(grid, pose), outside_band_m=math.inf)
                poly = footprint_polygon(grid, cov)
                xy = ref_grid.target_xy
                return shapely.contains_xy(poly, xy[:, 0], xy[:, 1]), cov.footprint_m2

            knob = "oversample" if alpha == 1.0 else "alpha"
            value = os_ if alpha == 1.0 else alpha
            paper = os_ == defaults["pointcloud_oversample"] and alpha == 1.0
            score("pointcloud", knob, value, inside, timing, note="paper" if paper else "")

    # cropping the occluders to the sensors' reach, on and off (targeted, 1 m)
    uncropped_grid = GroundGrid(full_scene, full_caster, 1.0, reach_m=MODEL.range_m)
    for crop, (g, c) in (("off", (uncropped_grid, full_caster)), ("on", (grid, caster))):
        ev = TargetedEvaluator(g, c)
        timing = _time(lambda p, ev=ev, g=g: ev.evaluate(MODEL, _at(g, p), BAND_M), poses)

        def verdicts(pose, ev=ev, g=g):
            cov = ev.evaluate(MODEL, _at(g, pose), outside_band_m=math.inf)
            return _cell_verdicts(g, cov.covered, ref_grid), cov.footprint_m2

        note = f"{len(full_scene.faces) if crop == 'off' else len(scene.faces)} triangles"
        score("cropping", "crop", crop, verdicts, timing, default=crop == "on", note=note)
    return rows


def verdicts_at(points_xy: np.ndarray, covered: np.ndarray, query_xy: np.ndarray) -> np.ndarray:
    """(R,) a method's verdict at each query point (R, 2): that of the method's target
    point nearest to it. On the method's lattice that is the point of the cell holding
    the query, or, along the target's edge where that cell's centre falls outside the
    target, the neighbouring one. points_xy (N, 2), covered (N,) bool."""
    _, nearest = cKDTree(points_xy).query(query_xy)
    return covered[nearest]


def _cell_verdicts(grid: GroundGrid, covered: np.ndarray, ref: GroundGrid) -> np.ndarray:
    """``verdicts_at`` for target ordinals ``covered`` of ``grid``, at ``ref``'s points."""
    mask = np.zeros(grid.n_targets, dtype=bool)
    mask[covered] = True
    return verdicts_at(grid.target_xy, mask, ref.target_xy)


def _time(evaluate, poses: list[SensorPose]) -> float:
    evaluate(poses[0])  # warm up lazily dropped cells and caches
    t0 = time.perf_counter()
    for pose in poses:
        evaluate(pose)
    return (time.perf_counter() - t0) / len(poses)


def _time_cached(grid, caster, poses, q, per_position, rng) -> float:
    """Seconds per evaluation when each lattice position is tried ``per_position``
    times with different orientations, as the ES does (fresh cache)."""
    ev = CachedTargetedEvaluator(grid, caster)
    t0 = time.perf_counter()
    count = 0
    for pose in poses:
        x, y = round(pose.x / q) * q, round(pose.y / q) * q
        for _ in range(per_position):
            pitch = float(np.clip(pose.pitch_deg + rng.normal(0, 5), 31.0, 70.0))
            p = place(grid, x, y, pose.height_m, pitch, (pose.yaw_deg + rng.normal(0, 30)) % 360)
            ev.evaluate(MODEL, p, BAND_M)
            count += 1
    return (time.perf_counter() - t0) / count


# --- optimizer runs, stability, scaling ---------------------------------------------------

ES = OptimizeSettings(optimizer="es")
CONFIGS = {
    "es": ES,
    "greedy": OptimizeSettings(optimizer="greedy"),
    "lp": OptimizeSettings(optimizer="lp"),
    "es, position_step_1m": replace(ES, position_step_m=1.0),
    "es, position_step_4m": replace(ES, position_step_m=4.0),
}
# Deterministic configurations: one run says all (the seed plays no part).
DETERMINISTIC = ("greedy", "lp")


def optimize_runs(plan: Plan, seed: int) -> list[dict[str, Any]]:
    """Whole optimizations on two_routes: the paper's ES over ``plan.seeds`` seeds, its
    other configurations over a third as many, greedy and lp once."""
    scene, make_caster = load_scene(str(SAMPLES / "two_routes.blend"), MODEL.range_m)
    rows = []
    for name, settings in CONFIGS.items():
        count = plan.seeds if name == "es" else max(1, plan.seeds // 3)
        if name in DETERMINISTIC:
            count = 1
        seeds = range(seed, seed + count)
        for s in seeds:
            res = Run(scene, make_caster, MODEL, replace(settings, seed=s)).result()
            m = res.metrics
            rows.append(
                {
                    "config": name,
                    "seed": s,
                    "wall_s": m["wall_s"],
                    "sensors": m["sensors"],
                    "masts": m["masts"],
                    "coverage_fraction": m["coverage_fraction"],
                    "rays_cast": m["rays_cast"],
                    "cost": m["cost"],
                }
            )
            print(
                f"  optimize {name:<22} seed {s}: {m['sensors']} sensors, {m['masts']} masts, "
                f"{m['coverage_fraction']:.2%}, {m['wall_s']:.1f} s"
            )
    return rows


def stability(rows: list[dict[str, Any]]) -> dict[str, Any]:
    """Spread of the paper's ES answer over seeds."""
    out: dict[str, Any] = {"seeds": [r["seed"] for r in rows]}
    for key in ("sensors", "masts", "coverage_fraction", "wall_s"):
        v = np.array([r[key] for r in rows], dtype=float)
        out[key] = {
            "min": float(v.min()),
            "max": float(v.max()),
            "mean": round(float(v.mean()), 4),
            "std": round(float(v.std()), 4),
        }
    return out


def scaling(plan: Plan, seed: int) -> dict[str, Any]:
    """The default optimization on growing parts of full_ground (its first k of 12
    tiles), against the same k tiles optimized one by one.

    The tiles differ (turned, mirrored, their own trees), and one alone may take a
    quarter longer than another: seconds per m^2 against the first tile would charge
    the algorithm with the scene. So the test of linear time is the whole against the
    sum of its parts. Runs go one at a time, each in a fresh process (its peak memory
    is its own) on the same core, each part right after its newest tiles alone: two
    runs side by side slowed each other by 40 % here, and by 8 % more on one core than
    on the other. Times are CPU seconds; wall seconds are kept too.
    """
    alone: list[dict[str, Any]] = []
    points = []
    for k in plan.scaling_tiles:
        for t in range(len(alone) + 1, k + 1):
            alone.append(_scaling_run((t,), seed, f"tile {t:>2} alone"))
        whole = (
            dict(alone[0])
            if k == 1
            else _scaling_run(tuple(range(1, k + 1)), seed, f"{k:>2} tiles")
        )
        parts = alone[:k]
        whole["sum_of_parts_cpu_s"] = round(sum(a["cpu_s"] for a in parts), 2)
        whole["time_vs_sum_of_parts"] = round(whole["cpu_s"] / whole["sum_of_parts_cpu_s"], 3)
        for key in ("sensors", "evaluations"):
            whole[f"{key}_vs_sum_of_parts"] = round(whole[key] / sum(a[key] for a in parts), 3)
        points.append(whole)
        print(f"  scaling {k:>2} tiles against one by one: {whole['time_vs_sum_of_parts']}")
    base = points[0]
    # Per sensor and per evaluation tell whether a miss comes from the algorithm or
    # from a larger part needing more sensors per m^2.
    for p in points:
        for key, per in (("m2", "target_m2"), ("sensor", "sensors"), ("evaluation", "evaluations")):
            p[f"s_per_{key}_vs_first_tile"] = round(
                (p["cpu_s"] / p[per]) / (base["cpu_s"] / base[per]), 3
            )
    return {
        "date": date.today().isoformat(),
        "tiles_alone": alone,
        "points": points,
        "time_vs_sum_of_parts_largest": points[-1]["time_vs_sum_of_parts"],
        "time_per_area_vs_first_tile_largest": points[-1]["s_per_m2_vs_first_tile"],
        "linear_or_better": all(p["time_vs_sum_of_parts"] <= 1.1 for p in points),
    }


def _scaling_run(tiles: tuple[int, ...], seed: int, label: str) -> dict[str, Any]:
    """``_scaling_point`` in a fresh process; prints its figures."""
    row = _in_fresh_process(_scaling_point, tiles, seed)
    print(
        f"  scaling {label}: {row['target_m2']:.0f} m^2, {row['sensors']} sensors, "
        f"{row['evaluations']} evaluations, {row['cpu_s']:.1f} CPU s ({row['wall_s']:.1f} s "
        f"wall), {row['peak_rss_mb']:.0f} MB"
    )
    return row


def _scaling_point(tiles: tuple[int, ...], seed: int) -> dict[str, Any]:
    from autoscoop_blender.scene.factory import BVHFactory, forget_blender_script_paths

    forget_blender_script_paths()  # a spawned child: the pip bpy must win

    if hasattr(os, "sched_setaffinity"):  # every run on the same core (see ``scaling``)
        os.sched_setaffinity(0, {max(os.sched_getaffinity(0))})
    scene, _ = load_scene(str(SAMPLES / "full_ground.blend"))
    keep = {f"_T{t:02d}_" for t in tiles}
    part = replace(
        scene,
        targets=tuple(a for a in scene.targets if any(k in a.name for k in keep)),
        sensor_areas=tuple(a for a in scene.sensor_areas if any(k in a.name for k in keep)),
    ).cropped(MODEL.range_m)
    cpu = time.process_time()
    res = Run(part, BVHFactory.of(part), MODEL, replace(ES, seed=seed)).result()
    cpu = time.process_time() - cpu
    m = res.metrics
    return {
        "tiles": len(tiles),
        "tile_ids": list(tiles),
        "target_m2": m["target_area_m2"],
        "sensors": m["sensors"],
        "evaluations": m["evaluations"],
        "coverage_fraction": m["coverage_fraction"],
        "wall_s": m["wall_s"],
        "cpu_s": round(cpu, 2),
        "peak_rss_mb": _peak_rss_mb(),
    }


def _peak_rss_mb() -> float:
    """This process's peak resident memory, MB. (Not ru_maxrss: on Linux a spawned
    child inherits its parent's peak through fork and exec.)"""
    for line in Path("/proc/self/status").read_text().splitlines():
        if line.startswith("VmHWM:"):
            return round(int(line.split()[1]) / 1024, 1)
    return round(resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024, 1)


# --- objective against time, with the proven lower bound ---------------------------------

BOUND_RUNS = {
    "es": ES,
    "greedy": OptimizeSettings(optimizer="greedy"),
    "lp": OptimizeSettings(optimizer="lp"),
    "lp, sensors": OptimizeSettings(optimizer="lp", objective="sensors"),
    "lp, masts": OptimizeSettings(optimizer="lp", objective="masts"),
}


@dataclass(frozen=True)
class BoundScene:
    """A scene of the bound chart: ``source``, a sample .blend's name or an OpenDRIVE
    file of ``tests/data/xodr`` (``.xodr``, imported at the defaults first); the runs
    of ``BOUND_RUNS`` made on it; full_ground's ``tiles`` (none: the whole scene); the
    coverage every target point needs (``coverage_k``)."""

    source: str
    runs: tuple[str, ...]
    tiles: tuple[int, ...] = ()
    coverage_k: int = 1


def bound_scenes(plan: Plan) -> dict[str, BoundScene]:
    """The bound chart's scenes by name: the two samples and, in the full plan, the
    samples at ``coverage_k = 2`` and each OpenDRIVE file that ``bench xodr`` plans
    (Town04 about half an hour for lp at its default time limit)."""
    from tools.xodr_bench import FILES

    tiles = tuple(range(1, plan.bound_tiles + 1))
    scenes = {
        "two_routes": BoundScene("two_routes", tuple(BOUND_RUNS)),
        f"full_ground, {plan.bound_tiles} tiles": BoundScene(
            "full_ground", ("es", "greedy", "lp"), tiles
        ),
    }
    if plan is QUICK:
        return scenes
    scenes["two_routes, coverage_k = 2"] = BoundScene("two_routes", ("greedy", "lp"), (), 2)
    for name in FILES:
        scenes[name] = BoundScene(f"{name}.xodr", ("greedy", "lp"))
    return scenes


def bound_section(
    plan: Plan, only: tuple[str, ...] = (), before: dict[str, Any] | None = None
) -> dict[str, Any]:
    """The objective (cost = 3 x masts + sensors unless named) of each scene's runs
    against wall seconds, with lp's proven lower bound (``bound_scenes``). Each run in
    a fresh process, one at a time. only: measure just these scenes, keeping the
    others' rows, dates and machines from ``before`` (an earlier bound section): on
    a shared machine a scene can be measured again alone."""
    from tools.xodr_bench import XODR, imported_blend

    fresh: dict[str, list[dict[str, Any]]] = {}
    with tempfile.TemporaryDirectory() as tmp:
        for scene, how in bound_scenes(plan).items():
            if only and scene not in only:
                continue
            if how.source.endswith(".xodr"):
                blend = imported_blend(XODR / how.source, Path(tmp))
            else:
                blend = SAMPLES / f"{how.source}.blend"
            rows = fresh[scene] = []
            for name in how.runs:
                row = _in_fresh_process(_bound_point, str(blend), how.tiles, name, how.coverage_k)
                rows.append(row)
                print(
                    f"  bound {scene}, {name}: {row['sensors']} sensors on {row['masts']} "
                    f"masts, objective {row['objective']:g} >= {row['lower_bound']}, gap "
                    f"{row['gap']}, {row['wall_s']:.1f} s, {row['peak_rss_mb']:.0f} MB",
                    flush=True,
                )
    return merged_bound(before if only else None, fresh, date.today().isoformat(), machine_line())


def merged_bound(
    before: dict[str, Any] | None, fresh: dict[str, Any], today: str, machine: str
) -> dict[str, Any]:
    """A bound section: ``before``'s scenes (None: none), each with the date and
    machine it was measured on (where it kept none, ``before``'s date and no machine),
    then ``fresh``'s rows by scene, measured ``today`` on ``machine``, in place of
    any before."""
    before = before or {}
    scenes = dict(before.get("scenes", {}))
    measured = {
        name: before.get("measured", {}).get(name, {"date": before.get("date"), "machine": None})
        for name in scenes
    }
    for name, rows in fresh.items():
        scenes[name] = rows
        measured[name] = {"date": today, "machine": machine}
    return {"date": today, "measured": measured, "scenes": scenes}


def _in_fresh_process(fn, *args):
    """``fn(*args)`` in a spawned process of its own (its memory and time are its own)."""
    ctx = multiprocessing.get_context("spawn")
    with ProcessPoolExecutor(1, mp_context=ctx) as pool:
        return pool.submit(fn, *args).result()


def only_tiles(scene: Any, tiles: tuple[int, ...]) -> Any:
    """The scene's targets and sensor areas of full_ground's ``tiles`` only (all when
    none are named): their curves' names hold ``_Tnn_``."""
    if not tiles:
        return scene
    keep = {f"_T{t:02d}_" for t in tiles}
    return replace(
        scene,
        targets=tuple(a for a in scene.targets if any(k in a.name for k in keep)),
        sensor_areas=tuple(a for a in scene.sensor_areas if any(k in a.name for k in keep)),
    )


def _bound_point(blend: str, tiles: tuple[int, ...], name: str, coverage_k: int) -> dict[str, Any]:
    from autoscoop_blender.scene.factory import BVHFactory, forget_blender_script_paths

    forget_blender_script_paths()  # a spawned child: the pip bpy must win
    scene, _ = load_scene(blend)
    scene = only_tiles(scene, tiles)
    scene = scene.cropped(MODEL.range_m)
    settings = replace(BOUND_RUNS[name], coverage_k=coverage_k)
    run = Run(scene, BVHFactory.of(scene), MODEL, settings)
    # lp's best plan and its proven bound as they change: [s, best, bound] (best None
    # while a ground in parts has no whole plan yet, bound None before the first)
    trace: list[list[Any]] = []
    t0 = time.perf_counter()
    for p in run.steps():
        seen = p.best is not None or p.bound is not None
        if seen and (not trace or trace[-1][1:] != [p.best, p.bound]):
            trace.append([round(time.perf_counter() - t0, 2), p.best, p.bound])
    res = run.result()
    m = res.metrics
    cands = run.problem.candidates
    # The plan as written (world metres, rounded), evaluated afresh as `headless
    # coverage` does.
    again = evaluate_layout(
        scene, BVHFactory.of(scene)(), parse_sensors(result_dict(res), "the plan"), settings
    )
    return {
        "config": name,
        "objective_kind": settings.objective,
        "sensors": m["sensors"],
        "masts": m["masts"],
        "cost": m["cost"],
        "objective": m["objective"],
        "lower_bound": m["lower_bound"],
        "gap": m["gap"],
        "sensors_lower_bound": m["sensors_lower_bound"],
        "masts_lower_bound": m["masts_lower_bound"],
        "lp_bound": m["lp_bound"],
        "lp_rounds": m["lp_rounds"],
        "coverage_fraction": m["coverage_fraction"],
        "coverage_recomputed": again.metrics["coverage_fraction"],
        "wall_s": m["wall_s"],
        "target_m2": m["target_area_m2"],
        "candidates": None if cands is None else len(cands),
        "nonzeros": None if cands is None else int(cands.matrix.nnz),
        "peak_rss_mb": _peak_rss_mb(),
        "trace": trace,
    }


# --- the default pipeline against the paper's -------------------------------------------


def _checkpoint_records(run_dir: Path) -> list[dict[str, Any]]:
    """The fixed-sensor records of a run's checkpoint (none if there is none)."""
    path = run_dir / "checkpoint.jsonl"
    if not path.is_file():
        return []
    return [json.loads(line) for line in path.read_text().splitlines()[1:] if line.strip()]


def paper_figures(paper_dir: Path) -> dict[str, Any]:
    """The paper-faithful run's figures from its output folder: from ``result.json`` when
    it finished, else from its checkpoint so far (``paper_complete`` false, no masts:
    those are grouped at the end)."""
    result = paper_dir / "result.json"
    if result.is_file():
        p = json.loads(result.read_text())["metrics"]
        return {
            "paper_complete": True,
            "paper_wall_s": p["wall_s"],
            "paper_sensors": p["sensors"],
            "paper_masts": p["masts"],
            "paper_coverage": p["coverage_fraction"],
            "paper_rays_cast": p["rays_cast"],
            "paper_source": str(result),
        }
    records = _checkpoint_records(paper_dir)
    if not records:
        return {
            "paper_source": f"missing: run `python -m headless optimize --method pointcloud "
            f"--out-dir {paper_dir}`"
        }
    last = records[-1]
    return {
        "paper_complete": False,
        "paper_wall_s": last["wall_s"],
        "paper_sensors": len(records),
        "paper_masts": None,
        "paper_coverage": last["coverage"],
        "paper_rays_cast": last["rays_cast"],
        "paper_source": f"{paper_dir / 'checkpoint.jsonl'} (unfinished)",
    }


def default_vs_paper(paper_dir: Path, seed: int, out_dir: Path) -> dict[str, Any]:
    """Speed-up of the paper's ES with the default coverage method (cached targeted:
    ``headless optimize --optimizer es``) over the paper-faithful pipeline (the same ES
    with pointcloud) on two_routes, and how often the former's coverage verdicts for
    the layout it found differ from the reference's."""
    import subprocess
    import sys

    where = out_dir / "default_targeted"
    cmd = [
        sys.executable,
        "-m",
        "headless",
        "optimize",
        "--optimizer",
        "es",
        "--out-dir",
        str(where),
        "--overwrite",  # the bench's own folder, from an earlier bench run
        "--seed",
        str(seed),
    ]
    subprocess.run(cmd, check=True, capture_output=True)
    doc = json.loads((where / "result.json").read_text())
    specs = parse_sensors(doc, "result.json")
    scene, make_caster = load_scene(str(SAMPLES / "two_routes.blend"), MODEL.range_m)
    claimed = evaluate_layout(scene, make_caster(), specs, CoverageSettings())
    full_scene, make_full = load_scene(str(SAMPLES / "two_routes.blend"))
    full_caster = make_full()

    def reference_of(sensors):
        """The reference's coverage of a layout: (result, (R,) covered mask)."""
        ref = evaluate_layout(
            full_scene, full_caster, sensors, CoverageSettings(grid_m=REFERENCE_GRID_M)
        )
        return ref, ref.n_covered > 0

    reference, ref_mask = reference_of(specs)
    mine = verdicts_at(claimed.points[:, :2], claimed.n_covered > 0, reference.points[:, :2])
    m = doc["metrics"]
    out: dict[str, Any] = {
        "default_wall_s": m["wall_s"],
        "default_sensors": m["sensors"],
        "default_masts": m["masts"],
        "default_coverage": m["coverage_fraction"],
        "default_rays_cast": m["rays_cast"],
        "reference_coverage_of_default_layout": round(float(ref_mask.mean()), 6),
        "point_disagreement": round(float((mine != ref_mask).mean()), 6),
    }
    paper = paper_figures(paper_dir)
    out.update(paper)
    if paper.get("paper_complete"):
        # Each pipeline reports its own method's coverage; the reference judges both.
        paper_doc = json.loads((paper_dir / "result.json").read_text())
        _, paper_mask = reference_of(parse_sensors(paper_doc, "result.json"))
        out["reference_coverage_of_paper_layout"] = round(float(paper_mask.mean()), 6)
    if paper.get("paper_wall_s"):
        # An unfinished paper-faithful run took at least this long: a lower bound.
        out["speedup"] = round(paper["paper_wall_s"] / m["wall_s"], 1)
        out["speedup_is_lower_bound"] = not paper["paper_complete"]
        # Where the paper's run stopped short: the default's coverage with as many sensors.
        default_records = _checkpoint_records(where)
        n = paper["paper_sensors"]
        if not paper["paper_complete"] and 0 < n <= len(default_records):
            out["default_coverage_at_paper_sensors"] = default_records[n - 1]["coverage"]
    else:
        out["speedup"] = None
    print(f"  default vs paper: {out}")
    return out
