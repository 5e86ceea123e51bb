"""The ``lp`` optimizer: a proven lower bound, and a plan close to it.

On the problem's candidate set (``core/candidates.py``):

1. a greedy plan gives the first columns and a first incumbent;
2. the LP relaxation by column generation (``bound.cover_lp``; in parts of at most
   ``budget.PART_POINTS`` target points, ``bound.split_cover_lp``) and, in a second
   thread, the fewest masts by a MILP over positions (``bound.site_cover``; its LP
   only on a target in parts) prove the lower bounds: sensors, masts, and cost (the
   largest of mast_cost x masts + sensor_cost x sensors, the mast-aware LP's bound
   and, on a ground solved whole, the joint bound: the fewest sensors on at most m
   masts, for every m, by an LP started on whichever thread frees first,
   ``joint.py``);
3. still in the second thread, plans on the positions of the fewest masts and on
   those of its LP relaxation: greedy per cost (a new mast costs extra), improved,
   masts closed while that is cheaper; then the mast-aware MILP over the cheaper
   plan's masts (``bound.sensors_on_sites``, started from that plan; on at most
   ``MAX_MILP_CANDIDATES`` of their candidates, ``milp_candidates``);
4. plans are built from the LP: the candidates at or above a threshold of their LP
   value, completed greedily from a pool (the restricted LP's columns and every
   candidate whose reduced cost is within ``POOL_REDUCED_COST``), then improved by
   pruning and two-for-one swaps (``cover.py``; only on a ground solved whole where
   masts cost nothing: they are rounded for the sensors, and where masts count, or
   in a part, they never came near); and greedy per cost over the LP's columns, as
   in 3 (``plan_from``); with the plan on the fewest masts, the one that is best for
   the objective wins.

Deterministic (no random choice; the seed plays no part; HiGHS' MILP is limited in
nodes, not seconds) unless the time limit ends it (``planner.py``: by default 240 s a
part): then the bounds stop where they are (still proven) and the plans come from
what the LP has so far. At k > 1 the windows (``_Windows``) follow the clock too:
each window's MILP has 10 s, and the roundings come after 25 s without a cheaper
plan, so the plan may differ from run to run (two_routes at k = 2 gave 131 twice on
2026-12-08; the windows alone had given 137-146). A ground too large for one matrix
is planned in parts with the same machinery (``parts.py``).

A little over 500 lines: the whole-ground search (bounds beside plans, the LP's
rounding, the mast-aware MILP's plan) is one generator with its stop and deadline.
"""

from __future__ import annotations

import dataclasses
import logging
import math
import threading
import time
from collections.abc import Generator, Iterator
from dataclasses import dataclass
from functools import partial
from typing import Any, TypeVar

import numpy as np
from numpy.typing import NDArray
from scipy import sparse

from .. import budget
from ..candidates import CandidateSet, sensor_price
from ..model.sensors import SensorPose
from ..problem import Problem
from .base import (
    PlanBound,
    Progress,
    Solution,
    StopReason,
    candidates_of,
    candidates_until,
    fix_candidate,
    taken_candidates,
)
from .bound import (
    LPProgress,
    LPSolution,
    SiteSolution,
    cover_lp,
    mast_aware_bound,
    parts_of,
    sensors_on_sites,
    site_cover,
    split_cover_lp,
)
from .cover import (
    Cover,
    CoverInstance,
    MastCost,
    SensorCost,
    close_sites,
    complete,
    cost_at,
    improve,
    plan_price,
)
from .joint import MastsSensors, OnMasts, joint_bound, sensors_on_masts, whole_sensors
from .neighbourhoods import improve as improve_by_windows

F64 = NDArray[np.float64]
I64 = NDArray[np.int64]

T = TypeVar("T")
log = logging.getLogger(__name__)

# Candidates whose LP reduced cost is within this join the pool plans are built from.
POOL_REDUCED_COST = 0.2
# LP values at or above which a candidate is kept when rounding, one plan each.
THRESHOLDS = (0.9, 0.7, 0.5, 0.3, 0.2)
# Plans rounded from the LP on the plan's own masts (``plan_on_masts``), in this order
# while time is left: at k = 2 on two_routes, from a plan of 152 on 23 masts, 0.25
# gave 135, 0.75 137, 0.5 and 0.99 138 (0.7-0.8 s each).
ON_MASTS_THRESHOLDS = (0.25, 0.75, 0.5, 0.99)
# Windows that have found nothing cheaper for this long, s, give way to plans rounded
# from the LP on the plan's masts (``_Windows``) when the plan has changed since the
# last of those.
STALL_S = 25.0
# At k > 1, the LP values above which its columns are a pool for greedy per cost
# (``_then_windows``), one plan each. On two_routes at k = 2 (2026-11-30, one stored
# LP of 320 columns above 0) they gave 151 (above 0), 141 (above 0.05) and 142
# (above 0.1); above 0.2 and 0.3, 144 and 149: the columns the LP barely uses lead
# greedy to masts the LP does not want. Windows from those plans (150 s, one core)
# reached 142 (from 151), 138 (from 141) and 137 (from 142).
ABOVE = (0.0, 0.05, 0.1)
# The mast-aware MILP runs on at most this many candidates: two_routes' 13 masts
# have 2,611 and HiGHS proves the optimum at its root in 18 s; on three tiles of
# full_ground, 49 masts with about 10,000 took it 1,070 s, while 37 masts with the
# 100 candidates each that see the most (3,710) took 148 s and lowered the cost
# from 239 to 215.
MAX_MILP_CANDIDATES = 4000
# A start's mast-aware MILP after the first looks only for plans at least this much
# cheaper than the best so far (in the MILP's objective; below any cost step).
CUTOFF_EPS = 1e-6
# A part's LP (``parts.py``) stops once its bound is within this fraction of its value
# (0.5 % took two_routes' parts twice as long as the whole LP, which stops once its
# integer bound is final). Started from a sample's LP (``bound.sample_columns``),
# Town01's parts took 37-54 s at 1 % and 36-42 s at 2 %, and their lines proved 57.42
# sensors together, against 56.99 (2026-12-07): at 2 % the whole bound was 1 lower.
PART_REL_GAP = 0.01


