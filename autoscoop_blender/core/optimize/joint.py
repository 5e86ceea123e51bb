"""A joint bound on masts and sensors: the fewest sensors any plan on at most m masts needs.

A plan costs ``mast_cost x masts + sensor_cost x sensors``. The masts bound
(``bound.site_cover``) and the sensors bound (``bound.cover_lp``) are each proven
alone: neither knows the other, nor the cap on sensors per mast, and their sum is
loose when the plans on the fewest masts need more sensors than the fewest sensors
(spread over many masts) do. This module bounds both together.

**The LP.** For a number of masts m, the fewest sensors (at costs ``cost_c``) of
any plan with at most m new masts, relaxed:

    S_LP(m) = min  sum_c cost_c x_c
              s.t. sum_c a_nc x_c - k_n u_n >= 0     every point n      (pi_n >= 0)
                   sum_n u_n >= goal                                    (sigma >= 0)
                   x_c <= y_s(c),  sum_{c at s} x_c <= cap y_s           every site s
                   sum_{s not standing} y_s <= m
                   0 <= u_n, y_s <= 1,  x_c >= 0

(``y_s`` opens site s; a mast that stands already costs nothing and is outside the
sum). Every plan with at most m new masts is a solution, so its sensors cost at
least S_LP(m).

**One dual solution bounds every m.** Move the cover rows and the goal row into the
objective with any pi >= 0, sigma >= 0. What is left splits by site: a site open at
y_s takes the candidates with the largest excess ``e_c = (A pi)_c - cost_c > 0``, at
most ``cap`` of them, each at most y_s; so

    S_LP(m') >= f(m') = sigma goal - sum_n max(0, sigma - k_n pi_n)
                        - sum_{s standing} phi_s - (the m' largest phi_s of the others)

for every m', with ``phi_s`` the sum of the ``cap`` largest excesses at s. A plan
with m' new masts (m' at least the fewest masts, M) costs at least
``mast_cost m' + sensor_cost ceil(max(f(m'), S))`` (S: the sensors bound, which
holds for every m'), and the least of these over m' >= M is the **joint bound**
(``joint_cost_bound``). On the instance where the cap forces a second mast that
neither bound sees (``tests/core/test_joint.py``) it is the optimum.

**Site rows (``tight``).** A point covered by a plan is seen from one of its masts,
so ``sum_s b_ns y_s >= k_n u_n`` holds too (b_ns: min(site s's candidates seeing n,
k_n), as in ``site_cover``). Without these rows a site open at 1/2 may carry two
candidates at 1/2 that both see a point, which counts it covered once; with them it
counts 1/2. With their duals rho >= 0 the per-site term becomes ``phi_s + (B^T
rho)_s`` and a point's ``k_n pi_n`` becomes ``k_n (pi_n + rho_n)``: the same argument,
so f still bounds every m'. They join as the LP's y leaves a point short, and a
site may join for them alone. On two_routes at m = 13 they lift S_LP from 31.02 to
32.05, and the cost bound from 71 to 72, for 2.5-3 x the LP's time (150-180 s
against 58 s, 2026-11-28): an option (``tight_bound``), not the default.

**Row and column generation.** The LP at one m is solved from the sensors LP's
columns and the points its duals price (on two_routes 4,045 of 16,555): a point
without its row counts as covered (the goal less those points: a relaxation). Each
round new columns (the candidates of sites in the LP whose reduced cost,
``cost_c - (A pi)_c`` plus their site's cap dual, is negative; the best ``cap`` of
sites outside whose excess beats the masts' dual) join; when none does, the points
the LP's x leaves short of their k get their rows. Every round's duals give ``f``
over all points and candidates, so the bound holds whenever the search stops. On
two_routes at m = 13 it passes 31 (S_LP(13) = 31.02; the sensors LP is 30.93) in
12 rounds, 38 s, and lifts the cost bound from 70 to 71.

**Whole sensors.** The cost bound counts whole sensors, ``ceil(f(m))``, so once a
solution of the whole LP costs no more than that integer, S_LP(m) is no higher and
no later round can raise it: the LP stops (``settled``). The restricted LP's own
solution is none while rows are missing: it may break links it has no row for, and
it counts the points without a row as covered. ``repaired_cost`` builds one from it:
each x_c clipped to its site's y, the points still short of the goal covered by
candidates at the open sites within their links and caps, y unchanged (so the budget
holds). On two_routes at m = 13 the bound passes 31 in round 9 of 15 and the repaired
solution costs 31.20 there, so the LP ends 6 rounds early with the same 32 sensors.

Hand-written pricing around HiGHS (which solves each restricted LP): no library
generates rows and columns of this model, nor repairs its solutions.
"""

from __future__ import annotations

