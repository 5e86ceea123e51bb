"""Result -> Blender objects: cameras, frusta, footprints, masts and a coverage map.

Everything goes into one collection, ``names.RESULTS_COLLECTION``, linked to the
scene's master collection, with one child collection per group so the panel can hide
groups. Spawning only ever *adds* data: the user's objects are never modified, renamed
or unlinked, and ``remove_results`` deletes nothing but the results tree and the
datablocks that only it used.

Frames and units
----------------
World metres, Z up, degrees as in ``core.model.sensors``: yaw counter-clockwise from +X,
pitch = depression below the horizon, roll 0. The sensor frame's rows are
``frame(pitch, yaw)`` = forward, left, up. A Blender camera looks along its local -Z
with local +Y up and +X right, so its world rotation has the columns
``(-left, up, -forward)``.

Mesh objects are anchored at a natural point (the sensor, the mast foot, the centre of
the coverage points) and their vertices are stored relative to it: vertex coordinates
are float32, and small local coordinates keep them accurate to micrometres even on
proving grounds kilometres across.

Every spawned object carries ``names.IGNORE_PROP = True`` and lives in the results
tree, so ``extract`` never treats it as an occluder on either count.

One module: the cameras, frusta, footprints, masts and coverage colouring are one
collection, made, replaced and undone together.
"""

from __future__ import annotations

import logging
import math
from collections.abc import Iterable

import bpy
import numpy as np
from mathutils import Matrix
from numpy.typing import NDArray

from .. import names
from ..core.geom.drape import drape
from ..core.model.sensors import SensorModel, frame
from ..core.result import MastRecord, Result, SensorRecord

log = logging.getLogger(__name__)

F64 = NDArray[np.float64]
I32 = NDArray[np.int32]

# Child collections of the results collection, one per group the panel can toggle.
SENSORS_COLLECTION = "AutoSCOOP Sensors"
FRUSTA_COLLECTION = "AutoSCOOP Frusta"
FOOTPRINTS_COLLECTION = "AutoSCOOP Footprints"
MASTS_COLLECTION = "AutoSCOOP Masts"
COVERAGE_COLLECTION = "AutoSCOOP Coverage"
GROUP_COLLECTIONS = (
    SENSORS_COLLECTION,
    FRUSTA_COLLECTION,
    FOOTPRINTS_COLLECTION,
    MASTS_COLLECTION,
    COVERAGE_COLLECTION,
)

# Tags the results collection, so it is found even if Blender had to suffix its name.
RESULTS_TAG = names.RESULTS_TAG

# Custom properties on spawned objects.
SENSOR_PROP = "autoscoop_sensor"
MODEL_PROP = "autoscoop_model"
MAST_PROP = "autoscoop_mast"

# Object names; ``n`` is the record's number.
SENSOR_NAME = "Sensor_{:02d}"
FRUSTUM_NAME = "Frustum_{:02d}"
FOOTPRINT_NAME = "Footprint_{:02d}"
MAST_NAME = "Mast_{:02d}"
COVERAGE_NAME = "Coverage"

# Materials (one per group, shared by its objects).
FOOTPRINT_MATERIAL = "AutoSCOOP Footprint"
MAST_MATERIAL = "AutoSCOOP Mast"
COVERAGE_MATERIAL = "AutoSCOOP Coverage"

# Blender's hard limit on a camera's lens angle is about 172.8 deg (a pinhole can never
# reach 180). 170 deg is the largest round angle below it; a 360 deg lidar's camera gets
# this, and its frustum mesh shows the true field of view.
MAX_CAMERA_ANGLE_DEG = 170.0
# The camera sensor's narrower side (mm); the lens and the other side follow from the FoV.
CAMERA_SENSOR_MM = 36.0

# Frustum far cap: at most this many degrees between neighbouring sample directions.
FRUSTUM_STEP_DEG = 10.0

