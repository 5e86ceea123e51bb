"""Proven lower bounds over the candidate set: the LP by column generation, and masts.

**Sensors.** The LP relaxation of "the fewest candidates that cover at least ``goal``
target points":

    min  sum_c cost_c x_c
    s.t. sum_{c covers n} x_c - u_n >= 0     for every point n   (dual pi_n >= 0)
         sum_n u_n >= goal                                        (dual sigma)
         0 <= u_n <= 1,  x_c >= 0

is solved by column generation: a restricted LP (HiGHS, warm started) holds a few
thousand candidates; its point duals price every candidate with one sparse product,
``reduced_c = cost_c - (M pi)_c``; the best candidate of each of the ``per_round``
most promising positions joins (one per position: neighbouring orientations at one
position are nearly the same column, and adding them all slows the LP down). An
artificial column (cost 1 per point of the demand) keeps the restricted LP feasible.

At every round the duals, scaled by ``t = min(1, min_c cost_c / (M pi)_c)``, are
feasible for the dual of the full LP, so ``t z`` is a proven lower bound on it
(Farley's bound; ``z`` the restricted LP's value). When no candidate has a negative
reduced cost the bound equals ``z``, the LP value. For integer objectives the search
may stop as soon as ``ceil(bound) == ceil(z)``: the integer bound cannot rise further.

**Masts.** The fewest mast positions whose candidates together cover ``goal`` points:
a small MILP over positions (each covers the union of its candidates' points),
solved by HiGHS; its proven dual bound is the masts bound, and its solution a set of
sites a plan may use.

**Masts and sensors together.** The mast-aware model links each candidate to its
mast's site, ``x_c <= y_s``, and costs ``mast_cost`` per open site plus
``sensor_cost`` per candidate. Its LP relaxation is weak (a fractional plan opens
sites as fractionally as it picks candidates: on ``two_routes`` its value falls below
50, far under the 70 of the masts and sensors bounds added), so its bound is taken
cheaply from the sensors LP's duals (``mast_aware_bound``). As a MILP over the sites
of the fewest masts (``sensors_on_sites``) it is exact and small: the fewest sensors
(and cost) on those sites, started from a greedy plan on them.

Solves run in a thread and the generators yield while they wait, so a caller (the
Blender operator) stays responsive; closing the generator cancels the solve.
"""

from __future__ import annotations

import math
import threading
import time
from collections.abc import Generator
from dataclasses import dataclass

import highspy
import numpy as np
from numpy.typing import NDArray
from scipy import sparse

from .cover import CoverInstance

F64 = NDArray[np.float64]
I64 = NDArray[np.int64]

# How often a waiting generator yields, s.
POLL_S = 0.05
# A bound is lowered by this much (relative) against the solver's tolerances.
SAFETY = 1e-6
# Branch-and-bound nodes of the mast-aware MILP: a limit in work, not seconds, so the
# plan is the same on a fast and a slow machine.
MAX_NODES = 2000


def _run(h: highspy.Highs, stop: threading.Event | None = None) -> Generator[None, None, bool]:
    """Run ``h`` in a thread, yielding while it works; cancel it if closed early or
    when ``stop`` is set. Returns whether the solve ran to its end."""
    done = threading.Event()

    def work() -> None:
        h.run()
        done.set()

    thread = threading.Thread(target=work, daemon=True)
    thread.start()
    stopped = False
    try:
        while not done.wait(POLL_S):
            if stop is not None and stop.is_set() and not stopped:
                h.cancelSolve()
                stopped = True
            yield
    finally:
        if not done.is_set():
            h.cancelSolve()
        thread.join()
    return not stopped


def _empty_rows(h: highspy.Highs, lower: F64, upper: F64) -> None:
    none = np.zeros(0, dtype=np.int32)
    h.addRows(len(lower), lower, upper, 0, none, none, np.zeros(0))


def _add_columns(
    h: highspy.Highs, matrix: sparse.csr_matrix, cost: F64, upper: float | F64
) -> None:
    """Columns of the LP from rows of a CSR matrix (a candidate's points are its rows)."""
    n = matrix.shape[0]
    h.addCols(
        n,
        np.asarray(cost, dtype=float),
        np.zeros(n),
        np.broadcast_to(np.asarray(upper, dtype=float), (n,)).copy(),
        matrix.nnz,
        matrix.indptr[:-1].astype(np.int32),
        matrix.indices.astype(np.int32),
        np.ones(matrix.nnz),
    )


