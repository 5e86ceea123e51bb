"""The panel's jobs, on the same pipeline as ``python -m headless``.

``OptimizeJob`` snapshots the scene into numpy at the start (``extract_scene``, the
BVHTree caster factory, ``core.run.Run``), is stepped in time slices by the modal
operator or drained by ``execute``, shows each fixed sensor as a camera in a
temporary collection while it runs, and on ``finish`` writes the results collection
(``spawn.spawn_results``) from the run's ``Result`` - the same poses and metrics
``headless optimize`` finds for the same seed. ``cancel`` removes the temporary
collection, so the scene is as it was. ``evaluate_cameras`` runs
``core.evaluate.evaluate_layout``, the function behind ``headless coverage``.

Nothing here keeps a Blender ID across time slices: only names and numpy.
"""

from __future__ import annotations

import json
import math
import time
from dataclasses import replace
from pathlib import Path
from typing import Any

import bpy
import numpy as np

from .. import names
from ..core.coverage.reference import reference_footprint_m2
from ..core.errors import AutoscoopError, InputError
from ..core.evaluate import evaluate_layout
from ..core.model.scene import area_from_rings
from ..core.model.sensors import SensorModel, SensorPack, SensorSpec
from ..core.optimize.base import Progress
from ..core.result import Result
from ..core.run import Run
from ..core.settings import (
    PANEL_SETTINGS,
    CoverageSettings,
    OptimizeSettings,
    from_mapping,
    settings_schema,
)
from ..io.figure import render_png
from ..io.reports import coverage_dict, gis_files, result_dict, sensors_csv
from .extract import (
    area_role,
    check_flat_rings,
    curve_rings,
    extract_scene,
    occluder_surface,
)
from .factory import BVHFactory
from .spawn import (
    COVERAGE_COLLECTION,
    FOOTPRINTS_COLLECTION,
    FRUSTA_COLLECTION,
    MODEL_PROP,
    find_results,
    sensor_camera,
    spawn_results,
)

# Cameras of fixed sensors appear here while a run goes on; removed at the end.
LIVE_COLLECTION = "AutoSCOOP Run (in progress)"

# The last layout per scene, for the export buttons (this Blender session only).
_LAST: dict[str, tuple[Result, dict[str, Any], str]] = {}


# --- settings ------------------------------------------------------------------------


def model_from(props: Any) -> SensorModel:
    """The panel's sensor model, validated (InputError names the setting)."""
    return props.sensor_model().validated("Sensor")


def pack_from(props: Any) -> SensorModel | SensorPack:
    """The panel's model, or its mixed pack (the model and the "Mix with" one),
    validated; InputError names the setting."""
    pack = props.sensor_pack()
    if isinstance(pack, SensorModel):
        return pack.validated("Sensor")
    main = pack.models[0].validated("Sensor")
    if pack.models[1] == main:
        return main  # mixed with itself: one model
    return replace(pack, models=(main, pack.models[1]))


def settings_from(props: Any) -> OptimizeSettings:
    """The panel's optimizer settings (its knobs, the defaults for the rest), validated."""
    data: dict[str, Any] = {}
    for setting in PANEL_SETTINGS:
        *groups, name = setting.path.split(".")
        table = data
        for group in groups:
            table = table.setdefault(group, {})
        value = getattr(props, setting.prop_name)
        if setting.kind is float:
            # Blender keeps float properties in single precision (0.97 reads back as
            # 0.9700000286): the value as typed has at most 7 significant digits.
            value = float(f"{value:.7g}")
        table[name] = value
    return OptimizeSettings.from_mapping(data, "AutoSCOOP panel")


def coverage_settings_from(props: Any) -> CoverageSettings:
    """The coverage part of the panel's settings (an optimization's are a superset)."""
    mine = {s.path for s in settings_schema(CoverageSettings)}
    data = {k: v for k, v in settings_from(props).to_dict().items() if k in mine}
    return from_mapping(CoverageSettings, data, "AutoSCOOP panel").validated()