import logging
import math
import threading
import time
from collections.abc import Generator
from dataclasses import dataclass

import highspy
import numpy as np
from numpy.typing import NDArray
from scipy import sparse

from .bound import (
    SAFETY,
    MergedPoints,
    Solve,
    _add_columns,
    _cover_rows,
    _le_zero_rows,
    _new_highs,
    _run,
    limit_to,
    site_matrix,
)
from .cover import CoverInstance

F64 = NDArray[np.float64]
I64 = NDArray[np.int64]

log = logging.getLogger(__name__)

# The most new columns, and new point rows, a round.
PER_ROUND = 200
ROWS_PER_ROUND = 500
# The most raises of a repair (``repaired_cost``). On two_routes at k = 2 (the joint LP
# at 16 masts) 50 found a solution from round 14 on, 500 and 5,000 from round 11
# (62.85: the LP settles there); the LP's y leaves no more room to raise by then.
REPAIR_STEPS = 1000


@dataclass(frozen=True)
class MastsSensors:
    """The LP of the fewest sensors on at most ``masts`` masts, as far as it was solved.

    sensors: (n + 1,) f(m') for m' = 0 .. n other sites (n: the sites without a
    standing mast): a proven lower bound on the sensors' cost of any plan with at most
    m' new masts, from the best duals found (non-increasing in m'); value: the last
    restricted LP's optimum (not a bound); rounds; complete: no row and no column was
    left to add, so ``sensors[masts]`` is S_LP(masts) up to the solver's tolerance;
    settled: stopped once ``sensors[masts]``, rounded up to whole sensors, could rise
    no more (see the module docstring)."""

    masts: int
    sensors: F64
    value: float
    rounds: int
    complete: bool
    settled: bool = False

    def at(self, m: int) -> float:
        """The bound on the sensors' cost of plans with at most ``m`` new masts."""
        return float(self.sensors[min(max(m, 0), len(self.sensors) - 1)])


def _cap(inst: CoverInstance, site_of: I64) -> int:
    """The most candidates a site may hold: the instance's cap, or all of a site's."""
    return inst.cap if inst.cap is not None else int(np.max(np.bincount(site_of), initial=1))


def site_excess(
    inst: CoverInstance, cost: F64, site_of: I64, n_sites: int, pi: F64
) -> tuple[F64, F64]:
    """((C,) each candidate's excess max(0, (A pi)_c - cost_c), (n_sites,) phi_s: the
    sum of the cap largest at each site), for point duals pi (N,) >= 0. Prices in
    float64: a float32 sum of thousands of duals is off by more than the tolerance."""
    excess = np.maximum(0.0, np.asarray(inst.matrix @ pi, dtype=float) - cost)
    top = _top_per_site(excess, site_of, _cap(inst, site_of))
    phi = np.bincount(site_of[top], weights=excess[top], minlength=n_sites).astype(float)
    return excess, phi


def _top_per_site(score: F64, site_of: I64, cap: int | I64) -> I64:
    """The indices of the ``cap`` largest ``score`` at each site (of ``site_of``);
    cap: one for all, or one per entry (its site's, the same for each of them)."""
    order = np.lexsort((-score, site_of))
    sites = site_of[order]
    rank = np.arange(len(order)) - np.searchsorted(sites, sites)
    return order[rank < (cap if np.ndim(cap) == 0 else np.asarray(cap)[order])]


def dual_curve(
    inst: CoverInstance, phi: F64, standing: NDArray[np.bool_], pi: F64, sigma: float
) -> F64:
    """f(m') for m' = 0 .. the sites without a standing mast (see the module
    docstring), from point duals pi (N,) >= 0, sigma >= 0 and their sites' excesses
    phi (sites,) (``site_excess``), lowered by ``SAFETY``."""
    fixed = float(phi[standing].sum())
    others = np.sort(phi[~standing])[::-1]
    base = sigma * inst.goal - float(np.maximum(0.0, sigma - inst.k * pi).sum()) - fixed
    curve = base - np.concatenate([[0.0], np.cumsum(others)])
    return curve - SAFETY * (np.abs(curve) + 1.0)


def joint_cost_bound(
    solved: list[MastsSensors],
    fewest_masts: int,
    n_masts: int,
    mast_cost: float,
    sensor_cost: float,
    sensors: float,
    integral: bool,
) -> tuple[float, int]:
    """(the joint bound, the fewest m' where it is least): the least over m' from
    ``fewest_masts`` to ``n_masts`` (the sites without a standing mast) of
    ``mast_cost m' + sensor_cost s(m')``, s(m') the largest of the ``solved`` curves
    at m' and ``sensors`` (the sensors bound), rounded up when ``integral`` (unit
    sensor costs: whole sensors)."""
    best, where = math.inf, fewest_masts
    for m in range(max(fewest_masts, 0), max(n_masts, fewest_masts) + 1):
        if mast_cost * m + sensor_cost * sensors >= best:
            break  # s(m') >= sensors for every m': no larger m' is cheaper
        s = max([sensors] + [j.at(m) for j in solved])
        if integral:
            s = max(0.0, math.ceil(s - 1e-6))
        value = mast_cost * m + sensor_cost * s
        if value < best:
            best, where = value, m
    return best, where


