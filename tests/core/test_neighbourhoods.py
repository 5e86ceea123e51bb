"""Plans improved window by window (``core/optimize/neighbourhoods.py``): against
plans worked out by hand and a brute-force optimum."""

from __future__ import annotations

import threading
import time

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st
from scipy.spatial import cKDTree

from autoscoop_blender.core.optimize import neighbourhoods
from autoscoop_blender.core.optimize.cover import plan_price
from tests.core.test_joint import _brute_force, _instance
from tests.core.test_lp import steps

MAST = 3.0
# One mast a window, six positions within 12 m, all candidates.
ONE_MAST = (neighbourhoods.Size(1, 6, 12.0, 1000),)


def _improve(inst, xy, chosen, mast_cost=MAST, stop=None):
    """(the improved plan, the plans yielded on the way)."""
    go = neighbourhoods.improve(
        inst, inst.site_of, np.asarray(xy, float), chosen, mast_cost, 1.0, stop=stop
    )
    plan, yielded = steps(go)
    return plan, [p for p in yielded if p is not None]


def _cost(inst, plan, mast_cost=MAST):
    return plan_price(plan, inst.site_of, mast_cost, 1.0)


def _reaches(inst, plan):
    counts = np.asarray(inst.matrix[plan].sum(axis=0)).ravel()
    return np.count_nonzero(counts >= inst.k) >= inst.goal


def test_two_masts_become_one_between_them():
    """Sites 0 and 1 (10 m apart) each see half of six points; site 2 between them
    sees all six with one candidate. The plan on 0 and 1 costs 2 masts + 2 sensors = 8;
    the window of both (with site 2, 5 m away) gives 3 + 1 = 4, the optimum."""
    inst = _instance([[0, 1, 2], [3, 4, 5], [0, 1, 2, 3, 4, 5]], 6, [0, 1, 2], goal=6, cap=4)
    plan, yielded = _improve(inst, [(0, 0), (10, 0), (5, 0)], [0, 1])
    assert plan == [2] and yielded == [[2]]
    assert _cost(inst, plan) == 4.0 == _brute_force(inst, MAST, np.zeros(3, bool))


def test_the_rest_of_the_plan_is_kept_and_far_positions_are_not_offered(monkeypatch):
    """One mast a window. Site 0 carries two sensors ({0}, {1}; 3 + 2 = 5), site 2
    (5 m from it) one that sees both (3 + 1 = 4); site 1, 100 m away, carries {2, 3}
    and has nothing better near it. Site 3, 50 m from both, sees all four points with
    one candidate (the optimum, 4) but lies beyond 12 m of each: the plan
    goes from 9 to 8, site 1's sensor kept."""
    monkeypatch.setattr(neighbourhoods, "SIZES", ONE_MAST)
    rows = [[0], [1], [2, 3], [0, 1], [0, 1, 2, 3]]
    inst = _instance(rows, 4, [0, 0, 1, 2, 3], goal=4, cap=4)
    xy = [(0, 0), (100, 0), (5, 0), (50, 0)]
    plan, _ = _improve(inst, xy, [0, 1, 2])
    assert sorted(plan) == [2, 3] and _cost(inst, plan) == 8.0
    assert _brute_force(inst, MAST, np.zeros(4, bool)) == 4.0


def test_at_k_2_two_sensors_on_one_mast_replace_four_on_two():
    """Points 0-3 need 2 sensors each. The plan: two sensors on site 0 that see 0, 1
    and two on site 1 that see 2, 3 (2 x 3 + 4 = 10). Site 2 between them has two
    candidates that each see all four: 3 + 2 = 5, the optimum."""
    rows = [[0, 1], [0, 1], [2, 3], [2, 3], [0, 1, 2, 3], [0, 1, 2, 3]]
    inst = _instance(rows, 4, [0, 0, 1, 1, 2, 2], goal=4, cap=4, need=[2] * 4)
    plan, _ = _improve(inst, [(0, 0), (8, 0), (4, 0)], [0, 1, 2, 3])
    assert sorted(plan) == [4, 5] and _reaches(inst, plan)
    assert _cost(inst, plan) == 5.0 == _brute_force(inst, MAST, np.zeros(3, bool))


