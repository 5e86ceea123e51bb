"""The optimization: sensors fixed one at a time by the paper's ES until rho of the
target is covered, then grouped into masts (Algorithm 1, outer loop).

``OptimizationRun.steps()`` is a generator that yields a ``Progress`` after every
candidate evaluation, so the Blender operator can time-slice it and the CLI can draw
a progress bar; both drain the same generator, so the same seed gives the same
answer everywhere. Each fixed sensor is reported to ``on_fixed`` with the random
generator's state, which is all a resumed run needs to go on exactly as before.

Stop rules: the covered fraction reaches rho; or ``patience`` searches in a row find
no pose that adds a single target point (then the uncovered parts are named); or
``max_sensors`` is reached. The loop never runs forever.
"""

from __future__ import annotations

import math
import time
from collections.abc import Callable, Iterator, Mapping
from concurrent.futures import Future
from dataclasses import asdict, dataclass, field, fields, replace
from functools import lru_cache
from typing import Any

import numpy as np
import shapely
from numpy.typing import NDArray
from scipy import ndimage

from .cached import CachedTargetedEvaluator
from .coverage import (
    METHODS,
    CoverageSummary,
    PointcloudEvaluator,
    SensorCoverage,
    TargetedEvaluator,
    place,
    summarize,
)
from .errors import InputError
from .es import ESParams, SearchSpace, SensorSearch
from .fitness import FitnessParams, FixedSensors, fitness
from .greedy import greedy_steps
from .grid import GroundGrid
from .masts import choose_sites, group_positions
from .placement import Placement, build_placement
from .raycast import BoxCaster, RayCaster
from .scene_model import Area, SceneModel
from .sensors import SensorModel, SensorPose

F64 = NDArray[np.float64]

# "es": the paper's evolution strategy; "greedy": set cover over a candidate set.
OPTIMIZERS = ("es", "greedy")


@dataclass(frozen=True)
class OptimizeSettings:
    """Everything that decides the answer (with the scene, the model and the seed).

    position_step_m: lattice of mast positions (None: twice the grid spacing, 2 m by
    default: finer than a planner needs for a mast, coarse enough that the ES
    revisits positions and reuses their sight rays). mast_join_m:
    sensors this close share a mast. patience: searches in a row that add nothing
    before giving up. max_sensors: a cap (None: none; the run still ends, since each
    sensor adds at least one target point).
    cache: targeted only, cache sight lines per position (same answers, fewer rays).
    oversample (None: derived), alpha: pointcloud knobs (``coverage.PointcloudEvaluator``).
    """

    optimizer: str = "es"
    method: str = "targeted"
    grid_m: float = 1.0
    target_height_m: float = 0.0
    rho: float = 0.97
    seed: int = 0
    position_step_m: float | None = None
    mast_join_m: float = 3.0
    patience: int = 2
    max_sensors: int | None = None
    cache: bool = True
    oversample: int | None = None
    alpha: float = 1.0
    es: ESParams = field(default_factory=ESParams)
    fitness: FitnessParams = field(default_factory=FitnessParams)

    def to_dict(self) -> dict[str, Any]:
        return asdict(self)

    @classmethod
    def from_mapping(cls, data: Mapping[str, Any], label: str) -> OptimizeSettings:
        """Settings from a config mapping (TOML): top-level keys plus [es] and
        [fitness] tables; unknown keys are an InputError naming ``label``."""
        data = dict(data)
        nested: dict[str, Any] = {}
        for name, kind in (("es", ESParams), ("fitness", FitnessParams)):
            table = data.pop(name, {})
            if not isinstance(table, Mapping):
                raise InputError(f"{label}: [{name}] must be a table")
            nested[name] = _build(kind, table, f"{label} [{name}]")
        return _build(cls, {**data, **nested}, label)

    def validated(self) -> OptimizeSettings:
        if self.method not in METHODS:
            raise InputError(f"method {self.method!r}: choose one of {', '.join(METHODS)}")
        if self.optimizer not in OPTIMIZERS:
            raise InputError(f"optimizer {self.optimizer!r}: choose one of {', '.join(OPTIMIZERS)}")
        if self.optimizer == "greedy" and self.method != "targeted":
            raise InputError("the greedy optimizer needs the targeted method")
        checks = [
            ("grid_m", self.grid_m > 0),
            ("target_height_m", self.target_height_m >= 0),
            ("rho", 0 < self.rho <= 1),
            ("mast_join_m", self.mast_join_m >= 0),
            ("patience", self.patience >= 1),
            ("alpha", self.alpha > 0),
            ("es.mu", self.es.mu >= 1),
            ("es.lam", self.es.lam >= 1),
            ("es.eps", self.es.eps >= 0),
            ("es.max_epochs", self.es.max_epochs >= 0),
            ("es.decay", 0 < self.es.decay <= 1),
            ("fitness.theta_m", self.fitness.theta_m > 0),
            ("fitness.theta_tau_m", self.fitness.theta_tau_m > 0),
        ]
        if self.position_step_m is not None:
            checks.append(("position_step_m", self.position_step_m > 0))
        if self.max_sensors is not None:
            checks.append(("max_sensors", self.max_sensors >= 1))
        if self.oversample is not None:
            checks.append(("oversample", self.oversample >= 1))
        for name, ok in checks:
            value = _lookup(self, name)
            if isinstance(value, float) and not math.isfinite(value):
                ok = False
            if not ok:
                raise InputError(f"setting {name} = {value!r} is out of range")
        return self


