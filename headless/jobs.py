"""The jobs behind the subcommands: each parses nothing, computes, writes, returns 0."""

from __future__ import annotations

import argparse
import os
import sys
import time
from collections.abc import Callable
from dataclasses import replace
from pathlib import Path
from typing import Any

import numpy as np

from autoscoop_blender.core.budget import Estimate
from autoscoop_blender.core.errors import AutoscoopError, InputError
from autoscoop_blender.core.evaluate import evaluate_layout
from autoscoop_blender.core.model.scene import SceneModel
from autoscoop_blender.core.model.sensors import PRESETS, SensorPack
from autoscoop_blender.core.optimize.base import Progress
from autoscoop_blender.core.optimize.parts import PartBuilder
from autoscoop_blender.core.optimize.planner import time_limit
from autoscoop_blender.core.refusal import bytes_text, count_text
from autoscoop_blender.core.result import Result, area_at
from autoscoop_blender.core.run import Run
from autoscoop_blender.core.settings import (
    CoverageSettings,
    OptimizeSettings,
    flag_values,
    with_values,
)
from autoscoop_blender.io.config import load_config
from autoscoop_blender.io.figure import render_png
from autoscoop_blender.io.progress_text import duration, number
from autoscoop_blender.io.reports import (
    POINTS_HEADER,
    coverage_dict,
    gis_files,
    point_rows,
    result_dict,
    sensors_csv,
)
from autoscoop_blender.io.sensor_file import Standing, read_existing, read_sensors
from headless import interrupts, notes
from headless.checkpoint import NAME as CHECKPOINT_NAME
from headless.checkpoint import Checkpoint, checkpoint_header
from headless.files import (
    blend_bytes,
    check_outputs,
    csv_text,
    json_text,
    load_scene,
    quiet_fds,
    write_files,
)
from headless.interrupts import STOP_GRACE_S
from headless.lock import NAME as LOCK_NAME
from headless.lock import OutDirLock
from headless.paths import SAMPLES
from headless.progress import ProgressBar


def coverage(args: argparse.Namespace) -> int:
    """``coverage``: evaluate a sensors file on a scene, write OUT.json, its coverage
    map OUT.png beside it (+ the points' CSV)."""
    settings = CoverageSettings(**flag_values(CoverageSettings, vars(args))).validated()
    notes_path = notes.beside(Path(args.out))
    map_path = map_beside(Path(args.out))
    outputs = {Path(args.out): "--out", notes_path: "--out's notes", map_path: "--out's map"}
    if args.points_csv:
        outputs[Path(args.points_csv)] = "--points-csv"
    inputs = {Path(args.sensors): "the sensors file (--sensors)"}
    inputs.update(scene_input(args.scene))
    check_outputs(outputs, inputs, args.overwrite)
    specs = read_sensors(args.sensors)
    scene, make_caster = load_scene(args.scene, max(s.model.range_m for s in specs))
    result = evaluate_layout(scene, make_caster(), specs, settings)
    for w in result.warnings:
        print(f"warning: {w}", file=sys.stderr)
    for line in notes.exclusion_lines(result.excluded, no_mast_names(scene), notes_path):
        print(f"note: {line}", file=sys.stderr)
    for line in result.notes:
        print(f"note: {line}", file=sys.stderr)

    files: dict[Path, str | bytes] = {
        Path(args.out): json_text(coverage_dict(result)),
        map_path: render_png(result),
    }
    if args.points_csv:
        files[Path(args.points_csv)] = csv_text(POINTS_HEADER, point_rows(result))
    every_note = notes.exclusion_file(result.excluded)
    if every_note is not None:
        files[notes_path] = every_note
    write_files(files)
    if every_note is None:  # an earlier run's notes are not this one's
        notes_path.unlink(missing_ok=True)
    m = result.metrics
    print(
        f"coverage {m['coverage_fraction']:.2%} ({m['covered_m2']:.0f} of "
        f"{m['target_area_m2']:.0f} m^2) by {len(specs)} sensor(s), "
        f"{m['rays_cast']} rays, {m['wall_s']:.2f} s -> {args.out}, {map_path}"
    )
    return 0


