"""The cached targeted evaluator answers exactly as the direct one, with fewer rays."""

import math
from dataclasses import replace

import numpy as np
import pytest

from autoscoop_blender.core.coverage.base import place
from autoscoop_blender.core.coverage.cached import CachedTargetedEvaluator
from autoscoop_blender.core.coverage.targeted import TargetedEvaluator
from autoscoop_blender.core.geom.grid import GroundGrid
from autoscoop_blender.core.geom.raycast import BoxCaster
from autoscoop_blender.core.model.sensors import (
    CCTV_CAMERA,
    PAPER_CAMERA,
    ROADSIDE_LIDAR,
    SensorPose,
    frame,
)
from tests.core.flat import down_camera, flat_grid, flat_scene
from tests.core.test_coverage import lattice, offsets

BOXES = [((10, -2, 0), (12, 6, 3)), ((-30, 20, 0), (-20, 30, 8)), ((30, -40, 0), (34, -30, 5))]


class CountingCaster:
    def __init__(self, inner):
        self.inner, self.rays = inner, 0

    def cast(self, o, d, m):
        self.rays += len(d)
        return self.inner.cast(o, d, m)

    def cast_normals(self, o, d, m):
        return self.inner.cast_normals(o, d, m)


@pytest.mark.parametrize("model", [PAPER_CAMERA, ROADSIDE_LIDAR])
@pytest.mark.parametrize("band", [None, 4.9])
def test_cached_equals_direct(model, band):
    grid, caster = flat_grid(
        spacing=1.0, boxes=BOXES, target=(-60, -60, 60, 60), sensor=(-50, -50, 50, 50)
    )
    direct_caster, cached_caster = CountingCaster(caster), CountingCaster(caster)
    direct = TargetedEvaluator(grid, direct_caster)
    cached = CachedTargetedEvaluator(grid, cached_caster)
    rng = np.random.default_rng(2)
    positions = np.round(rng.uniform(-40, 40, (4, 2)))
    for x, y in positions:
        for _ in range(12):  # many orientations per position, as an optimizer does
            pitch = rng.uniform(model.pitch_min_deg, model.pitch_max_deg)
            pose = place(grid, x, y, 7.0, pitch, rng.uniform(0, 360))
            a = direct.evaluate(model, pose, outside_band_m=band)
            b = cached.evaluate(model, pose, outside_band_m=band)
            assert np.array_equal(a.covered, b.covered)
            assert np.array_equal(a.chi, b.chi)  # bit for bit
            assert np.array_equal(np.sort(a.outside), np.sort(b.outside))
    assert cached_caster.rays < direct_caster.rays / 2
    assert cached.positions == len(positions)


def test_evicted_positions_answer_the_same_without_new_rays():
    """A byte bound that holds one position's geometry: revisiting the other position
    recomputes its geometry but keeps its ray answers, so no ray is cast twice."""
    grid, caster = flat_grid(spacing=1.0, boxes=BOXES, target=(-60, -60, 60, 60))
    roomy_caster, tight_caster = CountingCaster(caster), CountingCaster(caster)
    roomy = CachedTargetedEvaluator(grid, roomy_caster)
    tight = CachedTargetedEvaluator(grid, tight_caster, max_bytes=1)
    poses = [place(grid, x, 0.0, 7.0, 40.0, yaw) for yaw in (0, 90, 180) for x in (-20, 20)]
    for pose in poses + poses:  # every evaluation after the first evicts the other position
        a = roomy.evaluate(PAPER_CAMERA, pose)
        b = tight.evaluate(PAPER_CAMERA, pose)
        assert np.array_equal(a.covered, b.covered)
        assert np.array_equal(a.chi, b.chi)
    assert len(tight._reach) == 1 and len(roomy._reach) == 2
    assert tight_caster.rays == roomy_caster.rays > 0
    assert tight._bytes == next(iter(tight._reach.values())).nbytes


