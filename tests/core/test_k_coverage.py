"""k-coverage (redundancy, issue 16 point 1): figures worked out by hand, bounds
against brute force, and every optimizer's plan recounted sensor by sensor."""

import itertools
import math
from dataclasses import replace
from types import SimpleNamespace

import numpy as np
import pytest
import shapely

from autoscoop_blender.core.candidates import CandidateSet
from autoscoop_blender.core.coverage.base import place
from autoscoop_blender.core.coverage.targeted import TargetedEvaluator
from autoscoop_blender.core.errors import InputError
from autoscoop_blender.core.evaluate import evaluate_layout
from autoscoop_blender.core.geom.grid import GroundGrid
from autoscoop_blender.core.geom.raycast import BoxCaster
from autoscoop_blender.core.model.scene import Area, SceneModel
from autoscoop_blender.core.model.sensors import PAPER_CAMERA, SensorPose, SensorSpec
from autoscoop_blender.core.optimize.base import Solution, fix_candidate
from autoscoop_blender.core.optimize.bound import cover_lp, site_cover
from autoscoop_blender.core.optimize.cover import Cover, CoverInstance, complete, improve
from autoscoop_blender.core.optimize.greedy import Greedy
from autoscoop_blender.core.run import Run
from autoscoop_blender.core.settings import CoverageSettings, OptimizeSettings
from autoscoop_blender.io.reports import coverage_dict
from tests.core.flat import box_caster, down_camera, flat_scene
from tests.core.test_lp import drain, instance

DOWN = down_camera(30.0)  # its footprint: the square 2 h tan(30 deg) under it


def height_for(side):
    return side / 2 / math.tan(math.radians(30))


# The hand-countable layout on the 30 x 10 m target (1 m grid: 300 points, centres at
# .5): squares x 0..20 and x 10..30 (side 20, full height of the target) and a third
# x 14..20, y 2..8 (side 6). Counts: x 0..10 and 20..30 once (200 points), x 10..20
# twice (100), of which the 6 x 6 square three times (36).
TARGET = (0.0, 0.0, 30.0, 10.0)
LAYOUT = [(10.0, 5.0, 20.0), (20.0, 5.0, 20.0), (17.0, 5.0, 6.0)]  # x, y, side


def specs(layout=LAYOUT):
    return [SensorSpec(DOWN, x, y, height_for(side), 90.0, 0.0) for x, y, side in layout]


def evaluated(settings, scene=None):
    scene = scene or flat_scene(target=TARGET, sensor=(-1, -1, 31, 11))
    return evaluate_layout(scene, BoxCaster(ground_z=0.0), specs(), settings)


@pytest.mark.parametrize(("k", "covered"), [(1, 300), (2, 100), (3, 36)])
def test_coverage_at_k_matches_the_layout_counted_by_hand(k, covered):
    res = evaluated(CoverageSettings(coverage_k=k))
    assert np.bincount(res.n_covered).tolist() == [0, 200, 64, 36]
    m = res.metrics
    assert m["coverage_k"] == k and m["covered_m2"] == covered
    assert m["coverage_fraction"] == pytest.approx(covered / 300, abs=1e-6)
    assert m["coverage_by_k"] == {
        "1": {"fraction": 1.0, "m2": 300.0},
        "2": {"fraction": pytest.approx(1 / 3, abs=1e-6), "m2": 100.0},
        "3": {"fraction": 0.12, "m2": 36.0},
    }
    # The points short of k form the gaps: x 0..10 and 20..30 at k = 2.
    assert sum(p["m2"] for p in res.uncovered) == 300 - covered
    doc = coverage_dict(res)
    assert doc["coverage_k"] == {"setting": k, "max": k, "areas": {}}
    assert doc["coverage_by_k"]["3"]["m2"] == 36.0


