"""Blender tests run against the pip ``bpy`` module, one factory-fresh file per test."""

import bpy
import pytest

from tests.conftest import ROOT

SAMPLES = ROOT / "sample_blends"


@pytest.fixture(autouse=True)
def clean_factory():
    bpy.ops.wm.read_factory_settings(use_empty=True)
    yield


@pytest.fixture
def open_sample():
    """Open ``sample_blends/<name>.blend``."""

    def _open(name: str):
        bpy.ops.wm.open_mainfile(filepath=str(SAMPLES / f"{name}.blend"))
        return bpy.context.scene

    return _open
