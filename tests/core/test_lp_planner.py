"""The lp optimizer's own steps (``optimize/lp.py``) on hand-made candidate sets: the
instance of what is left, the costs and bounds it hands on, the plans it rounds from
an LP, the order it fixes them in and why it stops. Every expected value is worked
out on paper from the rows in each test; the solvers run for real (HiGHS)."""

import inspect
import itertools
import logging
import math
import threading
import time
from dataclasses import replace
from types import SimpleNamespace

import numpy as np
import pytest

from autoscoop_blender.core import budget
from autoscoop_blender.core.candidates import CandidateSet
from autoscoop_blender.core.model.sensors import PAPER_CAMERA, SensorPose
from autoscoop_blender.core.optimize import bound as bound_module
from autoscoop_blender.core.optimize import joint as joint_module
from autoscoop_blender.core.optimize import lp as lp_module
from autoscoop_blender.core.optimize import planner as planner_module
from autoscoop_blender.core.optimize.base import FixedSensor, Solution, StopReason
from autoscoop_blender.core.optimize.bound import LPSolution, SiteSolution
from autoscoop_blender.core.optimize.cover import Cover, CoverInstance
from autoscoop_blender.core.optimize.planner import LPPlanner
from autoscoop_blender.core.settings import OptimizeSettings
from tests.core.test_lp import instance as rows_instance
from tests.core.test_lp import steps


class HandLP:
    """What the lp optimizer reads of a Problem, on hand-made candidates: candidate c
    stands at site ``site_of[c]`` (x = 10 m per site), looks at pitch 10, yaw 10 c
    (its own orientation) and covers the points ``rows[c]``."""

    def __init__(
        self,
        rows,
        n_points,
        site_of,
        need=None,
        goal=None,
        standing=None,
        sensor_costs=(1.0,),
        model=None,
        max_sensors=None,
        **settings,
    ):
        n = len(rows)
        site_of = np.asarray(site_of, dtype=np.int64)
        n_sites = int(site_of.max()) + 1
        self.rows = rows
        self.need = np.ones(n_points, np.int32) if need is None else np.asarray(need, np.int32)
        self.rho = 1.0
        self.goal = n_points if goal is None else goal
        self.n_targets = n_points
        self.max_sensors = max_sensors or 2 * n
        self.sensor_costs = np.asarray(sensor_costs, dtype=float)
        model = np.zeros(n, np.int64) if model is None else np.asarray(model, np.int64)
        angles = np.array([(10.0, 10.0 * c) for c in range(n)])
        self.candidates = CandidateSet(
            positions=np.array([(10.0 * s, 0.0) for s in range(n_sites)]),
            angles=(angles,) * len(self.sensor_costs),
            models=(PAPER_CAMERA,) * len(self.sensor_costs),
            position=site_of,
            orientation=np.arange(n, dtype=np.int64),
            model=model,
            matrix=rows_instance(rows, n_points, self.goal).matrix,
        )
        standing = np.zeros(n_sites, bool) if standing is None else np.asarray(standing)
        self.space = SimpleNamespace(standing=standing, step=4.0)
        self.grid = SimpleNamespace(target_xy=np.zeros((n_points, 2)), spacing=2.0)
        self.settings = OptimizeSettings(optimizer="lp", **settings)
        self.estimate = SimpleNamespace(parts=1)  # planned whole
        self.t0 = time.perf_counter()  # the run's clock

    def reached(self, n_covered):
        return n_covered >= self.goal

    def pose(self, x, y, pitch, yaw, model=0):
        return SensorPose(float(x), float(y), 6.0, 6.0, float(pitch), float(yaw))

    def evaluate(self, pose, model=0):
        points = self.rows[round(pose.yaw_deg / 10.0)]
        return SimpleNamespace(covered=np.array(points, dtype=np.int64), rays=1)


def solve(problem, solution=None):
    """(the solution, the progress reports) of the lp optimizer on ``problem``."""
    if solution is None:
        solution = Solution(np.zeros(problem.n_targets, bool), need=problem.need)
    return steps(LPPlanner().solve(problem, solution))


def poses_of(solution):
    """The candidates fixed, by their yaw, in order."""
    return [round(s.pose.yaw_deg / 10.0) for s in solution.sensors]


def spy(monkeypatch, *names, module=lp_module):
    """Wrap ``module``'s ``names`` (functions it calls; lp.py's by default): each
    call's arguments by name, the defaults filled in, and under "returned" what it
    returned, listed per name."""
    calls = {name: [] for name in names}
    for name in names:
        real = getattr(module, name)

        def wrapper(*args, _real=real, _name=name, **kwargs):
            bound = inspect.signature(_real).bind(*args, **kwargs)
            bound.apply_defaults()
            call = dict(bound.arguments)
            calls[_name].append(call)
            call["returned"] = _real(*args, **kwargs)
            return call["returned"]

        monkeypatch.setattr(module, name, wrapper)
    return calls


# ---------------------------------------------------------------- what is left


def test_the_instance_drops_covered_points_and_taken_candidates():
    """Points 0..4 with k = 1, 2, 2, 1, 1; point 0 covered, points 0 and 2 seen once
    already; candidate 0 taken. Left: points 1..4 needing 2, 1, 1, 1; point 1 is seen
    by candidate 1 alone (candidate 0 no longer counts), point 4 by none: 2 coverable
    of the 4 points left, so the goal is 2 (of 5 - 1)."""
    rows = [[0, 1], [1, 2], [2, 3], [0]]
    problem = HandLP(rows, 5, [0, 0, 1, 1], need=[1, 2, 2, 1, 1])
    covered = np.array([True, False, False, False, False])
    counts = np.array([1, 0, 1, 0, 0], np.int32)
    inst = lp_module.instance(problem.candidates, problem, covered, counts, np.array([0]))
    dense = inst.matrix.toarray()
    assert dense.tolist() == [[0, 0, 0, 0], [1, 1, 0, 0], [0, 1, 1, 0], [0, 0, 0, 0]]
    assert inst.k.tolist() == [2, 1, 1, 1] and inst.goal == 2
    assert inst.site_of.tolist() == [0, 0, 1, 1] and inst.cap == 4
    assert inst.xy.shape == (4, 2)
    # Candidate 0 not taken: point 1 is seen twice, its k; 3 coverable.
    free = lp_module.instance(problem.candidates, problem, covered, counts)
    assert free.matrix.toarray()[0].tolist() == [1, 0, 0, 0] and free.goal == 3
    assert lp_module.instance(problem.candidates, problem, covered, counts, np.zeros(0)).goal == 3


def test_the_instance_of_a_fresh_start_and_points_already_at_their_k():
    """Nothing covered: every column stays, the goal is the problem's (4 of the 5
    points, all coverable but point 4). A point not marked covered whose counts reach
    its k still needs one candidate (k clipped to 1)."""
    rows = [[0, 1], [1, 2], [2, 3], [0]]
    problem = HandLP(rows, 5, [0, 0, 1, 1], need=[1, 2, 2, 1, 1], goal=4)
    none = np.zeros(5, bool)
    inst = lp_module.instance(problem.candidates, problem, none)
    assert inst.matrix.shape == (4, 5) and inst.matrix.nnz == 7
    assert inst.k.tolist() == [1, 2, 2, 1, 1] and inst.goal == 4
    # Points 1 and 2 seen twice already: k 1 each; now 4 points are coverable.
    counts = np.array([0, 2, 2, 0, 0], np.int32)
    at_k = lp_module.instance(problem.candidates, problem, none, counts)
    assert at_k.k.tolist() == [1, 1, 1, 1, 1] and at_k.goal == 4
    # The goal is what can be covered when that is less: point 1 needs 3, seen by 2.
    short = HandLP(rows, 5, [0, 0, 1, 1], need=[1, 3, 1, 1, 1])
    assert lp_module.instance(short.candidates, short, none).goal == 3


def test_the_bound_scope_counts_positions_yaws_and_pitches():
    """Three positions; the first model's angles hold 2 pitches and 3 yaws."""
    problem = HandLP([[0], [0], [0]], 1, [0, 1, 2])
    angles = np.array([(10.0, 0.0), (10.0, 90.0), (20.0, 0.0), (20.0, 90.0), (20.0, 180.0)])
    cands = replace(problem.candidates, angles=(angles, np.zeros((1, 2))))
    assert lp_module.bound_scope(cands, problem) == (
        "plans on the candidate set: 3 mast positions on a 4 m lattice x 3 yaws x 2 "
        "pitches; the 2 m target grid"
    )


# ---------------------------------------------------------------- costs


def test_plan_cost_per_objective():
    """Candidates at sites 0, 0, 1, 2; the plan 0, 1, 2 uses sites 0 and 1: 2 masts,
    3 sensors; at a mast cost of 5 and sensor costs 1, 2, 4, 8 it costs 10 + 7."""
    cands = HandLP([[0]] * 4, 1, [0, 0, 1, 2]).candidates
    plan = [0, 1, 2]
    assert lp_module.plan_cost(cands, plan, "sensors", 5.0, 2.0) == (3.0, 2)
    assert lp_module.plan_cost(cands, plan, "masts", 5.0, 2.0) == (2 + 3e-6, 2)
    assert lp_module.plan_cost(cands, plan, "cost", 5.0, 2.0) == (16.0, 2)
    prices = np.array([1.0, 2.0, 4.0, 8.0])
    assert lp_module.plan_cost(cands, plan, "cost", 5.0, prices) == (17.0, 2)
    # A mast stands at site 0 already: one new mast.
    standing = np.array([True, False, False])
    assert lp_module.plan_cost(cands, plan, "cost", 5.0, prices, standing) == (12.0, 1)
    assert lp_module.plan_cost(cands, plan, "masts", 5.0, 1.0, standing)[1] == 1
    # Two sensors at site 0: above a cap of 1, within a cap of 2.
    assert lp_module.plan_cost(cands, plan, "cost", 5.0, prices, standing, 1) == (math.inf, 1)
    assert lp_module.plan_cost(cands, plan, "cost", 5.0, prices, None, 2) == (17.0, 2)
    assert lp_module.plan_cost(cands, [], "cost", 5.0, prices, None, 1) == (0.0, 0)


