"""A finished sensor layout in world coordinates: what reports and the scene show.

Every output (result.json, sensors.csv, sensors.geojson, coverage.png, the results
collection in Blender) is written from a ``Placement``; nothing downstream needs the
optimizer or the ray caster.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray
from shapely.geometry.base import BaseGeometry

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
