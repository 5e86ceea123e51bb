"""Lower bounds and the lp optimizer: known optima on hand-made cases, bounds never
above brute force, cover moves that keep the goal."""

import itertools
import time
from dataclasses import replace

import numpy as np
import pytest
import shapely
from scipy import sparse

from autoscoop_blender.core.model.sensors import PAPER_CAMERA
from autoscoop_blender.core.optimize import lp as lp_module
from autoscoop_blender.core.optimize.bound import (
    LPProgress,
    best_scale,
    combined_bound,
    cover_lp,
    mast_aware_bound,
    parts_of,
    sensors_on_sites,
    site_cover,
    split_cover_lp,
)
from autoscoop_blender.core.optimize.cover import (
    Cover,
    CoverInstance,
    close_sites,
    complete,
    improve,
    prune,
    swap_two_for_one,
)
from autoscoop_blender.core.run import Run
from autoscoop_blender.core.settings import OptimizeSettings
from tests.core.flat import areas_scene, box_caster

LP = OptimizeSettings(optimizer="lp", rho=0.9)


def steps(gen):
    """Run a generator to its end: (its return value, what it yielded, in order)."""
    yielded = []
    while True:
        try:
            yielded.append(next(gen))
        except StopIteration as done:
            return done.value, yielded


def drain(gen):
    """Run a generator to its end; its return value."""
    return steps(gen)[0]


def instance(rows, n_points, goal):
    """A cover instance from lists of covered points per candidate."""
    indptr = np.cumsum([0, *map(len, rows)])
    indices = np.concatenate([np.asarray(r, dtype=np.int64) for r in rows])
    m = sparse.csr_matrix(
        (np.ones(len(indices), np.float32), indices, indptr), (len(rows), n_points)
    )
    return CoverInstance(m, goal)


def brute_force(inst, group=None):
    """The fewest candidates (or groups of them) covering the goal, by enumeration."""
    units = range(inst.matrix.shape[0]) if group is None else range(group.max() + 1)
    for k in range(len(units) + 1):
        for pick in itertools.combinations(units, k):
            cols = pick if group is None else np.flatnonzero(np.isin(group, pick))
            covered = np.zeros(inst.n_points, bool)
            for c in cols:
                covered[inst.covers(c)] = True
            if covered.sum() >= inst.goal:
                return k
    return None


def random_instance(rng, n_cand=10, n_points=24):
    rows = [rng.choice(n_points, size=rng.integers(2, 9), replace=False) for _ in range(n_cand)]
    covered = np.unique(np.concatenate(rows))
    goal = int(rng.integers(1, len(covered) + 1))
    return instance(rows, n_points, goal)


@pytest.mark.parametrize("seed", range(12))
def test_bounds_never_exceed_the_brute_force_optimum(seed):
    rng = np.random.default_rng(seed)
    inst = random_instance(rng)
    group = rng.integers(0, 4, inst.matrix.shape[0])
    group[:4] = np.arange(4)  # every site has a candidate
    best = brute_force(inst)
    ones = np.ones(inst.matrix.shape[0])
    lp = drain(cover_lp(inst, ones, group, np.arange(1), integral=False))
    assert lp.complete and lp.integer_bound() <= best
    assert lp.value - 1e-5 <= lp.bound <= lp.value  # solved to the end: bound = value
    # Stopped as soon as the integer bound is final: the same integer bound.
    early = drain(cover_lp(inst, ones, group, np.arange(1)))
    assert early.integer_bound() == lp.integer_bound() and early.rounds <= lp.rounds
    sites = drain(site_cover(inst, group, 4))
    assert sites.bound == brute_force(inst, group) == len(sites.sites)
    # A greedy plan, improved, is feasible and no better than the optimum.
    every = np.arange(inst.matrix.shape[0])
    cover = improve(complete(Cover(inst), every), every)
    assert cover.slack >= 0 and len(cover.chosen) >= best


def test_the_fewest_masts_lp_alone_bounds_them():
    """Without the MILP the masts bound is the LP's rounded up: three candidates at
    three sites, each covering two of three points, goal 3: the LP takes each at
    1/2 (1.5), so at least 2 masts; no set is found."""
    inst = instance([[0, 1], [1, 2], [0, 2]], 3, 3)
    group = np.arange(3)
    lp_only = drain(site_cover(inst, group, 3, milp=False))
    assert lp_only.bound == 2 and len(lp_only.sites) == 0
    assert sorted(lp_only.lp_sites) == [0, 1, 2]
    full = drain(site_cover(inst, group, 3))
    assert full.bound == 2 == len(full.sites)


def test_parts_are_compact_and_even():
    """Two clusters 1 km apart split into two parts, one each; four parts of a long
    strip are four runs of consecutive points, 25 each."""
    rng = np.random.default_rng(3)
    xy = np.vstack([rng.uniform(0, 10, (30, 2)), rng.uniform(0, 10, (30, 2)) + [1000, 0]])
    part = parts_of(xy, 2)
    assert set(part[:30]) == {part[0]} and set(part[30:]) == {part[30]} and part[0] != part[30]
    strip = np.column_stack([np.arange(100.0), np.zeros(100)])
    part = parts_of(strip, 4)
    assert np.bincount(part).tolist() == [25] * 4
    assert np.all(np.diff(part) >= 0)  # consecutive runs along x


def test_combined_bound_is_the_best_split_of_the_goal():
    """Two parts with value lines g - 2 and 2 g (5 points each), goal 6: the best
    split gives part 0 five points (5 - 2 = 3) and part 1 one (2): 5. With an
    unsolved part (line 0) that can cover the goal alone, nothing is proven."""
    lines, coverable = [(1.0, 2.0), (2.0, 0.0)], [5, 5]
    by_hand = min(max(0.0, g - 2.0) + max(0.0, 2.0 * (6 - g)) for g in np.linspace(1, 5, 401))
    assert combined_bound(lines, coverable, 6) == pytest.approx(5.0) == pytest.approx(by_hand)
    assert combined_bound([(1.0, 2.0), (0.0, 0.0)], [5, 6], 6) == 0.0


