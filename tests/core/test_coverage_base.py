"""The pieces every coverage method shares (``coverage/base.py``), one at a time, on
hand-made input: sight lines worked out by Pythagoras, a ray caster that answers
from a script, frames against the matrix product, the pixel density each area asks
for, footprints of single cells and the union's counts."""

import math
import warnings
from dataclasses import replace
from types import SimpleNamespace

import numpy as np
import pytest

from autoscoop_blender.core.coverage.base import (
    SIGHT_MARGIN_M,
    SensorCoverage,
    clear_sight,
    footprint_polygon,
    pixel_need,
    place,
    sight_lines,
    summarize,
    to_sensor,
    view,
)
from autoscoop_blender.core.model.sensors import CCTV_CAMERA, PAPER_CAMERA, ROADSIDE_LIDAR
from tests.core.flat import flat_grid


def _cell(grid, x, y):
    """The flat index of the cell centred at (x, y)."""
    (cell,) = grid.cells_in_disk(np.array([x, y]), 0.1)
    assert grid.xy(np.array([cell])).tolist() == [[x, y]]
    return cell


def test_a_pose_is_placed_its_height_above_the_ground():
    grid, _ = flat_grid(spacing=1.0, target=(0, 0, 10, 10))
    pose = place(grid, 3.0, 4.0, 7.0, 40.0, 10.0)
    assert (pose.x, pose.y, pose.z, pose.height_m) == (3.0, 4.0, 7.0, 7.0)
    assert (pose.pitch_deg, pose.yaw_deg) == (40.0, 10.0)


@pytest.mark.parametrize("target_height", [0.0, 1.0])
def test_sight_lines_by_pythagoras(target_height):
    """From (0.5, 0.5, 10) to the cell at (10.5, 0.5): the ground 10 m away and 10 m
    down (sqrt 200), the target point raised by its height (sqrt(100 + (10 - h)^2));
    the cell right below at 10 m (9 m to a raised point). No warning for a cell at
    the sensor's own place (0 m: no direction)."""
    grid, _ = flat_grid(spacing=1.0, target=(0, 0, 20, 20))
    grid.target_height_m = target_height
    s = np.array([0.5, 0.5, 10.0])
    cells = np.array([_cell(grid, 10.5, 0.5), _cell(grid, 0.5, 0.5)])
    lines = sight_lines(grid, s, cells)
    h = target_height
    assert lines.dist.tolist() == pytest.approx([math.hypot(10, 10 - h), 10 - h])
    assert lines.gd[0] == pytest.approx(np.array([10.0, 0.0, -10.0]) / math.sqrt(200))
    assert lines.d[0] == pytest.approx(np.array([10.0, 0.0, h - 10.0]) / lines.dist[0])
    assert (lines.gd is lines.d) == (h == 0.0) and lines.facing is None
    sub = lines.subset(np.array([1]))
    assert sub.dist.tolist() == pytest.approx([10 - h]) and (sub.gd is sub.d) == (h == 0.0)
    on_ground = np.array([0.5, 0.5, h])
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        own = sight_lines(grid, on_ground, cells[1:], pixels=True)
    assert own.facing is not None and np.isnan(own.d).all()
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        in_view, density, _ = view(PAPER_CAMERA, np.eye(3), own)
    assert in_view.tolist() == [False] and density.tolist() == [0.0]


class ScriptedCaster:
    """Answers each ``cast`` with the next of ``hits`` (distances, inf: nothing hit),
    and keeps what it was asked."""

    def __init__(self, *hits):
        self.hits = list(hits)
        self.asked = []

    def cast(self, origins, dirs, max_dist):
        self.asked.append((np.array(origins), np.array(dirs), np.array(max_dist)))
        return np.array(self.hits.pop(0), dtype=float)