# Footprints: the lift (m) above the ground that keeps them from z-fighting with it.
FOOTPRINT_LIFT_M = 0.15
FOOTPRINT_RGBA = (0.10, 0.80, 0.20, 0.40)
# Each sensor kind its own footprint and frustum colour (a camera's: the ones above),
# and its own footprint material (``FOOTPRINT_MATERIAL`` + " lidar", ...).
KIND_FOOTPRINT_RGBA = {
    "camera": FOOTPRINT_RGBA,
    "lidar": (0.10, 0.35, 0.95, 0.40),
    "radar": (0.85, 0.20, 0.75, 0.40),
}

MAST_RADIUS_M = 0.15
MAST_SIDES = 12
MAST_RGBA = (0.35, 0.02, 0.02, 1.0)

# Coverage map: quad edge as a fraction of the grid cell, lift above the point (m).
COVERAGE_QUAD_FRACTION = 0.9
COVERAGE_LIFT_M = 0.05
COVERAGE_ATTR = "autoscoop_sensors"  # INT, FACE domain: n_covered
COVERAGE_COLOR_ATTR = "coverage"  # BYTE_COLOR, CORNER domain
# sRGB colour by n_covered = 0, 1, 2, >= 3.
COVERAGE_PALETTE = np.array(
    [
        (1.0, 0.0, 0.0, 1.0),  # red: not covered
        (1.0, 1.0, 0.0, 1.0),  # yellow: one sensor
        (0.0, 1.0, 0.0, 1.0),  # green: two sensors
        (0.0, 1.0, 1.0, 1.0),  # cyan: three or more
    ],
    dtype=np.float32,
)

FRUSTUM_RGBA = (1.0, 0.6, 0.0, 1.0)
KIND_FRUSTUM_RGBA = {
    "camera": FRUSTUM_RGBA,
    "lidar": (0.20, 0.60, 1.00, 1.0),
    "radar": (0.90, 0.30, 0.90, 1.0),
}


# --- public API --------------------------------------------------------------------


def spawn_results(scene: bpy.types.Scene, result: Result) -> bpy.types.Collection:
    """Replace the results collection with one built from ``result``; return it.

    Footprints are the core's draped meshes (``SensorRecord.drape``); one without a
    drape lies flat at its sensor's mast foot (``z - height_m``). Footprints float
    ``FOOTPRINT_LIFT_M`` above the ground. Nothing here casts a ray.
    """
    _check_result(result)
    remove_results(scene)
    results = _new_collection(names.RESULTS_COLLECTION, scene.collection.children)
    results[RESULTS_TAG] = True
    groups = {name: _new_collection(name, results.children) for name in GROUP_COLLECTIONS}

    footprint_mats = {
        kind: _flat_material(
            FOOTPRINT_MATERIAL if kind == "camera" else f"{FOOTPRINT_MATERIAL} {kind}", rgba
        )
        for kind, rgba in KIND_FOOTPRINT_RGBA.items()
        if any(rec.model.kind == kind for rec in result.sensors) or kind == "camera"
    }
    mast_mat = _flat_material(MAST_MATERIAL, MAST_RGBA)

    for rec in result.sensors:
        _link(groups[SENSORS_COLLECTION], _sensor_object(rec))
        _link(groups[FRUSTA_COLLECTION], _frustum_object(rec))
        footprint = _footprint_object(rec, footprint_mats[rec.model.kind])
        if footprint is not None:
            _link(groups[FOOTPRINTS_COLLECTION], footprint)
    for mast in result.masts:
        _link(groups[MASTS_COLLECTION], _mast_object(mast, mast_mat))
    if len(result.points):
        _link(groups[COVERAGE_COLLECTION], _coverage_object(result))

    # A material nobody ended up using (e.g. every footprint empty) would be an orphan.
    for mat in (*footprint_mats.values(), mast_mat):
        if mat.users == 0:
            bpy.data.materials.remove(mat)
    log.info(
        "spawned %d sensors, %d masts, %d coverage points into %r",
        len(result.sensors),
        len(result.masts),
        len(result.points),
        results.name,
    )
    return results


