"""The evolution strategy: saturation at the borders, and it finds optima."""

import numpy as np
import pytest
import shapely

from autoscoop_blender.core.optimize.es import SensorSearch, mutate, sample
from autoscoop_blender.core.problem import SearchSpace
from autoscoop_blender.core.settings import ESParams

AREAS = [shapely.box(0, 0, 10, 4), shapely.Polygon([(20, 0), (30, 0), (25, 8)])]


def test_lattice_and_tiny_areas():
    space = SearchSpace([*AREAS, shapely.box(50.2, 50.2, 50.6, 50.6)], 1.0, 31, 70)
    inside = shapely.union_all(AREAS + [shapely.box(50.2, 50.2, 50.6, 50.6)])
    assert shapely.intersects_xy(inside, *space.positions.T).all()
    # An area smaller than the lattice still gets one position (its inner point).
    assert ((space.positions[:, 0] > 50) & (space.positions[:, 0] < 51)).sum() == 1
    # Lattice points: 11 x 5 in the box; in the triangle, by Pick's theorem
    # (area 40, 12 on the boundary): 35 inside + 12 = 47; plus the tiny area's one.
    assert len(space.positions) == 55 + 47 + 1


def test_mutation_stays_inside_and_within_limits():
    space = SearchSpace(AREAS, 1.0, 31.0, 70.0)
    rng = np.random.default_rng(0)
    pop = sample(space, 200, rng)
    union = shapely.union_all(AREAS)
    for _ in range(5):
        pop = mutate(space, pop, np.array([30.0, 30.0, 40.0, 90.0]), 5, rng)
        assert shapely.intersects_xy(union, pop[:, 0], pop[:, 1]).all()
        assert (pop[:, 2] >= 31.0).all() and (pop[:, 2] <= 70.0).all()
        assert (pop[:, 3] >= 0.0).all() and (pop[:, 3] < 360.0).all()
    # Positions stay on the lattice.
    assert np.array_equal(pop[:, :2], np.round(pop[:, :2]))


def _search(seed, target=(25.0, 5.0, 50.0, 120.0)):
    space = SearchSpace(AREAS, 1.0, 31.0, 70.0)
    t = np.array(target)

    def f(ind):  # a smooth hill with its top at ``target`` (yaw on the circle)
        dyaw = (ind[3] - t[3] + 180) % 360 - 180
        return 100.0 * np.exp(-np.sum(((ind[:3] - t[:3]) / [5, 5, 10]) ** 2) - (dyaw / 60) ** 2)

    search = SensorSearch(space, ESParams(), np.random.default_rng(seed), lambda pop: map(f, pop))
    for _ in search.steps():
        pass
    return search


def test_finds_the_top_of_a_hill_and_is_deterministic():
    a, b = _search(3), _search(3)
    assert np.array_equal(a.best, b.best) and a.epochs == b.epochs
    assert a.best_fitness > 90.0
    assert a.best[:2] == pytest.approx([25.0, 5.0], abs=1.0)
    assert 1 <= a.epochs <= ESParams().max_epochs
    # Paper's population sizes: mu initial evaluations, then mu + lambda per epoch.
    assert a.evaluations == 40 + 60 * a.epochs


def test_convergence_rule():
    s = SensorSearch(SearchSpace(AREAS, 1.0, 31, 70), ESParams(eps=0.2), None, None)
    assert s.converged(np.array([10.0, 9.0, 8.1]))
    assert not s.converged(np.array([10.0, 9.0, 7.9]))
    assert s.converged(np.zeros(3))
