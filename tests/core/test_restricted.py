"""The restricted LP of column generation over merged points (``bound._Restricted``):
its groups are exactly the points its columns tell apart (and their k), checked
against a partition worked out point by point; its value is the LP over every point
(scipy's linprog, nothing merged: ``test_bound.full_lp``); its duals, shared out, are
optimal duals of that LP; and the basis it carries over from round to round is an
optimum still when the new column cannot help (no simplex step)."""

import highspy
import numpy as np
import pytest
from scipy import sparse

from autoscoop_blender.core.optimize import bound
from autoscoop_blender.core.optimize.cover import CoverInstance
from tests.core.test_bound import full_lp, random_needing
from tests.core.test_lp import drain, random_instance


def _of_rows(rows, n_points):
    """A (candidates, n_points) float32 matrix of 1s: candidate i covers ``rows[i]``."""
    indptr = np.cumsum([0, *map(len, rows)])
    data = np.ones(indptr[-1], np.float32)
    return sparse.csr_matrix((data, np.concatenate(rows), indptr), shape=(len(rows), n_points))


def _partition(matrix, columns, need):
    """{point: key}: a point's (k, the (column, entry) pairs of ``columns`` that cover
    it), for the points some column covers, worked out point by point."""
    dense = matrix.toarray()
    keys = {}
    for p in range(matrix.shape[1]):
        pairs = tuple((c, float(dense[c, p])) for c in columns if dense[c, p] != 0)
        if pairs:
            keys[p] = (int(need[p]), pairs)
    return keys


def _same_partition(label, keys, n):
    """Whether ``label`` (N,) groups the points exactly as ``keys`` do (-1: in none)."""
    if any((label[p] >= 0) != (p in keys) for p in range(n)):
        return False
    pts = sorted(keys)
    return all(
        (label[a] == label[b]) == (keys[a] == keys[b]) for i, a in enumerate(pts) for b in pts[i:]
    )


def _valued(rng, n_cand, n_points):
    """A random instance whose entries are 1 or 2 (a mast site at k = 2 adds up to 2 to
    a point) and whose points need 1 or 2."""
    inst = random_instance(rng, n_cand=n_cand, n_points=n_points)
    m = inst.matrix.copy()
    m.data = rng.integers(1, 3, m.nnz).astype(np.float32)
    need = rng.integers(1, 3, n_points).astype(np.int32)
    return CoverInstance(m, inst.goal, need=need)


@pytest.mark.parametrize("seed", range(25))
def test_the_groups_are_the_points_the_columns_tell_apart(seed):
    """Columns joining a few at a time, entries 1 or 2, points needing 1 or 2: after
    each batch, two points share a group exactly when the same columns cover them with
    the same entries and they need the same; the sizes count the groups' points."""
    rng = np.random.default_rng(seed)
    inst = _valued(rng, 16, 30)
    r = bound._Restricted(inst, np.ones(16), 1.0, interior=False)
    joined = []
    for batch in np.array_split(rng.permutation(16), 5):
        r.add(batch)
        joined += batch.tolist()
        keys = _partition(inst.matrix, joined, inst.k)
        assert _same_partition(r.label, keys, 30)
        assert r.size.tolist() == np.bincount(r.label[r.label >= 0]).tolist()
        assert r.n_groups == len(set(keys.values()))
    assert r.columns == joined


def _solve(r):
    h = r.model(None)
    h.run()
    assert h.getModelStatus() == highspy.HighsModelStatus.kOptimal
    r.solved()
    return h