def repaired_cost(
    inst: CoverInstance,
    cost: F64,
    site_of: I64,
    x: F64,
    y: F64,
    reach: F64 | None = None,
) -> tuple[float, F64]:
    """(its cost, x') of a solution of the whole LP (module docstring) made from a
    restricted one's x (C,) and y (sites,), y kept: each x_c clipped to its site's
    y (and a site's x scaled down to its cap times y, which the restricted LP's cap
    rows keep already), then the points short of the goal covered, the most per
    cost first, by candidates at sites with y > 0, each up to its site's y and
    within the site's cap times y. A point counts what the x' cover of it, at most
    its k and, with the site rows, at most ``reach`` (N,) (its site rows' sum of
    y). (inf, x') when the goal is not met within ``REPAIR_STEPS`` raises.
    The cost is then an upper bound on S_LP(m) for every m that y's budget
    fits."""
    cap = _cap(inst, site_of)
    x = np.minimum(x, y[site_of])
    load = np.bincount(site_of, weights=x, minlength=len(y))
    over = load > cap * y  # (never in the restricted LP's solutions)
    scale = np.ones(len(y))
    scale[over] = cap * y[over] / load[over]
    x = x * scale[site_of]
    load = np.bincount(site_of, weights=x, minlength=len(y))
    k = np.maximum(inst.k, 1).astype(float)
    limit = k if reach is None else np.minimum(k, reach)
    used = np.flatnonzero(x > 0)
    covers = np.asarray(inst.matrix[used].T @ x[used], dtype=float)

    def counted() -> float:
        return float((np.minimum(covers, limit) / k).sum())

    short = inst.goal - counted()
    pool = np.flatnonzero(y[site_of] > 1e-9)
    rows = sparse.csr_matrix(inst.matrix[pool], dtype=float)
    by_point = sparse.csc_matrix(rows)
    sites = site_of[pool]
    # What a unit of each candidate adds while no point it raises reaches its limit,
    # per cost: kept up to date as points reach their limits (one product over the
    # pool at the start, not one a raise: on two_routes at k = 2 that took 3-8 s for
    # 500 raises).
    below = covers < limit
    rate = np.asarray(rows @ np.where(below, 1.0 / k, 0.0), dtype=float) / cost[pool]
    for _ in range(REPAIR_STEPS):
        if short <= 0:
            return float(cost @ x), x
        room = np.maximum(0.0, np.minimum(y[sites] - x[pool], cap * y[sites] - load[sites]))
        usable = np.where(room > 1e-12, rate, 0.0)
        best = int(np.argmax(usable)) if len(usable) else -1
        if best < 0 or usable[best] <= 1e-12:
            break
        c = pool[best]
        amount = min(room[best], short / (usable[best] * cost[c]) + 1e-9)
        before = counted()
        row = rows[best]
        covers[row.indices] += amount * row.data
        x[c] += amount
        load[site_of[c]] += amount
        short -= counted() - before
        reached = row.indices[below[row.indices] & (covers[row.indices] >= limit[row.indices])]
        if len(reached):
            below[reached] = False
            lost = by_point[:, reached] @ (1.0 / k[reached])
            rate -= np.asarray(lost, dtype=float) / cost[pool]
    return (float(cost @ x), x) if short <= 0 else (math.inf, x)