def _build(kind: type, table: Mapping[str, Any], label: str) -> Any:
    """``kind`` with the defaults replaced by ``table``; InputError for unknown keys or
    values of the wrong type (every setting is a number, except these)."""
    known = {f.name for f in fields(kind)}
    unknown = sorted(set(table) - known)
    if unknown:
        raise InputError(f"{label}: unknown setting(s) {', '.join(unknown)}")
    for key, value in table.items():
        want = {
            "optimizer": str,
            "method": str,
            "cache": bool,
            "es": ESParams,
            "fitness": FitnessParams,
        }.get(key)
        if want is not None:
            ok = isinstance(value, want)
        else:
            ok = isinstance(value, (int, float)) and not isinstance(value, bool)
        if not ok:
            kind_name = want.__name__ if want in (str, bool) else "number"
            raise InputError(f"{label}: {key} must be a {kind_name}, got {value!r}")
    return replace(kind(), **table)


def _lookup(obj: Any, dotted: str) -> Any:
    for part in dotted.split("."):
        obj = getattr(obj, part)
    return obj


@dataclass(frozen=True)
class Progress:
    """Where a run is: for progress bars, status lines and the modal operator."""

    phase: str  # "search" | "fixed" | "masts" | "report" | "done"
    sensors: int
    coverage: float
    rho: float
    epoch: int
    evaluations: int

    @property
    def fraction(self) -> float:
        """Progress towards the goal in [0, 1]."""
        return 1.0 if self.phase == "done" else min(1.0, self.coverage / self.rho)


@dataclass
class FixedSensor:
    """A sensor as the ES fixed it (local metres, degrees)."""

    pose: SensorPose
    fitness: float
    epochs: int
    evaluations: int
    new_points: int
    mast: int = -1


@dataclass
class OptimizationResult:
    """A finished run: sensors, masts, final coverage, metrics, stop reason."""

    scene: SceneModel
    grid: GroundGrid
    model: SensorModel
    settings: OptimizeSettings
    sensors: list[FixedSensor]
    coverages: list[SensorCoverage]
    summary: CoverageSummary
    masts: list[tuple[float, float, float, float, tuple[int, ...]]]
    stop_reason: str
    uncovered: list[dict[str, Any]]
    metrics: dict[str, Any]

    def placement(self) -> Placement:
        """The layout in world coordinates, for reports and the scene."""
        return build_placement(
            self.scene,
            self.grid,
            self.coverages,
            self.summary,
            [s.mast for s in self.sensors],
            [s.fitness for s in self.sensors],
            [s.epochs for s in self.sensors],
        )


