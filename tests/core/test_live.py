"""Live re-scoring (``core.live``): moving one sensor gives exactly the counts a full
evaluation of the new layout gives, and squares seen straight down give the figures
worked out by hand."""

from __future__ import annotations

import math
from dataclasses import replace

import numpy as np
import pytest
import shapely

from autoscoop_blender.core.evaluate import evaluate_layout
from autoscoop_blender.core.live import LiveLayout
from autoscoop_blender.core.model.scene import Area
from autoscoop_blender.core.model.sensors import SensorModel, SensorSpec
from autoscoop_blender.core.settings import CoverageSettings
from tests.core.flat import box_caster, flat_scene

# A pinhole camera looking straight down sees a square of side 2 h tan 30 deg.
DOWN = SensorModel.from_spec(
    {"preset": "paper_camera", "pattern": "pinhole", "h_fov_deg": 60, "v_fov_deg": 60,
     "range_m": 40, "pitch_min_deg": 90, "pitch_max_deg": 90, "min_density_per_m2": 0},
    "test",
)  # fmt: skip
WALL = [((28.0, -30.0, 0.0), (29.0, 30.0, 4.0))]


def down(x: float, y: float, side: float = 20.0) -> SensorSpec:
    """A camera over (x, y) whose square on the ground is ``side`` wide."""
    return SensorSpec(DOWN, x, y, side / 2 / math.tan(math.radians(30)), 90.0, 0.0)


def test_squares_seen_straight_down_count_as_by_hand():
    """Target x 0..100, y -20..20 (1 m grid: 4,000 points). Squares of 20 m over
    (30, 0) and (40, 0): x 20..50 seen (600 points), x 30..40 twice (200)."""
    scene = flat_scene(target=(0.0, -20.0, 100.0, 20.0), sensor=(0.0, -20.0, 100.0, 20.0))
    live = LiveLayout(scene, box_caster()(), [down(30, 0), down(40, 0)], CoverageSettings())
    m = live.metrics()
    # x 20..50 by y -10..10: 600 points once or more; 200 (x 30..40) twice.
    assert (m["covered_m2"], m["target_area_m2"]) == (600.0, 4000.0)
    assert np.count_nonzero(live.counts == 2) == 200
    assert (m["sensors"], m["masts"], m["cost"]) == (2, 2, 8.0)  # 10 m apart: 2 masts
    # Each covers 400 m^2 (10 % of the target); without one, the 200 only it sees.
    assert live.alone(0) == live.alone(1)
    assert (live.alone(0).covers_m2, live.alone(0).share, live.alone(0).lost_m2) == (
        400.0, 0.1, 200.0,
    )  # fmt: skip
    # Moved onto the other: 400 covered, twice; neither loses anything alone.
    live.move(1, down(30, 0))
    assert live.metrics()["covered_m2"] == 400.0 and live.alone(1).lost_m2 == 0.0
    assert live.metrics()["masts"] == 1
    # Moved away to (80, 0): 800 once, each loses its own 400 without it.
    live.move(1, down(80, 0))
    assert live.metrics()["covered_m2"] == 800.0 and live.alone(0).lost_m2 == 400.0
    live.remove(0)
    assert live.metrics()["covered_m2"] == 400.0 and live.counts.sum() == 400
    assert live.add(down(80, 0)) == 1 and np.count_nonzero(live.counts == 2) == 400


def test_with_k_two_a_sensor_loses_what_only_it_brings_to_two():
    """k = 2: the 200 points both squares see count; without either, none does."""
    scene = flat_scene(target=(0.0, -20.0, 100.0, 20.0), sensor=(0.0, -20.0, 100.0, 20.0))
    settings = CoverageSettings(coverage_k=2)
    live = LiveLayout(scene, box_caster()(), [down(30, 0), down(40, 0)], settings)
    assert live.metrics()["covered_m2"] == 200.0
    assert live.alone(0).lost_m2 == 200.0 and live.alone(0).covers_m2 == 400.0


@pytest.mark.parametrize("seed", [0, 1])
def test_moves_give_what_a_full_evaluation_gives(seed):
    """A wall at x 28..29 casts shadows; after each random move (position, height,
    pitch, yaw, and now and then a camera swapped for a straight-down one) the counts
    equal ``evaluate_layout``'s on the layout as it stands, point for point."""
    rng = np.random.default_rng(seed)
    scene = flat_scene(target=(0.0, -20.0, 60.0, 20.0), sensor=(-5.0, -25.0, 65.0, 25.0),
                       boxes=WALL)  # fmt: skip
    caster = box_caster(WALL)()
    camera = SensorModel.from_spec("paper_camera", "test")

    def random_spec() -> SensorSpec:
        if rng.random() < 0.2:
            return down(float(rng.uniform(5, 55)), float(rng.uniform(-15, 15)))
        return SensorSpec(
            camera, float(rng.uniform(-5, 65)), float(rng.choice([-25.0, 25.0])),
            float(rng.uniform(4, 10)), float(rng.uniform(31, 70)), float(rng.uniform(0, 360)),
        )  # fmt: skip

    settings = CoverageSettings()
    live = LiveLayout(scene, caster, [random_spec() for _ in range(4)], settings, reach_m=80.0)
    for _ in range(12):
        live.move(int(rng.integers(len(live.specs))), random_spec())
        whole = evaluate_layout(scene, caster, live.specs, settings)
        np.testing.assert_array_equal(live.counts, whole.n_covered)
        assert live.metrics()["coverage_fraction"] == whole.metrics["coverage_fraction"]
        assert live.metrics()["masts"] == whole.metrics["masts"]
    assert live.counts.max() >= 1 and live.counts.sum() > 0  # the moves saw something