def test_out_of_limits_and_reports_go_direct():
    grid, caster = flat_grid(spacing=1.0, boxes=BOXES, target=(-60, -60, 60, 60))
    cached = CachedTargetedEvaluator(grid, caster)
    pose = place(grid, 0.0, 0.0, 7.0, 10.0, 0.0)  # pitch 10: outside [31, 70]
    a = TargetedEvaluator(grid, caster).evaluate(PAPER_CAMERA, pose)
    assert np.array_equal(a.covered, cached.evaluate(PAPER_CAMERA, pose).covered)
    assert cached.positions == 0


def test_reachable_is_an_upper_bound_and_exact_on_visibility():
    grid, caster = flat_grid(spacing=1.0, boxes=BOXES, target=(-60, -60, 60, 60))
    cached = CachedTargetedEvaluator(grid, caster)
    pose = place(grid, 0.0, 0.0, 7.0, 40.0, 0.0)
    wanted = np.ones(grid.n_targets, dtype=bool)
    reach = set(cached.reachable(PAPER_CAMERA, pose, wanted))
    covered = set()
    for yaw in range(0, 360, 5):
        for pitch in (31, 40, 50, 60, 70):
            p = place(grid, 0.0, 0.0, 7.0, pitch, yaw)
            covered |= set(cached.evaluate(PAPER_CAMERA, p).covered)
    assert covered <= reach
    assert len(covered) > 0.9 * len(reach)


# --- straight down over flat ground (see test_coverage): the cache's own answers -----
#
# ``down_camera`` at (0.5, 0.5), 10 m up, on a 1 m grid: every cell at a whole offset
# (a, b). The 60 x 60 deg pinhole's corner is t_c off its axis, tan t_c =
# sqrt(2) tan 30 deg = sqrt(2 / 3); looking straight down (its only pitch) it could
# cover ground whose depression is at least 90 deg - t_c: within h tan t_c =
# 10 sqrt(2 / 3) = 8.165 m of the mast, a^2 + b^2 <= 200 / 3.

H = 10.0
BAND_R2 = H**2 * 2.0 / 3.0  # 66.67
WALL = ((2.8, -30.0, 0.0), (3.2, 30.0, 5.0))  # hides a = 3, 4, 5 (test_coverage)


def _shadowed(a):
    return 2.7 <= a <= 2.7 * H / (H - 5.0)


def _down(caster_boxes=(), target=(-20, -20, 21, 21)):
    grid, caster = flat_grid(spacing=1.0, boxes=caster_boxes, target=target, reach=25.0)
    counting = CountingCaster(caster)
    return grid, counting, CachedTargetedEvaluator(grid, counting)


def test_a_pose_evaluated_again_casts_no_ray():
    """Pitch 90 is both pitch limits: still within them, so the answers are kept. The
    second look casts nothing and says so; every ray cast is counted once."""
    grid, counting, cached = _down()
    pose = place(grid, 0.5, 0.5, H, 90.0, 0.0)
    first = cached.evaluate(down_camera(20.0), pose)
    again = cached.evaluate(down_camera(20.0), pose)
    assert first.rays == 121 and again.rays == 0 and counting.rays == 121
    assert np.array_equal(first.covered, again.covered) and len(first.covered) == 121
    assert cached.positions == 1 and cached.extra_rays == 0