def map_beside(out: Path) -> Path:
    """The coverage map of ``coverage --out OUT.json``: OUT.png beside it."""
    return (
        out.with_suffix(".png")
        if out.suffix.lower() != ".png"
        else out.with_name(out.name + ".png")
    )


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
    settings = with_values(settings, {k: v for k, v in overrides.items() if v is not None})
    settings = settings.validated()
    if args.model is not None:
        model = PRESETS[args.model]
    workers = default_workers() if args.workers is None else args.workers
    if workers < 1:
        raise InputError(f"--workers {workers}: must be at least 1")
    if args.repair and not args.resume:
        raise InputError("--repair: only with --resume (it repairs the checkpoint resumed)")
    out_dir = Path(args.out_dir)
    if out_dir.exists() and not out_dir.is_dir():
        raise InputError(f"{out_dir}: exists and is not a folder")
    scene_path = args.scene or default_scene()
    _check_out_dir(out_dir, args, scene_path)

    standing = read_existing(args.existing) if args.existing else Standing([], [])
    existing, existing_masts = standing.sensors, standing.masts
    SensorPack.of(model).check_optimizer(settings.optimizer)
    reach = max(m.range_m for m in SensorPack.of(model).models)
    scene, make_caster = load_scene(scene_path, reach)
    for w in scene.warnings:
        print(f"warning: {w}", file=sys.stderr)
    for line in notes.exclusion_lines(scene.excluded, no_mast_names(scene), out_dir / notes.NAME):
        print(f"note: {line}", file=sys.stderr)
    for w in standing_warnings(scene, standing, args.existing):
        print(f"warning: {w}", file=sys.stderr)
    with OutDirLock(out_dir) as lock:
        if lock.stale_pid is not None:
            print(
                f"note: {out_dir}: took over the lock of run {lock.stale_pid}, which has ended",
                file=sys.stderr,
            )
        header = checkpoint_header(scene, model, settings, existing, existing_masts)
        checkpoint = Checkpoint(out_dir, header)
        resume = checkpoint.resume(repair=args.repair) if args.resume else []

        def checkpoint_kept() -> str:
            return checkpoint.kept_text(settings.optimizer)

        interrupts.keep(checkpoint_kept)
        builder = part_builder(args.engine, make_caster, args.workers)
        run: Run | None = None
        bar: ProgressBar | None = None
        try:  # from here on an interrupt leaves no worker, Ray's included
            run = Run(
                scene, make_caster, model, settings, resume, on_fixed=checkpoint.append,
                workers=workers, existing=existing, existing_masts=existing_masts,
                part_builder=builder,
            )  # fmt: skip
            if resume:
                print(f"resuming after {len(resume)} fixed sensor(s)", file=sys.stderr)
            est = run.problem.estimate
            limit = ""
            if settings.optimizer == "lp":
                limit = f"; {time_text(est.build_s, time_limit(settings, est.parts))}"
            print(f"estimate: {estimate_text(est)}{limit}", file=sys.stderr, flush=True)
            preload_figure()
            bar = ProgressBar(t0=run.t0)
            stop = EarlyStop(run, checkpoint_kept)
            with interrupts.early_stop(stop):
                for progress in run.steps():
                    stop.see(progress)
                    bar.update(progress)
        finally:  # interrupted too: no worker left, the bar's line ended
            if run is not None:
                run.close()
            if builder is not None:
                builder.close()
            if bar is not None:
                bar.close()
        result = run.result()
        stopped = interrupts.stopped()
        if stopped:
            result = replace(result, interrupted=True)
        # Stopped, the run has until the watchdog's end (``interrupts.STOP_GRACE_S``):
        # no render of several seconds then.
        write_results(result, out_dir, render=args.render and not stopped)
        if args.render and stopped:  # an earlier run's view would not be this plan's
            (out_dir / "result_view.png").unlink(missing_ok=True)
        interrupts.keep(
            stopped_text(result, out_dir, args.render)
            if stopped
            else f"the results are written in {out_dir}"
        )
    for line in result.notes:
        print(f"note: {line}", file=sys.stderr)
    print(f"{plan_line(result, bool(existing or existing_masts))} -> {out_dir}")
    where = gap_line(result)
    if where is not None:
        print(where)
    print(result.stop_reason)
    m = result.metrics
    if stopped:
        interrupts.last_line()
        return interrupts.EXIT_INTERRUPTED
    if m["coverage_fraction"] < settings.rho:
        print(
            f"short of the goal: {m['coverage_fraction']:.2%} of {settings.rho:.0%} covered "
            f"(exit code {EXIT_SHORT_OF_GOAL}; the result is written)",
            file=sys.stderr,
        )
        return EXIT_SHORT_OF_GOAL
    return 0


