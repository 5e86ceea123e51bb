"""Memory and work of a run, estimated before anything big is allocated.

Every big allocation of a run scales with the grid spacing g, and most with the
sensors' reach r rather than with the target:

* the ground grid holds the cells within r of the target and sensor areas, about
  (area + perimeter r + pi r^2) / g^2 of them however small the target is, and one
  table entry per ``GRID_CHUNK`` cells of the lattice over their bounds plus r;
* a full coverage evaluation (``headless coverage``, the final report) looks at every
  cell within r of the sensor, pi r^2 / g^2 of them, and drops onto the ground those
  not dropped yet, one ray each;
* the candidate set of the lp and greedy optimizers holds one nonzero per (candidate,
  covered target point) pair: positions (sensor area / step^2) x orientations x the
  points each covers (~ footprint / g^2), so it grows as 1 / (g^2 step^2);
* the cached ``targeted`` evaluator keeps the sight lines of every target point in
  reach of every position it visits;
* the ``pointcloud`` method casts rays_h x rays_v x oversample^2 rays a pose.

``estimate_grid`` (the ground grid and what a coverage run does on it) and
``estimate_run`` (an optimization) compute those figures from the settings, the sensor
model and the scene's areas alone: nothing is cast and nothing allocated but a raster
of the areas (``footprints``: the points a candidate covers, from the model's
footprint on flat, empty ground convolved with the target raster). The grid's layout
is ``geom.grid_layout``'s, the machine's memory ``machine``'s. ``refusal`` refuses,
with one line that gives the estimate and names the setting to change, a run that
needs more memory than the machine has or more than a documented limit:
``GroundGrid`` checks the grid (so ``headless coverage`` and the panel's Evaluate are
protected), ``Problem`` the whole run, ``build_candidates`` the candidate matrix as it
is filled (``nonzero_limit``).

The bytes per cell, point, ray and nonzero were measured on ``flat_wall``,
``two_routes`` and ``full_ground`` at several grids (peak RSS from
``resource.getrusage`` and RSS sampled while the stage ran, less the RSS before it;
the arrays' ``nbytes``); they round up. Memory is in bytes throughout, lengths in metres.
"""

from __future__ import annotations

import logging
import math
from collections.abc import Callable, Sequence
from dataclasses import dataclass, replace

import numpy as np
import shapely
from numpy.typing import NDArray

from .footprints import Footprints, site_footprints
from .geom.grid_layout import (
    GRID_CHUNK,
    areas_bounds,
    chunk_count,
    chunk_dtype,
    grid_chunks,
    grid_shape,
)
from .machine import machine_memory_bytes, resident_bytes
from .model.scene import Area, SceneModel
from .model.sensors import SensorModel
from .settings import CANDIDATE_OPTIMIZERS, OptimizeSettings

log = logging.getLogger(__name__)

F64 = NDArray[np.float64]
I64 = NDArray[np.int64]

# --- limits --------------------------------------------------------------------------
# One evaluation is one step of a run: the progress bar and the Blender operator (whose
# Esc cannot interrupt a step) wait for it to end. 20 M rays are about 45 s at the
# BVHTree caster's measured 450,000 rays/s.
MAX_RAYS_PER_EVALUATION = 20_000_000
# Rays of one pose of the pointcloud method: about 20 us a ray with its densities and
# triangulations (measured 31 s for 1.5 M rays on flat_wall at 0.1 m, 5.4 s for 276 k
# at 0.25 m), so 2 M rays are about 40 s a pose.
MAX_PATTERN_RAYS = 2_000_000
# Candidate-matrix nonzeros. The bytes per nonzero below hold for scipy's int32
# indices, which it uses up to this count (beyond, int64: more bytes), and HiGHS takes
# the columns of a part as int32 arrays (``optimize/bound.py``).
MAX_NONZEROS = 2**31 - 1

