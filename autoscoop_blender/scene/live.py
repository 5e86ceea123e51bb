"""Live coverage in the viewport: when a sensor camera moves, turns, or is re-parented,
its coverage is evaluated again and the Results panel, ``scene.autoscoop.result_json``
and the coverage colouring follow, without a button.

The layout (``core.live.LiveLayout``: the ground grid, the evaluator, each sensor's
covered points and the counts) is cached per scene by name, built at the first
change after an Optimize or Evaluate, and dropped when the scene's own geometry
changes (a mesh or curve outside the results moves or is edited), when the sensors
are added or removed, or when another file is opened.

The ``depsgraph_update_post`` handler only notes which scene's sensors changed (moved,
turned, re-parented, added or deleted); the work runs:
- in background mode (scripts, ``blender --background``), in the handler itself, so a
  script that moves a camera and calls ``view_layer.update()`` reads the new metrics;
- with a user interface, in a timer 50 ms later, once for all the changes made by
  then (a drag gives many updates; at most one evaluation is in flight).

Nothing here keeps a Blender ID: only names and numpy.
"""

from __future__ import annotations

import json
from dataclasses import dataclass
from typing import Any

import bpy
import numpy as np

from .. import names as names_mod
from ..core.errors import AutoscoopError, InputError
from ..core.live import LiveLayout
from ..core.model.sensors import SensorModel, SensorSpec
from . import pipeline
from .extract import extract_scene
from .factory import BVHFactory
from .spawn import (
    COVERAGE_ATTR,
    COVERAGE_COLOR_ATTR,
    COVERAGE_NAME,
    SENSOR_PROP,
    coverage_colors,
    find_results,
    sensor_camera,
)

# Seconds between the first change and the re-score, with a user interface.
DELAY_S = 0.05
# A misplaced sensor camera's object colour, and where its own colour is kept.
MISPLACED_RGBA = (1.0, 0.1, 0.1, 1.0)
KEPT_COLOR_PROP = "autoscoop_own_color"


@dataclass
class _Entry:
    """A scene's cached layout and which camera is which sensor (by name)."""

    live: LiveLayout
    cameras: list[str]
    fallback: SensorModel  # the panel's model when the layout was scored


_CACHE: dict[str, _Entry] = {}
_PENDING: set[str] = set()
# Per scene: which result (its keys but those this module writes) and how its sensor
# cameras stood when it was made. No layout is built while they stand so: a plan just
# spawned costs nothing more to show, however large the ground.
_BASELINE: dict[str, tuple[int, dict[str, SensorSpec]]] = {}
_LIVE_KEYS = ("metrics", "edited", "as_optimized")


def cached(scene_name: str) -> LiveLayout | None:
    """The scene's live layout, if one is cached."""
    entry = _CACHE.get(scene_name)
    return entry.live if entry else None


def alone(scene_name: str, camera: str) -> tuple[float, float, float] | None:
    """What the sensor camera named ``camera`` covers in the cached layout: (m^2, share
    of the target, m^2 the layout would lose without it); None when not cached."""
    entry = _CACHE.get(scene_name)
    if entry is None or camera not in entry.cameras:
        return None
    a = entry.live.alone(entry.cameras.index(camera))
    return a.covers_m2, a.share, a.lost_m2


def forget(scene_name: str | None = None) -> None:
    """Drop the cached layout of a scene (None: of every scene)."""
    if scene_name is None:
        _CACHE.clear()
        _PENDING.clear()
        _BASELINE.clear()
    else:
        _CACHE.pop(scene_name, None)


def _sensor_names(scene: bpy.types.Scene) -> set[str]:
    return {o.name for o in pipeline.sensor_cameras(scene)}


def _is_results(obj: bpy.types.Object, results: bpy.types.Collection | None) -> bool:
    return results is not None and obj.name in results.all_objects


def _model_changed(scene: bpy.types.Scene, entry: _Entry) -> bool:
    """Whether the panel's sensor model (that of every camera without its own) is not
    the one the layout was scored with."""
    try:
        return pipeline.model_from(scene.autoscoop) != entry.fallback
    except AutoscoopError:
        return False  # a model being typed in: scored once it reads


