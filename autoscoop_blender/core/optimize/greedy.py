"""Greedy set cover over the candidate set: beyond the paper, fewer sensors.

While the goal is not met, the candidate (``core/candidates.py``) that covers the most
target points still below their k (multicover: with k = 1, the uncovered ones) per
its model's cost (with the ``cost`` objective and a pack of models of different
costs; else per sensor) is fixed, each candidate at most once, except that one
standing on a mast already used wins if it adds at least 1 / (1 + p) of the best,
p = MAST_PREFERENCE of the objective (for cost at 1: half the best; fewer masts for
part of one sensor's coverage). A mast carrying ``max_sensors_per_mast`` new sensors
takes no more (sensors that stood already do not count against it). Greedy set cover
needs at most about ln(N) times the optimum number of the same candidates (N target
points). Deterministic: the seed plays no part.

A ground too large for one candidate matrix is covered in parts, as lp's is
(``parts.py``): the same parts, each its candidates over its own points, each part's
sensors fixed before the next part's matrix is built, so the memory follows the
largest part.
"""

from __future__ import annotations

import math
from collections.abc import Generator
from dataclasses import replace

import numpy as np
from numpy.typing import NDArray

from ..candidates import CandidateSet, sensor_price
from ..problem import Problem
from .base import (
    Progress,
    Solution,
    StopReason,
    T,
    building,
    candidates_of,
    fix_candidate,
    taken_candidates,
)
from .bound import parts_of
from .parts import LocalBuilder, PartBuilder, prune

I64 = NDArray[np.int64]

# Per objective: a candidate on a mast already used wins against a new mast that adds
# up to this fraction more (0: only on ties). ``bench constants`` (2026-11-23; two_routes,
# full_ground's tiles 1-2 and tile 3, FlexZoneCrossing): cost is lowest on average at 1
# (within 2.1 % of each scene's best; 0.1 costs up to 13 % more); no value has the fewest
# sensors everywhere, and 0.1 has them on 3 of the 4 with far fewer masts than 0; the
# masts keep falling as it rises (no optimum up to 100, the sensors rising fast), so
# they take the cost's value.
MAST_PREFERENCE = {"cost": 1.0, "sensors": 0.1, "masts": 1.0}


def pick_candidate(
    gains: NDArray[np.float32], on_mast: NDArray[np.bool_], objective: str = "cost"
) -> int:
    """Index of the candidate to fix: the largest gain (new target points), where a
    candidate on a mast already used counts ``1 + MAST_PREFERENCE[objective]`` times;
    the first on ties."""
    p = MAST_PREFERENCE[objective]
    return int(np.argmax(gains * np.where(on_mast, 1.0 + p, 1.0)))


class Greedy:
    """Greedy set cover as an optimizer (see the module docstring). A ground that the
    problem's estimate splits (``budget.part_count``) is covered part by part with one
    part's candidates held at a time (built by ``builder``; default here,
    ``parts.LocalBuilder``): each part's sensors are fixed before the next part's
    candidates are built, then those the seams made redundant are dropped
    (``parts.prune``)."""

    name = "greedy"

    def __init__(self, builder: PartBuilder | None = None) -> None:
        self.builder = builder

    def close(self) -> None:
        pass

    def solve(self, problem: Problem, solution: Solution) -> Generator[Progress, None, Solution]:
        if problem.estimate.parts > 1:
            return (yield from self._in_parts(problem, solution, problem.estimate.parts))
        cands = yield from candidates_of(problem, solution)
        if len(cands) == 0:
            solution.stop_reason = StopReason.out_of_sight("candidate pose")
            return solution
        every = np.arange(problem.n_targets, dtype=np.int64)
        short_of = yield from cover(problem, solution, cands, every, problem.goal)
        solution.stop_reason = short_of or StopReason.reached(problem.rho)
        return solution

    def _in_parts(
        self, problem: Problem, solution: Solution, n_parts: int
    ) -> Generator[Progress, None, Solution]:
        part_of = parts_of(problem.grid.target_xy, n_parts)
        builder = self.builder or LocalBuilder()
        reach_m = max(m.range_m for m in problem.models)
        builder.start(problem, [np.flatnonzero(part_of == k) for k in range(n_parts)], reach_m)
        short_of = None
        carry = 0  # points the parts so far fell short of: the next part's to cover
        try:
            for k in range(n_parts):
                # Each part covers rho of its own points (what covers them already
                # counts) and what the parts before fell short of, as lp's parts do:
                # a resumed run skips the parts it finished.
                points = np.flatnonzero(part_of == k)
                want = math.ceil(problem.rho * len(points)) + carry
                if np.count_nonzero(solution.covered[points]) >= want:
                    carry = 0
                    continue
                part = yield from _as_part(
                    building(builder.build(k), problem, solution), k, n_parts
                )
                assert part is not None  # nothing stops the build
                short_of = yield from _as_part(
                    cover(problem, solution, part.cands, points, want), k, n_parts
                )
                del part  # its matrix goes before the next part's is built
                carry = max(0, want - int(np.count_nonzero(solution.covered[points])))
                if len(solution.sensors) >= problem.max_sensors:
                    break
        finally:
            builder.close()
        dropped = prune(problem, solution)
        if problem.reached(solution.n_covered):
            solution.stop_reason = StopReason.reached(problem.rho)
        else:
            solution.stop_reason = short_of or StopReason.out_of_sight("candidate pose")
        if dropped:
            solution.stop_reason += f" {dropped} sensor(s) the parts' seams made redundant dropped."
        return solution


