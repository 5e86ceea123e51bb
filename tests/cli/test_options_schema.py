"""The command line is derived from the settings schema: each knob with a flag is an
option of the same type, choices and default, and lands in the knob of that name."""

import pytest

from autoscoop_blender.core.errors import InputError
from autoscoop_blender.core.settings import (
    CoverageSettings,
    OptimizeSettings,
    flag_values,
    settings_schema,
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
def test_every_flagged_knob_is_an_option(command, cls, overrides):
    options = _options(command)
    flagged = [s for s in settings_schema(cls) if s.knob.flag]
    assert {"--method", "--grid", "--alpha"} <= {s.knob.flag for s in flagged}
    for s in flagged:
        action = options[s.knob.flag]
        assert action.dest == s.path
        # An optimize option overrides the config file: unset unless given.
        assert action.default == (None if overrides else s.default)
        if s.knob.choices:
            assert action.choices == [c[0] for c in s.knob.choices]
        elif s.kind is bool:  # a switch that turns the knob on
            assert action.const is True and action.nargs == 0
        else:
            assert action.type is s.kind
        assert action.help.startswith(s.knob.help)


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