def test_reachable_is_the_depression_band_minus_the_shadow():
    """The target a = 0..11, b = -8..8 (its first point, a = 0, b = -8, lies 8 m
    away, inside the band); the wall hides a = 3, 4, 5. Rays only to wanted points,
    each once, all counted as probe rays."""
    grid, counting, cached = _down([WALL], target=(0, -8, 12, 9))
    model = down_camera(20.0)
    pose = place(grid, 0.5, 0.5, H, 90.0, 0.0)
    assert cached.extra_rays == 0
    xy = grid.target_xy - 0.5
    north = xy[:, 1] >= 0
    got = offsets(grid, cached.reachable(model, pose, north))

    def band(a, b):
        return 0 <= a <= 11 and -8 <= b <= 8 and a * a + b * b <= BAND_R2

    assert got == lattice(lambda a, b: band(a, b) and b >= 0 and not _shadowed(a))
    asked_north = len(lattice(lambda a, b: band(a, b) and b >= 0))
    assert cached.extra_rays == counting.rays == asked_north
    everything = np.ones(grid.n_targets, dtype=bool)
    got = offsets(grid, cached.reachable(model, pose, everything))
    assert got == lattice(lambda a, b: band(a, b) and not _shadowed(a))
    assert (0, -8) in got and grid.target_xy[0].tolist() == [0.5, -7.5]  # ordinal 0
    assert cached.extra_rays == counting.rays == len(lattice(band))
    # Another position adds its own rays to the count.
    other = place(grid, 2.5, 0.5, H, 90.0, 0.0)
    n_other = len(cached.reachable(model, other, everything))
    assert n_other > 0 and cached.extra_rays == counting.rays > len(lattice(band))


def test_reachable_with_a_pixel_density_level():
    """Straight down over flat ground a point at distance r gets f^2 h / (r^3 cos^3 t)
    px^2/m^2 at angle t off the axis; the sharpest any orientation could give it is at
    the FoV's corner: best(r) = f sqrt(h / (r^3 cos^3 t_c)) = (f / h) (cos t /
    cos t_c)^(3/2), where cos t = h / r. With 1000 x 1000 px on 60 deg (f = 866.0 px)
    a level P reaches out to cos t = cos t_c (P h / f)^(2/3).
    P chosen for 5.5 m (104.2 px/m): the disk a^2 + b^2 <= 30.25, inside the band,
    though no point is covered (f / h = 86.6 px/m straight down). P = 80 px/m would
    reach 9.2 m, past the band: the band's disk."""
    f = 500.0 / math.tan(math.radians(30.0))
    cos_c = 1.0 / math.sqrt(1.0 + 2.0 * math.tan(math.radians(30.0)) ** 2)
    cos_55 = H / math.hypot(H, 5.5)
    level = f / H * (cos_55 / cos_c) ** 1.5
    assert level == pytest.approx(104.19, abs=0.01)
    base = replace(down_camera(20.0), resolution_px=(1000, 1000), rays_h=100, rays_v=100)
    for px, r2 in ((level, 5.5**2), (80.0, BAND_R2)):
        grid, counting, cached = _down()
        model = replace(base, min_px_per_m=px).validated("test")
        pose = place(grid, 0.5, 0.5, H, 90.0, 0.0)
        got = cached.reachable(model, pose, np.ones(grid.n_targets, dtype=bool))
        assert offsets(grid, got) == lattice(lambda a, b, r2=r2: a * a + b * b <= r2)
        assert cached.extra_rays == counting.rays == len(got)
        covered = cached.evaluate(model, pose).covered
        assert len(covered) == (0 if px > f / H else 121)


def test_cover_many_covers_the_square_and_the_diamond():
    """Straight down, yaw 0 sees |a|, |b| <= 5.77; yaw 45 deg the square turned:
    |a + b|, |a - b| <= 5.77 sqrt(2). The wall hides a = 3, 4, 5 from both. One ray
    to each point either needs, cast once, counted as probe rays."""
    grid, counting, cached = _down([WALL])
    model = down_camera(20.0)
    pose = place(grid, 0.5, 0.5, H, 90.0, 0.0)
    half = H * math.tan(math.radians(30.0))

    def square(a, b):
        return abs(a) <= half and abs(b) <= half

    def diamond(a, b):
        return abs(a + b) <= half * math.sqrt(2) and abs(a - b) <= half * math.sqrt(2)

    rots = np.array([frame(90.0, 0.0), frame(90.0, 45.0)])
    covered, ordinal = cached.cover_many(model, pose, rots)
    assert covered.shape == (2, len(ordinal))
    for row, shape in zip(covered, (square, diamond)):
        want = lattice(lambda a, b, shape=shape: shape(a, b) and not _shadowed(a))
        assert offsets(grid, ordinal[row]) == want
    union = lattice(lambda a, b: square(a, b) or diamond(a, b))
    assert cached.extra_rays == counting.rays == len(union)
    cached.cover_many(model, pose, rots)
    assert cached.extra_rays == counting.rays == len(union)  # nothing asked twice


