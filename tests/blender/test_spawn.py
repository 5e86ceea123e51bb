"""Results in the scene: cameras, frusta, footprints, masts, coverage map, clean removal.

Expected numbers are worked out here from the inputs (hand areas, the sensor frame
formula, the FoV angles), not read back from the module under test.
"""

import math
import time
from dataclasses import replace

import bpy
import numpy as np
import pytest
from mathutils import Vector
from shapely.geometry import MultiPolygon, Polygon, box

from autoscoop_blender import names
from autoscoop_blender.core.geom.drape import drape
from autoscoop_blender.core.model.sensors import PAPER_CAMERA, ROADSIDE_LIDAR
from autoscoop_blender.core.result import MastRecord, Result, SensorRecord
from autoscoop_blender.scene import spawn
from autoscoop_blender.scene.extract import extract_scene
from autoscoop_blender.scene.spawn import remove_results, spawn_results
from tests.blender import builders as b

PINHOLE_CAMERA = replace(PAPER_CAMERA, h_fov_deg=60.0, v_fov_deg=40.0, pattern="pinhole")

# Footprint of sensor 1: a 30 x 20 m rectangle with a 6 x 6 m hole -> 600 - 36 m^2.
RING = Polygon(b.rect(10, -10, 40, 10), [b.rect(20, -3, 26, 3)])
RING_M2 = 30 * 20 - 6 * 6
# Footprint of sensor 2: a trapezoid, parallel sides 10 and 20 m, 15 m apart.
TRAPEZOID = Polygon([(-5, -5), (5, -5), (10, -20), (-10, -20)])
TRAPEZOID_M2 = (10 + 20) / 2 * 15
# Footprint of the lidar: two disjoint squares, 100 + 25 m^2.
TWO_SQUARES = MultiPolygon([box(20, 30, 30, 40), box(35, 45, 40, 50)])
TWO_SQUARES_M2 = 125.0

# n_covered of the 6 x 5 target grid (cell 1 m) at z = 0.5.
GRID_NX, GRID_NY, CELL_M, GRID_Z = 6, 5, 1.0, 0.5


def sensor(n, model, xyz, height, pitch, yaw, mast, footprint):
    return SensorRecord(
        n=n,
        x=xyz[0],
        y=xyz[1],
        z=xyz[2],
        height_m=height,
        pitch_deg=pitch,
        yaw_deg=yaw,
        model=model,
        mast=mast,
        fitness=0.5,
        epochs=3,
        covered_target_m2=100.0,
        footprint_m2=footprint.area,
        footprint=footprint,
    )


def grid_points():
    ix, iy = np.meshgrid(np.arange(GRID_NX), np.arange(GRID_NY), indexing="ij")
    xy = np.column_stack([ix.ravel(), iy.ravel()]) * CELL_M + (-20.0, 5.0)
    pts = np.column_stack([xy, np.full(len(xy), GRID_Z)])
    n_covered = (np.arange(len(pts)) % 5).astype(np.int32)  # 0, 1, 2, 3, 4, 0, ...
    return pts, n_covered


def make_result(extra_sensors=()):
    sensors = (
        sensor(1, PAPER_CAMERA, (-8.0, 0.0, 7.0), 7.0, 40.0, 0.0, 0, RING),
        sensor(2, PAPER_CAMERA, (-8.0, 0.0, 7.0), 7.0, 70.0, 270.0, 0, TRAPEZOID),
        sensor(3, PINHOLE_CAMERA, (30.0, 40.0, 8.0), 7.0, 31.0, 135.0, 1, Polygon()),
        sensor(4, ROADSIDE_LIDAR, (30.0, 40.0, 6.0), 5.0, 10.0, 45.0, 1, TWO_SQUARES),
        *extra_sensors,
    )
    masts = (
        MastRecord(1, -8.0, 0.0, 0.0, 7.0, (1, 2)),
        MastRecord(2, 30.0, 40.0, 1.0, 7.0, (3, 4)),
    )
    pts, n_covered = grid_points()
    return Result(
        sensors=sensors,
        masts=masts,
        targets=(("Target_Area", box(0, -25, 50, 25)),),
        sensor_areas=(("SensorArea_1", box(-12, -4, -4, 4)),),
        points=pts,
        n_visible=n_covered + 1,
        n_covered=n_covered,
        cell_m=CELL_M,
    )


