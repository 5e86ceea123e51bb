"""A layout's coverage kept current one sensor at a time: the panel's live re-scoring
while a sensor camera is moved.

The ground grid and the evaluator are built once per scene (``LiveLayout``); each
sensor keeps the target points it covers, and the layout keeps how many sensors cover
each point. Moving, adding or removing a sensor evaluates that sensor alone and
updates the counts, so a move costs one sensor's evaluation however many sensors
stand. The counts are exactly ``evaluate_layout``'s (``headless coverage``): the same
grid, the same evaluator and the same pose of each sensor (``evaluate.sensor_pose``).

Positions are world metres (``SensorSpec``); areas m^2.
"""

from __future__ import annotations

import time
from collections.abc import Sequence
from dataclasses import dataclass, replace

import numpy as np
import shapely
import shapely.ops
from numpy.typing import NDArray

from . import refusal
from .coverage.evaluator import make_evaluator
from .evaluate import placement_problem, resolve_model, sensor_pose
from .geom.grid import GroundGrid
from .geom.raycast import RayCaster
from .masts import group_positions
from .model.scene import SceneModel
from .model.sensors import SensorSpec
from .problem import point_need
from .settings import CoverageSettings

# How far inside the allowed ground a snapped sensor's mast stands, m: on the border a
# mast would touch the zone or the object it must keep off.
SNAP_INSET_M = 0.05

I32 = NDArray[np.int32]
I64 = NDArray[np.int64]


@dataclass(frozen=True)
class Alone:
    """What one sensor adds to a layout: ``covers_m2`` of target it covers (each point
    once), ``share`` of the whole target that is, and ``lost_m2``: target that counts
    as covered with it and would not without it."""

    covers_m2: float
    share: float
    lost_m2: float