@pytest.mark.parametrize("seed", range(8))
def test_the_lp_in_parts_bounds_the_whole(seed):
    """Solved in two parts (candidates seeing both shared out by their points), the
    bound never exceeds the whole LP's value (so never the optimum); on two equal
    halves no candidate spans, it is the whole LP's value."""
    rng = np.random.default_rng(200 + seed)
    inst = random_instance(rng, n_cand=14, n_points=24)
    xy = np.column_stack([np.arange(24.0), np.zeros(24)])
    inst = CoverInstance(inst.matrix, inst.goal, xy)
    ones, group = np.ones(14), np.arange(14)
    whole = drain(cover_lp(inst, ones, group, np.arange(1), integral=False))
    split = drain(split_cover_lp(inst, ones, group, np.arange(1), parts_of(xy, 2), rel_gap=0))
    assert split.parts == 2 and 0 <= split.bound <= whole.value + 1e-6
    assert split.bound <= brute_force(inst) + 1e-6
    # Two copies of one instance, side by side, goal doubled, each half started alike
    # (the same duals, so the same line: a half's LP may have a kink at its goal, where
    # halves started apart can return different tangents, whose best split is lower).
    half = random_instance(rng, n_cand=8, n_points=12)
    m = sparse.block_diag([half.matrix, half.matrix]).tocsr()
    xy2 = np.column_stack([np.arange(24.0), np.zeros(24)])
    twice = CoverInstance(m, 2 * half.goal, xy2)
    ones2, group2, start2 = np.ones(16), np.arange(16), np.array([0, 8])
    whole2 = drain(cover_lp(twice, ones2, group2, start2, integral=False))
    split2 = drain(split_cover_lp(twice, ones2, group2, start2, parts_of(xy2, 2), rel_gap=0))
    assert split2.bound == pytest.approx(whole2.value, rel=1e-4)


def cheapest(inst, group, mast_cost, sensor_cost, sites=None):
    """The least mast_cost x masts + sensor_cost x sensors of any plan (on ``sites``
    only, if given), by enumeration of all candidate subsets."""
    allowed = np.arange(inst.matrix.shape[0])
    if sites is not None:
        allowed = allowed[np.isin(group[allowed], sites)]
    best = np.inf
    for k in range(len(allowed) + 1):
        for pick in itertools.combinations(allowed, k):
            covered = np.zeros(inst.n_points, bool)
            for c in pick:
                covered[inst.covers(c)] = True
            if covered.sum() >= inst.goal:
                cost = mast_cost * len(set(group[list(pick)])) + sensor_cost * k
                best = min(best, cost)
    return best


@pytest.mark.parametrize("seed", range(8))
@pytest.mark.parametrize("mast_cost", [0.5, 3.0])
def test_mast_aware_bound_and_milp_against_brute_force(seed, mast_cost):
    """The mast-aware bound never exceeds the cheapest plan; the mast-aware MILP on a
    set of sites finds the cheapest plan on them, from a worse start."""
    rng = np.random.default_rng(100 + seed)
    inst = random_instance(rng, n_cand=12, n_points=20)
    group = rng.integers(0, 4, inst.matrix.shape[0])
    group[:4] = np.arange(4)
    ones = np.ones(inst.matrix.shape[0])
    lp = drain(cover_lp(inst, ones, group, np.arange(1), integral=False))
    best = cheapest(inst, group, mast_cost, 1.0)
    # Scaled from the sensors LP's duals: at least the LP (mast cost > 0), never
    # above the optimum.
    cost_lp = mast_aware_bound(lp, group, mast_cost, 1.0)
    assert lp.value - 1e-4 <= cost_lp <= best + 1e-9
    sites = np.array([0, 1, 2, 3])
    start = list(range(inst.matrix.shape[0]))  # every candidate: feasible, expensive
    plan = drain(sensors_on_sites(inst, group, sites, start, mast_cost, 1.0))
    covered = np.zeros(inst.n_points, bool)
    for c in plan:
        covered[inst.covers(c)] = True
    assert covered.sum() >= inst.goal
    cost = mast_cost * len(set(group[plan])) + len(plan)
    assert cost == pytest.approx(best)
    # Restricted to two sites: the cheapest plan on them (or the start, if none).
    two = np.array([0, 1])
    on_two = cheapest(inst, group, mast_cost, 1.0, two)
    if np.isfinite(on_two):
        start2 = list(np.flatnonzero(np.isin(group, two)))
        plan2 = drain(sensors_on_sites(inst, group, two, start2, mast_cost, 1.0))
        assert set(group[plan2]) <= {0, 1}
        assert mast_cost * len(set(group[plan2])) + len(plan2) == pytest.approx(on_two)


def test_mast_aware_bound_beats_the_sensors_lp_when_masts_are_dear():
    """Two points, each seen by one candidate at its own site: any plan pays two masts
    and two sensors. The sensors LP is 2; scaled with mast cost 3 the bound is 8."""
    inst = instance([[0], [1]], 2, 2)
    group = np.array([0, 1])
    lp = drain(cover_lp(inst, np.ones(2), group, np.arange(1), integral=False))
    assert lp.value == pytest.approx(2.0)
    assert mast_aware_bound(lp, group, 3.0, 1.0) == pytest.approx(8.0, rel=1e-5)


@pytest.mark.parametrize("seed", range(8))
def test_any_duals_at_their_best_scale_bound_the_lp(seed):
    """Duals that are not the LP's (random, >= 0), scaled by ``best_scale``'s t, stay
    below the LP's value, and above the bound at any other scale: Farley's (where no
    candidate pays), 1 (the plain Lagrangian) and a grid, up to the float32 prices'
    round-off in where the peak is; what the candidates pay is the exact sum."""
    rng = np.random.default_rng(400 + seed)
    inst = random_instance(rng, n_cand=12, n_points=20)
    cost = rng.uniform(0.5, 2.0, 12)
    lp = drain(cover_lp(inst, cost, np.arange(12), np.arange(1), integral=False))
    sigma = rng.uniform(0.2, 1.0)
    duals = sigma * rng.uniform(0.5, 1.5, 20)
    total = inst.goal * sigma - float(np.maximum(0.0, sigma - duals).sum())
    priced = np.asarray(inst.matrix @ duals.astype(np.float32), dtype=float)
    t, paid = best_scale(total, priced, cost, inst.matrix, duals)
    exact = inst.matrix @ duals
    assert paid == pytest.approx(np.maximum(0.0, t * exact - cost).sum(), abs=1e-12)
    assert t * total - paid <= lp.value + 1e-9
    farley = min(1.0, float(np.min(cost[exact > 0] / exact[exact > 0])))
    for s in [farley, 1.0, *np.linspace(0.0, 3.0, 61)]:
        assert t * total - paid >= s * total - np.maximum(0.0, s * exact - cost).sum() - 1e-6


