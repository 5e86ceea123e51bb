"""The optimization problem, built once and shared by every optimizer.

A ``Problem`` holds what an optimizer draws from and nothing of any optimizer's own
state: the ground grid with its target points, the coverage evaluator of the chosen
method (and the exact cached ``targeted`` probe beside it, for candidate sets and
reachability), the search space of mast positions and orientations, and the demand
(how many target points make the goal). Poses are placed on the ground here, in one
place, so that every optimizer and every later stage stands masts the same way.

Before any of it is built, the run's memory and work are estimated from the settings,
the model and the scene's areas (``refusal.check_run``): a run that cannot finish is
refused with one line naming the setting to change.
"""

from __future__ import annotations

import math
import time
from dataclasses import dataclass, replace
from typing import Any

import numpy as np
import shapely
from numpy.typing import NDArray
from shapely.geometry.base import BaseGeometry

from . import budget, refusal
from .coverage.base import SensorCoverage
from .coverage.cached import CachedTargetedEvaluator
from .coverage.evaluator import Evaluator, make_evaluator
from .coverage.pointcloud import auto_oversample
from .geom.grid import GridArrays, GroundGrid
from .geom.raycast import RayCaster
from .model.scene import SceneModel
from .model.sensors import SensorModel, SensorPack, SensorPose
from .settings import OptimizeSettings

F64 = NDArray[np.float64]


def orientations(
    pitch_min: float, pitch_max: float, yaw_step_deg: float = 10.0, pitches: int = 6
) -> F64:
    """(O, 2) (pitch, yaw) degrees: yaw in steps from 0, pitch evenly over the limits.
    The orientations of the candidate set (``candidates.py``)."""
    yaws = np.arange(0.0, 360.0, yaw_step_deg)
    ps = np.linspace(pitch_min, pitch_max, pitches) if pitch_max > pitch_min else [pitch_min]
    return np.array([(p, y) for p in ps for y in yaws])


def model_orientations(model: SensorModel) -> F64:
    """(O, 2) the candidate orientations of ``model`` (``orientations`` over its pitch
    limits), with one yaw at pitch 0 for a pattern that goes all the way round (a
    spinning lidar): level, it covers the same at every yaw (tilted, it does not:
    it looks down on one side and up on the other)."""
    angles = orientations(model.pitch_min_deg, model.pitch_max_deg)
    if model.pattern == "angular" and model.h_fov_deg >= 360.0:
        angles = angles[(angles[:, 0] != 0.0) | (angles[:, 1] == 0.0)]
    return angles


def run_estimate(
    scene: SceneModel,
    model: SensorModel,
    settings: OptimizeSettings,
    check: bool = False,
    workers: int = 1,
) -> budget.Estimate:
    """What an optimization of ``model`` sensors on ``scene`` with ``settings`` will
    need (``budget.estimate_run`` with the candidate orientations and the pointcloud's
    oversampling), ``workers`` ES worker processes included; ``check``: InputError
    when it cannot go ahead (``refusal.check_run``). ``min_density_per_m2`` in the
    settings overrides the model's, as in ``Problem``."""
    if settings.min_density_per_m2 is not None:
        model = replace(model, min_density_per_m2=settings.min_density_per_m2)
    angles = model_orientations(model)

    def oversample_at(grid_m: float) -> int:
        return settings.oversample or auto_oversample(model, grid_m)

    if check:
        return refusal.check_run(scene, model, settings, angles, oversample_at, workers)
    return budget.estimate_run(scene, model, settings, angles, oversample_at, workers=workers)


def point_need(grid: GroundGrid | GridArrays, coverage_k: int) -> NDArray[np.int32]:
    """(N,) how many sensors must cover each target point: its target area's
    ``coverage_k`` (``grid.region_k``), or the run's ``coverage_k`` where the area sets
    none (0)."""
    own = np.asarray(grid.region_k, dtype=np.int32)[np.asarray(grid.target_region)]
    return np.where(own > 0, own, np.int32(coverage_k)).astype(np.int32)


