"""The candidate set: positions x orientations x models, and what each covers.

Every mast position of the problem's lattice times a grid of orientations (yaw every
``yaw_step_deg``, pitch at ``pitches`` values spread over each model's limits; one yaw
for a level pattern that goes all the way round, ``problem.model_orientations``) times each
model of the problem's pack is a candidate. What each covers comes from the problem's exact cached ``targeted`` probe:
one numpy pass over all orientations per position, each sight ray cast once and only
if some orientation needs it. The result is a sparse matrix, rows = candidates,
columns = target points, 1 where the candidate covers the point; candidates that
cover nothing are left out. It is what set-cover optimizers work on: greedy today,
bounds and exact methods next.

The covered sets are bit-identical to ``targeted`` for the same poses, so a fixed
candidate's coverage is exactly what any later evaluation reports.

The matrix's size was estimated with the problem (``Problem.estimate``); as it fills,
a matrix that outgrows what this process can still hold through the optimizer's peak
(``budget.nonzero_limit``) stops the build with a one-line InputError rather than a
MemoryError later.
"""

from __future__ import annotations

from collections.abc import Generator
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray
from scipy import sparse

from . import budget
from .errors import InputError
from .model.sensors import SensorModel, SensorPose, frame
from .problem import Problem, model_orientations

F64 = NDArray[np.float64]
I64 = NDArray[np.int64]

# Positions between two progress reports while a candidate set is built.
POSITIONS_PER_REPORT = 16


@dataclass(frozen=True)
class CandidateSet:
    """Candidates and the target points each covers.

    positions: (K, 2) local metres (the problem's lattice); angles: per model, (O_m, 2)
    (pitch, yaw) degrees; models: the sensor models. Per candidate c (C in all):
    position[c], orientation[c] (a row of ``angles[model[c]]``), model[c]; matrix:
    (C, N) CSR float32, 1 where candidate c covers target point n.
    """

    positions: F64
    angles: tuple[F64, ...]
    models: tuple[SensorModel, ...]
    position: I64
    orientation: I64
    model: I64
    matrix: sparse.csr_matrix

    def __len__(self) -> int:
        return len(self.position)

    def pose(self, problem: Problem, c: int) -> SensorPose:
        """Candidate ``c`` as a pose on its mast (at its model's height)."""
        x, y = self.positions[self.position[c]]
        pitch, yaw = self.angles[self.model[c]][self.orientation[c]]
        return problem.pose(x, y, pitch, yaw, int(self.model[c]))


def build_candidates(problem: Problem) -> Generator[int, None, CandidateSet]:
    """The problem's candidate set (see the module docstring), every model of the
    problem's pack in turn; yields the number of (model, position) pairs done every
    ``POSITIONS_PER_REPORT`` positions. Built once per problem:
    later calls return the same set (``Problem.candidates``)."""
    if problem.candidates is not None:
        cached: CandidateSet = problem.candidates
        return cached
    models = problem.models
    positions = problem.space.positions
    angles = tuple(model_orientations(m) for m in models)
    limit = budget.nonzero_limit(problem.settings.optimizer)
    nonzeros = 0
    # Column indices as int32, the matrix's own index type (scipy keeps them uncopied).
    cols: list[NDArray[np.int32]] = []
    cand_pos: list[int] = []
    cand_ori: list[int] = []
    cand_model: list[int] = []
    total = len(positions) * len(models)  # (position, model) pairs to go through
    for m, (model, ang) in enumerate(zip(models, angles)):
        rots = np.array([frame(p, y) for p, y in ang])
        for i, (x, y) in enumerate(positions):
            pose = problem.pose(x, y, ang[0, 0], ang[0, 1], m)
            covered, ordinal = problem.probe.cover_many(model, pose, rots)
            ordinal32 = ordinal.astype(np.int32)
            for o in np.flatnonzero(covered.any(axis=1)):
                cols.append(ordinal32[covered[o]])
                cand_pos.append(i)
                cand_ori.append(int(o))
                cand_model.append(m)
            nonzeros += int(np.count_nonzero(covered))
            if nonzeros > limit:
                done = m * len(positions) + i + 1
                raise InputError(_outgrown(problem, nonzeros, done, total, limit))
            if i % POSITIONS_PER_REPORT == 0:
                yield m * len(positions) + i
    counts = [len(c) for c in cols]
    matrix = sparse.csr_matrix(
        (
            np.ones(sum(counts), dtype=np.float32),
            np.concatenate(cols) if cols else np.zeros(0, dtype=np.int32),
            np.cumsum([0, *counts]),
        ),
        shape=(len(cols), problem.n_targets),
    )
    problem.candidates = CandidateSet(
        positions=positions,
        angles=angles,
        models=models,
        position=np.array(cand_pos, dtype=np.int64),
        orientation=np.array(cand_ori, dtype=np.int64),
        model=np.array(cand_model, dtype=np.int64),
        matrix=matrix,
    )
    return problem.candidates


def sensor_price(problem: Problem, cands: CandidateSet) -> float | F64:
    """What one sensor costs in the ``cost`` objective: one number when every model
    of the problem's pack costs the same, else (C,) each candidate's model's cost."""
    costs = problem.sensor_costs
    if np.all(costs == costs[0]):
        return float(costs[0])
    return costs[cands.model]


def _outgrown(problem: Problem, nonzeros: int, done: int, total: int, limit: int) -> str:
    """The refusal of a candidate matrix that outgrew what the process can hold."""
    est = problem.estimate
    return (
        f"the candidate matrix at grid_m = {problem.grid.spacing:g} outgrew its estimate "
        f"({budget.count_text(est.nonzeros)} nonzeros): {budget.count_text(nonzeros)} after "
        f"{done} of {total} mast positions, more than the {budget.count_text(limit)} this "
        f"machine can hold through the {problem.settings.optimizer} optimizer: raise "
        "grid_m (--grid) or position_step_m, or use --optimizer es"
    )
