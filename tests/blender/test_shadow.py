"""flat_wall: the ground the wall hides matches the analytic shadow within 1 %."""

import math
from dataclasses import replace

import bpy
import numpy as np
import pytest
import shapely

from autoscoop_blender.core.coverage.base import place
from autoscoop_blender.core.coverage.pointcloud import PointcloudEvaluator
from autoscoop_blender.core.coverage.targeted import TargetedEvaluator
from autoscoop_blender.core.geom.grid import GroundGrid
from autoscoop_blender.core.model.sensors import PAPER_CAMERA
from autoscoop_blender.scene.bvh import BVHCaster
from autoscoop_blender.scene.extract import extract_scene
from tools.samples import FLAT_WALL_BOX

SENSOR = np.array([-8.0, 0.0, 7.0])  # inside SensorArea_1, 7 m over flat ground


def analytic_hidden_m2():
    """Shadow of the wall box from a point light at SENSOR on z = 0, without the
    wall's own base (where target points sit on the wall top, in plain view)."""
    x0, y0, z0, x1, y1, z1 = FLAT_WALL_BOX
    corners = np.array([[x, y, z] for x in (x0, x1) for y in (y0, y1) for z in (z0, z1)])
    scale = SENSOR[2] / (SENSOR[2] - corners[:, 2:3])
    hull = shapely.MultiPoint(SENSOR[:2] + (corners[:, :2] - SENSOR[:2]) * scale).convex_hull
    return hull.area - (x1 - x0) * (y1 - y0)


def _seen_m2(evaluator_factory, model, pitch, yaw, grid_m):
    """Footprint area with the wall and without it (the wall set to be ignored)."""
    out = []
    for ignore in (False, True):
        bpy.data.objects["Wall"]["autoscoop_ignore"] = ignore
        scene = extract_scene()
        caster = BVHCaster.from_scene(scene)
        grid = GroundGrid(scene, caster, grid_m, reach_m=model.range_m)
        pose = place(grid, SENSOR[0], SENSOR[1], SENSOR[2], pitch, yaw)
        cov = evaluator_factory(grid, caster).evaluate(model, pose, outside_band_m=math.inf)
        out.append(cov.footprint_m2)
    return out


def test_targeted_hides_the_analytic_shadow(open_sample):
    open_sample("flat_wall")
    model = replace(PAPER_CAMERA, min_density_per_m2=0.0)  # line of sight only
    with_wall, without = _seen_m2(TargetedEvaluator, model, 40.0, 0.0, 0.25)
    expected = analytic_hidden_m2()
    assert 150 < expected < 250
    assert without - with_wall == pytest.approx(expected, rel=0.01)


def test_pointcloud_hides_the_analytic_shadow(open_sample):
    """With enough rays: a narrow sensor aimed at the shadow, rays every 0.05 deg."""
    open_sample("flat_wall")
    model = replace(
        PAPER_CAMERA,
        h_fov_deg=50.0,
        v_fov_deg=20.0,
        rays_h=1000,
        rays_v=400,
        min_density_per_m2=0.0,
    )
    with_wall, without = _seen_m2(lambda g, c: PointcloudEvaluator(g, c), model, 16.0, 7.0, 0.5)
    assert without - with_wall == pytest.approx(analytic_hidden_m2(), rel=0.01)


def test_pointcloud_with_the_papers_own_pattern_misses_the_shadow_by_2_percent(open_sample):
    """Table I's 192 x 160 rays, aimed as the targeted test above: the alpha shape bridges
    part of the shadow's edge, so the README quotes 2 % here (measured +1.8 % on the
    0.25 m grid, +2.5 % on 0.5 m), against 1 % for the 400,000-ray sensor."""
    open_sample("flat_wall")
    model = replace(PAPER_CAMERA, min_density_per_m2=0.0)
    with_wall, without = _seen_m2(lambda g, c: PointcloudEvaluator(g, c), model, 40.0, 0.0, 0.25)
    hidden = without - with_wall
    assert hidden == pytest.approx(analytic_hidden_m2(), rel=0.02)
    assert hidden > analytic_hidden_m2()  # what it gets wrong: shadow edges bridged
