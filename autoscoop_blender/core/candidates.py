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
from typing import NamedTuple

import numpy as np
from numpy.typing import NDArray
from scipy import sparse
from scipy.spatial import cKDTree

from . import budget, refusal
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
    # Candidates left out because another at the same position and of the same model
    # covers every point they cover (``dominated``), and their nonzeros.
    dominated: int = 0
    dominated_nonzeros: int = 0

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
    everywhere = np.arange(problem.n_targets, dtype=np.int64)
    built = yield from _build(problem, everywhere, np.arange(len(problem.space.positions)))
    problem.candidates = built.cands
    return built.cands


@dataclass(frozen=True)
class PartCandidates:
    """The candidates of one part of the target (``optimize/parts.py``).

    cands: the candidates that cover a point of the part, over the problem's
    positions, the matrix's columns the part's points in order; share: (C,) each
    candidate's points in the part over all the points it covers (the part's share of
    its cost); sites: (S,) the positions they stand at; site_share: (S,) the same
    share for a site, of the points any of its candidates covers.
    """

    cands: CandidateSet
    share: F64
    sites: I64
    site_share: F64


def near_positions(problem: Problem, points: I64, reach_m: float) -> I64:
    """The positions (indices into the problem's, sorted) within ``reach_m`` of one
    of the target points ``points``: those a part's candidates stand at."""
    xy = problem.grid.target_xy[points]
    dist, _ = cKDTree(xy).query(problem.space.positions, distance_upper_bound=reach_m)
    return np.flatnonzero(np.isfinite(dist))


def build_part(
    problem: Problem, points: I64, reach_m: float, shared: SharedPositions | None = None
) -> Generator[int, None, PartCandidates]:
    """The candidates of the part of the target with ordinals ``points`` (sorted):
    every position within ``reach_m`` (the longest range) of one of them, each
    candidate covering a point there (see ``build_candidates``; yields the same).
    Only the part's matrix is held: its memory follows the part, not the ground.
    shared: what the parts before cast at positions this part reaches too."""
    near = near_positions(problem, points, reach_m)
    return (yield from _build(problem, points, near, shared))


class _Kept(NamedTuple):
    """A position's ``cover_many`` for one model, kept: of its ``orientations``, the
    ``rows`` that cover something, as ``bits`` (np.packbits of their (P,) rows), over
    the points ``ordinal`` (P,); ``dropped``: (orientations dominated, their nonzeros)."""

    orientations: int
    rows: I64
    bits: NDArray[np.uint8]
    ordinal: I64
    dropped: tuple[int, int]


class SharedPositions:
    """What ``cover_many`` gave (after ``dominated``) at the positions that more than
    one part reaches, kept from the first of those parts' builds until the last, so
    that each position's rays are cast once: on Town01's 3 parts, 11,686 position
    builds were of 6,964 positions (2026-11-29). The parts are built in order
    (``at(k)`` before part k); what is kept is each position's covered orientations
    as bits, dropped once the last part that reaches it has taken it.

    near: per part, the positions it reaches (``near_positions``)."""

    def __init__(self, near: list[I64], n_positions: int) -> None:
        self.last = np.full(n_positions, -1, dtype=np.int64)
        for k, positions in enumerate(near):
            self.last[positions] = k
        self.part = 0
        self._kept: dict[tuple[int, int], _Kept] = {}  # by (position, model)

    def at(self, k: int) -> None:
        """Part k is built next: what no later part reaches is dropped."""
        self.part = k
        for key in [key for key in self._kept if self.last[key[0]] < k]:
            del self._kept[key]

    def keep(
        self, i: int, m: int, covered: NDArray[np.bool_], ordinal: I64, dropped: tuple[int, int]
    ) -> None:
        """Position i's ``cover_many`` for model m (``covered`` (O, P) after
        ``dominated``, ``ordinal`` (P,)) and its (dropped, their nonzeros), when a
        later part reaches it."""
        if self.last[i] > self.part:
            rows = np.flatnonzero(covered.any(axis=1))
            bits = np.packbits(covered[rows], axis=1)
            self._kept[(i, m)] = _Kept(len(covered), rows, bits, ordinal, dropped)

    def take(self, i: int, m: int) -> tuple[NDArray[np.bool_], I64, tuple[int, int]] | None:
        """What ``keep`` kept of position i and model m, or None."""
        got = self._kept.get((i, m))
        if got is None:
            return None
        if self.last[i] <= self.part:
            del self._kept[(i, m)]
        covered = np.zeros((got.orientations, len(got.ordinal)), dtype=bool)
        covered[got.rows] = np.unpackbits(got.bits, axis=1, count=len(got.ordinal)).astype(bool)
        return covered, got.ordinal, got.dropped

    def __len__(self) -> int:
        return len(self._kept)


