"""An oblique picture of the results, rendered by Blender's Workbench engine.

``render_view(scene)`` returns the PNG bytes of a view from the south-west, looking
``VIEW_ELEVATION_DEG`` down on the target areas and the results: terrain, occluders,
the coverage map in its colours, footprints, masts, the sensors and their frusta.

The scene is not touched. The render happens in a temporary scene that links the
user's collections and objects (so it shows them as they are) and adds what only the
picture needs: an orthographic camera, a world colour, and overlay meshes, because
Workbench draws neither cameras nor wireframes. Footprints are drawn as a faint fill
with an outline, sensors as small solid pyramids along their field of view, and frusta
as the edges through its corners, down to the ground; line widths and pyramid sizes
are in pixels, so they read the same on any scene size. Every
datablock the render made (the temporary scene and its objects, meshes, materials,
world, camera and the "Render Result" image) is deleted before returning, also on
failure.

Colours: the shading's colour type is ``VERTEX`` ("Attribute"), so the coverage mesh
shows its ``coverage`` colour attribute and every other object its material's
viewport colour (``Material.diffuse_color``: spawn's footprint and mast colours, the
overlays' own). The view transform is "Standard": colours come out as given.

Frames and units: world metres, Z up; the view camera stands at azimuth
``VIEW_AZIMUTH_DEG`` (counter-clockwise from +X) of the framed box's centre.
"""

from __future__ import annotations

import logging
import math
import tempfile
from collections.abc import Callable, Iterable, Iterator
from contextlib import contextmanager
from pathlib import Path

import bpy
import numpy as np
from mathutils import Matrix
from numpy.typing import NDArray

from .. import names
from ..core.model.sensors import SensorModel, frame
from . import spawn
from .extract import area_role

log = logging.getLogger(__name__)

F64 = NDArray[np.float64]
I32 = NDArray[np.int32]

VIEW_SIZE = (1600, 1000)  # px
VIEW_AZIMUTH_DEG = 225.0  # the camera stands south-west of the framed box
VIEW_ELEVATION_DEG = 50.0  # how steeply it looks down
VIEW_MARGIN = 1.06  # the framed box's extent times this fills the picture
BACKGROUND_RGB = (0.70, 0.72, 0.76)  # linear
# Workbench's studio light, fixed to the view: "outdoor" lights upward faces brightly
# from above, so the coverage colours stay clear and walls still show their sides.
STUDIO_LIGHT = "outdoor.sl"

LINE_PX = 2.0  # footprint outline width
FRUSTUM_PX = 1.5  # frustum edge width
SENSOR_PX = 22.0  # length of a sensor's pyramid
SENSOR_RGBA = (0.05, 0.05, 0.05, 1.0)
FOOTPRINT_FILL_ALPHA = 0.12
FOOTPRINT_LINE_LIFT_M = 0.05  # outlines float this far above the (lifted) footprint

VIEW_NAME = "AutoSCOOP View"


def render_view(scene: bpy.types.Scene, size: tuple[int, int] = VIEW_SIZE) -> bytes:
    """PNG bytes of the oblique view of ``scene`` and its results collection.

    Raises ValueError if the scene has no results collection, RuntimeError if Blender
    cannot render.
    """
    results = spawn.find_results(scene)
    if results is None:
        raise ValueError(f"scene {scene.name!r} has no results to render")
    width, height = size
    pts = _framed_points(scene, results)
    rot, look_at, scale = _framing(pts, width / height)
    px = scale / width  # metres per pixel
    groups = {c.name.split(".")[0]: c for c in results.children}
    sensors = _sensor_cameras(groups.get(spawn.SENSORS_COLLECTION))
    reach = max([float(o.data.clip_end) for o in sensors] + [0.0])
    distance = float(np.ptp(pts, axis=0).max()) * 2 + reach + 10.0

    with _temporary() as new:
        view = new(bpy.data.scenes.new(VIEW_NAME))
        for child in scene.collection.children:
            view.collection.children.link(child)
        for obj in scene.collection.objects:
            view.collection.objects.link(obj)
        _copy_exclusion(scene.view_layers[0].layer_collection, view.view_layers[0].layer_collection)
        _add_overlays(view, new, groups, sensors, pts, px)

        cam = new(bpy.data.cameras.new(VIEW_NAME))
        cam.type = "ORTHO"
        cam.sensor_fit = "HORIZONTAL"
        cam.ortho_scale = scale
        cam.clip_start = 0.1
        cam.clip_end = 2 * distance
        cam_obj = new(bpy.data.objects.new(VIEW_NAME, cam))
        cam_obj.matrix_world = Matrix(_homogeneous(rot, look_at + rot[:, 2] * distance).tolist())
        view.collection.objects.link(cam_obj)
        view.camera = cam_obj
        world = new(bpy.data.worlds.new(VIEW_NAME))
        world.color = BACKGROUND_RGB
        view.world = world
        _settings(view, width, height)
        log.info("view of %.0f m across, %d x %d px", scale, width, height)

        with tempfile.TemporaryDirectory() as tmp:
            path = Path(tmp) / "view.png"
            view.render.filepath = str(path)
            bpy.ops.render.render(write_still=True, scene=view.name)
            if not path.is_file():
                raise RuntimeError("Blender wrote no image")
            return path.read_bytes()


