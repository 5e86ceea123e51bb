"""The developer tools behind ``./dev.sh mutants`` and ``./dev.sh coverage``: their
arguments, the module-to-tests map, and the pins and settings they rely on. Nothing here
runs mutmut or coverage (both are slow and kept out of the default run)."""

from __future__ import annotations

import re
import subprocess
import tomllib

import pytest

from tests.conftest import ROOT
from tools import mutants


def test_every_mapped_module_and_test_file_exists():
    for module, tests in mutants.TESTS_FOR.items():
        assert (ROOT / module).is_file(), module
        assert module.startswith("autoscoop_blender/core/"), module
        assert tests, module
        for test in tests:
            assert (ROOT / test).is_file(), (module, test)


def test_modules_are_named_as_paths_and_kept_in_order_once():
    args = mutants.parse_args(
        [
            "./autoscoop_blender/core/masts.py",
            str(ROOT / "autoscoop_blender/core/candidates.py"),
            "autoscoop_blender/core/masts.py",
            "-j",
            "2",
        ]
    )
    assert args.modules == [
        "autoscoop_blender/core/masts.py",
        "autoscoop_blender/core/candidates.py",
    ]
    assert args.jobs == 2
    assert args.rev is None
    assert args.only == []


def test_no_module_means_every_mapped_one():
    assert mutants.parse_args([]).modules == list(mutants.TESTS_FOR)


def test_only_patterns_are_kept_in_order():
    args = mutants.parse_args(["--only", "*x_f__*", "--only", "*x_g__mutmut_1"])
    assert args.only == ["*x_f__*", "*x_g__mutmut_1"]


@pytest.mark.parametrize(
    "argv",
    [["autoscoop_blender/core/nothing.py"], ["autoscoop_blender/io/__init__.py"], ["-j", "0"]],
)
def test_an_unmapped_module_or_no_jobs_is_refused(argv, capsys):
    with pytest.raises(SystemExit) as exit_:
        mutants.parse_args(argv)
    assert exit_.value.code == 2
    assert "error" in capsys.readouterr().err


def test_the_mutmut_settings_mutate_one_module_with_its_tests():
    module = "autoscoop_blender/core/masts.py"
    table = tomllib.loads(mutants.mutmut_config(module))["tool"]["mutmut"]
    assert table["only_mutate"] == [module]
    assert table["pytest_add_cli_args_test_selection"] == mutants.TESTS_FOR[module]
    assert table["source_paths"] == ["autoscoop_blender"]
    assert table["use_git_change_detection"] is False
    # The repository's own pyproject must not hold a second [tool.mutmut].
    assert "mutmut" not in tomllib.loads((ROOT / "pyproject.toml").read_text())["tool"]


def test_the_score_counts_timeouts_as_killed_and_lists_the_rest():
    status = {
        "m.x_f__mutmut_10": "survived",
        "m.x_f__mutmut_2": "killed",
        "m.x_f__mutmut_3": "timeout",
        "m.x_g__mutmut_1": "no tests",
    }
    diffs = {"m.x_f__mutmut_10": ["-    return a < b", "+    return a <= b"]}
    score = mutants.Score("m.py", status, diffs)
    assert (score.killed, score.total) == (2, 4)
    assert score.survivors() == ["m.x_f__mutmut_10", "m.x_g__mutmut_1"]
    text = mutants.report([score])
    assert text.splitlines()[0] == "m.py: killed 2 of 4"
    assert "+    return a <= b".strip() in text
    assert text.splitlines()[-1] == "killed 2 of 4"


def test_mutants_left_out_by_only_are_neither_killed_nor_survivors():
    status = dict.fromkeys(["m.x_g__mutmut_1", "m.x_g__mutmut_2"], "not checked")
    status |= {"m.x_f__mutmut_1": "killed", "m.x_f__mutmut_2": "survived"}
    score = mutants.Score("m.py", status)
    assert (score.killed, score.total, score.not_run) == (1, 2, 2)
    assert score.survivors() == ["m.x_f__mutmut_2"]
    text = mutants.report([score])
    assert text.splitlines()[0] == "m.py: killed 1 of 2 run, 2 not run"
    assert text.splitlines()[-1] == "killed 1 of 2"


def test_the_copy_lives_in_an_ignored_folder():
    ignored = subprocess.run(
        ["git", "check-ignore", "-q", ".mutants/x/autoscoop_blender/core/masts.py"],
        cwd=ROOT,
    )
    assert ignored.returncode == 0
    assert mutants.WORK == ROOT / ".mutants"


def test_the_tools_are_pinned_and_out_of_the_default_run():
    pins = (ROOT / "requirements.txt").read_text()
    for name in ("mutmut", "pytest-cov", "coverage"):
        assert re.search(rf"^{name}==[0-9.]+", pins, re.M), name
    dev = (ROOT / "dev.sh").read_text()
    test_case = dev.split("\n    test)", 1)[1].split(";;", 1)[0]
    assert "mutants" not in test_case and "--cov" not in test_case
    settings = tomllib.loads((ROOT / "pyproject.toml").read_text())
    assert "--cov" not in settings["tool"]["pytest"]["ini_options"].get("addopts", "")
    run = settings["tool"]["coverage"]["run"]
    assert run["branch"] is True
    assert run["source"] == ["autoscoop_blender/core", "autoscoop_blender/io"]