def flat_footprint_text(props: Any) -> str:
    """The model's largest flat-ground footprint, for the panel (2 m grid: quick)."""
    try:
        model = model_from(props)
    except AutoscoopError as e:
        return f"invalid: {e}"
    return f"{reference_footprint_m2(model, 2.0):,.0f} m^2 on flat ground (largest over pitch)"


# --- scene check for the panel ---------------------------------------------------------

_AREA_CACHE: dict[str, list[tuple[str, str, str]]] = {}


def area_report(scene: bpy.types.Scene) -> list[tuple[str, str, str]]:
    """(role, object name, "1,234 m^2" or the problem) for every marked curve.

    Cached until the next depsgraph update, since panels redraw often.
    """
    key = scene.name
    if key in _AREA_CACHE:
        return _AREA_CACHE[key]
    rows = []
    # Whether a planar sloping curve follows the terrain needs the occluders: gathered
    # only when such a curve is met.
    surface = occluder_surface()
    for obj in scene.objects:
        role = area_role(obj)
        if role is None:
            continue
        if obj.type != "CURVE":
            rows.append((role, obj.name, f"is a {obj.type.lower()}, not a curve"))
            continue
        try:
            rings = curve_rings(obj)
            geom = area_from_rings(obj.name, rings)
            check_flat_rings(obj, rings, surface)
            rows.append((role, obj.name, f"{geom.area:,.0f} m^2"))
        except AutoscoopError as e:
            rows.append((role, obj.name, str(e).removeprefix(f"{obj.name}: ")))
    _AREA_CACHE[key] = rows
    return rows


@bpy.app.handlers.persistent
def forget_area_report(*_args: Any) -> None:
    """depsgraph_update_post and load_post handler: the scene changed or another file
    was opened (whose scene may have the same name), check it again. Persistent: a
    handler that is not is dropped when a file is opened."""
    _AREA_CACHE.clear()


# --- optimize ----------------------------------------------------------------------------


class OptimizeJob:
    """One optimization run from the panel (see module docstring)."""

    def __init__(self, context: bpy.types.Context) -> None:
        props = context.scene.autoscoop
        self.scene_name = context.scene.name
        self.pack = pack_from(props)
        self.model = SensorPack.of(self.pack).models[0]
        self.settings = settings_from(props)
        reach = max(m.range_m for m in SensorPack.of(self.pack).models)
        self.scene_model = extract_scene(context.scene).cropped(reach)
        # Cameras the user marked as sensors stand already: the plan adds to them; so
        # do empties marked as masts, with free slots.
        existing = [camera_spec(o, self.model) for o in marked_cameras(context.scene)]
        masts = marked_masts(context.scene)
        self.run = Run(
            self.scene_model,
            BVHFactory.of(self.scene_model),
            self.pack,
            self.settings,
            existing=existing,
            existing_masts=masts,
        )
        self.steps = self.run.steps()
        self.progress = Progress("search", 0, 0.0, self.settings.rho, 0, 0)
        self.done = False
        self.stopping = False  # asked to end early with the best plan so far
        self._shown = len(existing)  # the live view shows new sensors only

    def step(self, budget_s: float) -> bool:
        """Work for about ``budget_s`` seconds; True when the run has finished."""
        deadline = time.perf_counter() + budget_s
        for progress in self.steps:
            self.progress = progress
            if progress.phase == "fixed":
                self._show_fixed()
            if time.perf_counter() > deadline:
                return False
        self.done = True
        return True

    def _show_fixed(self) -> None:
        """A camera for each sensor fixed since the last call, in the live collection."""
        scene = bpy.data.scenes[self.scene_name]
        live = bpy.data.collections.get(LIVE_COLLECTION)
        if live is None:
            live = bpy.data.collections.new(LIVE_COLLECTION)
            scene.collection.children.link(live)
        for k in range(self._shown, len(self.run.sensors)):
            p = self.run.sensors[k].pose
            xyz = self.scene_model.to_world(p.position)
            cam = sensor_camera(k + 1, xyz, p.pitch_deg, p.yaw_deg, self.run.problem.model)
            cam[names.IGNORE_PROP] = True
            live.objects.link(cam)
        self._shown = len(self.run.sensors)

    def finish(self, context: bpy.types.Context) -> dict[str, Any]:
        """Replace the results collection with the run's layout; the result dict."""
        while not self.done:
            self.step(math.inf)
        remove_live()
        result = self.run.result()
        spawn_results(context.scene, result)
        doc = result_dict(result, {"blender": bpy.app.version_string})
        _remember(context.scene, result, doc)
        apply_result_visibility(context.scene)
        return doc

    def cancel(self) -> None:
        """Drop the run: the scene keeps exactly what it had before it started."""
        self.steps.close()
        remove_live()


