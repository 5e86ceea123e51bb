"""The paper's layout metrics on a case worked out by hand."""

import math

import pytest

from autoscoop_blender.core.evaluate import evaluate_layout
from autoscoop_blender.core.geom.raycast import BoxCaster
from autoscoop_blender.core.model.sensors import SensorSpec
from autoscoop_blender.core.settings import CoverageSettings
from tests.core.flat import down_camera, flat_scene

# Its corners 12.9 m away at h = 10, inside the 20 m range.
DOWN = down_camera(20.0)


def side(h):
    return 2 * h * math.tan(math.radians(30))


def test_relative_sensor_coverage_cluster_ratio_and_overlap_by_hand():
    """Two cameras 30 m apart, at 10 m (a 133.3 m^2 square, the model's largest flat
    footprint: its mount height) and at 5 m (33.3 m^2): relative sensor coverage =
    mean footprint / reference = (133.3 + 33.3) / 2 / 133.3 = 0.625; two masts for two
    sensors; the target is 60 x 40 m, so the overlap factor is 166.7 / 2400."""
    scene = flat_scene(target=(-30, -20, 30, 20), sensor=(-16, -1, 16, 1))
    specs = [
        SensorSpec(DOWN, -15.0, 0.0, 10.0, 90.0, 0.0),
        SensorSpec(DOWN, 15.0, 0.0, 5.0, 90.0, 0.0),
    ]
    res = evaluate_layout(scene, BoxCaster(ground_z=0.0), specs, CoverageSettings(grid_m=0.1))
    m = res.metrics
    big, small = side(10) ** 2, side(5) ** 2
    assert m["reference_footprint_m2"] == pytest.approx(big, rel=0.01)
    assert [s.footprint_m2 for s in res.sensors] == pytest.approx([big, small], rel=0.01)
    assert m["relative_sensor_coverage"] == pytest.approx((big + small) / 2 / big, rel=0.01)
    assert m["relative_sensor_coverage"] == pytest.approx(0.625, rel=0.01)
    assert (m["sensors"], m["masts"], m["cluster_ratio"]) == (2, 2, 1.0)
    assert m["overlap_factor"] == pytest.approx((big + small) / 2400, rel=0.01)
    assert m["coverage_fraction"] == pytest.approx((big + small) / 2400, rel=0.01)