class OptimizationRun:
    """One optimization of ``model`` sensors on a scene (see module docstring).

    resume: records of sensors fixed by an earlier run with the same inputs (as
    given to ``on_fixed``); the run starts after the last of them, with its random
    state. on_fixed(record): called with a JSON-ready dict after each fixed sensor.
    workers: processes that evaluate each ES population in parallel (same answer;
    progress then comes a population at a time).
    """

    def __init__(
        self,
        scene: SceneModel,
        caster: RayCaster,
        model: SensorModel,
        settings: OptimizeSettings,
        resume: list[dict[str, Any]] = (),  # type: ignore[assignment]
        on_fixed: Callable[[dict[str, Any]], None] | None = None,
        workers: int = 1,
    ) -> None:
        self.settings = settings = settings.validated()
        self.scene = scene
        self.model = model
        self.on_fixed = on_fixed
        self.t0 = time.perf_counter()
        self.grid = GroundGrid(
            scene, caster, settings.grid_m, settings.target_height_m, model.range_m
        )
        self.evaluator = _evaluator(settings, self.grid, caster)
        step = settings.position_step_m or 2.0 * settings.grid_m
        self.space = SearchSpace(
            [a.geometry for a in scene.sensor_areas], step, model.pitch_min_deg, model.pitch_max_deg
        )
        self.rng = np.random.default_rng(settings.seed)
        self.fixed = FixedSensors(np.zeros(self.grid.n_targets, dtype=bool))
        # Each fixed sensor's newly covered ordinals and mast, in order: what worker
        # processes are sent to catch up, instead of the whole covered array each time.
        self._fixed_log: list[tuple[NDArray[np.int64], tuple[float, float]]] = []
        self.sensors: list[FixedSensor] = []
        self.sight_rays = 0
        self.evaluations = 0
        self.stop_reason = ""
        self._mast: dict[tuple[float, float], tuple[float, float]] = {}
        # Rays to uncovered points, for restarts aimed at gaps and for the proof
        # that a gap cannot be seen: always the exact targeted geometry.
        self.probe = (
            self.evaluator
            if isinstance(self.evaluator, CachedTargetedEvaluator)
            else CachedTargetedEvaluator(self.grid, caster)
        )
        ref = reference_footprint_m2(model, settings.grid_m)
        self.min_gain = max(1, round(0.01 * ref / self.grid.cell_area))
        self._result: OptimizationResult | None = None
        # Every fixed sensor adds at least one target point, so without a cap the run
        # still ends after at most one sensor per point.
        self.max_sensors = settings.max_sensors or self.grid.n_targets
        for record in resume:
            self._replay(record)
        # Worker processes evaluate populations in parallel; each builds the same run
        # from a pickled copy (the caster must pickle, as BVHCaster does).
        self._pool: _Pool | None = None
        if workers > 1:
            self._pool = _Pool(workers, (scene, caster, model, settings))

    # --- poses -------------------------------------------------------------------
    def height_at(self, x: float, y: float) -> float:
        """Mast height at local (x, y): the sensor area's ``height_m``, else the model's."""
        for area in self.scene.sensor_areas:
            if area.height_m is not None and shapely.intersects_xy(area.geometry, x, y):
                return area.height_m
        return self.model.mount_height_m

    def pose(self, x: float, y: float, pitch: float, yaw: float) -> SensorPose:
        """The pose at local (x, y) on its mast (ground and height looked up once)."""
        key = (float(x), float(y))
        if key not in self._mast:
            height = self.height_at(*key)
            self._mast[key] = (place(self.grid, *key, height, 0.0, 0.0).z, height)
        z, height = self._mast[key]
        return SensorPose(key[0], key[1], z, height, float(pitch), float(yaw))

    def evaluate(self, pose: SensorPose) -> tuple[SensorCoverage, Any]:
        cov = self.evaluator.evaluate(self.model, pose, outside_band_m=self.settings.fitness.band_m)
        self.sight_rays += cov.rays
        self.evaluations += 1
        return cov, fitness(self.grid, cov, self.fixed, self.settings.fitness)

    def _fitness_of(self, pop: F64) -> Iterator[float]:
        """f_s of each individual (P, 4), in order: here one by one, or by the worker
        processes a batch at a time (same numbers either way: evaluation is exact)."""
        if self._pool is None:
            for ind in pop:
                yield self.evaluate(self.pose(*ind))[1].f_s
            return
        chunks = np.array_split(pop, self._pool.workers)
        futures = [
            self._pool.submit(k, chunk, self._fixed_log)
            for k, chunk in enumerate(chunks)
            if len(chunk)
        ]
        for future in futures:
            fits, rays = future.result()
            self.sight_rays += rays
            self.evaluations += len(fits)
            yield from fits

    def close(self) -> None:
        """Stop the worker processes (also done when the run finishes)."""
        if self._pool is not None:
            self._pool.shutdown()
            self._pool = None

    # --- the run -----------------------------------------------------------------
    @property
    def coverage(self) -> float:
        return self.fixed.n_covered / len(self.fixed.covered)

    def _progress(self, phase: str, epoch: int = 0) -> Progress:
        return Progress(
            phase, len(self.sensors), self.coverage, self.settings.rho, epoch, self.evaluations
        )

    def steps(self) -> Iterator[Progress]:
        """Run to the end, yielding after each evaluation; then ``result()``."""
        s = self.settings
        if s.optimizer == "greedy":
            yield from greedy_steps(self)
            yield from self._wrap_up()
            return
        stale = 0
        while True:
            if self.coverage >= s.rho:
                self.stop_reason = f"reached rho = {s.rho:.0%} of the target"
                break
            if len(self.sensors) >= self.max_sensors:
                self.stop_reason = f"stopped at max_sensors = {self.max_sensors}"
                break
            found = yield from self._search(None)
            if found[2].new_points < self.min_gain:
                # The random start found (almost) nothing new: start again from
                # positions that can see the gaps, first on a coarse lattice, then
                # on every position (which also proves when nothing can).
                aimed = self._gap_population(coarse=True)
                if aimed is None:
                    aimed = self._gap_population(coarse=False)
                if aimed is None:
                    if found[2].new_points == 0:
                        self.stop_reason = (
                            "the rest of the target cannot be seen from any position in "
                            "the sensor areas (line of sight, range, density, pitch limits)"
                        )
                        break
                else:
                    again = yield from self._search(aimed)
                    found = max(found, again, key=lambda f: (f[2].new_points, f[2].f_s))
            pose, cov, fit, epochs, evals = found
            if fit.new_points == 0:
                stale += 1
                if stale >= s.patience:
                    self.stop_reason = (
                        f"{stale} searches in a row added nothing, though parts of the "
                        "rest may be within reach of some position (an upper bound)"
                    )
                    break
                continue
            stale = 0
            self._fix(pose, cov, fit.f_s, epochs, evals)
            yield self._progress("fixed")
        yield from self._wrap_up()

    def _wrap_up(self) -> Iterator[Progress]:
        """After the last sensor: masts, the final full evaluation, the result."""
        self.close()
        yield self._progress("masts")
        masts = self._group_masts()
        yield self._progress("report")
        self._result = self._finish(masts)
        yield self._progress("done")

    def _search(self, initial: F64 | None):
        """One ES for the next sensor (yields progress); returns its best
        (pose, coverage, fitness, epochs, evaluations)."""
        search = SensorSearch(self.space, self.settings.es, self.rng, self._fitness_of)
        for epoch in search.steps(initial):
            yield self._progress("search", epoch)
        assert search.best is not None
        pose = self.pose(*search.best)
        cov, fit = self.evaluate(pose)
        return pose, cov, fit, search.epochs, search.evaluations

    def blind_areas(self, step_every: int = 2) -> list[str]:
        """Sensor areas from whose positions (every ``step_every``-th lattice point,
        and always at least one) no target point can be covered at all."""
        wanted = np.ones(self.grid.n_targets, dtype=bool)
        blind = []
        k = np.round(self.space.positions / self.space.step).astype(int)
        every = (k[:, 0] % step_every == 0) & (k[:, 1] % step_every == 0)
        for area in self.scene.sensor_areas:
            inside = shapely.intersects_xy(area.geometry, *self.space.positions.T)
            probe = self.space.positions[inside & every]
            if len(probe) == 0:
                probe = self.space.positions[inside][:1]
            seen = any(
                len(self.probe.reachable(self.model, self.pose(x, y, 0.0, 0.0), wanted))
                for x, y in probe
            )
            if not seen:
                blind.append(area.name)
        return blind

    def _gap_population(self, coarse: bool) -> F64 | None:
        """(mu, 4) first parents aimed at uncovered target points within reach, or None
        when no probed position reaches any.

        Positions are drawn in proportion to how many uncovered points they might
        cover (``CachedTargetedEvaluator.reachable``); each looks at the centroid of
        those points. ``coarse`` probes every 4th lattice point in x and y.
        """
        positions = self.space.positions
        if coarse:
            k = np.round(positions / self.space.step).astype(int)
            positions = positions[(k[:, 0] % 4 == 0) & (k[:, 1] % 4 == 0)]
        wanted = ~self.fixed.covered
        counts = np.zeros(len(positions))
        aims = np.zeros((len(positions), 2))
        pts = self.grid.target_points
        for i, (x, y) in enumerate(positions):
            pose = self.pose(x, y, self.model.pitch_min_deg, 0.0)
            ords = self.probe.reachable(self.model, pose, wanted)
            counts[i] = len(ords)
            if len(ords):
                v = pts[ords].mean(axis=0) - pose.position
                yaw = math.degrees(math.atan2(v[1], v[0])) % 360.0
                pitch = math.degrees(math.atan2(-v[2], math.hypot(v[0], v[1])))
                aims[i] = (pitch, yaw)
        if counts.sum() == 0:
            return None
        mu = self.settings.es.mu
        pick = self.rng.choice(len(positions), size=mu, p=counts / counts.sum())
        lo, hi = self.model.pitch_min_deg, self.model.pitch_max_deg
        pitch = np.clip(aims[pick, 0] + self.rng.normal(0, 5.0, mu), lo, hi)
        yaw = (aims[pick, 1] + self.rng.normal(0, 15.0, mu)) % 360.0
        return np.column_stack([positions[pick], pitch, yaw])

    def result(self) -> OptimizationResult:
        if self._result is None:
            for _ in self.steps():
                pass
        assert self._result is not None
        return self._result

    def _fix(
        self, pose: SensorPose, cov: SensorCoverage, f_s: float, epochs: int, evals: int
    ) -> None:
        new = self._add(cov)
        self.sensors.append(FixedSensor(pose, f_s, epochs, evals, new))
        if self.on_fixed is not None:
            self.on_fixed(
                {
                    "n": len(self.sensors),
                    "x": pose.x,
                    "y": pose.y,
                    "pitch_deg": pose.pitch_deg,
                    "yaw_deg": pose.yaw_deg,
                    "fitness": f_s,
                    "epochs": epochs,
                    "evaluations": evals,
                    "new_points": new,
                    "coverage": self.coverage,
                    "wall_s": round(time.perf_counter() - self.t0, 3),
                    "rays_cast": self.sight_rays,
                    "evaluations_total": self.evaluations,
                    "rng_state": self.rng.bit_generator.state,
                }
            )

    def _add(self, cov: SensorCoverage) -> int:
        """Fix ``cov``'s sensor in the covered state; returns how many points it adds."""
        newly = self.fixed.add(cov)
        self._fixed_log.append((newly, (cov.pose.x, cov.pose.y)))
        return len(newly)

    def _replay(self, record: dict[str, Any]) -> None:
        """Re-fix a sensor from a checkpoint record and take over its random state."""
        pose = self.pose(record["x"], record["y"], record["pitch_deg"], record["yaw_deg"])
        cov = self.evaluator.evaluate(self.model, pose, outside_band_m=self.settings.fitness.band_m)
        new = self._add(cov)
        self.sensors.append(
            FixedSensor(pose, record["fitness"], record["epochs"], record["evaluations"], new)
        )
        self.rng.bit_generator.state = record["rng_state"]
        # Time, rays and evaluations spent before the interruption still count.
        self.t0 = time.perf_counter() - record.get("wall_s", 0.0)
        self.sight_rays = record.get("rays_cast", self.sight_rays)
        self.evaluations = record.get("evaluations_total", self.evaluations)

    def _group_masts(self) -> list[tuple[float, float, float, float, tuple[int, ...]]]:
        """Group sensors into masts; move members to the chosen site (re-placed)."""
        if not self.sensors:
            return []
        xy = np.array([[s.pose.x, s.pose.y] for s in self.sensors])
        labels = group_positions(xy, self.settings.mast_join_m)

        def cover(i: int, x: float, y: float) -> NDArray[np.int64]:
            s = self.sensors[i]
            pose = self.pose(x, y, s.pose.pitch_deg, s.pose.yaw_deg)
            return self.evaluator.evaluate(self.model, pose).covered

        goal = math.ceil(self.settings.rho * self.grid.n_targets)
        keep = min(self.fixed.n_covered, goal)
        new_xy, labels = choose_sites(xy, labels, cover, self.grid.n_targets, keep)
        masts = []
        for s, (x, y), label in zip(self.sensors, new_xy, labels):
            s.pose = self.pose(x, y, s.pose.pitch_deg, s.pose.yaw_deg)
            s.mast = int(label)
        for label in range(int(labels.max()) + 1):
            members = tuple(int(k) + 1 for k in np.flatnonzero(labels == label))
            first = self.sensors[members[0] - 1].pose
            height = max(self.sensors[m - 1].pose.height_m for m in members)
            masts.append((first.x, first.y, first.z - first.height_m, height, members))
        return masts

    def _finish(self, masts: list) -> OptimizationResult:
        """Final full evaluation (footprints, visibility), metrics and stop report."""
        coverages = [
            self.evaluator.evaluate(self.model, s.pose, outside_band_m=math.inf, visibility=True)
            for s in self.sensors
        ]
        self.sight_rays += sum(c.rays for c in coverages)
        summary = summarize(self.grid, coverages)
        cell = self.grid.cell_area
        target_m2 = self.grid.target_area_m2
        n = len(self.sensors)
        reference = reference_footprint_m2(self.model, self.settings.grid_m)
        footprints = [c.footprint_m2 or 0.0 for c in coverages]
        wall = time.perf_counter() - self.t0
        metrics = {
            "coverage_fraction": round(summary.coverage_fraction, 6),
            "covered_m2": summary.covered_m2,
            "target_area_m2": target_m2,
            "sensors": n,
            "masts": len(masts),
            "cluster_ratio": round(len(masts) / n, 4) if n else None,
            "relative_sensor_coverage": round(float(np.mean(footprints)) / reference, 4)
            if n
            else None,
            "reference_footprint_m2": round(reference, 2),
            "overlap_factor": round(sum(len(c.covered) for c in coverages) * cell / target_m2, 4),
            "mean_epochs_per_sensor": round(float(np.mean([s.epochs for s in self.sensors])), 2)
            if n
            else None,
            "evaluations": self.evaluations,
            "wall_s": round(wall, 2),
            "rays_cast": self.sight_rays + self.grid.drop_rays + self.probe.extra_rays,
        }
        return OptimizationResult(
            scene=self.scene,
            grid=self.grid,
            model=self.model,
            settings=self.settings,
            sensors=self.sensors,
            coverages=coverages,
            summary=summary,
            masts=masts,
            stop_reason=self.stop_reason,
            uncovered=uncovered_parts(self.grid, summary.n_covered == 0, self.scene),
            metrics=metrics,
        )


