"""The Blender extension: registration, operators in background mode, the modal path,
undo, parity with the headless pipeline, panels, and bad input reported in Blender's
way."""

import json

import bpy
import pytest

import autoscoop_blender
from autoscoop_blender import names, ui
from autoscoop_blender import ops as ui_ops
from autoscoop_blender.core.errors import AutoscoopError
from autoscoop_blender.scene import extract, pipeline
from tests.blender import builders as b
from tests.blender.conftest import SAMPLES
from tests.cli.conftest import run_headless

FAST = {"rho": 0.6, "es_mu": 8, "es_lam": 4, "es_max_epochs": 4}
FAST_TOML = "rho = 0.6\n[es]\nmu = 8\nlam = 4\nmax_epochs = 4\n"


@pytest.fixture(scope="module", autouse=True)
def registered():
    autoscoop_blender.register()
    yield
    autoscoop_blender.unregister()


def _flat_wall(**settings):
    bpy.ops.wm.open_mainfile(filepath=str(SAMPLES / "flat_wall.blend"))
    props = bpy.context.scene.autoscoop
    for key, value in {**FAST, **settings}.items():
        setattr(props, key, value)
    return props


def _snapshot():
    """Every object with its matrix, and the datablock counts."""
    objs = {o.name: [list(r) for r in o.matrix_world] for o in bpy.data.objects}
    counts = {
        k: len(getattr(bpy.data, k)) for k in ("meshes", "cameras", "materials", "collections")
    }
    return objs, counts


def test_register_unregister_register_leaves_nothing_behind():
    autoscoop_blender.unregister()
    assert not hasattr(bpy.types.Scene, "autoscoop")
    for cls in ("AUTOSCOOP_OT_optimize", "AUTOSCOOP_PT_main", "AUTOSCOOP_PG_settings"):
        assert not hasattr(bpy.types, cls)
    handlers = (bpy.app.handlers.depsgraph_update_post, bpy.app.handlers.load_post)
    assert all(pipeline.forget_area_report not in h for h in handlers)
    autoscoop_blender.register()
    assert hasattr(bpy.types.Scene, "autoscoop") and hasattr(bpy.types, "AUTOSCOOP_OT_optimize")
    assert all(h.count(pipeline.forget_area_report) == 1 for h in handlers)


def test_the_list_of_areas_follows_the_file_opened():
    # Both samples' scenes are named "Scene": the list must not be the last file's.
    bpy.ops.wm.open_mainfile(filepath=str(SAMPLES / "flat_wall.blend"))
    first = pipeline.area_report(bpy.context.scene)
    bpy.ops.wm.open_mainfile(filepath=str(SAMPLES / "two_routes.blend"))
    assert bpy.app.handlers.load_post.count(pipeline.forget_area_report) == 1
    rows = pipeline.area_report(bpy.context.scene)
    assert rows != first
    assert sorted(n for _, n, _ in rows) == sorted(
        o.name for o in bpy.context.scene.objects if extract.area_role(o) is not None
    )


def test_optimize_and_evaluate_in_background():
    props = _flat_wall()
    before, _ = _snapshot()
    assert bpy.ops.autoscoop.optimize("INVOKE_DEFAULT") == {"FINISHED"}
    results = bpy.data.collections[names.RESULTS_COLLECTION]
    cams = [o for o in results.all_objects if o.type == "CAMERA"]
    doc = json.loads(props.result_json)
    assert len(cams) == doc["metrics"]["sensors"] >= 1
    assert doc["metrics"]["coverage_fraction"] >= 0.6
    # The user's objects are untouched; only the results collection was added.
    after, _ = _snapshot()
    assert {k: v for k, v in after.items() if k in before} == before
    assert bpy.data.collections.get(pipeline.LIVE_COLLECTION) is None

    # Evaluate the cameras where they stand: the same coverage.
    assert bpy.ops.autoscoop.evaluate() == {"FINISHED"}
    again = json.loads(props.result_json)
    assert again["metrics"]["coverage_fraction"] == pytest.approx(
        doc["metrics"]["coverage_fraction"]
    )

    # Moving a camera away changes it; evaluate sees the move.
    cam = next(
        o for o in bpy.data.collections[names.RESULTS_COLLECTION].all_objects if o.type == "CAMERA"
    )
    cam.location.x += 200.0
    bpy.context.view_layer.update()
    assert bpy.ops.autoscoop.evaluate() == {"FINISHED"}
    moved = json.loads(props.result_json)
    assert moved["metrics"]["coverage_fraction"] < again["metrics"]["coverage_fraction"]