@pytest.fixture
def user_scene():
    """flat_wall's contract geometry plus a user camera and a material on the wall."""
    b.flat_wall_scene()
    mat = bpy.data.materials.new("Concrete")
    bpy.data.objects["Wall"].data.materials.append(mat)
    cam = bpy.data.objects.new("UserCam", bpy.data.cameras.new("UserCam"))
    cam.location = (3.0, -4.0, 2.0)
    bpy.context.scene.collection.objects.link(cam)
    bpy.context.view_layer.update()
    return bpy.context.scene


def spawned(kind_collection):
    """Objects of one group collection, keyed by their sensor / mast number."""
    coll = bpy.data.collections[kind_collection]
    key = spawn.MAST_PROP if kind_collection == spawn.MASTS_COLLECTION else spawn.SENSOR_PROP
    return {o[key]: o for o in coll.objects}


def world_vertices(obj):
    co = np.empty(len(obj.data.vertices) * 3)
    obj.data.vertices.foreach_get("co", co)
    m = np.array(obj.matrix_world)
    return co.reshape(-1, 3) @ m[:3, :3].T + m[:3, 3]


def faces_of(mesh):
    """List of vertex-index arrays, one per face."""
    start = np.empty(len(mesh.polygons), dtype=np.int32)
    total = np.empty(len(mesh.polygons), dtype=np.int32)
    mesh.polygons.foreach_get("loop_start", start)
    mesh.polygons.foreach_get("loop_total", total)
    vi = np.empty(len(mesh.loops), dtype=np.int32)
    mesh.loops.foreach_get("vertex_index", vi)
    return [vi[s : s + t] for s, t in zip(start, total)]


def snapshot():
    """Names of every datablock kind spawning may touch."""
    return {
        kind: sorted(x.name for x in getattr(bpy.data, kind))
        for kind in ("objects", "meshes", "cameras", "materials", "collections", "curves")
    }


def user_matrices():
    return {o.name: [list(r) for r in o.matrix_world] for o in bpy.data.objects}


# --- cameras -----------------------------------------------------------------------

POSES = [(40.0, 0.0), (70.0, 270.0), (31.0, 135.0), (0.0, 90.0), (90.0, 30.0), (-15.0, 200.0)]


def expected_axes(pitch, yaw):
    """Forward and up by hand: forward from pitch/yaw, up = forward x left."""
    p, y = math.radians(pitch), math.radians(yaw)
    forward = np.array([math.cos(p) * math.cos(y), math.cos(p) * math.sin(y), -math.sin(p)])
    left = np.array([-math.sin(y), math.cos(y), 0.0])
    return forward, np.cross(forward, left)


def test_camera_looks_along_the_sensor_forward(user_scene):
    extra = tuple(
        sensor(10 + k, PAPER_CAMERA, (5.0 * k, -30.0, 9.0), 7.0, p, y, 0, Polygon())
        for k, (p, y) in enumerate(POSES)
    )
    spawn_results(user_scene, make_result(extra))
    bpy.context.view_layer.update()  # matrix_world re-derived from loc/rot/scale
    cams = spawned(spawn.SENSORS_COLLECTION)
    for k, (pitch, yaw) in enumerate(POSES):
        cam = cams[10 + k]
        rot = cam.matrix_world.to_3x3()
        forward, up = expected_axes(pitch, yaw)
        assert np.allclose(rot @ Vector((0, 0, -1)), forward, atol=1e-6), (pitch, yaw)
        assert np.allclose(rot @ Vector((0, 1, 0)), up, atol=1e-6), (pitch, yaw)
        assert np.allclose(cam.matrix_world.translation, (5.0 * k, -30.0, 9.0), atol=1e-6)
        assert np.allclose(cam.matrix_world.to_scale(), (1, 1, 1), atol=1e-6)
    # yaw 270, pitch 70 by hand: looking -Y and steeply down.
    fwd = np.array(cams[2].matrix_world.to_3x3() @ Vector((0, 0, -1)))
    s70, c70 = math.sin(math.radians(70)), math.cos(math.radians(70))
    assert np.allclose(fwd, (0.0, -c70, -s70), atol=1e-6)


