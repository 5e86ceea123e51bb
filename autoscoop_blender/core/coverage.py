"""Coverage of one sensor pose, by two methods, and of a set of sensors.

Both methods answer the same question for a pose: which target points does the
sensor cover (line of sight, inside range and FoV, point density at least the
model's threshold), with what density chi, and what is its footprint on the ground.

``pointcloud`` (the paper): cast the whole ray pattern, project the hits to XY, give
each hit the density of the pattern around it, keep the hits over the threshold and
take the alpha shape of the kept hits as the footprint; target points inside it are
covered, chi interpolated from the hits. Rays per pose: the pattern size.

``targeted``: test every target point against range and FoV, and its analytic
density, in numpy; cast one ray from the sensor to each point that passes; the point
is covered if nothing is hit before it. Rays per pose: the points that can count.
Exact at the grid's resolution.

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
from scipy import ndimage
from shapely.geometry.base import BaseGeometry

from .alpha import Triangulation, alpha_mask, triangulate, union_triangles
from .grid import GroundGrid
from .raycast import RayCaster
from .sensors import SensorModel, SensorPose, frame, surface_factor

I64 = NDArray[np.int64]
F64 = NDArray[np.float64]

METHODS = ("targeted", "pointcloud")

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
    (K,) its orientation-free density factor (``sensors.surface_factor``).
    """

    d: F64
    dist: F64
    gd: F64
    surface: F64

    def subset(self, rows: NDArray[np.int_]) -> SightLines:
        d = self.d[rows]
        gd = d if self.gd is self.d else self.gd[rows]  # no target height: one array
        return SightLines(d, self.dist[rows], gd, self.surface[rows])


def sight_lines(grid: GroundGrid, s: F64, cells: I64) -> SightLines:
    """Sight lines from position ``s`` (3,) to ``cells`` (dropping them if needed)."""
    z, normals = grid.surface(cells)
    ground = np.column_stack([grid.xy(cells), z])
    gvec = ground - s
    gdist = np.linalg.norm(gvec, axis=1)
    with np.errstate(invalid="ignore", divide="ignore"):
        gd = gvec / gdist[:, None]
    surface = surface_factor(gd, gdist, normals)
    if grid.target_height_m == 0.0:
        return SightLines(gd, gdist, gd, surface)
    vec = gvec + (0.0, 0.0, grid.target_height_m)
    dist = np.linalg.norm(vec, axis=1)
    with np.errstate(invalid="ignore", divide="ignore"):
        d = vec / dist[:, None]
    return SightLines(d, dist, gd, surface)


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


def view(model: SensorModel, rot: F64, lines: SightLines) -> tuple[NDArray[np.bool_], F64]:
    """(K,) whether each target point lies inside range and FoV, and (K,) the
    pattern's density on the surface under it (points/m^2, sensor units); for
    several frames ``rot`` (O, 3, 3), both are (O, K)."""
    with np.errstate(invalid="ignore"):
        in_range = (lines.dist > 1e-9) & (lines.dist <= model.range_m)
        local = to_sensor(lines.d, rot)
        in_view = in_range & model.in_fov(local)
        ground = local if lines.gd is lines.d else to_sensor(lines.gd, rot)
        density = model.rays_per_sr(ground) * lines.surface
    return in_view, np.where(in_view, density, 0.0)


class TargetedEvaluator:
    """One sight ray per target point that can count (see module docstring)."""

    method = "targeted"

    def __init__(self, grid: GroundGrid, caster: RayCaster) -> None:
        self.grid = grid
        self.caster = caster

    def evaluate(
        self,
        model: SensorModel,
        pose: SensorPose,
        outside_band_m: float | None = None,
        visibility: bool = False,
    ) -> SensorCoverage:
        grid = self.grid
        s = pose.position
        cells, ordinal = _cells_in_reach(grid, s, model.range_m, outside_band_m)
        is_target = ordinal >= 0
        lines = sight_lines(grid, s, cells)
        in_view, density = view(model, frame(pose.pitch_deg, pose.yaw_deg), lines)
        dense = in_view & (density >= model.min_density_per_m2)
        ask = dense | (in_view & is_target) if visibility else dense
        idx = np.flatnonzero(ask)
        clear = np.zeros(len(cells), dtype=bool)
        clear[idx] = clear_sight(self.caster, s, lines, idx)

        covered = clear & dense
        cov_t = covered & is_target
        full = outside_band_m is not None and math.isinf(outside_band_m)
        return SensorCoverage(
            pose=pose,
            model=model,
            method=self.method,
            covered=ordinal[cov_t],
            chi=density[cov_t],
            visible=ordinal[clear & in_view & is_target] if visibility else None,
            outside=cells[covered & ~is_target],
            footprint_m2=float(covered.sum() * grid.cell_area) if full else None,
            rays=len(idx),
            _cells=cells[covered],
        )


