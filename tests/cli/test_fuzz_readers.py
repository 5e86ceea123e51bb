"""Fuzzing the input readers (issue 14): random and boundary values thrown at the
sensors file, the sensor model, the optimize config and the scene's curves.

Each reader must either give a valid result (every number finite, within its limits)
or raise the project's one-line error (``AutoscoopError``: ``InputError`` for files,
``SceneContractError`` for scenes) whose message has no newline. Any other exception
is a bug. Bounded for CI: hypothesis keeps no example database (``database=None``)
and each test runs a fixed number of examples.
"""

from __future__ import annotations

import json
import math
import tempfile
from dataclasses import fields
from pathlib import Path

import bpy
import numpy as np
import pytest
from hypothesis import HealthCheck, event, given, settings
from hypothesis import strategies as st
from hypothesis.control import currently_in_test_context

from autoscoop_blender.core.errors import AutoscoopError
from autoscoop_blender.core.model.sensors import (
    MAX_COORD_M,
    MAX_RANGE_M,
    MAX_RAYS,
    PRESETS,
    SensorModel,
    SensorSpec,
)
from autoscoop_blender.core.settings import OptimizeSettings, settings_schema
from autoscoop_blender.io.config import load_config
from autoscoop_blender.io.sensor_file import parse_sensors, read_sensors
from autoscoop_blender.scene.extract import extract_scene
from tests.blender import builders as b

FUZZ = settings(
    max_examples=300,
    deadline=None,
    database=None,
    suppress_health_check=[HealthCheck.too_slow, HealthCheck.data_too_large],
)

# --- values -----------------------------------------------------------------------------

BOUNDARY_FLOATS = [
    math.nan, math.inf, -math.inf, -0.0, 0.0, 5e-324, 1e-300, 1e308, -1e308, 1.7976931348623157e308,
    1e7, 1e7 + 1, -1e7, 2000.0, 2000.0001, 0.1, 0.09, 90.0, 90.0000001, -90.0, 180.0, 360.0,
    1.9, 2.0, 0.5, 4096.0, 1e9,
]  # fmt: skip
HUGE_INTS = [2**53 + 1, 2**63, -(2**63) - 1, 10**20, 10**308, 10**309, 10**400, -(10**400)]

numbers = st.one_of(
    st.sampled_from(BOUNDARY_FLOATS),
    st.sampled_from(HUGE_INTS),
    st.floats(allow_nan=True, allow_infinity=True),
    st.floats(-1e4, 1e4),
    st.integers(-10, 100_000),
    st.integers(),
)
texts = st.text(max_size=10)
scalars = st.one_of(st.none(), st.booleans(), numbers, texts)
junk = st.recursive(
    scalars,
    lambda inner: st.lists(inner, max_size=3) | st.dictionaries(texts, inner, max_size=3),
    max_leaves=6,
)
values = st.one_of(numbers, numbers, junk)

MODEL_KEYS = [f.name for f in fields(SensorModel)]
SENSOR_KEYS = ["x", "y", "height_m", "pitch_deg", "yaw_deg"]
# Near misses and strangers: typos, case, unicode, empty.
ODD_KEYS = ["heigth_m", "pich_deg", "X", "yaw", "rang_m", "préset", "ключ", "", " x", "x\n", "🛰"]


def with_keys(base_keys, value_strategy):
    """Dicts over ``base_keys`` (each maybe missing), plus maybe odd or random keys."""
    return st.builds(
        lambda kept, odd: {**kept, **odd},
        st.fixed_dictionaries({}, optional={k: value_strategy for k in base_keys}),
        st.dictionaries(st.sampled_from(ODD_KEYS) | texts, value_strategy, max_size=2)
        | st.just({}),
    )


# Values a key might plausibly hold, boundary values, and anything else.
near_values = st.one_of(
    st.floats(-100, 3000), st.integers(-5, 5000), st.sampled_from(BOUNDARY_FLOATS), values
)


