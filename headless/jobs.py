"""The jobs behind the subcommands: each parses nothing, computes, writes, returns 0."""

from __future__ import annotations

import argparse
import os
import sys
import tempfile
import time
from dataclasses import replace
from pathlib import Path
from typing import Any

from autoscoop_blender.core.errors import AutoscoopError, InputError
from autoscoop_blender.core.evaluate import evaluate_layout
from autoscoop_blender.core.model.sensors import SensorPack
from autoscoop_blender.core.result import Result
from autoscoop_blender.core.run import Run
from autoscoop_blender.core.settings import CoverageSettings, OptimizeSettings, flag_values
from autoscoop_blender.io.config import load_config
from autoscoop_blender.io.figure import render_png
from autoscoop_blender.io.reports import (
    POINTS_HEADER,
    coverage_dict,
    gis_files,
    point_rows,
    result_dict,
    sensors_csv,
)
from autoscoop_blender.io.sensor_file import read_existing, read_sensors
from headless.checkpoint import Checkpoint, checkpoint_header
from headless.files import csv_text, json_text, load_scene, quiet_fds, write_files
from headless.lock import OutDirLock
from headless.paths import SAMPLES
from headless.progress import ProgressBar


def coverage(args: argparse.Namespace) -> int:
    """``coverage``: evaluate a sensors file on a scene, write OUT.json (+ CSV)."""
    settings = CoverageSettings(**flag_values(CoverageSettings, vars(args))).validated()
    if args.points_csv and Path(args.points_csv).resolve() == Path(args.out).resolve():
        raise InputError(f"{args.out}: given as both --out and --points-csv; name two files")
    specs = read_sensors(args.sensors)
    scene, make_caster = load_scene(args.scene, max(s.model.range_m for s in specs))
    result = evaluate_layout(scene, make_caster(), specs, settings)
    for w in result.warnings:
        print(f"warning: {w}", file=sys.stderr)
    for e in result.excluded:
        print(f"note: {e.text()}", file=sys.stderr)

    outputs: dict[Path, str | bytes] = {Path(args.out): json_text(coverage_dict(result))}
    if args.points_csv:
        outputs[Path(args.points_csv)] = csv_text(POINTS_HEADER, point_rows(result))
    write_files(outputs)
    m = result.metrics
    print(
        f"coverage {m['coverage_fraction']:.2%} ({m['covered_m2']:.0f} of "
        f"{m['target_area_m2']:.0f} m^2) by {len(specs)} sensor(s), "
        f"{m['rays_cast']} rays, {m['wall_s']:.2f} s -> {args.out}"
    )
    return 0


EXIT_SHORT_OF_GOAL = 3
"""optimize's exit code when the plan ends short of the coverage goal (result written)."""


def optimize(args: argparse.Namespace) -> int:
    """``optimize``: place sensors on a scene; result files in the output folder.

    Every input is checked before the output folder is touched; the folder is locked
    for the run (``headless.lock``); the checkpoint is replaced only once the first
    sensor is fixed. Returns 0 when the goal was reached, ``EXIT_SHORT_OF_GOAL`` when
    not, 130 when interrupted.
    """
    settings, model = load_config(args.config)
    overrides = flag_values(OptimizeSettings, vars(args))
    settings = replace(settings, **{k: v for k, v in overrides.items() if v is not None})
    settings = settings.validated()
    workers = default_workers() if args.workers is None else args.workers
    if workers < 1:
        raise InputError(f"--workers {workers}: must be at least 1")
    if args.repair and not args.resume:
        raise InputError("--repair: only with --resume (it repairs the checkpoint resumed)")
    out_dir = Path(args.out_dir)
    if out_dir.exists() and not out_dir.is_dir():
        raise InputError(f"{out_dir}: exists and is not a folder")

    existing, existing_masts = read_existing(args.existing) if args.existing else ([], [])
    SensorPack.of(model).check_optimizer(settings.optimizer)
    reach = max(m.range_m for m in SensorPack.of(model).models)
    scene, make_caster = load_scene(args.scene or default_scene(), reach)
    for w in scene.warnings:
        print(f"warning: {w}", file=sys.stderr)
    for e in scene.excluded:
        print(f"note: {e.text()}", file=sys.stderr)
    with OutDirLock(out_dir) as lock:
        if lock.stale_pid is not None:
            print(
                f"note: {out_dir}: took over the lock of run {lock.stale_pid}, which has ended",
                file=sys.stderr,
            )
        header = checkpoint_header(scene, model, settings, existing, existing_masts)
        checkpoint = Checkpoint(out_dir, header)
        resume = checkpoint.resume(repair=args.repair) if args.resume else []
        run = Run(
            scene, make_caster, model, settings, resume, on_fixed=checkpoint.append,
            workers=workers, existing=existing, existing_masts=existing_masts,
        )  # fmt: skip
        if resume:
            print(f"resuming after {len(resume)} fixed sensor(s)", file=sys.stderr)
        bar = ProgressBar()
        try:
            for progress in run.steps():
                bar.update(progress)
        except KeyboardInterrupt:
            run.close()
            bar.close()
            print(
                f"interrupted: {len(run.sensors)} sensor(s) kept in {checkpoint.path}; "
                "run again with --resume to go on",
                file=sys.stderr,
            )
            return 130
        bar.close()
        result = run.result()
        write_results(result, out_dir, render=args.render)
    m = result.metrics
    kept = ""
    if existing or existing_masts:
        kept = f" ({m['existing_sensors']} and {m['existing_masts']} of them existing)"
    print(
        f"{m['sensors']} sensors on {m['masts']} masts{kept} cover "
        f"{m['coverage_fraction']:.2%} in {m['wall_s']:.1f} s -> {out_dir}\n{result.stop_reason}"
    )
    if m["coverage_fraction"] < settings.rho:
        print(
            f"short of the goal: {m['coverage_fraction']:.2%} of {settings.rho:.0%} covered "
            f"(exit code {EXIT_SHORT_OF_GOAL}; the result is written)",
            file=sys.stderr,
        )
        return EXIT_SHORT_OF_GOAL
    return 0