def test_a_window_needs_only_what_the_rest_leaves_short(monkeypatch):
    """One mast a window. Points 0 and 1 need 2 sensors, point 2 one. Site 1 (100 m
    away) carries the only sensor that sees point 2, which sees 0 and 1 too; site 0
    carries two more that see 0 and 1. With site 1's sensor kept, 0 and 1 need one
    more each, so one sensor on site 0 is enough: 9 -> 8, the optimum. Had the
    window asked for both of a point's k it would keep both."""
    monkeypatch.setattr(neighbourhoods, "SIZES", ONE_MAST)
    rows = [[0, 1, 2], [0, 1], [0, 1]]
    inst = _instance(rows, 3, [1, 0, 0], goal=3, cap=4, need=[2, 2, 1])
    plan, _ = _improve(inst, [(0, 0), (100, 0)], [0, 1, 2])
    assert 0 in plan and len(plan) == 2 and _reaches(inst, plan)
    assert _cost(inst, plan) == 8.0 == _brute_force(inst, MAST, np.zeros(2, bool))


def test_a_partial_goal_leaves_the_cheapest_points_out():
    """Goal 4 of 6 points: site 0's two sensors see {0, 1, 2} and {3, 4, 5}; site 1
    (5 m away) has one that sees {0, 1, 2, 3}. The window moves the mast there:
    3 + 1 = 4 against 3 + 2 = 5."""
    inst = _instance([[0, 1, 2], [3, 4, 5], [0, 1, 2, 3]], 6, [0, 0, 1], goal=4, cap=4)
    plan, _ = _improve(inst, [(0, 0), (5, 0)], [0, 1])
    assert plan == [2] and _reaches(inst, plan)
    assert _cost(inst, plan) == 4.0 == _brute_force(inst, MAST, np.zeros(2, bool))


def test_a_standing_mast_costs_nothing():
    """As the first test, but a mast stands at site 1 already (cost 0 there): the
    plan on sites 0 and 1 (3 + 0 + 2 = 5) becomes site 1's sensor and one more on
    it that sees what site 0's did (0 + 2 = 2), not site 2 (3 + 1)."""
    rows = [[0, 1, 2], [3, 4, 5], [0, 1, 2, 3, 4, 5], [0, 1, 2]]
    inst = _instance(rows, 6, [0, 1, 2, 1], goal=6, cap=4)
    costs = np.array([MAST, 0.0, MAST])
    plan, _ = _improve(inst, [(0, 0), (10, 0), (5, 0)], [0, 1], mast_cost=costs)
    assert sorted(plan) == [1, 3] and _cost(inst, plan, costs) == 2.0


def test_an_optimal_plan_and_a_stopped_search_are_left_as_they_are():
    inst = _instance([[0, 1, 2], [3, 4, 5], [0, 1, 2, 3, 4, 5]], 6, [0, 1, 2], goal=6, cap=4)
    xy = [(0, 0), (10, 0), (5, 0)]
    assert _improve(inst, xy, [2]) == ([2], [])
    stop = threading.Event()
    stop.set()
    assert _improve(inst, xy, [0, 1], stop=stop) == ([0, 1], [])