@dataclass(frozen=True)
class PartInputs:
    """How a part of a ground planned in parts is solved (``parts.py``): its LP at
    ``lp_cost`` (C,) (its shares) on ``lp_inst`` (the part with nothing fixed: it bounds
    the part, while its plans cover what the parts before left), and instead of the
    fewest masts' MILP, ``sites``: the part's masts LP, a generator that yields while
    it works and returns the sites to plan on. It runs beside the sensors LP, as the
    fewest masts do on a whole ground (two solves, two cores)."""

    lp_cost: F64
    lp_inst: CoverInstance
    sites: Generator[None, None, SiteSolution]
    # Goals at which its LP gives lines too (``bound.cover_lp``'s ``also_at``).
    other_goals: tuple[int, ...] = ()


@dataclass(frozen=True)
class Incumbent:
    """A plan found while the bounds are still being proven (``masts_then_plan``):
    its objective, reported at once as the best plan so far, and its candidates."""

    value: float
    chosen: list[int]


@dataclass
class _Held:
    """The best plan so far in ``prove_bound``: its objective and its candidates."""

    value: float
    chosen: list[int]


def instance(
    cands: CandidateSet,
    problem: Problem,
    covered: NDArray[np.bool_],
    counts: NDArray[np.int32] | None = None,
    taken: I64 | None = None,
) -> CoverInstance:
    """The cover instance of what is left: the points not ``covered`` (to their k) yet
    (columns of the candidate matrix dropped), each needing its k less the sensors
    that cover it already (``counts``), and the goal less what is covered. When no
    plan can reach the goal (parts of the target that fewer than their k candidates
    see), the goal is what all candidates together cover: the most any plan can."""
    matrix = cands.matrix
    if taken is not None and len(taken):  # a candidate counts once: not those fixed
        keep = np.ones(matrix.shape[0])
        keep[taken] = 0.0
        matrix = (sparse.diags(keep.astype(matrix.dtype)) @ matrix).tocsr()
        matrix.eliminate_zeros()
    need = problem.need - (0 if counts is None else counts)
    if covered.any():
        matrix = matrix[:, np.flatnonzero(~covered)].tocsr()
        need = need[~covered]
    seen_by = np.bincount(matrix.indices, minlength=matrix.shape[1])
    coverable = int(np.count_nonzero(seen_by >= np.maximum(need, 1)))
    goal = min(problem.goal - int(np.count_nonzero(covered)), coverable)
    return CoverInstance(
        matrix,
        goal,
        problem.grid.target_xy[~covered],
        need=np.maximum(need, 1).astype(np.int32),
        site_of=cands.position,
        cap=problem.settings.max_sensors_per_mast,
    )


def bound_scope(cands: CandidateSet, problem: Problem) -> str:
    """Over which plans the bound holds, in words."""
    ang = cands.angles[0]
    pitches = len(np.unique(ang[:, 0]))
    yaws = len(np.unique(ang[:, 1]))
    return (
        f"plans on the candidate set: {len(cands.positions)} mast positions on a "
        f"{problem.space.step:g} m lattice x {yaws} yaws x {pitches} pitches; the "
        f"{problem.grid.spacing:g} m target grid"
    )


def plan_cost(
    cands: CandidateSet,
    chosen: list[int],
    objective: str,
    mc: float,
    sc: SensorCost,
    standing: NDArray[np.bool_] | None = None,
    cap: int | None = None,
) -> tuple[float, int]:
    """(objective value, new masts) of a plan of candidates: one mast per position
    used, except where one stands already (``standing``, per position); a sensor
    costs ``sc`` (one for all, or (C,) per candidate). inf for a plan with more than
    ``cap`` candidates at one position."""
    used, per = np.unique(cands.position[chosen], return_counts=True)
    masts = len(used) if standing is None else int(np.count_nonzero(~standing[used]))
    if cap is not None and len(per) and int(per.max()) > cap:
        return math.inf, masts
    price = float(cost_at(sc, np.asarray(chosen, dtype=np.int64)).sum())
    return objective_value(objective, masts, len(chosen), mc, price), masts


def objective_value(
    objective: str, masts: int, sensors: int, mast_cost: float, sensors_price: float
) -> float:
    """A plan's objective from its counts: new ``masts``, ``sensors`` planned, and
    what those sensors cost in all (``sensors_price``)."""
    if objective == "sensors":
        return float(sensors)
    if objective == "masts":
        return masts + sensors * 1e-6  # the fewest sensors break ties
    return mast_cost * masts + sensors_price


def _both(
    first: Generator[Any, None, Any], second: Generator[Any, None, Any]
) -> Generator[Any, None, tuple[Any, Any]]:
    """Drive two generators that yield while their solver works, side by side; yields
    what they yield, returns both values."""
    gens: list[Generator[Any, None, Any] | None] = [first, second]
    values: list[Any] = [None, None]
    try:
        while any(g is not None for g in gens):
            for k, g in enumerate(gens):
                if g is None:
                    continue
                try:
                    yield next(g)
                except StopIteration as done:
                    values[k], gens[k] = done.value, None
    finally:
        for g in gens:
            if g is not None:
                g.close()
    return values[0], values[1]


def mast_aware_costs(
    problem: Problem, cands: CandidateSet, n_candidates: int
) -> tuple[MastCost, SensorCost]:
    """(mast, sensor) costs of the mast-aware MILP for the problem's objective; for
    masts, one mast outweighs every sensor there is. Where masts stand already, the
    mast cost is per site, 0 on those; with models of different costs, the sensor
    cost is per candidate (``sensor_price``)."""
    s = problem.settings
    if s.objective == "sensors":
        return 0.0, 1.0
    mast = float(n_candidates + 1) if s.objective == "masts" else s.mast_cost
    sensor = 1.0 if s.objective == "masts" else sensor_price(problem, cands)
    return _per_site(problem, mast), sensor


def plan_value(problem: Problem, cands: CandidateSet, chosen: list[int]) -> float:
    """The objective of a plan of candidates (``plan_cost`` with the problem's
    settings; inf past the sensors-per-mast cap)."""
    s = problem.settings
    return plan_cost(
        cands,
        chosen,
        s.objective,
        s.mast_cost,
        sensor_price(problem, cands),
        _standing(problem),
        s.max_sensors_per_mast,
    )[0]


def _per_site(problem: Problem, mast_cost: float) -> MastCost:
    """``mast_cost``, or (sites,) with 0 where a mast stands already."""
    standing = problem.space.standing
    return np.where(standing, 0.0, mast_cost) if standing.any() else mast_cost


def _standing(problem: Problem) -> NDArray[np.bool_] | None:
    """(sites,) where masts stand already, or None when none does."""
    return problem.space.standing if problem.space.standing.any() else None


