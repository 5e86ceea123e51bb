"""The joint bound on masts and sensors (``core/optimize/joint.py``): against plans
worked out by hand, a brute-force optimum, and the LP solved whole by other code."""

from __future__ import annotations

import dataclasses
import itertools
import math
import threading
import time

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st
from scipy import optimize, sparse

from autoscoop_blender.core.optimize import joint
from autoscoop_blender.core.optimize.cover import CoverInstance
from tests.core.test_lp import steps


def _instance(rows, n_points, site_of, goal, cap, need=None):
    """rows[c]: the points candidate c covers; site_of[c]: its site."""
    data = [(c, n) for c, points in enumerate(rows) for n in points]
    r, n = zip(*data, strict=True) if data else ((), ())
    matrix = sparse.csr_matrix((np.ones(len(r), np.float32), (r, n)), shape=(len(rows), n_points))
    need = None if need is None else np.asarray(need, np.int32)
    site_of = np.asarray(site_of, np.int64)
    return CoverInstance(matrix, goal, need=need, site_of=site_of, cap=cap)


# The first test's instance: site 0 sees points 0-4 with a candidate each (cap 4),
# sites 1 and 2 see points 0-2 and 3-4 with one candidate each.
CAP_ROWS = [[0], [1], [2], [3], [4], [0, 1, 2], [3, 4]]


def _cap_instance():
    return _instance(CAP_ROWS, 5, [0, 0, 0, 0, 0, 1, 2], goal=5, cap=4)


def _bound(inst, mast_cost, standing=None, fewest=0, sensors=0.0):
    """The joint bound from no columns and no rows: the search adds what it needs."""
    n_sites = int(inst.site_of.max()) + 1
    standing = np.zeros(n_sites, bool) if standing is None else np.asarray(standing)
    go = joint.joint_bound(
        inst, inst.site_of, standing, fewest, mast_cost, 1.0, sensors,
        np.zeros(0, np.int64), np.zeros(0, np.int64),
    )  # fmt: skip
    return steps(go)[0]


def _brute_force(inst, mast_cost, standing):
    """The cheapest plan by trying every set of candidates: a new mast per site used
    (none where one stands), one per sensor, at most ``cap`` a site, and at least
    ``goal`` points covered to their k (inf: none reaches it)."""
    m = inst.matrix.toarray() > 0
    best = math.inf
    for size in range(len(m) + 1):
        for chosen in itertools.combinations(range(len(m)), size):
            chosen = list(chosen)
            sites, per = np.unique(inst.site_of[chosen], return_counts=True)
            if len(per) and per.max() > inst.cap:
                continue
            covered = np.count_nonzero(m[chosen].sum(axis=0) >= inst.k)
            if covered >= inst.goal:
                new = np.count_nonzero(~standing[sites])
                best = min(best, mast_cost * new + size)
    return best


def _direct_lp(inst, masts, standing, tight=False):
    """S_LP(masts) by scipy's linprog over every row and column at once (variables:
    x (C), u (N), y (sites)); ``tight``: with the site rows, k_n u_n <= sum_s
    min(site s's candidates covering n, k_n) y_s."""
    a = inst.matrix.toarray().astype(float)
    n_cands, n_points = a.shape
    n_sites = len(standing)
    n_var = n_cands + n_points + n_sites
    cost = np.concatenate([np.ones(n_cands), np.zeros(n_points + n_sites)])
    rows, rhs = [], []
    for n in range(n_points):  # k_n u_n - sum_c a_nc x_c <= 0
        row = np.zeros(n_var)
        row[:n_cands] = -a[:, n]
        row[n_cands + n] = inst.k[n]
        rows.append(row), rhs.append(0.0)
    row = np.zeros(n_var)
    row[n_cands : n_cands + n_points] = -1.0
    rows.append(row), rhs.append(-float(inst.goal))
    for c in range(n_cands):  # x_c - y_s <= 0
        row = np.zeros(n_var)
        row[c], row[n_cands + n_points + inst.site_of[c]] = 1.0, -1.0
        rows.append(row), rhs.append(0.0)
    for s in range(n_sites):  # sum_{c at s} x_c - cap y_s <= 0
        row = np.zeros(n_var)
        row[:n_cands] = inst.site_of == s
        row[n_cands + n_points + s] = -inst.cap
        rows.append(row), rhs.append(0.0)
    for n in range(n_points * tight):  # k_n u_n - sum_s b_ns y_s <= 0
        row = np.zeros(n_var)
        row[n_cands + n] = inst.k[n]
        for s in range(n_sites):
            row[n_cands + n_points + s] = -min(a[inst.site_of == s, n].sum(), inst.k[n])
        rows.append(row), rhs.append(0.0)
    row = np.zeros(n_var)
    row[n_cands + n_points :] = ~standing
    rows.append(row), rhs.append(float(masts))
    res = optimize.linprog(cost, np.array(rows), np.array(rhs), bounds=(0, 1), method="highs")
    return res.fun if res.status == 0 else math.inf


