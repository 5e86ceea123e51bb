"""The jobs behind the subcommands: each parses nothing, computes, writes, returns 0."""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

from autoscoop_blender.core.analysis import CoverageSettings, evaluate_sensors
from autoscoop_blender.core.sensor_file import read_sensors
from headless.files import csv_text, json_text, load_scene, write_files

POINTS_HEADER = ("x", "y", "z", "n_visible", "n_covered", "best_density")


def coverage(args: argparse.Namespace) -> int:
    """``coverage``: evaluate a sensors file on a scene, write OUT.json (+ CSV)."""
    settings = CoverageSettings(
        method=args.method,
        grid_m=args.grid,
        target_height_m=args.target_height,
        min_density_per_m2=args.min_density,
        oversample=args.oversample,
        alpha=args.alpha,
    ).validated()
    specs = read_sensors(args.sensors)
    scene, caster = load_scene(args.scene)
    result = evaluate_sensors(scene, caster, specs, settings)
    for w in result.warnings:
        print(f"warning: {w}", file=sys.stderr)

    outputs: dict[Path, str | bytes] = {Path(args.out): json_text(result.to_dict())}
    if args.points_csv:
        outputs[Path(args.points_csv)] = csv_text(POINTS_HEADER, result.point_rows())
    write_files(outputs)
    s = result.summary
    print(
        f"coverage {s.coverage_fraction:.2%} ({s.covered_m2:.0f} of "
        f"{result.grid.target_area_m2:.0f} m^2) by {len(specs)} sensor(s), "
        f"{result.rays_cast} rays, {result.wall_s:.2f} s -> {args.out}"
    )
    return 0