class _Pool:
    """Worker processes, one executor each so that the run knows which worker takes
    which chunk: each holds its own OptimizationRun of the same inputs and is sent only
    the sensors fixed since its last chunk."""

    def __init__(self, workers: int, inputs: tuple) -> None:
        import multiprocessing
        from concurrent.futures import ProcessPoolExecutor

        spawn = multiprocessing.get_context("spawn")
        self.executors = [
            ProcessPoolExecutor(
                max_workers=1, mp_context=spawn, initializer=_start_worker, initargs=inputs
            )
            for _ in range(workers)
        ]
        self.synced = [0] * workers  # entries of the fixed log each worker has been sent

    @property
    def workers(self) -> int:
        return len(self.executors)

    def submit(self, k: int, pop: F64, fixed_log: list) -> Future:
        """Score ``pop`` (P, 4) on worker ``k``, first bringing its fixed sensors up to date."""
        since = fixed_log[self.synced[k] :]
        self.synced[k] = len(fixed_log)
        return self.executors[k].submit(_score_in_worker, pop, since)

    def shutdown(self) -> None:
        for executor in self.executors:
            executor.shutdown(cancel_futures=True)


_WORKER_RUN: OptimizationRun | None = None


def _start_worker(scene, caster, model, settings) -> None:
    global _WORKER_RUN
    _WORKER_RUN = OptimizationRun(scene, caster, model, settings)