def test_plan_value_reads_the_settings():
    """The plan 0, 1, 2 of sites 0, 0, 1: 2 masts at 3 (the default), sensors at 1.5;
    with a mast standing at site 1, one; two models (1 and 4) priced per candidate;
    a cap of 1 sensor per mast."""
    rows = [[0]] * 3
    plain = HandLP(rows, 1, [0, 0, 1], sensor_costs=(1.5,))
    assert lp_module.plan_value(plain, plain.candidates, [0, 1, 2]) == 3 * 2 + 1.5 * 3
    standing = HandLP(rows, 1, [0, 0, 1], standing=[False, True], sensor_costs=(1.5,))
    assert lp_module.plan_value(standing, standing.candidates, [0, 1, 2]) == 3 + 4.5
    mixed = HandLP(rows, 1, [0, 0, 1], sensor_costs=(1.0, 4.0), model=[0, 1, 1])
    assert lp_module.plan_value(mixed, mixed.candidates, [0, 1, 2]) == 6 + 9
    capped = HandLP(rows, 1, [0, 0, 1], max_sensors_per_mast=1, objective="sensors")
    assert lp_module.plan_value(capped, capped.candidates, [0, 2]) == 2.0
    assert lp_module.plan_value(capped, capped.candidates, [0, 1, 2]) == math.inf


@pytest.mark.parametrize(
    "objective, standing, mast, sensor",
    [
        ("sensors", None, 0.0, 1.0),
        ("masts", None, 8.0, 1.0),  # one mast outweighs all 7 candidates
        ("cost", None, 3.0, 2.0),
        ("masts", [True, False], [0.0, 8.0], 1.0),
        ("cost", [False, True], [3.0, 0.0], 2.0),
        ("sensors", [False, True], 0.0, 1.0),
    ],
)
def test_mast_aware_costs_per_objective(objective, standing, mast, sensor):
    problem = HandLP(
        [[0]] * 3, 1, [0, 0, 1], standing=standing, sensor_costs=(2.0,), objective=objective
    )
    got_mast, got_sensor = lp_module.mast_aware_costs(problem, problem.candidates, 7)
    assert np.asarray(got_mast).tolist() == mast and got_sensor == sensor
    assert np.ndim(got_mast) == np.ndim(mast)


def test_mast_aware_costs_price_each_candidate_by_its_model():
    problem = HandLP([[0]] * 3, 1, [0, 0, 1], sensor_costs=(1.0, 3.0), model=[0, 1, 1])
    mast, sensor = lp_module.mast_aware_costs(problem, problem.candidates, 7)
    assert mast == 3.0 and sensor.tolist() == [1.0, 3.0, 3.0]


# ---------------------------------------------------------------- two solvers side by side


def test_both_interleaves_two_generators_and_returns_both_values():
    def gen(name, n, log):
        try:
            for k in range(n):
                yield f"{name}{k}"
            return name.upper()
        finally:
            log.append(name)

    log = []
    got, yielded = steps(lp_module._both(gen("a", 3, log), gen("b", 1, log)))
    assert got == ("A", "B") and yielded == ["a0", "b0", "a1", "a2"]
    assert log == ["b", "a"]  # each ended once, when it was done
    got, yielded = steps(lp_module._both(gen("a", 0, []), gen("b", 2, [])))
    assert got == ("A", "B") and yielded == ["b0", "b1"]
    # Closed half way, both generators still running are closed.
    log = []
    both = lp_module._both(gen("a", 3, log), gen("b", 3, log))
    assert [next(both), next(both)] == ["a0", "b0"]
    both.close()
    assert sorted(log) == ["a", "b"]
    # One done already: only the other is closed (the done one ended by itself once).
    log = []
    both = lp_module._both(gen("a", 0, log), gen("b", 3, log))
    assert next(both) == "b0" and log == ["a"]
    both.close()
    assert log == ["a", "b"]


# ---------------------------------------------------------------- bounds handed on


def _lp(bound, columns=(0,), x=(1.0,), reduced=None, rounds=3):
    n = 4
    return LPSolution(
        value=bound,
        bound=bound,
        columns=np.asarray(columns, np.int64),
        x=np.asarray(x, float),
        priced=np.zeros(n),
        reduced=np.ones(n) if reduced is None else np.asarray(reduced, float),
        rounds=rounds,
        complete=True,
    )


def test_plan_bound_with_one_price(monkeypatch):
    """An LP bound of 2.2 proves 3 sensors; at a sensor cost of 2, 6 for the sensors;
    the mast-aware bound gets the per-site mast costs and the one price."""
    calls = []

    def fake_bound(lp, position, mast, sensor, price=None):
        calls.append((lp.bound, position.tolist(), np.asarray(mast).tolist(), sensor, price))
        return 42.0

    monkeypatch.setattr(lp_module, "mast_aware_bound", fake_bound)
    problem = HandLP(
        [[0]] * 4, 1, [0, 0, 1, 1], standing=[True, False], sensor_costs=(2.0,), mast_cost=5.0
    )
    sites = SiteSolution(2, np.array([0, 1]), np.zeros(0, np.int64))
    got = lp_module._plan_bound(_lp(2.2), sites, problem.candidates, problem)
    assert (got.sensors, got.masts, got.lp, got.rounds) == (3, 2, 2.2, 3)
    assert got.cost_lp == 42.0 and got.sensor_cost_lp == 6.0
    assert got.scope.startswith("plans on the candidate set: 2 mast positions")
    assert calls == [(2.2, [0, 0, 1, 1], [0.0, 5.0], 2.0, None)]
    # For the sensors objective the price is the settings' sensor_cost.
    sensors = HandLP([[0]] * 4, 1, [0, 0, 1, 1], objective="sensors", sensor_cost=1.5)
    got = lp_module._plan_bound(_lp(2.0), sites, sensors.candidates, sensors)
    assert got.sensors == 2 and got.sensor_cost_lp == 3.0 and calls[-1][3] == 1.5


def test_plan_bound_with_a_price_per_model(monkeypatch):
    """Models at 1 and 2.5: an LP of sensor costs 7.5 (+ rounding noise) proves 3
    sensors (none costs more than 2.5), and 7.5 for the sensors."""
    calls = []
    monkeypatch.setattr(
        lp_module,
        "mast_aware_bound",
        lambda lp, position, mast, sensor, price=None: calls.append((sensor, price)) or 9.0,
    )
    problem = HandLP(
        [[0]] * 4, 1, [0, 0, 1, 1], sensor_costs=(1.0, 2.5), model=[0, 1, 1, 0], mast_cost=5.0
    )
    sites = SiteSolution(1, np.array([0]), np.zeros(0, np.int64))
    got = lp_module._plan_bound(_lp(7.5 + 1e-9), sites, problem.candidates, problem)
    assert (got.sensors, got.masts, got.cost_lp) == (3, 1, 9.0)
    assert got.sensor_cost_lp == pytest.approx(7.5) and got.lp == got.sensor_cost_lp
    assert calls[0][0] == 1.0 and calls[0][1].tolist() == [1.0, 2.5, 2.5, 1.0]
    assert lp_module._plan_bound(_lp(7.6), sites, problem.candidates, problem).sensors == 4
    free = HandLP([[0]] * 2, 1, [0, 1], sensor_costs=(0.0, 0.0, 1.0), model=[0, 1])
    assert lp_module._plan_bound(_lp(0.0), sites, free.candidates, free).sensors == 0


def test_the_masts_bound_counts_the_fewest_sensors_at_the_cap(monkeypatch):
    """An LP of 4.6 proves 5 sensors. At 2 a mast they need 3 masts where the
    fewest-masts MILP proved 1; a standing mast takes 2 of them (2 new masts); at 4
    a mast 2; with 3 standing, the MILP's 1 stands. The cost bound at 3 a mast is
    3 x 3 + 5 = 14."""
    monkeypatch.setattr(lp_module, "mast_aware_bound", lambda *args: 0.0)
    sites = SiteSolution(1, np.array([0]), np.zeros(0, np.int64))

    def masts(cap, standing=()):
        flags = [s in standing for s in range(4)]
        problem = HandLP([[0]] * 4, 1, [0, 1, 2, 3], standing=flags, max_sensors_per_mast=cap)
        return lp_module._plan_bound(_lp(4.6), sites, problem.candidates, problem)

    got = masts(2)
    assert (got.sensors, got.masts) == (5, 3)
    assert got.objective("cost", 3.0, 1.0) == 14.0 and got.objective("masts", 3.0, 1.0) == 3
    assert masts(2, standing=(0,)).masts == 2
    assert masts(4).masts == 2
    assert masts(2, standing=(0, 1, 2)).masts == 1
    assert [lp_module.capped_masts(n, 4, 0) for n in (0, 1, 4, 5, 8, 9)] == [0, 1, 1, 2, 2, 3]
    assert lp_module.capped_masts(9, 4, 2) == 1 and lp_module.capped_masts(9, 4, 3) == 0


@pytest.mark.parametrize(
    "bound, value, standing, starts",
    [
        (20.2, 21.0, (), True),  # 21 sensors need 6 masts at 4, and 6 are proven now
        (19.5, 21.0, (), False),  # 20 proven: 5 masts; the LP may end at 21, 6 masts
        (19.5, 20.0, (), True),  # it cannot end above 20: 5 masts either way
        (10.0, 15.0, (), True),  # the fewest masts' 5 hold 20: the cap moves nothing
        (10.0, 21.5, (0,), True),  # a standing mast holds 4: 5 new hold 24 with it
        (10.0, math.inf, (), False),  # no optimal restricted LP yet: no upper end
    ],
)
def test_the_joint_lp_waits_while_the_sensors_lp_may_still_raise_its_masts(
    bound, value, standing, starts
):
    """The fewest masts are 5, the cap 4. While the sensors LP works (proven so far
    ``bound``, its restricted LP at ``value``, never below the LP's), the joint LP
    starts only when the masts that the sensors need at the cap cannot rise above
    where it would start: ceil(ceil(value) / 4) new masts, less the standing ones,
    at most max(5, ceil(ceil(bound) / 4)). Once the LP has ended it starts anyway."""
    flags = [s in standing for s in range(3)]
    problem = HandLP([[0], [1], [2]], 3, [0, 1, 2], standing=flags, max_sensors_per_mast=4)
    inst = rows_instance(problem.rows, 3, 3)
    start = lp_module._JointStart(problem, problem.candidates, inst, 100.0, None, None)
    start.sites = SiteSolution(5, np.arange(3), np.zeros(0, np.int64))
    duals = np.ones(3)
    start.latest = bound_module.LPProgress(4, value, bound, 3, duals, np.arange(3))
    got = start._start()
    assert (got is not None) == starts
    if starts:
        assert got[2] == math.ceil(bound)
    start.lp = replace(_lp(bound), pi=duals)
    assert start._start() is not None


# ---------------------------------------------------------------- plans from the LP


def test_the_pool_is_the_lps_columns_and_the_nearly_as_good():
    lp = _lp(1.0, columns=(3, 0), x=(1.0, 0.5), reduced=(0.5, 0.2, 0.25, 0.9))
    assert lp_module._pool(lp).tolist() == [0, 1, 3]