def test_camera_lens_range_and_properties(user_scene):
    spawn_results(user_scene, make_result())
    cams = spawned(spawn.SENSORS_COLLECTION)
    assert [c.name for c in sorted(cams.values(), key=lambda c: c.name)] == [
        "Sensor_01",
        "Sensor_02",
        "Sensor_03",
        "Sensor_04",
    ]
    cam = cams[1].data
    assert cam.type == "PERSP"
    assert cam.angle_x == pytest.approx(math.radians(80), abs=1e-5)
    assert cam.angle_y == pytest.approx(math.radians(80), abs=1e-5)
    assert cam.clip_end == pytest.approx(80.0)
    pin = cams[3].data
    assert pin.sensor_fit == "HORIZONTAL"
    assert (pin.angle_x, pin.angle_y) == (
        pytest.approx(math.radians(60), abs=1e-5),
        pytest.approx(math.radians(40), abs=1e-5),
    )
    lidar = cams[4].data  # 360 deg does not fit a lens: the documented cap
    assert lidar.sensor_fit == "HORIZONTAL"
    assert lidar.angle_x == pytest.approx(math.radians(spawn.MAX_CAMERA_ANGLE_DEG), abs=1e-5)
    assert lidar.angle_y == pytest.approx(math.radians(33.2), abs=1e-5)
    assert spawn.MAX_CAMERA_ANGLE_DEG < math.degrees(
        bpy.types.Camera.bl_rna.properties["angle"].hard_max
    )

    obj = cams[2]
    assert obj[spawn.SENSOR_PROP] == 2
    assert (obj["pitch_deg"], obj["yaw_deg"], obj["height_m"], obj["mast"]) == (70, 270, 7, 0)
    model = obj[spawn.MODEL_PROP].to_dict()
    assert model == PAPER_CAMERA.to_dict()


# --- frusta ------------------------------------------------------------------------


def fov_with_tolerance(model, d, tol):
    """Whether sensor-frame unit directions lie in the FoV or within ``tol`` of it."""
    ha, va = math.radians(model.h_fov_deg) / 2, math.radians(model.v_fov_deg) / 2
    if model.pattern == "angular":
        az = np.abs(np.arctan2(d[:, 1], d[:, 0]))
        el = np.abs(np.arcsin(np.clip(d[:, 2], -1, 1)))
        return (az <= ha + tol) & (el <= va + tol)
    return (
        (d[:, 0] > 0)
        & (np.abs(d[:, 1]) <= (math.tan(ha) + tol) * d[:, 0])
        & (np.abs(d[:, 2]) <= (math.tan(va) + tol) * d[:, 0])
    )


def signed_volume(verts, faces):
    v = verts[np.array(faces)]
    return np.einsum("ij,ij->i", v[:, 0], np.cross(v[:, 1], v[:, 2])).sum() / 6


def test_frusta_stay_inside_fov_and_range(user_scene):
    result = make_result()
    spawn_results(user_scene, result)
    frusta = spawned(spawn.FRUSTA_COLLECTION)
    assert len(frusta) == len(result.sensors)
    for rec in result.sensors:
        obj = frusta[rec.n]
        assert obj.name == f"Frustum_{rec.n:02d}"
        assert obj.display_type == "WIRE"
        rel = world_vertices(obj) - (rec.x, rec.y, rec.z)
        dist = np.linalg.norm(rel, axis=1)
        apex = dist < 1e-6
        assert apex.sum() == 1
        assert dist.max() <= rec.model.range_m + 1e-4
        assert np.allclose(dist[~apex], rec.model.range_m, atol=1e-4)  # the far cap
        d_world = rel[~apex] / dist[~apex, None]
        d_sensor = d_world @ expected_frame(rec.pitch_deg, rec.yaw_deg).T
        assert np.all(rec.model.in_fov(d_sensor) | fov_with_tolerance(rec.model, d_sensor, 1e-6))

        faces = faces_of(obj.data)
        tris = [f for f in faces if len(f) == 3]
        assert len(tris) == len(faces)
        # Closed and consistently wound: every edge in two faces, once each way.
        edges = np.concatenate([np.stack([f, np.roll(f, -1)], 1) for f in faces])
        assert len({tuple(e) for e in edges}) == len(edges)
        assert {tuple(e) for e in edges} == {tuple(e[::-1]) for e in edges}
        # Outward normals and the right volume: R^3 / 3 times the FoV's solid angle.
        ha, va = math.radians(rec.model.h_fov_deg) / 2, math.radians(rec.model.v_fov_deg) / 2
        if rec.model.pattern == "angular":
            solid = 2 * ha * 2 * math.sin(va)
        else:  # a rectangular pyramid's solid angle
            solid = 4 * math.asin(math.sin(ha) * math.sin(va))
        vol = signed_volume(rel, faces)
        assert vol == pytest.approx(rec.model.range_m**3 / 3 * solid, rel=0.03)