def test_a_target_areas_own_k_overrides_the_setting():
    """Junction (x 0..15) asks k = 2, Straight (x 15..30) k = 1: the Junction's
    points count only twice covered (x 10..15: 50 of its 150), the Straight's once
    (all 150): 200 of 300, whatever the setting says."""
    junction = Area("Target_Junction", shapely.box(0, 0, 15, 10), coverage_k=2)
    straight = Area("Target_Straight", shapely.box(15, 0, 30, 10), coverage_k=1)
    base = flat_scene(target=TARGET, sensor=(-1, -1, 31, 11))
    scene = replace(base, targets=(junction, straight))
    for setting in (1, 3):
        res = evaluated(CoverageSettings(coverage_k=setting), scene)
        assert res.metrics["covered_m2"] == 200.0
        assert res.metrics["coverage_k_max"] == 2
        assert coverage_dict(res)["coverage_k"]["areas"] == {
            "Target_Junction": 2,
            "Target_Straight": 1,
        }
    # Only the Junction with its own k: the Straight takes the setting's 3 (x 15..20
    # holds 5 x 6 of the triple square: 30 points) and the Junction 2 (50).
    scene = replace(base, targets=(junction, Area("Target_Straight", straight.geometry)))
    res = evaluated(CoverageSettings(coverage_k=3), scene)
    assert res.metrics["covered_m2"] == 50.0 + 30.0
    np.testing.assert_array_equal(np.unique(res.need), [2, 3])


@pytest.mark.parametrize("bad", [0, 11])
def test_coverage_k_outside_1_to_10_is_refused(bad):
    with pytest.raises(InputError, match=r"coverage_k \(--coverage-k\) = .* must be in \[1, 10\]"):
        CoverageSettings(coverage_k=bad).validated()
    with pytest.raises(InputError, match="coverage_k must be an integer"):
        OptimizeSettings.from_mapping({"coverage_k": 1.5}, "plan.toml")


# ----------------------------------------------------------------- cover and bounds


def multi(rows, n_points, goal, need):
    inst = instance(rows, n_points, goal)
    return CoverInstance(inst.matrix, goal, need=np.asarray(need, dtype=np.int32))


def brute_force(inst, group=None):
    """The fewest distinct candidates (or groups) covering ``goal`` points each by its
    k, by enumeration."""
    units = range(inst.matrix.shape[0]) if group is None else range(group.max() + 1)
    for size in range(len(units) + 1):
        for pick in itertools.combinations(units, size):
            cols = pick if group is None else np.flatnonzero(np.isin(group, pick))
            count = np.zeros(inst.n_points, int)
            for c in cols:
                count[inst.covers(c)] += 1
            if np.count_nonzero(count >= inst.k) >= inst.goal:
                return size
    return None


def test_the_lp_counts_each_candidate_once():
    """A covers points 0..9, B point 0, C points 1..9; every k = 2, goal 10: point 0
    needs A and B, the rest A and C, so 3 sensors. An LP that let A count twice
    would prove only 2."""
    inst = multi([range(10), [0], range(1, 10)], 10, 10, [2] * 10)
    assert brute_force(inst) == 3
    lp = drain(cover_lp(inst, np.ones(3), np.arange(3), np.arange(1), integral=False))
    assert lp.complete and lp.value == pytest.approx(3.0)
    assert lp.integer_bound() == 3
    cover = improve(complete(Cover(inst), np.arange(3)), np.arange(3))
    assert sorted(cover.chosen) == [0, 1, 2] and cover.slack == 0


