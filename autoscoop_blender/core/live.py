"""A layout's coverage kept current one sensor at a time: the panel's live re-scoring
while a sensor camera is moved.

The ground grid and the evaluator are built once per scene (``LiveLayout``); each
sensor keeps the target points it covers, and the layout keeps how many sensors cover
each point. Moving, adding or removing a sensor evaluates that sensor alone and
updates the counts, so a move costs one sensor's evaluation however many sensors
stand. The counts are exactly ``evaluate_layout``'s (``headless coverage``): the same
grid, the same evaluator and the same pose of each sensor (``evaluate.sensor_pose``).

Beside the counts: why a sensor's mast may not stand where it does (``problems``), the
nearest place it may (``snapped``), and the one sensor to add that raises the most
points short of their k (``best_addition``): the panel's editing tools.

Positions are world metres (``SensorSpec``); areas m^2.
"""

from __future__ import annotations

import math
import time
from collections.abc import Sequence
from dataclasses import dataclass, replace

import numpy as np
import shapely
import shapely.ops
from numpy.typing import NDArray

from . import refusal
from .coverage.base import place
from .coverage.evaluator import Evaluator, make_evaluator
from .evaluate import mount_height, placement_problem, resolve_model, sensor_pose
from .geom.grid import GroundGrid
from .geom.raycast import RayCaster
from .masts import group_positions
from .model.scene import SceneModel
from .model.sensors import SensorModel, SensorSpec
from .model.sites import site_blockers
from .problem import point_need
from .result import uncovered_parts
from .settings import CoverageSettings

# Filling a gap (``best_addition``): places tried beyond the standing masts, their
# lattice, m, and the orientations at each (as the candidate set's: yaw every 10 deg,
# six pitches), searched coarse to fine.
FILL_SITES = 40
FILL_STEP_M = 2.0
FILL_YAW_DEG = 10
FILL_PITCHES = 6
FILL_COARSE_YAW_DEG = 30
FILL_REFINE = 3
# How far inside the allowed ground a snapped sensor's mast stands, m: on the border a
# mast would touch the zone or the object it must keep off.
SNAP_INSET_M = 0.05

F64 = NDArray[np.float64]
I32 = NDArray[np.int32]
I64 = NDArray[np.int64]


@dataclass(frozen=True)
class Addition:
    """A sensor to add (``spec``, world metres), the target points short of their k it
    raises, and whether it goes on a mast that stands already."""

    spec: SensorSpec
    gain_points: int
    on_standing_mast: bool


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
        self.caster = caster
        self.evaluator = make_evaluator(self.settings, self.grid, caster)
        self._search: Evaluator | None = None  # a cached evaluator, to fill gaps
        self._standing_sites = 0
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

    def best_addition(
        self, model: SensorModel, most_sites: int = FILL_SITES, step_m: float = FILL_STEP_M
    ) -> Addition | None:
        """The one sensor of ``model`` that raises the most target points now short of
        their k, searched at the masts standing first (a sensor there adds no mast),
        then at up to ``most_sites`` places a mast may stand on a ``step_m`` lattice,
        the nearest to the largest uncovered patch first. Coarse to fine: every site at
        yaws ``FILL_COARSE_YAW_DEG`` apart and three pitches, then the ``FILL_REFINE``
        best sites at every 10 deg within one coarse step and six pitches over the
        model's limits (the candidate set's orientations). None when nothing is
        uncovered or no site sees any of it."""
        short = self.counts < self.need
        if not short.any():
            return None
        sites = self._fill_sites(short, most_sites, step_m)
        if self._search is None:
            self._search = make_evaluator(self.settings, self.grid, self.caster, cache=True)
        pitches = np.linspace(model.pitch_min_deg, model.pitch_max_deg, FILL_PITCHES)
        coarse_yaws = np.arange(0.0, 360.0, FILL_COARSE_YAW_DEG)
        coarse = [
            self._best_at(model, short, xy, pitches[[0, FILL_PITCHES // 2, -1]], coarse_yaws)
            for xy in sites
        ]
        # Stable by gain, so the standing masts (first) win ties.
        order = sorted(range(len(sites)), key=lambda k: -coarse[k][0])[:FILL_REFINE]
        best: Addition | None = None
        for k in order:
            around = coarse[k][2] + np.arange(
                -FILL_COARSE_YAW_DEG + FILL_YAW_DEG, FILL_COARSE_YAW_DEG, FILL_YAW_DEG
            )
            gain, pitch, yaw, height = self._best_at(model, short, sites[k], pitches, around % 360)
            if gain > (best.gain_points if best else 0):
                world = self.scene.to_world(sites[k][None])[0]
                spec = SensorSpec(model, float(world[0]), float(world[1]), height, pitch, yaw)
                best = Addition(spec, gain, k < self._standing_sites)
        return best

    def _best_at(
        self, model: SensorModel, short: NDArray[np.bool_], xy: F64, pitches: F64, yaws: F64
    ) -> tuple[int, float, float, float]:
        """The orientation of a sensor at local ``xy`` that raises the most ``short``
        points: (points, pitch, yaw, height above the ground); the first on ties."""
        x, y = float(xy[0]), float(xy[1])
        height = mount_height(self.scene, self.grid, _at(model, x, y), model, x, y)
        best = (0, float(pitches[0]), float(yaws[0]), height)
        assert self._search is not None
        for pitch in pitches:
            for yaw in yaws:
                pose = place(self.grid, x, y, height, float(pitch), float(yaw))
                gain = int(np.count_nonzero(short[self._search.evaluate(model, pose).covered]))
                if gain > best[0]:
                    best = (gain, float(pitch), float(yaw), height)
        return best

    def _fill_sites(self, short: NDArray[np.bool_], most: int, step_m: float) -> F64:
        """(K, 2) local places to try: the standing masts, then lattice places in the
        sensor areas where a mast may stand, nearest the largest uncovered patch."""
        standing = self.scene.to_local(
            np.array([[s.x, s.y] for s in self.specs], dtype=float).reshape(-1, 2)
        )
        if len(standing):
            standing = standing[np.unique(group_positions(standing, self.settings.mast_join_m),
                                          return_index=True)[1]]  # fmt: skip
        self._standing_sites = len(standing)
        patch = uncovered_parts(self.grid, short, self.scene)[0]
        centre = self.scene.to_local(np.array([[patch["x"], patch["y"]]]))[0]
        allowed = shapely.union_all([a.geometry for a in self.scene.sensor_areas])
        x0, y0, x1, y1 = allowed.bounds
        xs = np.arange(math.floor(x0 / step_m), math.ceil(x1 / step_m) + 1) * step_m
        ys = np.arange(math.floor(y0 / step_m), math.ceil(y1 / step_m) + 1) * step_m
        lattice = np.stack(np.meshgrid(xs, ys, indexing="ij"), axis=-1).reshape(-1, 2)
        lattice = lattice[shapely.contains_xy(allowed, lattice[:, 0], lattice[:, 1])]
        lattice = lattice[np.argsort(np.hypot(*(lattice - centre).T), kind="stable")]
        # The nearest places first, off no-mast zones and standing objects (one query
        # for a few times as many as wanted: most places are free).
        near = lattice[: 4 * most]
        free = near[[b is None for b in site_blockers(self.scene, near)]][:most]
        return np.concatenate([standing, free.reshape(-1, 2)])

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


def _at(model: SensorModel, x: float, y: float) -> SensorSpec:
    """A spec at local (x, y) with nothing but its model: its height is found as any
    sensor's is (the sensor area's, else the model's mount height)."""
    return SensorSpec(model, x, y, None, 0.0, 0.0)