@st.composite
def mutated(draw, base, keys):
    """``base`` (a dict) with 0 to 2 of ``keys`` replaced, removed, or odd keys added."""
    out = dict(base)
    for _ in range(draw(st.integers(0, 2))):
        how = draw(st.sampled_from(["set", "set", "set", "drop", "odd"]))
        if how == "set":
            out[draw(st.sampled_from(keys))] = draw(near_values)
        elif how == "drop" and out:
            out.pop(draw(st.sampled_from(sorted(out))))
        elif how == "odd":
            out[draw(st.sampled_from(ODD_KEYS) | texts)] = draw(near_values)
    return out


model_specs = st.one_of(
    st.sampled_from([*PRESETS, "Paper_Camera", "paper camera", "", "nope"]),
    st.sampled_from(list(PRESETS)).flatmap(
        lambda name: mutated({"preset": name}, [*MODEL_KEYS, "preset"])
    ),
    st.sampled_from(list(PRESETS.values())).flatmap(lambda m: mutated(m.to_dict(), MODEL_KEYS)),
    with_keys(MODEL_KEYS, values),
    junk,
)
good_pose = st.fixed_dictionaries(
    {
        "x": st.floats(-1e7, 1e7) | st.integers(-100, 100),
        "y": st.floats(-1e7, 1e7) | st.integers(-100, 100),
        "pitch_deg": st.floats(-90, 90),
        "yaw_deg": st.floats(-1e6, 1e6) | st.sampled_from([-0.0, -1e-20, 360.0, 720]),
    },
    optional={"height_m": st.floats(0, 2000) | st.integers(0, 20)},
)
sensor_entries = st.one_of(
    good_pose.flatmap(lambda pose: mutated(pose, SENSOR_KEYS)),
    good_pose.flatmap(lambda pose: mutated(pose, SENSOR_KEYS)),
    st.builds(lambda pose, model: {**pose, "model": model}, good_pose, model_specs),
    with_keys(SENSOR_KEYS, values),
    junk,
)
sensor_documents = st.one_of(
    st.builds(
        lambda model, sensors: {"model": model, "sensors": sensors},
        st.sampled_from(list(PRESETS)) | model_specs,
        st.lists(good_pose, min_size=1, max_size=3),
    ),
    st.builds(
        lambda model, sensors, extra: {"model": model, "sensors": sensors, **extra},
        model_specs,
        st.lists(sensor_entries, min_size=1, max_size=3),
        st.dictionaries(st.sampled_from(["schema", "modle", "sensor", "🛰"]), values, max_size=1)
        | st.just({})
        | st.just({})
        | st.just({}),
    ),
    st.fixed_dictionaries({}, optional={"model": model_specs, "sensors": junk}),
    junk,
)


def assert_clean(error: AutoscoopError) -> None:
    if currently_in_test_context():
        event("error")
    message = str(error)
    assert message and "\n" not in message and "\r" not in message, repr(message)


def assert_valid_model(model: SensorModel) -> None:
    for f in fields(model):
        v = getattr(model, f.name)
        if f.name in ("kind", "pattern"):
            assert isinstance(v, str)
        elif f.name == "resolution_px":  # None, or whole pixels on a pinhole camera
            assert v is None or (
                model.pattern == "pinhole"
                and len(v) == 2
                and all(type(n) is int and n >= 1 for n in v)
            ), v
        else:
            assert type(v) is (int if f.name in ("rays_h", "rays_v") else float), (f.name, v)
            assert math.isfinite(v), (f.name, v)
    assert 0 < model.range_m <= MAX_RANGE_M and 0 <= model.mount_height_m < model.range_m
    assert 1 <= model.n_rays <= MAX_RAYS
    assert model.validated("again") == model


def assert_valid_spec(spec: SensorSpec) -> None:
    assert_valid_model(spec.model)
    for v in (spec.x, spec.y, spec.pitch_deg, spec.yaw_deg):
        assert type(v) is float and math.isfinite(v)
    assert abs(spec.x) <= MAX_COORD_M and abs(spec.y) <= MAX_COORD_M
    assert -90 <= spec.pitch_deg <= 90 and 0 <= spec.yaw_deg < 360
    assert spec.height_m is None or 0 <= spec.height_m <= MAX_RANGE_M


# --- (a) sensors file and sensor model ---------------------------------------------------


@FUZZ
@given(sensor_documents)
def test_parse_sensors(data):
    try:
        specs = parse_sensors(data, "f.json")
    except AutoscoopError as e:
        assert_clean(e)
        return
    event("valid")
    assert specs
    for spec in specs:
        assert_valid_spec(spec)