def test_an_early_stop_keeps_a_proven_bound():
    """Stopped before the LP is complete, the bound is still below the optimum."""
    rng = np.random.default_rng(7)
    inst = random_instance(rng, n_cand=14, n_points=30)
    best = brute_force(inst)
    group = np.arange(inst.matrix.shape[0])
    lp = drain(cover_lp(inst, np.ones(len(group)), group, np.arange(1), per_round=1, deadline=0.0))
    assert not lp.complete and lp.rounds == 1
    assert lp.bound <= lp.integer_bound() <= best


def test_cover_moves_keep_the_goal():
    # Points 0-9. Chosen 0, 1, 2, 4: 0 = {0-4} is redundant (4 covers 0-2, 2 covers
    # 3-4), and so are 2 and 4 on their own; 1 alone covers 7, 8, 9.
    rows = [range(0, 5), range(5, 10), range(3, 7), range(0, 10), range(0, 3)]
    inst = instance(rows, 10, 10)
    cover = Cover(inst, (0, 1, 2, 4))
    assert cover.slack == 0 and [cover.exclusive(c) for c in (0, 1, 2, 4)] == [0, 3, 0, 0]
    prune(cover)  # drops 0 (the first that loses nothing); then each loses points
    assert sorted(cover.chosen) == [1, 2, 4] and cover.slack == 0
    # 1 and 2 alone cover 3-9 (7 points): candidate 3 covers them all.
    assert swap_two_for_one(cover, np.arange(5))
    assert cover.chosen == [4, 3] and cover.slack == 0
    prune(cover)
    assert cover.chosen == [3]
    # With a goal of 8, without candidate 3: no single candidate covers 8 points, and
    # 0 + 2 or 1 + 2 cover 7; 0 + 1 or 1 + 4 cover enough.
    inst8 = instance(rows, 10, 8)
    cover = improve(complete(Cover(inst8), np.array([0, 1, 2, 4])), np.array([0, 1, 2, 4]))
    assert cover.slack >= 0 and len(cover.chosen) == 2


def test_greedy_per_cost_and_closing_masts():
    """Points 0-11. Site 0 holds candidates 0-2 (4 points each, together all 12);
    site 1 holds candidate 3 (points 0-5), site 2 candidate 4 (points 6-11).
    From candidate 0 (site 0 in use), plain greedy takes candidate 4 (6 new points)
    and then 1: two masts, cost 2 x 3 + 3 = 9. Per cost, with a mast at 3, candidates
    1 and 2 (4 new points for 1 each, on the mast in use) beat candidate 4 (6 for 4):
    one mast, cost 3 + 3 = 6."""
    rows = [range(0, 4), range(4, 8), range(8, 12), range(0, 6), range(6, 12)]
    inst = instance(rows, 12, 12)
    site_of = np.array([0, 0, 0, 1, 2])
    every = np.arange(5)
    assert complete(Cover(inst, (0,)), every).chosen == [0, 4, 1]
    by_cost = complete(Cover(inst, (0,)), every, site_of, mast_cost=3.0, sensor_cost=1.0)
    assert by_cost.chosen == [0, 1, 2]
    # From a plan on all three sites (cost 14): closing sites 1 and 2 (re-covering
    # from the masts left) leaves site 0's three (cost 6); site 0 cannot close.
    spread = Cover(inst, (0, 1, 2, 3, 4))
    closed = close_sites(spread, site_of, 3.0, 1.0)
    assert sorted(closed.chosen) == [0, 1, 2] and closed.slack == 0
    # With cheap masts, nothing is worth closing from the two-mast plan.
    assert sorted(close_sites(Cover(inst, (3, 4)), site_of, 0.5, 1.0).chosen) == [3, 4]


# --- the cover moves on instances small enough to follow by hand -------------------


def test_counts_go_back_down_when_a_candidate_leaves():
    inst = instance([range(0, 5), range(3, 8)], 8, 8)
    cover = Cover(inst, (0, 1))
    assert cover.n_covered == 8 and cover.count.tolist() == [1, 1, 1, 2, 2, 1, 1, 1]
    cover.remove(1)
    assert cover.count.tolist() == [1] * 5 + [0] * 3 and cover.n_covered == 5
    cover.remove(0)
    assert not cover.count.any() and cover.n_covered == 0 and cover.slack == -8


def test_greedy_stops_at_the_goal_and_when_nothing_adds():
    """Points 0-9: candidate 0 = {0-4}, 1 = {5-9}. A goal of 5 is met by 0 alone
    (candidate 1 would add 5 more, not wanted). Point 10 no candidate covers: goal 11
    is out of reach, so greedy stops after 0 and 1, with each once, and no candidate
    that adds nothing."""
    rows = [range(0, 5), range(5, 10), range(0, 3)]
    assert complete(Cover(instance(rows, 11, 5)), np.arange(3)).chosen == [0]
    short = complete(Cover(instance(rows, 11, 11), (0,)), np.arange(3))
    assert short.chosen == [0, 1] and short.slack == -1


def test_greedy_picks_by_the_gains_left():
    """0 = {0-5}, 1 = {0-4}, 2 = {6-8}: after 0, candidate 1 adds nothing (its five
    points are covered), 2 adds three: greedy takes 0 then 2."""
    inst = instance([range(0, 6), range(0, 5), range(6, 9)], 9, 9)
    assert complete(Cover(inst), np.arange(3)).chosen == [0, 2]


def test_greedy_with_k2_never_takes_a_candidate_twice():
    """Every k = 2; A = {0-9} is chosen. A would gain all ten points again, but a
    candidate counts once: C (9 points) then B (point 0)."""
    inst = CoverInstance(
        instance([range(10), [0], range(1, 10)], 10, 10).matrix, 10, need=np.full(10, 2, np.int32)
    )
    cover = complete(Cover(inst, (0,)), np.arange(3))
    assert cover.chosen == [0, 2, 1] and cover.slack == 0


