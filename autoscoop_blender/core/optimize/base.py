"""What every optimizer shares: the protocol, its progress reports and its solution.

An optimizer is a strategy: ``solve(problem, solution)`` is a generator that places
sensors on a ``Problem``, starting from ``solution`` (empty, or the sensors of an
interrupted run), yields a ``Progress`` after each small unit of work (so that the
Blender operator can time-slice it and the CLI can draw a bar), and returns the
solution. It reads the problem's public interface only; its own state (the ES's
random generator and parents, greedy's gains) stays inside it, except what a resumed
run needs, which it leaves in ``Solution.state`` at every fixed sensor.
"""

from __future__ import annotations

import threading
from collections.abc import Generator
from dataclasses import dataclass, field
from typing import Any, Protocol, TypeVar

import numpy as np
from numpy.typing import NDArray

from ..candidates import CandidateSet, build_candidates
from ..model.sensors import SensorPose
from ..problem import Problem

T = TypeVar("T")


@dataclass(frozen=True)
class FixedSensor:
    """A sensor an optimizer fixed: its pose (local metres, degrees), its fitness (the
    ES's f_s; greedy: the points it raised towards their k), the ES epochs and
    evaluations it took, the target ordinals it newly covered to their k when it was
    fixed, and ``seen``: every target ordinal it covers (None: the same as ``newly``,
    which is all a sensor can add when every k is 1). existing: a sensor that stands
    already (given to the run: kept as it is, at no cost). model: its model, an index
    into the problem's ``models``."""

    pose: SensorPose
    fitness: float
    epochs: int
    evaluations: int
    newly: NDArray[np.int64]
    seen: NDArray[np.int64] | None = None
    existing: bool = False
    model: int = 0

    @property
    def new_points(self) -> int:
        return len(self.newly)


@dataclass(frozen=True)
class Progress:
    """Where a run is: for progress bars, status lines and the modal operator.

    fixed: the sensor just fixed (phase "fixed"), else None. bound, best: the lower
    bound on the objective proven so far and the best plan's objective, when the
    optimizer knows them (the lp optimizer). stage: what the optimizer is doing, in a
    word or two ("candidates", "bounds", "plans", ...; "" when it does not say);
    part, parts: the part of the ground being worked on, 1-based, of how many (0, 0:
    the ground is not planned in parts); plan: (sensors, masts) of the best plan so
    far; eta_s: the optimizer's estimate of the seconds left (None: no estimate).
    """

    phase: str  # "search" | "fixed" | "masts" | "report" | "done"
    sensors: int
    coverage: float
    rho: float
    epoch: int
    evaluations: int
    fixed: FixedSensor | None = None
    bound: float | None = None
    best: float | None = None
    stage: str = ""
    part: int = 0
    parts: int = 0
    plan: tuple[int, int] | None = None
    eta_s: float | None = None

    @property
    def fraction(self) -> float:
        """Progress towards the goal in [0, 1]: coverage / rho, so a run that ends short
        of its goal ends with the bar short of full."""
        return min(1.0, self.coverage / self.rho)


@dataclass(frozen=True)
class PlanBound:
    """What no plan on the candidate set can beat, proven (see ``bound.py``).

    sensors: the fewest sensors any plan needs; masts: the fewest masts (None: not
    proven); lp: the proven lower bound on the LP relaxation's value (sensors; equal
    to it when the LP was solved to the end); rounds: of column generation;
    scope: over which plans the bound holds, in words; cost_lp: a proven lower bound
    on the cost from the mast-aware LP (``bound.mast_aware_bound``), 0 if not known;
    sensor_cost_lp: a proven lower bound on what the sensors cost together (None:
    ``sensor_cost`` x ``sensors``); with models of different costs ``lp`` is that
    bound and ``sensors`` follows from it through the dearest model; joint: a proven
    lower bound on the cost from masts and sensors together (``joint.py``), 0 if not
    known; on_masts: the fewest new sensors of any plan whose new sensors stand on
    the plan's own masts or those that stood already (``joint.sensors_on_masts``;
    None: not proven). Unlike the others it holds for plans on those masts alone: it
    tells whether a plan with fewer sensors could keep them.
    """

    sensors: int
    masts: int | None
    lp: float
    scope: str
    rounds: int = 0
    cost_lp: float = 0.0
    sensor_cost_lp: float | None = None
    joint: float = 0.0
    on_masts: int | None = None

    def objective(self, objective: str, mast_cost: float, sensor_cost: float) -> float:
        """The bound on ``objective``: sensors, masts, or cost = mast_cost x masts +
        sensor_cost x sensors: the larger of each part at its own bound and the
        mast-aware LP's and the joint bound."""
        masts = self.masts or 0
        if objective == "sensors":
            return float(self.sensors)
        if objective == "masts":
            return float(masts)
        sensors = self.sensor_cost_lp
        if sensors is None:
            sensors = sensor_cost * self.sensors
        return max(self.cost_lp, self.joint, mast_cost * masts + sensors)


