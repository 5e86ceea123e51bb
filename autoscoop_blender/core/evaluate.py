"""Coverage of a given set of sensors on a scene: ``headless coverage`` and the panel's
Evaluate.

It runs the same stages as an optimization without the optimizer: the ground grid,
the evaluator of the chosen method, one full evaluation per sensor, masts for
sensors that stand together (shown, not moved), and ``result.finish_layout``.
"""

from __future__ import annotations

import math
import time
from dataclasses import replace

import numpy as np

from ..names import MOUNT_PROP
from . import refusal
from .coverage.base import place
from .coverage.evaluator import make_evaluator
from .coverage.pointcloud import auto_oversample
from .geom.grid import GroundGrid
from .geom.raycast import RayCaster, inside_solid
from .masts import group_positions
from .model.scene import SceneModel
from .model.sensors import SensorModel, SensorPose, SensorSpec
from .model.sites import site_blockers
from .result import Provenance, Result, area_at, finish_layout
from .settings import CoverageSettings


def resolve_model(spec: SensorSpec, settings: CoverageSettings) -> SensorModel:
    """The spec's model with the settings' threshold override applied."""
    if settings.min_density_per_m2 is None:
        return spec.model
    return replace(spec.model, min_density_per_m2=settings.min_density_per_m2)


def mount_height(
    scene: SceneModel, grid: GroundGrid, spec: SensorSpec, model: SensorModel, x: float, y: float
) -> float:
    """How high above the ground a sensor at local (x, y) stands, m: its ``height_m``,
    else its absolute ``z`` less the ground there, else its sensor area's height, else
    its model's mount height."""
    if spec.height_m is not None:
        return spec.height_m
    if spec.z is not None:
        ground = float(grid.ground_z(np.array([[x, y]]))[0])
        return max(spec.z - scene.origin[2] - ground, 0.0)
    area = area_at(scene, x, y)
    return area.height_m if area is not None and area.height_m is not None else model.mount_height_m


def placement_problem(scene: SceneModel, x: float, y: float) -> str | None:
    """Why no mast may stand at local (x, y): on or beside a no-mast zone or an object
    standing on the ground (``sites``), or outside every sensor area; None where one
    may."""
    blocker = site_blockers(scene, np.array([[x, y]], dtype=float))[0]
    if blocker is not None:
        return f"on or beside {blocker}, where no mast may stand"
    if area_at(scene, x, y) is None:
        return "outside every sensor area"
    return None


def sensor_pose(
    scene: SceneModel, grid: GroundGrid, spec: SensorSpec, model: SensorModel
) -> SensorPose:
    """Where a sensor of world ``spec`` stands and looks, in the grid's local frame."""
    x, y = (float(v) for v in scene.to_local(np.array([[spec.x, spec.y]], dtype=float))[0])
    return place(grid, x, y, mount_height(scene, grid, spec, model, x, y), spec.pitch_deg,
                 spec.yaw_deg)  # fmt: skip


def evaluate_layout(
    scene: SceneModel,
    caster: RayCaster,
    specs: list[SensorSpec],
    settings: CoverageSettings,
) -> Result:
    """Coverage of each sensor and of their union, with footprints and visibility.

    specs: world metres (see ``SensorSpec`` for how each height is found). Warnings
    (in ``Result.warnings``): a sensor where no mast may stand (``sites``), outside
    every sensor area, inside an occluder, or mounted at or above its range.
    """
    settings = settings.validated()
    t0 = time.perf_counter()
    warnings = list(scene.warnings)
    reach = max(s.model.range_m for s in specs)
    models = [resolve_model(s, settings) for s in specs]

    def pattern_rays_at(grid_m: float) -> int:
        """The most rays a pointcloud pose of these sensors casts at ``grid_m``."""
        return max(
            m.n_rays * (settings.oversample or auto_oversample(m, grid_m)) ** 2 for m in models
        )

    pattern = pattern_rays_at if settings.method == "pointcloud" else None
    refusal.check_grid(scene, settings.grid_m, reach, pattern)
    grid = GroundGrid(scene, caster, settings.grid_m, settings.target_height_m, reach, check=False)
    evaluator = make_evaluator(settings, grid, caster)
    if settings.method == "pointcloud" and settings.target_height_m > 0:
        warnings.append(
            "pointcloud: the point cloud lies on surfaces; --target-height applies to targeted only"
        )

    local_xy = scene.to_local(np.array([[s.x, s.y] for s in specs], dtype=float))
    blockers = site_blockers(scene, local_xy)
    coverages = []
    for k, spec in enumerate(specs, start=1):
        x, y = (float(v) for v in local_xy[k - 1])
        area = area_at(scene, x, y)
        if blockers[k - 1] is not None:
            warnings.append(
                f"sensor {k} at ({spec.x:g}, {spec.y:g}) stands where no mast may: on or "
                f"beside {blockers[k - 1]} (masts stand on the ground; a roof or gantry "
                f"with {MOUNT_PROP} = True may carry one)"
            )
        elif area is None:
            warnings.append(
                f"sensor {k} at ({spec.x:g}, {spec.y:g}) stands outside every sensor area"
            )
        model = models[k - 1]
        height = mount_height(scene, grid, spec, model, x, y)
        if height >= model.range_m:
            warnings.append(
                f"sensor {k} at ({spec.x:g}, {spec.y:g}) is mounted {height:g} m high, not "
                f"below its range of {model.range_m:g} m: it cannot reach the ground under it"
            )
        pose = place(grid, x, y, height, spec.pitch_deg, spec.yaw_deg)
        if inside_solid(caster, pose.position)[0]:
            warnings.append(
                f"sensor {k} at ({spec.x:g}, {spec.y:g}) stands inside an occluder "
                "(or under the ground): it sees nothing"
            )
        coverages.append(evaluator.evaluate(model, pose, outside_band_m=math.inf, visibility=True))
    xy = np.array([[c.pose.x, c.pose.y] for c in coverages]).reshape(-1, 2)
    mast_of = [int(v) for v in group_positions(xy, settings.mast_join_m)]
    how = Provenance(t0=t0, warnings=tuple(warnings), settings=settings)
    return finish_layout(scene, grid, coverages, mast_of, how)