def _new_highs(time_limit_s: float | None) -> highspy.Highs:
    h = highspy.Highs()
    h.setOptionValue("output_flag", False)
    h.setOptionValue("threads", 1)
    if time_limit_s is not None:
        h.setOptionValue("time_limit", max(float(time_limit_s), 0.01))
    return h


def _cover_rows(h: highspy.Highs, n_points: int, goal: int) -> None:
    """Rows ``covering - u_n >= 0`` for every point, ``sum u >= goal``, and the u."""
    inf = highspy.kHighsInf
    _empty_rows(h, np.concatenate([np.zeros(n_points), [float(goal)]]), np.full(n_points + 1, inf))
    idx = np.empty(2 * n_points, dtype=np.int32)
    idx[0::2] = np.arange(n_points)
    idx[1::2] = n_points
    val = np.empty(2 * n_points)
    val[0::2], val[1::2] = -1.0, 1.0
    starts = (np.arange(n_points) * 2).astype(np.int32)
    h.addCols(
        n_points,
        np.zeros(n_points),
        np.zeros(n_points),
        np.ones(n_points),
        2 * n_points,
        starts,
        idx,
        val,
    )


@dataclass(frozen=True)
class LPProgress:
    """One round of column generation: the restricted LP's value and the bound."""

    rounds: int
    value: float
    bound: float
    columns: int


@dataclass(frozen=True)
class LPSolution:
    """The LP relaxation as far as it was solved.

    value: the restricted LP's optimum (the full LP's value when ``complete``); bound:
    a proven lower bound on the full LP's value; columns, x: the candidates in the
    restricted LP and their values; priced, reduced: (C,) every candidate's dual
    weight (the last point duals summed over its points) and its reduced cost, cost
    less that; complete: no candidate could improve the LP any more.
    """

    value: float
    bound: float
    columns: I64
    x: F64
    priced: F64
    reduced: F64
    rounds: int
    complete: bool

    def integer_bound(self) -> int:
        """The bound on an integer objective: the next integer at or above it."""
        return max(0, math.ceil(self.bound - 1e-6))


def cover_lp(
    inst: CoverInstance,
    cost: F64,
    group: I64,
    initial: I64,
    per_round: int = 50,
    integral: bool = True,
    deadline: float | None = None,
    stop: threading.Event | None = None,
) -> Generator[LPProgress | None, None, LPSolution]:
    """The LP relaxation by column generation (see the module docstring).

    cost: (C,) > 0 per candidate; group: (C,) its position (one new column per group
    and round); initial: candidates to start from (e.g. a greedy plan); integral: stop
    once the integer bound is final; deadline: ``time.perf_counter()`` to stop at, and
    stop: an event to stop at once (the bound then holds, the LP is not complete; a
    round cut short is dropped). Yields None while HiGHS works and an ``LPProgress``
    after each round.
    """
    matrix, n = inst.matrix, inst.n_points
    h = _new_highs(None)
    _cover_rows(h, n, inst.goal)
    # The artificial demand slack: 1 per point, so the restricted LP is always feasible.
    h.addCols(
        1,
        np.ones(1),
        np.zeros(1),
        np.full(1, highspy.kHighsInf),
        1,
        np.zeros(1, np.int32),
        np.array([n], np.int32),
        np.ones(1),
    )
    first = n + 1  # index of the first candidate column
    in_lp = np.zeros(matrix.shape[0], dtype=bool)
    order: list[int] = []

    def add(cols: I64) -> None:
        cols = cols[~in_lp[cols]]
        in_lp[cols] = True
        order.extend(int(c) for c in cols)
        if len(cols):
            _add_columns(h, matrix[cols], cost[cols], highspy.kHighsInf)

    add(np.unique(np.asarray(initial, dtype=np.int64)))
    best = 0.0
    rounds = 0
    # Before any round: the initial columns as the plan, no bound, nothing priced.
    last = LPSolution(
        np.inf, 0.0, np.array(order, dtype=np.int64), np.ones(len(order)),
        np.zeros(0), np.full(matrix.shape[0], np.inf), 0, False,
    )  # fmt: skip
    while True:
        rounds += 1
        if not (yield from _run(h, stop)):
            return last  # stopped in the middle of a solve: its values are not optimal
        sol = h.getSolution()
        value = float(h.getInfo().objective_function_value)
        duals = np.asarray(sol.row_dual)[:n]
        priced = np.asarray(matrix @ duals.astype(matrix.dtype), dtype=float)
        reduced = cost - priced
        with np.errstate(divide="ignore"):
            scale = min(1.0, float(np.min(np.where(priced > 0, cost / priced, np.inf))))
        best = max(best, scale * value * (1 - SAFETY) - SAFETY)
        yield LPProgress(rounds, value, best, len(order))
        negative = np.flatnonzero(reduced < -1e-9)
        complete = len(negative) == 0
        done_int = integral and math.ceil(best - 1e-6) >= math.ceil(value - 1e-6)
        late = deadline is not None and time.perf_counter() > deadline
        late = late or (stop is not None and stop.is_set())
        if complete:
            best = max(best, value * (1 - SAFETY) - SAFETY)
        x = np.asarray(sol.col_value)[first:]
        last = LPSolution(
            value, best, np.array(order, dtype=np.int64), x, priced, reduced, rounds, complete
        )
        if complete or done_int or late:
            return last
        # The best candidate of each group, the most negative groups first.
        by_group = negative[np.lexsort((reduced[negative], group[negative]))]
        firsts = by_group[np.r_[True, group[by_group][1:] != group[by_group][:-1]]]
        add(firsts[np.argsort(reduced[firsts], kind="stable")[:per_round]])


