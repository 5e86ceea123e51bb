"""Cameras marked as sensors stand already: the panel's plan keeps them where they are
and adds to them (issue 16 point 2)."""

import json
import math

import bpy
import pytest

import autoscoop_blender
from autoscoop_blender import names
from autoscoop_blender.scene import pipeline
from tests.blender.conftest import SAMPLES


@pytest.fixture(scope="module", autouse=True)
def registered():
    autoscoop_blender.register()
    yield
    autoscoop_blender.unregister()


def test_a_marked_camera_is_kept_and_flagged():
    bpy.ops.wm.open_mainfile(filepath=str(SAMPLES / "flat_wall.blend"))
    props = bpy.context.scene.autoscoop
    props.optimizer, props.rho = "greedy", 0.6
    # A camera 7 m over (-8, 0) in the sensor area, looking east (yaw 0), 45 deg down.
    cam = bpy.data.objects.new("Cam_Standing", bpy.data.cameras.new("Cam_Standing"))
    bpy.context.scene.collection.objects.link(cam)
    cam.location = (-8.0, 0.0, 7.0)
    cam.rotation_euler = (math.radians(45.0), 0.0, math.radians(-90.0))
    cam[names.ROLE_PROP] = names.ROLE_SENSOR
    job = pipeline.OptimizeJob(bpy.context)
    doc = job.finish(bpy.context)
    first = doc["sensors"][0]
    assert first["existing"] is True
    assert (first["x"], first["y"], first["z"]) == pytest.approx((-8.0, 0.0, 7.0), abs=1e-4)
    assert first["pitch_deg"] == pytest.approx(45.0, abs=1e-4)
    assert abs((first["yaw_deg"] + 180.0) % 360.0 - 180.0) < 1e-4  # east, 0 or 360
    assert [s["existing"] for s in doc["sensors"][1:]] == [False] * (len(doc["sensors"]) - 1)
    assert doc["metrics"]["existing_sensors"] == 1
    assert json.loads(props.result_json)["sensors"][0]["existing"] is True
    # The results' camera for it says so too.
    spawned = [o for o in bpy.data.objects if o.type == "CAMERA" and o.get("existing")]
    assert len(spawned) == 1 and tuple(spawned[0].location) == pytest.approx((-8.0, 0.0, 7.0))
    assert spawned[0] is not cam
    # The user's camera is untouched.
    assert tuple(cam.location) == pytest.approx((-8.0, 0.0, 7.0))


def test_an_empty_marked_as_mast_carries_new_sensors_at_no_mast_cost():
    """The plan from scratch puts its first mast somewhere; an empty marked as a
    standing mast there makes that mast an existing one: 3 cheaper, flagged."""
    bpy.ops.wm.open_mainfile(filepath=str(SAMPLES / "flat_wall.blend"))
    props = bpy.context.scene.autoscoop
    props.optimizer, props.rho = "greedy", 0.6
    scratch = pipeline.OptimizeJob(bpy.context).finish(bpy.context)
    first = scratch["masts"][0]
    bpy.ops.wm.open_mainfile(filepath=str(SAMPLES / "flat_wall.blend"))
    props = bpy.context.scene.autoscoop
    props.optimizer, props.rho = "greedy", 0.6
    empty = bpy.data.objects.new("Mast_Standing", None)
    bpy.context.scene.collection.objects.link(empty)
    empty.location = (first["x"], first["y"], 0.0)
    bpy.ops.object.select_all(action="DESELECT")
    empty.select_set(True)
    assert bpy.ops.autoscoop.mark(role=names.ROLE_MAST) == {"FINISHED"}
    assert empty[names.ROLE_PROP] == names.ROLE_MAST
    doc = pipeline.OptimizeJob(bpy.context).finish(bpy.context)
    standing = [m for m in doc["masts"] if m["existing"]]
    assert [(m["x"], m["y"]) for m in standing] == [(first["x"], first["y"])]
    assert doc["metrics"]["existing_masts"] == 1 and doc["metrics"]["existing_sensors"] == 0
    # The same plan (greedy prefers a standing mast as one in use): one mast less paid.
    assert len(doc["sensors"]) == len(scratch["sensors"])
    assert doc["metrics"]["cost"] == scratch["metrics"]["cost"] - 3.0