@FUZZ
@given(model_specs)
def test_sensor_model_from_spec(spec):
    try:
        model = SensorModel.from_spec(spec, "m")
    except AutoscoopError as e:
        assert_clean(e)
        return
    event("valid")
    assert_valid_model(model)


json_fragments = st.sampled_from(
    ["1" * 5000, "[" * 5000, "1e400", "-1e400", "NaN", "Infinity", '"\\ud800"', "\x00", "{", "}"]
)


@settings(FUZZ, max_examples=100)
@given(st.one_of(st.binary(max_size=60), st.lists(json_fragments | texts, max_size=4).map("".join)))
def test_read_sensors_raw_bytes(raw):
    with tempfile.TemporaryDirectory() as tmp:
        path = Path(tmp) / "s.json"
        path.write_bytes(raw if isinstance(raw, bytes) else raw.encode("utf-8", "surrogatepass"))
        try:
            read_sensors(path)
        except AutoscoopError as e:
            assert_clean(e)


@settings(FUZZ, max_examples=100)
@given(sensor_documents)
def test_read_sensors_through_json(data):
    """The same documents as a file (JSON writes NaN and Infinity as such)."""
    with tempfile.TemporaryDirectory() as tmp:
        path = Path(tmp) / "s.json"
        path.write_text(json.dumps(data))
        try:
            specs = read_sensors(path)
        except AutoscoopError as e:
            assert_clean(e)
            return
        event("valid")
        for spec in specs:
            assert_valid_spec(spec)


# --- (b) the optimize config ------------------------------------------------------------

SETTING_PATHS = [s.path for s in settings_schema(OptimizeSettings)]
TOP_SETTINGS = [p for p in SETTING_PATHS if "." not in p]
GROUPS = sorted({p.split(".")[0] for p in SETTING_PATHS if "." in p})
SCHEMA = {st_.path: st_ for st_ in settings_schema(OptimizeSettings)}


def setting_values(path):
    """Values of the knob's kind around its limits, or anything else."""
    knob, kind = SCHEMA[path].knob, SCHEMA[path].kind
    edges = [v for v in (knob.lo, knob.hi) if v is not None]
    near = [*edges, *(e + d for e in edges for d in (-1, -1e-9, 1e-9, 1))]
    if kind is str:
        right = st.sampled_from([c[0] for c in knob.choices] or ["x"]) | texts
    elif kind is bool:
        right = st.booleans()
    elif kind is int:
        right = st.integers(-3, 1000) | st.sampled_from([int(v) for v in near] or [0])
    else:
        right = st.floats(-10, 1000) | st.sampled_from(near or [0.0])
    return st.one_of(
        right, right, right, st.none(), st.sampled_from([*BOUNDARY_FLOATS, *HUGE_INTS]), values
    )


@st.composite
def config_mappings(draw):
    """The defaults with 0 to 3 knobs set (in their [group] tables), maybe odd keys."""
    data: dict = {}
    for _ in range(draw(st.integers(0, 3))):
        path = draw(st.sampled_from(sorted(SCHEMA)))
        *group, name = path.split(".")
        table = data.setdefault(group[0], {}) if group else data
        if isinstance(table, dict):
            table[name] = draw(setting_values(path))
    if draw(st.integers(0, 4)) == 0:
        data[draw(st.sampled_from([*ODD_KEYS, "es", "fitness", "rh0"]) | texts)] = draw(values)
    return data


FLOAT_SETTINGS = {s.path for s in settings_schema(OptimizeSettings) if s.kind is float}


def assert_valid_settings(s: OptimizeSettings) -> None:
    for setting in settings_schema(OptimizeSettings):
        v = s
        for part in setting.path.split("."):
            v = getattr(v, part)
        if isinstance(v, (int, float)) and not isinstance(v, bool):
            assert math.isfinite(v), (setting.path, v)


@FUZZ
@given(config_mappings())
def test_optimize_settings_from_mapping(data):
    try:
        s = OptimizeSettings.from_mapping(data, "c.toml").validated()
    except AutoscoopError as e:
        assert_clean(e)
        return
    event("valid")
    assert_valid_settings(s)