# --- bytes, measured -----------------------------------------------------------------
# Ground grid, resident, per cell held: dist, z (float32), normal (3 x float32), target
# ordinal (int32); and per chunk of the whole lattice an entry of its table (int32, or
# int64 on a lattice of more than 2^30 cells: ``chunk_dtype``).
GRID_CELL_BYTES = 24
# Ground grid while it is built, at the peak, per cell held: the resident arrays plus
# the held chunks' indices (measured 24.1 on two_routes, Town01 and Town04 at 1 and
# 0.5 m; what it takes per target point is in TARGET_POINT_BYTES).
GRID_BUILD_CELL_BYTES = 25
# Finding the target points: the lattice cells tried against one target area at a
# time, at most about GRID_RASTER_BATCH of them: flat index, lattice coordinates,
# centre and the test (49 bytes a cell; 14 MB at the peak on a 2.8 km diagonal road
# at 0.25 m).
GRID_RASTER_BATCH = 1 << 18
GRID_RASTER_CELL_BYTES = 50
# Distances to the targets are measured against a tree of the targets' border points,
# built when first asked for (``GroundGrid.dist_to_target``): finding the border takes
# about 50 a target point for a moment, the tree (cKDTree and the points' coordinates)
# about 50 a border point (measured 35 to 45 for the tree), counted for every target
# point as a one-cell-wide target is all border.
TARGET_TREE_BYTES = 64
# A target point: flat index, region, height and normal (float64), centre (float64).
# Measured 86 to 95 (flat_wall at 0.1 and 0.05 m, two_routes at 0.1 m).
TARGET_POINT_BYTES = 100
# Rays in flight in one cast: the BVHTree caster turns each batch into Python lists
# and Vectors. Measured 740 a drop ray (own origin, with normals) and 450 a sight ray
# (shared origin). Drops go in batches of ``DROP_BATCH`` (``GroundGrid.drop``).
DROP_RAY_BYTES = 760
SIGHT_RAY_BYTES = 460
DROP_BATCH = 1 << 18
# A full targeted evaluation, per cell within reach besides its rays: the square of
# float64 distances in ``cells_in_disk``, the sight lines (float64 directions,
# distances, surface) and the view test. Measured 169 and 177 with the rays (flat_wall
# at 0.05 and 0.1 m, 11 % of the cells in view), so about 125 without.
EVALUATION_CELL_BYTES = 140
# The reference footprint (``coverage.reference``), per cell of its flat grid: the grid
# with every cell a target point, its drops, and its evaluations. Measured 201 and 209
# (0.05 and 0.1 m).
REFERENCE_CELL_BYTES = 220
# The pointcloud method, per ray of a pose's pattern: the pattern and its rotation
# (float64), hits, densities, the caster's lists and two Delaunay triangulations
# (measured 934 and 975 on flat_wall at 0.25 and 0.1 m: 276 k and 1.5 M rays).
POINTCLOUD_RAY_BYTES = 1000
# The cached targeted evaluator per (position, point) row: 56 of geometry, bounded by
# CACHE_GEOMETRY_BYTES (``CachedTargetedEvaluator.max_bytes``), and 1 of ray answer,
# kept for the whole run.
CACHE_ROW_BYTES = 56
# A camera with a resolution also keeps each row's facing factor (float64).
CACHE_PIXEL_ROW_BYTES = 8
CACHE_ANSWER_BYTES = 1
CACHE_GEOMETRY_BYTES = 2 << 30
# ``cover_many`` per (orientation, row) of one position: the rows in each sensor frame
# (float64 x 3), FoV tests, densities and masks.
COVER_TEST_BYTES = 64
# A mast position: its lattice coordinates and its entry in the position index (a
# Python dict); per point of an area's bounding lattice while the lattice is made.
POSITION_BYTES = 250
LATTICE_POINT_BYTES = 56
# Candidate matrix, per nonzero, at the peak of each stage (the matrix itself is
# float32 data and int32 indices: 8): while it is built (per-position int32 index
# arrays, their concatenation and the data), and while each optimizer works on it,
# everything of the run included (greedy's copy by columns; lp's restricted LPs, site
# matrix and pools). Measured on two_routes at 1 m (40.9 M nonzeros): greedy 23.8, lp
# 37.9; flat_wall at 0.5 m (14.1 M): greedy 27.3, lp 37.4 (before the int32 build,
# three tiles of full_ground, 125.7 M: greedy 26.1, lp 36.7). lp also holds HiGHS's
# models and a second thread's heap: about 170 MiB beyond its nonzeros on two_routes
# at 2 m (2.5 M nonzeros).
NONZERO_BYTES = 8
NONZERO_BUILD_BYTES = 16
NONZERO_OPTIMIZER_BYTES = {"greedy": 26, "lp": 36}
LP_BASE_BYTES = 192 << 20
# The lp optimizer plans a target in parts (``optimize/parts.py``) of at most this many
# target points (two_routes, 16,555, is one part) and, where the candidate matrix is
# dense, of at most ``PART_NONZEROS`` (about 3.6 GB through the optimizer's peak).
PART_POINTS = 20_000
PART_NONZEROS = 100_000_000
# The densest part's nonzeros over the average part's, allowed for in the estimate.
PART_IMBALANCE = 1.5
# The most parts a run is let go ahead with: a square kilometre at 1 m is about 50.
MAX_PARTS = 64
# Seconds of one core to build the candidate set, per estimated nonzero (dominated
# candidates included), measured 2026-11-25 on this project's 2-core machine: two_routes
# 43.0 M in 11.3 s, a part of Town04 in 23.5 s. A ground in parts builds the positions
# near the parts' borders once for each part they reach: PART_OVERLAP more.
BUILD_S_PER_NONZERO = 0.3e-6
PART_OVERLAP = 1.2
# An ES worker process before its grid and cache: a spawned interpreter with bpy,
# numpy, scipy and shapely imported and the caster built (measured 373 MiB on
# two_routes at 0.5 m, less its 19 MiB grid). Each worker then rebuilds the grid and
# keeps its own cache (``optimize/parallel.py``).
WORKER_BASE_BYTES = 400 << 20