class EarlyStop:
    """The first Ctrl-C or SIGTERM of a run whose optimizer keeps its best plan when
    stopped early (lp, ``Run.stop_early``): the run is asked to stop, and goes on to
    write that plan (``interrupts.early_stop``). Before the optimizer has a plan (while
    its candidates are built) there is nothing to keep, and the interrupt ends the run
    as with the other optimizers."""

    def __init__(self, run: Run, kept: Callable[[], str]) -> None:
        self.run = run
        self.kept = kept  # what the run keeps if the watchdog has to end it
        self.has_plan = False

    def see(self, p: Progress) -> None:
        self.has_plan |= p.best is not None or p.plan is not None or p.phase != "search"

    def __call__(self) -> bool:
        if not (self.has_plan and self.run.stop_early()):
            return False
        interrupts.keep(self._late)
        return True

    def _late(self) -> str:
        return (
            f"asked to stop early, the run had not written its plan {STOP_GRACE_S:g} s "
            f"later; {self.kept()}"
        )


def estimate_text(est: Estimate) -> str:
    """What the run was estimated to need before its heavy work (``Problem.estimate``):
    peak memory above what the process holds, and the counts it follows from. The
    estimate holds no time."""
    what = [f"{est.optimizer}", f"{est.target_points:,} target points"]
    if est.orientations:
        what.append(f"{est.positions:,} mast positions x {est.orientations} orientations")
    elif est.positions:
        what.append(f"{est.positions:,} mast positions")
    if est.nonzeros:
        what.append(f"~{count_text(est.nonzeros)} candidate matrix entries")
    if est.parts > 1:
        what.append(f"in {est.parts} parts")
    if est.optimizer == "es" and est.workers > 1:  # (only the ES has worker processes)
        what.append(f"{est.workers} processes")
    peak = f"peak ~{bytes_text(est.peak_bytes)} (at the {est.peak_stage} stage)"
    return f"{peak} for {', '.join(what)}"


def time_text(build_s: float, limit_s: float) -> str:
    """How long an lp run takes: its candidates (``Estimate.build_s``), then its search
    until its plan is done, within its time limit. A limit shorter than the candidates
    take does not cut them short (no plan exists without them): the line says so."""
    if limit_s < build_s:
        return (
            f"time: candidates ~{duration(build_s)} of one core, longer than the time limit "
            f"({duration(limit_s)}): the run ends once they are built, with the best plan by then"
        )
    return (
        f"time: candidates ~{duration(build_s)} of one core, the whole run at most "
        f"{duration(limit_s)} (its time limit)"
    )


def plan_line(result: Result, standing: bool = False) -> str:
    """What a finished run planned, in a line: "3 sensors on 1 mast cover 99.88 %,
    cost 6 >= 6 (optimal on the candidate set), in 5.1 s"; with ``standing``, how
    many of them stood already."""
    m = result.metrics
    kept = ""
    if standing:
        kept = f" ({m['existing_sensors']} and {m['existing_masts']} of them existing)"
    text = (
        f"{_count(m['sensors'], 'sensor')} on {_count(m['masts'], 'mast')}{kept} cover "
        f"{m['coverage_fraction']:.2%}"
    )
    if m.get("objective") is not None:
        name = result.settings.objective
        text += f", {name} {number(m['objective'])}"
        if m.get("lower_bound") is not None:
            proof = "optimal on the candidate set" if m["gap"] == 0 else f"gap {m['gap']:.1%}"
            text += f" >= {number(m['lower_bound'])} ({proof})"
    return f"{text}, in {m['wall_s']:.1f} s"