def test_running_twice_replaces_results_and_undo_removes_them():
    _flat_wall()
    # Background Blender keeps no undo steps unless asked; after an operator with the
    # UNDO flag finishes, the UI pushes one, which the test does by hand.
    bpy.ops.ed.undo_push(message="before")
    before, counts = _snapshot()
    bpy.ops.autoscoop.optimize()
    bpy.ops.ed.undo_push(message="Optimize")
    first = sorted(o.name for o in bpy.data.collections[names.RESULTS_COLLECTION].all_objects)
    bpy.ops.autoscoop.optimize()
    bpy.ops.ed.undo_push(message="Optimize")
    second = sorted(o.name for o in bpy.data.collections[names.RESULTS_COLLECTION].all_objects)
    assert first == second  # replaced, not duplicated
    assert (
        len([c for c in bpy.data.collections if c.name.startswith(names.RESULTS_COLLECTION)]) == 1
    )
    bpy.ops.ed.undo()  # one undo step: back to the first run's results ...
    assert (
        sorted(o.name for o in bpy.data.collections[names.RESULTS_COLLECTION].all_objects) == first
    )
    bpy.ops.ed.undo()  # ... and one more: no results at all, the scene as it was
    assert _snapshot() == (before, counts)
    assert bpy.context.scene.autoscoop.result_json == ""
    # What was undone cannot be exported any more. (Blender turns an operator's ERROR
    # report into a RuntimeError for Python callers; the UI shows it as a report.)
    with pytest.raises(RuntimeError, match="run Optimize or Evaluate first"):
        bpy.ops.autoscoop.export(kind="JSON")


def test_same_poses_as_headless(tmp_path):
    props = _flat_wall(seed=4)
    bpy.ops.autoscoop.optimize()
    panel = json.loads(props.result_json)["sensors"]
    cfg = tmp_path / "fast.toml"
    cfg.write_text(FAST_TOML)
    code, _, stderr = run_headless(
        "optimize", SAMPLES / "flat_wall.blend", "--config", cfg, "--seed", 4, "--out-dir", tmp_path
    )
    assert code == 0, stderr
    headless = json.loads((tmp_path / "result.json").read_text())["sensors"]
    pose = lambda s: (s["x"], s["y"], s["pitch_deg"], s["yaw_deg"])  # noqa: E731
    assert [pose(s) for s in panel] == [pose(s) for s in headless]


def test_modal_path_progresses_and_cancel_leaves_the_scene_as_it_was():
    props = _flat_wall(rho=0.9, optimizer="es")
    before = _snapshot()
    job = pipeline.OptimizeJob(bpy.context)
    seen = []
    for _ in range(400):
        if job.step(0.01):
            break
        seen.append(job.progress.evaluations)
        if job.progress.sensors >= 2:
            break
    assert seen == sorted(seen) and seen[-1] > seen[0]  # it makes progress
    live = bpy.data.collections[pipeline.LIVE_COLLECTION]
    assert len([o for o in live.objects if o.type == "CAMERA"]) == job.progress.sensors >= 2
    job.cancel()
    assert _snapshot() == before
    assert props.result_json == ""


