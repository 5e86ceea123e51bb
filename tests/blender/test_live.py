"""Live coverage (``scene/live.py``): a sensor camera moved by a script changes the
metrics and the coverage colouring to exactly what a full evaluation of the new
poses gives; undo brings the old ones back; a new wall is seen; nothing is left
registered after the add-on goes."""

from __future__ import annotations

import json
import math

import bpy
import numpy as np
import pytest
from mathutils import Matrix

import autoscoop_blender
from autoscoop_blender import names
from autoscoop_blender.core.evaluate import evaluate_layout
from autoscoop_blender.scene import live, pipeline
from autoscoop_blender.scene.extract import extract_scene
from autoscoop_blender.scene.factory import BVHFactory
from autoscoop_blender.scene.spawn import COVERAGE_ATTR, COVERAGE_NAME, MODEL_PROP
from tests.blender.conftest import SAMPLES


@pytest.fixture(autouse=True)
def registered():
    autoscoop_blender.register()
    yield
    autoscoop_blender.unregister()


def _planned():
    """flat_wall planned by greedy to 60 %: its cameras spawned, its metrics stored."""
    bpy.ops.wm.open_mainfile(filepath=str(SAMPLES / "flat_wall.blend"))
    props = bpy.context.scene.autoscoop
    props.optimizer, props.rho = "greedy", 0.6
    bpy.ops.autoscoop.optimize()
    return props


def _full(scene):
    """What a full evaluation (``headless coverage``'s) of the cameras as they stand
    gives: (coverage fraction, counts per target point)."""
    props = scene.autoscoop
    specs = [pipeline.camera_spec(o, pipeline.model_from(props)) for o in
             pipeline.sensor_cameras(scene)]  # fmt: skip
    model = extract_scene(scene).cropped(max(s.model.range_m for s in specs))
    result = evaluate_layout(model, BVHFactory.of(model)(), specs,
                             pipeline.coverage_settings_from(props))  # fmt: skip
    return result.coverage_fraction, np.asarray(result.n_covered)


def _mesh_counts(scene):
    results = bpy.data.collections[names.RESULTS_COLLECTION]
    mesh = next(o for o in results.all_objects if o.name.startswith(COVERAGE_NAME)).data
    values = np.zeros(len(mesh.polygons), dtype=np.int32)
    mesh.attributes[COVERAGE_ATTR].data.foreach_get("value", values)
    return values


def _move(obj, dx=0.0, dy=0.0, turn_deg=0.0):
    """Move a camera in world x, y and turn it about the vertical, as a user would."""
    m = obj.matrix_world.copy()
    turn = Matrix.Rotation(math.radians(turn_deg), 4, "Z")
    loc = m.translation.copy()
    m = turn @ Matrix.Translation(-loc) @ m
    m.translation = loc + type(loc)((dx, dy, 0.0))
    obj.matrix_world = m
    bpy.context.view_layer.update()


def test_a_moved_camera_is_scored_again_as_a_full_evaluation_scores_it():
    props = _planned()
    scene = bpy.context.scene
    before = json.loads(props.result_json)["metrics"]
    bpy.context.view_layer.update()
    assert live.cached(scene.name) is None  # as planned: nothing built to show it
    cam = pipeline.sensor_cameras(scene)[0]
    _move(cam, dx=-6.0, turn_deg=170.0)  # turned away from most of the target
    after = json.loads(props.result_json)
    fraction, counts = _full(scene)
    assert after["metrics"]["coverage_fraction"] == pytest.approx(fraction, abs=1e-6)
    assert after["metrics"]["coverage_fraction"] < before["coverage_fraction"]
    assert after["edited"] is True and props.live_error == ""
    # The edited plan has no bound of its own; the optimizer's plan's figures are kept.
    assert after["metrics"]["lower_bound"] is None and after["metrics"]["gap"] is None
    assert after["as_optimized"]["coverage_fraction"] == before["coverage_fraction"]
    np.testing.assert_array_equal(_mesh_counts(scene), counts)
    np.testing.assert_array_equal(live.cached(scene.name).counts, counts)
    # What the moved camera alone covers, and what the plan would lose without it: the
    # points only it brings to their k, counted from the full evaluation's counts.
    covers, share, lost = live.alone(scene.name, cam.name)
    mine = live.cached(scene.name).covered[pipeline.sensor_cameras(scene).index(cam)]
    assert covers == len(mine) and share == pytest.approx(len(mine) / len(counts), abs=1e-6)
    assert lost == np.count_nonzero(counts[mine] == 1)
    # A second move re-scores that camera alone, and again agrees.
    _move(cam, dy=3.0, turn_deg=-90.0)
    fraction, counts = _full(scene)
    metrics = json.loads(props.result_json)["metrics"]
    assert metrics["coverage_fraction"] == pytest.approx(fraction, abs=1e-6)
    np.testing.assert_array_equal(_mesh_counts(scene), counts)