@pytest.mark.parametrize("seed", range(10))
def test_k2_bounds_never_exceed_brute_force(seed):
    rng = np.random.default_rng(seed)
    n_cand, n_points = 9, 16
    rows = [rng.choice(n_points, size=rng.integers(3, 10), replace=False) for _ in range(n_cand)]
    seen = np.bincount(np.concatenate(rows), minlength=n_points)
    need = rng.integers(1, 3, n_points)  # a mix of k = 1 and 2
    coverable = int(np.count_nonzero(seen >= need))
    goal = int(rng.integers(1, coverable + 1))
    inst = multi(rows, n_points, goal, need)
    group = rng.integers(0, 4, n_cand)
    group[:4] = np.arange(4)
    best = brute_force(inst)
    ones = np.ones(n_cand)
    # Cut short after its first round, and solved to the end: both bounds hold.
    first = drain(cover_lp(inst, ones, group, np.arange(1), per_round=1, integral=False))
    lp = drain(cover_lp(inst, ones, group, np.arange(1), integral=False))
    assert lp.complete and first.bound <= lp.bound + 1e-9
    assert lp.integer_bound() <= best
    sites = drain(site_cover(inst, group, 4))
    assert sites.bound <= brute_force(inst, group)
    every = np.arange(n_cand)
    cover = improve(complete(Cover(inst), every), every)
    assert cover.slack >= 0 and len(cover.chosen) >= best
    assert len(set(cover.chosen)) == len(cover.chosen)  # no candidate twice
    # Raising every k to 2 never lowers the bound.
    k1 = drain(cover_lp(multi(rows, n_points, goal, [1] * n_points), ones, group, np.arange(1)))
    assert k1.integer_bound() <= lp.integer_bound()


# --------------------------------------------------------------------- optimizers

ROAD = shapely.box(0, -5, 40, 5)
SENSOR_STRIP = shapely.box(0, 8, 40, 12)


def road_scene(targets=((ROAD, None),)):
    return SceneModel(
        vertices=np.zeros((0, 3)),
        faces=np.zeros((0, 3), dtype=np.int32),
        occluders=(),
        targets=tuple(Area(f"Target_{n}", g, coverage_k=k) for n, (g, k) in enumerate(targets)),
        sensor_areas=(Area("SensorArea", SENSOR_STRIP),),
    )


def recount(scene, result, model=PAPER_CAMERA):
    """Sensors covering each target point, each sensor evaluated afresh (the plain
    targeted evaluator on a grid of its own, not the optimizers' cached probe)."""
    caster = BoxCaster(ground_z=0.0)
    grid = GroundGrid(scene, caster, result.cell_m, reach_m=model.range_m)
    ev = TargetedEvaluator(grid, caster)
    counts = np.zeros(grid.n_targets, dtype=int)
    for s in result.sensors:
        x, y = np.array([s.x, s.y]) - result.origin[:2]
        pose = place(grid, x, y, s.height_m, s.pitch_deg, s.yaw_deg)
        counts[ev.evaluate(model, pose).covered] += 1
    return grid, counts


@pytest.mark.parametrize("optimizer", ["greedy", "lp"])
def test_candidate_optimizers_reach_the_goal_at_k2(optimizer):
    scene = road_scene()
    settings = OptimizeSettings(optimizer=optimizer, rho=0.9, bound=True)
    plans = {k: Run(scene, box_caster(), PAPER_CAMERA, replace(settings, coverage_k=k)).result()
             for k in (1, 2)}  # fmt: skip
    res = plans[2]
    assert res.stop_reason.startswith("Reached the goal")
    _, counts = recount(scene, res)
    np.testing.assert_array_equal(counts, res.n_covered)
    assert np.count_nonzero(counts >= 2) >= math.ceil(0.9 * len(counts))
    assert res.metrics["coverage_fraction"] == pytest.approx((counts >= 2).mean(), abs=1e-6)
    assert res.metrics["coverage_k"] == 2
    poses = [(s.x, s.y, s.pitch_deg, s.yaw_deg) for s in res.sensors]
    assert len(set(poses)) == len(poses)  # a candidate once
    m1, m2 = plans[1].metrics, res.metrics
    assert m1["lower_bound"] <= m2["lower_bound"] <= m2["cost"]
    assert m1["sensors_lower_bound"] <= m2["sensors_lower_bound"] <= m2["sensors"]
    # Every point twice needs at least two sensors; one sensor alone covers it once.
    assert m2["sensors_lower_bound"] >= 2 * 1


