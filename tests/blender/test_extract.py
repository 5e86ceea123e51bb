"""Scene extraction: the contract, what occludes, and one-line errors naming objects."""

import math

import bpy
import numpy as np
import pytest

from autoscoop_blender import names
from autoscoop_blender.core.errors import SceneContractError
from autoscoop_blender.scene.extract import extract_scene
from tests.blender import builders as b


def test_flat_wall_sample(open_sample):
    open_sample("flat_wall")
    scene = extract_scene()
    assert set(scene.occluders) == {"Ground", "Wall"}
    assert len(scene.faces) == 2 + 12  # a quad and a box, triangulated
    (target,), (sensor,) = scene.targets, scene.sensor_areas
    assert (target.name, target.area_m2) == ("Target_Area", pytest.approx(2500.0))
    assert (sensor.name, sensor.area_m2) == ("SensorArea_1", pytest.approx(64.0))
    assert np.array_equal(scene.origin, np.zeros(3)) and not scene.warnings


def test_bezier_curves_are_sampled_as_drawn():
    b.plane("Ground", -50, -50, 50, 50)
    b.curve("Target_Square", [b.rect(0, 0, 10, 10)], kind="BEZIER")
    # A circle from 4 Bezier points with the standard handle length.
    circ = b.curve("SensorArea_Circle", [[(20, 0), (0, 20), (-20, 0), (0, -20)]], kind="BEZIER")
    k = 4 / 3 * math.tan(math.pi / 8) * 20
    for bp in circ.data.splines[0].bezier_points:
        x, y, _ = bp.co
        tangent = np.array([-y, x]) / 20 * k
        bp.handle_left_type = bp.handle_right_type = "FREE"
        bp.handle_left = (x - tangent[0], y - tangent[1], 0)
        bp.handle_right = (x + tangent[0], y + tangent[1], 0)
    circ.data.splines[0].resolution_u = 32
    scene = extract_scene()
    assert scene.targets[0].area_m2 == pytest.approx(100.0)
    assert scene.sensor_areas[0].area_m2 == pytest.approx(math.pi * 400, rel=2e-3)


def test_object_transform_and_even_odd_splines():
    b.plane("Ground", -50, -50, 50, 50)
    loop = b.curve("target_loop", [b.rect(0, 0, 40, 40), b.rect(10, 10, 30, 30)])
    loop.location = (100.0, 0.0, 0.0)
    loop.scale = (2.0, 1.0, 1.0)
    b.curve("Sensor_Area 1", [b.rect(-5, -5, 0, 0)])
    bpy.context.view_layer.update()
    scene = extract_scene()
    target = scene.targets[0].geometry
    assert target.area == pytest.approx(2 * (1600 - 400))
    assert target.bounds == pytest.approx((100, 0, 180, 40))


def test_what_occludes():
    b.flat_wall_scene()
    b.box("Ignored", (20, 0, 0), (21, 1, 5))["autoscoop_ignore"] = True
    hidden = b.box("Hidden", (30, 0, 0), (31, 1, 5))
    hidden.hide_set(True)
    b.box("Marked_Target_Mesh_Is_Fine", (40, 0, 0), (41, 1, 5))
    results = bpy.data.collections.new(names.RESULTS_COLLECTION)
    bpy.context.scene.collection.children.link(results)
    b.box("Frustum_1", (0, 0, 0), (1, 1, 1), collection=results)
    # A collection instance occludes where it is instanced.
    lib = bpy.data.collections.new("TreeLib")
    b.box("TreeSource", (0, 0, 0), (1, 1, 4), collection=lib)
    inst = bpy.data.objects.new("TreeInstance", None)
    inst.instance_type = "COLLECTION"
    inst.instance_collection = lib
    inst.location = (25.0, 10.0, 0.0)
    bpy.context.scene.collection.objects.link(inst)
    bpy.context.view_layer.update()
    scene = extract_scene()
    assert set(scene.occluders) == {"Ground", "Wall", "Marked_Target_Mesh_Is_Fine", "TreeSource"}
    # The instance's triangles sit at its location, not the source's.
    tree = scene.vertices[scene.vertices[:, 2] == 4.0]
    assert tree[:, 0].min() == pytest.approx(25.0) and tree[:, 1].min() == pytest.approx(10.0)


