"""A finished sensor layout in world coordinates: what reports and the scene show.

Every output (result.json, sensors.csv, sensors.geojson, coverage.png, the results
collection in Blender) is written from a ``Placement``; nothing downstream needs the
optimizer or the ray caster.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
import shapely.affinity
from numpy.typing import NDArray
from shapely.geometry.base import BaseGeometry

from .coverage import CoverageSummary, SensorCoverage, footprint_polygon
from .grid import GroundGrid
from .scene_model import SceneModel
from .sensors import SensorModel


@dataclass(frozen=True)
class SensorRecord:
    """One placed sensor. World metres, degrees; ``mast`` indexes ``Placement.masts``.

    ``footprint`` is the ground region it covers (density over the threshold, line of
    sight), a (Multi)Polygon in world XY; ``footprint_m2`` its area.
    """

    n: int
    x: float
    y: float
    z: float
    height_m: float
    pitch_deg: float
    yaw_deg: float
    model: SensorModel
    mast: int
    fitness: float
    epochs: int
    covered_target_m2: float
    footprint_m2: float
    footprint: BaseGeometry


@dataclass(frozen=True)
class MastRecord:
    """A mast: world position of its foot (``z_ground``), height, the sensors on it
    (their ``n``)."""

    n: int
    x: float
    y: float
    z_ground: float
    height_m: float
    sensors: tuple[int, ...]


@dataclass(frozen=True)
class Placement:
    """Sensors, masts, areas and per-target-point coverage, all in world coordinates.

    points: (N, 3) target points; n_visible, n_covered: (N,) counts of sensors that
    see / cover each point; cell_m: the target grid spacing (each point stands for
    cell_m^2 of ground).
    """

    sensors: tuple[SensorRecord, ...]
    masts: tuple[MastRecord, ...]
    targets: tuple[tuple[str, BaseGeometry], ...]
    sensor_areas: tuple[tuple[str, BaseGeometry], ...]
    points: NDArray[np.float64]
    n_visible: NDArray[np.int32]
    n_covered: NDArray[np.int32]
    cell_m: float

    @property
    def coverage_fraction(self) -> float:
        return float((self.n_covered > 0).mean()) if len(self.n_covered) else 0.0


def build_placement(
    scene: SceneModel,
    grid: GroundGrid,
    coverages: Sequence[SensorCoverage],
    summary: CoverageSummary,
    mast_of: Sequence[int],
    fitness: Sequence[float] | None = None,
    epochs: Sequence[int] | None = None,
) -> Placement:
    """A Placement in world coordinates from evaluated (local) coverages.

    mast_of: (n,) each sensor's mast label 0..m-1; a mast stands where its first
    sensor stands and is as tall as its tallest. fitness, epochs: per sensor (0 if
    not optimized).
    """
    ox, oy, oz = (float(v) for v in scene.origin)
    sensors = []
    for k, cov in enumerate(coverages):
        p = cov.pose
        sensors.append(
            SensorRecord(
                n=k + 1,
                x=p.x + ox,
                y=p.y + oy,
                z=p.z + oz,
                height_m=p.height_m,
                pitch_deg=p.pitch_deg,
                yaw_deg=p.yaw_deg,
                model=cov.model,
                mast=int(mast_of[k]),
                fitness=float(fitness[k]) if fitness is not None else 0.0,
                epochs=int(epochs[k]) if epochs is not None else 0,
                covered_target_m2=len(cov.covered) * grid.cell_area,
                footprint_m2=float(cov.footprint_m2 or 0.0),
                footprint=shapely.affinity.translate(footprint_polygon(grid, cov), ox, oy),
            )
        )
    masts = []
    for label in range(max(mast_of, default=-1) + 1):
        members = [s for s in sensors if s.mast == label]
        first = members[0]
        masts.append(
            MastRecord(
                n=label + 1,
                x=first.x,
                y=first.y,
                z_ground=first.z - first.height_m,
                height_m=max(s.height_m for s in members),
                sensors=tuple(s.n for s in members),
            )
        )

    def world(areas):
        return tuple((a.name, shapely.affinity.translate(a.geometry, ox, oy)) for a in areas)

    return Placement(
        sensors=tuple(sensors),
        masts=tuple(masts),
        targets=world(scene.targets),
        sensor_areas=world(scene.sensor_areas),
        points=scene.to_world(grid.target_points),
        n_visible=summary.n_visible,
        n_covered=summary.n_covered,
        cell_m=grid.spacing,
    )
