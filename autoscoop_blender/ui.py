"""The sidebar panel "AutoSCOOP" (3D viewport, N panel): scene, sensor, optimizer, run,
results. Problems show as red lines before the user presses Optimize."""

from __future__ import annotations

import json

import bpy

from . import names
from .core.settings import PANEL_SETTINGS
from .scene import live, pipeline


class _Panel:
    bl_space_type = "VIEW_3D"
    bl_region_type = "UI"
    bl_category = names.PANEL_CATEGORY


class AUTOSCOOP_PT_main(_Panel, bpy.types.Panel):
    bl_label = "AutoSCOOP"

    def draw(self, context: bpy.types.Context) -> None:
        self.layout.label(text="Road-side sensor placement", icon="OUTLINER_OB_CAMERA")


class AUTOSCOOP_PT_scene(_Panel, bpy.types.Panel):
    bl_label = "Scene"
    bl_parent_id = "AUTOSCOOP_PT_main"

    def draw(self, context: bpy.types.Context) -> None:
        layout = self.layout
        rows = pipeline.area_report(context.scene)
        for role, title in (
            (names.ROLE_TARGET, "Target areas"),
            (names.ROLE_SENSOR_AREA, "Sensor areas"),
            (names.ROLE_NO_MAST, "No-mast zones"),
        ):
            mine = [r for r in rows if r[0] == role]
            if role == names.ROLE_NO_MAST and not mine:
                continue  # optional: shown only when there is one
            box = layout.box()
            box.label(text=f"{title}: {len(mine)}")
            if not mine:
                line = box.row()
                line.alert = True
                line.label(text="none: mark curves below", icon="ERROR")
            for _, name, info in mine:
                line = box.row()
                line.alert = not info.endswith("m^2")
                line.label(text=f"{name}: {info}", icon="ERROR" if line.alert else "CURVE_DATA")
        col = layout.column(align=True)
        row = col.row(align=True)
        row.operator(names.OP_MARK, text="Target").role = names.ROLE_TARGET
        row.operator(names.OP_MARK, text="Sensor Area").role = names.ROLE_SENSOR_AREA
        row.operator(names.OP_MARK, text="No Mast").role = names.ROLE_NO_MAST
        row = col.row(align=True)
        row.operator(names.OP_MARK, text="Camera as Sensor").role = names.ROLE_SENSOR
        row.operator(names.OP_MARK, text="Empty as Mast").role = names.ROLE_MAST
        row.operator(names.OP_MARK, text="Unmark").role = names.ROLE_NONE
        layout.operator(names.OP_CHECK, icon="VIEWZOOM")
        layout.operator(names.OP_IMPORT_XODR, text="Import OpenDRIVE...", icon="IMPORT")
        check = context.scene.autoscoop.check_text
        for line in check.splitlines():
            row = layout.row()
            row.alert = line != "OK"
            row.label(text=line, icon="ERROR" if row.alert else "CHECKMARK")
        for line in context.scene.autoscoop.check_notes.splitlines():
            layout.label(text=line, icon="INFO")


class AUTOSCOOP_PT_sensor(_Panel, bpy.types.Panel):
    bl_label = "Sensor"
    bl_parent_id = "AUTOSCOOP_PT_main"

    def draw(self, context: bpy.types.Context) -> None:
        props = context.scene.autoscoop
        layout = self.layout
        layout.use_property_split = True
        layout.prop(props, "preset")
        col = layout.column(align=True)
        for name in ("kind", "pattern", "h_fov_deg", "v_fov_deg", "range_m", "mount_height_m"):
            col.prop(props, name)
        col = layout.column(align=True)
        col.prop(props, "pitch_min_deg")
        col.prop(props, "pitch_max_deg")
        col = layout.column(align=True)
        col.prop(props, "rays_h")
        col.prop(props, "rays_v")
        layout.prop(props, "min_density_per_m2")
        # A pinhole camera's pixel density (DORI): one row each, the label aligned with
        # the split properties' above (Blender splits at 0.4).
        for label, fields in (
            ("Resolution", ("resolution_px",)),
            ("Pixel density", ("min_px_per_m", "dori")),
        ):
            split = layout.split(factor=0.4)
            split.alignment = "RIGHT"
            split.label(text=label)
            row = split.row(align=True)
            row.use_property_split = False
            for name in fields:
                row.prop(props, name, text="")
        text = props.flat_footprint or pipeline.flat_footprint_text(props)
        row = layout.row()
        row.alert = text.startswith("invalid")
        row.label(text=text, icon="ERROR" if row.alert else "INFO")
        # A mixed pack: a second model beside this one, at its own cost.
        layout.prop(props, "mix_preset")
        if props.mix_preset != "NONE":
            layout.prop(props, "mix_cost")


class AUTOSCOOP_PT_optimizer(_Panel, bpy.types.Panel):
    bl_label = "Optimizer"
    bl_parent_id = "AUTOSCOOP_PT_main"

    def draw(self, context: bpy.types.Context) -> None:
        props = context.scene.autoscoop
        layout = self.layout
        layout.use_property_split = True
        for setting in PANEL_SETTINGS:
            if "." not in setting.path:
                layout.prop(props, setting.prop_name)
        row = layout.row()
        row.use_property_split = False
        row.prop(
            props, "show_es", icon="TRIA_DOWN" if props.show_es else "TRIA_RIGHT", emboss=False
        )
        if props.show_es:
            col = layout.column(align=True)
            for setting in PANEL_SETTINGS:
                if setting.path.startswith("es."):
                    col.prop(props, setting.prop_name)


