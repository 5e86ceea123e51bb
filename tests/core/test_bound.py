"""The bound code on hand cases: column generation round by round (one candidate per
position, the integral stop, the LP as a line in the goal); the LP in parts returns
the whole LP's solution, not just its bound, and stops at a deadline, a stop, its gap
or a solve cut short; the parts follow the points' extent; the mast-aware bound's
scale per site; the mast-aware MILP counts a candidate once, keeps within the cap and
its limits; the fewest masts count each point's k and masts that stand. The LP
optima below are worked out on paper (each unique).

Part 0, points 0-2: a = {0, 1}, b = {1, 2}, c = {0, 2} at 1 each and e = {0} at 0.1.
Every point once: e + b = 1.1 (point 1 needs a or b, point 2 b or c; b does both).
Every point twice (x <= 1): a + b >= 2 and b + c >= 2 force a = b = c = 1: 3.
Part 1, points 3-5: a' = {3, 4}, b' = {4, 5}, c' = {3, 5} at 1 each. Once: each pair
sums to 1 at the least 1.5, all three at 0.5 (the only optimum). Twice: all three, 3.
"""

import itertools
import threading
import time

import numpy as np
import pytest
from scipy import sparse
from scipy.optimize import linprog

from autoscoop_blender.core.optimize import bound
from autoscoop_blender.core.optimize.bound import (
    LPProgress,
    MergedPoints,
    combined_bound,
    combined_sum_bound,
    cover_lp,
    parts_of,
    sensors_on_sites,
    site_cover,
    site_matrix,
    split_cover_lp,
)
from autoscoop_blender.core.optimize.cover import Cover, CoverInstance, complete
from tests.core.test_lp import drain, instance, random_instance, steps

ROWS = [[0, 1], [1, 2], [0, 2], [0], [3, 4], [4, 5], [3, 5]]
COST = np.array([1.0, 1.0, 1.0, 0.1, 1.0, 1.0, 1.0])
PART = np.array([0, 0, 0, 1, 1, 1])
# Each candidate's value in the LP's unique optimum (every point once).
X_ONCE = {1: 1.0, 3: 1.0, 4: 0.5, 5: 0.5, 6: 0.5}


def _parts_lp(need):
    """(split LP's solution, its progress reports) on all six points, each needed
    ``need`` times."""
    inst = CoverInstance(instance(ROWS, 6, 6).matrix, 6, need=np.full(6, need, np.int32))
    gen = split_cover_lp(inst, COST, np.arange(7), np.zeros(0, np.int64), PART, rel_gap=0)
    sol, yielded = steps(gen)
    return sol, [r for r in yielded if isinstance(r, LPProgress)]


def test_the_lp_in_parts_returns_the_whole_lps_solution():
    sol, reports = _parts_lp(1)
    assert sol.parts == 2 and sol.complete
    assert sol.value == pytest.approx(1.1 + 1.5)
    assert sol.bound == pytest.approx(2.6, rel=1e-5) and sol.bound <= 2.6
    x = dict(zip(sol.columns.tolist(), sol.x.tolist(), strict=True))
    assert {c: v for c, v in x.items() if v > 1e-9} == pytest.approx(X_ONCE)
    # The duals price every candidate: none below its cost (the LP is complete), those
    # in the optimum at their cost exactly (complementary slackness); the duals are
    # summed in float32, within 1e-6 of the exact sums here.
    assert sol.reduced == pytest.approx(COST - sol.priced)
    assert (sol.reduced >= -1e-6).all()
    assert sol.reduced[list(X_ONCE)] == pytest.approx(0.0, abs=1e-6)
    # One report per part, the values and rounds adding up, the last bound the final.
    alone = [
        drain(cover_lp(instance([[p - first for p in r] for r in ROWS[rows]], 3, 3),
                       COST[rows], np.arange(len(COST[rows])), np.zeros(0, np.int64),
                       integral=False))
        for first, rows in ((0, slice(0, 4)), (3, slice(4, 7)))
    ]  # fmt: skip
    assert [r.value for r in reports] == pytest.approx([1.1, 2.6])
    assert [r.rounds for r in reports] == [alone[0].rounds, alone[0].rounds + alone[1].rounds]
    assert sol.rounds == reports[-1].rounds and reports[-1].bound == sol.bound
    assert reports[0].bound <= 1.1 + 1e-9  # part 1 unsolved counts nothing yet
    assert [r.columns for r in reports] == [4, 7] and len(sol.columns) == 7


def test_the_lp_in_parts_keeps_each_points_k():
    sol, _ = _parts_lp(2)
    assert sol.value == pytest.approx(3.0 + 3.0)
    assert sol.bound == pytest.approx(6.0, rel=1e-5) and sol.bound <= 6.0