def test_greedy_per_cost_depends_on_cost_ratios_and_mast_costs_per_site():
    """``test_greedy_per_cost_and_closing_masts``'s instance. Costs a tenth as large
    (mast 0.3, sensor 0.1) choose as mast 3, sensor 1: [0, 1, 2]. Without costs given,
    plain greedy: [0, 4, 1]. With a mast already at site 2 (cost 0 there, 3 at the
    others), candidate 4 costs one sensor for 6 new points: [0, 4, 1]; a cost of 3 at
    every site gives what the number 3 does."""
    rows = [range(0, 4), range(4, 8), range(8, 12), range(0, 6), range(6, 12)]
    inst = instance(rows, 12, 12)
    site_of = np.array([0, 0, 0, 1, 2])
    every = np.arange(5)
    assert complete(Cover(inst, (0,)), every, site_of, 0.3, 0.1).chosen == [0, 1, 2]
    assert complete(Cover(inst, (0,)), every, site_of).chosen == [0, 4, 1]
    there = np.array([3.0, 3.0, 0.0])
    assert complete(Cover(inst, (0,)), every, site_of, there, 1.0).chosen == [0, 4, 1]
    dear = np.full(3, 3.0)
    assert complete(Cover(inst, (0,)), every, site_of, dear, 1.0).chosen == [0, 1, 2]


def test_greedy_per_cost_prices_only_the_new_masts_site_down():
    """Points 0-13; site 0: 0 = {0-3}, 1 = {4-7}, 2 = {8-12}; site 1: 3 = {4-7, 13}.
    Mast 10, sensor 1, from 0: 2 (5 per 1), then 1 (4 per 1; 3 gives 5 per 11), then
    3 for point 13 alone. Taking a sensor on site 0 must not make site 1 cheap."""
    inst = instance([range(0, 4), range(4, 8), range(8, 13), [4, 5, 6, 7, 13]], 14, 14)
    site_of = np.array([0, 0, 0, 1])
    got = complete(Cover(inst, (0,)), np.arange(4), site_of, 10.0, 1.0)
    assert got.chosen == [0, 2, 1, 3]


def test_prune_drops_a_redundant_candidate_wherever_it_is():
    """``test_cover_moves_keep_the_goal``'s cover with the essential 1 listed first:
    0 still goes."""
    rows = [range(0, 5), range(5, 10), range(3, 7), range(0, 10), range(0, 3)]
    cover = prune(Cover(instance(rows, 10, 10), (1, 0, 2, 4)))
    assert cover.chosen == [1, 2, 4] and cover.slack == 0


def test_swap_drops_two_without_a_third_when_the_slack_allows():
    """0 = {0-4}, 1 = {5-9}, 2 = {0}, 3 = {5}: 2 and 3 alone cover nothing, so the
    pair goes for no candidate, the goal (10, slack 0; 9, slack 1) still met."""
    rows = [range(0, 5), range(5, 10), [0], [5]]
    for goal in (10, 9):
        cover = Cover(instance(rows, 10, goal), (0, 1, 2, 3))
        assert swap_two_for_one(cover, np.arange(4))
        assert cover.chosen == [0, 1] and cover.slack == 10 - goal


def test_swap_tries_the_pair_that_covers_least_alone_first():
    """0 = {0-4}, 1 = {5}, 2 = {6, 7}, 3 = {8, 9}, alone 5, 1, 2, 2; pool 4 = {0-5},
    5 = {5, 6, 7}. Both (0, 1) (six points, 4 brings them back) and (1, 2) (three, 5)
    could go; (1, 2) alone covers fewer, so it goes first."""
    rows = [range(0, 5), [5], [6, 7], [8, 9], range(0, 6), [5, 6, 7]]
    cover = Cover(instance(rows, 10, 10), (0, 1, 2, 3))
    assert swap_two_for_one(cover, np.array([4, 5]))
    assert cover.chosen == [0, 3, 5] and cover.slack == 0


def test_swap_never_breaks_the_goal():
    """0 = {0-4}, 1 = {5}, 2 = {5}, goal 6 of points 0-6: the pair (1, 2) loses point
    5, one more than the slack (0), and the pool (3 = {6}) brings nothing back;
    every other pair loses five: no swap."""
    cover = Cover(instance([range(0, 5), [5], [5], [6]], 7, 6), (0, 1, 2))
    assert not swap_two_for_one(cover, np.array([3]))
    assert cover.chosen == [0, 1, 2] and cover.slack == 0


def test_swap_with_k2_never_brings_back_a_chosen_candidate():
    """Every k = 2, points 0-3: A = {0-3}, B = {0, 1}, C = {2, 3} chosen, E = {0-3} in
    the pool. Dropping B and C leaves each point once; A would bring all four back,
    but A is chosen already (it would count twice): E replaces them."""
    rows = [range(4), [0, 1], [2, 3], range(4)]
    inst = CoverInstance(instance(rows, 4, 4).matrix, 4, need=np.full(4, 2, np.int32))
    cover = Cover(inst, (0, 1, 2))
    assert swap_two_for_one(cover, np.arange(4))
    assert cover.chosen == [0, 3] and cover.slack == 0 and cover.count.tolist() == [2] * 4
    # Every k = 2, points 0-1: A = B = {0}, C = D = {1}, all chosen, the pool only
    # them. Any pair leaves one point short by one or two; only a candidate not chosen
    # could bring it back (C counted again would "cover" point 1 three times): no swap.
    inst = CoverInstance(instance([[0], [0], [1], [1]], 2, 2).matrix, 2,
                         need=np.full(2, 2, np.int32))  # fmt: skip
    cover = Cover(inst, (0, 1, 2, 3))
    assert not swap_two_for_one(cover, np.arange(4))
    assert cover.chosen == [0, 1, 2, 3]


