"""From parsed roads to what a scene needs: road meshes, target and sensor-area rings.

Sampling rule (along s, per lane section, both ends of every section included):
every start of a geometry, lane section, width/border record, laneOffset, elevation
and superelevation record is a station; between two stations the step is the
largest that keeps

- the heading turn per step at most ``MAX_TURN`` = 0.05 rad (a chord polygon of an
  arc, at any lateral offset, then has sin(d)/d - 1 < 0.05 % of the area),
- the chord error of every cubic profile (lateral borders from widths and laneOffset,
  elevation, superelevation times the road's half width), bounded by
  |f''| * h^2 / 8 from the records' coefficients, at most ``CHORD_TOL`` = 5 mm,
- and the step at most ``MAX_STEP`` = 20 m,

so the plan-area error of a lane is a few hundredths of a per cent.

Sizing before building: every road is first planned (``_plan_road``): its stations
counted from the rule above, then made and the road evaluated there, and every figure
checked against the limits below (length, stations, mesh points, coordinates, lane
widths, heights, slopes; the file's records, mesh points, extent and header offset).
Past a limit the import is refused with one line naming the road and the figure,
before a single polygon is made (only the budget of self-crossing strips, and a
target area's tilt, are checked as those are made). The limits agree with what a
scene must be for ``optimize`` (the scene contract in ``scene/extract.py`` and
``core/model``), and reuse its constants: an import that succeeds gives a scene
``extract_scene`` accepts.

A planView whose next geometry starts away from where the one before it ends (more
than ``GAP_TOL_M``) is warned about, and the lanes are cut there: sampling splits at
the jump, so no strip is invented across it. A lane whose ring crosses itself (it
folds: a lateral offset beyond the radius of curvature; or the road winds over the
same ground) is the union of its steps, made in chunks: no ``make_valid`` on a ring
that may loop round a hundred times.

One module of about 1,100 lines: the roads' sizing and limits, the lane borders
sampled along s, and the meshes and areas made of them share one set of per-road
sample arrays; ``parse.py`` reads the XML and ``geometry.py`` the reference lines.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from functools import partial

import numpy as np
import shapely
from numpy.typing import NDArray
from shapely.geometry import MultiPolygon, Polygon
from shapely.geometry.base import BaseGeometry

from ...core.errors import InputError, SceneContractError
from ...core.model.scene import LOCAL_ORIGIN_BEYOND_M, MAX_RING_TILT_DEG, area_from_rings
from ...core.model.sensors import MAX_COORD_M, MAX_RANGE_M
from ..georef import MAX_OFFSET_M
from .geometry import (
    ReferenceLine,
    eval_poly_slopes,
    eval_polys,
    second_derivative_bounds,
    section_borders,
)
from .parse import MAX_ROADS, LaneSection, OpenDriveNetwork, Road, skipped_reasons
from .progress import Progress, Ticker

F64 = NDArray[np.float64]

LANE_TYPES = (
    "driving", "stop", "shoulder", "biking", "sidewalk", "border", "restricted",
    "parking", "bidirectional", "median", "special1", "special2", "special3",
    "roadWorks", "tram", "rail", "entry", "exit", "offRamp", "onRamp",
    "connectingRamp", "bus", "taxi", "HOV", "mwyEntry", "mwyExit", "none",
)  # fmt: skip
_CANONICAL = {t.lower(): t for t in LANE_TYPES}

MAX_TURN = 0.05  # rad per sampling step
CHORD_TOL = 0.005  # m, chord error of a cubic profile per step
MAX_STEP = 20.0  # m
NEGATIVE_WIDTH_TOL = 1e-3  # m: widths above -1 mm count as zero (rounding in files)
SHIFT_BEYOND_M = 10_000.0
GROUND_MARGIN_M = 20.0
GROUND_BELOW_M = 0.05
MIN_SENSOR_PART_M2 = 1.0
MIN_TARGET_PART_M2 = 0.01  # slivers from section seams in unions

# --- limits: past one, the import is refused naming the road and the figure ------------
# A road's length (and the s its lane sections span). The longest roads of real files
# are a few kilometres (Town04's longest is 584 m); a road is cut into many where a
# network is longer. 100 km is 5,000 stations at the 20 m step, and bounds the work
# of a file whose one road says 1e9 m (it grew to 23 GB before).
MAX_ROAD_LENGTH_M = 100_000.0
# Stations of one road, by the sampling rule: Town04's most are 77. 50,000 leave room
# for a 100 km road turning through 2,500 rad; beyond, the rule is being asked to
# follow a profile no road has (a width cubic with d = 1e6 asks for millions).
MAX_ROAD_STATIONS = 50_000
# Mesh points (stations x lane borders, summed over lane sections) of one road and of
# the whole file. Town04 has 20,000 in all, 770 on its biggest road. A road of
# 150,000 (a 100 km road of 14 lanes a side) is about 2 s of geometry, so progress is
# heard every few seconds; a file of 3 million about a minute (measured: 47 roads of
# 60 km, 20 lanes each, 2.96 million points, imported in 52 s at 1 GB peak).
MAX_ROAD_POINTS = 150_000
MAX_POINTS = 3_000_000
# Records whose work is per record, not per point, in the whole file: planView
# geometries (0.15 ms each, measured on a road of 20,000), lane sections (2 ms each,
# measured on 200 roads of 50: 10,000 sections in 22 s) and lanes counted in every
# section (0.4 ms each, on a road of 2,000 sections of 10). Each limit is about a
# minute; Town04 has 1,215 geometries, 775 lane sections and 1,475 lanes.
MAX_GEOMETRIES = 200_000
MAX_SECTIONS = 25_000
MAX_LANES = 100_000
# A lane wider than this is no lane (the widest proving-ground areas drawn as one lane,
# vehicle-dynamics pads, are a few hundred metres across; the real files' widest
# lane is 7 m).
MAX_LANE_WIDTH_M = 1_000.0
# Heights a road may have (elevation, and superelevation's rise at the lane border):
# a scene's origin is moved near its areas in plan only (``choose_origin``), so a
# height keeps the precision float32 (Blender's meshes, the ray caster) has there:
# about 1 mm within LOCAL_ORIGIN_BEYOND_M = 10 km. Roads on Earth lie between -430 m
# and 5,800 m.
MAX_HEIGHT_M = LOCAL_ORIGIN_BEYOND_M
# Grade and superelevation: a target area follows its road, and a scene refuses one
# tilted beyond MAX_RING_TILT_DEG (45 deg, a 100 % grade); real roads stay under 40 %.
MAX_GRADE = math.tan(math.radians(MAX_RING_TILT_DEG))
MAX_SUPERELEVATION_RAD = math.radians(MAX_RING_TILT_DEG)
# A planView geometry starting farther than this from where the one before it ends is
# a jump (warned; the lanes are cut there). The real files' largest is 1.5 mm.
GAP_TOL_M = 0.1
# Jumps in the whole file: each cuts a road into pieces that stay apart through every
# merge, and merging thousands of parts is slow (a road of 5,000 jumps took 28 s). The
# real files have none; a thousand is a broken export, not a road network.
MAX_JUMPS = 1_000
# Steps of lanes (and sensor bands) whose ring crosses itself, summed over the file,
# checked before each is made. Merging the pieces of such a strip costs more the more
# often it covers the same ground: 12,000 steps wound 95 times round a 1.7 m radius
# take about 0.5 s a strip, 48,000 wound 380 times round 0.5 m about 2.5 s. 60,000
# keep the worst to about 5 s and take the four strips (two lanes, two bands) of a
# 1 km arc at curvature 0.6.
MAX_TANGLED_STEPS = 60_000
# Steps of such a strip made into one polygon before the pieces are merged: short
# enough that a piece seldom crosses itself (a lane turning 3.2 rad), long enough to
# keep the pieces few.
CHUNK_STEPS = 64
# Vertices of a piece of the roads' merged surface (``_subdivide``): a band's
# difference with the few pieces it meets stays cheap however big the network.
SUBDIVIDE_POINTS = 256


@dataclass(frozen=True)
class SurfaceMesh:
    name: str
    road_id: str | None
    vertices: NDArray[np.float64]  # (V, 3)
    faces: NDArray[np.int32]  # (F, 3), counter-clockwise seen from above


@dataclass(frozen=True)
class AreaRings:
    name: str
    road_id: str
    lane_types: tuple[str, ...]
    rings: list[NDArray[np.float64]]  # (K, 3) each, closed implicitly, even-odd fill
    area_m2: float


@dataclass(frozen=True)
class ImportedNetwork:
    surfaces: list[SurfaceMesh]
    ground: SurfaceMesh | None
    targets: list[AreaRings]
    sensor_areas: list[AreaRings]
    shift: NDArray[np.float64]
    crs: str | None
    crs_offset: tuple[float, float, float, float]
    warnings: list[str] = field(default_factory=list)
    lane_area_m2: dict[str, float] = field(default_factory=dict)


@dataclass
class _Edge:
    """The outermost surface border of one side of one run of a lane section."""

    side: int
    xy: F64  # (N, 2) plan points
    normal: F64  # (N, 2) unit left normals
    z: F64  # (N,)
    ref: F64  # (N, 2) the reference line's plan points
    q: F64  # (N,) the border's plan lateral offset: xy = ref + q * normal
    s: F64  # (N,)
    h: F64  # (N,) heading, rad


@dataclass
class _RoadParts:
    road_id: str
    vertices: F64
    faces: NDArray[np.int32]
    lanes: list[tuple[str, Polygon | MultiPolygon]] = field(default_factory=list)
    edges: list[_Edge] = field(default_factory=list)


@dataclass
class _Run:
    """Stations of a lane section between planView jumps, the road evaluated there:
    s, x, y, heading, elevation, superelevation (N,) and every border's t (N,)."""

    s: F64
    x: F64
    y: F64
    h: F64
    elev: F64
    phi: F64
    borders: dict[int, F64]