def test_bad_input_is_reported_in_one_line():
    """Blender turns an operator's ERROR report into a RuntimeError for Python callers
    (in the UI it is a red report line); the message is ours, in one line."""

    def error_of(op, **kw):
        with pytest.raises(RuntimeError) as info:
            op(**kw)
        text = str(info.value).strip()
        assert text.startswith("Error: ") and "\n" not in text and "Traceback" not in text
        return text

    bpy.ops.wm.read_factory_settings(use_empty=True)
    b.curve("SensorArea", [b.rect(0, 0, 5, 5)])
    assert "no target area" in error_of(bpy.ops.autoscoop.optimize)

    props = _flat_wall(pitch_min_deg=60.0, pitch_max_deg=40.0)
    assert "pitch limits contradict" in error_of(bpy.ops.autoscoop.optimize)
    assert props.result_json == ""

    bpy.ops.wm.read_factory_settings(use_empty=True)
    b.curve("Target", [b.rect(0, 0, 5, 5)])
    b.curve("SensorArea", [b.rect(-5, 0, -1, 4)])
    assert "no sensor to evaluate" in error_of(bpy.ops.autoscoop.evaluate)
    assert "run Optimize or Evaluate first" in error_of(bpy.ops.autoscoop.export, kind="PNG")
    assert "Nothing selected" in error_of(bpy.ops.autoscoop.mark, role=names.ROLE_TARGET)


def test_open_curve_and_blind_area_show_before_optimizing():
    bpy.ops.wm.open_mainfile(filepath=str(SAMPLES / "flat_wall.blend"))
    b.curve("Target_Open", [b.rect(100, 0, 110, 10)], cyclic=False)
    rows = {name: info for _, name, info in pipeline.area_report(bpy.context.scene)}
    assert rows["Target_Open"].startswith("curve is open")
    assert rows["Target_Area"] == "2,500 m^2"
    bpy.data.objects.remove(bpy.data.objects["Target_Open"])
    pipeline.forget_area_report()
    # A sensor area boxed in by walls taller than the mast sees nothing.
    b.curve("SensorArea_Boxed", [b.rect(-40, 30, -36, 34)])
    for name, lo, hi in (
        ("W1", (-42, 28, 0), (-34, 28.3, 12)), ("W2", (-42, 35.7, 0), (-34, 36, 12)),
        ("W3", (-42, 28, 0), (-41.7, 36, 12)), ("W4", (-34.3, 28, 0), (-34, 36, 12)),
    ):  # fmt: skip
        b.box(name, lo, hi)
    assert bpy.ops.autoscoop.check() == {"FINISHED"}
    assert "SensorArea_Boxed: no line of sight" in bpy.context.scene.autoscoop.check_text
    assert "SensorArea_1" not in bpy.context.scene.autoscoop.check_text


def test_marking_and_unmarking():
    bpy.ops.wm.read_factory_settings(use_empty=True)
    road = b.curve("Road", [b.rect(0, 0, 10, 10)])
    lawn = b.curve("Target_Lawn", [b.rect(20, 0, 30, 10)])
    cam = bpy.data.objects.new("MyCam", bpy.data.cameras.new("MyCam"))
    bpy.context.scene.collection.objects.link(cam)
    for obj in (road, lawn, cam):
        obj.select_set(obj is road)
    assert bpy.ops.autoscoop.mark(role=names.ROLE_TARGET) == {"FINISHED"}
    road.select_set(False)
    lawn.select_set(True)
    assert bpy.ops.autoscoop.mark(role=names.ROLE_NONE) == {"FINISHED"}
    rows = [(r, n) for r, n, _ in pipeline.area_report(bpy.context.scene)]
    assert rows == [(names.ROLE_TARGET, "Road")]
    lawn.select_set(False)
    cam.select_set(True)
    assert bpy.ops.autoscoop.mark(role=names.ROLE_SENSOR) == {"FINISHED"}
    assert pipeline.sensor_cameras(bpy.context.scene) == [cam]
    assert bpy.ops.autoscoop.mark(role=names.ROLE_TARGET) == {"CANCELLED"}  # not a curve


class _Layout:
    """A stand-in for bpy.types.UILayout that checks what a panel asks for: every
    property exists on its data, every operator exists and gets real properties."""

    def __init__(self, log):
        self.log = log
        self.alert = self.enabled = self.use_property_split = False
        self.scale_y = 1.0

    def _sub(self, *_, **__):
        return _Layout(self.log)

    row = column = box = grid_flow = split = _sub

    def label(self, text="", icon="NONE"):
        self.log.append(("label", text))

    def separator(self, **_):
        pass

    def prop(self, data, name, **_):
        assert name in data.bl_rna.properties, name
        self.log.append(("prop", name))

    def operator(self, idname, **_):
        module, op = idname.split(".")
        rna = getattr(getattr(bpy.ops, module), op).get_rna_type()
        log = self.log

        class _Props:
            def __setattr__(self, key, value):
                assert key in rna.properties, f"{idname}.{key}"
                log.append(("operator", idname, key, value))

        log.append(("operator", idname))
        return _Props()