def test_plans_are_rounded_from_the_lp_at_each_threshold_and_stay_in_the_pool():
    """Points 0..3; candidate 0 covers 0, 1; 1 covers 2; 2 covers 2, 3; 3 covers all
    but is out of the pool (not a column, reduced cost 1). At LP values 1, 0.6 and
    0.25 each threshold keeps 0 (and 1, 2 below 0.6 and 0.25), completes with 2 and
    prunes 1: five plans of 0 and 2, never 3."""
    inst = rows_instance([[0, 1], [2], [2, 3], [0, 1, 2, 3]], 4, 4)
    lp = _lp(2.0, columns=(0, 1, 2), x=(1.0, 0.6, 0.25), reduced=(0.0, 0.0, 0.0, 1.0))
    plans = list(lp_module._lp_plans(inst, lp))
    assert [sorted(p) for p in plans] == [[0, 2]] * 5
    # Without candidate 2 in the pool no plan reaches the goal: none is given.
    lp = _lp(2.0, columns=(0, 1), x=(1.0, 0.6), reduced=(0.0, 0.0, 1.0, 1.0))
    assert list(lp_module._lp_plans(inst, lp)) == []


def test_plans_from_the_lp_are_completed_per_cost():
    """Point 0 alone is left; candidate 1 (cost 1) and 2 (cost 5) cover it, both in
    the pool; per cost the plan takes 1, per point the first, 1 as well; at costs
    5, 1 it takes 2."""
    inst = rows_instance([[1], [0], [0]], 2, 2)
    lp = _lp(2.0, columns=(0,), x=(1.0,), reduced=(0.0, 0.0, 0.0, 1.0))
    cheap = list(lp_module._lp_plans(inst, lp, np.array([1.0, 1.0, 5.0])))
    assert [sorted(p) for p in cheap] == [[0, 1]] * 5
    dear = list(lp_module._lp_plans(inst, lp, np.array([1.0, 5.0, 1.0])))
    assert [sorted(p) for p in dear] == [[0, 2]] * 5


def test_the_plan_is_fixed_in_greedy_order():
    """k = 1: 1 (3 points) first, then 0 (point 3), then 2 (nothing new); of 0 and
    2 alone, 2 (2 points) first. k = 2: after 1, candidate 2 raises points 0 and 1
    to their k, 0 only point 3."""
    rows = [[3], [0, 1, 2], [0, 1]]
    inst = rows_instance(rows, 4, 4)
    assert lp_module.in_gain_order(inst, [0, 1, 2]) == [1, 0, 2]
    assert lp_module.in_gain_order(inst, [0, 2]) == [2, 0]
    k2 = CoverInstance(inst.matrix, 4, need=np.full(4, 2, np.int32))
    assert lp_module.in_gain_order(k2, [0, 1, 2]) == [1, 2, 0]
    assert lp_module.in_gain_order(k2, []) == []


# ---------------------------------------------------------------- the solves

# Points 0..6. Greedy takes 0 (4 points), then 1 (4, 6), then 2 (5): 3 sensors on 3
# masts; 1 and 2 alone cover all (points 4 and 6 only 1 sees, 5 only 2): the LP is 2.
GREEDY_TRAP = [[0, 1, 2, 3], [0, 1, 4, 6], [2, 3, 5]]


def test_the_fewest_masts_then_a_plan_on_them():
    """Site 0 holds 0 (points 0, 1), 1 (2, 3) and 2 (4, 5); site 1 holds 3 (4, 5).
    Site 0 alone covers all: one mast, and the plan on it is 0, 1, 2."""
    rows = [[0, 1], [2, 3], [4, 5], [4, 5]]
    problem = HandLP(rows, 6, [0, 0, 0, 1], objective="sensors")
    inst = lp_module.instance(problem.candidates, problem, np.zeros(6, bool))
    go = lp_module.masts_then_plan
    sites, plan = steps(go(problem, problem.candidates, inst, None, None, True))[0]
    assert sites.bound == 1 and sites.sites.tolist() == [0] and sites.lp_sites.tolist() == [0]
    assert sorted(plan) == [0, 1, 2]
    sites, plan = steps(go(problem, problem.candidates, inst, None, None, False))[0]
    assert sites.bound == 1 and plan is None
    # Asked to stop (here before it starts): no plan on the sites.
    stop = threading.Event()
    stop.set()
    assert steps(go(problem, problem.candidates, inst, None, stop, True))[0][1] is None
    # Only the LP over sites: no set of sites of its own, the plan on the LP's.
    sites, plan = steps(go(problem, problem.candidates, inst, None, None, True, False))[0]
    assert sites.sites.tolist() == [] and sites.bound == 1 and sorted(plan) == [0, 1, 2]


@pytest.mark.parametrize("most, sensors", [(1000, 2), (2, 3)])
def test_at_k_2_a_large_mast_aware_milp_is_not_solved(most, sensors):
    """k = 2 on site 0's three candidates (each sees points 0, 1), started from all
    three: the MILP finds two of them enough when it may run on 3 candidates, and the
    start is the answer when at most 2 are allowed at k > 1."""
    problem = HandLP([[0, 1], [0, 1], [0, 1]], 2, [0, 0, 0], need=[2, 2], objective="cost")
    inst = lp_module.instance(problem.candidates, problem, np.zeros(2, bool))
    site_of = problem.candidates.position
    go = bound_module.sensors_on_sites(
        inst, site_of, np.array([0]), [0, 1, 2], 3.0, 1.0, most_multi=most
    )
    plan = steps(go)[0]
    assert len(set(plan)) == len(plan) == sensors and set(plan) <= {0, 1, 2}


def test_a_full_mast_takes_the_rest_from_another_site():
    """As above with at most 2 sensors a mast: site 0 cannot hold all three, so point
    4, 5 goes to candidate 3 on site 1 (0 and 1 are the only ones that see 0..3)."""
    rows = [[0, 1], [2, 3], [4, 5], [4, 5]]
    for objective in ("sensors", "cost", "masts"):
        problem = HandLP(rows, 6, [0, 0, 0, 1], objective=objective, max_sensors_per_mast=2)
        inst = lp_module.instance(problem.candidates, problem, np.zeros(6, bool))
        go = lp_module.masts_then_plan(problem, problem.candidates, inst, None, None, True)
        sites, plan = steps(go)[0]
        assert sites.bound == 1 and sorted(plan) == [0, 1, 3]
    # One site with a cap of 1 and two candidates needed: no plan at all.
    problem = HandLP([[0], [1]], 2, [0, 0], max_sensors_per_mast=1)
    inst = lp_module.instance(problem.candidates, problem, np.zeros(2, bool))
    go = lp_module.masts_then_plan(problem, problem.candidates, inst, None, None, True)
    sites, plan = steps(go)[0]
    assert sites.bound == 1 and plan is None


def _bound_run(problem, plan=False):
    """(bound, lp, plan on the fewest masts, greedy covers), the progress reports."""
    inst = lp_module.instance(problem.candidates, problem, np.zeros(problem.n_targets, bool))
    solution = Solution(np.zeros(problem.n_targets, bool))
    go = lp_module.prove_bound(problem, problem.candidates, inst, solution, None, plan=plan)
    return steps(go)


def test_prove_bound_reports_the_greedy_plan_and_the_lp_as_it_rises():
    """GREEDY_TRAP on three sites: greedy's 3 sensors against an LP of 2 sensors and
    2 masts."""
    problem = HandLP(GREEDY_TRAP, 7, [0, 1, 2], objective="sensors")
    (bound, lp, on_sites, (greedy, greedy_masts)), reports = _bound_run(problem)
    assert sorted(greedy.chosen) == [0, 1, 2] and on_sites is None
    assert sorted(greedy_masts.chosen) == [0, 1, 2]  # a mast costs nothing for "sensors"
    assert (bound.sensors, bound.masts, bound.lp) == (2, 2, pytest.approx(2.0, abs=1e-4))
    assert lp.complete and {r.best for r in reports} == {3.0}
    assert {r.phase for r in reports} == {"search"}
    proven = [r.bound for r in reports if r.bound is not None]
    assert max(proven) == pytest.approx(2.0, abs=1e-4) and reports[-1].bound == max(proven)
    assert proven == sorted(proven)  # it only rises
    # The same for cost, at 2 a sensor: the LP proves 4 as soon as it is solved.
    cost = HandLP(GREEDY_TRAP, 7, [0, 1, 2], sensor_costs=(2.0,))
    (bound, *_), reports = _bound_run(cost)
    assert {r.best for r in reports} == {3 * 3 + 2 * 3}
    assert max(r.bound for r in reports if r.bound is not None) == pytest.approx(4.0, abs=1e-4)
    # For masts the LP proves nothing on the way.
    masts = HandLP(GREEDY_TRAP, 7, [0, 1, 2], objective="masts")
    (bound, *_), reports = _bound_run(masts)
    assert bound.masts == 2 and {r.bound for r in reports} == {None}
    assert {r.best for r in reports} == {3 + 3e-6}


def test_the_plan_on_the_fewest_masts_is_the_best_so_far_while_the_lp_works(monkeypatch):
    """GREEDY_TRAP with a plan: the plan on the fewest masts (1 and 2: 2 sensors, where
    greedy has 3) is reported as soon as it is found, while a slow LP (here 40 waits
    before its rounds) has proven nothing yet."""
    problem = HandLP(GREEDY_TRAP, 7, [0, 1, 2], objective="sensors")
    real = lp_module.cover_lp

    def slow_lp(*args, **kwargs):
        for _ in range(40):
            yield None
        return (yield from real(*args, **kwargs))

    monkeypatch.setattr(lp_module, "cover_lp", slow_lp)
    (bound, _, on_sites, _), reports = _bound_run(problem, plan=True)
    assert sorted(on_sites) == [1, 2] and bound.sensors == 2
    first_plan = next(i for i, r in enumerate(reports) if r.best == 2.0)
    first_bound = next(i for i, r in enumerate(reports) if r.bound is not None and r.bound > 1)
    assert reports[0].best == 3.0 and first_plan < first_bound
    assert all(r.best == 2.0 for r in reports[first_plan:])  # it never goes back


def test_prove_bound_with_models_of_different_costs():
    """Candidate 2 of model 1 costs 3: the LP prices it (1 + 3 = 4 for the plan of 1
    and 2), and the count follows through the dearest model: 4 / 3 -> 2."""
    problem = HandLP(GREEDY_TRAP, 7, [0, 1, 2], sensor_costs=(1.0, 3.0), model=[0, 0, 1])
    (bound, lp, *_), reports = _bound_run(problem)
    assert lp.complete and lp.value == pytest.approx(4.0)
    assert bound.sensor_cost_lp == pytest.approx(4.0, abs=1e-4) and bound.sensors == 2
    assert max(r.bound for r in reports if r.bound is not None) == pytest.approx(4.0, abs=1e-4)
    # Greedy per cost: 0 (4 points for 1), then 1 (2 for 1), then 2: 3 x 3 + 5.
    assert {r.best for r in reports} == {14.0}