@dataclass
class _RoadPlan:
    """A road sized and checked: its lane sections' runs, counts and plan extent."""

    road: Road
    sections: list[tuple[LaneSection, float, list[_Run]]]
    stations: int
    points: int
    jumps: int
    lo: F64  # (2,) plan box of every lane border point
    hi: F64


@dataclass
class _Tangles:
    """Steps of self-crossing strips made so far (``MAX_TANGLED_STEPS``)."""

    steps: int = 0


def _section_ends(road: Road) -> list[tuple[LaneSection, float, float]]:
    out = []
    for k, sec in enumerate(road.sections):
        end = road.sections[k + 1].s if k + 1 < len(road.sections) else road.length
        end = min(end, road.length)
        if end - sec.s > 1e-6:
            out.append((sec, sec.s, end))
    return out


def _cuts(road: Road, sec: LaneSection, s0: float, s1: float) -> F64:
    """The stations every record start makes in [s0, s1] (both ends included)."""
    marks = {s0, s1}
    marks |= {g.s for g in road.geometries}
    marks |= {r.s for r in (*road.lane_offsets, *road.elevation, *road.superelevation)}
    for lane in (*sec.left, *sec.right):
        marks |= {sec.s + r.s for r in (*lane.widths, *lane.borders)}
    cuts = np.array(sorted(m for m in marks if s0 <= m <= s1))
    cuts = cuts[np.concatenate([[True], np.diff(cuts) > 1e-9])]
    if cuts[-1] < s1 - 1e-9:
        cuts = np.append(cuts, s1)
    else:
        cuts[-1] = s1
    return cuts


def _steps(road: Road, ref: ReferenceLine, sec: LaneSection, cuts: F64) -> tuple[F64, str]:
    """Steps between consecutive cuts by the rule in the module docstring, as floats
    (inf where a profile overflows), and what asks for the most of them."""
    a, b = cuts[:-1], cuts[1:]
    length = b - a
    turn = ref.turns(a, b)
    # A cut ending where the next geometry starts also turns by the kink there.
    nxt = ref.index(b) != ref.index(a)
    if nxt.any():
        with np.errstate(over="ignore", invalid="ignore"):
            h1 = ref.evaluate(b[nxt])[2]
            h0 = ref.evaluate(b[nxt], before=True)[2]
            turn[nxt] += np.abs((h1 - h0 + np.pi) % (2.0 * np.pi) - np.pi)
    borders, _ = section_borders(road, sec, cuts)
    with np.errstate(over="ignore", invalid="ignore", divide="ignore"):
        reach = np.max(np.abs(np.stack(list(borders.values()))), axis=0)
        half = np.maximum(reach[:-1], reach[1:]) + 1.0
        bound = second_derivative_bounds(road.lane_offsets, a, b, 0.0)
        bound = bound + second_derivative_bounds(road.elevation, a, b, 0.0)
        bound = bound + half * second_derivative_bounds(road.superelevation, a, b, 0.0)
        for lane in (*sec.left, *sec.right):
            bound = bound + second_derivative_bounds(lane.widths or lane.borders, a, b, sec.s)
        bound[np.isnan(bound)] = np.inf  # inf x 0: a profile overflowed
        by_length = np.ceil(length / MAX_STEP)
        by_turn = np.ceil(turn / MAX_TURN)
        by_turn[np.isnan(by_turn)] = np.inf
        by_chord = np.where(bound > 0, np.ceil(length / np.sqrt(8.0 * CHORD_TOL / bound)), 0.0)
        by_chord[np.isnan(by_chord)] = np.inf
    n = np.maximum(np.maximum(1.0, by_length), np.maximum(by_turn, by_chord))
    k = int(np.argmax(n))
    if by_chord[k] >= n[k] and by_chord[k] > by_turn[k]:
        why = (
            f"a cubic profile (lane width, offset or height) bends by up to "
            f"{bound[k]:.3g} 1/m near s={a[k]:g}, so chords within "
            f"{CHORD_TOL * 1000:g} mm need that many"
        )
    elif by_turn[k] >= n[k] and by_turn[k] > by_length[k]:
        why = f"its heading turns {turn.sum():.4g} rad, {MAX_TURN:g} rad a step"
    else:
        why = f"{length.sum():.4g} m at {MAX_STEP:g} m a step"
    return n, why


