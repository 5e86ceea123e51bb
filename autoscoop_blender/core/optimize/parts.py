"""The lp optimizer on a ground too large to plan whole: part by part.

Two sensors 200 m apart never see the same target point, so a large ground is split
into compact parts of its target points (``bound.parts_of``: halved at a quantile of
the longer extent, again and again), and each part is planned on its own:

1. its candidates: every mast position within sensor reach of one of its points, each
   candidate's matrix row over the part's points only (``candidates.build_part``);
   only one part's matrix is held at a time, so the memory follows the largest part;
2. its LP and plans, as the whole ground's would be (``lp.prove_and_plan``) for its
   share of the coverage goal; the plan's sensors are fixed at once, so the run has
   a plan for the parts done (and a checkpoint of them) as soon as the first part is;
3. after the last part, the sensors the seams made redundant (a sensor of one part
   covering what the next part's covers too) are dropped while the goal stays met;
4. then the plan is planned again over the whole ground on its own masts (``rejoin``:
   the mast-aware MILP, every candidate at those positions over every point): a part
   planned with the parts before fixed cannot move their sensors, so across a seam
   two half-used masts may stand where one would do.

**The bound stays a proof for the whole ground.** The parts' bounds cannot simply be
added: a candidate near a border serves two parts and would be paid twice. So each
part's LP prices a candidate at its *share* of its cost, the fraction of the points it
covers that lie in the part; a site (mast position) likewise. For any plan of the
whole ground, its candidates that see part p form a plan of part p covering what it
covers there, at the shared cost; over the parts the shares add up to the plan's cost.
So the sum of the parts' LP values, each at the goal the plan meets in it, is at most
the plan's cost. A share is where a part's sensors LP starts: it keeps of each
candidate's cost only what its line's duals price it at, and hands the rest on to the
parts after it (``CostLedger``); a plan's candidates still cost at most their cost
over the parts. Each part's LP duals give its value as a line in its goal
(``bound.LPSolution.slope``), and ``bound.combined_bound`` takes the least total over
every split of the whole goal among the parts: a lower bound on every plan, whatever
split the parts were solved at. A part not solved yet counts 0 at any goal. The same
holds for the fewest masts, with the LP over sites (a site covers what any of its
candidates covers; with k > 1 it adds at most min(its candidates there, k) to a
point). A tangent at the part's goal sags below the LP away from it, and the best
split moves goal to where the tangents are flattest; so the masts LP, whose last
points cost the most, gives lines at the goals either side too, the sensors LP at
goals below its own where its tangent is steep (``OTHER_GOALS``), and each part's
bound is the highest of its lines (still convex in its goal). The cost bound is
mast_cost x masts + sensor_cost x sensors, each rounded up; or, higher where the
masts' best split of the goal is not the sensors', the least over one split for
both of the parts' mast_cost x masts + sensor_cost x sensors lines (a plan covers
what it covers in a part whichever it is counted by: ``bound.combined_sum_bound``),
raised to the next cost that whole counts make (``cheapest_counts``).

About 600 lines: a part's build, bound, plan and the seams' repair run in one
loop that holds the run's deadline, stop and lines of the bound.
"""

from __future__ import annotations

import copy
import logging
import math
import threading
import time
from collections.abc import Generator, Iterator
from contextlib import contextmanager
from dataclasses import replace
from typing import Any, NamedTuple, Protocol

import numpy as np
from numpy.typing import NDArray
from scipy import sparse

from ..candidates import (
    CandidateSet,
    PartCandidates,
    SharedPositions,
    build_on_sites,
    build_part,
    near_positions,
)
from ..problem import Problem
from .base import (
    FixedSensor,
    PlanBound,
    Progress,
    Solution,
    StopReason,
    fix_candidate,
    newly_covered,
    taken_candidates,
)
from .bound import (
    DualPolish,
    SiteSolution,
    combined_bound,
    combined_sum_bound,
    cover_lp,
    parts_of,
    quiet,
    sensors_on_sites,
    site_cover,
    site_matrix,
)
from .cover import Cover, CoverInstance, complete
from .joint import sensors_on_masts, whole_sensors
from .lp import (
    PartInputs,
    in_gain_order,
    mast_aware_costs,
    milp_candidates,
    objective_value,
    plan_value,
    prove_and_plan,
)

F64 = NDArray[np.float64]
I64 = NDArray[np.int64]
Line = tuple[float, float]

log = logging.getLogger(__name__)

# The masts LP of a part gets at most this long, s (on its sample, ``site_line``).
SITE_LP_S = 90.0
# A site is one the LP uses above this value (an interior point's values are never 0).
SITE_USED = 1e-3
# Dual steps on a part's masts LP over every point (``site_line``, ``either_side``): 5 ms
# each on Town04's third part (2,130 sites, 13,586 points), 20-35 ms on the parts of
# six tiles of full_ground (2026-11-26/28).
SITE_POLISH_STEPS = 1000
# The dual steps of a masts LP yield once per this much of them, s. They share the
# main thread with the sensors LP's steps beside its solves, one of those (0.2-0.3 s
# on a part of Town04) per yield: yielding after each step, steps of 5 ms alone took
# about 95 ms each in a Town04 run (2026-11-27/28).
WALK_SLICE_S = 0.25
# The share of the time limit the parts leave to the re-plan over the whole ground
# (``rejoin_windows``): the parts of Town04 and of 12 tiles use all the time they are
# given. Town04's plan of 306 sensors went from 687 to 632 in 583 s of re-planning by
# windows, against nothing in the 50 s that 10 % left it (2026-11-27).
REJOIN_SHARE = 0.25
# The share of a part's time left that the fewest masts' MILP may take (``fewest_masts``):
# on Town01's three parts its sites, beside the masts LP's, took the parts' plans
# from 55, 74 and 68 to 51, 66 and 56 (each part alone, 2026-11-27); in the default
# run its LP and MILP took 30, 24 and 61 s (the last cut by this share).
FEWEST_SHARE = 0.4
# A part's masts LP and its fewest masts are solved on one point in this many grid
# cells squared (``CoverInstance.thinned``). On Town04's third part (13,586 points, 2,130
# sites) the masts LP on one point in 2 x 2 (3,721) took 6.5 s where every point took
# 85-89 s, for 11.78 against 11.85; 1,000 dual steps over every point from its duals
# then proved 11.60 (98 %) in 5 s, where the same steps from nothing prove about 97 %.
# On Town01's third part (7,606 points, 3,259 positions) the fewest masts on 2,157
# points gave the same 10 masts as every point, in 7 s instead of 41 s, and they cover
# 99.0 % of the part's points for a goal of 97 % (2026-11-27/28).
SAMPLE_CELLS = 2
# The offsets, in squares, of the samples that look for more sets of the fewest masts
# (``fewest_masts``). The sets of as few masts differ in what their plans cost: on
# Town01's first part alone, 4-5 s each, the unmoved sample's 9 masts carry 26 sensors
# at best (the mast-aware MILP on all their candidates), the samples moved by half a
# square in x, in y and in both 24, 25 and 24 (2026-12-06).
SAMPLE_OFFSETS = ((0.5, 0.0), (0.0, 0.5), (0.5, 0.5))
# A part's sensors LP gives lines at these fractions of the part's points below its
# goal, and at all it can cover, where its tangent is steep (``bound.cover_lp``'s
# ``also_at``): on two_routes in 3 parts one part's 11 sensors counted 0 in the whole's
# bound, its goal moved 257 points down where its tangent was 0 at 111.
OTHER_GOALS = (0.01, 0.03, 0.06)
# The most masts re-planned at once (``rejoin_windows``): Town01's 33 took 22 s
# (1,675 candidates); Town04's 117 at once found nothing cheaper in their share
# (about 160 s).
REJOIN_MASTS = 40