@bpy.app.handlers.persistent
def on_depsgraph(scene: bpy.types.Scene, depsgraph: bpy.types.Depsgraph) -> None:
    """depsgraph_update_post: note a moved sensor camera (re-score), or drop the cache
    when the scene's own geometry changed."""
    if not scene.autoscoop.result_json:
        return  # no plan or evaluation to keep current
    results = find_results(scene)
    sensors: set[str] | None = None
    moved = False
    for update in depsgraph.updates:
        obj = update.id
        if isinstance(obj, (bpy.types.Collection, bpy.types.Scene)):
            # Objects added or deleted: did the sensors change?
            entry = _CACHE.get(scene.name)
            if entry is not None:
                sensors = _sensor_names(scene) if sensors is None else sensors
                moved = moved or set(entry.cameras) != sensors or _model_changed(scene, entry)
            continue
        if not isinstance(obj, bpy.types.Object):
            continue
        obj = obj.original
        if sensors is None:
            sensors = _sensor_names(scene)
        if obj.name in sensors or obj.type == "EMPTY":
            # A sensor (moved, turned, its model edited), or a mast it may be on: the
            # re-score compares every sensor with what it was.
            moved = True
        elif obj.type in {"MESH", "CURVE"} and not _is_results(obj, results):
            if update.is_updated_geometry or update.is_updated_transform:
                forget(scene.name)  # a wall, the terrain or an area: built anew next time
    if not moved:
        return
    _PENDING.add(scene.name)
    if bpy.app.background:
        run_pending()
    elif not bpy.app.timers.is_registered(run_pending):
        bpy.app.timers.register(run_pending, first_interval=DELAY_S)


def run_pending() -> None:
    """Re-score every scene noted as changed (a timer: returns None, runs once)."""
    names = list(_PENDING)
    _PENDING.clear()
    for name in names:
        scene = bpy.data.scenes.get(name)
        if scene is None:
            forget(name)
            continue
        try:
            rescore(scene, force=False)
        except AutoscoopError as e:  # a camera's model that does not read: say so
            scene.autoscoop.live_error = str(e)
    return None


def _as_left(scene: bpy.types.Scene, names: list[str], specs: list[SensorSpec]) -> bool:
    """Whether the sensor cameras stand as the scene's result left them (the first
    look at a result records how they stand)."""
    doc = json.loads(scene.autoscoop.result_json or "{}")
    key = hash(json.dumps({k: v for k, v in doc.items() if k not in _LIVE_KEYS}, sort_keys=True))
    now = dict(zip(names, specs))
    base = _BASELINE.get(scene.name)
    if base is None or base[0] != key:
        _BASELINE[scene.name] = (key, now)
        return True
    return base[1] == now


def rescore(scene: bpy.types.Scene, force: bool = True) -> dict[str, Any] | None:
    """Bring the scene's metrics and coverage colouring up to date with its sensor
    cameras as they stand; the new metrics (None: no sensors, or, unless ``force``,
    no layout built and the cameras as the result left them)."""
    cams = pipeline.sensor_cameras(scene)
    if not cams:
        forget(scene.name)
        return None
    props = scene.autoscoop
    fallback = pipeline.model_from(props)
    specs = [pipeline.camera_spec(o, fallback) for o in cams]
    names = [o.name for o in cams]
    entry = _CACHE.get(scene.name)
    if entry is None and not force and _as_left(scene, names, specs):
        return None
    if entry is None or entry.cameras != names or _out_of_reach(entry.live, specs):
        entry = _Entry(_build(scene, specs), names, fallback)
        _CACHE[scene.name] = entry
        changed = True
    else:
        entry.fallback = fallback
        moved = [i for i, spec in enumerate(specs) if spec != entry.live.specs[i]]
        for i in moved:
            entry.live.move(i, specs[i])
        changed = bool(moved)
    metrics = entry.live.metrics()
    _write_metrics(scene, metrics)
    if changed:  # (a selection or an update of nothing that counts leaves the colours)
        _color(scene, entry.live.counts)
    _mark_misplaced(cams, entry.live.problems)
    props.live_error = ""
    return metrics