def test_prove_bound_splits_a_large_target_and_runs_the_masts_lp_alone(monkeypatch):
    """With parts of at most 4 points, the 7 points are solved in 2 parts; the fewest
    masts then get their LP alone unless the masts are the objective."""
    monkeypatch.setattr(budget, "PART_POINTS", 4)
    calls = spy(monkeypatch, "site_cover")
    for objective in ("sensors", "masts"):
        problem = HandLP(GREEDY_TRAP, 7, [0, 1, 2], objective=objective)
        problem.grid.target_xy = np.array([(float(n), 0.0) for n in range(7)])
        (bound, lp, *_), _ = _bound_run(problem)
        assert lp.parts == 2 and bound.sensors == 2 and bound.masts == 2
    assert [call["milp"] for call in calls["site_cover"]] == [False, True]
    problem = HandLP(GREEDY_TRAP, 7, [0, 1, 2], objective="sensors")
    problem.grid.target_xy = np.zeros((7, 2))
    monkeypatch.setattr(budget, "PART_POINTS", 7)
    (bound, lp, *_), _ = _bound_run(problem)
    assert lp.parts == 1 and calls["site_cover"][-1]["milp"] is True


def test_prove_and_plan_beats_greedy_and_reports_it():
    problem = HandLP(GREEDY_TRAP, 7, [0, 1, 2], objective="sensors")
    inst = lp_module.instance(problem.candidates, problem, np.zeros(7, bool))
    solution = Solution(np.zeros(7, bool))
    go = lp_module.prove_and_plan(problem, problem.candidates, inst, solution, None)
    (plan, bound, _), reports = steps(go)
    assert sorted(plan) == [1, 2] and bound.sensors == 2
    # After the bounds: the plan on the fewest masts is already 2; then 5 LP plans.
    after = [r for r in reports if r.bound == 2.0 and r.best == 2.0]
    assert len(after) == 1 + 5 and reports[-6:] == after
    assert {(r.phase, r.rho) for r in reports} == {("search", 1.0)}


def _cheapest_by_brute_force(rows, n_points, site_of, k, cap, mast_cost=3.0):
    """The least cost (mast_cost per site used, 1 per sensor) of any set of the
    candidates ``rows`` that covers every point k times, at most ``cap`` a site."""
    best = math.inf
    for n in range(len(rows) + 1):
        for chosen in itertools.combinations(range(len(rows)), n):
            count = np.bincount([p for c in chosen for p in rows[c]], minlength=n_points)
            per_site = np.bincount([site_of[c] for c in chosen], minlength=max(site_of) + 1)
            if (count >= k).all() and per_site.max(initial=0) <= cap:
                best = min(best, mast_cost * np.count_nonzero(per_site) + n)
    return best


def test_a_plan_on_the_lps_columns_finds_what_the_fewest_masts_hide(monkeypatch):
    """k = 2, at most 2 sensors a mast. Site 1 carries two candidates that see all 4
    points: cost 3 + 2 = 5, the optimum by a search of all 64 sets. Site 2 too sees
    every point twice; the fewest masts, which do not know of the cap, choose it, and
    the plans from the masts cost 8. The LP (2 sensors: each of its columns sees all
    4 points) spreads over sites 0 and 1; greedy over its columns, then closing a
    mast, gives site 1's pair."""
    rows = [[0, 1, 2, 3], [0, 1, 2, 3], [0, 1, 2, 3], [0, 1, 2], [1, 3], [0, 1, 2, 3]]
    site_of = [0, 1, 1, 2, 2, 2]
    assert _cheapest_by_brute_force(rows, 4, site_of, 2, 2) == 5
    calls = spy(monkeypatch, "plan_from")
    problem = HandLP(rows, 4, site_of, need=[2] * 4, objective="cost", max_sensors_per_mast=2)
    res, _ = solve(problem)
    assert sorted(poses_of(res)) == [1, 2] and res.n_covered == 4
    on_lp = calls["plan_from"][-1]  # after the plans on the masts' sites
    assert set(on_lp["pool"].tolist()) <= {0, 1, 2, 5} and len(on_lp["pool"]) >= 2
    assert sorted(on_lp["returned"].chosen) == [1, 2]
    # Without the plan on the LP's columns the windows (``_then_windows``) start from
    # the masts' plan (8) and find site 1's pair too (the window of that plan's masts
    # with site 1 among the positions near them).
    real = lp_module.plan_from

    def masts_only(problem, cands, inst, pool):
        if "_then_windows" in inspect.stack()[1].function:  # mutmut renames it
            return Cover(inst)
        return real(problem, cands, inst, pool)

    monkeypatch.setattr(lp_module, "plan_from", masts_only)
    res, _ = solve(problem)
    assert sorted(poses_of(res)) == [1, 2] and res.n_covered == 4

    # Without either, the plans rounded from the LP on the plan's own masts (two,
    # site 1 among them) find site 1's pair as well.
    def unchanged(inst, site_of, site_xy, chosen, *rest):
        yield None
        return chosen

    monkeypatch.setattr(lp_module, "improve_by_windows", unchanged)
    res, _ = solve(problem)
    assert sorted(poses_of(res)) == [1, 2] and res.n_covered == 4
    # Without those too, the same run settles for two masts.
    monkeypatch.setattr(lp_module, "ON_MASTS_THRESHOLDS", ())
    res, _ = solve(problem)
    masts = len({site_of[c] for c in poses_of(res)})
    assert res.n_covered == 4 and 3 * masts + len(res.sensors) == 8


def _fixed(problem, c, existing=False, seen=True):
    """Candidate ``c`` of ``problem`` as a sensor: what it sees, all new."""
    cands = problem.candidates
    x, y = cands.positions[cands.position[c]]
    pose = problem.pose(x, y, 10.0, 10.0 * c)
    points = np.array(problem.rows[c], np.int64)
    return FixedSensor(pose, 0.0, 0, 0, points, points if seen else None, existing=existing)


def test_the_lp_optimizer_fixes_its_plan_in_greedy_order():
    problem = HandLP(GREEDY_TRAP, 7, [0, 1, 2], objective="sensors")
    res, reports = solve(problem)
    assert poses_of(res) == [1, 2]  # 1 sees 4 points, 2 then 3
    assert res.stop_reason == StopReason.reached(1.0) and res.n_covered == 7
    assert res.bound.sensors == 2 and res.bound.masts == 2
    fixed = [r for r in reports if r.phase == "fixed"]
    assert [r.sensors for r in fixed] == [1, 2] and fixed[0].fixed is res.sensors[0]


def test_the_lp_optimizer_goes_on_from_a_resumed_run():
    """Candidate 0 fixed already: points 4, 5, 6 are left, which 1 and 2 cover."""
    problem = HandLP(GREEDY_TRAP, 7, [0, 1, 2], objective="sensors")
    start = Solution(np.zeros(7, bool), need=problem.need)
    start.fix(_fixed(problem, 0))
    res, _ = solve(problem, start)
    assert poses_of(res) == [0, 1, 2] and res.n_covered == 7
    assert res.bound.sensors == 2


@pytest.mark.parametrize(
    "rows, goal, why",
    [
        (GREEDY_TRAP, 0, StopReason.reached(1.0)),  # nothing to do
        ([[], [], []], 7, StopReason.out_of_sight("candidate pose")),  # nothing seen
    ],
)
def test_the_lp_optimizer_with_nothing_to_plan(rows, goal, why):
    problem = HandLP(rows, 7, [0, 1, 2], goal=goal)
    res, reports = solve(problem)
    assert res.stop_reason == why and res.sensors == [] and res.bound is None
    assert reports == []


def test_the_lp_optimizer_stops_at_the_sensor_limit_and_short_of_sight():
    capped = HandLP(GREEDY_TRAP, 7, [0, 1, 2], objective="sensors", max_sensors=1)
    res, _ = solve(capped)
    assert poses_of(res) == [1] and res.stop_reason == StopReason.sensor_limit(1)
    # Point 7 is seen by none: the plan covers the 7 others and says why it stops.
    blind = HandLP(GREEDY_TRAP, 8, [0, 1, 2], objective="sensors")
    res, _ = solve(blind)
    assert poses_of(res) == [1, 2] and res.n_covered == 7
    assert res.stop_reason == StopReason.out_of_sight("candidate pose")


def test_the_lp_optimizer_stopped_early_still_places_a_plan():
    """Stopped before it starts (Esc): the plan found by then, greedy's 3 sensors
    (nothing more is rounded from the LP once stopped), and the words for an early
    stop. Past its time limit the plans are still rounded from the LP it has: greedy's
    3 improved to 2."""
    problem = HandLP(GREEDY_TRAP, 7, [0, 1, 2], objective="sensors")
    planner = LPPlanner()
    planner.stop_early()
    res = steps(planner.solve(problem, Solution(np.zeros(7, bool))))[0]
    assert res.stop_reason == StopReason.reached(1.0, early=True) and res.n_covered == 7
    assert len(res.sensors) == 3 and res.bound.sensors <= 2
    late = HandLP(GREEDY_TRAP, 7, [0, 1, 2], objective="sensors", time_limit_s=1e-9)
    res, _ = solve(late)
    assert res.stop_reason == StopReason.reached(1.0, early=True) and len(res.sensors) == 2
    assert planner.close() is None


@pytest.mark.parametrize("limit, drawn", [(None, 3), (1e-9, 1)])
def test_past_its_time_limit_one_plan_is_rounded_from_the_lp(monkeypatch, limit, drawn):
    """Three plans to round (each greedy's own): without a limit all three are drawn;
    past the limit the first alone (it may still beat greedy; more would overrun)."""
    draws = []

    def three(inst, lp, price=1.0):
        for plan in ([0, 1, 2], [0, 1, 2], [0, 1, 2]):
            draws.append(plan)
            yield plan

    monkeypatch.setattr(lp_module, "_lp_plans", three)
    solve(HandLP(GREEDY_TRAP, 7, [0, 1, 2], objective="sensors", time_limit_s=limit))
    assert len(draws) == drawn


@pytest.mark.parametrize(
    "existing, seen, sensors", [(True, True, 1), (True, False, 1), (False, True, 2)]
)
def test_the_bound_for_another_plan_leaves_out_what_stands(existing, seen, sensors):
    """Candidate 1 standing already (existing) leaves points 2, 3, 5: candidate 2
    alone. A sensor the plan placed itself counts for nothing: 2, as for the whole."""
    problem = HandLP(GREEDY_TRAP, 7, [0, 1, 2], objective="sensors")
    solution = Solution(np.zeros(7, bool), need=problem.need)
    solution.fix(_fixed(problem, 1, existing, seen))
    bound = steps(lp_module.bound_only(problem, solution))[0]
    assert bound.sensors == sensors


