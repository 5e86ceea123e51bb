"""Scene settings of the panel: ``Scene.autoscoop`` (one PropertyGroup).

The sensor fields mirror ``core.model.sensors.SensorModel``; choosing a preset copies
its numbers into them. The optimizer's fields are generated from the settings schema
(``core.settings``): every knob with a panel label becomes a property of the same
name (dots as underscores), with its type, default, limits and help text. Everything
the optimizer reads is converted in ``scene.pipeline``; nothing here runs the
optimization.
"""

from __future__ import annotations

from typing import Any

import bpy
from bpy.props import (
    BoolProperty,
    EnumProperty,
    FloatProperty,
    IntProperty,
    IntVectorProperty,
    PointerProperty,
    StringProperty,
)

from .core.model.sensors import (
    DORI_PX_PER_M,
    MAX_PX_AXIS,
    MAX_PX_PER_M,
    PRESETS,
    SensorModel,
    SensorPack,
)
from .core.settings import PANEL_SETTINGS, Setting

_PRESET_ITEMS = [
    ("paper_camera", "Paper camera", "The paper's Table I camera: 80 x 80 deg, 80 m, 7 m mast"),
    ("roadside_lidar", "Roadside lidar", "A 64-beam spinning lidar: 360 x 33.2 deg, 80 m"),
    ("traffic_radar", "Traffic radar", "A 77 GHz traffic radar: 100 x 16 deg, 150 m"),
    ("cctv_camera", "CCTV camera", "A 1080p camera, 80 deg, 50 m, judged by DORI detect"),
]
# The DORI levels (EN 62676-4) that set the pixel density, "none" (0) first; "custom"
# is what the choice shows for a density typed by hand that is no level.
_DORI_ITEMS = [
    ("NONE", "None", "No pixel density required (0 px/m)", 0),
    *(
        (name.upper(), f"{name.capitalize()} {px:g}", f"DORI {name}: {px:g} px/m", n + 1)
        for n, (name, px) in enumerate(DORI_PX_PER_M.items())
    ),
    ("CUSTOM", "Custom", "The pixel density as typed, no DORI level", len(DORI_PX_PER_M) + 1),
]
_DORI_PX = [0.0, *DORI_PX_PER_M.values()]
_SENSOR_FIELDS = (
    "kind",
    "pattern",
    "h_fov_deg",
    "v_fov_deg",
    "range_m",
    "mount_height_m",
    "pitch_min_deg",
    "pitch_max_deg",
    "rays_h",
    "rays_v",
    "min_density_per_m2",
)


def _apply_preset(self: AUTOSCOOP_PG_settings, _context: bpy.types.Context) -> None:
    model = PRESETS[self.preset]
    self["_loading"] = True
    try:
        for name in _SENSOR_FIELDS:
            setattr(
                self,
                name,
                getattr(model, name).upper()
                if name in ("kind", "pattern")
                else getattr(model, name),
            )
        # The pixel fields: a preset without them clears them (0 x 0, 0 px/m).
        self.resolution_px = model.resolution_px or (0, 0)
        self.min_px_per_m = model.min_px_per_m
    finally:
        self["_loading"] = False
    _sensor_changed(self, _context)


def _get_dori(self: AUTOSCOOP_PG_settings) -> int:
    """The DORI level the pixel density is (float properties are single precision:
    the levels are exact in it); "custom" when it is none of them."""
    for n, px in enumerate(_DORI_PX):
        if abs(self.min_px_per_m - px) < 1e-3:
            return n
    return len(_DORI_PX)


def _set_dori(self: AUTOSCOOP_PG_settings, value: int) -> None:
    """Choosing a level sets the pixel density; "custom" keeps it as typed."""
    if value < len(_DORI_PX):
        self.min_px_per_m = _DORI_PX[value]


def _sensor_changed(self: AUTOSCOOP_PG_settings, _context: bpy.types.Context) -> None:
    """Recompute the flat-ground footprint shown under the sensor settings."""
    if self.get("_loading"):
        return
    from .scene.pipeline import flat_footprint_text

    self.flat_footprint = flat_footprint_text(self)


def _toggle_results(self: AUTOSCOOP_PG_settings, context: bpy.types.Context) -> None:
    from .scene.pipeline import apply_result_visibility

    apply_result_visibility(context.scene)


