"""Proven lower bounds over the candidate set: the LP by column generation, and masts.

**Sensors.** The LP relaxation of "the fewest candidates that cover at least ``goal``
target points":

    min  sum_c cost_c x_c
    s.t. sum_{c covers n} x_c - u_n >= 0     for every point n   (dual pi_n >= 0)
         sum_n u_n >= goal                                        (dual sigma)
         0 <= u_n <= 1,  x_c >= 0

is solved by column generation: a restricted LP (HiGHS, warm started) holds a few
thousand candidates, over its points merged where they cover them alike
(``_Restricted``); its point duals price every candidate with one sparse product,
``reduced_c = cost_c - (M pi)_c``; the best candidate of each of the ``per_round``
most promising positions joins (one per position: neighbouring orientations at one
position are nearly the same column, and adding them all slows the LP down), priced
at the duals moved towards the best point of the dual steps (``SMOOTHING``). An
artificial column keeps the restricted LP feasible: it costs what the dearest
candidate does per point of the demand (k_max times that with k > 1), so no optimum
of the full LP leaves demand to it (the goal is at most what can be covered: a point
short of its demand always has a candidate that raises it at no more than that).

At every round the duals, scaled by ``t = min(1, min_c cost_c / (M pi)_c)``, are
feasible for the dual of the full LP, so ``t z`` is a proven lower bound on it
(Farley's bound; ``z`` the restricted LP's value). Scaled by any t >= 0 they still
give one, a Lagrangian bound with every ``x_c <= 1`` (no optimum needs more, as
``u_n <= 1``): ``t z - sum_c max(0, t (M pi)_c - cost_c)``, concave in t and at its
peak at least Farley's (on two_routes it passes 30 at round 31, Farley's at 33, of
4 to 8 s each). When no candidate has a negative reduced cost the bound equals ``z``,
the LP value. For integer objectives the search may stop as soon as
``ceil(bound) == ceil(z)``: the integer bound cannot rise further.

**In parts.** The restricted LP's solves grow faster than the target (three tiles of
full_ground: 3 x the candidates of two_routes, 8 x the LP's time), so a large target
is solved in compact parts of its points (``split_cover_lp``), each an LP of
two_routes' size, and the parts' bounds combined: the time grows with the number of
parts.

**Masts.** The fewest mast positions whose candidates together cover ``goal`` points:
a small MILP over positions (each covers the union of its candidates' points),
solved by HiGHS; its proven dual bound is the masts bound, and its solution a set of
sites a plan may use. Its LP relaxation, solved first, gives a second such set: the
sites with a positive value (on three tiles of full_ground 59 of 1,995, where the
MILP keeps 34; a plan on the 59 costs 236, on the 34 it costs 277, because fewer
masts need many more sensors).

**Masts and sensors together.** The mast-aware model links each candidate to its
mast's site, ``x_c <= y_s``, and costs ``mast_cost`` per open site plus
``sensor_cost`` per candidate. Its LP relaxation is weak (a fractional plan opens
sites as fractionally as it picks candidates: on ``two_routes`` its value falls below
50, far under the 70 of the masts and sensors bounds added), so its bound is taken
cheaply from the sensors LP's duals (``mast_aware_bound``). As a MILP over the sites
of a plan (``sensors_on_sites``) it is exact and small: the fewest sensors (and cost)
on those sites, started from that plan.

Solves run in a thread and the generators yield while they wait, so a caller (the
Blender operator) stays responsive; closing the generator cancels the solve.

One module of about 900 lines, on purpose: the sensors LP, its dual steps, the masts
LP and MILP, the mast-aware bound and the parts' combination share the machinery of
the restricted LP (HiGHS in a thread, the Lagrangian's pricing, ``LPSolution``) and are
proven together in ``tests/core/test_bound.py``.
"""

from __future__ import annotations

import enum
import itertools
import math
import threading
import time
from collections.abc import Generator, Iterator, Sequence
from dataclasses import dataclass, replace
from typing import Any, TypeVar

import highspy
import numpy as np
from numpy.typing import NDArray
from scipy import sparse

from .cover import CoverInstance, MastCost, SensorCost, cost_at, plan_price

F64 = NDArray[np.float64]
I64 = NDArray[np.int64]

# How often a waiting generator yields, s.
POLL_S = 0.05
# How long a cancelled solve is waited for, s (``_run``).
CANCEL_WAIT_S = 0.3
# The name of a solve's thread (``_run``; ``solving``).
SOLVE_THREAD = "autoscoop-solve"
# A bound is lowered by this much (relative) against the solver's tolerances.
SAFETY = 1e-6
# The most one goal's solve may take in ``_lines_at``, s; and how much of the LP's
# bound its tangent must lose by the lowest goal asked for them to be sought.
GOAL_SOLVE_S = 10.0
STEEP = 0.5
# The weight of the dual steps' best point in the duals that price new columns
# (``cover_lp``; 0: the restricted LP's own). On two_routes' LP alone 0.5 took 21 rounds,
# 41 s, and 0 took 27 rounds, 78 s; smoothed towards the best point of all the steps
# (which depends on timing), 0.3, 0.5, 0.7 and 0.85 took 23, 20, 19 and 19 rounds.
SMOOTHING = 0.5
# A dual step sums the rows of the candidates that pay when fewer than one in this
# many do (``DualPolish._covered``), else takes M^T over every candidate.
FEW_PAY = 20
# Branch-and-bound nodes of the mast-aware MILP: a limit in work, not seconds, so the
# plan is the same on a fast and a slow machine.
MAX_NODES = 2000
# At k > 1 a point's u is whole too, and the mast-aware MILP grows hard: on two_routes
# at k = 2 (24 masts, 3,984 candidates) HiGHS found nothing cheaper than its start in
# 150-170 s beside the LP, still in its root node's cuts, and held 0.5 GiB. Above this
# many candidates it is not solved: the start is the answer.
MAX_MULTI_MILP_CANDIDATES = 1000
# The LP over every point starts from the columns of an LP on one point per square of
# this side, m (``sample_columns``), on targets of at least ``SAMPLE_MIN_POINTS``
# points (smaller ones solve in seconds; none smaller was measured); that LP ends
# within ``SAMPLE_REL_GAP`` of its value and takes at most ``SAMPLE_SHARE`` of the time
# left. Its columns that the LP uses come first, then the others by reduced cost, up to
# ``START_NONZEROS`` matrix entries in all: the first solve over every point grows
# steeply with them (two_routes: 0.46 M entries 13.3 s, 0.74 M 33.7 s; a part of
# Town04: 0.34 M 40 s, 0.64 M 115 s), and fewer cost rounds (a part of Town01: 0.03 M
# 23 s, 0.40 M 9.3 s).
SAMPLE_M = 2.0
SAMPLE_MIN_POINTS = 5000
SAMPLE_REL_GAP = 0.02
SAMPLE_SHARE = 1 / 3
START_NONZEROS = 400_000


class Solve(enum.Enum):
    """How a solve in its thread (``_run``) ended: ran to its end (an optimum, or the
    solver's own limits); stopped, the model idle and readable; or never ran or left
    running in its thread, where the model must not be read."""

    DONE = "done"
    STOPPED = "stopped"
    GONE = "gone"


def _run(
    h: highspy.Highs,
    stop: threading.Event | None = None,
    beside: Iterator[None] | None = None,
) -> Generator[None, None, Solve]:
    """Run ``h`` in a thread, yielding while it works; cancel it if closed early or
    when ``stop`` is set. Set already, nothing is started (a stopped run begins no new
    solve). A cancelled solve is waited for at most ``CANCEL_WAIT_S``: HiGHS notices
    a cancel between its own steps (on two_routes 1 to 2 s into an LP, 4 s into a
    MILP), and a stopped run must end within 5 s; one that has not noticed yet ends in
    its (daemon) thread. ``beside``: steps of other work done here while the solve
    runs (one each time it waits), instead of sleeping."""
    if stop is not None and stop.is_set():
        return Solve.GONE
    done = threading.Event()

    def work() -> None:
        h.run()
        done.set()

    thread = threading.Thread(target=work, daemon=True, name=SOLVE_THREAD)
    thread.start()
    stopped = False

    def waited() -> bool:
        """Whether the solve is done, after one step of ``beside`` (none once
        ``stop`` is set: a step can take 0.3 s) or a pause."""
        nonlocal beside
        if stop is not None and stop.is_set():
            return done.is_set()
        if beside is not None and next(beside, StopIteration) is StopIteration:
            beside = None
        return done.is_set() if beside is not None else done.wait(POLL_S)

    try:
        while not waited():
            if stop is not None and stop.is_set() and not stopped:
                h.cancelSolve()
                stopped = True
                break
            yield
    finally:
        if not done.is_set():
            if not stopped:  # closed early (the operator cancelled)
                h.cancelSolve()
            done.wait(CANCEL_WAIT_S)
    if not stopped:
        return Solve.DONE
    return Solve.STOPPED if done.is_set() else Solve.GONE