def _stations_from(cuts: F64, n: NDArray[np.int64]) -> F64:
    """``np.linspace(a, b, n + 1)[1:]`` of every cut after the first station, at once
    (the same arithmetic: a + i * ((b - a) / n), the last exactly b)."""
    a, b = cuts[:-1], cuts[1:]
    step = (b - a) / n
    first = np.cumsum(n) - n
    i = np.arange(int(n.sum()), dtype=np.float64) - np.repeat(first, n) + 1.0
    s = i * np.repeat(step, n) + np.repeat(a, n)
    s[np.cumsum(n) - 1] = b
    return np.concatenate([cuts[:1], s])


def _first(bad: NDArray[np.bool_]) -> int:
    return int(np.flatnonzero(bad)[0])


def _check_run(road: Road, sec: LaneSection, s0: float, run: _Run, outer: float) -> None:
    """InputError naming the road, the figure and where, for a run past a limit."""
    rid, s = road.id, run.s
    finite = np.isfinite(run.x) & np.isfinite(run.y) & np.isfinite(run.h)
    if not finite.all():
        k = _first(~finite)
        raise InputError(
            f"road {rid}: its reference line overflows at s={s[k]:g} (x = {run.x[k]:g}, "
            f"y = {run.y[k]:g}): a geometry's numbers are too large to evaluate"
        )
    lateral = np.zeros_like(s)
    for lane in (*sec.left, *sec.right):
        side = 1 if lane.id > 0 else -1
        with np.errstate(over="ignore", invalid="ignore"):
            width = side * (run.borders[lane.id] - run.borders[lane.id - side])
        wide = ~(np.abs(width) <= MAX_LANE_WIDTH_M)  # NaN counts as too wide
        if wide.any():
            k = _first(wide)
            raise InputError(
                f"road {rid}: lane {lane.id} is {width[k]:.3g} m wide at s={s[k]:g} (lane "
                f"section at s={s0:g}), beyond the {MAX_LANE_WIDTH_M:,.0f} m a lane may be"
            )
    for t in run.borders.values():
        with np.errstate(invalid="ignore"):
            lateral = np.maximum(lateral, np.abs(t))
    if not np.isfinite(lateral).all():
        k = _first(~np.isfinite(lateral))
        raise InputError(f"road {rid}: its lane offset is not finite at s={s[k]:g}")
    reach = np.maximum(np.abs(run.x), np.abs(run.y)) + lateral + outer
    far = reach > MAX_COORD_M
    if far.any():
        k = _first(far)
        raise InputError(
            f"road {rid}: reaches {reach[k]:.3g} m from the file's origin at s={s[k]:g} "
            f"(reference line at x = {run.x[k]:.4g}, y = {run.y[k]:.4g}), beyond the "
            f"{MAX_COORD_M:g} m a scene point may lie"
        )
    with np.errstate(over="ignore", invalid="ignore"):
        height = np.abs(run.elev) + lateral * np.abs(np.sin(run.phi))
    high = ~(height <= MAX_HEIGHT_M)
    if high.any():
        k = _first(high)
        raise InputError(
            f"road {rid}: height {run.elev[k]:.3g} m at s={s[k]:g} is beyond the "
            f"+-{MAX_HEIGHT_M:g} m a road may have (float32, in which Blender keeps it, "
            "holds 1 mm only within that)"
        )
    with np.errstate(over="ignore", invalid="ignore"):
        grade = np.abs(eval_poly_slopes(road.elevation, s))
    steep = ~(grade <= MAX_GRADE)
    if steep.any():
        k = _first(steep)
        raise InputError(
            f"road {rid}: climbs {grade[k]:.3g} m a metre at s={s[k]:g} "
            f"({math.degrees(math.atan(grade[k])):.0f} deg), steeper than the "
            f"{MAX_RING_TILT_DEG:g} deg a target area may tilt"
        )
    bank = ~(np.abs(run.phi) <= MAX_SUPERELEVATION_RAD)
    if bank.any():
        k = _first(bank)
        raise InputError(
            f"road {rid}: superelevation {run.phi[k]:.3g} rad at s={s[k]:g} is steeper "
            f"than the {MAX_RING_TILT_DEG:g} deg a target area may tilt"
        )


