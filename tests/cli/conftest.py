"""Helpers to run ``python -m headless`` as a user would, and to make bad scenes."""

import json
import signal
import subprocess
import sys
from pathlib import Path

import bpy
import pytest

from tests.blender import builders as b
from tests.conftest import ROOT

SAMPLES = ROOT / "sample_blends"

# The commands run here stand for a user at a terminal, where Ctrl-C reaches them. A
# test run started as a shell's background job (``./dev.sh test &``, ``nohup``)
# ignores SIGINT, every command it starts would inherit that, and the command line
# rightly leaves an ignored SIGINT ignored (``headless.interrupts``): the interrupt
# tests would fail for the shell's sake. A handled SIGINT is the default in a child.
if signal.getsignal(signal.SIGINT) is signal.SIG_IGN:
    signal.signal(signal.SIGINT, signal.default_int_handler)


def run_headless(*args, script=False):
    """Run the CLI in a fresh interpreter; (returncode, stdout, stderr)."""
    entry = [str(ROOT / "headless" / "__main__.py"), "--"] if script else ["-m", "headless"]
    proc = subprocess.run(
        [sys.executable, *entry, *map(str, args)],
        cwd=ROOT,
        capture_output=True,
        text=True,
        timeout=600,
    )
    return proc.returncode, proc.stdout, proc.stderr


def live_processes(field: int, value: int) -> set[int]:
    """Live (not zombie) processes whose /proc stat field after the name is ``value``
    there: field 1 the parent's process id, 2 the process group (Linux)."""
    out = set()
    for stat in Path("/proc").glob("[0-9]*/stat"):
        try:
            fields = stat.read_text().rsplit(")", 1)[1].split()
        except OSError:
            continue
        if int(fields[field]) == value and fields[0] != "Z":
            out.add(int(stat.parent.name))
    return out


@pytest.fixture
def sensors_file(tmp_path):
    """Write a sensors JSON and return its path."""

    def _write(data, name="sensors.json"):
        path = tmp_path / name
        path.write_text(json.dumps(data))
        return path

    return _write


@pytest.fixture
def blend_file(tmp_path):
    """Build a scene with a function of ``builders`` and save it as a .blend."""

    def _make(build, name="scene.blend"):
        bpy.ops.wm.read_factory_settings(use_empty=True)
        build(b)
        path = tmp_path / name
        bpy.ops.wm.save_as_mainfile(filepath=str(path))
        return path

    return _make
