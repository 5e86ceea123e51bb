"""``targeted`` coverage: one sight ray per target point that can count.

Every target point within range is tested against the FoV, the pattern's analytic
density and (a camera with a resolution) the pixel density in numpy; one ray is cast from the sensor to each point that passes, and the
point is covered when nothing is hit before it. Rays per pose: the points that can
count (a few hundred for the paper camera). Exact at the grid's resolution.
"""

from __future__ import annotations

import math

import numpy as np

from ..geom.grid import GroundGrid
from ..geom.raycast import RayCaster
from ..model.sensors import SensorModel, SensorPose, frame
from .base import SensorCoverage, cells_in_reach, clear_sight, pixel_need, sight_lines, view


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
        cells, ordinal = cells_in_reach(grid, s, model.range_m, outside_band_m)
        is_target = ordinal >= 0
        lines = sight_lines(grid, s, cells, pixels=model.resolution_px is not None)
        need = pixel_need(grid, model, ordinal)
        rot = frame(pose.pitch_deg, pose.yaw_deg)
        in_view, density, dense = view(model, rot, lines, need)
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