def expected_frame(pitch, yaw):
    forward, up = expected_axes(pitch, yaw)
    left = np.cross(up, forward)
    return np.array([forward, left, up])


def test_camera_frustum_reaches_its_corners_and_lidar_goes_round(user_scene):
    result = make_result()
    spawn_results(user_scene, result)
    frusta = spawned(spawn.FRUSTA_COLLECTION)

    def angles(n):
        rec = result.sensors[n - 1]
        rel = world_vertices(frusta[n]) - (rec.x, rec.y, rec.z)
        rel = rel[np.linalg.norm(rel, axis=1) > 1e-6]
        d = rel / np.linalg.norm(rel, axis=1, keepdims=True)
        d = d @ expected_frame(rec.pitch_deg, rec.yaw_deg).T
        return np.degrees(np.arctan2(d[:, 1], d[:, 0])), np.degrees(np.arcsin(d[:, 2]))

    az, el = angles(1)  # 80 x 80 camera: all four corners of the angular FoV
    for sa in (-1, 1):
        for se in (-1, 1):
            assert np.any((np.abs(az - 40 * sa) < 1e-4) & (np.abs(el - 40 * se) < 1e-4))
    az, el = angles(4)  # lidar: the whole turn, +-16.6 deg
    gaps = np.diff(np.sort(np.unique(np.round(az, 4))))
    assert gaps.max() <= 10.0 + 1e-6 and np.ptp(az) >= 350.0
    assert el.min() == pytest.approx(-16.6, abs=1e-4)
    assert el.max() == pytest.approx(16.6, abs=1e-4)


# --- footprints --------------------------------------------------------------------


def xy_triangles(obj):
    v = world_vertices(obj)
    faces = faces_of(obj.data)
    assert all(len(f) == 3 for f in faces)
    return v, v[np.array(faces)]


def xy_areas(tri):
    e1, e2 = tri[:, 1, :2] - tri[:, 0, :2], tri[:, 2, :2] - tri[:, 0, :2]
    return (e1[:, 0] * e2[:, 1] - e1[:, 1] * e2[:, 0]) / 2


def inside_any(tri, p):
    """Whether XY point ``p`` lies inside (or on) any counter-clockwise triangle."""
    a, b_, c = tri[:, 0, :2], tri[:, 1, :2], tri[:, 2, :2]

    def side(u, w):
        return (w[:, 0] - u[:, 0]) * (p[1] - u[:, 1]) - (w[:, 1] - u[:, 1]) * (p[0] - u[:, 0])

    return bool(np.any((side(a, b_) >= 0) & (side(b_, c) >= 0) & (side(c, a) >= 0)))


def test_footprint_area_holes_and_flat_height(user_scene):
    spawn_results(user_scene, make_result())
    feet = spawned(spawn.FOOTPRINTS_COLLECTION)
    assert sorted(feet) == [1, 2, 4]  # sensor 3's footprint is empty
    for n, expected in ((1, RING_M2), (2, TRAPEZOID_M2), (4, TWO_SQUARES_M2)):
        v, tri = xy_triangles(feet[n])
        areas = xy_areas(tri)
        assert np.all(areas > 0)  # wound counter-clockwise: normals up
        assert areas.sum() == pytest.approx(expected, rel=0.005)
        # Densified: no edge longer than a 2 m cell's diagonal.
        edges = np.linalg.norm(tri - np.roll(tri, 1, axis=1), axis=2)
        assert edges.max() <= 2 * math.sqrt(2) + 1e-6
    v, tri = xy_triangles(feet[1])
    assert not inside_any(tri, (23.0, 0.0))  # the hole
    assert inside_any(tri, (15.0, 0.0)) and inside_any(tri, (35.0, 8.0))
    assert not inside_any(tri, (45.0, 0.0))
    assert np.allclose(v[:, 2], 0.0 + 0.15, atol=1e-5)  # mast foot z 0, lifted 0.15
    v, _ = xy_triangles(feet[4])
    assert np.allclose(v[:, 2], 1.0 + 0.15, atol=1e-5)  # lidar's mast foot at z = 1
    assert all(o.data.materials[0].name.startswith(spawn.FOOTPRINT_MATERIAL) for o in feet.values())


