"""Outputs never land on inputs, and an existing file is replaced only with
--overwrite: the same rule in coverage, optimize and import-xodr (``headless.files``).

Every refusal is one line with exit code 2, before any work, and leaves every file as
it was (compared byte for byte). Writes go through a temporary file and a rename: a
symbolic link is replaced, never written through, and a write that fails (a file
size limit standing in for a full disk) leaves no temporary file behind.
"""

import json
import os
import resource
import shutil
import subprocess
import sys
from pathlib import Path

import pytest

from headless.jobs import RESULT_NAMES
from tests.cli.conftest import SAMPLES, run_headless
from tests.conftest import ROOT

FLAT = SAMPLES / "flat_wall.blend"
XODR = ROOT / "tests" / "data" / "xodr" / "AstaZero_FlexZoneCrossing.xodr"
ONE_SENSOR = {
    "model": "paper_camera",
    "sensors": [{"x": -8, "y": 0, "pitch_deg": 40, "yaw_deg": 0}],
}
GREEDY = 'optimizer = "greedy"\nrho = 0.5\n'


def snapshot(folder: Path) -> dict[str, bytes]:
    """Every file under ``folder`` (links as what they point at), by relative path."""
    out = {}
    for p in sorted(folder.rglob("*")):
        if p.is_symlink():
            out[str(p.relative_to(folder))] = b"-> " + os.readlink(p).encode()
        elif p.is_file():
            out[str(p.relative_to(folder))] = p.read_bytes()
    return out


def refused(args, folder: Path, words: str) -> str:
    """Run the CLI; it must refuse with one line holding ``words`` and change nothing
    under ``folder``. Returns the line."""
    before = snapshot(folder)
    code, _, stderr = run_headless(*args)
    lines = stderr.strip().splitlines()
    assert code == 2, stderr
    assert len(lines) == 1 and lines[0].startswith("error: ") and words in lines[0], stderr
    assert snapshot(folder) == before
    return lines[0]


@pytest.fixture
def work(tmp_path):
    """A folder with a scene and a sensors file of the user's."""
    shutil.copy(FLAT, tmp_path / "S.blend")
    (tmp_path / "plan.json").write_text(json.dumps(ONE_SENSOR))
    return tmp_path


def coverage_args(work: Path, out: Path, *extra):
    return ("coverage", work / "S.blend", "--sensors", work / "plan.json", "--out", out, *extra)


@pytest.mark.parametrize("name", ["S.blend", "plan.json"])
def test_coverage_out_on_an_input_is_refused_even_with_overwrite(work, name):
    line = refused(coverage_args(work, work / name, "--overwrite"), work, "an input")
    assert str(work / name) in line


def test_an_input_by_another_name_is_refused(work):
    """A symbolic link to the scene, a hard link to it, a path through ``..``, and a
    linked folder: each is the scene."""
    (work / "link.json").symlink_to(work / "S.blend")
    os.link(work / "plan.json", work / "hard.json")
    (work / "sub").mkdir()
    (work / "alias").symlink_to(work, target_is_directory=True)
    for out in (
        work / "link.json",
        work / "hard.json",
        work / "sub" / ".." / "S.blend",
        work / "alias" / "plan.json",
    ):
        refused(coverage_args(work, out, "--overwrite"), work, "an input")


def test_out_and_points_csv_as_one_file_are_refused(work):
    (work / "alias").symlink_to(work, target_is_directory=True)
    args = coverage_args(work, work / "c.json", "--points-csv", work / "alias" / "c.json")
    refused(args, work, "are one file")


def test_an_existing_output_is_replaced_only_with_overwrite(work):
    out = work / "c.json"
    out.write_text("mine")
    refused(coverage_args(work, out), work, "--overwrite replaces it")
    code, _, stderr = run_headless(*coverage_args(work, out, "--overwrite"))
    assert code == 0, stderr
    assert json.loads(out.read_text())["scene"] == "S.blend"


def test_an_output_link_is_replaced_not_written_through(work):
    """--overwrite onto a symbolic link to a file of the user's replaces the link."""
    mine = work / "mine.txt"
    mine.write_text("keep me")
    (work / "c.json").symlink_to(mine)
    code, _, stderr = run_headless(*coverage_args(work, work / "c.json", "--overwrite"))
    assert code == 0, stderr
    assert mine.read_text() == "keep me"
    assert not (work / "c.json").is_symlink()
    assert json.loads((work / "c.json").read_text())["scene"] == "S.blend"


def test_import_xodr_refuses_an_existing_blend_and_its_own_input(tmp_path):
    out = tmp_path / "mine.blend"
    shutil.copy(FLAT, out)
    refused(("import-xodr", XODR, "--out", out), tmp_path, "--overwrite replaces it")
    (tmp_path / "road.blend").symlink_to(XODR)
    line = refused(("import-xodr", XODR, "--out", tmp_path / "road.blend", "--overwrite"),
                   tmp_path, "the OpenDRIVE file")  # fmt: skip
    assert XODR.read_bytes()[:5] == b"<?xml"
    code, _, stderr = run_headless("import-xodr", XODR, "--out", out, "--overwrite")
    assert code == 0, stderr
    assert out.read_bytes() != FLAT.read_bytes()
    assert "an input" in line


def optimize_args(work: Path, scene: Path, out_dir: Path, *extra):
    (work / "g.toml").write_text(GREEDY)
    return ("optimize", scene, "--config", work / "g.toml", "--out-dir", out_dir, *extra)


@pytest.mark.parametrize("how", ["same name", "hard link"])
def test_optimize_never_replaces_its_scene(work, how):
    """The scene is DIR/result.blend (or a hard link to it) and the output folder DIR."""
    scene = work / "result.blend"
    if how == "same name":
        (work / "S.blend").rename(scene)
    else:
        os.link(work / "S.blend", scene)
    line = refused(optimize_args(work, scene, work, "--overwrite"), work, "the scene")
    assert "choose another --out-dir" in line


