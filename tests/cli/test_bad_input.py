"""Bad input through the CLI (issue 14): each case fails with exit code 2 and one line
``error: <what>: <problem>`` on stderr, no traceback, and writes nothing."""

import json
import math

import bpy
import pytest

from autoscoop_blender.core.model.sensors import MAX_COORD_M, MAX_RANGE_M
from tests.cli.conftest import SAMPLES, run_headless

FLAT = SAMPLES / "flat_wall.blend"
POSE = {"x": -8, "y": 0, "pitch_deg": 40, "yaw_deg": 0}


def one_error_line(code, stderr):
    assert "Traceback" not in stderr, stderr
    assert code == 2, stderr
    lines = stderr.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith("error: "), stderr
    return lines[0]


def bad_coverage(tmp_path, scene, sensors):
    out = tmp_path / "never.json"
    line = one_error_line(*run_headless("coverage", scene, "--sensors", sensors, "--out", out)[::2])
    assert not out.exists()
    return line


def bad_optimize(tmp_path, scene):
    out = tmp_path / "never"
    line = one_error_line(*run_headless("optimize", scene, "--out-dir", out)[::2])
    assert not out.exists() or not any(out.iterdir())
    return line


def sensors_text(tmp_path, text, name="sensors.json"):
    """A sensors file written as raw text (JSON that json.dumps would not write)."""
    path = tmp_path / name
    path.write_text(text)
    return path


def flat_scene(target=None, sensor_area=None):
    """flat_wall's geometry with the target or sensor area replaced by a builder."""

    def build(b):
        b.plane("Ground", -60, -60, 60, 60)
        b.box("Wall", (10.0, -2.0, 0.0), (10.3, 8.0, 3.0))
        if target is None:
            b.curve("Target_Area", [b.rect(0, -25, 50, 25)])
        else:
            target(b)
        if sensor_area is None:
            b.curve("SensorArea_1", [b.rect(-12, -4, -4, 4)])
        else:
            sensor_area(b)

    return build


def empty_curve(name):
    def build(_b):
        data = bpy.data.curves.new(name, "CURVE")
        bpy.context.scene.collection.objects.link(bpy.data.objects.new(name, data))

    return build


# --- 1. a curve with no splines ----------------------------------------------------------


@pytest.mark.parametrize("role", ["target", "sensor_area"])
def test_area_curve_without_splines(tmp_path, blend_file, sensors_file, role):
    name = "Target_Empty" if role == "target" else "SensorArea_Empty"
    build = flat_scene(**{role: empty_curve(name)})
    line = bad_coverage(
        tmp_path, blend_file(build), sensors_file({"model": "paper_camera", "sensors": [POSE]})
    )
    assert line == f"error: {name}: curve has no splines"


# --- 2. numbers too large for a float, coordinates out of range ---------------------------


@pytest.mark.parametrize(
    "sensor, model, message",
    [
        ('"x": ' + "9" * 400, '"paper_camera"', "sensor 1: x is a 400-digit integer; it must be in [-1e+07, 1e+07] m"),
        ('"x": -' + "9" * 400, '"paper_camera"', "sensor 1: x is a 400-digit negative integer"),
        ('"x": 1e400', '"paper_camera"', "sensor 1: x is inf (must be a finite number; 1e309 and beyond overflow to inf)"),
        ('"x": 2e7', '"paper_camera"', "sensor 1: x 2e+07 must be in [-1e+07, 1e+07] m"),
        ('"y": -1e300', '"paper_camera"', "sensor 1: y -1e+300 must be in [-1e+07, 1e+07] m"),
        ('"yaw_deg": ' + "7" * 400, '"paper_camera"', "sensor 1: yaw_deg is a 400-digit integer, too large"),
        ('"pitch_deg": ' + "4" * 400, '"paper_camera"', "sensor 1: pitch_deg is a 400-digit integer"),
        ('"height_m": ' + "5" * 400, '"paper_camera"', "sensor 1: height_m is a 400-digit integer"),
        ('"height_m": 1e5', '"paper_camera"', "sensor 1: height_m 100000 must be in [0, 2,000] m (the mast height"),
        ("", '{"preset": "paper_camera", "range_m": ' + "8" * 400 + "}", "model: range_m is a 400-digit integer; it must be in [0, 2,000] m"),
        ("", '{"preset": "paper_camera", "rays_h": ' + "1" * 400 + "}", "model: rays_h is a 400-digit integer; it must be in [1, 100,000]"),
        ("", '{"preset": "paper_camera", "min_density_per_m2": -1e400}', "model: min_density_per_m2 is -inf"),
    ],
)  # fmt: skip
def test_huge_and_overflowing_numbers(tmp_path, sensor, model, message):
    pose = dict(POSE)
    text = json.dumps(pose)
    if sensor:
        key = sensor.split(":")[0].strip('"')
        pose.pop(key, None)
        text = json.dumps(pose)[:-1] + ", " + sensor + "}"
    sensors = sensors_text(tmp_path, f'{{"model": {model}, "sensors": [{text}]}}')
    assert bad_coverage(tmp_path, FLAT, sensors).startswith(f"error: sensors.json: {message}")


