"""Masts stand on the ground: not on walls, guard walls or tree crowns; on mounts when
marked; under overhangs. Every figure is worked out from the boxes' corners."""

import math

import bpy
import numpy as np
import pytest
import shapely

from autoscoop_blender import names
from autoscoop_blender.core.evaluate import evaluate_layout
from autoscoop_blender.core.model.sensors import PAPER_CAMERA, SensorSpec
from autoscoop_blender.core.model.sites import FOOT_M
from autoscoop_blender.core.problem import Problem
from autoscoop_blender.core.settings import CoverageSettings, OptimizeSettings
from autoscoop_blender.scene.extract import extract_scene
from autoscoop_blender.scene.factory import BVHFactory
from tests.blender import builders as b

# Every box edge lies on a half metre, so that no lattice point (whole metres) sits on
# an edge, where a downward ray could land on either side.
WALL = ((-15.5, -2.5, 0.0), (-14.5, 1.5, 3.0))  # 1 m x 4 m, 3 m high
GUARD_WALL = ((-9.5, -8.5, -0.2), (-5.5, -8.3, 0.3))  # 4 m x 0.2 m, sunk, 0.3 m up
CROWN = ((-8.5, -3.5, 3.0), (-6.5, -1.5, 8.0))  # a tree crown, 2 m x 2 m, no trunk
KERB = ((-9.5, 3.5, -0.1), (-5.5, 6.5, 0.15))  # 0.15 m up: a mast base spans it
ROAD = (-19.5, -9.5, -16.5, 9.5, 0.02)  # a road surface laid on the terrain
BUILDING = ((-14.5, -9.5, 0.0), (-10.5, -5.5, 6.0))  # marked as a mount: 6 m roof
CANOPY = ((-13.5, 3.5, 4.0), (-10.5, 7.5, 5.0))  # marked as an overhang


def _buffered_m2(lo, hi):
    """Area of a box's plan widened by FOOT_M: a b + 2 r (a + b) + pi r^2."""
    a, c = hi[0] - lo[0], hi[1] - lo[1]
    return a * c + 2 * FOOT_M * (a + c) + math.pi * FOOT_M**2


def site_scene():
    """A 16 m x 20 m sensor area west of the target, with one of each kind of object."""
    b.plane("Ground", -60, -60, 60, 60)
    b.curve("Target", [b.rect(0, -25, 50, 25)])
    b.curve("SensorArea_West", [b.rect(-20, -10, -4, 10)])
    for name, (lo, hi) in {
        "Wall": WALL,
        "GuardWall": GUARD_WALL,
        "Crown": CROWN,
        "Kerb": KERB,
        "Building": BUILDING,
        "Canopy": CANOPY,
    }.items():
        b.box(name, lo, hi)
    b.plane("RoadSurface", *ROAD)
    bpy.data.objects["Building"][names.MOUNT_PROP] = True
    bpy.data.objects["Canopy"][names.OVERHANG_PROP] = True


def _ground_by_hand(x, y):
    """Height a mast at (x, y) stands on, from the boxes above."""

    def inside(lo, hi):
        return lo[0] < x < hi[0] and lo[1] < y < hi[1]

    if inside(*BUILDING):
        return BUILDING[1][2]
    if inside(*KERB):
        return KERB[1][2]
    if ROAD[0] < x < ROAD[2] and ROAD[1] < y < ROAD[3]:
        return ROAD[4]
    return 0.0


def test_what_stands_on_the_ground_is_cut_out_and_reported():
    site_scene()
    scene = extract_scene()
    got = {e.cause: e.m2 for e in scene.excluded}
    assert {e.area for e in scene.excluded} == {"SensorArea_West"}
    # The wall, the sunk 0.3 m guard wall and the crown; not the 0.15 m kerb, the road
    # surface, the terrain, the mount or the overhang. shapely's round corners are
    # polygons: within 0.002 m^2 of the circle.
    assert got == {
        "Wall": pytest.approx(_buffered_m2(*WALL), abs=2e-3),
        "GuardWall": pytest.approx(_buffered_m2(*GUARD_WALL), abs=2e-3),
        "Crown": pytest.approx(_buffered_m2(*CROWN), abs=2e-3),
    }
    (west,) = scene.sensor_areas
    assert west.geometry.area == pytest.approx(320.0 - sum(got.values()), abs=1e-6)


@pytest.mark.parametrize("step_m", [1.0, 2.0])
def test_every_mast_position_stands_on_the_ground_or_a_mount(step_m):
    site_scene()
    scene = extract_scene()
    settings = OptimizeSettings(optimizer="greedy", position_step_m=step_m)
    problem = Problem(scene, BVHFactory.of(scene)(), PAPER_CAMERA, settings)
    xy = problem.space.positions + scene.origin[:2]
    assert len(xy) > 0.9 * 300 / step_m**2
    # None within FOOT_M of what stands on the ground ...
    for lo, hi in (WALL, GUARD_WALL, CROWN):
        box = shapely.box(lo[0], lo[1], hi[0], hi[1])
        assert shapely.distance(box, shapely.points(xy)).min() >= FOOT_M - 1e-9
    # ... and each one on the surface worked out by hand: the terrain, the kerb, the
    # road surface, the roof of the mount; under the overhang, on the terrain.
    heights = []
    for x, y in problem.space.positions:
        pose = problem.pose(float(x), float(y), 45.0, 0.0)
        heights.append(pose.z + scene.origin[2] - pose.height_m)
    expected = [_ground_by_hand(x, y) for x, y in xy]
    np.testing.assert_allclose(heights, expected, atol=1e-4)
    # Each kind of site is there to be checked.
    assert {round(h, 2) for h in expected} == {0.0, 0.02, 0.15, 6.0}
    under = shapely.contains_xy(shapely.box(-13.5, 3.5, -10.5, 7.5), xy[:, 0], xy[:, 1])
    assert under.sum() >= 12 / step_m**2 / 2


def test_a_sensor_placed_by_hand_on_a_wall_is_named():
    site_scene()
    scene = extract_scene()
    specs = [
        SensorSpec(x=-15.0, y=0.0, height_m=7.0, pitch_deg=45, yaw_deg=0, model=PAPER_CAMERA),
        SensorSpec(x=-12.5, y=-7.5, height_m=7.0, pitch_deg=45, yaw_deg=0, model=PAPER_CAMERA),
        SensorSpec(x=-18.0, y=0.0, height_m=7.0, pitch_deg=45, yaw_deg=0, model=PAPER_CAMERA),
    ]
    result = evaluate_layout(scene, BVHFactory.of(scene)(), specs, CoverageSettings(grid_m=2.0))
    on_wall = [w for w in result.warnings if "no mast may" in w]
    assert len(on_wall) == 1 and on_wall[0].startswith("sensor 1 at (-15, 0)")
    assert "beside Wall " in on_wall[0]
    # The one on the mount stands on its roof: 6 m + 7 m.
    assert result.sensors[1].z == pytest.approx(13.0, abs=1e-4)
    assert [e["cause"] for e in _doc(result)] == ["Wall", "GuardWall", "Crown"]


def _doc(result):
    from autoscoop_blender.io.reports import coverage_dict

    return coverage_dict(result)["no_mast_sites"]
