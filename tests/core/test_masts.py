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
    xy = np.array([[0, 0], [2, 0], [10, 0], [11, 0]], float)
    labels = np.array([0, 0, 1, 1])

    def covered(new_xy):
        # Group 0 loses nothing wherever it stands; group 1 loses 5 points if moved.
        return 100 - 5 * int(not np.array_equal(new_xy[2:], xy[2:]))

    new_xy, final = choose_sites(xy, labels, covered, keep_at_least=100)
    assert np.array_equal(new_xy[0], new_xy[1])  # merged onto one member's spot
    assert np.array_equal(new_xy[2:], xy[2:])  # kept apart
    assert final[0] == final[1] and final[2] != final[3]
    assert sorted(set(final)) == [0, 1, 2]