class AUTOSCOOP_PG_settings(bpy.types.PropertyGroup):
    # --- sensor ----------------------------------------------------------------
    preset: EnumProperty(  # type: ignore[valid-type]
        name="Preset", items=_PRESET_ITEMS, default="paper_camera", update=_apply_preset
    )
    kind: EnumProperty(  # type: ignore[valid-type]
        name="Kind",
        items=[("CAMERA", "Camera", ""), ("LIDAR", "Lidar", ""), ("RADAR", "Radar", "")],
        default="CAMERA",
        update=_sensor_changed,
    )
    pattern: EnumProperty(  # type: ignore[valid-type]
        name="Ray pattern",
        items=[
            ("ANGULAR", "Angular", "Rays evenly spaced in angle (spinning lidar, ray-cast sensor)"),
            ("PINHOLE", "Pinhole", "Rays through an even grid on an image plane (camera)"),
        ],
        default="ANGULAR",
        update=_sensor_changed,
    )
    h_fov_deg: FloatProperty(  # type: ignore[valid-type]
        name="Horizontal FoV", default=80.0, min=0.1, max=360.0, update=_sensor_changed
    )
    v_fov_deg: FloatProperty(  # type: ignore[valid-type]
        name="Vertical FoV", default=80.0, min=0.1, max=179.0, update=_sensor_changed
    )
    range_m: FloatProperty(  # type: ignore[valid-type]
        name="Range", default=80.0, min=0.1, max=2000.0, unit="LENGTH", update=_sensor_changed
    )
    mount_height_m: FloatProperty(  # type: ignore[valid-type]
        name="Mount height", default=7.0, min=0.0, max=200.0, unit="LENGTH", update=_sensor_changed
    )
    pitch_min_deg: FloatProperty(  # type: ignore[valid-type]
        name="Pitch min", default=31.0, min=-90.0, max=90.0, update=_sensor_changed
    )
    pitch_max_deg: FloatProperty(  # type: ignore[valid-type]
        name="Pitch max", default=70.0, min=-90.0, max=90.0, update=_sensor_changed
    )
    rays_h: IntProperty(name="Rays across", default=192, min=1, max=100_000, update=_sensor_changed)  # type: ignore[valid-type]
    rays_v: IntProperty(name="Rays down", default=160, min=1, max=100_000, update=_sensor_changed)  # type: ignore[valid-type]
    min_density_per_m2: FloatProperty(  # type: ignore[valid-type]
        name="Detection threshold",
        description="Minimum point density (points per m^2, XY projection) for a point to count",
        default=1.727,
        min=0.0,
        update=_sensor_changed,
    )
    resolution_px: IntVectorProperty(  # type: ignore[valid-type]
        name="Resolution",
        description="Image width and height in pixels, for the pixel density (DORI) of a "
        "pinhole camera; 0 x 0: none",
        size=2,
        default=(0, 0),
        min=0,
        max=MAX_PX_AXIS,
        update=_sensor_changed,
    )
    min_px_per_m: FloatProperty(  # type: ignore[valid-type]
        name="Pixel density",
        description="Pixels per metre a point needs to count (needs the resolution); 0: none",
        default=0.0,
        min=0.0,
        max=MAX_PX_PER_M,
        update=_sensor_changed,
    )
    dori: EnumProperty(  # type: ignore[valid-type]
        name="DORI level",
        description="Sets the pixel density to a DORI level of EN 62676-4",
        items=_DORI_ITEMS,
        get=_get_dori,
        set=_set_dori,
    )
    flat_footprint: StringProperty(name="Flat footprint", default="")  # type: ignore[valid-type]
    # A second model the plan may mix with the one above (a mixed pack), at its own cost.
    mix_preset: EnumProperty(  # type: ignore[valid-type]
        name="Mix with",
        description="A second sensor model the lp and greedy optimizers may use beside "
        "the one above (the ES plans one model)",
        items=[("NONE", "None", "One model: the one above"), *_PRESET_ITEMS],
        default="NONE",
    )
    mix_cost: FloatProperty(  # type: ignore[valid-type]
        name="Its cost",
        description="What one sensor of the second model costs, in the units of the mast "
        "cost (the model above costs the sensor cost, 1 by default)",
        default=4.0,
        min=0.0,
        soft_max=100.0,
    )
    check_text: StringProperty(name="Scene check", default="")  # type: ignore[valid-type]
    # The check's notes: where the sensor areas offer no mast site, and why.
    check_notes: StringProperty(name="Scene notes", default="")  # type: ignore[valid-type]

    # --- optimizer: the knobs of PANEL_SETTINGS, added below -------------------------
    show_es: BoolProperty(name="Evolution strategy", default=False)  # type: ignore[valid-type]

    # --- results -----------------------------------------------------------------
    result_json: StringProperty(default="")  # type: ignore[valid-type]
    # Why the last live re-score could not run (``scene/live.py``), "" when it ran.
    live_error: StringProperty(default="")  # type: ignore[valid-type]
    export_misplaced: BoolProperty(  # type: ignore[valid-type]
        name="Export Anyway",
        default=False,
        description="Export a plan whose sensors stand where no mast may (red in the view)",
    )
    show_frusta: BoolProperty(name="Frusta", default=True, update=_toggle_results)  # type: ignore[valid-type]
    show_footprints: BoolProperty(name="Footprints", default=True, update=_toggle_results)  # type: ignore[valid-type]
    show_coverage: BoolProperty(name="Coverage", default=True, update=_toggle_results)  # type: ignore[valid-type]
    export_dir: StringProperty(  # type: ignore[valid-type]
        name="Export to", default="//autoscoop/", subtype="DIR_PATH"
    )

    def sensor_model(self) -> SensorModel:
        """The model the panel describes (not yet validated)."""
        values = {name: getattr(self, name) for name in _SENSOR_FIELDS}
        values["kind"] = values["kind"].lower()
        values["pattern"] = values["pattern"].lower()
        width, height = self.resolution_px
        # 0 x 0: no resolution; a single 0 goes to the model's check, which names it.
        values["resolution_px"] = None if width == height == 0 else (width, height)
        # As typed, not as Blender's single precision keeps it.
        values["min_px_per_m"] = float(f"{self.min_px_per_m:.7g}")
        return SensorModel(**values)

    def sensor_pack(self) -> SensorModel | SensorPack:
        """The model above, or a pack of it and the ``mix_preset`` model at
        ``mix_cost`` (not yet validated)."""
        model = self.sensor_model()
        if self.mix_preset == "NONE":
            return model
        return SensorPack((model, PRESETS[self.mix_preset]), (None, float(f"{self.mix_cost:.7g}")))


