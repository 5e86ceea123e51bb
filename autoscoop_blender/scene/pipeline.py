"""The panel's jobs, on the same pipeline as ``python -m headless``.

``OptimizeJob`` snapshots the scene into numpy at the start (``extract_scene``, the
BVHTree caster, ``core.optimize.OptimizationRun``), is stepped in time slices by the
modal operator or drained by ``execute``, shows each fixed sensor as a camera in a
temporary collection while it runs, and on ``finish`` writes the results collection
(``spawn.spawn_results``) — the same poses ``headless optimize`` finds for the same
seed. ``cancel`` removes the temporary collection, so the scene is as it was.

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
from ..core.analysis import CoverageSettings, evaluate_sensors
from ..core.errors import AutoscoopError, InputError
from ..core.es import ESParams
from ..core.optimize import OptimizationRun, OptimizeSettings, Progress, reference_footprint_m2
from ..core.placement import Placement, SensorRecord
from ..core.report_png import render_png
from ..core.reports import result_dict, sensors_csv, sensors_geojson
from ..core.scene_model import area_from_rings
from ..core.sensor_file import SensorSpec
from ..core.sensors import SensorModel
from .bvh import BVHCaster
from .extract import area_role, curve_rings, extract_scene
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
_LAST: dict[str, tuple[Placement, dict[str, Any], str]] = {}


# --- settings ------------------------------------------------------------------------


def model_from(props: Any) -> SensorModel:
    """The panel's sensor model, validated (InputError names the setting)."""
    return props.sensor_model().validated("Sensor")


def settings_from(props: Any) -> OptimizeSettings:
    """The panel's optimizer settings, validated."""
    es = ESParams(
        mu=props.es_mu, lam=props.es_lam, eps=props.es_eps, max_epochs=props.es_max_epochs
    )
    return OptimizeSettings(
        optimizer=props.optimizer,
        method=props.method,
        grid_m=props.grid_m,
        rho=props.rho,
        seed=props.seed,
        es=es,
    ).validated()


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
    for obj in scene.objects:
        role = area_role(obj)
        if role is None:
            continue
        if obj.type != "CURVE":
            rows.append((role, obj.name, f"is a {obj.type.lower()}, not a curve"))
            continue
        try:
            geom = area_from_rings(obj.name, curve_rings(obj))
            rows.append((role, obj.name, f"{geom.area:,.0f} m^2"))
        except AutoscoopError as e:
            rows.append((role, obj.name, str(e).removeprefix(f"{obj.name}: ")))
    _AREA_CACHE[key] = rows
    return rows


def forget_area_report(*_args: Any) -> None:
    """depsgraph_update_post handler: the scene changed, check it again."""
    _AREA_CACHE.clear()


# --- optimize ----------------------------------------------------------------------------


class OptimizeJob:
    """One optimization run from the panel (see module docstring)."""

    def __init__(self, context: bpy.types.Context) -> None:
        props = context.scene.autoscoop
        self.scene_name = context.scene.name
        self.model = model_from(props)
        self.settings = settings_from(props)
        self.scene_model = extract_scene(context.scene).cropped(self.model.range_m)
        caster = BVHCaster.from_scene(self.scene_model)
        self.run = OptimizationRun(self.scene_model, caster, self.model, self.settings)
        self.steps = self.run.steps()
        self.progress = Progress("search", 0, 0.0, self.settings.rho, 0, 0)
        self.done = False
        self._shown = 0

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
        ox, oy, oz = (float(v) for v in self.scene_model.origin)
        for k in range(self._shown, len(self.run.sensors)):
            p = self.run.sensors[k].pose
            rec = SensorRecord(
                k + 1, p.x + ox, p.y + oy, p.z + oz, p.height_m, p.pitch_deg, p.yaw_deg,
                self.model, -1, 0.0, 0, 0.0, 0.0, None,  # type: ignore[arg-type]
            )  # fmt: skip
            cam = sensor_camera(rec)
            cam[names.IGNORE_PROP] = True
            live.objects.link(cam)
        self._shown = len(self.run.sensors)

    def finish(self, context: bpy.types.Context) -> dict[str, Any]:
        """Replace the results collection with the run's layout; the result dict."""
        while not self.done:
            self.step(math.inf)
        remove_live()
        result = self.run.result()
        placement = result.placement()
        spawn_results(context.scene, placement, ground_z=_ground_z(result.grid, self.scene_model))
        doc = result_dict(result, placement, {"blender": bpy.app.version_string})
        _remember(context.scene, placement, doc)
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


def _ground_z(grid: Any, scene_model: Any):
    def ground_z(xy_world: np.ndarray) -> np.ndarray:
        z, _ = grid.drop(scene_model.to_local(xy_world))
        return z + scene_model.origin[2]

    return ground_z


def _remember(scene: bpy.types.Scene, placement: Placement, doc: dict[str, Any]) -> None:
    text = json.dumps(doc)
    scene.autoscoop.result_json = text
    _LAST[scene.name] = (placement, doc, text)


# --- evaluate ------------------------------------------------------------------------


