"""The report's work on each sensor, done ahead while the search runs.

The report evaluates every sensor of the plan in full (its whole footprint and line of
sight) and drapes its footprint on the ground: about 40 ms a sensor on Town04, 14 s for
its 306 sensors (2026-11-27). A run stopped early (Ctrl-C, Esc) has 4.5 s to write its
plan (``headless.interrupts.STOP_GRACE_S``). So between its progress reports the run
hands ``ReportAhead`` the sensors it has fixed so far and, from the lp, which fixes its
sensors only once its plan is done, those of its best plan so far
(``Solution.ahead``); each is evaluated once, kept by its pose, and the report takes
what is ready. The report is the same either way: the evaluation of a pose does not
depend on when it is made.
"""

from __future__ import annotations

import time
from collections.abc import Sequence

from .coverage.base import SensorCoverage
from .model.sensors import SensorPose
from .optimize.base import FixedSensor
from .problem import Problem
from .result import SensorPieces, sensor_pieces

WARM_SHARE = 0.15
"""The most of a run's time the work ahead may take: on Town04 it needs about 12 s of
27 minutes (0.7 %), and on a ground of few sensors it ends as soon as they are ready.
The lp's first plan comes late (two_routes: 48 sensors, 1.8 s of work, at second 13),
and at 0.05 a run stopped 2 s later had 17 to 20 of its 43 sensors ready, at 0.15
all but 2 (2026-11-29)."""

WARM_SLICE_S = 0.04
"""Seconds of work ahead at a time, between two steps of the search: sensors are made
ready until it is spent (one takes 30-40 ms on two_routes), as the panel's modal
operator runs the search in slices of that length."""


class ReportAhead:
    """Full evaluations and ``SensorPieces`` of poses, made once each (see the module
    docstring). Poses are local metres, as the run's sensors stand."""

    def __init__(self, problem: Problem) -> None:
        self.problem = problem
        self.spent_s = 0.0  # on the work ahead (``warm``), s
        self._ready: dict[tuple[SensorPose, int], tuple[SensorCoverage, SensorPieces]] = {}

    def get(self, pose: SensorPose, model: int) -> tuple[SensorCoverage, SensorPieces]:
        """The full evaluation of ``pose`` (a sensor of the problem's model ``model``)
        and what the report draws of it: made now unless it is ready."""
        key = (pose, model)
        if key not in self._ready:
            p = self.problem
            cov = p.evaluate_full(pose, model)
            self._ready[key] = (cov, sensor_pieces(p.scene, p.grid, cov))
        return self._ready[key]

    def ready(self, pose: SensorPose, model: int) -> bool:
        return (pose, model) in self._ready

    def warm(
        self,
        sensors: Sequence[FixedSensor],
        elapsed_s: float,
        planned: Sequence[tuple[SensorPose, int]] = (),
    ) -> None:
        """Make ready the plan's ``sensors``, then the sensors it would fix if stopped
        now (``planned``: (pose, model), ``Solution.ahead``), that are not, for
        ``WARM_SLICE_S`` (at least one), unless the work ahead has taken
        ``WARM_SHARE`` of the run's ``elapsed_s`` already; poses in neither are
        forgotten (a better plan, or a part re-planned, moves them)."""
        if self.spent_s > WARM_SHARE * elapsed_s:
            return
        wanted = [(f.pose, f.model) for f in sensors] + list(planned)
        keep = set(wanted)
        for key in [k for k in self._ready if k not in keep]:
            del self._ready[key]
        began = time.perf_counter()
        for pose, model in wanted:
            if (pose, model) not in self._ready:
                self.get(pose, model)
                if time.perf_counter() - began > WARM_SLICE_S:
                    break
        self.spent_s += time.perf_counter() - began
