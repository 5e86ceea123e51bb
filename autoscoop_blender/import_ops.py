"""File > Import > OpenDRIVE (.xodr), also a button in the panel's Scene section.

The operator's options are ``headless import-xodr``'s; the work is in
``scene.xodr_import``. A file that cannot be imported is reported in one line and
changes nothing.
"""

from __future__ import annotations

import bpy
from bpy.props import EnumProperty, FloatProperty, StringProperty
from bpy_extras.io_utils import ImportHelper

from . import names
from .core.errors import AutoscoopError
from .scene.xodr_import import import_xodr, parse_lanes


class AUTOSCOOP_OT_import_xodr(bpy.types.Operator, ImportHelper):
    """Import the roads of an OpenDRIVE file: road surfaces that occlude, target areas
    from the chosen lane types, sensor areas in a band beside the roads"""

    bl_idname = names.OP_IMPORT_XODR
    bl_label = "Import OpenDRIVE"
    bl_options = {"REGISTER", "UNDO"}

    filename_ext = ".xodr"
    filter_glob: StringProperty(default="*.xodr", options={"HIDDEN"})  # type: ignore[valid-type]
    lanes: StringProperty(  # type: ignore[valid-type]
        name="Target lanes",
        description="Lane types that become target areas, comma-separated "
        "(driving, parking, shoulder, sidewalk, biking, ...)",
        default="driving",
    )
    band_inner: FloatProperty(  # type: ignore[valid-type]
        name="Band from",
        description="Sensor areas begin this far outside the outermost lane border",
        default=1.0,
        min=0.0,
        unit="LENGTH",
    )
    band_outer: FloatProperty(  # type: ignore[valid-type]
        name="Band to",
        description="Sensor areas end this far outside the outermost lane border",
        default=6.0,
        min=0.0,
        unit="LENGTH",
    )
    terrain: EnumProperty(  # type: ignore[valid-type]
        name="Terrain",
        items=[
            ("flat", "Flat", "A flat ground under everything, just below the lowest road"),
            ("none", "None", "Roads only (model the terrain yourself)"),
        ],
        default="flat",
    )

    def execute(self, context: bpy.types.Context) -> set[str]:
        wm = context.window_manager
        wm.progress_begin(0, 1000)  # the cursor's counter, per mille of the import

        def progress(stage: str, done: int, total: int) -> None:
            if stage in IMPORT_STAGES:
                k = IMPORT_STAGES.index(stage) + done / max(total, 1)
                wm.progress_update(int(1000 * k / len(IMPORT_STAGES)))

        try:
            lanes = parse_lanes(self.lanes)
            band = (self.band_inner, self.band_outer)
            summary = import_xodr(self.filepath, lanes, band, self.terrain, context.scene, progress)
        except AutoscoopError as e:
            self.report({"ERROR"}, str(e))
            return {"CANCELLED"}
        finally:
            wm.progress_end()
        for w in summary.warnings:
            self.report({"WARNING"}, w)
        self.report({"INFO"}, f"{summary.collection}: {summary.text()}")
        return {"FINISHED"}


# The stages ``import_xodr`` reports, in order.
IMPORT_STAGES = ("reading", "parsing", "sizing", "roads", "targets", "sensor areas", "objects")


def _menu_entry(self: bpy.types.Menu, context: bpy.types.Context) -> None:
    self.layout.operator(names.OP_IMPORT_XODR, text="OpenDRIVE (.xodr)")


classes = (AUTOSCOOP_OT_import_xodr,)
_register, _unregister = bpy.utils.register_classes_factory(classes)


def register() -> None:
    _register()
    bpy.types.TOPBAR_MT_file_import.append(_menu_entry)


def unregister() -> None:
    bpy.types.TOPBAR_MT_file_import.remove(_menu_entry)
    _unregister()