# ---------------------------------------------------------------- what each solve is handed


def test_the_deadline_and_the_stop_reach_every_solve(monkeypatch):
    """GREEDY_TRAP, a mast standing at site 1: the LP starts from greedy's columns,
    one column per position; the fewest masts get the standing mast; the mast-aware
    MILP the plan's sites, its start and its candidates; all the deadline and the
    stop."""
    problem = HandLP(
        GREEDY_TRAP, 7, [0, 1, 2], standing=[False, True, False], sensor_costs=(1.0, 2.0),
        model=[0, 1, 0],
    )  # fmt: skip
    calls = spy(
        monkeypatch, "cover_lp", "split_cover_lp", "site_cover", "milp_candidates",
        "sensors_on_sites", "_lp_plans",
    )  # fmt: skip
    cands = problem.candidates
    inst = lp_module.instance(cands, problem, np.zeros(7, bool))
    deadline, stop = time.perf_counter() + 100.0, threading.Event()
    go = lp_module.prove_and_plan(problem, cands, inst, Solution(np.zeros(7, bool)), deadline, stop)
    plan, *_ = steps(go)[0]
    assert sorted(plan) == [1, 2] and calls["split_cover_lp"] == []
    (lp,) = calls["cover_lp"]
    assert lp["inst"] is inst and lp["group"] is cands.position
    assert lp["cost"].tolist() == [1.0, 2.0, 1.0]
    assert sorted(lp["initial"].tolist()) == [0, 1, 2]  # greedy took all three
    (sites,) = calls["site_cover"]
    assert sites["standing"].tolist() == [False, True, False] and sites["n_sites"] == 3
    assert sites["site_of"] is cands.position and sites["milp"] is True
    (cols,) = calls["milp_candidates"]
    (milp,) = calls["sensors_on_sites"]
    assert cols["inst"] is inst and cols["site_of"] is cands.position
    assert milp["sites"] is cols["used"] and milp["start"] is cols["start"]
    assert milp["cols"] is cols["returned"] and milp["inst"] is inst
    assert sorted(milp["start"]) == [1, 2] and milp["sites"].tolist() == [1, 2]
    assert milp["mast_cost"].tolist() == [3.0, 0.0, 3.0]
    assert milp["sensor_cost"].tolist() == [1.0, 2.0, 1.0]
    for call in (lp, sites, milp):
        assert call["deadline"] == deadline and call["stop"] is stop
    assert calls["_lp_plans"] == []  # masts cost 3: nothing rounded for the sensors alone


def test_the_windows_at_k_2_are_handed_the_plan_the_deadline_and_the_stop(monkeypatch):
    """At k = 2 the windows (``_then_windows``) start from the best plan found before
    them, at the masts' costs, with the search's deadline and stop, on the
    candidates' positions; at k = 1 none run."""
    calls = spy(monkeypatch, "improve_by_windows", "rounded_on_masts")
    rows = [[0, 1, 2, 3], [0, 1, 2, 3], [0, 1, 2, 3], [0, 1, 2], [1, 3], [0, 1, 2, 3]]
    site_of = [0, 1, 1, 2, 2, 2]
    problem = HandLP(rows, 4, site_of, need=[2] * 4, objective="cost", max_sensors_per_mast=2)
    cands = problem.candidates
    inst = lp_module.instance(cands, problem, np.zeros(4, bool))
    deadline, stop = time.perf_counter() + 100.0, threading.Event()
    go = lp_module.prove_and_plan(problem, cands, inst, Solution(np.zeros(4, bool)), deadline, stop)
    plan, *_ = steps(go)[0]
    assert sorted(plan) == [1, 2]
    (windows,) = calls["improve_by_windows"]
    assert windows["deadline"] == deadline and windows["stop"] is stop
    assert windows["site_of"] is cands.position and windows["site_xy"] is cands.positions
    assert windows["mast_cost"] == 3.0 and windows["sensor_cost"] == 1.0
    # The plan on the LP's columns (site 1's pair, 5) came before them, and the plans
    # rounded on its masts before the windows.
    assert sorted(windows["chosen"]) == [1, 2]
    rounding = calls["rounded_on_masts"][0]
    assert rounding["chosen"] == windows["chosen"] and rounding["inst"] is inst
    assert rounding["deadline"] == deadline and rounding["stop"] is stop
    calls["improve_by_windows"].clear()
    problem = HandLP(GREEDY_TRAP, 7, [0, 1, 2], objective="cost")
    inst = lp_module.instance(problem.candidates, problem, np.zeros(7, bool))
    steps(lp_module.prove_and_plan(problem, problem.candidates, inst, Solution(np.zeros(7, bool)),
                                   deadline, stop))  # fmt: skip
    assert calls["improve_by_windows"] == []


def _scripted_windows(monkeypatch, script, rounding=()):
    """``improve_by_windows`` replaced: each call records its start plan and the
    generator's close, and yields ``script``'s plans for it (None: HiGHS at work).
    ``rounded_on_masts`` replaced too: each call records its plan and returns at once
    the plans ``rounding`` lists for it (none by default). Returns (runs, rounds)."""
    runs = []
    rounds = []

    def scripted(inst, site_of, site_xy, chosen, *rest):
        run = {"chosen": list(chosen), "closed": False}
        runs.append(run)
        try:
            yield from script[len(runs) - 1]
        except GeneratorExit:
            run["closed"] = True
            raise
        return chosen

    def rounded(problem, cands, inst, chosen, deadline, stop):
        yield from ()
        rounds.append(list(chosen))
        plans = rounding[len(rounds) - 1] if len(rounds) <= len(rounding) else []
        return joint_module.OnMasts(0.0, np.zeros(0, np.int64)), [list(p) for p in plans]

    monkeypatch.setattr(lp_module, "improve_by_windows", scripted)
    monkeypatch.setattr(lp_module, "rounded_on_masts", rounded)
    return runs, rounds


def test_windows_go_on_from_their_own_plan_unless_a_better_one_comes(monkeypatch):
    """The windows start from the best plan so far ([0, 1, 2, 3], sites 0-2: 3 x 3 +
    4 = 13), and their cheaper plans are incumbents. A pause (a new ``steps``) goes on
    where they were while their plan is the best; a better plan from elsewhere (5)
    closes them and starts them again from it; once they end nothing runs until a
    still better plan comes."""
    rows = [[0, 1, 2, 3], [0, 1, 2, 3], [0, 1, 2, 3], [0, 1, 2], [1, 3], [0, 1, 2, 3]]
    problem = HandLP(rows, 4, [0, 1, 1, 2, 2, 2], need=[2] * 4, objective="cost")
    cands = problem.candidates
    inst = lp_module.instance(cands, problem, np.zeros(4, bool))
    runs, _ = _scripted_windows(monkeypatch, [[None, [0, 1, 2], None, [0, 3]], [None], []])
    held = lp_module._Held(13.0, [0, 1, 2, 3])
    windows = lp_module._Windows(problem, cands, inst, held, None, None)
    first = windows.steps()
    got = [next(first), next(first)]
    assert got[0] is None and got[1] == lp_module.Incumbent(9.0, [0, 1, 2])
    held.value, held.chosen = got[1].value, got[1].chosen  # as prove_bound holds it
    rest = steps(windows.steps())[1]  # paused, then on: the same windows
    assert rest == [None, lp_module.Incumbent(8.0, [0, 3])] and len(runs) == 1
    held.value, held.chosen = 8.0, [0, 3]
    # They have ended: nothing runs on the plan they ended on.
    assert steps(windows.steps())[1] == [] and len(runs) == 1
    # A better plan from elsewhere: the windows again, from it.
    held.value, held.chosen = 5.0, [1, 2]
    assert steps(windows.steps())[1] == [None]
    assert [r["chosen"] for r in runs] == [[0, 1, 2, 3], [1, 2]]
    # One closed while at work when a better plan comes.
    runs, _ = _scripted_windows(monkeypatch, [[None, None], [None]])
    held = lp_module._Held(13.0, [0, 1, 2, 3])
    windows = lp_module._Windows(problem, cands, inst, held, None, None)
    assert next(windows.steps()) is None
    held.value, held.chosen = 5.0, [1, 2]
    assert steps(windows.steps())[1] == [None]
    assert [(r["chosen"], r["closed"]) for r in runs] == [([0, 1, 2, 3], True), ([1, 2], False)]
    # No plan reaches the goal: no windows.
    empty = lp_module._Windows(problem, cands, inst, lp_module._Held(math.inf, []), None, None)
    assert steps(empty.steps())[1] == [] and len(runs) == 2


def test_windows_alternate_with_plans_rounded_on_the_plans_masts(monkeypatch):
    """From the best plan so far ([0, 1, 2, 3] on sites 0-2: 3 x 3 + 4 = 13) a
    rounding on its masts comes first: of its plans, the dearer [0, 1, 2, 3, 4] (14)
    is passed over and the cheapest, [0, 1, 2] (9), taken and yielded; the windows
    start from it. Their cheaper plan [0, 3] (8), once they find nothing more for
    ``STALL_S`` (here: at once), is rounded from with the windows kept where they are:
    that rounding offers only plans it has been at or dearer ones, so the same
    windows go on, to [1, 2] (5). Rounded from, that gives [3, 5], as cheap and not
    yet seen: taken, not yielded (no cheaper), the windows closed and started again
    from it. They end on it, and it was rounded from already: the search ends."""
    rows = [[0, 1, 2, 3], [0, 1, 2, 3], [0, 1, 2, 3], [0, 1, 2], [1, 3], [0, 1, 2, 3]]
    problem = HandLP(rows, 4, [0, 1, 1, 2, 2, 2], need=[2] * 4, objective="cost")
    cands = problem.candidates
    inst = lp_module.instance(cands, problem, np.zeros(4, bool))
    monkeypatch.setattr(lp_module, "STALL_S", -1.0)
    script = [[None, [0, 3], None, [1, 2], None], [None]]
    rounding = [[[0, 1, 2, 3, 4], [0, 1, 2]], [[0, 1, 2], [0, 3], [0, 3, 4]], [[3, 5]]]
    runs, rounds = _scripted_windows(monkeypatch, script, rounding)
    held = lp_module._Held(13.0, [0, 1, 2, 3])
    windows = lp_module._Windows(problem, cands, inst, held, None, None)
    got = steps(windows.steps())[1]
    incumbent = lp_module.Incumbent
    assert got == [incumbent(9.0, [0, 1, 2]), None, incumbent(8.0, [0, 3]), None,
                   incumbent(5.0, [1, 2]), None]  # fmt: skip
    assert rounds == [[0, 1, 2, 3], [0, 3], [1, 2]]
    assert [(r["chosen"], r["closed"]) for r in runs] == [([0, 1, 2], True), ([3, 5], False)]
    # Without the stall, the windows run to their end before the plan they reach is
    # rounded from: once, as they ended on [1, 2].
    monkeypatch.setattr(lp_module, "STALL_S", 600.0)
    runs, rounds = _scripted_windows(monkeypatch, script, [[[0, 1, 2]]])
    windows = lp_module._Windows(problem, cands, inst, held, None, None)
    assert steps(windows.steps())[1] == [incumbent(9.0, [0, 1, 2]), None,
                                          incumbent(8.0, [0, 3]), None,
                                          incumbent(5.0, [1, 2]), None]  # fmt: skip
    assert rounds == [[0, 1, 2, 3], [1, 2]] and len(runs) == 1 and not runs[0]["closed"]
    # Stopped, or past the deadline: neither rounds nor windows.
    stop = threading.Event()
    stop.set()
    past = time.perf_counter() - 1.0
    for deadline, stopped in ((None, stop), (past, None)):
        late = lp_module._Windows(problem, cands, inst, held, deadline, stopped)
        runs, rounds = _scripted_windows(monkeypatch, script, rounding)
        assert steps(late.steps())[1] == [] and runs == [] and rounds == []


