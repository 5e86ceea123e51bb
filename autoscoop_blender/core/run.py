"""One optimization, end to end: problem -> optimizer -> masts -> result.

``Run.steps()`` is the pipeline as a generator. It builds nothing twice and hands each
stage's output to the next: the ``Problem`` (grid, evaluators, search space, demand)
is built once; the optimizer chosen by the settings (``optimize/``) places sensors on
it and returns a ``Solution``; sensors within ``mast_join_m`` are grouped into masts
(``masts.py``); ``result.finish_layout`` evaluates the final layout in full and hands
back a ``Result`` in world metres, with draped footprints and metrics, that holds no
caster or grid. The sensors fixed so far are evaluated for that report while the
search runs, and so are those of the lp's best plan so far, which it fixes at its end
(``ahead.py``), so that a run stopped early writes its plan in seconds.

The Blender operator time-slices the generator and the CLI draws a progress bar from
it; both drain the same generator, so the same seed gives the same answer everywhere.
After every fixed sensor ``on_fixed`` gets a JSON-ready record with what the optimizer
needs to go on (the ES's random state): a run resumed from those records goes on
exactly as the uninterrupted one would have.
"""

from __future__ import annotations

import logging
import time
from collections.abc import Callable, Iterator, Sequence
from typing import Any

import numpy as np

from .ahead import ReportAhead
from .errors import InputError
from .geom.raycast import RayCaster
from .masts import choose_sites, group_positions
from .model.scene import SceneModel
from .model.sensors import SensorModel, SensorPack, SensorPose, SensorSpec
from .optimize.base import FixedSensor, Optimizer, Progress, Solution, newly_covered
from .optimize.es import EvolutionStrategy
from .optimize.greedy import Greedy
from .optimize.lp import bound_only
from .optimize.parallel import WorkerPool
from .optimize.parts import PartBuilder
from .optimize.planner import LPPlanner
from .problem import Problem
from .result import Provenance, Result, finish_layout
from .settings import OptimizeSettings

log = logging.getLogger(__name__)

# A picklable callable that builds the ray caster (in this process and in workers).
CasterFactory = Callable[[], RayCaster]