def _plan_road(
    road: Road, outer: float, warnings: list[str], tick: Callable[[], None] = lambda: None
) -> _RoadPlan | None:
    """Size and check one road (see the module docstring): its runs of stations with
    the road evaluated there. None (with a warning) for a road that cannot be built;
    InputError naming the road and the figure for one past a limit. ``tick()`` after
    each lane section (progress within a big road)."""
    rid = road.id
    if road.length > MAX_ROAD_LENGTH_M:
        raise InputError(
            f"road {rid}: length {road.length:.4g} m is beyond the "
            f"{MAX_ROAD_LENGTH_M / 1000:g} km a road may have"
        )
    if not road.sections:
        warnings.append(f"road {rid}: no lane section; road skipped")
        return None
    ends = _section_ends(road)
    if not ends:
        warnings.append(
            f"road {rid}: its lane sections cover none of its length "
            f"({road.length:g} m); road skipped"
        )
        return None
    lo_s, hi_s = min(e[1] for e in ends), max(e[2] for e in ends)
    if hi_s - lo_s > MAX_ROAD_LENGTH_M:
        raise InputError(
            f"road {rid}: its lane sections span {hi_s - lo_s:.4g} m (s from {lo_s:g}), "
            f"beyond the {MAX_ROAD_LENGTH_M / 1000:g} km a road may have"
        )
    ref = ReferenceLine(road.geometries)
    steps: list[tuple[LaneSection, float, float, F64, F64]] = []
    total = 0.0
    for sec, s0, s1 in ends:
        cuts = _cuts(road, sec, s0, s1)
        if len(cuts) > MAX_ROAD_STATIONS:
            raise InputError(
                f"road {rid}: {len(cuts):,} record starts (geometries, lane widths, "
                f"profiles) make more stations than the {MAX_ROAD_STATIONS:,} a road may "
                "have"
            )
        mixed = [ln.id for ln in (*sec.left, *sec.right) if ln.widths and ln.borders]
        if mixed:
            warnings.append(
                f"road {rid}: lane {mixed[0]} in the lane section at s={s0:g} has both "
                "<width> and <border> records; road skipped"
            )
            return None
        n, why = _steps(road, ref, sec, cuts)
        total += float(n.sum()) + 1.0
        if total > MAX_ROAD_STATIONS:
            raise InputError(
                f"road {rid}: sampling it takes {total:.3g} stations ({why}), beyond "
                f"the {MAX_ROAD_STATIONS:,} a road may have"
            )
        steps.append((sec, s0, s1, cuts, n))
        tick()
    jumps = []
    for s_jump, gap in ref.jumps():
        if not lo_s < s_jump <= hi_s:
            continue
        if gap > GAP_TOL_M:
            warnings.append(
                f"road {rid}: the planView jumps {gap:.4g} m at s={s_jump:g} (the geometry "
                "there starts away from where the one before it ends); the lanes are cut "
                "there, not bridged"
            )
        if not gap <= GAP_TOL_M:  # NaN too: evaluated apart, then checked
            jumps.append(s_jump)
    sections: list[tuple[LaneSection, float, list[_Run]]] = []
    points = 0
    lo = np.full(2, np.inf)
    hi = np.full(2, -np.inf)
    for sec, s0, s1, cuts, n in steps:
        s = _stations_from(cuts, n.astype(np.int64))
        # Each jump is a station (every geometry start is a cut, give or take the
        # 1e-9 m that merges cuts): the nearest one is set to it and runs end there.
        here = np.array([j for j in jumps if s0 < j <= s1])
        i = np.clip(np.searchsorted(s, here), 1, len(s) - 1)
        i -= (np.abs(s[i - 1] - here) <= np.abs(s[i] - here)).astype(i.dtype)
        s[i] = here
        at = set(i.tolist())
        bounds = [0, *sorted(at), len(s) - 1]
        runs = []
        for i0, i1 in zip(bounds[:-1], bounds[1:], strict=True):
            if i1 <= i0:
                continue
            run = _evaluate(road, ref, sec, s[i0 : i1 + 1], end_before=i1 in at)
            _check_run(road, sec, s0, run, outer)
            runs.append(run)
            points += len(run.s) * len(run.borders)
            for t in run.borders.values():
                px = run.x - np.sin(run.h) * t * np.cos(run.phi)
                py = run.y + np.cos(run.h) * t * np.cos(run.phi)
                lo = np.minimum(lo, [px.min(), py.min()])
                hi = np.maximum(hi, [px.max(), py.max()])
        sections.append((sec, s0, runs))
        tick()
    return _RoadPlan(road, sections, int(total), points, len(jumps), lo, hi)


def _evaluate(road: Road, ref: ReferenceLine, sec: LaneSection, s: F64, end_before: bool) -> _Run:
    """The road at stations s; the last one with the geometry that ends there when a
    jump is there (``end_before``)."""
    with np.errstate(over="ignore", invalid="ignore"):
        x, y, h = ref.evaluate(s)
        if end_before:
            xe, ye, he = ref.evaluate(s[-1:], before=True)
            x[-1], y[-1], h[-1] = xe[0], ye[0], he[0]
        borders, _ = section_borders(road, sec, s)
        elev = eval_polys(road.elevation, s)
        phi = eval_polys(road.superelevation, s)
    return _Run(s, x, y, h, elev, phi, borders)


def _polygonal(geom: BaseGeometry) -> Polygon | MultiPolygon:
    """The polygonal part of a geometry (make_valid may add lines and points)."""
    if isinstance(geom, Polygon | MultiPolygon):
        return geom
    parts = [g for g in getattr(geom, "geoms", []) if isinstance(g, Polygon | MultiPolygon)]
    if not parts:
        return Polygon()
    merged = shapely.union_all(parts)
    return merged if isinstance(merged, Polygon | MultiPolygon) else Polygon()


def _steps_union(a: F64, b: F64) -> Polygon | MultiPolygon:
    """The union of the steps between borders a and b (N, 2): two triangles a step,
    as the mesh has them; bounded work, whatever the borders do."""
    t1 = np.stack([a[:-1], a[1:], b[1:], a[:-1]], axis=1)
    t2 = np.stack([a[:-1], b[1:], b[:-1], a[:-1]], axis=1)
    tri = np.concatenate([t1, t2])
    u, v = tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0]
    tri = tri[np.abs(u[:, 0] * v[:, 1] - u[:, 1] * v[:, 0]) > 1e-12]
    if not len(tri):
        return Polygon()
    return _polygonal(shapely.union_all(shapely.polygons(tri)))


def _chunked(a: F64, b: F64) -> list[Polygon | MultiPolygon]:
    """Pieces of ``CHUNK_STEPS`` steps of the strip between a and b (N, 2): each its
    ring if that is valid, else the union of its steps; pieces of no width left out."""
    pieces = []
    for k0 in range(0, len(a) - 1, CHUNK_STEPS):
        sl = slice(k0, min(k0 + CHUNK_STEPS, len(a) - 1) + 1)
        if not np.any(np.abs(a[sl] - b[sl]) > 1e-12):
            continue
        ring = np.concatenate([a[sl], b[sl][::-1]])
        # Points a rounding apart made one: a fold on an arc ends every step at its
        # centre, which a zigzag of 1e-15 m would make a ring that crosses itself.
        ring = ring[np.concatenate([[True], np.abs(np.diff(ring, axis=0)).max(axis=1) > 1e-9])]
        piece = Polygon(ring) if len(ring) >= 3 else Polygon()
        pieces.append(piece if piece.is_valid else _steps_union(a[sl], b[sl]))
    return pieces


def _fold_line(s: F64, h: F64, q1: F64, q2: F64) -> F64 | None:
    """Where a strip between plan laterals q1 and q2 (N,) passes the centre of
    curvature (q = 1 / curvature): per station the nearer of its two steps' centres,
    where that lies inside the strip, else q2. None where it never does."""
    with np.errstate(divide="ignore", invalid="ignore"):
        centre = np.diff(s) / np.diff(np.unwrap(h))  # +-inf where straight
    before = np.concatenate([centre[:1], centre])
    after = np.concatenate([centre, centre[-1:]])
    near = np.where(np.abs(before) < np.abs(after), before, after)
    inside = (near > np.minimum(q1, q2)) & (near < np.maximum(q1, q2))
    if not inside.any():
        return None
    out: F64 = np.where(inside, near, q2)
    return out