def mast_aware_bound(lp: LPSolution, site_of: I64, mast_cost: float, sensor_cost: float) -> float:
    """A proven lower bound on the mast-aware LP (so on the cost of every plan) from
    the last duals of the sensors LP (solved with unit costs): scaled by the largest
    ``t`` for which every site ``s`` can share ``mast_cost`` out as the link duals its
    candidates need, ``sum_{c at s} max(0, sensor_cost (t priced_c - 1)) <=
    mast_cost``, they are feasible for the mast-aware LP's dual, whose value is then
    ``t sensor_cost value``. 0 when nothing was solved."""
    if not np.isfinite(lp.value) or len(lp.priced) == 0 or sensor_cost <= 0:
        return 0.0
    n_sites = int(site_of.max()) + 1

    def fits(t: float) -> bool:
        excess = np.maximum(0.0, sensor_cost * (t * lp.priced - 1.0))
        return bool((np.bincount(site_of, weights=excess, minlength=n_sites) <= mast_cost).all())

    lo, hi = 0.0, 1.0
    while fits(hi) and hi < 1e6:  # the feasible t may exceed 1
        lo, hi = hi, 2 * hi
    for _ in range(50):  # bisection; lo stays feasible
        mid = (lo + hi) / 2
        lo, hi = (mid, hi) if fits(mid) else (lo, mid)
    return max(0.0, lo * sensor_cost * lp.value * (1 - SAFETY) - SAFETY)


@dataclass(frozen=True)
class SiteSolution:
    """The fewest sites covering the goal: a proven lower bound, and the best set found
    (optimal when ``bound == len(sites)``)."""

    bound: int
    sites: I64