def remove_results(scene: bpy.types.Scene) -> None:
    """Delete the results collection, its child collections, their objects and the
    datablocks only they used (meshes, cameras, materials) — nothing else.

    An object that is also linked to a collection outside the results tree (the user
    put it there) is only unlinked from the tree, not deleted.
    """
    root = find_results(scene)
    if root is None:
        return
    tree = _collection_tree(root)
    tree_ids = {c.as_pointer() for c in tree}
    doomed: list[bpy.types.Object] = []
    seen: set[int] = set()
    for coll in tree:
        for obj in list(coll.objects):
            if obj.as_pointer() in seen:
                continue
            seen.add(obj.as_pointer())
            outside = [c for c in obj.users_collection if c.as_pointer() not in tree_ids]
            if outside:
                for c in tree:
                    if c.objects.get(obj.name) == obj:
                        c.objects.unlink(obj)
            else:
                doomed.append(obj)

    data = [o.data for o in doomed if o.data is not None]
    materials = [s.material for o in doomed for s in o.material_slots if s.material is not None]
    materials += [m for d in data if hasattr(d, "materials") for m in d.materials if m is not None]

    bpy.data.batch_remove(doomed)
    _remove_unused(data)
    _remove_unused(materials)
    bpy.data.batch_remove(tree)


def find_results(scene: bpy.types.Scene) -> bpy.types.Collection | None:
    """The scene's results collection (a direct child of its master collection)."""
    for coll in scene.collection.children:
        if coll.name == names.RESULTS_COLLECTION or coll.get(RESULTS_TAG):
            return coll
    return None


# --- sensors -----------------------------------------------------------------------


def camera_rotation(pitch_deg: float, yaw_deg: float) -> F64:
    """(3, 3) world rotation of a Blender camera looking along the sensor's forward.

    Columns are the camera's local X (right = -left), Y (up) and Z (-forward) in world
    coordinates; a proper rotation because forward x left = up.
    """
    forward, left, up = frame(pitch_deg, yaw_deg)
    return np.column_stack([-left, up, -forward])


def camera_angles_deg(model: SensorModel) -> tuple[float, float]:
    """Horizontal and vertical lens angles (deg) for a model, capped at
    ``MAX_CAMERA_ANGLE_DEG`` (a pinhole cannot show 180 deg or more)."""
    return min(model.h_fov_deg, MAX_CAMERA_ANGLE_DEG), min(model.v_fov_deg, MAX_CAMERA_ANGLE_DEG)


def sensor_camera(
    n: int, position: Iterable[float], pitch_deg: float, yaw_deg: float, model: SensorModel
) -> bpy.types.Object:
    """A camera at ``position`` (world m) looking along the sensor's forward, lens
    matching the model's FoV; named and tagged as sensor ``n``.

    The lens and the sensor width/height are chosen so that ``angle_x`` and ``angle_y``
    both equal the (capped) FoV, the narrower side of the sensor being
    ``CAMERA_SENSOR_MM`` (Blender keeps both sides >= 1 mm); ``sensor_fit`` names the
    wider axis, which Blender keeps exact while the other follows the scene's render
    aspect (left untouched).
    """
    name = SENSOR_NAME.format(n)
    cam = bpy.data.cameras.new(name)
    h_deg, v_deg = camera_angles_deg(model)
    th, tv = math.tan(math.radians(h_deg) / 2), math.tan(math.radians(v_deg) / 2)
    cam.lens = CAMERA_SENSOR_MM / (2 * min(th, tv))
    cam.sensor_width = 2 * cam.lens * th
    cam.sensor_height = 2 * cam.lens * tv
    cam.sensor_fit = "HORIZONTAL" if h_deg >= v_deg else "VERTICAL"
    cam.clip_start = min(0.1, model.range_m / 100)
    cam.clip_end = model.range_m
    cam.display_size = 1.5

    obj = bpy.data.objects.new(name, cam)
    obj.matrix_world = _matrix(camera_rotation(pitch_deg, yaw_deg), position)
    obj[SENSOR_PROP] = int(n)
    obj["pitch_deg"] = float(pitch_deg)
    obj["yaw_deg"] = float(yaw_deg)
    obj[MODEL_PROP] = model.to_dict()
    return obj