def _lane_split(run: _Run, frame: _Frame, t1: F64, t2: F64) -> F64 | None:
    """Plan points (N, 2) where a lane from lateral t1 to t2 passes the centre of its
    curve (``_fold_line``; t is along the tilted road plane, t cos(phi) in plan)."""
    cphi = frame[4]
    q = _fold_line(run.s, run.h, t1 * cphi, t2 * cphi)
    return None if q is None else _point(frame, q / cphi)[:, :2]


def _band_split(e: _Edge, inner: float, outer: float) -> F64 | None:
    """As ``_lane_split``, for the band from ``inner`` to ``outer`` beyond an edge."""
    q = _fold_line(e.s, e.h, e.q + e.side * inner, e.q + e.side * outer)
    return None if q is None else e.ref + e.normal * q[:, None]


def _strip_polygon(
    a: F64,
    b: F64,
    split: Callable[[], F64 | None] | None = None,
    tangled: Callable[[int], None] | None = None,
) -> tuple[Polygon | MultiPolygon, bool]:
    """The plan region between borders a and b (N, 2, the same stations) and whether
    its ring crossed itself. An ordinary lane is the polygon of its ring. A ring that
    crosses itself (the lane folds where it passes the centre of its curve, winds over
    the same ground, or pinches to zero width) is the union of its steps, made in
    pieces (``_chunked``); a fold first splits the strip along the centres of
    curvature (``split`` gives those points, (N, 2)), so that the pieces on each side
    are simple rings (exactly so on an arc). Never ``make_valid`` on the whole ring: on
    a ring wound a hundred times that ran for minutes, and its even-odd rule drops
    ground covered twice. ``tangled(steps)`` is told of such a strip first."""
    poly = Polygon(np.concatenate([a, b[::-1]]))
    if poly.is_valid:
        return poly, False
    if tangled is not None:
        tangled(len(a) - 1)  # may refuse before the work
    mid = split() if split is not None else None
    pieces = _chunked(a, b) if mid is None else _chunked(a, mid) + _chunked(mid, b)
    if not pieces:
        return Polygon(), True
    return _polygonal(shapely.union_all(pieces)), True


def _tangle(tangles: _Tangles, steps: int, *, rid: str, path: str) -> None:
    """Counts steps of self-crossing strips; InputError past ``MAX_TANGLED_STEPS``."""
    tangles.steps += steps
    if tangles.steps > MAX_TANGLED_STEPS:
        raise InputError(
            f"{path}: road {rid}: lanes whose outlines cross themselves add up to "
            f"{tangles.steps:,} steps, more than the {MAX_TANGLED_STEPS:,} an import "
            "untangles (lanes wider than the radius of their curve, or roads winding "
            "over the same ground)"
        )


_Frame = tuple[F64, F64, F64, F64, F64, F64]  # x, y, normal (N, 2), elev, cos, sin phi


def _point(frame: _Frame, t: F64) -> F64:
    """3D points at lateral t: t*cos(phi) along the plan normal, elev + t*sin(phi) up."""
    x, y, normal, elev, cphi, sphi = frame
    return np.column_stack(
        [x + normal[:, 0] * t * cphi, y + normal[:, 1] * t * cphi, elev + t * sphi]
    )


def _fold(run: _Run, t: F64) -> int | None:
    """The first station where a border at lateral t runs backward along the road
    (1 - t * curvature < 0: it passed the centre of curvature), or None."""
    kappa = np.diff(np.unwrap(run.h)) / np.maximum(np.diff(run.s), 1e-12)
    back = t[:-1] * kappa > 1.0
    return int(np.flatnonzero(back)[0]) if back.any() else None


def _build_road(
    plan: _RoadPlan,
    warnings: list[str],
    tangles: _Tangles,
    path: str,
    tick: Callable[[], None] = lambda: None,
) -> _RoadParts:
    """The mesh, lane polygons and outer edges of a planned road; ``tick()`` after
    each lane (progress within a big road)."""
    rid = plan.road.id
    verts: list[F64] = []
    faces: list[NDArray[np.int64]] = []
    parts = _RoadParts(rid, np.zeros((0, 3)), np.zeros((0, 3), dtype=np.int32))
    n_verts = 0
    for sec, s0, runs in plan.sections:
        folded: set[int] = set()
        for run in runs:
            s, borders = run.s, run.borders
            normal = np.column_stack([-np.sin(run.h), np.cos(run.h)])
            frame = (run.x, run.y, normal, run.elev, np.cos(run.phi), np.sin(run.phi))
            columns: dict[int, int] = {}  # border id -> first vertex index of its column
            outermost = {1: 0, -1: 0}
            n = len(s)
            for lane in (*sec.left, *sec.right):
                side = 1 if lane.id > 0 else -1
                inner_id = lane.id - side
                width = side * (borders[lane.id] - borders[inner_id])
                if lane.type.lower() == "none" or float(width.max()) <= 1e-9:
                    continue
                if float(width.min()) < -NEGATIVE_WIDTH_TOL:
                    k = int(width.argmin())
                    warnings.append(
                        f"road {rid}: lane {lane.id} in the lane section at s={s0:g} has a "
                        f"negative width ({width[k]:.3g} m at s={s[k]:.4g}); lane skipped"
                    )
                    continue
                for bid in (inner_id, lane.id):
                    if bid not in columns:
                        columns[bid] = n_verts
                        verts.append(_point(frame, borders[bid]))
                        n_verts += n
                if abs(lane.id) > abs(outermost[side]):
                    outermost[side] = lane.id
                right, left = (inner_id, lane.id) if side > 0 else (lane.id, inner_id)
                a = columns[right] + np.arange(n - 1)
                d = columns[left] + np.arange(n - 1)
                tris = np.concatenate(
                    [np.column_stack([a, a + 1, d + 1]), np.column_stack([a, d + 1, d])]
                )
                faces.append(tris)
                rpts = _point(frame, borders[right])[:, :2]
                lpts = _point(frame, borders[left])[:, :2]
                split = partial(_lane_split, run, frame, borders[right], borders[left])
                count = partial(_tangle, tangles, rid=rid, path=path)
                poly, tangled = _strip_polygon(rpts, lpts, split, count)
                tick()
                if tangled:
                    fold = _fold(run, borders[lane.id])
                    if fold is not None and lane.id not in folded:
                        folded.add(lane.id)
                        warnings.append(
                            f"road {rid}: lane {lane.id} in the lane section at s={s0:g} "
                            f"folds over itself from s={s[fold]:.4g} (its border "
                            f"{abs(float(borders[lane.id][fold])):.3g} m out is beyond the "
                            "centre of the curve); its area is the ground it covers"
                        )
                parts.lanes.append((lane.type, poly))
            if not columns:
                continue
            for side, bid in outermost.items():
                edge = _point(frame, borders[bid])
                ref = np.column_stack([run.x, run.y])
                q = borders[bid] * frame[4]
                parts.edges.append(
                    _Edge(side, edge[:, :2], normal, edge[:, 2], ref, q, run.s, run.h)
                )
    if not verts:
        return parts
    vertices = np.concatenate(verts)
    tri = np.concatenate(faces)
    p = vertices[tri][:, :, :2]
    area2: F64 = (p[:, 1, 0] - p[:, 0, 0]) * (p[:, 2, 1] - p[:, 0, 1]) - (
        p[:, 2, 0] - p[:, 0, 0]
    ) * (p[:, 1, 1] - p[:, 0, 1])
    parts.vertices = vertices
    parts.faces = tri[area2 > 1e-10].astype(np.int32)
    return parts