def solving() -> bool:
    """Whether a solve still runs in its thread: a cancelled one HiGHS has not noticed
    yet (``_run`` leaves it). A process that exits then can abort in HiGHS' clean-up
    ("terminate called without an active exception", exit -6), its work written."""
    return any(t.name == SOLVE_THREAD and t.is_alive() for t in threading.enumerate())


def _empty_rows(h: highspy.Highs, lower: F64, upper: F64) -> None:
    none = np.zeros(0, dtype=np.int32)
    h.addRows(len(lower), lower, upper, 0, none, none, np.zeros(0))


def _le_zero_rows(h: highspy.Highs, rows: sparse.csr_matrix) -> None:
    """Rows ``rows @ columns <= 0`` (rows: (R, columns so far), CSR)."""
    n = rows.shape[0]
    h.addRows(n, np.full(n, -highspy.kHighsInf), np.zeros(n), rows.nnz,
              rows.indptr[:-1].astype(np.int32), rows.indices.astype(np.int32),
              rows.data.astype(float))  # fmt: skip


def _add_columns(
    h: highspy.Highs,
    matrix: sparse.csr_matrix,
    cost: F64,
    upper: float | F64,
    values: F64 | None = None,
) -> None:
    """Columns of the LP from rows of a CSR matrix (a candidate's points are its rows),
    every entry 1 or, given, ``values`` (one per stored entry)."""
    n = matrix.shape[0]
    h.addCols(
        n,
        np.asarray(cost, dtype=float),
        np.zeros(n),
        np.broadcast_to(np.asarray(upper, dtype=float), (n,)).copy(),
        matrix.nnz,
        matrix.indptr[:-1].astype(np.int32),
        matrix.indices.astype(np.int32),
        np.ones(matrix.nnz) if values is None else np.asarray(values, dtype=float),
    )


def limit_to(h: highspy.Highs, deadline: float) -> None:
    """Make ``h``'s next run end by ``deadline`` (``time.perf_counter()``). HiGHS holds
    its time limit against the run time of every run of the object so far, not the
    next run's alone: a limit of the time left, set before a later round of row or
    column generation, ended the joint LP on two_routes after 8 of its 19 rounds, 65 s
    before the run's deadline (2026-11-28)."""
    left = max(deadline - time.perf_counter(), 0.01)
    h.setOptionValue("time_limit", float(h.getRunTime()) + left)


def _new_highs(time_limit_s: float | None) -> highspy.Highs:
    h = highspy.Highs()
    # Without it ``cancelSolve`` does nothing and a stopped run waits for the solve.
    h.HandleUserInterrupt = True
    h.setOptionValue("output_flag", False)
    h.setOptionValue("threads", 1)
    if time_limit_s is not None:
        h.setOptionValue("time_limit", max(float(time_limit_s), 0.01))
    return h


def _cover_rows(
    h: highspy.Highs,
    n_points: int,
    goal: int,
    need: NDArray[np.int32] | None = None,
    weight: F64 | None = None,
) -> None:
    """Rows ``covering - k_n u_n >= 0`` for every point (k_n: ``need``, default 1),
    ``sum weight_n u_n >= goal`` (weight: default 1; a merged point's size), and the u."""
    inf = highspy.kHighsInf
    _empty_rows(h, np.concatenate([np.zeros(n_points), [float(goal)]]), np.full(n_points + 1, inf))
    idx = np.empty(2 * n_points, dtype=np.int32)
    idx[0::2] = np.arange(n_points)
    idx[1::2] = n_points
    val = np.empty(2 * n_points)
    val[0::2] = -1.0 if need is None else -np.asarray(need, dtype=float)
    val[1::2] = 1.0 if weight is None else weight
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
class MergedPoints:
    """The points of a (C, N) matrix merged where the same columns cover them with
    the same values and they need the same: ``matrix`` (C, G), one column per group
    (G <= N; a point no column covers is in none), ``weight`` (G,) its points, ``need``
    (G,) their k. A model over the groups, each group's u weighted by its size in the
    goal row, has the same optima in x as over the points: the u of points with the
    same row are interchangeable (and in an LP can be taken equal). On two_routes'
    mast-aware MILP (14 sites, 1,261 candidates) 16,555 points make 8,486 groups, and
    HiGHS solves it in 20 s instead of 75 s."""

    matrix: sparse.csr_matrix
    weight: F64
    need: NDArray[np.int32]

    @classmethod
    def of(cls, matrix: sparse.csr_matrix, need: NDArray[np.int32]) -> MergedPoints:
        by_point = sparse.csc_matrix(matrix)
        by_point.sort_indices()
        n = by_point.shape[1]
        count = np.diff(by_point.indptr)
        covered = np.flatnonzero(count > 0)
        # A key per point: its count, its need and two random sums over its column
        # indices and values; equal keys are then checked entry by entry, so a
        # collision only splits a group again (never merges different rows).
        rng = np.random.default_rng(0)
        salt = rng.integers(1, 2**62, size=(2, by_point.shape[0]), dtype=np.int64).view(np.uint64)
        bits = by_point.data.astype(np.float64).view(np.uint64) | np.uint64(1)
        keys = np.zeros((n, 4), dtype=np.uint64)
        keys[:, 0], keys[:, 1] = count, need
        starts = by_point.indptr[:-1][covered]
        for j in range(2):
            mixed = salt[j][by_point.indices] * bits
            keys[covered, 2 + j] = np.add.reduceat(mixed, starts) if len(covered) else []
        keys = keys[covered]
        _, first, group = np.unique(keys, axis=0, return_index=True, return_inverse=True)
        group = group.ravel()
        rep = covered[first][group]  # (covered,) the first point with the same key
        within = np.arange(by_point.nnz) - np.repeat(by_point.indptr[:-1][covered], count[covered])
        mine = np.repeat(by_point.indptr[covered], count[covered]) + within
        theirs = np.repeat(by_point.indptr[rep], count[covered]) + within
        differs = (by_point.indices[mine] != by_point.indices[theirs]) | (
            by_point.data[mine] != by_point.data[theirs]
        )
        odd = np.unique(np.repeat(np.arange(len(covered)), count[covered])[differs])
        group[odd] = group.max(initial=-1) + 1 + np.arange(len(odd))  # each on its own
        _, first, group = np.unique(group, return_index=True, return_inverse=True)
        kept = covered[first]
        return cls(
            sparse.csr_matrix(by_point[:, kept]),
            np.bincount(group.ravel(), minlength=len(kept)).astype(float),
            np.asarray(need, dtype=np.int32)[kept],
        )


