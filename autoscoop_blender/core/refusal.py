"""Refusing what a machine cannot run, in one line: a run whose estimate
(``budget.Estimate``) needs more memory than the machine has, or more than a limit,
is refused with the figures and the setting to change (a coarser grid first).
``check_grid`` guards the ground grid (``GroundGrid``, ``headless coverage``, the
panel's Evaluate), ``check_run`` a whole optimization (``Problem``)."""

from __future__ import annotations

import logging
from collections.abc import Callable
from dataclasses import replace

import numpy as np
from numpy.typing import NDArray

from . import budget, footprints
from .budget import Estimate
from .errors import InputError
from .machine import machine_memory_bytes, resident_bytes
from .model.scene import SceneModel
from .model.sensors import SensorModel
from .settings import OptimizeSettings

log = logging.getLogger(__name__)

F64 = NDArray[np.float64]

GRID_LADDER = (0.01, 0.02, 0.025, 0.05, 0.1, 0.2, 0.25, 0.5, 1.0, 2.0, 5.0, 10.0, 20.0)


def verdict(
    est: Estimate, memory_bytes: int | None = None, resident: int | None = None
) -> tuple[str, str] | None:
    """None when a run with this estimate may go ahead; else (what stops it: a stage
    of ``Estimate.stages`` or "rays", "nonzeros"; the limit it breaks, in words).

    The grid comes first (nothing else can be built without it), then the work of one
    evaluation, then the whole run's memory, then the matrix's index limit.
    ``memory_bytes``: the machine's (default ``machine_memory_bytes``); ``resident``:
    what the process holds already (default ``resident_bytes``).
    """
    memory = machine_memory_bytes() if memory_bytes is None else memory_bytes
    held = resident_bytes() if resident is None else resident
    used = f" ({bytes_text(held)} of it in use here already)" if held > 0.05 * memory else ""
    have = f"the machine has {bytes_text(memory)}{used}"
    if held + est.stage_bytes("grid") > memory:
        return "grid", have
    if est.pattern_rays > budget.MAX_PATTERN_RAYS:
        return "pattern", (
            f"the limit is {count_text(budget.MAX_PATTERN_RAYS)} rays a pose (about 40 s, in which "
            "nothing can interrupt it)"
        )
    if est.rays_per_evaluation > budget.MAX_RAYS_PER_EVALUATION:
        return "rays", (
            f"the limit is {count_text(budget.MAX_RAYS_PER_EVALUATION)} rays an evaluation (about "
            "45 s, in which nothing can interrupt it)"
        )
    if held + est.peak_bytes > memory:
        return est.peak_stage, have
    if est.parts > budget.MAX_PARTS:
        return "nonzeros", (
            f"that is {est.parts:,} parts of at most {budget.PART_POINTS:,} points and "
            f"{count_text(budget.PART_NONZEROS)} nonzeros, and the limit is {budget.MAX_PARTS} (about 5 "
            "minutes a part)"
        )
    if est.nonzeros / est.parts > budget.MAX_NONZEROS:
        return "nonzeros", f"the limit is {count_text(budget.MAX_NONZEROS)} (int32 indices)"
    return None


def check(
    est: Estimate,
    redo: Callable[[float], Estimate],
    memory_bytes: int | None = None,
    resident: int | None = None,
) -> Estimate:
    """``est``, or InputError (one line) when ``verdict`` finds it cannot go ahead: the
    estimate, the limit, and the setting to change, with the first coarser grid of
    ``GRID_LADDER`` that ``redo(grid_m)`` finds allowed and what it needs."""
    log.info("budget: %s", est)
    found = verdict(est, memory_bytes, resident)
    if found is None:
        return est
    stage, why = found
    hint = "raise grid_m (--grid)"
    for g in GRID_LADDER:
        if g > est.grid_m:
            other = redo(g)
            if verdict(other, memory_bytes, resident) is None:
                hint = f"raise grid_m (--grid; {g:g} needs {_needs(other)})"
                break
    raise InputError(f"{_what(est, stage)}; {why}: {hint}{_other_fixes(est, stage)}")


def check_grid(
    scene: SceneModel,
    spacing: float,
    reach_m: float,
    pattern_rays_at: Callable[[float], int] | None = None,
) -> Estimate:
    """``budget.estimate_grid`` checked (InputError when it cannot go ahead);
    ``pattern_rays_at(grid_m)``: the most rays a pointcloud pose casts at a grid (None
    for the targeted method)."""

    def at(g: float) -> Estimate:
        return budget.estimate_grid(
            scene, g, reach_m, pattern_rays=pattern_rays_at(g) if pattern_rays_at else 0
        )

    return check(at(spacing), at)