def test_a_window_keeps_its_own_sensors_when_candidates_are_trimmed():
    """At most 3 candidates a window, over sites 0 and 1 (5 candidates): 3 // 2 = 1 at
    each site, the one that sees the most of the window's points ({0, 1}: what the
    plan's sensor, candidate 1, sees), the first at a tie; and the plan's own sensor."""
    rows = [[0, 1, 2], [0, 1], [0], [0, 1, 2, 3], [1]]
    inst = _instance(rows, 4, [0, 0, 0, 1, 1], goal=2, cap=4)
    w = _window(inst, [(0.0, 0.0), (5.0, 0.0)], [1], freed=[0], candidates=3)
    assert w.cols.tolist() == [0, 1, 3] and w.sites.tolist() == [0, 1]
    assert w.cols[w.start].tolist() == [1] and w.inst.goal == 2
    # Exactly as many candidates as allowed (4; 2 a site if trimmed): none is left
    # out, not even candidate 2, which sees the fewest of the window's points.
    inst = _instance(rows[:4], 4, [0, 0, 0, 1], goal=2, cap=4)
    w = _window(inst, [(0.0, 0.0), (5.0, 0.0)], [1], freed=[0], candidates=4)
    assert w.cols.tolist() == [0, 1, 2, 3]


def _window(inst, xy, chosen, freed, new_sites=6, candidates=1000):
    """The window of sites ``freed`` of the plan ``chosen``: at most ``new_sites``
    positions within 12 m, ``candidates`` candidates."""
    xy = np.asarray(xy, float)
    taken = np.isin(np.arange(len(xy)), inst.site_of[chosen])
    size = neighbourhoods.Size(len(freed), new_sites, 12.0, candidates)
    return neighbourhoods.window(
        inst, inst.site_of, xy, chosen, np.asarray(freed), cKDTree(xy), taken, size
    )


def test_the_positions_offered_are_those_that_see_most_of_the_windows_points():
    """Site 0 carries the plan's sensor (points 0, 1; point 2 is short of the goal but
    not the window's, point 3 covered by site 4's sensor, 100 m away). Of the free
    positions 5 m away, site 1 sees one of the window's points, site 2 both, site 3
    only points 2 and 3: with room for one, site 2 is offered; with room for three,
    sites 1 and 2, never site 3 (it sees none of the window's points)."""
    rows = [[0, 1], [0], [0, 1], [2, 3], [3]]
    inst = _instance(rows, 4, [0, 1, 2, 3, 4], goal=3, cap=4)
    xy = [(0, 0), (5, 0), (0, 5), (-5, 0), (100, 0)]
    assert _window(inst, xy, [0, 4], freed=[0], new_sites=1).sites.tolist() == [0, 2]
    w = _window(inst, xy, [0, 4], freed=[0], new_sites=3)
    assert w.sites.tolist() == [0, 1, 2]
    # The points short of their k that the window's candidates see; the goal less
    # what site 4 covers.
    assert w.inst.n_points == 2 and w.inst.goal == 2


def test_a_point_only_one_candidate_sees_is_in_the_window():
    """Points 0-2, all needed. Site 0 carries {0} and {1}, site 1 (5 m away) {2}: 9.
    Site 0 has a third candidate that sees {1, 2}: the plan {0}, {1, 2} on site 0
    costs 5, the optimum; point 0 is seen by one candidate alone."""
    rows = [[0], [1], [2], [1, 2]]
    inst = _instance(rows, 3, [0, 0, 1, 0], goal=3, cap=4)
    plan, _ = _improve(inst, [(0, 0), (5, 0)], [0, 1, 2])
    assert sorted(plan) == [0, 3]
    assert _cost(inst, plan) == 5.0 == _brute_force(inst, MAST, np.zeros(2, bool))


def test_the_cap_holds_in_a_window():
    """At most 2 sensors a mast. Site 0 carries {0, 1} and {2, 3}, site 1 {4, 5}: 9.
    Site 2 between them has a candidate for each pair: all three there would cost 6,
    but only two fit, so 9 is the optimum and the plan stays as it is."""
    rows = [[0, 1], [2, 3], [4, 5], [0, 1], [2, 3], [4, 5]]
    inst = _instance(rows, 6, [0, 0, 1, 2, 2, 2], goal=6, cap=2)
    plan, _ = _improve(inst, [(0, 0), (10, 0), (5, 0)], [0, 1, 2])
    assert _cost(inst, plan) == 9.0 == _brute_force(inst, MAST, np.zeros(3, bool))