def test_lp_per_area_k():
    """The west half asks k = 2, the east half k = 1 (setting 1): every counted west
    point is seen twice; the plan needs more than the k = 1 plan and no more than
    the k = 2 plan of the whole road."""
    west, east = shapely.box(0, -5, 20, 5), shapely.box(20, -5, 40, 5)
    scene = road_scene(((west, 2), (east, 1)))
    settings = OptimizeSettings(optimizer="lp", rho=0.95)
    run = Run(scene, box_caster(), PAPER_CAMERA, settings)
    res = run.result()
    grid, counts = recount(scene, res)
    need = np.where(grid.target_region == 0, 2, 1)
    np.testing.assert_array_equal(run.problem.need, need)
    assert np.count_nonzero(counts >= need) >= math.ceil(0.95 * len(counts))
    assert res.metrics["coverage_fraction"] == pytest.approx((counts >= need).mean(), abs=1e-6)
    m = res.metrics
    assert m["lower_bound"] <= m["cost"] and m["coverage_k_max"] == 2


def test_es_at_k2_on_a_small_road():
    """The paper's ES with k = 2: the goal reached, every counted point covered by two
    sensors in a recount; same seed, same plan (and the same with worker processes)."""
    scene = road_scene(((shapely.box(0, -5, 20, 5), None),))
    es = replace(OptimizeSettings().es, mu=6, lam=6, max_epochs=4)
    settings = OptimizeSettings(optimizer="es", rho=0.9, coverage_k=2, seed=3, es=es)
    res = Run(scene, box_caster(), PAPER_CAMERA, settings).result()
    assert res.stop_reason.startswith("Reached the goal")
    _, counts = recount(scene, res)
    assert np.count_nonzero(counts >= 2) >= math.ceil(0.9 * len(counts))
    again = Run(scene, box_caster(), PAPER_CAMERA, settings, workers=2).result()
    assert [(s.x, s.y, s.pitch_deg, s.yaw_deg) for s in again.sensors] == [
        (s.x, s.y, s.pitch_deg, s.yaw_deg) for s in res.sensors
    ]


def test_a_resumed_k2_run_goes_on_as_the_whole_one():
    scene = road_scene()
    settings = OptimizeSettings(optimizer="greedy", rho=0.9, coverage_k=2)
    records = []
    whole = Run(scene, box_caster(), PAPER_CAMERA, settings, on_fixed=records.append).result()
    assert len(records) >= 2
    resumed = Run(scene, box_caster(), PAPER_CAMERA, settings, resume=records[:1]).result()
    assert [(s.x, s.y, s.pitch_deg, s.yaw_deg) for s in resumed.sensors] == [
        (s.x, s.y, s.pitch_deg, s.yaw_deg) for s in whole.sensors
    ]


# ------------------------------------------------------------ greedy's gain rule

# Eight target points 0..7, each asking k = 2; seven candidates (each on a mast of its
# own, so the mast preference plays no part) and the points each covers. A gain is
# the number of a candidate's points still below their k (one covered once counts
# once, one covered twice not at all). By hand, the first on ties:
#   start  A 5, B 4, G 4, C 3, D 3, E 1, F 4  -> A (0..4 once)
#   then   B 4, G 4, C 3, D 3, E 1, F 4       -> B, the first 4 (0..3 twice)
#   then   G 3, C 3, D 3, E 1, F 1            -> G (3 stays at k; 5, 6, 7 once)
#   then   C 3, D 3, E 1, F 1                 -> C (4, 5, 6 twice)
#   then   D 1, E 1, F 1                      -> D (7 twice): 8 of 8, the goal.
# Counting points already at k picks F fourth (its 0, 1, 2 would still count: 4);
# counting the missing cover (a point at 0 counted twice: after A, G 7 beats B 4) or
# only points not covered at all (the k = 1 rule: B 0, G 3) picks G second; taking
# a point that reaches k off twice (G 2 after B) picks C third.
HAND_K2 = {
    "A": [0, 1, 2, 3, 4],
    "B": [0, 1, 2, 3],
    "G": [3, 5, 6, 7],
    "C": [4, 5, 6],
    "D": [5, 6, 7],
    "E": [7],
    "F": [0, 1, 2, 7],
}
HAND_ORDER = ["A", "B", "G", "C", "D"]
HAND_GAINS = [5, 4, 3, 3, 1]
HAND_NEWLY = [[], [0, 1, 2, 3], [], [4, 5, 6], [7]]  # the points each brings to k = 2


