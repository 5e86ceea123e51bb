"""Each method driven into its failure region: a correct answer, or a clear error or
warning, never a crash or a silently wrong number (core, analytic scenes)."""

import math
from dataclasses import replace

import numpy as np
import pytest
import shapely

from autoscoop_blender.core.coverage.base import place
from autoscoop_blender.core.coverage.pointcloud import PointcloudEvaluator, auto_oversample
from autoscoop_blender.core.coverage.targeted import TargetedEvaluator
from autoscoop_blender.core.errors import InputError
from autoscoop_blender.core.geom.alpha import alpha_mask, alpha_shape, triangulate
from autoscoop_blender.core.geom.raycast import BoxCaster, inside_solid
from autoscoop_blender.core.model.scene import Area
from autoscoop_blender.core.model.sensors import PAPER_CAMERA, ROADSIDE_LIDAR, SensorPose
from autoscoop_blender.core.run import Run
from autoscoop_blender.core.settings import ESParams, OptimizeSettings
from tests.core.flat import box_caster, flat_grid, open_scene

# --- alpha shape ---------------------------------------------------------------------


@pytest.mark.parametrize("n", [0, 1, 2])
def test_alpha_shape_of_too_few_points_is_empty(n):
    shape = alpha_shape(np.zeros((n, 2)) + np.arange(n)[:, None], 5.0)
    assert shape.is_empty and shape.area == 0.0


def test_alpha_shape_of_collinear_points_is_empty():
    pts = np.column_stack([np.linspace(0, 10, 50), np.linspace(0, 5, 50)])
    assert alpha_shape(pts, 100.0).area == 0.0


def _lattice(x0, y0, x1, y1, step=1.0):
    xs, ys = np.meshgrid(np.arange(x0, x1 + 1e-9, step), np.arange(y0, y1 + 1e-9, step))
    return np.column_stack([xs.ravel(), ys.ravel()])


def test_two_clusters_stay_two_parts():
    pts = np.vstack([_lattice(0, 0, 10, 10), _lattice(30, 0, 40, 10)])
    shape = alpha_shape(pts, 1.0)
    assert len(shape.geoms) == 2
    assert shape.area == pytest.approx(200.0)


def test_a_hole_wider_than_alpha_stays_a_hole_narrower_is_bridged():
    pts = _lattice(0, 0, 30, 30)
    hole = (np.abs(pts[:, 0] - 15) < 5) & (np.abs(pts[:, 1] - 15) < 5)  # 9 x 9 m gap
    pts = pts[~hole]
    kept = alpha_shape(pts, 1.0)
    assert not kept.contains(shapely.Point(15, 15))
    # The hole's edge runs through the lattice points around the gap, a 10 m square
    # whose corners are cut by the cells' diagonals: 100 - 4 x 0.5 m^2.
    assert kept.area == pytest.approx(900.0 - 98.0)
    bridged = alpha_shape(pts, 10.0)  # alpha radius larger than the gap
    assert bridged.contains(shapely.Point(15, 15)) and bridged.area == pytest.approx(900.0)


def test_alpha_too_small_keeps_nothing_too_large_gives_the_hull():
    rng = np.random.default_rng(0)
    pts = rng.uniform(0, 20, (400, 2))
    tri = triangulate(pts)
    assert not alpha_mask(tri, 1e-3).any()
    hull = shapely.MultiPoint(pts).convex_hull.area
    assert alpha_shape(pts, 1e6).area == pytest.approx(hull)


def test_pointcloud_alpha_extremes_are_defined():
    box = ((10.0, -2.0, 0.0), (12.0, 6.0, 3.0))
    grid, caster = flat_grid(spacing=0.5, boxes=[box], target=(0, -30, 50, 30))
    pose = place(grid, -6.0, 0.0, 7.0, 40.0, 0.0)
    model = replace(PAPER_CAMERA, min_density_per_m2=0.0)
    normal = PointcloudEvaluator(grid, caster).evaluate(model, pose, outside_band_m=math.inf)
    tiny = PointcloudEvaluator(grid, caster, alpha=1e-3).evaluate(
        model, pose, outside_band_m=math.inf
    )
    huge = PointcloudEvaluator(grid, caster, alpha_m=1e4).evaluate(
        model, pose, outside_band_m=math.inf
    )
    assert tiny.footprint_m2 == 0.0 and len(tiny.covered) == 0
    # A huge alpha bridges the box's shadow: more is "covered" than is visible.
    assert huge.footprint_m2 > normal.footprint_m2
    shadow_pt = grid.target_ordinal(grid.cells_in_disk(np.array([16.0, 2.0]), 0.3))
    assert set(shadow_pt[shadow_pt >= 0]) <= set(huge.covered)
    assert not set(shadow_pt[shadow_pt >= 0]) & set(normal.covered)


# --- ray casting and density ------------------------------------------------------