def masts_then_plan(
    problem: Problem,
    cands: CandidateSet,
    inst: CoverInstance,
    deadline: float | None,
    stop: threading.Event | None,
    plan: bool,
    milp: bool = True,
    known: Generator[None, None, SiteSolution] | None = None,
    every_start: bool = False,
) -> Generator[Any, None, tuple[SiteSolution, list[int] | None]]:
    """The fewest masts and, when ``plan``, a plan on a few positions: on the sites
    of the fewest masts' MILP and on those of its LP relaxation (more sites, each
    chosen for what it sees), the cheapest by greedy per cost (a new mast costs
    extra), improved, then with masts closed while that is cheaper; the cheaper of
    the two, and then the mast-aware MILP over its masts (``milp_candidates``). None
    when there is no plan. Each plan is yielded as an ``Incumbent`` when found, so the
    progress shows it while the LP still works. ``milp``: solve the fewest masts'
    MILP (else its LP only); ``known``: where the sites come from instead (a part's
    masts LP, ``PartInputs``); ``every_start``: the mast-aware MILP over the masts of
    every site set's plan, the cheapest first, while the time lasts, and the best of
    them (a part's: there the cheapest start is a poor guide, see ``parts.py``)."""
    if known is None:
        known = _fewest_masts(problem, cands, inst, deadline, stop, milp)
    sites = yield from known
    if not plan or (stop is not None and stop.is_set()):
        return sites, None
    site_of = cands.position
    starts: list[Cover] = []
    for on in sites.site_sets():
        start = plan_from(problem, cands, inst, np.flatnonzero(np.isin(site_of, on)))
        if start.slack >= 0:
            starts.append(start)
        yield None
    if not starts:
        return sites, None
    starts.sort(key=lambda c: plan_value(problem, cands, c.chosen))
    yield Incumbent(plan_value(problem, cands, starts[0].chosen), starts[0].chosen)
    best: list[int] | None = None
    best_value = math.inf
    for i, start in enumerate(starts if every_start else starts[:1]):
        if i and (
            (stop is not None and stop.is_set())
            or (deadline is not None and time.perf_counter() >= deadline)
        ):
            break
        used = np.unique(site_of[start.chosen])
        cols = milp_candidates(inst, site_of, used, start.chosen)
        mc, sc = mast_aware_costs(problem, cands, len(cols))
        # After the first, only a plan cheaper than the best so far is of use: HiGHS
        # prunes the rest (on Town01's third part the last start's MILP took 11.4 s
        # for 56 where the first's had 47).
        cutoff = None if best is None else plan_price(best, site_of, mc, sc) - CUTOFF_EPS
        began = time.perf_counter()
        chosen = yield from sensors_on_sites(
            inst, site_of, used, start.chosen, mc, sc, deadline, stop, cols=cols, cutoff=cutoff
        )
        value = plan_value(problem, cands, chosen) if chosen else math.inf
        log.info(
            "mast-aware MILP on %d sites, %d candidates: %g -> %g in %.1f s", len(used),
            len(cols), plan_value(problem, cands, start.chosen), value, time.perf_counter() - began,
        )  # fmt: skip
        if value < best_value:
            best, best_value = chosen, value
            yield Incumbent(value, chosen)
    return sites, best


def plan_from(problem: Problem, cands: CandidateSet, inst: CoverInstance, pool: I64) -> Cover:
    """A plan by greedy per cost over the candidates ``pool`` (a new mast costs extra),
    the rest from every candidate when those fall short, improved, then with masts
    closed while that is cheaper; short of the goal when no candidate can reach it."""
    site_of = cands.position
    pool = np.asarray(pool, dtype=np.int64)
    mc, sc = mast_aware_costs(problem, cands, len(pool))
    plan = complete(Cover(inst), pool, site_of, mc, sc)
    if plan.slack < 0:
        # Full masts (the sensors-per-mast cap, which the fewest masts do not know
        # of), or a pool that sees too little: the rest from every site.
        every = np.arange(len(cands), dtype=np.int64)
        plan = complete(plan, every, site_of, mc, sc)
        pool = np.flatnonzero(np.isin(site_of, site_of[plan.chosen])).astype(np.int64)
    return close_sites(improve(plan, pool, sc), site_of, mc, sc)


def _fewest_masts(
    problem: Problem,
    cands: CandidateSet,
    inst: CoverInstance,
    deadline: float | None,
    stop: threading.Event | None,
    milp: bool,
) -> Generator[None, None, SiteSolution]:
    """The fewest masts (``bound.site_cover``) over the candidates' positions."""
    return site_cover(
        inst, cands.position, len(cands.positions), deadline, stop, milp, _standing(problem)
    )


