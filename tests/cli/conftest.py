"""Helpers to run ``python -m headless`` as a user would, and to make bad scenes."""

import json
import subprocess
import sys

import bpy
import pytest

from tests.blender import builders as b
from tests.conftest import ROOT

SAMPLES = ROOT / "sample_blends"


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