def gap_line(result: Result) -> str | None:
    """Where a plan's gap lies, in a line: the fewest masts and the fewest sensors that
    any plan on the candidate set needs (each proven on its own) against this plan's,
    the new ones only where some stood already (they cost nothing, and the bounds count
    the new ones). None when the plan is proven optimal or nothing was proven. It tells
    a planner how many masts a better plan could save at most: "no plan on the
    candidate set has fewer than 26 masts or fewer than 58 sensors; this one has 29
    and 73". With the fewest sensors on the plan's own masts proven
    (``sensors_on_masts_lower_bound``) it says whether a cheaper plan could keep
    them: "...; none on its masts has fewer sensors: a plan with fewer needs other
    masts" (and where the masts are the fewest too, as on two_routes, so does a
    cheaper plan)."""
    m = result.metrics
    if not m.get("gap"):
        return None
    new = "new " if m.get("existing_masts") or m.get("existing_sensors") else ""
    fewest, have = [], []
    for what in ("mast", "sensor"):
        least = m.get(f"{what}s_lower_bound")
        if least:  # (0: nothing proven of it)
            fewest.append(f"fewer than {_count(least, new + what)}")
            have.append(str(m[f"{what}s"] - m.get(f"existing_{what}s", 0)))
    if not fewest:
        return None
    text = (
        f"no plan on the candidate set has {' or '.join(fewest)}; "
        f"this one has {' and '.join(have)}"
    )
    on_masts = m.get("sensors_on_masts_lower_bound")
    if on_masts is None:
        return text
    if on_masts >= m["sensors"] - m.get("existing_sensors", 0):
        return f"{text}; none on its masts has fewer sensors: a plan with fewer needs other masts"
    return f"{text}; on its masts a plan needs at least {_count(on_masts, new + 'sensor')}"


def _count(n: int, what: str) -> str:
    return f"{n} {what}{'s' * (n != 1)}"


def stopped_text(result: Result, out_dir: Path, render: bool) -> str:
    """The last line of a run stopped early (without ``interrupted: ``): the plan kept,
    with its bound, and where it is."""
    m = result.metrics
    proof = ""
    if m.get("lower_bound") is not None:
        proof = f", bound {number(m['lower_bound'])}, gap {m['gap']:.1%}"
    skipped = " (result_view.png not rendered)" if render else ""
    return (
        f"stopped early; the best plan by then, {m['sensors']} sensors on {m['masts']} masts "
        f"(objective {number(m['objective'])}{proof}, coverage {m['coverage_fraction']:.2%}), "
        f'is written in {out_dir}{skipped}; result.json says "interrupted": true'
    )


def preload_figure() -> None:
    """Import what draws coverage.png now rather than at the end: 0.7 s of the
    finish of a run stopped early (``interrupts.STOP_GRACE_S``) on two_routes."""
    import matplotlib.backends.backend_agg  # noqa: F401
    import matplotlib.collections  # noqa: F401
    import matplotlib.figure  # noqa: F401
    import matplotlib.style  # noqa: F401


def no_mast_names(scene: SceneModel) -> list[str]:
    """The names of the scene's no-mast zones (``notes.exclusion_lines``)."""
    return [zone.name for zone in scene.no_mast]


def part_builder(engine: str, make_caster: Any, workers: int | None) -> PartBuilder | None:
    """Where lp and greedy build a ground's parts (``--engine``): None for here, or a
    ``RayBuilder`` (InputError without Ray, or inside a Blender binary, whose Python
    Ray's workers would start and which cannot import bpy)."""
    if engine != "ray":
        return None
    import bpy

    if bpy.app.binary_path:
        raise InputError("--engine ray: not inside a Blender binary; run with Python and bpy")
    from headless.ray_engine import RayBuilder

    return RayBuilder(make_caster, workers=workers)


def standing_warnings(scene: SceneModel, standing: Standing, path: str) -> list[str]:
    """Why ``--existing PATH`` may belong to another ground: a result.json planned for
    other target areas (``SceneModel.targets_fingerprint``), sensors or masts that
    stand outside every sensor area (``coverage`` warns of those too). They are still
    counted as standing: an existing mast may stand where no new one may."""
    out = []
    theirs = standing.targets_fingerprint
    if theirs is not None and theirs != scene.targets_fingerprint():
        out.append(
            f"--existing {path}: planned for other target areas than {scene.source}'s "
            "(its targets_fingerprint differs): is it this ground's plan?"
        )
    parts = []
    for what, xy in (
        ("sensor", [(s.x, s.y) for s in standing.sensors]),
        ("mast", list(standing.masts)),
    ):
        local = scene.to_local(np.array(xy, dtype=float).reshape(-1, 2))
        outside = sum(area_at(scene, float(x), float(y)) is None for x, y in local)
        if outside:
            parts.append(f"{outside} of its {len(xy)} {what}(s)")
    if parts:
        out.append(
            f"--existing {path}: {' and '.join(parts)} stand outside every sensor area of "
            f"{scene.source}; they are counted as standing all the same"
        )
    return out


