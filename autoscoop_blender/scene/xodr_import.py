"""An OpenDRIVE file -> objects in a Blender scene that follow the scene contract.

``io.opendrive`` reads the file and computes everything (road surfaces, target and
sensor-area rings, the ground, the georeference) without bpy; this module only makes
Blender data of it, in one new collection per import:

    OpenDRIVE <file>            the import
        <file> roads            a mesh per road ("Road_<id>", occludes), the ground
        <file> targets          curves "Target_<lane type>_road<id>"
        <file> sensor areas     curves "SensorArea_road<id>"

Each object carries the road id and lane types (``names.XODR_ROAD_PROP``,
``names.XODR_LANES_PROP``), so a user can find, delete or re-mark them. The scene gets
the file's georeference (``names.CRS_PROP``, ``names.CRS_OFFSET_PROP``). Everything is
checked before the first object is made: a refused import changes nothing. What is
made is what ``scene.extract.extract_scene`` accepts (``io.opendrive.build`` sizes and
checks every road against the scene contract's limits; here, that there is a target
and a sensor area at all). A long import reports progress through ``progress(stage,
done, total)``, at least every second or so.
"""

from __future__ import annotations

import math
import os
import time
from collections.abc import Sequence
from dataclasses import dataclass
from functools import reduce
from pathlib import Path

import bpy
import numpy as np
import shapely
from numpy.typing import NDArray

from .. import names
from ..core.errors import InputError, SceneContractError
from ..core.model.sensors import MAX_RANGE_M
from ..io.georef import check_crs
from ..io.opendrive import AreaRings, SurfaceMesh, build_import, read_opendrive
from ..io.opendrive.build import MIN_SENSOR_PART_M2, MIN_TARGET_PART_M2
from ..io.opendrive.progress import Progress, Ticker
from .extract import area_role

# Viewport colours (solid mode, "Object" colour): asphalt, grass.
_ROAD_COLOUR = (0.25, 0.25, 0.27, 1.0)
_GROUND_COLOUR = (0.42, 0.5, 0.36, 1.0)


@dataclass(frozen=True)
class ImportSummary:
    """What an import made: the collection's name; counts; plan areas in m^2: the
    targets' union (what a run covers: junctions' connecting roads overlap the roads
    they join), the chosen lanes' own areas summed road by road, the sensor areas';
    the warnings about the file; seconds spent (reading, geometry, Blender data)."""

    collection: str
    roads: int
    targets: int
    target_m2: float
    lane_m2: float
    sensor_areas: int
    sensor_area_m2: float
    crs: str | None
    warnings: tuple[str, ...]
    seconds: float

    def text(self) -> str:
        """One line for a report."""
        crs = "georeferenced" if self.crs else "no CRS"
        return (
            f"{self.roads} roads, {self.targets} target areas covering {self.target_m2:,.0f} "
            f"m^2 (lanes {self.lane_m2:,.0f} m^2 summed road by road), {self.sensor_areas} "
            f"sensor areas of {self.sensor_area_m2:,.0f} m^2; {crs}; {self.seconds:.1f} s"
        )


def parse_lanes(text: str) -> tuple[str, ...]:
    """ "driving,parking" -> ("driving", "parking"); InputError for an empty list."""
    lanes = tuple(t.strip() for t in text.split(",") if t.strip())
    if not lanes:
        raise InputError(f"--lanes {text!r}: name at least one lane type, e.g. driving")
    return lanes


def parse_band(text: str) -> tuple[float, float]:
    """ "1:6" -> (1.0, 6.0): metres outside the outermost lane border; InputError when
    it is not two numbers with 0 <= INNER < OUTER."""
    parts = text.split(":")
    try:
        inner, outer = (float(p) for p in parts)
    except ValueError:
        raise InputError(f"--band {text!r}: give INNER:OUTER in metres, e.g. 1:6") from None
    if not (math.isfinite(inner) and math.isfinite(outer) and 0 <= inner < outer):
        raise InputError(f"--band {text!r}: needs 0 <= INNER < OUTER, e.g. 1:6")
    if outer > MAX_RANGE_M:
        raise InputError(
            f"--band {text!r}: OUTER may be at most {MAX_RANGE_M:g} m (a road-side sensor's "
            "longest reach)"
        )
    return inner, outer