# 2^-9 m (about 2 mm): multiples of it below 2^15 m (32.8 km, beyond the 10 km at which
# the import shifts coordinates) are exact in float32's 24-bit significand.
FLOAT32_GRID_M = 2.0**-9
# Where that stops: area rings farther than this from the scene's origin (after the
# shift) would move once Blender rounds them, and may cross themselves. So a file's
# roads and bands must fit within it of their centre: about 64 km across.
FLOAT32_EXACT_M = FLOAT32_GRID_M * 2.0**24


def _clean(geom: BaseGeometry, min_part: float, min_hole: float) -> Polygon | MultiPolygon:
    """Valid polygons without parts under ``min_part`` or holes under ``min_hole`` m^2."""
    geom = _polygonal(geom if geom.is_valid else shapely.make_valid(geom))
    polys = list(geom.geoms) if isinstance(geom, MultiPolygon) else [geom]
    kept = []
    for poly in polys:
        if poly.is_empty or poly.area < min_part:
            continue
        holes = [r for r in poly.interiors if Polygon(r).area >= min_hole]
        kept.append(Polygon(poly.exterior, holes))
    if not kept:
        return Polygon()
    # Snapped to a grid that float32 holds exactly (Blender keeps curve points in
    # float32): a ring simple in float64 may otherwise touch itself once rounded.
    # (shapely's numpy wrapper warns of a part that collapses on the grid; it is
    # dropped below, so the warning says nothing the result does not.)
    with np.errstate(divide="ignore", invalid="ignore"):
        out = shapely.set_precision(shapely.union_all(kept), FLOAT32_GRID_M)
    return _polygonal(out)


def _rings(geom: Polygon | MultiPolygon) -> list[F64]:
    """Exteriors counter-clockwise, holes clockwise; first point not repeated."""
    polys = list(geom.geoms) if isinstance(geom, MultiPolygon) else [geom]
    out = []
    for poly in polys:
        if poly.is_empty:
            continue
        poly = shapely.geometry.polygon.orient(poly, 1.0)
        for ring in (poly.exterior, *poly.interiors):
            pts = np.asarray(ring.coords)[:-1, :2]
            if len(pts) >= 3:
                out.append(pts)
    return out


def _surface_z(vertices: F64, faces: NDArray[np.int32], pts: F64) -> F64:
    """Height of the mesh at plan points (the nearest triangle, barycentric)."""
    tri = vertices[faces]
    tree = shapely.STRtree(shapely.polygons(tri[:, :, :2]))
    hit = tree.query_nearest(shapely.points(pts), all_matches=False)
    idx = np.empty(len(pts), dtype=np.int64)
    idx[hit[0]] = hit[1]
    t = tri[idx]
    a, b, c = t[:, 0, :2], t[:, 1, :2], t[:, 2, :2]
    v0, v1, v2 = b - a, c - a, pts - a
    den = v0[:, 0] * v1[:, 1] - v1[:, 0] * v0[:, 1]
    den = np.where(np.abs(den) < 1e-15, 1e-15, den)
    l1 = (v2[:, 0] * v1[:, 1] - v1[:, 0] * v2[:, 1]) / den
    l2 = (v0[:, 0] * v2[:, 1] - v2[:, 0] * v0[:, 1]) / den
    lam = np.clip(np.column_stack([1.0 - l1 - l2, l1, l2]), 0.0, None)
    lam /= np.maximum(lam.sum(axis=1, keepdims=True), 1e-15)
    out: F64 = (lam * t[:, :, 2]).sum(axis=1)
    return out


def _band(
    parts: _RoadParts, inner: float, outer: float, tangles: _Tangles, path: str
) -> BaseGeometry:
    strips = []
    for e in parts.edges:
        if len(e.xy) < 2:
            continue
        off = e.side * e.normal
        near = e.xy + off * inner
        far = e.xy + off * outer

        split = partial(_band_split, e, inner, outer)
        count = partial(_tangle, tangles, rid=parts.road_id, path=path)
        strip, _ = _strip_polygon(near, far, split, count)
        strips.append(strip)
    return shapely.union_all(strips) if strips else Polygon()


def _subdivide(geom: BaseGeometry, max_points: int = SUBDIVIDE_POINTS) -> list[BaseGeometry]:
    """Polygonal ``geom`` cut by halving its box until each piece has at most
    ``max_points`` vertices (or is under 1 m across): pieces an STRtree can pick."""
    out: list[BaseGeometry] = []
    todo = [g for g in getattr(geom, "geoms", [geom]) if not g.is_empty]
    while todo:
        g = todo.pop()
        x0, y0, x1, y1 = g.bounds
        if shapely.get_num_coordinates(g) <= max_points or max(x1 - x0, y1 - y0) < 1.0:
            out.append(g)
            continue
        if x1 - x0 >= y1 - y0:
            xm = 0.5 * (x0 + x1)
            halves = [(x0, y0, xm, y1), (xm, y0, x1, y1)]
        else:
            ym = 0.5 * (y0 + y1)
            halves = [(x0, y0, x1, ym), (x0, ym, x1, y1)]
        for rect in halves:
            part = _polygonal(shapely.clip_by_rect(g, *rect))
            todo.extend(p for p in getattr(part, "geoms", [part]) if not p.is_empty)
    return out


