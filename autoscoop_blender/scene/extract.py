"""Blender scene -> SceneModel: occluder triangles, target areas, sensor areas.

Reads the *evaluated* depsgraph, so modifiers, geometry-node scatter and collection
instances occlude as the viewport shows them, in world coordinates. Nothing here
changes the user's data. The contract (see ``names``): curves named ``Target*`` or
``SensorArea*`` (or marked with ``autoscoop_role``) are areas; every other visible
object with faces occludes unless it has ``autoscoop_ignore`` set or lives in the
results collection.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Iterable
from dataclasses import dataclass, replace
from pathlib import Path

import bpy
import numpy as np
from mathutils import Vector
from mathutils.bvhtree import BVHTree
from numpy.typing import NDArray

from .. import names
from ..core.errors import SceneContractError
from ..core.model.scene import Area, SceneModel, area_from_rings, choose_origin
from ..core.model.sensors import DORI_PX_PER_M, KINDS, MAX_COORD_M, MAX_RANGE_M
from ..core.model.sites import mast_sites
from ..io.georef import check_crs, check_offset

F64 = NDArray[np.float64]

_GEOMETRY_TYPES = {"MESH", "CURVE", "SURFACE", "META", "FONT"}

# An area curve whose points lie in one plane counts as flat (in the XY plane) up to
# this tilt. A curve that follows the terrain (points at different heights: not in one
# plane, or on a sloping surface) is drawn in plan and is not tilted; the core refuses
# it only beyond 45 deg.
MAX_FLAT_TILT_DEG = 1.0
# Points within this fraction of a ring's size (plus float32 rounding of Blender's
# coordinates) of its best-fit plane lie in that plane. Terrain a curve was drawn on
# is rougher; a curve rotated out of the XY plane is exact up to that rounding.
_PLANE_TOL = 1e-4
# A ring in one sloping plane follows the terrain when all its points lie this close
# to an occluder's surface (snapped onto a ramp, or drawn just above it to stay seen).
_ON_SURFACE_M = 0.25


def area_role(obj: bpy.types.Object) -> str | None:
    """``names.ROLE_TARGET``, ``names.ROLE_SENSOR_AREA``, ``names.ROLE_NO_MAST`` or
    None for an object."""
    role = obj.get(names.ROLE_PROP)
    if role in (names.ROLE_TARGET, names.ROLE_SENSOR_AREA, names.ROLE_NO_MAST):
        return role
    if role in (names.ROLE_NONE, names.ROLE_SENSOR):
        return None
    if names.TARGET_RE.match(obj.name):
        return names.ROLE_TARGET
    if names.SENSOR_AREA_RE.match(obj.name):
        return names.ROLE_SENSOR_AREA
    if names.NO_MAST_RE.match(obj.name):
        return names.ROLE_NO_MAST
    return None


def results_collections() -> set[str]:
    """Names of AutoSCOOP's results collection and every collection inside it."""
    out: set[str] = set()
    for coll in bpy.data.collections:
        if coll.name == names.RESULTS_COLLECTION or coll.get(names.RESULTS_TAG):
            out.add(coll.name)
            out.update(c.name for c in coll.children_recursive)
    return out


def in_results(obj: bpy.types.Object, results: set[str] | None = None) -> bool:
    """Whether the object belongs to AutoSCOOP's own results (at any depth)."""
    results = results_collections() if results is None else results
    return any(c.name in results for c in obj.users_collection)