class AUTOSCOOP_PT_run(_Panel, bpy.types.Panel):
    bl_label = "Run"
    bl_parent_id = "AUTOSCOOP_PT_main"

    def draw(self, context: bpy.types.Context) -> None:
        layout = self.layout
        row = layout.row()
        row.scale_y = 1.5
        row.operator(names.OP_OPTIMIZE, icon="PLAY")
        row = layout.row(align=True)
        row.operator(names.OP_EVALUATE, icon="HIDE_OFF")
        row.operator(names.OP_CLEAR, icon="TRASH")


class AUTOSCOOP_PT_results(_Panel, bpy.types.Panel):
    bl_label = "Results"
    bl_parent_id = "AUTOSCOOP_PT_main"

    def draw(self, context: bpy.types.Context) -> None:
        props = context.scene.autoscoop
        layout = self.layout
        if not props.result_json:
            layout.label(text="No result yet")
            return
        doc = json.loads(props.result_json)
        m = doc.get("metrics", {})
        grid = layout.grid_flow(columns=2, even_columns=True)
        for label, key, fmt in (
            ("Coverage", "coverage_fraction", "{:.1%}"),
            ("Sensors", "sensors", "{}"),
            ("Masts", "masts", "{}"),
            ("Uncovered", "uncovered_m2", "{:,.0f} m²"),
            ("Cost", "cost", "{:g}"),
            ("Cluster ratio", "cluster_ratio", "{:.2f}"),
            ("Overlap factor", "overlap_factor", "{:.2f}"),
            ("Objective", "objective", "{:g}"),
            ("Lower bound", "lower_bound", "{:g}"),
            ("Gap", "gap", "{:.1%}"),
            # Where the gap lies: each count's own bound (the new masts and sensors).
            ("Fewest masts", "masts_lower_bound", "≥ {}"),
            ("Fewest sensors", "sensors_lower_bound", "≥ {}"),
            ("Sensors on its masts", "sensors_on_masts_lower_bound", "≥ {}"),
            ("Time", "wall_s", "{:.1f} s"),
        ):
            value = m.get(key)
            grid.label(text=label)
            grid.label(text="-" if value is None else fmt.format(value))
        if doc.get("stop_reason"):
            layout.label(text=doc["stop_reason"], icon="INFO")
        if doc.get("edited"):
            was = doc.get("as_optimized", {})
            text = "Edited by hand"
            if was.get("lower_bound") is not None:
                text += (
                    f"; as optimized: {was.get('objective', 0):g} >= bound {was['lower_bound']:g}"
                    " (the bound is that plan's)"
                )
            layout.label(text=text, icon="INFO")
        if props.live_error:
            layout.label(text=props.live_error, icon="ERROR")
        row = layout.row(align=True)
        row.operator(names.OP_FILL)
        row.operator(names.OP_REPLAN)
        misplaced = live.problems(context.scene.name)
        for name, why in misplaced:
            layout.label(text=f"{name}: stands {why}", icon="ERROR")
        if misplaced:
            layout.prop(props, "export_misplaced")
        active = context.active_object
        mine = live.alone(context.scene.name, active.name) if active else None
        if mine is not None:
            covers, share, lost = mine
            box = layout.box()
            box.label(text=f"{active.name}: covers {covers:,.0f} m² ({share:.1%} of the target)")
            box.label(text=f"Without it the plan loses {lost:,.0f} m²")
            box.operator(names.OP_SNAP)
        row = layout.row(align=True)
        row.prop(props, "show_frusta", toggle=True)
        row.prop(props, "show_footprints", toggle=True)
        row.prop(props, "show_coverage", toggle=True)
        layout.prop(props, "export_dir")
        row = layout.row(align=True)
        for kind, text in (
            ("JSON", "JSON"),
            ("CSV", "CSV"),
            ("GEOJSON", "GeoJSON"),
            ("PNG", "PNG"),
        ):
            row.operator(names.OP_EXPORT, text=text).kind = kind


classes = (
    AUTOSCOOP_PT_main,
    AUTOSCOOP_PT_scene,
    AUTOSCOOP_PT_sensor,
    AUTOSCOOP_PT_optimizer,
    AUTOSCOOP_PT_run,
    AUTOSCOOP_PT_results,
)
_register, _unregister = bpy.utils.register_classes_factory(classes)


# When the panel's list of areas must be made again.
_FORGET_ON = (bpy.app.handlers.depsgraph_update_post, bpy.app.handlers.load_post)


def register() -> None:
    _register()
    for handlers in _FORGET_ON:
        handlers.append(pipeline.forget_area_report)


def unregister() -> None:
    for handlers in _FORGET_ON:
        if pipeline.forget_area_report in handlers:
            handlers.remove(pipeline.forget_area_report)
    _unregister()