@dataclass(frozen=True)
class Estimate:
    """What a run will need, estimated before it starts.

    Counts: ``grid_cells`` ground cells the grid holds (``grid_chunks``: those within
    ``reach_m`` (m, the longest sensor range) of the areas, by whole chunks) and
    ``target_points`` at spacing ``grid_m`` (m);
    ``disk_cells`` cells within reach of one sensor (a full evaluation looks at them);
    ``rays_per_evaluation`` the most rays one full targeted evaluation may cast (drops
    of the cells within reach plus sight rays to those in view; the model's share in
    view, or all of them when the model is not known); ``pattern_rays`` the rays of a
    pointcloud pose (0 for targeted);
    ``positions`` mast positions on the lattice of ``step_m`` (m); ``orientations``
    per position; ``nonzeros`` of the candidate matrix (0 when no candidate set is
    built); ``candidate_rays`` sight rays to build it; ``cache_rows`` (position, point)
    rows the cached evaluator may keep. Bytes: ``grid_bytes`` the grid resident,
    ``stages`` (name, peak bytes) of each stage with what is resident by then
    ("grid", "evaluation", "reference", "positions", "pattern", "cache",
    "candidates", "optimizer", "workers"), ``peak_bytes`` the largest, above what the process
    held before the run, ``peak_stage`` its name.
    ``optimizer`` and ``method`` say which run: None for a coverage run;
    ``workers`` the processes of the run (this one and the ES's workers beside it).
    """

    grid_m: float
    reach_m: float
    grid_cells: int
    target_points: int
    disk_cells: int
    rays_per_evaluation: int
    grid_bytes: int
    peak_bytes: int
    peak_stage: str
    stages: tuple[tuple[str, int], ...] = ()
    optimizer: str | None = None
    method: str = "targeted"
    step_m: float = 0.0
    positions: int = 0
    orientations: int = 0
    nonzeros: int = 0
    candidate_rays: int = 0
    cache_rows: int = 0
    pattern_rays: int = 0
    workers: int = 1
    parts: int = 1

    @property
    def candidates(self) -> int:
        """Candidate poses (positions x orientations), before those covering nothing
        are left out."""
        return self.positions * self.orientations

    def stage_bytes(self, stage: str) -> int:
        """Peak bytes of one stage (0 when the run has no such stage)."""
        return dict(self.stages).get(stage, 0)

    @property
    def build_s(self) -> float:
        """Seconds to build the candidate set (0 without one), on one core of a machine
        like this project's (``BUILD_S_PER_NONZERO``)."""
        overlap = PART_OVERLAP if self.parts > 1 else 1.0
        return self.nonzeros * BUILD_S_PER_NONZERO * overlap