def test_optimize_refuses_an_earlier_runs_files_until_told(work):
    out = work / "out"
    code, _, stderr = run_headless(*optimize_args(work, work / "S.blend", out))
    assert code in (0, 3), stderr
    result = (out / "result.json").read_bytes()
    # The files the rule guards are all the run writes.
    run_files = set(RESULT_NAMES) | {"checkpoint.jsonl", ".autoscoop.lock"}
    assert {p.name for p in out.iterdir()} <= run_files
    line = refused(optimize_args(work, work / "S.blend", out), work, "an earlier run's checkpoint")
    assert "--resume goes on from it, --overwrite starts again" in line
    (out / "checkpoint.jsonl").unlink()
    line = refused(optimize_args(work, work / "S.blend", out), work, "exist already")
    assert str(out / "result.json") in line and "--overwrite replaces them" in line
    code, _, stderr = run_headless(*optimize_args(work, work / "S.blend", out, "--overwrite"))
    assert code in (0, 3), stderr
    # Same settings, same answer: replaced by equal bytes but for the wall time.
    assert (
        json.loads((out / "result.json").read_bytes())["sensors"] == json.loads(result)["sensors"]
    )


def linked_in_out(work: Path, name: str) -> tuple[Path, Path]:
    """work/out/NAME, a symbolic link to a file of the user's: (out, that file)."""
    out = work / "out"
    out.mkdir()
    mine = work / "notes.txt"
    mine.write_text("mine")
    (out / name).symlink_to(mine)
    return out, mine


def test_a_linked_checkpoint_is_never_written_through(work):
    out, mine = linked_in_out(work, "checkpoint.jsonl")
    refused(optimize_args(work, work / "S.blend", out, "--resume"), work, "symbolic link")
    code, _, stderr = run_headless(*optimize_args(work, work / "S.blend", out, "--overwrite"))
    assert code in (0, 3), stderr
    assert mine.read_text() == "mine"
    assert not (out / "checkpoint.jsonl").is_symlink()
    assert len((out / "checkpoint.jsonl").read_text().splitlines()) >= 2


def test_a_linked_lock_is_refused(work):
    out, mine = linked_in_out(work, ".autoscoop.lock")
    refused(optimize_args(work, work / "S.blend", out), work, "symbolic link")
    assert mine.read_text() == "mine"


def test_a_checkpoint_that_is_a_folder_is_one_line(work):
    out = work / "out"
    (out / "checkpoint.jsonl").mkdir(parents=True)
    refused(optimize_args(work, work / "S.blend", out, "--resume"), work, "is a folder")
    refused(optimize_args(work, work / "S.blend", out, "--overwrite"), work, "is a folder")


def capped(limit: int):
    """A file size limit for the child (writes past it fail with EFBIG, as on a full
    disk: Python ignores SIGXFSZ)."""

    def apply():
        resource.setrlimit(resource.RLIMIT_FSIZE, (limit, limit))

    return apply


@pytest.mark.parametrize("command", ["coverage", "optimize"])
def test_a_failed_write_leaves_no_temporary_file(work, command):
    """The first output staged is small, a later one is too big: nothing is replaced,
    no temporary file stays."""
    out = work / "out"
    out.mkdir()
    if command == "coverage":
        (out / "c.json").write_text("mine")
        args = coverage_args(work, out / "c.json", "--overwrite", "--points-csv", out / "p.csv")
        limit = 20_000  # c.json (about 7 kB) fits, the points CSV (about 60 kB) does not
    else:
        args = optimize_args(work, work / "S.blend", out)
        limit = 100_000  # result.json fits, result.blend (about 200 kB) does not
    before = snapshot(out)
    proc = subprocess.run(
        [sys.executable, "-m", "headless", *map(str, args)],
        cwd=ROOT, capture_output=True, text=True, timeout=600, preexec_fn=capped(limit),
    )  # fmt: skip
    assert proc.returncode == 2, proc.stderr
    last = proc.stderr.strip().splitlines()[-1]
    assert last.startswith("error: "), proc.stderr
    if command == "coverage":
        assert "cannot write it (File too large)" in last
    else:  # Blender's own save of result.blend fails first, silently: a file cut short
        assert "Blender could not save the scene (the file it wrote is cut short" in last
    after = snapshot(out)
    if command == "optimize":  # the checkpoint was written as sensors were fixed
        after.pop("checkpoint.jsonl")
        after.pop(".autoscoop.lock")
    assert after == before
    assert not [p for p in out.iterdir() if p.name.startswith(".") and "lock" not in p.name]


def test_a_device_or_a_link_to_one_is_never_replaced(work, tmp_path):
    """/dev/null, or a link to it: a rename would put a file where the device was."""
    (work / "null.csv").symlink_to("/dev/null")
    for out in (Path("/dev/null"), work / "null.csv"):
        args = coverage_args(work, work / "c.json", "--points-csv", out, "--overwrite")
        refused(args, work, "is not a regular file")
    assert Path("/dev/null").is_char_device()


def test_a_blend_cut_short_is_told_from_a_whole_one():
    """Blender's compressed files end with zstd's seek table, uncompressed ones with
    the ENDB block: any cut loses that end."""
    from headless.files import whole_blend

    data = FLAT.read_bytes()
    assert whole_blend(data)
    assert not any(whole_blend(data[:n]) for n in (0, 4, len(data) // 2, len(data) - 1))
    plain = b"BLENDER-v405" + b"\0" * 100 + b"ENDB" + b"\0" * 20
    assert whole_blend(plain) and not whole_blend(plain[:100])