def _score_in_worker(
    pop: F64, fixed_since: list[tuple[NDArray[np.int64], tuple[float, float]]]
) -> tuple[list[float], int]:
    """f_s of each individual once the sensors fixed since the last chunk are marked;
    and the rays cast."""
    run = _WORKER_RUN
    assert run is not None
    for newly, position in fixed_since:
        run.fixed.mark(newly, position)
    before = run.sight_rays
    fits = [run.evaluate(run.pose(*ind))[1].f_s for ind in pop]
    return fits, run.sight_rays - before


def _evaluator(settings: OptimizeSettings, grid: GroundGrid, caster: RayCaster):
    if settings.method == "pointcloud":
        return PointcloudEvaluator(grid, caster, settings.oversample, settings.alpha)
    if settings.cache:
        return CachedTargetedEvaluator(grid, caster)
    return TargetedEvaluator(grid, caster)


def uncovered_parts(
    grid: GroundGrid, uncovered: NDArray[np.bool_], scene: SceneModel, min_m2: float = 0.0
) -> list[dict[str, Any]]:
    """Connected patches of uncovered target points (8-neighbour), largest first.

    Each: the target area's name, m^2, and the patch centroid in world x, y.
    """
    if not uncovered.any():
        return []
    mask = np.zeros(grid.nx * grid.ny, dtype=bool)
    mask[grid.target_cells[uncovered]] = True
    labels, count = ndimage.label(mask.reshape(grid.nx, grid.ny), structure=np.ones((3, 3)))
    flat = labels.ravel()[grid.target_cells]
    parts = []
    for k in range(1, count + 1):
        members = np.flatnonzero(flat == k)
        m2 = len(members) * grid.cell_area
        if m2 < min_m2:
            continue
        cx, cy = scene.to_world(grid.target_xy[members].mean(axis=0))
        region = int(np.bincount(grid.target_region[members]).argmax())
        parts.append(
            {
                "target": scene.targets[region].name,
                "m2": m2,
                "x": round(float(cx), 2),
                "y": round(float(cy), 2),
            }
        )
    parts.sort(key=lambda p: -p["m2"])
    return parts


@lru_cache(maxsize=16)
def reference_footprint_m2(model: SensorModel, grid_m: float = 1.0) -> float:
    """The model's largest footprint on flat, empty ground over its pitch range, m^2
    (the paper's reference for the relative sensor coverage: 1229.95 for its camera).

    Evaluated with ``targeted`` at the given grid spacing, pitch in 1 deg steps.
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
