"""Operators: optimize (modal), evaluate, mark objects, check the scene, export.

Every operator turns a user mistake (``AutoscoopError``) into ``self.report`` and
``{"CANCELLED"}``; anything else is a bug and raises. The work itself is in
``scene.pipeline``, shared with ``python -m headless``.
"""

from __future__ import annotations

import time

import bpy
from bpy.props import EnumProperty

from . import names
from .core.errors import AutoscoopError
from .core.optimize.base import Progress
from .io.progress_text import progress_text
from .scene import live, pipeline


def _fail(op: bpy.types.Operator, error: AutoscoopError) -> set[str]:
    op.report({"ERROR"}, str(error))
    return {"CANCELLED"}


def status_text(p: Progress, elapsed_s: float, optimizer: str, stopping: bool) -> str:
    """The status bar's line while a run works: the same facts in the same words as
    the command line's progress lines, and what Esc does now."""
    if stopping:
        esc = "stopping: Esc again to cancel"
    elif optimizer == "lp":
        esc = "Esc to stop with the best plan"
    else:
        esc = "Esc to cancel"
    return f"AutoSCOOP: {progress_text(p, elapsed_s)}  -  {esc}"


class AUTOSCOOP_OT_optimize(bpy.types.Operator):
    """Place sensors until the coverage goal is met (Esc: the lp optimizer keeps its
    best plan so far; otherwise, or at a second Esc, cancel and change nothing)"""

    bl_idname = names.OP_OPTIMIZE
    bl_label = "Optimize"
    bl_options = {"REGISTER", "UNDO"}

    _budget_s = 0.04  # a time slice: the UI stays responsive between slices
    _job: pipeline.OptimizeJob | None = None
    _timer = None

    def _start(self, context: bpy.types.Context) -> pipeline.OptimizeJob | None:
        try:
            job = pipeline.OptimizeJob(context)
        except AutoscoopError as e:
            _fail(self, e)
            return None
        for area in job.run.blind_areas():
            self.report({"WARNING"}, f"{area}: no line of sight to any target point")
        return job

    def _finish(self, context: bpy.types.Context, job: pipeline.OptimizeJob) -> set[str]:
        doc = job.finish(context)
        m = doc["metrics"]
        level = "INFO" if m["coverage_fraction"] >= job.settings.rho else "WARNING"
        self.report(
            {level},
            f"{m['sensors']} sensors on {m['masts']} masts cover "
            f"{m['coverage_fraction']:.1%} ({doc['stop_reason']})",
        )
        return {"FINISHED"}

    def execute(self, context: bpy.types.Context) -> set[str]:
        job = self._start(context)
        if job is None:
            return {"CANCELLED"}
        return self._finish(context, job)

    def invoke(self, context: bpy.types.Context, event: bpy.types.Event) -> set[str]:
        if bpy.app.background or context.window is None:
            return self.execute(context)
        self._job = self._start(context)
        if self._job is None:
            return {"CANCELLED"}
        wm = context.window_manager
        self._timer = wm.event_timer_add(0.05, window=context.window)
        wm.modal_handler_add(self)
        wm.progress_begin(0, 1000)
        return {"RUNNING_MODAL"}

    def modal(self, context: bpy.types.Context, event: bpy.types.Event) -> set[str]:
        job = self._job
        assert job is not None
        if event.type == "ESC":
            # The first Esc ends an optimizer that keeps its best plan (lp) early;
            # otherwise, or at the second Esc, the run is dropped.
            if not job.stopping and job.run.stop_early():
                job.stopping = True
                self.report({"INFO"}, "Stopping: keeping the best plan so far (Esc again cancels)")
                return {"RUNNING_MODAL"}
            job.cancel()
            self._cleanup(context)
            self.report({"INFO"}, "Optimization cancelled; nothing was changed")
            return {"CANCELLED"}
        if event.type != "TIMER":
            return {"PASS_THROUGH"}
        done = job.step(self._budget_s)
        p = job.progress
        context.window_manager.progress_update(int(1000 * p.fraction))
        elapsed = time.perf_counter() - job.run.t0
        text = status_text(p, elapsed, job.settings.optimizer, job.stopping)
        context.workspace.status_text_set(text)
        if not done:
            return {"RUNNING_MODAL"}
        self._cleanup(context)
        return self._finish(context, job)

    def cancel(self, context: bpy.types.Context) -> None:
        if self._job is not None:
            self._job.cancel()
        self._cleanup(context)

    def _cleanup(self, context: bpy.types.Context) -> None:
        wm = context.window_manager
        if self._timer is not None:
            wm.event_timer_remove(self._timer)
            self._timer = None
        wm.progress_end()
        context.workspace.status_text_set(None)


