"""A greedy set cover over a candidate set: beyond the paper, fewer sensors.

Candidates are every mast position of the lattice (the ES's) times a grid of
orientations: yaw every ``yaw_step_deg``, pitch at ``pitches`` values spread over the
model's limits. What each candidate covers comes from the cached targeted evaluator
(each sight ray cast once, only if some orientation needs it), one numpy pass over all
orientations per position. Then, while the goal is not met, the candidate that covers
the most still-uncovered target points is fixed, except that one standing on a mast
already used wins if it adds at least 1 / (1 + MAST_PREFERENCE) of the best (fewer
masts for a few per cent of one sensor's coverage). Greedy set cover needs at most
about ln(N) times the optimum number of the same candidates (N target points).

The covered sets are bit-identical to ``targeted`` for the same poses, so the fixed
sensors' coverage is exactly what any later evaluation reports.
"""

from __future__ import annotations

import math
from collections.abc import Iterator
from typing import TYPE_CHECKING

import numpy as np
from numpy.typing import NDArray
from scipy import sparse

from .sensors import frame

if TYPE_CHECKING:
    from .optimize import OptimizationRun, Progress

F64 = NDArray[np.float64]

# A candidate on a mast already used wins against a new mast that adds up to this
# fraction more (0: only on ties).
MAST_PREFERENCE = 0.1


def orientations(
    pitch_min: float, pitch_max: float, yaw_step_deg: float = 10.0, pitches: int = 6
) -> F64:
    """(O, 2) (pitch, yaw) degrees: yaw in steps from 0, pitch evenly over the limits."""
    yaws = np.arange(0.0, 360.0, yaw_step_deg)
    ps = np.linspace(pitch_min, pitch_max, pitches) if pitch_max > pitch_min else [pitch_min]
    return np.array([(p, y) for p in ps for y in yaws])


def pick_candidate(gains: NDArray[np.float32], on_mast: NDArray[np.bool_]) -> int:
    """Index of the candidate to fix: the largest gain (new target points), where a
    candidate on a mast already used counts ``1 + MAST_PREFERENCE`` times; the first
    on ties."""
    return int(np.argmax(gains * np.where(on_mast, 1.0 + MAST_PREFERENCE, 1.0)))


def greedy_steps(run: OptimizationRun) -> Iterator[Progress]:
    """Fix sensors on ``run`` greedily until its goal (yields progress)."""
    model, settings = run.model, run.settings
    angles = orientations(model.pitch_min_deg, model.pitch_max_deg)
    rots = np.array([frame(p, y) for p, y in angles])
    positions = run.space.positions

    # Candidate coverage: rows = candidates (position, orientation), columns = targets.
    cols, cand_pos, cand_ori = [], [], []
    for i, (x, y) in enumerate(positions):
        pose = run.pose(x, y, angles[0, 0], angles[0, 1])
        covered, ordinal = run.probe.cover_many(model, pose, rots)
        useful = np.flatnonzero(covered.any(axis=1))
        for o in useful:
            cols.append(ordinal[covered[o]])
            cand_pos.append(i)
            cand_ori.append(o)
        if i % 16 == 0:
            yield run._progress("search")
    n_cand = len(cand_pos)
    if n_cand == 0:
        run.stop_reason = "no candidate pose covers any target point"
        return
    counts = [len(c) for c in cols]
    matrix = sparse.csr_matrix(
        (np.ones(sum(counts), dtype=np.float32), np.concatenate(cols), np.cumsum([0, *counts])),
        shape=(n_cand, run.grid.n_targets),
    )
    cand_pos_arr = np.array(cand_pos)
    goal = math.ceil(settings.rho * run.grid.n_targets)
    index = {(float(x), float(y)): i for i, (x, y) in enumerate(positions)}
    used_positions = {
        index[(s.pose.x, s.pose.y)] for s in run.sensors if (s.pose.x, s.pose.y) in index
    }
    by_point = matrix.tocsc()  # which candidates cover a point: for the gain updates
    gains = matrix @ (~run.fixed.covered).astype(np.float32)
    while run.fixed.n_covered < goal:
        if len(run.sensors) >= run.max_sensors:
            run.stop_reason = f"stopped at max_sensors = {run.max_sensors}"
            return
        best = float(gains.max())
        if best <= 0:
            run.stop_reason = (
                "no candidate pose adds coverage; the rest of the target cannot be seen "
                "from the candidates (positions x orientations)"
            )
            return
        pick = pick_candidate(gains, np.isin(cand_pos_arr, list(used_positions)))
        i, o = cand_pos[pick], cand_ori[pick]
        x, y = positions[i]
        pose = run.pose(x, y, angles[o, 0], angles[o, 1])
        cov, fit = run.evaluate(pose)
        newly = cov.covered[~run.fixed.covered[cov.covered]]
        run._fix(pose, cov, float(fit.new_points), 0, 0)
        # A point covered now adds nothing to any candidate any more.
        gains -= np.asarray(by_point[:, newly].sum(axis=1)).ravel()
        used_positions.add(i)
        yield run._progress("fixed")
    run.stop_reason = f"reached rho = {settings.rho:.0%} of the target"