def test_improve_swaps_then_prunes_to_one():
    """``test_cover_moves_keep_the_goal``'s moves through ``improve``: [3]."""
    rows = [range(0, 5), range(5, 10), range(3, 7), range(0, 10), range(0, 3)]
    cover = improve(Cover(instance(rows, 10, 10), (0, 1, 2, 4)), np.arange(5))
    assert cover.chosen == [3]


def test_closing_a_site_must_lower_the_cost():
    """Points 0-5; site 0: 0 = {0-2}, 1 = {3, 4}, 2 = {5}; site 1: 3 = {3-5}. From
    (0, 3), closing site 1 gives (0, 1, 2): one mast and three sensors against two and
    two, cheaper when the mast costs more than a sensor (1.5 against 1), not when it
    costs less (0.5), and at a tie (1 and 1) the plan stays."""
    inst = instance([range(0, 3), [3, 4], [5], range(3, 6)], 6, 6)
    site_of = np.array([0, 0, 0, 1])
    for mast, want in ((1.5, [0, 1, 2]), (0.5, [0, 3]), (1.0, [0, 3])):
        got = close_sites(Cover(inst, (0, 3)), site_of, mast, 1.0)
        assert sorted(got.chosen) == want and got.slack == 0


def test_closing_a_site_starts_from_the_candidates_kept():
    """Points 0-14, all needed; rows R1 = {0-6} (site 0), R2 = {7-13} (site 1), r =
    {14} (site 2) chosen; site 0 also holds B1 = {0-3, 7-10}, B2 = {4, 5, 11, 12}, B3 =
    {6, 13} and site 1 R2x = {7-14}. Closing site 2 from R1 and R2 needs R2x alone
    (R2 then pruned): (R1, R2x), cost 4 against 6. Greedy from nothing would take B1,
    B2, B3 and R2x (their 8, 4, 2 and 1 new points), cost 6, and close nothing."""
    rows = [range(7), range(7, 14), [14], [0, 1, 2, 3, 7, 8, 9, 10], [4, 5, 11, 12], [6, 13],
            range(7, 15)]  # fmt: skip
    site_of = np.array([0, 1, 2, 0, 0, 0, 1])
    got = close_sites(Cover(instance(rows, 15, 15), (0, 1, 2)), site_of, 1.0, 1.0)
    assert sorted(got.chosen) == [0, 6] and got.slack == 0


def test_closing_sites_goes_on_while_a_pass_closes_one():
    """Points 0-8, all needed. Chosen: x = {0-3} (site 0), y1 = {4, 5}, y2 = {6, 7}
    (site 1), zb = {8} (site 2), cost 3 masts + 4 sensors = 7. Site 2 also holds z =
    {0, 1, 4-7}, w = {2, 3}, u = {0, 1, 2}, v = {3}. First pass: closing site 0 takes u
    then w (cost 7, no gain); site 2 cannot close; closing site 1 takes z (cost 5).
    Second pass: with z chosen, closing site 0 needs only w: cost 4, one mast."""
    rows = [range(4), [4, 5], [6, 7], [8], [0, 1, 4, 5, 6, 7], [2, 3], [0, 1, 2], [3]]
    site_of = np.array([0, 1, 1, 2, 2, 2, 2, 2])
    got = close_sites(Cover(instance(rows, 9, 9), (0, 1, 2, 3)), site_of, 1.0, 1.0)
    assert sorted(got.chosen) == [3, 4, 5]


def test_swap_with_k2_may_keep_one_of_the_pair():
    """Every k = 2, points 0-3: A = {0-3}, B = {0-3}, C = {0, 1} chosen (not pruned
    first), nothing else in the pool but them. The pair (A, C) goes first (2 + 0
    points only they hold to k): without both every point is left once, and A, a
    member of the pair, brings all four back, so the swap drops C alone."""
    rows = [range(4), range(4), [0, 1]]
    inst = CoverInstance(instance(rows, 4, 4).matrix, 4, need=np.full(4, 2, np.int32))
    cover = Cover(inst, (0, 1, 2))
    assert swap_two_for_one(cover, np.arange(3))
    assert sorted(cover.chosen) == [0, 1] and cover.count.tolist() == [2] * 4


def test_a_swap_must_cost_less_than_the_two():
    """a = {0}, b = {1} chosen at 1 each; d = {0, 1} in the pool. d replaces the pair
    when it costs less than their 2 (1.5), not at 2 or 2.5; with one point of slack
    (goal 1) the pair needs one point back and the dear d is still refused. Through
    ``improve`` too (pruning first changes nothing: each holds a point alone)."""
    rows = [[0], [1], [0, 1]]
    for d_cost, goal, swapped in ((1.5, 2, True), (2.0, 2, False), (2.5, 2, False),
                                  (2.5, 1, False)):  # fmt: skip
        cost = np.array([1.0, 1.0, d_cost])
        cover = Cover(instance(rows, 2, goal), (0, 1))
        assert swap_two_for_one(cover, np.array([2]), sensor_cost=cost) is swapped
        assert cover.chosen == ([2] if swapped else [0, 1])
    cover = improve(Cover(instance(rows, 2, 2), (0, 1)), np.array([2]), np.array([1, 1, 2.5]))
    assert cover.chosen == [0, 1]
    # A dear d and a cheap copy of it, e, in the pool, d first: e replaces the pair.
    cover = Cover(instance([*rows, [0, 1]], 2, 2), (0, 1))
    assert swap_two_for_one(cover, np.array([2, 3]), sensor_cost=np.array([1, 1, 2.5, 1.5]))
    assert cover.chosen == [3]


