"""A given layout's coverage (``core/evaluate.py``) on hand-made scenes: each sensor's
height from what its spec gives, each warning with the sensor it names, a footprint
past the areas' edge, the threshold override, what is seen beside what is covered, and
the pointcloud ray limit checked before any ray."""

from dataclasses import replace

import numpy as np
import pytest
import shapely

from autoscoop_blender.core.errors import InputError
from autoscoop_blender.core.evaluate import evaluate_layout, resolve_model
from autoscoop_blender.core.geom.raycast import BoxCaster
from autoscoop_blender.core.model.scene import Area
from autoscoop_blender.core.model.sensors import SensorSpec
from autoscoop_blender.core.settings import CoverageSettings
from tests.core.flat import down_camera, flat_scene
from tests.core.test_sites import box, plane, scene_of

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


def test_a_footprint_past_the_areas_edge_is_whole():
    """A sensor 2 m inside the target's northern edge (y = 20), 10 m high, straight
    down: its 11.55 m square holds 12 x 12 cell centres, 4 rows of them past the edge
    (y 20.5 .. 23.5), on ground the grid keeps within the sensors' reach. It covers the
    other 12 x 8."""
    res = _run([SensorSpec(DOWN, 0.0, 18.0, 10.0, 90.0, 0.0)])
    assert res.sensors[0].footprint_m2 == 144.0
    assert res.sensors[0].covered_target_m2 == 96.0


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


HUT = ((-16.5, -2.5, 5.0), (-13.5, 1.5, 8.0))  # 3 m x 4 m, 3 m high on ground at 5 m


def test_each_warning_names_its_sensor_on_raised_ground():
    """Terrain at z = 5 m, a hut in the sensor area (x -20 .. -4), world z over an
    origin at 100 m. Sensor 1 (z = 112: 7 m over the ground) is fine and looks
    straight down: its footprint is the square 2 x 7 tan 30 deg = 8.08 m on a side
    under it, counted here on the grid's own points (1 m apart). Sensor 2 stands 0.1 m
    north of the hut (within a mast's 0.25 m foot of it); sensor 3 stands 1 m below the
    hut's roof, inside it, and sees nothing. Sensor 3's 90 deg model is not sensor 1's."""
    scene = scene_of(
        {"Terrain": [plane(-40, -30, 40, 30, z=lambda x, y: 5.0)], "Hut": [box(*HUT)]},
        sensors=((-20.0, -10.0, -4.0, 10.0),),
    )
    target = (Area("Target", shapely.box(-30, -10, 10, 10)),)
    scene = replace(scene, targets=target, origin=np.array([0.0, 0.0, 100.0]))
    wide = replace(DOWN, h_fov_deg=90.0, v_fov_deg=90.0)
    specs = [
        SensorSpec(DOWN, -8.0, 0.0, None, 90.0, 0.0, z=112.0),
        SensorSpec(DOWN, -15.0, 1.6, 6.0, 90.0, 0.0),
        SensorSpec(wide, -15.0, 0.0, -1.0, 90.0, 0.0),
    ]
    res = evaluate_layout(scene, BoxCaster([HUT], ground_z=5.0), specs, CoverageSettings())
    rule = "(masts stand on the ground; a roof or gantry with autoscoop_mount = True may carry one)"
    assert res.warnings == (
        f"sensor 2 at (-15, 1.6) stands where no mast may: on or beside Hut {rule}",
        f"sensor 3 at (-15, 0) stands where no mast may: on or beside Hut {rule}",
        "sensor 3 at (-15, 0) stands inside an occluder (or under the ground): it sees nothing",
    )
    assert [s.height_m for s in res.sensors] == [7.0, 6.0, -1.0]
    assert res.sensors[2].covered_target_m2 == 0.0
    half = 7.0 * np.tan(np.radians(30.0))
    xy = res.points[:, :2]  # world = local in plan here
    under = (np.abs(xy[:, 0] + 8.0) <= half) & (np.abs(xy[:, 1]) <= half)
    assert under.sum() == 64  # 8 x 8 cell centres on half metres
    assert res.sensors[0].covered_target_m2 == pytest.approx(under.sum() * 1.0)


def test_a_pointcloud_pose_over_the_ray_limit_is_refused_before_any_ray():
    """A 1,000 x 1,000-ray camera (60 deg: 1.05 mrad between rays) with 20 m range.
    Given --oversample 3 it casts 9 M rays a pose, over the 2 M limit; the targeted
    method casts no pattern and goes ahead (the 12 x 12 cells of its square at 10 m,
    as in the threshold test). Left to choose, at a 2 cm grid it takes
    ceil(1.05e-3 x 20 / 0.02) = 2 (4.0 M rays again) and at 2.5 cm 1 (1.0 M), which the
    refusal offers."""
    dense = replace(DOWN, rays_h=1000, rays_v=1000)
    spec = SensorSpec(dense, 0.0, 0.0, 10.0, 90.0, 0.0)
    with pytest.raises(InputError) as err:
        _run([spec], method="pointcloud", oversample=3)
    assert str(err.value).startswith("method pointcloud at grid_m = 1 casts 9.0 M rays a pose")
    assert "the limit is 2.0 M rays a pose" in str(err.value)
    assert _run([spec], oversample=3).n_covered.sum() == 144
    with pytest.raises(InputError) as err:
        evaluate_layout(
            _scene(), BoxCaster([BOX], ground_z=0.0), [spec],
            CoverageSettings(grid_m=0.02, method="pointcloud"),
        )  # fmt: skip
    msg = str(err.value)
    assert msg.startswith("method pointcloud at grid_m = 0.02 casts 4.0 M rays a pose")
    assert "raise grid_m (--grid; 0.025 needs " in msg
