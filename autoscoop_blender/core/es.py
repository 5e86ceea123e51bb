"""The paper's evolution strategy for one sensor (Algorithm 1, inner loop).

An individual is a pose ``(x, y, pitch, yaw)``: local metres and degrees. Per epoch:

1. reproduction: lambda offspring copy parents drawn at random (with replacement);
2. mutation: offspring get Gaussian steps of width sigma_lambda(t), and the parents
   themselves get steps of width sigma_mu(t) (Algorithm 1 mutates both);
3. saturation: a step that leaves the sensor areas is retried with half the width,
   up to ``retries`` times, then dropped (the position stays); pitch is clipped to
   the model's limits; yaw wraps around;
4. evaluation of all mu + lambda individuals, and selection of the best mu as the
   next parents.

Termination (the paper's epsilon_sensor): the parents have converged when
``(f_best - f_worst) / f_best <= eps`` (0.2, Table II), or at ``max_epochs``. The
result is the best individual seen in any epoch (parents are mutated too, so the
best of the last epoch need not be the best ever).

Choices where the paper is silent: sigma(t) = sigma(0) * decay^t with sigma(0) =
(4 m, 4 m, 5 deg, 30 deg) for offspring and half that for parents (offspring explore,
parents refine), decay 0.93 per epoch; positions live on a lattice (default 2 m, see
``OptimizeSettings.position_step_m``) so that a revisited mast position reuses its
cached sight lines and the reported pose is exactly the evaluated one.
"""

from __future__ import annotations

from collections.abc import Callable, Iterable, Iterator
from dataclasses import dataclass

import numpy as np
import shapely
from numpy.typing import NDArray
from shapely.geometry.base import BaseGeometry

F64 = NDArray[np.float64]


@dataclass(frozen=True)
class ESParams:
    """Population sizes (Table II), convergence and mutation widths."""

    mu: int = 40
    lam: int = 20
    eps: float = 0.2
    max_epochs: int = 100
    sigma_xy_m: float = 4.0
    sigma_pitch_deg: float = 5.0
    sigma_yaw_deg: float = 30.0
    parent_sigma: float = 0.5
    decay: float = 0.93
    retries: int = 5

    def sigma(self, epoch: int) -> F64:
        """(4,) offspring mutation widths in epoch ``epoch`` (1-based)."""
        s0 = np.array([self.sigma_xy_m, self.sigma_xy_m, self.sigma_pitch_deg, self.sigma_yaw_deg])
        return s0 * self.decay ** (epoch - 1)


class SearchSpace:
    """Where a sensor may stand and how it may point.

    positions: (K, 2) the lattice points (spacing ``step_m``) inside the sensor areas,
    plus one point for any area too small to hold a lattice point. Pitch in
    [pitch_min, pitch_max] degrees; yaw in [0, 360).
    """

    def __init__(
        self,
        areas: list[BaseGeometry],
        step_m: float,
        pitch_min_deg: float,
        pitch_max_deg: float,
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
        self.positions = np.unique(np.concatenate(parts), axis=0)
        self._index = {self._key(x, y): k for k, (x, y) in enumerate(self.positions)}

    def _key(self, x: float, y: float) -> tuple[int, int]:
        return (int(round(x / self.step)), int(round(y / self.step)))

    def _member(self, x: float, y: float) -> bool:
        k = self._index.get(self._key(x, y))
        return k is not None and bool(np.all(self.positions[k] == (x, y)))

    def sample(self, n: int, rng: np.random.Generator) -> F64:
        """(n, 4) random individuals: positions uniform over the lattice."""
        pos = self.positions[rng.integers(0, len(self.positions), n)]
        pitch = rng.uniform(*self.pitch, n)
        yaw = rng.uniform(0.0, 360.0, n)
        return np.column_stack([pos, pitch, yaw])

    def mutate(self, pop: F64, sigma: F64, retries: int, rng: np.random.Generator) -> F64:
        """(P, 4) mutated copies of ``pop`` with saturation at the borders."""
        out = pop.copy()
        for row in out:
            scale = 1.0
            for _ in range(retries + 1):
                step = rng.normal(0.0, sigma[:2] * scale)
                x, y = self._snap(row[0] + step[0], row[1] + step[1])
                if self._member(x, y):
                    row[0], row[1] = x, y
                    break
                scale *= 0.5  # saturate: retry with half the width
        out[:, 2] = np.clip(out[:, 2] + rng.normal(0.0, sigma[2], len(out)), *self.pitch)
        out[:, 3] = (out[:, 3] + rng.normal(0.0, sigma[3], len(out))) % 360.0
        return out

    def _snap(self, x: float, y: float) -> tuple[float, float]:
        return (round(x / self.step) * self.step, round(y / self.step) * self.step)


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
        parents = self.space.sample(p.mu, self.rng) if initial is None else initial
        fit = []
        for f in self._score(parents):
            fit.append(f)
            yield 0
        parent_fit = np.array(fit)
        while self.epochs < p.max_epochs and not self.converged(parent_fit):
            self.epochs += 1
            sigma = p.sigma(self.epochs)
            kids = parents[self.rng.integers(0, p.mu, p.lam)]
            kids = self.space.mutate(kids, sigma, p.retries, self.rng)
            moved = self.space.mutate(parents, sigma * p.parent_sigma, p.retries, self.rng)
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
