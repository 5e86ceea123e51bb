"""Grouping fixed sensors into shared masts (the last step of Algorithm 1).

Sensors whose feet lie within ``join_m`` of each other (complete linkage: every pair
of a group) would share one mast. The mast stands at one of the members' positions;
all members move there, keeping their height, pitch and yaw. The site chosen is the
one that keeps the most target points covered (each by its k sensors, when a ``need``
is given); a group whose best site would drop
the coverage below what it was (or below the goal, whichever is lower) stays apart.
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np
from numpy.typing import NDArray
from scipy.cluster.hierarchy import fcluster, linkage
from scipy.spatial.distance import pdist

F64 = NDArray[np.float64]


def group_positions(xy: F64, join_m: float) -> NDArray[np.int_]:
    """(n,) group labels 0..g-1 for positions (n, 2): complete linkage at ``join_m``.

    Labels are numbered in order of each group's first member, so the result does not
    depend on scipy's internal numbering.
    """
    n = len(xy)
    if n == 0:
        return np.zeros(0, dtype=int)
    if n == 1:
        return np.zeros(1, dtype=int)
    # Distances first: two sensors at one spot would otherwise look like a distance
    # matrix to scipy (the same numbers: linkage computes these distances itself).
    raw = fcluster(linkage(pdist(xy), method="complete"), t=join_m, criterion="distance")
    order: dict[int, int] = {}
    return np.array([order.setdefault(int(r), len(order)) for r in raw])


def choose_sites(
    xy: F64,
    labels: NDArray[np.int_],
    cover: Callable[[int, float, float], NDArray[np.int_]],
    n_points: int,
    keep_at_least: int,
    need: NDArray[np.int32] | None = None,
    fixed: NDArray[np.bool_] | None = None,
    cap: int | None = None,
) -> tuple[F64, NDArray[np.int_]]:
    """Mast sites for grouped sensors.

    xy: (n, 2) sensor positions; labels: their groups; ``cover(i, x, y)`` gives the
    target points (distinct indices below ``n_points``) sensor i covers when it
    stands at (x, y); need: (n_points,) sensors each point needs to count as covered
    (None: 1); fixed: (n,) sensors that may not move (masts that stand already): a
    group with one takes its site, if any; cap: the most sensors one mast may carry:
    a larger group is not merged. Returns the sensors' new positions (n, 2)
    and their final mast labels (one mast per distinct position in a group: a group
    that cannot merge without losing coverage below ``keep_at_least`` is split).

    Each trial site is scored by the change it makes on the points its moved sensors
    cover before or after the move, not by a recount of every sensor: the work grows
    with the number of sensors, not with its square.
    """
    current = xy.copy()
    final = labels.copy()
    still = np.zeros(len(xy), dtype=bool) if fixed is None else np.asarray(fixed, dtype=bool)
    covers = [np.asarray(cover(i, *p), dtype=np.int64) for i, p in enumerate(current)]
    counts = np.zeros(n_points, dtype=np.int32)  # sensors covering each point
    for c in covers:
        counts[c] += 1
    k = np.ones(n_points, dtype=np.int32) if need is None else np.asarray(need, dtype=np.int32)
    covered = int(np.count_nonzero(counts >= k))
    next_label = int(labels.max()) + 1 if len(labels) else 0
    for g in range(int(labels.max()) + 1 if len(labels) else 0):
        members = np.flatnonzero(labels == g)
        if len(np.unique(current[members], axis=0)) == 1:
            continue
        if cap is None or len(members) <= cap:  # a larger group would overload a mast
            covered = _merge(members, current, still, covers, counts, covered, k, cover,
                             keep_at_least)  # fmt: skip
        # One mast per distinct position left in the group.
        for spot in np.unique(current[members], axis=0)[1:]:
            at = members[np.all(current[members] == spot, axis=1)]
            final[at] = next_label
            next_label += 1
    return current, _renumber(final)


def _merge(
    members: NDArray[np.int_],
    current: F64,
    still: NDArray[np.bool_],
    covers: list[NDArray[np.int64]],
    counts: NDArray[np.int32],
    covered: int,
    k: NDArray[np.int32],
    cover: Callable[[int, float, float], NDArray[np.int_]],
    keep_at_least: int,
) -> int:
    """Move a group's ``members`` to the one site of theirs (an anchored member's,
    if any) that keeps the most points covered, when that keeps at least
    ``keep_at_least``; ``current``, ``covers`` and ``counts`` are updated in place.
    Returns the points covered to their k after it."""
    anchored = members[still[members]]
    sites = np.unique(current[anchored if len(anchored) else members], axis=0)
    # (covered, site, {moved sensor: its new cover})
    best: tuple[int, F64 | None, dict[int, NDArray[np.int64]]] = (-1, None, {})
    for site in sites:
        moved = [m for m in members if not still[m] and not np.array_equal(current[m], site)]
        new = {m: np.asarray(cover(m, *site), dtype=np.int64) for m in moved}
        after = covered + _gain(counts, [covers[m] for m in moved], list(new.values()), k)
        if after > best[0]:
            best = (after, site, new)
    after, site, new = best
    if after < keep_at_least:
        return covered
    for m, c in new.items():
        counts[covers[m]] -= 1
        counts[c] += 1
        covers[m] = c
        current[m] = site
    return after


def _gain(counts: NDArray[np.int32], old: list, new: list, need: NDArray[np.int32]) -> int:
    """Change in the number of points covered to their k (``need``) when covers
    ``old`` are replaced by ``new`` (lists of index arrays); ``counts`` is left as it
    was."""
    if not old:
        return 0
    touched = np.unique(np.concatenate(old + new))
    before = int(np.count_nonzero(counts[touched] >= need[touched]))
    for c in old:
        counts[c] -= 1
    for c in new:
        counts[c] += 1
    after = int(np.count_nonzero(counts[touched] >= need[touched]))
    for c in new:
        counts[c] -= 1
    for c in old:
        counts[c] += 1
    return after - before


def _renumber(labels: NDArray[np.int_]) -> NDArray[np.int_]:
    order: dict[int, int] = {}
    return np.array([order.setdefault(int(v), len(order)) for v in labels], dtype=int)
