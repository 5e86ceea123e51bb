"""Greedy's own rules on hand cases: it goes on from sensors fixed before (a resumed
run, sensors that stand) without breaking the per-mast cap, prices per cost only in
the cost objective and in any unit of money, and stops with the reason a planner
reads. On the two-site scene below the points each pose adds are the candidate
matrix's (``test_candidates`` checks it against evaluating every pose afresh); which
pose wins, given them, is worked out by hand from greedy's rule."""

from dataclasses import replace

import pytest
import shapely

from autoscoop_blender.core.candidates import build_candidates
from autoscoop_blender.core.model.scene import Area
from autoscoop_blender.core.model.sensors import ROADSIDE_LIDAR, SensorPack, SensorSpec
from autoscoop_blender.core.optimize.base import StopReason
from autoscoop_blender.core.problem import Problem
from autoscoop_blender.core.run import Run
from autoscoop_blender.core.settings import OptimizeSettings
from tests.core.flat import box_caster, flat_scene
from tests.core.test_lp import drain
from tests.core.test_mixed_pack import CAMERA, LIDAR, TARGET, TILTED, two_sites

# On ``two_sites`` (sites A (0, 0) and B (2, 0)) with the TILTED camera, the 60 % goal
# is 540 of the 900 points. Greedy fixes yaws 150 and 230 on B (249 and 220 new
# points), then B's yaw 50 (187 new, 374 at the cost objective's mast preference of 1)
# over A's yaw 30 (209 new); with two per mast B is full and A's yaw 30 comes third.
# (x, y, yaw, new points) as fixed:
TWO_SITES_PLAN = {
    4: [(2.0, 0.0, 150.0, 249), (2.0, 0.0, 230.0, 220), (2.0, 0.0, 50.0, 187)],
    2: [(2.0, 0.0, 150.0, 249), (2.0, 0.0, 230.0, 220), (0.0, 0.0, 30.0, 209)],
}


def _greedy(cap=4, objective="cost", **kw):
    """The run's result and its fixed sensors as (x, y, yaw, new points), in order (the
    result's sensors are after mast grouping, which may move them to a nearby mast)."""
    given = {"rho": 0.6, "max_sensors_per_mast": cap, "objective": objective}
    settings = OptimizeSettings(optimizer="greedy", **(given | kw.pop("settings", {})))
    records = []
    run = Run(two_sites(), box_caster(), TILTED, settings, on_fixed=records.append, **kw)
    res = run.result()
    return res, [(r["x"], r["y"], r["yaw_deg"], r["new_points"]) for r in records]


@pytest.mark.parametrize("cap", [4, 2])
def test_the_two_site_plans(cap):
    res, fixed = _greedy(cap)
    assert fixed == TWO_SITES_PLAN[cap]
    assert sorted(len(m.sensors) for m in res.masts) == ([3] if cap == 4 else [1, 2])


def test_the_sensors_objective_prefers_a_mast_in_use_less():
    """At the sensors objective's preference of 0.1, B's 187 new points count 205.7 on
    its mast in use: A's 209 win the third sensor."""
    assert _greedy(4, "sensors")[1] == TWO_SITES_PLAN[2]


@pytest.mark.parametrize(("cap", "kept"), [(4, 1), (4, 2), (2, 2)])
def test_a_resumed_run_goes_on_as_the_whole_one(cap, kept):
    """Resumed after B's first two sensors, B's mast is in use: its yaw 50 is preferred
    over A's yaw 30 (as after one); at a cap of two B is full and the third goes to A,
    as in the runs that were never cut."""
    settings = OptimizeSettings(optimizer="greedy", rho=0.6, max_sensors_per_mast=cap)
    records = []
    Run(two_sites(), box_caster(), TILTED, settings, on_fixed=records.append).result()
    _, fixed = _greedy(cap, resume=records[:kept])
    assert fixed == TWO_SITES_PLAN[cap][kept:]


def test_a_sensor_that_stands_leaves_the_masts_slots_free():
    """B's first sensor stands already: two new ones still fit on B at a cap of two
    (standing sensors do not count against it), so the plan is the four-per-mast one;
    B's mast stands, so the plan costs the two new sensors alone."""
    first = SensorSpec(TILTED, 2.0, 0.0, 10.0, 45.0, 150.0)
    res, fixed = _greedy(2, existing=[first])
    assert fixed == TWO_SITES_PLAN[4][1:]
    assert len(res.masts) == 1 and res.metrics["cost"] == 2.0


def test_a_resumed_run_at_a_full_mast_adds_nothing():
    """Site B alone at one sensor per mast: the first sensor fills it and the run stops
    short of 60 %; resumed after that sensor it stops at once."""
    scene = replace(two_sites(), sensor_areas=two_sites().sensor_areas[1:])
    settings = OptimizeSettings(optimizer="greedy", rho=0.6, max_sensors_per_mast=1)
    records = []
    whole = Run(scene, box_caster(), TILTED, settings, on_fixed=records.append).result()
    assert len(records) == 1 and records[0]["new_points"] == 249
    resumed = Run(scene, box_caster(), TILTED, settings, resume=records).result()
    assert len(resumed.sensors) == 1
    assert resumed.stop_reason == whole.stop_reason == StopReason.out_of_sight("candidate pose")