def test_the_cap_forces_a_second_mast_that_neither_bound_sees():
    """Site 0 sees all 5 points, one candidate each, but holds 4 sensors; sites 1 and
    2 see points 0-2 and 3-4 with one candidate each. The fewest masts are 1 (site 0,
    without the cap) and the fewest sensors 2 (on sites 1 and 2): apart, 3 x 1 + 2 = 5.
    One mast cannot carry 5 sensors, so every plan has 2 masts; the cheapest is sites
    1 and 2 (3 x 2 + 2 = 8, where sites 0 and 1 cost 6 + 3). The joint bound is 8."""
    inst = _cap_instance()
    standing = np.zeros(3, bool)
    assert _brute_force(inst, 3.0, standing) == 8
    assert _bound(inst, 3.0, fewest=1, sensors=2.0) == pytest.approx(8.0)
    # Without the cap one mast does: 3 + 5 = 8 on site 0, or 8 on sites 1 and 2.
    assert _bound(_instance(CAP_ROWS, 5, [0] * 5 + [1, 2], goal=5, cap=5), 3.0) == 8.0
    # At a mast cost of 1 the 5 sensors on one mast would cost 6 and 2 masts 4: the
    # joint bound is 4 (the separate bounds give 1 + 2 = 3).
    assert _bound(inst, 1.0, fewest=1, sensors=2.0) == 4.0


def test_a_standing_mast_is_free_and_outside_the_budget():
    """The same with a mast standing at site 0: its 4 sensors leave a point to a new
    mast. The cheapest is site 1's candidate (points 0-2) with site 0's for points 3
    and 4: one new mast, 3 sensors, cost 6. By hand, on one new mast the LP puts x = a
    on site 1 and b on site 2 (a + b <= 1), 1 - a or 1 - b on site 0's: 5 - 2a - b,
    least at a = 1: 3 sensors, so 3 + 3 = 6; on two new masts 2 sensors, 6 + 2 = 8;
    on none site 0 cannot cover the 5 points."""
    inst = _cap_instance()
    standing = np.array([True, False, False])
    assert _brute_force(inst, 3.0, standing) == 6
    assert _bound(inst, 3.0, standing) == pytest.approx(6.0)


def test_a_sensor_needs_its_whole_mast():
    """Sites 0 and 1 see points 0-1 and 2-3 with one candidate each; site 2 sees each
    of the 4 points with a candidate of its own (cap 4). On one mast only site 2
    covers all: 4 sensors, 3 + 4 = 7; on two, sites 0 and 1: 6 + 2 = 8. Without
    ``x_c <= y_s`` the LP would open sites 0 and 1 a quarter each (4 y_s >= x_c) and
    prove only 3 + 2 = 5."""
    rows = [[0, 1], [2, 3], [0], [1], [2], [3]]
    inst = _instance(rows, 4, [0, 1, 2, 2, 2, 2], goal=4, cap=4)
    assert _brute_force(inst, 3.0, np.zeros(3, bool)) == 7
    assert _bound(inst, 3.0, fewest=1, sensors=2.0) == pytest.approx(7.0)
    solved = []
    go = joint.joint_bound(
        inst, inst.site_of, np.zeros(3, bool), 1, 3.0, 1.0, 2.0,
        np.zeros(0, np.int64), np.zeros(0, np.int64), solved=solved,
    )  # fmt: skip
    steps(go)
    # Settled: its bound, 4, is what a solution of the whole LP costs.
    assert [(lp.masts, lp.settled) for lp in solved] == [(1, True)]
    assert solved[0].value == pytest.approx(4.0) and solved[0].at(1) == pytest.approx(4.0, abs=1e-5)