def import_xodr(
    path: str | os.PathLike[str],
    lane_types: Sequence[str] = ("driving",),
    band: tuple[float, float] = (1.0, 6.0),
    terrain: str = "flat",
    scene: bpy.types.Scene | None = None,
    progress: Progress | None = None,
) -> ImportSummary:
    """Import an OpenDRIVE file into ``scene`` (default: the context's); see the module
    docstring. InputError (one line) for a file that is not OpenDRIVE, bad options, a
    file past the import's limits (naming the road and the figure), one that would
    give no target or no sensor area, or a scene georeferenced otherwise; then nothing
    is changed. ``progress(stage, done, total)``: "reading" (bytes), "parsing",
    "sizing", "roads", "targets", "sensor areas" (roads), "objects" (Blender objects).
    """
    t0 = time.perf_counter()
    scene = scene or bpy.context.scene
    network = read_opendrive(path, progress)
    imported = build_import(network, tuple(lane_types), band, terrain, progress)
    warnings = list(imported.warnings)
    # A scene needs a target and a sensor area (``extract_scene``): one the import
    # does not make is an error, unless the scene has one already (a second import).
    have = {area_role(obj) for obj in scene.objects}
    for made, role, text in (
        (
            imported.targets,
            names.ROLE_TARGET,
            f"no target area: the {', '.join(lane_types)} lanes leave no part of "
            f"{MIN_TARGET_PART_M2:g} m^2 or more",
        ),
        (
            imported.sensor_areas,
            names.ROLE_SENSOR_AREA,
            f"no sensor area: the band {band[0]:g}:{band[1]:g} m beside the roads leaves "
            f"no part of {MIN_SENSOR_PART_M2:g} m^2 or more once every road's surface is "
            "cut out of it",
        ),
    ):
        if made:
            continue
        if role not in have:
            raise InputError(f"{network.path}: {text}")
        warnings.append(f"{Path(path).name}: {text} (the scene has others)")
    crs = _usable_crs(imported.crs, Path(path).name, warnings)
    _check_georeference(scene, crs, imported.crs_offset, Path(path).name)

    stem = Path(path).stem
    top = _collection(f"OpenDRIVE {stem}", scene.collection)
    roads = _collection(f"{stem} roads", top)
    targets = _collection(f"{stem} targets", top)
    sensors = _collection(f"{stem} sensor areas", top)
    total = len(imported.surfaces) + len(imported.targets) + len(imported.sensor_areas)
    tick = Ticker(progress, "objects", total)
    for surface in imported.surfaces:
        _mesh_object(surface, roads, _ROAD_COLOUR)
        tick(tick.done_units + 1)
    if imported.ground is not None:
        ground = _mesh_object(imported.ground, roads, _GROUND_COLOUR)
        ground.display_type = "SOLID"
    for area in imported.targets:
        _curve_object(area, targets)
        tick(tick.done_units + 1)
    for area in imported.sensor_areas:
        _curve_object(area, sensors)
        tick(tick.done_units + 1)
    tick.done()
    if crs:
        scene[names.CRS_PROP] = crs
    elif imported.crs:
        scene[names.XODR_GEOREF_PROP] = imported.crs
    if crs or any(imported.crs_offset):
        scene[names.CRS_OFFSET_PROP] = [float(v) for v in imported.crs_offset]
    return ImportSummary(
        collection=top.name,
        roads=len(imported.surfaces),
        targets=len(imported.targets),
        target_m2=_union_m2(imported.targets),
        lane_m2=sum(imported.lane_area_m2.values()),
        sensor_areas=len(imported.sensor_areas),
        sensor_area_m2=_union_m2(imported.sensor_areas),
        crs=crs,
        warnings=tuple(warnings),
        seconds=time.perf_counter() - t0,
    )


def _union_m2(areas: Sequence[AreaRings]) -> float:
    """Plan area of the areas together, m^2 (each area's rings even-odd, as
    ``area_from_rings`` reads them; the import made every ring simple, so its checks,
    30 times the cost, are skipped: 20,000 areas took 30 s with them)."""
    if not areas:
        return 0.0
    polys = [
        reduce(shapely.symmetric_difference, [shapely.Polygon(r[:, :2]) for r in a.rings])
        for a in areas
    ]
    return float(shapely.union_all(polys).area)