def _lane_types(lane_types: Sequence[str]) -> tuple[str, ...]:
    if isinstance(lane_types, str):
        lane_types = [lane_types]
    out: list[str] = []
    for name in lane_types:
        canon = _CANONICAL.get(str(name).strip().lower())
        if canon is None:
            raise InputError(
                f"lane type {name!r} is not an OpenDRIVE lane type "
                f"(one of: {', '.join(LANE_TYPES)})"
            )
        if canon not in out:
            out.append(canon)
    if not out:
        raise InputError("no lane type chosen")
    return tuple(out)


def _plan_all(
    network: OpenDriveNetwork, outer: float, warnings: list[str], progress: Progress | None
) -> list[_RoadPlan]:
    """Every road planned (``_plan_road``) and the file's totals checked."""
    path = network.path
    if len(network.roads) > MAX_ROADS:
        raise InputError(
            f"{path}: {len(network.roads):,} roads are more than the {MAX_ROADS:,} an "
            "import takes; split the file"
        )
    counts = (
        (sum(len(r.geometries) for r in network.roads), MAX_GEOMETRIES, "planView geometries"),
        (sum(len(r.sections) for r in network.roads), MAX_SECTIONS, "lane sections"),
        (
            sum(len(s.left) + len(s.right) for r in network.roads for s in r.sections),
            MAX_LANES,
            "lanes (counted in every lane section)",
        ),
    )
    for count, limit, what in counts:
        if count > limit:
            raise InputError(
                f"{path}: {count:,} {what} are more than the {limit:,} an import builds "
                "(about a minute's work); split the file"
            )
    plans: list[_RoadPlan] = []
    points = jumps = 0
    tick = Ticker(progress, "sizing", len(network.roads))
    for k, road in enumerate(network.roads):
        try:
            # Overflows are expected of hostile numbers: every figure is checked after.
            with np.errstate(all="ignore"):
                plan = _plan_road(road, outer, warnings, partial(tick, k))
        except InputError as exc:
            raise InputError(f"{path}: {exc}") from None
        if plan is not None:
            if plan.points > MAX_ROAD_POINTS:
                raise InputError(
                    f"{path}: road {road.id}: {plan.points:,} mesh points ({plan.stations:,} "
                    f"stations x its lane borders) are more than the {MAX_ROAD_POINTS:,} a "
                    "road may have"
                )
            plans.append(plan)
            points += plan.points
            jumps += plan.jumps
            if jumps > MAX_JUMPS:
                raise InputError(
                    f"{path}: its planViews jump more than {MAX_JUMPS:,} times (road "
                    f"{road.id} alone {plan.jumps:,} times): a broken export, not a road "
                    "network"
                )
            if points > MAX_POINTS:
                raise InputError(
                    f"{path}: its roads make more than {MAX_POINTS:,} mesh points (stations "
                    f"x lane borders; road {road.id} alone {plan.points:,}), more than an "
                    "import builds; split the file"
                )
        tick(k + 1)
    tick.done()
    return plans


def _shift(plans: list[_RoadPlan], outer: float, path: str) -> F64:
    """The plan shift (whole km, only beyond ``SHIFT_BEYOND_M``) that brings the roads
    near the origin; InputError when they do not then fit within ``FLOAT32_EXACT_M``."""
    lo = np.min([p.lo for p in plans], axis=0)
    hi = np.max([p.hi for p in plans], axis=0)
    shift = np.zeros(3)
    corners = np.array([[lo[0], lo[1]], [lo[0], hi[1]], [hi[0], lo[1]], [hi[0], hi[1]]])
    if float(np.hypot(corners[:, 0], corners[:, 1]).max()) > SHIFT_BEYOND_M:
        shift[:2] = np.round((lo + hi) / 2.0 / 1000.0) * 1000.0
    reach = np.maximum(np.abs(lo - shift[:2]), np.abs(hi - shift[:2])) + outer
    if float(reach.max()) >= FLOAT32_EXACT_M:
        axis = int(np.argmax(reach))
        first = min(plans, key=lambda p: float(p.lo[axis]))
        last = max(plans, key=lambda p: float(p.hi[axis]))
        name = "xy"[axis]
        raise InputError(
            f"{path}: the roads span {(hi[axis] - lo[axis]) / 1000:,.4g} km in {name} "
            f"(road {first.road.id} at {name} = {first.lo[axis]:,.0f} m to road "
            f"{last.road.id} at {last.hi[axis]:,.0f} m), more than the "
            f"{2 * FLOAT32_EXACT_M / 1000:.0f} km an import may span: area outlines are "
            f"snapped to a {FLOAT32_GRID_M * 1000:.1f} mm grid that float32, as Blender "
            f"keeps curves, holds only within {FLOAT32_EXACT_M / 1000:.1f} km of the origin"
        )
    return shift


def _check_target(area: AreaRings, path: str) -> None:
    """A target whose rings are not flat refused as the scene contract would refuse
    it (a road so steep, or overlapping itself at such different heights, that its
    area tilts past ``MAX_RING_TILT_DEG``): InputError naming the road."""
    if all(np.ptp(r[:, 2]) == 0.0 for r in area.rings):
        return
    rounded = [r.astype(np.float32).astype(np.float64) for r in area.rings]
    try:
        area_from_rings(area.name, rounded)
    except SceneContractError as exc:
        raise InputError(
            f"{path}: road {area.road_id}: a scene would refuse its target area ({exc})"
        ) from None