def build_on_sites(problem: Problem, sites: I64) -> Generator[int, None, CandidateSet]:
    """The candidates at the positions ``sites`` (indices into the problem's, sorted)
    over every target point (see ``build_candidates``; yields the same): the mast-aware
    MILP's over a whole ground planned in parts (``parts.rejoin``)."""
    every = np.arange(problem.n_targets, dtype=np.int64)
    return (yield from _build(problem, every, np.asarray(sites, dtype=np.int64))).cands


def _build(
    problem: Problem, points: I64, near: I64, shared: SharedPositions | None = None
) -> Generator[int, None, PartCandidates]:
    """Candidates at the positions ``near`` (indices into the problem's) over the
    target points ``points`` (sorted ordinals; the matrix's columns, in order);
    shared: what was cast at them for a part before, and is kept for one after."""
    models = problem.models
    positions = problem.space.positions
    angles = tuple(model_orientations(m) for m in models)
    limit = budget.nonzero_limit(problem.settings.optimizer)
    local = np.full(problem.n_targets, -1, dtype=np.int64)
    local[points] = np.arange(len(points))
    whole = len(points) == problem.n_targets  # every point: no share to count
    # Dominated candidates go where each point needs one sensor (``dominated``); the
    # site's union (``seen``) is theirs too, so its share does not change.
    prune = problem.k_max == 1
    n_dropped = dropped_nonzeros = 0
    nonzeros = 0
    # Column indices as int32, the matrix's own index type (scipy keeps them uncopied).
    cols: list[NDArray[np.int32]] = []
    cand_pos: list[int] = []
    cand_ori: list[int] = []
    cand_model: list[int] = []
    share: list[float] = []
    # Per position: the target ordinals some candidate there covers (all models).
    seen: dict[int, I64] = {}
    total = len(near) * len(models)  # (position, model) pairs to go through
    for m, (model, ang) in enumerate(zip(models, angles)):
        rots = np.array([frame(p, y) for p, y in ang])
        for j, i in enumerate(near):
            got = None if shared is None else shared.take(int(i), m)
            if got is None:
                x, y = positions[i]
                pose = problem.pose(x, y, ang[0, 0], ang[0, 1], m)
                covered, ordinal = problem.probe.cover_many(model, pose, rots)
                dropped = (0, 0)
                if prune:
                    drop = dominated(covered)
                    dropped = (int(drop.sum()), int(covered[drop].sum()))
                    covered[drop] = False
                if shared is not None:
                    shared.keep(int(i), m, covered, ordinal, dropped)
            else:
                covered, ordinal, dropped = got
            n_dropped += dropped[0]
            dropped_nonzeros += dropped[1]
            here = local[ordinal]
            here32 = here.astype(np.int32)
            mine = covered if whole else covered & (here >= 0)
            in_part = mine.sum(axis=1)
            fraction = in_part / np.maximum(covered.sum(axis=1), 1)
            for o in np.flatnonzero(in_part):
                cols.append(here32[mine[o]])
                cand_pos.append(int(i))
                cand_ori.append(int(o))
                cand_model.append(m)
                share.append(float(fraction[o]))
            if not whole:
                union = ordinal[covered.any(axis=0)]
                if len(union):
                    seen[int(i)] = np.union1d(seen.get(int(i), union), union)
            nonzeros += int(in_part.sum())
            if nonzeros > limit:
                done = m * len(near) + j + 1
                raise InputError(_outgrown(problem, nonzeros, done, total, limit))
            if j % POSITIONS_PER_REPORT == 0:
                yield m * len(near) + j
    counts = [len(c) for c in cols]
    matrix = sparse.csr_matrix(
        (
            np.ones(sum(counts), dtype=np.float32),
            np.concatenate(cols) if cols else np.zeros(0, dtype=np.int32),
            np.cumsum([0, *counts]),
        ),
        shape=(len(cols), len(points)),
    )
    cands = CandidateSet(
        positions=positions,
        angles=angles,
        models=models,
        position=np.array(cand_pos, dtype=np.int64),
        orientation=np.array(cand_ori, dtype=np.int64),
        model=np.array(cand_model, dtype=np.int64),
        matrix=matrix,
        dominated=n_dropped,
        dominated_nonzeros=dropped_nonzeros,
    )
    sites = np.unique(cands.position)
    site_share = np.ones(len(sites))
    if not whole:
        site_share = np.array(
            [np.count_nonzero(local[seen[int(s)]] >= 0) / len(seen[int(s)]) for s in sites]
        )
    return PartCandidates(cands, np.array(share, dtype=float), sites, site_share)