def test_undo_of_a_move_brings_the_metrics_back():
    props = _planned()
    scene = bpy.context.scene
    bpy.ops.ed.undo_push(message="planned")
    planned = json.loads(props.result_json)["metrics"]["coverage_fraction"]
    _move(pipeline.sensor_cameras(scene)[0], dx=-8.0, turn_deg=180.0)
    bpy.ops.ed.undo_push(message="moved")
    assert json.loads(props.result_json)["metrics"]["coverage_fraction"] != planned
    bpy.ops.ed.undo()
    bpy.context.view_layer.update()
    scene = bpy.context.scene
    metrics = json.loads(scene.autoscoop.result_json)["metrics"]
    assert metrics["coverage_fraction"] == pytest.approx(planned, abs=1e-6)
    fraction, counts = _full(scene)
    assert fraction == pytest.approx(planned, abs=1e-6)


def test_a_new_wall_is_seen_by_the_next_rescore():
    props = _planned()
    scene = bpy.context.scene
    cam = pipeline.sensor_cameras(scene)[0]
    _move(cam, dx=0.5)
    first = live.cached(scene.name)
    open_before = json.loads(props.result_json)["metrics"]["coverage_fraction"]
    # A tall box right in front of the camera: the cache must go, and the next
    # re-score must see the box.
    x, y, z = cam.matrix_world.translation
    bpy.ops.mesh.primitive_cube_add(size=1.0, location=(x, y, z))
    box = bpy.context.active_object
    box.scale = (8.0, 8.0, 30.0)
    bpy.context.view_layer.update()
    _move(cam, dx=0.01)
    assert live.cached(scene.name) is not first
    fraction, counts = _full(scene)
    metrics = json.loads(props.result_json)["metrics"]
    assert metrics["coverage_fraction"] == pytest.approx(fraction, abs=1e-6)
    assert metrics["coverage_fraction"] < open_before  # the box hides what it saw


def test_nothing_stays_registered_and_another_file_drops_the_cache():
    _planned()
    scene = bpy.context.scene
    _move(pipeline.sensor_cameras(scene)[0], dx=1.0)
    assert live.cached(scene.name) is not None
    bpy.ops.wm.open_mainfile(filepath=str(SAMPLES / "flat_wall.blend"))
    assert live.cached(bpy.context.scene.name) is None
    autoscoop_blender.unregister()
    try:
        assert live.on_depsgraph not in bpy.app.handlers.depsgraph_update_post
        assert live.on_load not in bpy.app.handlers.load_post
        assert not bpy.app.timers.is_registered(live.run_pending)
    finally:
        autoscoop_blender.register()


def test_a_sensor_moved_out_of_its_area_turns_red_and_export_waits(tmp_path):
    """Moved 30 m off the 8 x 8 m sensor area: red, the panel's reason, and Export
    refused in one line naming it, until it is moved back or exported anyway."""
    props = _planned()
    props.export_dir = str(tmp_path)
    scene = bpy.context.scene
    cam = pipeline.sensor_cameras(scene)[0]
    own = tuple(cam.color)
    _move(cam, dx=30.0)
    assert live.problems(scene.name) == [(cam.name, "outside every sensor area")]
    assert tuple(cam.color) == pytest.approx(live.MISPLACED_RGBA)
    name = cam.name
    bpy.ops.autoscoop.evaluate()  # the plan as it stands, for the export (new cameras)
    with pytest.raises(RuntimeError, match=f"{name}: stands outside every sensor area"):
        bpy.ops.autoscoop.export(kind="JSON")
    assert not (tmp_path / "result.json").exists()
    props.export_misplaced = True
    assert bpy.ops.autoscoop.export(kind="JSON") == {"FINISHED"}
    cam = scene.objects[name]
    assert tuple(cam.color) == pytest.approx(live.MISPLACED_RGBA)
    # Snap to Mast brings it back onto the sensor area (x -12..-4, y -4..4), to the
    # border nearest to it less the inset, at its height above the flat ground; one
    # undo step takes the snap back.
    bpy.ops.ed.undo_push(message="moved out")
    bpy.context.view_layer.objects.active = cam
    z = cam.matrix_world.translation.z
    assert bpy.ops.autoscoop.snap_to_mast() == {"FINISHED"}
    bpy.ops.ed.undo_push(message="snapped")
    cam = scene.objects[name]
    x, y, _ = cam.matrix_world.translation
    assert x == pytest.approx(-4.05, abs=1e-4) and -4.0 < y < 4.0
    assert cam.matrix_world.translation.z == pytest.approx(z)
    assert live.problems(scene.name) == [] and tuple(cam.color) == pytest.approx(own)
    bpy.ops.ed.undo()
    bpy.context.view_layer.update()
    assert bpy.context.scene.objects[name].matrix_world.translation.x > 20.0