class _Restricted:
    """The restricted LP of ``cover_lp`` in HiGHS, over its points merged where the
    columns in it cover them alike: one row and one u, weighted by its points in the
    goal row, stand for a group (``MergedPoints``' argument), and a point no column
    covers is in no row (its u can only be 0).

    Each new column splits the groups whose points it tells apart (partition
    refinement, exact: a group's points have the same entry in every column), and the
    model is built again over the new groups and started from the last basis: a
    group keeps its parent's row and u status, and a group split off adds one basic,
    its u where the parent's u was basic (at the parent's value), else its row's
    slack. So the primal simplex goes on from the last solution, feasible, as it did
    over every point. On two_routes' LP at 1,000 columns the 16,555 points make 7,900
    groups, and a round's solve took 0.7 s instead of 2.6 s (2026-12-01).

    The duals of a group's row shared evenly among its points are optimal duals of
    the LP over every point: the same reduced costs and value (the even share also
    keeps each point's u dual-feasible, as the group's is). A point in no row gets
    sigma / k_n, the least price at which its u at 0 is optimal (over every point,
    its row ``-k_n u_n >= 0`` would have that dual or more).

    Columns of the model: the groups' u, the artificial goal slack, then the
    candidates in the order they joined; rows: the groups', then the goal row."""

    def __init__(
        self, inst: CoverInstance, cost: F64, artificial: float, interior: bool
    ) -> None:
        self.matrix, self.cost, self.goal = inst.matrix, cost, inst.goal
        self.need = inst.k
        self.upper = 1.0 if inst.multi else highspy.kHighsInf
        self.artificial, self.interior = artificial, interior
        self.columns: list[int] = []
        n = inst.n_points
        self.label = np.full(n, -1, dtype=np.int64)  # (N,) each point's group, -1: none
        self.size = np.zeros(0, dtype=np.int64)  # (G,) points in each group
        # (G,) the group of the last model each group descends from (-1: its points
        # were in no row); a group of that model is its own origin.
        self.origin = np.zeros(0, dtype=np.int64)
        self.built_groups, self.built_columns = 0, 0
        self.basis: highspy.HighsBasis | None = None
        self.h: highspy.Highs | None = None

    @property
    def n_groups(self) -> int:
        return len(self.size)

    def add(self, cols: I64) -> None:
        """Candidates ``cols`` (new ones) join; their points' groups split."""
        m = self.matrix
        for c in cols:
            lo, hi = m.indptr[c], m.indptr[c + 1]
            if lo == hi:
                continue
            self._split(m.indices[lo:hi], m.data[lo:hi])
        self.columns.extend(int(c) for c in cols)

    def _split(self, points: I64, values: NDArray[Any]) -> None:
        """Split the groups of ``points`` by a column's entries ``values`` there."""
        old = self.label[points]
        _, code = np.unique(values, return_inverse=True)
        # Points in no row yet join by their k too: a row holds one k.
        fresh = np.where(old < 0, self.need[points], 0)
        key = np.column_stack([old, fresh, code.ravel()])
        _, first, inverse, counts = np.unique(
            key, axis=0, return_index=True, return_inverse=True, return_counts=True
        )
        parent = old[first]  # (K,) each piece's old group, sorted
        inside = np.bincount(parent + 1, weights=counts, minlength=self.n_groups + 1)
        whole = (parent >= 0) & (inside[parent + 1] == np.r_[0, self.size][parent + 1])
        # A group wholly in the column keeps its label for its first piece (so none is
        # left empty); every other piece is a new group.
        keeps = whole & np.r_[True, parent[1:] != parent[:-1]]
        new = np.flatnonzero(~keeps)
        label = parent.copy()
        label[new] = self.n_groups + np.arange(len(new))
        self.label[points] = label[inverse.ravel()]
        split = parent[new] >= 0
        np.subtract.at(self.size, parent[new][split], counts[new][split])
        self.size = np.concatenate([self.size, counts[new]])
        self.origin = np.concatenate([self.origin, np.r_[-1, self.origin][parent[new] + 1]])

    def model(self, deadline: float | None) -> highspy.Highs:
        """The model over the groups and columns so far, from the last basis, its time
        limit ``deadline`` (``time.perf_counter()``; None: none)."""
        if self.h is None or (self.n_groups, len(self.columns)) != (
            self.built_groups, self.built_columns
        ):
            self._build()
        assert self.h is not None
        if deadline is not None:
            limit_to(self.h, deadline)
        return self.h

    def _build(self) -> None:
        g, inf = self.n_groups, highspy.kHighsInf
        rows = np.flatnonzero(self.label >= 0)
        _, first = np.unique(self.label[rows], return_index=True)
        rep = rows[first]  # (G,) a point of each group, in group order
        h = _new_highs(None)
        if self.interior:
            # An interior point method without crossover: on the dense columns of mast
            # sites, one solve of every column took 57 s where the simplex had not
            # finished in 60 s (a part of Town04: 1,422 sites, 13,586 points).
            h.setOptionValue("solver", "ipm")
            h.setOptionValue("run_crossover", "off")
        else:
            # New columns leave the last basis primal feasible: the primal simplex goes
            # on from it (two_routes' 27 rounds: 80 s of solves, where HiGHS' choice,
            # the dual simplex, took 98 s for 30).
            h.setOptionValue("simplex_strategy", 4)
        _cover_rows(h, g, self.goal, self.need[rep], self.size.astype(float))
        h.addCols(1, np.full(1, self.artificial), np.zeros(1), np.full(1, inf), 1,
                  np.zeros(1, np.int32), np.array([g], np.int32), np.ones(1))  # fmt: skip
        cols = np.asarray(self.columns, dtype=np.int64)
        if len(cols):
            merged = sparse.csr_matrix(self.matrix[cols][:, rep])
            _add_columns(h, merged, self.cost[cols], self.upper, merged.data)
        if self.basis is not None and not self.interior:
            h.setBasis(self._carried(self.basis))
        self.h, self.built_groups, self.built_columns = h, g, len(cols)

    def _carried(self, old: highspy.HighsBasis) -> highspy.HighsBasis:
        """The last model's basis ``old`` for the groups and columns now (see the class
        docstring)."""
        s = highspy.HighsBasisStatus
        g0, g, c0 = self.built_groups, self.n_groups, self.built_columns
        col, row = list(old.col_status), list(old.row_status)
        u = [col[o] if o >= 0 else s.kLower for o in self.origin]
        rows = row[:g0] + [
            s.kLower if u[j] == s.kBasic else s.kBasic for j in range(g0, g)
        ]  # fmt: skip
        basis = highspy.HighsBasis()
        basis.col_status = u + col[g0 : g0 + 1 + c0] + [s.kLower] * (len(self.columns) - c0)
        basis.row_status = rows + [row[g0]]
        basis.valid = True
        return basis

    def solved(self) -> None:
        """Keep the basis of the solve that ended, and make the groups the model's."""
        assert self.h is not None
        basis = self.h.getBasis()
        self.basis = basis if basis.valid else None
        self.origin = np.arange(self.n_groups, dtype=np.int64)

    def has_duals(self) -> bool:
        assert self.h is not None
        return len(self.h.getSolution().row_dual) == self.n_groups + 1

    def duals(self) -> tuple[F64, float]:
        """(pi (N,), sigma): the point duals and the goal's (see the class docstring)."""
        assert self.h is not None
        row_dual = np.maximum(np.asarray(self.h.getSolution().row_dual), 0.0)
        sigma = float(row_dual[self.n_groups])
        pi = sigma / self.need.astype(float)
        inside = self.label >= 0
        group = self.label[inside]
        pi[inside] = row_dual[group] / self.size[group]
        return pi, sigma

    def x(self) -> F64:
        """(columns,) the candidates' values, in the order they joined."""
        assert self.h is not None
        return np.asarray(self.h.getSolution().col_value)[self.n_groups + 1 :]

    def set_goal(self, goal: int) -> None:
        assert self.h is not None
        self.h.changeRowBounds(self.n_groups, float(goal), highspy.kHighsInf)


@dataclass(frozen=True)
class LPProgress:
    """One round of column generation: the restricted LP's value and the bound; the
    round's point duals (N,) and the candidates in the LP (None: not known)."""

    rounds: int
    value: float
    bound: float
    columns: int
    duals: F64 | None = None
    in_lp: I64 | None = None


@dataclass(frozen=True)
class LPSolution:
    """The LP relaxation as far as it was solved.

    value: the restricted LP's optimum (the full LP's value when ``complete``); bound:
    a proven lower bound on the full LP's value; columns, x: the candidates in the
    restricted LP and their values; priced, reduced: (C,) every candidate's dual
    weight (the last point duals summed over its points) and its reduced cost, cost
    less that; complete: no candidate could improve the LP any more; parts: how many
    parts of the target it was solved in (``split_cover_lp``).
    """

    value: float
    bound: float
    columns: I64
    x: F64
    priced: F64
    reduced: F64
    rounds: int
    complete: bool
    # The bound as a line in the goal g: LP(g) >= slope g - intercept for every g
    # (from the same dual solution; see ``split_cover_lp``).
    slope: float = 0.0
    intercept: float = 0.0
    parts: int = 1
    # With k > 1 (candidates bounded by 1): the value of the last point duals alone,
    # sigma goal - sum_n max(0, sigma - k_n pi_n), for ``mast_aware_bound`` (nan: use
    # ``value``, which equals it when every k is 1).
    dual: float = math.nan
    # (N,) the last round's point duals (None: solved in parts), where the joint
    # bound's LP starts (``joint.py``).
    pi: F64 | None = None
    # (N,) the point duals whose Lagrangian bound is the line (slope, intercept); what
    # they price each candidate at is what a part's line takes of its cost
    # (``parts.CostLedger``). None: no line.
    line_pi: F64 | None = None
    # Lines at other goals (``cover_lp``'s ``also_at``), each with its point duals.
    more_lines: tuple[tuple[float, float], ...] = ()
    more_pi: tuple[F64, ...] = ()

    def integer_bound(self) -> int:
        """The bound on an integer objective: the next integer at or above it."""
        return max(0, math.ceil(self.bound - 1e-6))


