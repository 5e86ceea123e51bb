"""The coverage evaluator a setting asks for, behind one protocol."""

from __future__ import annotations

from typing import Protocol

from ..geom.grid import GroundGrid
from ..geom.raycast import RayCaster
from ..model.sensors import SensorModel, SensorPose
from ..settings import CoverageSettings
from .base import SensorCoverage
from .cached import CachedTargetedEvaluator
from .pointcloud import PointcloudEvaluator
from .targeted import TargetedEvaluator


class Evaluator(Protocol):
    """Coverage of one pose on a grid (see ``base.SensorCoverage``).

    ``outside_band_m``: footprint cells outside the targets looked at (None: none,
    inf: all within range, and the whole footprint's area); ``visibility``: also the
    target points in line of sight whatever their density.
    """

    method: str

    def evaluate(
        self,
        model: SensorModel,
        pose: SensorPose,
        outside_band_m: float | None = None,
        visibility: bool = False,
    ) -> SensorCoverage: ...


def make_evaluator(
    settings: CoverageSettings, grid: GroundGrid, caster: RayCaster, cache: bool = False
) -> Evaluator:
    """The evaluator of ``settings.method`` with its knobs; ``cache``: for
    ``targeted``, keep sight rays per mast position (same answers, fewer rays)."""
    if settings.method == "pointcloud":
        return PointcloudEvaluator(
            grid, caster, settings.oversample, settings.alpha, settings.alpha_m
        )
    if cache:
        return CachedTargetedEvaluator(grid, caster)
    return TargetedEvaluator(grid, caster)