def auto_oversample(model: SensorModel, grid_m: float) -> int:
    """Rays per pattern ray (per axis) so that neighbouring rays land at most one grid
    cell apart across the ray at the sensor's full range: ceil(spacing x range / grid).
    1 for the paper camera on a 1 m grid (0.5 deg x 80 m = 0.70 m): Table I's rays."""
    h = math.radians(model.h_fov_deg) / model.rays_h
    v = math.radians(model.v_fov_deg) / model.rays_v
    return max(1, math.ceil(max(h, v) * model.range_m / grid_m - 1e-9))


class PointcloudEvaluator:
    """The paper's method: ray pattern -> hits -> density -> alpha-shape footprint.

    ``oversample`` casts ``oversample^2`` rays per pattern ray (densities stay in the
    sensor's own units); None picks ``auto_oversample`` per model. ``alpha`` scales the alpha radius to the local ray spacing
    (a triangle is kept when its circumradius is at most ``alpha`` times the largest
    spacing at its corners); ``alpha_m`` instead fixes the radius in metres.
    """

    method = "pointcloud"

    def __init__(
        self,
        grid: GroundGrid,
        caster: RayCaster,
        oversample: int | None = None,
        alpha: float = 1.0,
        alpha_m: float | None = None,
    ) -> None:
        self.grid = grid
        self.caster = caster
        self.oversample = oversample
        self.alpha = float(alpha)
        self.alpha_m = alpha_m
        self._patterns: dict[SensorModel, F64] = {}

    def _radius_limit(self, tri: Triangulation, spacing: F64) -> F64 | float:
        """Alpha radius per triangle: fixed, or ``alpha`` x the widest corner spacing."""
        if self.alpha_m is not None:
            return self.alpha_m
        return self.alpha * spacing[tri.simplices].max(axis=1)

    def rays_per_pattern_ray(self, model: SensorModel) -> int:
        """The oversampling used for ``model`` (per axis)."""
        if self.oversample is not None:
            return int(self.oversample)
        return auto_oversample(model, self.grid.spacing)

    def _pattern(self, model: SensorModel) -> F64:
        if model not in self._patterns:
            self._patterns[model] = model.pattern_directions(self.rays_per_pattern_ray(model))
        return self._patterns[model]

    def evaluate(
        self,
        model: SensorModel,
        pose: SensorPose,
        outside_band_m: float | None = None,
        visibility: bool = False,
    ) -> SensorCoverage:
        grid = self.grid
        s = pose.position
        rot = frame(pose.pitch_deg, pose.yaw_deg)
        dirs = self._pattern(model) @ rot  # sensor frame -> world, (nv, nh, 3)
        flat = dirs.reshape(-1, 3)
        dist = self.caster.cast(np.broadcast_to(s, flat.shape), flat, model.range_m)
        dist = dist.reshape(dirs.shape[:2])
        hit = np.isfinite(dist)
        xy = np.where(hit[..., None], s[:2] + dirs[..., :2] * dist[..., None], np.nan)

        density, spacing = _pattern_density(xy, hit, self.rays_per_pattern_ray(model) ** 2)
        pts, pts_density, pts_spacing = xy[hit], density[hit], spacing[hit]
        cells, ordinal = _cells_in_reach(grid, s, model.range_m, outside_band_m)
        is_target = ordinal >= 0
        qxy = grid.xy(cells)

        # The footprint is the alpha shape of the hits over the threshold (the
        # paper's filtered FoV); line of sight alone is the alpha shape of all hits.
        dense = np.flatnonzero(pts_density >= model.min_density_per_m2)
        full = outside_band_m is not None and math.isinf(outside_band_m)
        if not full and len(dense):
            # Only the cells asked about matter. An alpha triangle holding a cell
            # lies within twice its radius limit of it, and its circumcircle holds no
            # other hit; so triangulating just the hits within that distance of the
            # cells gives exactly the triangles the cells fall in, for less work.
            reach = 2.0 * self._max_radius(pts_spacing[dense]) + grid.spacing
            dense = dense[_near(grid, pts[dense], qxy, reach)]
        tri = triangulate(pts[dense])
        keep_tri = alpha_mask(tri, self._radius_limit(tri, pts_spacing[dense]))
        covered, simplex = _inside(tri, keep_tri, qxy, grid.spacing)
        cov_t = covered & is_target
        chi = _interpolate(tri, pts_density[dense], qxy[cov_t], simplex[cov_t])

        visible = None
        if visibility:
            all_tri = triangulate(pts)
            all_keep = alpha_mask(all_tri, self._radius_limit(all_tri, pts_spacing))
            seen, _ = _inside(all_tri, all_keep, qxy[is_target], grid.spacing)
            visible = ordinal[is_target][seen | covered[is_target]]
        return SensorCoverage(
            pose=pose,
            model=model,
            method=self.method,
            covered=ordinal[cov_t],
            chi=chi,
            visible=visible,
            outside=cells[covered & ~is_target],
            footprint_m2=float(tri.areas()[keep_tri].sum()) if full else None,
            rays=int(flat.shape[0]),
            _triangles=tri.points[tri.simplices[keep_tri]],
        )

    def _max_radius(self, spacing: F64) -> float:
        """The largest alpha radius any triangle of these hits can be allowed."""
        if self.alpha_m is not None:
            return self.alpha_m
        return self.alpha * float(spacing.max(initial=0.0))