class AUTOSCOOP_OT_evaluate(bpy.types.Operator):
    """Coverage of the sensor cameras where they stand now (results and marked cameras)"""

    bl_idname = names.OP_EVALUATE
    bl_label = "Evaluate"
    bl_options = {"REGISTER", "UNDO"}

    def execute(self, context: bpy.types.Context) -> set[str]:
        try:
            doc = pipeline.evaluate_cameras(context)
        except AutoscoopError as e:
            return _fail(self, e)
        m = doc["metrics"]
        self.report({"INFO"}, f"{m['sensors']} sensors cover {m['coverage_fraction']:.1%}")
        return {"FINISHED"}


class AUTOSCOOP_OT_mark(bpy.types.Operator):
    """Mark the selected objects for AutoSCOOP (or unmark them)"""

    bl_idname = names.OP_MARK
    bl_label = "Mark"
    bl_options = {"REGISTER", "UNDO"}

    role: EnumProperty(  # type: ignore[valid-type]
        name="Role",
        items=[
            (names.ROLE_TARGET, "Target area", "Selected curves: roads to watch"),
            (names.ROLE_SENSOR_AREA, "Sensor area", "Selected curves: where masts may stand"),
            (names.ROLE_NO_MAST, "No-mast zone", "Selected curves: where masts may not stand"),
            (names.ROLE_SENSOR, "Sensor", "Selected cameras: sensors to evaluate"),
            (names.ROLE_MAST, "Standing mast", "Selected empties: masts that stand already"),
            (names.ROLE_NONE, "Unmark", "Selected objects: no role, whatever their name"),
        ],
    )

    def execute(self, context: bpy.types.Context) -> set[str]:
        wanted = {names.ROLE_SENSOR: "CAMERA", names.ROLE_MAST: "EMPTY"}.get(self.role, "CURVE")
        chosen = list(context.selected_objects)
        if not chosen:
            self.report({"ERROR"}, "Nothing selected")
            return {"CANCELLED"}
        marked = 0
        for obj in chosen:
            if self.role != names.ROLE_NONE and obj.type != wanted:
                self.report(
                    {"WARNING"}, f"{obj.name}: is a {obj.type.lower()}, not a {wanted.lower()}"
                )
                continue
            obj[names.ROLE_PROP] = self.role
            marked += 1
        pipeline.forget_area_report()
        if marked == 0:
            return {"CANCELLED"}
        self.report({"INFO"}, f"{marked} object(s) marked as {self.role.replace('_', ' ')}")
        return {"FINISHED"}


class AUTOSCOOP_OT_check(bpy.types.Operator):
    """Check the scene: areas, curves, line of sight from every sensor area, and where
    no mast may stand"""

    bl_idname = names.OP_CHECK
    bl_label = "Check Scene"

    def execute(self, context: bpy.types.Context) -> set[str]:
        try:
            job = pipeline.OptimizeJob(context)
        except AutoscoopError as e:
            context.scene.autoscoop.check_text = str(e)
            context.scene.autoscoop.check_notes = ""
            return _fail(self, e)
        lines = [f"{a}: no line of sight to any target point" for a in job.run.blind_areas()]
        lines += list(job.scene_model.warnings)
        notes = [e.text() for e in job.scene_model.excluded]
        job.cancel()
        context.scene.autoscoop.check_text = "\n".join(lines) or "OK"
        context.scene.autoscoop.check_notes = "\n".join(notes)
        for line in lines:
            self.report({"WARNING"}, line)
        for line in notes:
            self.report({"INFO"}, line)
        if not lines:
            self.report({"INFO"}, "Scene OK")
        return {"FINISHED"}


