"""The type checker runs clean on the Blender-free code (core and io)."""

import subprocess
import sys

from tests.conftest import ROOT


def test_mypy_is_clean_on_core_and_io():
    # The folders and options are in pyproject.toml ([tool.mypy]).
    proc = subprocess.run(
        [sys.executable, "-m", "mypy", "--no-error-summary"],
        cwd=ROOT,
        capture_output=True,
        text=True,
    )
    assert proc.returncode == 0, proc.stdout + proc.stderr
