"""Grouping sensors into masts."""

from dataclasses import replace

import numpy as np
import pytest

from autoscoop_blender.core.masts import choose_sites, group_positions
from autoscoop_blender.core.model.sensors import PAPER_CAMERA
from autoscoop_blender.core.run import Run
from tests.core.flat import box_caster
from tests.core.test_optimize import BOX, FAST, road_scene


def test_complete_linkage_groups():
    xy = np.array([[0, 0], [0, 0], [2, 0], [10, 0], [12.5, 0], [40, 0]], float)
    labels = group_positions(xy, 3.0)
    assert list(labels) == [0, 0, 0, 1, 1, 2]
    # Chains do not merge: every pair in a group is within the distance.
    chain = np.array([[0, 0], [2.5, 0], [5, 0]], float)
    assert len(set(group_positions(chain, 3.0))) == 2


def test_sites_keep_coverage_or_stay_apart():
    """Sensors cover the 10 points to either side of where they stand (a 1-D road of
    100 points, one per metre). Group 0 (x = 0, 2) loses nothing by merging at x = 2;
    group 1 (x = 60, 80) loses 20 points wherever it merges, so it stays apart."""
    xy = np.array([[0, 0], [2, 0], [60, 0], [80, 0]], float)
    labels = np.array([0, 0, 1, 1])

    def cover(i, x, y):
        return np.arange(max(0, int(x) - 10), min(100, int(x) + 11))

    # Covered now: 0..12 (13 points) and 50..90 (41 points) = 54.
    new_xy, final = choose_sites(xy, labels, cover, n_points=100, keep_at_least=54)
    assert np.array_equal(new_xy[0], [2, 0]) and np.array_equal(new_xy[1], [2, 0])
    assert np.array_equal(new_xy[2:], xy[2:])  # kept apart
    assert final[0] == final[1] and final[2] != final[3]
    assert sorted(set(final)) == [0, 1, 2]
    # With a lower floor group 1 merges too, onto its first site: (60) covers 50..70,
    # 21 points, the same as at 80, and the first best site wins.
    new_xy, final = choose_sites(xy, labels, cover, n_points=100, keep_at_least=30)
    assert np.array_equal(new_xy[2], [60, 0]) and np.array_equal(new_xy[3], [60, 0])
    assert sorted(set(final)) == [0, 1]


def test_group_diameters_never_exceed_the_join_distance():
    """What complete linkage promises, on random feet: every pair in a group lies within
    join_m, and no two groups could be one (their union would not be)."""
    rng = np.random.default_rng(3)
    for _ in range(20):
        xy = rng.uniform(0, 30, size=(25, 2))
        labels = group_positions(xy, 3.0)
        first = [int(np.flatnonzero(labels == g)[0]) for g in range(labels.max() + 1)]
        assert first == sorted(first)  # numbered by their first member
        for g in range(labels.max() + 1):
            members = xy[labels == g]
            d = np.linalg.norm(members[:, None] - members[None], axis=-1)
            assert d.max() <= 3.0
        for g in range(labels.max() + 1):
            for h in range(g + 1, labels.max() + 1):
                both = xy[(labels == g) | (labels == h)]
                d = np.linalg.norm(both[:, None] - both[None], axis=-1)
                assert d.max() > 3.0


@pytest.mark.parametrize("optimizer", ["es", "greedy"])
def test_mast_invariants_of_a_plan(optimizer):
    """Each sensor stands on its mast's foot, at the mast's height; each mast holds
    exactly the sensors that name it; masts are the distinct positions of the plan."""
    settings = replace(FAST, optimizer=optimizer)
    res = Run(road_scene(), box_caster([BOX]), PAPER_CAMERA, settings).result()
    assert res.masts and len(res.sensors) >= len(res.masts)
    by_n = {m.n: m for m in res.masts}
    for s in res.sensors:
        mast = by_n[s.mast + 1]
        assert (s.x, s.y) == (mast.x, mast.y) and s.height_m == mast.height_m
        assert s.z == pytest.approx(mast.z_ground + mast.height_m)
        assert s.n in mast.sensors
    assert sum(len(m.sensors) for m in res.masts) == len(res.sensors)
    assert len({(s.x, s.y) for s in res.sensors}) == len(res.masts)