def test_a_sensor_says_why_its_mast_may_not_stand_where_it_does():
    """A no-mast zone over x 40..50: a mast there may not stand; nor one outside the
    sensor area (y beyond 25); one in the area may."""
    scene = flat_scene(target=(0.0, -20.0, 60.0, 20.0), sensor=(-5.0, -25.0, 65.0, 25.0))
    lane = Area("NoMast_Lane", shapely.box(40.0, -25.0, 50.0, 25.0))
    scene = replace(scene, no_mast=(lane,))
    live = LiveLayout(scene, box_caster()(), [down(10, 0)], CoverageSettings())
    assert live.problems == [None]
    live.move(0, down(45, 0))
    assert live.problems == ["on or beside NoMast_Lane, where no mast may stand"]
    live.move(0, down(10, 40))
    assert live.problems == ["outside every sensor area"]
    live.add(down(20, 0))
    live.remove(0)
    assert live.problems == [None]


def test_snapping_moves_a_mast_to_the_nearest_place_it_may_stand():
    """In the no-mast zone x 40..50 at x = 44 the nearest allowed ground is x = 40
    (less the inset); beyond the area at y = 40 it is y = 25; a sensor where a mast
    may stand stays; a sensor area out of range is no place to snap to."""
    scene = flat_scene(target=(0.0, -20.0, 60.0, 20.0), sensor=(-5.0, -25.0, 65.0, 25.0))
    scene = replace(scene, no_mast=(Area("NoMast_Lane", shapely.box(40.0, -25.0, 50.0, 25.0)),))
    # (The extraction cuts the zone out of the areas: here by hand.)
    cut = shapely.difference(scene.sensor_areas[0].geometry, scene.no_mast[0].geometry)
    scene = replace(scene, sensor_areas=(Area("SensorArea", cut),))
    live = LiveLayout(scene, box_caster()(), [down(44, 3), down(10, 40)], CoverageSettings())
    inset = 0.05
    first = live.snapped(0)
    assert (first.x, first.y) == pytest.approx((40.0 - inset, 3.0), abs=1e-6)
    assert first.height_m == live.specs[0].height_m
    second = live.snapped(1)
    assert (second.x, second.y) == pytest.approx((10.0, 25.0 - inset), abs=1e-6)
    live.move(0, first)
    live.move(1, second)
    assert live.problems == [None, None]
    assert live.snapped(0) == live.specs[0]  # already where a mast may stand
    far = down(10, 25.0 + DOWN.range_m + 5.0)
    live.move(1, far)
    assert live.snapped(1) is None


def test_filling_a_gap_adds_the_sensor_that_raises_the_most_points_short():
    """Squares of 400 points over (30, 0) and (40, 0) cover x 20..50. A camera added at
    the model's mount height, 7 m, sees a square of 2 x 7 tan 30 deg = 8.08 m: 64
    points, all of them new where nothing is seen, and added it covers them. With
    k = 2 a camera on the standing mast at (30, 0) raises 64 points of its square to
    2 as much as one anywhere raises 64 to 1: the standing mast is taken (no new
    mast)."""
    scene = flat_scene(target=(0.0, -20.0, 100.0, 20.0), sensor=(0.0, -20.0, 100.0, 20.0))
    live = LiveLayout(scene, box_caster()(), [down(30, 0), down(40, 0)], CoverageSettings())
    add = live.best_addition(DOWN, most_sites=30)
    assert add.gain_points == 64 and not add.on_standing_mast
    live.add(add.spec)
    assert live.metrics()["covered_m2"] == 664.0
    twice = LiveLayout(scene, box_caster()(), [down(30, 0)], CoverageSettings(coverage_k=2))
    add = twice.best_addition(DOWN, most_sites=30)
    assert add.gain_points == 64 and add.on_standing_mast
    assert (add.spec.x, add.spec.y) == (30.0, 0.0)


def test_nothing_to_fill_when_all_is_covered():
    scene = flat_scene(target=(20.0, -10.0, 40.0, 10.0), sensor=(0.0, -20.0, 100.0, 20.0))
    live = LiveLayout(scene, box_caster()(), [down(30, 0)], CoverageSettings())
    assert live.metrics()["coverage_fraction"] == 1.0 and live.best_addition(DOWN) is None
