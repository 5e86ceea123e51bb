"""Partial set cover on the candidate set: the moves a plan is built and improved with.

The instance: candidates (rows of the candidate matrix), target points (columns), and
the goal: at least ``goal`` points covered, each by its k candidates (``need``;
multicover, every k = 1 by default; a candidate is chosen once at most). A ``Cover``
is a set of chosen candidates with the number of them covering each point. The moves,
each cheap enough to repeat thousands of times on 130,000 candidates:

* ``complete``: add the candidate that covers the most points still uncovered per
  its cost (a new mast costing extra), until the goal is met (greedy);
* ``prune``: drop chosen candidates whose points stay covered well enough without them
  (the one whose removal loses the fewest points first);
* ``swap_two_for_one``: replace two chosen candidates by one of a pool (cheaper than
  the two) that covers what only those two covered (less the slack over the goal);
* ``improve``: prune and swap until neither helps;
* ``close_sites``: close a mast and cover its points from the other masts, while that
  lowers the cost.

Candidates may cost differently (a pack of models); the instance may cap the
candidates one mast site holds (``CoverInstance.cap``, less the sensors standing
there already): the moves keep within it.

They are hand-written because no library does partial set cover moves on sparse
matrices; the LP behind them is HiGHS (``bound.py``).
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
from numpy.typing import NDArray
from scipy import sparse

I64 = NDArray[np.int64]


@dataclass
class CoverInstance:
    """matrix: (C, N) CSR, 1 where candidate c covers point n; goal: points to cover;
    xy: (N, 2) where the points are, m (None if not known); need: (N,) candidates
    that must cover each point for it to count (None: 1 each); site_of: (C,) each
    candidate's mast site and cap: the most candidates one site may hold (None: no
    limit; both or neither); held: (sites,) the planned sensors that stand at each
    site already, which count against its cap (None: none)."""

    matrix: sparse.csr_matrix
    goal: int
    xy: NDArray[np.float64] | None = None
    need: NDArray[np.int32] | None = None
    site_of: I64 | None = None
    cap: int | None = None
    held: I64 | None = None
    _by_point: sparse.csc_matrix | None = field(default=None, repr=False)

    def __post_init__(self) -> None:
        if self.need is None:
            self.need = np.ones(self.matrix.shape[1], dtype=np.int32)

    @property
    def k(self) -> NDArray[np.int32]:
        """(N,) ``need``, always set."""
        assert self.need is not None
        return self.need

    @property
    def multi(self) -> bool:
        """Whether some point needs more than one candidate."""
        return bool(len(self.k) and int(self.k.max()) > 1)

    def room(self, sites: I64) -> I64:
        """(len(sites),) how many more candidates each of ``sites`` may hold: the cap
        less what stands there already (``held``). Needs ``cap``."""
        assert self.cap is not None
        sites = np.asarray(sites)
        held = np.zeros(sites.shape, np.int64) if self.held is None else self.held[sites]
        return np.maximum(self.cap - held, 0).astype(np.int64)

    @property
    def n_points(self) -> int:
        return int(self.matrix.shape[1])

    def covers(self, c: int) -> I64:
        """The points candidate ``c`` covers."""
        m = self.matrix
        return m.indices[m.indptr[c] : m.indptr[c + 1]]

    @property
    def by_point(self) -> sparse.csc_matrix:
        """The matrix by columns: which candidates cover a point (built once)."""
        if self._by_point is None:
            self._by_point = self.matrix.tocsc()
        return self._by_point

    def cells(self, cell_m: float, offset: tuple[float, float] = (0.0, 0.0)) -> tuple[I64, I64]:
        """The squares of ``cell_m`` the points fall in (their grid moved by ``offset``,
        m): (S,) the first point of each square, in the points' order, and (N,) the
        square of each point, as an index into those. Needs ``xy``."""
        assert self.xy is not None
        cell = np.floor((self.xy + np.asarray(offset)) / cell_m).astype(np.int64)
        _, first, square = np.unique(cell, axis=0, return_index=True, return_inverse=True)
        order = np.argsort(first)
        rank = np.empty_like(order)
        rank[order] = np.arange(len(order))
        return first[order].astype(np.int64), rank[square.ravel()].astype(np.int64)

    def thinned(self, cell_m: float, offset: tuple[float, float] = (0.0, 0.0)) -> CoverInstance:
        """The instance on one point per square of ``cell_m`` (the first in the
        square, ``cells``; the squares moved by ``offset``, m), its goal the same share
        of the points, rounded up: a cheaper model of the ground for a heuristic or a
        start that needs no proof (no bound of the sample's is one of the whole).
        Needs ``xy``."""
        assert self.xy is not None
        keep, _ = self.cells(cell_m, offset)
        goal = -(-self.goal * len(keep) // max(self.n_points, 1))
        return CoverInstance(
            self.matrix[:, keep].tocsr(), goal, self.xy[keep], self.k[keep], self.site_of,
            self.cap, self.held,
        )  # fmt: skip


class Cover:
    """Chosen candidates and, per point, how many of them cover it."""

    def __init__(self, inst: CoverInstance, chosen: list[int] | tuple[int, ...] = ()) -> None:
        self.inst = inst
        self.chosen: list[int] = []
        self.count = np.zeros(inst.n_points, dtype=np.int32)
        self.n_covered = 0
        # Chosen candidates per site, when sites have a cap.
        self.at_site: dict[int, int] = {}
        for c in chosen:
            self.add(c)

    def full(self, site: int) -> bool:
        """Whether ``site`` holds as many chosen candidates as its cap allows (less
        the sensors that stand there already)."""
        inst = self.inst
        if inst.cap is None:
            return False
        held = 0 if inst.held is None else int(inst.held[site])
        return self.at_site.get(site, 0) >= inst.cap - held

    @property
    def slack(self) -> int:
        """Points covered to their k beyond the goal (negative: short of it)."""
        return self.n_covered - self.inst.goal

    def add(self, c: int) -> None:
        pts = self.inst.covers(c)
        self.n_covered += int(np.count_nonzero(self.count[pts] == self.inst.k[pts] - 1))
        self.count[pts] += 1
        self.chosen.append(int(c))
        if self.inst.site_of is not None:
            site = int(self.inst.site_of[c])
            self.at_site[site] = self.at_site.get(site, 0) + 1

    def remove(self, c: int) -> None:
        pts = self.inst.covers(c)
        self.count[pts] -= 1
        self.n_covered -= int(np.count_nonzero(self.count[pts] == self.inst.k[pts] - 1))
        self.chosen.remove(int(c))
        if self.inst.site_of is not None:
            self.at_site[int(self.inst.site_of[c])] -= 1

    def short(self) -> NDArray[np.bool_]:
        """(N,) the points below their k."""
        return self.count < self.inst.k

    def exclusive(self, c: int) -> int:
        """Points that drop below their k if chosen candidate ``c`` is removed (k = 1:
        the points only it covers)."""
        pts = self.inst.covers(c)
        return int(np.count_nonzero(self.count[pts] == self.inst.k[pts]))


# A mast cost: one for every site, or (S,) one per site (0 where a mast stands already).
MastCost = float | NDArray[np.float64]
# A sensor cost: one for every candidate, or (C,) one per candidate (a mixed pack).
SensorCost = float | NDArray[np.float64]


def cost_at(cost: MastCost | SensorCost, index: I64) -> NDArray[np.float64]:
    """(len(index),) the cost (one for all, or one per site or candidate) at each of
    ``index``."""
    if np.ndim(cost) == 0:
        return np.full(len(index), float(cost))
    return np.asarray(cost, dtype=float)[index]


def plan_price(
    chosen: list[int], site_of: I64, mast_cost: MastCost, sensor_cost: SensorCost
) -> float:
    """What a plan of candidates costs at these prices: its sensors' and its masts'
    (the mast-aware MILP's objective, ``bound.sensors_on_sites``)."""
    picked = np.asarray(chosen, dtype=np.int64)
    masts = np.unique(site_of[picked])
    return float(cost_at(sensor_cost, picked).sum() + cost_at(mast_cost, masts).sum())


def complete(
    cover: Cover,
    pool: I64,
    site_of: I64 | None = None,
    mast_cost: MastCost = 0.0,
    sensor_cost: SensorCost = 1.0,
    barred: NDArray[np.bool_] | None = None,
    prepared: tuple[sparse.csr_matrix, sparse.csc_matrix] | None = None,
) -> Cover:
    """Add candidates of ``pool`` until the goal is met: each time the one covering
    the most uncovered points per ``sensor_cost`` (one for all, or (C,) per
    candidate) or, given each candidate's site (``site_of``, all candidates), per
    that plus the site's ``mast_cost`` at a site no chosen candidate uses yet. A site
    at the instance's cap takes no more. Stops early when no candidate adds a point.
    barred: (len(pool),) candidates of the pool not to take; prepared: the pool's
    rows of the matrix and their transpose (``pool_matrices``), made if not given."""
    inst = cover.inst
    sub, by_point = pool_matrices(inst, pool) if prepared is None else prepared
    gains = np.asarray(sub @ cover.short().astype(np.float32)).ravel()
    # A candidate is chosen once at most (with k > 1 a chosen one may still gain).
    gains[np.isin(pool, cover.chosen)] = -1.0
    if barred is not None:
        gains[barred] = -1.0
    own = np.maximum(cost_at(sensor_cost, pool), 1e-9)  # never divide by 0
    price = own.copy()
    capped = inst.site_of if inst.cap is not None else None
    if capped is not None:
        full = [s for s in cover.at_site if cover.full(s)]
        gains[np.isin(capped[pool], full) | (inst.room(capped[pool]) == 0)] = -1.0
    if site_of is not None:
        site = site_of[pool]
        used = np.isin(site, site_of[cover.chosen])
        # A sensor on a mast in use is taken before one that needs a new mast.
        price = np.maximum(own + cost_at(mast_cost, site) * ~used, 1e-9)
    while cover.slack < 0 and len(pool):
        k = int(np.argmax(gains / price))
        if gains[k] <= 0:
            break
        c = int(pool[k])
        new = inst.covers(c)
        new = new[cover.count[new] == inst.k[new] - 1]
        cover.add(c)
        if site_of is not None:
            at = site == site_of[c]
            price[at] = own[at]
        # Points covered to their k now add nothing to any candidate any more.
        gains -= np.asarray(by_point[:, new].sum(axis=1)).ravel()
        gains[k] = -1.0
        if capped is not None and cover.full(int(capped[c])):
            gains[capped[pool] == capped[c]] = -1.0
    return cover


def pool_matrices(inst: CoverInstance, pool: I64) -> tuple[sparse.csr_matrix, sparse.csc_matrix]:
    """(len(pool), N) the pool's rows of the matrix, by candidates and by points."""
    every = len(pool) == inst.matrix.shape[0] and bool(np.all(pool == np.arange(len(pool))))
    sub = inst.matrix if every else inst.matrix[pool]  # (no copy of every candidate)
    return sub, sub.tocsc()


def close_sites(cover: Cover, site_of: I64, mast_cost: MastCost, sensor_cost: SensorCost) -> Cover:
    """Close masts while that lowers the cost (``mast_cost`` per site in use plus
    ``sensor_cost`` per candidate): for each site in use, the one with the fewest
    candidates first, drop its candidates, cover the goal again from the candidates
    at the other sites in use (greedy per cost, pruned) and keep that if it costs
    less. Returns the cheapest cover found (``cover`` itself if none is cheaper)."""
    inst = cover.inst

    def cost(c: Cover) -> float:
        return plan_price(c.chosen, site_of, mast_cost, sensor_cost)

    best = cover
    closed = True
    while closed:  # passes over the sites in use until none closes
        closed = False
        sites, counts = np.unique(site_of[best.chosen], return_counts=True)
        in_use = set(sites.tolist())
        # Every site in use's candidates, by points once a pass (not once a site: on
        # two_routes at k = 2 that took 1.1 of the 2.5 s), each site left out in turn.
        pool = np.flatnonzero(np.isin(site_of, sites)).astype(np.int64)
        prepared = pool_matrices(inst, pool)
        for s in sites[np.lexsort((sites, counts))]:
            barred = ~np.isin(site_of[pool], np.array(sorted(in_use - {int(s)}), np.int64))
            kept = [c for c in best.chosen if site_of[c] != s]
            trial = prune(
                complete(Cover(inst, kept), pool, sensor_cost=sensor_cost, barred=barred,
                         prepared=prepared)
            )  # fmt: skip
            if trial.slack >= 0 and cost(trial) < cost(best):
                best, closed = trial, True
                in_use = set(site_of[best.chosen].tolist())
    return best


def prune(cover: Cover) -> Cover:
    """Drop chosen candidates while the goal stays met: the one that loses the fewest
    points first, as long as that is within the slack."""
    while cover.chosen:
        losses = np.array([cover.exclusive(c) for c in cover.chosen])
        k = int(np.argmin(losses))
        if losses[k] > cover.slack:
            break
        cover.remove(cover.chosen[k])
    return cover


def swap_two_for_one(
    cover: Cover,
    pool: I64,
    by_point: sparse.csr_matrix | None = None,
    sensor_cost: SensorCost = 1.0,
) -> bool:
    """Replace two chosen candidates by one from ``pool`` (or by none) keeping the goal;
    True when a swap was made. Tries pairs in order of how few points they alone cover.
    ``by_point``: the pool's matrix transposed to rows of points (made if not given).
    With a cost per candidate (``sensor_cost``, (C,)) the one must cost less than the
    two; a site at the instance's cap takes it only in place of one of the two.
    """
    inst = cover.inst
    if by_point is None:
        by_point = pool_by_point(inst, pool)
    chosen = list(cover.chosen)
    alone = {c: cover.exclusive(c) for c in chosen}
    pairs = sorted(
        ((a, b) for i, a in enumerate(chosen) for b in chosen[i + 1 :]),
        key=lambda p: alone[p[0]] + alone[p[1]],
    )
    # What holds for every pair, worked out once (the cover changes only on a swap,
    # which ends the call): at k > 1 the chosen candidates, which may not come in
    # again (save the two that leave), and the sites full or with no room.
    taken = np.isin(pool, chosen) if inst.multi else None
    unit = by_point.data.max(initial=0) <= 1  # a gain then counts points, at most ``back``
    pool_cost = cost_at(sensor_cost, pool) if np.ndim(sensor_cost) > 0 else None
    site_of = inst.site_of if inst.cap is not None else None
    if site_of is not None:
        at = site_of[pool]
        at_full = np.isin(at, [s for s in cover.at_site if cover.full(s)])
        no_room = inst.room(at) == 0
    for a, b in pairs:
        pa, pb = inst.covers(a), inst.covers(b)
        both, twice = np.unique(np.concatenate([pa, pb]), return_counts=True)
        count, k_both = cover.count[both], inst.k[both]
        left = count - twice
        lost = both[(count >= k_both) & (left < k_both)]
        need = len(lost) - cover.slack
        if need <= 0:
            cover.remove(a)
            cover.remove(b)
            return True
        # One candidate brings back only the lost points one short of their k.
        back = both[(count >= k_both) & (left == k_both - 1)]
        if unit and len(back) < need:  # no candidate brings back enough
            continue
        gains = _row_sums(by_point, back)
        if taken is not None:
            gains[taken & (pool != a) & (pool != b)] = -1.0
        if pool_cost is not None:
            gains[pool_cost >= cost_at(sensor_cost, np.array([a, b])).sum()] = -1.0
        if site_of is not None:
            # A full site may take one in place of one of the two that leave it.
            left_full = at_full & (at != site_of[a]) & (at != site_of[b])
            gains[left_full | no_room] = -1.0
        k = int(np.argmax(gains))
        if gains[k] >= need:
            cover.remove(a)
            cover.remove(b)
            cover.add(int(pool[k]))
            return True
    return False


def _row_sums(rows: sparse.csr_matrix, which: I64) -> NDArray[np.float64]:
    """(columns,) the sums of ``rows``' rows ``which`` (as ``rows[which].sum(0)``,
    without building the slice: the swaps' inner loop makes tens of thousands)."""
    starts, ends = rows.indptr[which], rows.indptr[np.asarray(which) + 1]
    lengths = ends - starts
    take = np.repeat(starts - np.cumsum(lengths) + lengths, lengths) + np.arange(lengths.sum())
    sums = np.bincount(rows.indices[take], rows.data[take], minlength=rows.shape[1])
    return sums.astype(np.float64)


def pool_by_point(inst: CoverInstance, pool: I64) -> sparse.csr_matrix:
    """(N, len(pool)) CSR: for each point, the pool candidates that cover it."""
    return inst.matrix[pool].T.tocsr()


def improve(cover: Cover, pool: I64, sensor_cost: SensorCost = 1.0) -> Cover:
    """``prune`` and ``swap_two_for_one`` (with ``sensor_cost``) until neither makes
    the cover smaller or cheaper."""
    prune(cover)
    by_point = pool_by_point(cover.inst, pool)
    while swap_two_for_one(cover, pool, by_point, sensor_cost):
        prune(cover)
    return cover
