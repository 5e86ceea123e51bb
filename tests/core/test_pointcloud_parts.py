"""The paper's pointcloud method in parts (``coverage/pointcloud.py``): the rays per
pattern ray, each hit's step to its nearer neighbour and the density and spacing
that follow, the raster that keeps hits near the cells asked about, and chi
interpolated in a triangle. Every value is worked out by hand on a few points."""

import math
import warnings
from dataclasses import replace
from types import SimpleNamespace

import numpy as np
import pytest

from autoscoop_blender.core.coverage.base import place
from autoscoop_blender.core.coverage.pointcloud import (
    PointcloudEvaluator,
    _interpolate,
    _near,
    _nearer_step,
    _pattern_density,
    auto_oversample,
)
from autoscoop_blender.core.geom.alpha import triangulate
from autoscoop_blender.core.model.sensors import PAPER_CAMERA
from tests.core.flat import down_camera, flat_grid

# 1 deg between rays across (90 over 90), 0.5 deg down (45 over 90), 100 m range: the
# rays land 100 x pi / 180 = 1.745 m apart at full range.
WIDE = replace(PAPER_CAMERA, h_fov_deg=90.0, rays_h=90, v_fov_deg=45.0, rays_v=90,
               range_m=100.0)  # fmt: skip


@pytest.mark.parametrize(
    "grid_m, want",
    [(0.5, 4), (1.0, 2), (2.0, 1), (10.0, 1), (100.0 * math.pi / 180.0, 1)],
)
def test_rays_per_pattern_ray_put_neighbours_a_cell_apart(grid_m, want):
    """ceil(1.745 / grid), at least 1; exactly one cell apart needs no more rays."""
    assert auto_oversample(WIDE, grid_m) == want
    assert (
        PointcloudEvaluator(SimpleNamespace(spacing=grid_m), None).rays_per_pattern_ray(WIDE)
        == want
    )
    assert PointcloudEvaluator(None, None, oversample=3).rays_per_pattern_ray(WIDE) == 3


def _row(xs, ys=None):
    """(1, n, 2) hits along one pattern row; nan x: a miss."""
    ys = np.zeros(len(xs)) if ys is None else ys
    xy = np.array([[(x, y) for x, y in zip(xs, ys)]], dtype=float)
    return xy, ~np.isnan(xy[..., 0])


def test_each_hit_steps_to_its_nearer_neighbour():
    """Hits at x = 0, 1, 3, 6: steps 1, 1 (back, nearer), 2 (back), 3 (the last has
    only its back step). With the hit at 3 missing: 1, 1, none, none."""
    xy, hit = _row([0.0, 1.0, 3.0, 6.0])
    assert _nearer_step(xy, hit, axis=1)[0, :, 0].tolist() == [1.0, 1.0, 2.0, 3.0]
    xy, hit = _row([0.0, 1.0, np.nan, 6.0])
    steps = _nearer_step(xy, hit, axis=1)[0, :, 0]
    assert steps[:2].tolist() == [1.0, 1.0] and np.isnan(steps[2:]).all()
    # Equally near both ways (1, 0.5) back and (1, -0.5) ahead: the step ahead.
    xy, hit = _row([0.0, 1.0, 2.0], [0.0, 0.5, 0.0])
    assert _nearer_step(xy, hit, axis=1)[0, 1].tolist() == [1.0, -0.5]
    # Along the other axis a single row has no neighbour at all.
    assert np.isnan(_nearer_step(xy, hit, axis=0)).all()


def test_the_density_of_a_regular_grid_of_hits():
    """3 x 3 hits 2 m apart in x, 1 m in y: each stands for 2 m^2, density 1/2 (1/8
    with 2 x 2 rays per pattern ray), spacing 2. A missed ray: density and spacing 0;
    hits in a line (a wall seen edge on) stand for no area: infinite density."""
    xs, ys = np.meshgrid([0.0, 2.0, 4.0], [0.0, 1.0, 2.0])
    xy = np.stack([xs, ys], axis=-1)
    hit = np.ones((3, 3), dtype=bool)
    density, spacing = _pattern_density(xy, hit, 1)
    assert np.allclose(density, 0.5) and np.allclose(spacing, 2.0)
    assert np.allclose(_pattern_density(xy, hit, 4)[0], 0.125)
    xy[1, 1], hit[1, 1] = np.nan, False
    density, spacing = _pattern_density(xy, hit, 1)
    assert density[1, 1] == 0.0 and spacing[1, 1] == 0.0 and density[0, 0] == 0.5
    line = np.stack([xs, np.zeros((3, 3))], axis=-1)  # every row on y = 0
    with warnings.catch_warnings():
        warnings.simplefilter("error")  # no division-by-zero warning for it
        assert np.isinf(_pattern_density(line, np.ones((3, 3), bool), 1)[0]).all()