def _as_part(
    gen: Generator[Progress, None, T], k: int, n_parts: int
) -> Generator[Progress, None, T]:
    """``gen``'s value, its progress reported as in part k (0-based) of ``n_parts``."""
    try:
        while True:
            try:
                p = next(gen)
            except StopIteration as done:
                value: T = done.value
                return value
            yield replace(p, part=k + 1, parts=n_parts)
    finally:
        gen.close()


def cover(
    problem: Problem, solution: Solution, cands: CandidateSet, points: I64, want: int
) -> Generator[Progress, None, str | None]:
    """Fix candidates of ``cands`` (matrix columns: the target ordinals ``points``)
    the greedy way until ``want`` of those points are covered to their k. Returns
    None then, else why it stopped short (the sensor limit; no candidate adds a
    point)."""
    rho = problem.rho
    index = {(float(x), float(y)): i for i, (x, y) in enumerate(cands.positions)}
    used = problem.space.standing.copy()  # masts that stand already are in use
    load = np.zeros(len(cands.positions), dtype=np.int64)  # new sensors per mast
    cap = problem.settings.max_sensors_per_mast
    for s in solution.sensors:
        if (s.pose.x, s.pose.y) in index:
            used[index[(s.pose.x, s.pose.y)]] = True
            load[index[(s.pose.x, s.pose.y)]] += not s.existing
    column = np.full(problem.n_targets, -1, dtype=np.int64)  # a point's matrix column
    column[points] = np.arange(len(points))
    done = int(np.count_nonzero(solution.covered[points]))
    by_point = cands.matrix.tocsc()  # which candidates cover a point: for the updates
    gains = cands.matrix @ solution.short()[points].astype(np.float32)
    # A candidate is a pose: fixed once at most (with k > 1 it may still gain).
    taken = taken_candidates(cands, solution.sensors)
    gains[taken] = -1.0
    gains[load[cands.position] >= cap] = -1.0
    price = sensor_price(problem, cands) if problem.settings.objective == "cost" else 1.0
    # Per cost only when the costs differ: equal costs pick as the count does.
    per = np.maximum(np.asarray(price, dtype=np.float32), 1e-9) if np.ndim(price) else None
    while done < want:
        if len(solution.sensors) >= problem.max_sensors:
            return StopReason.sensor_limit(problem.max_sensors)
        if float(gains.max(initial=0.0)) <= 0:
            return StopReason.out_of_sight("candidate pose")
        value = gains if per is None else np.where(gains > 0, gains / per, gains)
        pick = pick_candidate(value, used[cands.position], problem.settings.objective)
        sensor = fix_candidate(problem, solution, cands, pick)
        # A point covered to its k now adds nothing to any candidate any more.
        newly = column[sensor.newly]
        newly = newly[newly >= 0]
        done += len(newly)
        gains -= np.asarray(by_point[:, newly].sum(axis=1)).ravel()
        gains[pick] = -1.0
        site = cands.position[pick]
        used[site] = True
        load[site] += 1
        if load[site] >= cap:
            gains[cands.position == site] = -1.0
        yield solution.progress("fixed", rho, fixed=sensor)
    return None
