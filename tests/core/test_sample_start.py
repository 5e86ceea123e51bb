"""The sensors LP started from a sample's LP (``bound.sample_columns``): on random
grounds of points on a 1 m lattice, seen by candidates that cover disks, the LP over
every point reaches the LP that scipy's linprog solves with every candidate at once,
and reports only its own rounds; the start is the sample LP's support (an optimum on
the sample, checked by linprog on those columns alone), then more of its columns as
the entries allow."""

import numpy as np
import pytest
from scipy import sparse

from autoscoop_blender.core.optimize import bound
from autoscoop_blender.core.optimize.bound import LPProgress, cover_lp, sample_columns
from autoscoop_blender.core.optimize.cover import CoverInstance
from tests.core.test_bound import full_lp
from tests.core.test_lp import drain, steps


def disk_ground(rng, side=14, n_cand=40):
    """(instance, costs, positions: each candidate its own): points on a side x side
    lattice, 1 m apart; each candidate covers the points within 1.5-4 m of a random
    centre; the goal is 90 % of the points some candidate covers."""
    xy = np.stack(np.meshgrid(np.arange(side), np.arange(side)), -1).reshape(-1, 2).astype(float)
    centres = rng.uniform(0, side, (n_cand, 2))
    radii = rng.uniform(1.5, 4.0, n_cand)
    dist = np.linalg.norm(xy[None, :, :] - centres[:, None, :], axis=2)
    matrix = sparse.csr_matrix((dist <= radii[:, None]).astype(np.float32))
    seen = int(np.count_nonzero(matrix.sum(axis=0)))
    inst = CoverInstance(matrix, int(0.9 * seen), xy=xy)
    return inst, rng.uniform(0.5, 2.0, n_cand), np.arange(n_cand)


@pytest.fixture
def any_size(monkeypatch):
    """The sample is taken on grounds of any size (these have 196 points)."""
    monkeypatch.setattr(bound, "SAMPLE_MIN_POINTS", 0)


@pytest.mark.parametrize("seed", range(6))
def test_a_sampled_start_reaches_the_full_lp_and_reports_its_own_rounds(seed, any_size):
    inst, cost, group = disk_ground(np.random.default_rng(4100 + seed))
    none = np.zeros(0, np.int64)
    sol, yielded = steps(cover_lp(inst, cost, group, none, integral=False, sample=True))
    reports = [r for r in yielded if isinstance(r, LPProgress)]
    assert sol.complete and sol.value == pytest.approx(full_lp(inst, cost), rel=1e-6)
    # The sample's rounds are not reported as the whole's: one report a round, counted
    # from 1, every bound below the whole LP's value.
    assert [r.rounds for r in reports] == list(range(1, sol.rounds + 1))
    assert all(r.bound <= sol.value + 1e-9 for r in reports)
    # The first round already holds the sample's columns (it starts from none).
    start = drain(sample_columns(inst, cost, group, none))
    assert len(start) > 0 and reports[0].columns == len(start)


@pytest.mark.parametrize("seed", range(6))
def test_the_start_is_the_samples_support_then_more_as_the_entries_allow(seed, monkeypatch):
    inst, cost, group = disk_ground(np.random.default_rng(4200 + seed))
    none = np.zeros(0, np.int64)
    sample = inst.thinned(bound.SAMPLE_M)
    assert sample.n_points < inst.n_points
    entries = np.diff(inst.matrix.indptr)
    starts = {}
    for budget in (0, 150, 400, 10**9):
        monkeypatch.setattr(bound, "START_NONZEROS", budget)
        starts[budget] = drain(sample_columns(inst, cost, group, none))
    used = starts[0]
    # With no entries to spare: the sample LP's support, an optimum of the sample within
    # its stopping gap, by linprog over those columns alone.
    assert len(used) < len(starts[10**9])  # not every column the sample LP took
    alone = CoverInstance(sample.matrix[used], sample.goal)
    assert full_lp(alone, cost[used]) <= full_lp(sample, cost) * (1 + bound.SAMPLE_REL_GAP) + 1e-9
    for small, large in [(0, 150), (150, 400), (400, 10**9)]:
        assert list(starts[large][: len(starts[small])]) == list(starts[small])  # a prefix
    for budget in (150, 400):
        assert entries[starts[budget]].sum() <= max(budget, entries[used].sum())
        # the next column (if any) would have passed the budget
        nxt = starts[10**9][len(starts[budget]) :]
        if len(nxt) and len(starts[budget]) > len(used):
            assert entries[starts[budget]].sum() + entries[nxt[0]] > budget
    assert len(set(starts[10**9])) == len(starts[10**9])