class DualPolish:
    """Better duals for the LP's Lagrangian bound than the restricted LP's, by the
    subgradient method with Polyak's steps (hand-written: it is a few lines of numpy
    over the candidate matrix, and no library does it on a sparse matrix of this size).

    For any pi >= 0 (N,) and sigma >= 0 the LP is at least

        L(pi, sigma) = sigma goal - sum_n max(0, sigma - k_n pi_n)
                       - sum_c max(0, (M pi)_c - cost_c)

    (the cover rows and the goal row moved into the objective, with every x_c <= 1 and
    u_n in [0, 1]: no optimum needs more). Column generation proves its bound with the
    restricted LP's duals, which price the candidates outside it badly until the last
    rounds; a few cheap steps uphill of L from them (each one product with the
    matrix) prove much more early on: on a part of Town04, 200 steps (19 s) from the
    duals of round 12 reached 15.59 where the rounds' own bound was 9.2 and took
    until round 24 (330 s) to reach 16.44. Steps move (pi, sigma) along L's
    subgradient (k_n u_n less what the candidates that pay cover, and goal less sum
    u), by (target - L) / |g|^2 times a factor halved when ``PATIENCE`` steps find nothing
    better, from each round's duals; the target is the restricted LP's value, never
    below the LP's."""

    # Steps from each round's duals, while the next round's solve runs (in its thread:
    # the steps cost it no time on a second core), and as many more after it as make
    # MIN_STEPS (a short solve leaves no time for them; from the last round's duals,
    # all of them).
    MIN_STEPS = 20
    MAX_STEPS = 200
    # Steps without a better point before the step is halved (10 stalled a masts LP
    # of Town04 at 94 % of its value after 300 steps; 50 reached 97 % in 1,000).
    PATIENCE = 50

    def __init__(self, inst: CoverInstance, cost: F64) -> None:
        self.matrix, self.cost = inst.matrix, cost
        self.k = inst.k.astype(float)
        self.goal = inst.goal
        self.center: tuple[F64, float] | None = None  # the best (pi, sigma) so far
        self.center_value = -math.inf
        self.factor = 1.0
        self.since = 0
        self.steps = 0  # taken by the latest walk
        # The best point of the walks' first MIN_STEPS steps, which every run takes
        # alike (the steps beside a solve, as many as its time allows, are not): the
        # one that prices new columns, so the columns do not depend on timing (the
        # first steps' sizes do not either: they halve only after PATIENCE > MIN_STEPS).
        self.steady: F64 | None = None  # its point duals pi (N,)
        self.steady_value = -math.inf

    def value(self, pi: F64, sigma: float) -> tuple[float, F64]:
        """(L(pi, sigma) with the candidates' prices in float32, the prices (C,))."""
        priced = np.asarray(self.matrix @ pi.astype(self.matrix.dtype), dtype=float)
        paid = float(np.maximum(0.0, priced - self.cost).sum())
        excess = float(np.maximum(0.0, sigma - self.k * pi).sum())
        return sigma * self.goal - excess - paid, priced

    def walk(
        self, pi: F64, sigma: float, target: float, steps: int | None = None
    ) -> Iterator[None]:
        """Steps from (pi, sigma), at most ``steps`` (``MAX_STEPS``), yielding after each: a round's
        duals are a better start than the best point so far, even where their own L is
        lower (a few candidates they price too high cost much, and the first steps
        mend that). A new walk starts at once: the last one's steps count no more."""
        self.factor, self.since, self.steps = 1.0, 0, 0
        return self._steps(pi.copy(), sigma, target, steps)

    def _steps(self, pi: F64, sigma: float, target: float, steps: int | None) -> Iterator[None]:
        for _ in range(self.MAX_STEPS if steps is None else steps):
            now, priced = self.value(pi, sigma)
            if self.steps < self.MIN_STEPS and now > self.steady_value + 1e-9:
                self.steady, self.steady_value = pi.copy(), now
            if now > self.center_value + 1e-9:
                self.center, self.center_value, self.since = (pi.copy(), sigma), now, 0
            else:
                self.since += 1
                if self.since >= self.PATIENCE:
                    self.factor, self.since = self.factor / 2, 0
            covered = self._covered(np.flatnonzero(priced > self.cost))
            u = (self.k * pi < sigma).astype(float)
            g_pi = self.k * u - covered
            g_pi[(pi <= 0) & (g_pi < 0)] = 0.0  # pi stays >= 0
            g_sigma = self.goal - float(u.sum())
            norm = float(g_pi @ g_pi) + g_sigma * g_sigma
            if norm <= 0 or target <= now:
                break
            step = self.factor * (target - now) / norm
            pi = np.maximum(0.0, pi + step * g_pi)
            sigma = max(0.0, sigma + step * g_sigma)
            self.steps += 1
            yield

    def _covered(self, pays: I64) -> F64:
        """(N,) what the candidates ``pays`` cover together (each point, the sum of
        their entries). Few pay in most steps (a median of 0.09 % of two_routes'
        candidates, 2026-12-01): then their rows alone, summed (0.3 ms against 22 ms
        for M^T over every candidate). When many pay (early steps), M^T 1_pays, with
        no copy of their rows (0.04 s against 0.24 s on two_routes' 43 M entries when
        most pay). The entries are small integers: either sum is exact."""
        m = self.matrix
        if len(pays) * FEW_PAY < m.shape[0]:
            rows = m[pays]
            sums = np.bincount(rows.indices, weights=rows.data, minlength=m.shape[1])
            return np.asarray(sums, dtype=float)
        ones = np.zeros(m.shape[0], dtype=m.dtype)
        ones[pays] = 1
        return np.asarray(m.T @ ones, dtype=float)

    def line(self) -> tuple[float, float, float]:
        """The best point's bound, proven: (L at the goal, slope, intercept) of the line
        L(g) = sigma g - intercept, the candidates that may pay priced again in float64
        (``best_scale``'s argument)."""
        if self.center is None:
            return 0.0, 0.0, 0.0
        pi, sigma = self.center
        priced = np.asarray(self.matrix @ pi.astype(self.matrix.dtype), dtype=float)
        near = np.flatnonzero(priced >= self.cost * (1 - 1e-3))
        exact = np.asarray(self.matrix[near] @ pi, dtype=float)
        paid = float(np.maximum(0.0, exact - self.cost[near]).sum())
        excess = float(np.maximum(0.0, sigma - self.k * pi).sum())
        slope = sigma * (1 - SAFETY)
        intercept = excess + paid + SAFETY
        return slope * self.goal - intercept, slope, intercept

    def better(
        self, best: float, line: tuple[float, float], pi: F64 | None
    ) -> tuple[float, tuple[float, float], F64 | None]:
        """(bound at the goal, (slope, intercept), the point duals (N,) of that line):
        ``best``, its ``line`` and ``pi``, or the best point's when that proves more."""
        if self.center is None:
            return best, line, pi
        polished, slope, intercept = self.line()
        if polished > best:
            return polished, (slope, intercept), self.center[0]
        return best, line, pi