def extract_scene(
    scene: bpy.types.Scene | None = None,
    depsgraph: bpy.types.Depsgraph | None = None,
) -> SceneModel:
    """The SceneModel of a Blender scene (default: the context's), in local metres.

    Raises SceneContractError naming the object for any contract violation, and the
    scene and property for a georeference (``names.CRS_PROP``, ``names.CRS_OFFSET_PROP``)
    that is not one; that is checked first, before any work.
    """
    scene = scene or bpy.context.scene
    crs, crs_offset = scene_georef(scene)
    depsgraph = depsgraph or bpy.context.evaluated_depsgraph_get()
    source = bpy.data.filepath and Path(bpy.data.filepath).name or scene.name

    results = results_collections()
    rings_of: dict[str, list[tuple[bpy.types.Object, list[F64]]]] = {
        names.ROLE_TARGET: [],
        names.ROLE_SENSOR_AREA: [],
        names.ROLE_NO_MAST: [],
    }
    for obj in scene.objects:
        role = area_role(obj)
        if role is None or in_results(obj, results):
            continue
        if obj.type != "CURVE":
            raise SceneContractError(
                f"{obj.name}: is a {obj.type.lower()}, but a {_ROLE_WORDS[role]} must be a curve"
            )
        rings_of[role].append((obj, curve_rings(obj)))
    target_rings = rings_of[names.ROLE_TARGET]
    sensor_rings = rings_of[names.ROLE_SENSOR_AREA]
    no_mast_rings = rings_of[names.ROLE_NO_MAST]
    if not target_rings:
        raise SceneContractError(
            f"{source}: no target area (a closed curve named 'Target...' or marked "
            "as target in the AutoSCOOP panel)"
        )
    if not sensor_rings:
        raise SceneContractError(
            f"{source}: no sensor area (a closed curve named 'SensorArea...' or "
            "marked as sensor area in the AutoSCOOP panel)"
        )

    all_pts = np.concatenate([r for _, rings in target_rings + sensor_rings for r in rings])
    origin = choose_origin(all_pts)
    targets = tuple(_target_area(obj, rings, origin) for obj, rings in target_rings)
    sensors = tuple(_area(obj, rings, origin, with_height=True) for obj, rings in sensor_rings)
    no_mast = tuple(_area(obj, rings, origin) for obj, rings in no_mast_rings)

    occ = occluder_mesh(depsgraph, results)
    vertices, faces = occ.vertices - origin, occ.faces
    # Tilted areas last: whether a ring follows the terrain depends on the occluders.
    surface = _Surface(lambda: (vertices, faces))
    for obj, rings in target_rings + sensor_rings + no_mast_rings:
        check_flat_rings(obj, rings, surface, origin)
    warnings: list[str] = []
    if not occ.names:
        warnings.append(
            f"{source}: no occluder in the scene - flat nothing: targets lie on a "
            "plane at the curves' height and nothing blocks the view"
        )
    scene_model = SceneModel(
        vertices=vertices,
        faces=faces,
        occluders=tuple(occ.names),
        targets=targets,
        sensor_areas=sensors,
        origin=origin,
        source=source,
        warnings=tuple(warnings),
        ground_faces=None if occ.ground.all() else occ.ground,
        crs=crs,
        crs_offset=crs_offset,
        no_mast=no_mast,
        face_object=occ.owner,
        mounts=tuple(occ.mounts),
    )
    # Where masts may stand: the sensor areas less no-mast zones and what stands on
    # the ground (walls, roofs, tree crowns), one rule for every optimizer.
    return mast_sites(scene_model)


def scene_georef(scene: bpy.types.Scene) -> tuple[str | None, tuple[float, float, float, float]]:
    """The scene's CRS (None: none) and offset (x, y, z, hdg) from its custom
    properties, checked with pyproj; SceneContractError naming the scene and the
    property otherwise."""
    where = f"scene {scene.name!r}"
    if bpy.data.filepath:
        where = f"{Path(bpy.data.filepath).name}, {where}"
    crs = check_crs(scene.get(names.CRS_PROP), where, names.CRS_PROP)
    offset = check_offset(scene.get(names.CRS_OFFSET_PROP), where, names.CRS_OFFSET_PROP)
    return crs, offset


# The most sensors a target area may ask to see each point (a junction needing 3 is
# already a rare demand; more would mean a plan of several times the sensors).
MAX_COVERAGE_K = 10

_ROLE_WORDS = {
    names.ROLE_TARGET: "target area",
    names.ROLE_SENSOR_AREA: "sensor area",
    names.ROLE_NO_MAST: "no-mast zone",
}


def _target_area(obj: bpy.types.Object, rings: list[F64], origin: F64) -> Area:
    """A target area with its requirements (``names.COVERAGE_K_PROP``, ``DORI_PROP``,
    ``REQUIRE_PROP``); SceneContractError naming the curve and property for a value
    that is not one."""
    area = _area(obj, rings, origin)
    k = obj.get(names.COVERAGE_K_PROP)
    if k is not None:
        if isinstance(k, bool) or not isinstance(k, int) or not 1 <= k <= MAX_COVERAGE_K:
            raise SceneContractError(
                f"{obj.name}: custom property {names.COVERAGE_K_PROP} must be a whole number "
                f"from 1 to {MAX_COVERAGE_K} (sensors that must see each point), got {k!r}"
            )
    dori = _choice(obj, names.DORI_PROP, DORI_PX_PER_M, "DORI level")
    require = _choice(obj, names.REQUIRE_PROP, KINDS, "sensor kind")
    return replace(area, coverage_k=k, dori=dori, require=require)


