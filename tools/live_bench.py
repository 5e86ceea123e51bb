"""Live re-scoring measured: ``python -m tools.live_bench [--plan result.json]``.

On ``two_routes`` with a plan (``--plan``: a result.json; default: the default
optimization's plan, made first, about 2 minutes), the ``core.live.LiveLayout`` is
built once, then 50 random moves (``--moves``) of one sensor each are re-scored: a
sensor picked at random moved by up to 15 m in x and y, turned by up to 60 deg of yaw,
its pitch anywhere in its model's limits. Printed and written to ``bench/live.json``:
the build's seconds and the memory it holds (its allocations, by tracemalloc), each
move's milliseconds (median, 95th percentile, most), and whether the counts after the
moves equal a full evaluation of the same poses (``evaluate_layout``, as ``headless
coverage`` runs it), point for point.
"""

from __future__ import annotations

import argparse
import json
import subprocess
import sys
import tempfile
import time
import tracemalloc
from dataclasses import replace
from datetime import date
from pathlib import Path

import numpy as np

from autoscoop_blender.core.evaluate import evaluate_layout
from autoscoop_blender.core.live import LiveLayout
from autoscoop_blender.core.settings import CoverageSettings
from autoscoop_blender.io.sensor_file import read_sensors
from headless.files import load_scene
from headless.paths import REPO, SAMPLES
from tools.machine import machine_line


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--plan", help="a result.json on two_routes (default: made first)")
    parser.add_argument("--moves", type=int, default=50)
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--out", default=str(REPO / "bench" / "live.json"))
    args = parser.parse_args(argv)
    scene_path = SAMPLES / "two_routes.blend"
    tmp_dir = tempfile.TemporaryDirectory(prefix="live-bench-")
    plan = Path(args.plan) if args.plan else default_plan(scene_path, Path(tmp_dir.name))
    specs = read_sensors(plan)
    scene, factory = load_scene(str(scene_path), max(s.model.range_m for s in specs))
    caster = factory()
    settings = CoverageSettings()

    # What the layout holds: Python's and numpy's allocations it leaves behind
    # (tracemalloc sees both; the resident set moves too little to measure here).
    tracemalloc.start()
    t0 = time.perf_counter()
    live = LiveLayout(scene, caster, specs, settings)
    build_s = time.perf_counter() - t0
    held = tracemalloc.get_traced_memory()[0]
    tracemalloc.stop()

    rng = np.random.default_rng(args.seed)
    times = []
    for _ in range(args.moves):
        i = int(rng.integers(len(live.specs)))
        s = live.specs[i]
        lo, hi = s.model.pitch_min_deg, s.model.pitch_max_deg
        moved = replace(
            s,
            x=s.x + float(rng.uniform(-15, 15)),
            y=s.y + float(rng.uniform(-15, 15)),
            pitch_deg=float(rng.uniform(lo, hi)),
            yaw_deg=(s.yaw_deg + float(rng.uniform(-60, 60))) % 360.0,
        )
        live.move(i, moved)
        times.append(live.last_s * 1000.0)
    whole = evaluate_layout(scene, caster, live.specs, settings)
    agree = bool(np.array_equal(live.counts, whole.n_covered))

    # Filling a gap: the plan again, 3 sensors deleted, the best one added.
    gap = LiveLayout(scene, caster, specs, settings)
    full_m2 = gap.metrics()["covered_m2"]
    deleted = sorted((int(i) for i in rng.choice(len(specs), 3, replace=False)), reverse=True)
    for i in deleted:
        gap.remove(i)
    holed_m2 = gap.metrics()["covered_m2"]
    # What limits one sensor: each deleted one, put back alone, brings back this much.
    alone_m2 = []
    for i in deleted:
        gap.add(specs[i])
        alone_m2.append(gap.metrics()["covered_m2"] - holed_m2)
        gap.remove(len(gap.specs) - 1)
    t0 = time.perf_counter()
    add = gap.best_addition(specs[0].model)
    fill_s = time.perf_counter() - t0
    if add is not None:
        gap.add(add.spec)
    filled_m2 = gap.metrics()["covered_m2"]
    recovered = (filled_m2 - holed_m2) / (full_m2 - holed_m2) if full_m2 > holed_m2 else 1.0

    ms = np.array(times)
    figures = {
        "date": date.today().isoformat(),
        "machine": machine_line(),
        "command": "python -m tools.live_bench" + (f" --plan {args.plan}" if args.plan else ""),
        "scene": "two_routes",
        "sensors": len(live.specs),
        "target_points": int(len(live.counts)),
        "build_s": round(build_s, 2),
        "held_mb": round(held / 2**20, 1),
        "moves": args.moves,
        "move_ms_median": round(float(np.median(ms)), 1),
        "move_ms_p95": round(float(np.percentile(ms, 95)), 1),
        "move_ms_max": round(float(ms.max()), 1),
        "counts_equal_full_evaluation": agree,
        "fill_s": round(fill_s, 2),
        "fill_lost_m2": round(full_m2 - holed_m2, 1),
        "fill_recovered_m2": round(filled_m2 - holed_m2, 1),
        "fill_recovered_share": round(recovered, 3),
        "fill_on_standing_mast": bool(add and add.on_standing_mast),
        "deleted_alone_m2": [round(a, 1) for a in alone_m2],
    }
    if (plan.parent / "result.blend").is_file():
        figures.update(blender_moves(plan, args.moves, args.seed))
    tmp_dir.cleanup()
    Path(args.out).write_text(json.dumps(figures, indent=1) + "\n")
    print(
        f"two_routes, {figures['sensors']} sensors: built in {build_s:.2f} s, holding "
        f"{figures['held_mb']} MB; {args.moves} moves: median {figures['move_ms_median']} ms, "
        f"95th percentile {figures['move_ms_p95']} ms, most {figures['move_ms_max']} ms; "
        f"counts equal to a full evaluation: {agree}; 3 sensors deleted lose "
        f"{figures['fill_lost_m2']} m^2, the best one added in {fill_s:.2f} s recovers "
        f"{figures['fill_recovered_m2']} m^2 ({recovered:.0%}; each deleted sensor alone "
        f"brings back {', '.join(f'{a:g}' for a in alone_m2)} m^2) -> {args.out}"
    )
    if "blender_move_ms_median" in figures:
        print(
            f"in Blender (the plan's result.blend, the add-on's handler in background mode): "
            f"the first re-score {figures['blender_first_s']} s, then a move and "
            f"view_layer.update() {figures['blender_move_ms_median']} ms (median; 95th "
            f"percentile {figures['blender_move_ms_p95']} ms); the panel's coverage equals a "
            f"full evaluation: {figures['blender_equal_full_evaluation']}; Fill Largest Gap "
            f"after 3 cameras deleted: {figures['blender_fill_s']} s"
        )
    return 0 if agree else 1