def test_the_density_of_a_sheared_grid_of_hits():
    """Steps (1, 0.5) along a row and (0.25, 0.5) down a column: each hit stands for
    the parallelogram |1 x 0.5 - 0.5 x 0.25| = 0.375 m^2, density 1 / 0.375; its
    spacing is the longer step, sqrt(1.25)."""
    i, j = np.meshgrid(np.arange(3.0), np.arange(3.0))  # j down the columns, i along
    xy = np.stack([1.0 * i + 0.25 * j, 0.5 * i + 0.5 * j], axis=-1)
    density, spacing = _pattern_density(xy, np.ones((3, 3), bool), 1)
    assert np.allclose(density, 1 / 0.375) and np.allclose(spacing, math.sqrt(1.25))


def test_hits_near_the_cells_asked_about():
    """Cells at (10, 20) and (14, 20) on a 2 m grid, reach 3 m: a hit counts within
    reach + one cell (5 m) on the raster, whose cells start at (5, 15), 2 m each.
    (10, 24), (17, 20) and (6, 20) are 2 cells from a query cell: near; (20, 20) is 3
    cells away, (4, 20) and (21.5, 20) off the raster: not near. No cells: none."""
    grid = SimpleNamespace(spacing=2.0)
    cells = np.array([(10.0, 20.0), (14.0, 20.0)])
    pts = np.array([(10.0, 24.0), (17.0, 20.0), (6.0, 20.0), (20.0, 20.0), (4.0, 20.0),
                    (21.5, 20.0)])  # fmt: skip
    near = _near(grid, pts, cells, 3.0)
    assert near.tolist() == [True, True, True, False, False, False]
    assert near.dtype == bool
    assert _near(grid, pts, np.zeros((0, 2)), 3.0).tolist() == [False] * 6


def test_chi_is_interpolated_in_its_triangle_and_walls_are_capped():
    """Corners (0, 0), (1, 0), (0, 1) at 1, 2, 3: at (0.25, 0.25) the weights are
    0.5, 0.25, 0.25, so 0.5 + 0.5 + 0.75 = 1.75. An infinite corner takes the densest
    finite one (3): 2.0; all infinite: 0."""
    tri = triangulate(np.array([(0.0, 0.0), (1.0, 0.0), (0.0, 1.0)]))
    at = np.array([(0.25, 0.25)])
    simplex = tri.locate_kept(at, np.ones(1, dtype=bool), 1.0)
    values = np.array([1.0, 2.0, 3.0])
    assert _interpolate(tri, values, at, simplex) == pytest.approx([1.75])
    assert _interpolate(tri, np.array([1.0, np.inf, 3.0]), at, simplex) == pytest.approx([2.0])
    assert _interpolate(tri, np.full(3, np.inf), at, simplex).tolist() == [0.0]
    assert _interpolate(tri, values, np.zeros((0, 2)), simplex[:0]).shape == (0,)
    # Two triangles far apart, each with an infinite corner: each takes its own
    # densest (3 and 7), not the densest of all: (1 + 3 + 3) / 3 and (7 + 7 + 5) / 3 at
    # their centroids.
    pts = np.array([(0.0, 0.0), (1.0, 0.0), (0.0, 1.0), (10.0, 0.0), (11.0, 0.0), (10.0, 1.0)])
    apart = triangulate(pts)
    centres = np.array([pts[:3].mean(axis=0), pts[3:].mean(axis=0)])
    cells = apart.locate_kept(centres, np.ones(len(apart.simplices), dtype=bool), 1.0)
    values = np.array([1.0, np.inf, 3.0, 7.0, np.inf, 5.0])
    got = _interpolate(apart, values, centres, cells)
    assert got.tolist() == pytest.approx([(1 + 3 + 3) / 3, (7 + 7 + 5) / 3])


