"""Coverage of a given set of sensors on a scene: the ``headless coverage`` job.

Everything here is Blender-free: it takes a SceneModel and a RayCaster, so the CLI,
the Blender operator and the tests run the same code.
"""

from __future__ import annotations

import math
import time
from dataclasses import asdict, dataclass, field, replace
from typing import Any

import numpy as np
import shapely

from .coverage import (
    METHODS,
    CoverageSummary,
    SensorCoverage,
    make_evaluator,
    place,
    summarize,
)
from .errors import InputError
from .grid import GroundGrid
from .masts import group_positions
from .placement import Placement, build_placement
from .raycast import RayCaster, inside_solid
from .scene_model import SceneModel
from .sensor_file import SensorSpec
from .sensors import SensorModel


@dataclass(frozen=True)
class CoverageSettings:
    """How coverage is computed. Lengths in metres, densities in points/m^2.

    ``min_density_per_m2`` overrides every model's threshold when set. ``oversample``
    (None: derived from the pattern, range and grid), ``alpha`` and ``alpha_m`` are the
    point-cloud method's knobs.
    """

    method: str = "targeted"
    grid_m: float = 1.0
    target_height_m: float = 0.0
    min_density_per_m2: float | None = None
    oversample: int | None = None
    alpha: float = 1.0
    alpha_m: float | None = None

    def validated(self) -> CoverageSettings:
        if self.method not in METHODS:
            raise InputError(f"--method {self.method!r}: choose one of {', '.join(METHODS)}")
        checks = [
            ("--grid", self.grid_m, self.grid_m > 0),
            ("--target-height", self.target_height_m, self.target_height_m >= 0),
            ("alpha", self.alpha, self.alpha > 0),
        ]
        if self.min_density_per_m2 is not None:
            d = self.min_density_per_m2
            checks.append(("--min-density", d, d >= 0))
        if self.alpha_m is not None:
            checks.append(("alpha_m", self.alpha_m, self.alpha_m > 0))
        if self.oversample is not None:
            checks.append(("--oversample", self.oversample, self.oversample >= 1))
        for name, value, ok in checks:
            if not (math.isfinite(value) and ok):
                raise InputError(f"{name} {value}: out of range")
        return self

    def knobs(self) -> dict[str, Any]:
        """Keyword arguments for the evaluator of ``method``."""
        if self.method == "pointcloud":
            return {"oversample": self.oversample, "alpha": self.alpha, "alpha_m": self.alpha_m}
        return {}


@dataclass
class CoverageResult:
    """Everything ``headless coverage`` reports; ``to_dict`` is the OUT.json schema."""

    scene: SceneModel
    grid: GroundGrid
    settings: CoverageSettings
    specs: list[SensorSpec]
    coverages: list[SensorCoverage]
    summary: CoverageSummary
    sensor_area_names: list[str | None]
    wall_s: float
    warnings: list[str] = field(default_factory=list)

    @property
    def rays_cast(self) -> int:
        return self.sight_rays + self.grid.drop_rays

    @property
    def sight_rays(self) -> int:
        return sum(c.rays for c in self.coverages)

    def to_dict(self) -> dict[str, Any]:
        g = self.grid
        sensors = []
        for k, (cov, area) in enumerate(zip(self.coverages, self.sensor_area_names), start=1):
            p = cov.pose
            x, y, z = self.scene.to_world(np.array([p.x, p.y, p.z]))
            sensors.append(
                {
                    "n": k,
                    "x": round(float(x), 4),
                    "y": round(float(y), 4),
                    "z": round(float(z), 4),
                    "height_m": p.height_m,
                    "pitch_deg": p.pitch_deg,
                    "yaw_deg": p.yaw_deg,
                    "model": cov.model.to_dict(),
                    "sensor_area": area,
                    "covered_target_m2": len(cov.covered) * g.cell_area,
                    "footprint_m2": _round(cov.footprint_m2),
                    "rays_cast": cov.rays,
                }
            )
        s = self.summary
        return {
            "scene": self.scene.source,
            "method": self.settings.method,
            "settings": asdict(self.settings),
            "target_area_m2": g.target_area_m2,
            "target_polygon_m2": round(float(self.scene.target_union.area), 2),
            "target_points": g.n_targets,
            "covered_m2": s.covered_m2,
            "coverage_fraction": round(s.coverage_fraction, 6),
            "sensors": sensors,
            "rays_cast": self.rays_cast,
            "rays": {"sight": self.sight_rays, "drop": g.drop_rays},
            "wall_s": round(self.wall_s, 3),
            "origin": [float(v) for v in self.scene.origin],
            "warnings": self.warnings,
        }

    def placement(self, mast_join_m: float = 3.0) -> Placement:
        """The evaluated layout in world coordinates; sensors within ``mast_join_m``
        of each other are shown on one mast (they are not moved)."""
        xy = np.array([[c.pose.x, c.pose.y] for c in self.coverages]).reshape(-1, 2)
        labels = group_positions(xy, mast_join_m)
        return build_placement(self.scene, self.grid, self.coverages, self.summary, labels)

    def point_rows(self) -> list[tuple[float, float, float, int, int, float]]:
        """One row per target point: world x, y, z, n_visible, n_covered, best_density."""
        pts = self.scene.to_world(self.grid.target_points)
        s = self.summary
        return [
            (
                round(float(x), 3),
                round(float(y), 3),
                round(float(z), 3),
                int(v),
                int(c),
                round(float(b), 4),
            )
            for (x, y, z), v, c, b in zip(pts, s.n_visible, s.n_covered, s.best_density)
        ]