def _choice(obj: bpy.types.Object, prop: str, allowed: Iterable[str], what: str) -> str | None:
    """A custom property that names one of ``allowed`` (case-insensitive), or None."""
    value = obj.get(prop)
    if value is None:
        return None
    options = list(allowed)
    text = value.strip().lower() if isinstance(value, str) else None
    if text == "recognize":  # the American spelling of the DORI level
        text = "recognise"
    if text not in options:
        raise SceneContractError(
            f"{obj.name}: custom property {prop} must be a {what}: one of "
            f"{', '.join(options)}; got {value!r}"
        )
    return text


def _area(obj: bpy.types.Object, rings: list[F64], origin: F64, with_height: bool = False) -> Area:
    local = [r - origin for r in rings]
    height = None
    if with_height and names.HEIGHT_PROP in obj:
        raw = obj[names.HEIGHT_PROP]
        ok = isinstance(raw, (int, float)) and not isinstance(raw, bool)
        if not ok or not 0 <= raw <= MAX_RANGE_M:  # False for nan
            shown = repr(raw) if ok else type(raw).__name__
            raise SceneContractError(
                f"{obj.name}: custom property {names.HEIGHT_PROP} must be a number in "
                f"[0, {MAX_RANGE_M:g}] m (the mast height), got {shown}"
            )
        height = float(raw)
    z = float(np.mean(np.concatenate(local)[:, 2]))
    return Area(obj.name, area_from_rings(obj.name, local), z, height)


def curve_rings(obj: bpy.types.Object) -> list[F64]:
    """World-space rings (K, 3) of a curve object, one per spline.

    POLY splines give their points; BEZIER splines are sampled with the curve's
    resolution as Blender draws them. SceneContractError naming the curve (and spline)
    for no splines, open splines, NURBS, and coordinates that are not finite or farther
    than ``MAX_COORD_M`` from the origin. (Whether a ring is tilted depends on the
    occluders too: ``extract_scene`` checks that.)
    """
    mat = np.array(obj.matrix_world)
    splines = obj.data.splines
    if len(splines) == 0:
        raise SceneContractError(f"{obj.name}: curve has no splines")
    rings = []
    for k, spline in enumerate(splines):
        label = _ring_label(obj, k)
        if spline.type == "POLY":
            pts = np.array([p.co[:3] for p in spline.points], dtype=float).reshape(-1, 3)
            _check_coordinates(label, pts, "curve point")
        elif spline.type == "BEZIER":
            bp = spline.bezier_points
            ctrl = [(*p.co, *p.handle_left, *p.handle_right) for p in bp]
            ctrl_pts = np.array(ctrl, dtype=float).reshape(-1, 3)
            _check_coordinates(label, ctrl_pts, "Bezier point or handle")
            pts = _bezier_points(spline)
        else:
            raise SceneContractError(
                f"{label}: {spline.type} splines are not supported; convert the curve "
                "to Poly or Bezier"
            )
        world = pts @ mat[:3, :3].T + mat[:3, 3]
        _check_coordinates(label, world, "curve point, placed by the object's transform,")
        closed_by_points = len(pts) > 2 and np.allclose(pts[0], pts[-1])
        if not (spline.use_cyclic_u or closed_by_points):
            raise SceneContractError(f"{label}: curve is open; close it (Toggle Cyclic, Alt+C)")
        rings.append(world)
    return rings


def _ring_label(obj: bpy.types.Object, k: int) -> str:
    """How errors name spline ``k`` of a curve object."""
    return obj.name if len(obj.data.splines) == 1 else f"{obj.name} (spline {k + 1})"


def _check_coordinates(label: str, pts: F64, what: str) -> None:
    """SceneContractError for a point (N, 3) that is not finite or lies farther than
    ``MAX_COORD_M`` from the origin in any axis."""
    finite = np.isfinite(pts).all(axis=1)
    if not finite.all():
        p = pts[~finite][0]
        raise SceneContractError(f"{label}: a {what} is not finite ({p[0]:g}, {p[1]:g}, {p[2]:g})")
    far = (np.abs(pts) > MAX_COORD_M).any(axis=1)
    if far.any():
        p = pts[far][0]
        raise SceneContractError(
            f"{label}: a {what} ({p[0]:g}, {p[1]:g}, {p[2]:g}) lies beyond "
            f"{MAX_COORD_M:g} m (10,000 km) from the origin"
        )