def cover_lp(
    inst: CoverInstance,
    cost: F64,
    group: I64,
    initial: I64,
    per_round: int = 50,
    integral: bool = True,
    deadline: float | None = None,
    stop: threading.Event | None = None,
    rel_gap: float = 0.0,
    interior: bool = False,
    line_anyway: bool = False,
    also_at: Sequence[int] = (),
    sample: bool = False,
) -> Generator[LPProgress | None, None, LPSolution]:
    """The LP relaxation by column generation (see the module docstring).

    cost: (C,) > 0 per candidate; group: (C,) its position (one new column per group
    and round); initial: candidates to start from (e.g. a greedy plan); integral: stop
    once the integer bound is final; rel_gap: stop once the bound is within this
    fraction of the LP's value; deadline: ``time.perf_counter()`` to stop at, and
    stop: an event to stop at once (the bound then holds, the LP is not complete; a
    round cut short is dropped); line_anyway: when the deadline cuts the first solve
    short of optimal duals, ``DualPolish.MIN_STEPS`` dual steps from the duals it
    has, or from nothing, towards the cost of ``initial``, still prove a line (a part
    that starts at the parts' end: Town04's last had none, and its sensors counted 0
    in the bound); also_at: goals at which the LP, once it ends, gives lines too
    (``_lines_at``; ``LPSolution.more_lines``); sample: start from the columns of
    an LP on a sample of the points too (``sample_columns``), on a large target.
    Yields None while HiGHS works and an ``LPProgress`` after each round.
    """
    matrix = inst.matrix
    need = inst.k
    multi = inst.multi
    # The artificial demand slack, so the restricted LP is always feasible: priced as
    # the dearest candidate per point (with k > 1, k_max of them), never cheaper.
    artificial = float(np.max(cost, initial=0.0)) * (float(need.max()) if multi else 1.0)
    # With k > 1 a candidate counts once: x_c <= 1 (with k = 1 it never needs more).
    # A column's entries are the matrix's: 1, or for a mast site with k > 1 what it
    # adds to a point (``parts.site_matrix``).
    restricted = _Restricted(inst, cost, artificial, interior)
    in_lp = np.zeros(matrix.shape[0], dtype=bool)
    order = restricted.columns

    def add(cols: I64) -> None:
        cols = cols[~in_lp[cols]]
        in_lp[cols] = True
        restricted.add(cols)

    add(np.unique(np.asarray(initial, dtype=np.int64)))
    target = float(cost[np.asarray(initial, dtype=np.int64)].sum())  # for ``line_anyway``
    if sample and inst.xy is not None and inst.n_points >= SAMPLE_MIN_POINTS:
        add((yield from sample_columns(inst, cost, group, initial, deadline, stop)))
    polish = DualPolish(inst, cost)
    walk: Iterator[None] | None = None
    best, line = 0.0, (0.0, 0.0)
    line_pi: F64 | None = None  # the point duals whose Lagrangian is ``line``
    rounds = 0
    # Before any round: the initial columns as the plan, no bound, nothing priced.
    last = LPSolution(
        np.inf, 0.0, np.array(order, dtype=np.int64), np.ones(len(order)),
        np.zeros(0), np.full(matrix.shape[0], np.inf), 0, False,
    )  # fmt: skip
    while True:
        rounds += 1
        h = restricted.model(deadline)
        began = time.perf_counter()
        if (yield from _run(h, stop, walk)) is not Solve.DONE:
            return last  # stopped in the middle of a solve: its values are not optimal
        restricted.solved()
        _top_up(walk, polish, stop)
        # Cut short by the time limit: the duals so far still give a Lagrangian bound
        # (if there are any), but the objective is no optimum to scale.
        optimal = h.getModelStatus() == highspy.HighsModelStatus.kOptimal
        # Cut short in its first solve, asked for a line anyway: steps from the duals
        # it has (none: from nothing), towards the initial columns' cost.
        anyway = line_anyway and rounds == 1 and not optimal
        anyway = anyway and not (stop is not None and stop.is_set())
        if not optimal and not restricted.has_duals():
            if anyway:
                for _ in polish.walk(np.zeros(inst.n_points), 0.0, target, DualPolish.MIN_STEPS):
                    yield None
                at, slope, intercept = polish.line()
                pi = None if polish.center is None else polish.center[0]
                last = replace(
                    last, bound=max(0.0, at), slope=slope, intercept=intercept, line_pi=pi
                )
            return last
        value = float(h.getInfo().objective_function_value) if optimal else math.inf
        duals, sigma = restricted.duals()
        priced = np.asarray(matrix @ duals.astype(matrix.dtype), dtype=float)
        reduced = cost - priced
        with np.errstate(divide="ignore"):
            scale = min(1.0, float(np.min(np.where(priced > 0, cost / priced, np.inf))))
        (slope, intercept), t, total = scaled_line(inst, cost, duals, sigma, priced)
        if slope * inst.goal - intercept > best:
            best, line, line_pi = slope * inst.goal - intercept, (slope, intercept), t * duals
        # Steps uphill from this round's duals (the restricted LP's value is a target
        # above the LP's), taken beside the next round's solve (on the second core):
        # 20 steps before it cost two_routes 25 s of its 107 s LP. The best point of
        # every walk so far gives the bound.
        walk = polish.walk(duals, sigma, value) if optimal else None
        if anyway:
            for _ in polish.walk(duals, sigma, target, DualPolish.MIN_STEPS):
                yield None
        best, line, line_pi = polish.better(best, line, line_pi)
        # With k > 1 (x_c <= 1) the restricted LP's value holds the bounds' duals too:
        # not a bound scaled, and ``mast_aware_bound`` takes the point duals' ``total``.
        dual = total if multi else math.nan
        if not multi and optimal:
            best = max(best, scale * value * (1 - SAFETY) - SAFETY)
        yield LPProgress(rounds, value, best, len(order), duals, np.array(order, dtype=np.int64))
        # Columns in the LP priced below 0 only by round-off (duals clipped at 0) are
        # not new: the LP is complete when no other candidate is.
        negative = np.flatnonzero((reduced < -1e-9) & ~in_lp)
        complete = len(negative) == 0
        done_int = integral and optimal and math.ceil(best - 1e-6) >= math.ceil(value - 1e-6)
        done_gap = rel_gap > 0 and best >= (1 - rel_gap) * value
        late = deadline is not None and time.perf_counter() > deadline
        late = late or (stop is not None and stop.is_set())
        # Lines at other goals only where the tangent is steep: where it loses more
        # than ``STEEP`` of its value by the lowest of them (on a part of Town04, 0.006
        # a point, losing 19 % by 6 % below its goal, the solves took 42 s for lines
        # below the tangent; on two_routes in 3 parts, 7 s for the 11 sensors above).
        # With those to come, no round is begun that the deadline would likely cut
        # short (as long as this one, and half again: rounds grow): they go on from
        # an optimal basis.
        lowest = min(also_at, default=inst.goal)
        steep = line[0] * (inst.goal - lowest) > STEEP * max(best, 1e-9)
        solve_s = time.perf_counter() - began
        short = steep and time.perf_counter() + 1.5 * solve_s > (deadline or math.inf)
        ending = complete or done_int or done_gap or late or short or not optimal
        if ending and not late:
            # No next solve to walk beside: the last duals' steps now, for the line
            # the LP returns (a part's tangent in its goal, ``combined_bound``).
            _top_up(walk, polish)
            best, line, line_pi = polish.better(best, line, line_pi)
        if complete and optimal:
            best = max(best, value * (1 - SAFETY) - SAFETY)
        x = restricted.x()
        last = LPSolution(
            value, best, np.array(order, dtype=np.int64), x, priced, reduced, rounds, complete,
            *line, dual=dual, pi=duals, line_pi=line_pi,
        )  # fmt: skip
        if ending:
            if steep and optimal and not (stop is not None and stop.is_set()):
                more = yield from _lines_at(restricted, inst, cost, also_at, stop)
                last = replace(
                    last, more_lines=tuple(m[0] for m in more), more_pi=tuple(m[1] for m in more)
                )
            return last
        # New columns are priced at duals between this round's and the best point of
        # the dual steps (smoothing, after Wentges; ``DualPolish.steady``): the
        # restricted LP's duals swing from round to round and price columns no optimum
        # needs (``SMOOTHING``). When the smoothed duals price no candidate below its
        # cost, this round's do.
        if polish.steady is not None and SMOOTHING > 0:
            mixed = SMOOTHING * polish.steady + (1 - SMOOTHING) * duals
            smoothed = cost - np.asarray(matrix @ mixed.astype(matrix.dtype), dtype=float)
            ahead = np.flatnonzero((smoothed < -1e-9) & ~in_lp)
            if len(ahead):
                negative, reduced = ahead, smoothed
        # The best candidate of each group, the most negative groups first.
        by_group = negative[np.lexsort((reduced[negative], group[negative]))]
        firsts = by_group[np.r_[True, group[by_group][1:] != group[by_group][:-1]]]
        add(firsts[np.argsort(reduced[firsts], kind="stable")[:per_round]])


def _lines_at(
    restricted: _Restricted,
    inst: CoverInstance,
    cost: F64,
    goals: Sequence[int],
    stop: threading.Event | None,
) -> Generator[None, None, list[tuple[tuple[float, float], F64]]]:
    """Lines of the LP ``inst`` at ``goals`` (line: (slope, intercept), and its point
    duals (N,)): the restricted LP solved again at each goal, its duals
    scaled as a round's are (``best_scale``) and ``DualPolish.MIN_STEPS`` dual steps
    from them. At most ``GOAL_SOLVE_S`` a goal; none once ``stop`` is set.

    Why: a part's line is a tangent at its own goal and sags below its LP away from
    it, where the whole's bound moves goal (``combined_bound``). On two_routes in 3
    parts one part's goal was 14 points below all it could cover, its tangent
    0.1 a point: at 111 points below its own goal the tangent was 0, and the best
    split took 257 points off it, so its 11 sensors counted 0."""
    out: list[tuple[tuple[float, float], F64]] = []
    h = restricted.model(None)
    # The goal's bound changed, the basis stays dual feasible: the dual simplex goes on.
    h.setOptionValue("simplex_strategy", 1)
    for goal in goals:
        restricted.set_goal(goal)
        limit_to(h, time.perf_counter() + GOAL_SOLVE_S)
        if (yield from _run(h, stop)) is not Solve.DONE:
            break
        if h.getModelStatus() != highspy.HighsModelStatus.kOptimal:
            continue
        value = float(h.getInfo().objective_function_value)
        duals, sigma = restricted.duals()
        at = replace(inst, goal=int(goal))
        (slope, intercept), t, _ = scaled_line(at, cost, duals, sigma)
        polish = DualPolish(at, cost)
        for _ in polish.walk(duals, sigma, value, DualPolish.MIN_STEPS):
            yield None
        _, line, pi = polish.better(slope * goal - intercept, (slope, intercept), t * duals)
        assert pi is not None
        out.append((line, pi))
    return out