class CostLedger:
    """What the parts solved so far took of each candidate's cost in their sensors
    LPs' bounds, so that the parts after them may take the rest (the bound's
    decomposition, module docstring).

    A part's line is the Lagrangian bound of point duals pi (``LPSolution.line_pi``),
    sigma goal - sum_n max(0, sigma - k_n pi_n) - sum_c max(0, (M pi)_c - cost_c), at
    its candidates' costs in the part. Lowering a cost to min(cost_c, (M pi)_c) leaves
    that bound as it is: the part needs only that much of the candidate. The rest goes
    to the parts after it, split by the points the candidate covers in each. So the
    costs over the parts still add up to at most each candidate's cost, and a part
    after another gets at least its share (``PartCandidates.share``; exactly that when
    every part before took all of its own). The first part's costs are its shares.

    Held per (model, position, orientation), a float and a count each: Town04's
    15,992 positions x 216 orientations take 55 MB."""

    def __init__(self) -> None:
        self.taken = np.zeros(0)  # of each candidate's cost, by the parts before
        self.counted = np.zeros(0, dtype=np.int64)  # its points in the parts before
        self.offset = np.zeros(1, dtype=np.int64)  # where each model's entries begin

    def _index(self, cands: CandidateSet) -> I64:
        """(C,) each candidate's entry, the ledger sized at the first call."""
        orientations = np.array([len(a) for a in cands.angles], dtype=np.int64)  # per model
        if len(self.taken) == 0:
            self.offset = np.concatenate([[0], np.cumsum(len(cands.positions) * orientations)])
            self.taken = np.zeros(int(self.offset[-1]))
            self.counted = np.zeros(int(self.offset[-1]), dtype=np.int64)
        at = cands.position * orientations[cands.model] + cands.orientation
        out: I64 = self.offset[cands.model] + at
        return out

    def costs(self, part: PartCandidates, unit: F64 | float) -> F64:
        """(C,) the part's candidates' costs for its LP: of each candidate's cost
        ``unit`` what the parts before left, split by its points in this part against
        those in the parts after it."""
        idx = self._index(part.cands)
        here = np.diff(part.cands.matrix.indptr).astype(float)
        total = np.rint(here / np.maximum(part.share, 1e-300))
        ahead = np.maximum(total - self.counted[idx], here)
        left = np.maximum(0.0, unit - self.taken[idx])
        out: F64 = left * here / np.maximum(ahead, 1.0)
        return out

    def take(
        self, part: PartCandidates, cost: F64, matrix: sparse.csr_matrix, pis: list[F64]
    ) -> None:
        """Enter what the part's lines took: min(cost_c, the most any of their duals
        price it at) for each candidate (``matrix``: (C, N) the rows its LP had,
        ``pis``: each line's point duals (N,); none: no line, nothing taken), and its
        points."""
        idx = self._index(part.cands)
        if pis:
            priced = np.max([np.asarray(matrix @ pi, dtype=float) for pi in pis], axis=0)
            # Rounded up: taking more than the lines need is safe, less is not.
            self.taken[idx] += np.minimum(cost, priced * (1 + 1e-9) + 1e-12)
        self.counted[idx] += np.diff(part.cands.matrix.indptr)


def part_count(problem: Problem) -> int:
    """How many parts the problem's target is planned in: as its estimate says
    (``budget.part_count``), so that the memory estimated is the memory used."""
    return problem.estimate.parts


def split_instance(
    cands: CandidateSet,
    points: I64,
    covered: NDArray[np.bool_],
    counts: NDArray[np.int32],
    need: NDArray[np.int32],
    xy: F64,
    cap: int,
    taken: I64,
    held: I64 | None = None,
) -> tuple[CoverInstance, I64]:
    """The cover instance of a part (goal 0; set it with ``replace``): its points
    (ordinals ``points``, the matrix's columns) not yet ``covered``, each needing its
    k less ``counts``; the ``taken`` candidates (fixed already) cover nothing more;
    ``held``: (positions,) the planned sensors at each mast position already, which
    count against the ``cap``. Returns it and the ordinals of its columns."""
    matrix = cands.matrix
    if len(taken):
        keep = np.ones(matrix.shape[0], dtype=matrix.dtype)
        keep[taken] = 0
        matrix = (sparse.diags(keep) @ matrix).tocsr()
        matrix.eliminate_zeros()
    cols = np.flatnonzero(~covered[points])
    matrix = matrix[:, cols].tocsr()
    ordinals = points[cols]
    left = np.maximum(need[ordinals] - counts[ordinals], 1).astype(np.int32)
    inst = CoverInstance(
        matrix, 0, xy[ordinals], need=left, site_of=cands.position, cap=cap, held=held
    )
    return inst, ordinals