def _round(v: float | None) -> float | None:
    return None if v is None else round(v, 3)


def resolve_model(spec: SensorSpec, settings: CoverageSettings) -> SensorModel:
    """The spec's model with the settings' threshold override applied."""
    if settings.min_density_per_m2 is None:
        return spec.model
    return replace(spec.model, min_density_per_m2=settings.min_density_per_m2)


def evaluate_sensors(
    scene: SceneModel,
    caster: RayCaster,
    specs: list[SensorSpec],
    settings: CoverageSettings,
) -> CoverageResult:
    """Coverage of each sensor and of their union, with footprints and visibility."""
    settings = settings.validated()
    t0 = time.perf_counter()
    warnings = list(scene.warnings)
    reach = max(s.model.range_m for s in specs)
    grid = GroundGrid(scene, caster, settings.grid_m, settings.target_height_m, reach)
    evaluator = make_evaluator(settings.method, grid, caster, **settings.knobs())
    if settings.method == "pointcloud" and settings.target_height_m > 0:
        warnings.append(
            "pointcloud: the point cloud lies on surfaces; --target-height applies to targeted only"
        )

    coverages, area_names = [], []
    for k, spec in enumerate(specs, start=1):
        x, y = scene.to_local(np.array([spec.x, spec.y]))
        area = _area_at(scene, x, y)
        if area is None:
            warnings.append(
                f"sensor {k} at ({spec.x:g}, {spec.y:g}) stands outside every sensor area"
            )
        height = spec.height_m
        if height is None:
            height = area.height_m if area is not None and area.height_m is not None else None
        model = resolve_model(spec, settings)
        if height is None:
            height = model.mount_height_m
        pose = place(grid, float(x), float(y), height, spec.pitch_deg, spec.yaw_deg)
        if inside_solid(caster, pose.position)[0]:
            warnings.append(
                f"sensor {k} at ({spec.x:g}, {spec.y:g}) stands inside an occluder "
                "(or under the ground): it sees nothing"
            )
        coverages.append(evaluator.evaluate(model, pose, outside_band_m=math.inf, visibility=True))
        area_names.append(area.name if area is not None else None)
    return CoverageResult(
        scene=scene,
        grid=grid,
        settings=settings,
        specs=specs,
        coverages=coverages,
        summary=summarize(grid, coverages),
        sensor_area_names=area_names,
        wall_s=time.perf_counter() - t0,
        warnings=warnings,
    )


def _area_at(scene: SceneModel, x: float, y: float):
    """The first sensor area containing local (x, y) (border included), or None."""
    for area in scene.sensor_areas:
        if shapely.intersects_xy(area.geometry, x, y):
            return area
    return None
