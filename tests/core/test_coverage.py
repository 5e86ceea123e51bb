"""Coverage invariants and the analytic shadow of a box, without Blender."""

import math
from dataclasses import replace

import numpy as np
import pytest
import shapely

from autoscoop_blender.core.coverage.base import place, summarize
from autoscoop_blender.core.coverage.pointcloud import PointcloudEvaluator
from autoscoop_blender.core.coverage.targeted import TargetedEvaluator
from autoscoop_blender.core.geom.grid import GroundGrid
from autoscoop_blender.core.model.sensors import PAPER_CAMERA
from tests.core.flat import flat_grid, flat_scene

BOX = ((10.0, -2.0, 0.0), (12.0, 6.0, 3.0))


def analytic_shadow(sensor_xyz, lo, hi):
    """Area of ground a box hides from a point light, minus the box's own base:
    the convex hull of the vertices projected from the light onto z = 0."""
    s = np.asarray(sensor_xyz, dtype=float)
    corners = np.array(
        [[x, y, z] for x in (lo[0], hi[0]) for y in (lo[1], hi[1]) for z in (lo[2], hi[2])]
    )
    proj = s[:2] + (corners[:, :2] - s[:2]) * (s[2] / (s[2] - corners[:, 2:3]))
    hull = shapely.MultiPoint(proj).convex_hull
    return hull.area - shapely.box(lo[0], lo[1], hi[0], hi[1]).area


def test_targeted_hides_the_analytic_shadow_of_a_box():
    model = replace(PAPER_CAMERA, min_density_per_m2=0.0)
    open_grid, open_caster = flat_grid(spacing=0.25, target=(0, -30, 50, 30))
    boxed_grid, boxed_caster = flat_grid(spacing=0.25, boxes=[BOX], target=(0, -30, 50, 30))
    areas = []
    for grid, caster in ((open_grid, open_caster), (boxed_grid, boxed_caster)):
        pose = place(grid, -6.0, 0.0, 7.0, 40.0, 0.0)
        cov = TargetedEvaluator(grid, caster).evaluate(model, pose)
        areas.append(len(cov.covered) * grid.cell_area)
    expected = analytic_shadow((-6.0, 0.0, 7.0), *BOX)
    assert areas[0] - areas[1] == pytest.approx(expected, rel=0.01)


def test_targets_above_the_road_see_past_a_box():
    """target_height_m = 1 (a vehicle): the points sit on the plane z = 1, where only
    the box's part above 1 m casts a shadow: the hull of its section at 1 m and its
    top corners projected from the sensor onto z = 1, minus the box's base (its points
    stand on its top, in view)."""
    t, sensor = 1.0, np.array([-6.0, 0.0, 7.0])
    (x0, y0, _), (x1, y1, top) = BOX
    section = [(x, y) for x in (x0, x1) for y in (y0, y1)]
    roof = np.array([(x, y, top) for x, y in section])
    projected = sensor[:2] + (roof[:, :2] - sensor[:2]) * ((sensor[2] - t) / (sensor[2] - top))
    hull = shapely.MultiPoint(np.vstack([section, projected])).convex_hull
    expected = hull.area - shapely.box(x0, y0, x1, y1).area
    assert expected < analytic_shadow(sensor, *BOX) - 20  # a real difference to find
    model = replace(PAPER_CAMERA, min_density_per_m2=0.0)
    areas = []
    for boxes in ((), (BOX,)):
        _, caster = flat_grid(spacing=0.25, boxes=boxes, target=(0, -30, 50, 30))
        scene = flat_scene(boxes=boxes, target=(0, -30, 50, 30))
        lifted = GroundGrid(scene, caster, 0.25, target_height_m=t, reach_m=80.0)
        cov = TargetedEvaluator(lifted, caster).evaluate(
            model, place(lifted, *sensor[:2], 7.0, 40.0, 0.0)
        )
        areas.append(len(cov.covered) * lifted.cell_area)
    assert areas[0] - areas[1] == pytest.approx(expected, rel=0.01)