def _add_overlays(
    view: bpy.types.Scene,
    new: Callable,
    groups: dict[str, bpy.types.Collection],
    sensors: list[bpy.types.Object],
    pts: F64,
    px: float,
) -> None:
    """Footprint fills and outlines, frustum edges and sensor pyramids, in the view
    scene only; the footprints' and frusta's own groups are left out of its view layer.
    A group the user hid from renders (the panel's toggles) gets no overlay."""

    def add(name: str, verts: F64, faces: I32, rgba: tuple[float, ...]) -> None:
        if len(faces) == 0:
            return
        mesh = new(_mesh(name, verts, faces))
        mesh.materials.append(new(_material(name, rgba)))
        view.collection.objects.link(new(bpy.data.objects.new(name, mesh)))

    footprints = groups.get(spawn.FOOTPRINTS_COLLECTION)
    if footprints is not None:
        _exclude(view, footprints)
    if footprints is not None and not footprints.hide_render:
        fill = new(_material("Footprint fill", (*spawn.FOOTPRINT_RGBA[:3], FOOTPRINT_FILL_ALPHA)))
        for obj in footprints.all_objects:
            if obj.type == "MESH" and obj.material_slots:
                # Shares the footprint's mesh; its own material slot overrides the colour.
                copy = new(bpy.data.objects.new(f"{obj.name} fill", obj.data))
                copy.matrix_world = obj.matrix_world
                copy.material_slots[0].link = "OBJECT"
                copy.material_slots[0].material = fill
                view.collection.objects.link(copy)
        radius = LINE_PX * px / 2
        edges = _outline_segments(footprints.all_objects)
        edges += (0.0, 0.0, FOOTPRINT_LINE_LIFT_M + radius)
        add("Footprint outlines", *_tubes(edges, radius), (*spawn.FOOTPRINT_RGBA[:3], 1.0))

    frusta = groups.get(spawn.FRUSTA_COLLECTION)
    if frusta is not None:
        _exclude(view, frusta)
    if sensors and (frusta is None or not frusta.hide_render):
        # Cut to the framed box (a little wider): edges running far off into the
        # distance only clutter the picture.
        lo, hi = pts.min(axis=0), pts.max(axis=0)
        pad = np.array([0.05, 0.05, 0.0]) * float(np.ptp(pts[:, :2], axis=0).max())
        edges = np.concatenate([_frustum_edges(o) for o in sensors])
        edges = _clipped(edges, lo - pad - (0, 0, 1), hi + pad)
        add("Frustum edges", *_tubes(edges, FRUSTUM_PX * px / 2), spawn.FRUSTUM_RGBA)
    if sensors:
        add("Sensors", *_pyramids(sensors, SENSOR_PX * px), SENSOR_RGBA)


# --- framing -----------------------------------------------------------------------


def _framed_points(scene: bpy.types.Scene, results: bpy.types.Collection) -> F64:
    """(N, 3) world points the view frames: the results' mesh vertices and sensor
    positions (not the frusta, which reach far past what matters) and the corners of
    the target areas' bounding boxes; the whole scene's if there are none."""
    frusta = [
        c for c in results.children_recursive if c.name.split(".")[0] == spawn.FRUSTA_COLLECTION
    ]
    skip = {o.as_pointer() for c in frusta for o in c.all_objects}
    objs = [o for o in results.all_objects if o.as_pointer() not in skip]
    objs += [o for o in scene.objects if area_role(o) == names.ROLE_TARGET]
    pts = _points(objs)
    if len(pts) == 0:
        pts = _points(scene.objects)
    return pts if len(pts) else np.array([[-1.0, -1, -1], [1, 1, 1]])