def _near(grid: GroundGrid, pts: F64, qxy: F64, reach: float) -> NDArray[np.bool_]:
    """(P,) whether each point (P, 2) lies within ``reach`` m (give or take one cell)
    of any query cell centre (Q, 2), through a distance transform on a local raster."""
    if len(qxy) == 0:
        return np.zeros(len(pts), dtype=bool)
    g = grid.spacing
    lo = qxy.min(axis=0) - reach - g
    shape = np.ceil((qxy.max(axis=0) + reach + g - lo) / g).astype(int) + 1
    raster = np.ones(shape, dtype=bool)
    qi = np.floor((qxy - lo) / g).astype(int)
    raster[qi[:, 0], qi[:, 1]] = False
    dist = ndimage.distance_transform_edt(raster) * g
    pi = np.floor((pts - lo) / g).astype(int)
    inside = np.all((pi >= 0) & (pi < shape), axis=1)
    near = np.zeros(len(pts), dtype=bool)
    near[inside] = dist[pi[inside, 0], pi[inside, 1]] <= reach + g
    return near


def _cells_in_reach(
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


def _inside(
    tri: Triangulation, keep: NDArray[np.bool_], xy: F64, cell: float
) -> tuple[NDArray[np.bool_], NDArray[np.int_]]:
    """(K,) whether lattice centres (K, 2) lie in a kept triangle, and its index."""
    simplex = tri.locate_kept(xy, keep, cell)
    return simplex >= 0, simplex


def _pattern_density(xy: F64, hit: NDArray[np.bool_], rays_per_pattern_ray: int) -> tuple[F64, F64]:
    """Density (points/m^2, sensor units) and spacing (m) of every hit of a ray grid.

    xy: (nv, nh, 2) projected hits (nan for a miss). Each hit spans the parallelogram
    of the steps to its nearer hit neighbour along each pattern axis; its area is the
    ground one pattern ray stands for, so density = 1 / area (divided by the
    oversampling). The nearer neighbour is taken so that a step across a shadow edge
    or onto a wall does not count. A hit with no neighbour along an axis has density 0
    and spacing 0 (it neither counts nor widens the alpha radius).
    """
    du = _nearer_step(xy, hit, axis=1)
    dv = _nearer_step(xy, hit, axis=0)
    area = np.abs(du[..., 0] * dv[..., 1] - du[..., 1] * dv[..., 0])
    with np.errstate(divide="ignore", invalid="ignore"):
        density = np.where(area > 0, 1.0 / (area * rays_per_pattern_ray), np.inf)
    density = np.where(np.isnan(area), 0.0, density)
    spacing = np.fmax(np.linalg.norm(du, axis=-1), np.linalg.norm(dv, axis=-1))
    return density, np.nan_to_num(spacing, nan=0.0)


def _nearer_step(xy: F64, hit: NDArray[np.bool_], axis: int) -> F64:
    """(nv, nh, 2) step to the nearer hit neighbour along ``axis`` (nan if none)."""
    fwd = np.full_like(xy, np.nan)
    bwd = np.full_like(xy, np.nan)
    n = xy.shape[axis]
    head = [slice(None)] * 3
    tail = [slice(None)] * 3
    head[axis], tail[axis] = slice(0, n - 1), slice(1, n)
    step = xy[tuple(tail)] - xy[tuple(head)]  # nan where either end missed
    fwd[tuple(head)] = step
    bwd[tuple(tail)] = step
    lf = np.linalg.norm(fwd, axis=-1)
    lb = np.linalg.norm(bwd, axis=-1)
    use_b = np.isnan(lf) | (lb < lf)
    out = np.where(use_b[..., None], bwd, fwd)
    out[~hit] = np.nan
    return out


def _interpolate(tri: Triangulation, values: F64, xy: F64, simplex: NDArray[np.int_]) -> F64:
    """Linear interpolation of per-point values (P,) at points xy (K, 2) in triangles."""
    if len(xy) == 0:
        return np.zeros(0)
    w = tri.barycentric(xy, simplex)
    v = values[tri.simplices[simplex]]
    # Wall hits project onto a line and report infinite density; cap them at the
    # densest finite neighbour so chi stays a number.
    finite = np.isfinite(v)
    cap = np.where(finite, v, -np.inf).max(axis=1, keepdims=True)
    v = np.where(finite, v, np.where(np.isfinite(cap), cap, 0.0))
    return np.einsum("kj,kj->k", w, v)


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


def make_evaluator(method: str, grid: GroundGrid, caster: RayCaster, **knobs: float):
    """The evaluator for ``method`` ("targeted" | "pointcloud") with its knobs."""
    if method == "targeted":
        return TargetedEvaluator(grid, caster)
    if method == "pointcloud":
        return PointcloudEvaluator(grid, caster, **knobs)  # type: ignore[arg-type]
    raise ValueError(f"unknown coverage method {method!r} (known: {', '.join(METHODS)})")
