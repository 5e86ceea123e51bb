"""The core must never pull in Blender: checked in a clean interpreter."""

import subprocess
import sys

from tests.conftest import ROOT

CORE_MODULES = [
    "alpha",
    "analysis",
    "coverage",
    "errors",
    "grid",
    "raycast",
    "scene_model",
    "sensor_file",
    "sensors",
]


def test_core_imports_no_blender():
    imports = "; ".join(f"import autoscoop_blender.core.{m}" for m in CORE_MODULES)
    code = (
        f"import sys; {imports}; sys.exit(bool({{'bpy', 'mathutils', 'bmesh'}} & set(sys.modules)))"
    )
    subprocess.run([sys.executable, "-c", code], check=True, cwd=ROOT)