class _Model:
    """The restricted LP in HiGHS, with where each point, site and candidate sits in it.

    Rows: 0 the goal, 1 the masts' budget, then the points', the sites' caps, the
    candidates' links and (``tight``) the points' site rows as they join. Columns: 0
    an artificial slack on the goal row (so the restricted LP is always feasible: a
    budget too small for the goal makes it expensive, and the duals then bound that
    m' high), then the u, y and x."""

    def __init__(
        self,
        inst: CoverInstance,
        cost: F64,
        site_of: I64,
        standing: NDArray[np.bool_],
        m: int,
        tight: bool = False,
    ) -> None:
        self.inst, self.cost, self.site_of, self.standing = inst, cost, site_of, standing
        self.cap, self.tight = inst.cap, tight
        n_cands, n_points = inst.matrix.shape
        # (points, sites) and (sites, points): what an open site adds to a point (the
        # site rows, ``tight``; ``site_cover``'s rows)
        self.sites_of_point = (
            sparse.csr_matrix(site_matrix(inst, site_of, len(standing)).T)
            if tight
            else sparse.csr_matrix((n_points, len(standing)))
        )
        self.points_of_site = sparse.csr_matrix(self.sites_of_point.T)
        self.site_row_of = np.full(n_points, -1, dtype=np.int64)
        self.u_of = np.full(n_points, -1, dtype=np.int64)
        self.row_of = np.full(n_points, -1, dtype=np.int64)
        self.col_of = np.full(n_cands, -1, dtype=np.int64)
        self.linked = np.zeros(n_cands, dtype=bool)  # has its link row
        self.y_of = np.full(len(standing), -1, dtype=np.int64)
        self.cap_row_of = np.full(len(standing), -1, dtype=np.int64)
        self.h = h = _new_highs(None)
        inf = highspy.kHighsInf
        none_i, none_f = np.zeros(0, np.int32), np.zeros(0)
        # The goal row's right-hand side: the goal less the points without a row yet.
        h.addRows(2, np.array([float(inst.goal - n_points), -inf]), np.array([inf, float(m)]),
                  0, np.zeros(2, np.int32), none_i, none_f)  # fmt: skip
        slack = float(np.max(cost, initial=1.0)) * float(inst.k.max(initial=1)) * 1e3
        h.addCols(1, np.array([slack]), np.zeros(1), np.array([inf]), 1,
                  np.zeros(1, np.int32), np.zeros(1, np.int32), np.ones(1))  # fmt: skip
        self.outside = n_points  # points without a row

    def _le_zero(self, rows: sparse.csr_matrix) -> int:
        """Rows ``rows @ columns <= 0``; the index of the first."""
        first = self.h.getNumRow()
        _le_zero_rows(self.h, rows)
        return first

    def _cols(self, cost: F64, cols: sparse.csc_matrix) -> int:
        """Columns in [0, 1] with the entries of ``cols`` (rows so far, new columns);
        the index of the first."""
        first = self.h.getNumCol()
        by_column = sparse.csr_matrix(cols.T)
        _add_columns(self.h, by_column, cost, 1.0, by_column.data)
        return first

    def add_points(self, points: I64) -> int:
        """Rows for ``points`` (without one yet): their cover rows over the x in the
        LP, and their u."""
        points = points[self.row_of[points] < 0]
        if not len(points):
            return 0
        k, inst = len(points), self.inst
        # The points' entries over the candidates in the LP, from their rows alone (no
        # copy of the whole matrix by point: 213 MB on two_routes).
        cands = np.flatnonzero(self.col_of >= 0)
        sub = inst.matrix[cands][:, points].tocoo()
        rows = sparse.csr_matrix(
            (sub.data, (sub.col, self.col_of[cands][sub.row])), shape=(k, self.h.getNumCol())
        )
        first = self.h.getNumRow()
        self.h.addRows(k, np.zeros(k), np.full(k, highspy.kHighsInf), rows.nnz,
                       rows.indptr[:-1].astype(np.int32), rows.indices.astype(np.int32),
                       rows.data.astype(float))  # fmt: skip
        self.row_of[points] = first + np.arange(k)
        # u_n: -k_n in its row, 1 in the goal row (row 0); its site row joins when
        # the LP's y leaves it short (``add_site_rows``).
        entries = sparse.csc_matrix(
            (np.concatenate([-inst.k[points].astype(float), np.ones(k)]),
             (np.concatenate([first + np.arange(k), np.zeros(k, np.int64)]),
              np.tile(np.arange(k), 2))),
            shape=(self.h.getNumRow(), k),
        )  # fmt: skip
        self.u_of[points] = self.h.getNumCol() + np.arange(k)
        self._cols(np.zeros(k), entries)
        self.outside -= k
        self.h.changeRowBounds(0, float(self.inst.goal - self.outside), highspy.kHighsInf)
        return k

    def add_sites(self, sites: I64) -> int:
        """Columns y for ``sites`` (not in the LP yet), with their cap rows."""
        sites = np.unique(sites[self.y_of[sites] < 0])
        if not len(sites):
            return 0
        k = len(sites)
        row, val = [], []
        if self.cap is not None:
            first = self._le_zero(sparse.csr_matrix((k, self.h.getNumCol())))
            self.cap_row_of[sites] = first + np.arange(k)
            row.append(self.cap_row_of[sites])
            val.append(np.full(k, -float(self.cap)))
        budget = ~self.standing[sites]  # a standing mast is outside the budget (row 1)
        row.append(np.ones(int(budget.sum()), np.int64))
        val.append(np.ones(int(budget.sum())))
        col = [np.arange(k)] * (self.cap is not None) + [np.flatnonzero(budget)]
        sub = self.points_of_site[sites].tocoo()
        inside = self.site_row_of[sub.col] >= 0
        row.append(self.site_row_of[sub.col[inside]])
        val.append(sub.data[inside].astype(float))
        col.append(sub.row[inside])
        entries = sparse.csc_matrix(
            (np.concatenate(val), (np.concatenate(row), np.concatenate(col))),
            shape=(self.h.getNumRow(), k),
        )
        self.y_of[sites] = self._cols(np.zeros(k), entries) + np.arange(k)
        return k

    def add_columns(self, cands: I64) -> int:
        """Columns for ``cands`` (not in the LP yet), and their sites' y and cap rows
        (their links ``x_c - y_s <= 0`` join when broken: ``add_links``)."""
        cands = np.unique(cands[self.col_of[cands] < 0])
        if not len(cands):
            return 0
        k = len(cands)
        self.add_sites(self.site_of[cands])
        sub = self.inst.matrix[cands].tocoo()
        inside = self.row_of[sub.col] >= 0
        row = [self.row_of[sub.col[inside]]]
        col = [sub.row[inside]]
        val = [sub.data[inside].astype(float)]
        if self.cap is not None:
            row.append(self.cap_row_of[self.site_of[cands]])
            col.append(np.arange(k))
            val.append(np.ones(k))
        entries = sparse.csc_matrix(
            (np.concatenate(val), (np.concatenate(row), np.concatenate(col))),
            shape=(self.h.getNumRow(), k),
        )
        self.col_of[cands] = self._cols(self.cost[cands], entries) + np.arange(k)
        return k

    def add_site_rows(self, most: int) -> int:
        """Site rows ``sum_s b_ns y_s - k_n u_n >= 0`` for at most ``most`` points
        (with a cover row) whose u the LP's y leaves short, the shortest first."""
        values = np.asarray(self.h.getSolution().col_value)
        points = np.flatnonzero((self.u_of >= 0) & (self.site_row_of < 0))
        short = self.inst.k[points] * values[self.u_of[points]] - np.asarray(
            self.sites_of_point[points] @ self.y(), dtype=float
        )
        keep = short > 1e-7
        points = points[keep][np.argsort(-short[keep], kind="stable")][:most]
        if not len(points):
            return 0
        k = len(points)
        sub = self.sites_of_point[points].tocoo()
        inside = self.y_of[sub.col] >= 0
        rows = sparse.csr_matrix(
            (np.concatenate([sub.data[inside], -self.inst.k[points].astype(float)]),
             (np.concatenate([sub.row[inside], np.arange(k)]),
              np.concatenate([self.y_of[sub.col[inside]], self.u_of[points]]))),
            shape=(k, self.h.getNumCol()),
        )  # fmt: skip
        first = self.h.getNumRow()
        self.h.addRows(k, np.zeros(k), np.full(k, highspy.kHighsInf), rows.nnz,
                       rows.indptr[:-1].astype(np.int32), rows.indices.astype(np.int32),
                       rows.data.astype(float))  # fmt: skip
        self.site_row_of[points] = first + np.arange(k)
        return k

    def add_links(self) -> int:
        """Link rows ``x_c - y_s <= 0`` for the candidates in the LP whose x exceeds
        their site's y (the others hold without a row: only the cap rows tie x to y
        until a solution breaks a link)."""
        values = np.asarray(self.h.getSolution().col_value)
        cands = np.flatnonzero((self.col_of >= 0) & ~self.linked)
        cols, sites = self.col_of[cands], self.y_of[self.site_of[cands]]
        cands = cands[values[cols] > values[sites] + 1e-9]
        if not len(cands):
            return 0
        k = len(cands)
        links = sparse.csr_matrix(
            (np.tile([1.0, -1.0], k),
             (np.repeat(np.arange(k), 2),
              np.stack([self.col_of[cands], self.y_of[self.site_of[cands]]], 1).ravel())),
            shape=(k, self.h.getNumCol()),
        )  # fmt: skip
        self._le_zero(links)
        self.linked[cands] = True
        return k

    def duals(self) -> tuple[F64, F64, float, float, F64]:
        """(pi (N,), rho (N,) the site rows', sigma, the budget's dual, each site's cap
        dual (sites,)), all >= 0 (0 for rows not in the LP)."""
        row_dual = np.asarray(self.h.getSolution().row_dual)
        pi = np.zeros(len(self.row_of))
        has = self.row_of >= 0
        pi[has] = np.maximum(row_dual[self.row_of[has]], 0.0)
        rho = np.zeros(len(self.row_of))
        sited = self.site_row_of >= 0
        rho[sited] = np.maximum(row_dual[self.site_row_of[sited]], 0.0)
        beta = np.zeros(len(self.cap_row_of))
        on = self.cap_row_of >= 0
        beta[on] = np.maximum(-row_dual[self.cap_row_of[on]], 0.0)
        return pi, rho, max(float(row_dual[0]), 0.0), max(-float(row_dual[1]), 0.0), beta

    def _values(self, col_of: I64) -> F64:
        """The LP's value of each column ``col_of`` names (0 where it is -1: not in it)."""
        values = np.asarray(self.h.getSolution().col_value)
        out = np.zeros(len(col_of))
        has = col_of >= 0
        out[has] = values[col_of[has]]
        return out

    def y(self) -> F64:
        """(sites,) every site's value in the LP (0 outside it)."""
        return self._values(self.y_of)

    def x(self) -> F64:
        """(C,) every candidate's value in the LP (0 outside it)."""
        return self._values(self.col_of)

    def upper(self) -> float:
        """The cost of a solution of the whole LP repaired from this one's
        (``repaired_cost``; with the site rows when built ``tight``)."""
        y = self.y()
        reach = np.asarray(self.sites_of_point @ y, dtype=float) if self.tight else None
        return repaired_cost(self.inst, self.cost, self.site_of, self.x(), y, reach)[0]

    def covered(self) -> F64:
        """(N,) how much the LP's x covers each point (the sum of its entries)."""
        cands = np.flatnonzero(self.col_of >= 0)
        x = np.asarray(self.h.getSolution().col_value)[self.col_of[cands]]
        return np.asarray(self.inst.matrix[cands].T @ x, dtype=float)


