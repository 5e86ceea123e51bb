"""The report's work on each sensor, done ahead while the search runs.

The report evaluates every sensor of the plan in full (its whole footprint and line of
sight) and drapes its footprint on the ground: about 40 ms a sensor on Town04, 14 s for
its 306 sensors (2026-11-27). A run stopped early (Ctrl-C, Esc) has 4.5 s to write its
plan (``headless.interrupts.STOP_GRACE_S``). So between its progress reports the run
hands ``ReportAhead`` the sensors it has fixed so far; each is evaluated once, kept by
its pose, and the report takes what is ready. The report is the same either way: the
evaluation of a pose does not depend on when it is made.
"""

from __future__ import annotations

import time
from collections.abc import Sequence

from .coverage.base import SensorCoverage
from .model.sensors import SensorPose
from .optimize.base import FixedSensor
from .problem import Problem
from .result import SensorPieces, sensor_pieces

WARM_SHARE = 0.05
"""The most of a run's time the work ahead may take: on Town04 it needs about 12 s of
27 minutes (0.7 %), and on a ground of few sensors it ends as soon as they are ready."""


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

    def warm(self, sensors: Sequence[FixedSensor], elapsed_s: float) -> None:
        """Make ready the first of the plan's ``sensors`` that is not, unless the work
        ahead has taken ``WARM_SHARE`` of the run's ``elapsed_s`` already; poses no
        longer in the plan are forgotten (a part re-planned moves them)."""
        if self.spent_s > WARM_SHARE * elapsed_s:
            return
        wanted = {(f.pose, f.model) for f in sensors}
        for key in [k for k in self._ready if k not in wanted]:
            del self._ready[key]
        for f in sensors:
            if (f.pose, f.model) not in self._ready:
                started = time.perf_counter()
                self.get(f.pose, f.model)
                self.spent_s += time.perf_counter() - started
                return
