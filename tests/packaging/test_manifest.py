"""The extension manifest passes Blender's own validator (the CLI inside the bpy wheel)."""

import importlib.util
import shutil
import subprocess
import sys
from pathlib import Path

from tests.conftest import ROOT


def test_staged_package_validates(tmp_path):
    scripts = next(Path(importlib.util.find_spec("bpy").origin).parent.glob("*/scripts"))
    ext = scripts / "addons_core/bl_pkg/cli/blender_ext.py"
    tags = scripts / "modules/_bpy_internal/extensions/tags.py"
    stage = tmp_path / "autoscoop"
    shutil.copytree(ROOT / "autoscoop_blender", stage, ignore=shutil.ignore_patterns("__pycache__"))
    shutil.copy(ROOT / "blender_manifest.toml", stage)
    proc = subprocess.run(
        [sys.executable, ext, "validate", "--valid-tags", tags, stage],
        capture_output=True,
        text=True,
    )
    assert proc.returncode == 0, proc.stdout + proc.stderr