def test_after_the_lp_plans_are_built_on_its_columns_above_each_value(monkeypatch, caplog):
    """Once the LP ends (columns 0, 1, 3, 5, 2 at 1, 0.03, 0.07, 0.5, 0), greedy per
    cost builds a plan on the columns above 0 (the first four), above 0.05 (0, 3, 5)
    and above 0.1 (0, 5), each an incumbent, logged with their costs; then the
    windows run from the best plan so far. A stopped run builds none."""
    rows = [[0, 1, 2, 3], [0, 1, 2, 3], [0, 1, 2, 3], [0, 1, 2], [1, 3], [0, 1, 2, 3]]
    problem = HandLP(rows, 4, [0, 1, 1, 2, 2, 2], need=[2] * 4, objective="cost")
    cands = problem.candidates
    inst = lp_module.instance(cands, problem, np.zeros(4, bool))
    calls = spy(monkeypatch, "plan_from")
    runs, _ = _scripted_windows(monkeypatch, [[None]])
    held = lp_module._Held(13.0, [0, 1, 2, 3])
    lp = _lp(2.0, columns=(0, 1, 3, 5, 2), x=(1.0, 0.03, 0.07, 0.5, 0.0))

    def lp_side():
        yield "lp at work"
        return lp

    windows = lp_module._Windows(problem, cands, inst, held, None, None)
    with caplog.at_level(logging.INFO, logger=lp_module.log.name):
        value, got = steps(lp_module._then_windows(problem, cands, inst, windows, lp_side()))
    assert value is lp and got[0] == "lp at work" and got[-1] is None
    pools = [sorted(c["pool"].tolist()) for c in calls["plan_from"]]
    assert pools == [[0, 1, 3, 5], [0, 3, 5], [0, 5]]
    plans = [c["returned"].chosen for c in calls["plan_from"]]
    values = [lp_module.plan_value(problem, cands, p) for p in plans]
    assert got[1:4] == [lp_module.Incumbent(v, p) for v, p in zip(values, plans, strict=True)]
    assert len(runs) == 1
    (logged,) = [r.getMessage() for r in caplog.records if "LP's columns above" in r.getMessage()]
    head = f"plans on the LP's columns above (0.0, 0.05, 0.1): {values} in "
    assert logged.startswith(head) and 0.0 <= float(logged[len(head) : -2]) < 60.0
    assert logged.endswith(" s")
    stop = threading.Event()
    stop.set()
    calls["plan_from"].clear()
    windows = lp_module._Windows(problem, cands, inst, held, None, stop)
    value, got = steps(lp_module._then_windows(problem, cands, inst, windows, lp_side()))
    assert value is lp and got == ["lp at work"] and calls["plan_from"] == []


def test_windows_run_while_the_joint_lp_waits(monkeypatch):
    """While the joint LP cannot start (the fewest masts not known yet), the side
    that waits for it steps the windows instead of idling; once it can start, it
    does, and the windows wait for the sensors LP's side."""
    rows = [[0, 1, 2, 3], [0, 1, 2, 3], [0, 1, 2, 3], [0, 1, 2], [1, 3], [0, 1, 2, 3]]
    problem = HandLP(rows, 4, [0, 1, 1, 2, 2, 2], need=[2] * 4, objective="cost")
    cands = problem.candidates
    inst = lp_module.instance(cands, problem, np.zeros(4, bool))
    runs, _ = _scripted_windows(monkeypatch, [[None, [0, 1, 2], None, None]])
    held = lp_module._Held(13.0, [0, 1, 2, 3])
    windows = lp_module._Windows(problem, cands, inst, held, None, None)
    joint = lp_module._JointStart(problem, cands, inst, 100.0, None, None, windows)
    started = []

    def fake_joint_bound(*args, **kwargs):
        started.append(True)
        yield "joint"
        return 0.0

    monkeypatch.setattr(lp_module, "joint_bound", fake_joint_bound)

    def done_at_once():
        return (yield from ())

    gen = joint.then(done_at_once())
    got = [next(gen), next(gen)]  # no fewest masts yet: the windows' steps
    assert got == [None, lp_module.Incumbent(9.0, [0, 1, 2])] and not started
    joint.sites = SiteSolution(1, np.arange(3), np.zeros(0, np.int64))
    joint.lp = replace(_lp(2.0, columns=(0, 1), x=(1.0, 1.0)), pi=np.ones(4))
    assert next(gen) == "joint" and started == [True]
    assert len(runs) == 1 and not runs[0]["closed"]


def test_the_lp_in_parts_is_handed_the_deadline_and_the_stop(monkeypatch):
    monkeypatch.setattr(budget, "PART_POINTS", 4)
    calls = spy(monkeypatch, "cover_lp", "split_cover_lp")
    problem = HandLP(GREEDY_TRAP, 7, [0, 1, 2], objective="sensors")
    problem.grid.target_xy = np.array([(float(n), 0.0) for n in range(7)])
    inst = lp_module.instance(problem.candidates, problem, np.zeros(7, bool))
    deadline, stop = time.perf_counter() + 100.0, threading.Event()
    go = lp_module.prove_bound(problem, problem.candidates, inst, Solution(np.zeros(7, bool)),
                               deadline, stop)  # fmt: skip
    steps(go)
    (split,) = calls["split_cover_lp"]
    assert split["deadline"] == deadline and split["stop"] is stop
    assert sorted(split["initial"].tolist()) == [0, 1, 2]
    assert split["part"].tolist() == [0, 0, 0, 0, 1, 1, 1]
    assert split["group"] is problem.candidates.position
    # The parts' own LPs are the split's business: none solved whole here.
    assert all(call["rel_gap"] > 0 for call in calls["cover_lp"])


def test_prices_follow_the_objective(monkeypatch):
    """Models at 1 and 3 (candidate 2 the dear one): for the sensors objective every
    candidate counts 1 in greedy, the LP and the LP's plans (the bound counts 2
    sensors, not 4 of cost); for cost (masts free, so plans are rounded from the LP)
    each its model's price."""
    calls = spy(monkeypatch, "cover_lp", "_lp_plans")
    for objective, price in (("sensors", [1.0, 1.0, 1.0]), ("cost", [1.0, 1.0, 3.0])):
        problem = HandLP(
            GREEDY_TRAP, 7, [0, 1, 2], sensor_costs=(1.0, 3.0), model=[0, 0, 1],
            objective=objective, mast_cost=0.0,
        )  # fmt: skip
        inst = lp_module.instance(problem.candidates, problem, np.zeros(7, bool))
        go = lp_module.prove_and_plan(
            problem, problem.candidates, inst, Solution(np.zeros(7, bool)), None
        )
        _, bound, _ = steps(go)[0]
        assert calls["cover_lp"][-1]["cost"].tolist() == price
        assert np.asarray(calls["_lp_plans"][-1]["price"]).tolist() == (
            1.0 if objective == "sensors" else price
        )
        assert bound.sensors == 2
    assert bound.lp == pytest.approx(4.0, abs=1e-4)


@pytest.mark.parametrize(
    "objective, mast_cost, rounded",
    [("sensors", 3.0, True), ("cost", 0.0, True), ("cost", 3.0, False), ("masts", 3.0, False)],
)
def test_plans_are_rounded_from_the_lp_only_where_masts_cost_nothing(
    monkeypatch, objective, mast_cost, rounded
):
    """The LP counts sensors alone, so its rounded plans do too: they are drawn for the
    sensors objective or the cost with free masts, and not where masts count."""
    calls = spy(monkeypatch, "_lp_plans")
    problem = HandLP(GREEDY_TRAP, 7, [0, 1, 2], objective=objective, mast_cost=mast_cost)
    inst = lp_module.instance(problem.candidates, problem, np.zeros(7, bool))
    go = lp_module.prove_and_plan(
        problem, problem.candidates, inst, Solution(np.zeros(7, bool)), None
    )
    steps(go)
    assert len(calls["_lp_plans"]) == int(rounded)


def test_greedy_goes_by_cost():
    """Candidate 0 of model 1 costs 3: per cost greedy takes 1 (4 points for 1), then
    2 (3 for 1): 2 masts at 3 and 2 sensors, 8; per point it would take 0 first and
    end with three (14)."""
    problem = HandLP(GREEDY_TRAP, 7, [0, 1, 2], sensor_costs=(1.0, 3.0), model=[1, 0, 0])
    (bound, lp, on_sites, (greedy, _)), reports = _bound_run(problem)
    assert sorted(greedy.chosen) == [1, 2] and {r.best for r in reports} == {8.0}
    assert {r.rho for r in reports} == {1.0}


def _fake_sites(monkeypatch, sites, lp_sites, bound=2):
    """The fewest masts as given (their MILP's ``sites``, its LP's ``lp_sites``)."""

    def site_cover(*args, **kwargs):
        return SiteSolution(bound, np.array(sites, np.int64), np.array(lp_sites, np.int64))
        yield  # a generator, like the real one

    monkeypatch.setattr(lp_module, "site_cover", site_cover)


# Sites 0, 1, 2 around points 0..2: site 0 holds 0 (point 0) and 1 (point 1); site 1
# holds 2 (point 1) and 3 (point 2); site 2 holds 4 (points 0 and 2). On sites 0, 1
# a plan needs 3 sensors; with site 2 too, 2 (candidate 4 and 1 or 2).
TRIANGLE = [[0], [1], [1], [2], [0, 2]]
TRIANGLE_SITES = [0, 0, 1, 1, 2]