def sensor_cameras(scene: bpy.types.Scene) -> list[bpy.types.Object]:
    """Cameras to evaluate: those of the results collection and those the user marked
    as sensors (``autoscoop_role = "sensor"``), in a stable order."""
    results = find_results(scene)
    spawned = [o for o in results.all_objects if o.type == "CAMERA"] if results else []
    marked = [
        o for o in scene.objects
        if o.type == "CAMERA" and o.get(names.ROLE_PROP) == names.ROLE_SENSOR and o not in spawned
    ]  # fmt: skip
    return sorted(spawned, key=lambda o: o.name) + sorted(marked, key=lambda o: o.name)


def camera_spec(obj: bpy.types.Object, fallback: SensorModel) -> SensorSpec:
    """Where a camera stands and looks (world), as a sensor; its own model if it has one."""
    m = np.array(obj.matrix_world)
    forward = -m[:3, 2] / np.linalg.norm(m[:3, 2])
    yaw = math.degrees(math.atan2(forward[1], forward[0])) % 360.0
    pitch = math.degrees(math.asin(float(np.clip(-forward[2], -1.0, 1.0))))
    model = fallback
    if MODEL_PROP in obj:
        model = SensorModel.from_spec(dict(obj[MODEL_PROP]), f"{obj.name}: model")
    return SensorSpec(model, float(m[0, 3]), float(m[1, 3]), None, pitch, yaw)


def evaluate_cameras(context: bpy.types.Context) -> dict[str, Any]:
    """Coverage of the sensor cameras where they stand now; results replaced."""
    scene = context.scene
    props = scene.autoscoop
    cams = sensor_cameras(scene)
    if not cams:
        raise InputError(
            "no sensor to evaluate: run Optimize, or mark cameras as sensors in the panel"
        )
    fallback = model_from(props)
    specs = [camera_spec(o, fallback) for o in cams]
    scene_model = extract_scene(scene).cropped(max(s.model.range_m for s in specs))
    caster = BVHCaster.from_scene(scene_model)
    # The camera's own z (wherever the user moved it) sets its height over the ground.
    specs = _with_heights(specs, cams, scene_model, caster)
    settings = CoverageSettings(method=props.method, grid_m=props.grid_m)
    result = evaluate_sensors(scene_model, caster, specs, settings)
    placement = result.placement()
    doc = result.to_dict()
    doc["metrics"] = {
        "coverage_fraction": doc["coverage_fraction"],
        "sensors": len(placement.sensors),
        "masts": len(placement.masts),
        "cluster_ratio": round(len(placement.masts) / len(placement.sensors), 4),
        "overlap_factor": round(
            sum(s.covered_target_m2 for s in placement.sensors) / result.grid.target_area_m2, 4
        ),
        "wall_s": doc["wall_s"],
        "rays_cast": doc["rays_cast"],
    }
    spawn_results(scene, placement, ground_z=_ground_z(result.grid, scene_model))
    _remember(scene, placement, doc)
    apply_result_visibility(scene)
    return doc


def _with_heights(specs, cams, scene_model, caster) -> list[SensorSpec]:
    """Specs whose height is the camera's height above the top surface under it."""
    from ..core.raycast import FloorCaster

    floor = FloorCaster(caster, scene_model.floor_z())
    _, top = scene_model.z_range()
    out = []
    for spec, cam in zip(specs, cams):
        x, y = scene_model.to_local(np.array([spec.x, spec.y]))
        origin = np.array([[x, y, top + 1.0]])
        dist = floor.cast(origin, np.array([[0.0, 0.0, -1.0]]), top - scene_model.floor_z() + 2.0)
        ground = top + 1.0 - float(dist[0])
        z = cam.matrix_world.translation.z - scene_model.origin[2]
        out.append(replace(spec, height_m=max(z - ground, 0.0)))
    return out


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


def last_layout(scene: bpy.types.Scene) -> tuple[Placement, dict[str, Any]] | None:
    """The layout behind the scene's current result, if this session made it (an undo
    or another file leaves the scene's result and the remembered one apart)."""
    entry = _LAST.get(scene.name)
    if entry is None or entry[2] != scene.autoscoop.result_json:
        return None
    return entry[0], entry[1]


def export(scene: bpy.types.Scene, kind: str, folder: str) -> Path:
    """Write one report (JSON, CSV, GEOJSON or PNG) of the last layout; its path."""
    layout = last_layout(scene)
    if layout is None:
        raise InputError("no result in this session: run Optimize or Evaluate first")
    placement, doc = layout
    out = Path(bpy.path.abspath(folder or "//"))
    if not str(out).strip() or (not bpy.data.filepath and folder.startswith("//")):
        raise InputError("save the .blend file first, or choose an absolute export folder")
    out.mkdir(parents=True, exist_ok=True)
    files = {
        "JSON": ("result.json", lambda: json.dumps(doc, indent=2) + "\n"),
        "CSV": ("sensors.csv", lambda: sensors_csv(placement)),
        "GEOJSON": ("sensors.geojson", lambda: json.dumps(sensors_geojson(placement)) + "\n"),
        "PNG": ("coverage.png", lambda: render_png(placement)),
    }
    name, make = files[kind]
    data = make()
    path = out / name
    path.write_bytes(data if isinstance(data, bytes) else data.encode("utf-8"))
    return path