@pytest.mark.parametrize("need", [1, 2])
@pytest.mark.parametrize("seed", range(10))
def test_the_merged_lp_is_the_lp_over_every_point_and_its_duals_are_optimal(seed, need):
    """Round after round (columns joining by threes, from a model carried over): the
    value is linprog's over every point; the shared-out duals price each column in the
    LP at no more than its cost (at k > 1 the x <= 1 bounds take the excess), and
    their value, sigma goal - sum_n max(0, sigma - k_n pi_n) less that excess, is the
    LP's (strong duality over every point: they are optimal there)."""
    rng = np.random.default_rng(40 + seed)
    inst = random_needing(rng, 15, 28, need)
    cost = rng.uniform(0.5, 2.0, 15)
    # The artificial column as cover_lp prices it: never cheaper than the candidates.
    r = bound._Restricted(inst, cost, float(cost.max()) * need, interior=False)
    for batch in np.array_split(rng.permutation(15), 5):
        r.add(batch)
        h = _solve(r)
        value = h.getInfo().objective_function_value
        cols = np.asarray(r.columns)
        pi, sigma = r.duals()
        priced = np.asarray(inst.matrix[cols] @ pi, dtype=float)
        excess = np.maximum(0.0, priced - cost[cols])
        if need == 1:
            assert (excess <= 1e-7).all()
        dual = sigma * inst.goal - np.maximum(0.0, sigma - inst.k * pi).sum() - excess.sum()
        art = h.getSolution().col_value[r.n_groups]
        if art < 1e-9:  # the goal is met by the columns: their LP over every point
            restricted = CoverInstance(inst.matrix[cols], inst.goal, need=inst.k)
            assert value == pytest.approx(full_lp(restricted, cost[cols]), abs=1e-7)
            assert dual == pytest.approx(value, abs=1e-6)
        # A point no column covers is priced at sigma / k.
        alone = r.label < 0
        assert pi[alone] == pytest.approx(sigma / inst.k[alone])


def test_a_column_that_cannot_help_takes_no_simplex_step():
    """Points 0-3; a = {0, 1} and b = {2, 3} at 1 each cover the goal of 4 (the LP
    2). Then c = {1, 2} at 5 splits both groups in two; the model built again from the
    carried basis is optimal as it stands: 0 simplex iterations, the same value. A
    fourth column d = {0, 1, 2, 3} at 1 helps (the LP 1) and takes a step."""
    m = _of_rows([[0, 1], [2, 3], [1, 2], [0, 1, 2, 3]], 4)
    inst = CoverInstance(m, 4)
    cost = np.array([1.0, 1.0, 5.0, 1.0])
    r = bound._Restricted(inst, cost, 5.0, interior=False)
    r.add(np.array([0, 1]))
    assert _solve(r).getInfo().objective_function_value == pytest.approx(2.0)
    assert r.n_groups == 2
    r.add(np.array([2]))
    assert r.n_groups == 4
    h = _solve(r)
    assert h.getInfo().objective_function_value == pytest.approx(2.0)
    assert h.getInfo().simplex_iteration_count == 0
    r.add(np.array([3]))
    h = _solve(r)
    assert h.getInfo().objective_function_value == pytest.approx(1.0)
    assert h.getInfo().simplex_iteration_count > 0


def test_a_group_split_off_a_fractional_u_keeps_it_basic():
    """Points 0-3, goal 3: a = {0, 1} at 1 covers two, b = {2, 3} at 1.2 the third at
    one half (the LP 1.6, the only optimum: b's group's u basic at 1/2). c = {2} at 5
    splits that group; the part split off keeps the u basic at 1/2 (its row tight),
    so the model built again is optimal as it stands: 0 simplex iterations, 1.6."""
    m = _of_rows([[0, 1], [2, 3], [2]], 4)
    r = bound._Restricted(CoverInstance(m, 3), np.array([1.0, 1.2, 5.0]), 5.0, interior=False)
    r.add(np.array([0, 1]))
    h = _solve(r)
    assert h.getInfo().objective_function_value == pytest.approx(1.6)
    split = r.label[2]
    assert h.getBasis().col_status[split] == highspy.HighsBasisStatus.kBasic
    r.add(np.array([2]))
    assert r.n_groups == 3
    h = _solve(r)
    assert h.getInfo().objective_function_value == pytest.approx(1.6)
    assert h.getInfo().simplex_iteration_count == 0


def test_column_generation_over_merged_points_reaches_the_lp_of_a_strip():
    """200 points in 20 runs of 10; candidate i (19 of them) covers runs i and i + 1;
    goal 190. Each point's cover is x_{j-1} + x_j over its run j, and summed over the
    runs those are 2 sum x, so sum u >= 19 needs sum x >= 9.5; every x at 1/2 meets it
    (runs 1-18 covered, the two end runs half): the LP is 9.5, and a run's ten points
    make one group. Column generation from nothing ends there."""
    m = _of_rows([list(range(10 * i, 10 * i + 20)) for i in range(19)], 200)
    inst = CoverInstance(m, 190)
    sol = drain(bound.cover_lp(inst, np.ones(19), np.arange(19), np.zeros(0, np.int64),
                               integral=False))  # fmt: skip
    assert sol.complete and sol.value == pytest.approx(9.5)
    assert full_lp(inst, np.ones(19)) == pytest.approx(9.5)
    r = bound._Restricted(inst, np.ones(19), 1.0, interior=False)
    r.add(np.arange(19))
    assert r.n_groups == 20 and r.size.tolist() == [10] * 20