def test_fill_largest_gap_adds_one_camera_and_undo_takes_it_away():
    """A camera deleted from the plan leaves a gap; Fill Largest Gap adds one camera
    that raises coverage again, scored as a full evaluation scores it, and the report
    says how much; one undo removes it."""
    props = _planned()
    scene = bpy.context.scene
    planned = json.loads(props.result_json)["metrics"]["coverage_fraction"]
    bpy.data.objects.remove(pipeline.sensor_cameras(scene)[0])
    bpy.context.view_layer.update()
    holed = json.loads(props.result_json)["metrics"]["coverage_fraction"]
    assert holed < planned
    bpy.ops.ed.undo_push(message="deleted")
    n = len(pipeline.sensor_cameras(scene))
    assert bpy.ops.autoscoop.fill_gap() == {"FINISHED"}
    bpy.ops.ed.undo_push(message="filled")
    assert len(pipeline.sensor_cameras(scene)) == n + 1
    filled = json.loads(props.result_json)["metrics"]["coverage_fraction"]
    fraction, counts = _full(scene)
    assert filled == pytest.approx(fraction, abs=1e-6) and filled > holed
    np.testing.assert_array_equal(live.cached(scene.name).counts, counts)
    bpy.ops.ed.undo()
    bpy.context.view_layer.update()
    assert len(pipeline.sensor_cameras(bpy.context.scene)) == n


def test_replan_the_rest_keeps_the_selected_sensor_and_plans_around_it():
    """One camera selected: it becomes the user's own, kept as it stands; the new
    plan counts it as existing at its pose and reaches the goal; one undo step takes
    the re-plan back."""
    props = _planned()
    scene = bpy.context.scene
    bpy.ops.ed.undo_push(message="planned")
    planned = json.loads(props.result_json)
    keep = pipeline.sensor_cameras(scene)[1]
    name = keep.name
    x, y, _ = keep.matrix_world.translation
    bpy.ops.object.select_all(action="DESELECT")
    keep.select_set(True)
    assert bpy.ops.autoscoop.replan_rest() == {"FINISHED"}
    bpy.ops.ed.undo_push(message="re-planned")
    doc = json.loads(scene.autoscoop.result_json)
    kept = [s for s in doc["sensors"] if s["existing"]]
    assert len(kept) == 1 and doc["metrics"]["existing_sensors"] == 1
    assert (kept[0]["x"], kept[0]["y"]) == pytest.approx((x, y), abs=1e-3)
    assert doc["metrics"]["coverage_fraction"] >= 0.6
    own = scene.objects[f"Kept {name}"]
    assert own.get(names.ROLE_PROP) == names.ROLE_SENSOR
    # The kept sensor is counted once: the plan's camera of it and the user's own
    # stand in one place.
    cams = pipeline.sensor_cameras(scene)
    assert own in cams and len(cams) == doc["metrics"]["sensors"]
    bpy.ops.ed.undo()
    assert json.loads(bpy.context.scene.autoscoop.result_json) == planned
    assert f"Kept {name}" not in bpy.context.scene.objects
    with pytest.raises(RuntimeError, match="select the sensor cameras to keep"):
        bpy.ops.object.select_all(action="DESELECT")
        bpy.ops.autoscoop.replan_rest()


def test_export_after_a_hand_edit_writes_the_plan_as_it_stands(tmp_path):
    """A moved camera, then Export: result.json holds the coverage of the cameras as
    they stand (a full evaluation's), marked edited, with the optimizer's plan's
    figures apart; sensors.csv has the moved camera where it stands now."""
    props = _planned()
    props.export_dir = str(tmp_path)
    scene = bpy.context.scene
    cam = pipeline.sensor_cameras(scene)[0]
    _move(cam, dx=-2.0, turn_deg=45.0)
    fraction, _ = _full(scene)
    for kind in ("JSON", "CSV"):
        assert bpy.ops.autoscoop.export(kind=kind) == {"FINISHED"}
    doc = json.loads((tmp_path / "result.json").read_text())
    assert doc["edited"] is True and doc["coverage_fraction"] == pytest.approx(fraction, abs=1e-6)
    assert doc["as_optimized"]["sensors"] == len(doc["sensors"])
    x = cam.matrix_world.translation.x
    rows = (tmp_path / "sensors.csv").read_text().splitlines()[1:]
    assert any(abs(float(r.split(",")[1]) - x) < 1e-3 for r in rows)


def test_a_cameras_model_changed_is_scored_again():
    """A spawned camera's own model given a 15 m range: re-scored as a full evaluation
    scores it, with less covered."""
    props = _planned()
    scene = bpy.context.scene
    cam = pipeline.sensor_cameras(scene)[0]
    _move(cam, dx=0.2)
    before = json.loads(props.result_json)["metrics"]["coverage_fraction"]
    model = dict(cam[MODEL_PROP])
    model["range_m"] = 15.0
    cam[MODEL_PROP] = model
    cam.update_tag()
    bpy.context.view_layer.update()
    after = json.loads(props.result_json)["metrics"]["coverage_fraction"]
    fraction, _ = _full(scene)
    assert after == pytest.approx(fraction, abs=1e-6) and after < before