def test_the_site_rows_keep_a_half_open_mast_from_covering_a_point_twice():
    """Points 0-2, cap 2. Site 0 holds candidates seeing {0} and {0, 1}; site 1 those
    seeing {0, 2} and {1, 2}. On one mast only site 1 covers all three, with both its
    candidates: 2 sensors. The LP without the site rows opens each site half and
    takes {0, 1}, {0, 2} and {1, 2} at 1/2: every point covered once, 1.5 sensors. With
    them a point counts at most the open share of the sites that see it: point 2 needs
    site 1 whole, and the LP is the integer 2."""
    inst = _instance([[0], [0, 1], [0, 2], [1, 2]], 3, [0, 0, 1, 1], goal=3, cap=2)
    standing = np.zeros(2, bool)
    for tight, value in ((False, 1.5), (True, 2.0)):
        go = joint.masts_sensors_lp(
            inst, np.ones(4), inst.site_of, standing, 1, np.zeros(0, np.int64),
            np.zeros(0, np.int64), tight=tight,
        )  # fmt: skip
        lp = steps(go)[0]
        assert lp.complete and lp.value == pytest.approx(value)
        assert lp.at(1) == pytest.approx(value, abs=1e-5)
        assert _direct_lp(inst, 1, standing, tight) == pytest.approx(value)
        # The same LP from the joint bound's search, which passes ``tight`` on (and
        # leaves the site rows out unless asked).
        solved = []
        flag = {"tight": True} if tight else {}
        go = joint.joint_bound(
            inst, inst.site_of, standing, 1, 3.0, 1.0, 0.0, np.zeros(0, np.int64),
            np.zeros(0, np.int64), solved=solved, **flag,
        )  # fmt: skip
        steps(go)
        assert solved[0].masts == 1 and solved[0].value == pytest.approx(value)


def test_a_point_joins_while_short_of_its_k(monkeypatch):
    """Points 0 and 1 each need 2 sensors: candidate 0 sees both, 1 sees point 0 and 2
    sees point 1 (one site, cap 3): all three are needed. With one row a round, point
    0 joins first and its LP (candidates 0 and 1) leaves point 1 with one sensor: it
    must join too, and the LP is 3. (Every column is there from the start, so no
    round adds columns and rows from the same stale x.)"""
    monkeypatch.setattr(joint, "ROWS_PER_ROUND", 1)
    inst = _instance([[0, 1], [0], [1]], 2, [0, 0, 0], goal=2, cap=3, need=[2, 2])
    solved = []
    go = joint.joint_bound(
        inst, inst.site_of, np.zeros(1, bool), 1, 3.0, 1.0, 0.0,
        np.arange(3), np.zeros(0, np.int64), solved=solved,
    )  # fmt: skip
    assert steps(go)[0] == pytest.approx(6.0)
    assert solved[0].value == pytest.approx(3.0)
    # Three solves: no row, point 0's, both; the third's solution is one of the whole
    # LP at 3 sensors, its bound's whole sensors: settled, nothing more to add.
    assert solved[0].rounds == 3 and solved[0].settled


@st.composite
def instances(draw):
    n_sites = draw(st.integers(1, 3))
    n_points = draw(st.integers(1, 6))
    site_of = draw(st.lists(st.integers(0, n_sites - 1), min_size=1, max_size=8))
    site_of = np.sort(np.array(site_of, np.int64))
    n_sites = int(site_of.max()) + 1
    rows = [
        draw(st.lists(st.integers(0, n_points - 1), max_size=n_points, unique=True))
        for _ in site_of
    ]
    need = draw(st.lists(st.integers(1, 2), min_size=n_points, max_size=n_points))
    cap = draw(st.integers(1, 3))
    goal = draw(st.integers(1, n_points))
    standing = np.array(draw(st.lists(st.booleans(), min_size=n_sites, max_size=n_sites)))
    mast_cost = draw(st.sampled_from([0.5, 1.0, 3.0]))
    return _instance(rows, n_points, site_of, goal, cap, need), standing, mast_cost