def _sensor_object(rec: SensorRecord) -> bpy.types.Object:
    """The camera of a placed sensor, with its figures as custom properties."""
    obj = sensor_camera(rec.n, (rec.x, rec.y, rec.z), rec.pitch_deg, rec.yaw_deg, rec.model)
    obj["height_m"] = float(rec.height_m)
    obj["mast"] = int(rec.mast)
    obj["fitness"] = float(rec.fitness)
    obj["covered_target_m2"] = float(rec.covered_target_m2)
    obj["footprint_m2"] = float(rec.footprint_m2)
    obj["existing"] = rec.existing  # it stood before the plan
    return obj


# --- frusta ------------------------------------------------------------------------


def frustum_directions(model: SensorModel, step_deg: float = FRUSTUM_STEP_DEG) -> F64:
    """(R, C, 3) unit directions in the sensor frame over the FoV's closed boundary grid.

    Rows run bottom to top (elevation / image v), columns right to left (azimuth /
    image u), the corners on the FoV's edge. ``angular``: azimuth a in [-h/2, h/2],
    elevation b in [-v/2, v/2], d = (cos b cos a, cos b sin a, sin b); a full 360 deg
    turn leaves out the last column (it equals the first). ``pinhole``: points of the
    image plane at focal length 1, normalised.
    """
    ha, va = math.radians(model.h_fov_deg) / 2, math.radians(model.v_fov_deg) / 2
    cols = max(2, math.ceil(model.h_fov_deg / step_deg)) + 1
    rows = max(2, math.ceil(model.v_fov_deg / step_deg)) + 1
    if model.pattern == "angular":
        a = np.linspace(-ha, ha, cols)
        if _full_turn(model):
            a = a[:-1]
        b = np.linspace(-va, va, rows)
        bb, aa = np.meshgrid(b, a, indexing="ij")
        return np.stack([np.cos(bb) * np.cos(aa), np.cos(bb) * np.sin(aa), np.sin(bb)], -1)
    u = np.linspace(-math.tan(ha), math.tan(ha), cols)
    v = np.linspace(-math.tan(va), math.tan(va), rows)
    vv, uu = np.meshgrid(v, u, indexing="ij")
    d = np.stack([np.ones_like(uu), uu, vv], axis=-1)
    return d / np.linalg.norm(d, axis=-1, keepdims=True)


def frustum_geometry(model: SensorModel, pitch_deg: float, yaw_deg: float) -> tuple[F64, I32]:
    """The FoV volume clipped at the range, relative to the sensor, world axes.

    Returns vertices (V, 3) m — vertex 0 is the apex (the origin), the rest the far
    cap at ``range_m`` on ``frustum_directions`` — and faces (F, 3) int: the cap's grid
    cells split into triangles plus fans from the apex to the cap's border, wound so
    normals point out. A 360 deg lidar gives a closed ring band (top and bottom cones
    and a spherical belt, no side walls).
    """
    d = frustum_directions(model)
    rows, cols = d.shape[:2]
    world = d.reshape(-1, 3) @ frame(pitch_deg, yaw_deg)  # sensor -> world axes
    verts = np.vstack([np.zeros((1, 3)), model.range_m * world])
    idx = 1 + np.arange(rows * cols).reshape(rows, cols)
    wrap = _full_turn(model)
    if wrap:
        idx = np.hstack([idx, idx[:, :1]])  # close the ring

    # Cap: quad (r, c) -> (r, c+1) -> (r+1, c+1) -> (r+1, c) is counter-clockwise seen
    # from outside (left x up = forward), split into two triangles.
    a, b = idx[:-1, :-1].ravel(), idx[:-1, 1:].ravel()
    c, e = idx[1:, 1:].ravel(), idx[1:, :-1].ravel()
    faces = [np.stack([a, b, c], 1), np.stack([a, c, e], 1)]

    def fan(border: I32) -> I32:
        """Triangles apex -> border[k] -> border[k+1]."""
        return np.stack([np.zeros(len(border) - 1, int), border[:-1], border[1:]], 1)

    faces.append(fan(idx[-1]))  # top: normal points up
    faces.append(fan(idx[0][::-1]))  # bottom
    if not wrap:
        faces.append(fan(idx[:, 0]))  # right side (azimuth -h/2)
        faces.append(fan(idx[::-1, -1]))  # left side
    return verts, np.concatenate(faces).astype(np.int32)