class _Surface:
    """The occluders' surfaces, asked whether points lie on them. ``mesh()`` gives the
    vertices (V, 3) and triangles (F, 3) in the frame of the points asked; it and the
    BVHTree are made on the first question only (rarely asked: see ``_check_flat``)."""

    def __init__(self, mesh: Callable[[], tuple[F64, NDArray[np.int32]]]) -> None:
        self._mesh = mesh
        self._tree: BVHTree | None = None
        self._empty = False

    def holds(self, pts: F64, tol: float) -> bool:
        """Whether every point (N, 3) lies within ``tol`` m of an occluder's surface."""
        if self._tree is None and not self._empty:
            vertices, faces = self._mesh()
            self._empty = len(faces) == 0
            if not self._empty:
                self._tree = BVHTree.FromPolygons(
                    vertices.tolist(), faces.tolist(), all_triangles=True
                )
        if self._tree is None:
            return False
        near = self._tree.find_nearest
        return all(near(Vector(p), tol)[0] is not None for p in pts.tolist())


def occluder_surface() -> _Surface:
    """The context's occluders' surfaces in world metres, for ``check_flat_rings``
    outside a run (the panel's list of areas): gathered only if a ring asks."""

    def mesh() -> tuple[F64, NDArray[np.int32]]:
        depsgraph = bpy.context.evaluated_depsgraph_get()
        occ = occluder_mesh(depsgraph, results_collections())
        return occ.vertices, occ.faces

    return _Surface(mesh)


def check_flat_rings(
    obj: bpy.types.Object, rings: list[F64], surface: _Surface, origin: F64 | None = None
) -> None:
    """SceneContractError naming the curve (and spline) when one of its rings (K, 3,
    world metres) is tilted (``_check_flat``); ``surface`` is in world metres less
    ``origin`` (default: none)."""
    for k, ring in enumerate(rings):
        # Blender keeps coordinates in float32: allow for its rounding of world ones.
        rounding = 1e-6 * float(np.abs(ring).max())
        local = ring if origin is None else ring - origin
        _check_flat(_ring_label(obj, k), local, surface, rounding)


def _check_flat(label: str, pts: F64, surface: _Surface, rounding: float = 0.0) -> None:
    """SceneContractError when a ring is tilted: its points lie in one plane inclined
    more than ``MAX_FLAT_TILT_DEG`` and not on the occluders' surfaces. Such a curve was
    drawn flat and turned out of the XY plane, and its area in plan would shrink by
    cos(tilt) unnoticed.

    Not tilted: a ring whose points are not in one plane, or lie on the terrain (within
    ``_ON_SURFACE_M``), follows the terrain; its plan shape is what counts. Rings too
    short or on a line are left to the core ("at least 3 points", "no area").
    ``rounding``: how far (m) float32 storage may have moved the points.
    """
    if len(pts) < 3:
        return
    centred = pts - pts.mean(axis=0)
    _, sv, vt = np.linalg.svd(centred, full_matrices=False)
    if len(sv) < 3 or sv[1] <= 1e-9 * max(sv[0], 1e-300):
        return  # on a line: "encloses no area"
    normal = vt[2]
    tilt = math.degrees(math.acos(min(1.0, abs(float(normal[2])))))
    if tilt <= MAX_FLAT_TILT_DEG:
        return
    size = float(np.ptp(pts, axis=0).max())
    tol = _PLANE_TOL * size + rounding
    if float(np.abs(centred @ normal).max()) > tol:
        return  # not in one plane: follows the terrain
    if surface.holds(pts, _ON_SURFACE_M):
        return  # on a sloping surface: follows the terrain
    x, y = pts[:, 0], pts[:, 1]
    plan = 0.5 * abs(float(np.dot(x, np.roll(y, -1)) - np.dot(y, np.roll(x, -1))))
    drawn = plan / max(abs(float(normal[2])), 1e-12)
    raise SceneContractError(
        f"{label}: curve is not in the XY plane (tilted {tilt:.1f} deg, flat is within "
        f"{MAX_FLAT_TILT_DEG:g} deg): its {drawn:,.0f} m^2 would count as {plan:,.0f} m^2 "
        "in plan; flatten it (scale Z to 0) or clear the object's X/Y rotation"
    )


def _bezier_points(spline: bpy.types.Spline) -> F64:
    """Points along a Bezier spline, ``resolution_u`` per segment, closing if cyclic."""
    bp = spline.bezier_points
    n = len(bp)
    if n < 2:
        return np.array([p.co[:] for p in bp], dtype=float)
    res = max(int(spline.resolution_u), 1)
    t = np.linspace(0.0, 1.0, res, endpoint=False)[:, None]
    segs = range(n if spline.use_cyclic_u else n - 1)
    out = []
    for i in segs:
        a, b = bp[i], bp[(i + 1) % n]
        p0, p1 = np.array(a.co), np.array(a.handle_right)
        p2, p3 = np.array(b.handle_left), np.array(b.co)
        out.append(
            (1 - t) ** 3 * p0 + 3 * (1 - t) ** 2 * t * p1 + 3 * (1 - t) * t**2 * p2 + t**3 * p3
        )
    if not spline.use_cyclic_u:
        out.append(np.array([bp[n - 1].co[:]]))
    return np.concatenate(out)