@settings(max_examples=200, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(instances(), st.sampled_from([1, 200]), st.sampled_from([1, 500]), st.booleans())
def test_the_joint_bound_never_exceeds_the_optimum(case, per_round, rows_per_round, tight):
    """On random instances with a cap, k = 1 or 2, masts standing, with the site rows
    or without: the joint bound is at most the brute-force optimum; each LP, solved to
    the end, is S_LP(m) as linprog finds it over the whole model; and its duals bound
    S_LP at every m'. One column or one row a round makes each round's pricing count."""
    inst, standing, mast_cost = case
    best = _brute_force(inst, mast_cost, standing)
    solved = []
    go = joint.joint_bound(
        inst, inst.site_of, standing, 0, mast_cost, 1.0, 0.0,
        np.zeros(0, np.int64), np.zeros(0, np.int64), solved=solved, tight=tight,
    )  # fmt: skip
    with pytest.MonkeyPatch.context() as patch:
        patch.setattr(joint, "PER_ROUND", per_round)
        patch.setattr(joint, "ROWS_PER_ROUND", rows_per_round)
        bound = steps(go)[0]
    assert bound <= best + 1e-6
    for lp in solved:
        assert lp.complete or lp.settled
        direct = _direct_lp(inst, lp.masts, standing, tight)
        if math.isfinite(direct) and lp.complete:
            assert lp.value == pytest.approx(direct, abs=1e-5)
            assert lp.at(lp.masts) == pytest.approx(direct, abs=1e-5)
        elif math.isfinite(direct):  # settled: the same whole sensors as at the end
            assert math.ceil(lp.at(lp.masts) - 1e-6) == math.ceil(direct - 1e-6)
        for m in range(len(lp.sensors)):
            assert lp.at(m) <= _direct_lp(inst, m, standing, tight) + 1e-6


def _check_whole_lp_solution(inst, x, y, reach=None):
    """x (C,) within its links (x_c <= y_s) and caps (sum at s <= cap y_s), covering
    the goal, each point counted min(1, covered / k) (and at most reach / k)."""
    assert np.all(x >= -1e-12) and np.all(x <= y[inst.site_of] + 1e-9)
    load = np.bincount(inst.site_of, weights=x, minlength=len(y))
    assert np.all(load <= inst.cap * y + 1e-9)
    covered = inst.matrix.toarray().T.astype(float) @ x
    if reach is not None:
        covered = np.minimum(covered, reach)
    assert np.minimum(1.0, covered / inst.k).sum() >= inst.goal - 1e-7


@settings(max_examples=200, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(instances(), st.data())
def test_a_repaired_solution_is_one_of_the_whole_lp(case, data):
    """From any x (C,) and y (sites,) in [0, 1], links broken or not: a repair that
    succeeds keeps y, and its x' keeps the links and the caps and covers the goal, at
    the cost it states; so that cost is at least S_LP(m) for every m that y's budget
    fits (linprog over the whole model)."""
    inst, standing, _ = case
    unit = st.floats(0.0, 1.0)
    x = np.array(data.draw(st.lists(unit, min_size=len(inst.site_of), max_size=len(inst.site_of))))
    y = np.array(data.draw(st.lists(unit, min_size=len(standing), max_size=len(standing))))
    cost, fixed = joint.repaired_cost(inst, np.ones(len(x)), inst.site_of, x.copy(), y)
    if math.isfinite(cost):
        _check_whole_lp_solution(inst, fixed, y)
        assert cost == pytest.approx(fixed.sum())
        masts = math.ceil(float(y[~standing].sum()) - 1e-9)
        assert cost >= _direct_lp(inst, masts, standing) - 1e-6


def test_a_repair_clips_broken_links_and_covers_what_they_lose():
    """The first test's instance (cap 4, goal 5). Every site open (y = 1) and no x:
    the repair covers the 5 points, at most 4 at site 0, 5 sensors at most (one per
    point). Site 0 open at 1/2 with its five candidates at 1 (links broken): they are
    clipped to 1/2, 4 x 1/2 at the cap of 4 y = 2 at most, so site 0 covers at most
    2 points' worth; with sites 1 and 2 open the repair covers the rest."""
    inst = _cap_instance()
    y = np.ones(3)
    cost, x = joint.repaired_cost(inst, np.ones(7), inst.site_of, np.zeros(7), y)
    _check_whole_lp_solution(inst, x, y)
    assert cost <= 5.0 and cost >= _direct_lp(inst, 3, np.zeros(3, bool)) - 1e-6
    y = np.array([0.5, 1.0, 1.0])
    x = np.array([1.0] * 5 + [0.0, 0.0])
    cost, fixed = joint.repaired_cost(inst, np.ones(7), inst.site_of, x, y)
    _check_whole_lp_solution(inst, fixed, y)
    assert np.all(fixed[:5] <= 0.5) and fixed[:5].sum() <= 2.0 + 1e-9
    assert fixed[5:].sum() > 0  # sites 1 and 2 make up what the clipping lost
    # Without sites 1 and 2 nothing can: site 0 at 1/2 covers at most 2 points' worth.
    cost, _ = joint.repaired_cost(inst, np.ones(7), inst.site_of, x, np.array([0.5, 0.0, 0.0]))
    assert cost == math.inf


def test_a_repair_stops_counting_points_that_reached_their_k():
    """Points 0-2 (k = 1, goal 3), both sites open (cap 2): candidates 0 and 1 at site
    0 see points 0 and 1, candidate 2 at site 1 sees point 2. The repair raises
    candidate 0 first (2 points a sensor) to 1, which covers points 0 and 1; candidate
    1 then adds nothing, so candidate 2 covers point 2: 2 sensors. Were points 0 and 1
    still counted for candidate 1, it would be raised first, for nothing: 3."""
    inst = _instance([[0, 1], [0, 1], [2]], 3, [0, 0, 1], goal=3, cap=2)
    cost, x = joint.repaired_cost(inst, np.ones(3), inst.site_of, np.zeros(3), np.ones(2))
    assert cost == pytest.approx(2.0)
    assert x == pytest.approx([1.0, 0.0, 1.0])


def test_the_lp_settles_before_its_end_with_the_same_whole_sensors(monkeypatch):
    """Points 0-2, one site (cap 1), candidates seeing 1, 2 and both 0 and 1; goal 2
    on 1 mast: one sensor (the third candidate). With one column and one row a round
    the LP settles at 1 sensor in fewer solves than it takes to its end."""
    monkeypatch.setattr(joint, "PER_ROUND", 1)
    monkeypatch.setattr(joint, "ROWS_PER_ROUND", 1)
    inst = _instance([[1], [2], [0, 1]], 3, [0, 0, 0], goal=2, cap=1)

    def solve(whole):
        go = joint.masts_sensors_lp(
            inst, np.ones(3), inst.site_of, np.zeros(1, bool), 1, np.zeros(0, np.int64),
            np.zeros(0, np.int64), whole=whole,
        )  # fmt: skip
        return steps(go)[0]

    to_the_end, settled = solve(False), solve(True)
    assert to_the_end.complete and not to_the_end.settled
    assert settled.settled and not settled.complete
    assert settled.rounds < to_the_end.rounds
    assert math.ceil(settled.at(1) - 1e-6) == math.ceil(to_the_end.at(1) - 1e-6) == 1


@pytest.mark.parametrize(
    ("best", "mast_cost", "price", "masts"),
    [(74, 3, 1, 13), (74, 3, 2, 13), (23, 3, 1, 4), (10.5, 2.5, 1.5, 1)],
)
def test_enough_sensors_is_where_the_bound_reaches_the_best_plan(best, mast_cost, price, masts):
    """Past ``enough_sensors`` the joint bound at ``masts`` (whole sensors, rounded up
    as ``joint_cost_bound`` rounds them) costs at least ``best``; a little below it,
    less. By hand: 74 - 3 x 13 = 35 at 1 a sensor needs 35 sensors (past 34); at 2 a
    sensor, 17.5 of them, so 18 (past 17, not 16.5); 23 - 12 = 11 needs 11 (past 10);
    (10.5 - 2.5) / 1.5 = 5.33 needs 6 (past 5)."""
    enough = joint.enough_sensors(best, mast_cost, price, masts)
    needed = {(74, 1): 35, (74, 2): 18, (23, 1): 11, (10.5, 1.5): 6}[(best, price)]
    assert needed - 1 < enough < needed - 1 + 1e-4

    def bound(sensors):
        return joint.joint_cost_bound([], masts, masts, mast_cost, price, sensors, True)[0]

    assert bound(enough) >= best
    assert bound(enough - 2e-5) < best


def test_the_joint_bound_of_no_goal_is_nothing():
    """A goal of no points needs no sensor and no mast: the bound is 0 (at 0 masts),
    not a sensor's price."""
    assert joint.joint_cost_bound([], 0, 3, 3.0, 1.0, 0.0, True) == (0.0, 0)


def test_the_joint_bound_names_the_fewest_masts_where_it_is_least():
    """f(m') = 5, 4, 3, 3 at a mast cost of 1: 5 + 0, 4 + 1 and 3 + 2 tie at 5, and
    3 + 3 = 6; the bound is 5, at 0 masts (the first of the tie)."""
    curve = joint.MastsSensors(0, np.array([5.0, 4.0, 3.0, 3.0]), 5.0, 1, True)
    assert joint.joint_cost_bound([curve], 0, 3, 1.0, 1.0, 0.0, True) == (5.0, 0)


def test_each_site_takes_its_cap_largest_excesses():
    """Point duals 1, 0.5 and 0.25 at unit cost: candidate 0 (points 0 and 1) has
    excess 1.5 - 1 = 0.5, candidate 1 (all three) 0.75, candidates 2 (point 2) and
    3 (point 0) none. Candidates 0 and 1 stand at site 0, 2 at site 1, 3 at site 2;
    site 3 has none. With a cap of 1 site 0's phi is 0.75; without a cap, 1.25;
    every other site's 0, and phi has one entry per site."""
    rows = [[0, 1], [0, 1, 2], [2], [0]]
    site_of = np.array([0, 0, 1, 2])
    pi = np.array([1.0, 0.5, 0.25])
    for cap, phi0 in [(1, 0.75), (None, 1.25)]:
        inst = _instance(rows, 3, site_of, goal=3, cap=cap)
        excess, phi = joint.site_excess(inst, np.ones(4), site_of, 4, pi)
        assert excess == pytest.approx([0.5, 0.75, 0.0, 0.0])
        assert phi == pytest.approx([phi0, 0.0, 0.0, 0.0])


def test_the_dual_curve_lies_below_the_dual_value_by_the_safety_margin():
    """sigma = 1 and pi = 1 at 3 points of k = 1, goal 2: sigma x goal less
    sum max(0, sigma - pi) = 2; phi = 0.5 and 1.5 at two sites, one of them standing
    (always subtracted): f(0) = 2 - 0.5 = 1.5 and f(1) = 1.5 - 1.5 = 0, each lowered
    by SAFETY x (|f| + 1), so that round-off never lifts it over the true value."""
    inst = _instance([[0], [1], [2]], 3, [0, 1, 1], goal=2, cap=4)
    curve = joint.dual_curve(inst, np.array([0.5, 1.5]), np.array([True, False]), np.ones(3), 1.0)
    exact = np.array([1.5, 0.0])
    assert curve == pytest.approx(exact - joint.SAFETY * (np.abs(exact) + 1), rel=0, abs=1e-12)
    assert (curve < exact).all()


def test_no_lp_is_solved_when_stopped_late_or_already_at_the_best_plan():
    """The cap instance of the first test (8 at best; apart 3 x 1 + 2 = 5): stopped,
    past its deadline, or with a plan of 5 known, the search solves no LP and the
    bound is the separate bounds' 5; otherwise it solves and proves 8."""
    inst = _cap_instance()
    stopped = threading.Event()
    stopped.set()
    for kwargs, bound in [
        ({"stop": stopped}, 5.0),
        ({"deadline": time.perf_counter() - 1.0}, 5.0),
        ({"best": 5.0}, 5.0),
        ({}, 8.0),
    ]:
        solved = []
        go = joint.joint_bound(
            inst, inst.site_of, np.zeros(3, bool), 1, 3.0, 1.0, 2.0, np.zeros(0, np.int64),
            np.zeros(0, np.int64), solved=solved, **kwargs,
        )  # fmt: skip
        assert steps(go)[0] == pytest.approx(bound), kwargs
        assert (solved == []) == (bound == 5.0), kwargs


def test_an_lp_stopped_before_its_first_solve_proves_nothing():
    """Stopped before HiGHS runs: no round, not complete, no value, and a curve of 0
    at every number of masts (0 to the 3 sites), which bounds any plan."""
    inst = _cap_instance()
    stopped = threading.Event()
    stopped.set()
    go = joint.masts_sensors_lp(
        inst, np.ones(7), inst.site_of, np.zeros(3, bool), 1, np.arange(7), np.arange(5),
        stop=stopped,
    )  # fmt: skip
    lp = steps(go)[0]
    assert (lp.masts, lp.rounds, lp.complete, lp.value) == (1, 0, False, math.inf)
    assert lp.sensors.tolist() == [0.0, 0.0, 0.0, 0.0]


def _on_masts(inst, sites, **kwargs):
    return steps(joint.sensors_on_masts(inst, inst.site_of, np.asarray(sites), **kwargs))[0].bound


def test_the_sensors_on_given_masts_by_hand():
    """On the cap instance: site 0 alone cannot reach the goal (5 one-point
    candidates, room for 4); sites 1 and 2 need their 2; sites 0 and 1 need site 1's
    candidate for points 0-2 and two of site 0's for points 3 and 4: 3."""
    inst = _cap_instance()
    assert _on_masts(inst, [0]) == math.inf
    assert _on_masts(inst, [1, 2]) == pytest.approx(2.0, abs=1e-5)
    assert _on_masts(inst, [0, 1]) == pytest.approx(3.0, abs=1e-5)
    assert _on_masts(inst, [0, 1, 2]) == pytest.approx(2.0, abs=1e-5)


def test_the_sensors_on_given_masts_count_halves_and_the_room_left():
    """Three candidates at one site covering two of three points each ({0, 1}, {1, 2},
    {0, 2}): the LP takes each at 1/2, 1.5 sensors (two in any plan). With two sensors
    standing at the site already and a cap of 3, one more fits: x sums to at most 1,
    short of 1.5, so no plan on that site reaches the goal. A goal of 2 points: 1."""
    rows = [[0, 1], [1, 2], [0, 2]]
    inst = _instance(rows, 3, [0, 0, 0], goal=3, cap=3)
    assert _on_masts(inst, [0]) == pytest.approx(1.5, abs=1e-5)
    held = dataclasses.replace(inst, held=np.array([2]))
    assert _on_masts(held, [0]) == math.inf
    assert _on_masts(dataclasses.replace(inst, goal=2), [0]) == pytest.approx(1.0, abs=1e-5)


def test_the_sensors_on_given_masts_take_each_masts_room_not_its_cap():
    """Site 0 has three candidates of two points each (0-1, 2-3, 4-5) and one sensor
    standing (cap 3: room for 2); site 1 one candidate per point. All 6 points: two
    pairs from site 0 and two single points from site 1, 4 sensors. A bound that let
    site 0 take all three pairs (its cap, not its room) would prove only 3."""
    rows = [[0, 1], [2, 3], [4, 5]] + [[n] for n in range(6)]
    inst = _instance(rows, 6, [0, 0, 0] + [1] * 6, goal=6, cap=3)
    inst = dataclasses.replace(inst, held=np.array([1, 0]))
    assert _brute_force_on(inst, [0, 1]) == 4
    assert _on_masts(inst, [0, 1]) == pytest.approx(4.0, abs=1e-5)


def test_whole_sensors_round_up_past_the_tolerance():
    """two_routes' LP on the plan's 13 masts, 34.33: 35; a bound a hair above a whole
    number (the solver's noise) stays at it; 0 and inf prove nothing."""
    assert joint.whole_sensors(34.333) == 35
    assert joint.whole_sensors(35.0000001) == 35
    assert joint.whole_sensors(0.0) is None and joint.whole_sensors(math.inf) is None


def test_the_sensors_on_given_masts_stopped_or_late_prove_nothing():
    stopped = threading.Event()
    stopped.set()
    assert _on_masts(_cap_instance(), [1, 2], stop=stopped) == 0.0
    assert _on_masts(_cap_instance(), [1, 2], deadline=time.perf_counter() - 1.0) == 0.0
    assert _on_masts(_cap_instance(), [1, 2], deadline=time.perf_counter() + 60.0) > 1.99


def _brute_force_on(inst, sites):
    """The fewest candidates at ``sites`` that cover at least ``goal`` points to their
    k, at most ``cap`` less what stands at a site (inf: none reach it)."""
    m = inst.matrix.toarray() > 0
    held = np.zeros(int(inst.site_of.max()) + 1, int) if inst.held is None else inst.held
    pool = [c for c in range(len(m)) if inst.site_of[c] in sites]
    for size in range(len(pool) + 1):
        for chosen in itertools.combinations(pool, size):
            chosen = list(chosen)
            per = np.bincount(inst.site_of[chosen], minlength=len(held))
            if np.any(per > inst.cap - held):
                continue
            if np.count_nonzero(m[chosen].sum(axis=0) >= inst.k) >= inst.goal:
                return size
    return math.inf


def _direct_lp_on(inst, sites):
    """The LP of plans on ``sites`` by scipy's linprog over every row at once
    (variables: x of the candidates there, u (N))."""
    a = inst.matrix.toarray().astype(float)
    pool = np.flatnonzero(np.isin(inst.site_of, sites))
    n_x, n_points = len(pool), a.shape[1]
    held = np.zeros(int(inst.site_of.max()) + 1, int) if inst.held is None else inst.held
    rows, rhs = [], []
    for n in range(n_points):  # k_n u_n - sum_c a_nc x_c <= 0
        rows.append(np.concatenate([-a[pool, n], np.eye(n_points)[n] * inst.k[n]]))
        rhs.append(0.0)
    rows.append(np.concatenate([np.zeros(n_x), -np.ones(n_points)]))
    rhs.append(-float(inst.goal))
    for s in sites:  # sum_{c at s} x_c <= cap - held_s
        rows.append(np.concatenate([inst.site_of[pool] == s, np.zeros(n_points)]))
        rhs.append(float(inst.cap - held[s]))
    cost = np.concatenate([np.ones(n_x), np.zeros(n_points)])
    res = optimize.linprog(cost, np.array(rows), np.array(rhs), bounds=(0, 1), method="highs")
    return res.fun if res.status == 0 else math.inf


@settings(max_examples=200, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(instances(), st.data())
def test_the_sensors_on_given_masts_are_their_lp_and_below_any_plan_there(case, data):
    """On random instances (a cap, k = 1 or 2, sensors standing at some sites): the
    bound on a random set of sites is linprog's LP over the same plans, and never above
    the fewest sensors of a plan on them found by trying every set."""
    inst, standing, _ = case
    n_sites = len(standing)
    held = np.array(data.draw(st.lists(st.integers(0, 1), min_size=n_sites, max_size=n_sites)))
    inst = dataclasses.replace(inst, held=np.minimum(held, inst.cap))
    sites = data.draw(st.lists(st.integers(0, n_sites - 1), min_size=1, unique=True))
    bound = _on_masts(inst, sorted(sites))
    direct = _direct_lp_on(inst, sorted(sites))
    if math.isinf(direct):
        assert bound == math.inf
    else:
        assert bound == pytest.approx(direct, abs=1e-5)
        assert bound <= direct + 1e-9
    assert bound <= _brute_force_on(inst, sites) + 1e-9