class Run:
    """One optimization of ``model`` sensors (or of a ``SensorPack`` of models a plan
    may mix) on a scene (see module docstring).

    make_caster: builds the caster over the scene's occluders (worker processes call
    it too). existing: sensors that stand already (world metres, each of one of the
    run's models): they count toward coverage, are never moved or dropped, cost
    nothing, and their masts carry new sensors for the sensor cost alone. existing_masts: world (x, y)
    of masts that stand with free slots: candidate sites where a new sensor adds no
    mast. Both join the search space. resume: records of sensors
    fixed by an earlier run with the same inputs (as given to ``on_fixed``); the run
    goes on after the last of them. workers: processes that score each ES population
    (same answer). part_builder: where the lp and greedy optimizers build the candidates
    of a ground they plan in parts (None: in this process; ``headless/ray_engine.py``: on
    Ray; same answer).
    """

    def __init__(
        self,
        scene: SceneModel,
        make_caster: CasterFactory,
        model: SensorModel | SensorPack,
        settings: OptimizeSettings,
        resume: Sequence[dict[str, Any]] = (),
        on_fixed: Callable[[dict[str, Any]], None] | None = None,
        workers: int = 1,
        existing: Sequence[SensorSpec] = (),
        existing_masts: Sequence[tuple[float, float]] = (),
        part_builder: PartBuilder | None = None,
    ) -> None:
        self.t0 = time.perf_counter()
        world = [(s.x, s.y) for s in existing] + list(existing_masts)
        standing = scene.to_local(np.array(world, dtype=float).reshape(-1, 2))
        self.problem = Problem(scene, make_caster(), model, settings, workers, standing)
        self.settings = self.problem.settings
        self.on_fixed = on_fixed
        self.solution = Solution(
            np.zeros(self.problem.n_targets, dtype=bool), need=self.problem.need.copy()
        )
        for k, spec in enumerate(existing, start=1):
            self._stand(k, spec)
        for record in resume:
            self._replay(record)
        self.part_builder = part_builder
        self.ahead = ReportAhead(self.problem)
        self._result: Result | None = None
        # Last: the caller closes what it starts (its worker processes) from here on.
        self.optimizer = self._optimizer(make_caster, workers)

    def _optimizer(self, make_caster: CasterFactory, workers: int) -> Optimizer:
        if self.settings.optimizer == "greedy":
            return Greedy(self.part_builder)
        if self.settings.optimizer == "lp":
            return LPPlanner(self.part_builder)
        pool = None
        if workers > 1:
            pool = WorkerPool(self.problem.worker_inputs(), make_caster, workers)
        return EvolutionStrategy(pool)

    @property
    def sensors(self) -> list[FixedSensor]:
        """The sensors fixed so far (local poses), in order."""
        return self.solution.sensors

    def blind_areas(self) -> list[str]:
        """Sensor areas that see no target point (``Problem.blind_areas``)."""
        return self.problem.blind_areas()

    def steps(self) -> Iterator[Progress]:
        """Run to the end, yielding progress; then ``result()``."""
        rho = self.problem.rho
        solve = self.optimizer.solve(self.problem, self.solution)
        try:
            while True:
                try:
                    progress = next(solve)
                except StopIteration:
                    break
                if progress.fixed is not None and self.on_fixed is not None:
                    self.on_fixed(self._record(progress.fixed))
                yield progress
                self.ahead.warm(
                    self.solution.sensors, time.perf_counter() - self.t0, self.solution.ahead
                )
        finally:
            solve.close()
            self.close()
        if self.settings.bound and self.solution.bound is None:
            self.solution.bound = yield from bound_only(self.problem, self.solution)
        yield self.solution.progress("masts", rho)
        poses, mast_of = self._masts()
        yield self.solution.progress("report", rho)
        self._result = self._finish(poses, mast_of)
        yield self.solution.progress("done", rho)

    def result(self) -> Result:
        if self._result is None:
            for _ in self.steps():
                pass
        assert self._result is not None
        return self._result

    def close(self) -> None:
        """Stop any worker processes (also done when the search ends)."""
        self.optimizer.close()

    def stop_early(self) -> bool:
        """Ask the optimizer to end its search now and keep the best plan so far;
        False when it cannot (then only cancelling stops it)."""
        stop = getattr(self.optimizer, "stop_early", None)
        if stop is None:
            return False
        stop()
        return True

    # --- checkpoints ---------------------------------------------------------------
    def _record(self, sensor: FixedSensor) -> dict[str, Any]:
        s = self.solution
        return {
            "n": len(s.sensors),
            "x": sensor.pose.x,
            "y": sensor.pose.y,
            "pitch_deg": sensor.pose.pitch_deg,
            "yaw_deg": sensor.pose.yaw_deg,
            "fitness": sensor.fitness,
            "epochs": sensor.epochs,
            "evaluations": sensor.evaluations,
            "new_points": sensor.new_points,
            "model": sensor.model,
            "coverage": s.coverage,
            "wall_s": round(time.perf_counter() - self.t0, 3),
            "rays_cast": s.sight_rays,
            "evaluations_total": s.evaluations,
            **s.state,
        }

    def _stand(self, k: int, spec: SensorSpec) -> None:
        """Fix existing sensor ``k`` where it stands: its height as given (``height_m``,
        else its absolute ``z``, else the sensor area's or the model's)."""
        p = self.problem
        if spec.model not in p.models:
            raise InputError(
                f"existing sensor {k} at ({spec.x:g}, {spec.y:g}): its model is not one "
                "of the run's; give existing sensors a model being planned"
            )
        model = p.models.index(spec.model)
        x, y = (float(v) for v in p.scene.to_local(np.array([spec.x, spec.y])))
        ground = float(p.grid.ground_z(np.array([[x, y]]))[0])
        height = spec.height_m
        if height is None and spec.z is not None:
            height = spec.z - p.scene.origin[2] - ground
        if height is None:
            height = p.height_at(x, y, model)
        pose = SensorPose(x, y, ground + height, height, spec.pitch_deg, spec.yaw_deg)
        cov = p.evaluate(pose, model=model)
        self.solution.sight_rays += cov.rays
        newly = newly_covered(self.solution, cov.covered)
        self.solution.fix(
            FixedSensor(pose, 0.0, 0, 0, newly, cov.covered, existing=True, model=model)
        )

    def _replay(self, record: dict[str, Any]) -> None:
        """Re-fix a sensor from a checkpoint record and take over the optimizer's state."""
        p = self.problem
        model = int(record.get("model", 0))
        pose = p.pose(record["x"], record["y"], record["pitch_deg"], record["yaw_deg"], model)
        cov = p.evaluate(pose, model=model)
        newly = newly_covered(self.solution, cov.covered)
        self.solution.fix(
            FixedSensor(
                pose,
                record["fitness"],
                record["epochs"],
                record["evaluations"],
                newly,
                cov.covered,
                model=model,
            )
        )
        self.solution.state = {k: record[k] for k in ("rng_state",) if k in record}
        # Time, rays and evaluations spent before the interruption still count.
        self.t0 = time.perf_counter() - record.get("wall_s", 0.0)
        self.solution.sight_rays = record.get("rays_cast", self.solution.sight_rays)
        self.solution.evaluations = record.get("evaluations_total", self.solution.evaluations)

    # --- after the optimizer -------------------------------------------------------
    def _masts(self) -> tuple[list[SensorPose], list[int]]:
        """Sensors grouped into masts: their poses moved to the chosen sites, and each
        one's mast label."""
        p, sensors = self.problem, self.solution.sensors
        if not sensors:
            return [], []
        xy = np.array([[s.pose.x, s.pose.y] for s in sensors])
        labels = group_positions(xy, self.settings.mast_join_m)

        def cover(i: int, x: float, y: float) -> np.ndarray:
            s = sensors[i]
            pose = p.pose(x, y, s.pose.pitch_deg, s.pose.yaw_deg, s.model)
            if pose == s.pose and s.seen is not None:  # as evaluated when it was fixed
                return s.seen
            return p.evaluate(pose, model=s.model).covered

        keep = min(self.solution.n_covered, p.goal)
        existing = np.array([s.existing for s in sensors])
        new_xy, labels = choose_sites(
            xy, labels, cover, p.n_targets, keep, p.need, existing,
            cap=self.settings.max_sensors_per_mast,
        )  # fmt: skip
        poses = [
            p.pose(x, y, s.pose.pitch_deg, s.pose.yaw_deg, s.model)
            for s, (x, y) in zip(sensors, new_xy)
        ]
        return poses, [int(label) for label in labels]

    def _finish(self, poses: list[SensorPose], mast_of: list[int]) -> Result:
        """The final full evaluation of every sensor, and the result."""
        p, s = self.problem, self.solution
        ready = sum(self.ahead.ready(pose, f.model) for pose, f in zip(poses, s.sensors))
        log.info(
            "report: %d of %d sensors evaluated ahead, in %.1f s of work ahead",
            ready, len(poses), self.ahead.spent_s,
        )  # fmt: skip
        done = [self.ahead.get(pose, f.model) for pose, f in zip(poses, s.sensors)]
        coverages = [cov for cov, _ in done]
        how = Provenance(
            t0=self.t0,
            fitness=[f.fitness for f in s.sensors],
            epochs=[f.epochs for f in s.sensors],
            evaluations=s.evaluations,
            sight_rays=s.sight_rays,
            stop_reason=s.stop_reason,
            warnings=p.scene.warnings,
            settings=self.settings,
            model=p.model,
            pack=p.pack if p.pack.mixed else None,
            sensor_costs=[float(p.sensor_costs[f.model]) for f in s.sensors],
            bound=s.bound,
            existing=[f.existing for f in s.sensors],
            standing=p.space.positions[p.space.standing],
        )
        return finish_layout(
            p.scene, p.grid, coverages, mast_of, how, p.probe.extra_rays, need=p.need,
            pieces=[pieces for _, pieces in done],
        )  # fmt: skip
