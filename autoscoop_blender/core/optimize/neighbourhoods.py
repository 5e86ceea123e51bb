"""Plans improved a neighbourhood at a time: a few of the plan's masts, and the
positions around them, re-planned by the mast-aware MILP with the rest kept.

The mast-aware MILP over the whole ground is too large to solve (on two_routes at
k = 2 HiGHS found nothing in 170 s on 24 sites: ``bound.MAX_MULTI_MILP_CANDIDATES``),
and over the plan's own masts it cannot move a mast. Here each window is small: a
few masts of the plan near one another, their sensors freed, and a few positions
near them that the plan does not use (those that see the most of what the window's
sensors see). The rest of the plan is fixed: what it covers counts already, a point
it covers k' < k times needs k - k' more, and the goal left is the goal less what it
covers. The MILP then looks only for a window plan cheaper than the window's own
sensors (HiGHS' cutoff), so an improvement is a cheaper plan that still meets the
goal: the whole plan's cost falls by as much. A window is tried again only when the
plan in and around it has changed.

**Sizes.** Windows start small (``SIZES``: 3 masts, 6 positions within 12 m, at most
250 candidates) and grow only when a whole pass over the plan's masts has found
nothing cheaper; after a change the smallest come back. At k = 2 most windows of
2,000 candidates ran into their 10 s and few found anything, where those of 250
often end within a second: on two_routes' k = 2 plan of 151 (offline, one core,
2026-11-30) windows of 2,000 candidates reached 146 at 54 s and 144 at 133 s (240 s);
of 800, 144 at 176 s; of 250 alone 142 at 69 s and nothing more (all passes done at
173 s); the sizes here 142 at 36 s and 140 at 238 s.

In the default run at k = 2 they took the plan from 146 to 137 (``lp._Windows``). At
k = 1 nothing cheaper than two_routes' plan of 74 was found: neither by a whole pass
of windows of 2,000 candidates (92 s) nor by these sizes in 300 s, nor than the
plans of Town01's three parts (150-180 s each), so the windows run at k > 1 only.

Hand-written around HiGHS: the choice of windows is this problem's own (masts,
positions, a coverage goal shared by the whole ground).
"""

from __future__ import annotations

import threading
import time
from collections.abc import Generator
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray
from scipy import sparse
from scipy.spatial import cKDTree

from .bound import sensors_on_sites
from .cover import CoverInstance, MastCost, SensorCost, cost_at, plan_price

F64 = NDArray[np.float64]
I64 = NDArray[np.int64]


@dataclass(frozen=True)
class Size:
    """A window's size: the plan's masts freed at once, the positions outside the
    plan offered to them, how far from a freed mast those may stand (m), and the
    most candidates its MILP may have."""

    masts: int
    new_sites: int
    radius_m: float
    candidates: int


# The windows' sizes, the smallest first: a larger one is tried once a whole pass of
# the one before has found nothing cheaper, and after a change the smallest again.
SIZES = (
    Size(3, 6, 12.0, 250),
    Size(3, 6, 12.0, 500),
    Size(3, 6, 25.0, 1000),
    Size(4, 10, 25.0, 2000),
)
# Seconds at most of one window's MILP (and MAX_NODES in bound.py).
WINDOW_S = 10.0
# Below this much cheaper a window plan is no improvement (the costs' rounding).
EPS = 1e-6


@dataclass(frozen=True)
class Window:
    """One window's MILP: ``inst`` over its candidates ``cols`` (global indices) and
    the points the kept plan leaves short; ``local_site``: each column's site as an
    index into ``sites`` (global site indices); ``start``: the window's own sensors,
    as indices into ``cols``."""

    inst: CoverInstance
    cols: I64
    sites: I64
    local_site: I64
    start: list[int]