def coverable(inst: CoverInstance) -> int:
    """Points of ``inst`` that at least their k candidates see: the most any plan covers."""
    seen_by = np.bincount(inst.matrix.indices, minlength=inst.n_points)
    return int(np.count_nonzero(seen_by >= inst.k))


class SiteLP(NamedTuple):
    """A part's masts LP (``site_line``): its line at the part's goal, its rounds, the
    sites (positions) it uses, and for ``either_side``: the LP over sites (``inst``,
    ``cost``) and the best dual point found (pi, sigma), if any."""

    line: Line
    rounds: int
    used: I64
    inst: CoverInstance
    cost: F64
    center: tuple[F64, float] | None


def site_line(
    inst: CoverInstance,
    part: PartCandidates,
    standing: NDArray[np.bool_],
    cell_m: float,
    deadline: float | None,
    stop: threading.Event | None,
    steps_until: float | None = None,
) -> Generator[None, None, SiteLP]:
    """The part's fewest-masts LP as a line in its goal (see the module docstring):
    sites as columns at their share of one mast (0 where a mast stands), each
    covering what its candidates cover (k > 1: at most min(their count, k) a point).

    Solved on one point per square of ``cell_m`` (``CoverInstance.thinned``), every
    site at once, by HiGHS' interior point method for at most ``SITE_LP_S``: the
    sites it uses are where the part's plans look for masts. Its duals, each
    sample point's shared among the points of its square, start
    ``SITE_POLISH_STEPS`` dual steps over every point, whose best point is the line
    (the sample's own line proves nothing of the part). The steps end at
    ``steps_until`` (default ``deadline``) or ``stop`` after ``DualPolish.MIN_STEPS``,
    with the line by then: a part that has spent its time still proves its line
    (Town04's last part, 20 steps at its deadline: 4.72 where 1,000 proved 7.23)."""
    cands = part.cands
    sites = site_matrix(inst, np.searchsorted(part.sites, cands.position), len(part.sites))
    cost = np.where(standing[part.sites], 0.0, part.site_share)
    every = np.arange(len(part.sites), dtype=np.int64)
    site_inst = CoverInstance(sites, inst.goal, inst.xy, need=inst.k)
    keep, square = site_inst.cells(cell_m)
    sample = site_inst.thinned(cell_m)
    limit = time.perf_counter() + SITE_LP_S
    lp = yield from quiet(
        cover_lp(
            sample, cost, every, every, integral=False, interior=True, stop=stop,
            deadline=limit if deadline is None else min(deadline, limit),
        )
    )  # fmt: skip
    greedy = complete(Cover(site_inst), every, sensor_cost=cost + 1e-6).chosen
    if len(lp.x) == len(every):
        used = part.sites[lp.columns[lp.x > SITE_USED]]
    else:  # no solution: the sites of a greedy cover
        used = part.sites[greedy]
    polish = DualPolish(site_inst, cost)
    if lp.pi is not None:  # the sample's point duals
        start = spread_duals(lp.pi, square), lp.slope * len(keep) / max(site_inst.n_points, 1)
    else:  # cut short before its first solve: from nothing
        start = np.zeros(site_inst.n_points), 0.0
    until = deadline if steps_until is None else steps_until
    yield from _walk(polish, start, float(cost[greedy].sum()), until, stop)
    _, slope, intercept = polish.line()
    used = np.sort(used).astype(np.int64)
    return SiteLP((slope, intercept), lp.rounds, used, site_inst, cost, polish.center)


def _walk(
    polish: DualPolish,
    start: tuple[F64, float],
    target: float,
    deadline: float | None,
    stop: threading.Event | None,
) -> Generator[None, None, None]:
    """``SITE_POLISH_STEPS`` dual steps of ``polish`` from ``start`` (pi, sigma) towards
    ``target``, yielding once per ``WALK_SLICE_S`` of them; after
    ``DualPolish.MIN_STEPS`` they end at ``deadline`` or ``stop`` (none once ``stop``
    is set)."""
    if stop is not None and stop.is_set():
        return
    last = time.perf_counter()
    for _ in polish.walk(*start, target, SITE_POLISH_STEPS):
        now = time.perf_counter()
        if polish.steps >= DualPolish.MIN_STEPS and (
            (stop is not None and stop.is_set()) or (deadline is not None and now > deadline)
        ):
            return
        if now - last >= WALK_SLICE_S:
            last = now
            yield None


def spread_duals(pi: F64, square: I64) -> F64:
    """(N,) point duals from a sample's (S,): each sample point's shared equally among
    the points of its square (``square``: (N,) an index into the sample). Were the
    points of a square alike, the LP over every point would have these duals; they
    are a start for dual steps, not a bound."""
    count = np.bincount(square, minlength=len(pi))
    out: F64 = pi[square] / count[square]
    return out


def either_side(
    lp: SiteLP, reach: int, deadline: float | None, stop: threading.Event | None
) -> Generator[None, None, list[Line]]:
    """Lines of the masts LP ``lp`` at the goals either side of its own: ``reach``
    (all the part can cover) and as far below, each by ``SITE_POLISH_STEPS`` dual
    steps from its best point, until ``deadline`` or ``stop`` (the best line by then).

    Why: a line is a tangent at the part's goal, and the whole's bound moves goal
    between the parts (by up to the 3 % a 97 % goal leaves); the LP is convex in its
    goal and steepest near all the part can cover, so these lines hold the parts'
    bound up where the tangent sags (``combined_bound`` takes the highest)."""
    lines: list[Line] = []
    own = lp.inst.goal
    if lp.center is None or reach <= own or (stop is not None and stop.is_set()):
        return lines
    every = np.arange(len(lp.cost), dtype=np.int64)
    for goal in (reach, max(0, 2 * own - reach)):
        at = replace(lp.inst, goal=goal)
        polish = DualPolish(at, lp.cost)
        aim = float(lp.cost[complete(Cover(at), every, sensor_cost=lp.cost + 1e-6).chosen].sum())
        yield from _walk(polish, lp.center, aim, deadline, stop)
        lines.append(polish.line()[1:])
    return lines


