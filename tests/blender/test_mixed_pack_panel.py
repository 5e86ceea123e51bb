"""A mixed sensor pack from the panel (issue 16 point 3): the Sensor panel's "Mix with"
model at its own cost joins the plan; the results tell the kinds apart."""

import bpy
import pytest

import autoscoop_blender
from autoscoop_blender.core.errors import InputError
from autoscoop_blender.scene import pipeline, spawn
from tests.blender.conftest import SAMPLES


@pytest.fixture(scope="module", autouse=True)
def registered():
    autoscoop_blender.register()
    yield
    autoscoop_blender.unregister()


def _open(optimizer, mix="roadside_lidar", cost=0.5):
    bpy.ops.wm.open_mainfile(filepath=str(SAMPLES / "flat_wall.blend"))
    props = bpy.context.scene.autoscoop
    props.optimizer, props.rho = optimizer, 0.6
    props.mix_preset, props.mix_cost = mix, cost
    return props


def test_a_cheap_lidar_joins_the_plan_and_its_results_differ_in_colour():
    _open("greedy")
    doc = pipeline.OptimizeJob(bpy.context).finish(bpy.context)
    assert [m["kind"] for m in doc["models"]] == ["camera", "lidar"]
    assert [m["sensor_cost"] for m in doc["models"]] == [1.0, 0.5]
    kinds = [s["model"]["kind"] for s in doc["sensors"]]
    assert "lidar" in kinds and set(kinds) <= {"camera", "lidar"}
    # The cost counts each sensor at its model's: 3 per mast, 1 per camera, 0.5 per lidar.
    m = doc["metrics"]
    paid = sum(1.0 if k == "camera" else 0.5 for k in kinds)
    assert m["cost"] == pytest.approx(3 * m["masts"] + paid)
    for s, kind in zip(doc["sensors"], kinds):
        frustum = bpy.data.objects[spawn.FRUSTUM_NAME.format(s["n"])]
        assert tuple(frustum.color) == pytest.approx(spawn.KIND_FRUSTUM_RGBA[kind])
        footprint = bpy.data.objects.get(spawn.FOOTPRINT_NAME.format(s["n"]))
        if footprint is not None:
            assert tuple(footprint.color) == pytest.approx(spawn.KIND_FOOTPRINT_RGBA[kind])
            material = footprint.data.materials[0].name
            assert material.endswith(" lidar") == (kind == "lidar")


def test_no_mix_plans_one_model():
    _open("greedy", mix="NONE")
    doc = pipeline.OptimizeJob(bpy.context).finish(bpy.context)
    assert "models" not in doc
    assert all("model" not in s for s in doc["sensors"])


def test_the_es_refuses_the_mix_in_one_line():
    _open("es")
    with pytest.raises(InputError, match="es optimizer plans one sensor model") as err:
        pipeline.OptimizeJob(bpy.context)
    assert "\n" not in str(err.value)
