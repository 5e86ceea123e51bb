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


# --- issue 14: keys, whole numbers, huge numbers ----------------------------------------

POSE = {"x": 1, "y": 2, "pitch_deg": 40, "yaw_deg": 0}


def test_a_result_json_is_a_sensors_file_with_its_own_keys():
    sensor = {**POSE, "n": 1, "z": 7.0, "height_m": 7.0, "mast": 1, "fitness": 0.9,
              "epochs": 3, "target_covered_m2": 100.0, "footprint_m2": 120.0}  # fmt: skip
    doc = {"schema": "autoscoop.result/1", "scene": "s.blend", "model": "paper_camera",
           "sensors": [sensor], "masts": [], "metrics": {}, "origin": [0, 0, 0]}  # fmt: skip
    (spec,) = parse_sensors(doc, "result.json")
    assert (spec.x, spec.height_m) == (1.0, 7.0)
    # Without the result's schema the same keys are strangers (but "masts", which a
    # sensors file may carry: masts that stand, for --existing).
    with pytest.raises(InputError, match="unknown top-level keys 'scene', 'metrics', 'origin'"):
        parse_sensors({k: v for k, v in doc.items() if k != "schema"}, "s.json")


def test_unknown_keys_name_the_closest_known_one():
    with pytest.raises(InputError) as info:
        parse_sensors({"model": "paper_camera", "sensors": [{**POSE, "Yaw_deg": 1}]}, "s.json")
    assert str(info.value) == (
        "s.json: sensor 1: unknown sensor key 'Yaw_deg' (did you mean 'yaw_deg'?)"
    )
    with pytest.raises(InputError, match=r"unknown sensor preset 'paper_camrea' \(did you mean"):
        parse_sensors({"model": "paper_camrea", "sensors": [POSE]}, "s.json")


def test_whole_rays_and_yaw_wrapping():
    (spec,) = parse_sensors(
        {"model": {"preset": "paper_camera", "rays_h": 96.0}, "sensors": [POSE]}, "s.json"
    )
    assert spec.model.rays_h == 96 and type(spec.model.rays_h) is int
    (spec,) = parse_sensors(
        {"model": "paper_camera", "sensors": [{**POSE, "yaw_deg": -1e-20}]}, "s"
    )
    assert spec.yaw_deg == 0.0


@pytest.mark.parametrize(
    "sensor, message",
    [
        ({**POSE, "x": 10**400}, "x is a 401-digit integer; it must be in [-1e+07, 1e+07] m"),
        ({**POSE, "y": -(2**1100)}, "y is a 332-digit negative integer; it must be in"),
        ({**POSE, "yaw_deg": 10**400}, "yaw_deg is a 401-digit integer, too large for a number"),
        ({**POSE, "height_m": True}, "height_m must be a number, got True"),
        ({**POSE, "pitch_deg": float("inf")}, "pitch_deg is inf (must be a finite number"),
    ],
)
def test_numbers_too_large_for_a_float(sensor, message):
    with pytest.raises(InputError) as info:
        parse_sensors({"model": "paper_camera", "sensors": [sensor]}, "s.json")
    assert str(info.value).startswith(f"s.json: sensor 1: {message}")


def test_json_too_deep_or_too_long_for_python(tmp_path):
    deep = tmp_path / "deep.json"
    deep.write_text("[" * 100_000)
    with pytest.raises(InputError, match=r"^deep.json: not valid JSON \(nested too deeply\)$"):
        read_sensors(deep)
    long = tmp_path / "long.json"
    long.write_text('{"sensors": [{"x": ' + "1" * 5000 + "}]}")
    with pytest.raises(InputError, match=r"^long.json: not valid JSON \(Exceeds the limit"):
        read_sensors(long)
