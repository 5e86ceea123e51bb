"""The README's commands run as written, its figures are what they give, and the docs
site builds strictly with reference pages that match the code."""

from __future__ import annotations

import csv
import json
import os
import re
import subprocess
import sys
from pathlib import Path

import pytest

from autoscoop_blender.core.result import CLEAR_SIGHT_NOTE
from autoscoop_blender.io.result_fields import MAST, METRICS, RESULT, SENSOR, SENSORS_CSV
from tests.conftest import ROOT
from tools import docs

README = ROOT / "README.md"


def shell_lines(text: str) -> list[str]:
    """The commands of the ```bash blocks, comments and continuations resolved."""
    lines = []
    for block in re.findall(r"```bash\n(.*?)```", text, flags=re.S):
        for line in block.replace("\\\n", " ").splitlines():
            line = line.split("  #")[0].strip()
            if line and not line.startswith("#"):
                lines.append(line)
    return lines


def test_the_readme_is_short_and_its_links_resolve():
    text = README.read_text()
    assert len(text.splitlines()) <= 200
    links = re.findall(r"\]\(([^)#]+)(?:#[^)]*)?\)", text)
    assert links
    for link in links:
        assert (ROOT / link).exists(), link


def test_the_readmes_dev_sh_commands_exist():
    jobs = re.search(r'case "\$\{1:-\}" in(.*)esac', (ROOT / "dev.sh").read_text(), re.S)
    handled = set(re.findall(r"^\s+([a-z|]+)\)", jobs.group(1), flags=re.M))
    handled = {job for group in handled for job in group.split("|")}
    used = [line.split()[1] for line in shell_lines(README.read_text()) if line.startswith("./")]
    assert used and set(used) <= handled


@pytest.fixture(scope="module")
def readme_run(tmp_path_factory):
    """The README's ``.venv/bin/python -m headless`` lines run as written, in a folder
    that holds what they name from the repository (``.venv``, ``tests``)."""
    here = tmp_path_factory.mktemp("readme")
    (here / ".venv").symlink_to(Path(sys.prefix))
    (here / "tests").symlink_to(ROOT / "tests")
    env = {**os.environ, "PYTHONPATH": str(ROOT)}
    commands = [c for c in shell_lines(README.read_text()) if c.startswith(".venv/bin/python")]
    assert [c.split()[3] for c in commands] == ["import-xodr", "optimize", "coverage"]
    printed = {}
    for command in commands:
        proc = subprocess.run(
            command, shell=True, cwd=here, env=env, capture_output=True, text=True, timeout=600
        )
        assert proc.returncode == 0, (command, proc.stderr[-2000:])
        printed[command.split()[3]] = proc.stdout
    return here, printed


def test_the_readmes_example_plans_what_it_says(readme_run):
    here, printed = readme_run
    out = here / "out" / "garage"
    result = json.loads((out / "result.json").read_text())
    m = result["metrics"]
    # "3 cameras on one mast cover 99.9 % of the garage's 828 m^2 of lanes, at cost 6,
    # proven optimal on the candidate set"
    assert (m["sensors"], m["masts"], m["cost"], m["gap"]) == (3, 1, 6.0, 0.0)
    assert round(m["coverage_fraction"], 3) == 0.999
    assert round(m["target_area_m2"]) == 828
    recount = json.loads((out / "recount.json").read_text())
    assert recount["coverage_fraction"] == pytest.approx(m["coverage_fraction"], abs=1e-6)
    # Its output is the plan's, not Blender's ("Read blend: ..."), and the imported
    # ground, where nothing stands up, says that its sight lines were clear.
    assert printed["optimize"].splitlines() == [
        "3 sensors on 1 mast cover 99.88%, cost 6 >= 6 (optimal on the candidate set), in "
        f"{m['wall_s']:.1f} s -> out/garage",
        "Reached the goal: 97% of the target is covered.",
    ]
    assert result["notes"] == [CLEAR_SIGHT_NOTE] == recount["notes"]


def test_the_result_files_hold_the_documented_keys(readme_run):
    """Every key a run writes is in the reference's tables, and every documented key is
    written (those for mixed packs only excepted: this run has one model)."""
    out = readme_run[0] / "out" / "garage"
    result = json.loads((out / "result.json").read_text())
    for written, documented, mixed_only in (
        (result, RESULT, {"models"}),
        (result["metrics"], METRICS, set()),
        (result["sensors"][0], SENSOR, {"model"}),
        (result["masts"][0], MAST, set()),
    ):
        assert set(written) == set(documented) - mixed_only
    with open(out / "sensors.csv", newline="") as f:
        assert next(csv.reader(f)) == list(SENSORS_CSV)


def test_the_reference_pages_are_what_the_code_generates():
    for path, text in docs.pages().items():
        assert path.read_text() == text, f"{path.name}: run ./dev.sh docs"


def test_the_docs_site_builds_strictly(tmp_path):
    proc = subprocess.run(
        [sys.executable, "-m", "mkdocs", "build", "--strict", "--site-dir", str(tmp_path)],
        cwd=ROOT,
        capture_output=True,
        text=True,
        env={**os.environ, "NO_MKDOCS_2_WARNING": "1"},
        timeout=300,
    )
    assert proc.returncode == 0, proc.stderr[-3000:]
    assert (tmp_path / "reference" / "settings" / "index.html").is_file()
    assert (tmp_path / "guide" / "scene" / "index.html").is_file()
