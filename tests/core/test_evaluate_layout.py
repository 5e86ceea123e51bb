"""A given layout's coverage (``core/evaluate.py``) on hand-made flat scenes: each
sensor's height from what its spec gives, each warning with the sensor it names, the
threshold override, what is seen beside what is covered."""

from dataclasses import replace

import numpy as np
import shapely

from autoscoop_blender.core.evaluate import evaluate_layout, resolve_model
from autoscoop_blender.core.geom.raycast import BoxCaster
from autoscoop_blender.core.model.scene import Area
from autoscoop_blender.core.model.sensors import SensorSpec
from autoscoop_blender.core.settings import CoverageSettings
from tests.core.flat import down_camera, flat_scene

DOWN = down_camera(20.0)
BOX = ((30.0, -2.0, 0.0), (34.0, 2.0, 3.0))  # a 3 m high hut, 4 m square


def _scene(origin=(0.0, 0.0, 0.0), area_height=None):
    """A 60 x 40 m target, a sensor area from x = -16 to 16 (mast height
    ``area_height``), the hut east of it; world = local + ``origin``."""
    scene = flat_scene(target=(-30, -20, 40, 20), sensor=(-16, -1, 16, 1), boxes=[BOX])
    areas = (Area("SensorArea", shapely.box(-16, -1, 16, 1), height_m=area_height),)
    return replace(scene, sensor_areas=areas, origin=np.array(origin))


def _run(specs, scene=None, **settings):
    return evaluate_layout(
        scene or _scene(), BoxCaster([BOX], ground_z=0.0), specs,
        CoverageSettings(grid_m=1.0, **settings),
    )  # fmt: skip


def test_each_sensors_height_from_what_its_spec_gives():
    """Given: 4 m. A world z of 108 over an origin at z = 100 and flat ground at 0:
    8 m (never below the ground: z 90 gives 0). Neither: the sensor area's 6 m, and
    outside every area the model's own 10 m."""
    specs = [
        SensorSpec(DOWN, 0.0, 0.0, 4.0, 90.0, 0.0),
        SensorSpec(DOWN, 5.0, 0.0, None, 90.0, 0.0, z=108.0),
        SensorSpec(DOWN, 10.0, 0.0, None, 90.0, 0.0),
        SensorSpec(DOWN, -10.0, 10.0, None, 90.0, 0.0),
        SensorSpec(DOWN, -5.0, 0.0, None, 90.0, 0.0, z=90.0),
    ]
    res = _run(specs, _scene(origin=(0.0, 0.0, 100.0), area_height=6.0))
    assert [s.height_m for s in res.sensors] == [4.0, 8.0, 6.0, 10.0, 0.0]
    assert res.warnings == ("sensor 4 at (-10, 10) stands outside every sensor area",)


def test_the_warnings_name_each_sensor_and_its_problem():
    """Sensor 1 is fine; 2 stands outside every area; 3 is mounted at its range
    (20 m) exactly. The paper's method on raised target points says it ignores their
    height."""
    specs = [
        SensorSpec(DOWN, 0.0, 0.0, 10.0, 90.0, 0.0),
        SensorSpec(DOWN, 0.0, 10.0, 10.0, 90.0, 0.0),
        SensorSpec(DOWN, 5.0, 0.0, 20.0, 90.0, 0.0),
    ]
    res = _run(specs)
    assert res.warnings == (
        "sensor 2 at (0, 10) stands outside every sensor area",
        "sensor 3 at (5, 0) is mounted 20 m high, not below its range of 20 m: it cannot "
        "reach the ground under it",
    )
    assert res.settings.grid_m == 1.0
    pc = _run(specs[:1], method="pointcloud", target_height_m=1.0, oversample=1)
    assert pc.warnings == (
        "pointcloud: the point cloud lies on surfaces; --target-height applies to targeted only",
    )
    assert _run(specs[:1], method="pointcloud", oversample=1).warnings == ()


def test_the_threshold_override_and_what_is_seen_beside_what_is_covered():
    """The straight-down camera's density is a uniform 30,720 / (4 tan^2 30 deg h^2):
    230.4 points/m^2 at 10 m high. Asked for 231 it covers nothing and still sees its
    whole square (11.55 m on a side: 12 x 12 of the 1 m cells)."""
    spec = SensorSpec(DOWN, 0.0, 0.0, 10.0, 90.0, 0.0)
    assert resolve_model(spec, CoverageSettings()) is DOWN
    strict = resolve_model(spec, CoverageSettings(min_density_per_m2=231.0))
    assert strict.min_density_per_m2 == 231.0 and strict.h_fov_deg == DOWN.h_fov_deg
    res = _run([spec], min_density_per_m2=231.0)
    assert res.n_covered.sum() == 0 and res.n_visible.sum() == 144
    assert _run([spec], min_density_per_m2=230.0).n_covered.sum() == 144
    assert res.metrics["coverage_fraction"] == 0.0
    # No flat ground meets 231 points/m^2 either: no reference footprint, no ratio
    # (not a division by zero).
    assert res.metrics["reference_footprint_m2"] == 0.0
    assert res.metrics["relative_sensor_coverage"] is None