def knob_property(setting: Setting) -> Any:
    """The bpy property of a knob: its type, default, limits, help and label."""
    k = setting.knob
    common: dict[str, Any] = {"name": k.label, "description": k.help[:1].upper() + k.help[1:]}
    if k.choices:
        return EnumProperty(items=list(k.choices), default=setting.default, **common)
    if setting.kind is bool:
        return BoolProperty(default=setting.default, **common)
    limits: dict[str, Any] = {}
    if k.lo is not None:
        limits["min"] = k.lo
    if k.hi is not None:
        limits["max"] = k.hi
    if k.soft is not None:
        limits["soft_min"], limits["soft_max"] = k.soft
    if setting.kind is int:
        # Blender's integer properties are 32-bit: a wider limit is the type's own.
        limits = {k: v for k, v in limits.items() if abs(v) < 2**31}
        return IntProperty(default=setting.default, **limits, **common)
    if setting.name.endswith("_m"):
        common["unit"] = "LENGTH"
    if k.lo == 0.0 and k.hi == 1.0:
        common["subtype"] = "FACTOR"
    return FloatProperty(default=setting.default, **limits, **common)


AUTOSCOOP_PG_settings.__annotations__.update(
    {s.prop_name: knob_property(s) for s in PANEL_SETTINGS}
)

classes = (AUTOSCOOP_PG_settings,)
_register, _unregister = bpy.utils.register_classes_factory(classes)


def register() -> None:
    _register()
    bpy.types.Scene.autoscoop = PointerProperty(type=AUTOSCOOP_PG_settings)


def unregister() -> None:
    del bpy.types.Scene.autoscoop
    _unregister()