def test_least_recently_used_position_is_evicted():
    """A bound that holds exactly two positions' geometry keeps two; a third evicts
    the one used least recently, not the newest. The bytes counted are the bytes
    held."""
    grid, counting, cached = _down()
    model = down_camera(12.0)
    a, b, c = (place(grid, x, 0.5, H, 90.0, 0.0) for x in (0.5, 3.5, -2.5))
    cached.evaluate(model, a)
    one = cached._bytes
    cached.max_bytes = 2 * one
    cached.evaluate(model, b)
    assert len(cached._reach) == 2 and cached._bytes == 2 * one  # exactly the bound
    rays = counting.rays
    cached.evaluate(model, a)  # a is now the most recently used
    assert counting.rays == rays
    cached.evaluate(model, c)
    kept = {key[1] for key in cached._reach}
    assert kept == {0.5, -2.5}
    assert cached._bytes == sum(e.nbytes for e in cached._reach.values()) == 2 * one


def test_a_pixel_level_over_a_target_height_counts_the_ground_past_the_corner():
    """The CCTV camera (f = 1144.08 px, 80 x 50.534 deg) 7 m up at pitch 15 deg, its
    lowest, along +X; targets 2 m up (a van). A target point (X, Y, 2) lies in the
    FoV when, at its depth D_t = X cos p + 5 sin p along the axis, |Y| <= tan 40 deg
    D_t and |X sin p - 5 cos p| <= tan(V / 2) D_t; its pixel density is measured on
    the ground under it, at depth D_g = X cos p + 7 sin p: sqrt(f^2 h / D_g^3), which
    reaches P up to D_g = (f^2 h / P^2)^(1/3) (test_dori's closed form), 8 m here.
    Near the lower corners of the image that ground lies further off the axis than
    the FoV's corner (D_g / r_g < cos t_c), where it gets more pixels than the
    corner could give: it counts all the same, through the cached evaluator too."""
    h, t, pitch, depth = 7.0, 2.0, 15.0, 8.0
    f = 960.0 / math.tan(math.radians(40.0))
    model = replace(CCTV_CAMERA, min_px_per_m=f * math.sqrt(h / depth**3)).validated("test")
    caster = BoxCaster([], ground_z=0.0)
    grid = GroundGrid(flat_scene(target=(0, -8, 8, 8)), caster, 0.1, t, reach_m=20.0)
    x, y = grid.target_xy.T
    p = math.radians(pitch)
    tu, tv = math.tan(math.radians(40.0)), 1080 / 1920 * math.tan(math.radians(40.0))
    d_t = x * math.cos(p) + (h - t) * math.sin(p)
    d_g = x * math.cos(p) + h * math.sin(p)
    in_fov = (np.abs(y) <= tu * d_t) & (np.abs(x * math.sin(p) - (h - t) * math.cos(p)) <= tv * d_t)
    hand = np.flatnonzero(in_fov & (d_g <= depth))
    assert 500 < len(hand) and x[hand].max() < 7.9 and np.abs(y[hand]).max() < 7.9
    cos_corner = 1.0 / math.sqrt(1.0 + tu * tu + tv * tv)
    past_corner = d_g[hand] / np.sqrt(x[hand] ** 2 + y[hand] ** 2 + h * h) < cos_corner
    assert past_corner.sum() >= 10  # what this test is about
    pose = SensorPose(0.0, 0.0, h, h, pitch, 0.0)
    for ev in (TargetedEvaluator(grid, caster), CachedTargetedEvaluator(grid, caster)):
        assert np.array_equal(np.sort(ev.evaluate(model, pose).covered), hand)
