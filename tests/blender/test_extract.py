"""Scene extraction: the contract, what occludes, and one-line errors naming objects."""

import math

import bpy
import numpy as np
import pytest
import shapely

from autoscoop_blender import names
from autoscoop_blender.core.errors import SceneContractError
from autoscoop_blender.core.model.sensors import PAPER_CAMERA
from autoscoop_blender.core.problem import Problem
from autoscoop_blender.core.settings import OptimizeSettings
from autoscoop_blender.scene import pipeline
from autoscoop_blender.scene.extract import extract_scene
from autoscoop_blender.scene.factory import BVHFactory
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


# --- tilt, coordinates and heights (issue 14) ------------------------------------------


def test_a_curve_following_the_terrain_is_not_tilted():
    """Points at different heights, not in one plane: drawn in plan, its plan area."""
    b.plane("Ground", -50, -50, 250, 50)
    road = [(0, 0, 0.0), (100, 0, 3.0), (200, 0, 1.0), (200, 20, 4.0), (0, 20, -2.0)]
    b.curve("Target_Hill", [road])
    b.curve("SensorArea", [b.rect(-10, 0, -2, 8)])
    assert extract_scene().targets[0].area_m2 == pytest.approx(4000.0)


def test_a_curve_on_a_ramp_follows_it():
    """In one sloping plane (6 deg) but on the ramp's surface: not tilted."""

    def z(x, y):
        return 0.03 * x - 0.1 * y

    corners = [(-50, -50), (250, -50), (250, 50), (-50, 50)]
    b.mesh("Ramp", [(x, y, z(x, y)) for x, y in corners], [(0, 1, 2, 3)])
    b.curve("Target_Ramp", [[(x, y, z(x, y)) for x, y in b.rect(0, 0, 200, 20)]])
    b.curve("SensorArea", [[(x, y, z(x, y) + 0.1) for x, y in b.rect(-10, 0, -2, 8)]])
    assert extract_scene().targets[0].area_m2 == pytest.approx(4000.0)
    pipeline.forget_area_report()  # the add-on's handlers are not registered here
    rows = {name: info for _, name, info in pipeline.area_report(bpy.context.scene)}
    assert rows["Target_Ramp"] == "4,000 m^2"
    # Lifted 2 m off the ramp, the same curve is a tilted one: so says the panel too.
    bpy.data.objects["Target_Ramp"].location.z = 2.0
    with pytest.raises(SceneContractError, match=r"^Target_Ramp: .* \(tilted 6\.0 deg"):
        extract_scene()
    pipeline.forget_area_report()
    rows = {name: info for _, name, info in pipeline.area_report(bpy.context.scene)}
    assert rows["Target_Ramp"].startswith("curve is not in the XY plane (tilted 6.0 deg")
    assert rows["SensorArea"] == "64 m^2"
    pipeline.forget_area_report()


def test_a_curve_within_one_degree_of_flat_passes():
    b.plane("Ground", -50, -50, 50, 50)
    b.curve("Target", [b.rect(0, 0, 10, 10)]).rotation_euler = (math.radians(0.9), 0, 0)
    b.curve("SensorArea", [b.rect(-10, 0, -2, 8)])
    area = extract_scene().targets[0].area_m2
    assert area == pytest.approx(100.0 * math.cos(math.radians(0.9)))


def test_a_flat_curve_tilted_out_of_the_xy_plane():
    def build():
        t = math.tan(math.radians(5))
        b.curve("Target_Ramp", [[(0, 0, 0), (10, 0, 0), (10, 10, 10 * t), (0, 10, 10 * t)]])
        b.curve("SensorArea", [b.rect(-10, 0, -2, 8)])

    assert _err(build).startswith(
        "Target_Ramp: curve is not in the XY plane (tilted 5.0 deg, flat is within 1 deg): "
        "its 100 m^2 would count as 100 m^2 in plan"
    )


def test_curve_without_splines_and_bad_points():
    def empty():
        data = bpy.data.curves.new("Target_None", "CURVE")
        bpy.context.scene.collection.objects.link(bpy.data.objects.new("Target_None", data))
        b.curve("SensorArea", [b.rect(-5, 0, -1, 4)])

    assert _err(empty) == "Target_None: curve has no splines"
    bpy.ops.wm.read_factory_settings(use_empty=True)

    def nan_point():
        b.curve("Target", [b.rect(0, 0, 10, 10)])
        b.curve("SensorArea_N", [b.rect(-5, 0, -1, 4), [(0, 0), (1, 0), (math.nan, 1)]])

    assert _err(nan_point) == "SensorArea_N (spline 2): a curve point is not finite (nan, 1, 0)"


def test_occluders_beyond_the_coordinate_limit_are_named():
    def far():
        b.curve("Target", [b.rect(0, 0, 10, 10)])
        b.curve("SensorArea", [b.rect(-5, 0, -1, 4)])
        b.box("Moon", (0, 0, 3.8e8), (10, 10, 3.8e8 + 10))

    assert _err(far).startswith("Moon: occluder reaches 3.8e+08 m from the origin, beyond 1e+07 m")
    bpy.ops.wm.read_factory_settings(use_empty=True)
    b.curve("Target", [b.rect(0, 0, 10, 10)])
    b.curve("SensorArea", [b.rect(-5, 0, -1, 4)])
    b.box("Moon", (0, 0, 3.8e8), (10, 10, 3.8e8 + 10))["autoscoop_ignore"] = True
    assert extract_scene().occluders == ()