def scaled_line(
    inst: CoverInstance, cost: F64, duals: F64, sigma: float, priced: F64 | None = None
) -> tuple[tuple[float, float], float, float]:
    """((slope, intercept), t, total): the LP's bound as a line in its goal g from the
    point duals ``duals`` (N,) and goal dual ``sigma`` scaled by t (``best_scale``):
    t (sigma g - sum_n max(0, sigma - k_n pi_n)) less what the candidates that t prices
    above their cost pay (none at Farley's t), lowered by ``SAFETY``; total: the
    duals' own value at the instance's goal. priced: (C,) ``M pi`` if known."""
    matrix = inst.matrix
    if priced is None:
        priced = np.asarray(matrix @ duals.astype(matrix.dtype), dtype=float)
    excess = np.maximum(0.0, sigma - (inst.k * duals if inst.multi else duals))
    total = inst.goal * sigma - float(excess.sum())
    t, paid = best_scale(total, priced, cost, matrix, duals)
    return (t * sigma * (1 - SAFETY), t * float(excess.sum()) + paid + SAFETY), t, total


def _top_up(
    walk: Iterator[None] | None, polish: DualPolish, stop: threading.Event | None = None
) -> None:
    """Take the steps of ``walk`` that make ``DualPolish.MIN_STEPS`` (fewer if it ends),
    or none once ``stop`` is set: they make the next round's columns independent of
    timing, and a stopped LP has no next round (on two_routes a step takes about 0.2 s,
    and a solve that ended just before the stop left 1.5 s of them, of a stopped run's
    5 s)."""
    if walk is None:
        return
    for _ in range(max(0, DualPolish.MIN_STEPS - polish.steps)):
        if (stop is not None and stop.is_set()) or next(walk, StopIteration) is StopIteration:
            return


def best_scale(
    total: float, priced: F64, cost: F64, matrix: sparse.csr_matrix, duals: F64
) -> tuple[float, float]:
    """(t, paid): the scale t >= 0 of duals pi >= 0 whose Lagrangian bound on the LP,
    ``t total - paid`` with paid = sum_c max(0, t priced_c - cost_c), is highest.
    total: the duals' value, sigma goal - sum_n max(0, sigma - k_n pi_n); priced:
    (C,) the candidates' ``M pi`` as float32 sums; matrix: (C, N) M; duals: (N,) pi."""
    pays = priced > 0
    if total <= 0 or not pays.any():
        return 0.0, 0.0
    breaks = cost[pays] / priced[pays]
    order = np.argsort(breaks, kind="stable")
    # The bound's slope in t is total less the priced of the candidates past their
    # break: its peak is at the first break where those add up to total.
    k = int(np.searchsorted(np.cumsum(priced[pays][order]), total))
    t = float(breaks[order[min(k, len(order) - 1)]])
    # A float32 sum of up to ~16,000 duals is within 1e-3 of the exact one: the
    # candidates that may pay at t, priced again in float64 (a few dozen at the peak,
    # where their priced add up to about total).
    near = np.flatnonzero(t * priced >= cost * (1 - 1e-3))
    exact = np.asarray(matrix[near] @ duals, dtype=float)
    return t, float(np.maximum(0.0, t * exact - cost[near]).sum())


