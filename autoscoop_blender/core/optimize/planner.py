"""The ``lp`` optimizer: the whole ground at once (``lp.py``) or, where it is too large
for that, part by part (``parts.py``); the problem's estimate decides
(``budget.part_count``)."""

from __future__ import annotations

import threading
import time
from collections.abc import Generator

from ..problem import Problem
from .base import Progress, Solution
from .lp import solve_whole
from .parts import part_count, solve_in_parts


class LPPlanner:
    """The ``lp`` optimizer (see ``lp.py`` and ``parts.py``)."""

    name = "lp"

    def __init__(self) -> None:
        self.stop = threading.Event()

    def close(self) -> None:
        pass

    def stop_early(self) -> None:
        """End the search now: the bounds proven so far, the best plan by then."""
        self.stop.set()

    def solve(self, problem: Problem, solution: Solution) -> Generator[Progress, None, Solution]:
        s = problem.settings
        deadline = None if s.time_limit_s is None else time.perf_counter() + s.time_limit_s
        n_parts = part_count(problem)
        if n_parts > 1:
            return (yield from solve_in_parts(problem, solution, n_parts, deadline, self.stop))
        return (yield from solve_whole(problem, solution, deadline, self.stop))
