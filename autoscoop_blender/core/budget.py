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
of the areas of at most ``RASTER_CELLS`` cells. The points a candidate covers come from
the model's footprint on flat, empty ground (within 2 % there; occluders lower it)
convolved with the target raster, summed over the sensor areas. ``check`` refuses,
with one line that gives the estimate and names the setting to change, a run that
needs more memory than the machine has or more than a documented limit.
``GroundGrid`` checks the grid (so ``headless coverage`` and the panel's Evaluate are
protected), ``Problem`` the whole run, ``build_candidates`` the candidate matrix as it
is filled.

The bytes per cell, point, ray and nonzero were measured on ``flat_wall``,
``two_routes`` and ``full_ground`` at several grids (peak RSS from
``resource.getrusage`` and RSS sampled while the stage ran, less the RSS before it;
the arrays' ``nbytes``); they round up. Memory is in bytes throughout, lengths in metres.
"""

from __future__ import annotations

import logging
import math
import os
import sys
from collections.abc import Callable, Sequence
from dataclasses import dataclass, replace

import numpy as np
import shapely
from numpy.typing import NDArray
from scipy import signal
from shapely.geometry.base import BaseGeometry

from .errors import InputError
from .model.scene import Area, SceneModel
from .model.sensors import SensorModel, frame
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
# The machine's memory where it cannot be read (neither POSIX sysconf nor Windows).
FALLBACK_MEMORY_BYTES = 8 << 30

# --- the ground grid's layout ----------------------------------------------------------
# The grid holds only the cells a sensor may see a target point from or a mast in a
# sensor area may look at (``grid_chunks``): those in tiles of GRID_TILE x GRID_TILE
# lattice cells whose ground lies within reach of an area, stored by chunks of
# GRID_CHUNK consecutive flat indices (a run of one lattice row, or the end of one and
# the start of the next), found from the flat index by a shift and one table entry
# (``GroundGrid``).
GRID_TILE = 32
GRID_CHUNK = 64

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

# --- the estimate's raster ---------------------------------------------------------------
# The areas are rasterized to at most this many cells (sampled 2 x 2 a cell), cells of
# at least RASTER_MIN_M: enough to weigh a footprint of about 1,000 m^2 against roads.
RASTER_CELLS = 1 << 18
RASTER_MIN_M = 1.0
# Radial samples of a footprint profile, and bearings around the mast.
PROFILE_RADII = 400
PROFILE_BEARINGS = 720


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


# --- the machine -------------------------------------------------------------------------


def machine_memory_bytes() -> int:
    """Physical memory of the machine, bytes: POSIX ``sysconf`` (page size x physical
    pages), or Windows' ``GlobalMemoryStatusEx``; the smaller limit of a Linux cgroup
    (a container) when there is one; ``FALLBACK_MEMORY_BYTES`` when none can be read."""
    total = 0
    try:
        total = os.sysconf("SC_PAGE_SIZE") * os.sysconf("SC_PHYS_PAGES")
    except (AttributeError, ValueError, OSError):
        total = _windows_memory()
    if total <= 0:
        total = FALLBACK_MEMORY_BYTES
    limit = _cgroup_limit()
    return min(total, limit) if limit else total


def _windows_memory() -> int:
    if sys.platform != "win32":
        return 0
    import ctypes

    class _Status(ctypes.Structure):
        _fields_ = [
            ("dwLength", ctypes.c_ulong),
            ("dwMemoryLoad", ctypes.c_ulong),
            ("ullTotalPhys", ctypes.c_ulonglong),
            ("ullAvailPhys", ctypes.c_ulonglong),
            ("ullTotalPageFile", ctypes.c_ulonglong),
            ("ullAvailPageFile", ctypes.c_ulonglong),
            ("ullTotalVirtual", ctypes.c_ulonglong),
            ("ullAvailVirtual", ctypes.c_ulonglong),
            ("ullAvailExtendedVirtual", ctypes.c_ulonglong),
        ]

    status = _Status()
    status.dwLength = ctypes.sizeof(_Status)
    try:
        windll = ctypes.windll  # type: ignore[attr-defined,unused-ignore]  # Windows only
        ok = windll.kernel32.GlobalMemoryStatusEx(ctypes.byref(status))
    except (AttributeError, OSError):
        return 0
    return int(status.ullTotalPhys) if ok else 0


def _cgroup_limit() -> int:
    """The memory limit of this process's Linux cgroup (v2 or v1), 0 for none."""
    for path in ("/sys/fs/cgroup/memory.max", "/sys/fs/cgroup/memory/memory.limit_in_bytes"):
        try:
            with open(path) as f:
                text = f.read().strip()
        except OSError:
            continue
        if text.isdigit() and int(text) < 1 << 60:  # v1 says "no limit" with ~2^63
            return int(text)
    return 0


def resident_bytes() -> int:
    """What this process holds now (resident set), bytes; 0 where it cannot be read
    (then the check counts the run alone)."""
    try:
        with open("/proc/self/statm") as f:
            return int(f.read().split()[1]) * os.sysconf("SC_PAGE_SIZE")
    except (OSError, ValueError, IndexError, AttributeError):
        pass
    try:
        import resource
    except ImportError:  # Windows
        return 0
    peak = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss
    return int(peak) if sys.platform == "darwin" else int(peak) * 1024  # macOS: bytes


# --- the ground grid -----------------------------------------------------------------------


def grid_shape(
    bounds: Sequence[float], spacing: float, reach_m: float
) -> tuple[float, float, int, int]:
    """(x0, y0, nx, ny): the lattice corner (m) and cell counts of a ground grid of
    ``spacing`` (m) over ``bounds`` (minx, miny, maxx, maxy; m) plus ``reach_m`` and
    two cells around them. ``GroundGrid`` is built on exactly this lattice."""
    minx, miny, maxx, maxy = (float(b) for b in bounds)
    g = float(spacing)
    pad = reach_m + 2 * g
    x0 = math.floor((minx - pad) / g) * g
    y0 = math.floor((miny - pad) / g) * g
    nx = int(math.ceil((maxx + pad - x0) / g))
    ny = int(math.ceil((maxy + pad - y0) / g))
    return x0, y0, nx, ny


def grid_chunks(
    geometries: Sequence[BaseGeometry],
    lattice: tuple[float, float, int, int],
    spacing: float,
    reach_m: float,
) -> tuple[I64, I64]:
    """The chunks a ground grid holds, as sorted, disjoint ranges [starts, stops) of
    chunk indices (chunk c: flat cells c * GRID_CHUNK to c * GRID_CHUNK + GRID_CHUNK - 1).

    lattice: (x0, y0, nx, ny) of ``grid_shape``. A chunk is held when one of its cells
    lies in a tile (``tile_runs``) whose ground is within ``reach_m`` (m) of one of
    ``geometries``: every cell whose centre is within reach of an area. Computed from
    the geometry alone, so the estimate and the grid count the same chunks.
    """
    x0, y0, nx, ny = lattice
    ti, tj0, tj1 = tile_runs(geometries, lattice, spacing, reach_m)
    t = GRID_TILE
    # Each tile run is a run of cells in each of its GRID_TILE lattice rows.
    rows = np.minimum(ti * t + t, nx) - ti * t
    i = ranges(ti * t, ti * t + rows)
    lo = i * ny + np.repeat(tj0 * t, rows)
    hi = i * ny + np.repeat(np.minimum(tj1 * t, ny), rows)
    return merged(lo // GRID_CHUNK, (hi - 1) // GRID_CHUNK + 1)


def chunk_count(nx: int, ny: int) -> int:
    """Chunks of ``GRID_CHUNK`` flat indices over a lattice of nx x ny cells: the
    grid's table entries."""
    return -(-nx * ny // GRID_CHUNK)


def chunk_dtype(nx: int, ny: int) -> type[np.int32] | type[np.int64]:
    """The dtype of the grid's table over a lattice of nx x ny cells: int32 while a
    flat index plus the least int32 stays below minus the cells held (at most the
    lattice's, rounded up to a chunk), so that numpy refuses it as an index; int64
    beyond (2^30 cells)."""
    return np.int32 if 2 * nx * ny + GRID_CHUNK < 2**31 else np.int64


def tile_runs(
    geometries: Sequence[BaseGeometry],
    lattice: tuple[float, float, int, int],
    spacing: float,
    distance: float,
    window: tuple[int, int, int, int] | None = None,
) -> tuple[I64, I64, I64]:
    """Tiles of GRID_TILE x GRID_TILE lattice cells whose ground (the cells' squares,
    clipped to the lattice) lies within ``distance`` (m) of one of ``geometries``, as
    runs along j: (ti, tj0, tj1), tiles (ti, tj0) to (ti, tj1 - 1), sorted, adjacent
    runs joined. Tile (ti, tj) holds cells i = ti T .. ti T + T - 1, j likewise.

    lattice: (x0, y0, nx, ny); window: (ti0, tj0, ti1, tj1), only the tiles
    ti0 <= ti < ti1, tj0 <= tj < tj1 (default: all). A quadtree over the tiles: a
    square of tiles farther than ``distance`` is dropped whole, one whose centre lies
    within ``distance`` less its half diagonal is taken whole, others are split, so
    the work follows the border of what is taken, not the lattice's size.
    """
    x0, y0, nx, ny = lattice
    g, t = float(spacing), GRID_TILE
    nti, ntj = -(-nx // t), -(-ny // t)
    wi0, wj0, wi1, wj1 = window or (0, 0, nti, ntj)
    wi1, wj1 = min(wi1, nti), min(wj1, ntj)
    parts = shapely.get_parts(np.asarray(geometries, dtype=object))
    none = np.zeros(0, dtype=np.int64)
    if wi1 <= wi0 or wj1 <= wj0 or len(parts) == 0:
        return none, none, none
    tree = shapely.STRtree(parts)
    size = 1 << max(0, math.ceil(math.log2(max(wi1 - wi0, wj1 - wj0))))
    ti, tj = np.array([wi0], dtype=np.int64), np.array([wj0], dtype=np.int64)
    whole: list[tuple[I64, I64, I64]] = []  # squares taken whole: (ti, tj, side)
    while len(ti):
        ia, ib = ti * t, np.minimum(np.minimum(ti + size, wi1) * t, nx)
        ja, jb = tj * t, np.minimum(np.minimum(tj + size, wj1) * t, ny)
        xa, xb, ya, yb = x0 + ia * g, x0 + ib * g, y0 + ja * g, y0 + jb * g
        near = tree.query(shapely.box(xa, ya, xb, yb), predicate="dwithin", distance=distance)
        hit = np.unique(near[0])
        ti, tj, xa, xb, ya, yb = ti[hit], tj[hit], xa[hit], xb[hit], ya[hit], yb[hit]
        if size == 1:
            whole.append((ti, tj, np.ones(len(ti), dtype=np.int64)))
            break
        room = distance - 0.5 * np.hypot(xb - xa, yb - ya)
        full = np.zeros(len(ti), dtype=bool)
        if (room >= 0).any():
            k = np.flatnonzero(room >= 0)
            centres = shapely.points(0.5 * (xa[k] + xb[k]), 0.5 * (ya[k] + yb[k]))
            inner = tree.query(centres, predicate="dwithin", distance=room[k])
            full[k[np.unique(inner[0])]] = True
        whole.append((ti[full], tj[full], np.full(int(full.sum()), size, dtype=np.int64)))
        size //= 2
        ti, tj = ti[~full], tj[~full]
        ti = np.concatenate([ti, ti + size, ti, ti + size])
        tj = np.concatenate([tj, tj, tj + size, tj + size])
        inside = (ti < wi1) & (tj < wj1)
        ti, tj = ti[inside], tj[inside]
    si, sj, side = (np.concatenate(a) for a in zip(*whole))
    # A square of side s: s runs, one per tile row.
    height = np.minimum(si + side, wi1) - si
    ri = ranges(si, si + height)
    r0 = np.repeat(sj, height)
    r1 = np.repeat(np.minimum(sj + side, wj1), height)
    order = np.lexsort((r0, ri))
    ri, r0, r1 = ri[order], r0[order], r1[order]
    # Join runs that touch in the same tile row (r1 of one is r0 of the next).
    new = np.ones(len(ri), dtype=bool)
    new[1:] = (ri[1:] != ri[:-1]) | (r0[1:] != r1[:-1])
    last = np.append(np.flatnonzero(new)[1:] - 1, len(ri) - 1)
    return ri[new], r0[new], r1[last]


def ranges(starts: I64, stops: I64) -> I64:
    """The integers of each range [starts, stops), concatenated in order."""
    n = np.maximum(np.asarray(stops) - np.asarray(starts), 0)
    offset = np.repeat(np.asarray(starts) - (np.cumsum(n) - n), n)
    return np.arange(int(n.sum()), dtype=np.int64) + offset


def merged(starts: I64, stops: I64) -> tuple[I64, I64]:
    """Ranges [starts, stops) joined where they overlap or touch: sorted, disjoint."""
    if len(starts) == 0:
        return starts.astype(np.int64), stops.astype(np.int64)
    order = np.argsort(starts, kind="stable")
    lo, hi = starts[order], np.maximum.accumulate(stops[order])
    new = np.ones(len(lo), dtype=bool)
    new[1:] = lo[1:] > hi[:-1]
    last = np.append(np.flatnonzero(new)[1:] - 1, len(lo) - 1)
    return lo[new].astype(np.int64), hi[last].astype(np.int64)


def areas_bounds(areas: Sequence[Area]) -> tuple[float, float, float, float]:
    """(minx, miny, maxx, maxy) of the areas together, m."""
    b = np.array([a.geometry.bounds for a in areas], dtype=float).reshape(-1, 4)
    return float(b[:, 0].min()), float(b[:, 1].min()), float(b[:, 2].max()), float(b[:, 3].max())


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


@dataclass(frozen=True)
class _Footprints:
    """What a run's figures at any grid come from, per mast position in m^2 of target
    (divide by g^2 for points): ``reach_m2`` within reach of some allowed orientation
    (the cached evaluator's rows; mean over the sensor areas), ``widest_m2`` its
    largest, ``band_m2`` the same for the targets and the ES's band beside them,
    ``covers_m2`` covered, summed over the candidate orientations (the matrix's
    nonzeros); ``view_fraction`` the largest share of the disk within range that one
    orientation has in view; ``orientations`` of the candidate grid."""

    reach_m2: float
    widest_m2: float
    band_m2: float
    covers_m2: float
    view_fraction: float
    orientations: int


def _footprints(
    scene: SceneModel, model: SensorModel, settings: OptimizeSettings, angles: F64
) -> _Footprints:
    """The grid-free part of ``estimate_run`` (see ``_Footprints``) for the candidate
    orientations ``angles`` (O, 2): the model's flat-ground profiles from each mast
    height, convolved with the raster of the targets."""
    heights = _heights(scene, model)
    profiles = {h: _profile(model, h, settings.target_height_m, angles) for h in set(heights)}
    raster = _Raster(scene, model.range_m, heights)
    targets = raster.fractions(scene.target_union)
    reach, widest = raster.over_positions(targets, profiles, "reach")
    band = 0.0
    if settings.optimizer == "es":
        ring = raster.fractions(scene.target_union.buffer(settings.fitness.band_m))
        band = raster.over_positions(ring, profiles, "reach")[0]
    covers = 0.0
    if settings.optimizer in CANDIDATE_OPTIMIZERS or settings.bound:
        covers = raster.over_positions(targets, profiles, "covers")[0]
    return _Footprints(
        reach_m2=reach,
        widest_m2=widest,
        band_m2=band,
        covers_m2=covers,
        view_fraction=max(p.view_fraction for p in profiles.values()),
        orientations=len(angles),
    )


def estimate_run(
    scene: SceneModel,
    model: SensorModel,
    settings: OptimizeSettings,
    angles: F64,
    oversample_at: Callable[[float], int] | None = None,
    footprints: _Footprints | None = None,
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
    fp = footprints or _footprints(scene, model, settings, angles)
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
        # lp plans a large ground in parts, one part's matrix at a time
        # (``optimize/parts.py``): the largest part's share of the nonzeros, with room
        # for parts of unequal density.
        held = nonzeros
        if settings.optimizer == "lp":
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


def _heights(scene: SceneModel, model: SensorModel) -> list[float]:
    """Each sensor area's mast height (its own, else the model's), m."""
    return [
        a.height_m if a.height_m is not None else model.mount_height_m for a in scene.sensor_areas
    ]


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


@dataclass(frozen=True)
class _Profile:
    """A model's footprint on flat, empty ground from one mast height, by horizontal
    distance ``radii`` (R,) m from the mast: ``covers`` (R,) how many orientations of
    the candidate grid cover a point there (averaged over bearings), ``reach`` (R,)
    whether some allowed orientation might (the cached evaluator's rows);
    ``view_fraction`` the largest share of the disk within range that one orientation
    has in view."""

    radii: F64
    covers: F64
    reach: F64
    view_fraction: float


def _profile(model: SensorModel, height_m: float, target_height_m: float, angles: F64) -> _Profile:
    """The model's ``_Profile`` from ``height_m`` above flat ground (see ``_Profile``)
    for the candidate orientations ``angles`` (O, 2), pitch and yaw in degrees; yaws
    evenly spaced round the circle at each pitch."""
    r = model.range_m
    radii = (np.arange(PROFILE_RADII) + 0.5) * (r / PROFILE_RADII)
    b = (np.arange(PROFILE_BEARINGS) + 0.5) * (2 * math.pi / PROFILE_BEARINGS)
    rho, bb = np.meshgrid(radii, b, indexing="ij")
    x, y = (rho * np.cos(bb)).ravel(), (rho * np.sin(bb)).ravel()
    ground = np.column_stack([x, y, np.full(x.shape, -height_m)])
    gdist = np.linalg.norm(ground, axis=1)
    gd = ground / gdist[:, None]
    aim = ground + (0.0, 0.0, target_height_m)
    dist = np.linalg.norm(aim, axis=1)
    d = aim / dist[:, None]
    surface = np.abs(gd[:, 2]) / np.maximum(gdist, 1e-9) ** 2  # flat ground: n = +z
    in_range = dist <= r
    pitches, yaws = np.unique(angles[:, 0], return_counts=True)
    covers = np.zeros(len(radii))
    view = 0.0
    ring = radii * (r / PROFILE_RADII) * 2 * math.pi  # ring areas, m^2
    for pitch, n_yaws in zip(pitches, yaws):
        rot = frame(float(pitch), 0.0)
        in_view = in_range & model.in_fov(d @ rot.T)
        density = model.rays_per_sr(gd @ rot.T) * surface
        covered = (in_view & (density >= model.min_density_per_m2)).reshape(rho.shape)
        covers += n_yaws * covered.mean(axis=1)
        seen = in_view.reshape(rho.shape).mean(axis=1)
        view = max(view, float((seen * ring).sum() / (math.pi * r**2)))
    off = math.radians(model.max_off_axis_deg())
    depression = -np.arcsin(np.clip(d[:, 2], -1.0, 1.0))
    band = (depression >= math.radians(model.pitch_min_deg) - off) & (
        depression <= math.radians(model.pitch_max_deg) + off
    )
    best = model.max_rays_per_sr() * surface * (1 + 1e-9)
    maybe = in_range & band & (best >= model.min_density_per_m2)
    reach = maybe.reshape(rho.shape).mean(axis=1)
    return _Profile(radii, covers, reach, min(view, 1.0))


class _Raster:
    """The scene's areas on a raster of square cells (``RASTER_CELLS`` at most) over
    their bounds, each cell holding m^2 of an area (sampled 2 x 2 a cell, then scaled so
    that the sum is the area's m^2). Profiles convolved with the target raster and
    weighed over the sensor areas give per-position sums."""

    def __init__(self, scene: SceneModel, reach_m: float, heights: list[float]) -> None:
        minx, miny, maxx, maxy = areas_bounds((*scene.targets, *scene.sensor_areas))
        extent = max(maxx - minx, 1e-9) * max(maxy - miny, 1e-9)
        self.cell = max(RASTER_MIN_M, math.sqrt(extent / RASTER_CELLS), reach_m / 4096)
        self.x0, self.y0 = minx, miny
        self.nx = max(1, math.ceil((maxx - minx) / self.cell))
        self.ny = max(1, math.ceil((maxy - miny) / self.cell))
        self.reach_m = reach_m
        # Each sensor area's cells: (window slices, m^2 per cell), and its mast height.
        self.sensors = [(self._window(a.geometry), h) for a, h in zip(scene.sensor_areas, heights)]

    def fractions(self, geometry: BaseGeometry) -> F64:
        """(nx, ny) m^2 of ``geometry`` in each cell of the raster."""
        (si, sj), area = self._window(geometry)
        out = np.zeros((self.nx, self.ny))
        out[si, sj] = area
        return out

    def _window(self, geometry: BaseGeometry) -> tuple[tuple[slice, slice], F64]:
        """The cells under the geometry's bounds, and its m^2 in each of them."""
        c, sub = self.cell, 2
        minx, miny, maxx, maxy = geometry.bounds
        i0 = min(max(int((minx - self.x0) // c), 0), self.nx - 1)
        j0 = min(max(int((miny - self.y0) // c), 0), self.ny - 1)
        i1 = min(max(int(math.ceil((maxx - self.x0) / c)), i0 + 1), self.nx)
        j1 = min(max(int(math.ceil((maxy - self.y0) / c)), j0 + 1), self.ny)
        s = c / sub
        xs = self.x0 + i0 * c + (np.arange((i1 - i0) * sub) + 0.5) * s
        ys = self.y0 + j0 * c + (np.arange((j1 - j0) * sub) + 0.5) * s
        xx, yy = np.meshgrid(xs, ys, indexing="ij")
        shapely.prepare(geometry)
        inside = shapely.contains_xy(geometry, xx, yy).astype(float)
        area = inside.reshape(i1 - i0, sub, j1 - j0, sub).sum(axis=(1, 3)) * s * s
        total = float(geometry.area)
        if area.sum() > 0:
            area *= total / area.sum()
        elif total > 0:  # smaller than a sample: all of it in the cell of a point in it
            p = geometry.representative_point()
            i = min(max(int((p.x - self.x0) // c) - i0, 0), i1 - i0 - 1)
            j = min(max(int((p.y - self.y0) // c) - j0, 0), j1 - j0 - 1)
            area[i, j] = total
        return (slice(i0, i1), slice(j0, j1)), area

    def _summed(self, area: F64, profile: _Profile, kind: str) -> F64:
        """(nx, ny) at each cell centre: the profile ``kind`` ("covers" or "reach") at
        each cell's distance, summed over ``area`` (m^2 a cell); m^2."""
        c = self.cell
        n = int(math.ceil(self.reach_m / c))
        k = np.arange(-n, n + 1) * c
        dist = np.hypot(k[:, None], k[None, :])
        values = getattr(profile, kind)
        kernel = np.where(
            dist <= self.reach_m, np.interp(dist, profile.radii, values, left=values[0]), 0.0
        )
        out: F64 = signal.fftconvolve(area, kernel, mode="same")
        return np.maximum(out, 0.0)  # FFT round-off

    def over_positions(
        self, area: F64, profiles: dict[float, _Profile], kind: str
    ) -> tuple[float, float]:
        """(mean, largest) over the sensor areas' cells (the mean weighted by their
        m^2) of the profile ``kind`` summed over ``area``: per position, m^2."""
        summed = {h: self._summed(area, p, kind) for h, p in profiles.items()}
        num = den = top = 0.0
        for (window, weight), h in self.sensors:
            values = summed[h][window]
            num += float((weight * values).sum())
            den += float(weight.sum())
            if (weight > 0).any():
                top = max(top, float(values[weight > 0].max()))
        return (num / den if den > 0 else 0.0), top


# --- refusing ----------------------------------------------------------------------------

# Coarser grids offered in a refusal, m.
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
    if est.pattern_rays > MAX_PATTERN_RAYS:
        return "pattern", (
            f"the limit is {count_text(MAX_PATTERN_RAYS)} rays a pose (about 40 s, in which "
            "nothing can interrupt it)"
        )
    if est.rays_per_evaluation > MAX_RAYS_PER_EVALUATION:
        return "rays", (
            f"the limit is {count_text(MAX_RAYS_PER_EVALUATION)} rays an evaluation (about "
            "45 s, in which nothing can interrupt it)"
        )
    if held + est.peak_bytes > memory:
        return est.peak_stage, have
    if est.parts > MAX_PARTS:
        return "nonzeros", (
            f"that is {est.parts:,} parts of at most {PART_POINTS:,} points and "
            f"{count_text(PART_NONZEROS)} nonzeros, and the limit is {MAX_PARTS} (about 5 "
            "minutes a part)"
        )
    if est.nonzeros / est.parts > MAX_NONZEROS:
        return "nonzeros", f"the limit is {count_text(MAX_NONZEROS)} (int32 indices)"
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
    """``estimate_grid`` checked (InputError when it cannot go ahead);
    ``pattern_rays_at(grid_m)``: the most rays a pointcloud pose casts at a grid (None
    for the targeted method)."""

    def at(g: float) -> Estimate:
        return estimate_grid(
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
    """``estimate_run`` checked (InputError when it cannot go ahead)."""
    fp = _footprints(scene, model, settings, angles)
    est = estimate_run(scene, model, settings, angles, oversample_at, fp, workers)

    def redo(g: float) -> Estimate:
        s = replace(settings, grid_m=g)
        return estimate_run(scene, model, s, angles, oversample_at, fp, workers)

    return check(est, redo)


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
        cells = count_text(reference_cells(est.reach_m, est.grid_m))
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
