"""The sensors file: what is accepted and the one-line errors for what is not."""

import json

import pytest

from autoscoop_blender.core.errors import InputError
from autoscoop_blender.core.model.sensors import PAPER_CAMERA, ROADSIDE_LIDAR
from autoscoop_blender.io.sensor_file import parse_sensors, read_sensors


def test_defaults_and_per_sensor_models():
    specs = parse_sensors(
        {
            "model": "paper_camera",
            "sensors": [
                {"x": 1, "y": 2, "pitch_deg": 40, "yaw_deg": -90},
                {
                    "x": 3,
                    "y": 4,
                    "height_m": 9,
                    "pitch_deg": 10,
                    "yaw_deg": 0,
                    "model": "roadside_lidar",
                },
            ],
        },
        "s.json",
    )
    assert specs[0].model is PAPER_CAMERA and specs[0].height_m is None
    assert specs[0].yaw_deg == 270.0
    assert specs[1].model is ROADSIDE_LIDAR and specs[1].height_m == 9.0


@pytest.mark.parametrize(
    "data, message",
    [
        ([], "expected an object"),
        ({"model": "paper_camera", "sensors": []}, "non-empty list"),
        ({"sensors": [{"x": 0, "y": 0, "pitch_deg": 40, "yaw_deg": 0}]}, "sensor 1: no model"),
        (
            {"model": "paper_camera", "sensors": [{"x": 0, "pitch_deg": 40, "yaw_deg": 0}]},
            "sensor 1: missing y",
        ),
        (
            {
                "model": "paper_camera",
                "sensors": [{"x": 0, "y": "a", "pitch_deg": 40, "yaw_deg": 0}],
            },
            "y must be a number",
        ),
        (
            {
                "model": "paper_camera",
                "sensors": [{"x": float("nan"), "y": 0, "pitch_deg": 40, "yaw_deg": 0}],
            },
            "x is nan",
        ),
        (
            {"model": "paper_camera", "sensors": [{"x": 0, "y": 0, "pitch_deg": 95, "yaw_deg": 0}]},
            r"not in \[-90, 90\]",
        ),
        (
            {
                "model": "paper_camera",
                "sensors": [{"x": 0, "y": 0, "height_m": -1, "pitch_deg": 9, "yaw_deg": 0}],
            },
            "height_m",
        ),
        (
            {"model": {"preset": "paper_camera", "h_fov_deg": 0}, "sensors": [{"x": 0}]},
            "model: h_fov_deg",
        ),
        ({"model": {"preset": "paper_camera", "range_m": -5}, "sensors": [{"x": 0}]}, "range_m"),
    ],
)
def test_bad_sensor_files(data, message):
    with pytest.raises(InputError, match=message):
        parse_sensors(data, "s.json")


def test_read_sensors_file_errors(tmp_path):
    with pytest.raises(InputError, match="not found"):
        read_sensors(tmp_path / "missing.json")
    bad = tmp_path / "bad.json"
    bad.write_text("{not json")
    with pytest.raises(InputError, match="bad.json: not valid JSON"):
        read_sensors(bad)
    good = tmp_path / "good.json"
    good.write_text(
        json.dumps(
            {"model": "traffic_radar", "sensors": [{"x": 0, "y": 0, "pitch_deg": 5, "yaw_deg": 0}]}
        )
    )
    assert len(read_sensors(good)) == 1
