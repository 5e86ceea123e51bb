"""Failure regions on real Blender geometry: edges, overhangs, a sensor in a wall,
georeferenced coordinates, cropping."""

import math
from dataclasses import replace

import bpy
import numpy as np
import pytest
import shapely

from autoscoop_blender.core.coverage.base import place
from autoscoop_blender.core.coverage.targeted import TargetedEvaluator
from autoscoop_blender.core.evaluate import evaluate_layout
from autoscoop_blender.core.geom.grid import GroundGrid
from autoscoop_blender.core.model.sensors import PAPER_CAMERA
from autoscoop_blender.core.settings import CoverageSettings
from autoscoop_blender.io.sensor_file import parse_sensors
from autoscoop_blender.scene.bvh import BVHCaster
from autoscoop_blender.scene.extract import extract_scene
from tests.blender import builders as b


def _model():
    scene = extract_scene()
    return scene, BVHCaster.from_scene(scene)


def test_target_points_exactly_on_mesh_edges_do_not_fall_through():
    # A ground at z = 5 split into triangles whose edges pass through every lattice
    # centre (x + 0.5, y + 0.5), over a deeper floor at z = 0.
    n = 20
    verts = [(x - 0.5, y - 0.5, 5.0) for y in range(n + 1) for x in range(n + 1)]
    faces = []
    for y in range(n):
        for x in range(n):
            a = y * (n + 1) + x
            faces += [(a, a + 1, a + n + 2), (a, a + n + 2, a + n + 1)]
    b.mesh("Ground", verts, faces)
    b.plane("Deep", -50, -50, 50, 50, z=0.0)
    b.curve("Target", [b.rect(0, 0, n - 1, n - 1)])
    b.curve("SensorArea", [b.rect(-5, 0, -2, 3)])
    scene, caster = _model()
    grid = GroundGrid(scene, caster, 1.0)
    assert np.allclose(grid.target_z, 5.0)  # no centre slipped through a crack


def _bridge_scene(overhang):
    b.plane("Ground", -60, -60, 60, 60)
    b.curve("Target_Road", [b.rect(0, -3, 40, 3)])
    b.curve("SensorArea", [b.rect(18, -12, 22, -8)])
    deck = b.box("Bridge_Deck", (15.0, -11.0, 5.0), (25.0, 11.0, 5.5))
    if overhang:
        deck["autoscoop_overhang"] = True


@pytest.mark.parametrize("overhang", [False, True])
def test_target_under_a_bridge(overhang):
    """A tall mast beside the road looks steeply down at the road under a bridge."""
    _bridge_scene(overhang)
    scene, caster = _model()
    grid = GroundGrid(scene, caster, 1.0)
    under = (grid.target_xy[:, 0] > 15.0) & (grid.target_xy[:, 0] < 25.0)
    pose = place(grid, 20.0, -10.0, 30.0, 70.0, 90.0)
    cov = TargetedEvaluator(grid, caster).evaluate(PAPER_CAMERA, pose, visibility=True)
    seen_under = np.isin(np.flatnonzero(under), cov.visible)
    if overhang:
        # The points lie on the road under the deck, and the deck hides them.
        assert np.allclose(grid.target_z[under], 0.0)
        assert not seen_under.any()
        assert pose.z == pytest.approx(30.0)  # the mast stands on the ground, not the deck
    else:
        # Unmarked, the deck is the top surface: the points lie on it, in plain view.
        assert np.allclose(grid.target_z[under], 5.5)
        assert seen_under.all()


def test_a_sensor_inside_a_wall_is_a_warning_and_sees_nothing():
    b.flat_wall_scene()
    b.box("Thick_Wall", (-9.0, -3.0, 0.0), (-7.0, 3.0, 12.0))
    scene, caster = _model()
    specs = parse_sensors(
        {
            "model": "paper_camera",
            "sensors": [
                {"x": -8, "y": 0, "pitch_deg": 40, "yaw_deg": 0},
                {"x": -5, "y": 0, "pitch_deg": 40, "yaw_deg": 0},
            ],
        },
        "s.json",
    )
    # The drop at (-8, 0) lands on the wall top (12 m): 5 m below it is inside.
    specs[0] = replace(specs[0], height_m=-5.0)
    res = evaluate_layout(scene, caster, specs, CoverageSettings())
    assert any("sensor 1" in w and "inside an occluder" in w for w in res.warnings)
    assert not any("sensor 2" in w for w in res.warnings)
    assert res.sensors[0].covered_target_m2 == 0 and res.sensors[1].covered_target_m2 > 0