def part_sites(
    masts_lp: Generator[None, None, SiteLP],
    before: I64,
    found: dict[str, Any],
    fewest: Generator[None, None, SiteSolution] | None = None,
) -> Generator[None, None, SiteSolution]:
    """The sets of sites a part's plans look for masts at, each with ``before`` (the
    masts the parts before stood there): those its masts LP (``site_line``) uses and,
    with ``fewest`` (``fewest_masts``), the fewest masts' MILP's, its LP's and the
    moved samples' MILPs'. The masts LP (``SiteLP``) goes into ``found`` ("lp", with
    "seconds") once it is solved.

    The fewest masts come first. The masts LP's dual steps share the main thread
    with the sensors LP's steps beside its solves, so they get a slice now and then
    and end about when that LP does (within 0.3-2 s in each of Town01's parts). With
    the fewest masts after them, one core idled while their MILPs ran, 19-21 s a
    part (2026-12-07). Solved first, the MILPs run in HiGHS' thread beside the
    sensors LP's solves."""
    least = None
    if fewest is not None:
        t1 = time.perf_counter()
        least = yield from fewest
        # (Cut short by the part's time, the MILP has no set and its bound is no count.)
        log.info(
            "fewest masts: %s (%d sites; %d in its LP) in %.1f s",
            least.bound if len(least.sites) else "none found", len(least.sites),
            len(least.lp_sites), time.perf_counter() - t1,
        )  # fmt: skip
    t0 = time.perf_counter()
    lp = yield from masts_lp
    found.update(lp=lp, seconds=time.perf_counter() - t0)
    mine = np.union1d(lp.used, before).astype(np.int64)
    if least is None:
        return SiteSolution(0, mine[:0], mine)
    milp, relaxed = (
        np.union1d(on, before).astype(np.int64) if len(on) else on
        for on in (least.sites, least.lp_sites)
    )
    moved = (np.union1d(on, before).astype(np.int64) for on in least.more)
    return SiteSolution(0, milp, mine, (relaxed, *moved))


def fewest_masts(
    inst: CoverInstance,
    site_of: I64,
    standing: NDArray[np.bool_],
    grid_m: float,
    deadline: float | None,
    stop: threading.Event | None,
) -> Generator[None, None, SiteSolution]:
    """The fewest new masts whose candidates cover what is left of a part
    (``bound.site_cover`` on the sites' matrix of ``inst``, thinned to one point in
    ``SAMPLE_CELLS``² grid cells of ``grid_m``; ``standing``: (sites,) where masts
    stand, those of the parts before included, at no cost), for at most
    ``FEWEST_SHARE`` of the part's time left when it starts (``deadline``): where its
    plans may need fewer masts than on the sites its masts LP uses (that LP prices a
    site at its share of the part, so it spreads over more of them); then, while that
    time lasts, the same on samples whose squares are moved (``SAMPLE_OFFSETS``),
    their sets as ``more``. A heuristic: its bound is the sample's, no proof."""
    now = time.perf_counter()
    limit = None if deadline is None else now + FEWEST_SHARE * max(0.0, deadline - now)
    cell = SAMPLE_CELLS * grid_m
    n_sites = len(standing)
    # The samples are taken of the sites' matrix, built once: a Town01 part's has
    # 2.0 M entries where its candidates' have 31 M (sampling the candidates' matrix
    # for each sample, Town01's run peaked at 2.84 GiB, against 2.58 GiB so).
    by_site = CoverInstance(site_matrix(inst, site_of, n_sites), inst.goal, inst.xy, inst.k)
    every = np.arange(n_sites, dtype=np.int64)
    first = by_site.thinned(cell)
    least = yield from site_cover(first, every, n_sites, limit, stop, True, standing)
    first_s = time.perf_counter() - now
    # Samples on squares moved by half a square find other sets of as few masts,
    # which may carry a cheaper plan (see ``SAMPLE_OFFSETS``), while the time lasts,
    # each for at most as long as the first took (or 1 s): a part's plans wait for
    # them (on Town01's third part, without that, 58 s where the first took 7 s).
    more: list[I64] = []
    for dx, dy in SAMPLE_OFFSETS:
        began = time.perf_counter()
        until = None if limit is None else min(limit, began + max(first_s, 1.0))
        if (stop is not None and stop.is_set()) or (until is not None and began >= until):
            break
        sample = by_site.thinned(cell, (dx * cell, dy * cell))
        other = yield from site_cover(sample, every, n_sites, until, stop, True, standing)
        if len(other.sites):
            more.append(other.sites)
    return replace(least, more=tuple(more))


def _mast_sites(problem: Problem, sensors: list[FixedSensor]) -> I64:
    """The positions (indices into the problem's) of the sensors' masts."""
    found = (problem.space.index_of(f.pose.x, f.pose.y) for f in sensors)
    return np.unique([k for k in found if k is not None]).astype(np.int64)


def _held(problem: Problem, sensors: list[FixedSensor]) -> I64:
    """(positions,) the planned sensors (not those that stood) at each mast position:
    what counts against the cap of sensors a mast."""
    held = np.zeros(len(problem.space.positions), dtype=np.int64)
    for f in sensors:
        k = problem.space.index_of(f.pose.x, f.pose.y)
        if k is not None and not f.existing:
            held[k] += 1
    return held


@contextmanager
def _standing_too(problem: Problem, sites: I64) -> Iterator[None]:
    """Within the block the problem's search space counts a mast as standing at
    ``sites`` too (a part's plan puts sensors on the masts of the parts before at no
    mast cost); the space itself is not changed."""
    space = problem.space
    if len(sites) == 0:
        yield
        return
    other = copy.copy(space)
    other.standing = space.standing.copy()
    other.standing[sites] = True
    problem.space = other
    try:
        yield
    finally:
        problem.space = space