def site_cover(
    inst: CoverInstance,
    site_of: I64,
    n_sites: int,
    deadline: float | None = None,
    stop: threading.Event | None = None,
) -> Generator[None, None, SiteSolution]:
    """The fewest sites (mast positions) whose candidates cover the goal: a MILP over
    sites (see the module docstring); stops at ``deadline``, or when ``stop`` is set,
    with the bound proven so far and the best set found.
    """
    m = inst.matrix
    # Site s covers point n when any candidate at s does.
    pick = sparse.csr_matrix(
        (np.ones(len(site_of)), (site_of, np.arange(len(site_of)))), shape=(n_sites, m.shape[0])
    )
    sites = (pick @ sparse.csr_matrix((np.ones(m.nnz), m.indices, m.indptr), shape=m.shape)).tocsr()
    limit = None if deadline is None else deadline - time.perf_counter()
    h = _new_highs(limit)
    _cover_rows(h, inst.n_points, inst.goal)
    _add_columns(h, sites, np.ones(n_sites), 1.0)
    n = inst.n_points
    h.changeColsIntegrality(
        n_sites,
        np.arange(n, n + n_sites, dtype=np.int32),
        np.array([highspy.HighsVarType.kInteger] * n_sites),
    )
    yield from _run(h, stop)
    info = h.getInfo()
    if h.getModelStatus() == highspy.HighsModelStatus.kOptimal:
        bound = round(float(info.objective_function_value))
    else:  # stopped early: the dual bound so far (none yet: 0)
        dual = float(info.mip_dual_bound)
        bound = max(0, math.ceil(dual - 1e-6)) if math.isfinite(dual) else 0
    values = np.asarray(h.getSolution().col_value)
    chosen = np.zeros(0, dtype=np.int64)
    if len(values) == n + n_sites and info.primal_solution_status == 2:  # feasible
        chosen = np.flatnonzero(values[n:] > 0.5).astype(np.int64)
    return SiteSolution(bound, chosen)


def sensors_on_sites(
    inst: CoverInstance,
    site_of: I64,
    sites: I64,
    start: list[int],
    mast_cost: float,
    sensor_cost: float,
    deadline: float | None = None,
    stop: threading.Event | None = None,
) -> Generator[None, None, list[int]]:
    """The best plan on ``sites`` by the mast-aware MILP: every candidate at those
    sites (x_c, binary, ``sensor_cost``), each site (y_s, binary, ``mast_cost``),
    ``x_c <= y_s``, and the cover rows. ``start`` (candidates at those sites that
    reach the goal) is HiGHS' first incumbent. At most ``MAX_NODES`` branch-and-bound
    nodes, so the answer does not depend on the machine's speed; stops at ``deadline``
    or ``stop`` with the best plan so far. Returns the chosen candidates."""
    cols = np.flatnonzero(np.isin(site_of, sites)).astype(np.int64)
    site_idx = np.searchsorted(sites, site_of[cols])
    n, n_cols, n_sites = inst.n_points, len(cols), len(sites)
    limit = None if deadline is None else deadline - time.perf_counter()
    h = _new_highs(limit)
    h.setOptionValue("mip_max_nodes", MAX_NODES)
    _cover_rows(h, n, inst.goal)
    _add_columns(h, inst.matrix[cols], np.full(n_cols, sensor_cost), 1.0)
    none = np.zeros(0, dtype=np.int32)
    h.addCols(n_sites, np.full(n_sites, mast_cost), np.zeros(n_sites), np.ones(n_sites), 0,
              np.zeros(n_sites, dtype=np.int32), none, np.zeros(0))  # fmt: skip
    # x_c - y_s <= 0, one row per candidate
    index = np.empty(2 * n_cols, dtype=np.int32)
    index[0::2] = n + np.arange(n_cols)
    index[1::2] = n + n_cols + site_idx
    value = np.tile([1.0, -1.0], n_cols)
    h.addRows(n_cols, np.full(n_cols, -highspy.kHighsInf), np.zeros(n_cols), 2 * n_cols,
              (2 * np.arange(n_cols)).astype(np.int32), index, value)  # fmt: skip
    binary = np.arange(n, n + n_cols + n_sites, dtype=np.int32)
    h.changeColsIntegrality(
        len(binary), binary, np.array([highspy.HighsVarType.kInteger] * len(binary))
    )
    picked = np.isin(cols, start)
    covered = np.zeros(n, dtype=bool)
    for c in cols[picked]:
        covered[inst.covers(int(c))] = True
    first = highspy.HighsSolution()
    first.col_value = (
        np.concatenate([covered, picked, np.isin(np.arange(n_sites), site_idx[picked])])
        .astype(float)
        .tolist()
    )
    h.setSolution(first)
    yield from _run(h, stop)
    values = np.asarray(h.getSolution().col_value)
    if len(values) != n + n_cols + n_sites or h.getInfo().primal_solution_status != 2:
        return list(start)
    return [int(c) for c in cols[values[n : n + n_cols] > 0.5]]