def test_clear_sight_casts_again_past_the_sensors_own_surface():
    """Three lines 10 m long: the first hits at 0 m (the sensor's own surface), the
    second nothing, the third a wall at 5 m; the first is cast again from 1 cm along,
    1 cm shorter, and is clear. A hit at exactly 1 cm is a real one."""
    s = np.array([0.0, 0.0, 5.0])
    d = np.array([[1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, -1.0]])
    lines = SimpleNamespace(d=d, dist=np.full(3, 10.0))
    caster = ScriptedCaster([0.0, np.inf, 5.0], [np.inf])
    rows = np.array([0, 1, 2])
    assert clear_sight(caster, s, lines, rows).tolist() == [True, True, False]
    limit = 10.0 * (1 - 1e-7) - SIGHT_MARGIN_M
    (o1, d1, m1), (o2, d2, m2) = caster.asked
    assert np.allclose(o1, s) and np.array_equal(d1, d) and np.allclose(m1, limit)
    assert o2.tolist() == [[0.01, 0.0, 5.0]] and d2.tolist() == [[1.0, 0.0, 0.0]]
    assert m2 == pytest.approx([limit - SIGHT_MARGIN_M])
    # A line shorter than the margin is cast again with no length, not a negative one.
    short = SimpleNamespace(d=d[:1], dist=np.array([0.015]))
    caster = ScriptedCaster([0.0], [np.inf])
    assert clear_sight(caster, s, short, np.array([0])).tolist() == [True]
    assert caster.asked[1][2].tolist() == [0.0]
    caster = ScriptedCaster([SIGHT_MARGIN_M])
    assert clear_sight(caster, s, lines, np.array([0])).tolist() == [False]
    assert len(caster.asked) == 1
    empty = clear_sight(ScriptedCaster(), s, lines, np.zeros(0, np.int64))
    assert empty.dtype == bool and empty.shape == (0,)


def test_directions_in_a_sensor_frame_are_the_matrix_product():
    rot = np.array([[1.0, 2.0, 3.0], [4.0, 5.0, 6.0], [7.0, 8.0, 10.0]])
    d = np.array([[1.0, 1.0, 1.0], [1.0, 0.0, -1.0], [0.5, -2.0, 3.0]])
    assert to_sensor(d, rot) == pytest.approx(d @ rot.T)
    frames = np.stack([rot, -rot.T, np.eye(3)])
    batched = to_sensor(d, frames)
    assert batched.shape == (3, 3, 3)
    for k in range(3):
        assert batched[k] == pytest.approx(d @ frames[k].T)


def _regions(px, kind, region_of):
    """A grid as ``pixel_need`` reads it: per region the px/m it asks for and the
    sensor kind it requires (-1: any); per target ordinal its region."""
    return SimpleNamespace(
        region_px_per_m=np.array(px, float),
        region_kind=np.array(kind),
        target_region=np.array(region_of),
    )


def test_the_pixel_density_each_point_needs():
    """Target points 0 (region 1) and 1 (region 0) and an outside cell (-1; the last
    target point is in region 1 too). Region 1 asks for 62 px/m (observe); the CCTV
    camera detects at 25 px/m."""
    ordinal = np.array([0, 1, -1])
    asks = _regions([0.0, 62.0], [-1, -1], [1, 0, 1])
    assert pixel_need(asks, CCTV_CAMERA, ordinal).tolist() == [62.0, 25.0, 25.0]
    # A model without a resolution cannot give pixels: it covers no point that asks.
    assert pixel_need(asks, PAPER_CAMERA, ordinal).tolist() == [math.inf, 0.0, 0.0]
    # However little it asks.
    little = _regions([0.0, 0.5], [-1, -1], [1, 0, 1])
    assert pixel_need(little, PAPER_CAMERA, ordinal).tolist() == [math.inf, 0.0, 0.0]
    # Nothing asked anywhere: nothing needed of a model without a resolution.
    none = _regions([0.0, 0.0], [-1, -1], [1, 0])
    assert pixel_need(none, PAPER_CAMERA, ordinal) is None
    assert pixel_need(none, CCTV_CAMERA, ordinal).tolist() == [25.0] * 3
    # A camera with pixels asked for none: nothing needed either.
    assert pixel_need(none, replace(CCTV_CAMERA, min_px_per_m=0.0), ordinal) is None