def solve_deadline(
    now: float,
    parts_end: float | None,
    share: float,
    build_s: list[float],
    after: int,
    over_s: list[float] | None = None,
) -> float | None:
    """When a part's solve ends (``time.perf_counter()``; None: no limit): ``share`` of
    the time to ``parts_end``, less what each of the ``after`` parts after it will
    spend outside its own solve's share: waiting for its candidates, as long as the
    builds so far (``build_s``, s) on average, and working past its deadline, as
    long as the parts so far did (``over_s``, s; the masts LP's lines either side
    and the sensors' fixing come after the part's plan). Without that reserve it
    all came out of the last parts' time: Town04's builds take 25-70 s each and
    its parts ran 12-32 s past their deadlines, so its last part had 14 s and no
    sensors LP."""
    if parts_end is None:
        return None
    each = sum(build_s) / len(build_s) if build_s else 0.0
    each += sum(over_s) / len(over_s) if over_s else 0.0
    return now + max(0.0, parts_end - now - after * each) * share


def whole_bound(
    problem: Problem,
    sensor_lines: list[list[Line]],
    mast_lines: list[list[Line]],
    coverable: list[int],
    goal: int,
    rounds: int,
    dearest: float | None,
) -> PlanBound:
    """The proven bound of the whole ground from the parts' lines (module docstring).
    mast_lines: each part's lines (the highest of them bounds it). dearest: with
    models of different costs, the dearest sensor's cost (the sensors LP priced each
    candidate at its model's cost); None when all cost the same."""
    lp = combined_bound(sensor_lines, coverable, goal)
    masts_lp = combined_bound(mast_lines, coverable, goal)
    unit = float(problem.sensor_costs[0]) if dearest is None else 1.0
    if dearest is None:
        sensors = max(0, math.ceil(lp - 1e-6))
        sensor_cost = unit * sensors
    else:
        sensors = max(0, math.ceil(lp / dearest - 1e-6)) if dearest > 0 else 0
        sensor_cost = lp
    standing = int(np.count_nonzero(problem.space.standing))
    s = problem.settings
    cap = s.max_sensors_per_mast
    masts = max(0, math.ceil(masts_lp - 1e-6), math.ceil((sensors - cap * standing) / cap))
    # The cost with one split of the goal for masts and sensors both (a plan's own).
    together = combined_sum_bound(
        [(s.mast_cost, mast_lines), (unit, sensor_lines)], coverable, goal
    )
    if dearest is None:
        together = cheapest_counts(together, sensors, masts, unit, s.mast_cost)
    return PlanBound(
        sensors=sensors,
        masts=masts,
        lp=lp,
        scope=f"plans on the candidate set, proven part by part ({len(coverable)} parts)",
        rounds=rounds,
        sensor_cost_lp=sensor_cost,
        joint=together,
    )


def cheapest_counts(
    total: float, sensors: int, masts: int, sensor_cost: float, mast_cost: float
) -> float:
    """The least ``mast_cost`` x m + ``sensor_cost`` x s over whole numbers s >=
    ``sensors`` and m >= ``masts`` that is at least ``total`` (less round-off): a
    plan's cost is such a sum, so a bound ``total`` on it rises to the next one."""
    if sensor_cost <= 0 or mast_cost <= 0:
        return max(total, mast_cost * masts + sensor_cost * sensors)
    best, m = math.inf, masts
    while True:
        n = max(sensors, math.ceil((total - mast_cost * m) / sensor_cost - 1e-6))
        best = min(best, mast_cost * m + sensor_cost * n)
        if n == sensors:
            return best
        m += 1


def prune(problem: Problem, solution: Solution) -> int:
    """Drop the planned sensors (not those that stood already, ``existing``) that the
    goal does not need, the least useful first (fewest points only it holds to their
    k; a sensor alone on its mast before one that shares it), and fix the rest again
    in order. Returns how many were dropped. A resumed run's sensors, read back from
    the checkpoint, are planned ones too: pruned again, the same ones go, and a resume
    ends with the plan the run it resumes would have ended with."""
    assert solution.need is not None
    sensors = solution.sensors
    counts = solution.counts.copy()
    need = solution.need
    n_covered = solution.n_covered
    at = [(s.pose.x, s.pose.y) for s in sensors]
    per_mast = {xy: at.count(xy) for xy in set(at)}

    def held(i: int) -> int:  # points that would drop below their k without sensor i
        ords = _seen(sensors[i])
        return int(np.count_nonzero(counts[ords] == need[ords]))

    planned = [i for i, f in enumerate(sensors) if not f.existing]
    order = sorted(planned, key=lambda i: (held(i), per_mast[at[i]], i))
    dropped = set()
    for i in order:
        lost = held(i)
        if n_covered - lost >= problem.goal:
            ords = _seen(sensors[i])
            counts[ords] -= 1
            n_covered -= lost
            dropped.add(i)
    if not dropped:
        return 0
    _fix_again(solution, [s for i, s in enumerate(sensors) if i not in dropped])
    return len(dropped)


def _seen(sensor: FixedSensor) -> I64:
    """Every target ordinal ``sensor`` covers."""
    return sensor.newly if sensor.seen is None else sensor.seen


def _fix_again(solution: Solution, sensors: list[FixedSensor]) -> None:
    """The solution emptied and ``sensors`` fixed in it again, in order (their
    ``newly`` recounted; nothing evaluated afresh)."""
    solution.sensors = []
    solution.counts[:] = 0
    solution.covered[:] = False
    solution.n_covered = 0
    for s in sensors:
        solution.fix(replace(s, newly=newly_covered(solution, _seen(s))))


class Rejoined(NamedTuple):
    """What ``rejoin`` did: the re-planned sensors' cost (the objective) before and
    after, and a lower bound on the new sensors of any plan on the masts it re-planned
    on and those that stood already (``joint.sensors_on_masts``; 0: not proven, as by
    windows)."""

    before: float
    after: float
    on_masts: float = 0.0