def test_sensors_standing_on_a_mast_count_against_its_cap():
    """Points 0-2; site 0 holds c0 = {0}, c1 = {1}, c2 = {2}, site 1 holds c3-c5, the
    same one point each; a cap of 4. With no sensor standing, greedy takes c0, c1 and
    c2 (ties go to the first), all on site 0; with 2 planned sensors standing on
    site 0 (``held``), its room is 2, so c2's point comes from site 1 (c5). An
    independent count: at most 4 - 2 on site 0, all 3 points covered."""
    rows = [[0], [1], [2], [0], [1], [2]]
    site_of = np.array([0, 0, 0, 1, 1, 1])
    matrix = instance(rows, 3, 3).matrix
    free = complete(Cover(CoverInstance(matrix, 3, site_of=site_of, cap=4)), np.arange(6))
    assert sorted(free.chosen) == [0, 1, 2]
    inst = CoverInstance(matrix, 3, site_of=site_of, cap=4, held=np.array([2, 0]))
    assert inst.room(np.array([0, 1])).tolist() == [2, 4]
    cover = complete(Cover(inst), np.arange(6))
    assert sorted(cover.chosen) == [0, 1, 5] and cover.n_covered == 3
    assert cover.full(0) and not cover.full(1)
    # Site 0 full before anything is chosen (4 stand there): all from site 1.
    inst = CoverInstance(matrix, 3, site_of=site_of, cap=4, held=np.array([4, 0]))
    assert sorted(complete(Cover(inst), np.arange(6)).chosen) == [3, 4, 5]
    # A sample of the instance keeps what stands.
    assert CoverInstance(matrix, 3, np.zeros((3, 2)), site_of=site_of, cap=4,
                         held=np.array([2, 0])).thinned(1.0).held.tolist() == [2, 0]  # fmt: skip


def test_a_swap_keeps_within_the_cap():
    """One per site: a = {0} (site 0), b = {1} (site 1), c = {2} (site 2) chosen; d =
    {0, 1} replaces a and b on a site a or b frees (site 0), never on full site 2."""
    rows = [[0], [1], [2], [0, 1]]
    for d_site, swapped in ((0, True), (2, False)):
        site_of = np.array([0, 1, 2, d_site])
        inst = instance(rows, 3, 3)
        inst = CoverInstance(inst.matrix, 3, site_of=site_of, cap=1)
        cover = Cover(inst, (0, 1, 2))
        assert swap_two_for_one(cover, np.array([3])) is swapped
        assert sorted(cover.chosen) == ([2, 3] if swapped else [0, 1, 2])
        assert cover.at_site == ({0: 1, 1: 0, 2: 1} if swapped else {0: 1, 1: 1, 2: 1})
    # c = {2, 3} and a goal of 3 of the 4 points: the pair (a, b) needs one point back,
    # and d, on c's full site, may not bring it; every other pair frees site 2 but
    # needs two points back, and d brings one.
    rows = [[0], [1], [2, 3], [0, 1]]
    inst = CoverInstance(instance(rows, 4, 3).matrix, 3, site_of=np.array([0, 1, 2, 2]), cap=1)
    cover = Cover(inst, (0, 1, 2))
    assert not swap_two_for_one(cover, np.array([3]))
    assert cover.chosen == [0, 1, 2]
    # d on the full site 2 and a copy of it, e, on site 0, d first: e replaces a and b.
    rows = [[0], [1], [2], [0, 1], [0, 1]]
    inst = CoverInstance(instance(rows, 3, 3).matrix, 3, site_of=np.array([0, 1, 2, 2, 0]), cap=1)
    cover = Cover(inst, (0, 1, 2))
    assert swap_two_for_one(cover, np.array([3, 4]))
    assert sorted(cover.chosen) == [2, 4]


def test_greedy_adds_nothing_on_a_site_full_from_the_start():
    """One per site: a = {0} chosen on site 0; b = {1, 2} (site 0) would add two
    points, c = {1} (site 1) one. Site 0 is full: c is added, and point 2, which only b
    sees, stays short."""
    inst = CoverInstance(instance([[0], [1, 2], [1]], 3, 3).matrix, 3,
                         site_of=np.array([0, 0, 1]), cap=1)  # fmt: skip
    cover = complete(Cover(inst, (0,)), np.array([1, 2]))
    assert cover.chosen == [0, 2] and cover.slack == -1


def test_a_cover_counts_what_each_site_holds():
    inst = instance([[0], [1], [2]], 3, 3)
    inst = CoverInstance(inst.matrix, 3, site_of=np.array([0, 0, 1]), cap=2)
    cover = Cover(inst, (0, 1, 2))
    assert cover.at_site == {0: 2, 1: 1} and cover.full(0) and not cover.full(1)
    cover.remove(1)
    assert cover.at_site == {0: 1, 1: 1} and not cover.full(0)


def test_closing_a_site_completes_per_cost():
    """p = {0, 1} (site 0) and r = {2} (site 1) chosen at 1 each, masts at 1: cost 4.
    Site 0 also holds big = {0, 1, 2} at 3 and small = {2} at 1. Closing site 1, the
    point 2 goes to small per cost (p and small: 3); per point big would come first and
    p be pruned (big alone: 4, no gain), and nothing close."""
    rows = [[0, 1], [2], [0, 1, 2], [2]]
    site_of = np.array([0, 1, 0, 0])
    cost = np.array([1.0, 1.0, 3.0, 1.0])
    got = close_sites(Cover(instance(rows, 3, 3), (0, 1)), site_of, 1.0, cost)
    assert sorted(got.chosen) == [0, 3]


def test_three_disjoint_strips_need_three_sensors():
    """Three 10 x 4 m strips 300 m apart, each with a sensor area beside it: no sensor
    sees two, one sees a whole strip; so 3 sensors on 3 masts, and the bound is 3."""
    strips = [shapely.box(300 * k, 0, 300 * k + 10, 4) for k in range(3)]
    areas = [shapely.box(300 * k, 14, 300 * k + 10, 18) for k in range(3)]
    settings = replace(LP, rho=1.0, objective="sensors")
    res = Run(areas_scene(strips, areas), box_caster(), PAPER_CAMERA, settings).result()
    m = res.metrics
    assert m["coverage_fraction"] == 1.0
    assert m["sensors"] == 3 and m["sensors_lower_bound"] == 3 and m["gap"] == 0.0
    assert m["masts"] == 3 and m["masts_lower_bound"] == 3


def test_two_sensors_on_one_mast_beat_two_masts():
    """Two targets on opposite sides of a narrow sensor area, each needing its own
    sensor: with masts dearer than sensors, both sensors share one mast (cost 3 + 2)
    and the bound proves it: 1 mast, 2 sensors."""
    north = shapely.box(-6, 12, 6, 20)
    south = shapely.box(-6, -20, 6, -12)
    area = shapely.box(-1, -1, 1, 1)
    res = Run(
        areas_scene([north, south], [area]), box_caster(), PAPER_CAMERA, replace(LP, rho=1.0)
    ).result()
    m = res.metrics
    assert m["coverage_fraction"] == 1.0
    assert (m["sensors"], m["masts"]) == (2, 1)
    assert m["cost"] == m["objective"] == m["lower_bound"] == 3 * 1 + 1 * 2
    assert m["gap"] == 0.0


