"""``pointcloud`` coverage, the paper's method: ray pattern, hits, density, alpha shape.

Cast the whole ray pattern, project the hits to XY, give each hit the density of the
pattern around it, keep the hits over the threshold and take the alpha shape of the
kept hits as the footprint; target points inside it are covered, chi interpolated
from the hits. Rays per pose: the pattern size (30,720 for Table I's camera).

A camera with a resolution also needs pixel density (``sensors`` module docstring).
Each hit gets its pixels per metre from the pinhole geometry at the hit (its direction,
distance and the surface normal the caster returns), exactly as ``targeted`` computes
it at a target point: the pixels are the camera's, not the pattern's, so nothing is
estimated from neighbouring hits. Each pixel density asked for (the model's, and
each target area's ``dori`` above it) gets its own alpha shape of the hits that reach
it; a target point is covered when it lies in the shape of the density it needs. The
footprint drawn and measured is the shape at the model's own ``min_px_per_m``. A model
without a resolution covers no point whose target area asks for pixels.
"""

from __future__ import annotations

import math

import numpy as np
from numpy.typing import NDArray
from scipy import ndimage

from ..geom.alpha import Triangulation, alpha_mask, triangulate
from ..geom.grid import GroundGrid
from ..geom.raycast import RayCaster
from ..model.sensors import SensorModel, SensorPose, facing_factor, frame
from .base import SensorCoverage, cells_in_reach, pixel_need

F64 = NDArray[np.float64]


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
        origins = np.broadcast_to(s, flat.shape)
        pixels = model.resolution_px is not None
        if pixels:
            dist, normals = self.caster.cast_normals(origins, flat, model.range_m)
        else:
            dist = self.caster.cast(origins, flat, model.range_m)
        flat_dist = dist
        dist = dist.reshape(dirs.shape[:2])
        hit = np.isfinite(dist)
        xy = np.where(hit[..., None], s[:2] + dirs[..., :2] * dist[..., None], np.nan)

        density, spacing = _pattern_density(xy, hit, self.rays_per_pattern_ray(model) ** 2)
        pts, pts_density, pts_spacing = xy[hit], density[hit], spacing[hit]
        cells, ordinal = cells_in_reach(grid, s, model.range_m, outside_band_m)
        is_target = ordinal >= 0
        qxy = grid.xy(cells)
        pts_px = None
        if pixels:
            on = hit.reshape(-1)
            facing = facing_factor(flat[on], flat_dist[on], normals[on])
            pts_px = model.px_per_m(self._pattern(model).reshape(-1, 3)[on], facing)

        # The footprint is the alpha shape of the hits over the threshold (the
        # paper's filtered FoV); line of sight alone is the alpha shape of all hits.
        # One shape per pixel density asked for; without any, one shape, as the paper.
        need = pixel_need(grid, model, ordinal)
        need = np.zeros(len(cells)) if need is None else need
        own = model.min_px_per_m if pixels else 0.0
        full = outside_band_m is not None and math.isinf(outside_band_m)
        covered = np.zeros(len(cells), dtype=bool)
        chi_rows = np.zeros(len(cells))
        for level in sorted({own, *need[np.isfinite(need)].tolist()}):
            rows = np.flatnonzero(need == level)
            ok = pts_density >= model.min_density_per_m2
            if pts_px is not None and level > 0:
                ok &= pts_px >= level
            dense = np.flatnonzero(ok)
            if not full and len(dense):
                # Only the cells asked about matter. An alpha triangle holding a cell
                # lies within twice its radius limit of it, and its circumcircle holds
                # no other hit; so triangulating just the hits within that distance of
                # the cells gives exactly the triangles the cells fall in, for less work.
                reach = 2.0 * self._max_radius(pts_spacing[dense]) + grid.spacing
                dense = dense[_near(grid, pts[dense], qxy[rows], reach)]
            tri = triangulate(pts[dense])
            keep_tri = alpha_mask(tri, self._radius_limit(tri, pts_spacing[dense]))
            inside, simplex = _inside(tri, keep_tri, qxy[rows], grid.spacing)
            covered[rows] = inside
            got = inside & is_target[rows]
            chi_rows[rows[got]] = _interpolate(
                tri, pts_density[dense], qxy[rows[got]], simplex[got]
            )
            if level == own:
                footprint_tri, footprint_keep = tri, keep_tri
        cov_t = covered & is_target
        chi = chi_rows[cov_t]

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
            footprint_m2=float(footprint_tri.areas()[footprint_keep].sum()) if full else None,
            rays=int(flat.shape[0]),
            _triangles=footprint_tri.points[footprint_tri.simplices[footprint_keep]],
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