def test_the_sensor_limit_stops_greedy_with_its_reason():
    res, fixed = _greedy(settings={"rho": 1.0, "max_sensors": 2})
    assert fixed == TWO_SITES_PLAN[4][:2]
    assert res.stop_reason == StopReason.sensor_limit(2)


def test_greedy_adds_no_sensor_that_adds_nothing():
    """A second target 600 m off, past every range: greedy covers the road and stops,
    each of its sensors adding new points, with the reason named."""
    scene = flat_scene(target=TARGET, sensor=(-1, -1, 31, 11))
    far = Area("Target_Far", shapely.box(600, 0, 630, 10))
    scene = replace(scene, targets=(*scene.targets, far))
    records = []
    settings = OptimizeSettings(optimizer="greedy", rho=0.97)
    res = Run(scene, box_caster(), CAMERA, settings, on_fixed=records.append).result()
    assert res.stop_reason == StopReason.out_of_sight("candidate pose")
    assert len(records) >= 2 and all(r["new_points"] > 0 for r in records)
    near = res.points[:, 0] < 100
    assert (res.n_covered[near] > 0).all() and (res.n_covered[~near] == 0).all()
    # Resumed after the first sensor: the same sensors follow, the first never again.
    again = []
    Run(scene, box_caster(), CAMERA, settings, resume=records[:1], on_fixed=again.append).result()
    fixed = [(r["n"], r["x"], r["y"], r["yaw_deg"], r["new_points"]) for r in records]
    assert [(r["n"], r["x"], r["y"], r["yaw_deg"], r["new_points"]) for r in again] == fixed[1:]


def test_a_target_out_of_every_range_has_no_candidate():
    scene = flat_scene(target=(600, 0, 630, 10), sensor=(-1, -1, 31, 11))
    res = Run(scene, box_caster(), CAMERA, OptimizeSettings(optimizer="greedy")).result()
    assert res.sensors == () and res.stop_reason == StopReason.out_of_sight("candidate pose")


def test_one_candidate_for_one_point():
    """A level spinning lidar (one orientation) on a site of one lattice position, and
    a 1 m^2 target (one grid point) 20 m off, past the 16.8 m the lidar's lowest beam
    (16.6 deg down from 5 m) first meets the ground: one candidate, and it is fixed."""
    lidar = replace(ROADSIDE_LIDAR, pitch_max_deg=0.0)
    scene = flat_scene(target=(20, 0, 21, 1), sensor=(-0.4, -0.4, 0.4, 0.4))
    settings = OptimizeSettings(optimizer="greedy", rho=1.0)
    problem = Problem(scene, box_caster()(), lidar, settings)
    assert problem.n_targets == 1 and len(drain(build_candidates(problem))) == 1
    res = Run(scene, box_caster(), lidar, settings).result()
    assert len(res.sensors) == 1 and res.metrics["coverage_fraction"] == 1.0


def _pack_plan(costs, objective):
    settings = OptimizeSettings(optimizer="greedy", objective=objective, mast_cost=0.0)
    scene = flat_scene(target=TARGET, sensor=(-1, -1, 31, 11))
    pack = SensorPack((CAMERA, LIDAR), costs)
    return sorted(s.model.kind for s in Run(scene, box_caster(), pack, settings).result().sensors)


def test_greedy_prices_per_cost_in_any_unit():
    """The lidar (240 points) at 4 cameras' price (110 each): per cost the cameras win
    (three of them), whether a camera costs 1 or 0.25."""
    assert _pack_plan((1.0, 4.0), "cost") == ["camera"] * 3
    assert _pack_plan((0.25, 1.0), "cost") == ["camera"] * 3


def test_one_point_goes_to_the_cheaper_model():
    """A 1 m^2 target that the lidar (listed first, cost 4) and the camera (cost 1)
    both see: one new point each, per cost the camera's is worth four times more."""
    settings = OptimizeSettings(optimizer="greedy", objective="cost", rho=1.0)
    scene = flat_scene(target=(0, 0, 1, 1), sensor=(-0.4, -0.4, 0.4, 0.4))
    pack = SensorPack((LIDAR, CAMERA), (4.0, 1.0))
    res = Run(scene, box_caster(), pack, settings).result()
    assert [s.model.kind for s in res.sensors] == ["camera"]


def test_greedy_counts_sensors_in_the_sensors_objective():
    """The fewest sensors: the lidar's 240 points first, whatever it costs, and one
    camera for the rest (two sensors, not three cameras)."""
    assert _pack_plan((1.0, 4.0), "sensors") == ["camera", "lidar"]