def dominated(covered: NDArray[np.bool_]) -> NDArray[np.bool_]:
    """(O,) which of O orientations at one position are dominated: another covers every
    point they cover (``covered``: (O, K) bool), and more points, or as many with a
    lower index (of equal sets the first stays). Orientations that cover nothing are
    not dominated (they are no candidates anyway).

    Leaving them out changes no bound and no optimum where each point needs one
    sensor: a plan that uses a dominated candidate is at least as good with its
    dominator in its place (same mast, same cost, a superset of points), so the best
    plan and every LP bound on the candidates without them are those of all
    candidates. (With k > 1 a plan may need both, so they are kept there.)

    Per point, the set of orientations covering it as a bitset; orientation o is
    dominated when the AND of its points' bitsets holds an orientation ranked above
    it (more points, or as many and a lower index). Hand-written: no library tests
    subset relations among rows of a boolean matrix."""
    size = covered.sum(axis=1)
    rows = np.flatnonzero(size)
    out = np.zeros(len(covered), dtype=bool)
    if len(rows) < 2:
        return out
    cov = covered[rows][:, covered[rows].any(axis=0)]
    n = len(rows)
    words = (n + 63) // 64

    def bitsets(bits: NDArray[np.bool_]) -> NDArray[np.uint64]:
        """(R, n) bool -> (R, words) uint64, bit j of row r = bits[r, j]."""
        packed = np.packbits(bits, axis=1, bitorder="little")
        padded = np.zeros((len(bits), words * 8), dtype=np.uint8)
        padded[:, : packed.shape[1]] = packed
        return padded.view(np.uint64)

    by_point = bitsets(cov.T)  # (points, words)
    r, pts = np.nonzero(cov)  # row-major: each orientation's points in a run
    starts = np.searchsorted(r, np.arange(n))
    common = np.bitwise_and.reduceat(by_point[pts], starts, axis=0)  # (n, words)
    # rank: more points first, then the lower index; above[o]: those ranked before o.
    rank = np.empty(n, dtype=np.int64)
    rank[np.lexsort((np.arange(n), -size[rows]))] = np.arange(n)
    above = bitsets(rank[None, :] < rank[:, None])
    out[rows] = (common & above).any(axis=1)
    return out


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
        f"({refusal.count_text(est.nonzeros)} nonzeros): {refusal.count_text(nonzeros)} after "
        f"{done} of {total} mast positions, more than the {refusal.count_text(limit)} this "
        f"machine can hold through the {problem.settings.optimizer} optimizer: raise "
        "grid_m (--grid) or position_step_m, or use --optimizer es"
    )
