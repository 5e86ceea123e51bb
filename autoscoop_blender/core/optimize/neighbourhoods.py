"""Plans improved a neighbourhood at a time: a few of the plan's masts, and the
positions around them, re-planned by the mast-aware MILP with the rest kept.

The mast-aware MILP over the whole ground is too large to solve (on two_routes at
k = 2 HiGHS found nothing in 170 s on 24 sites: ``bound.MAX_MULTI_MILP_CANDIDATES``),
and over the plan's own masts it cannot move a mast. Here each window is small:
``WINDOW_MASTS`` masts of the plan near one another, their sensors freed, and
``NEW_SITES`` positions within ``RADIUS_M`` of them that the plan does not use
(those that see the most of what the window's sensors see). The rest of the plan is
fixed: what it covers counts already, a point it covers k' < k times needs k - k'
more, and the goal left is the goal less what it covers. The MILP then looks only
for a window plan cheaper than the window's own sensors (HiGHS' cutoff), so an
improvement is a cheaper plan that still meets the goal: the whole plan's cost falls
by as much. Windows are tried until a pass over the plan's masts improves nothing
(or the time is up); a window is tried again only when the plan in and around it
has changed.

On two_routes at k = 2 (2026-11-30) the default run's plan went from 142 (greedy per
cost on the LP's columns) to 140 (74 sensors on 22 masts) in the same 228 s, in two
more runs from 151 to 146, and offline, on one core, from 151 to 144 in 150 s. At k = 1 a whole pass over
the plan of 74 found nothing cheaper (92 s), so the windows run at k > 1 only
(``lp._then_windows``).

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

# The plan's masts freed at once, the positions outside the plan offered to them, and
# how far from a freed mast those may stand (m).
WINDOW_MASTS = 3
NEW_SITES = 6
RADIUS_M = 12.0
# Seconds at most of one window's MILP (and MAX_NODES in bound.py), and the most
# candidates it may have at k > 1 (a window of 9 sites on two_routes has about 1,300).
WINDOW_S = 10.0
WINDOW_CANDIDATES = 2000
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
) -> Window:
    """The MILP of the window ``freed`` (sites of the plan ``chosen``): their sensors
    and those of up to ``NEW_SITES`` free positions within ``RADIUS_M``, the best
    first by how many points of the window's sensors their best candidate sees.
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
    near = np.unique(np.concatenate(tree.query_ball_point(site_xy[freed], RADIUS_M)))
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
        near = order[best[order] > 0][:NEW_SITES]
    sites = np.union1d(freed, near).astype(np.int64)
    cols = np.flatnonzero(np.isin(site_of, sites)).astype(np.int64)
    if len(cols) > WINDOW_CANDIDATES:
        # At each site the candidates that see the most of the window's points, and
        # the window's own sensors.
        seen = np.asarray(inst.matrix[cols] @ mine).ravel()
        order = np.lexsort((cols, -seen, site_of[cols]))
        rank = np.arange(len(order)) - np.searchsorted(site_of[cols][order], site_of[cols][order])
        keep = cols[order][rank < WINDOW_CANDIDATES // len(sites)]
        cols = np.union1d(keep, own).astype(np.int64)
    sub = inst.matrix[cols]
    points = np.flatnonzero(short & (np.bincount(sub.indices, minlength=inst.n_points) > 0))
    matrix = sparse.csr_matrix(sub[:, points])
    local_site = np.searchsorted(sites, site_of[cols]).astype(np.int64)
    need = (inst.k[points] - counts[points]).astype(np.int32)
    sub_inst = CoverInstance(matrix, max(goal, 0), need=need, site_of=local_site, cap=inst.cap)
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
    window by window (see the module docstring) until a pass over its masts finds
    nothing cheaper, or ``deadline`` / ``stop``. mast_cost: one or (sites,) per site
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

    # Windows tried, by their masts and what the plan there holds: a window is tried
    # again only when the plan around it has changed.
    done: set[tuple[object, ...]] = set()
    improved = True
    while improved and not over():
        improved = False
        # The masts with the fewest sensors first: there a mast costs the most per
        # sensor. On two_routes at k = 2 this order took the plan from 151 to 146 in
        # 54 s, the masts' own order in 79 s (one core each, 2026-11-30).
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
                site_xy[s], k=min(WINDOW_MASTS, len(in_plan))
            )
            freed = np.sort(in_plan[np.atleast_1d(nearest)])
            w = window(inst, site_of, site_xy, plan, freed, tree, taken)
            key = (
                tuple(freed.tolist()), tuple(w.cols[w.start].tolist()), w.inst.goal,
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
                cutoff=before - EPS, most_multi=WINDOW_CANDIDATES,
            )  # fmt: skip
            if plan_price(local, w.local_site, mc, sc) < before - EPS:
                kept = [c for c in plan if not np.isin(site_of[c], freed)]
                plan = kept + [int(w.cols[c]) for c in local]
                improved = True
                yield plan
    return plan