def test_each_models_pattern_is_built_once():
    """2 x 2 rays per pattern ray: a 4 x 6 pattern gives (8, 12) directions, unit
    vectors, the same array on the next call."""
    small = replace(PAPER_CAMERA, rays_h=6, rays_v=4)
    ev = PointcloudEvaluator(None, None, oversample=2)
    dirs = ev._pattern(small)
    assert dirs.shape == (8, 12, 3) and np.allclose(np.linalg.norm(dirs, axis=-1), 1.0)
    assert ev._pattern(small) is dirs
    assert ev._pattern(replace(small, rays_h=5)).shape == (8, 10, 3)
    # Without a set oversampling, the model's own: ceil(20 deg x 80 m / 14 m) = 2.
    auto = PointcloudEvaluator(SimpleNamespace(spacing=14.0), None)
    assert auto._pattern(small).shape == (8, 12, 3)


def test_the_alpha_radius_fixed_or_from_the_widest_corner_spacing():
    """Two triangles over corners spaced 1, 2, 3, 4 apart: alpha 1.5 allows 1.5 x the
    widest corner spacing of each; ``alpha_m`` fixes it."""
    tri = triangulate(np.array([(0.0, 0.0), (1.0, 0.0), (0.0, 1.0), (1.0, 1.0)]))
    spacing = np.array([1.0, 2.0, 3.0, 4.0])
    scaled = PointcloudEvaluator(None, None, alpha=1.5)
    want = [1.5 * spacing[s].max() for s in tri.simplices]
    assert scaled._radius_limit(tri, spacing).tolist() == want
    assert scaled._max_radius(spacing) == 6.0 and scaled._max_radius(np.zeros(0)) == 0.0
    assert PointcloudEvaluator(None, None)._max_radius(spacing) == 4.0  # alpha 1
    fixed = PointcloudEvaluator(None, None, alpha=1.5, alpha_m=2.5)
    assert fixed._radius_limit(tri, spacing) == 2.5 and fixed._max_radius(spacing) == 2.5


def test_a_camera_straight_down_over_a_target_with_a_margin():
    """The 60 x 60 deg camera 10 m over (10, 10) sees the square 2 x 10 tan 30 deg =
    11.55 m on a side, x and y in 4.23 .. 15.77: of the 1 m cells, the 12 x 12 with
    centres 4.5 .. 15.5. The target is the 10 x 10 of them from 5.5 to 14.5 (every
    target point, ordinal 0 too); the other 44 lie outside it. One ray per pattern
    ray: 192 x 160 rays, the footprint the square less half a pixel each side. The
    pattern's density is uniform, 30,720 / (4 tan^2 30 deg x 100 m^2) = 230.4
    points/m^2: asked for 231, no point is covered, all 100 are still seen."""
    grid, caster = flat_grid(spacing=1.0, target=(5, 5, 15, 15))
    model = down_camera(80.0)
    ev = PointcloudEvaluator(grid, caster, oversample=1)
    pose = place(grid, 10.0, 10.0, 10.0, 90.0, 0.0)
    cov = ev.evaluate(model, pose)
    assert (cov.pose, cov.model, cov.method) == (pose, model, "pointcloud")
    assert sorted(cov.covered.tolist()) == list(range(100)) and cov.rays == 192 * 160
    assert cov.visible is None and cov.footprint_m2 is None and len(cov.outside) == 0
    full = ev.evaluate(model, pose, outside_band_m=math.inf, visibility=True)
    assert np.array_equal(np.sort(full.covered), np.sort(cov.covered))
    assert len(full.outside) == 44 and sorted(full.visible.tolist()) == list(range(100))
    # The rays pass through pixel centres: the outermost lie half a pixel inside.
    side = 20 * math.tan(math.radians(30))
    want = (side - side / 192) * (side - side / 160)
    assert full.footprint_m2 == pytest.approx(want, rel=1e-4)
    thin = ev.evaluate(replace(model, min_density_per_m2=231.0), pose, visibility=True)
    assert len(thin.covered) == 0 and sorted(thin.visible.tolist()) == list(range(100))
    assert ev.evaluate(replace(model, min_density_per_m2=230.0), pose).covered.size == 100
