"""The OpenDRIVE import into Blender (``scene/xodr_import.py``, File > Import and the
panel): what it makes follows the scene contract and lies where the file says; a
refused import changes nothing."""

import math

import bpy
import numpy as np
import pytest
import shapely
from mathutils import Vector
from mathutils.bvhtree import BVHTree

import autoscoop_blender
from autoscoop_blender import names
from autoscoop_blender.io.opendrive import build_import, read_opendrive
from autoscoop_blender.scene.extract import extract_scene
from tests.conftest import ROOT

XODR = ROOT / "tests" / "data" / "xodr"
FLEX = XODR / "AstaZero_FlexZoneCrossing.xodr"


@pytest.fixture(scope="module", autouse=True)
def registered():
    autoscoop_blender.register()
    yield
    autoscoop_blender.unregister()


def _import(path=FLEX, **options):
    assert bpy.ops.autoscoop.import_xodr(filepath=str(path), **options) == {"FINISHED"}


def _tagged(prefix):
    return [o for o in bpy.data.objects if o.name.startswith(prefix)]


def test_the_objects_are_the_files_roads_and_areas():
    expected = build_import(read_opendrive(FLEX))
    _import()
    roads = [o for o in bpy.data.objects if o.type == "MESH" and o.name.startswith("Road_")]
    assert sorted(o.name for o in roads) == sorted(s.name for s in expected.surfaces)
    assert sorted(o.name for o in _tagged("Target_")) == sorted(a.name for a in expected.targets)
    assert sorted(o.name for o in _tagged("SensorArea_")) == sorted(
        a.name for a in expected.sensor_areas
    )
    # Tagged with where they came from, so a user can find them.
    for area in expected.targets:
        obj = bpy.data.objects[area.name]
        assert obj[names.XODR_ROAD_PROP] == area.road_id
        assert obj[names.XODR_LANES_PROP] == ",".join(area.lane_types)
    # The georeference of the file's header, on the scene.
    scene = bpy.context.scene
    assert scene[names.CRS_PROP].startswith("+proj=tmerc +lat_0=57.77527428642261")
    assert list(scene[names.CRS_OFFSET_PROP]) == pytest.approx(list(expected.crs_offset))


def test_the_scene_runs_as_imported():
    """extract_scene takes it unchanged: every area, its plan area, the roads occlude,
    and each target curve lies on its road (its points within 1 cm of the road's
    mesh)."""
    expected = build_import(read_opendrive(FLEX))
    _import()
    model = extract_scene()
    areas = {a.name: a.area_m2 for a in (*model.targets, *model.sensor_areas)}
    for area in (*expected.targets, *expected.sensor_areas):
        # Blender keeps the points in float32: about 1e-7 relative.
        assert areas[area.name] == pytest.approx(area.area_m2, rel=1e-5)
    assert set(model.occluders) >= {s.name for s in expected.surfaces} | {"Ground"}
    for area in expected.targets:
        road = bpy.data.objects[f"Road_{area.road_id}"]
        tree = BVHTree.FromObject(road, bpy.context.evaluated_depsgraph_get())
        for ring in area.rings:
            for p in ring[:: max(1, len(ring) // 20)]:
                near = tree.find_nearest(Vector(p))[0]
                assert near is not None and (near - Vector(p)).length < 0.01, (area.name, p)


def test_options_reach_the_import():
    _import(lanes="driving,shoulder", band_inner=2.0, band_outer=4.0, terrain="none")
    assert "Ground" not in bpy.data.objects
    kinds = {o[names.XODR_LANES_PROP] for o in _tagged("Target_")}
    expected = build_import(read_opendrive(FLEX), ("driving", "shoulder"), (2.0, 4.0), "none")
    assert kinds == {",".join(a.lane_types) for a in expected.targets}
    total = sum(a.area_m2 for a in expected.sensor_areas)
    model = extract_scene()
    assert sum(a.area_m2 for a in model.sensor_areas) == pytest.approx(total, rel=1e-5)


def test_a_refused_import_changes_nothing(tmp_path):
    not_xodr = tmp_path / "map.xodr"
    not_xodr.write_text('<svg xmlns="http://www.w3.org/2000/svg"></svg>')
    before = (len(bpy.data.objects), len(bpy.data.collections), dict(bpy.context.scene.items()))
    with pytest.raises(RuntimeError) as err:
        bpy.ops.autoscoop.import_xodr(filepath=str(not_xodr))
    text = str(err.value).strip()
    assert text.startswith("Error: ") and "not an OpenDRIVE file" in text and "\n" not in text
    # A scene already in another CRS: the two would not line up.
    bpy.context.scene[names.CRS_PROP] = "EPSG:3006"
    before = (len(bpy.data.objects), len(bpy.data.collections))
    with pytest.raises(RuntimeError, match="its CRS differs from scene"):
        bpy.ops.autoscoop.import_xodr(filepath=str(FLEX))
    assert (len(bpy.data.objects), len(bpy.data.collections)) == before
    assert bpy.context.scene[names.CRS_PROP] == "EPSG:3006"


def test_a_second_import_of_the_same_site_lines_up():
    _import()
    first = {o.name: o.matrix_world.translation.copy() for o in bpy.data.objects}
    _import(lanes="shoulder")  # same CRS and offset: accepted, beside the first
    assert all(bpy.data.objects[n].matrix_world.translation == t for n, t in first.items())
    assert len([c for c in bpy.data.collections if c.name.startswith("OpenDRIVE ")]) == 2


def test_the_flat_ground_lies_under_every_road():
    _import()
    ground = bpy.data.objects["Ground"]
    gz = max(v.co.z for v in ground.data.vertices)
    ground_box = shapely.box(
        *np.min([v.co[:2] for v in ground.data.vertices], axis=0),
        *np.max([v.co[:2] for v in ground.data.vertices], axis=0),
    )
    for obj in bpy.data.objects:
        if obj.type == "MESH" and obj.name.startswith("Road_"):
            co = np.array([v.co[:] for v in obj.data.vertices])
            assert co[:, 2].min() > gz - 1e-3
            assert ground_box.contains(shapely.MultiPoint(co[:, :2]))
    assert not math.isnan(gz)


def test_a_georeference_proj_cannot_read_leaves_the_scene_without_crs():
    # CARLA's towns name an origin but no projection: "+lat_0=49 +lon_0=8".
    _import(XODR / "Town01.xodr")
    scene = bpy.context.scene
    assert names.CRS_PROP not in scene and names.CRS_OFFSET_PROP not in scene
    assert scene[names.XODR_GEOREF_PROP].startswith("+lat_0=4.9")
    assert extract_scene().crs is None