def test_footprint_drapes_on_terrain(user_scene):
    """The core drapes footprints (``core.geom.drape``); spawn builds the mesh as given."""

    def hill(xy):
        return 0.1 * xy[:, 0] + 2.0 * np.sin(xy[:, 1] / 5.0)

    result = make_result()
    sensors = tuple(
        replace(s, drape=None if s.footprint.is_empty else drape(s.footprint, hill))
        for s in result.sensors
    )
    spawn_results(user_scene, replace(result, sensors=sensors))
    v, tri = xy_triangles(spawned(spawn.FOOTPRINTS_COLLECTION)[1])
    assert np.allclose(v[:, 2], hill(v[:, :2]) + 0.15, atol=1e-4)
    # Interior vertices too, not only the outline: every point of the 2 m lattice
    # inside the ring (16 x 11 in the rectangle, less 2 x 3 inside the hole) is a vertex.
    lattice = np.array([(x, y) for x in range(10, 41, 2) for y in range(-10, 11, 2)], float)
    in_hole = (np.abs(lattice[:, 0] - 23) < 3) & (np.abs(lattice[:, 1]) < 3)
    lattice = lattice[~in_hole]
    assert len(lattice) == 16 * 11 - 2 * 3
    gap = np.linalg.norm(lattice[:, None, :] - v[None, :, :2], axis=2).min(axis=1)
    assert gap.max() < 1e-5
    assert xy_areas(tri).sum() == pytest.approx(RING_M2, rel=0.005)


# --- masts and coverage ------------------------------------------------------------


def test_masts(user_scene):
    spawn_results(user_scene, make_result())
    masts = spawned(spawn.MASTS_COLLECTION)
    assert sorted(masts) == [1, 2]
    for n, (x, y, z0, h) in {1: (-8.0, 0.0, 0.0, 7.0), 2: (30.0, 40.0, 1.0, 7.0)}.items():
        obj = masts[n]
        assert obj.name == f"Mast_{n:02d}"
        v = world_vertices(obj)
        assert v[:, 2].min() == pytest.approx(z0, abs=1e-5)
        assert v[:, 2].max() == pytest.approx(z0 + h, abs=1e-5)
        radius = np.linalg.norm(v[:, :2] - (x, y), axis=1)
        assert np.allclose(radius, 0.15, atol=1e-5)
        assert 8 <= len(v) // 2 <= 12
        assert obj["height_m"] == h
    assert list(masts[2]["sensors"]) == [3, 4]


def test_coverage_mesh(user_scene):
    result = make_result()
    spawn_results(user_scene, result)
    (obj,) = bpy.data.collections[spawn.COVERAGE_COLLECTION].objects
    mesh = obj.data
    n = len(result.points)
    assert len(mesh.polygons) == n == GRID_NX * GRID_NY

    values = np.empty(n, dtype=np.int32)
    mesh.attributes[spawn.COVERAGE_ATTR].data.foreach_get("value", values)
    assert mesh.attributes[spawn.COVERAGE_ATTR].domain == "FACE"
    assert np.array_equal(values, result.n_covered)

    # Each face: a horizontal 0.9 x 0.9 m square centred 5 cm above its point.
    v = world_vertices(obj)
    faces = faces_of(mesh)
    quads = v[np.array(faces)]
    assert np.allclose(quads.mean(axis=1), result.points + (0, 0, 0.05), atol=1e-5)
    assert np.allclose(quads[:, :, 2], GRID_Z + 0.05, atol=1e-5)
    assert np.allclose(np.ptp(quads[:, :, 0], axis=1), 0.9 * CELL_M, atol=1e-5)
    assert np.allclose(np.ptp(quads[:, :, 1], axis=1), 0.9 * CELL_M, atol=1e-5)

    colors = mesh.color_attributes[spawn.COVERAGE_COLOR_ATTR]
    assert (colors.domain, colors.data_type) == ("CORNER", "BYTE_COLOR")
    assert mesh.color_attributes.active_color.name == spawn.COVERAGE_COLOR_ATTR
    rgba = np.empty(len(mesh.loops) * 4, dtype=np.float32)
    colors.data.foreach_get("color_srgb", rgba)
    rgba = rgba.reshape(-1, 4)
    start = np.empty(n, dtype=np.int32)
    mesh.polygons.foreach_get("loop_start", start)
    expected = {0: (1, 0, 0), 1: (1, 1, 0), 2: (0, 1, 0)}
    for count, rgb in expected.items():
        face = int(np.flatnonzero(result.n_covered == count)[0])
        corners = rgba[start[face] : start[face] + 4, :3]
        assert np.allclose(corners, rgb, atol=1e-6), count
    four = int(np.flatnonzero(result.n_covered == 4)[0])
    r, g, b_ = rgba[start[four], :3]
    assert r == 0 and b_ == 1  # cyan / blue for three or more

    # The material reads the colour attribute into Base Color.
    tree = mesh.materials[0].node_tree
    (attr,) = [nd for nd in tree.nodes if nd.bl_idname == "ShaderNodeAttribute"]
    assert attr.attribute_name == spawn.COVERAGE_COLOR_ATTR
    link = attr.outputs["Color"].links[0]
    assert link.to_socket.name == "Base Color"


