"""The settings schema: every knob defined once, and everything read through it."""

import math
from dataclasses import replace

import numpy as np
import pytest

from autoscoop_blender.core.errors import InputError
from autoscoop_blender.core.settings import (
    PANEL_SETTINGS,
    CoverageSettings,
    ESParams,
    FitnessParams,
    OptimizeSettings,
    from_mapping,
    settings_schema,
)
from autoscoop_blender.io.config import load_config

SCHEMA = list(settings_schema(OptimizeSettings))


def test_every_knob_has_a_type_default_and_help_and_its_default_is_valid():
    paths = [s.path for s in SCHEMA]
    assert len(paths) == len(set(paths)) >= 30
    for s in SCHEMA:
        assert s.kind in (int, float, bool, str), s.path
        assert len(s.knob.help) > 10, s.path
        assert s.default is not None or s.optional, s.path
        s.check(s.default)  # raises if a default broke its own limits
    OptimizeSettings().validated()
    # The groups are in it, under their table names.
    assert {"es.mu", "es.decay", "fitness.w_sc", "rho", "grid_m", "seed"} <= set(paths)


def test_a_file_round_trips_through_the_schema():
    s = OptimizeSettings(rho=0.9, seed=7, es=ESParams(mu=8), fitness=FitnessParams(w_sc=1.0))
    data = s.to_dict()
    assert from_mapping(OptimizeSettings, data, "x") == s
    # Nested tables as TOML writes them.
    assert OptimizeSettings.from_mapping({"es": {"mu": 8}}, "c.toml").es == ESParams(mu=8)


@pytest.mark.parametrize(
    ("data", "message"),
    [
        ({"rhoo": 0.9}, "c.toml: unknown setting(s) rhoo"),
        ({"es": {"muu": 3}}, r"c.toml [es]: unknown setting(s) muu"),
        ({"es": 3}, "c.toml [es]: must be a table"),
        ({"rho": "high"}, "c.toml: rho must be a number, got 'high'"),
        ({"seed": 1.5}, "c.toml: seed must be an integer, got 1.5"),
        ({"es": {"mu": 40.5}}, "c.toml [es]: mu must be an integer, got 40.5"),
        ({"max_sensors": True}, "c.toml: max_sensors must be an integer, got True"),
        ({"max_sensors": 2.5}, "c.toml: max_sensors must be an integer, got 2.5"),
        ({"cache": 1}, "c.toml: cache must be true or false, got 1"),
        ({"rho": 1.5}, "setting rho (--rho) = 1.5 is out of range: must be in (0, 1]"),
        ({"rho": 0.0}, "setting rho (--rho) = 0.0 is out of range: must be in (0, 1]"),
        ({"seed": -1}, "setting seed (--seed) = -1 is out of range: must be in [0, 9.22337e+18]"),
        ({"seed": 10**400}, "setting seed (--seed) = 1000"),
        (
            {"es": {"sigma_xy_m": -1}},
            "setting es.sigma_xy_m (--es-sigma-xy-m) = -1.0 is out of range",
        ),
        (
            {"es": {"sigma_yaw_deg": math.nan}},
            "setting es.sigma_yaw_deg (--es-sigma-yaw-deg) = nan is out of range",
        ),
        ({"grid_m": 0}, "setting grid_m (--grid) = 0.0 is out of range: must be > 0"),
        (
            {"fitness": {"theta_m": math.inf}},
            "setting fitness.theta_m (--fitness-theta-m) = inf is out of range",
        ),
        ({"method": "raster"}, "method 'raster': choose one of targeted, pointcloud"),
        ({"optimizer": "greedy", "method": "pointcloud"}, "greedy optimizer needs the targeted"),
    ],
)
def test_bad_values_are_one_line_errors_naming_the_key(data, message):
    with pytest.raises(InputError) as err:
        OptimizeSettings.from_mapping(data, "c.toml")
    assert message in str(err.value) and "\n" not in str(err.value)


def test_limits_hold_however_the_settings_were_built():
    with pytest.raises(InputError, match="rho"):
        replace(OptimizeSettings(), rho=1.5).validated()
    with pytest.raises(InputError, match="es.decay"):
        OptimizeSettings(es=ESParams(decay=0.0)).validated()
    with pytest.raises(InputError, match="--alpha"):
        CoverageSettings(alpha=-1.0).validated()
    # Optional knobs take None (derive it) or a value within limits.
    assert OptimizeSettings(max_sensors=None).validated().max_sensors is None
    with pytest.raises(InputError, match="max_sensors"):
        OptimizeSettings(max_sensors=0).validated()


def test_int_knobs_take_integers_and_float_knobs_take_both():
    s = OptimizeSettings.from_mapping({"rho": 1, "grid_m": 2}, "c.toml")
    assert s.rho == 1.0 and isinstance(s.rho, float) and s.grid_m == 2.0
    assert np.isfinite(s.fitness.band_m)
    # band_m: where tau of Eq. 2 falls to 0.05, exp(-d^2 / (2 theta^2)) = 0.05.
    assert s.fitness.band_m == pytest.approx(2.0 * math.sqrt(2 * math.log(20)))


def test_the_config_file_reads_model_and_settings(tmp_path):
    path = tmp_path / "c.toml"
    path.write_text('model = "roadside_lidar"\nrho = 0.8\n[es]\nmu = 9\n')
    settings, model = load_config(path)
    assert model.kind == "lidar" and settings.rho == 0.8 and settings.es.mu == 9
    path.write_text("rho = 0.8\n[es]\nmu = 9.5\n")
    with pytest.raises(InputError, match=r"c.toml \[es\]: mu must be an integer"):
        load_config(path)


def test_the_panel_shows_the_labelled_knobs():
    shown = {s.path for s in PANEL_SETTINGS}
    assert shown == {
        "method", "grid_m", "coverage_k", "optimizer", "rho", "seed", "objective",
        "max_sensors_per_mast",
        "es.mu", "es.lam", "es.eps", "es.max_epochs",
    }  # fmt: skip
    assert all(s.knob.label for s in PANEL_SETTINGS)