def parts_of(xy: F64, n_parts: int) -> I64:
    """(N,) the part of each point (xy: (N, 2) m): the points split in two at a
    quantile of their longer extent, again and again, into ``n_parts`` compact parts
    of nearly equal counts (compact, so that few candidates see into two parts)."""
    part = np.zeros(len(xy), dtype=np.int64)

    def split(idx: I64, k: int, first: int) -> None:
        if k == 1 or len(idx) == 0:
            part[idx] = first
            return
        axis = int(np.argmax(np.ptp(xy[idx], axis=0)))
        idx = idx[np.argsort(xy[idx, axis], kind="stable")]
        cut = round(len(idx) * (k // 2) / k)
        split(idx[:cut], k // 2, first)
        split(idx[cut:], k - k // 2, first + k // 2)

    split(np.arange(len(xy)), n_parts, 0)
    return part


PartLines = Sequence[tuple[float, float] | list[tuple[float, float]]]


def combined_bound(lines: PartLines, coverable: list[int], goal: int) -> float:
    """The least total of the parts' LP values over every way to split ``goal`` among
    them, each part's value bounded below by its line (slope, intercept), or by the
    highest of its lines, and by 0; its share of the goal at most what it can cover
    (together at least ``goal``). Each part's bound is then convex and piecewise
    linear in its goal, 0 up to where its first line rises: the goal goes to the
    parts' pieces with the smallest slopes first (``_pieces``). 0 when the parts cover
    the goal at no cost."""
    return combined_sum_bound([(1.0, lines)], coverable, goal)


def combined_sum_bound(
    weighted: Sequence[tuple[float, PartLines]], coverable: list[int], goal: int
) -> float:
    """``combined_bound`` of a weighted sum of bounds, each given by the parts' lines
    (weighted: (weight >= 0, the parts' lines) per bound): the least over every split
    of ``goal`` of the sum over the parts of sum_w weight_w f_w,p(goal_p). The split
    is one for every bound, since a plan covers what it covers in a part whichever
    bound counts it; so this is at least the weighted sum of the bounds split apart
    (e.g. mast_cost x the masts' + sensor_cost x the sensors')."""
    pieces, total = [], 0.0
    for p, c in enumerate(coverable):
        terms = []
        for weight, lines in weighted:
            mine = lines[p]
            many = mine if isinstance(mine, list) else [mine]
            terms.append((weight, [(a, b) for a, b in many if a > 0 or b < 0] or [(0.0, 0.0)]))
        at_zero, more = _pieces(terms, c)
        total += at_zero
        pieces.extend(more)
    left = float(goal)
    for slope, length in sorted(pieces):
        if left <= 0:
            break
        take = min(left, length)
        total += slope * take
        left -= take
    return total


def _pieces(
    terms: list[tuple[float, list[tuple[float, float]]]], coverable: float
) -> tuple[float, list[tuple[float, float]]]:
    """f(g) = sum over ``terms`` (weight, lines) of weight x max(0, slope g - intercept
    over its lines) for g from 0 to ``coverable``: f(0), and the (slope, length) of
    its pieces in order (their slopes rise: f is convex, a sum of convex terms)."""
    at = {0.0, float(coverable)}
    for _, lines in terms:
        for a, b in lines:
            if a != 0:
                at.add(b / a)  # where the line crosses 0
        for (a1, b1), (a2, b2) in itertools.combinations(lines, 2):
            if a1 != a2:
                at.add((b1 - b2) / (a1 - a2))  # where two lines cross
    points = sorted(g for g in at if 0.0 <= g <= coverable)

    def value(g: float) -> float:
        return sum(w * max(0.0, max(a * g - b for a, b in lines)) for w, lines in terms)

    pieces = [
        ((value(hi) - value(lo)) / (hi - lo), hi - lo)
        for lo, hi in itertools.pairwise(points)
        if hi > lo
    ]
    return value(0.0), pieces


T = TypeVar("T")


def sample_columns(
    inst: CoverInstance,
    cost: F64,
    group: I64,
    initial: I64,
    deadline: float | None = None,
    stop: threading.Event | None = None,
) -> Generator[None, None, I64]:
    """Candidates to start ``inst``'s LP from: those of the LP on one point per
    ``SAMPLE_M`` square (``CoverInstance.thinned``, from ``initial``) that it uses,
    then its other columns by their reduced cost there, up to ``START_NONZEROS``
    entries of ``inst.matrix`` (see there). The sample proves nothing of the whole (its
    progress is not passed on); it only saves the whole LP rounds: on two_routes 7 of
    25 rounds, 20 s in all instead of 26 s; on a part of Town01 7.6 + 9.3 s instead of
    30.3 s (offline, 2026-12-07).
    Empty when the sample's LP did not end a round (stopped, or out of time); when it
    was cut short in a later one, its columns by reduced cost alone."""
    left = None if deadline is None else deadline - time.perf_counter()
    lp = yield from quiet(cover_lp(
        inst.thinned(SAMPLE_M), cost, group, initial, integral=False, rel_gap=SAMPLE_REL_GAP,
        deadline=None if left is None else time.perf_counter() + SAMPLE_SHARE * left,
        stop=stop,
    ))  # fmt: skip
    if lp.rounds == 0:
        return np.zeros(0, dtype=np.int64)
    # Cut short in a round (value inf): its x is no optimum, but its columns, priced at
    # the duals it reached, still save rounds (on Town04's parts in a default run the
    # sample took its third of the time in 2 of 8).
    used = lp.x > 1e-9 if math.isfinite(lp.value) else np.zeros(len(lp.columns), dtype=bool)
    rest = lp.columns[~used]
    ranked = np.concatenate([lp.columns[used], rest[np.argsort(lp.reduced[rest], kind="stable")]])
    entries = np.cumsum(np.diff(inst.matrix.indptr)[ranked])
    within = int(np.searchsorted(entries, START_NONZEROS, "right"))
    return ranked[: max(int(np.count_nonzero(used)), within)]


def quiet(gen: Generator[Any, None, T]) -> Generator[None, None, T]:
    """``gen``'s value, yielding None for whatever it yields (a part's LP progress is
    not the whole's)."""
    try:
        while True:
            try:
                next(gen)
            except StopIteration as done:
                return done.value
            yield None
    finally:
        gen.close()


def split_cover_lp(
    inst: CoverInstance,
    cost: F64,
    group: I64,
    initial: I64,
    part: I64,
    rel_gap: float = 0.005,
    deadline: float | None = None,
    stop: threading.Event | None = None,
) -> Generator[LPProgress | None, None, LPSolution]:
    """A lower bound on the LP relaxation solved part by part (``part``: (N,) each
    point's part), for targets too large to solve whole: the LP's time grows faster
    than its size (two_routes 83 s, three tiles of full_ground 690 s, for 3 x the
    candidates), each part's stays that of one such.

    Each part is the cover LP of its own points with a copy of every candidate that
    sees any of them, at the share of the candidate's cost that its points there
    are of all its points, and the goal split by what each part can cover. Any plan
    of the whole gives every part a plan at the same total cost, so the parts' LP
    values, at the best split of the goal, bound the whole LP from below. Each part's
    duals give its value as a line in its goal (``LPSolution.slope``), and
    ``combined_bound`` finds the best split of the goal against those lines, so
    the split of the goal used to solve the parts costs nothing in validity.

    Columns, values and reduced costs of the parts are mapped back to the
    candidates (the most any part gives a candidate; its reduced costs summed), for
    the plans built from the LP. Yields as ``cover_lp``, with the bound proven so
    far after each part.
    """
    matrix = inst.matrix
    n_parts = int(part.max()) + 1 if len(part) else 1
    sizes = np.maximum(np.diff(matrix.indptr), 1)
    # A point can be covered when at least its k candidates see it.
    coverable_all = np.bincount(matrix.indices, minlength=inst.n_points) >= inst.k
    coverable = [int(np.count_nonzero(coverable_all[part == k])) for k in range(n_parts)]
    total = max(sum(coverable), 1)
    lines = [(0.0, 0.0)] * n_parts  # parts not solved yet: 0 for any goal
    value, rounds, complete = 0.0, 0, True
    x = np.zeros(matrix.shape[0])
    priced = np.zeros(matrix.shape[0])
    in_lp = np.zeros(matrix.shape[0], dtype=bool)
    for k in range(n_parts):
        points = np.flatnonzero(part == k)
        sub = matrix[:, points].tocsr()
        rows = np.flatnonzero(np.diff(sub.indptr) > 0)
        if len(rows) == 0:  # no point of the part, or none any candidate sees
            continue
        sub = sub[rows]
        share = cost[rows] * np.diff(sub.indptr) / sizes[rows]
        goal = min(coverable[k], math.ceil(inst.goal * coverable[k] / total))
        start = np.flatnonzero(np.isin(rows, initial))
        lp = yield from quiet(cover_lp(
            CoverInstance(sub, goal, need=inst.k[points]), share, group[rows], start,
            integral=False,
            deadline=deadline, stop=stop, rel_gap=rel_gap,
        ))  # fmt: skip
        if not np.isfinite(lp.value):  # stopped before its first solve
            complete = False
            continue
        lines[k] = (lp.slope, lp.intercept)
        value += lp.value
        rounds += lp.rounds
        complete = complete and lp.complete
        cols = rows[lp.columns]
        x[cols] = np.maximum(x[cols], lp.x)
        in_lp[cols] = True
        priced[rows] += lp.priced
        bound = combined_bound(lines, coverable, inst.goal)
        yield LPProgress(rounds, value, bound, int(np.count_nonzero(in_lp)))
    bound = combined_bound(lines, coverable, inst.goal)
    columns = np.flatnonzero(in_lp).astype(np.int64)
    return LPSolution(
        value, bound, columns, x[columns], priced, cost - priced, rounds, complete,
        parts=n_parts,
    )  # fmt: skip


def mast_aware_bound(
    lp: LPSolution,
    site_of: I64,
    mast_cost: MastCost,
    sensor_cost: float,
    lp_cost: F64 | None = None,
) -> float:
    """A proven lower bound on the mast-aware LP (so on the cost of every plan) from
    the last duals of the sensors LP, solved with the costs ``lp_cost`` (C,) (None:
    1 each), a sensor costing ``sensor_cost`` times that: scaled by the largest ``t``
    for which every site ``s`` can share ``mast_cost`` out as the link duals its
    candidates need, ``sum_{c at s} sensor_cost max(0, t priced_c - lp_cost_c) <=
    mast_cost``, they are feasible for the mast-aware LP's dual, whose value is then
    ``t sensor_cost value``. 0 when nothing was solved, or when the LP was solved in
    parts (their duals are not one dual solution of the whole)."""
    if not np.isfinite(lp.value) or len(lp.priced) == 0 or sensor_cost <= 0 or lp.parts > 1:
        return 0.0
    value = lp.value if math.isnan(lp.dual) else lp.dual
    unit = 1.0 if lp_cost is None else lp_cost
    n_sites = max(int(site_of.max()) + 1, int(np.size(mast_cost)))
    per_site = cost_at(mast_cost, np.arange(n_sites))

    def fits(t: float) -> bool:
        excess = sensor_cost * np.maximum(0.0, t * lp.priced - unit)
        return bool((np.bincount(site_of, weights=excess, minlength=n_sites) <= per_site).all())

    lo, hi = 0.0, 1.0
    while fits(hi) and hi < 1e6:  # the feasible t may exceed 1
        lo, hi = hi, 2 * hi
    for _ in range(50):  # bisection; lo stays feasible
        mid = (lo + hi) / 2
        lo, hi = (mid, hi) if fits(mid) else (lo, mid)
    return max(0.0, lo * sensor_cost * value * (1 - SAFETY) - SAFETY)


@dataclass(frozen=True)
class SiteSolution:
    """The fewest sites covering the goal: a proven lower bound, the best set found
    (optimal when ``bound == len(sites)``), and the sites the LP relaxation uses
    (value > 0; empty if it was not solved); ``more``: other sets a plan may look
    for masts at (a part's, ``parts.part_sites``)."""

    bound: int
    sites: I64
    lp_sites: I64
    more: tuple[I64, ...] = ()

    def site_sets(self) -> list[I64]:
        """The distinct non-empty site sets, the best set found first."""
        sets: list[I64] = []
        for on in (self.sites, self.lp_sites, *self.more):
            if len(on) and not any(np.array_equal(on, seen) for seen in sets):
                sets.append(on)
        return sets


def site_matrix(inst: CoverInstance, site_of: I64, n_sites: int) -> sparse.csr_matrix:
    """(n_sites, points), float64, indices sorted: what an open site adds to a point's
    cover. Site s covers point n when any candidate at s (``site_of``: (C,)) does;
    with k > 1 it adds up to min(its candidates covering n, k_n) (every plan's
    sensors there are among those candidates); with k = 1, 1. The rows of ``inst``
    count as many candidates as their entries say (1 each in a candidate matrix), so
    a site matrix given as ``inst`` with ``site_of`` = its rows comes back the same."""
    m = inst.matrix
    # (Counted in float32, exact for these counts: a float64 copy of a Town01 part's
    # 31 M entries would be 0.25 GB more at the run's peak.)
    one = np.float32
    pick = sparse.csr_matrix(
        (np.ones(len(site_of), one), (site_of, np.arange(len(site_of)))),
        shape=(n_sites, m.shape[0]),
    )
    seen = sparse.csr_matrix((m.data.astype(one), m.indices, m.indptr), shape=m.shape)
    sites = (pick @ seen).tocsr().astype(np.float64)
    sites.sort_indices()
    k = inst.k[sites.indices]
    sites.data = np.minimum(sites.data, k) if inst.multi else np.ones(sites.nnz)
    return sites


def site_cover(
    inst: CoverInstance,
    site_of: I64,
    n_sites: int,
    deadline: float | None = None,
    stop: threading.Event | None = None,
    milp: bool = True,
    standing: NDArray[np.bool_] | None = None,
) -> Generator[None, None, SiteSolution]:
    """The fewest sites (mast positions) whose candidates cover the goal: the LP
    relaxation, then, when ``milp``, the MILP over sites (see the module docstring);
    stops at ``deadline``, or when ``stop`` is set, with the bound proven so far and
    the best set found. Without the MILP the bound is the LP's rounded up and no set
    is found. standing: (n_sites,) sites where a mast stands already: they cost
    nothing, so the bound is on the new masts.
    """
    sites = site_matrix(inst, site_of, n_sites)
    multi = inst.multi
    # Points seen from the same sites are one row (two_routes: 16,555 points, 8,310 rows;
    # the MILP took 5 s instead of 19 s).
    merged = MergedPoints.of(sites, inst.k)
    n = merged.matrix.shape[1]
    need = merged.need if multi else None

    def model() -> highspy.Highs:
        # A fresh model for each solve: HiGHS' MILP on a model whose LP was solved
        # before took 92 s on two_routes where a fresh one takes 11 s.
        limit = None if deadline is None else deadline - time.perf_counter()
        h = _new_highs(limit)
        _cover_rows(h, n, inst.goal, need, merged.weight)
        weight = np.ones(n_sites) if standing is None else np.where(standing, 0.0, 1.0)
        _add_columns(h, merged.matrix, weight, 1.0, merged.matrix.data if multi else None)
        return h

    h = model()
    lp_sites = np.zeros(0, dtype=np.int64)
    lp_bound = 0
    solved = yield from _run(h, stop)
    if solved is Solve.DONE and h.getModelStatus() == highspy.HighsModelStatus.kOptimal:
        lp_sites = np.flatnonzero(np.asarray(h.getSolution().col_value)[n:] > 1e-6)
        lp_bound = math.ceil(float(h.getInfo().objective_function_value) * (1 - SAFETY) - 1e-6)
    if not milp:
        return SiteSolution(max(lp_bound, 0), np.zeros(0, dtype=np.int64), lp_sites)
    h = model()
    # With k > 1 a point's u must be whole too: one of its k would count it half.
    first = 0 if need is not None else n
    h.changeColsIntegrality(
        n + n_sites - first,
        np.arange(first, n + n_sites, dtype=np.int32),
        np.array([highspy.HighsVarType.kInteger] * (n + n_sites - first)),
    )
    if (yield from _run(h, stop)) is Solve.GONE:
        return SiteSolution(max(lp_bound, 0), np.zeros(0, dtype=np.int64), lp_sites)
    info = h.getInfo()
    if h.getModelStatus() == highspy.HighsModelStatus.kOptimal:
        bound = round(float(info.objective_function_value))
    else:  # stopped early: the dual bound so far (none yet: 0)
        dual = float(info.mip_dual_bound)
        bound = max(lp_bound, math.ceil(dual - 1e-6) if math.isfinite(dual) else 0)
    values = np.asarray(h.getSolution().col_value)
    chosen = np.zeros(0, dtype=np.int64)
    if len(values) == n + n_sites and info.primal_solution_status == 2:  # feasible
        chosen = np.flatnonzero(values[n:] > 0.5).astype(np.int64)
    return SiteSolution(bound, chosen, lp_sites)


def sensors_on_sites(
    inst: CoverInstance,
    site_of: I64,
    sites: I64,
    start: list[int],
    mast_cost: MastCost,
    sensor_cost: SensorCost,
    deadline: float | None = None,
    stop: threading.Event | None = None,
    cols: I64 | None = None,
    cutoff: float | None = None,
    most_multi: int = MAX_MULTI_MILP_CANDIDATES,
) -> Generator[None, None, list[int]]:
    """The best plan on ``sites`` by the mast-aware MILP: every candidate at those
    sites, or those of ``cols`` there (x_c, binary, ``sensor_cost``: one for all or
    (C,) per candidate), each site (y_s, binary, ``mast_cost``), ``x_c <= y_s``, at
    most the instance's ``cap`` candidates per site (less those standing there,
    ``held``), and the cover rows. ``start`` (candidates at those sites that reach
    the goal) is HiGHS' first incumbent. At most
    ``MAX_NODES`` branch-and-bound nodes, so the answer does not depend on the
    machine's speed; stops at ``deadline`` or ``stop`` with the best plan so far.
    ``cutoff``: only plans whose objective is below it are looked for (HiGHS prunes
    every node whose bound is not; a start above it is not given to it); ``start``
    when none is found, or at k > 1 on more than ``most_multi`` candidates.
    Returns the chosen candidates."""
    if cols is None:
        cols = np.flatnonzero(np.isin(site_of, sites)).astype(np.int64)
    cols = np.unique(cols[np.isin(site_of[cols], sites)])
    if inst.multi and len(cols) > most_multi:
        return list(start)
    site_idx = np.searchsorted(sites, site_of[cols])
    # Points seen by the same of these candidates are one row (see ``MergedPoints``).
    merged = MergedPoints.of(inst.matrix[cols], inst.k)
    n, n_cols, n_sites = merged.matrix.shape[1], len(cols), len(sites)
    limit = None if deadline is None else deadline - time.perf_counter()
    h = _new_highs(limit)
    h.setOptionValue("mip_max_nodes", MAX_NODES)
    if cutoff is not None:
        h.setOptionValue("objective_bound", float(cutoff))
    _cover_rows(h, n, inst.goal, merged.need if inst.multi else None, merged.weight)
    _add_columns(h, merged.matrix, cost_at(sensor_cost, cols), 1.0)
    none = np.zeros(0, dtype=np.int32)
    h.addCols(n_sites, cost_at(mast_cost, sites), np.zeros(n_sites), np.ones(n_sites), 0,
              np.zeros(n_sites, dtype=np.int32), none, np.zeros(0))  # fmt: skip
    # Columns: the n u, then the x of cols, then the y of sites. Rows, each <= 0:
    # x_c - y_s for each candidate, and with a cap sum_{c at s} x_c - room_s y_s per
    # site (the cap less the sensors standing there, ``CoverInstance.room``).
    x_col, y_col = n + np.arange(n_cols), n + n_cols + np.arange(n_sites)
    row, col = [np.arange(n_cols)] * 2, [x_col, y_col[site_idx]]
    val = [np.ones(n_cols), -np.ones(n_cols)]
    n_rows = n_cols
    if inst.cap is not None:
        row += [n_cols + site_idx, n_cols + np.arange(n_sites)]
        col += [x_col, y_col]
        val += [np.ones(n_cols), -inst.room(sites).astype(float)]
        n_rows += n_sites
    rows = (np.concatenate(val), (np.concatenate(row), np.concatenate(col)))
    _le_zero_rows(h, sparse.csr_matrix(rows, shape=(n_rows, n + n_cols + n_sites)))
    # With k > 1 a point's u must be whole too: one of its k would count it half.
    binary = np.arange(0 if inst.multi else n, n + n_cols + n_sites, dtype=np.int32)
    h.changeColsIntegrality(
        len(binary), binary, np.array([highspy.HighsVarType.kInteger] * len(binary))
    )
    picked = np.isin(cols, start)
    count = np.asarray((merged.matrix[picked] != 0).sum(axis=0)).ravel()
    covered = count >= merged.need
    first = highspy.HighsSolution()
    first.col_value = (
        np.concatenate([covered, picked, np.isin(np.arange(n_sites), site_idx[picked])])
        .astype(float)
        .tolist()
    )
    if cutoff is None or plan_price(start, site_of, mast_cost, sensor_cost) < cutoff:
        h.setSolution(first)
    if (yield from _run(h, stop)) is Solve.GONE:
        return list(start)
    values = np.asarray(h.getSolution().col_value)
    if len(values) != n + n_cols + n_sites or h.getInfo().primal_solution_status != 2:
        return list(start)
    chosen = [int(c) for c in cols[values[n : n + n_cols] > 0.5]]
    # HiGHS' heuristics may return a plan above the cutoff (it prunes by it, no more).
    if cutoff is not None and plan_price(chosen, site_of, mast_cost, sensor_cost) >= cutoff:
        return list(start)
    return chosen