def test_a_roof_top_lidar_sees_all_around():
    """A 360 deg lidar on a 10 m mast, level: with nothing in the way it covers the
    ring between where its lowest ray meets the ground and its range, every bearing."""
    from autoscoop_blender.core.model.sensors import ROADSIDE_LIDAR

    model = replace(ROADSIDE_LIDAR, h_fov_deg=360.0, range_m=40.0, min_density_per_m2=0.0)
    grid, caster = flat_grid(spacing=0.5, target=(-50, -50, 50, 50), sensor=(-1, -1, 1, 1))
    cov = TargetedEvaluator(grid, caster).evaluate(model, place(grid, 0.0, 0.0, 10.0, 0.0, 0.0))
    xy = grid.target_xy[cov.covered]
    r = np.hypot(xy[:, 0], xy[:, 1])
    inner = 10.0 / math.tan(math.radians(model.v_fov_deg / 2))  # lowest ray's ground hit
    outer = math.sqrt(40.0**2 - 10.0**2)  # the 40 m range, 10 m up
    ring = math.pi * (outer**2 - inner**2)
    assert len(cov.covered) * grid.cell_area == pytest.approx(ring, rel=0.02)
    assert r.min() >= inner - 0.5 and r.max() <= outer + 0.5
    # Every bearing: the covered points' angles leave no gap wider than a few cells.
    bearings = np.sort(np.degrees(np.arctan2(xy[:, 1], xy[:, 0])))
    assert np.diff(np.concatenate([bearings, bearings[:1] + 360])).max() < 2.0


@pytest.fixture(scope="module")
def boxed():
    boxes = [((10, -2, 0), (12, 6, 3)), ((-30, 20, 0), (-20, 30, 8)), ((30, -40, 0), (34, -30, 5))]
    return flat_grid(spacing=1.0, boxes=boxes, target=(-60, -60, 60, 60), sensor=(-50, -50, 50, 50))


def _random_poses(grid, n, seed):
    rng = np.random.default_rng(seed)
    return [
        place(grid, *rng.uniform(-50, 50, 2), 7.0, rng.uniform(31, 70), rng.uniform(0, 360))
        for _ in range(n)
    ]


@pytest.mark.parametrize("method", ["targeted", "pointcloud"])
def test_coverage_never_drops_when_a_sensor_is_added(boxed, method):
    grid, caster = boxed
    ev = (
        TargetedEvaluator(grid, caster)
        if method == "targeted"
        else PointcloudEvaluator(grid, caster)
    )
    covs = [ev.evaluate(PAPER_CAMERA, p, visibility=True) for p in _random_poses(grid, 6, 1)]
    fractions = [summarize(grid, covs[:k]).coverage_fraction for k in range(len(covs) + 1)]
    assert fractions[0] == 0.0
    assert all(b >= a for a, b in zip(fractions, fractions[1:]))
    assert 0.0 < fractions[-1] <= 1.0
    s = summarize(grid, covs)
    # Covered implies visible; the best density is over the threshold where covered.
    assert (s.n_covered <= s.n_visible).all()
    assert (s.best_density[s.n_covered > 0] >= PAPER_CAMERA.min_density_per_m2 - 1e-9).all()


@pytest.mark.parametrize("method", ["targeted", "pointcloud"])
def test_same_input_same_output(boxed, method):
    grid, caster = boxed
    ev = (
        TargetedEvaluator(grid, caster)
        if method == "targeted"
        else PointcloudEvaluator(grid, caster)
    )
    pose = _random_poses(grid, 1, 7)[0]
    a = ev.evaluate(PAPER_CAMERA, pose, outside_band_m=math.inf, visibility=True)
    b = ev.evaluate(PAPER_CAMERA, pose, outside_band_m=math.inf, visibility=True)
    assert np.array_equal(a.covered, b.covered) and np.array_equal(a.chi, b.chi)
    assert np.array_equal(a.visible, b.visible) and a.footprint_m2 == b.footprint_m2


def test_min_density_zero_makes_covered_equal_visible(boxed):
    grid, caster = boxed
    model = replace(PAPER_CAMERA, min_density_per_m2=0.0)
    for pose in _random_poses(grid, 3, 3):
        cov = TargetedEvaluator(grid, caster).evaluate(model, pose, visibility=True)
        assert np.array_equal(np.sort(cov.covered), np.sort(cov.visible))


def test_targeted_casts_no_ray_for_points_it_does_not_need(boxed):
    """Rays go only to target points in range, FoV and over the threshold."""
    grid, caster = boxed
    # Pitch 35: the footprint ends where the density falls below the threshold.
    pose = place(grid, 0.0, 0.0, 7.0, 35.0, 60.0)
    cov = TargetedEvaluator(grid, caster).evaluate(PAPER_CAMERA, pose)
    loose = TargetedEvaluator(grid, caster).evaluate(
        replace(PAPER_CAMERA, min_density_per_m2=0.0), pose
    )
    assert len(cov.covered) <= cov.rays < loose.rays