@pytest.mark.parametrize(
    "required, model, want",
    [
        (1, PAPER_CAMERA, [math.inf, 0.0, 0.0]),  # a lidar area: not for a camera
        (1, ROADSIDE_LIDAR, None),  # for the lidar: nothing needed
        (0, ROADSIDE_LIDAR, [math.inf, 0.0, 0.0]),  # a camera area: not for a lidar
        (0, CCTV_CAMERA, [25.0, 25.0, 25.0]),
    ],
)
def test_an_area_that_requires_a_sensor_kind(required, model, want):
    """Region 1 (point 0) requires kind ``required`` (0 camera, 1 lidar)."""
    grid = _regions([0.0, 0.0], [-1, required], [1, 0])
    got = pixel_need(grid, model, np.array([0, 1, -1]))
    assert (got if got is None else got.tolist()) == want


def test_view_out_of_sight_has_no_density_and_a_model_without_pixels_gives_none():
    """The paper's camera looking along x: a point 10 m ahead and 1 m down is in view,
    one behind is not (density 0, not 1); where a point needs pixels (need > 0) a
    model without a resolution detects nothing, where it needs none it detects as
    ever."""
    lines = SimpleNamespace(
        d=np.array([[10.0, 0.0, -1.0], [-10.0, 0.0, -1.0]]) / math.sqrt(101.0),
        dist=np.full(2, math.sqrt(101.0)),
        surface=np.ones(2),
        facing=None,
    )
    lines.gd = lines.d
    rot = np.eye(3)
    model = replace(PAPER_CAMERA, min_density_per_m2=0.0)
    in_view, density, detects = view(model, rot, lines)
    assert in_view.tolist() == [True, False] and density[1] == 0.0 and density[0] > 0
    assert detects.tolist() == [True, False]
    _, _, needs = view(model, rot, lines, np.array([25.0, 0.0]))
    assert needs.tolist() == [False, False]
    _, _, free = view(model, rot, lines, np.array([0.0, 0.0]))
    assert free.tolist() == [True, False]


def _cov(covered, visible=None, chi=None, cells=None):
    covered = np.array(covered, np.int64)
    chi = np.ones(len(covered)) if chi is None else np.array(chi, float)
    return SensorCoverage(
        None, PAPER_CAMERA, "targeted", covered, chi,
        None if visible is None else np.array(visible, np.int64),
        np.zeros(0, np.int64), None, 0, _cells=cells,
    )  # fmt: skip


def test_the_footprint_of_no_cell_and_of_one_cell():
    grid, _ = flat_grid(spacing=2.0, target=(0, 0, 10, 10))
    assert footprint_polygon(grid, _cov([])).is_empty
    one = np.array([_cell(grid, 3.0, 5.0)])
    square = footprint_polygon(grid, _cov([0], cells=one))
    assert square.area == pytest.approx(4.0) and square.bounds == (2.0, 4.0, 4.0, 6.0)


def test_the_union_counts_each_sensor_once_per_point():
    """Three sensors over 4 points: the first sees 0..2 and covers 0, 1; the second
    (no visible set: what it covers) covers 1, 2; the third covers 1 at density 5."""
    grid = SimpleNamespace(n_targets=4, cell_area=2.25)
    covs = [_cov([0, 1], [0, 1, 2], [3.0, 1.0]), _cov([1, 2]), _cov([1], chi=[5.0])]
    got = summarize(grid, covs)
    assert got.n_visible.tolist() == [1, 3, 2, 0] and got.n_covered.tolist() == [1, 3, 1, 0]
    assert got.n_visible.dtype == got.n_covered.dtype == np.int32
    assert got.best_density.tolist() == [3.0, 5.0, 1.0, 0.0]
    assert (got.covered_points, got.coverage_fraction, got.covered_m2) == (3, 0.75, 6.75)