def build_import(
    network: OpenDriveNetwork,
    lane_types: Sequence[str] = ("driving",),
    band: tuple[float, float] = (1.0, 6.0),
    terrain: str = "flat",
    progress: Progress | None = None,
) -> ImportedNetwork:
    """Road meshes, targets (chosen lane types) and sensor-area bands of a network.

    Every road is sized and checked first (module docstring): InputError, one line
    naming the road and the figure, past a limit. ``progress(stage, done, total)`` is
    called as the stages go ("sizing", "roads", "targets", "sensor areas"; in roads),
    at least every ``progress.INTERVAL_S`` while one runs.
    """
    types = _lane_types(lane_types)
    try:
        inner, outer = float(band[0]), float(band[1])
    except (TypeError, ValueError, IndexError):
        raise InputError(f"band {band!r}: give two distances in metres, INNER:OUTER") from None
    if not (math.isfinite(inner) and math.isfinite(outer)) or inner < 0 or outer <= inner:
        raise InputError(
            f"band {inner:g}:{outer:g}: needs 0 <= inner < outer (metres outside the road)"
        )
    if outer > MAX_RANGE_M:
        raise InputError(
            f"band {inner:g}:{outer:g}: outer may be at most {MAX_RANGE_M:g} m (a "
            "road-side sensor's longest reach)"
        )
    if terrain not in ("flat", "none"):
        raise InputError(f"terrain {terrain!r}: must be 'flat' or 'none'")
    path = network.path
    wanted = {t.lower() for t in types}
    present = {
        ln.type for r in network.roads for sec in r.sections for ln in (*sec.left, *sec.right)
    }
    if not any(t.lower() in wanted for t in present):
        kinds = sorted(present)
        have = ", ".join(kinds[:8]) + (f" and {len(kinds) - 8:,} more" if len(kinds) > 8 else "")
        have = have or "no lanes"
        skipped = skipped_reasons(network.warnings)
        raise InputError(
            f"{path}: no lane of type {', '.join(types)} (the file has: {have})"
            + (f"; roads skipped: {skipped}" if skipped else "")
        )

    warnings = list(network.warnings)
    plans = _plan_all(network, outer, warnings, progress)
    if not plans:
        raise InputError(f"{path}: no road could be built: {skipped_reasons(warnings)}")
    shift = _shift(plans, outer, path)
    sx, sy = float(shift[0]), float(shift[1])

    built: list[_RoadParts] = []
    tangles = _Tangles()
    tick = Ticker(progress, "roads", len(plans))
    for k, plan in enumerate(plans):
        parts = _build_road(plan, warnings, tangles, path, partial(tick, k))
        plan.sections = []  # the evaluated stations are not needed again
        if len(parts.faces):
            built.append(parts)
        tick(k + 1)
    tick.done()
    if not built:
        reasons = skipped_reasons(warnings)
        raise InputError(
            f"{path}: no road could be built: "
            + (reasons or "no lane has a width (every one is zero, negative or type none)")
        )

    def moved(geom: BaseGeometry) -> BaseGeometry:
        return shapely.affinity.translate(geom, -sx, -sy) if sx or sy else geom

    surfaces = [
        SurfaceMesh(f"Road_{p.road_id}", p.road_id, p.vertices - shift, p.faces) for p in built
    ]
    lane_area = {t: 0.0 for t in types}
    surface_polys: list[BaseGeometry] = []
    for p in built:
        for ltype, poly in p.lanes:
            surface_polys.append(poly)
            canon = _CANONICAL.get(ltype.lower())
            if canon in lane_area:
                lane_area[canon] += float(poly.area)
    # Every road's surface, merged once and cut into small pieces: each band takes
    # the pieces it meets. (Merging the surfaces a band meets, band by band, was
    # quadratic: 2,000 roads stacked on one another took 12 s, 10,000 would take 5 min.)
    pieces = _subdivide(moved(shapely.union_all(surface_polys)))
    tree = shapely.STRtree(pieces)

    targets: list[AreaRings] = []
    tick = Ticker(progress, "targets", len(built))
    for k, p in enumerate(built):
        verts = p.vertices - shift
        for t in types:
            polys = [g for lt, g in p.lanes if lt.lower() == t.lower() and not g.is_empty]
            if not polys:
                continue
            union = moved(shapely.union_all(polys))
            region = _clean(union, MIN_TARGET_PART_M2, MIN_TARGET_PART_M2)
            rings2 = _rings(region)
            if not rings2:
                continue
            # All rings at once: one search tree of the road's triangles, not one a
            # ring (a road cut into 1,000 pieces by planView jumps took minutes).
            heights = np.split(
                _surface_z(verts, p.faces, np.concatenate(rings2)),
                np.cumsum([len(r) for r in rings2])[:-1],
            )
            rings = [np.column_stack([r, zr]) for r, zr in zip(rings2, heights, strict=True)]
            area = AreaRings(
                f"Target_{t}_road{p.road_id}", p.road_id, (t,), rings, float(region.area)
            )
            _check_target(area, path)
            targets.append(area)
        tick(k + 1)
    tick.done()

    z_min = float(min(s.vertices[:, 2].min() for s in surfaces))
    ground_z = z_min - GROUND_BELOW_M
    bands: list[tuple[_RoadParts, Polygon | MultiPolygon]] = []
    tick = Ticker(progress, "sensor areas", len(built))
    for k, p in enumerate(built):
        raw = _band(p, inner, outer, tangles, path)
        tick(k + 1)
        if raw.is_empty:
            continue
        raw = moved(raw)
        near = tree.query(raw, predicate="intersects")
        if len(near):
            raw = raw.difference(shapely.union_all([pieces[int(j)] for j in near]))
        region = _clean(raw, MIN_SENSOR_PART_M2, MIN_TARGET_PART_M2)
        if not region.is_empty:
            bands.append((p, region))
    tick.done()
    sensor_areas = []
    for p, region in bands:
        if terrain == "flat":
            z = ground_z
        else:
            z = float(np.mean(np.concatenate([e.z for e in p.edges]))) - float(shift[2])
        rings = [np.column_stack([r, np.full(len(r), z)]) for r in _rings(region)]
        sensor_areas.append(
            AreaRings(f"SensorArea_road{p.road_id}", p.road_id, (), rings, float(region.area))
        )

    ground = None
    if terrain == "flat":
        xy = [s.vertices[:, :2] for s in surfaces]
        xy += [np.asarray(b.bounds).reshape(2, 2) for _, b in bands]
        pts = np.concatenate(xy)
        (x0, y0), (x1, y1) = pts.min(axis=0) - GROUND_MARGIN_M, pts.max(axis=0) + GROUND_MARGIN_M
        gv = np.array(
            [[x0, y0, ground_z], [x1, y0, ground_z], [x1, y1, ground_z], [x0, y1, ground_z]]
        )
        ground = SurfaceMesh("Ground", None, gv, np.array([[0, 1, 2], [0, 2, 3]], dtype=np.int32))

    ox, oy, oz, oh = network.offset or (0.0, 0.0, 0.0, 0.0)
    c, s_ = math.cos(oh), math.sin(oh)
    crs_offset = (ox + c * sx - s_ * sy, oy + s_ * sx + c * sy, oz + float(shift[2]), oh)
    if max(abs(v) for v in crs_offset[:3]) > MAX_OFFSET_M:
        raise InputError(
            f"{path}: the header's <offset> with the import's shift places the scene at "
            f"({crs_offset[0]:g}, {crs_offset[1]:g}, {crs_offset[2]:g}) m, beyond the "
            f"{MAX_OFFSET_M:g} m a scene's offset may be"
        )
    return ImportedNetwork(
        surfaces=surfaces,
        ground=ground,
        targets=targets,
        sensor_areas=sensor_areas,
        shift=shift,
        crs=network.geo_reference,
        crs_offset=crs_offset,
        warnings=warnings,
        lane_area_m2=lane_area,
    )