def check_run(
    scene: SceneModel,
    model: SensorModel,
    settings: OptimizeSettings,
    angles: F64,
    oversample_at: Callable[[float], int] | None = None,
    workers: int = 1,
) -> Estimate:
    """``budget.estimate_run`` checked (InputError when it cannot go ahead)."""
    fp = footprints.site_footprints(scene, model, settings, angles)
    est = budget.estimate_run(scene, model, settings, angles, oversample_at, fp, workers)

    def redo(g: float) -> Estimate:
        s = replace(settings, grid_m=g)
        return budget.estimate_run(scene, model, s, angles, oversample_at, fp, workers)

    return check(est, redo)


def _what(est: Estimate, stage: str) -> str:
    """What the estimate says of ``stage`` (see ``verdict``), in words."""
    g = f"grid_m = {est.grid_m:g}"
    reach = f"the sensors' {est.reach_m:g} m reach"
    peak = bytes_text(est.stage_bytes(stage) or est.peak_bytes)
    if stage in ("candidates", "optimizer", "nonzeros"):
        return (
            f"the {est.optimizer} optimizer at {g} needs a candidate matrix of about "
            f"{count_text(est.nonzeros)} nonzeros ({count_text(est.positions)} mast "
            f"positions x {est.orientations} orientations over "
            f"{count_text(est.target_points)} target points; {peak} at its peak)"
        )
    if stage == "pattern":
        return f"method pointcloud at {g} casts {count_text(est.pattern_rays)} rays a pose ({peak})"
    if stage in ("rays", "evaluation"):
        return (
            f"{g}: one full coverage evaluation looks at {count_text(est.disk_cells)} cells "
            f"within {reach} and casts up to {count_text(est.rays_per_evaluation)} rays "
            f"({peak} at the peak)"
        )
    if stage == "reference":
        cells = count_text(budget.reference_cells(est.reach_m, est.grid_m))
        return f"{g}: the reference footprint's flat grid of {cells} cells needs {peak}"
    if stage == "cache":
        return (
            f"the {est.optimizer} optimizer at {g} keeps sight lines of up to "
            f"{count_text(est.cache_rows)} (position, point) pairs ({peak} at the peak)"
        )
    if stage == "workers":
        return (
            f"the es optimizer at {g} with {est.workers} worker processes, each with its "
            f"own grid and sight lines of up to {count_text(est.cache_rows)} (position, "
            f"point) pairs, needs {peak} together"
        )
    if stage == "positions":
        return (
            f"{g} with mast positions every {est.step_m:g} m needs "
            f"{count_text(est.positions)} positions ({peak})"
        )
    return (
        f"{g} needs {count_text(est.grid_cells)} ground cells ({peak}) within {reach} of the areas"
    )


def _other_fixes(est: Estimate, stage: str) -> str:
    if stage in ("candidates", "optimizer", "nonzeros", "positions"):
        return " or position_step_m, or use --optimizer es"
    if stage == "pattern":
        return " or lower oversample (--oversample)"
    if stage == "workers":
        return " or use fewer workers (--workers)"
    return ""


def _needs(est: Estimate) -> str:
    """What an allowed estimate needs, briefly."""
    if est.nonzeros:
        return f"{count_text(est.nonzeros)} nonzeros, {bytes_text(est.peak_bytes)}"
    return bytes_text(est.peak_bytes)


def count_text(n: float) -> str:
    """A count in words: 46.6 G, 650 M, 26.0 k, 512; 1.2e+18 beyond T."""
    if n >= 1e15:
        return f"{n:.1e}"
    for size, unit in ((1e12, "T"), (1e9, "G"), (1e6, "M"), (1e3, "k")):
        if n >= size:
            value = n / size
            return f"{value:.1f} {unit}" if value < 100 else f"{value:,.0f} {unit}"
    return f"{int(n)}"


def bytes_text(n: float) -> str:
    """Bytes in binary units: 43 GiB, 1.9 GiB, 310 MiB; 1.2e+12 GiB beyond a PiB."""
    gib = n / (1 << 30)
    if gib >= 1 << 20:
        return f"{gib:.1e} GiB"
    if gib >= 1:
        return f"{gib:.1f} GiB" if gib < 100 else f"{gib:,.0f} GiB"
    return f"{max(n, 0) / (1 << 20):.0f} MiB"
