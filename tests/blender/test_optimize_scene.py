"""Optimization on Blender scenes: a wall that hides the target keeps sensors away."""

import bpy
import numpy as np
import shapely

from autoscoop_blender.core.model.sensors import PAPER_CAMERA
from autoscoop_blender.core.run import Run
from autoscoop_blender.core.settings import ESParams, OptimizeSettings
from autoscoop_blender.scene.extract import extract_scene
from autoscoop_blender.scene.factory import BVHFactory
from tests.blender import builders as b

FAST = OptimizeSettings(optimizer="es", rho=0.9, es=ESParams(mu=12, lam=6, max_epochs=8))


def walled_scene():
    """flat_wall plus a second sensor area west of the target behind a 12 m wall:
    from a 7 m mast there, the wall hides every target point."""
    b.flat_wall_scene()
    b.curve("SensorArea_Behind", [b.rect(-12, 20, -6, 30)])
    b.box("Wall_High", (-4.0, -40.0, 0.0), (-3.7, 50.0, 12.0))


def _run():
    scene = extract_scene()
    return Run(scene, BVHFactory.of(scene), PAPER_CAMERA, FAST)


def test_sensor_behind_the_wall_is_never_chosen():
    walled_scene()
    run = _run()
    problem = run.problem
    behind = next(a for a in problem.scene.sensor_areas if a.name == "SensorArea_Behind")
    # The wall hides the whole target from there (checked with rays) ...
    wanted = np.ones(problem.n_targets, dtype=bool)
    from_behind = set()
    for x, y in problem.space.positions:
        if shapely.intersects_xy(behind.geometry, x, y):
            pose = problem.pose(x, y, PAPER_CAMERA.pitch_min_deg, 0.0)
            from_behind |= set(problem.reachable(pose, wanted))
    assert not from_behind
    assert run.blind_areas() == ["SensorArea_Behind"]
    # ... and no sensor is placed there.
    res = run.result()
    assert res.metrics["coverage_fraction"] >= 0.9
    for s in res.sensors:
        assert not shapely.intersects_xy(behind.geometry, s.x, s.y)

    # Without the wall the same area would see the target.
    bpy.data.objects["Wall_High"]["autoscoop_ignore"] = True
    problem = _run().problem
    pose = problem.pose(-8.0, 24.0, PAPER_CAMERA.pitch_min_deg, 0.0)
    assert len(problem.reachable(pose, wanted)) > 100