def test_a_target_only_one_position_sees():
    """A long sensor strip behind a 20 m wall with one 1 m gap: only the position at
    the gap sees the target (boxes: the wall, left and right of the gap)."""
    target = shapely.box(-5, 10, 5, 16)
    strip = shapely.box(-60, -5, 60, -3)
    wall = [((-80.0, -1.0, 0.0), (-0.5, -0.6, 20.0)), ((0.5, -1.0, 0.0), (80.0, -0.6, 20.0))]
    scene = areas_scene([target], [strip], wall)
    settings = replace(LP, rho=0.3, objective="sensors")
    run = Run(scene, box_caster(wall), PAPER_CAMERA, settings)
    res = run.result()
    assert res.metrics["coverage_fraction"] >= 0.3
    assert all(abs(s.x) <= 1.0 for s in res.sensors)  # at the gap
    assert res.metrics["sensors"] == res.metrics["sensors_lower_bound"]
    cands = run.problem.candidates
    assert set(np.unique(np.abs(cands.positions[cands.position, 0]))) <= {0.0, 1.0}


def test_same_settings_same_plan():
    scene = areas_scene([shapely.box(0, -7, 60, 7)], [shapely.box(0, 10, 60, 14)])
    runs = [Run(scene, box_caster(), PAPER_CAMERA, LP).result() for _ in range(2)]
    assert [(s.x, s.y, s.pitch_deg, s.yaw_deg) for s in runs[0].sensors] == [
        (s.x, s.y, s.pitch_deg, s.yaw_deg) for s in runs[1].sensors
    ]
    m = runs[0].metrics
    assert m["objective"] >= m["lower_bound"] and 0 <= m["gap"] < 1
    # Proven optimal (3 sensors on 2 masts): no LP on its own masts is asked for (the
    # CLI's two_routes run checks one with a gap).
    assert m["gap"] == 0 and m["sensors_on_masts_lower_bound"] is None


def test_the_lp_on_the_plans_masts_may_take_half_the_finish(monkeypatch):
    """A whole ground with a limit of 60 s: the search ends at 57 s (the finish keeps
    3 s), and the LP on the plan's own masts may go on to 58.5 s."""
    seen = []

    def spy(problem, cands, inst, solution, chosen, bound, deadline, stop):
        seen.append(deadline)
        return bound, chosen
        yield

    monkeypatch.setattr(lp_module, "_on_masts", spy)
    scene = areas_scene([shapely.box(0, -7, 60, 7)], [shapely.box(0, 10, 60, 14)])
    run = Run(scene, box_caster(), PAPER_CAMERA, replace(LP, time_limit_s=60.0))
    run.result()
    assert seen == [pytest.approx(run.problem.t0 + 58.5)]


def test_other_optimizers_get_the_bound_when_asked():
    scene = areas_scene([shapely.box(0, -7, 60, 7)], [shapely.box(0, 10, 60, 14)])
    fast_es = replace(LP, optimizer="es", es=replace(LP.es, mu=8, lam=4, max_epochs=4))
    for settings in (replace(LP, optimizer="greedy"), fast_es):
        plain = Run(scene, box_caster(), PAPER_CAMERA, settings).result().metrics
        assert plain["lower_bound"] is None and plain["objective"] == plain["cost"]
        m = Run(scene, box_caster(), PAPER_CAMERA, replace(settings, bound=True)).result().metrics
        assert m["sensors"] == plain["sensors"]  # the bound does not change the plan
        assert 0 < m["lower_bound"] <= m["objective"] and m["gap"] >= 0
        assert m["sensors_lower_bound"] >= 1 and m["masts_lower_bound"] >= 1


def test_stopping_early_keeps_the_best_plan_and_a_proven_bound():
    """Asked to stop at its first report once the candidates are built (the Blender
    operator's Esc), the lp optimizer ends its search at once and still places a plan
    that reaches the goal, with the bound proven so far (0 if none yet) below it. (A
    stop while they are built drops them: ``test_parts``.)"""
    scene = areas_scene([shapely.box(0, -7, 100, 7)], [shapely.box(0, 10, 100, 14)])
    run = Run(scene, box_caster(), PAPER_CAMERA, LP)
    for progress in run.steps():
        if progress.phase == "search" and progress.stage != "candidates":
            assert run.stop_early()
    res = run.result()
    m = res.metrics
    assert "Stopped early" in res.stop_reason and m["coverage_fraction"] >= 0.9
    assert 0 <= m["lower_bound"] <= m["objective"]
    assert m["sensors_on_masts_lower_bound"] is None  # (no LP on its masts once stopped)
    full = Run(scene, box_caster(), PAPER_CAMERA, LP).result().metrics
    assert m["lower_bound"] <= full["lower_bound"] and full["objective"] <= m["objective"]
    # The ES has no early stop: Esc cancels it.
    assert not Run(scene, box_caster(), PAPER_CAMERA, replace(LP, optimizer="es")).stop_early()


def test_milp_candidates_are_the_largest_per_site_within_the_limit(monkeypatch):
    """Two sites of three candidates (sizes 1, 3, 2 and 2, 1, 3), a limit of 4: two a
    site, the largest (1 and 2; 5 and 3), and the plan's candidate 0 besides."""
    monkeypatch.setattr(lp_module, "MAX_MILP_CANDIDATES", 4)
    inst = instance([[0], [0, 1, 2], [0, 1], [0, 1], [0], [0, 1, 2]], 3, 3)
    site_of = np.array([0, 0, 0, 1, 1, 1])
    cols = lp_module.milp_candidates(inst, site_of, np.array([0, 1]), [0])
    assert cols.tolist() == [0, 1, 2, 3, 5]
    monkeypatch.setattr(lp_module, "MAX_MILP_CANDIDATES", 6)
    assert lp_module.milp_candidates(inst, site_of, np.array([1]), [3]).tolist() == [3, 4, 5]