class SearchSpace:
    """Where a sensor may stand and how it may point.

    positions: (K, 2) the lattice points (spacing ``step_m``) inside the sensor areas
    (local metres), plus one point for any area too small to hold a lattice point, plus
    ``standing``: (M, 2) sites where a mast stands already (they may lie anywhere).
    Pitch in [pitch_min, pitch_max] degrees; yaw in [0, 360).
    """

    def __init__(
        self,
        areas: list[BaseGeometry],
        step_m: float,
        pitch_min_deg: float,
        pitch_max_deg: float,
        standing: F64 | None = None,
    ) -> None:
        self.step = float(step_m)
        self.pitch = (float(pitch_min_deg), float(pitch_max_deg))
        parts = []
        for area in areas:
            minx, miny, maxx, maxy = area.bounds
            i = np.arange(np.floor(minx / step_m), np.ceil(maxx / step_m) + 1)
            j = np.arange(np.floor(miny / step_m), np.ceil(maxy / step_m) + 1)
            ii, jj = np.meshgrid(i, j, indexing="ij")
            xy = np.column_stack([ii.ravel(), jj.ravel()]) * step_m
            xy = xy[shapely.intersects_xy(area, xy[:, 0], xy[:, 1])]
            if len(xy) == 0:
                p = area.representative_point()
                xy = np.array([[p.x, p.y]])
            parts.append(xy)
        if standing is not None:
            parts.append(np.asarray(standing, dtype=float).reshape(-1, 2))
        self.positions: F64 = np.unique(np.concatenate(parts), axis=0)
        self._index = {self._key(x, y): k for k, (x, y) in enumerate(self.positions)}
        # (K,) True where a mast stands already: a new sensor there adds no mast.
        self.standing = np.zeros(len(self.positions), dtype=bool)
        if standing is not None and len(standing):
            hit = (self.positions[:, None, :] == np.asarray(standing)[None]).all(axis=2)
            self.standing = hit.any(axis=1)

    def _key(self, x: float, y: float) -> tuple[int, int]:
        return (int(round(x / self.step)), int(round(y / self.step)))

    def member(self, x: float, y: float) -> bool:
        """Whether (x, y) is one of the positions."""
        return self.index_of(x, y) is not None

    def index_of(self, x: float, y: float) -> int | None:
        """The index of position (x, y), or None when it is not one."""
        k = self._index.get(self._key(x, y))
        return k if k is not None and bool(np.all(self.positions[k] == (x, y))) else None

    def snap(self, x: float, y: float) -> tuple[float, float]:
        """The lattice point nearest to (x, y) (it may lie outside the areas)."""
        return (round(x / self.step) * self.step, round(y / self.step) * self.step)

    def every(self, k: int) -> NDArray[np.bool_]:
        """(K,) the positions on every ``k``-th lattice line in x and y."""
        ij = np.round(self.positions / self.step).astype(int)
        return (ij[:, 0] % k == 0) & (ij[:, 1] % k == 0)


@dataclass(frozen=True)
class WorkerInputs:
    """What a worker process needs to score poses as this problem does: the grid as
    arrays, the model and the coverage settings (a caster factory comes beside it)."""

    grid: GridArrays
    model: SensorModel
    settings: OptimizeSettings


