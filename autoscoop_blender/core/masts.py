"""Grouping fixed sensors into shared masts (the last step of Algorithm 1).

Sensors whose feet lie within ``join_m`` of each other (complete linkage: every pair
of a group) would share one mast. The mast stands at one of the members' positions;
all members move there, keeping their height, pitch and yaw. The site chosen is the
one that keeps the most target points covered; a group whose best site would drop
the coverage below what it was (or below the goal, whichever is lower) stays apart.
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np
from numpy.typing import NDArray
from scipy.cluster.hierarchy import fcluster, linkage

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
    raw = fcluster(linkage(xy, method="complete"), t=join_m, criterion="distance")
    order: dict[int, int] = {}
    return np.array([order.setdefault(int(r), len(order)) for r in raw])


def choose_sites(
    xy: F64,
    labels: NDArray[np.int_],
    coverage_with: Callable[[F64], int],
    keep_at_least: int,
) -> tuple[F64, NDArray[np.int_]]:
    """Mast sites for grouped sensors.

    xy: (n, 2) sensor positions; labels: their groups; ``coverage_with(new_xy)`` gives
    the number of target points covered when the sensors stand at ``new_xy`` (n, 2).
    Returns the sensors' new positions (n, 2) and their final mast labels (a group
    that cannot merge without losing coverage below ``keep_at_least`` is split).
    """
    current = xy.copy()
    final = labels.copy()
    next_label = int(labels.max()) + 1 if len(labels) else 0
    for g in range(int(labels.max()) + 1 if len(labels) else 0):
        members = np.flatnonzero(labels == g)
        sites = np.unique(current[members], axis=0)
        if len(sites) == 1:
            continue
        best_site, best_cov = None, -1
        for site in sites:
            trial = current.copy()
            trial[members] = site
            cov = coverage_with(trial)
            if cov > best_cov:
                best_site, best_cov = site, cov
        if best_cov >= keep_at_least:
            current[members] = best_site
        else:
            # Keep members apart: one mast per distinct position.
            for site in sites[1:]:
                at = members[np.all(current[members] == site, axis=1)]
                final[at] = next_label
                next_label += 1
    return current, _renumber(final)


def _renumber(labels: NDArray[np.int_]) -> NDArray[np.int_]:
    order: dict[int, int] = {}
    return np.array([order.setdefault(int(v), len(order)) for v in labels], dtype=int)
