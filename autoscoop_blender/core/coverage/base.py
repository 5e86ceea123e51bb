"""What every coverage method shares: the answer for one pose, sight lines, and the
union over a set of sensors.

A coverage method answers, for a sensor pose, which target points the sensor covers
(line of sight, inside range and FoV, point density at least the model's threshold,
for a camera with a resolution the pixel density its model and the point's target
area ask for, and the sensor kind the area requires: ``pixel_need``, ``sensors``
module docstring), with what density chi,
and what its footprint on the ground is. The methods are
``targeted`` (``targeted.py``, one sight ray per target point that can count; exact at
the grid's resolution), its cached form (``cached.py``) and the paper's ``pointcloud``
(``pointcloud.py``, the whole ray pattern and an alpha shape).

A footprint outside the targets matters to the paper's fitness (its tau term) and to
the relative-coverage metric; evaluators look at outside cells only within
``outside_band_m`` of the targets (``None``: none, ``inf``: all within range).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np
import shapely
from numpy.typing import NDArray
from shapely.geometry.base import BaseGeometry

from ..geom.alpha import union_triangles
from ..geom.grid import GroundGrid
from ..geom.raycast import RayCaster
from ..model.sensors import KINDS, SensorModel, SensorPose, facing_factor, surface_factor

I64 = NDArray[np.int64]
F64 = NDArray[np.float64]

# A sight line stops this short of its target point, so that the surface the point
# lies on cannot block it through rounding (the caster works in single precision).
SIGHT_MARGIN_M = 0.01


@dataclass
class SensorCoverage:
    """What one pose covers. Indices into the grid's target arrays are "ordinals".

    covered: (K,) target ordinals covered; chi: (K,) their density, points/m^2.
    visible: target ordinals with line of sight inside range and FoV (any density),
    or None when not asked for. outside: flat cells outside the targets that the
    footprint covers (within the band asked for). footprint_m2: the whole footprint's
    area, or None when it was not evaluated in full.
    """

    pose: SensorPose
    model: SensorModel
    method: str
    covered: I64
    chi: F64
    visible: I64 | None
    outside: I64
    footprint_m2: float | None
    rays: int
    # What the footprint polygon is built from, on demand (see footprint_polygon).
    _triangles: F64 | None = field(default=None, repr=False)
    _cells: I64 | None = field(default=None, repr=False)


def place(
    grid: GroundGrid,
    x: float,
    y: float,
    height_m: float,
    pitch_deg: float,
    yaw_deg: float,
) -> SensorPose:
    """A pose at local (x, y), ``height_m`` above the top surface there."""
    z, _ = grid.drop(np.array([[x, y]]))
    return SensorPose(x, y, float(z[0]) + height_m, height_m, pitch_deg, yaw_deg)


@dataclass(frozen=True)
class SightLines:
    """Sight lines from one sensor position to K cells; independent of orientation.

    d, dist: (K, 3) unit directions and (K,) distances to the target points (the
    cell's surface point raised by the target height); gd: (K, 3) unit directions
    to the surface point itself, where the pattern's density is measured; surface:
    (K,) its orientation-free density factor (``sensors.surface_factor``); facing:
    (K,) the pixel density's (``sensors.facing_factor``), or None when not asked for
    (a model without a resolution never needs it).
    """

    d: F64
    dist: F64
    gd: F64
    surface: F64
    facing: F64 | None = None

    def subset(self, rows: NDArray[np.int_]) -> SightLines:
        d = self.d[rows]
        gd = d if self.gd is self.d else self.gd[rows]  # no target height: one array
        facing = None if self.facing is None else self.facing[rows]
        return SightLines(d, self.dist[rows], gd, self.surface[rows], facing)


def sight_lines(grid: GroundGrid, s: F64, cells: I64, pixels: bool = False) -> SightLines:
    """Sight lines from position ``s`` (3,) to ``cells`` (dropping them if needed);
    ``pixels``: with the pixel density's factor too."""
    z, normals = grid.surface(cells)
    ground = np.column_stack([grid.xy(cells), z])
    gvec = ground - s
    gdist = np.linalg.norm(gvec, axis=1)
    with np.errstate(invalid="ignore", divide="ignore"):
        gd = gvec / gdist[:, None]
    surface = surface_factor(gd, gdist, normals)
    facing = facing_factor(gd, gdist, normals) if pixels else None
    if grid.target_height_m == 0.0:
        return SightLines(gd, gdist, gd, surface, facing)
    vec = gvec + (0.0, 0.0, grid.target_height_m)
    dist = np.linalg.norm(vec, axis=1)
    with np.errstate(invalid="ignore", divide="ignore"):
        d = vec / dist[:, None]
    return SightLines(d, dist, gd, surface, facing)


def clear_sight(
    caster: RayCaster, s: F64, lines: SightLines, rows: NDArray[np.int_]
) -> NDArray[np.bool_]:
    """(len(rows),) whether nothing blocks the sight line to each of ``rows``; one ray
    each, stopping just short of the point.

    A hit within ``SIGHT_MARGIN_M`` of the sensor is the surface the sensor itself
    stands on (a mast of height 0): those rays are cast again from just past it.
    """
    if len(rows) == 0:
        return np.zeros(0, dtype=bool)
    d = lines.d[rows]
    limit = lines.dist[rows] * (1 - 1e-7) - SIGHT_MARGIN_M
    hit = caster.cast(np.broadcast_to(s, (len(rows), 3)), d, limit)
    own = np.flatnonzero(hit < SIGHT_MARGIN_M)
    if len(own):
        start = s + d[own] * SIGHT_MARGIN_M
        hit[own] = caster.cast(start, d[own], np.maximum(limit[own] - SIGHT_MARGIN_M, 0.0))
    return ~np.isfinite(hit)


def to_sensor(d: F64, rot: F64) -> F64:
    """Directions (K, 3) in the sensor frame of ``rot`` (rows forward, left, up), or
    in each of several frames ``rot`` (O, 3, 3) at once, giving (O, K, 3).

    Written out per component (not a matrix product) so that every element's value is
    the same whatever rows or frames it is computed with: the cached, the batched and
    the direct evaluators must agree to the last bit on which points they cover.
    """
    x, y, z = d[:, 0], d[:, 1], d[:, 2]
    if rot.ndim == 2:
        out = np.empty_like(d)
        for k in range(3):
            out[:, k] = rot[k, 0] * x + rot[k, 1] * y + rot[k, 2] * z
        return out
    out = np.empty((len(rot), len(d), 3))
    for k in range(3):
        out[:, :, k] = rot[:, k, 0:1] * x + rot[:, k, 1:2] * y + rot[:, k, 2:3] * z
    return out


def pixel_need(grid: GroundGrid, model: SensorModel, ordinal: I64) -> F64 | None:
    """(K,) the pixel density (px/m) each row (target ordinal, -1 outside the targets)
    must reach for ``model`` to cover it: the larger of the model's ``min_px_per_m``
    and the target area's ``dori`` (``grid.region_px_per_m``); ``inf`` where the model
    cannot cover the point at all: it has no resolution and the area asks for one, or
    the area requires another sensor kind (``grid.region_kind``). None when no row asks
    for anything (every model on a scene without ``dori`` and ``require``)."""
    region_px = grid.region_px_per_m
    t = ordinal >= 0
    other_kind = np.zeros(len(ordinal), dtype=bool)
    if (grid.region_kind >= 0).any():
        kind = grid.region_kind[grid.target_region[ordinal[t]]]
        other_kind[t] = (kind >= 0) & (kind != KINDS.index(model.kind))
    asks = bool(region_px.any())
    if model.resolution_px is None and not asks and not other_kind.any():
        return None
    need = np.full(len(ordinal), model.min_px_per_m)
    if asks:
        need[t] = np.maximum(need[t], region_px[grid.target_region[ordinal[t]]])
    if model.resolution_px is None:
        need[need > 0] = np.inf
    need[other_kind] = np.inf
    if not need.any():
        return None
    return need


def view(
    model: SensorModel, rot: F64, lines: SightLines, need: F64 | None = None
) -> tuple[NDArray[np.bool_], F64, NDArray[np.bool_]]:
    """(K,) whether each target point lies inside range and FoV; (K,) the pattern's
    density on the surface under it (points/m^2, sensor units); (K,) whether the
    sensor detects it there (in view, the density at least the model's threshold,
    and the pixel density at least ``need``, px/m, from ``pixel_need``; a model
    without a resolution only where ``need`` is 0). For several frames ``rot``
    (O, 3, 3), all three are (O, K). Line of sight is not tested here."""
    with np.errstate(invalid="ignore"):
        in_range = (lines.dist > 1e-9) & (lines.dist <= model.range_m)
        local = to_sensor(lines.d, rot)
        in_view = in_range & model.in_fov(local)
        ground = local if lines.gd is lines.d else to_sensor(lines.gd, rot)
        density = np.where(in_view, model.rays_per_sr(ground) * lines.surface, 0.0)
        detects = in_view & (density >= model.min_density_per_m2)
        if need is not None:
            if model.resolution_px is None:
                detects &= need == 0
            else:
                assert lines.facing is not None, "sight_lines(..., pixels=True) for pixels"
                detects &= model.px_per_m(ground, lines.facing) >= need
    return in_view, density, detects


def detects_many(
    model: SensorModel, rots: F64, lines: SightLines, need: F64 | None = None
) -> NDArray[np.bool_]:
    """(O, K) ``view(model, rots, lines, need)[2]`` for O frames ``rots`` (O, 3, 3): the
    same element by element, for less work. A direction in the FoV lies within the
    FoV's cone about the optical axis: its forward component is at least the cone's
    cosine. That is screened for every pair with one matrix product (its rounding,
    ~1e-16, far inside the 1e-9 of room given), and only the pairs that pass (on
    two_routes about a fifth) go through ``to_sensor``'s and ``view``'s arithmetic,
    so the answers are bit for bit those of ``view``."""
    out = np.zeros((len(rots), len(lines.dist)), dtype=bool)
    in_range = (lines.dist > 1e-9) & (lines.dist <= model.range_m)
    # The cone a hair wider than the FoV's, for the FoV test's own tolerance.
    off_axis = math.radians(model.max_off_axis_deg()) + 1e-6
    if off_axis < math.pi / 2:
        screen = (rots[:, 0, :] @ lines.d.T >= math.cos(off_axis) - 2e-9) & in_range
    else:
        screen = np.broadcast_to(in_range, out.shape)
    o, k = np.nonzero(screen)
    d = lines.d[k]
    local = np.empty((len(o), 3))
    for c in range(3):
        local[:, c] = rots[o, c, 0] * d[:, 0] + rots[o, c, 1] * d[:, 1] + rots[o, c, 2] * d[:, 2]
    with np.errstate(invalid="ignore"):
        in_view = model.in_fov(local)
        if lines.gd is lines.d:
            ground = local
        else:
            gd = lines.gd[k]
            ground = np.empty_like(local)
            for c in range(3):
                ground[:, c] = (
                    rots[o, c, 0] * gd[:, 0] + rots[o, c, 1] * gd[:, 1] + rots[o, c, 2] * gd[:, 2]
                )
        density = np.where(in_view, model.rays_per_sr(ground) * lines.surface[k], 0.0)
        detects = in_view & (density >= model.min_density_per_m2)
        if need is not None:
            if model.resolution_px is None:
                detects &= need[k] == 0
            else:
                assert lines.facing is not None, "sight_lines(..., pixels=True) for pixels"
                detects &= model.px_per_m(ground, lines.facing[k]) >= need[k]
    out[o[detects], k[detects]] = True
    return out


def cells_in_reach(
    grid: GroundGrid, s: F64, range_m: float, outside_band_m: float | None
) -> tuple[I64, I64]:
    """Cells within range of ``s`` that count: targets, plus outside cells in the band.

    Returns flat cell indices (K,) and their target ordinals (K,), -1 outside.
    """
    cells = grid.cells_in_disk(s[:2], range_m)
    ordinal = grid.target_ordinal(cells).astype(np.int64)
    keep = ordinal >= 0
    if outside_band_m is not None:
        keep |= grid.dist_to_target(cells) <= outside_band_m
    return cells[keep], ordinal[keep]


def footprint_polygon(grid: GroundGrid, cov: SensorCoverage) -> BaseGeometry:
    """The footprint as a (Multi)Polygon in local metres (empty if nothing covered)."""
    if cov._triangles is not None:
        return union_triangles(cov._triangles)
    cells = cov._cells if cov._cells is not None else np.zeros(0, dtype=np.int64)
    if len(cells) == 0:
        return shapely.Polygon()
    c = grid.xy(cells)
    h = grid.spacing / 2
    return shapely.coverage_union_all(
        shapely.box(c[:, 0] - h, c[:, 1] - h, c[:, 0] + h, c[:, 1] + h)
    )


@dataclass(frozen=True)
class CoverageSummary:
    """Per-target-point counts over a set of sensors, and the union's totals.

    n_visible, n_covered: (N,) sensors with line of sight / covering each target
    point; best_density: (N,) the highest chi among the covering sensors (0: none).
    """

    n_visible: NDArray[np.int32]
    n_covered: NDArray[np.int32]
    best_density: F64
    cell_area: float

    @property
    def covered_points(self) -> int:
        return int((self.n_covered > 0).sum())

    @property
    def coverage_fraction(self) -> float:
        return self.covered_points / max(len(self.n_covered), 1)

    @property
    def covered_m2(self) -> float:
        return self.covered_points * self.cell_area


def summarize(grid: GroundGrid, coverages: list[SensorCoverage]) -> CoverageSummary:
    """Combine per-sensor coverages over the grid's target points."""
    n = grid.n_targets
    n_vis = np.zeros(n, dtype=np.int32)
    n_cov = np.zeros(n, dtype=np.int32)
    best = np.zeros(n)
    for cov in coverages:
        visible = cov.visible if cov.visible is not None else cov.covered
        n_vis[visible] += 1
        n_cov[cov.covered] += 1
        np.maximum.at(best, cov.covered, cov.chi)
    return CoverageSummary(n_vis, n_cov, best, grid.cell_area)