def toml_value(v):
    """TOML for a value of the fuzzed documents (None has no TOML form: callers drop it)."""
    if isinstance(v, bool):
        return "true" if v else "false"
    if isinstance(v, int):
        return str(v)
    if isinstance(v, float):
        return "nan" if math.isnan(v) else {math.inf: "inf", -math.inf: "-inf"}.get(v, repr(v))
    if isinstance(v, str):
        return json.dumps(v).replace("\x7f", "\\u007f")
    if isinstance(v, list):
        return "[" + ", ".join(toml_value(x) for x in v if x is not None) + "]"
    items = (f"{json.dumps(k)} = {toml_value(x)}" for k, x in v.items() if x is not None)
    return "{ " + ", ".join(items) + " }"


@settings(FUZZ, max_examples=200)
@given(config_mappings(), st.one_of(st.none(), model_specs))
def test_load_config(data, model):
    if model is not None:
        data = {**data, "model": model}
    text = "\n".join(f"{json.dumps(k)} = {toml_value(v)}" for k, v in data.items() if v is not None)
    with tempfile.TemporaryDirectory() as tmp:
        path = Path(tmp) / "c.toml"
        path.write_text(text + "\n", encoding="utf-8")
        try:
            s, m = load_config(path)
        except AutoscoopError as e:
            assert_clean(e)
            return
    event("valid")
    assert_valid_settings(s)
    assert_valid_model(m)


def test_a_huge_int_for_a_float_setting_is_one_line():
    with pytest.raises(
        AutoscoopError, match="mast_join_m is a 310-digit integer, too large"
    ) as info:
        OptimizeSettings.from_mapping({"mast_join_m": 10**309}, "c.toml")
    assert_clean(info.value)
    with pytest.raises(AutoscoopError, match="a 4,999-or-more-digit integer"):  # str() refuses it
        OptimizeSettings.from_mapping({"mast_join_m": 10**4999}, "c.toml")


def test_an_unknown_setting_with_a_line_break_stays_one_line():
    with pytest.raises(AutoscoopError, match=r"unknown setting\(s\) 'x\\n'") as info:
        OptimizeSettings.from_mapping({"x\n": 1}, "c.toml")
    assert_clean(info.value)


def test_a_toml_integer_too_long_to_read_is_one_line(tmp_path):
    cfg = tmp_path / "long.toml"
    cfg.write_text("rho = " + "1" * 5000 + "\n")
    with pytest.raises(AutoscoopError, match="long.toml: not readable TOML") as info:
        load_config(cfg)
    assert_clean(info.value)


# --- (c) the scene's curves -------------------------------------------------------------

sane = st.floats(-60, 60)
coordinates = st.one_of(
    sane,
    st.sampled_from([math.nan, math.inf, -math.inf, -0.0, 1e12, -1e12, 1e308, 1e7, 5e6, 1e-30]),
    st.floats(allow_nan=True, allow_infinity=True, width=32),
)


@st.composite
def rings(draw):
    """1 to 8 points: random, with repeats, on a line, or a rectangle (maybe tilted);
    most with ordinary coordinates, some with any."""
    coord = draw(st.sampled_from([sane, sane, sane, coordinates]))
    z_of = st.sampled_from([0.0, 0.0, 2.5]) | coord
    shape = draw(st.sampled_from(["rect", "rect", "rect", "rect", "random", "repeats", "line"]))
    if shape == "rect":
        x0, y0 = draw(st.floats(-50, 40)), draw(st.floats(-50, 40))
        size = st.sampled_from([5.0, 20.0]) | st.floats(1, 20) | st.floats(0, 20)
        w, h = draw(size), draw(size)
        z = draw(z_of)
        slope = draw(st.sampled_from([0.0, 0.0, 0.0, 0.01, 0.1, 0.5, 1e6]))
        corners = [(x0, y0), (x0 + w, y0), (x0 + w, y0 + h), (x0, y0 + h)]
        return [(x, y, z + slope * (y - y0)) for x, y in corners]
    least = draw(st.sampled_from([1, 3, 3, 3]))
    pts = draw(st.lists(st.tuples(coord, coord, z_of), min_size=least, max_size=8))
    if shape == "repeats":
        pts = [pts[draw(st.integers(0, len(pts) - 1))] for _ in range(draw(st.integers(1, 8)))]
    elif shape == "line":
        (x0, y0, z0), (dx, dy) = pts[0], (draw(st.floats(-5, 5)), draw(st.floats(-5, 5)))
        pts = [(x0 + k * dx, y0 + k * dy, z0) for k in range(draw(st.integers(1, 6)))]
    return pts