class LiveLayout:
    """The coverage of sensors on a scene, kept current as they move.

    scene, caster: the scene (local frame inside, world specs outside) and its ray
    caster; specs: the sensors, world metres; settings: how coverage is computed;
    reach_m: the longest range any sensor may get (the grid is built for it: a model
    with a longer range needs a new ``LiveLayout``); mast_cost, sensor_cost: the
    cost of a mast and of a sensor, for ``metrics``.
    """

    def __init__(
        self,
        scene: SceneModel,
        caster: RayCaster,
        specs: Sequence[SensorSpec],
        settings: CoverageSettings,
        reach_m: float | None = None,
        mast_cost: float = 3.0,
        sensor_cost: float = 1.0,
    ) -> None:
        self.settings = settings.validated()
        self.scene = scene
        self.reach_m = reach_m or max(s.model.range_m for s in specs)
        refusal.check_grid(scene, self.settings.grid_m, self.reach_m)
        self.grid = GroundGrid(
            scene, caster, self.settings.grid_m, self.settings.target_height_m, self.reach_m,
            check=False,
        )  # fmt: skip
        self.evaluator = make_evaluator(self.settings, self.grid, caster)
        self.need: I32 = point_need(self.grid, self.settings.coverage_k)
        self.counts: I32 = np.zeros(self.grid.n_targets, dtype=np.int32)
        self.specs: list[SensorSpec] = []
        self.covered: list[I64] = []
        # Why each sensor's mast may not stand where it does (None: it may).
        self.problems: list[str | None] = []
        self.mast_cost, self.sensor_cost = mast_cost, sensor_cost
        self.last_s = 0.0  # seconds the last change took
        for spec in specs:
            self.add(spec)

    # --- changes ---------------------------------------------------------------------

    def _problem(self, spec: SensorSpec) -> str | None:
        x, y = self.scene.to_local(np.array([[spec.x, spec.y]], dtype=float))[0]
        return placement_problem(self.scene, float(x), float(y))

    def _evaluate(self, spec: SensorSpec) -> I64:
        """The target ordinals ``spec`` covers (sorted, each once)."""
        if spec.model.range_m > self.reach_m:
            raise ValueError(f"range {spec.model.range_m:g} m is beyond the layout's reach")
        model = resolve_model(spec, self.settings)
        pose = sensor_pose(self.scene, self.grid, spec, model)
        return np.unique(self.evaluator.evaluate(model, pose).covered).astype(np.int64)

    def add(self, spec: SensorSpec) -> int:
        """Add a sensor; its index."""
        t0 = time.perf_counter()
        covered = self._evaluate(spec)
        self.counts[covered] += 1
        self.specs.append(spec)
        self.covered.append(covered)
        self.problems.append(self._problem(spec))
        self.last_s = time.perf_counter() - t0
        return len(self.specs) - 1

    def move(self, i: int, spec: SensorSpec) -> None:
        """Sensor ``i`` now stands and looks as ``spec`` says (a new model too)."""
        t0 = time.perf_counter()
        covered = self._evaluate(spec)
        self.counts[self.covered[i]] -= 1
        self.counts[covered] += 1
        if (spec.x, spec.y) != (self.specs[i].x, self.specs[i].y):
            self.problems[i] = self._problem(spec)
        self.specs[i], self.covered[i] = spec, covered
        self.last_s = time.perf_counter() - t0

    def snapped(self, i: int) -> SensorSpec | None:
        """Sensor ``i`` moved to the nearest place a mast may stand (in a sensor area,
        off no-mast zones and standing objects, ``SNAP_INSET_M`` inside the border) at
        the same height above the ground; None when there is none within its range."""
        spec = self.specs[i]
        here = self.scene.to_local(np.array([[spec.x, spec.y]], dtype=float))[0]
        allowed = shapely.union_all([a.geometry for a in self.scene.sensor_areas])
        inset = allowed.buffer(-SNAP_INSET_M)
        region = allowed if inset.is_empty else inset
        point = shapely.Point(*here)
        if region.is_empty or region.distance(point) > spec.model.range_m:
            return None
        if self._problem(spec) is None:
            return spec  # where a mast may stand already
        site = shapely.ops.nearest_points(region, point)[0]
        ground = self.grid.ground_z(np.array([here, (site.x, site.y)]))
        world = self.scene.to_world(np.array([[site.x, site.y]]))[0]
        z = None if spec.z is None else spec.z + float(ground[1] - ground[0])
        return replace(spec, x=float(world[0]), y=float(world[1]), z=z)

    def remove(self, i: int) -> None:
        """Take sensor ``i`` away; the sensors after it move down one index."""
        self.counts[self.covered[i]] -= 1
        del self.specs[i], self.covered[i], self.problems[i]

    # --- what the layout covers ------------------------------------------------------

    @property
    def cell_m2(self) -> float:
        return self.grid.spacing**2

    def masts(self) -> int:
        """Masts the sensors stand on: those within ``mast_join_m`` share one."""
        if not self.specs:
            return 0
        xy = np.array([[s.x, s.y] for s in self.specs], dtype=float)
        return int(group_positions(xy, self.settings.mast_join_m).max()) + 1

    def metrics(self) -> dict[str, float | int]:
        """Coverage (each point to its k), uncovered m^2, sensors, masts and cost."""
        n = len(self.counts)
        hit = int(np.count_nonzero(self.counts >= self.need))
        masts = self.masts()
        return {
            "coverage_fraction": round(hit / n, 6) if n else 0.0,
            "covered_m2": round(hit * self.cell_m2, 4),
            "uncovered_m2": round((n - hit) * self.cell_m2, 4),
            "target_area_m2": round(n * self.cell_m2, 4),
            "sensors": len(self.specs),
            "masts": masts,
            "cost": round(self.mast_cost * masts + self.sensor_cost * len(self.specs), 4),
        }

    def alone(self, i: int) -> Alone:
        """What sensor ``i`` covers, and what the layout would lose without it."""
        mine = self.covered[i]
        n = max(len(self.counts), 1)
        counts, need = self.counts[mine], self.need[mine]
        lost = int(np.count_nonzero((counts >= need) & (counts - 1 < need)))
        return Alone(
            covers_m2=round(len(mine) * self.cell_m2, 4),
            share=round(len(mine) / n, 6),
            lost_m2=round(lost * self.cell_m2, 4),
        )