def _points(objs: Iterable[bpy.types.Object]) -> F64:
    """(N, 3) world points of objects: a mesh's vertices, a camera's position, the
    corners of any other geometry's bounding box."""
    out = []
    for obj in objs:
        m = np.array(obj.matrix_world)
        if obj.type == "CAMERA":
            out.append(m[None, :3, 3])
            continue
        if obj.type == "MESH":
            local = np.empty(3 * len(obj.data.vertices))
            obj.data.vertices.foreach_get("co", local)
        elif obj.type in ("CURVE", "SURFACE", "FONT", "META"):
            local = np.array([tuple(c) for c in obj.bound_box], float)
        else:
            continue
        out.append(local.reshape(-1, 3) @ m[:3, :3].T + m[:3, 3])
    return np.concatenate(out) if out else np.zeros((0, 3))


def _framing(pts: F64, aspect: float) -> tuple[F64, F64, float]:
    """The view's rotation (``_view_rotation``), the point it looks at (the centre of
    the points' outline in the picture) and its orthographic scale (m across), so
    the points fill the picture of ``aspect`` = width / height with a margin."""
    rot = _view_rotation()
    u, v, w = pts @ rot[:, 0], pts @ rot[:, 1], pts @ rot[:, 2]
    scale = VIEW_MARGIN * max(float(np.ptp(u)), float(np.ptp(v)) * aspect, 1.0)
    look_at = rot @ np.array([(u.max() + u.min()) / 2, (v.max() + v.min()) / 2, w.mean()])
    return rot, look_at, scale


def _view_rotation() -> F64:
    """(3, 3) columns right, up, back (the camera's local X, Y, Z) of the view."""
    az, el = math.radians(VIEW_AZIMUTH_DEG), math.radians(VIEW_ELEVATION_DEG)
    back = np.array([math.cos(el) * math.cos(az), math.cos(el) * math.sin(az), math.sin(el)])
    right = np.cross((0.0, 0.0, 1.0), back)
    right /= np.linalg.norm(right)
    return np.column_stack([right, np.cross(back, right), back])


def _homogeneous(rot: F64, loc: F64) -> F64:
    m = np.eye(4)
    m[:3, :3], m[:3, 3] = rot, loc
    return m


# --- overlays ----------------------------------------------------------------------


def _sensor_cameras(coll: bpy.types.Collection | None) -> list[bpy.types.Object]:
    if coll is None or coll.hide_render:
        return []
    return [o for o in coll.all_objects if o.type == "CAMERA" and spawn.MODEL_PROP in o]


def _sensor_model(obj: bpy.types.Object) -> SensorModel:
    return SensorModel.from_spec(obj[spawn.MODEL_PROP].to_dict(), obj.name)


def _frustum_edges(obj: bpy.types.Object) -> F64:
    """(K, 2, 3) world segments: a sensor's frustum edges (from the sensor along the
    corners of its field of view; a 360 deg lidar: its lower and upper rims at four
    azimuths), each ending at its range or where it sinks below the mast foot; one
    that never sinks (it points at the horizon or above) stops after the mast's height."""
    model = _sensor_model(obj)
    d = _corner_directions(model) @ frame(obj["pitch_deg"], obj["yaw_deg"])
    apex = np.array(obj.matrix_world.translation)
    drop = float(obj.get("height_m", apex[2]))
    with np.errstate(divide="ignore"):
        to_foot = np.where(d[:, 2] < 0, drop / -d[:, 2], drop)
    length = np.minimum(model.range_m, to_foot)[:, None]
    return np.stack([np.broadcast_to(apex, d.shape), apex + length * d], axis=1)


def _corner_directions(model: SensorModel) -> F64:
    """(K, 3) unit directions in the sensor frame: the field of view's four corners
    (a 360 deg lidar: its lower and upper rims at four azimuths, K = 8)."""
    d = spawn.frustum_directions(model)
    if _full_turn(model):
        cols = np.linspace(0, d.shape[1], 4, endpoint=False).astype(int)
        return np.concatenate([d[0, cols], d[-1, cols]])
    return np.array([d[0, 0], d[0, -1], d[-1, -1], d[-1, 0]])


def _full_turn(model: SensorModel) -> bool:
    return model.pattern == "angular" and model.h_fov_deg >= 360.0 - 1e-9


