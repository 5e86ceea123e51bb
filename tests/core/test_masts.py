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


def test_no_sensor_and_one_sensor_make_no_group_and_one():
    """The shortcuts for fewer than two positions: integer labels, as many as given."""
    none = group_positions(np.zeros((0, 2)), 3.0)
    one = group_positions(np.array([[5.0, -2.0]]), 3.0)
    assert none.shape == (0,) and none.dtype.kind == "i"
    assert one.tolist() == [0] and one.dtype.kind == "i"
    assert group_positions(np.array([[0.0, 0.0], [9.0, 0.0]]), 3.0).tolist() == [0, 1]
    xy, final = choose_sites(np.zeros((0, 2)), np.zeros(0, dtype=int), None, 5, 0)
    assert xy.shape == (0, 2) and final.shape == (0,) and final.dtype.kind == "i"


def _band(i, x, y):
    """Sensor i at (x, y) covers the whole metres within 1 of x (0..22); sensor 2
    within 3."""
    r = 3 if i == 2 else 1
    return np.arange(max(0, int(x) - r), min(23, int(x) + r + 1))


def test_a_standing_sensor_holds_its_site():
    """A (fixed) at x = 0 and B at 2: free, they would meet at 2 (B's band 1..3 and A's
    0..1 moved there: 1..3, 3 points, against 0..1 at 0: 2 points); A standing, B
    comes to A."""
    xy = np.array([[0, 0], [2, 0]], float)
    labels = np.array([0, 0])
    free, _ = choose_sites(xy, labels, _band, n_points=23, keep_at_least=0)
    assert free.tolist() == [[2, 0], [2, 0]]
    held, final = choose_sites(
        xy, labels, _band, n_points=23, keep_at_least=0, fixed=np.array([True, False])
    )
    assert held.tolist() == [[0, 0], [0, 0]] and final.tolist() == [0, 0]


def test_two_standing_sensors_in_a_group_stay_and_the_free_one_joins_the_better():
    """A at 10 and B at 21 stand; C (band of 3) at 15 joins one of them. Now: A 9..11,
    C 12..18, B 20..22: 13 points. C at 10: 7..13 and 20..22, 10 points; C at 21:
    9..11 and 18..22 (the road ends at 22), 8 points. C goes to A; B stays: two masts."""
    xy = np.array([[10, 0], [21, 0], [15, 0]], float)
    new_xy, final = choose_sites(
        xy,
        np.array([0, 0, 0]),
        _band,
        n_points=23,
        keep_at_least=0,
        fixed=np.array([True, True, False]),
    )
    assert new_xy.tolist() == [[10, 0], [21, 0], [10, 0]]
    assert final.tolist() == [0, 1, 0]


def _reference(xy, labels, cover, n_points, keep_at_least, need=None, fixed=None):
    """choose_sites by brute force, from its docstring: groups in label order; each
    tries every distinct position of its standing members (of all its members when
    none stands), lowest (x, y) first, moving its free members there and recounting
    every point over every sensor; the first best site is taken when it keeps at
    least ``keep_at_least`` points covered to their need. One mast per distinct
    position of a group, numbered in order of first sensor."""
    n = len(xy)
    pos = [tuple(map(float, p)) for p in xy]
    still = [False] * n if fixed is None else [bool(f) for f in fixed]
    k = [1] * n_points if need is None else [int(v) for v in need]

    def covered(at):
        counts = [0] * n_points
        for i, p in enumerate(at):
            for t in set(int(t) for t in cover(i, *p)):
                counts[t] += 1
        return sum(c >= kk for c, kk in zip(counts, k))

    for g in sorted(set(int(v) for v in labels)):
        members = [i for i in range(n) if labels[i] == g]
        spots = sorted({pos[i] for i in members})
        if len(spots) == 1:
            continue
        anchors = sorted({pos[i] for i in members if still[i]})
        best = None
        for site in anchors or spots:
            trial = [site if (i in members and not still[i]) else p for i, p in enumerate(pos)]
            c = covered(trial)
            if best is None or c > best[0]:
                best = (c, trial)
        if best[0] >= keep_at_least:
            pos = best[1]
    masts: dict = {}
    final = [masts.setdefault((int(labels[i]), pos[i]), len(masts)) for i in range(n)]
    return np.array(pos).reshape(-1, 2), final


def test_sites_match_a_brute_force_recount():
    """Random small cases: sensors on a 4 x 3 lattice (so groups share spots), random
    groups, some sensors standing, points needing 1 to 3 sensors, each sensor's cover a
    random set of points fixed by (sensor, x, y) and sometimes empty (as a list). The
    plan and the masts equal the brute-force recount's (see _reference)."""
    rng = np.random.default_rng(18)
    for case in range(300):
        n = int(rng.integers(1, 9))
        n_points = int(rng.integers(1, 13))
        xy = rng.integers(0, [4, 3], size=(n, 2)).astype(float)
        # Groups numbered by their first member, as group_positions gives them.
        first: dict[int, int] = {}
        raw = rng.integers(0, max(1, n // 2), size=n)
        labels = np.array([first.setdefault(int(v), len(first)) for v in raw])
        need = rng.integers(1, 4, size=n_points).astype(np.int32) if case % 2 else None
        fixed = rng.random(n) < 0.25 if case % 3 == 0 else None

        def cover(i, x, y, case=case, n_points=n_points):
            # hash() of numbers is not salted: the same set in every run.
            r = np.random.default_rng(abs(hash((case, int(i), float(x), float(y)))) % 2**32)
            return [int(t) for t in np.flatnonzero(r.random(n_points) < 0.45)]

        keep = int(rng.integers(0, n_points + 1))
        want_xy, want_masts = _reference(xy, labels, cover, n_points, keep, need, fixed)
        got_xy, got_masts = choose_sites(xy, labels, cover, n_points, keep, need, fixed)
        assert np.array_equal(got_xy, want_xy), (case, got_xy, want_xy)
        assert got_masts.tolist() == want_masts, (case, got_masts, want_masts)


def test_a_group_of_standing_sensors_moves_nothing_and_counts_nothing():
    """Group 0: A at 0 and B at 4, both standing (two masts 4 m apart: nothing can
    move). Group 1: C at 10 and D at 13, free. Each covers the whole metres within 1 of
    x: A 0..1, B 3..5, C 9..11, D 12..14: 11 points. C and D merged cover 3 points
    instead of 6: 8 in all, under the 9 asked, so they stay apart; group 0 changes
    nothing on the way (had it counted a point, the 9 would have been met)."""
    xy = np.array([[0, 0], [4, 0], [10, 0], [13, 0]], float)

    def cover(i, x, y):
        return np.arange(max(0, int(x) - 1), min(23, int(x) + 2))

    new_xy, final = choose_sites(
        xy,
        np.array([0, 0, 1, 1]),
        cover,
        n_points=23,
        keep_at_least=9,
        fixed=np.array([True, True, False, False]),
    )
    assert new_xy.tolist() == xy.tolist()
    assert final.tolist() == [0, 1, 2, 3]
    # Asked for 8, C and D merge on C's site (the first of two equal ones).
    new_xy, final = choose_sites(
        xy, np.array([0, 0, 1, 1]), cover, 23, 8, fixed=np.array([True, True, False, False])
    )
    assert new_xy.tolist() == [[0, 0], [4, 0], [10, 0], [10, 0]]
    assert final.tolist() == [0, 1, 2, 2]