def masts_sensors_lp(
    inst: CoverInstance,
    cost: F64,
    site_of: I64,
    standing: NDArray[np.bool_],
    masts: int,
    columns: I64,
    points: I64,
    deadline: float | None = None,
    stop: threading.Event | None = None,
    enough: float = math.inf,
    tight: bool = False,
    whole: bool = False,
) -> Generator[None, None, MastsSensors]:
    """The LP of the fewest sensors on at most ``masts`` new masts (see the module
    docstring; with its site rows when ``tight``), by rows and columns, from
    ``columns`` (candidates, e.g. the sensors LP's) and ``points`` (e.g. those its
    duals price). cost: (C,) > 0; standing: (sites,) where a mast stands already. Stops when nothing is left to add, at
    ``deadline`` (``time.perf_counter()``), at ``stop``, or once the bound at
    ``masts`` reaches ``enough`` (more would prove nothing the caller needs: the
    restricted LP's value is no upper bound to stop at while rows are missing), or,
    when ``whole`` (costs in whole sensors), once that bound rounded up can rise no
    more (``settled``, module docstring). Yields None while HiGHS works."""
    n_sites = len(standing)
    cap = _cap(inst, site_of)
    at = min(masts, int(np.count_nonzero(~standing)))  # where the curve holds ``masts``
    began = time.perf_counter()
    lp = _Model(inst, cost, site_of, standing, masts, tight)
    lp.add_points(np.asarray(points, dtype=np.int64))
    lp.add_columns(np.asarray(columns, dtype=np.int64))
    best: F64 | None = None
    value, rounds, complete, settled, why = math.inf, 0, False, False, "stopped"
    while True:
        if deadline is not None:
            limit_to(lp.h, deadline)
        if (yield from _run(lp.h, stop)) is not Solve.DONE:
            break
        if lp.h.getModelStatus() != highspy.HighsModelStatus.kOptimal:
            why = f"HiGHS: {lp.h.modelStatusToString(lp.h.getModelStatus())}"
            break
        rounds += 1
        value = float(lp.h.getInfo().objective_function_value)
        pi, rho, sigma, mu, beta = lp.duals()
        excess, phi = site_excess(inst, cost, site_of, n_sites, pi)
        phi = phi + np.asarray(lp.points_of_site @ rho, dtype=float)
        curve = dual_curve(inst, phi, standing, pi + rho, sigma)
        if best is None or curve[at] > best[at]:
            best = curve
        if best[at] >= enough:
            why = "enough"
            break
        # A repair is tried only where it may settle the LP: the restricted LP's value
        # is no bound, but near the LP's once few rows and columns are missing.
        sensors = math.ceil(best[at] - 1e-6)
        if whole and sensors >= value and lp.upper() <= sensors:
            settled, why = True, "settled"
            break
        if stop is not None and stop.is_set():
            break
        if deadline is not None and time.perf_counter() > deadline:
            break
        # Columns: candidates at sites in the LP with a negative reduced cost; at
        # sites outside it, the best ``cap`` where their excess beats the budget's
        # dual (a standing mast's, any excess).
        reduced = beta[site_of] - excess  # cost - (A pi) + beta where that is negative
        open_site = lp.y_of >= 0
        joins = np.flatnonzero((reduced < -1e-9) & (lp.col_of < 0) & open_site[site_of])
        joins = joins[np.argsort(reduced[joins], kind="stable")[:PER_ROUND]]
        gain = phi - np.where(standing, 0.0, mu)
        new_sites = np.flatnonzero((gain > 1e-9) & ~open_site)
        new_sites = new_sites[np.argsort(-gain[new_sites], kind="stable")][
            : max(1, PER_ROUND // cap)
        ]
        at_new = np.flatnonzero(np.isin(site_of, new_sites) & (excess > 0))
        at_new = at_new[_top_per_site(excess[at_new], site_of[at_new], cap)]
        # Rows: the points the LP's x leaves short of their k (no row yet).
        covered = lp.covered()
        if tight:  # short of their k in the sites' cover too
            covered = np.minimum(covered, np.asarray(lp.sites_of_point @ lp.y(), dtype=float))
        short = np.flatnonzero((lp.row_of < 0) & (covered < inst.k - 1e-6))
        short = short[np.argsort(covered[short] - inst.k[short], kind="stable")]
        added = lp.add_points(short[:ROWS_PER_ROUND]) + lp.add_links()
        added += lp.add_columns(np.concatenate([joins, at_new]))
        if tight:
            # A site may join for its site rows' duals alone, before any candidate of
            # it prices in (the LP may price a point in either of its two rows).
            added += lp.add_site_rows(ROWS_PER_ROUND) + lp.add_sites(new_sites)
        if added == 0:
            complete, why = True, "complete"
            break
    if best is None:
        best = np.zeros(int(np.count_nonzero(~standing)) + 1)
    log.info(
        "joint LP at %d masts%s: %s after %d rounds in %.1f s, value %.3f, bound %.3f",
        masts, " (site rows)" if tight else "", why, rounds, time.perf_counter() - began,
        value, best[at],
    )  # fmt: skip
    return MastsSensors(masts, best, value, rounds, complete, settled)


@dataclass(frozen=True)
class OnMasts:
    """The LP of the sensors on given masts (``sensors_on_masts``): bound, a lower
    bound on the new sensors of any plan on them (0: nothing proven, inf: they cannot
    reach the goal); cols (K,) the candidates at those masts and x (K,) the LP's
    solution over them (None when it was not solved to its end)."""

    bound: float
    cols: I64
    x: F64 | None = None


def sensors_on_masts(
    inst: CoverInstance,
    site_of: I64,
    sites: I64,
    deadline: float | None = None,
    stop: threading.Event | None = None,
) -> Generator[None, None, OnMasts]:
    """A lower bound on the new sensors of any plan whose new sensors all stand at
    ``sites`` (mast positions, e.g. a plan's own; site_of: (C,) each candidate's):
    the LP of such plans (every candidate there in [0, 1], at most each site's room,
    the cover rows and the goal) bounded from its duals, as ``f`` is with the masts
    fixed open, so the solver's tolerance cannot lift it. It tells a planner whether
    a cheaper plan could keep the masts: on two_routes the plan of 35 sensors on 13
    masts has an LP of 34.33 on them, so none on those masts has fewer. The bound is
    inf when the sites cannot reach the goal; 0 when stopped, or at ``deadline``
    (``time.perf_counter()``), before the LP's end. Yields None while HiGHS works."""
    cols = np.flatnonzero(np.isin(site_of, sites))
    if deadline is not None and time.perf_counter() >= deadline:
        return OnMasts(0.0, cols)
    began = time.perf_counter()
    # Points seen by the same of these candidates are one row (``MergedPoints``): a
    # group's dual pi_g prices all of its ``weight_g`` points at once.
    merged = MergedPoints.of(sparse.csr_matrix(inst.matrix[cols]), inst.k)
    n, n_cols = merged.matrix.shape[1], len(cols)
    if merged.weight.sum() < inst.goal:
        return OnMasts(math.inf, cols)  # they see fewer points than the goal
    h = _new_highs(None)
    _cover_rows(h, n, inst.goal, merged.need if inst.multi else None, merged.weight)
    _add_columns(h, merged.matrix, np.ones(n_cols), 1.0)
    room: int | I64 = n_cols  # no cap: every candidate may stand
    if inst.cap is not None:
        local, which = np.unique(site_of[cols], return_inverse=True)
        which = which.ravel()
        limit = inst.room(local)
        room = limit[which]
        per_site = sparse.csr_matrix(
            (np.ones(n_cols), (which, n + np.arange(n_cols))), shape=(len(local), n + n_cols)
        )
        h.addRows(len(local), np.full(len(local), -highspy.kHighsInf), limit.astype(float),
                  per_site.nnz, per_site.indptr[:-1].astype(np.int32),
                  per_site.indices.astype(np.int32), per_site.data)  # fmt: skip
    if deadline is not None:
        limit_to(h, deadline)
    if (yield from _run(h, stop)) is not Solve.DONE:
        return OnMasts(0.0, cols)
    status = h.getModelStatus()
    if status in (
        highspy.HighsModelStatus.kInfeasible, highspy.HighsModelStatus.kUnboundedOrInfeasible
    ):  # (never unbounded: nothing costs less than 0)
        return OnMasts(math.inf, cols)  # these masts cannot reach the goal
    if status != highspy.HighsModelStatus.kOptimal:
        return OnMasts(0.0, cols)  # (the deadline)
    duals = np.asarray(h.getSolution().row_dual)
    pi, sigma = np.maximum(duals[:n], 0.0), max(float(duals[n]), 0.0)
    # The Lagrangian of the cover rows and the goal row at (pi, sigma): each group's
    # u at its best in [0, 1], each site's best ``room`` candidates at 1.
    excess = np.maximum(0.0, np.asarray(merged.matrix @ pi, dtype=float) - 1.0)
    kept = _top_per_site(excess, site_of[cols], room)
    value = (
        sigma * inst.goal
        - float(np.maximum(0.0, sigma * merged.weight - merged.need * pi).sum())
        - float(excess[kept].sum())
    )
    log.info(
        "sensors LP on %d masts (%d candidates, %d groups of points): %.3f in %.2f s",
        len(sites), n_cols, n, value, time.perf_counter() - began,
    )  # fmt: skip
    x = np.asarray(h.getSolution().col_value)[n:]
    return OnMasts(value - SAFETY * (abs(value) + 1.0), cols, x)


def whole_sensors(bound: float) -> int | None:
    """The fewest whole sensors that a bound on them (``sensors_on_masts``) proves;
    None where it proves nothing (0: stopped, inf: the masts cannot reach the goal,
    which a plan's own masts always can)."""
    if not 0 < bound < math.inf:
        return None
    return max(0, math.ceil(bound - 1e-6))


def enough_sensors(best: float, mast_cost: float, sensor_price: float, masts: int) -> float:
    """The sensors on ``masts`` masts beyond which the joint bound there proves
    nothing more: the whole sensors it rounds up to then cost at least ``best``, the
    best plan's cost, with the masts (``joint_cost_bound``). Whole sensors, not the
    cost's share: at a price of 2 a sensor, 74 less 13 masts at 3 takes 18 sensors,
    so the LP goes on past 16.5 to 17."""
    share = (best - mast_cost * masts) / sensor_price
    if not math.isfinite(share):  # no plan yet: nothing is enough
        return share
    return math.ceil(share - 1e-9) - 1 + 1e-5


def joint_bound(
    inst: CoverInstance,
    site_of: I64,
    standing: NDArray[np.bool_],
    fewest: int,
    mast_cost: float,
    sensor_price: float,
    sensors: float,
    columns: I64,
    points: I64,
    best: float = math.inf,
    solved: list[MastsSensors] | None = None,
    deadline: float | None = None,
    stop: threading.Event | None = None,
    tight: bool = False,
) -> Generator[None, None, float]:
    """The joint bound on a plan's cost, ``mast_cost`` a new mast and ``sensor_price``
    a sensor (see the module docstring): the LP of the fewest sensors on at most m
    masts, solved at the m where the bound is least (``joint_cost_bound``; ``solved``:
    those solved already, and it gets the new ones) until that m is solved (its value
    there is then final), as far as the ``deadline`` and ``stop`` allow, and while
    the best plan's cost ``best`` is above it; with the site rows when ``tight``.
    fewest: a lower bound on the new masts;
    sensors: on the sensors; columns, points: where each LP starts
    (``masts_sensors_lp``)."""
    solved = [] if solved is None else solved
    n_masts = int(np.count_nonzero(~standing))
    ones = np.ones(inst.matrix.shape[0])

    def least() -> tuple[float, int]:
        return joint_cost_bound(
            solved, fewest, n_masts, mast_cost, sensor_price, sensors, integral=True
        )

    while stop is None or not stop.is_set():
        if deadline is not None and time.perf_counter() >= deadline:
            break
        value, m = least()
        # Solved at m already: to the end (final), or as far as time allowed.
        if value >= best or any(j.masts == m for j in solved):
            break
        solved.append((yield from masts_sensors_lp(
            inst, ones, site_of, standing, m, columns, points, deadline, stop,
            enough_sensors(best, mast_cost, sensor_price, m), tight, whole=True,
        )))  # fmt: skip
    return least()[0]