def milp_candidates(inst: CoverInstance, site_of: I64, used: I64, start: list[int]) -> I64:
    """The candidates of the mast-aware MILP on the sites ``used``: all of them when
    they are at most ``MAX_MILP_CANDIDATES``, else at each site the ones that cover
    the most points, as many as that limit allows, and the plan ``start``."""
    cols = np.flatnonzero(np.isin(site_of, used)).astype(np.int64)
    if len(cols) <= MAX_MILP_CANDIDATES:
        return cols
    per_site = max(1, MAX_MILP_CANDIDATES // len(used))
    size = np.diff(inst.matrix.indptr)[cols]
    order = cols[np.lexsort((-size, site_of[cols]))]  # by site, the largest first
    rank = np.arange(len(order)) - np.searchsorted(site_of[order], site_of[order])
    return np.union1d(order[rank < per_site], start).astype(np.int64)


def hold_best(
    problem: Problem, cands: CandidateSet, solution: Solution, plans: list[list[int]]
) -> float:
    """The objective of the cheapest of ``plans`` (candidate lists), whose sensors the
    solution holds as those it would fix if stopped now (``Solution.ahead``)."""
    values = [plan_value(problem, cands, plan) for plan in plans]
    i = int(np.argmin(values))
    solution.ahead = sensors_of(problem, cands, plans[i])
    return values[i]


def _at_plans(
    problem: Problem, cands: CandidateSet, solution: Solution, lower: float, plans: list[list[int]]
) -> Progress:
    """A progress report at the plans' stage: the bound ``lower`` and the cheapest of
    ``plans``, which the solution then holds as its sensors ahead (``hold_best``)."""
    best = hold_best(problem, cands, solution, plans)
    return solution.progress("search", problem.rho, bound=lower, best=best, stage="plans")


def sensors_of(
    problem: Problem, cands: CandidateSet, plan: list[int]
) -> list[tuple[SensorPose, int]]:
    """(pose, model) of each candidate of ``plan``, in its order."""
    return [(cands.pose(problem, c), int(cands.model[c])) for c in plan]


def prove_bound(
    problem: Problem,
    cands: CandidateSet,
    inst: CoverInstance,
    solution: Solution,
    deadline: float | None,
    stop: threading.Event | None = None,
    plan: bool = False,
    part: PartInputs | None = None,
) -> Generator[Progress, None, tuple[PlanBound, LPSolution, list[int] | None, list[Cover]]]:
    """The lower bounds: the LP by column generation from a greedy plan's columns and,
    beside it, the fewest masts (then, when ``plan``, the best plan on them). Returns
    the bound, the LP, the best plan found beside them (on the fewest masts; at k > 1
    on a whole ground, improved by windows too: ``_then_windows``) and the greedy
    plans (per sensor, whose columns start the LP, and per cost with a new mast's
    cost: fewer masts).
    Progress reports the best greedy plan's objective and, as it rises, what the LP
    proves of the objective (sensor_cost x its bound for cost; nothing yet for masts).
    part: how a part of the ground is solved (``PartInputs``)."""
    s = problem.settings
    price = sensor_price(problem, cands) if s.objective == "cost" else 1.0
    every = np.arange(len(cands), dtype=np.int64)
    greedy = complete(Cover(inst), every, sensor_cost=price)
    mc, sc = mast_aware_costs(problem, cands, len(cands))
    greedy_masts = complete(Cover(inst), every, cands.position, mc, sc)
    greedies = [greedy, greedy_masts]
    best = hold_best(problem, cands, solution, [g.chosen for g in greedies])
    whole = [g.chosen for g in greedies if g.slack >= 0]  # those that reach the goal
    held = _Held(math.inf, [])
    if whole:
        chosen = min(whole, key=partial(plan_value, problem, cands))
        held = _Held(plan_value(problem, cands, chosen), chosen)
    yield solution.progress("search", problem.rho, best=best, stage="greedy")
    # The LP counts sensors (unit costs), or with models of different costs, prices
    # each candidate at its model's cost; the progress shows the cost it proves.
    ones = np.ones(len(cands)) if np.ndim(price) == 0 else np.asarray(price)
    if part is not None:
        ones = part.lp_cost
    unit = float(price) if np.ndim(price) == 0 else 1.0
    per_sensor = {"cost": unit, "sensors": 1.0}.get(s.objective)
    n_parts = 1 if inst.xy is None else math.ceil(inst.n_points / budget.PART_POINTS)
    initial = np.array(greedy.chosen, dtype=np.int64)
    if part is not None:
        start = complete(Cover(part.lp_inst), every, sensor_cost=price).chosen
        # A part's LP gives its bound as a line in its goal: solved near its end,
        # as ``split_cover_lp`` solves its parts.
        lp_gen = cover_lp(
            part.lp_inst, ones, cands.position, np.array(start, dtype=np.int64), integral=False,
            deadline=deadline, stop=stop, rel_gap=PART_REL_GAP, line_anyway=True,
            also_at=part.other_goals, sample=True,
        )  # fmt: skip
    elif inst.xy is not None and n_parts > 1:
        split = parts_of(inst.xy, n_parts)
        lp_gen = split_cover_lp(
            inst, ones, cands.position, initial, split, deadline=deadline, stop=stop
        )
    else:
        lp_gen = cover_lp(
            inst, ones, cands.position, initial, deadline=deadline, stop=stop, sample=True
        )
    # The fewest masts' MILP takes long on large targets (674 s on three tiles of
    # full_ground, where the LP's 33.51 already proves its 34): there only its LP
    # unless the masts are the objective.
    milp = n_parts == 1 or s.objective == "masts"
    so_far = None
    known = None if part is None else part.sites
    joint = None
    apart: PlanBound | None = None  # the bounds apart, once known beside the joint LP
    windows = None
    if plan and _by_windows(inst, part):
        windows = _Windows(problem, cands, inst, held, deadline, stop)
    if part is None and n_parts == 1 and _joint_applies(problem, cands):
        joint = _JointStart(problem, cands, inst, best, deadline, stop, windows)
        known = joint.keep_sites(_fewest_masts(problem, cands, inst, deadline, stop, milp))
        lp_gen = joint.then(lp_gen)
    if windows is not None:
        lp_gen = _then_windows(problem, cands, inst, windows, lp_gen)
    masts = masts_then_plan(
        problem, cands, inst, deadline, stop, plan, milp, known, every_start=part is not None
    )
    if joint is not None:
        masts = joint.then(masts)
    both = _both(lp_gen, masts)
    while True:
        try:
            step = next(both)
        except StopIteration as done:
            lp, (sites, on_sites) = done.value
            break
        if isinstance(step, LPProgress):
            if joint is not None:
                joint.latest = step
            if per_sensor is not None:
                so_far = per_sensor * step.bound
            if joint is not None and joint.sites is not None:
                # The fewest masts are known (the joint LP is for the cost): their
                # cost too, so the gap shown is the plan's, not the sensors' alone.
                sensors = unit * math.ceil(step.bound - 1e-6)
                so_far = s.mast_cost * joint.sites.bound + sensors
        if isinstance(step, Incumbent):  # a plan found beside the bounds, known at once
            if step.value < best:
                best = hold_best(problem, cands, solution, [step.chosen])
            if step.value < held.value:
                held.value, held.chosen = step.value, step.chosen
            if joint is not None:
                joint.best = best
        if joint is not None and joint.lp is not None and joint.sites is not None and not apart:
            # The LP and the masts are done while the joint LP works: their bound.
            apart = _plan_bound(joint.lp, joint.sites, cands, problem)
            so_far = apart.objective(s.objective, s.mast_cost, s.sensor_cost)
        yield solution.progress("search", problem.rho, bound=so_far, best=best, stage="bounds")
    plan_bound = _plan_bound(lp, sites, cands, problem)
    if on_sites and plan_value(problem, cands, on_sites) < best:
        best = hold_best(problem, cands, solution, [on_sites])
    if joint is not None and lp.pi is not None:
        more = _joint_bound(
            problem, cands, inst, lp, plan_bound, best, joint.solved, deadline, stop
        )
        plan_bound = yield from _progress(more, solution, problem, best, plan_bound)
    return plan_bound, lp, (held.chosen or None) if plan else None, greedies


def _joint_applies(problem: Problem, cands: CandidateSet) -> bool:
    """Whether the joint bound (``joint.py``) is sought: for the cost, with one price
    a sensor and a positive mast cost."""
    s = problem.settings
    price = sensor_price(problem, cands)
    return s.objective == "cost" and np.ndim(price) == 0 and s.mast_cost > 0


class _JointStart:
    """The joint bound's first LP (``joint.py``), at the fewest masts, started by
    whichever of the two searches side by side ends first (the sensors LP; the masts'
    MILPs and the plans on them), so that it takes the core that is free: on
    two_routes the MILPs end first (57 s, the LP ~75 s); with k = 2 the LP does and
    the mast-aware MILP runs to the time limit. It starts once the fewest masts are
    known, from the LP's last round (``latest``; its columns, and the points its
    duals price), or from the LP itself when it has ended; the LPs solved are in
    ``solved``. ``best``: the best plan's cost so far (more is not worth proving)."""

    def __init__(
        self,
        problem: Problem,
        cands: CandidateSet,
        inst: CoverInstance,
        best: float,
        deadline: float | None,
        stop: threading.Event | None,
        windows: _Windows | None = None,
    ) -> None:
        self.problem, self.cands, self.inst = problem, cands, inst
        self.best, self.deadline, self.stop = best, deadline, stop
        # Run while the joint LP waits for the sensors LP (the core is free).
        self.meanwhile = None if windows is None else windows.steps()
        self.latest: LPProgress | None = None
        self.sites: SiteSolution | None = None
        self.lp: LPSolution | None = None  # once the LP has ended
        self.started = False
        self.solved: list[MastsSensors] = []

    def keep_sites(
        self, gen: Generator[None, None, SiteSolution]
    ) -> Generator[None, None, SiteSolution]:
        """``gen``'s value (the fewest masts), kept."""
        self.sites = yield from gen
        return self.sites

    def then(self, gen: Generator[Any, None, Any]) -> Generator[Any, None, Any]:
        """``gen``'s value (the LP's, or the plans' on the fewest masts); then the
        joint LP, unless the other side has started it or it cannot start."""
        value = yield from gen
        if isinstance(value, LPSolution):
            self.lp = value
        elif isinstance(value, tuple) and value[1]:  # (sites, the plan on them)
            self.best = min(self.best, plan_value(self.problem, self.cands, value[1]))
        while not self.started and not (self.stop is not None and self.stop.is_set()):
            start = self._start()
            if start is None:
                if self.lp is not None and self.lp.pi is None and self.latest is None:
                    break  # the LP ended before a round: no duals to start from
                yield None if self.meanwhile is None else next(self.meanwhile, None)
                continue
            self.started = True
            columns, duals, sensors = start
            s = self.problem.settings
            standing = self.problem.space.standing
            fewest = _masts_bound(self.sites, sensors, self.problem)  # type: ignore[arg-type]
            yield from joint_bound(
                self.inst, self.cands.position, standing, fewest, s.mast_cost,
                float(sensor_price(self.problem, self.cands)), float(sensors), columns,
                np.flatnonzero(duals > 0), self.best, self.solved, self.deadline, self.stop,
                s.tight_bound,
            )  # fmt: skip
        return value

    def _start(self) -> tuple[I64, F64, int] | None:
        """(columns, point duals, the sensors bound) to start from, None while the
        fewest masts or the LP's duals are not known."""
        if self.sites is None:
            return None
        if self.lp is not None and self.lp.pi is not None:
            return self.lp.columns, self.lp.pi, self.lp.integer_bound()
        step = self.latest
        if step is None or step.duals is None or step.in_lp is None:
            return None
        sensors = max(0, math.ceil(step.bound - 1e-6))
        if self._cap_may_rise(sensors, step.value):
            return None
        return step.in_lp, step.duals, sensors

    def _cap_may_rise(self, sensors: int, value: float) -> bool:
        """Whether the LP, still at work, may yet prove that more masts are needed
        than the joint LP would start at: the sensors at the cap need more once its
        bound (``sensors`` now) reaches the restricted LP's ``value``, which is never
        below the LP's. At k = 2 on two_routes the fewest masts are 13 and the
        sensors end at 62, 16 masts at the cap: the joint LPs started at 14 and 15
        masts proved only that (150 s), and on the second core they slowed the LP,
        which took until second 190 to end (24 rounds, 79 s alone)."""
        if not math.isfinite(value):
            return True
        assert self.sites is not None
        most = math.ceil(value - 1e-6)
        return _masts_bound(self.sites, most, self.problem) > _masts_bound(
            self.sites, sensors, self.problem
        )


def _by_windows(inst: CoverInstance, part: PartInputs | None) -> bool:
    """Whether the plan is improved by windows (``_then_windows``): at k > 1 on a
    ground planned whole."""
    return part is None and inst.multi


class _Windows:
    """Windows (``neighbourhoods.improve``) on the best plan so far (``held``), run a
    step at a time by whichever search has a core to spare: the joint LP's while it
    waits for the sensors LP (``_JointStart.then``), the sensors LP's once it has
    ended (``_then_windows``). They go on from the plan they have reached unless a
    better one has come from elsewhere (the plan on the LP's columns), and then start
    again from that. At k > 1 only: there the mast-aware MILP over the plan's masts
    is too large (``MAX_MULTI_MILP_CANDIDATES``) and the plans are greedy's. On
    two_routes at k = 2 the joint LP waited from about 45 s to 1 min 18-31 s, and the
    LP ended at 2 min 06-20 s (three runs, 2026-11-30).

    The windows alternate with plans rounded from the LP on the plan's own masts
    (``rounded_on_masts``): those re-choose every sensor of the plan at once, where a
    window re-plans a few masts, and the windows move masts, which the rounding
    cannot. On two_routes at k = 2, from a plan of 152 (offline, one core,
    2026-12-08) the windows alone reached 140 in 180 s; rounded first and then
    alternating, 130 (70 sensors on 20 masts) at 99 s."""

    def __init__(
        self,
        problem: Problem,
        cands: CandidateSet,
        inst: CoverInstance,
        held: _Held,
        deadline: float | None,
        stop: threading.Event | None,
    ) -> None:
        self.problem, self.cands, self.inst, self.held = problem, cands, inst, held
        self.deadline, self.stop = deadline, stop
        self.costs = mast_aware_costs(problem, cands, len(cands))
        self.gen: Generator[list[int] | None, None, None] | None = None
        self.value = math.inf  # the plan the windows have reached (or ended on)

    def steps(self) -> Generator[Incumbent | None, None, None]:
        """Steps of the search until it ends (or the best plan is no plan), each
        cheaper plan as an ``Incumbent``, None while HiGHS works."""
        while self.held.chosen:
            if self.held.value < self.value:  # (re)start from the best plan so far
                if self.gen is not None:
                    self.gen.close()
                self.value = self.held.value
                self.gen = self._alternate(self.held.chosen)
            if self.gen is None:
                return  # ended on the best plan so far
            try:
                plan = next(self.gen)
            except StopIteration:
                self.gen = None
                return
            if plan is None:
                yield None
            else:
                self.value = plan_value(self.problem, self.cands, plan)
                yield Incumbent(self.value, plan)

    def _alternate(self, plan: list[int]) -> Generator[list[int] | None, None, None]:
        """Plans cheaper than ``plan``, each as found (None while HiGHS works): the
        cheapest plan rounded from the LP on its masts, taken when no dearer and not
        one the search has been at, then windows from it; when they have found
        nothing cheaper for ``STALL_S`` (kept where they are), or have ended, a
        rounding again from the plan they reached, if it changed since the last;
        until the windows end with nothing new to round, or the deadline."""
        value = partial(plan_value, self.problem, self.cands)
        seen: set[frozenset[int]] = set()  # plans rounded from, or taken from a rounding
        windows: Generator[list[int] | None, None, list[int]] | None = None
        ended = False  # the windows have ended on ``plan``
        while not self._over():
            if frozenset(plan) not in seen:
                seen.add(frozenset(plan))
                _, rounded = yield from rounded_on_masts(
                    self.problem, self.cands, self.inst, plan, self.deadline, self.stop
                )
                fresh = [p for p in rounded if frozenset(p) not in seen and value(p) <= value(plan)]
                if fresh:
                    new = min(fresh, key=value)
                    seen.add(frozenset(new))
                    if value(new) < value(plan):
                        yield new
                    plan, ended = new, False
                    if windows is not None:
                        windows.close()
                        windows = None
            if ended:
                return
            if windows is None:
                windows = improve_by_windows(
                    self.inst, self.cands.position, self.cands.positions, plan, *self.costs,
                    self.deadline, self.stop,
                )  # fmt: skip
            quiet = time.perf_counter()
            while frozenset(plan) in seen or time.perf_counter() - quiet <= STALL_S:
                try:
                    step = next(windows)
                except StopIteration:
                    windows, ended = None, True
                    break
                if step is not None:
                    plan, quiet = step, time.perf_counter()
                yield step

    def _over(self) -> bool:
        return (self.stop is not None and self.stop.is_set()) or (
            self.deadline is not None and time.perf_counter() >= self.deadline
        )


def _then_windows(
    problem: Problem,
    cands: CandidateSet,
    inst: CoverInstance,
    windows: _Windows,
    lp_side: Generator[Any, None, LPSolution],
) -> Generator[Any, None, LPSolution]:
    """``lp_side``'s value (the LP); once it ends, the plans greedy per cost builds on
    the LP's columns (``plan_from``; those above each of ``ABOVE``), each yielded as
    an ``Incumbent``, and then the ``windows`` (from the best plan so far) while the
    time lasts. On two_routes at k = 2 the windows took the default run's plan from
    146 (on the LP's columns) to 137 in 70 s, and in another run from 142 to 139
    (2026-11-30)."""
    lp = yield from lp_side
    if not len(lp.columns):
        return lp
    began, values = time.perf_counter(), []
    for above in ABOVE:
        if windows.stop is not None and windows.stop.is_set():
            return lp
        on_lp = plan_from(problem, cands, inst, lp.columns[lp.x > above + 1e-9])
        if on_lp.slack >= 0:
            values.append(plan_value(problem, cands, on_lp.chosen))
            yield Incumbent(values[-1], on_lp.chosen)
    log.info(
        "plans on the LP's columns above %s: %s in %.1f s", ABOVE, values,
        time.perf_counter() - began,
    )  # fmt: skip
    yield from windows.steps()
    return lp


def _progress(
    gen: Generator[None, None, T],
    solution: Solution,
    problem: Problem,
    best: float,
    plan_bound: PlanBound,
    stage: str = "bounds",
) -> Generator[Progress, None, T]:
    """``gen``'s value, with a progress report (the bound so far and ``best``, at
    ``stage``) each time it yields."""
    s = problem.settings
    lower = plan_bound.objective(s.objective, s.mast_cost, s.sensor_cost)
    while True:
        try:
            next(gen)
        except StopIteration as done:
            return done.value
        yield solution.progress("search", problem.rho, bound=lower, best=best, stage=stage)


def _on_masts(
    problem: Problem,
    cands: CandidateSet,
    inst: CoverInstance,
    solution: Solution,
    chosen: list[int],
    bound: PlanBound,
    deadline: float | None,
    stop: threading.Event | None,
) -> Generator[Progress, None, tuple[PlanBound, list[int]]]:
    """(``bound`` with the fewest new sensors of any plan on ``chosen``'s masts and
    those that stood already, the plan): the LP on those masts and the plans rounded
    from it (``rounded_on_masts``) where a gap is left for it to explain; the plan is
    the cheapest of ``chosen`` and those. Unless stopped."""
    s = problem.settings
    best = plan_value(problem, cands, chosen)
    late = deadline is not None and time.perf_counter() >= deadline
    if not chosen or best <= bound.objective(s.objective, s.mast_cost, s.sensor_cost) or late:
        return bound, chosen
    lp, rounded = yield from _progress(
        rounded_on_masts(problem, cands, inst, chosen, deadline, stop),
        solution, problem, best, bound, "plans",
    )  # fmt: skip
    bound = dataclasses.replace(bound, on_masts=whole_sensors(lp.bound))
    plans = [chosen, *rounded]
    lower = bound.objective(s.objective, s.mast_cost, s.sensor_cost)
    yield _at_plans(problem, cands, solution, lower, plans)
    return bound, min(plans, key=lambda p: plan_value(problem, cands, p))


def rounded_on_masts(
    problem: Problem,
    cands: CandidateSet,
    inst: CoverInstance,
    chosen: list[int],
    deadline: float | None,
    stop: threading.Event | None,
) -> Generator[None, None, tuple[OnMasts, list[list[int]]]]:
    """(the LP of the fewest new sensors on ``chosen``'s masts and those that stood
    already, the plans rounded from it that reach the goal): ``joint.sensors_on_masts``
    (on two_routes 0.65 s, at k = 2 3.9 s), then ``plan_on_masts`` at each of
    ``ON_MASTS_THRESHOLDS`` while the time before ``deadline`` lasts."""
    sites = np.union1d(cands.position[chosen], np.flatnonzero(problem.space.standing))
    lp = yield from sensors_on_masts(inst, cands.position, sites, deadline, stop)
    mc, sc = mast_aware_costs(problem, cands, len(lp.cols))
    plans = []
    for threshold in ON_MASTS_THRESHOLDS:
        if lp.x is None or (stop is not None and stop.is_set()):
            break
        if deadline is not None and time.perf_counter() >= deadline:
            break
        rounded = plan_on_masts(inst, cands.position, lp.cols, lp.x, threshold, mc, sc)
        if rounded.slack >= 0:
            plans.append(rounded.chosen)
        yield None
    if log.isEnabledFor(logging.INFO):
        log.info(
            "plans rounded from the LP on the plan's %d masts (%.2f): %s",
            len(sites), lp.bound, [plan_value(problem, cands, p) for p in [chosen, *plans]],
        )  # fmt: skip
    return lp, plans


def plan_on_masts(
    inst: CoverInstance,
    site_of: I64,
    cols: I64,
    x: F64,
    threshold: float,
    mast_cost: MastCost,
    sensor_cost: SensorCost,
) -> Cover:
    """A plan on the masts of ``cols`` (candidates; site_of: (C,) each one's mast) from
    an LP's solution x (len(cols),) over them (``joint.sensors_on_masts``): the
    candidates at ``threshold`` or above, the largest x first, each where its mast has
    room; completed by greedy per cost from ``cols``, improved, and with masts closed
    while that is cheaper. At k = 2 on two_routes, on 23 masts of a plan of 83 sensors
    (152): 135-138, 0.7-0.8 s each."""
    above = np.flatnonzero(x >= threshold - 1e-9)
    plan = Cover(inst)
    for c in cols[above[np.argsort(-x[above], kind="stable")]]:
        if not plan.full(int(site_of[c])):
            plan.add(int(c))
    plan = complete(plan, cols, site_of, mast_cost, sensor_cost)
    return close_sites(improve(plan, cols, sensor_cost), site_of, mast_cost, sensor_cost)


def _joint_bound(
    problem: Problem,
    cands: CandidateSet,
    inst: CoverInstance,
    lp: LPSolution,
    plan_bound: PlanBound,
    best: float,
    solved: list[MastsSensors],
    deadline: float | None,
    stop: threading.Event | None,
) -> Generator[None, None, PlanBound]:
    """``plan_bound`` with the joint bound on cost (``joint.joint_bound``; ``solved``:
    its LPs solved already), from the LP's last columns and duals."""
    s = problem.settings
    assert lp.pi is not None
    joint = yield from joint_bound(
        inst, cands.position, problem.space.standing, plan_bound.masts or 0, s.mast_cost,
        float(sensor_price(problem, cands)), float(plan_bound.sensors), lp.columns,
        np.flatnonzero(lp.pi > 0), best, solved, deadline, stop, s.tight_bound,
    )  # fmt: skip
    return dataclasses.replace(plan_bound, joint=max(plan_bound.joint, joint))


def prove_and_plan(
    problem: Problem,
    cands: CandidateSet,
    inst: CoverInstance,
    solution: Solution,
    deadline: float | None,
    stop: threading.Event | None = None,
    part: PartInputs | None = None,
) -> Generator[Progress, None, tuple[list[int], PlanBound, LPSolution]]:
    """The bounds, the best plan of candidates (see the module docstring) and the LP;
    ``stop`` ends the search early: the bounds so far and the best plan found by then
    (no more are rounded from the LP: a stopped run ends within 5 s). part: as for
    ``prove_bound``."""
    s = problem.settings

    def value(plan: list[int]) -> float:
        return plan_value(problem, cands, plan)

    bound, lp, on_sites, greedies = yield from prove_bound(
        problem, cands, inst, solution, deadline, stop, True, part
    )
    lower = bound.objective(s.objective, s.mast_cost, s.sensor_cost)
    plans = [g.chosen for g in greedies if g.slack >= 0] + ([on_sites] if on_sites else [])
    # At k > 1 on a whole ground ``_then_windows`` built this plan already.
    if len(lp.columns) and (stop is None or not stop.is_set()) and not _by_windows(inst, part):
        # The LP spreads a k > 1 cover over sites that the fewest masts, which count
        # what a site sees once and not the sensors it can carry, do not show: on
        # two_routes at k = 2 this plan was 76 sensors on 22 masts (142; 136 over
        # the LP solved to its end) where those on the fewest masts' sites were 83
        # on 24 (155). At k = 1 it is worse than those (82-86 against 74; 57-67
        # against 51 on Town01's first part), and the cheapest plan is kept.
        on_lp = plan_from(problem, cands, inst, lp.columns[lp.x > 1e-9])
        if on_lp.slack >= 0:
            plans.append(on_lp.chosen)
    plans = plans or [greedies[0].chosen]  # short of the goal: the most greedy covers
    yield _at_plans(problem, cands, solution, lower, plans)
    price = sensor_price(problem, cands) if s.objective == "cost" else 1.0
    # Plans rounded from the LP are rounded for the sensors alone, so only where masts
    # cost nothing. Where they do, they never won: on two_routes 128-146 against 74 at
    # k = 1 and 244-270 against 142 at k = 2, and took 8-15 s and 7-62 s
    # (2026-11-27 to 29); on Town01's 3 parts and Town04's 8, 80-200 where the plan
    # chosen was 47-137, for 1-16 s a part (2026-11-27).
    masts_count = s.objective == "masts" or (s.objective == "cost" and s.mast_cost > 0)
    rounded = _lp_plans(inst, lp, price) if part is None and not masts_count else iter(())
    found = len(plans)
    began = time.perf_counter()
    while stop is None or not stop.is_set():  # each plan is rounded only when asked for
        if deadline is not None and time.perf_counter() > deadline and len(plans) > found:
            # Past the deadline, one: at k = 2 on two_routes the five took 62 s
            # after a 240 s limit (2026-11-28).
            break
        plan = next(rounded, None)
        if plan is None:
            break
        plans.append(plan)
        yield _at_plans(problem, cands, solution, lower, plans)
    if log.isEnabledFor(logging.INFO):
        log.info(
            "plans: greedy, on the masts and on the LP's columns %s, rounded from the LP %s"
            " in %.1f s",
            [value(p) for p in plans[:found]], [value(p) for p in plans[found:]],
            time.perf_counter() - began,
        )  # fmt: skip
    return min(plans, key=value), bound, lp


def bound_only(problem: Problem, solution: Solution) -> Generator[Progress, None, PlanBound]:
    """The lower bound of the whole problem, for a plan another optimizer made (the
    ES's or greedy's, asked with ``bound = true``), on what it adds to the sensors
    that stood already."""
    cands = yield from candidates_of(problem, solution)
    # What the sensors that stood already cover is not the plan's to cover.
    counts = np.zeros(problem.n_targets, dtype=np.int32)
    for f in solution.sensors:
        if f.existing:
            counts[f.newly if f.seen is None else f.seen] += 1
    inst = instance(cands, problem, counts >= problem.need, counts)
    s = problem.settings
    deadline = None if s.time_limit_s is None else time.perf_counter() + s.time_limit_s
    bound, *_ = yield from prove_bound(problem, cands, inst, solution, deadline)
    solution.ahead = []  # the plan is another optimizer's
    return bound


def capped_masts(sensors: int, cap: int, standing: int) -> int:
    """The fewest new masts that can carry ``sensors`` new sensors at ``cap`` a mast,
    when ``standing`` masts stand already, each with room for ``cap`` (the sensors
    on them before the plan do not count against it)."""
    return max(0, math.ceil((sensors - cap * standing) / cap))


def _masts_bound(sites: SiteSolution, sensors: int, problem: Problem) -> int:
    """The fewest new masts: the fewest-masts MILP's (which does not know of the
    sensors-per-mast cap), or more when the fewest sensors cannot fit on that many."""
    standing = int(np.count_nonzero(problem.space.standing))
    return max(sites.bound, capped_masts(sensors, problem.settings.max_sensors_per_mast, standing))


def _plan_bound(
    lp: LPSolution, sites: SiteSolution, cands: CandidateSet, problem: Problem
) -> PlanBound:
    s = problem.settings
    price = sensor_price(problem, cands) if s.objective == "cost" else s.sensor_cost
    per_site = _per_site(problem, s.mast_cost)
    if np.ndim(price) == 0:
        sensors = lp.integer_bound()
        return PlanBound(
            sensors=sensors,
            masts=_masts_bound(sites, sensors, problem),
            lp=lp.bound,
            scope=bound_scope(cands, problem),
            rounds=lp.rounds,
            cost_lp=mast_aware_bound(lp, cands.position, per_site, float(price)),
            sensor_cost_lp=float(price) * sensors,
        )
    # The LP priced each candidate at its model's cost: it bounds the sensors' cost,
    # and the count through the dearest model (no sensor costs more).
    price = np.asarray(price)
    dearest = float(price.max())
    sensors = max(0, math.ceil(lp.bound / dearest - 1e-6)) if dearest > 0 else 0
    return PlanBound(
        sensors=sensors,
        masts=_masts_bound(sites, sensors, problem),
        lp=lp.bound,
        scope=bound_scope(cands, problem),
        rounds=lp.rounds,
        cost_lp=mast_aware_bound(lp, cands.position, per_site, 1.0, price),
        sensor_cost_lp=lp.bound,
    )


def _pool(lp: LPSolution) -> I64:
    """The candidates plans are built from: the LP's, and those nearly as good."""
    return np.union1d(lp.columns, np.flatnonzero(lp.reduced <= POOL_REDUCED_COST))


def _lp_plans(inst: CoverInstance, lp: LPSolution, price: SensorCost = 1.0) -> Iterator[list[int]]:
    """Plans rounded from the LP at each threshold, completed (per ``price``, one
    sensor's cost) and improved."""
    pool = _pool(lp)
    for threshold in THRESHOLDS:
        kept = lp.columns[lp.x >= threshold - 1e-9]
        cover = Cover(inst, tuple(int(c) for c in kept))
        cover = improve(complete(cover, pool, sensor_cost=price), pool, price)
        if cover.slack >= 0:
            yield cover.chosen


def in_gain_order(inst: CoverInstance, chosen: list[int]) -> list[int]:
    """The plan's candidates ordered as greedy would fix them: the most points raised
    towards their k first (k = 1: the most new points)."""
    left = list(chosen)
    count = np.zeros(inst.n_points, dtype=np.int32)
    out = []
    while left:
        gains = [
            int(np.count_nonzero(count[inst.covers(c)] < inst.k[inst.covers(c)])) for c in left
        ]
        c = left.pop(int(np.argmax(gains)))
        count[inst.covers(c)] += 1
        out.append(c)
    return out


def solve_whole(
    problem: Problem,
    solution: Solution,
    deadline: float | None,
    stop: threading.Event,
    proof_deadline: float | None = None,
) -> Generator[Progress, None, Solution]:
    """The lp optimizer on the whole ground at once (see the module docstring): the
    candidate set, the bounds and the best plan, whose sensors it then fixes.
    proof_deadline: when the LP of the sensors on the plan's own masts and the plans
    rounded from it must end (default: ``deadline``)."""
    cands = yield from candidates_until(problem, solution, stop)
    if cands is None:
        solution.stop_reason = StopReason.stopped_before_plan()
        return solution
    inst = instance(
        cands, problem, solution.covered, solution.counts, taken_candidates(cands, solution.sensors)
    )
    if problem.reached(solution.n_covered) or inst.goal <= 0:
        solution.stop_reason = (
            StopReason.reached(problem.rho)
            if problem.reached(solution.n_covered)
            else StopReason.out_of_sight("candidate pose")
        )
        return solution
    chosen, bound, _ = yield from prove_and_plan(problem, cands, inst, solution, deadline, stop)
    solution.bound, chosen = yield from _on_masts(
        problem, cands, inst, solution, chosen, bound,
        deadline if proof_deadline is None else proof_deadline, stop,
    )  # fmt: skip
    order = in_gain_order(inst, chosen)
    # In the order they are fixed: those the goal leaves unfixed last, made ready last.
    solution.ahead = sensors_of(problem, cands, order)
    for c in order:
        if problem.reached(solution.n_covered):
            break
        if len(solution.sensors) >= problem.max_sensors:
            solution.stop_reason = StopReason.sensor_limit(problem.max_sensors)
            return solution
        sensor = fix_candidate(problem, solution, cands, c)
        yield solution.progress("fixed", problem.rho, fixed=sensor, stage="fixing")
    solution.ahead = []  # the plan is fixed: the report needs its sensors alone
    late = stop.is_set() or (deadline is not None and time.perf_counter() > deadline)
    if problem.reached(solution.n_covered):
        solution.stop_reason = StopReason.reached(problem.rho, early=late)
    else:
        solution.stop_reason = StopReason.out_of_sight("candidate pose")
    return solution