def test_every_panel_draws_in_background():
    _flat_wall()
    bpy.ops.autoscoop.optimize()
    bpy.context.scene.autoscoop.show_es = True
    for cls in ui.classes:
        log = []
        panel = type("P", (), {"layout": _Layout(log)})()
        cls.draw(panel, bpy.context)
        assert log, cls.__name__
    texts = [entry[1] for entry in log if entry[0] == "label"]  # the results panel
    assert "Coverage" in texts and any(t.endswith("%") for t in texts)
    m = json.loads(bpy.context.scene.autoscoop.result_json)["metrics"]
    # Where the gap lies: each count's bound, beside the plan's count.
    assert texts[texts.index("Fewest masts") + 1] == f"≥ {m['masts_lower_bound']}"
    assert texts[texts.index("Fewest sensors") + 1] == f"≥ {m['sensors_lower_bound']}"
    assert 1 <= m["masts_lower_bound"] <= m["masts"]


def test_exports_write_every_report(tmp_path):
    props = _flat_wall()
    bpy.ops.autoscoop.optimize()
    props.export_dir = str(tmp_path)
    for kind in ("JSON", "CSV", "GEOJSON", "PNG"):
        assert bpy.ops.autoscoop.export(kind=kind) == {"FINISHED"}
    doc = json.loads((tmp_path / "result.json").read_text())
    assert doc == json.loads(props.result_json)
    rows = (tmp_path / "sensors.csv").read_text().splitlines()
    assert len(rows) == 1 + doc["metrics"]["sensors"]
    # No CRS on flat_wall: the scene's metres only.
    assert not (tmp_path / "sensors.geojson").exists() and not (tmp_path / "plan.gpkg").exists()
    geo = json.loads((tmp_path / "sensors_local.geojson").read_text())
    assert (
        sum(f["properties"]["kind"] == "mast" for f in geo["features"]) == doc["metrics"]["masts"]
    )
    assert (tmp_path / "coverage.png").read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"


def test_geojson_export_of_a_georeferenced_scene(tmp_path, monkeypatch):
    """With the scene's CRS the GeoJSON export writes WGS84, local metres and plan.gpkg;
    without one, only the local file, and the operator says so."""
    props = _flat_wall()
    bpy.context.scene[names.CRS_PROP] = "EPSG:3006"  # SWEREF99 TM
    bpy.context.scene[names.CRS_OFFSET_PROP] = (330_000.0, 6_400_000.0, 0.0, 0.0)
    bpy.ops.autoscoop.optimize()
    props.export_dir = str(tmp_path / "geo")
    assert bpy.ops.autoscoop.export(kind="GEOJSON") == {"FINISHED"}
    written = sorted(p.name for p in (tmp_path / "geo").iterdir())
    assert written == ["plan.gpkg", "sensors.geojson", "sensors_local.geojson"]
    geo = json.loads((tmp_path / "geo" / "sensors.geojson").read_text())
    lon, lat = geo["features"][0]["geometry"]["coordinates"]
    # SWEREF99 TM: 170 km west of 15 E (2.85 deg at 57.7 N), 6,400 km north.
    assert 11.9 < lon < 12.4 and 57.5 < lat < 58.0
    assert (tmp_path / "geo" / "plan.gpkg").read_bytes()[:16] == b"SQLite format 3\x00"

    del bpy.context.scene[names.CRS_PROP]
    bpy.ops.autoscoop.optimize()
    props.export_dir = str(tmp_path / "local")
    notes = []
    real = pipeline.export

    def spy(*args):
        paths, note = real(*args)
        notes.append(note)
        return paths, note

    monkeypatch.setattr(pipeline, "export", spy)
    assert bpy.ops.autoscoop.export(kind="GEOJSON") == {"FINISHED"}
    assert [p.name for p in (tmp_path / "local").iterdir()] == ["sensors_local.geojson"]
    assert notes and names.CRS_PROP in notes[0]