def remove_live() -> None:
    """Delete the live collection of a run and the cameras in it."""
    live = bpy.data.collections.get(LIVE_COLLECTION)
    if live is None:
        return
    cams = [o.data for o in live.objects if o.type == "CAMERA"]
    bpy.data.batch_remove(list(live.objects))
    bpy.data.batch_remove([c for c in cams if c.users == 0])
    bpy.data.collections.remove(live)


def _remember(scene: bpy.types.Scene, result: Result, doc: dict[str, Any]) -> None:
    text = json.dumps(doc)
    scene.autoscoop.result_json = text
    _LAST[scene.name] = (result, doc, text)


# --- evaluate ------------------------------------------------------------------------


def sensor_cameras(scene: bpy.types.Scene) -> list[bpy.types.Object]:
    """Cameras to evaluate: those of the results collection and those the user marked
    as sensors (``autoscoop_role = "sensor"``), each sensor once, in a stable order."""
    results = find_results(scene)
    spawned = [o for o in results.all_objects if o.type == "CAMERA"] if results else []
    marked = [o for o in marked_cameras(scene) if o not in spawned]
    # A plan shows the sensors that stood already as cameras of its own: where the
    # user's marked camera stands too, that one counts, once.
    stand = [np.array(o.matrix_world) for o in marked]
    spawned = [
        o for o in spawned
        if not (o.get("existing") and any(np.allclose(np.array(o.matrix_world), m, atol=1e-3)
                                          for m in stand))
    ]  # fmt: skip
    return sorted(spawned, key=lambda o: o.name) + marked


def marked_cameras(scene: bpy.types.Scene) -> list[bpy.types.Object]:
    """Cameras the user marked as sensors (``autoscoop_role = "sensor"``), by name."""
    marked = [
        o for o in scene.objects
        if o.type == "CAMERA" and o.get(names.ROLE_PROP) == names.ROLE_SENSOR
    ]  # fmt: skip
    return sorted(marked, key=lambda o: o.name)


def marked_masts(scene: bpy.types.Scene) -> list[tuple[float, float]]:
    """World (x, y) of the empties the user marked as masts that stand already
    (``autoscoop_role = "mast"``), by name: sites where a new sensor adds no mast."""
    marked = [
        o for o in scene.objects
        if o.type == "EMPTY" and o.get(names.ROLE_PROP) == names.ROLE_MAST
    ]  # fmt: skip
    return [
        (float(o.matrix_world.translation.x), float(o.matrix_world.translation.y))
        for o in sorted(marked, key=lambda o: o.name)
    ]


def camera_spec(obj: bpy.types.Object, fallback: SensorModel) -> SensorSpec:
    """Where a camera stands and looks (world), as a sensor at the camera's own height;
    its own model if it has one."""
    m = np.array(obj.matrix_world)
    forward = -m[:3, 2] / np.linalg.norm(m[:3, 2])
    yaw = math.degrees(math.atan2(forward[1], forward[0])) % 360.0
    pitch = math.degrees(math.asin(float(np.clip(-forward[2], -1.0, 1.0))))
    model = fallback
    if MODEL_PROP in obj:
        model = SensorModel.from_spec(dict(obj[MODEL_PROP]), f"{obj.name}: model")
    return SensorSpec(model, float(m[0, 3]), float(m[1, 3]), None, pitch, yaw, z=float(m[2, 3]))