splines = st.tuples(
    rings(),
    st.sampled_from(["POLY"] * 12 + ["BEZIER"] * 6 + ["NURBS"]),
    st.sampled_from([True] * 12 + [False]),
)
curves = st.tuples(
    st.one_of(*[st.lists(splines, min_size=1, max_size=2)] * 6, st.lists(splines, max_size=3)),
    st.one_of(  # object transform: none, a rotation, a scale, a far move
        *[st.just(None)] * 12,
        st.tuples(st.just("rotation"), st.tuples(*[st.floats(-math.pi, math.pi)] * 3)),
        st.tuples(st.just("rotation"), st.tuples(st.floats(-0.1, 0.1), st.just(0.0), st.just(0.0))),
        st.tuples(st.just("scale"), st.tuples(*[st.sampled_from([0.0, 1.0, -1.0, 1e-6, 1e6])] * 3)),
        st.tuples(st.just("location"), st.tuples(*[st.sampled_from([0.0, 1e5, -3e7])] * 3)),
    ),
)


def make_curve(name, spec):
    splines_, transform = spec
    data = bpy.data.curves.new(name, "CURVE")
    data.dimensions = "3D"
    for pts, kind, cyclic in splines_:
        sp = data.splines.new(kind)
        if kind == "BEZIER":
            sp.bezier_points.add(len(pts) - 1)
            for bp, p in zip(sp.bezier_points, pts):
                bp.co = p
                bp.handle_left_type = bp.handle_right_type = "VECTOR"
        else:
            sp.points.add(len(pts) - 1)
            for sp_pt, p in zip(sp.points, pts):
                sp_pt.co = (*p, 1.0)
        sp.use_cyclic_u = cyclic
    obj = bpy.data.objects.new(name, data)
    bpy.context.scene.collection.objects.link(obj)
    if transform is not None:
        setattr(obj, {"rotation": "rotation_euler"}.get(transform[0], transform[0]), transform[1])
    return obj


def assert_valid_scene(scene) -> None:
    assert np.isfinite(scene.vertices).all() and np.isfinite(scene.origin).all()
    for area in (*scene.targets, *scene.sensor_areas):
        assert area.geometry.is_valid and not area.geometry.is_empty
        assert math.isfinite(area.area_m2) and area.area_m2 > 0
        assert np.isfinite(area.geometry.bounds).all() and math.isfinite(area.z)
        assert max(map(abs, area.geometry.bounds)) <= 2 * MAX_COORD_M
    assert all("\n" not in w for w in scene.warnings)


grounds = st.one_of(
    st.none(),
    st.just("plane"),
    st.just("plane"),
    st.lists(st.tuples(coordinates, coordinates, coordinates), min_size=3, max_size=6),
)


@settings(FUZZ, max_examples=120)
@given(curves, st.one_of(st.none(), curves), grounds)
def test_extract_scene_with_random_curves(target, sensor_area, ground):
    """Random curves (and maybe a ground plane, or a mesh of random vertices)."""
    bpy.ops.wm.read_factory_settings(use_empty=True)
    if ground == "plane":
        b.plane("Ground", -60, -60, 60, 60)
    elif ground is not None:
        b.mesh("Junk", ground, [range(len(ground))])
    make_curve("Target_Fuzz", target)
    if sensor_area is None:
        b.curve("SensorArea", [b.rect(-12, -4, -4, 4)])
    else:
        make_curve("SensorArea_Fuzz", sensor_area)
    try:
        scene = extract_scene()
    except AutoscoopError as e:
        assert_clean(e)
        event(f"error: {str(e).split(': ', 1)[-1][:28]}")
        return
    event("valid")
    assert_valid_scene(scene)


@pytest.fixture(autouse=True, scope="module")
def empty_file_after():
    yield
    bpy.ops.wm.read_factory_settings(use_empty=True)
