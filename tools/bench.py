"""Benchmarks that print figures (not timed tests): ``./dev.sh bench ...``.

Figures are wall-clock on this machine; compare methods by the ratios measured in
one run, since shared machines are noisy.
"""

from __future__ import annotations

import argparse
import time
from datetime import date
from pathlib import Path

import numpy as np

from autoscoop_blender.core.coverage.base import place
from autoscoop_blender.core.coverage.pointcloud import PointcloudEvaluator
from autoscoop_blender.core.coverage.targeted import TargetedEvaluator
from autoscoop_blender.core.geom.grid import GroundGrid
from autoscoop_blender.core.model.scene import random_points
from autoscoop_blender.core.model.sensors import PAPER_CAMERA, frame
from headless.files import json_text, load_scene
from tools import suite
from tools.machine import machine_line


def main(args: argparse.Namespace) -> int:
    """``bench [all|coverage|optimize|scaling|bound|xodr|constants]``."""
    if args.what == "constants":
        from tools import constants_bench

        return constants_bench.run(args)
    if args.what == "xodr":
        from tools import xodr_bench

        return xodr_bench.run(args)
    if args.what == "coverage":
        return coverage(args)
    if args.what == "optimize":
        return optimize(args)
    if args.what == "bound":
        return suite.run_bound(args)
    return suite.run(args) if args.what == "all" else suite.run_scaling(args)


def coverage(args: argparse.Namespace) -> int:
    """Rays per second of the BVH caster; seconds and rays per pose for each method."""
    model = PAPER_CAMERA
    scene, make_caster = load_scene(args.scene, model.range_m)
    caster = make_caster()
    t0 = time.perf_counter()
    grid = GroundGrid(scene, caster, 1.0, reach_m=model.range_m)
    grid_s = time.perf_counter() - t0
    rng = np.random.default_rng(args.seed)

    # Poses spread over all sensor areas, pitch and yaw inside the model's limits.
    poses = []
    for k in range(args.poses):
        area = scene.sensor_areas[k % len(scene.sensor_areas)]
        ((x, y),) = random_points(area.geometry, 1, rng)
        pitch = rng.uniform(model.pitch_min_deg, model.pitch_max_deg)
        poses.append(place(grid, x, y, model.mount_height_m, pitch, rng.uniform(0, 360)))

    # Raw caster speed: the rays of one full pattern from each pose.
    dirs = model.pattern_directions().reshape(-1, 3)
    t0 = time.perf_counter()
    n_rays = 0
    for pose in poses[:4]:
        d = dirs @ frame(pose.pitch_deg, pose.yaw_deg)
        caster.cast(np.broadcast_to(pose.position, d.shape), d, model.range_m)
        n_rays += len(d)
    rays_per_s = n_rays / (time.perf_counter() - t0)

    methods = {
        "targeted": TargetedEvaluator(grid, caster),
        "pointcloud": PointcloudEvaluator(grid, caster),
    }
    per_method = {}
    for name, ev in methods.items():
        times, rays, covered = [], [], []
        for pose in poses:
            t = time.perf_counter()
            cov = ev.evaluate(model, pose)
            times.append(time.perf_counter() - t)
            rays.append(cov.rays)
            covered.append(len(cov.covered))
        per_method[name] = {
            "s_per_pose_mean": float(np.mean(times)),
            "s_per_pose_median": float(np.median(times)),
            "rays_per_pose_mean": float(np.mean(rays)),
            "covered_points_mean": float(np.mean(covered)),
        }
    ratio = per_method["pointcloud"]["s_per_pose_mean"] / per_method["targeted"]["s_per_pose_mean"]
    figures = {
        "date": date.today().isoformat(),
        "machine": machine_line(),
        "scene": Path(args.scene).name,
        "triangles": int(len(scene.faces)),
        "target_points": grid.n_targets,
        "grid_setup_s": round(grid_s, 3),
        "poses": len(poses),
        "bvh_rays_per_s": round(rays_per_s),
        "methods": per_method,
        "pointcloud_over_targeted_time": round(ratio, 1),
    }
    print(
        f"scene {figures['scene']}: {figures['triangles']} triangles, "
        f"{grid.n_targets} target points, grid set-up {grid_s:.2f} s"
    )
    print(f"BVHTree caster: {rays_per_s:,.0f} rays/s")
    print(
        f"{'method':<12}{'s/pose mean':>14}{'s/pose median':>15}{'rays/pose':>12}{'covered pts':>13}"
    )
    for name, m in per_method.items():
        print(
            f"{name:<12}{m['s_per_pose_mean']:>14.4f}{m['s_per_pose_median']:>15.4f}"
            f"{m['rays_per_pose_mean']:>12.0f}{m['covered_points_mean']:>13.0f}"
        )
    print(f"pointcloud / targeted time per pose: {ratio:.1f}x")
    if args.out:
        Path(args.out).write_text(json_text(figures))
    return 0


def optimize(args: argparse.Namespace) -> int:
    """The default optimization against the paper-faithful one on two_routes (wall s,
    rays, sensors, masts, coverage), into ``bench/optimize.json``; the paper-faithful
    run is read from ``--paper-dir`` (``headless optimize --method pointcloud``)."""
    out_dir = Path(args.out_dir)
    figures = {
        "date": date.today().isoformat(),
        "machine": machine_line(),
        **suite.default_vs_paper(Path(args.paper_dir), args.seed, out_dir),
    }
    out_dir.mkdir(parents=True, exist_ok=True)
    (out_dir / "optimize.json").write_text(json_text(figures))
    return 0
