"""The cover moves on random small instances (caps, k = 2, per-candidate costs)
against enumeration: a two-for-one swap is found exactly when one exists, a pool
with candidates barred plans as the pool without them, and closing masts goes site
by site as its docstring says."""

import itertools

import numpy as np
import pytest
from scipy import sparse

from autoscoop_blender.core.optimize.cover import (
    Cover,
    CoverInstance,
    _row_sums,
    close_sites,
    complete,
    plan_price,
    pool_matrices,
    prune,
    swap_two_for_one,
)

SEEDS = range(150)


def random_instance(rng, cap=True):
    """12-16 candidates on 5 sites over 30 points (each seen by about a quarter),
    some points needing 2; the goal a few points below what every candidate covers.
    None when every candidate covers fewer points than 10."""
    n_cands, n_points = int(rng.integers(12, 17)), 30
    dense = rng.random((n_cands, n_points)) < 0.25
    need = np.where(rng.random(n_points) < 0.3, 2, 1).astype(np.int32)
    reach = int((dense.sum(axis=0) >= need).sum())
    if reach < 10:
        return None
    site_of = rng.integers(0, 5, n_cands).astype(np.int64)
    inst = CoverInstance(
        sparse.csr_matrix(dense.astype(np.float32)), reach - int(rng.integers(0, 4)),
        need=need, site_of=site_of if cap else None, cap=int(rng.integers(2, 4)) if cap else None,
    )  # fmt: skip
    return inst, site_of


def covered(inst, chosen):
    """(N,) the points ``chosen`` (distinct candidates) covers to their k."""
    count = np.asarray(inst.matrix[chosen].sum(axis=0)).ravel() if chosen else 0
    return count >= inst.k


def meets(inst, chosen, among=None):
    """Whether ``chosen`` covers the goal (counting only the points ``among``)."""
    hits = covered(inst, chosen)
    return int(np.count_nonzero(hits if among is None else hits & among)) >= inst.goal


def within_cap(inst, chosen):
    if inst.cap is None:
        return True
    return bool(np.all(np.bincount(inst.site_of[chosen], minlength=5) <= inst.cap))


def some_swap(inst, chosen, pool, cost):
    """Whether two of ``chosen`` can be replaced by one of ``pool`` (not one already
    chosen, and cheaper than the two) or by none, the caps kept and the goal met on
    the points covered before (the move brings back what the two leave short; a
    point short before does not count)."""
    before = covered(inst, chosen)
    for a, b in itertools.combinations(chosen, 2):
        rest = [c for c in chosen if c not in (a, b)]
        if meets(inst, rest, before):
            return True
        for c in pool:
            if c in rest or cost[c] >= cost[a] + cost[b]:
                continue
            if meets(inst, [*rest, c], before) and within_cap(inst, [*rest, c]):
                return True
    return False


@pytest.mark.parametrize("seed", SEEDS)
def test_a_swap_is_made_exactly_when_enumeration_finds_one(seed):
    """From a greedy plan with a few extra candidates (so swaps exist on some
    instances and not on others), costs 1-3 a candidate."""
    rng = np.random.default_rng(seed)
    made = random_instance(rng)
    if made is None:
        pytest.skip("an instance with too little to cover")
    inst, _ = made
    every = np.arange(inst.matrix.shape[0])
    cost = rng.integers(1, 4, len(every)).astype(float)
    cover = complete(Cover(inst), every, sensor_cost=cost)
    if cover.slack < 0:
        pytest.skip("the goal out of reach under the caps")
    for c in rng.permutation(every)[:3]:
        if c not in cover.chosen and not cover.full(int(inst.site_of[c])):
            cover.add(int(c))
    before = list(cover.chosen)
    pool = rng.permutation(every)[: int(rng.integers(4, len(every) + 1))]
    expected = some_swap(inst, before, pool.tolist(), cost)
    assert swap_two_for_one(cover, pool, sensor_cost=cost) == expected
    if expected:
        assert len(cover.chosen) in (len(before) - 1, len(before) - 2)
        assert len(set(cover.chosen)) == len(cover.chosen)
        assert meets(inst, cover.chosen) and within_cap(inst, cover.chosen)
        assert plan_price(cover.chosen, inst.site_of, 0.0, cost) < plan_price(
            before, inst.site_of, 0.0, cost
        )
    else:
        assert cover.chosen == before


