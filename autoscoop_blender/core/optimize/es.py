"""The paper's optimizer: a sequential evolution strategy (Algorithm 1).

Outer loop (``EvolutionStrategy``): sensors are fixed one at a time, each the best
individual of one ES, until rho of the target is covered; masts come after it (the
run's next stage).

Inner loop (``SensorSearch``): an individual is a pose ``(x, y, pitch, yaw)``, local
metres and degrees. Per epoch:

1. reproduction: lambda offspring copy parents drawn at random (with replacement);
2. mutation: offspring get Gaussian steps of width sigma_lambda(t), and the parents
   themselves get steps of width sigma_mu(t) (Algorithm 1 mutates both);
3. saturation: a step that leaves the sensor areas is retried with half the width,
   up to ``retries`` times, then dropped (the position stays); pitch is clipped to
   the model's limits; yaw wraps around;
4. evaluation of all mu + lambda individuals with the fitness of Eq. 1-5
   (``fitness.py``), and selection of the best mu as the next parents.

Termination (the paper's epsilon_sensor): the parents have converged when
``(f_best - f_worst) / f_best <= eps`` (0.2, Table II), or at ``max_epochs``. The
result is the best individual seen in any epoch (parents are mutated too, so the
best of the last epoch need not be the best ever).

Choices where the paper is silent: sigma(t) = sigma(0) * decay^t with sigma(0) =
(4 m, 4 m, 5 deg, 30 deg) for offspring and half that for parents (offspring explore,
parents refine), decay 0.93 per epoch; positions live on a lattice (default 2 m, see
``OptimizeSettings.position_step_m``) so that a revisited mast position reuses its
cached sight lines and the reported pose is exactly the evaluated one.

Stop rules: the goal is met; or ``patience`` searches in a row find no pose that adds
a single target point; or ``max_sensors``. When a random start adds (almost) nothing,
the search restarts once from positions that can see the remaining gaps (the paper
names closing gaps as its open problem); when no position can, the run stops and
says so.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Generator, Iterable, Iterator

import numpy as np
from numpy.typing import NDArray

from ..coverage.base import SensorCoverage
from ..coverage.reference import reference_footprint_m2
from ..model.sensors import SensorPose
from ..problem import Problem, SearchSpace
from ..settings import ESParams
from .base import FixedSensor, Progress, Solution, StopReason
from .fitness import Fitness, FixedSensors, fitness
from .parallel import FixedMark, WorkerPool

F64 = NDArray[np.float64]

# One search's best: (pose, coverage, fitness, epochs, evaluations).
Found = tuple[SensorPose, SensorCoverage, Fitness, int, int]


def sample(space: SearchSpace, n: int, rng: np.random.Generator) -> F64:
    """(n, 4) random individuals: positions uniform over the lattice."""
    pos = space.positions[rng.integers(0, len(space.positions), n)]
    pitch = rng.uniform(*space.pitch, n)
    yaw = rng.uniform(0.0, 360.0, n)
    return np.column_stack([pos, pitch, yaw])


def mutate(space: SearchSpace, pop: F64, sigma: F64, retries: int, rng: np.random.Generator) -> F64:
    """(P, 4) mutated copies of ``pop`` with saturation at the borders."""
    out = pop.copy()
    for row in out:
        scale = 1.0
        for _ in range(retries + 1):
            step = rng.normal(0.0, sigma[:2] * scale)
            x, y = space.snap(row[0] + step[0], row[1] + step[1])
            if space.member(x, y):
                row[0], row[1] = x, y
                break
            scale *= 0.5  # saturate: retry with half the width
    out[:, 2] = np.clip(out[:, 2] + rng.normal(0.0, sigma[2], len(out)), *space.pitch)
    out[:, 3] = (out[:, 3] + rng.normal(0.0, sigma[3], len(out))) % 360.0
    return out


class SensorSearch:
    """One sensor's ES, driven one evaluation at a time (see module docstring).

    ``evaluate(population (P, 4))`` yields the P fitness values in order, lazily: one
    evaluation per value when run in this process, or a whole batch at once when the
    caller farms them out. After ``steps()`` is exhausted, ``best``, ``best_fitness``
    and ``epochs`` hold the answer.
    """

    def __init__(
        self,
        space: SearchSpace,
        params: ESParams,
        rng: np.random.Generator,
        evaluate: Callable[[F64], Iterable[float]],
    ) -> None:
        self.space = space
        self.params = params
        self.rng = rng
        self.evaluate = evaluate
        self.best: F64 | None = None
        self.best_fitness = -np.inf
        self.epochs = 0
        self.evaluations = 0

    def _score(self, pop: F64) -> Iterator[float]:
        for ind, f in zip(pop, self.evaluate(pop)):
            self.evaluations += 1
            if f > self.best_fitness:
                self.best_fitness, self.best = f, ind.copy()
            yield f

    def steps(self, initial: F64 | None = None) -> Iterator[int]:
        """Run the search; yields the epoch number after every evaluation.

        ``initial`` (mu, 4): the first parents; default: random (the paper's).
        """
        p = self.params
        parents = sample(self.space, p.mu, self.rng) if initial is None else initial
        fit = []
        for f in self._score(parents):
            fit.append(f)
            yield 0
        parent_fit = np.array(fit)
        while self.epochs < p.max_epochs and not self.converged(parent_fit):
            self.epochs += 1
            sigma = p.sigma(self.epochs)
            kids = parents[self.rng.integers(0, p.mu, p.lam)]
            kids = mutate(self.space, kids, sigma, p.retries, self.rng)
            moved = mutate(self.space, parents, sigma * p.parent_sigma, p.retries, self.rng)
            pool = np.vstack([moved, kids])
            fit = []
            for f in self._score(pool):
                fit.append(f)
                yield self.epochs
            order = np.argsort(-np.array(fit), kind="stable")[: p.mu]
            parents, parent_fit = pool[order], np.array(fit)[order]

    def converged(self, parent_fit: F64) -> bool:
        """The paper's epsilon_sensor: relative spread of the parents' fitness."""
        best, worst = float(parent_fit.max()), float(parent_fit.min())
        if best <= 0.0:
            return True  # nothing to gain anywhere: no gradient to follow
        return (best - worst) / best <= self.params.eps


class EvolutionStrategy:
    """The paper's sequential ES as an optimizer (see the module docstring).

    pool: worker processes that score each population (same answer; progress then
    comes a chunk at a time), or None to score here.
    """

    name = "es"

    def __init__(self, pool: WorkerPool | None = None) -> None:
        self.pool = pool

    def close(self) -> None:
        if self.pool is not None:
            self.pool.shutdown()
            self.pool = None

    def solve(self, problem: Problem, solution: Solution) -> Generator[Progress, None, Solution]:
        self.problem, self.solution = problem, solution
        s = problem.settings
        self.params = s.fitness
        self.rng = np.random.default_rng(s.seed)
        if "rng_state" in solution.state:
            self.rng.bit_generator.state = solution.state["rng_state"]
        # The fitness state, and the same as marks for the workers to catch up with.
        self.fixed = FixedSensors(np.zeros(problem.n_targets, dtype=bool), need=problem.need)
        self.log: list[FixedMark] = []
        for sensor in solution.sensors:
            self._mark(sensor.newly if sensor.seen is None else sensor.seen, sensor.pose)
        ref = reference_footprint_m2(problem.model, s.grid_m)
        min_gain = max(1, round(0.01 * ref / problem.grid.cell_area))
        stale = 0
        try:
            while True:
                if problem.reached(solution.n_covered):
                    solution.stop_reason = StopReason.reached(s.rho)
                    break
                if len(solution.sensors) >= problem.max_sensors:
                    solution.stop_reason = StopReason.sensor_limit(problem.max_sensors)
                    break
                found = yield from self._search(None)
                if found[2].new_points < min_gain:
                    # The random start found (almost) nothing new: start again from
                    # positions that can see the gaps, first on a coarse lattice, then
                    # on every position (which also proves when nothing can).
                    aimed = self._gap_population(coarse=True)
                    if aimed is None:
                        aimed = self._gap_population(coarse=False)
                    if aimed is None:
                        if found[2].new_points == 0:
                            solution.stop_reason = StopReason.out_of_sight(
                                "position in the sensor areas"
                            )
                            break
                    else:
                        again = yield from self._search(aimed)
                        found = max(found, again, key=lambda f: (f[2].new_points, f[2].f_s))
                pose, cov, fit, epochs, evals = found
                if fit.new_points == 0:
                    stale += 1
                    if stale >= s.patience:
                        solution.stop_reason = StopReason.gave_up(stale)
                        break
                    continue
                stale = 0
                newly = self.fixed.add(cov)
                self.log.append((cov.covered, (pose.x, pose.y)))
                sensor = FixedSensor(pose, fit.f_s, epochs, evals, newly, cov.covered)
                solution.fix(sensor)
                solution.state = {"rng_state": self.rng.bit_generator.state}
                yield solution.progress("fixed", s.rho, fixed=sensor)
        finally:
            self.close()
        return solution

    def _mark(self, seen: NDArray[np.int64], pose: SensorPose) -> None:
        self.fixed.mark(seen, (pose.x, pose.y))
        self.log.append((seen, (pose.x, pose.y)))

    def _evaluate(self, pose: SensorPose) -> tuple[SensorCoverage, Fitness]:
        cov = self.problem.evaluate(pose, self.params.band_m)
        self.solution.sight_rays += cov.rays
        self.solution.evaluations += 1
        return cov, fitness(self.problem.grid, cov, self.fixed, self.params)

    def _fitness_of(self, pop: F64) -> Iterator[float]:
        """f_s of each individual (P, 4), in order: here one by one, or by the worker
        processes a chunk at a time (same numbers either way: evaluation is exact)."""
        if self.pool is None:
            for ind in pop:
                yield self._evaluate(self.problem.pose(*ind))[1].f_s
            return
        chunks = np.array_split(pop, self.pool.workers)
        futures = [
            self.pool.submit(k, [self.problem.pose(*ind) for ind in chunk], self.log)
            for k, chunk in enumerate(chunks)
            if len(chunk)
        ]
        for future in futures:
            fits, rays = future.result()
            self.solution.sight_rays += rays
            self.solution.evaluations += len(fits)
            yield from fits

    def _search(self, initial: F64 | None) -> Generator[Progress, None, Found]:
        """One ES for the next sensor (yields progress); returns its best."""
        rho = self.problem.rho
        search = SensorSearch(
            self.problem.space, self.problem.settings.es, self.rng, self._fitness_of
        )
        for epoch in search.steps(initial):
            yield self.solution.progress("search", rho, epoch)
        assert search.best is not None
        pose = self.problem.pose(*search.best)
        cov, fit = self._evaluate(pose)
        return pose, cov, fit, search.epochs, search.evaluations

    def _gap_population(self, coarse: bool) -> F64 | None:
        """(mu, 4) first parents aimed at uncovered target points within reach, or None
        when no probed position reaches any.

        Positions are drawn in proportion to how many uncovered points they might
        cover (``Problem.reachable``); each looks at the centroid of those points.
        ``coarse`` probes every 4th lattice point in x and y.
        """
        problem = self.problem
        positions = problem.space.positions
        if coarse:
            positions = positions[problem.space.every(4)]
        wanted = self.fixed.short
        counts = np.zeros(len(positions))
        aims = np.zeros((len(positions), 2))
        pts = problem.grid.target_points
        model = problem.model
        for i, (x, y) in enumerate(positions):
            pose = problem.pose(x, y, model.pitch_min_deg, 0.0)
            ords = problem.reachable(pose, wanted)
            counts[i] = len(ords)
            if len(ords):
                v = pts[ords].mean(axis=0) - pose.position
                yaw = math.degrees(math.atan2(v[1], v[0])) % 360.0
                pitch = math.degrees(math.atan2(-v[2], math.hypot(v[0], v[1])))
                aims[i] = (pitch, yaw)
        if counts.sum() == 0:
            return None
        mu = problem.settings.es.mu
        pick = self.rng.choice(len(positions), size=mu, p=counts / counts.sum())
        lo, hi = model.pitch_min_deg, model.pitch_max_deg
        pitch = np.clip(aims[pick, 0] + self.rng.normal(0, 5.0, mu), lo, hi)
        yaw = (aims[pick, 1] + self.rng.normal(0, 15.0, mu)) % 360.0
        return np.column_stack([positions[pick], pitch, yaw])
