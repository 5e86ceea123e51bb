"""The four real OpenDRIVE files (tests/data/xodr): each reads and builds with no
traceback; what is built is consistent with the file's own lanes."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
import shapely
from shapely.geometry import Polygon

from autoscoop_blender.io.opendrive import build_import, read_opendrive
from autoscoop_blender.io.opendrive.build import FLOAT32_GRID_M

DATA = Path(__file__).resolve().parents[1] / "data" / "xodr"
FILES = ["Town01", "Town04", "AstaZero_FlexZoneCrossing", "AstaZero_GaragePlanHighRes"]


def _region(rings: list[np.ndarray]) -> shapely.Geometry:
    out = Polygon()
    for r in rings:
        out = out.symmetric_difference(Polygon(r[:, :2]))
    return out


@pytest.mark.parametrize("name", FILES)
def test_real_file_reads_and_builds(name):
    import xml.etree.ElementTree as ET

    path = DATA / f"{name}.xodr"
    net = read_opendrive(path)
    n_roads = len(ET.parse(path).getroot().findall("road"))
    assert len(net.roads) == n_roads
    assert net.geo_reference and not net.geo_reference.startswith("<![CDATA[")
    result = build_import(net)
    assert len(result.surfaces) == n_roads
    assert all(w.startswith(("road ", "junction ")) and "\n" not in w for w in result.warnings)
    # Every road with a driving lane has a target; the union is at most the lanes' sum
    # and loses little to overlaps of neighbouring lanes.
    target = sum(t.area_m2 for t in result.targets)
    lanes = result.lane_area_m2["driving"]
    # (The rings are snapped to the float32-exact grid: up to perimeter x grid more.)
    snap = sum(_region(t.rings).length for t in result.targets) * FLOAT32_GRID_M
    assert 0.97 * lanes < target <= lanes + snap
    for t in result.targets:
        assert all(len(r) >= 3 and r.shape[1] == 3 for r in t.rings)
        # Simple once Blender has rounded them to float32.
        for r in t.rings:
            assert np.array_equal(r[:, :2].astype(np.float32), r[:, :2])
            assert shapely.LinearRing(r[:, :2]).is_simple
        assert _region(t.rings).area == pytest.approx(t.area_m2, rel=1e-6)
    # Sensor areas never lie on a road surface.
    roads = shapely.union_all(
        np.concatenate([shapely.polygons(s.vertices[s.faces][:, :, :2]) for s in result.surfaces])
    )
    for sa in result.sensor_areas:
        region = _region(sa.rings)
        assert region.intersection(roads).area < 1e-3 * region.area + 0.01
    # Ground under everything, surfaces counter-clockwise.
    assert result.ground is not None
    zmin = min(s.vertices[:, 2].min() for s in result.surfaces)
    assert result.ground.vertices[0, 2] == pytest.approx(zmin - 0.05)
    for s in result.surfaces:
        p = s.vertices[s.faces][:, :, :2]
        u, v = p[:, 1] - p[:, 0], p[:, 2] - p[:, 0]  # z of u x v (numpy 2: no 2-D cross)
        assert np.all(u[:, 0] * v[:, 1] - u[:, 1] * v[:, 0] > 0)