# --- the ground grid ---------------------------------------------------------------------------------------


def disk_cells(reach_m: float, spacing: float) -> int:
    """Cells of spacing ``spacing`` whose centres lie within ``reach_m`` (m) of a point:
    pi r^2 / g^2, what one full evaluation looks at."""
    return int(math.ceil(math.pi * reach_m**2 / spacing**2))


def reference_cells(reach_m: float, spacing: float) -> int:
    """Cells of the flat grid on which the reference footprint is measured
    (``coverage.reference``): a square of side 2 r around the mast, every cell a target."""
    r = max(reach_m, 0.5)
    _, _, nx, ny = grid_shape((-r, -r, r, r), spacing, 0.0)
    return nx * ny


def estimate_grid(
    scene: SceneModel,
    spacing: float,
    reach_m: float,
    view_fraction: float = 1.0,
    pattern_rays: int = 0,
) -> Estimate:
    """What a ground grid of ``spacing`` (m) over the scene's areas plus ``reach_m``
    (m) needs, and what a coverage run on it does: one full evaluation per sensor,
    which drops the cells within reach and casts sight rays to those in view (at most
    ``view_fraction`` of them: 1 when the model is not known), and the reference
    footprint's flat grid of the same spacing; with ``pattern_rays`` > 0, the
    pointcloud method's evaluations instead, that many rays a pose.

    Stages (peak bytes above the process before the run): "grid" while it is built,
    "evaluation" a full evaluation with the grid resident, "reference" the reference
    grid with the grid resident, "pattern" a pointcloud pose with the grid resident.
    """
    g = float(spacing)
    areas = (*scene.targets, *scene.sensor_areas)
    lattice = grid_shape(areas_bounds(areas), g, reach_m)
    starts, stops = grid_chunks([a.geometry for a in areas], lattice, g, reach_m)
    cells = int((stops - starts).sum()) * GRID_CHUNK
    table = chunk_count(*lattice[2:]) * np.dtype(chunk_dtype(*lattice[2:])).itemsize
    targets = int(math.ceil(sum(a.area_m2 for a in scene.targets) / g**2))
    disk = disk_cells(reach_m, g) if reach_m > 0 else 0
    sight = int(math.ceil(disk * view_fraction))
    resident = cells * GRID_CELL_BYTES + table + targets * (TARGET_POINT_BYTES + TARGET_TREE_BYTES)
    drops = min(targets, DROP_BATCH) * DROP_RAY_BYTES
    raster = min(cells, GRID_RASTER_BATCH) * GRID_RASTER_CELL_BYTES
    build = cells * GRID_BUILD_CELL_BYTES + table + targets * TARGET_POINT_BYTES
    build += max(drops, raster)
    evaluation = (
        disk * EVALUATION_CELL_BYTES
        + min(disk, DROP_BATCH) * DROP_RAY_BYTES
        + sight * SIGHT_RAY_BYTES
    )
    stages = [("grid", build)]
    if disk:
        stages.append(("evaluation", resident + evaluation))
        stages.append(("reference", resident + reference_cells(reach_m, g) * REFERENCE_CELL_BYTES))
    if pattern_rays:
        stages.append(("pattern", resident + pattern_rays * POINTCLOUD_RAY_BYTES))
    stage, peak = max(stages, key=lambda s: s[1])
    return Estimate(
        grid_m=g,
        reach_m=float(reach_m),
        grid_cells=cells,
        target_points=targets,
        disk_cells=disk,
        rays_per_evaluation=disk + sight,
        grid_bytes=resident,
        peak_bytes=peak,
        peak_stage=stage,
        stages=tuple(stages),
        method="pointcloud" if pattern_rays else "targeted",
        pattern_rays=pattern_rays,
    )