def blender_moves(plan: Path, moves: int, seed: int) -> dict[str, float | bool]:
    """Moves in Blender: the plan's result.blend opened, the add-on registered, its
    result set, then ``moves`` random camera moves, each timed from the move to the
    end of ``view_layer.update()`` (the depsgraph handler re-scores in it)."""
    import bpy

    import autoscoop_blender
    from autoscoop_blender.scene import pipeline
    from headless.files import open_blend

    open_blend(str(plan.parent / "result.blend"))
    autoscoop_blender.register()
    try:
        scene = bpy.context.scene
        scene.autoscoop.result_json = json.dumps(json.loads(plan.read_text()))
        cams = pipeline.sensor_cameras(scene)
        rng = np.random.default_rng(seed + 1)

        def move(cam: bpy.types.Object) -> float:
            m = cam.matrix_world.copy()
            m.translation.x += float(rng.uniform(-5, 5))
            m.translation.y += float(rng.uniform(-5, 5))
            t0 = time.perf_counter()
            cam.matrix_world = m
            bpy.context.view_layer.update()
            return time.perf_counter() - t0

        first = move(cams[0])  # builds the live layout
        ms = np.array([move(cams[int(rng.integers(len(cams)))]) * 1000 for _ in range(moves)])
        shown = json.loads(scene.autoscoop.result_json)["metrics"]["coverage_fraction"]
        full = pipeline.evaluated_now(scene).coverage_fraction
        # Fill Largest Gap as the panel runs it, 3 cameras deleted first.
        for cam in list(cams)[:3]:
            bpy.data.objects.remove(cam)
        bpy.context.view_layer.update()
        t0 = time.perf_counter()
        bpy.ops.autoscoop.fill_gap()
        fill_s = time.perf_counter() - t0
    finally:
        autoscoop_blender.unregister()
    return {
        "blender_first_s": round(first, 2),
        "blender_move_ms_median": round(float(np.median(ms)), 1),
        "blender_move_ms_p95": round(float(np.percentile(ms, 95)), 1),
        "blender_equal_full_evaluation": bool(abs(shown - full) < 1e-6),
        "blender_fill_s": round(fill_s, 2),
    }


def default_plan(scene: Path, tmp: Path) -> Path:
    """The default optimization's plan of ``scene`` (its result.json)."""
    out = tmp / "plan"
    cmd = [sys.executable, "-m", "headless", "optimize", str(scene), "--out-dir", str(out)]
    subprocess.run(cmd, cwd=REPO, check=True, capture_output=True)
    return out / "result.json"


if __name__ == "__main__":
    sys.exit(main())