def test_grazing_sight_lines_are_not_blocked_by_their_own_ground():
    grid, caster = flat_grid(spacing=1.0, target=(0, -5, 200, 5), sensor=(-2, -1, 0, 1))
    model = replace(ROADSIDE_LIDAR, range_m=200.0, min_density_per_m2=0.0)
    pose = place(grid, -1.0, 0.0, 0.3, 0.0, 0.0)  # 30 cm over the ground, level
    cov = TargetedEvaluator(grid, caster).evaluate(model, pose, visibility=True)
    # Every target point within the 200 m range is visible, out to the last cell
    # centre in reach, x = 198.5 (199.5 m from the sensor; 200.5 is beyond), where the
    # sight line meets the ground at atan(0.3 / 199.5) = 0.09 deg.
    xy = grid.target_xy
    in_range = np.sqrt((xy[:, 0] + 1.0) ** 2 + xy[:, 1] ** 2 + 0.3**2) <= 200.0
    assert np.array_equal(np.sort(cov.visible), np.flatnonzero(in_range))
    assert grid.target_xy[cov.visible][:, 0].max() == 198.5
    assert len(cov.visible) == len(cov.covered)


def test_rays_that_start_on_the_ground():
    grid, caster = flat_grid(spacing=1.0, target=(0, -10, 40, 10), sensor=(-2, -1, 0, 1))
    model = replace(PAPER_CAMERA, min_density_per_m2=0.0, pitch_min_deg=-90.0)
    pose = place(grid, -1.0, 0.0, 0.0, 0.0, 0.0)  # mast height 0, level: on the surface
    cov = TargetedEvaluator(grid, caster).evaluate(model, pose, visibility=True)
    # Every point inside the +-40 deg FoV is visible; its own ground blocks nothing.
    xy = grid.target_xy
    in_fov = np.degrees(np.abs(np.arctan2(xy[:, 1], xy[:, 0] + 1.0))) <= 40.0
    assert np.array_equal(np.sort(cov.visible), np.flatnonzero(in_fov))


def test_a_sensor_inside_a_wall_sees_nothing_and_is_detected():
    wall = ((-1.0, -5.0, 0.0), (1.0, 5.0, 10.0))
    grid, caster = flat_grid(
        spacing=1.0, boxes=[wall], target=(5, -10, 40, 10), sensor=(-2, -2, 2, 2)
    )
    inside = place(grid, 0.0, 0.0, 1.0, 40.0, 0.0)  # the drop lands on the wall top ...
    inside = SensorPose(0.0, 0.0, 5.0, 5.0, 40.0, 0.0)  # ... so stand in it by hand
    cov = TargetedEvaluator(grid, caster).evaluate(PAPER_CAMERA, inside, visibility=True)
    assert len(cov.visible) == 0 and len(cov.covered) == 0
    assert inside_solid(caster, np.array([[0.0, 0.0, 5.0], [3.0, 0.0, 5.0]])).tolist() == [
        True,
        False,
    ]


def test_density_at_the_edges_of_range_and_fov():
    grid, caster = flat_grid(spacing=1.0, target=(-100, -100, 100, 100))
    model = replace(PAPER_CAMERA, min_density_per_m2=0.0, pitch_min_deg=0.0)
    ev = TargetedEvaluator(grid, caster)
    pose = SensorPose(0.0, 0.0, 7.0, 7.0, 0.0, 0.0)  # level: FoV azimuth = map azimuth
    cov = ev.evaluate(model, pose, visibility=True)
    xy = grid.target_xy[cov.covered]
    r3 = np.hypot(np.hypot(xy[:, 0], xy[:, 1]), 7.0)
    assert r3.max() <= 80.0 + 1e-9 and r3.max() > 79.0  # out to the range, not beyond
    az = np.degrees(np.abs(np.arctan2(xy[:, 1], xy[:, 0])))
    assert az.max() <= 40.0 + 1e-6 and az.max() > 39.0  # out to the FoV edge, not beyond
    assert np.isfinite(cov.chi).all() and (cov.chi > 0).all()
    # With the paper's threshold the far, grazing points drop out: finite, positive chi.
    strict = ev.evaluate(PAPER_CAMERA, replace(pose, pitch_deg=35.0))
    assert (strict.chi >= PAPER_CAMERA.min_density_per_m2).all()


def test_near_zero_incidence_gives_vanishing_density_not_nan():
    from autoscoop_blender.core.model.sensors import surface_factor

    d = np.array([[1.0, 0.0, -1e-9], [0.0, 0.0, -1.0]])
    normals = np.array([[0.0, 0.0, 1.0], [1.0, 0.0, 0.0]])  # ground; a vertical face
    f = surface_factor(d, np.array([50.0, 50.0]), normals)
    assert np.isfinite(f).all() and f[0] < 1e-12 and f[1] == 0.0


def test_auto_oversample_follows_spacing_range_and_grid():
    assert auto_oversample(PAPER_CAMERA, 1.0) == 1  # 0.5 deg x 80 m = 0.70 m
    assert auto_oversample(PAPER_CAMERA, 0.25) == 3
    coarse = replace(PAPER_CAMERA, rays_h=40, rays_v=40)  # 2 deg
    assert auto_oversample(coarse, 1.0) == 3  # 2 deg x 80 m = 2.8 m


