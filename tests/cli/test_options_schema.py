"""The command line is derived from the settings schema: every knob is an option of the
same type, choices and default, and lands in the knob of that name."""

import argparse

import pytest

from autoscoop_blender.core.errors import InputError
from autoscoop_blender.core.settings import (
    CoverageSettings,
    ESParams,
    OptimizeSettings,
    flag_values,
    settings_schema,
    with_values,
)
from headless.cli import build_parser


def _options(command):
    parser = build_parser()
    sub = next(a for a in parser._actions if a.dest == "command").choices[command]
    return {a.option_strings[0]: a for a in sub._actions if a.option_strings}


@pytest.mark.parametrize(
    ("command", "cls", "overrides"),
    [("coverage", CoverageSettings, False), ("optimize", OptimizeSettings, True)],
)
def test_every_knob_is_an_option(command, cls, overrides):
    options = _options(command)
    schema = list(settings_schema(cls))
    # Each knob has its own option, named by the knob's flag or derived from its path.
    assert len({s.flag for s in schema}) == len(schema)
    assert {"--method", "--grid", "--alpha", "--mast-join-m"} <= set(options)
    if cls is OptimizeSettings:
        assert {"--rho", "--es-mu", "--fitness-theta-tau-m", "--max-per-mast"} <= set(options)
    for s in schema:
        action = options[s.flag]
        assert action.dest == s.path
        # An optimize option overrides the config file: unset unless given.
        assert action.default == (None if overrides else s.default)
        if s.knob.choices:
            assert action.choices == [c[0] for c in s.knob.choices]
        elif s.kind is bool:  # --knob and --no-knob
            assert isinstance(action, argparse.BooleanOptionalAction)
        else:
            assert action.type is s.kind
        assert action.help.startswith(s.knob.help)
        if s.default is not None and s.kind in (int, str):
            assert action.help.endswith(f"(default {s.default})")


def test_nested_and_switch_options_land_in_their_knobs():
    args = build_parser().parse_args(
        ["optimize", "--rho", "0.9", "--es-mu", "7", "--no-cache", "--model", "roadside_lidar"]
    )
    given = {k: v for k, v in flag_values(OptimizeSettings, vars(args)).items() if v is not None}
    assert given == {"rho": 0.9, "es.mu": 7, "cache": False}
    settings = with_values(OptimizeSettings(), given).validated()
    assert settings == OptimizeSettings(rho=0.9, es=ESParams(mu=7), cache=False)
    assert args.model == "roadside_lidar"
    args = build_parser().parse_args(["optimize", "--es-decay", "1.5"])
    with pytest.raises(InputError, match=r"es.decay \(--es-decay\) = 1.5 is out of range"):
        with_values(OptimizeSettings(), {"es.decay": args.__dict__["es.decay"]}).validated()


def test_the_users_help_lists_the_users_commands_only(capsys):
    with pytest.raises(SystemExit):
        build_parser().parse_args(["--help"])
    text = capsys.readouterr().out
    commands = next(a for a in build_parser()._actions if a.dest == "command").choices
    assert sorted(commands) == ["coverage", "import-xodr", "optimize"]
    for word in ("build", "samples", "bench", "devtools", "AutoscoopError", ".py"):
        assert word not in text


def test_parsed_options_become_settings():
    args = build_parser().parse_args(
        ["coverage", "--sensors", "s.json", "--out", "o.json", "--grid", "0.5", "--alpha", "2"]
    )
    settings = CoverageSettings(**flag_values(CoverageSettings, vars(args))).validated()
    assert settings == CoverageSettings(grid_m=0.5, alpha=2.0)
    args = build_parser().parse_args(["coverage", "--sensors", "s", "--out", "o", "--grid", "-1"])
    with pytest.raises(InputError, match=r"grid_m \(--grid\) = -1.0 is out of range"):
        CoverageSettings(**flag_values(CoverageSettings, vars(args))).validated()
    args = build_parser().parse_args(
        ["optimize", "--seed", "4", "--optimizer", "greedy", "--bound"]
    )
    given = {k: v for k, v in flag_values(OptimizeSettings, vars(args)).items() if v is not None}
    assert given == {"seed": 4, "optimizer": "greedy", "bound": True}
