"""Sensor models: ray pattern, FoV test, analytic density against counted rays."""

import math
from dataclasses import replace

import numpy as np
import pytest

from autoscoop_blender.core.errors import InputError
from autoscoop_blender.core.geom.raycast import BoxCaster
from autoscoop_blender.core.model.sensors import PAPER_CAMERA, PRESETS, SensorModel, frame


def test_frame_is_right_handed_and_points_where_asked():
    r = frame(30.0, 90.0)
    forward, left, up = r
    assert np.allclose(r @ r.T, np.eye(3))
    assert np.allclose(np.cross(forward, left), up)
    # Yaw 90 looks along +Y; pitch 30 looks 30 deg below the horizon.
    assert np.allclose(forward, [0.0, math.cos(math.radians(30)), -0.5])
    assert up[2] > 0


@pytest.mark.parametrize("pattern", ["angular", "pinhole"])
def test_pattern_rays_lie_inside_the_fov(pattern):
    model = replace(PAPER_CAMERA, pattern=pattern, rays_h=40, rays_v=30)
    d = model.pattern_directions(2).reshape(-1, 3)
    assert d.shape == (40 * 30 * 4, 3)
    assert np.allclose(np.linalg.norm(d, axis=1), 1.0)
    assert model.in_fov(d).all()
    # Just outside the horizontal edge is outside.
    a = math.radians(model.h_fov_deg / 2 + 0.5)
    assert not model.in_fov(np.array([[math.cos(a), math.sin(a), 0.0]]))[0]


@pytest.mark.parametrize("pattern", ["angular", "pinhole"])
@pytest.mark.parametrize("spot", [(12.0, 3.0), (25.0, -9.0), (40.0, 10.0)])
def test_analytic_density_matches_counted_hits(pattern, spot):
    """Count the pattern's hits in a 2 m x 2 m patch of flat ground; compare with the
    analytic points/m^2 at the patch centre (sensor at 7 m, pitch 35, yaw 0)."""
    model = replace(PAPER_CAMERA, pattern=pattern)
    os_ = 4
    s = np.array([0.0, 0.0, 7.0])
    rot = frame(35.0, 0.0)
    dirs = model.pattern_directions(os_).reshape(-1, 3) @ rot
    dist = BoxCaster(ground_z=0.0).cast(np.broadcast_to(s, dirs.shape), dirs, 200.0)
    hit = s + dirs[np.isfinite(dist)] * dist[np.isfinite(dist), None]
    half = 1.0
    inside = (np.abs(hit[:, 0] - spot[0]) <= half) & (np.abs(hit[:, 1] - spot[1]) <= half)
    counted = inside.sum() / os_**2 / (2 * half) ** 2

    p = np.array([spot[0], spot[1], 0.0])
    v = p - s
    r = np.linalg.norm(v)
    d = (v / r)[None]
    analytic = model.ground_density(d @ rot.T, d, np.array([r]), np.array([[0.0, 0.0, 1.0]]))[0]
    assert counted == pytest.approx(analytic, rel=0.06)


def test_presets_are_valid_and_paper_camera_matches_table_one():
    for name, model in PRESETS.items():
        assert model.validated(name) == model
    m = PAPER_CAMERA
    assert (m.h_fov_deg, m.v_fov_deg, m.range_m, m.mount_height_m) == (80, 80, 80, 7)
    assert m.n_rays == 30720
    assert (m.pitch_min_deg, m.pitch_max_deg) == (31, 70)


@pytest.mark.parametrize(
    "change, message",
    [
        ({"h_fov_deg": 0.0}, "h_fov_deg"),
        ({"h_fov_deg": 180.0, "pattern": "pinhole"}, "h_fov_deg"),
        ({"v_fov_deg": 180.0}, "v_fov_deg"),
        ({"range_m": 0.0}, "range_m"),
        ({"range_m": 5.0}, "does not reach the ground"),
        ({"pitch_min_deg": -91.0}, "pitch_min_deg"),
        ({"pitch_min_deg": 60.0, "pitch_max_deg": 40.0}, "contradict"),
        ({"rays_h": 0}, "rays_h"),
        ({"min_density_per_m2": float("nan")}, "nan"),
        ({"kind": "sonar"}, "kind"),
    ],
)
def test_bad_models_are_rejected_with_the_key_named(change, message):
    with pytest.raises(InputError, match=message):
        replace(PAPER_CAMERA, **change).validated("model")


def test_model_from_spec():
    assert SensorModel.from_spec("paper_camera", "m") is PAPER_CAMERA
    m = SensorModel.from_spec({"preset": "paper_camera", "range_m": 60}, "m")
    assert m.range_m == 60.0 and m.h_fov_deg == 80.0
    full = SensorModel.from_spec(PAPER_CAMERA.to_dict(), "m")
    assert full == PAPER_CAMERA
    with pytest.raises(InputError, match="unknown sensor preset"):
        SensorModel.from_spec("nope", "m")
    with pytest.raises(InputError, match="misses key"):
        SensorModel.from_spec({"kind": "camera"}, "m")
    with pytest.raises(InputError, match="unknown model key"):
        SensorModel.from_spec({"preset": "paper_camera", "zoom": 2}, "m")
