"""Plans improved window by window (``core/optimize/neighbourhoods.py``): against
plans worked out by hand and a brute-force optimum."""

from __future__ import annotations

import threading

import numpy as np
from scipy.spatial import cKDTree

from autoscoop_blender.core.optimize import neighbourhoods
from autoscoop_blender.core.optimize.cover import plan_price
from tests.core.test_joint import _brute_force, _instance
from tests.core.test_lp import steps

MAST = 3.0


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
    one candidate (the optimum, 4) but lies beyond ``RADIUS_M`` of each: the plan
    goes from 9 to 8, site 1's sensor kept."""
    monkeypatch.setattr(neighbourhoods, "WINDOW_MASTS", 1)
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
    monkeypatch.setattr(neighbourhoods, "WINDOW_MASTS", 1)
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


def test_a_window_keeps_its_own_sensors_when_candidates_are_trimmed(monkeypatch):
    """At most 2 candidates a window, over sites 0 and 1 (one each): at each site the
    one that sees the most of the window's points ({0, 1}: what the plan's sensor,
    candidate 1, sees), the first at a tie, and the plan's own sensor as well."""
    monkeypatch.setattr(neighbourhoods, "WINDOW_CANDIDATES", 2)
    rows = [[0, 1, 2], [0, 1], [0], [0, 1, 2, 3]]
    inst = _instance(rows, 4, [0, 0, 1, 1], goal=2, cap=4)
    xy = np.array([(0.0, 0.0), (5.0, 0.0)])
    taken = np.array([True, False])
    w = neighbourhoods.window(inst, inst.site_of, xy, [1], np.array([0]), cKDTree(xy), taken)
    assert w is not None
    assert w.cols.tolist() == [0, 1, 3] and w.sites.tolist() == [0, 1]
    assert w.cols[w.start].tolist() == [1] and w.inst.goal == 2