def _usable_crs(text: str | None, file: str, warnings: list[str]) -> str | None:
    """The header's geoReference if PROJ reads it as a projected CRS in metres; else
    None, with a warning saying why (CARLA's towns give "+lat_0=49 +lon_0=8", with no
    projection named)."""
    if text is None:
        return None
    try:
        return check_crs(text, file, "geoReference")
    except SceneContractError:
        shown = " ".join(text.split())
        shown = shown if len(shown) <= 80 else shown[:77] + "..."
        warnings.append(
            f"{file}: the header's geoReference {shown!r} is not a projected CRS that PROJ "
            f"reads: the scene gets no CRS (kept as {names.XODR_GEOREF_PROP}); outputs stay "
            "in scene metres"
        )
        return None


def _check_georeference(
    scene: bpy.types.Scene,
    crs: str | None,
    offset: tuple[float, float, float, float],
    file: str,
) -> None:
    """InputError when the scene already sits in another CRS, or elsewhere in the same
    one: the two would not line up."""
    have = scene.get(names.CRS_PROP)
    if have is not None and crs is not None and str(have) != crs:
        raise InputError(
            f"{file}: its CRS differs from scene {scene.name!r}'s ({names.CRS_PROP}); "
            "import it into a new scene"
        )
    have_offset = scene.get(names.CRS_OFFSET_PROP)
    if have_offset is not None and not np.allclose(list(have_offset), offset, atol=1e-6):
        raise InputError(
            f"{file}: its coordinates are offset otherwise than scene {scene.name!r}'s "
            f"({names.CRS_OFFSET_PROP}); import it into a new scene"
        )


def _collection(name: str, parent: bpy.types.Collection) -> bpy.types.Collection:
    """A new collection under ``parent`` (Blender appends .001 to a name in use)."""
    coll = bpy.data.collections.new(name)
    parent.children.link(coll)
    return coll


def _tag(obj: bpy.types.Object, road_id: str | None, lanes: Sequence[str]) -> None:
    if road_id is not None:
        obj[names.XODR_ROAD_PROP] = road_id
    if lanes:
        obj[names.XODR_LANES_PROP] = ",".join(lanes)


def _mesh_object(
    surface: SurfaceMesh, coll: bpy.types.Collection, colour: tuple[float, ...]
) -> bpy.types.Object:
    """A mesh object of the surface's triangles (world metres)."""
    mesh = bpy.data.meshes.new(surface.name)
    _fill_mesh(mesh, surface.vertices, surface.faces)
    obj = bpy.data.objects.new(surface.name, mesh)
    obj.color = colour
    _tag(obj, surface.road_id, ())
    coll.objects.link(obj)
    return obj


def _fill_mesh(
    mesh: bpy.types.Mesh, vertices: NDArray[np.float64], faces: NDArray[np.int32]
) -> None:
    """Vertices (V, 3) and triangles (F, 3) into an empty mesh, in bulk (``foreach_set``
    rather than ``from_pydata``'s Python lists: Town04's roads are ~10^5 triangles)."""
    n_faces = len(faces)
    mesh.vertices.add(len(vertices))
    mesh.vertices.foreach_set("co", np.ascontiguousarray(vertices, dtype=np.float32).ravel())
    mesh.loops.add(3 * n_faces)
    mesh.loops.foreach_set("vertex_index", np.ascontiguousarray(faces, dtype=np.int32).ravel())
    mesh.polygons.add(n_faces)
    mesh.polygons.foreach_set("loop_start", np.arange(0, 3 * n_faces, 3, dtype=np.int32))
    mesh.polygons.foreach_set("loop_total", np.full(n_faces, 3, dtype=np.int32))
    mesh.update(calc_edges=True)
    mesh.validate()


def _curve_object(area: AreaRings, coll: bpy.types.Collection) -> bpy.types.Object:
    """A curve object with one closed poly spline per ring (world metres)."""
    curve = bpy.data.curves.new(area.name, "CURVE")
    curve.dimensions = "3D"
    for ring in area.rings:
        spline = curve.splines.new("POLY")
        spline.points.add(len(ring) - 1)
        co = np.column_stack([ring, np.ones(len(ring))]).astype(np.float32)
        spline.points.foreach_set("co", co.ravel())
        spline.use_cyclic_u = True
    obj = bpy.data.objects.new(area.name, curve)
    _tag(obj, area.road_id, area.lane_types)
    coll.objects.link(obj)
    return obj