@pytest.mark.parametrize("seed", range(6))
def test_the_lp_line_bounds_the_lp_at_every_goal(seed):
    """The duals of the LP solved at one goal bound its value at every other goal
    (slope g - intercept <= LP(g)), and meet it at the goal solved."""
    rng = np.random.default_rng(300 + seed)
    inst = random_instance(rng, n_cand=12, n_points=20)
    ones, group = np.ones(12), np.arange(12)
    lp = drain(cover_lp(inst, ones, group, np.arange(1), integral=False))
    assert lp.slope * inst.goal - lp.intercept == pytest.approx(lp.value, abs=1e-4)
    coverable = int(np.count_nonzero(np.bincount(inst.matrix.indices, minlength=20)))
    for g in range(1, coverable + 1):
        at_g = drain(
            cover_lp(CoverInstance(inst.matrix, g), ones, group, np.arange(1), integral=False)
        )
        assert lp.slope * g - lp.intercept <= at_g.value + 1e-6


def test_the_bound_shown_while_proving_is_a_proof_and_counts_the_masts(monkeypatch):
    """Every bound a progress report shows is at most the run's final bound (each is a
    proof when shown); while the sensors LP still works (held here, its last round
    reported again for 2 s, so that the fewest masts are known first), the reports
    count the fewest masts' cost too (mast_cost x masts), not the sensors' alone."""
    real = lp_module.cover_lp
    lp_done = []

    def slow_lp(*args, **kwargs):
        last = None
        gen = real(*args, **kwargs)
        while True:
            try:
                step = next(gen)
            except StopIteration as done:
                value = done.value
                break
            last = step if isinstance(step, LPProgress) else last
            yield step
        held = time.perf_counter() + 2.0
        while last is not None and time.perf_counter() < held:
            time.sleep(0.01)
            yield last
        lp_done.append(True)
        return value

    monkeypatch.setattr(lp_module, "cover_lp", slow_lp)
    scene = areas_scene([shapely.box(0, -7, 100, 7)], [shapely.box(0, 10, 100, 14)])
    run = Run(scene, box_caster(), PAPER_CAMERA, LP)
    shown = [(bool(lp_done), p.bound) for p in run.steps() if p.bound is not None]
    m = run.result().metrics
    assert shown and all(b <= m["lower_bound"] + 1e-9 for _, b in shown)
    masts = LP.mast_cost * m["masts_lower_bound"]
    assert masts > 0
    assert any(b >= masts for after, b in shown if not after)


def test_a_thinned_instance_keeps_one_point_a_square_and_the_goal_share():
    """Points at x = 0, 0.5, 1.5, 2.5 and 4.1 m (y = 0.2): in 2 m squares, [0, 2) holds
    the first three, [2, 4) the fourth, [4, 6) the fifth, so points 0, 3 and 4 stay
    (each the first of its square), with their columns and k. A goal of 4 of 5 becomes
    ceil(4 * 3 / 5) = 3 of 3."""
    xy = np.array([[0.0, 0.2], [0.5, 0.2], [1.5, 0.2], [2.5, 0.2], [4.1, 0.2]])
    matrix = sparse.csr_matrix(np.array([[1, 1, 0, 0, 1], [0, 0, 1, 1, 0]], dtype=np.float32))
    need = np.array([1, 1, 1, 2, 1], dtype=np.int32)
    inst = CoverInstance(matrix, 4, xy, need, np.array([0, 1]), 4)
    thin = inst.thinned(2.0)
    assert thin.xy.tolist() == xy[[0, 3, 4]].tolist()
    assert thin.matrix.toarray().tolist() == [[1, 0, 1], [0, 1, 0]]
    assert thin.k.tolist() == [1, 2, 1] and thin.goal == 3
    assert thin.site_of.tolist() == [0, 1] and thin.cap == 4
    assert CoverInstance(matrix, 2, xy).thinned(2.0).goal == 2  # ceil(2 * 3 / 5)
    # The points in reverse: the kept ones are again each square's first in the
    # points' order (0, 1, 2), and the last three share the third square.
    keep, square = CoverInstance(matrix, 2, xy[::-1]).cells(2.0)
    assert keep.tolist() == [0, 1, 2] and square.tolist() == [0, 1, 2, 2, 2]
    assert inst.cells(2.0)[1].tolist() == [0, 0, 0, 1, 2]
    # Squares moved by 1 m in x: [-1, 1) holds x = 0 and 0.5, [1, 3) 1.5 and 2.5, and
    # [3, 5) 4.1, so points 0, 2 and 4 stay; a move in y alone changes nothing here.
    assert inst.thinned(2.0, (1.0, 0.0)).xy.tolist() == xy[[0, 2, 4]].tolist()
    assert inst.cells(2.0, (1.0, 0.0))[1].tolist() == [0, 0, 1, 1, 2]
    assert inst.thinned(2.0, (0.0, 1.0)).xy.tolist() == xy[[0, 3, 4]].tolist()


def test_a_plan_rounded_on_given_masts_keeps_each_masts_room():
    """Site 0 holds candidates for points 0, 1 and 2 (cap 2), site 1 one for point 2.
    At x = 0.9, 0.8, 0.7, 0.1 and a threshold of 0.5 the two largest fill site 0, the
    third waits for room that never comes, and greedy completes the goal from site 1:
    candidates 0, 1 and 3 on two masts. Above every x, greedy alone plans it, within
    the cap too."""
    matrix = sparse.csr_matrix(
        (np.ones(4, np.float32), ([0, 1, 2, 3], [0, 1, 2, 2])), shape=(4, 3)
    )
    site_of = np.array([0, 0, 0, 1])
    inst = CoverInstance(matrix, 3, site_of=site_of, cap=2)
    cols, x = np.arange(4), np.array([0.9, 0.8, 0.7, 0.1])
    plan = lp_module.plan_on_masts(inst, site_of, cols, x, 0.5, 3.0, 1.0)
    assert sorted(plan.chosen) == [0, 1, 3] and plan.slack == 0
    alone = lp_module.plan_on_masts(inst, site_of, cols, x, 0.95, 3.0, 1.0)
    assert alone.slack == 0 and np.bincount(site_of[alone.chosen]).max() <= 2