def test_no_sample_below_its_size_or_without_the_points_positions(monkeypatch):
    """Below ``SAMPLE_MIN_POINTS``, or with no positions to thin by, the LP starts from
    its own columns alone: its first round holds just those."""
    inst, cost, group = disk_ground(np.random.default_rng(4300))
    initial = np.array([0, 1], dtype=np.int64)
    monkeypatch.setattr(bound, "SAMPLE_MIN_POINTS", inst.n_points + 1)
    _, yielded = steps(cover_lp(inst, cost, group, initial, integral=False, sample=True))
    assert next(r for r in yielded if isinstance(r, LPProgress)).columns == 2
    monkeypatch.setattr(bound, "SAMPLE_MIN_POINTS", 0)
    blind = CoverInstance(inst.matrix, inst.goal)
    _, yielded = steps(cover_lp(blind, cost, group, initial, integral=False, sample=True))
    assert next(r for r in yielded if isinstance(r, LPProgress)).columns == 2


def _sample_lp_returns(monkeypatch, value, rounds=3):
    """``cover_lp`` on the sample replaced: it returns columns 5, 2, 9 and 7 at x 0.5,
    0, 0.25 and 0 (reduced costs 0, 0.3, 0, 0.1) after ``rounds`` rounds at ``value``
    (inf: its last round cut short by the time limit)."""
    reduced = np.full(12, 1.0)
    reduced[[5, 2, 9, 7]] = [0.0, 0.3, 0.0, 0.1]

    def fake(*args, **kwargs):
        yield None
        return bound.LPSolution(
            value, 0.0, np.array([5, 2, 9, 7]), np.array([0.5, 0.0, 0.25, 0.0]),
            np.zeros(12), reduced, rounds, False,
        )  # fmt: skip

    monkeypatch.setattr(bound, "cover_lp", fake)


@pytest.mark.parametrize(
    ("value", "rounds", "budget", "want"),
    [
        (3.0, 3, 0, [5, 9]),  # its support alone
        (3.0, 3, 3, [5, 9, 7]),  # then the next by reduced cost, each column 1 entry
        (3.0, 3, 10, [5, 9, 7, 2]),
        (np.inf, 3, 0, []),  # cut short: no support, by reduced cost only
        (np.inf, 3, 2, [5, 9]),
        (np.inf, 3, 10, [5, 9, 7, 2]),
        (3.0, 0, 10, []),  # no round ended: nothing
    ],
)
def test_the_start_from_a_sample_lp_ended_or_cut_short(monkeypatch, value, rounds, budget, want):
    _sample_lp_returns(monkeypatch, value, rounds)
    monkeypatch.setattr(bound, "START_NONZEROS", budget)
    # candidate c sees point c % 4: one entry each
    matrix = sparse.csr_matrix(np.tile(np.eye(4, dtype=np.float32), (3, 1)))
    inst = CoverInstance(matrix, 3, xy=np.array([[0.0, 0.0], [5.0, 0.0], [0.0, 5.0], [5.0, 5.0]]))
    got = drain(sample_columns(inst, np.ones(12), np.arange(12), np.zeros(0, np.int64)))
    assert list(got) == want