# --- an optimization ---------------------------------------------------------------------
def estimate_run(
    scene: SceneModel,
    model: SensorModel,
    settings: OptimizeSettings,
    angles: F64,
    oversample_at: Callable[[float], int] | None = None,
    footprints: Footprints | None = None,
    workers: int = 1,
) -> Estimate:
    """What an optimization of ``model`` sensors on the scene with ``settings`` needs
    (``settings.min_density_per_m2`` already applied to the model): the grid stages of
    ``estimate_grid`` and, by optimizer, the mast positions, the candidate set (lp,
    greedy, or any with ``bound``) and the optimizer working on it, the cached
    evaluator's sight lines and, for ``pointcloud``, one pose's ray pattern.
    ``angles``: (O, 2) the candidate orientations, pitch and yaw in degrees
    (``problem.orientations``); ``oversample_at(grid_m)``: the pointcloud pattern's
    rays per pattern ray per axis at a grid (None: ``settings.oversample``, else 1);
    ``footprints``: ``_footprints`` of the same inputs, if known (they do not depend
    on the grid); ``workers``: processes scoring the ES's populations, each with its
    own grid, cache and evaluation in flight (stage "workers"; 1: none beside this
    one). ``problem.run_estimate`` fills these in.
    """
    fp = footprints or site_footprints(scene, model, settings, angles)
    g = settings.grid_m
    step = settings.position_step_m or 2.0 * g
    est = estimate_grid(scene, g, model.range_m, fp.view_fraction)
    stages = dict(est.stages)
    resident = est.grid_bytes

    positions, lattice = _positions(scene.sensor_areas, step)
    stages["positions"] = resident + positions * POSITION_BYTES + lattice * LATTICE_POINT_BYTES
    resident += positions * POSITION_BYTES

    pattern_rays = 0
    if settings.method == "pointcloud":
        oversample = oversample_at(g) if oversample_at else settings.oversample or 1
        pattern_rays = model.n_rays * oversample**2
        stages["pattern"] = resident + pattern_rays * POINTCLOUD_RAY_BYTES

    # Rows of the cached evaluator: targets within reach of each position
    # (reachability, candidates) and, for the ES, targets and the band beside them.
    cache_rows = int(positions * (fp.reach_m2 + fp.band_m2) / g**2)
    row_bytes = CACHE_ROW_BYTES + (CACHE_PIXEL_ROW_BYTES if model.resolution_px else 0)
    cache = min(cache_rows * row_bytes, CACHE_GEOMETRY_BYTES) + cache_rows * CACHE_ANSWER_BYTES
    stages["cache"] = resident + cache
    uses_candidates = settings.optimizer in CANDIDATE_OPTIMIZERS or settings.bound
    nonzeros = 0
    parts = 1
    if uses_candidates:
        nonzeros = int(positions * fp.covers_m2 / g**2)
        # lp and greedy plan a large ground in parts, one part's matrix at a time
        # (``optimize/parts.py``): the largest part's share of the nonzeros, with room
        # for parts of unequal density. Greedy's bound (``bound``) is the whole
        # ground's LP, so greedy with a bound plans whole.
        held = nonzeros
        if settings.optimizer == "lp" or (settings.optimizer == "greedy" and not settings.bound):
            parts = part_count(est.target_points, nonzeros)
            held = nonzeros if parts == 1 else int(nonzeros / parts * PART_IMBALANCE)
        tests = fp.orientations * fp.widest_m2 / g**2  # one position's cover_many
        stages["candidates"] = (
            resident + cache + held * NONZERO_BUILD_BYTES + int(tests * COVER_TEST_BYTES)
        )
        name = settings.optimizer if settings.optimizer in NONZERO_OPTIMIZER_BYTES else "lp"
        base = LP_BASE_BYTES if name == "lp" else 0
        stages["optimizer"] = resident + cache + base + held * NONZERO_OPTIMIZER_BYTES[name]
        # The matrix (a part's, in parts) stays referenced through the report.
        resident += held * NONZERO_BYTES
    for stage in ("evaluation", "reference"):
        stages[stage] += resident - est.grid_bytes + cache
    if settings.optimizer == "es" and workers > 1:
        in_flight = stages["evaluation"] - resident - cache
        worker = WORKER_BASE_BYTES + est.grid_bytes + cache + in_flight
        stages["workers"] = resident + cache + workers * worker
    stage, peak = max(stages.items(), key=lambda s: s[1])
    return replace(
        est,
        peak_bytes=peak,
        peak_stage=stage,
        stages=tuple(stages.items()),
        optimizer=settings.optimizer,
        method=settings.method,
        step_m=step,
        positions=positions,
        orientations=fp.orientations if uses_candidates else 0,
        nonzeros=nonzeros,
        parts=parts,
        candidate_rays=int(positions * fp.reach_m2 / g**2) if uses_candidates else 0,
        cache_rows=cache_rows,
        pattern_rays=pattern_rays,
        workers=workers,
    )