@pytest.mark.parametrize("seed", SEEDS[:60])
def test_a_barred_pool_plans_as_the_pool_without_them(seed):
    """The same candidates in the same order, with or without the pool's matrices
    given, per sensor or per cost with masts."""
    rng = np.random.default_rng(seed)
    made = random_instance(rng)
    if made is None:
        pytest.skip("an instance with too little to cover")
    inst, site_of = made
    pool = rng.permutation(inst.matrix.shape[0])[:10]
    barred = rng.random(len(pool)) < 0.3
    for mast_cost in (0.0, 2.5):
        plain = complete(Cover(inst), pool[~barred], site_of, mast_cost, 1.0).chosen
        assert complete(Cover(inst), pool, site_of, mast_cost, 1.0, barred=barred).chosen == plain
        prepared = pool_matrices(inst, pool)
        got = complete(Cover(inst), pool, site_of, mast_cost, 1.0, barred, prepared).chosen
        assert got == plain


def close_one_site_at_a_time(cover, site_of, mast_cost, sensor_cost):
    """``close_sites`` as its docstring says, each trial from its own pool: the
    candidates at the other sites in use."""
    inst, best, closed = cover.inst, cover, True
    while closed:
        closed = False
        sites, counts = np.unique(site_of[best.chosen], return_counts=True)
        in_use = set(sites.tolist())
        for s in sites[np.lexsort((sites, counts))]:
            pool = np.flatnonzero(np.isin(site_of, sorted(in_use - {int(s)})))
            kept = [c for c in best.chosen if site_of[c] != s]
            trial = prune(complete(Cover(inst, kept), pool, sensor_cost=sensor_cost))
            if trial.slack >= 0 and plan_price(
                trial.chosen, site_of, mast_cost, sensor_cost
            ) < plan_price(best.chosen, site_of, mast_cost, sensor_cost):
                best, closed = trial, True
                in_use = set(site_of[best.chosen].tolist())
    return best


@pytest.mark.parametrize("seed", SEEDS[:60])
@pytest.mark.parametrize("cap", [True, False])
def test_closing_sites_matches_closing_them_one_pool_at_a_time(seed, cap):
    """From the greedy plan per sensor (masts ignored, so some are worth closing)."""
    rng = np.random.default_rng(seed)
    made = random_instance(rng, cap)
    if made is None:
        pytest.skip("an instance with too little to cover")
    inst, site_of = made
    start = complete(Cover(inst), np.arange(inst.matrix.shape[0]))
    if start.slack < 0:
        pytest.skip("the goal out of reach under the caps")
    want = close_one_site_at_a_time(Cover(inst, start.chosen), site_of, 2.0, 1.0)
    got = close_sites(Cover(inst, start.chosen), site_of, 2.0, 1.0)
    assert got.chosen == want.chosen


def test_closing_sites_closes_some_on_these_instances():
    """The comparison above is not idle: on some of its instances a mast closes."""
    closes = 0
    for seed in SEEDS[:60]:
        made = random_instance(np.random.default_rng(seed))
        if made is None:
            continue
        inst, site_of = made
        start = complete(Cover(inst), np.arange(inst.matrix.shape[0]))
        if start.slack >= 0:
            got = close_sites(Cover(inst, start.chosen), site_of, 2.0, 1.0)
            closes += len(set(site_of[got.chosen])) < len(set(site_of[start.chosen]))
    assert closes >= 5


def test_row_sums_are_the_sums_of_the_rows_taken():
    """Rows taken twice, empty rows and no rows at all, with weights."""
    rng = np.random.default_rng(7)
    rows = sparse.random(40, 25, density=0.2, random_state=3, format="csr")
    rows.data = rng.integers(1, 4, rows.nnz).astype(float)
    rows[5] = 0
    rows.eliminate_zeros()
    for which in ([3, 3, 5, 17], [5], [], list(range(40))):
        want = np.asarray(rows[np.array(which, dtype=np.int64)].sum(axis=0)).ravel()
        assert np.array_equal(_row_sums(rows, np.array(which, dtype=np.int64)), want)
