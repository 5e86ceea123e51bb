"""Coverage invariants and the analytic shadow of a box, without Blender."""

import math
from dataclasses import replace

import numpy as np
import pytest
import shapely

from autoscoop_blender.core.coverage.base import footprint_polygon, place, summarize
from autoscoop_blender.core.coverage.cached import CachedTargetedEvaluator
from autoscoop_blender.core.coverage.pointcloud import PointcloudEvaluator
from autoscoop_blender.core.coverage.targeted import TargetedEvaluator
from autoscoop_blender.core.geom.grid import GroundGrid
from autoscoop_blender.core.model.sensors import PAPER_CAMERA, ROADSIDE_LIDAR
from tests.core.flat import down_camera, flat_grid, flat_scene

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


# --- a camera straight down over flat ground: every answer by hand ------------------
#
# ``down_camera``: a pinhole 60 x 60 deg looking straight down (pitch 90, its only
# allowed pitch, so the cached evaluator takes its cached path). It stands at (0.5, 0.5)
# on a 1 m grid, whose cell centres lie at k + 0.5: every cell is at a whole offset
# (a, b) from the mast. From h = 10 m it sees the square |a|, |b| <= h tan 30 deg =
# 5.77 m: a, b in -5..5, 121 cells. Its pattern of N rays lands N / (4 tan^2 30 deg)
# rays per steradian at cos^-3 t off the axis, and a steradian at angle t covers
# r^2 / cos t = h^2 / cos^3 t m^2 of ground: N / (4 tan^2 30 deg h^2) points per m^2
# everywhere in the square, 230.4 for the paper camera's 30,720 rays.

EVALUATORS = [TargetedEvaluator, CachedTargetedEvaluator]
DOWN_H = 10.0
HALF_SIDE = DOWN_H * math.tan(math.radians(30.0))  # 5.77 m
DOWN_CHI = 192 * 160 / (4 * math.tan(math.radians(30.0)) ** 2 * DOWN_H**2)  # 230.4


def offsets(grid, ordinals):
    """The whole offsets (a, b) from the mast at (0.5, 0.5) of target ordinals."""
    xy = grid.target_xy[ordinals] - 0.5
    assert np.allclose(xy, np.round(xy))
    return sorted(map(tuple, np.round(xy).astype(int).tolist()))


def lattice(keep, n=25):
    """The whole offsets (a, b), |a|, |b| <= n, for which ``keep(a, b)`` holds."""
    return sorted((a, b) for a in range(-n, n + 1) for b in range(-n, n + 1) if keep(a, b))


def in_square(a, b, half=HALF_SIDE):
    return abs(a) <= half and abs(b) <= half


@pytest.mark.parametrize("evaluator", EVALUATORS)
def test_straight_down_footprint_is_the_square_under_the_camera(evaluator):
    """The target holds the square's half a >= 0 (66 cells); the other 55 cells of
    the footprint lie outside it, at 1..5 m from the nearest target cell."""
    model = down_camera(20.0)
    grid, caster = flat_grid(spacing=1.0, target=(0, -20, 21, 21), reach=25.0)
    ev = evaluator(grid, caster)
    pose = place(grid, 0.5, 0.5, DOWN_H, 90.0, 0.0)
    cov = ev.evaluate(model, pose)
    assert offsets(grid, cov.covered) == lattice(lambda a, b: a >= 0 and in_square(a, b))
    assert cov.chi == pytest.approx(np.full(66, DOWN_CHI), rel=1e-9)
    assert cov.rays == 66  # one sight ray per point over the threshold
    assert cov.pose == pose and cov.model == model and cov.method == "targeted"
    # Not asked for: no visible set, no whole footprint, no outside cell.
    assert cov.visible is None and cov.footprint_m2 is None and len(cov.outside) == 0
    assert footprint_polygon(grid, cov).area == pytest.approx(66.0)
    # Outside cells within 2 m of the target: the columns a = -1, -2.
    band = ev.evaluate(model, pose, outside_band_m=2.0)
    assert np.array_equal(np.sort(band.covered), np.sort(cov.covered))
    assert len(band.outside) == 22 and band.footprint_m2 is None
    assert np.array_equal(np.sort(grid.xy(band.outside)[:, 0] - 0.5), np.repeat([-2, -1], 11))
    # All of it: the whole square, 121 m^2.
    full = ev.evaluate(model, pose, outside_band_m=math.inf)
    assert full.footprint_m2 == pytest.approx(121.0) and len(full.outside) == 55
    assert footprint_polygon(grid, full).area == pytest.approx(121.0)


WALL = ((2.8, -30.0, 0.0), (3.2, 30.0, 5.0))  # 5 m high, across the view at a = 2.3..2.7


def shadowed(a, b):
    """Similar triangles: the sight line from 10 m to a point a m away is at height
    10 (1 - u / a) at u m; it clears the wall's far edge (u = 2.7) above 5 m for
    a > 2.7 10 / (10 - 5) = 5.4, so the wall hides a in [2.7, 5.4]: a = 3, 4, 5."""
    return 2.7 <= a <= 2.7 * DOWN_H / (DOWN_H - 5.0)