def test_the_carried_basis_starts_a_new_group_of_uncovered_points_at_u_zero():
    """Points 0-4, goal 4: a = {0, 1} at 1 and b = {2, 3} at 1 cover it (the LP 2, x_b
    basic: the last column). Then c = {3, 4} at 5 joins: it splits b's group ({2} and
    {3}) and gives point 4, in no row before, a group of its own. The carried basis
    has as many basics as rows; the new group's u is at its bound 0 and its row's
    slack basic (its origin is no row, whatever the last column's status); the group
    split off {3} adds one basic (b's u was not basic, so its row's slack). Solved
    from it: the same 2 (not without a step: the first optimum is degenerate, its
    goal dual the artificial's 5, which prices point 4's new u in)."""
    m = _of_rows([[0, 1], [2, 3], [3, 4]], 5)
    r = bound._Restricted(CoverInstance(m, 4), np.array([1.0, 1.0, 5.0]), 5.0, interior=False)
    r.add(np.array([0, 1]))
    h = _solve(r)
    assert h.getInfo().objective_function_value == pytest.approx(2.0)
    s = highspy.HighsBasisStatus
    assert h.getBasis().col_status[-1] == s.kBasic  # x_b
    r.add(np.array([2]))
    assert r.n_groups == 4
    carried = r._carried(r.basis)
    cols, rows = list(carried.col_status), list(carried.row_status)
    assert len(cols) == r.n_groups + 1 + 3 and len(rows) == r.n_groups + 1
    assert sum(x == s.kBasic for x in cols + rows) == len(rows)
    alone = r.label[4]
    assert cols[alone] == s.kLower and rows[alone] == s.kBasic
    assert cols[-1] == s.kLower  # c, new
    assert _solve(r).getInfo().objective_function_value == pytest.approx(2.0)


@pytest.mark.parametrize("seed", range(5))
def test_the_interior_point_model_solves_the_same_lp(seed):
    """``interior``: the model is for HiGHS' interior point method (no simplex step),
    no basis carried; the value is linprog's over every point, round after round."""
    rng = np.random.default_rng(70 + seed)
    inst = random_needing(rng, 12, 24, 1)
    cost = rng.uniform(0.5, 2.0, 12)
    r = bound._Restricted(inst, cost, float(cost.max()), interior=True)
    compared = 0
    for batch in np.array_split(rng.permutation(12), 3):
        r.add(batch)
        h = _solve(r)
        solver = h.getOptionValue("solver")  # (status, value) in highspy 1.15
        assert (solver[1] if isinstance(solver, tuple) else solver) == "ipm"
        assert r.basis is None
        assert h.getInfo().simplex_iteration_count == 0
        if h.getSolution().col_value[r.n_groups] < 1e-9:
            cols = np.asarray(r.columns)
            restricted = CoverInstance(inst.matrix[cols], inst.goal, need=inst.k)
            value = h.getInfo().objective_function_value
            assert value == pytest.approx(full_lp(restricted, cost[cols]), abs=1e-6)
            compared += 1
    assert compared > 0  # every column at least meets the goal


@pytest.mark.parametrize("few", [True, False])
def test_the_paying_candidates_cover_the_sum_of_their_entries(few):
    """``DualPolish._covered``: what the candidates that pay cover, each point the sum
    of their entries (1, 2 or 3, float32 as the matrix holds them), in float64, the
    same by their rows alone (few pay: 2 of 60) and by M^T over all (most pay),
    against the dense sum."""
    rng = np.random.default_rng(5)
    inst = random_instance(rng, n_cand=60, n_points=50)
    m = inst.matrix.copy()
    m.data = rng.integers(1, 4, m.nnz).astype(np.float32)
    polish = bound.DualPolish(CoverInstance(m, inst.goal), np.ones(60))
    pays = np.array([3, 17]) if few else np.arange(0, 60, 2)
    assert (len(pays) * bound.FEW_PAY < 60) == few
    got = polish._covered(pays)
    assert got.dtype == np.float64
    assert got.tolist() == m.toarray()[pays].astype(np.float64).sum(axis=0).tolist()