def _full_turn(model: SensorModel) -> bool:
    return model.pattern == "angular" and model.h_fov_deg >= 360.0 - 1e-9


def _frustum_object(rec: SensorRecord) -> bpy.types.Object:
    """Wireframe FoV volume of one sensor, origin at the sensor; hidden in renders."""
    verts, faces = frustum_geometry(rec.model, rec.pitch_deg, rec.yaw_deg)
    name = FRUSTUM_NAME.format(rec.n)
    obj = bpy.data.objects.new(name, _build_mesh(name, verts, faces.ravel(), 3))
    obj.matrix_world = _matrix(np.eye(3), (rec.x, rec.y, rec.z))
    obj.display_type = "WIRE"
    obj.hide_render = True
    obj.color = KIND_FRUSTUM_RGBA[rec.model.kind]
    obj[SENSOR_PROP] = int(rec.n)
    return obj


# --- footprints --------------------------------------------------------------------


def _footprint_object(rec: SensorRecord, material: bpy.types.Material) -> bpy.types.Object | None:
    """The sensor's footprint on the ground, or None if it is empty."""
    if rec.footprint is None or rec.footprint.is_empty:
        return None
    foot_z = rec.z - rec.height_m
    xyz, tris = rec.drape or drape(rec.footprint, lambda xy: np.full(len(xy), foot_z))
    if len(tris) == 0:
        return None
    anchor = np.array([rec.x, rec.y, foot_z])
    verts = xyz + (0.0, 0.0, FOOTPRINT_LIFT_M) - anchor
    name = FOOTPRINT_NAME.format(rec.n)
    mesh = _build_mesh(name, verts, tris.ravel(), 3)
    mesh.materials.append(material)
    obj = bpy.data.objects.new(name, mesh)
    obj.matrix_world = _matrix(np.eye(3), anchor)
    obj.color = KIND_FOOTPRINT_RGBA[rec.model.kind]
    obj[SENSOR_PROP] = int(rec.n)
    obj["footprint_m2"] = float(rec.footprint_m2)
    return obj


# --- masts -------------------------------------------------------------------------


def mast_geometry(height_m: float) -> tuple[F64, I32, I32]:
    """A closed vertical cylinder from z = 0 to ``height_m``, radius ``MAST_RADIUS_M``.

    Returns vertices (2 * MAST_SIDES, 3) m (bottom ring then top ring), the flat corner
    list and the corner count per face (side quads, then bottom and top caps).
    """
    t = np.linspace(0.0, 2 * math.pi, MAST_SIDES, endpoint=False)
    ring = MAST_RADIUS_M * np.column_stack([np.cos(t), np.sin(t)])
    verts = np.vstack(
        [
            np.column_stack([ring, np.zeros(MAST_SIDES)]),
            np.column_stack([ring, np.full(MAST_SIDES, height_m)]),
        ]
    )
    k = np.arange(MAST_SIDES)
    k1 = (k + 1) % MAST_SIDES
    sides = np.stack([k, k1, k1 + MAST_SIDES, k + MAST_SIDES], 1).ravel()
    bottom = k[::-1]  # clockwise from above: normal down
    top = k + MAST_SIDES
    corners = np.concatenate([sides, bottom, top]).astype(np.int32)
    sizes = np.array([4] * MAST_SIDES + [MAST_SIDES, MAST_SIDES], dtype=np.int32)
    return verts, corners, sizes