def test_the_plan_on_the_lps_sites_wins_when_it_is_cheaper(monkeypatch):
    problem = HandLP(TRIANGLE, 3, TRIANGLE_SITES, objective="sensors")
    inst = lp_module.instance(problem.candidates, problem, np.zeros(3, bool))
    calls = spy(monkeypatch, "close_sites")
    _fake_sites(monkeypatch, [0, 1], [0, 1, 2])
    go = lp_module.masts_then_plan(problem, problem.candidates, inst, None, None, True)
    sites, plan = steps(go)[0]
    assert len(plan) == 2 and 4 in plan and len(calls["close_sites"]) == 2
    # The same sites twice: one plan on them.
    _fake_sites(monkeypatch, [0, 1], [0, 1])
    go = lp_module.masts_then_plan(problem, problem.candidates, inst, None, None, True)
    sites, plan = steps(go)[0]
    assert sorted(plan) == [0, 1, 3] or sorted(plan) == [0, 2, 3]
    assert len(calls["close_sites"]) == 3


def test_a_parts_plan_is_the_best_milp_over_every_start(monkeypatch):
    """TRIANGLE, sensors: on the fewest masts' sites 0, 1 greedy needs 3 sensors, on
    the LP's 0, 1, 2 it takes 4 and one of 1, 2 (2 sensors, on site 2 and 0 or 1): that
    start is the cheaper, its MILP first. The MILP is faked to keep a start on site 2
    and to return candidate 0 alone (1) on sites 0, 1. With ``every_start`` (a part's
    plans) both MILPs run and the plan is the cheaper MILP's, though its start was the
    dearer; without, only the cheaper start's; past the deadline, only the first. The
    second MILP looks only below the first's plan (2 sensors: a cutoff of 2 - 1e-6)."""
    problem = HandLP(TRIANGLE, 3, TRIANGLE_SITES, objective="sensors")
    inst = lp_module.instance(problem.candidates, problem, np.zeros(3, bool))
    _fake_sites(monkeypatch, [0, 1], [0, 1, 2])
    milps = []

    cutoffs = []

    def sensors_on_sites(inst, site_of, sites, start, *args, cutoff=None, **kwargs):
        milps.append(sorted(int(s) for s in sites))
        cutoffs.append(cutoff)
        return list(start) if 2 in sites else [0]
        yield  # a generator, like the real one

    monkeypatch.setattr(lp_module, "sensors_on_sites", sensors_on_sites)

    def run(every_start, deadline=None):
        milps.clear()
        go = lp_module.masts_then_plan(
            problem, problem.candidates, inst, deadline, None, True, every_start=every_start
        )
        (_, plan), yielded = steps(go)
        found = [y.value for y in yielded if isinstance(y, lp_module.Incumbent)]
        return plan, found

    plan, found = run(True)
    assert len(milps) == 2 and 2 in milps[0] and len(milps[0]) == 2 and milps[1] == [0, 1]
    assert plan == [0] and found == [2.0, 2.0, 1.0]
    assert cutoffs == [None, pytest.approx(2.0 - 1e-6, abs=1e-9)]
    plan, found = run(False)
    assert len(milps) == 1 and 2 in milps[0] and len(plan) == 2 and 4 in plan
    assert found == [2.0, 2.0]
    plan, found = run(True, deadline=time.perf_counter() - 1.0)
    assert len(milps) == 1 and len(plan) == 2 and 4 in plan


def test_site_sets_are_distinct_and_the_best_found_first():
    sites = SiteSolution(2, np.array([0, 1]), np.array([0, 1, 2]), (np.array([0, 1]), np.zeros(0)))
    assert [s.tolist() for s in sites.site_sets()] == [[0, 1], [0, 1, 2]]
    lp_only = SiteSolution(0, np.zeros(0, np.int64), np.array([3]))
    assert [s.tolist() for s in lp_only.site_sets()] == [[3]]


def test_the_plan_on_the_sites_is_built_per_cost(monkeypatch):
    """Cost objective, masts at 3, models at 1 and 2 (candidate 4 of model 1): the
    greedy start, its improvement and the masts closed all get the per-site mast
    cost and each candidate's price; a mast stands at site 2 already."""
    problem = HandLP(
        TRIANGLE, 3, TRIANGLE_SITES, sensor_costs=(1.0, 2.0), model=[0, 0, 0, 0, 1],
        standing=[False, False, True],
    )  # fmt: skip
    inst = lp_module.instance(problem.candidates, problem, np.zeros(3, bool))
    calls = spy(monkeypatch, "complete", "improve", "close_sites")
    _fake_sites(monkeypatch, [0, 1], [0, 1, 2])
    go = lp_module.masts_then_plan(problem, problem.candidates, inst, None, None, True)
    _, plan = steps(go)[0]
    assert sorted(plan) in ([1, 4], [2, 4])  # 2 on the standing mast + 1 + 3: 6
    price = [1.0, 1.0, 1.0, 1.0, 2.0]
    for call in calls["complete"] + calls["close_sites"]:
        assert call["site_of"] is problem.candidates.position
        assert call["mast_cost"].tolist() == [3.0, 3.0, 0.0]
        assert call["sensor_cost"].tolist() == price
    for call in calls["improve"]:
        assert call["sensor_cost"].tolist() == price
    assert [c["pool"].tolist() for c in calls["complete"]] == [[0, 1, 2, 3], [0, 1, 2, 3, 4]]


def test_the_plan_stays_on_the_fewest_masts_sites():
    """Site 0 alone covers all with 0, 1, 2; candidate 3 on site 1 sees 4 points, so
    a plan from every site would take 3 and 2 (2 sensors on 2 masts): for the masts
    the plan stays on site 0."""
    rows = [[0, 1], [2, 3], [4, 5], [0, 1, 2, 3]]
    problem = HandLP(rows, 6, [0, 0, 0, 1], objective="sensors")
    inst = lp_module.instance(problem.candidates, problem, np.zeros(6, bool))
    go = lp_module.masts_then_plan(problem, problem.candidates, inst, None, None, True)
    sites, plan = steps(go)[0]
    assert sites.sites.tolist() == [0] and sorted(plan) == [0, 1, 2]


# ---------------------------------------------------------------- more hand cases


def test_the_instance_keeps_its_types_and_takes_the_covered_off_the_goal():
    """Candidates 0..3 each see points; point 0 covered: a goal of 3 becomes 2 (all 4
    left are coverable). The matrix stays float32 and the k int32."""
    rows = [[0, 1], [1, 2], [2, 3], [3, 4]]
    problem = HandLP(rows, 5, [0, 0, 1, 1], goal=3)
    covered = np.array([True, False, False, False, False])
    inst = lp_module.instance(problem.candidates, problem, covered, taken=np.array([3]))
    assert inst.goal == 2 and inst.matrix.dtype == np.float32 and inst.k.dtype == np.int32


def test_plan_cost_counts_only_the_masts_not_standing():
    cands = HandLP([[0]] * 4, 1, [0, 0, 1, 2]).candidates
    standing = np.array([True, True, False])
    assert lp_module.plan_cost(cands, [0, 1, 2], "cost", 5.0, 1.0, standing) == (3.0, 0)


def test_plan_bound_through_cheap_or_priced_models(monkeypatch):
    """Models at 0.5 and 0.25: an LP of 1 proves 2 sensors (none costs more than
    0.5); an LP of 0 proves none; the scope and rounds are the LP's."""
    monkeypatch.setattr(lp_module, "mast_aware_bound", lambda *args: 0.0)
    problem = HandLP([[0]] * 2, 1, [0, 1], sensor_costs=(0.5, 0.25), model=[0, 1])
    sites = SiteSolution(1, np.array([0]), np.zeros(0, np.int64))
    got = lp_module._plan_bound(_lp(1.0, rounds=5), sites, problem.candidates, problem)
    assert got.sensors == 2 and got.rounds == 5
    assert got.scope == lp_module.bound_scope(problem.candidates, problem)
    assert lp_module._plan_bound(_lp(0.0), sites, problem.candidates, problem).sensors == 0


def test_plans_keep_what_the_lp_holds_at_each_threshold():
    """The 4-cycle: 0 = {0, 1}, 1 = {1, 2}, 2 = {2, 3}, 3 = {3, 0}, all at just under
    0.5 (within 1e-9): at 0.9 and 0.7 nothing is kept and greedy takes 0 and 2; at
    0.5, 0.3 and 0.2 all four are, and pruning in order drops 0 (its points covered
    by 1 and 3), keeps 1, drops 2: 1 and 3."""
    inst = rows_instance([[0, 1], [1, 2], [2, 3], [3, 0]], 4, 4)
    half = 0.5 - 1e-9
    lp = _lp(2.0, columns=(0, 1, 2, 3), x=(half,) * 4, reduced=(0.0,) * 4)
    plans = [sorted(p) for p in lp_module._lp_plans(inst, lp)]
    assert plans == [[0, 2], [0, 2], [1, 3], [1, 3], [1, 3]]


def test_plans_from_the_lp_are_improved_per_cost():
    """The LP keeps 0 = {0} and 1 = {1}; 2 = {0, 1} is in the pool at a price of 3: a
    swap of the two for it would cost more (3 > 2), so the plan stays 0, 1; at one
    price for all it would be 2 alone."""
    inst = rows_instance([[0], [1], [0, 1]], 2, 2)
    lp = _lp(2.0, columns=(0, 1), x=(1.0, 1.0), reduced=(0.0, 0.0, 0.0, 1.0))
    priced = list(lp_module._lp_plans(inst, lp, np.array([1.0, 1.0, 3.0])))
    assert [sorted(p) for p in priced] == [[0, 1]] * 5
    assert list(lp_module._lp_plans(inst, lp)) == [[2]] * 5


def test_greedy_order_counts_each_sensor_at_k2():
    """k = 2: 0 (3 points) first, then 1 (points 0, 1 to 2; 3 ties with it and comes
    later), then 3 (points 2, 3) before 2, which adds nothing once 0 and 1 are at 2."""
    inst = rows_instance([[0, 1, 2], [0, 1], [0, 1], [2, 3]], 4, 4)
    k2 = CoverInstance(inst.matrix, 4, need=np.full(4, 2, np.int32))
    assert lp_module.in_gain_order(k2, [0, 1, 2, 3]) == [0, 1, 3, 2]