@pytest.mark.parametrize("evaluator", EVALUATORS)
def test_a_wall_hides_the_similar_triangles_shadow(evaluator):
    grid, caster = flat_grid(spacing=1.0, boxes=[WALL], target=(-20, -20, 21, 21), reach=25.0)
    ev = evaluator(grid, caster)
    pose = place(grid, 0.5, 0.5, DOWN_H, 90.0, 0.0)
    lit = lattice(lambda a, b: in_square(a, b) and not shadowed(a, b))
    assert len(lit) == 121 - 33
    cov = ev.evaluate(down_camera(20.0), pose)
    assert offsets(grid, cov.covered) == lit
    assert cov.rays == 121  # the shadowed points were asked too
    # A threshold just over the square's 230.4 points/m^2: nothing is covered, but
    # every point in view and in line of sight is visible, one ray per point in view.
    strict = replace(down_camera(20.0), min_density_per_m2=DOWN_CHI * 1.001)
    vis = ev.evaluate(strict, pose, visibility=True)
    assert len(vis.covered) == 0 and offsets(grid, vis.visible) == lit
    assert vis.rays == 121


@pytest.mark.parametrize("evaluator", EVALUATORS)
def test_a_point_at_exactly_the_range_is_covered(evaluator):
    """3 m up with a range of 5 m, a 120 deg camera straight down reaches the ground
    out to 4 m (3-4-5): the points 4 m away lie at exactly 5 m and count."""
    model = replace(down_camera(5.0), h_fov_deg=120.0, v_fov_deg=120.0, mount_height_m=3.0)
    grid, caster = flat_grid(spacing=1.0, target=(-20, -20, 21, 21), reach=25.0)
    cov = evaluator(grid, caster).evaluate(model, place(grid, 0.5, 0.5, 3.0, 90.0, 0.0))
    got = offsets(grid, cov.covered)
    assert got == lattice(lambda a, b: a * a + b * b <= 16)
    assert len(got) == 49 and (4, 0) in got and (0, -4) in got


@pytest.mark.parametrize("evaluator", EVALUATORS)
def test_a_point_on_the_fovs_corner_ray_is_covered(evaluator):
    """A 2 atan(1/2) = 53.13 deg square pinhole straight down from 10 m sees
    |a|, |b| <= 5: the four points (+-5, +-5) lie exactly on its corner rays, and
    count (in up to and including the edge). The cached evaluator's reach once lost
    them: its depression band had no tolerance, and arcsin put them an ulp outside."""
    fov = math.degrees(2 * math.atan(0.5))
    model = replace(down_camera(50.0), h_fov_deg=fov, v_fov_deg=fov)
    grid, caster = flat_grid(spacing=1.0, target=(-20, -20, 21, 21), reach=25.0)
    ev = evaluator(grid, caster)
    for h, side in ((10.0, 5), (12.0, 6)):
        cov = ev.evaluate(model, place(grid, 0.5, 0.5, h, 90.0, 0.0))
        got = offsets(grid, cov.covered)
        assert got == lattice(lambda a, b, n=side: abs(a) <= n and abs(b) <= n)
        assert (side, side) in got and (-side, side) in got


@pytest.mark.parametrize("evaluator", EVALUATORS)
def test_a_camera_half_a_metre_up_covers_what_is_under_it(evaluator):
    """0.5 m up it sees |a|, |b| <= 0.5 tan 30 deg = 0.29 m: on a 0.25 m grid the
    3 x 3 cells around the mast (at (0.125, 0.125), a cell centre), all nearer than
    1 m."""
    grid, caster = flat_grid(spacing=0.25, target=(-2, -2, 2, 2), reach=5.0)
    ev = evaluator(grid, caster)
    cov = ev.evaluate(down_camera(5.0), place(grid, 0.125, 0.125, 0.5, 90.0, 0.0))
    d = grid.target_xy[cov.covered] - 0.125
    assert sorted(map(tuple, np.round(d / 0.25).astype(int).tolist())) == lattice(
        lambda a, b: abs(a) <= 1 and abs(b) <= 1
    )


@pytest.mark.parametrize("evaluator", EVALUATORS)
def test_a_lidar_on_the_ground_without_threshold_covers_the_disk(evaluator):
    """A level 360 deg lidar at height 0 with no density threshold: every ground point
    within its 6 m lies at elevation 0, in its FoV and (its own ground never blocks
    it) in sight; its density there is 0, which the threshold 0 accepts. The disk
    a^2 + b^2 <= 36 without the mast's own cell (distance 0): 113 - 1 points."""
    model = replace(ROADSIDE_LIDAR, min_density_per_m2=0.0, range_m=6.0)
    grid, caster = flat_grid(spacing=1.0, target=(-20, -20, 21, 21), reach=25.0)
    cov = evaluator(grid, caster).evaluate(model, place(grid, 0.5, 0.5, 0.0, 0.0, 0.0))
    assert offsets(grid, cov.covered) == lattice(lambda a, b: 0 < a * a + b * b <= 36)
    assert len(cov.covered) == 112 and np.all(cov.chi == 0.0)


@pytest.mark.parametrize("evaluator", EVALUATORS)
def test_straight_down_pixel_density_is_f_over_h(evaluator):
    """Straight down every ground point is at depth h along the axis, so its pixel
    density is sqrt(f^2 h / h^3) = f / h (``sensors`` docstring): with 1000 x 1000 px
    on 60 deg, f = 500 / tan 30 deg = 866.0 px and f / h = 86.6 px/m from 10 m. A
    level under that covers the whole square, one over it nothing."""
    f = 500.0 / math.tan(math.radians(30.0))
    grid, caster = flat_grid(spacing=1.0, target=(-20, -20, 21, 21), reach=25.0)
    ev = evaluator(grid, caster)
    pose = place(grid, 0.5, 0.5, DOWN_H, 90.0, 0.0)
    for level, square in ((0.99 * f / DOWN_H, lattice(in_square)), (1.01 * f / DOWN_H, [])):
        model = replace(down_camera(20.0), resolution_px=(1000, 1000), min_px_per_m=level)
        cov = ev.evaluate(model.validated("test"), pose)
        assert offsets(grid, cov.covered) == square