def test_result_toggles_hide_groups():
    props = _flat_wall()
    bpy.ops.autoscoop.optimize()
    results = bpy.data.collections[names.RESULTS_COLLECTION]
    groups = {c.name: c for c in results.children}
    props.show_frusta = False
    props.show_coverage = False
    assert groups["AutoSCOOP Frusta"].hide_viewport and groups["AutoSCOOP Coverage"].hide_viewport
    assert not groups["AutoSCOOP Footprints"].hide_viewport
    assert not groups["AutoSCOOP Sensors"].hide_viewport
    props.show_frusta = True
    assert not groups["AutoSCOOP Frusta"].hide_viewport


def test_panel_properties_come_from_the_settings_schema():
    """Every knob with a panel label is a property of the settings group, with the
    schema's default, limits, help and choices; the panel reads back into settings."""
    from autoscoop_blender.core.settings import PANEL_SETTINGS, ESParams, OptimizeSettings

    rna = bpy.types.Scene.bl_rna.properties["autoscoop"].fixed_type.properties
    for s in PANEL_SETTINGS:
        prop = rna[s.prop_name]
        assert prop.name == s.knob.label and prop.description.lower() == s.knob.help.lower()
        if s.knob.choices:
            assert [i.identifier for i in prop.enum_items] == [c[0] for c in s.knob.choices]
            assert prop.default == s.default
            continue
        assert prop.default == pytest.approx(s.default)  # float properties are float32
        if s.knob.lo is not None:
            assert prop.hard_min == pytest.approx(s.knob.lo)
        if s.knob.hi is not None:
            # An int wider than 32 bits keeps Blender's own limit (the seed's 2^63 - 1).
            assert prop.hard_max == pytest.approx(min(s.knob.hi, 2**31 - 1))
    bpy.ops.wm.read_factory_settings(use_empty=True)
    props = bpy.context.scene.autoscoop
    # Read back as typed, not as Blender's single precision keeps them (0.97, 0.2).
    assert pipeline.settings_from(props) == OptimizeSettings()
    props.es_mu, props.optimizer, props.seed = 7, "greedy", 3
    settings = pipeline.settings_from(props)
    assert settings.es == ESParams(mu=7) and settings.optimizer == "greedy" and settings.seed == 3
    assert pipeline.coverage_settings_from(props).grid_m == props.grid_m


def test_panel_pixel_density_fields_reach_the_sensor_model():
    """Resolution (width, height; 0 x 0: none) and the pixel density (0: none) with its
    DORI choice, which sets it: EN 62676-4's recognise is 125 px/m, observe 62."""
    props = bpy.context.scene.autoscoop
    assert tuple(props.resolution_px) == (0, 0) and props.min_px_per_m == 0.0
    assert props.dori == "NONE"
    model = pipeline.model_from(props)
    assert (model.resolution_px, model.min_px_per_m) == (None, 0.0)
    # A pinhole camera with square pixels: 1920 / 1080 = tan 40 deg / tan(v / 2).
    props.kind, props.pattern = "CAMERA", "PINHOLE"
    props.h_fov_deg, props.v_fov_deg = 80.0, 50.534
    props.resolution_px = (1920, 1080)
    props.dori = "RECOGNISE"
    assert props.min_px_per_m == 125.0
    model = pipeline.model_from(props)
    assert model.resolution_px == (1920, 1080) and model.min_px_per_m == 125.0
    assert props.flat_footprint.endswith("(largest over pitch)")  # valid, recomputed
    # A density typed by hand shows its level, or "custom"; the model takes it as typed.
    props.min_px_per_m = 62.0
    assert props.dori == "OBSERVE"
    props.min_px_per_m = 99.9
    assert props.dori == "CUSTOM" and pipeline.model_from(props).min_px_per_m == 99.9
    props.dori = "CUSTOM"  # keeps the number
    assert pipeline.model_from(props).min_px_per_m == 99.9
    props.dori = "NONE"
    assert props.min_px_per_m == 0.0 and pipeline.model_from(props).min_px_per_m == 0.0
    # One side 0 is no "none": the model's check names it.
    props.resolution_px = (1920, 0)
    with pytest.raises(AutoscoopError, match="resolution_px height 0"):
        pipeline.model_from(props)
    # A density without a resolution is refused, naming the field.
    props.resolution_px = (0, 0)
    props.dori = "DETECT"
    with pytest.raises(AutoscoopError, match="min_px_per_m 25 needs resolution_px"):
        pipeline.model_from(props)
    assert props.flat_footprint.startswith("invalid")
    # Presets set both: the CCTV camera's, and none for the paper camera.
    props.preset = "cctv_camera"
    assert tuple(props.resolution_px) == (1920, 1080) and props.dori == "DETECT"
    model = pipeline.model_from(props)
    assert (model.resolution_px, model.min_px_per_m) == ((1920, 1080), 25.0)
    props.preset = "paper_camera"
    assert tuple(props.resolution_px) == (0, 0) and props.dori == "NONE"
    model = pipeline.model_from(props)
    assert (model.resolution_px, model.min_px_per_m) == (None, 0.0)