def test_georeferenced_scene_covers_exactly_like_the_local_one():
    covered = []
    for e, n in ((0.0, 0.0), (500_000.0, 6_400_000.0)):
        bpy.ops.wm.read_factory_settings(use_empty=True)
        b.plane("Ground", e - 60, n - 60, e + 60, n + 60)
        b.curve("Target_Area", [b.rect(e, n - 25, e + 50, n + 25)])
        b.curve("SensorArea_1", [b.rect(e - 12, n - 4, e - 4, n + 4)])
        b.box("Wall", (e + 10.0, n - 2.0, 0.0), (e + 10.3, n + 8.0, 3.0))
        scene, caster = _model()
        specs = parse_sensors(
            {
                "model": "paper_camera",
                "sensors": [{"x": e - 8, "y": n, "pitch_deg": 40, "yaw_deg": 10}],
            },
            "s.json",
        )
        res = evaluate_layout(scene, caster, specs, CoverageSettings(grid_m=0.5))
        # The target points this sensor covers, relative to the scene's corner (e, n).
        covered.append(res.points[res.n_covered > 0, :2] - (e, n))
        assert res.sensors[0].x == pytest.approx(e - 8)
    assert np.array_equal(covered[0], covered[1]) and len(covered[0]) > 1000


def _segment_distance(p, a, b):
    """Distances from points p (..., 2) to segments a-b (..., 2), broadcast."""
    ab = b - a
    t = np.clip(((p - a) * ab).sum(-1) / np.maximum((ab * ab).sum(-1), 1e-300), 0.0, 1.0)
    return np.linalg.norm(p - (a + t[..., None] * ab), axis=-1)


def _plan_distances(tri, rings):
    """(T,) distances between triangles (T, 3, 2) and polygons' closed rings [(K, 2)]
    that do not overlap them: the least vertex-to-edge distance either way."""
    best = np.full(len(tri), np.inf)
    edges_a, edges_b = tri, np.roll(tri, -1, axis=1)  # (T, 3, 2) each
    for ring in rings:
        for start, end in zip(ring[:-1], ring[1:], strict=True):
            best = np.minimum(best, _segment_distance(tri, start, end).min(axis=1))
        for v in ring[:-1]:
            best = np.minimum(best, _segment_distance(v, edges_a, edges_b).min(axis=1))
    return best


def test_cropping_leaves_out_only_what_no_sensor_can_reach(open_sample):
    open_sample("two_routes")
    scene = extract_scene()
    cropped = scene.cropped(PAPER_CAMERA.range_m)
    assert len(cropped.faces) < len(scene.faces)
    # Exactly the faces whose plan comes within the range of a sensor area (or lies
    # over a target) are kept. The plan distance between a triangle and a polygon,
    # worked out here from vertices and segments (disjoint polygons are nearest at a
    # vertex of one and an edge of the other), not by the cropping's own GEOS call.
    r = PAPER_CAMERA.range_m
    kept = {tuple(f) for f in cropped.faces.tolist()}
    tri = scene.vertices[scene.faces][:, :, :2]
    areas = [np.asarray(a.geometry.exterior.coords)[:, :2] for a in scene.sensor_areas]
    inside = shapely.intersects(
        shapely.union_all([a.geometry for a in (*scene.sensor_areas, *scene.targets)]),
        shapely.polygons(np.concatenate([tri, tri[:, :1]], axis=1)),
    )
    dist = _plan_distances(tri, areas)
    is_kept = np.array([tuple(f) in kept for f in scene.faces.tolist()])
    assert np.array_equal(is_kept, (dist <= r) | inside)
    # Faces just beyond and just within the range exist, so the test tells them apart.
    dist = dist[~inside]
    assert ((dist > r) & (dist < r + 1.0)).any() and ((dist <= r) & (dist > r - 1.0)).any()
    # And coverage does not change.
    caster_full, caster_crop = BVHCaster.from_scene(scene), BVHCaster.from_scene(cropped)
    grid_full = GroundGrid(scene, caster_full, 1.0, reach_m=80.0)
    grid_crop = GroundGrid(cropped, caster_crop, 1.0, reach_m=80.0)
    rng = np.random.default_rng(0)
    for _ in range(4):
        area = scene.sensor_areas[int(rng.integers(len(scene.sensor_areas)))]
        p = area.geometry.representative_point()
        yaw = float(rng.uniform(0, 360))
        a = TargetedEvaluator(grid_full, caster_full).evaluate(
            PAPER_CAMERA, place(grid_full, p.x, p.y, 7.0, 35.0, yaw), outside_band_m=math.inf
        )
        c = TargetedEvaluator(grid_crop, caster_crop).evaluate(
            PAPER_CAMERA, place(grid_crop, p.x, p.y, 7.0, 35.0, yaw), outside_band_m=math.inf
        )
        # The same, but for the odd sight line that grazes a terrain edge: BVHTree
        # decides those in single precision, and a tree built from other triangles
        # may decide one the other way (a cell or two in a thousand).
        assert len(np.setxor1d(a.covered, c.covered)) <= 0.003 * len(a.covered)
        assert abs(a.footprint_m2 - c.footprint_m2) <= 0.003 * a.footprint_m2