# --- the scene contract ------------------------------------------------------------


def test_everything_in_results_and_nothing_occludes(user_scene):
    before = extract_scene(user_scene)
    old = set(bpy.data.objects)
    results = spawn_results(user_scene, make_result())
    bpy.context.view_layer.update()
    new = set(bpy.data.objects) - old
    assert results.name == names.RESULTS_COLLECTION
    assert user_scene.collection.children[names.RESULTS_COLLECTION] == results
    assert sorted(c.name for c in results.children) == sorted(spawn.GROUP_COLLECTIONS)
    assert new == set(results.all_objects)
    # 4 cameras, 4 frusta, 3 footprints, 2 masts, 1 coverage map
    assert len(new) == 14
    assert all(o.get(names.IGNORE_PROP) is True for o in new)
    after = extract_scene(user_scene)
    assert after.occluders == before.occluders == ("Ground", "Wall")
    assert np.array_equal(after.faces, before.faces)
    assert np.array_equal(after.vertices, before.vertices)


def test_spawning_twice_replaces_and_leaves_no_orphans(user_scene):
    users = snapshot()
    matrices = user_matrices()
    result = make_result()
    spawn_results(user_scene, result)
    first = snapshot()
    counts = {k: len(getattr(bpy.data, k)) for k in ("objects", "meshes", "cameras", "materials")}
    spawn_results(user_scene, result)
    again = {k: len(getattr(bpy.data, k)) for k in counts}
    assert again == counts
    assert snapshot() == first  # same names too: nothing suffixed ".001"
    bpy.context.view_layer.update()
    for name, m in matrices.items():
        assert [list(r) for r in bpy.data.objects[name].matrix_world] == m
    assert set(users["objects"]) <= set(first["objects"])


def test_remove_results_leaves_exactly_the_users_data(user_scene):
    users = snapshot()
    matrices = user_matrices()
    spawn_results(user_scene, make_result())
    remove_results(user_scene)
    assert snapshot() == users
    assert names.RESULTS_COLLECTION not in user_scene.collection.children
    bpy.context.view_layer.update()
    assert user_matrices() == matrices
    remove_results(user_scene)  # nothing to remove: no error
    assert snapshot() == users


def test_name_clashes_and_user_links_survive(user_scene):
    """User data named like ours keeps its name; a user object the user also put in
    the results tree is unlinked from it, not deleted."""
    mine = b.box("Sensor_01", (50, 50, 0), (51, 51, 1))
    mine_mat = bpy.data.materials.new(spawn.FOOTPRINT_MATERIAL)
    mine.data.materials.append(mine_mat)
    users = snapshot()
    spawn_results(user_scene, make_result())
    assert mine.name == "Sensor_01" and mine_mat.name == spawn.FOOTPRINT_MATERIAL
    assert spawned(spawn.SENSORS_COLLECTION)[1].name == "Sensor_01.001"

    bpy.data.collections[spawn.MASTS_COLLECTION].objects.link(bpy.data.objects["Wall"])
    remove_results(user_scene)
    assert snapshot() == users
    assert list(bpy.data.objects["Wall"].users_collection) == [user_scene.collection]
    assert mine.data.materials[0] == mine_mat


# --- speed -------------------------------------------------------------------------


def test_seventeen_thousand_quads_build_fast(user_scene):
    rng = np.random.default_rng(1)
    ij = np.mgrid[0:130, 0:131].reshape(2, -1).T.astype(float)
    pts = np.column_stack([ij * 2.0, rng.uniform(0, 3, len(ij))])
    n_covered = rng.integers(0, 5, len(pts)).astype(np.int32)
    result = replace(
        make_result(),
        points=pts,
        n_covered=n_covered,
        n_visible=n_covered,
        cell_m=2.0,
    )
    t = time.perf_counter()
    spawn_results(user_scene, result)
    elapsed = time.perf_counter() - t
    mesh = bpy.data.objects[spawn.COVERAGE_NAME].data
    assert len(mesh.polygons) == len(pts) == 17030
    assert elapsed < 2.0  # about 0.03 s here; a per-face Python loop takes far longer
