"""The committed sample scenes follow the contract, have the promised sizes, and are
exactly what the generator builds."""

import bpy
import numpy as np
import pytest
import shapely

from autoscoop_blender.scene.extract import extract_scene
from tests.blender.conftest import SAMPLES
from tools import samples


def _model(path):
    bpy.ops.wm.open_mainfile(filepath=str(path))
    return extract_scene()


def test_two_routes_is_a_proving_ground_section():
    scene = _model(SAMPLES / "two_routes.blend")
    target = scene.target_union
    assert len(scene.targets) == 2 and len(scene.sensor_areas) == 6
    assert 15_000 <= target.area <= 20_000
    minx, miny, maxx, maxy = target.bounds
    assert 200 <= maxx - minx <= 300 and 150 <= maxy - miny <= 300
    # The two routes come close at a narrow point without touching.
    a, b = (t.geometry for t in scene.targets)
    assert 0 < a.distance(b) < 12
    assert any(n.startswith("Wall") for n in scene.occluders)
    assert sum(n.startswith("Building") for n in scene.occluders) >= 3
    assert sum(n.startswith("Tree") for n in scene.occluders) >= 10
    relief = scene.vertices[:, 2].min(), np.percentile(scene.vertices[:, 2], 99)
    assert relief[1] - relief[0] >= 4.0
    # Sensor areas stand beside the roads, not on them.
    for area in scene.sensor_areas:
        assert area.geometry.intersection(target).area < 1e-6


def test_full_ground_is_ten_times_larger():
    two = _model(SAMPLES / "two_routes.blend").target_union.area
    full = _model(SAMPLES / "full_ground.blend").target_union.area
    assert full >= 10 * two


@pytest.mark.parametrize("name", ["flat_wall", "two_routes", "full_ground"])
def test_generator_rebuilds_the_committed_geometry(tmp_path, name):
    committed = _model(SAMPLES / f"{name}.blend")
    rebuilt = _model(getattr(samples, f"build_{name}")(tmp_path))
    assert np.array_equal(committed.vertices, rebuilt.vertices)
    assert np.array_equal(committed.faces, rebuilt.faces)
    for a, b in zip(
        committed.targets + committed.sensor_areas, rebuilt.targets + rebuilt.sensor_areas
    ):
        assert a.name == b.name and a.height_m == b.height_m
        assert shapely.equals_exact(a.geometry, b.geometry, tolerance=0.0)
