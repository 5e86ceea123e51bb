"""The paper's fitness terms (Eq. 1-5) on hand-made coverages, numbers by hand."""

import math

import numpy as np
import pytest

from autoscoop_blender.core.coverage.base import SensorCoverage
from autoscoop_blender.core.model.sensors import PAPER_CAMERA, SensorPose
from autoscoop_blender.core.optimize.fitness import FixedSensors, fitness
from autoscoop_blender.core.settings import FitnessParams
from tests.core.flat import flat_grid

P = FitnessParams()  # w_ca 1, w_ds 0.5, w_sc 2.5, zeta 0.02, theta_tau 2 m, theta 20 m


@pytest.fixture(scope="module")
def grid():
    # 1 m cells; target x, y in [0, 10] -> 100 target points, centres at .5
    g, _ = flat_grid(spacing=1.0, target=(0, 0, 10, 10), sensor=(-5, -5, -4, -4), reach=20)
    return g


def cov(grid, ordinals, chi, x=0.0, y=0.0, outside=()):
    ordinals = np.asarray(ordinals, dtype=np.int64)
    return SensorCoverage(
        pose=SensorPose(x, y, 7.0, 7.0, 40.0, 0.0),
        model=PAPER_CAMERA,
        method="targeted",
        covered=ordinals,
        chi=np.asarray(chi, dtype=float),
        visible=None,
        outside=np.asarray(outside, dtype=np.int64),
        footprint_m2=None,
        rays=0,
    )


def test_first_sensor_scores_its_density(grid):
    fixed = FixedSensors(np.zeros(grid.n_targets, dtype=bool))
    f = fitness(grid, cov(grid, [0, 1, 2], [2.0, 3.0, 5.0]), fixed, P)
    assert f.f_ca == pytest.approx(10.0) and f.f_s == pytest.approx(10.0)
    assert f.new_points == 3 and f.f_ds == 0 and f.f_sc == 0


def test_overlap_scores_zeta_and_distances_weigh_in(grid):
    fixed = FixedSensors(np.zeros(grid.n_targets, dtype=bool))
    fixed.add(cov(grid, [0, 1, 2, 3], [2.0] * 4, x=0.0, y=0.0))
    # Covers 2 old points (zeta each) and 2 new ones (density 4 each); stands 30 m
    # from the first sensor.
    c = cov(grid, [2, 3, 4, 5], [9.0, 9.0, 4.0, 4.0], x=30.0, y=40.0 - 40.0)
    f = fitness(grid, c, fixed, P)
    f_ca = 2 * 4.0 + 2 * 0.02
    assert f.f_ca == pytest.approx(f_ca) and f.new_points == 2
    assert f.f_ds == pytest.approx(f_ca * math.exp(-(30.0**2) / (2 * 20.0**2)))
    # The footprint's centroid: the four cells' centres, (x, y) in the target grid.
    centroid = grid.xy(grid.target_cells[[2, 3, 4, 5]]).mean(axis=0)
    d = math.hypot(*centroid)
    assert f.f_sc == pytest.approx(f_ca * math.exp(-(d**2) / (2 * 20.0**2)))
    assert f.f_s == pytest.approx(f_ca + 0.5 * f.f_ds + 2.5 * f.f_sc)


def test_mean_over_fixed_sensors(grid):
    fixed = FixedSensors(np.zeros(grid.n_targets, dtype=bool))
    fixed.add(cov(grid, [0], [2.0], x=0.0, y=0.0))
    fixed.add(cov(grid, [1], [2.0], x=100.0, y=0.0))
    f = fitness(grid, cov(grid, [9], [3.0], x=0.0, y=0.0), fixed, P)
    # z = 2: one fixed sensor at distance 0, one at 100 m.
    assert f.f_ds == pytest.approx(3.0 / 2 * (1.0 + math.exp(-(100.0**2) / 800.0)))


def test_footprint_outside_the_target_decays_with_distance(grid):
    fixed = FixedSensors(np.zeros(grid.n_targets, dtype=bool))
    # Outside cells at x = -0.5 (1 m from the nearest target centre, x = 0.5) and
    # x = -2.5 (3 m): tau = exp(-d^2 / 8).
    xy = grid.xy(np.arange(grid.nx * grid.ny))
    near = np.flatnonzero(np.isclose(xy[:, 0], -0.5) & np.isclose(xy[:, 1], 5.5))
    far = np.flatnonzero(np.isclose(xy[:, 0], -2.5) & np.isclose(xy[:, 1], 5.5))
    f = fitness(grid, cov(grid, [], [], outside=[near[0], far[0]]), fixed, P)
    assert f.f_ca == pytest.approx(math.exp(-1 / 8) + math.exp(-9 / 8))
    assert f.new_points == 0


def test_near_finds_exactly_the_sensors_within_the_radius():
    """Against brute force, with queries between fixings: a neighbourhood kept from an
    earlier query must take in the sensors fixed since."""
    rng = np.random.default_rng(4)
    fixed = FixedSensors(np.zeros(1, dtype=bool))
    xy = rng.uniform(-500, 500, (400, 2))
    queries = rng.uniform(-600, 600, (30, 2))
    for k, (x, y) in enumerate(xy):
        fixed.positions.append((float(x), float(y)))
        if k % 23 == 0:
            for qx, qy in queries:
                got = fixed.near(qx, qy, 120.0)
                brute = xy[: k + 1][np.hypot(xy[: k + 1, 0] - qx, xy[: k + 1, 1] - qy) <= 120.0]
                assert np.array_equal(got, brute)  # same rows, same order
    for x, y in rng.uniform(-600, 600, (50, 2)):
        brute = xy[np.hypot(xy[:, 0] - x, xy[:, 1] - y) <= 120.0]
        assert np.array_equal(fixed.near(x, y, 120.0), brute)


def test_far_sensors_change_the_closeness_terms_by_less_than_1e_7(grid):
    """f_ds with sensors 50 m and 300 m away: by hand, the 300 m one adds
    exp(-300^2 / 800) (about 1e-49), so f_ds is f_ca / 2 * exp(-50^2 / 800)."""
    fixed = FixedSensors(np.zeros(grid.n_targets, dtype=bool), [(50.0, 0.0), (300.0, 0.0)])
    f = fitness(grid, cov(grid, [0, 1], [2.0, 2.0]), fixed, P)
    expected = f.f_ca / 2 * math.exp(-(50.0**2) / (2 * 20.0**2))
    assert f.f_ds == pytest.approx(expected, rel=1e-7)


def test_the_covered_count_starts_from_the_array_and_follows_each_fix():
    fixed = FixedSensors(np.array([True, False, True, False, False]))
    assert fixed.n_covered == 2
    fixed.mark(np.array([1, 4]), (0.0, 0.0))
    assert fixed.n_covered == 3 + 1 == int(fixed.covered.sum())