def test_optimize_runs_with_the_panels_pixel_density():
    """The optimize operator takes the panel's pixel fields into its model (written
    with the result), and refuses a density with no resolution in one line."""
    props = _flat_wall(optimizer="greedy")
    props.preset = "cctv_camera"
    props.dori = "RECOGNISE"
    assert bpy.ops.autoscoop.optimize() == {"FINISHED"}
    model = json.loads(props.result_json)["model"]
    assert model["resolution_px"] == [1920, 1080] and model["min_px_per_m"] == 125.0
    props.resolution_px = (0, 0)
    with pytest.raises(RuntimeError, match="min_px_per_m 125 needs resolution_px"):
        bpy.ops.autoscoop.optimize()


class _Event:
    def __init__(self, kind):
        self.type = kind


def _modal_op(job):
    """The optimize operator's modal handler, driven by hand: background Blender has no
    event loop, so the test plays the timer and Esc events a window would send."""
    cls = ui_ops.AUTOSCOOP_OT_optimize
    op = type("ModalOp", (), {})()
    op._job, op._timer, op._budget_s = job, None, cls._budget_s
    op.reports = []
    op.report = lambda level, text: op.reports.append((set(level), text))
    for name in ("modal", "_cleanup", "_finish"):
        setattr(op, name, getattr(cls, name).__get__(op))
    return op


def test_esc_keeps_the_best_plan_so_far_and_one_undo_removes_it():
    props = _flat_wall(optimizer="lp")
    bpy.ops.ed.undo_push(message="before")
    before, counts = _snapshot()
    op = _modal_op(pipeline.OptimizeJob(bpy.context))
    state = op.modal(bpy.context, _Event("TIMER"))
    while state == {"RUNNING_MODAL"} and op._job.progress.best is None:
        state = op.modal(bpy.context, _Event("TIMER"))  # until lp holds a plan
    assert state == {"RUNNING_MODAL"}
    best = op._job.progress.best
    assert op.modal(bpy.context, _Event("ESC")) == {"RUNNING_MODAL"}
    assert "keeping the best plan so far" in op.reports[-1][1]
    while state == {"RUNNING_MODAL"}:
        state = op.modal(bpy.context, _Event("TIMER"))
    assert state == {"FINISHED"}
    result = json.loads(props.result_json)
    assert result["metrics"]["cost"] <= best  # the plan kept is at least that good
    assert len(bpy.data.collections[names.RESULTS_COLLECTION].all_objects) > 0
    bpy.ops.ed.undo_push(message="Optimize")
    bpy.ops.ed.undo()  # one step: the scene as it was
    assert _snapshot() == (before, counts)
    assert bpy.context.scene.autoscoop.result_json == ""


def test_esc_twice_cancels_and_changes_nothing():
    props = _flat_wall(optimizer="lp")
    before, counts = _snapshot()
    op = _modal_op(pipeline.OptimizeJob(bpy.context))
    op.modal(bpy.context, _Event("TIMER"))
    assert op.modal(bpy.context, _Event("ESC")) == {"RUNNING_MODAL"}
    assert op.modal(bpy.context, _Event("ESC")) == {"CANCELLED"}
    assert "nothing was changed" in op.reports[-1][1]
    assert _snapshot() == (before, counts) and props.result_json == ""
