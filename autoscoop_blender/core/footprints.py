"""What a candidate covers, estimated without casting a ray (``budget.estimate_run``):
each sensor model's footprint on flat, empty ground as a radial profile, convolved
with a raster of the target areas of at most ``RASTER_CELLS`` cells, summed over the
sensor areas. Within 2 % of the cast footprints on flat ground; occluders lower it.
Lengths in metres, areas in m^2.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
import shapely
from numpy.typing import NDArray
from scipy import signal
from shapely.geometry.base import BaseGeometry

from .geom.grid_layout import areas_bounds
from .model.scene import SceneModel
from .model.sensors import SensorModel, frame
from .settings import CANDIDATE_OPTIMIZERS, OptimizeSettings

F64 = NDArray[np.float64]

# The areas are rasterized to at most this many cells (sampled 2 x 2 a cell), cells of
# at least RASTER_MIN_M: enough to weigh a footprint of about 1,000 m^2 against roads.
RASTER_CELLS = 1 << 18
RASTER_MIN_M = 1.0
# Radial samples of a footprint profile, and bearings around the mast.
PROFILE_RADII = 400
PROFILE_BEARINGS = 720


@dataclass(frozen=True)
class Footprints:
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


def site_footprints(
    scene: SceneModel, model: SensorModel, settings: OptimizeSettings, angles: F64
) -> Footprints:
    """The grid-free part of ``estimate_run`` (see ``Footprints``) for the candidate
    orientations ``angles`` (O, 2): the model's flat-ground profiles from each mast
    height, convolved with the raster of the targets."""
    heights = mast_heights(scene, model)
    profiles = {h: profile(model, h, settings.target_height_m, angles) for h in set(heights)}
    raster = AreaRaster(scene, model.range_m, heights)
    targets = raster.fractions(scene.target_union)
    reach, widest = raster.over_positions(targets, profiles, "reach")
    band = 0.0
    if settings.optimizer == "es":
        ring = raster.fractions(scene.target_union.buffer(settings.fitness.band_m))
        band = raster.over_positions(ring, profiles, "reach")[0]
    covers = 0.0
    if settings.optimizer in CANDIDATE_OPTIMIZERS or settings.bound:
        covers = raster.over_positions(targets, profiles, "covers")[0]
    return Footprints(
        reach_m2=reach,
        widest_m2=widest,
        band_m2=band,
        covers_m2=covers,
        view_fraction=max(p.view_fraction for p in profiles.values()),
        orientations=len(angles),
    )


@dataclass(frozen=True)
class Profile:
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


def profile(model: SensorModel, height_m: float, target_height_m: float, angles: F64) -> Profile:
    """The model's ``Profile`` from ``height_m`` above flat ground (see ``Profile``)
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
    return Profile(radii, covers, reach, min(view, 1.0))


class AreaRaster:
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

    def _summed(self, area: F64, profile: Profile, kind: str) -> F64:
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
        self, area: F64, profiles: dict[float, Profile], kind: str
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


def mast_heights(scene: SceneModel, model: SensorModel) -> list[float]:
    """Each sensor area's mast height (its own, else the model's), m."""
    return [
        a.height_m if a.height_m is not None else model.mount_height_m for a in scene.sensor_areas
    ]