def _mast_object(mast: MastRecord, material: bpy.types.Material) -> bpy.types.Object:
    """A dark red pole standing on the mast foot."""
    verts, corners, sizes = mast_geometry(mast.height_m)
    name = MAST_NAME.format(mast.n)
    mesh = _build_mesh(name, verts, corners, sizes)
    mesh.materials.append(material)
    obj = bpy.data.objects.new(name, mesh)
    obj.matrix_world = _matrix(np.eye(3), (mast.x, mast.y, mast.z_ground))
    obj.color = MAST_RGBA
    obj[MAST_PROP] = int(mast.n)
    obj["height_m"] = float(mast.height_m)
    obj["sensors"] = [int(s) for s in mast.sensors]
    obj["existing"] = mast.existing  # it stood before the plan
    return obj


# --- coverage ----------------------------------------------------------------------


def coverage_colors(n_covered: NDArray[np.integer]) -> NDArray[np.float32]:
    """(N, 4) sRGB RGBA per count: 0 red, 1 yellow, 2 green, >= 3 cyan."""
    return COVERAGE_PALETTE[np.clip(np.asarray(n_covered), 0, len(COVERAGE_PALETTE) - 1)]


def _coverage_object(result: Result) -> bpy.types.Object:
    """One horizontal quad per target point, coloured by how many sensors cover it.

    Built with ``foreach_set`` on flat arrays; no per-face Python.
    """
    pts = np.asarray(result.points, dtype=float)
    n = len(pts)
    anchor = np.round(pts.mean(axis=0))
    half = COVERAGE_QUAD_FRACTION * result.cell_m / 2
    square = half * np.array([[-1, -1, 0], [1, -1, 0], [1, 1, 0], [-1, 1, 0]], float)
    centres = pts - anchor + np.array([0.0, 0.0, COVERAGE_LIFT_M])
    verts = (centres[:, None, :] + square[None]).reshape(-1, 3)
    mesh = _build_mesh(COVERAGE_NAME, verts, np.arange(4 * n, dtype=np.int32), 4)

    counts = np.asarray(result.n_covered, dtype=np.int32)
    attr = mesh.attributes.new(COVERAGE_ATTR, "INT", "FACE")
    attr.data.foreach_set("value", counts)
    colors = mesh.color_attributes.new(COVERAGE_COLOR_ATTR, "BYTE_COLOR", "CORNER")
    colors.data.foreach_set("color_srgb", np.repeat(coverage_colors(counts), 4, axis=0).ravel())
    mesh.color_attributes.active_color = colors
    mesh.color_attributes.render_color_index = _color_index(mesh, colors.name)
    mesh.materials.append(_coverage_material())

    obj = bpy.data.objects.new(COVERAGE_NAME, mesh)
    obj.matrix_world = _matrix(np.eye(3), anchor)
    obj["cell_m"] = float(result.cell_m)
    obj["coverage_fraction"] = result.coverage_fraction
    return obj


def _color_index(mesh: bpy.types.Mesh, name: str) -> int:
    return next(i for i, a in enumerate(mesh.color_attributes) if a.name == name)


def _coverage_material() -> bpy.types.Material:
    """Base Color from the ``coverage`` colour attribute (Material Preview, render)."""
    mat = bpy.data.materials.new(COVERAGE_MATERIAL)
    tree = _node_tree(mat)
    bsdf = _principled(tree)
    node = tree.nodes.new("ShaderNodeAttribute")
    node.attribute_type = "GEOMETRY"
    node.attribute_name = COVERAGE_COLOR_ATTR
    node.location = (bsdf.location.x - 300, bsdf.location.y)
    tree.links.new(node.outputs["Color"], bsdf.inputs["Base Color"])
    return mat


# --- Blender helpers ---------------------------------------------------------------


