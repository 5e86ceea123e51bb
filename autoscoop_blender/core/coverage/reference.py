"""The paper's reference footprint: a model's largest footprint on flat, empty ground."""

from __future__ import annotations

from functools import lru_cache

import numpy as np
import shapely

from ..geom.grid import GroundGrid
from ..geom.raycast import BoxCaster
from ..model.scene import Area, SceneModel
from ..model.sensors import SensorModel, SensorPose
from .targeted import TargetedEvaluator


@lru_cache(maxsize=16)
def reference_footprint_m2(model: SensorModel, grid_m: float = 1.0) -> float:
    """The model's largest footprint on flat, empty ground over its pitch range, m^2
    (the paper's reference for the relative sensor coverage: 1229.95 for its camera).

    Evaluated with ``targeted`` at the given grid spacing, pitch in 1 deg steps, the
    sensor at the model's mount height.
    """
    r = model.range_m
    flat = SceneModel(
        vertices=np.zeros((0, 3)),
        faces=np.zeros((0, 3), dtype=np.int32),
        occluders=(),
        targets=(Area("flat", shapely.box(-r, -r, r, r)),),
        sensor_areas=(Area("mast", shapely.box(-0.5, -0.5, 0.5, 0.5)),),
    )
    caster = BoxCaster(ground_z=0.0)
    grid = GroundGrid(flat, caster, grid_m, reach_m=0.0)
    ev = TargetedEvaluator(grid, caster)
    best = 0.0
    pitches = np.arange(model.pitch_min_deg, model.pitch_max_deg + 1e-9, 1.0)
    for pitch in pitches if len(pitches) else [model.pitch_min_deg]:
        pose = SensorPose(0.0, 0.0, model.mount_height_m, model.mount_height_m, float(pitch), 0.0)
        cov = ev.evaluate(model, pose)
        best = max(best, len(cov.covered) * grid.cell_area)
    return best