def snap(scene: bpy.types.Scene, obj: bpy.types.Object) -> str:
    """Move the sensor camera ``obj`` to the nearest place its mast may stand, at the
    same height above the ground (``LiveLayout.snapped``); what was done, in words.
    InputError when ``obj`` is no sensor camera or no such place is within its range."""
    rescore(scene)
    entry = _CACHE.get(scene.name)
    if entry is None or obj.name not in entry.cameras:
        raise InputError(f"{obj.name}: not a sensor camera (run Optimize, or mark it a sensor)")
    i = entry.cameras.index(obj.name)
    spec = entry.live.snapped(i)
    if spec is None:
        reach = entry.live.specs[i].model.range_m
        raise InputError(f"{obj.name}: no place a mast may stand within its range of {reach:g} m")
    if spec == entry.live.specs[i]:
        return f"{obj.name} stands where a mast may already"
    m = obj.matrix_world.copy()
    m.translation = (spec.x, spec.y, spec.z if spec.z is not None else m.translation.z)
    obj.matrix_world = m
    bpy.context.view_layer.update()
    return f"{obj.name} moved to ({spec.x:.2f}, {spec.y:.2f})"


def fill_gap(scene: bpy.types.Scene) -> str:
    """Add the one sensor camera (the panel's model) that raises the most target points
    now short of their k (``LiveLayout.best_addition``: the standing masts first);
    what was done, in words. InputError when nothing is uncovered or no place sees it."""
    rescore(scene)
    entry = _CACHE.get(scene.name)
    if entry is None:
        raise InputError("no sensors: run Optimize, or mark cameras as sensors")
    layout = entry.live
    model = pipeline.model_from(scene.autoscoop)
    if model.range_m > layout.reach_m:
        forget(scene.name)  # built for shorter sensors: once more, for this one
        rescore(scene)
        layout = _CACHE[scene.name].live
    uncovered = layout.metrics()["uncovered_m2"]
    add = layout.best_addition(model)
    if add is None:
        what = "nothing is uncovered" if uncovered == 0 else "no place a mast may stand sees"
        raise InputError(f"no sensor to add: {what} the uncovered target")
    spec = add.spec
    local = scene_local(layout, spec)
    ground = float(layout.grid.ground_z(local[None])[0])
    z = ground + float(spec.height_m or 0.0) + float(layout.scene.origin[2])
    cams = pipeline.sensor_cameras(scene)
    n = 1 + max((int(o.get(SENSOR_PROP, 0)) for o in cams), default=0)
    cam = sensor_camera(n, (spec.x, spec.y, z), spec.pitch_deg, spec.yaw_deg, model)
    cam["height_m"] = float(spec.height_m or 0.0)
    home = cams[0].users_collection[0] if cams else scene.collection
    home.objects.link(cam)
    bpy.context.view_layer.update()
    where = "on a mast that stands" if add.on_standing_mast else "on a new mast"
    m2 = add.gain_points * layout.cell_m2
    return (
        f"{cam.name} added {where} at ({spec.x:.1f}, {spec.y:.1f}): it raises {m2:,.0f} m^2 "
        f"of the {uncovered:,.0f} m^2 short of their k (one sensor's reach)"
    )


def keep_selected(scene: bpy.types.Scene, selected: list[bpy.types.Object]) -> list[str]:
    """Before "Re-plan the rest": the selected sensor cameras of the plan become the
    user's own, marked as sensors that stand (the next Optimize keeps them as they
    stand and plans around them; ``OptimizeJob``); their names. InputError when none of
    the selected is a sensor camera."""
    sensors = {o.name for o in pipeline.sensor_cameras(scene)}
    keep = [o for o in selected if o.name in sensors]
    if not keep:
        raise InputError("select the sensor cameras to keep, then Re-plan the Rest")
    results = find_results(scene)
    names = []
    for obj in keep:
        if results is not None and obj.name in results.all_objects:
            own = obj.copy()  # the results are replaced by the run: a copy of one's own
            own.data = obj.data.copy()
            own.name = f"Kept {obj.name}"
            scene.collection.objects.link(own)
            obj = own
        obj[names_mod.ROLE_PROP] = names_mod.ROLE_SENSOR
        names.append(obj.name)
    return names


def scene_local(layout: LiveLayout, spec: SensorSpec) -> np.ndarray:
    """(2,) the local x, y of a world spec."""
    return layout.scene.to_local(np.array([[spec.x, spec.y]], dtype=float))[0]


def problems(scene_name: str) -> list[tuple[str, str]]:
    """The sensor cameras whose mast may not stand where it does, with why."""
    entry = _CACHE.get(scene_name)
    if entry is None:
        return []
    return [(c, p) for c, p in zip(entry.cameras, entry.live.problems) if p is not None]