def _build_mesh(name: str, verts: F64, corners: I32, sizes: int | I32) -> bpy.types.Mesh:
    """A mesh from vertices (V, 3), the flat corner list and the corners per face
    (an int for uniform faces or an (F,) array), filled with ``foreach_set``."""
    corners = np.asarray(corners, dtype=np.int32)
    if np.isscalar(sizes):
        sizes = np.full(len(corners) // int(sizes), int(sizes), dtype=np.int32)
    sizes = np.asarray(sizes, dtype=np.int32)
    mesh = bpy.data.meshes.new(name)
    mesh.vertices.add(len(verts))
    mesh.vertices.foreach_set("co", np.asarray(verts, dtype=np.float32).ravel())
    mesh.loops.add(len(corners))
    mesh.loops.foreach_set("vertex_index", corners)
    mesh.polygons.add(len(sizes))
    starts = np.concatenate([[0], np.cumsum(sizes)[:-1]]).astype(np.int32)
    mesh.polygons.foreach_set("loop_start", starts)
    mesh.update(calc_edges=True)
    return mesh


def _flat_material(name: str, rgba: tuple[float, float, float, float]) -> bpy.types.Material:
    """A material of one colour: viewport display colour and Principled BSDF; alpha
    below 1 makes it blend (EEVEE) rather than hide what lies under it."""
    mat = bpy.data.materials.new(name)
    mat.diffuse_color = rgba
    bsdf = _principled(_node_tree(mat))
    bsdf.inputs["Base Color"].default_value = rgba
    if rgba[3] < 1.0:
        bsdf.inputs["Alpha"].default_value = rgba[3]
        if hasattr(mat, "surface_render_method"):
            mat.surface_render_method = "BLENDED"
    return mat


def _node_tree(mat: bpy.types.Material) -> bpy.types.NodeTree:
    # Blender 5 gives every new material a node tree; 4.x needs use_nodes switched on.
    if mat.node_tree is None:
        mat.use_nodes = True
    return mat.node_tree


def _principled(tree: bpy.types.NodeTree) -> bpy.types.Node:
    for node in tree.nodes:
        if node.bl_idname == "ShaderNodeBsdfPrincipled":
            return node
    bsdf = tree.nodes.new("ShaderNodeBsdfPrincipled")
    out = next((n for n in tree.nodes if n.bl_idname == "ShaderNodeOutputMaterial"), None)
    if out is None:
        out = tree.nodes.new("ShaderNodeOutputMaterial")
    tree.links.new(bsdf.outputs["BSDF"], out.inputs["Surface"])
    return bsdf


def _new_collection(
    name: str, parent_children: bpy.types.bpy_prop_collection
) -> bpy.types.Collection:
    coll = bpy.data.collections.new(name)
    if coll.name != name:
        # Another scene's results (or a user's collection) holds the name.
        log.warning("collection name %r is taken; results go into %r", name, coll.name)
    parent_children.link(coll)
    return coll


def _link(coll: bpy.types.Collection, obj: bpy.types.Object) -> None:
    obj[names.IGNORE_PROP] = True
    coll.objects.link(obj)


def _matrix(rot: F64, loc: Iterable[float]) -> Matrix:
    """4 x 4 world matrix from a rotation (3, 3) and a location (3,) m.

    Assigned to ``matrix_world`` (not ``location``) so that it is readable at once,
    before any depsgraph update; Blender also stores it as location and rotation.
    """
    m = np.eye(4)
    m[:3, :3] = rot
    m[:3, 3] = list(loc)
    return Matrix(m.tolist())


def _collection_tree(root: bpy.types.Collection) -> list[bpy.types.Collection]:
    """``root`` and all collections below it, each once, parents first."""
    out, seen, todo = [], set(), [root]
    while todo:
        coll = todo.pop(0)
        if coll.as_pointer() in seen:
            continue
        seen.add(coll.as_pointer())
        out.append(coll)
        todo.extend(coll.children)
    return out


def _remove_unused(ids: Iterable[bpy.types.ID]) -> None:
    """Delete the datablocks of ``ids`` that nothing uses any more."""
    unique = {i.as_pointer(): i for i in ids}
    orphans = [i for i in unique.values() if i.users == 0]
    if orphans:
        bpy.data.batch_remove(orphans)


def _check_result(result: Result) -> None:
    n = len(result.points)
    if result.points.shape not in ((n, 3), (0,)) or len(result.n_covered) != n:
        raise ValueError(
            f"result has points of shape {result.points.shape} and "
            f"{len(result.n_covered)} n_covered values"
        )
    if n and not result.cell_m > 0:
        raise ValueError(f"result cell_m {result.cell_m} must be > 0")