def test_empty_scene_is_valid_and_says_so():
    b.curve("Target", [b.rect(0, 0, 10, 10)], z=2.0)
    b.curve("SensorArea", [b.rect(-5, 0, -1, 4)], z=2.0)
    scene = extract_scene()
    assert len(scene.faces) == 0 and scene.floor_z() == pytest.approx(2.0)
    assert any("no occluder" in w and "flat nothing" in w for w in scene.warnings)


def test_georeferenced_scene_gets_a_local_origin():
    e, n = 500_000.0, 6_400_000.0
    b.plane("Ground", e - 60, n - 60, e + 60, n + 60)
    b.curve("Target", [b.rect(e, n - 25, e + 50, n + 25)])
    b.curve("SensorArea", [b.rect(e - 12, n - 4, e - 4, n + 4)])
    scene = extract_scene()
    assert np.array_equal(scene.origin, [e, n, 0.0])
    assert scene.targets[0].geometry.bounds == pytest.approx((0, -25, 50, 25))
    assert scene.vertices[:, :2].min() == pytest.approx(-60)


def _err(build):
    build()
    with pytest.raises(SceneContractError) as info:
        extract_scene()
    msg = str(info.value)
    assert "\n" not in msg
    return msg


def test_open_curve():
    def build():
        b.curve("Target_Open", [b.rect(0, 0, 10, 10)], cyclic=False)
        b.curve("SensorArea", [b.rect(-5, 0, -1, 4)])

    assert _err(build).startswith("Target_Open: curve is open")


def test_self_crossing_curve():
    def build():
        b.curve("Target", [b.rect(0, 0, 10, 10)])
        b.curve("SensorArea_Bow", [[(0, 0), (10, 10), (10, 0), (0, 10)]])

    assert _err(build) == "SensorArea_Bow: curve crosses itself"


def test_curve_not_in_xy_plane():
    def build():
        b.curve("Target_Wall", [[(0, 0, 0), (10, 0, 0), (10, 0, 10), (0, 0, 10)]])
        b.curve("SensorArea", [b.rect(-5, 0, -1, 4)])

    assert _err(build).startswith("Target_Wall: curve is not in the XY plane")


def test_missing_areas_and_wrong_types():
    assert "no target area" in _err(lambda: b.curve("SensorArea", [b.rect(0, 0, 1, 1)]))
    bpy.ops.wm.read_factory_settings(use_empty=True)
    assert "no sensor area" in _err(lambda: b.curve("Target", [b.rect(0, 0, 1, 1)]))
    bpy.ops.wm.read_factory_settings(use_empty=True)

    def mesh_target():
        b.plane("Target_Mesh", 0, 0, 1, 1)
        b.curve("SensorArea", [b.rect(0, 0, 1, 1)])

    assert _err(mesh_target) == "Target_Mesh: is a mesh, but a target area must be a curve"


def test_nurbs_and_bad_height():
    def nurbs():
        b.curve("Target_N", [b.rect(0, 0, 10, 10)], kind="NURBS")
        b.curve("SensorArea", [b.rect(-5, 0, -1, 4)])

    assert "Target_N: NURBS splines are not supported" in _err(nurbs)
    bpy.ops.wm.read_factory_settings(use_empty=True)

    def bad_height():
        b.curve("Target", [b.rect(0, 0, 10, 10)])
        b.curve("SensorArea_H", [b.rect(-5, 0, -1, 4)])["height_m"] = -3.0

    assert _err(bad_height).startswith("SensorArea_H: custom property height_m")


def test_marked_by_property_and_height():
    b.curve("Road", [b.rect(0, 0, 10, 10)])["autoscoop_role"] = "target"
    area = b.curve("Lawn", [b.rect(-5, 0, -1, 4)])
    area["autoscoop_role"] = "sensor_area"
    area["height_m"] = 9
    scene = extract_scene()
    assert scene.targets[0].name == "Road" and scene.sensor_areas[0].height_m == 9.0