class Problem:
    """One scene, one sensor model or a pack of them, one set of settings: see the
    module docstring.

    scene: local metres; caster: casts against the scene's occluders; model: a model,
    or a ``SensorPack`` of models a plan may mix (``models``, the first also
    ``model``: the one the ES plans), each sensor of model m costing
    ``sensor_costs[m]``; settings are validated here. ``min_density_per_m2`` in the
    settings overrides every model's.
    ``estimate``: what the run was estimated to need (``budget.Estimate``), with
    ``workers`` ES worker processes beside this one; InputError before anything is
    allocated when it cannot go ahead. standing: (M, 2) local sites where masts stand
    already, added to the search space (``SearchSpace.standing``).
    """

    def __init__(
        self,
        scene: SceneModel,
        caster: RayCaster,
        model: SensorModel | SensorPack,
        settings: OptimizeSettings,
        workers: int = 1,
        standing: F64 | None = None,
    ) -> None:
        # The run's clock: a time limit counts from here (``optimize/planner.py``).
        self.t0 = time.perf_counter()
        self.settings = settings = settings.validated()
        pack = SensorPack.of(model)
        pack.check_optimizer(settings.optimizer)
        # Each model's run is checked; the candidate build stops cleanly should their
        # sum outgrow the machine (``candidates.build_candidates``).
        for other in pack.models[1:]:
            run_estimate(scene, other, settings, check=True, workers=workers)
        self.estimate = run_estimate(scene, pack.models[0], settings, True, workers)
        if settings.min_density_per_m2 is not None:
            density = settings.min_density_per_m2
            models = tuple(replace(m, min_density_per_m2=density) for m in pack.models)
            pack = replace(pack, models=models)
        self.scene = scene
        self.models: tuple[SensorModel, ...] = pack.models
        self.model = pack.models[0]
        self.pack = pack
        # (M,) the cost of one sensor of each model, in the units of mast_cost.
        self.sensor_costs = pack.cost_of(settings.sensor_cost)
        reach = max(m.range_m for m in pack.models)
        self.grid = GroundGrid(
            scene, caster, settings.grid_m, settings.target_height_m, reach, check=False
        )
        self.evaluator: Evaluator = make_evaluator(settings, self.grid, caster, settings.cache)
        # Rays to uncovered points, candidate sets and the proof that a gap cannot be
        # seen: always the exact targeted geometry, shared when it is the evaluator.
        self.probe = (
            self.evaluator
            if isinstance(self.evaluator, CachedTargetedEvaluator)
            else CachedTargetedEvaluator(self.grid, caster)
        )
        step = settings.position_step_m or 2.0 * settings.grid_m
        self.space = SearchSpace(
            [a.geometry for a in scene.sensor_areas],
            step,
            self.model.pitch_min_deg,
            self.model.pitch_max_deg,
            standing,
        )
        # The demand: rho of the target points, each covered by its k sensors
        # (``need``). Every fixed sensor raises at least one point towards its k, so
        # without a cap a run still ends after k_max sensors per point.
        self.rho = settings.rho
        self.need = point_need(self.grid, settings.coverage_k)
        self.k_max = int(self.need.max()) if len(self.need) else 1
        self.goal = math.ceil(settings.rho * self.grid.n_targets)
        self.max_sensors = settings.max_sensors or self.grid.n_targets * self.k_max
        self._mast: dict[tuple[float, float, int], tuple[float, float]] = {}
        # The candidate set, once someone built it (``candidates.build_candidates``).
        self.candidates: Any = None

    @property
    def n_targets(self) -> int:
        return self.grid.n_targets

    def reached(self, n_covered: int) -> bool:
        """Whether ``n_covered`` target points (each covered to its k) meet the goal."""
        return n_covered >= self.goal

    # --- poses -------------------------------------------------------------------
    def height_at(self, x: float, y: float, model: int = 0) -> float:
        """Sensor height on a mast at local (x, y): the sensor area's ``height_m``,
        else the mount height of model ``model`` (an index into ``models``)."""
        for area in self.scene.sensor_areas:
            if area.height_m is not None and shapely.intersects_xy(area.geometry, x, y):
                return area.height_m
        return self.models[model].mount_height_m

    def pose(self, x: float, y: float, pitch: float, yaw: float, model: int = 0) -> SensorPose:
        """The pose of a sensor of model ``model`` at local (x, y) on its mast (ground
        and height looked up once)."""
        key = (float(x), float(y), int(model))
        if key not in self._mast:
            height = self.height_at(*key)
            ground = float(self.grid.ground_z(np.array([key[:2]]))[0])
            self._mast[key] = (ground + height, height)
        z, height = self._mast[key]
        return SensorPose(key[0], key[1], z, height, float(pitch), float(yaw))

    def evaluate(
        self, pose: SensorPose, band_m: float | None = None, model: int = 0
    ) -> SensorCoverage:
        """Coverage of ``pose`` by a sensor of model ``model`` with the problem's method,
        with footprint cells outside the targets within ``band_m`` (``coverage.base``)."""
        return self.evaluator.evaluate(self.models[model], pose, outside_band_m=band_m)

    def evaluate_full(self, pose: SensorPose, model: int = 0) -> SensorCoverage:
        """Coverage of ``pose`` (model ``model``) with its whole footprint and its line
        of sight, as a result reports it."""
        return self.evaluator.evaluate(
            self.models[model], pose, outside_band_m=math.inf, visibility=True
        )

    def reachable(
        self, pose: SensorPose, wanted: NDArray[np.bool_], model: int = 0
    ) -> NDArray[np.int64]:
        """Target ordinals among ``wanted`` (N,) that some orientation of model
        ``model`` within its pitch limits might cover from the pose's position
        (``CachedTargetedEvaluator``)."""
        return self.probe.reachable(self.models[model], pose, wanted)

    def blind_areas(self, step_every: int = 2) -> list[str]:
        """Sensor areas from whose positions (every ``step_every``-th lattice point,
        and always at least one) no target point can be covered at all."""
        wanted = np.ones(self.n_targets, dtype=bool)
        positions = self.space.positions
        every = self.space.every(step_every)
        blind = []
        for area in self.scene.sensor_areas:
            inside = shapely.intersects_xy(area.geometry, *positions.T)
            probe = positions[inside & every]
            if len(probe) == 0:
                probe = positions[inside][:1]
            seen = any(
                len(self.reachable(self.pose(x, y, 0.0, 0.0, m), wanted, m))
                for m in range(len(self.models))
                for x, y in probe
            )
            if not seen:
                blind.append(area.name)
        return blind

    def worker_inputs(self) -> WorkerInputs:
        """What a worker process needs to score poses as this problem does."""
        return WorkerInputs(self.grid.arrays(), self.model, self.settings)

    @property
    def extra_rays(self) -> int:
        """Rays cast outside evaluations: drops onto the ground, reachability probes."""
        return self.grid.drop_rays + self.probe.extra_rays
