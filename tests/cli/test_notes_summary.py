"""Repeated notes become one summary line (issue 34): a sensor area with many things
standing in it prints the first ``notes.SHOWN`` notes, then one line that counts them
by cause and sums their m^2; every note goes to notes.txt (optimize, in the output
folder) or OUT.notes.txt (coverage, beside --out), under the output rules."""

from __future__ import annotations

import json
import re

import pytest

from headless import notes
from tests.cli.conftest import run_headless

GREEDY = 'optimizer = "greedy"\nrho = 0.5\n'
PILLARS = 8  # 0.4 m square pillars, 2 m high, standing in the sensor area
ONE_SENSOR = {
    "model": "paper_camera",
    "sensors": [{"x": -8, "y": 0, "pitch_deg": 40, "yaw_deg": 0}],
}


def pillar_scene(b, pillars: int, zone: bool = True) -> None:
    """flat_wall's contract, with ``pillars`` pillars along the sensor area's south edge
    and a no-mast zone across its north edge (each its own note)."""
    b.flat_wall_scene()
    for k in range(pillars):
        x = -11.5 + k
        b.box(f"Pillar_{k}", (x, -3.8, 0.0), (x + 0.4, -3.4, 2.0))
    if zone:
        b.curve("NoMast_Pipe", [b.rect(-12.5, 3.0, -3.5, 4.5)])


def note_lines(stderr: str) -> list[str]:
    return [line for line in stderr.splitlines() if line.startswith("note: ")]


def test_optimize_prints_a_few_and_sums_up_the_rest(tmp_path, blend_file):
    scene = blend_file(lambda b: pillar_scene(b, PILLARS))
    (tmp_path / "g.toml").write_text(GREEDY)
    out = tmp_path / "out"
    code, _, stderr = run_headless(
        "optimize", scene, "--config", tmp_path / "g.toml", "--out-dir", out
    )
    assert code in (0, 3), stderr
    listed = json.loads((out / "result.json").read_text())["no_mast_sites"]
    assert len(listed) == PILLARS + 1  # each pillar, and the zone
    every = (out / "notes.txt").read_text().splitlines()
    assert len(every) == PILLARS + 1
    for entry, line in zip(listed, every):
        assert line.startswith(f"note: {entry['area']}: ") and f"({entry['cause']})" in line
    printed = [ln for ln in note_lines(stderr) if "no mast site" in ln]
    assert printed[: notes.SHOWN] == every[: notes.SHOWN]
    summary = printed[notes.SHOWN :]
    m2 = sum(entry["m2"] for entry in listed)
    assert summary == [
        f"note: {PILLARS + 1} sensor-area pieces with no mast site ({m2:,.1f} m^2 in all; "
        f"{PILLARS} under objects standing on the ground, 1 in no-mast zones): the first "
        f"{notes.SHOWN} above, every one in {out / 'notes.txt'} with the results"
    ]
    # Under the output rule: a second run refuses it (with the rest) until --overwrite.
    (out / "checkpoint.jsonl").unlink()
    code, _, stderr = run_headless(
        "optimize", scene, "--config", tmp_path / "g.toml", "--out-dir", out
    )
    assert code == 2 and "notes.txt" in stderr, stderr


def test_a_few_notes_are_all_printed_and_an_earlier_notes_file_goes(tmp_path, blend_file):
    scene = blend_file(lambda b: pillar_scene(b, 2, zone=False))
    (tmp_path / "g.toml").write_text(GREEDY)
    out = tmp_path / "out"
    out.mkdir()
    (out / "notes.txt").write_text("an earlier run's notes\n")
    code, _, stderr = run_headless(
        "optimize", scene, "--config", tmp_path / "g.toml", "--out-dir", out, "--overwrite"
    )
    assert code in (0, 3), stderr
    printed = [ln for ln in note_lines(stderr) if "no mast site" in ln]
    assert len(printed) == 2 and not any("every one in" in ln for ln in printed)
    assert not (out / "notes.txt").exists()


@pytest.mark.parametrize("pillars", [PILLARS, 1])
def test_coverage_writes_its_notes_beside_its_out(tmp_path, blend_file, sensors_file, pillars):
    scene = blend_file(lambda b: pillar_scene(b, pillars))
    out = tmp_path / "cov.json"
    beside = tmp_path / "cov.notes.txt"
    beside.write_text("an earlier run's notes\n")
    args = ("coverage", scene, "--sensors", sensors_file(ONE_SENSOR), "--out", out)
    code, _, stderr = run_headless(*args)
    assert code == 2 and str(beside) in stderr and not out.exists()  # the output rule
    code, _, stderr = run_headless(*args, "--overwrite")
    assert code == 0, stderr
    printed = note_lines(stderr)
    if pillars + 1 > notes.SHOWN:
        every = beside.read_text().splitlines()
        assert len(every) == pillars + 1 and printed[: notes.SHOWN] == every[: notes.SHOWN]
        assert re.fullmatch(
            rf"note: {pillars + 1} sensor-area pieces with no mast site \([\d.]+ m\^2 in all; "
            rf"{pillars} under objects standing on the ground, 1 in no-mast zones\): the "
            rf"first {notes.SHOWN} above, every one in {re.escape(str(beside))} with the results",
            printed[-1],
        )
    else:
        assert len(printed) == pillars + 1 and not beside.exists()