def test_an_integer_too_long_for_json_is_not_valid_json(tmp_path):
    sensors = sensors_text(tmp_path, '{"model": "paper_camera", "sensors": [{"x": ' + "1" * 5000)
    line = bad_coverage(tmp_path, FLAT, sensors)
    assert line.startswith("error: sensors.json: not valid JSON (Exceeds the limit (4300 digits)")


# --- 3. misspelt keys --------------------------------------------------------------------


def test_misspelt_sensor_keys_are_named_with_a_suggestion(tmp_path, sensors_file):
    pose = {"x": -8, "y": 0, "heigth_m": 12, "pich_deg": 40, "pitch_deg": 40, "yaw_deg": 0}
    line = bad_coverage(tmp_path, FLAT, sensors_file({"model": "paper_camera", "sensors": [pose]}))
    assert line == (
        "error: sensors.json: sensor 1: unknown sensor keys 'heigth_m' (did you mean "
        "'height_m'?), 'pich_deg' (did you mean 'pitch_deg'?)"
    )


def test_misspelt_top_level_and_model_keys(tmp_path, sensors_file):
    line = bad_coverage(tmp_path, FLAT, sensors_file({"modle": "paper_camera", "sensors": [POSE]}))
    assert line == "error: sensors.json: unknown top-level key 'modle' (did you mean 'model'?)"
    model = {"preset": "paper_camera", "rang_m": 60}
    line = bad_coverage(tmp_path, FLAT, sensors_file({"model": model, "sensors": [POSE]}))
    assert (
        line == "error: sensors.json: model: unknown model key 'rang_m' (did you mean 'range_m'?)"
    )
    line = bad_coverage(
        tmp_path, FLAT, sensors_file({"model": "paper_camera", "sensors": [{**POSE, "z": 9}]})
    )
    assert line == (
        "error: sensors.json: sensor 1: unknown sensor key 'z'; known: height_m, model, "
        "pitch_deg, x, y, yaw_deg"
    )


# --- 4. model numbers: whole rays, finite and in range --------------------------------------


@pytest.mark.parametrize(
    "change, message",
    [
        ({"rays_h": 1.9}, "model: rays_h must be a whole number, got 1.9"),
        ({"range_m": 1e9}, "model: range_m 1e+09 must be in [0, 2,000] m (a road-side sensor's reach"),
        ({"h_fov_deg": 0.01}, "model: h_fov_deg 0.01 must be at least 0.1 deg"),
        ({"h_fov_deg": 400}, "model: h_fov_deg 400 must be in [0, 360] deg"),
        ({"rays_h": 4096, "rays_v": 4096}, "model: rays_h x rays_v = 16,777,216 rays must be at most 4,194,304"),
        ({"mount_height_m": 5000, "range_m": 80}, "model: mount_height_m 5000 must be in [0, 2,000] m"),
        ({"min_density_per_m2": 1e7}, "model: min_density_per_m2 1e+07 must be in [0, 1e+06] points per m^2"),
    ],
)  # fmt: skip
def test_model_numbers_out_of_range(tmp_path, sensors_file, change, message):
    model = {"preset": "paper_camera", **change}
    line = bad_coverage(tmp_path, FLAT, sensors_file({"model": model, "sensors": [POSE]}))
    assert line.startswith(f"error: sensors.json: {message}")


def test_integral_float_rays_are_whole_numbers(tmp_path, sensors_file):
    """rays_h 192.0 is 192: the same coverage as the preset."""
    out = {}
    for name, model in (
        ("int", "paper_camera"),
        ("float", {"preset": "paper_camera", "rays_h": 192.0}),
    ):
        out[name] = tmp_path / f"{name}.json"
        sensors = sensors_file({"model": model, "sensors": [POSE]}, name=f"{name}-sensors.json")
        code, _, stderr = run_headless("coverage", FLAT, "--sensors", sensors, "--out", out[name])
        assert code == 0, stderr
    a, b = (json.loads(p.read_text()) for p in out.values())
    assert b["sensors"][0]["model"]["rays_h"] == 192
    assert a["coverage_fraction"] == b["coverage_fraction"] > 0.3


# --- 5. a mast at or above the sensor's range -----------------------------------------------