def window(
    inst: CoverInstance,
    site_of: I64,
    site_xy: F64,
    chosen: list[int],
    freed: I64,
    tree: cKDTree,
    taken: NDArray[np.bool_],
    size: Size,
) -> Window:
    """The MILP of the window ``freed`` (sites of the plan ``chosen``): their sensors
    and those of up to ``size.new_sites`` free positions within ``size.radius_m``, the
    best first by how many points of the window's sensors their best candidate sees.
    ``tree``: a KD-tree of ``site_xy``; ``taken``: (sites,) the sites the plan uses."""
    picked = np.asarray(chosen, dtype=np.int64)
    inside = np.isin(site_of[picked], freed)
    kept, own = picked[~inside], picked[inside]
    counts = np.zeros(inst.n_points, dtype=np.int64)
    if len(kept):
        counts = np.asarray(inst.matrix[kept].sum(axis=0)).ravel().astype(np.int64)
    short = counts < inst.k
    goal = inst.goal - int(np.count_nonzero(~short))
    # Free positions near the window, ranked by what they see of the window's points.
    near = np.unique(np.concatenate(tree.query_ball_point(site_xy[freed], size.radius_m)))
    near = near[~taken[near]].astype(np.int64)
    mine = np.zeros(inst.n_points)
    mine[np.unique(inst.matrix[own].indices)] = 1.0
    mine *= short
    if len(near):
        at = np.flatnonzero(np.isin(site_of, near))
        seen = np.asarray(inst.matrix[at] @ mine).ravel()
        best = np.zeros(len(site_xy))
        np.maximum.at(best, site_of[at], seen)
        order = near[np.lexsort((near, -best[near]))]
        near = order[best[order] > 0][: size.new_sites]
    sites = np.union1d(freed, near).astype(np.int64)
    cols = np.flatnonzero(np.isin(site_of, sites)).astype(np.int64)
    if len(cols) > size.candidates:
        # At each site the candidates that see the most of the window's points, and
        # the window's own sensors.
        seen = np.asarray(inst.matrix[cols] @ mine).ravel()
        order = np.lexsort((cols, -seen, site_of[cols]))
        rank = np.arange(len(order)) - np.searchsorted(site_of[cols][order], site_of[cols][order])
        keep = cols[order][rank < size.candidates // len(sites)]
        cols = np.union1d(keep, own).astype(np.int64)
    sub = inst.matrix[cols]
    points = np.flatnonzero(short & (np.bincount(sub.indices, minlength=inst.n_points) > 0))
    matrix = sparse.csr_matrix(sub[:, points])
    local_site = np.searchsorted(sites, site_of[cols]).astype(np.int64)
    need = (inst.k[points] - counts[points]).astype(np.int32)
    held = None if inst.held is None else inst.held[sites]
    sub_inst = CoverInstance(
        matrix, max(goal, 0), need=need, site_of=local_site, cap=inst.cap, held=held
    )
    start = np.searchsorted(cols, own).astype(np.int64).tolist()
    return Window(sub_inst, cols, sites, local_site, start)


def improve(
    inst: CoverInstance,
    site_of: I64,
    site_xy: F64,
    chosen: list[int],
    mast_cost: MastCost,
    sensor_cost: SensorCost,
    deadline: float | None = None,
    stop: threading.Event | None = None,
) -> Generator[list[int] | None, None, list[int]]:
    """The plan ``chosen`` (candidates of ``inst``, which meets its goal) improved
    window by window (see the module docstring) until a pass over its masts with the
    largest windows (``SIZES``) finds nothing cheaper, or ``deadline`` / ``stop``. mast_cost: one or (sites,) per site
    (0 where a mast stands); sensor_cost: one or (C,) per candidate. Yields each
    cheaper plan as found, None while HiGHS works; returns the best."""
    tree = cKDTree(site_xy)
    plan = list(chosen)

    def masts() -> tuple[I64, I64]:
        """(the sites the plan uses, the sensors on each)."""
        return np.unique(site_of[np.asarray(plan, dtype=np.int64)], return_counts=True)

    def over() -> bool:
        return (stop is not None and stop.is_set()) or (
            deadline is not None and time.perf_counter() >= deadline
        )

    # Windows tried, by their size, masts and what the plan there holds: a window is
    # tried again only when the plan around it has changed.
    done: set[tuple[object, ...]] = set()
    level = 0
    while level < len(SIZES) and not over():
        size = SIZES[level]
        level += 1
        # The masts with the fewest sensors first: there a mast costs the most per
        # sensor. On two_routes at k = 2 this order took the plan from 151 to 146 in
        # 54 s, the masts' own order in 79 s (one core each, windows of 2,000
        # candidates, 2026-11-30).
        sites, load = masts()
        for s in sites[np.lexsort((sites, load))]:
            if over():
                break
            in_plan = masts()[0]
            if s not in in_plan:
                continue  # closed by an earlier window of this pass
            taken = np.zeros(len(site_xy), dtype=bool)
            taken[in_plan] = True
            _, nearest = cKDTree(site_xy[in_plan]).query(
                site_xy[s], k=min(size.masts, len(in_plan))
            )
            freed = np.sort(in_plan[np.atleast_1d(nearest)])
            w = window(inst, site_of, site_xy, plan, freed, tree, taken, size)
            key = (
                size, tuple(freed.tolist()), tuple(w.cols[w.start].tolist()), w.inst.goal,
                w.inst.n_points, int(w.inst.k.sum()),
            )  # fmt: skip
            if key in done:
                continue
            done.add(key)
            mc = cost_at(mast_cost, w.sites)
            sc = cost_at(sensor_cost, w.cols)
            before = plan_price(w.start, w.local_site, mc, sc)
            limit = time.perf_counter() + WINDOW_S
            if deadline is not None:
                limit = min(limit, deadline)
            local = yield from sensors_on_sites(
                w.inst, w.local_site, np.arange(len(w.sites)), w.start, mc, sc, limit, stop,
                cutoff=before - EPS, most_multi=len(w.cols),
            )  # fmt: skip
            if plan_price(local, w.local_site, mc, sc) < before - EPS:
                kept = [c for c in plan if not np.isin(site_of[c], freed)]
                plan = kept + [int(w.cols[c]) for c in local]
                level = 0  # a change: the smallest windows again, after this pass
                yield plan
    return plan