@pytest.mark.parametrize("height", [2500.0, True, "7"])
def test_sensor_area_height_out_of_range(height):
    def build():
        b.curve("Target", [b.rect(0, 0, 10, 10)])
        b.curve("SensorArea_H", [b.rect(-5, 0, -1, 4)])["height_m"] = height

    assert _err(build).startswith(
        "SensorArea_H: custom property height_m must be a number in [0, 2000] m (the mast height)"
    )


def test_a_tilted_curve_far_from_the_origin():
    """Georeferenced points (float32 in Blender, 0.03 m steps at x = 500 km) in a
    30 deg plane are still one tilted plane; flat ones there still pass."""
    x0, y0, t = 500_000.0, 6_400_000.0, math.tan(math.radians(30))
    b.plane("Ground", x0 - 100, y0 - 100, x0 + 100, y0 + 100)
    b.curve("SensorArea", [[(x0 + x, y0 + y) for x, y in b.rect(-10, 0, -2, 8)]])
    b.curve("Target_Geo", [[(x0 + x, y0 + y, y * t) for x, y in b.rect(0.3, 0.7, 50.3, 20.7)]])
    with pytest.raises(SceneContractError, match=r"^Target_Geo: .*\(tilted 30\.0 deg"):
        extract_scene()
    target = bpy.data.objects["Target_Geo"]
    for p in target.data.splines[0].points:
        p.co.z = 0.0
    assert extract_scene().targets[0].area_m2 == pytest.approx(1000.0, rel=1e-5)


# --- no-mast zones and target requirements (issue 16) ----------------------------------


def test_a_no_mast_zone_cuts_a_hole_in_the_sensor_areas():
    b.plane("Ground", -50, -50, 50, 50)
    b.curve("Target", [b.rect(0, 20, 10, 30)])
    b.curve("SensorArea_Long", [b.rect(0, 0, 20, 10)])  # 200 m^2
    b.curve("SensorArea_Gone", [b.rect(30, 0, 34, 4)])  # wholly inside the second zone
    b.curve("NoMast_Pipeline", [b.rect(5, -5, 10, 15)])  # 5 m x 10 m of the first
    b.curve("No_Mast_Yard", [b.rect(29, -1, 35, 5)])
    scene = extract_scene()
    areas = {a.name: a for a in scene.sensor_areas}
    assert list(areas) == ["SensorArea_Long"]
    long = areas["SensorArea_Long"].geometry
    assert long.area == pytest.approx(200.0 - 50.0)
    assert not long.contains(shapely.Point(7.5, 5.0)) and long.contains(shapely.Point(2, 5))
    assert sorted(z.name for z in scene.no_mast) == ["NoMast_Pipeline", "No_Mast_Yard"]
    # What each zone took, for the panel and the reports: 5 m x 10 m, and 4 m x 4 m.
    assert [(e.area, e.cause, e.m2) for e in scene.excluded] == [
        ("SensorArea_Long", "NoMast_Pipeline", pytest.approx(50.0)),
        ("SensorArea_Gone", "No_Mast_Yard", pytest.approx(16.0)),
    ]
    # The zones are not occluders, nor targets.
    assert not {"NoMast_Pipeline", "No_Mast_Yard"} & set(scene.occluders)
    # Every mast position of a run stands outside the zones (on their edge at most:
    # x = 10 is the lattice line the first zone ends on).
    problem = Problem(
        scene, BVHFactory.of(scene)(), PAPER_CAMERA, OptimizeSettings(optimizer="greedy")
    )
    xy = problem.space.positions + scene.origin[:2]
    assert sorted(set(xy[:, 0])) == [0, 2, 4, 10, 12, 14, 16, 18, 20]
    zones = shapely.union_all([z.geometry for z in scene.no_mast])
    assert len(xy) and not shapely.contains_xy(zones, xy[:, 0], xy[:, 1]).any()


def test_no_sensor_area_left_outside_the_zones():
    def build():
        b.curve("Target", [b.rect(0, 20, 10, 30)])
        b.curve("SensorArea", [b.rect(0, 0, 4, 4)])
        b.curve("NoMast", [b.rect(-1, -1, 5, 5)])

    assert _err(build).endswith(
        "no sensor area has room for a mast: no-mast zones or objects standing on the "
        "ground cover them all (NoMast)"
    )


def test_target_requirements_are_read_and_checked():
    b.curve("Target_Junction", [b.rect(0, 0, 10, 10)])
    b.curve("Target_Straight", [b.rect(20, 0, 30, 10)])
    b.curve("SensorArea", [b.rect(-5, 0, -1, 4)])
    junction = bpy.data.objects["Target_Junction"]
    junction[names.COVERAGE_K_PROP] = 2
    junction[names.DORI_PROP] = "Recognize"  # either spelling, any case
    junction[names.REQUIRE_PROP] = "lidar"
    areas = {a.name: a for a in extract_scene().targets}
    assert (areas["Target_Junction"].coverage_k, areas["Target_Junction"].dori) == (2, "recognise")
    assert areas["Target_Junction"].require == "lidar"
    straight = areas["Target_Straight"]
    assert (straight.coverage_k, straight.dori, straight.require) == (None, None, None)
    for prop, value, message in (
        (names.COVERAGE_K_PROP, 0, "coverage_k must be a whole number from 1 to 10"),
        (names.COVERAGE_K_PROP, 1.5, "coverage_k must be a whole number from 1 to 10"),
        (names.DORI_PROP, "see", "dori must be a DORI level: one of detect, observe, "),
        (names.REQUIRE_PROP, "sonar", "require must be a sensor kind: one of camera, lidar"),
    ):
        junction[prop] = value
        with pytest.raises(SceneContractError) as err:
            extract_scene()
        assert str(err.value).startswith(f"Target_Junction: custom property {message}")
        del junction[prop]
