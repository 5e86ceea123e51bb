"""The ``lp`` optimizer: the whole ground at once (``lp.py``) or, where it is too large
for that, part by part (``parts.py``); the problem's estimate decides
(``budget.part_count``)."""

from __future__ import annotations

import threading
from collections.abc import Generator

from ..problem import Problem
from ..settings import OptimizeSettings
from .base import Progress, Solution
from .lp import solve_whole
from .parts import PartBuilder, part_count, solve_in_parts

# The default time budget: a ground planned whole gets DEFAULT_LIMIT_S (two_routes
# plans in about 2 minutes, within it; with k = 2 it ends within 5 minutes); one in
# parts (``budget.part_count``) DEFAULT_LIMIT_S_PER_PART a part, at least
# DEFAULT_LIMIT_S. Six tiles of full_ground (5 parts, 2026-11-26): 150 s a part gave
# cost 502, 240 s gave 456 (bound 334), each part's mast-aware MILP being what the
# time buys; at 210 s a part Town04 (8 parts) planned in 27 min 18 s (2026-11-26).
# A default run ends within DEFAULT_LIMIT_MAX_S (so within half an hour, the finish
# included) unless that leaves a part less than DEFAULT_LIMIT_MIN_S_PER_PART: a part's
# candidates alone take 10-45 s, and a larger ground is worth a longer run.
DEFAULT_LIMIT_S = 240.0
DEFAULT_LIMIT_S_PER_PART = 210.0
DEFAULT_LIMIT_MAX_S = 1680.0
DEFAULT_LIMIT_MIN_S_PER_PART = 120.0
# Of a time limit, what is kept for the work after the search (fixing the plan's
# sensors, masts, the report): two_routes' took 4 s.
FINISH_SHARE = 0.05
FINISH_MIN_S = 3.0


def time_limit(settings: OptimizeSettings, n_parts: int) -> float:
    """The run's time limit, s: ``time_limit_s``, else the default budget
    (``DEFAULT_LIMIT_S``, or ``DEFAULT_LIMIT_S_PER_PART`` a part, at most
    ``DEFAULT_LIMIT_MAX_S`` unless that leaves a part less than
    ``DEFAULT_LIMIT_MIN_S_PER_PART``)."""
    if settings.time_limit_s is not None:
        return settings.time_limit_s
    if n_parts == 1:
        return DEFAULT_LIMIT_S
    cap = max(DEFAULT_LIMIT_MAX_S, DEFAULT_LIMIT_MIN_S_PER_PART * n_parts)
    return max(DEFAULT_LIMIT_S, min(DEFAULT_LIMIT_S_PER_PART * n_parts, cap))


def finish_s(limit_s: float) -> float:
    """What a run within ``limit_s`` keeps for the work after the search, s."""
    return max(FINISH_MIN_S, FINISH_SHARE * limit_s)


def search_deadline(t0: float, limit_s: float) -> float:
    """When the search must end (``time.perf_counter()``) for a run started at ``t0``
    to end within ``limit_s``: the finish's share of the limit kept for it."""
    return t0 + limit_s - finish_s(limit_s)


class LPPlanner:
    """The ``lp`` optimizer (see ``lp.py`` and ``parts.py``)."""

    name = "lp"

    def __init__(self, builder: PartBuilder | None = None) -> None:
        """builder: where a ground planned in parts has its candidates built (None:
        here, ``parts.LocalBuilder``)."""
        self.stop = threading.Event()
        self.builder = builder

    def close(self) -> None:
        pass

    def stop_early(self) -> None:
        """End the search now: the bounds proven so far, the best plan by then."""
        self.stop.set()

    def solve(self, problem: Problem, solution: Solution) -> Generator[Progress, None, Solution]:
        n_parts = part_count(problem)
        limit = time_limit(problem.settings, n_parts)
        deadline = search_deadline(problem.t0, limit)
        if n_parts > 1:
            return (
                yield from solve_in_parts(
                    problem, solution, n_parts, deadline, self.stop, self.builder
                )
            )
        # The LP on the plan's own masts and the plans rounded from it may take half
        # the finish's share: a search that runs to its deadline (at k = 2) leaves
        # them no time, and the finish of a plan evaluated ahead takes about 1 s of 12.
        return (
            yield from solve_whole(
                problem, solution, deadline, self.stop, deadline + finish_s(limit) / 2
            )
        )