def default_workers() -> int:
    """One worker process per core, but none inside a Blender binary: its bundled
    Python, which worker processes would start, cannot import bpy."""
    import bpy

    return 1 if bpy.app.binary_path else (os.cpu_count() or 1)


def default_scene() -> str | None:
    """The file Blender opened (None: keep it), else the bundled two_routes sample."""
    import bpy

    return None if bpy.data.filepath else str(SAMPLES / "two_routes.blend")


def write_results(result: Result, out_dir: Path, render: bool = False) -> None:
    """result.json, sensors.csv, the GIS files, coverage.png and result.blend, all or
    none; result.blend holds the scene with the results collection. The GIS files
    (``reports.gis_files``): sensors_local.geojson, and with the scene's CRS
    sensors.geojson (WGS84) and plan.gpkg; without one a note on stderr says so.

    render: also result_view.png, the oblique view of that scene, rendered after
    result.blend's bytes were taken; the render leaves the scene as it was.
    """
    import bpy

    from autoscoop_blender.scene.spawn import spawn_results

    blender = {"blender": bpy.app.version_string}
    files: dict[Path, str | bytes] = {
        out_dir / "result.json": json_text(result_dict(result, blender)),
        out_dir / "sensors.csv": sensors_csv(result),
        out_dir / "coverage.png": render_png(result),
    }
    gis, note = gis_files(result)
    files.update({out_dir / name: data for name, data in gis.items()})
    if note:
        print(f"note: {note}", file=sys.stderr)
    spawn_results(bpy.context.scene, result)
    out_dir.mkdir(parents=True, exist_ok=True)
    with tempfile.TemporaryDirectory(dir=out_dir) as tmp:
        blend = Path(tmp) / "result.blend"
        with quiet_fds():  # Blender's "Info: Saved copy as ..." is not ours to print
            bpy.ops.wm.save_as_mainfile(filepath=str(blend), copy=True, compress=True)
        files[out_dir / "result.blend"] = blend.read_bytes()
    if render:
        files[out_dir / "result_view.png"] = render_view_png(bpy.context.scene)
    write_files(files)
    if note:
        # An earlier run's georeferenced files would not be this plan's.
        for name in STALE_WITHOUT_CRS:
            (out_dir / name).unlink(missing_ok=True)


STALE_WITHOUT_CRS = ("sensors.geojson", "plan.gpkg")
"""Written only with a CRS: removed from the output folder by a run without one."""


def render_view_png(scene: Any) -> bytes:
    """The PNG of ``render_view``, with Blender's render chatter (EGL warnings, "Saved:")
    kept off the terminal unless the render fails; prints how long it took."""
    from autoscoop_blender.scene.render_view import VIEW_SIZE, render_view

    start = time.perf_counter()
    try:
        with quiet_fds() as chatter:
            png = render_view(scene)
    except RuntimeError as e:
        sys.stderr.write("".join(chatter))
        raise AutoscoopError(
            f"result_view.png: Blender could not render the view ({e}); run without --render"
        ) from None
    print(
        f"result_view.png: {VIEW_SIZE[0]} x {VIEW_SIZE[1]} px, Workbench, "
        f"{time.perf_counter() - start:.1f} s",
        file=sys.stderr,
    )
    return png