class StopReason:
    """Why an optimizer stopped, as short sentences a planner reads in the report."""

    @staticmethod
    def reached(rho: float, early: bool = False) -> str:
        text = f"Reached the goal: {rho:.0%} of the target is covered."
        return text + (" Stopped early, with the best plan found by then." if early else "")

    @staticmethod
    def stopped_before_plan() -> str:
        return "Stopped early, before the candidates were built: no plan was made."

    @staticmethod
    def sensor_limit(max_sensors: int) -> str:
        return f"Stopped short of the goal at the sensor limit (max_sensors = {max_sensors})."

    @staticmethod
    def out_of_sight(from_where: str) -> str:
        return (
            f"The goal cannot be reached: no {from_where} sees the rest of the target "
            "(line of sight, range, density or pitch limits). The plan covers all that can "
            "be seen."
        )

    @staticmethod
    def gave_up(searches: int) -> str:
        return (
            f"Stopped short of the goal: {searches} searches in a row found nothing new. "
            "Some of the rest may still be visible; try the lp optimizer."
        )


@dataclass
class Solution:
    """Sensors fixed so far, in order, and the target points they cover.

    covered: (N,) bool over the grid's target points: covered by at least their k
    sensors (``need``, (N,), default all 1; ``counts``: how many cover each now).
    evaluations, sight_rays: what
    the optimizer spent (pose evaluations, sight rays cast by them). state: what the
    optimizer needs to go on after the last sensor exactly as it would have (the ES:
    its random generator's state); JSON-ready, written to checkpoints. bound: what no
    plan can beat, when it was proven. ahead: the sensors (local pose, model) that an
    optimizer which fixes them only once its plan is done (lp) would fix if stopped
    now: its best plan so far, which the report's work ahead evaluates meanwhile
    (``ahead.py``); empty for one that fixes them as it goes.
    """

    covered: NDArray[np.bool_]
    sensors: list[FixedSensor] = field(default_factory=list)
    stop_reason: str = ""
    evaluations: int = 0
    sight_rays: int = 0
    state: dict[str, Any] = field(default_factory=dict)
    bound: PlanBound | None = None
    need: NDArray[np.int32] | None = None
    ahead: list[tuple[SensorPose, int]] = field(default_factory=list)
    n_covered: int = field(init=False)
    counts: NDArray[np.int32] = field(init=False)

    def __post_init__(self) -> None:
        if self.need is None:
            self.need = np.ones(len(self.covered), dtype=np.int32)
        self.counts = np.where(self.covered, self.need, 0).astype(np.int32)
        self.n_covered = int(np.count_nonzero(self.covered))

    @property
    def coverage(self) -> float:
        """Covered fraction of the target points."""
        return self.n_covered / max(len(self.covered), 1)

    def fix(self, sensor: FixedSensor) -> None:
        """Add ``sensor``; its ``newly`` must be the points of ``seen`` one short of
        their k before (``newly_covered``)."""
        self.sensors.append(sensor)
        self.counts[sensor.newly if sensor.seen is None else sensor.seen] += 1
        self.covered[sensor.newly] = True
        self.n_covered += sensor.new_points

    def short(self) -> NDArray[np.bool_]:
        """(N,) the points still below their k."""
        assert self.need is not None
        return self.counts < self.need

    def progress(
        self,
        phase: str,
        rho: float,
        epoch: int = 0,
        fixed: FixedSensor | None = None,
        bound: float | None = None,
        best: float | None = None,
        **where: Any,
    ) -> Progress:
        """Where the run is now; ``where``: ``Progress``'s stage, part, parts, plan,
        eta_s."""
        return Progress(
            phase,
            len(self.sensors),
            self.coverage,
            rho,
            epoch,
            self.evaluations,
            fixed,
            bound,
            best,
            **where,
        )


