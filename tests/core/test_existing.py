"""Sensors that stand already (issue 16 point 2): kept exactly as given, counted toward
coverage, free of cost; the plan adds what is missing. Figures worked out by hand on
a 30 m x 10 m flat target watched by a camera looking straight down."""

import math

import numpy as np
import pytest

from autoscoop_blender.core.errors import InputError
from autoscoop_blender.core.masts import choose_sites
from autoscoop_blender.core.model.sensors import PAPER_CAMERA, SensorSpec
from autoscoop_blender.core.run import Run
from autoscoop_blender.core.settings import ESParams, OptimizeSettings
from tests.core.flat import box_caster, down_camera, flat_scene

DOWN = down_camera(30.0)
# From 10 m up its footprint is a square 2 x 10 x tan(30 deg) = 11.55 m on a side:
# 11 columns of 1 m cells (centres at .5) and all 10 rows of the target.
SIDE = 2 * 10 * math.tan(math.radians(30))
TARGET = (0.0, 0.0, 30.0, 10.0)
# Two cameras on the target's ends: x 0..10.77 and 19.23..30, 110 points each, 220 of
# 300. The 80 points in between (x 11..19) fit under one more camera; from scratch
# 97 % (291 points) needs ceil(291 / 110) = 3.
GIVEN = [SensorSpec(DOWN, 5.0, 5.0, 10.0, 90.0, 0.0), SensorSpec(DOWN, 25.0, 5.0, 10.0, 90.0, 0.0)]
FAST_ES = ESParams(mu=8, lam=4, max_epochs=6)


def _run(optimizer, existing=(), **kw):
    settings = OptimizeSettings(optimizer=optimizer, objective="sensors", es=FAST_ES, **kw)
    scene = flat_scene(target=TARGET, sensor=(-1, -1, 31, 11))
    return Run(scene, box_caster(), DOWN, settings, existing=existing).result()


@pytest.mark.parametrize("optimizer", ["greedy", "lp", "es"])
def test_given_sensors_stay_and_the_plan_adds_what_is_missing(optimizer):
    scratch = _run(optimizer)
    res = _run(optimizer, GIVEN)
    given = [s for s in res.sensors if s.existing]
    new = [s for s in res.sensors if not s.existing]
    # Never moved, never dropped: exactly where and as high as given.
    assert [(s.x, s.y, s.z, s.pitch_deg) for s in given] == [
        (5.0, 5.0, 10.0, 90.0),
        (25.0, 5.0, 10.0, 90.0),
    ]
    assert given[0].covered_target_m2 == given[1].covered_target_m2 == 110.0
    # Together they reach the goal; the new sensors are no more than from scratch.
    assert res.metrics["coverage_fraction"] >= 0.97
    assert scratch.metrics["coverage_fraction"] >= 0.97
    assert 1 <= len(new) <= len(scratch.sensors)
    # The given ones cost nothing: the objective counts the new sensors only.
    assert res.metrics["objective"] == len(new)
    assert res.metrics["existing_sensors"] == 2 and res.metrics["existing_masts"] == 2
    assert sum(m.existing for m in res.masts) == 2


def test_the_exact_plan_needs_one_more_and_proves_it():
    res = _run("lp", GIVEN)
    assert len(res.sensors) == 3 and res.metrics["objective"] == 1
    assert res.metrics["lower_bound"] == 1  # 80 points uncovered: at least one sensor
    assert _run("lp").metrics["objective"] == 3  # from scratch, as worked out above


def test_a_given_sensor_of_another_model_is_refused():
    other = SensorSpec(PAPER_CAMERA, 5.0, 5.0, 7.0, 45.0, 0.0)
    with pytest.raises(InputError, match=r"existing sensor 1 at \(5, 5\): its model is not one"):
        _run("greedy", [other])


def test_a_fixed_sensor_keeps_its_site_and_draws_the_others_to_it():
    """Two sensors in one group see the same points from either site: the movable one
    joins the fixed one, whichever it is."""
    xy = np.array([[0.0, 0.0], [1.0, 0.0]])
    labels = np.array([0, 0])

    def cover(i, x, y):
        return np.arange(5)

    for still in ([True, False], [False, True]):
        fixed = np.array(still)
        new_xy, final = choose_sites(xy, labels, cover, 5, 5, fixed=fixed)
        np.testing.assert_array_equal(new_xy, [xy[fixed.argmax()]] * 2)
        assert final.tolist() == [0, 0]
    # Two fixed sensors in one group stay two masts.
    new_xy, final = choose_sites(xy, labels, cover, 5, 5, fixed=np.array([True, True]))
    np.testing.assert_array_equal(new_xy, xy)
    assert final.tolist() == [0, 1]


def test_a_standing_mast_with_free_slots_takes_the_new_sensor():
    """A mast stands at (15, 5), off the 2 m lattice, with no sensor: a camera there
    covers the 80 points the given two leave (x 9.2..20.8), as do lattice sites
    14 and 16; greedy takes the standing mast, which adds no mast to the cost."""
    settings = OptimizeSettings(optimizer="greedy", objective="cost", mast_cost=3.0)
    scene = flat_scene(target=TARGET, sensor=(-1, -1, 31, 11))
    run = Run(scene, box_caster(), DOWN, settings, existing=GIVEN, existing_masts=[(15.0, 5.0)])
    res = run.result()
    new = [s for s in res.sensors if not s.existing]
    assert [(s.x, s.y) for s in new] == [(15.0, 5.0)]
    assert [m.existing for m in res.masts] == [True, True, True]
    assert res.metrics["cost"] == 1.0  # one sensor, no new mast
    # Without the standing mast the same plan needs a new one: 3 + 1.
    res = Run(scene, box_caster(), DOWN, settings, existing=GIVEN).result()
    assert res.metrics["cost"] == 4.0


@pytest.mark.parametrize("optimizer", ["lp", "greedy"])
def test_the_bound_knows_a_standing_mast_costs_nothing(optimizer):
    """With the mast at (15, 5) standing, the cheapest plan adds one sensor there and
    no mast: cost 1, and the proof says no plan costs less than 1."""
    settings = OptimizeSettings(optimizer=optimizer, objective="cost", mast_cost=3.0, bound=True)
    scene = flat_scene(target=TARGET, sensor=(-1, -1, 31, 11))
    run = Run(scene, box_caster(), DOWN, settings, existing=GIVEN, existing_masts=[(15.0, 5.0)])
    m = run.result().metrics
    assert m["cost"] == 1.0
    assert m["lower_bound"] == 1.0 and m["masts_lower_bound"] == 0
    # Without it: one new mast and one sensor at least, 3 + 1.
    m = Run(scene, box_caster(), DOWN, settings, existing=GIVEN).result().metrics
    assert m["cost"] == 4.0 and m["lower_bound"] == 4.0