RESULT_NAMES = (
    "result.json",
    notes.NAME,
    "sensors.csv",
    "coverage.png",
    "result.blend",
    "sensors_local.geojson",
    "sensors.geojson",
    "plan.gpkg",
)
"""What ``write_results`` writes (or removes: notes.txt when every note was printed, the
last two without a CRS) in the output folder; result_view.png too with ``--render``."""


def _check_out_dir(out_dir: Path, args: argparse.Namespace, scene: str | None) -> None:
    """``files.check_outputs`` for everything an optimize run may write in ``out_dir``:
    the results, the checkpoint (which ``--resume`` goes on with), the lock."""
    names = RESULT_NAMES + (("result_view.png",) if args.render else ())
    outputs = {out_dir / name: "--out-dir" for name in names}
    ckpt = out_dir / CHECKPOINT_NAME
    outputs[ckpt] = "the checkpoint"
    if args.repair:
        outputs[ckpt.with_name(CHECKPOINT_NAME + ".damaged")] = "--repair"
    outputs[out_dir / LOCK_NAME] = "the run's lock"
    inputs = scene_input(scene)
    for path, what in ((args.config, "--config"), (args.existing, "--existing")):
        if path:
            inputs[Path(path)] = f"the {what} file"
    kept = [out_dir / LOCK_NAME] + ([ckpt] if args.resume else [])
    for path in kept:  # opened in place, and never through a link (``O_NOFOLLOW``)
        if path.is_symlink():
            raise InputError(
                f"{path}: is a symbolic link, which AutoSCOOP does not follow; remove it"
            )
    if not args.resume and not args.overwrite and os.path.lexists(ckpt):
        raise InputError(
            f"{ckpt}: an earlier run's checkpoint; --resume goes on from it, --overwrite "
            "starts again, or choose another --out-dir"
        )
    check_outputs(outputs, inputs, args.overwrite, kept, "choose another --out-dir")


def scene_input(path: str | None) -> dict[Path, str]:
    """The scene file as an input for ``check_outputs``: the one given (or the bundled
    sample), else the one Blender opened; none in an unsaved Blender file."""
    import bpy

    given = path or bpy.data.filepath
    return {Path(given): "the scene"} if given else {}


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
    """result.json, sensors.csv, the GIS files, coverage.png, result.blend and the
    notes (``notes.exclusion_file``), all or none; result.blend holds the scene with
    the results collection. The GIS files (``reports.gis_files``):
    sensors_local.geojson, and with the scene's CRS sensors.geojson (WGS84) and
    plan.gpkg; without one a note on stderr says so. An earlier run's notes.txt and
    georeferenced files, when this run writes none, are removed: they would not be
    this plan's.

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
    files[out_dir / "result.blend"] = blend_bytes()
    if render:
        files[out_dir / "result_view.png"] = render_view_png(bpy.context.scene)
    every_note = notes.exclusion_file(result.excluded)
    if every_note is not None:
        files[out_dir / notes.NAME] = every_note
    write_files(files)
    stale = [notes.NAME] if every_note is None else []
    stale += list(STALE_WITHOUT_CRS) if note else []
    for name in stale:
        (out_dir / name).unlink(missing_ok=True)


STALE_WITHOUT_CRS = ("sensors.geojson", "plan.gpkg")
"""Written only with a CRS: removed from the output folder by a run without one."""


def render_view_png(scene: Any) -> bytes:
    """The PNG of ``render_view``, with Blender's render chatter (EGL warnings, "Saved:")
    kept off the terminal unless the render fails; prints how long it took."""
    from autoscoop_blender.scene.render_view import VIEW_SIZE, render_view

    start = time.perf_counter()
    try:
        with interrupts.held(), quiet_fds() as chatter:  # Blender renders (``interrupts``)
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