def test_a_sensor_mounted_above_its_range_is_warned(tmp_path, sensors_file):
    out = tmp_path / "out.json"
    sensors = sensors_file({"model": "paper_camera", "sensors": [{**POSE, "height_m": 100}]})
    code, _, stderr = run_headless("coverage", FLAT, "--sensors", sensors, "--out", out)
    assert code == 0, stderr
    res = json.loads(out.read_text())
    warning = (
        "sensor 1 at (-8, 0) is mounted 100 m high, not below its range of 80 m: it cannot "
        "reach the ground under it"
    )
    assert warning in res["warnings"] and f"warning: {warning}" in stderr
    assert res["coverage_fraction"] == 0.0


# --- 6. tilted curves ----------------------------------------------------------------------


def rotated_target(b):
    b.curve("Target_Tilt", [b.rect(0, -10, 50, 10)]).rotation_euler = (math.radians(30), 0, 0)


def inclined_target(b):
    t = math.tan(math.radians(30))
    b.curve(
        "Target_Tilt", [[(0, -10, -10 * t), (50, -10, -10 * t), (50, 10, 10 * t), (0, 10, 10 * t)]]
    )


def test_a_rotated_curve_is_tilted(tmp_path, blend_file, sensors_file):
    line = bad_coverage(
        tmp_path,
        blend_file(flat_scene(rotated_target)),
        sensors_file({"model": "paper_camera", "sensors": [POSE]}),
    )
    assert line == (
        "error: Target_Tilt: curve is not in the XY plane (tilted 30.0 deg, flat is within 1 deg): "
        "its 1,000 m^2 would count as 866 m^2 in plan; flatten it (scale Z to 0) or clear the "
        "object's X/Y rotation"
    )


def test_a_curve_drawn_in_an_inclined_plane_is_tilted_for_optimize_too(tmp_path, blend_file):
    line = bad_optimize(tmp_path, blend_file(flat_scene(inclined_target)))
    assert line.startswith("error: Target_Tilt: curve is not in the XY plane (tilted 30.0 deg")


def test_a_sensor_area_tilted_by_its_parent_is_named(tmp_path, blend_file, sensors_file):
    def tilted_area(b):
        area = b.curve("SensorArea_Roof", [b.rect(-12, -4, -4, 4)])
        area.rotation_euler = (0, math.radians(5), 0)

    line = bad_coverage(
        tmp_path,
        blend_file(flat_scene(sensor_area=tilted_area)),
        sensors_file({"model": "paper_camera", "sensors": [POSE]}),
    )
    assert line.startswith("error: SensorArea_Roof: curve is not in the XY plane (tilted 5.0 deg")


# --- 7. curve points that are not finite or far away -------------------------------------


@pytest.mark.parametrize(
    "point, message",
    [
        ((math.nan, 10), "Target_Bad: a curve point is not finite (nan, 10, 0)"),
        # Blender stores inf as the largest float32.
        ((math.inf, 10), "Target_Bad: a curve point (3.40282e+38, 10, 0) lies beyond 1e+07 m"),
        ((1e12, 10), "Target_Bad: a curve point (1e+12, 10, 0) lies beyond 1e+07 m (10,000 km) from the origin"),
    ],
)  # fmt: skip
def test_curve_points_not_finite_or_too_far(tmp_path, blend_file, sensors_file, point, message):
    def bad_target(b):
        b.curve("Target_Bad", [[(0, 0), (10, 0), point, (0, 10)]])

    line = bad_coverage(
        tmp_path,
        blend_file(flat_scene(bad_target)),
        sensors_file({"model": "paper_camera", "sensors": [POSE]}),
    )
    assert line.startswith(f"error: {message}")


def test_a_curve_pushed_far_away_by_its_transform(tmp_path, blend_file, sensors_file):
    def far(b):
        b.curve("SensorArea_Far", [b.rect(-12, -4, -4, 4)]).location = (0, 5e7, 0)

    line = bad_coverage(
        tmp_path,
        blend_file(flat_scene(sensor_area=far)),
        sensors_file({"model": "paper_camera", "sensors": [POSE]}),
    )
    assert line.startswith(
        "error: SensorArea_Far: a curve point, placed by the object's transform, (-12, 5e+07, 0) lies beyond 1e+07 m"
    )


# --- 8. a directory as the scene -----------------------------------------------------------


def test_a_directory_is_not_a_blend_file(tmp_path):
    folder = tmp_path / "some_dir"
    folder.mkdir()
    assert bad_optimize(tmp_path, folder) == f"error: {folder}: is a directory, not a .blend file"


def test_a_directory_is_not_a_sensors_file(tmp_path):
    assert (
        bad_coverage(tmp_path, FLAT, tmp_path)
        == f"error: {tmp_path}: is a directory, not a sensors file"
    )


# --- limits are those the README's numbers live within ---------------------------------


def test_the_limits_admit_a_georeferenced_scene_and_the_presets():
    assert MAX_COORD_M >= 10_000_000  # UTM northings (southern hemisphere) reach 10,000 km
    assert 300 < MAX_RANGE_M <= 2000  # the panel's Range field ends at 2000 m