def test_parts_follow_the_longer_extent_and_an_odd_count():
    """A strip along y (1 m wide, its points in no order) splits along y; three parts
    of 99 points are three runs of 33, five of 100 five runs of 20."""
    y = np.random.default_rng(0).permutation(100).astype(float)
    part = parts_of(np.column_stack([y % 2, y]), 4)
    assert np.bincount(part).tolist() == [25] * 4
    assert np.all(np.diff(part[np.argsort(y)]) >= 0)  # consecutive runs along y
    for n_parts, n in ((3, 99), (5, 100)):
        part = parts_of(np.column_stack([np.arange(float(n)), np.zeros(n)]), n_parts)
        assert np.bincount(part).tolist() == [n // n_parts] * n_parts
        assert np.all(np.diff(part) >= 0)


def test_combined_bound_fills_the_cheapest_slope_first_in_any_order():
    """``test_lp``'s two parts listed the other way round: still 5."""
    assert combined_bound([(2.0, 0.0), (1.0, 2.0)], [5, 5], 6) == pytest.approx(5.0)


def test_combined_bound_with_more_lines_a_part_is_their_upper_envelope():
    """Goal 15 of two parts. Part 1: 0.5 g - 2 on its 5 points (free up to 4, 0.5 for
    the fifth). Part 0 on 10 points by its tangent g - 5 alone: free up to 5, then 1 a
    point, so it takes the 6 left at 1 each less the fifth point of part 1 (0.5):
    5 + 0.5. With a second line 3 g - 22, steeper near all it covers (it passes g - 5
    at 8.5): 3.5 points at 1 and 1.5 at 3, 8 + 0.5. With room for 10 in part 1 the
    cheaper 0.5 takes the 6: 3, the second line unused."""
    tangent, near_all, other = (1.0, 5.0), (3.0, 22.0), (0.5, 2.0)
    assert combined_bound([[tangent], [other]], [10, 5], 15) == pytest.approx(5.5)
    assert combined_bound([[tangent, near_all], [other]], [10, 5], 15) == pytest.approx(8.5)
    assert combined_bound([[tangent, near_all], [other]], [10, 10], 15) == pytest.approx(3.0)


@pytest.mark.parametrize("seed", range(20))
def test_combined_bound_is_the_least_total_the_lp_finds(seed):
    """Random parts with 1-3 lines each: the least total over the splits of the goal,
    as an LP (each part's value above each of its lines and 0, its goal within what
    it can cover, the goals adding up to the whole's) solved by HiGHS, is what
    ``combined_bound`` gives."""
    rng = np.random.default_rng(seed)
    n = int(rng.integers(1, 5))
    lines = [
        [(float(rng.uniform(0, 2)), float(rng.uniform(-1, 20))) for _ in range(rng.integers(1, 4))]
        for _ in range(n)
    ]
    coverable = [int(rng.integers(1, 30)) for _ in range(n)]
    goal = int(rng.integers(0, sum(coverable) + 1))
    # Variables: each part's goal g_k, then its value t_k.
    rows, rhs = [], []
    for k, mine in enumerate(lines):
        for a, b in mine:  # a g_k - t_k <= b
            row = np.zeros(2 * n)
            row[k], row[n + k] = a, -1.0
            rows.append(row)
            rhs.append(b)
    rows.append(np.r_[-np.ones(n), np.zeros(n)])  # sum g_k >= goal
    rhs.append(-goal)
    bounds = [(0, c) for c in coverable] + [(0, None)] * n
    lp = linprog(np.r_[np.zeros(n), np.ones(n)], A_ub=np.array(rows), b_ub=rhs, bounds=bounds)
    assert lp.status == 0
    assert combined_bound(lines, coverable, goal) == pytest.approx(lp.fun, abs=1e-7)


def test_one_split_for_masts_and_sensors_beats_two():
    """Goal 10 of two parts of 10 points each. Part 0: sensors 0.5 a point, masts 1;
    part 1: sensors 1, masts 0.5. Apart, the sensors' split puts the goal in part 0
    (5) and the masts' in part 1 (5): 3 x 5 + 5 = 20 at masts 3, sensors 1. One
    split for both: a point costs 3.5 in part 0 and 2.5 in part 1, so all in part 1:
    25."""
    sensors, masts = [(0.5, 0.0), (1.0, 0.0)], [(1.0, 0.0), (0.5, 0.0)]
    apart = 3 * combined_bound(masts, [10, 10], 10) + combined_bound(sensors, [10, 10], 10)
    assert apart == pytest.approx(20.0)
    assert combined_sum_bound([(3.0, masts), (1.0, sensors)], [10, 10], 10) == pytest.approx(25)


@pytest.mark.parametrize("seed", range(20))
def test_combined_sum_bound_is_the_least_total_the_lp_finds(seed):
    """Random parts, two bounds of 1-3 lines each, weights in [0, 3]: the least
    weighted total over one split of the goal, as an LP (each part's value of each
    bound above its lines and 0) solved by HiGHS, is what ``combined_sum_bound``
    gives, and never below the bounds split apart."""
    rng = np.random.default_rng(100 + seed)
    n = int(rng.integers(1, 5))

    def some_lines():
        return [
            [(float(rng.uniform(0, 2)), float(rng.uniform(-1, 20)))
             for _ in range(rng.integers(1, 4))]
            for _ in range(n)
        ]  # fmt: skip

    bounds_lines = [some_lines(), some_lines()]
    weights = [float(w) for w in rng.uniform(0, 3, 2)]
    coverable = [int(rng.integers(1, 30)) for _ in range(n)]
    goal = int(rng.integers(0, sum(coverable) + 1))
    # Variables: each part's goal g_k, then each bound's value t_wk.
    rows, rhs = [], []
    for w, lines in enumerate(bounds_lines):
        for k, mine in enumerate(lines):
            for a, b in mine:  # a g_k - t_wk <= b
                row = np.zeros(3 * n)
                row[k], row[n + w * n + k] = a, -1.0
                rows.append(row)
                rhs.append(b)
    rows.append(np.r_[-np.ones(n), np.zeros(2 * n)])  # sum g_k >= goal
    rhs.append(-goal)
    cost = np.r_[np.zeros(n), np.full(n, weights[0]), np.full(n, weights[1])]
    box = [(0, c) for c in coverable] + [(0, None)] * (2 * n)
    lp = linprog(cost, A_ub=np.array(rows), b_ub=rhs, bounds=box)
    assert lp.status == 0
    weighted = list(zip(weights, bounds_lines, strict=True))
    got = combined_sum_bound(weighted, coverable, goal)
    assert got == pytest.approx(lp.fun, abs=1e-7)
    apart = sum(w * combined_bound(lines, coverable, goal) for w, lines in weighted)
    assert got >= apart - 1e-9


def test_the_mast_aware_milp_takes_a_candidate_once():
    """Points 0 and 1, each needed twice; A and B see both from one site, A at 1, B at
    3: A twice would cost 2 but counts once, so the plan is A and B (4 and the mast)."""
    inst = CoverInstance(instance([[0, 1], [0, 1]], 2, 2).matrix, 2,
                         need=np.full(2, 2, np.int32))  # fmt: skip
    site_of = np.zeros(2, dtype=np.int64)
    got = drain(sensors_on_sites(inst, site_of, np.array([0]), [0, 1], 1.0, np.array([1.0, 3.0])))
    assert sorted(got) == [0, 1]


def test_the_mast_aware_milp_keeps_within_the_cap():
    """Points 0-3, all needed; site 0: c0-c3, one point each; site 1: e01 = {0, 1};
    site 2: e23 = {2, 3}; listed interleaved. Masts at 10, sensors at 1. Four per mast:
    site 0 alone (10 + 4 = 14). Two per mast: e01 and e23 (22) beat two on site 0 and
    e23 (23, the start). Three per mast: still 22 (three on site 0 need a second mast)."""
    rows = [[0], [0, 1], [1], [2, 3], [2], [3]]
    site_of = np.array([0, 1, 0, 2, 0, 0])
    for cap, want in ((4, [0, 2, 4, 5]), (3, [1, 3]), (2, [1, 3])):
        inst = CoverInstance(instance(rows, 4, 4).matrix, 4, site_of=site_of, cap=cap)
        got = drain(sensors_on_sites(inst, site_of, np.arange(3), [0, 2, 3], 10.0, 1.0))
        assert sorted(got) == want
    # Four per mast, but 1 planned sensor stands on site 0 already: room for 3 there,
    # so again e01 and e23 (22), not four on site 0.
    inst = CoverInstance(instance(rows, 4, 4).matrix, 4, site_of=site_of, cap=4,
                         held=np.array([1, 0, 0]))  # fmt: skip
    got = drain(sensors_on_sites(inst, site_of, np.arange(3), [0, 2, 3], 10.0, 1.0))
    assert sorted(got) == [1, 3]


def test_the_fewest_masts_count_each_points_k():
    """Points 0 and 1, each needed twice; sites 0, 1, 2 each hold one candidate seeing
    both: one candidate counts once, so two masts (one would do at k = 1). Site 3 holds
    two such candidates: it alone is enough."""
    for rows, site_of, want in (
        ([[0, 1]] * 3, [0, 1, 2], 2),
        ([[0, 1]] * 5, [0, 1, 2, 3, 3], 1),
    ):
        inst = CoverInstance(instance(rows, 2, 2).matrix, 2, need=np.full(2, 2, np.int32))
        sol = drain(site_cover(inst, np.array(site_of), 4))
        assert sol.bound == want and len(sol.sites) == want
        # The sites' matrix as the instance, each row its own site: the same matrix
        # (site 3 adds 2 to each point) and the same fewest masts.
        sites = site_matrix(inst, np.array(site_of), 4)
        by_site = CoverInstance(sites, 2, need=inst.k)
        assert (site_matrix(by_site, np.arange(4), 4) != sites).nnz == 0
        assert sites.toarray()[3].tolist() == ([0, 0] if want == 2 else [2, 2])
        assert drain(site_cover(by_site, np.arange(4), 4)).bound == want


def test_masts_that_stand_cost_nothing():
    """Points 0 and 1; site 0 sees both, site 1 (standing) sees 0, site 2 sees 1: one
    new mast at least (site 0, or site 2 beside the standing one); with site 0's mast
    standing instead, none."""
    inst = instance([[0, 1], [0], [1]], 2, 2)
    site_of = np.arange(3)
    for standing, want in (([False, True, False], 1), ([True, False, False], 0)):
        sol = drain(site_cover(inst, site_of, 3, standing=np.array(standing)))
        assert sol.bound == want
        new = [s for s in sol.sites if not standing[s]]
        assert len(new) == want


def test_a_candidate_seen_in_two_parts():
    """S = {0-3} at 2 spans part 0 (points 0, 1) and part 1 (2, 3): each part has a copy
    at half the cost, 1. Part 0 has A = {0, 1} at 1.5, part 1 B = {2, 3} at 0.5. Part 0
    takes S's copy (1 < 1.5), part 1 takes B (0.5 < 1): S keeps its larger x, 1, and
    its dual weight adds up over the parts, 1 + 0.5 (each copy's points priced at what
    covers them there): 0.5 short of its cost."""
    inst = CoverInstance(instance([[0, 1, 2, 3], [0, 1], [2, 3]], 4, 4).matrix, 4)
    cost = np.array([2.0, 1.5, 0.5])
    part = np.array([0, 0, 1, 1])
    sol = drain(split_cover_lp(inst, cost, np.arange(3), np.zeros(0, np.int64), part, rel_gap=0))
    assert sol.value == pytest.approx(1.5) and sol.complete
    x = dict(zip(sol.columns.tolist(), sol.x.tolist(), strict=True))
    assert x[0] == pytest.approx(1.0) and x[2] == pytest.approx(1.0) and x.get(1, 0.0) < 1e-9
    assert sol.priced[0] == pytest.approx(1.5, abs=1e-6)
    assert sol.reduced[0] == pytest.approx(0.5, abs=1e-6)


def _groups(merged):
    """{the columns that cover a group, its need: its weight} of a ``MergedPoints``."""
    by_group = merged.matrix.tocsc()
    return {
        (tuple(sorted(by_group[:, g].indices)), int(merged.need[g])): merged.weight[g]
        for g in range(by_group.shape[1])
    }


# Points 0-5 seen by c0 = {0, 1, 2}, c1 = {1, 2, 4}, c2 = {3}; nothing sees point 5.
SEEN = instance([[0, 1, 2], [1, 2, 4], [3]], 6, 5).matrix


def test_points_seen_by_the_same_candidates_merge():
    """Points 1 and 2 are both seen by c0 and c1: one group of 2; the others alone;
    point 5 in none. Needed twice, point 2 stands apart from point 1."""
    ones = np.ones(6, np.int32)
    want = {((0,), 1): 1, ((0, 1), 1): 2, ((2,), 1): 1, ((1,), 1): 1}
    assert _groups(MergedPoints.of(SEEN, ones)) == want
    need = np.array([1, 1, 2, 1, 1, 1], np.int32)
    del want[((0, 1), 1)]
    want |= {((0, 1), 1): 1, ((0, 1), 2): 1}
    assert _groups(MergedPoints.of(SEEN, need)) == want


def test_points_whose_keys_collide_are_told_apart(monkeypatch):
    """With every salt 1 the key is a point's count and values alone: points 0, 3 and
    4 (one candidate each) share a key, and the entry by entry check parts them."""

    class Ones:
        def integers(self, low, high, size, dtype):
            return np.ones(size, dtype)

    monkeypatch.setattr(bound.np.random, "default_rng", lambda seed: Ones())
    want = {((0,), 1): 1, ((0, 1), 1): 2, ((2,), 1): 1, ((1,), 1): 1}
    assert _groups(MergedPoints.of(SEEN, np.ones(6, np.int32))) == want


def _cheapest_plan(inst, site_of, cap, mast_cost):
    """The least mast_cost x sites + sensors of any plan within the cap, by enumeration."""
    best = np.inf
    n_cand = inst.matrix.shape[0]
    for pick in itertools.product([0, 1], repeat=n_cand):
        cols = np.flatnonzero(pick)
        if len(cols) and np.bincount(site_of[cols]).max() > cap:
            continue
        count = np.zeros(inst.n_points, int)
        for c in cols:
            count[inst.covers(c)] += 1
        if (count >= inst.k).sum() >= inst.goal:
            best = min(best, mast_cost * len(np.unique(site_of[cols])) + len(cols))
    return best


@pytest.mark.parametrize("seed", range(8))
def test_the_mast_aware_milp_finds_the_cheapest_plan_on_merged_points(seed):
    """Random instances of 9 candidates on 3 sites, where many of the 30 points are seen
    alike (merged), k = 1 or 2 per point, a cap of 2: the MILP's plan costs what the
    cheapest plan by enumeration does; with a cutoff above it, the same; with one
    below it (no plan is that cheap), the start comes back."""
    rng = np.random.default_rng(seed)
    rows = [rng.choice(30, size=rng.integers(4, 16), replace=False) for _ in range(9)]
    site_of = np.repeat(np.arange(3), 3)
    need = rng.integers(1, 3, 30).astype(np.int32)
    base = instance(rows, 30, 1).matrix
    start = [0, 1, 3, 4, 6, 7]  # two on each site: the goal is at most what they cover
    count = np.asarray(base[start].sum(axis=0)).ravel()
    goal = int(rng.integers(1, (count >= need).sum() + 1))
    inst = CoverInstance(base, goal, need=need, site_of=site_of, cap=2)
    want = _cheapest_plan(inst, site_of, 2, 2.0)
    assert len(MergedPoints.of(base, need).weight) < 30  # some points are merged
    got = drain(sensors_on_sites(inst, site_of, np.arange(3), start, 2.0, 1.0))
    assert 2.0 * len(np.unique(site_of[got])) + len(got) == want
    assert np.bincount(site_of[got]).max() <= 2
    above = drain(sensors_on_sites(inst, site_of, np.arange(3), start, 2.0, 1.0, cutoff=want + 0.5))
    assert 2.0 * len(np.unique(site_of[above])) + len(above) == want
    below = drain(sensors_on_sites(inst, site_of, np.arange(3), start, 2.0, 1.0, cutoff=want - 1.0))
    assert below == start


def test_the_mast_aware_milp_counts_a_point_only_at_its_k():
    """Points 0 and 1, each needed twice, the goal one of them; A = {0, 1} and B = {0}
    at 1 each, one site. A alone brings both halfway, which counts nothing: the plan is
    A and B (point 0 twice), 2."""
    inst = CoverInstance(instance([[0, 1], [0]], 2, 1).matrix, 1, need=np.full(2, 2, np.int32))
    got = drain(sensors_on_sites(inst, np.zeros(2, np.int64), np.array([0]), [0, 1], 0.0, 1.0))
    assert sorted(got) == [0, 1]


def _cut_short(monkeypatch, cut):
    """Replace ``bound._run``: solve number i (from 1) returns at once, unsolved and
    cut short, when ``cut(i, stop)`` (stop: the event the solve was handed), as a
    real one does when a stop comes before HiGHS finishes, but not by timing. The
    tests hand in an event they never set (the fake stands for its being set while
    HiGHS works), so that a solve not handed the caller's stop runs to its end."""
    real_run = bound._run
    count = itertools.count(1)

    def run(h, stop=None, beside=None):
        if cut(next(count), stop):
            return bound.Solve.GONE
        return (yield from real_run(h, stop, beside))

    monkeypatch.setattr(bound, "_run", run)


def _split(inst, initial=(), **kwargs):
    """``split_cover_lp`` on ROWS' candidates and parts, run to its end."""
    group = kwargs.pop("group", np.arange(len(COST)))
    start = np.asarray(initial, dtype=np.int64)
    return drain(split_cover_lp(inst, COST, group, start, PART, **kwargs))


def test_one_column_a_round_still_reaches_the_lp():
    """All seven candidates at one position: one joins per round, so the parts take
    several rounds; each still runs to its LP value, 1.1 and 1.5, not to the first
    bound whose ceiling matches (2 and 2)."""
    inst = instance(ROWS, 6, 6)
    sol = _split(inst, group=np.zeros(7, np.int64), rel_gap=0)
    assert sol.rounds > 4 and sol.complete
    assert sol.value == pytest.approx(2.6)
    assert sol.bound == pytest.approx(2.6, rel=1e-5) and sol.bound <= 2.6


def test_the_default_gap_is_half_a_percent():
    """From a, b, a', b' the first round's bound is 1.6 (each part's value 2, priced at
    Farley's scale); by default the parts go on until within 0.5 % of 2.6."""
    sol = _split(instance(ROWS, 6, 6), [0, 1, 4, 5])
    assert 2.6 * (1 - 0.005) <= sol.bound <= 2.6


def test_a_part_stopped_in_its_first_solve_counts_nothing(monkeypatch):
    """Part 0's first solve is cut short (as by a stop): the part gives no line, the
    LP is not complete, and part 1 is still solved: 1.5 for the three points it must
    cover then (part 0 may cover its three for nothing, as far as is proven)."""
    _cut_short(monkeypatch, lambda i, stop: i == 1)
    sol = _split(instance(ROWS, 6, 6), rel_gap=0)
    assert sol.complete is False
    assert sol.value == pytest.approx(1.5)
    assert sol.bound == pytest.approx(1.5, rel=1e-5) and sol.bound <= 1.5


def test_a_past_deadline_ends_each_part_after_its_first_round():
    """Started from a, b, a', b' (each part 2, 4 in all) with the deadline gone: each
    part solves its LP over those columns once and stops there, incomplete; the
    bound still holds."""
    inst = instance(ROWS, 6, 6)
    sol = _split(inst, [0, 1, 4, 5], rel_gap=0, deadline=time.perf_counter() - 1.0)
    assert sol.rounds == 2 and not sol.complete
    assert sol.value == pytest.approx(4.0)
    assert sol.columns.tolist() == [0, 1, 4, 5]
    assert 0.0 <= sol.bound <= 2.6


def test_a_stop_set_before_the_start_ends_each_part_at_once():
    stop = threading.Event()
    stop.set()
    sol = _split(instance(ROWS, 6, 6), [0, 1, 4, 5], rel_gap=0, stop=stop)
    assert sol.rounds <= 2 and not sol.complete
    assert sol.bound <= 2.6


def test_a_wide_gap_stops_a_part_before_its_lp_is_complete():
    """Stopping once the bound is within 99 % of the value: from a, b, a', b' the first
    round's bound (Farley's, positive) already is, so each part stops after it."""
    sol = _split(instance(ROWS, 6, 6), [0, 1, 4, 5], rel_gap=0.99)
    assert sol.rounds == 2 and not sol.complete
    assert 0.0 < sol.bound <= 2.6


def test_parts_no_candidate_sees_or_one_candidate_sees():
    """Points: 0 (part 0) and 5 (part 2) no candidate sees; 1-3 (part 1) the triangle
    with e = {1} at 0.1 (1.1, as above); 4 (part 2) only d sees, at 1. The goal, the
    four points that can be covered, costs 2.1, whichever part comes first."""
    rows = [[1, 2], [2, 3], [1, 3], [1], [4]]
    inst = instance(rows, 6, 4)
    cost = np.array([1.0, 1.0, 1.0, 0.1, 1.0])
    part = np.array([0, 1, 1, 1, 2, 2])
    sol = drain(split_cover_lp(inst, cost, np.arange(5), np.zeros(0, np.int64), part, rel_gap=0))
    assert sol.complete and sol.value == pytest.approx(2.1)
    assert sol.bound == pytest.approx(2.1, rel=1e-5) and sol.bound <= 2.1


def test_tied_points_split_by_their_index():
    """Points on three lines x = 0, 1, 2 (in random order, y = 0) split into halves
    at x: where the cut falls among equal x, the lower indices go to the first part,
    so the parts are the same on every machine (numpy's default sort may reorder
    equal keys, differently with its SIMD kernels)."""
    x = np.random.default_rng(0).integers(0, 3, 40).astype(float)
    part = parts_of(np.column_stack([x, np.zeros(40)]), 2)
    order = np.lexsort((np.arange(40), x))  # by x, then by index
    assert part[order].tolist() == [0] * 20 + [1] * 20


def test_the_mast_aware_milp_is_limited_in_nodes_and_by_the_deadline(monkeypatch):
    """The Highs model is built with ``mip_max_nodes`` (the same plan on a fast and a
    slow machine) and the time left to the deadline."""
    made = []

    def keep(limit):
        h = new_highs(limit)
        made.append(h)
        return h

    new_highs = bound._new_highs
    monkeypatch.setattr(bound, "_new_highs", keep)
    inst = instance([[0, 1], [1]], 2, 2)
    deadline = time.perf_counter() + 30.0
    got = drain(sensors_on_sites(inst, np.zeros(2, np.int64), np.array([0]), [0, 1], 1.0, 1.0,
                                 deadline=deadline))  # fmt: skip
    assert got == [0]
    (h,) = made
    assert h.getOptionValue("mip_max_nodes")[1] == bound.MAX_NODES
    assert 25.0 < h.getOptionValue("time_limit")[1] <= 30.0


def _duals(priced, value=5.0, **kwargs):
    """A sensors LP's solution as ``mast_aware_bound`` reads it: the value and each
    candidate's dual weight."""
    priced = np.asarray(priced, dtype=float)
    return bound.LPSolution(value, value, np.arange(len(priced)), np.ones(len(priced)),
                            priced, 1.0 - priced, 3, True, **kwargs)  # fmt: skip


@pytest.mark.parametrize(
    ("mast_cost", "sensor_cost", "lp_cost", "t"),
    [
        # site 1 holds c2 (priced 3): 3t - 1 <= 1 gives t = 2/3 (site 0 pays 1/3 then)
        (1.0, 1.0, None, 2 / 3),
        # site 1's mast at 5 lets t reach 1, where site 0 pays (2 - 1) + (1 - 1) = 1
        (np.array([1.0, 5.0]), 1.0, None, 1.0),
        # dear masts: t above 1; site 1: 3t - 1 <= 10 (11/3), site 0: 3t - 2 <= 10 (4)
        (10.0, 1.0, None, 11 / 3),
        # a sensor at 2: 2 (3t - 1) <= 1, t = 1/2
        (1.0, 2.0, None, 0.5),
        # the LP's costs 2, 1, 1.5: 3t - 1.5 <= 1 gives t = 5/6 (site 0 pays nothing)
        (1.0, 1.0, np.array([2.0, 1.0, 1.5]), 5 / 6),
    ],
)
def test_the_mast_aware_bound_scales_the_duals_by_the_largest_t_every_site_pays(
    mast_cost, sensor_cost, lp_cost, t
):
    """c0 (priced 2) and c1 (1) at site 0, c2 (3) at site 1; the sensors LP's value 5:
    the bound is t x sensor_cost x 5 for the largest t at which each site's mast pays
    what its candidates are priced above their cost, sensor_cost max(0, t priced -
    cost) summed."""
    got = bound.mast_aware_bound(_duals([2.0, 1.0, 3.0]), np.array([0, 0, 1]), mast_cost,
                                 sensor_cost, lp_cost)  # fmt: skip
    want = t * sensor_cost * 5.0
    assert got == pytest.approx(want, rel=1e-5) and got <= want


def test_the_mast_aware_bound_takes_the_point_duals_value_at_k2_and_refuses_parts():
    """With k > 1 the LP's value holds the x <= 1 bounds' duals too: the bound scales
    the point duals' value (4 here) instead. Duals of parts are not one solution of
    the whole, a sensor that costs nothing prices nothing, and an LP stopped before
    its first solve has no duals: 0."""
    site_of = np.array([0, 0, 1])
    got = bound.mast_aware_bound(_duals([2.0, 1.0, 3.0], dual=4.0), site_of, 1.0, 1.0)
    assert got == pytest.approx(2 / 3 * 4.0, rel=1e-5)
    assert bound.mast_aware_bound(_duals([2.0, 1.0, 3.0], parts=2), site_of, 1.0, 1.0) == 0.0
    assert bound.mast_aware_bound(_duals([2.0, 1.0, 3.0]), site_of, 1.0, 0.0) == 0.0
    assert bound.mast_aware_bound(_duals([2.0, 1.0, 3.0], np.inf), site_of, 1.0, 1.0) == 0.0
    # Small values scale as any: 2/3 x 0.3; an LP worth 0 proves nothing more.
    got = bound.mast_aware_bound(_duals([2.0, 1.0, 3.0], 0.3), site_of, 1.0, 1.0)
    assert got == pytest.approx(0.2, rel=1e-5) and got <= 0.2
    assert bound.mast_aware_bound(_duals([2.0, 1.0, 3.0], 0.0), site_of, 1.0, 1.0) == 0.0
    # One candidate (priced 2) on its mast at 1: 2t - 1 <= 1, t = 1.
    got = bound.mast_aware_bound(_duals([2.0]), np.array([0]), 1.0, 1.0)
    assert got == pytest.approx(5.0, rel=1e-5)
    # More sites priced than hold candidates: site 2 has none and pays nothing.
    three = np.array([1.0, 1.0, 0.0])
    got = bound.mast_aware_bound(_duals([2.0, 1.0, 3.0]), site_of, three, 1.0)
    assert got == pytest.approx(2 / 3 * 5.0, rel=1e-5)


def _steps_beside(monkeypatch, beside_steps):
    """Replace ``bound._run``: the solve runs at once, and ``beside_steps`` of the
    walk beside it are taken first (as many as a solve's time would allow)."""
    real_run = bound._run

    def run(h, stop=None, beside=None):
        if beside is not None:
            for _ in itertools.islice(beside, beside_steps):
                pass
        return (yield from real_run(h, stop, None))

    monkeypatch.setattr(bound, "_run", run)


@pytest.mark.parametrize("seed", range(6))
def test_the_columns_do_not_depend_on_the_steps_beside_a_solve(seed, monkeypatch):
    """Priced at duals smoothed towards the dual steps' best point, the LP takes the
    same columns in the same order whether a solve leaves time for no step beside it
    or for all of them; both reach the LP's value."""
    rng = np.random.default_rng(300 + seed)
    inst = random_instance(rng, n_cand=30, n_points=40)
    ones, group = np.ones(30), np.arange(30) % 10
    runs = []
    for beside_steps in (0, bound.DualPolish.MAX_STEPS):
        _steps_beside(monkeypatch, beside_steps)
        runs.append(drain(cover_lp(inst, ones, group, np.arange(1), integral=False)))
    assert runs[0].columns.tolist() == runs[1].columns.tolist()
    assert runs[0].value == pytest.approx(runs[1].value, abs=1e-9)


def test_smoothed_duals_pick_other_columns_for_the_same_lp(monkeypatch):
    """On random instances the smoothed duals pick other columns than each round's
    own on some, and every LP ends at the same value either way."""
    differ = 0
    for seed in range(8):
        rng = np.random.default_rng(400 + seed)
        inst = random_instance(rng, n_cand=30, n_points=40)
        ones, group = np.ones(30), np.arange(30) % 10
        runs = []
        for smoothing in (0.0, bound.SMOOTHING):
            monkeypatch.setattr(bound, "SMOOTHING", smoothing)
            runs.append(drain(cover_lp(inst, ones, group, np.arange(1), integral=False)))
        assert runs[0].complete and runs[1].complete
        assert runs[0].value == pytest.approx(runs[1].value, abs=1e-7)
        differ += runs[0].columns.tolist() != runs[1].columns.tolist()
    assert differ > 0


def _part0(**kwargs):
    """``cover_lp`` on part 0 alone (points 0-2: a, b, c, e; LP 1.1), every candidate
    at one position unless ``group`` says otherwise: (solution, progress reports)."""
    group = kwargs.pop("group", np.zeros(4, np.int64))
    start = np.asarray(kwargs.pop("initial", ()), dtype=np.int64)
    sol, yielded = steps(cover_lp(instance(ROWS[:4], 3, 3), COST[:4], group, start, **kwargs))
    return sol, [r for r in yielded if r is not None]


@pytest.mark.parametrize(
    ("group", "per_round", "columns"),
    [
        ([0, 0, 0, 0], 50, [0, 1, 2, 3, 4]),  # one position: one joins a round
        ([0, 1, 2, 3], 50, [0, 4]),  # four positions: all join in round 1
        ([0, 1, 2, 3], 1, [0, 1, 2, 3, 4]),  # at most per_round a round
        ([0, 1, 1, 1], 50, [0, 2, 3, 4]),  # a and one of b, c, e; then one a round
    ],
)
def test_candidates_join_one_per_position_and_at_most_per_round(
    group, per_round, columns, monkeypatch
):
    """From nothing (the artificial column alone: 3, one per point), candidates join
    after each round until none prices below its cost: the LP, 1.1, every report's
    bound at most that, its values never rising. (Priced at each round's own duals.)"""
    monkeypatch.setattr(bound, "SMOOTHING", 0.0)
    sol, reports = _part0(group=np.array(group), per_round=per_round, integral=False)
    assert [r.columns for r in reports] == columns
    assert [r.rounds for r in reports] == list(range(1, len(columns) + 1))
    assert reports[0].value == pytest.approx(3.0)
    assert all(b.value <= a.value + 1e-9 for a, b in itertools.pairwise(reports))
    assert all(r.bound <= 1.1 for r in reports)
    assert sol.complete and sol.rounds == len(columns)
    assert sol.value == pytest.approx(1.1) and sol.bound == pytest.approx(1.1, rel=1e-5)


def test_the_integral_stop_and_the_lp_as_a_line_in_the_goal():
    """An integer objective stops once the bound's ceiling meets the value's: the
    first bound is already 1.1 (ceiling 2), and the value reaches 2 with a's column,
    after round 2. Either way the line is LP(g) = 0.5 g - 0.4 for goals 1 to 3 (e
    covers point 0 for 0.1; then each point costs 0.5: b at 1/2 covers 1 and 2 by
    half each), exact at every such g."""
    sol, reports = _part0()
    assert sol.rounds == 2 and not sol.complete
    assert sol.value == pytest.approx(2.0) and sol.integer_bound() == 2
    full, _ = _part0(integral=False)
    for lp in (sol, full):
        for goal, value in ((1, 0.1), (2, 0.6), (3, 1.1)):
            # lowered against the solver's tolerances by 1e-6 relative and 1e-6 absolute
            assert lp.slope * goal - lp.intercept == pytest.approx(value, abs=1e-5)
            assert lp.slope * goal - lp.intercept <= value


def test_an_lp_stopped_in_its_first_solve_keeps_its_start(monkeypatch):
    """Stopped in its first solve: the start as the plan (each candidate once, x = 1),
    no value, no bound, nothing priced."""
    stop = threading.Event()
    _cut_short(monkeypatch, lambda i, given: given is stop)
    sol, reports = _part0(initial=[3, 1, 3], stop=stop)
    assert reports == [] and sol.rounds == 0 and not sol.complete
    assert sol.value == np.inf and sol.bound == 0.0 and sol.integer_bound() == 0
    assert sol.columns.tolist() == [1, 3] and sol.x.tolist() == [1.0, 1.0]
    assert len(sol.priced) == 0 and np.isinf(sol.reduced).all() and len(sol.reduced) == 4


def test_an_lp_whose_solve_ends_as_the_stop_comes_takes_no_more_dual_steps(monkeypatch):
    """The second solve ends and the stop comes at that moment (no step beside either
    solve): the LP returns that round's solution without the steps that would top the
    first round's walk up to ``MIN_STEPS`` (seconds on a large ground, of a stopped
    run's 5), where unstopped it takes them."""
    real_run = bound._run
    stop = threading.Event()
    solves = itertools.count(1)
    taken = []
    real_value = bound.DualPolish.value

    def value(self, pi, sigma):
        taken.append(stop.is_set())
        return real_value(self, pi, sigma)

    def run(h, given=None, beside=None):
        solved = yield from real_run(h, None, None)
        if given is stop and next(solves) == 2:
            stop.set()
        return solved

    monkeypatch.setattr(bound, "_run", run)
    monkeypatch.setattr(bound.DualPolish, "value", value)
    sol, reports = _part0(stop=stop, integral=False)
    assert sol.rounds == 2 and len(reports) == 2 and not sol.complete
    assert taken == []  # no step at all: the stop came before the first top-up
    _part0(stop=threading.Event(), integral=False)  # the same LP, never stopped
    assert len(taken) >= bound.DualPolish.MIN_STEPS


# Three sites around three points, each seeing two: the LP opens each by half (1.5),
# the MILP two.
TRIANGLE = instance([[0, 1], [1, 2], [0, 2]], 3, 3)


def test_the_fewest_masts_lp_alone_rounds_its_value_up():
    sol = drain(site_cover(TRIANGLE, np.arange(3), 3, milp=False))
    assert sol.bound == 2 and len(sol.sites) == 0 and sol.lp_sites.tolist() == [0, 1, 2]
    # Whole values stay: one site that sees all, 1; two that each see one point, 2;
    # and a site that stands costs 0.
    one = instance([[0, 1, 2]], 3, 3)
    assert drain(site_cover(one, np.zeros(1, np.int64), 1, milp=False)).bound == 1
    two = instance([[0], [1]], 2, 2)
    assert drain(site_cover(two, np.arange(2), 2, milp=False)).bound == 2
    standing = np.array([True])
    sol = drain(site_cover(one, np.zeros(1, np.int64), 1, milp=False, standing=standing))
    assert sol.bound == 0


def test_the_fewest_masts_stopped_keep_what_they_proved(monkeypatch):
    """A stop before the start: nothing proven, no site. A stop during the MILP: the
    LP's bound rounded up and its sites, no MILP set."""
    stop = threading.Event()
    _cut_short(monkeypatch, lambda i, given: given is stop)
    sol = drain(site_cover(TRIANGLE, np.arange(3), 3, stop=stop))
    assert sol.bound == 0 and len(sol.sites) == 0 and len(sol.lp_sites) == 0
    monkeypatch.undo()
    _cut_short(monkeypatch, lambda i, given: i == 2 and given is stop)
    sol = drain(site_cover(TRIANGLE, np.arange(3), 3, stop=stop))
    assert sol.bound == 2 and len(sol.sites) == 0 and sol.lp_sites.tolist() == [0, 1, 2]


def test_a_point_halfway_covered_counts_no_mast():
    """Points 0 and 1, each needed twice, the goal one of them; three sites each see
    both with one candidate. One site brings both halfway, which counts nothing: two
    masts, as for a whole point."""
    inst = CoverInstance(instance([[0, 1]] * 3, 2, 1).matrix, 1, need=np.full(2, 2, np.int32))
    sol = drain(site_cover(inst, np.arange(3), 3))
    assert sol.bound == 2 and len(sol.sites) == 2


def test_the_fewest_masts_solves_stop_at_the_deadline(monkeypatch):
    """Both models, the LP's and the MILP's, get the time left to the deadline."""
    made = []
    new_highs = bound._new_highs
    monkeypatch.setattr(bound, "_new_highs", lambda limit: made.append(limit) or new_highs(limit))
    sol = drain(site_cover(TRIANGLE, np.arange(3), 3, deadline=time.perf_counter() + 30.0))
    assert sol.bound == 2 and len(made) == 2
    assert all(25.0 < limit <= 30.0 for limit in made)


@pytest.mark.parametrize(
    ("value", "want"), [(2.0, 2), (2.0 - 5e-7, 2), (1.5, 2), (2.01, 3), (-0.5, 0), (0.0, 0)]
)
def test_the_integer_bound_is_the_next_whole_number(value, want):
    """A bound lowered against the solver's tolerances (up to 1e-6 under a whole number)
    still proves that number; never below 0."""
    lp = bound.LPSolution(3.0, value, np.zeros(0, np.int64), np.zeros(0), np.zeros(0),
                          np.zeros(0), 1, False)  # fmt: skip
    assert lp.integer_bound() == want


def test_the_mast_aware_milp_stopped_before_the_start_keeps_the_start(monkeypatch):
    """The cap case above at two per mast, stopped before HiGHS starts: the plan is
    the start (23), not the optimum (22) that a finished solve returns."""
    rows = [[0], [0, 1], [1], [2, 3], [2], [3]]
    site_of = np.array([0, 1, 0, 2, 0, 0])
    inst = CoverInstance(instance(rows, 4, 4).matrix, 4, site_of=site_of, cap=2)
    stop = threading.Event()
    _cut_short(monkeypatch, lambda i, given: given is stop)
    got = drain(sensors_on_sites(inst, site_of, np.arange(3), [0, 2, 3], 10.0, 1.0, stop=stop))
    assert got == [0, 2, 3]


def test_an_lp_of_goal_0_claims_nothing_for_other_goals():
    """Nothing to cover costs 0, and no round's duals prove more than 0 for it: the
    line keeps claiming nothing (0 g - 0), below part 0's LP at every goal."""
    gen = cover_lp(instance(ROWS[:4], 3, 0), COST[:4], np.arange(4), np.zeros(0, np.int64),
                   integral=False)  # fmt: skip
    sol = drain(gen)
    assert sol.value == pytest.approx(0.0, abs=1e-9) and sol.bound <= 1e-9
    for goal, value in ((1, 0.1), (2, 0.6), (3, 1.1)):
        assert sol.slope * goal - sol.intercept <= value


@pytest.mark.parametrize("need", [1, 2])
@pytest.mark.parametrize("seed", range(8))
def test_every_rounds_bound_stays_below_the_lp(seed, need):
    """Random instances with candidates as cheap as 0.05 (priced above their cost
    early on), one joining per round: every round's bound, Farley's or the
    Lagrangian's, is at most the LP's value, which the last round reaches; with each
    point needed twice too."""
    rng = np.random.default_rng(900 + seed)
    inst = random_instance(rng, n_cand=14, n_points=30)
    inst = CoverInstance(inst.matrix, inst.goal, need=np.full(30, need, np.int32))
    cost = rng.uniform(0.05, 2.0, 14)
    whole = drain(cover_lp(inst, cost, np.arange(14), np.zeros(0, np.int64), integral=False))
    assert whole.complete
    gen = cover_lp(inst, cost, np.arange(14), np.zeros(0, np.int64), per_round=1, integral=False)
    sol, yielded = steps(gen)
    reports = [r for r in yielded if r is not None]
    assert len(reports) > 2
    assert all(r.bound <= whole.value + 1e-9 for r in reports)
    assert sol.value == pytest.approx(whole.value, rel=1e-6)
    # the final bound is the value lowered by 1e-6 relative and 1e-6 absolute
    assert sol.bound == pytest.approx(whole.value, rel=1e-5, abs=2e-6)


def random_needing(rng, n_cand, n_points, need):
    """``random_instance`` with every point needed ``need`` times, its goal at most
    the points that enough candidates see."""
    inst = random_instance(rng, n_cand=n_cand, n_points=n_points)
    seen = np.bincount(inst.matrix.indices, minlength=n_points)
    goal = min(inst.goal, int(np.count_nonzero(seen >= need)))
    return CoverInstance(inst.matrix, goal, need=np.full(n_points, need, np.int32))


def full_lp(inst, cost):
    """The cover LP with every candidate at once, by scipy's linprog (HiGHS, no column
    generation): min cost x s.t. M^T x >= k u, sum u >= goal, 0 <= u <= 1, x >= 0
    (x <= 1 with k > 1)."""
    n_cand, n = inst.matrix.shape
    a_points = sparse.hstack([-inst.matrix.T, sparse.diags(inst.k.astype(float))])
    a_goal = sparse.hstack([sparse.csr_matrix((1, n_cand)), -np.ones((1, n))])
    res = linprog(
        np.concatenate([cost, np.zeros(n)]),
        A_ub=sparse.vstack([a_points, a_goal]).tocsr(),
        b_ub=np.concatenate([np.zeros(n), [-inst.goal]]),
        bounds=[(0, 1 if inst.multi else None)] * n_cand + [(0, 1)] * n,
    )
    assert res.status == 0
    return res.fun


@pytest.mark.parametrize("need", [1, 2])
@pytest.mark.parametrize("seed", range(6))
def test_the_lp_with_candidates_dearer_than_one_is_the_full_lp(seed, need):
    """Candidates costing 0.5 to 5 (models of different prices): column generation
    ends at the LP over every candidate, solved at once, and never leaves demand to
    its artificial column, however cheaper than a candidate that would be."""
    rng = np.random.default_rng(1300 + seed)
    inst = random_needing(rng, 14, 30, need)
    cost = rng.uniform(0.5, 5.0, 14)
    sol = drain(cover_lp(inst, cost, np.arange(14), np.zeros(0, np.int64), integral=False))
    assert sol.complete and sol.value == pytest.approx(full_lp(inst, cost), rel=1e-6)
    assert sol.bound <= sol.value and sol.bound == pytest.approx(sol.value, rel=1e-5, abs=2e-6)


def test_at_k2_the_point_duals_value_less_the_candidates_excess_is_the_lp():
    """Every point of part 0 twice (a = b = c = 1, the LP 3): the LP's value is its
    point duals' value less what the x <= 1 bounds' duals take, sum_c max(0, priced -
    cost), by LP duality; ``mast_aware_bound`` scales the former."""
    inst = CoverInstance(instance(ROWS[:4], 3, 3).matrix, 3, need=np.full(3, 2, np.int32))
    sol = drain(cover_lp(inst, COST[:4], np.arange(4), np.zeros(0, np.int64), integral=False))
    assert sol.complete and sol.value == pytest.approx(3.0)
    excess = np.maximum(0.0, sol.priced - COST[:4]).sum()
    assert sol.dual - excess == pytest.approx(3.0, abs=1e-6)
    assert sol.dual > 3.0 + 1e-3  # the bounds' duals take a share here


def test_best_scale_by_hand():
    """Priced (2, 1) at costs (1, 1): breaks at t = 1/2 and 1. The duals' value 2.5
    past both (cumulative priced 2, 3): the peak at t = 1, paying 2 - 1. Worth 5, more
    than all the priced together: the slope stays positive, the last break, 1, paying
    1. Worth 0 or less, or nothing priced: t = 0, nothing paid."""
    matrix = instance([[0, 1], [1]], 2, 2).matrix
    duals = np.array([1.0, 1.0])
    priced = np.array([2.0, 1.0])
    cost = np.ones(2)
    assert bound.best_scale(2.5, priced, cost, matrix, duals) == pytest.approx((1.0, 1.0))
    assert bound.best_scale(5.0, priced, cost, matrix, duals) == pytest.approx((1.0, 1.0))
    # priced 1 and 2 at cost 1: breaks 1 and 1/2; at total 5 the last break is t = 1
    swapped = instance([[0], [0, 1]], 2, 2).matrix
    got = bound.best_scale(5.0, np.array([1.0, 2.0]), cost, swapped, duals)
    assert got == pytest.approx((1.0, 1.0))
    for total in (0.0, -1.0):
        assert bound.best_scale(total, priced, cost, matrix, duals) == (0.0, 0.0)
    assert bound.best_scale(2.5, np.zeros(2), cost, matrix, np.zeros(2)) == (0.0, 0.0)


class SlowHighs:
    """Stands for HiGHS on a long solve in ``bound._run``: ``run`` works until
    ``cancelSolve`` is called (and ``notices``), at most ``work_s`` seconds."""

    def __init__(self, work_s, notices=True):
        self.work_s = work_s
        self.notices = notices
        self.cancelled = threading.Event()
        self.cancels = 0
        self.runs = 0

    def run(self):
        self.runs += 1
        if self.notices:
            self.cancelled.wait(self.work_s)
        else:
            time.sleep(self.work_s)

    def cancelSolve(self):  # noqa: N802 (HiGHS' name)
        self.cancels += 1
        self.cancelled.set()


def test_a_solve_runs_to_its_end_yielding_while_it_works():
    """0.3 s of work, polled every 0.05 s: yields meanwhile, never cancels."""
    h = SlowHighs(0.3)
    finished, yields = steps(bound._run(h, threading.Event()))
    assert finished is bound.Solve.DONE and h.cancels == 0 and len(yields) >= 2


def stop_after(stop, seconds):
    threading.Timer(seconds, stop.set).start()


def test_a_stop_cancels_the_solve_once():
    h = SlowHighs(5.0)
    stop = threading.Event()
    stop_after(stop, 0.2)
    start = time.perf_counter()
    finished, _ = steps(bound._run(h, stop))
    assert finished is bound.Solve.STOPPED and h.cancels == 1
    assert time.perf_counter() - start < 1.0


def test_a_stopped_run_starts_no_solve():
    h = SlowHighs(5.0)
    stop = threading.Event()
    stop.set()
    finished, yields = steps(bound._run(h, stop))
    assert finished is bound.Solve.GONE and yields == []
    time.sleep(0.1)
    assert h.runs == 0 and h.cancels == 0


def test_a_solve_slow_to_notice_a_cancel_is_left_to_end_alone():
    """HiGHS notices a cancel only between its own steps: the run goes on after
    ``CANCEL_WAIT_S`` and must not read the model (GONE)."""
    h = SlowHighs(2.0, notices=False)
    stop = threading.Event()
    stop_after(stop, 0.2)
    start = time.perf_counter()
    finished, _ = steps(bound._run(h, stop))
    took = time.perf_counter() - start
    assert finished is bound.Solve.GONE and h.cancels == 1
    assert 0.2 + bound.CANCEL_WAIT_S - 0.05 < took < 1.2


def test_closing_the_wait_cancels_the_solve():
    """A caller that drops the generator (the Blender operator cancelled) stops
    HiGHS at once instead of waiting for it."""
    h = SlowHighs(5.0)
    gen = bound._run(h)
    start = time.perf_counter()
    next(gen)
    gen.close()
    assert h.cancels == 1 and time.perf_counter() - start < 2.0


def _no_duals(monkeypatch):
    """Replace ``bound._run``: each solve ends at once with no solution, as HiGHS does
    when its time limit (the deadline gone) comes before it has any duals."""

    def run(h, stop=None, beside=None):
        return bound.Solve.DONE
        yield  # a generator, like the real one

    monkeypatch.setattr(bound, "_run", run)


@pytest.mark.parametrize("seed", range(6))
def test_an_lp_with_no_duals_still_proves_a_line_when_asked(monkeypatch, seed):
    """The first solve ends with no duals: by default the LP proves nothing (a line of
    0); with ``line_anyway`` its dual steps from nothing, towards the greedy cover's
    cost (the initial columns, as a part starts), prove a line that holds at every
    goal (below the full LP by linprog at each) and is above 0 at its own."""
    rng = np.random.default_rng(seed)
    inst = random_instance(rng)
    cost = rng.uniform(0.5, 2.0, inst.matrix.shape[0])
    group = np.arange(inst.matrix.shape[0])
    every = np.arange(inst.matrix.shape[0], dtype=np.int64)
    greedy = np.array(complete(Cover(inst), every, sensor_cost=cost).chosen, np.int64)
    _no_duals(monkeypatch)
    plain = drain(bound.cover_lp(inst, cost, group, greedy))
    assert (plain.slope, plain.intercept, plain.bound) == (0.0, 0.0, 0.0)
    sol = drain(bound.cover_lp(inst, cost, group, greedy, line_anyway=True))
    assert sol.slope * inst.goal - sol.intercept > 0.0
    assert sol.bound == pytest.approx(sol.slope * inst.goal - sol.intercept)
    reach = len(np.unique(inst.matrix.indices))
    for goal in range(1, reach + 1):
        at = CoverInstance(inst.matrix, goal, inst.xy, need=inst.k)
        assert sol.slope * goal - sol.intercept <= full_lp(at, cost) + 1e-9


def random_lp(n=1500, seed=0):
    """A HiGHS model of min c x, A x >= 1, x >= 0 (n x n, 2 % dense): 0.1-0.5 s to solve."""
    import highspy

    rng = np.random.default_rng(seed)
    a = sparse.random(n, n, density=0.02, random_state=seed, format="csr")
    h = bound._new_highs(None)
    h.addVars(n, np.zeros(n), np.full(n, highspy.kHighsInf))
    h.changeColsCost(n, np.arange(n, dtype=np.int32), rng.random(n) + 0.1)
    h.addRows(n, np.ones(n), np.full(n, highspy.kHighsInf), a.nnz,
              a.indptr[:-1].astype(np.int32), a.indices.astype(np.int32), a.data)  # fmt: skip
    return h


def test_highs_holds_its_time_limit_against_every_run_so_far():
    """Why ``limit_to`` adds the run time: a limit under the time the model has run
    already ends the next solve, started from nothing, before its end."""
    import highspy

    h = random_lp()
    h.run()
    assert h.getModelStatus() == highspy.HighsModelStatus.kOptimal
    h.clearSolver()
    h.setOptionValue("time_limit", 0.5 * h.getRunTime())
    h.run()
    assert h.getModelStatus() == highspy.HighsModelStatus.kTimeLimit


class ClockedHighs:
    """Stands for a HiGHS model that has run ``ran_s`` seconds: records its time limit."""

    def __init__(self, ran_s):
        self.ran_s, self.limit = ran_s, None

    def getRunTime(self):  # noqa: N802 (HiGHS' name)
        return self.ran_s

    def setOptionValue(self, name, value):  # noqa: N802
        assert name == "time_limit"
        self.limit = value


@pytest.mark.parametrize("ran_s", [0.0, 100.0])
def test_limit_to_gives_the_next_run_the_time_left(ran_s):
    h = ClockedHighs(ran_s)
    before = time.perf_counter()
    bound.limit_to(h, before + 5.0)
    assert ran_s + 5.0 - (time.perf_counter() - before) <= h.limit <= ran_s + 5.0
    bound.limit_to(h, before - 1.0)  # past: the least limit HiGHS takes, not a negative one
    assert h.limit == pytest.approx(ran_s + 0.01)


def test_a_steep_tangent_gets_lines_at_the_goals_below_that_hold_there():
    """Candidate 0 covers points 0-15; points 16-19 each have a candidate of their
    own (cost 1 each). At goal 19 the LP is 4 (candidate 0 and three of the four), its
    goal dual 1: the tangent 1 g - 15 says nothing below 15 points, where the LP is
    g / 16 (candidate 0 in part). The lines asked at 12 and 8 prove 12/16 and 8/16
    there, and hold at every goal (linprog over every candidate, goals 1-20)."""
    rows = [list(range(16)), [16], [17], [18], [19]]
    inst = instance(rows, 20, 19)
    cost = np.ones(5)
    sol = drain(
        cover_lp(inst, cost, np.arange(5), np.array([0]), integral=False, also_at=(12, 8))
    )
    assert sol.value == pytest.approx(4.0)
    assert sol.slope == pytest.approx(1.0, rel=1e-5)
    assert sol.slope * 12 - sol.intercept < 0  # the tangent proves nothing at 12
    assert len(sol.more_lines) == 2 and len(sol.more_pi) == 2
    for goal, (a, b) in zip((12, 8), sol.more_lines):
        assert a * goal - b == pytest.approx(goal / 16, abs=1e-5)
    for g in range(1, 21):
        exact = full_lp(CoverInstance(inst.matrix, g), cost)
        assert all(a * g - b <= exact + 1e-9 for a, b in sol.more_lines)
    # A shallow tangent (every point as dear) seeks none: 20 points, one candidate each.
    flat = instance([[p] for p in range(20)], 20, 19)
    plain = drain(
        cover_lp(flat, np.ones(20), np.arange(20), np.array([0]), integral=False, also_at=(18,))
    )
    assert plain.value == pytest.approx(19.0) and plain.more_lines == ()
