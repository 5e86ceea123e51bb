"""Grouping sensors into masts."""

import numpy as np

from autoscoop_blender.core.masts import choose_sites, group_positions


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