# --- optimizer ----------------------------------------------------------------------

FAST = OptimizeSettings(optimizer="es", rho=0.9, es=ESParams(mu=6, lam=3, max_epochs=3))


def test_a_sensor_area_too_small_to_move_in():
    scene = open_scene(shapely.box(0, -5, 40, 5), [shapely.box(-3.2, 6.1, -3.0, 6.3)])
    run = Run(scene, box_caster(), PAPER_CAMERA, replace(FAST, rho=0.5))
    positions = run.problem.space.positions
    assert len(positions) == 1
    # The one position is the area's inner point.
    assert shapely.box(-3.2, 6.1, -3.0, 6.3).contains(shapely.Point(positions[0]))
    res = run.result()
    assert res.metrics["coverage_fraction"] >= 0.5
    assert {(s.x, s.y) for s in res.sensors} == {tuple(positions[0])}
    assert res.metrics["masts"] == 1


def test_a_target_that_needs_hundreds_of_sensors():
    road = shapely.box(0, -2, 3000, 2)  # 3 km of a narrow road
    verge = shapely.box(0, 3, 3000, 4)
    # A short-sighted camera: about 20 m of road per sensor.
    model = replace(PAPER_CAMERA, range_m=15.0, mount_height_m=3.0, min_density_per_m2=0.0)
    settings = replace(FAST, rho=0.97, grid_m=1.0, es=ESParams(mu=6, lam=3, max_epochs=3))
    res = Run(open_scene(road, [verge]), box_caster(), model, settings).result()
    assert res.metrics["coverage_fraction"] >= 0.97
    # Below: no sensor sees more than a disk of its horizontal reach, sqrt(15^2 - 3^2)
    # = 14.7 m, so at most 29.4 m of the 4 m road: 97 % of 3000 m needs >= 100 of them.
    # Above: this seed's run fixed 448 (2026-11-23; the short ES of FAST); a change that
    # needs a tenth more is a regression to look at, not noise (same seed, same answer).
    assert math.ceil(0.97 * 3000 / (2 * math.sqrt(15**2 - 3**2))) == 100
    assert 100 <= res.metrics["sensors"] <= 1.1 * 448
    assert "max_sensors" not in res.stop_reason


def test_contradictory_pitch_limits_are_an_error():
    with pytest.raises(InputError, match="pitch limits contradict"):
        replace(PAPER_CAMERA, pitch_min_deg=50.0, pitch_max_deg=40.0).validated("model")


def test_one_seed_against_another():
    scene = open_scene(shapely.box(0, -7, 100, 7), [shapely.box(0, 10, 100, 14)])
    results = [
        Run(scene, box_caster(), PAPER_CAMERA, replace(FAST, seed=s)).result() for s in (0, 1, 2)
    ]
    poses = [tuple((p.x, p.y) for p in r.sensors) for r in results]
    assert len(set(poses)) == 3  # different seeds search differently ...
    for r in results:  # ... and each reaches the goal
        assert r.metrics["coverage_fraction"] >= 0.9


# --- numbers ------------------------------------------------------------------------


def test_huge_coordinates_give_the_same_coverage():
    base = shapely.box(0, -25, 50, 25)
    area = shapely.box(-12, -4, -4, 4)
    results = []
    for shift in (0.0, 500_000.0):
        scene = open_scene(
            shapely.affinity.translate(base, shift, shift),
            [shapely.affinity.translate(area, shift, shift)],
        )
        from autoscoop_blender.core.model.scene import choose_origin

        origin = choose_origin(np.array([[shift - 12, shift - 25, 0], [shift + 50, shift + 25, 0]]))
        scene = replace(
            scene,
            origin=origin,
            targets=(
                Area(
                    "Target", shapely.affinity.translate(base, shift - origin[0], shift - origin[1])
                ),
            ),
            sensor_areas=(
                Area(
                    "SensorArea",
                    shapely.affinity.translate(area, shift - origin[0], shift - origin[1]),
                ),
            ),
        )
        res = Run(scene, box_caster(), PAPER_CAMERA, FAST).result()
        results.append(res)
    a, b = results
    assert a.metrics["coverage_fraction"] == b.metrics["coverage_fraction"]
    assert [(s.x + 500_000.0, s.y + 500_000.0) for s in a.sensors] == [
        (s.x, s.y) for s in b.sensors
    ]


def test_a_target_smaller_than_one_grid_cell_is_a_clear_error():
    from autoscoop_blender.core.errors import SceneContractError
    from autoscoop_blender.core.geom.grid import GroundGrid

    scene = open_scene(shapely.box(0.1, 0.1, 0.4, 0.4), [shapely.box(-5, 0, -1, 4)])
    with pytest.raises(SceneContractError, match="holds no point of the 1 m grid"):
        GroundGrid(scene, BoxCaster(ground_z=0.0), 1.0)
    fine = GroundGrid(scene, BoxCaster(ground_z=0.0), 0.1)
    assert fine.n_targets == 9 and fine.target_area_m2 == pytest.approx(0.09)