def _pyramids(sensors: list[bpy.types.Object], length: float) -> tuple[F64, I32]:
    """Small solid pyramids, apex at each sensor, opening along its field of view
    (a 360 deg lidar: a diamond round its position); vertices (V, 3), quads (F, 4)."""
    verts: list[F64] = []
    faces: list[I32] = []
    start = 0
    for obj in sensors:
        model = _sensor_model(obj)
        apex = np.array(obj.matrix_world.translation)
        rows = frame(obj["pitch_deg"], obj["yaw_deg"])
        if _full_turn(model):
            t = np.linspace(0, 2 * math.pi, 4, endpoint=False)
            ring = np.column_stack([np.cos(t), np.sin(t), np.zeros(4)]) * length / 2
            base = np.vstack([ring, [(0, 0, length / 2), (0, 0, -length / 2)]])
            up = [(4, k, (k + 1) % 4, 4) for k in range(4)]
            quads = up + [(5, (k + 1) % 4, k, 5) for k in range(4)]
            pts = apex + base
        else:
            tips = _corner_directions(model) @ rows
            pts = np.vstack([apex, apex + length * tips])
            quads = [(0, 1 + k, 1 + (k + 1) % 4, 0) for k in range(4)] + [(1, 2, 3, 4)]
        faces.append(np.array(quads, np.int32) + start)
        verts.append(pts)
        start += len(pts)
    return np.concatenate(verts), np.concatenate(faces).astype(np.int32)


def _outline_segments(objs: Iterable[bpy.types.Object]) -> F64:
    """(S, 2, 3) world segments of the meshes' boundary edges (used by one face)."""
    segs = []
    for obj in objs:
        if obj.type != "MESH" or not obj.data.polygons:
            continue
        mesh = obj.data
        co = np.empty(3 * len(mesh.vertices))
        mesh.vertices.foreach_get("co", co)
        loops = np.empty(len(mesh.loops), np.int32)
        mesh.loops.foreach_get("vertex_index", loops)
        starts = np.empty(len(mesh.polygons), np.int32)
        totals = np.empty(len(mesh.polygons), np.int32)
        mesh.polygons.foreach_get("loop_start", starts)
        mesh.polygons.foreach_get("loop_total", totals)
        nxt = np.arange(1, len(loops) + 1)
        nxt[starts + totals - 1] = starts
        pairs = np.sort(np.stack([loops, loops[nxt]], axis=1), axis=1)
        edges, counts = np.unique(pairs, axis=0, return_counts=True)
        m = np.array(obj.matrix_world)
        world = co.reshape(-1, 3) @ m[:3, :3].T + m[:3, 3]
        segs.append(world[edges[counts == 1]])
    return np.concatenate(segs) if segs else np.zeros((0, 2, 3))


def _clipped(segs: F64, lo: F64, hi: F64) -> F64:
    """The parts of segments (S, 2, 3) inside the box [lo, hi] (Liang-Barsky)."""
    a, d = segs[:, 0], segs[:, 1] - segs[:, 0]
    t0, t1 = np.zeros(len(segs)), np.ones(len(segs))
    with np.errstate(divide="ignore", invalid="ignore"):
        for k in range(3):
            flat = d[:, k] == 0
            outside = flat & ((a[:, k] < lo[k]) | (a[:, k] > hi[k]))
            ta, tb = (lo[k] - a[:, k]) / d[:, k], (hi[k] - a[:, k]) / d[:, k]
            t0 = np.where(flat, t0, np.maximum(t0, np.minimum(ta, tb)))
            t1 = np.where(flat, t1, np.minimum(t1, np.maximum(ta, tb)))
            t1 = np.where(outside, -1.0, t1)
    keep = t1 > t0
    a, d, t0, t1 = a[keep], d[keep], t0[keep, None], t1[keep, None]
    return np.stack([a + t0 * d, a + t1 * d], axis=1)