class HandProblem:
    """What greedy reads of a Problem, on the hand-made candidates above: candidate
    c stands at (10 c, 0), looks at pitch 45, yaw 0 and covers its ``HAND_K2`` points."""

    def __init__(self):
        rows = list(HAND_K2.values())
        n = len(rows)
        self.need = np.full(8, 2, dtype=np.int32)
        self.n_targets = 8
        self.rho = 1.0
        self.goal = 8
        self.estimate = SimpleNamespace(parts=1)  # planned whole
        self.max_sensors = 16
        self.candidates = CandidateSet(
            positions=np.array([(10.0 * c, 0.0) for c in range(n)]),
            angles=(np.array([(45.0, 0.0)]),),
            models=(PAPER_CAMERA,),
            position=np.arange(n),
            orientation=np.zeros(n, dtype=np.int64),
            model=np.zeros(n, dtype=np.int64),
            matrix=instance(rows, 8, self.goal).matrix,
        )
        self.space = SimpleNamespace(standing=np.zeros(n, dtype=bool))  # no mast stands
        self.settings = OptimizeSettings(optimizer="greedy", objective="sensors")
        self.sensor_costs = np.ones(1)

    def reached(self, n_covered):
        return n_covered >= self.goal

    def pose(self, x, y, pitch, yaw, model=0):
        return SensorPose(float(x), float(y), 6.0, 6.0, float(pitch), float(yaw))

    def evaluate(self, pose, model=0):
        points = list(HAND_K2.values())[round(pose.x / 10.0)]
        return SimpleNamespace(covered=np.array(points, dtype=np.int64), rays=0)


def hand_names(sensors):
    names = list(HAND_K2)
    return [names[round(s.pose.x / 10.0)] for s in sensors]


def test_greedy_at_k2_gains_count_points_still_below_their_k():
    problem = HandProblem()
    start = Solution(np.zeros(8, dtype=bool), need=problem.need)
    res = drain(Greedy().solve(problem, start))
    assert hand_names(res.sensors) == HAND_ORDER
    assert [s.fitness for s in res.sensors] == HAND_GAINS
    assert [s.newly.tolist() for s in res.sensors] == HAND_NEWLY
    # Point 3: A, B, G; 5 and 6: G, C, D; the rest twice.
    assert res.n_covered == 8 and res.counts.tolist() == [2, 2, 2, 3, 2, 3, 3, 2]
    assert res.stop_reason.startswith("Reached the goal")
    # The cover moves share the rule: complete() picks the same five.
    inst = multi(list(HAND_K2.values()), 8, 8, [2] * 8)
    cover = complete(Cover(inst), np.arange(len(HAND_K2)))
    assert [list(HAND_K2)[c] for c in cover.chosen] == HAND_ORDER


def test_greedy_resumed_at_k2_leaves_out_points_already_at_k():
    """Resumed after A and B (points 0..3 twice, 4 once): G, C, D as in the whole
    run; were the points at k counted from the start, F (4) would come before C."""
    problem = HandProblem()
    start = Solution(np.zeros(8, dtype=bool), need=problem.need)
    for c in (0, 1):
        fix_candidate(problem, start, problem.candidates, c)
    assert start.counts.tolist() == [2, 2, 2, 2, 1, 0, 0, 0] and start.n_covered == 4
    res = drain(Greedy().solve(problem, start))
    assert hand_names(res.sensors) == HAND_ORDER
    assert [s.fitness for s in res.sensors[2:]] == HAND_GAINS[2:]