def test_the_lp_optimizer_resumed_at_k2_takes_no_sensor_twice():
    """Points 0, 1 needed twice; 0, 1 and 2 each see both. Candidate 0 is fixed: one
    more is needed, not candidate 0 again."""
    problem = HandLP([[0, 1]] * 3, 2, [0, 1, 2], need=[2, 2], objective="sensors")
    start = Solution(np.zeros(2, bool), need=problem.need)
    start.fix(FixedSensor(_fixed(problem, 0).pose, 0.0, 0, 0, np.zeros(0, np.int64),
                          np.array([0, 1])))  # fmt: skip
    res, _ = solve(problem, start)
    assert poses_of(res) == [0, 1] and res.n_covered == 2 and res.bound.sensors == 1


def test_the_lp_optimizer_with_one_point_left():
    problem = HandLP([[0], [0, 1]], 2, [0, 1], goal=1, objective="sensors")
    res, _ = solve(problem)
    assert poses_of(res) == [1] and res.stop_reason == StopReason.reached(1.0)


class SeesMore(HandLP):
    """Candidate 1 evaluated afresh sees every point, more than its row."""

    def evaluate(self, pose, model=0):
        if round(pose.yaw_deg / 10.0) == 1:
            return SimpleNamespace(covered=np.arange(self.n_targets), rays=1)
        return super().evaluate(pose, model)


def test_the_lp_optimizer_stops_fixing_at_the_goal():
    problem = SeesMore(GREEDY_TRAP, 7, [0, 1, 2], objective="sensors")
    res, reports = solve(problem)
    assert poses_of(res) == [1] and res.stop_reason == StopReason.reached(1.0)
    assert [(r.phase, r.rho) for r in reports if r.fixed] == [("fixed", 1.0)]


@pytest.mark.parametrize(
    "limit, parts, search_s",
    [
        (100.0, 1, 95.0),
        (20.0, 1, 17.0),
        (None, 1, 228.0),
        (None, 3, 598.5),
        (None, 8, 1596.0),
        (None, 10, 1596.0),
        (None, 20, 2280.0),
    ],
)
def test_the_lp_optimizer_hands_on_its_deadline_and_stop(monkeypatch, limit, parts, search_s):
    """The search ends when the run's limit (from the problem's start) less what the
    finish needs has passed: 5 % of the limit, at least 3 s; by default 240 s whole
    and 210 s a part in parts (3 parts: 630 s, 8 parts: 1,680 s), at most 1,680 s in
    all unless that leaves a part less than 120 s (10 parts: 1,680 s, 20: 2,400 s)."""
    calls = spy(monkeypatch, "prove_and_plan")
    problem = HandLP(GREEDY_TRAP, 7, [0, 1, 2], objective="sensors", time_limit_s=limit)
    problem.t0 -= 10.0  # the problem took 10 s to build
    default = {1: 240.0, 3: 630.0, 8: 1680.0, 10: 1680.0, 20: 2400.0}[parts]
    assert planner_module.time_limit(problem.settings, parts) == (limit or default)
    planner = LPPlanner()
    res = steps(planner.solve(problem, Solution(np.zeros(7, bool))))[0]
    (call,) = calls["prove_and_plan"]
    if parts == 1:
        assert call["deadline"] == pytest.approx(problem.t0 + search_s, abs=1e-9)
    assert planner_module.search_deadline(problem.t0, planner_module.time_limit(
        problem.settings, parts)) == pytest.approx(problem.t0 + search_s)  # fmt: skip
    assert call["stop"] is planner.stop
    assert res.stop_reason == StopReason.reached(1.0)  # well within its time


@pytest.mark.parametrize("limit", [None, 100.0])
def test_the_bound_for_another_plan_has_the_time_limit(monkeypatch, limit):
    calls = spy(monkeypatch, "prove_bound")
    problem = HandLP(GREEDY_TRAP, 7, [0, 1, 2], objective="sensors", time_limit_s=limit)
    t0 = time.perf_counter()
    steps(lp_module.bound_only(problem, Solution(np.zeros(7, bool))))
    deadline = calls["prove_bound"][0]["deadline"]
    if limit is None:
        assert deadline is None
    else:
        assert t0 + limit <= deadline <= time.perf_counter() + limit


@pytest.mark.parametrize("standing, bound", [(1, 1), (2, 0), (0, 2)])
def test_the_bound_for_another_plan_at_k2_counts_each_standing_sensor(standing, bound):
    """Points 0, 1 needed twice; 0, 1 and 2 each see both. With one sensor standing
    already (its points in ``seen``, none newly at k) 1 more is needed; with two, none;
    with none, 2."""
    problem = HandLP([[0, 1]] * 3, 2, [0, 1, 2], need=[2, 2], objective="sensors")
    solution = Solution(np.zeros(2, bool), need=problem.need)
    for c in range(standing):
        newly = np.zeros(0, np.int64) if c == 0 else np.array([0, 1])
        pose = _fixed(problem, c).pose
        solution.fix(FixedSensor(pose, 0.0, 0, 0, newly, np.array([0, 1]), existing=True))
    assert steps(lp_module.bound_only(problem, solution))[0].sensors == bound


def test_the_rest_from_every_site_is_per_cost_too(monkeypatch):
    """Two sensors a mast at most: site 0 (0, 1, 2) cannot hold all three, the rest
    comes from every site per cost, as the start did."""
    rows = [[0, 1], [2, 3], [4, 5], [4, 5]]
    problem = HandLP(rows, 6, [0, 0, 0, 1], max_sensors_per_mast=2, sensor_costs=(1.0, 2.0),
                     model=[0, 0, 1, 0])  # fmt: skip
    inst = lp_module.instance(problem.candidates, problem, np.zeros(6, bool))
    calls = spy(monkeypatch, "complete")
    go = lp_module.masts_then_plan(problem, problem.candidates, inst, None, None, True)
    assert sorted(steps(go)[0][1]) == [0, 1, 3]
    first, rest = calls["complete"]
    assert rest["pool"].tolist() == [0, 1, 2, 3] and rest["cover"] is first["returned"]
    assert rest["site_of"] is problem.candidates.position and rest["mast_cost"] == 3.0
    assert rest["sensor_cost"].tolist() == [1.0, 1.0, 2.0, 1.0]


def test_prove_bound_plans_only_when_asked(monkeypatch):
    """By default no plan on the fewest masts (``bound_only`` needs none); a target
    whose points have no known place is solved whole, with the masts' MILP."""
    monkeypatch.setattr(budget, "PART_POINTS", 4)
    calls = spy(monkeypatch, "site_cover")
    problem = HandLP(GREEDY_TRAP, 7, [0, 1, 2], objective="sensors")
    inst = rows_instance(GREEDY_TRAP, 7, 7)  # no xy
    go = lp_module.prove_bound(problem, problem.candidates, inst, Solution(np.zeros(7, bool)), None)
    bound, lp, on_sites, _ = steps(go)[0]
    assert on_sites is None and lp.parts == 1 and bound.masts == 2
    assert calls["site_cover"][0]["milp"] is True


@pytest.mark.parametrize(
    "limit, want",
    [
        (6, [0, 1, 2, 3, 4, 5]),  # at the limit: every candidate of the sites
        (5, [0, 1, 4, 5]),  # past it: 5 // 2 = 2 a site, the largest
        (3, [0, 4]),  # 3 // 2 = 1 a site (not 1.5)
        (1, [0, 4]),  # less than one a site: still one
    ],
)
def test_milp_candidates_at_and_past_the_limit(monkeypatch, limit, want):
    """Site 0 holds candidates 0..3 covering 4, 3, 2, 1 points; site 1 holds 4 and
    5 covering 2 and 1."""
    monkeypatch.setattr(lp_module, "MAX_MILP_CANDIDATES", limit)
    rows = [[0, 1, 2, 3], [0, 1, 2], [0, 1], [0], [0, 1], [0]]
    inst = rows_instance(rows, 4, 4)
    site_of = np.array([0, 0, 0, 0, 1, 1])
    assert lp_module.milp_candidates(inst, site_of, np.array([0, 1]), []).tolist() == want


# Site 0 sees all 5 points, one candidate each, and holds 4 sensors; sites 1 and 2
# see points 0-2 and 3-4 with one candidate each (``tests/core/test_joint.py``).
CAPPED = [[0], [1], [2], [3], [4], [0, 1, 2], [3, 4]]


@pytest.mark.parametrize("plan", [False, True])
def test_the_cost_bound_takes_the_joint_bound(plan, monkeypatch):
    """On CAPPED at a mast cost of 3 the separate bounds prove 1 mast and 2 sensors,
    3 + 2 = 5; no mast carries 5 sensors, and the joint bound proves the optimum, 8,
    with a plan or without (either way its LP starts beside the sensors LP)."""
    calls = spy(monkeypatch, "masts_sensors_lp", module=joint_module)
    problem = HandLP(CAPPED, 5, [0] * 5 + [1, 2], mast_cost=3.0, max_sensors_per_mast=4)
    (bound, *_), _ = _bound_run(problem, plan=plan)
    assert (bound.masts, bound.sensors) == (1, 2)
    assert bound.joint == pytest.approx(8.0)
    assert bound.objective("cost", 3.0, 1.0) == pytest.approx(8.0)
    solves = calls["masts_sensors_lp"]
    # One LP, at 1 mast (which cannot carry the goal): its duals bound 2 masts by the
    # 2 sensors, 8, which is greedy's plan: nothing is left to prove.
    assert [call["masts"] for call in solves] == [1]
    # For the sensors objective it is not sought.
    sensors = HandLP(CAPPED, 5, [0] * 5 + [1, 2], objective="sensors", max_sensors_per_mast=4)
    (bound, *_), _ = _bound_run(sensors, plan=plan)
    assert bound.joint == 0.0 and len(solves) == 1


def test_no_joint_lp_where_the_cap_and_the_bounds_apart_prove_the_plan(monkeypatch):
    """Three sites, each with one candidate for each of 5 points (each point its own
    sensor): one mast sees every point, but 5 sensors at 2 a mast need 3 masts, and
    greedy's plan has 3 masts and 5 sensors, 3 x 3 + 5 = 14 (the optimum, by hand).
    The bounds apart with the cap prove it, so the joint LP is not solved (at the 1
    mast the fewest masts' MILP proves, it would only find that 1 mast cannot carry
    the sensors)."""
    calls = spy(monkeypatch, "masts_sensors_lp", module=joint_module)
    rows = [[n] for _ in range(3) for n in range(5)]
    problem = HandLP(rows, 5, np.repeat([0, 1, 2], 5), mast_cost=3.0, max_sensors_per_mast=2)
    (bound, *_), _ = _bound_run(problem)
    assert (bound.masts, bound.sensors) == (3, 5)
    assert bound.objective("cost", 3.0, 1.0) == pytest.approx(14.0)
    assert calls["masts_sensors_lp"] == []
