"""Optimization on Blender scenes: a wall that hides the target keeps sensors away,
and no mast climbs it."""

import bpy
import numpy as np
import pytest
import shapely

from autoscoop_blender.core.model.sensors import PAPER_CAMERA
from autoscoop_blender.core.model.sites import FOOT_M
from autoscoop_blender.core.run import Run
from autoscoop_blender.core.settings import ESParams, OptimizeSettings
from autoscoop_blender.scene.extract import extract_scene
from autoscoop_blender.scene.factory import BVHFactory
from tests.blender import builders as b

GREEDY = OptimizeSettings(optimizer="greedy", rho=0.9)
FAST_ES = OptimizeSettings(optimizer="es", rho=0.9, es=ESParams(mu=12, lam=6, max_epochs=8))


def walled_scene():
    """A flat target (x 0..50, y -25..0) watched from two sensor areas: one open, south
    of it, and one west of it behind a 12 m wall at x = -4 .. -3.7. From a 7 m mast
    the wall hides every target point from the western area."""
    b.plane("Ground", -60, -60, 60, 60)
    b.curve("Target_Area", [b.rect(0, -25, 50, 0)])
    b.curve("SensorArea_Open", [b.rect(0, -31, 50, -27)])
    b.curve("SensorArea_Behind", [b.rect(-12, -4, -4, 4)])  # up to the wall's face
    b.box("Wall_High", (-4.0, -40.0, 0.0), (-3.7, 50.0, 12.0))


def _run(settings=GREEDY):
    scene = extract_scene()
    return Run(scene, BVHFactory.of(scene), PAPER_CAMERA, settings)


def test_sensors_go_to_the_open_area_and_stand_on_the_ground():
    walled_scene()
    run = _run()
    problem = run.problem
    behind = next(a for a in problem.scene.sensor_areas if a.name == "SensorArea_Behind")
    # No mast stands on the wall: the western area ends FOOT_M short of its face.
    assert behind.geometry.bounds[2] == pytest.approx(-4.0 - FOOT_M)
    # The wall hides the whole target from the western area (checked with rays) ...
    wanted = np.ones(problem.n_targets, dtype=bool)
    from_behind = set()
    for x, y in problem.space.positions:
        if shapely.intersects_xy(behind.geometry, x, y):
            pose = problem.pose(x, y, PAPER_CAMERA.pitch_min_deg, 0.0)
            assert pose.z == pytest.approx(PAPER_CAMERA.mount_height_m)  # on the ground
            from_behind |= set(problem.reachable(pose, wanted))
    assert not from_behind
    assert run.blind_areas() == ["SensorArea_Behind"]
    # ... so every sensor stands in the open area, on a 7 m mast on the ground, in
    # greedy's plan (which reaches the goal) and in a short ES run's (which stalls
    # short of it with so small a population).
    res = run.result()
    assert res.metrics["coverage_fraction"] >= 0.9
    es = _run(FAST_ES).result()
    for s in res.sensors + es.sensors:
        assert 0 <= s.x <= 50 and -31 <= s.y <= -27
        assert s.z == pytest.approx(PAPER_CAMERA.mount_height_m, abs=1e-4)
    assert len(es.sensors) >= 3

    # Without the wall the western area would see the target.
    bpy.data.objects["Wall_High"]["autoscoop_ignore"] = True
    problem = _run().problem
    pose = problem.pose(-8.0, 0.0, PAPER_CAMERA.pitch_min_deg, 0.0)
    assert len(problem.reachable(pose, wanted)) > 100