class Optimizer(Protocol):
    """A strategy that places sensors (see the module docstring)."""

    name: str

    def solve(self, problem: Problem, solution: Solution) -> Generator[Progress, None, Solution]:
        """Place sensors until the problem's goal or a stop rule; yields progress,
        returns ``solution`` with its sensors and ``stop_reason`` set."""
        ...

    def close(self) -> None:
        """Release what the optimizer holds (worker processes); safe to call twice."""
        ...


def newly_covered(solution: Solution, ordinals: NDArray[np.int64]) -> NDArray[np.int64]:
    """The ``ordinals`` (target points a pose covers) that one more sensor brings to
    their k: those one short of it (with k = 1: those not covered yet)."""
    assert solution.need is not None
    return ordinals[solution.counts[ordinals] == solution.need[ordinals] - 1]


def fix_candidate(problem: Problem, solution: Solution, cands: CandidateSet, c: int) -> FixedSensor:
    """Fix candidate ``c`` as a sensor: its pose evaluated afresh (the rays counted),
    its fitness the points it raises towards their k (with k = 1: newly covers)."""
    pose = cands.pose(problem, c)
    model = int(cands.model[c])
    cov = problem.evaluate(pose, model=model)
    solution.sight_rays += cov.rays
    solution.evaluations += 1
    newly = newly_covered(solution, cov.covered)
    gain = int(np.count_nonzero(solution.short()[cov.covered]))
    sensor = FixedSensor(pose, float(gain), 0, 0, newly, cov.covered, model=model)
    solution.fix(sensor)
    return sensor


def candidates_of(problem: Problem, solution: Solution) -> Generator[Progress, None, CandidateSet]:
    """The problem's candidate set, reporting progress while it is built."""
    cands = yield from candidates_until(problem, solution, None)
    assert cands is not None  # nothing stops it
    return cands


def candidates_until(
    problem: Problem, solution: Solution, stop: threading.Event | None
) -> Generator[Progress, None, CandidateSet | None]:
    """The problem's candidate set, reporting progress while it is built; None when
    ``stop`` is set before it is (the build is dropped: no plan can come of it)."""
    return (yield from building(build_candidates(problem), problem, solution, stop))


def building(
    build: Generator[int, None, T],
    problem: Problem,
    solution: Solution,
    stop: threading.Event | None = None,
) -> Generator[Progress, None, T | None]:
    """What ``build`` (a candidate set's build, whole or of a part) returns, reporting
    progress while it works; None when ``stop`` is set first (the build is dropped)."""
    try:
        while True:
            try:
                next(build)
            except StopIteration as done:
                built: T = done.value
                return built
            if stop is not None and stop.is_set():
                return None
            yield solution.progress("search", problem.rho, stage="candidates")
    finally:
        build.close()


def taken_candidates(cands: CandidateSet, sensors: list[FixedSensor]) -> NDArray[np.int64]:
    """The candidates whose poses are ``sensors`` already (a resumed run's, those that
    stand)."""
    if not sensors:
        return np.zeros(0, dtype=np.int64)
    fixed = {(s.pose.x, s.pose.y, s.pose.pitch_deg, s.pose.yaw_deg, s.model) for s in sensors}
    xy = cands.positions[cands.position]
    taken = []
    for c, ((x, y), m, o) in enumerate(zip(xy, cands.model, cands.orientation)):
        pitch, yaw = cands.angles[m][o]
        if (float(x), float(y), float(pitch), float(yaw), int(m)) in fixed:
            taken.append(c)
    return np.array(taken, dtype=np.int64)