def rejoin_windows(
    problem: Problem, solution: Solution, deadline: float | None, stop: threading.Event | None
) -> Generator[None, None, Rejoined]:
    """``rejoin`` over the whole plan when it has at most ``REJOIN_MASTS`` masts; else
    window by window: its masts split into compact groups of at most that many
    (``parts_of`` on their positions), each re-planned with the sensors outside it
    kept as they are, each window given an equal share of the time left. Returns the
    plan's cost before and after (both 0 when nothing was planned), and by windows no
    bound on its masts."""
    planned = [f for f in solution.sensors if not f.existing]
    sites = _mast_sites(problem, planned)
    n = math.ceil(len(sites) / REJOIN_MASTS)
    if n <= 1:
        return (yield from rejoin(problem, solution, deadline, stop))
    group = parts_of(problem.space.positions[sites], n)
    before = after = plan_cost_of(problem, solution.sensors)
    for k in range(n):
        if stop is not None and stop.is_set():
            break
        now = time.perf_counter()
        if deadline is not None and now >= deadline:
            break
        share = None if deadline is None else now + (deadline - now) / (n - k)
        yield from rejoin(problem, solution, share, stop, window=sites[group == k])
        after = plan_cost_of(problem, solution.sensors)
    return Rejoined(before, after)


def plan_cost_of(problem: Problem, sensors: list[FixedSensor]) -> float:
    """The objective of ``sensors`` as ``lp.plan_value`` counts it: for the cost,
    ``mast_cost`` a new mast (a position a planned sensor stands at, where none
    stood) and each planned sensor its model's cost; those that stood already cost
    nothing."""
    planned = [f for f in sensors if not f.existing]
    sites = _mast_sites(problem, planned)
    masts = int(np.count_nonzero(~problem.space.standing[sites]))
    price = sum(float(problem.sensor_costs[f.model]) for f in planned)
    s = problem.settings
    return objective_value(s.objective, masts, len(planned), s.mast_cost, price)


def rejoin(
    problem: Problem,
    solution: Solution,
    deadline: float | None,
    stop: threading.Event | None,
    window: I64 | None = None,
) -> Generator[None, None, Rejoined]:
    """The plan re-planned over the whole ground on its own masts: the mast-aware MILP
    (``sensors_on_sites``) on every candidate at the positions its planned sensors
    stand at, each over every target point, from the plan itself. Each part was
    planned with the parts before fixed, so across a seam a mast may carry what two
    half-used ones do: the MILP moves sensors between the masts and closes those it
    can, or moves them onto the masts that stood already, at no mast cost; the
    sensors that stood already stay. window: only the planned sensors on these masts
    (positions) are re-planned, the others kept as they are. The plan is replaced
    only by a cheaper one that still meets the goal when its sensors are evaluated
    afresh. Returns the cost (the objective) of the sensors re-planned before and
    after, (0, 0) when nothing was planned; and over the whole plan, the LP of the
    fewest new sensors on those masts, solved before the MILP, which may use the time
    to its deadline (on Town01's 29 masts 70.36, where the plan has 71; the whole
    re-plan took 8 s)."""
    inside = None if window is None else {int(k) for k in window}

    def replanned(f: FixedSensor) -> bool:
        return not f.existing and (
            inside is None or problem.space.index_of(f.pose.x, f.pose.y) in inside
        )

    planned = [f for f in solution.sensors if replanned(f)]
    kept = [f for f in solution.sensors if not replanned(f)]
    if not planned:
        return Rejoined(0.0, 0.0)
    # Its masts, and those that stand already (a sensor moved there adds no mast).
    sites = np.union1d(_mast_sites(problem, planned), np.flatnonzero(problem.space.standing))
    cands = yield from quiet(build_on_sites(problem, sites))
    need = problem.need
    counts = np.zeros(problem.n_targets, dtype=np.int32)
    for f in kept:
        counts[_seen(f)] += 1
    covered = counts >= need
    every = np.arange(problem.n_targets, dtype=np.int64)
    s = problem.settings
    inst, ordinals = split_instance(
        cands, every, covered, counts, need, problem.grid.target_xy,
        s.max_sensors_per_mast, taken_candidates(cands, kept), _held(problem, kept),
    )  # fmt: skip
    inst = replace(inst, goal=max(0, problem.goal - int(np.count_nonzero(covered))))
    # The plan as candidates: at each sensor's mast the one that covers the most of
    # what it does (its own pose, or one that covers all of that and more).
    column = np.full(problem.n_targets, -1, dtype=np.int64)
    column[ordinals] = np.arange(len(ordinals))
    start = []
    for f in planned:
        at = np.flatnonzero(cands.position == problem.space.index_of(f.pose.x, f.pose.y))
        if len(at) == 0:  # it sees no target point: nothing to start from
            return Rejoined(0.0, 0.0)
        mine = np.zeros(inst.n_points)
        mine[column[_seen(f)][column[_seen(f)] >= 0]] = 1.0
        start.append(int(at[np.argmax(inst.matrix[at] @ mine)]))
    before = plan_value(problem, cands, start)
    on_masts = 0.0
    if window is None:
        on_masts = (yield from sensors_on_masts(inst, cands.position, sites, deadline, stop)).bound
    cols = milp_candidates(inst, cands.position, sites, start)
    mc, sc = mast_aware_costs(problem, cands, len(cols))
    chosen = yield from sensors_on_sites(
        inst, cands.position, sites, start, mc, sc, deadline, stop, cols=cols
    )
    after = plan_value(problem, cands, chosen)
    if after >= before:
        return Rejoined(before, before, on_masts)
    old = list(solution.sensors)
    _fix_again(solution, kept)
    for c in in_gain_order(inst, chosen):
        fix_candidate(problem, solution, cands, c)
    if not problem.reached(solution.n_covered):  # the fresh evaluation fell short
        _fix_again(solution, old)
        return Rejoined(before, before, on_masts)
    return Rejoined(before, after, on_masts)


class PartBuilder(Protocol):
    """Builds the parts' candidate sets (``candidates.build_part``), in this process or
    elsewhere (``headless/ray_engine.py``). The planner calls ``start`` once with every
    part, then ``build(k)`` for the parts it plans, in order, then ``close``. Every
    builder gives the same candidates, so the plan does not depend on the builder."""

    def start(self, problem: Problem, parts: list[I64], reach_m: float) -> None:
        """The parts (target ordinals, sorted) to come; a builder may begin on them."""
        ...

    def build(self, k: int) -> Generator[int, None, PartCandidates]:
        """Part k's candidates; yields while they are being built."""
        ...

    def close(self) -> None:
        """Release what the builder holds; safe to call twice."""
        ...