def _tubes(segs: F64, radius: float) -> tuple[F64, I32]:
    """Square prisms of half-diagonal ``radius`` round segments (S, 2, 3), each
    lengthened by ``radius`` at both ends so joints close; vertices (8S, 3), quads (4S, 4)."""
    if len(segs) == 0:
        return np.zeros((0, 3)), np.zeros((0, 4), np.int32)
    a, b = segs[:, 0], segs[:, 1]
    d = b - a
    d /= np.maximum(np.linalg.norm(d, axis=1, keepdims=True), 1e-12)
    ref = np.where(np.abs(d[:, 2:3]) > 0.9, [[1.0, 0.0, 0.0]], [[0.0, 0.0, 1.0]])
    u = np.cross(d, ref)
    u /= np.linalg.norm(u, axis=1, keepdims=True)
    v = np.cross(d, u)
    ring = radius * np.stack([u, v, -u, -v], axis=1)  # (S, 4, 3)
    a, b = a - radius * d, b + radius * d
    verts = np.concatenate([a[:, None] + ring, b[:, None] + ring], axis=1)  # (S, 8, 3)
    k = np.arange(4)
    quad = np.stack([k, (k + 1) % 4, 4 + (k + 1) % 4, 4 + k], axis=1)  # (4, 4)
    faces = quad[None] + 8 * np.arange(len(segs))[:, None, None]
    return verts.reshape(-1, 3), faces.reshape(-1, 4).astype(np.int32)


# --- Blender helpers ---------------------------------------------------------------


def _mesh(name: str, verts: F64, quads: I32) -> bpy.types.Mesh:
    """A mesh of quads (F, 4); a quad may repeat its first corner last (a triangle)."""
    mesh = bpy.data.meshes.new(name)
    tri = quads[:, 3] == quads[:, 0]
    sizes = np.where(tri, 3, 4).astype(np.int32)
    keep = np.ones(quads.shape, bool)
    keep[tri, 3] = False
    corners = quads[keep]
    mesh.vertices.add(len(verts))
    mesh.vertices.foreach_set("co", np.asarray(verts, np.float32).ravel())
    mesh.loops.add(len(corners))
    mesh.loops.foreach_set("vertex_index", np.asarray(corners, np.int32))
    mesh.polygons.add(len(sizes))
    mesh.polygons.foreach_set("loop_start", (np.cumsum(sizes) - sizes).astype(np.int32))
    mesh.update(calc_edges=True)
    return mesh


def _material(name: str, rgba: tuple[float, ...]) -> bpy.types.Material:
    mat = bpy.data.materials.new(f"{VIEW_NAME} {name}")
    mat.diffuse_color = rgba
    return mat


def _settings(view: bpy.types.Scene, width: int, height: int) -> None:
    r = view.render
    r.engine = "BLENDER_WORKBENCH"
    r.resolution_x, r.resolution_y, r.resolution_percentage = width, height, 100
    r.film_transparent = False
    for prop in r.bl_rna.properties:  # no burnt-in stamp, no metadata (file path, date)
        if prop.identifier.startswith("use_stamp"):
            setattr(r, prop.identifier, False)
    r.image_settings.file_format = "PNG"
    r.image_settings.color_mode = "RGB"
    r.image_settings.color_depth = "8"
    view.display.render_aa = "5"  # samples; "8" costs ~40 % more, FXAA blurs the coverage grid
    shading = view.display.shading
    shading.light = "STUDIO"
    if STUDIO_LIGHT in {s.name for s in bpy.context.preferences.studio_lights}:
        shading.studio_light = STUDIO_LIGHT
    shading.color_type = "VERTEX"
    shading.show_cavity = True
    shading.show_shadows = False
    shading.show_specular_highlight = False
    view.view_settings.view_transform = "Standard"
    view.view_settings.look = "None"
    view.view_settings.exposure = 0.0
    view.view_settings.gamma = 1.0


def _copy_exclusion(src: bpy.types.LayerCollection, dst: bpy.types.LayerCollection) -> None:
    """Exclude in ``dst``'s tree what the user excluded in ``src``'s (same collections)."""
    by_name = {c.name: c for c in dst.children}
    for child in src.children:
        twin = by_name.get(child.name)
        if twin is not None:
            twin.exclude = child.exclude
            _copy_exclusion(child, twin)


def _exclude(view: bpy.types.Scene, coll: bpy.types.Collection) -> None:
    """Leave ``coll`` out of the view scene's (own) view layer."""
    todo = [view.view_layers[0].layer_collection]
    while todo:
        layer = todo.pop()
        if layer.collection == coll:
            layer.exclude = True
            return
        todo.extend(layer.children)


@contextmanager
def _temporary() -> Iterator:
    """Yields ``new(id) -> id``, which registers a datablock for deletion; on exit
    they are deleted, with every image that appeared meanwhile (the render result)."""
    made: list[bpy.types.ID] = []
    images = {i.as_pointer() for i in bpy.data.images}

    def new(datablock):
        made.append(datablock)
        return datablock

    try:
        yield new
    finally:
        made += [i for i in bpy.data.images if i.as_pointer() not in images]
        bpy.data.batch_remove(made)