def test_a_mast_the_rest_makes_redundant_is_closed(monkeypatch):
    """Goal 2 of 4 points, one mast a window: site 0's sensor sees {0, 1}, site 1's
    (100 m away) {2, 3}. Site 0's window (the first, at a tie in sensors) has nothing
    left to cover: it is closed, and site 1's sensor stays (cost 4)."""
    monkeypatch.setattr(neighbourhoods, "SIZES", ONE_MAST)
    inst = _instance([[0, 1], [2, 3]], 4, [0, 1], goal=2, cap=4)
    assert _improve(inst, [(0, 0), (100, 0)], [0, 1]) == ([1], [[1]])
    # A goal of nothing: no sensor is needed at all.
    inst = _instance([[0, 1]], 2, [0], goal=0, cap=4)
    assert _improve(inst, [(0, 0)], [0]) == ([], [[]])


def test_passes_go_on_while_a_window_changes_the_plan(monkeypatch):
    """One mast a window, every point needed. Site 0 (100 m away from the rest)
    carries {0}; site 1 carries {1, 2} and {3, 4}: 9. Site 2, 5 m from site 1, sees
    all five points. Site 0's window comes first (fewer sensors) and finds nothing;
    site 1's moves its mast to site 2 (8); then, in a second pass, site 0's window
    has nothing left to cover: 4, the optimum."""
    monkeypatch.setattr(neighbourhoods, "SIZES", ONE_MAST)
    rows = [[0], [1, 2], [3, 4], [0, 1, 2, 3, 4]]
    inst = _instance(rows, 5, [0, 1, 1, 2], goal=5, cap=4)
    plan, yielded = _improve(inst, [(0, 0), (100, 0), (105, 0)], [0, 1, 2])
    assert [_cost(inst, p) for p in yielded] == [8.0, 4.0] and plan == [3]
    assert _brute_force(inst, MAST, np.zeros(3, bool)) == 4.0


def test_each_window_solve_is_handed_the_stop_a_cutoff_and_a_time_limit(monkeypatch):
    """The MILP of each window gets the search's stop, a cutoff just below the
    window's own cost, at most ``WINDOW_S`` seconds (never past the deadline) and a
    limit on candidates that lets it solve the window it is given (trimmed already);
    a stopped search solves nothing."""
    calls = []
    real = neighbourhoods.sensors_on_sites

    def spy(inst, site_of, sites, start, mc, sc, deadline, stop, cutoff, most_multi):
        calls.append((deadline, stop, cutoff, most_multi, time.perf_counter()))
        return (yield from real(inst, site_of, sites, start, mc, sc, deadline, stop,
                                cutoff=cutoff, most_multi=most_multi))  # fmt: skip

    monkeypatch.setattr(neighbourhoods, "sensors_on_sites", spy)
    inst = _instance([[0, 1, 2], [3, 4, 5], [0, 1, 2, 3, 4, 5]], 6, [0, 1, 2], goal=6, cap=4)
    xy = np.array([(0.0, 0), (10, 0), (5, 0)])
    stop = threading.Event()
    for deadline in (time.perf_counter() + 3600.0, time.perf_counter() + 2.0):
        calls.clear()
        go = neighbourhoods.improve(inst, inst.site_of, xy, [0, 1], MAST, 1.0, deadline, stop)
        assert steps(go)[0] == [2]
        limit, handed, cutoff, most, at = calls[0]
        # Every candidate of the window (sites 0-2, one each): none is left unsolved.
        assert handed is stop and most == 3
        assert cutoff == pytest.approx(8.0 - neighbourhoods.EPS, abs=1e-12)
        assert limit <= min(deadline, at + neighbourhoods.WINDOW_S)
        assert limit >= min(deadline, at + neighbourhoods.WINDOW_S) - 0.5
    stop.set()
    calls.clear()
    go = neighbourhoods.improve(inst, inst.site_of, xy, [0, 1], MAST, 1.0, None, stop)
    assert steps(go)[0] == [0, 1] and calls == []