def evaluated_now(scene: bpy.types.Scene) -> Result:
    """The coverage of the scene's sensor cameras where they stand now (what
    ``headless coverage`` computes for those poses)."""
    props = scene.autoscoop
    cams = sensor_cameras(scene)
    if not cams:
        raise InputError(
            "no sensor to evaluate: run Optimize, or mark cameras as sensors in the panel"
        )
    fallback = model_from(props)
    specs = [camera_spec(o, fallback) for o in cams]
    scene_model = extract_scene(scene).cropped(max(s.model.range_m for s in specs))
    caster = BVHFactory.of(scene_model)()
    return evaluate_layout(scene_model, caster, specs, coverage_settings_from(props))


def evaluate_cameras(context: bpy.types.Context) -> dict[str, Any]:
    """Coverage of the sensor cameras where they stand now; results replaced."""
    scene = context.scene
    result = evaluated_now(scene)
    doc = coverage_dict(result)
    spawn_results(scene, result)
    _remember(scene, result, doc)
    apply_result_visibility(scene)
    return doc


# --- results display and exports -----------------------------------------------------


def apply_result_visibility(scene: bpy.types.Scene) -> None:
    """Show or hide the frusta, footprints and coverage groups as the panel says."""
    results = find_results(scene)
    if results is None:
        return
    props = scene.autoscoop
    for child in results.children:
        show = {
            FRUSTA_COLLECTION: props.show_frusta,
            FOOTPRINTS_COLLECTION: props.show_footprints,
            COVERAGE_COLLECTION: props.show_coverage,
        }.get(child.name.split(".")[0], True)
        child.hide_viewport = not show
        child.hide_render = not show


def last_layout(scene: bpy.types.Scene) -> tuple[Result, dict[str, Any]] | None:
    """The layout behind the scene's current result, if this session made it (an undo
    or another file leaves the scene's result and the remembered one apart)."""
    entry = _LAST.get(scene.name)
    if entry is None or entry[2] != scene.autoscoop.result_json:
        return None
    return entry[0], entry[1]


def export(scene: bpy.types.Scene, kind: str, folder: str) -> tuple[list[Path], str | None]:
    """Write one report (JSON, CSV, GEOJSON or PNG) of the last layout (a plan edited
    by hand since: as it stands, counted again, with the optimizer's figures under
    ``as_optimized``): its paths, and a note when the scene has no CRS. GEOJSON writes sensors_local.geojson, and with
    the scene's CRS also sensors.geojson (WGS84) and plan.gpkg (``reports.gis_files``)."""
    layout = last_layout(scene)
    current = json.loads(scene.autoscoop.result_json or "{}")
    if layout is None and current.get("edited"):
        # Edited by hand: the plan as it stands, counted again; the optimizer's
        # figures kept apart, as its plan's.
        result = evaluated_now(scene)
        doc = {**coverage_dict(result), "edited": True}
        doc["as_optimized"] = current.get("as_optimized", {})
        layout = result, doc
    if layout is None:
        raise InputError("no result in this session: run Optimize or Evaluate first")
    result, doc = layout
    out = Path(bpy.path.abspath(folder or "//"))
    if not str(out).strip() or (not bpy.data.filepath and folder.startswith("//")):
        raise InputError("save the .blend file first, or choose an absolute export folder")
    out.mkdir(parents=True, exist_ok=True)
    note = None
    if kind == "GEOJSON":
        data, note = gis_files(result)
    else:
        files = {
            "JSON": ("result.json", lambda: json.dumps(doc, indent=2) + "\n"),
            "CSV": ("sensors.csv", lambda: sensors_csv(result)),
            "PNG": ("coverage.png", lambda: render_png(result)),
        }
        name, make = files[kind]
        data = {name: make()}
    paths = []
    for name, content in data.items():
        path = out / name
        path.write_bytes(content if isinstance(content, bytes) else content.encode("utf-8"))
        paths.append(path)
    return paths, note
