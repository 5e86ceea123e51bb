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
"""

from __future__ import annotations

from collections.abc import Generator

import numpy as np
from numpy.typing import NDArray

from ..candidates import sensor_price
from ..problem import Problem
from .base import Progress, Solution, StopReason, candidates_of, fix_candidate, taken_candidates

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
    """Greedy set cover as an optimizer (see the module docstring)."""

    name = "greedy"

    def close(self) -> None:
        pass

    def solve(self, problem: Problem, solution: Solution) -> Generator[Progress, None, Solution]:
        rho = problem.rho
        cands = yield from candidates_of(problem, solution)
        if len(cands) == 0:
            solution.stop_reason = StopReason.out_of_sight("candidate pose")
            return solution
        index = {(float(x), float(y)): i for i, (x, y) in enumerate(cands.positions)}
        used = problem.space.standing.copy()  # masts that stand already are in use
        load = np.zeros(len(cands.positions), dtype=np.int64)  # new sensors per mast
        cap = problem.settings.max_sensors_per_mast
        for s in solution.sensors:
            if (s.pose.x, s.pose.y) in index:
                used[index[(s.pose.x, s.pose.y)]] = True
                load[index[(s.pose.x, s.pose.y)]] += not s.existing
        by_point = cands.matrix.tocsc()  # which candidates cover a point: for the updates
        gains = cands.matrix @ solution.short().astype(np.float32)
        # A candidate is a pose: fixed once at most (with k > 1 it may still gain).
        taken = taken_candidates(cands, solution.sensors)
        gains[taken] = -1.0
        gains[load[cands.position] >= cap] = -1.0
        price = sensor_price(problem, cands) if problem.settings.objective == "cost" else 1.0
        # Per cost only when the costs differ: equal costs pick as the count does.
        per = np.maximum(np.asarray(price, dtype=np.float32), 1e-9) if np.ndim(price) else None
        while not problem.reached(solution.n_covered):
            if len(solution.sensors) >= problem.max_sensors:
                solution.stop_reason = StopReason.sensor_limit(problem.max_sensors)
                return solution
            if float(gains.max()) <= 0:
                solution.stop_reason = StopReason.out_of_sight("candidate pose")
                return solution
            value = gains if per is None else np.where(gains > 0, gains / per, gains)
            pick = pick_candidate(value, used[cands.position], problem.settings.objective)
            sensor = fix_candidate(problem, solution, cands, pick)
            # A point covered to its k now adds nothing to any candidate any more.
            gains -= np.asarray(by_point[:, sensor.newly].sum(axis=1)).ravel()
            gains[pick] = -1.0
            site = cands.position[pick]
            used[site] = True
            load[site] += 1
            if load[site] >= cap:
                gains[cands.position == site] = -1.0
            yield solution.progress("fixed", rho, fixed=sensor)
        solution.stop_reason = StopReason.reached(rho)
        return solution