def check_export(scene: bpy.types.Scene) -> None:
    """InputError naming the first misplaced sensor camera, unless the user chose to
    export the plan anyway (``export_misplaced``)."""
    misplaced = problems(scene.name)
    if misplaced and not scene.autoscoop.export_misplaced:
        name, why = misplaced[0]
        more = f" (and {len(misplaced) - 1} more)" if len(misplaced) > 1 else ""
        raise InputError(
            f"{name}: stands {why}{more}; move it, or tick Export Anyway to export the plan"
        )


def _mark_misplaced(cams: list[bpy.types.Object], why: list[str | None]) -> None:
    """Misplaced cameras turn red (their object colour, kept to be given back)."""
    for obj, problem in zip(cams, why):
        if problem is not None and KEPT_COLOR_PROP not in obj:
            obj[KEPT_COLOR_PROP] = list(obj.color)
            obj.color = MISPLACED_RGBA
        elif problem is None and KEPT_COLOR_PROP in obj:
            obj.color = obj[KEPT_COLOR_PROP]
            del obj[KEPT_COLOR_PROP]


def _out_of_reach(live: LiveLayout, specs: list[SensorSpec]) -> bool:
    return max(s.model.range_m for s in specs) > live.reach_m


def _build(scene: bpy.types.Scene, specs: list[SensorSpec]) -> LiveLayout:
    props = scene.autoscoop
    reach = max(s.model.range_m for s in specs)
    model = extract_scene(scene).cropped(reach)
    settings = pipeline.settings_from(props)
    return LiveLayout(
        model,
        BVHFactory.of(model)(),
        specs,
        pipeline.coverage_settings_from(props),
        reach_m=reach,
        mast_cost=settings.mast_cost,
        sensor_cost=settings.sensor_cost,
    )


def _write_metrics(scene: bpy.types.Scene, metrics: dict[str, Any]) -> None:
    """The layout's metrics into the scene's result, marked as edited by hand when they
    differ from what the optimizer or Evaluate found. The plan as optimized (its cost,
    bound and gap) is kept under ``as_optimized``; the edited plan has no bound."""
    props = scene.autoscoop
    doc = json.loads(props.result_json)
    old = doc.setdefault("metrics", {})
    new = {k: metrics[k] for k in ("coverage_fraction", "covered_m2", "sensors", "masts")}
    if "cost" in old:
        new["cost"] = metrics["cost"]
    if all(old.get(k) == v for k, v in new.items()):
        return  # as planned or evaluated (the spawn's own update comes here)
    if "as_optimized" not in doc:  # the first edit: what the optimizer's plan was
        keep = ("objective", "cost", "lower_bound", "gap", "sensors", "masts", "coverage_fraction")
        doc["as_optimized"] = {k: old[k] for k in keep if old.get(k) is not None}
    old.update(new, uncovered_m2=metrics["uncovered_m2"])
    # A bound is the optimizer's, about its plan: none is proven for the edited one.
    old.update(lower_bound=None, gap=None)
    doc["edited"] = True
    props.result_json = json.dumps(doc)


def _color(scene: bpy.types.Scene, counts: np.ndarray) -> None:
    """The coverage points' counts and colours, where the mesh holds one face a point."""
    results = find_results(scene)
    if results is None:
        return
    obj = next((o for o in results.all_objects if o.name.startswith(COVERAGE_NAME)), None)
    if obj is None or obj.type != "MESH" or len(obj.data.polygons) != len(counts):
        return
    mesh = obj.data
    values = np.asarray(counts, dtype=np.int32)
    mesh.attributes[COVERAGE_ATTR].data.foreach_set("value", values)
    rgba = np.repeat(coverage_colors(values), 4, axis=0).ravel()
    mesh.color_attributes[COVERAGE_COLOR_ATTR].data.foreach_set("color_srgb", rgba)
    mesh.update()


@bpy.app.handlers.persistent
def on_load(*_args: Any) -> None:
    """load_post: another file, other scenes."""
    forget()


HANDLERS = (
    (bpy.app.handlers.depsgraph_update_post, on_depsgraph),
    (bpy.app.handlers.load_post, on_load),
)


def register() -> None:
    for handlers, fn in HANDLERS:
        if fn not in handlers:
            handlers.append(fn)


def unregister() -> None:
    for handlers, fn in HANDLERS:
        if fn in handlers:
            handlers.remove(fn)
    if bpy.app.timers.is_registered(run_pending):
        bpy.app.timers.unregister(run_pending)
    forget()