class LocalBuilder:
    """Each part's candidates built here, when the planner asks for it: one part's
    matrix held at a time, and what the positions that later parts reach too gave
    (``candidates.SharedPositions``)."""

    def start(self, problem: Problem, parts: list[I64], reach_m: float) -> None:
        self.problem, self.parts, self.reach_m = problem, parts, reach_m
        near = [near_positions(problem, points, reach_m) for points in parts]
        self.shared = SharedPositions(near, len(problem.space.positions))

    def build(self, k: int) -> Generator[int, None, PartCandidates]:
        self.shared.at(k)
        return build_part(self.problem, self.parts[k], self.reach_m, self.shared)

    def close(self) -> None:
        self.shared = SharedPositions([], 0)


def solve_in_parts(
    problem: Problem,
    solution: Solution,
    n_parts: int,
    deadline: float | None,
    stop: threading.Event,
    builder: PartBuilder | None = None,
) -> Generator[Progress, None, Solution]:
    """Plan the problem part by part (see the module docstring); fixes the sensors of
    each part as it is solved, sets the solution's bound and stop reason. builder:
    builds the parts' candidates (default ``LocalBuilder``)."""
    rho, s = problem.rho, problem.settings
    t0 = time.perf_counter()
    xy = problem.grid.target_xy
    part_of = parts_of(xy, n_parts)
    start_covered = solution.covered.copy()
    start_counts = solution.counts.copy()
    first = len(solution.sensors)
    assert solution.need is not None
    open_points = [np.count_nonzero(~start_covered[part_of == k]) for k in range(n_parts)]
    total_open = max(sum(open_points), 1)
    goal = max(0, problem.goal - solution.n_covered)
    sensor_lines: list[list[Line]] = [[(0.0, 0.0)]] * n_parts
    mast_lines: list[list[Line]] = [[(0.0, 0.0)]] * n_parts
    reach = list(open_points)  # what each part can cover: at most its open points
    rounds = 0
    costs = problem.sensor_costs
    mixed = s.objective == "cost" and not np.all(costs == costs[0])
    dearest = float(costs.max()) if mixed else None
    carry = 0  # goal the parts so far fell short of: the next part's to meet
    reach_m = max(m.range_m for m in problem.models)
    stopped = False
    build_s: list[float] = []  # how long each part's candidates took to come, s
    over_s: list[float] = []  # how long each part's work went on past its deadline, s
    # The parts end before the run does: what is left is the re-plan's (``rejoin``).
    parts_end = None if deadline is None else deadline - REJOIN_SHARE * max(0.0, deadline - t0)

    known: dict[str, PlanBound] = {}

    def bound_now() -> PlanBound:
        # Asked at every progress report (1.3 ms on Town04's 8 parts): computed again
        # only when the lines have changed.
        # (within a part ``_standing_too`` counts the masts of the parts before too)
        standing = int(np.count_nonzero(problem.space.standing))
        key = repr((sensor_lines, mast_lines, reach, rounds, standing))
        if key not in known:
            known.clear()
            known[key] = whole_bound(
                problem, sensor_lines, mast_lines, reach, min(goal, sum(reach)), rounds, dearest
            )
        return known[key]

    def late() -> bool:
        return stop.is_set() or (deadline is not None and time.perf_counter() > deadline)

    def where(p: Progress, k: int, stage: str, finished: bool = False) -> Progress:
        """``p`` with the whole ground's bound and plan, in part k (0-based)."""
        done = sum(open_points[: k + finished])
        spent = time.perf_counter() - t0
        eta = spent * (total_open - done) / done if done else None
        if stage == "seams":  # every part is done; the re-plan ends by the deadline
            eta = None if deadline is None else math.inf
        if eta is not None and deadline is not None:  # the run ends by its deadline
            eta = min(eta, max(0.0, deadline - t0 - spent))
        masts = len({(f.pose.x, f.pose.y) for f in solution.sensors[first:]})
        bound = bound_now().objective(s.objective, s.mast_cost, s.sensor_cost)
        return replace(
            p,
            stage=p.stage or stage,
            part=k + 1,
            parts=n_parts,
            bound=bound if bound > 0 else None,  # 0: nothing proven yet, not shown
            best=None,
            plan=(len(solution.sensors) - first, masts),
            eta_s=eta,
        )

    def busy(
        gen: Generator[Any, None, Any], k: int, stage: str, stop: threading.Event | None = None
    ) -> Generator[Progress, None, Any]:
        """``gen``'s value, reporting progress in part k while it works; None when
        ``stop`` is set first (``gen`` is dropped)."""
        try:
            while True:
                if stop is not None and stop.is_set():
                    return None
                try:
                    next(gen)
                except StopIteration as done:
                    return done.value
                yield where(solution.progress("search", rho), k, stage)
        finally:
            gen.close()

    ledger = CostLedger()  # what each part's sensors line took of the candidates' costs
    builder = builder or LocalBuilder()
    builder.start(problem, [np.flatnonzero(part_of == k) for k in range(n_parts)], reach_m)
    try:
        for k in range(n_parts):
            # Each part covers rho of its own points (what covers them already counts),
            # and what the parts before fell short of: the goal is met part by part, and
            # a resumed run skips the parts it finished.
            points = np.flatnonzero(part_of == k)
            have = int(np.count_nonzero(solution.covered[points]))
            target = max(0, math.ceil(rho * len(points)) - have) + carry
            if target <= 0:
                continue
            # Stopped (Esc, Ctrl-C): the parts done are the plan. Past the time limit,
            # the parts left are still planned, each from its greedy plans (no LP):
            # a plan that leaves parts of the ground uncovered is no plan.
            if stop.is_set():
                stopped = True
                break
            started = time.perf_counter()
            part = yield from busy(builder.build(k), k, "candidates", stop)
            if part is None:  # stopped while it was built
                stopped = True
                break
            build_s.append(time.perf_counter() - started)
            cands = part.cands
            log.info(
                "part %d/%d: %d points, %d candidates (%d dominated left out), %d nonzeros "
                "in %.1f s", k + 1, n_parts, len(points), len(cands), cands.dominated,
                cands.matrix.nnz, time.perf_counter() - started,
            )  # fmt: skip
            solving = time.perf_counter()
            taken = taken_candidates(cands, solution.sensors)
            # The part as the bound sees it (nothing fixed but what the run started
            # with: a plan of the whole ground may use a candidate the parts before
            # fixed) and as its plan does (what the parts before cover is covered).
            full, _ = split_instance(
                cands, points, start_covered, start_counts, solution.need, xy,
                s.max_sensors_per_mast, taken_candidates(cands, solution.sensors[:first]),
            )  # fmt: skip
            reach[k] = coverable(full)
            # Its LP is solved at its share of the whole goal (its line holds at any).
            full = replace(full, goal=min(reach[k], math.ceil(goal * open_points[k] / total_open)))
            left, _ = split_instance(
                cands, points, solution.covered, solution.counts, solution.need, xy,
                s.max_sensors_per_mast, taken, _held(problem, solution.sensors),
            )  # fmt: skip
            left = replace(left, goal=min(coverable(left), target))
            if left.goal > 0 and full.goal > 0:
                # The rest of the time, shared by the parts left by their points.
                share = open_points[k] / max(sum(open_points[k:]), 1)
                part_deadline = solve_deadline(
                    time.perf_counter(), parts_end, share, build_s, n_parts - 1 - k, over_s
                )
                # Its plans look for masts where its masts LP puts them, where the
                # fewest new masts stand, and where the parts before stood theirs,
                # which cost it nothing more.
                used = _mast_sites(problem, solution.sensors[first:])
                masts_lp: dict[str, Any] = {}
                standing = problem.space.standing.copy()
                standing[used] = True
                sites = part_sites(
                    site_line(
                        full,
                        part,
                        problem.space.standing,
                        SAMPLE_CELLS * s.grid_m,
                        part_deadline,
                        stop,
                        parts_end,
                    ),
                    np.intersect1d(used, part.sites),
                    masts_lp,
                    fewest_masts(left, cands.position, standing, s.grid_m, part_deadline, stop),
                )
                unit = costs[cands.model] if mixed else 1.0
                lp_cost = ledger.costs(part, unit)
                below = (int(full.goal - f * len(points)) for f in OTHER_GOALS)
                goals = tuple(g for g in (*below, reach[k]) if 0 < g != full.goal)
                how = PartInputs(lp_cost, full, sites, goals)
                with _standing_too(problem, used):
                    solve = prove_and_plan(problem, cands, left, solution, part_deadline, stop, how)
                    while True:
                        try:
                            p = next(solve)
                        except StopIteration as done:
                            chosen, _, lp = done.value
                            break
                        yield where(p, k, "solve")
                sensor_lines[k] = [(lp.slope, lp.intercept), *lp.more_lines]
                pis = [] if lp.line_pi is None else [lp.line_pi, *lp.more_pi]
                ledger.take(part, lp_cost, full.matrix, pis)
                site_lp: SiteLP | None = masts_lp.get("lp")
                if site_lp is not None:
                    # After the part's plan, which does not need them, and at most until
                    # the parts' end (on Town04 they took about 100 s of a part's 210).
                    more = either_side(site_lp, reach[k], parts_end, stop)
                    mast_lines[k] = [site_lp.line, *((yield from busy(more, k, "bounds")) or [])]
                    rounds += site_lp.rounds
                rounds += lp.rounds
                at = full.goal
                log.info(
                    "part %d/%d: sensors LP %.2f >= %.2f at goal %d (%d rounds), masts LP "
                    "line %.2f (%.1f s), plan %d; %.1f s", k + 1, n_parts, lp.value,
                    lp.slope * at - lp.intercept, at, lp.rounds,
                    max(a * at - b for a, b in mast_lines[k]), masts_lp.get("seconds", 0.0),
                    len(chosen), time.perf_counter() - solving,
                )  # fmt: skip
                for c in in_gain_order(left, chosen):
                    if len(solution.sensors) >= problem.max_sensors:
                        break
                    sensor = fix_candidate(problem, solution, cands, c)
                    yield where(solution.progress("fixed", rho, fixed=sensor), k, "fixing")
                if part_deadline is not None:
                    over_s.append(max(0.0, time.perf_counter() - part_deadline))
            got = int(np.count_nonzero(solution.covered[points])) - have
            carry = max(0, target - got)
            del part, cands, full, left  # the part's matrix goes before the next part's is built
            yield where(solution.progress("search", rho), k, "part done", finished=True)
    finally:
        builder.close()
    dropped = prune(problem, solution)
    # Cut short: stopped, or the parts ran to their end (the time limit less the re-plan's).
    early = stopped or late() or (parts_end is not None and time.perf_counter() > parts_end)
    saved = Rejoined(0.0, 0.0)
    if n_parts > 1 and not late() and problem.reached(solution.n_covered):
        last = max(n_parts - 1, 0)
        replan = rejoin_windows(problem, solution, deadline, stop)
        saved = (yield from busy(replan, last, "seams")) or saved
        log.info(
            "seams: the plan over the whole ground on its own masts: %g -> %g (its sensors "
            "LP there %.2f)", *saved,
        )  # fmt: skip
    solution.bound = replace(bound_now(), on_masts=whole_sensors(saved.on_masts))
    if problem.reached(solution.n_covered):
        solution.stop_reason = StopReason.reached(rho, early=early)
    elif stopped:
        solution.stop_reason = (
            "Stopped early: the plan covers the parts planned by then "
            f"({solution.coverage:.2%} of the target)."
        )
    else:
        solution.stop_reason = StopReason.out_of_sight("candidate pose")
    if dropped:
        solution.stop_reason += f" {dropped} sensor(s) the parts' seams made redundant dropped."
    if saved.after < saved.before:
        solution.stop_reason += (
            f" Re-planned over the whole ground on its own masts: {saved.before:g} -> "
            f"{saved.after:g}."
        )
    return solution