class AUTOSCOOP_OT_export(bpy.types.Operator):
    """Write a report of the last result into the export folder"""

    bl_idname = names.OP_EXPORT
    bl_label = "Export"

    kind: EnumProperty(  # type: ignore[valid-type]
        name="Format",
        items=[
            ("JSON", "JSON", "result.json"),
            ("CSV", "CSV", "sensors.csv"),
            (
                "GEOJSON",
                "GeoJSON",
                "sensors_local.geojson (scene metres); with the scene's CRS also "
                "sensors.geojson (WGS84) and plan.gpkg (GeoPackage)",
            ),
            ("PNG", "PNG", "coverage.png"),
        ],
    )

    def execute(self, context: bpy.types.Context) -> set[str]:
        try:
            live.check_export(context.scene)
            paths, note = pipeline.export(
                context.scene, self.kind, context.scene.autoscoop.export_dir
            )
        except AutoscoopError as e:
            return _fail(self, e)
        except OSError as e:
            self.report({"ERROR"}, f"{context.scene.autoscoop.export_dir}: {e.strerror}")
            return {"CANCELLED"}
        self.report({"INFO"}, "Wrote " + ", ".join(str(p) for p in paths))
        if note:
            self.report({"WARNING"}, note)
        return {"FINISHED"}


class AUTOSCOOP_OT_clear_results(bpy.types.Operator):
    """Delete the results collection (never the user's own objects)"""

    bl_idname = names.OP_CLEAR
    bl_label = "Clear Results"
    bl_options = {"REGISTER", "UNDO"}

    def execute(self, context: bpy.types.Context) -> set[str]:
        from .scene.spawn import remove_results

        remove_results(context.scene)
        context.scene.autoscoop.result_json = ""
        return {"FINISHED"}


class AUTOSCOOP_OT_snap_to_mast(bpy.types.Operator):
    """Move the active sensor camera to the nearest place its mast may stand: in a
    sensor area, off no-mast zones and objects standing on the ground"""

    bl_idname = names.OP_SNAP
    bl_label = "Snap to Mast"
    bl_options = {"REGISTER", "UNDO"}

    @classmethod
    def poll(cls, context: bpy.types.Context) -> bool:
        obj = context.active_object
        return obj is not None and obj.type == "CAMERA"

    def execute(self, context: bpy.types.Context) -> set[str]:
        try:
            text = live.snap(context.scene, context.active_object)
        except AutoscoopError as e:
            return _fail(self, e)
        self.report({"INFO"}, text)
        return {"FINISHED"}


class AUTOSCOOP_OT_fill_gap(bpy.types.Operator):
    """Add the one sensor (the panel's model) that covers the most of what is uncovered
    now: on a standing mast first, else on a new one where a mast may stand"""

    bl_idname = names.OP_FILL
    bl_label = "Fill Largest Gap"
    bl_options = {"REGISTER", "UNDO"}

    def execute(self, context: bpy.types.Context) -> set[str]:
        try:
            text = live.fill_gap(context.scene)
        except AutoscoopError as e:
            return _fail(self, e)
        self.report({"INFO"}, text)
        return {"FINISHED"}


class AUTOSCOOP_OT_replan_rest(bpy.types.Operator):
    """Keep the selected sensors as they stand and optimize the others again, with the
    current optimizer and settings (a run with progress; Esc as in Optimize)"""

    bl_idname = names.OP_REPLAN
    bl_label = "Re-plan the Rest"
    bl_options = {"REGISTER", "UNDO"}

    def execute(self, context: bpy.types.Context) -> set[str]:
        return self._run(context, "EXEC_DEFAULT")

    def invoke(self, context: bpy.types.Context, event: bpy.types.Event) -> set[str]:
        return self._run(context, "INVOKE_DEFAULT")

    def _run(self, context: bpy.types.Context, how: str) -> set[str]:
        try:
            kept = live.keep_selected(context.scene, list(context.selected_objects))
        except AutoscoopError as e:
            return _fail(self, e)
        self.report({"INFO"}, f"Keeping {len(kept)} sensor(s): {', '.join(kept)}")
        ran = bpy.ops.autoscoop.optimize(how)
        # A run still going on (modal) is Optimize's own: this one has done its part.
        return {"FINISHED"} if ran & {"FINISHED", "RUNNING_MODAL"} else {"CANCELLED"}


classes = (
    AUTOSCOOP_OT_optimize,
    AUTOSCOOP_OT_evaluate,
    AUTOSCOOP_OT_mark,
    AUTOSCOOP_OT_check,
    AUTOSCOOP_OT_export,
    AUTOSCOOP_OT_clear_results,
    AUTOSCOOP_OT_snap_to_mast,
    AUTOSCOOP_OT_fill_gap,
    AUTOSCOOP_OT_replan_rest,
)
register, unregister = bpy.utils.register_classes_factory(classes)