@dataclass(frozen=True)
class Occluders:
    """All occluding triangles in world metres: vertices (V, 3), faces (F, 3); the
    objects' names, (F,) each face's index into them, (F,) False for faces of
    overhangs (``names.OVERHANG_PROP``), and the names of mounts (``names.MOUNT_PROP``)."""

    vertices: F64
    faces: NDArray[np.int32]
    names: list[str]
    owner: NDArray[np.int32]
    ground: NDArray[np.bool_]
    mounts: list[str]


def occluder_mesh(depsgraph: bpy.types.Depsgraph, results: set[str]) -> Occluders:
    """The scene's occluders (see ``Occluders``)."""
    verts: list[F64] = []
    faces: list[NDArray[np.int32]] = []
    ground: list[NDArray[np.bool_]] = []
    owner: list[NDArray[np.int32]] = []
    used: list[str] = []
    mounts: list[str] = []
    offset = 0
    for inst in depsgraph.object_instances:
        obj = inst.instance_object if inst.is_instance else inst.object
        if obj is None or obj.type not in _GEOMETRY_TYPES:
            continue
        orig = obj.original
        if not inst.is_instance and not orig.visible_get():
            continue
        if area_role(orig) is not None or orig.get(names.IGNORE_PROP) or in_results(orig, results):
            continue
        v, f = _triangles(inst.object, np.array(inst.matrix_world))
        if len(f) == 0:
            continue
        if not (np.isfinite(v).all() and np.abs(v).max() <= MAX_COORD_M):
            _check_occluder(orig.name, v[np.unique(f)])  # loose vertices do not count
        verts.append(v)
        faces.append(f + offset)
        ground.append(np.full(len(f), not orig.get(names.OVERHANG_PROP, False)))
        offset += len(v)
        if orig.name not in used:
            used.append(orig.name)
            if orig.get(names.MOUNT_PROP, False):
                mounts.append(orig.name)
        owner.append(np.full(len(f), used.index(orig.name), dtype=np.int32))
    if not faces:
        none = np.zeros(0, dtype=np.int32)
        return Occluders(
            np.zeros((0, 3)), np.zeros((0, 3), dtype=np.int32), [], none, none.astype(bool), []
        )
    return Occluders(
        np.concatenate(verts),
        np.concatenate(faces).astype(np.int32),
        used,
        np.concatenate(owner),
        np.concatenate(ground),
        mounts,
    )


def _check_occluder(name: str, v: F64) -> None:
    """SceneContractError for an occluder with a vertex (of a face) that is not finite
    or lies beyond ``MAX_COORD_M``: the ray caster would give nonsense."""
    if not np.isfinite(v).all():
        raise SceneContractError(
            f"{name}: occluder has vertices that are not finite; fix the mesh or set "
            f"the custom property {names.IGNORE_PROP}"
        )
    reach = float(np.abs(v).max()) if len(v) else 0.0
    if reach > MAX_COORD_M:
        raise SceneContractError(
            f"{name}: occluder reaches {reach:.3g} m from the origin, beyond "
            f"{MAX_COORD_M:g} m (10,000 km); fix it or set the custom property "
            f"{names.IGNORE_PROP}"
        )


def _triangles(eval_obj: bpy.types.Object, matrix: F64) -> tuple[F64, NDArray[np.int32]]:
    """World vertices (V, 3) and triangles (F, 3) of one evaluated object; degenerate
    (zero-area) triangles dropped."""
    mesh = eval_obj.to_mesh()
    try:
        mesh.calc_loop_triangles()
        co = np.empty(len(mesh.vertices) * 3, dtype=np.float64)
        mesh.vertices.foreach_get("co", co)
        tri = np.empty(len(mesh.loop_triangles) * 3, dtype=np.int32)
        mesh.loop_triangles.foreach_get("vertices", tri)
    finally:
        eval_obj.to_mesh_clear()
    v = co.reshape(-1, 3) @ matrix[:3, :3].T + matrix[:3, 3]
    f = tri.reshape(-1, 3)
    if len(f):
        e1 = v[f[:, 1]] - v[f[:, 0]]
        e2 = v[f[:, 2]] - v[f[:, 0]]
        f = f[np.linalg.norm(np.cross(e1, e2), axis=1) > 1e-12]
    return v, f