def part_count(target_points: int, nonzeros: int) -> int:
    """How many parts the lp optimizer plans a target in: enough for at most
    ``PART_POINTS`` points and ``PART_NONZEROS`` estimated nonzeros a part. Depends on
    the estimate only, never on the machine: the same inputs are split the same way."""
    return max(1, math.ceil(target_points / PART_POINTS), math.ceil(nonzeros / PART_NONZEROS))


def _positions(areas: Sequence[Area], step: float) -> tuple[int, int]:
    """(mast positions, points of the largest area's bounding lattice): counted exactly
    as ``SearchSpace`` makes them when the lattices are small, else area / step^2."""
    lattices = []
    for a in areas:
        minx, miny, maxx, maxy = a.geometry.bounds
        ni = math.ceil(maxx / step) - math.floor(minx / step) + 1
        nj = math.ceil(maxy / step) - math.floor(miny / step) + 1
        lattices.append(ni * nj)
    if sum(lattices) > 1 << 21:
        return sum(max(1, int(a.area_m2 / step**2)) for a in areas), max(lattices)
    parts: list[F64] = []
    for a in areas:
        minx, miny, maxx, maxy = a.geometry.bounds
        i = np.arange(np.floor(minx / step), np.ceil(maxx / step) + 1)
        j = np.arange(np.floor(miny / step), np.ceil(maxy / step) + 1)
        ii, jj = np.meshgrid(i, j, indexing="ij")
        ij = np.column_stack([ii.ravel(), jj.ravel()])
        inside = shapely.intersects_xy(a.geometry, ij[:, 0] * step, ij[:, 1] * step)
        parts.append(ij[inside] if inside.any() else np.array([[math.inf, len(parts)]]))
    return len(np.unique(np.concatenate(parts), axis=0)), max(lattices)


def nonzero_limit(
    optimizer: str, memory_bytes: int | None = None, resident: int | None = None
) -> int:
    """The most candidate-matrix nonzeros this process can still hold through the
    optimizer's peak (``NONZERO_OPTIMIZER_BYTES``; lp's for the ES with a bound): what
    the machine has less what the process holds now, at most ``MAX_NONZEROS``."""
    memory = machine_memory_bytes() if memory_bytes is None else memory_bytes
    held = resident_bytes() if resident is None else resident
    per = NONZERO_OPTIMIZER_BYTES.get(optimizer, NONZERO_OPTIMIZER_BYTES["lp"])
    base = 0 if optimizer == "greedy" else LP_BASE_BYTES
    return int(min(MAX_NONZEROS, max(memory - held - base, 0) // per))
