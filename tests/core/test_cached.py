"""The cached targeted evaluator answers exactly as the direct one, with fewer rays."""

import numpy as np
import pytest

from autoscoop_blender.core.coverage.base import place
from autoscoop_blender.core.coverage.cached import CachedTargetedEvaluator
from autoscoop_blender.core.coverage.targeted import TargetedEvaluator
from autoscoop_blender.core.model.sensors import PAPER_CAMERA, ROADSIDE_LIDAR
from tests.core.flat import flat_grid

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