@settings(max_examples=40, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(st.data())
def test_on_random_grounds_every_change_is_cheaper_and_meets_the_goal(data):
    """Random grounds of up to 7 candidates on up to 3 sites (k = 1 or 2, a partial
    goal), started from every candidate: each plan yielded costs less than the one
    before, the last reaches the goal, and none is below the brute-force optimum."""
    n_points = data.draw(st.integers(2, 5))
    n_cands = data.draw(st.integers(1, 7))
    rows = [
        sorted(data.draw(st.sets(st.integers(0, n_points - 1), min_size=1))) for _ in range(n_cands)
    ]
    site_of = [data.draw(st.integers(0, 2)) for _ in range(n_cands)]
    k = data.draw(st.integers(1, 2))
    everything = _instance(rows, n_points, site_of, goal=0, cap=n_cands, need=[k] * n_points)
    seen = np.asarray(everything.matrix.sum(axis=0)).ravel()
    coverable = int(np.count_nonzero(seen >= k))
    goal = data.draw(st.integers(0, coverable))
    inst = _instance(rows, n_points, site_of, goal, n_cands, need=[k] * n_points)
    xy = [(0.0, 0.0), (6.0, 0.0), (0.0, 6.0)]
    start = list(range(n_cands))
    plan, yielded = _improve(inst, xy, start)
    costs = [_cost(inst, p) for p in [start, *yielded]]
    assert all(b < a for a, b in zip(costs, costs[1:], strict=False))
    assert _reaches(inst, plan) and _cost(inst, plan) == costs[-1]
    assert costs[-1] >= _brute_force(inst, MAST, np.zeros(3, bool))


def test_a_larger_window_is_tried_once_the_smaller_find_nothing(monkeypatch):
    """The ground of the second test (optimum 4: site 3, 50 m from the others, sees
    all four points with one candidate). Windows of one mast and 12 m take the plan
    from 9 to 8 and then find nothing; windows of two masts and 60 m are tried next
    and find the optimum; after that change the smallest windows are tried again, on
    the new plan (site 3 alone)."""
    small = neighbourhoods.Size(1, 6, 12.0, 100)
    large = neighbourhoods.Size(2, 6, 60.0, 100)
    monkeypatch.setattr(neighbourhoods, "SIZES", (small, large))
    sizes = []
    real = neighbourhoods.window

    def spy(inst, site_of, site_xy, chosen, freed, tree, taken, size):
        sizes.append((size, sorted(set(site_of[chosen].tolist()))))
        return real(inst, site_of, site_xy, chosen, freed, tree, taken, size)

    monkeypatch.setattr(neighbourhoods, "window", spy)
    rows = [[0], [1], [2, 3], [0, 1], [0, 1, 2, 3]]
    inst = _instance(rows, 4, [0, 0, 1, 2, 3], goal=4, cap=4)
    xy = [(0, 0), (100, 0), (5, 0), (50, 0)]
    plan, yielded = _improve(inst, xy, [0, 1, 2])
    assert [_cost(inst, p) for p in yielded] == [8.0, 4.0] and plan == [4]
    assert _brute_force(inst, MAST, np.zeros(4, bool)) == 4.0
    # Small windows: site 1's (nothing within 12 m), site 0's (to site 2: 8), then
    # the same two again (site 1's seen before, site 2's nothing). Then large ones:
    # site 1's takes its nearest mast, site 2, with it (4). Then the smallest again
    # on site 3, and the larger once more, both finding nothing.
    assert [size for size, _ in sizes] == [small] * 4 + [large, small, large]
    assert [plan for _, plan in sizes] == [[0, 1]] * 2 + [[1, 2]] * 3 + [[3]] * 2
    # Without the larger windows the plan stays at 8.
    monkeypatch.setattr(neighbourhoods, "SIZES", (small,))
    assert _cost(inst, _improve(inst, xy, [0, 1, 2])[0]) == 8.0
