"""The benchmark's error measure: a method's verdict at a reference point is its grid
cell's verdict (worked by hand on two flat grids)."""

import numpy as np

from headless.bench_suite import _cell_verdicts
from tests.core.flat import flat_grid


def test_cell_verdicts_follow_the_containing_cell():
    coarse, _ = flat_grid(spacing=1.0, target=(0, 0, 4, 2), sensor=(-3, 0, -2, 1), reach=0)
    fine, _ = flat_grid(spacing=0.25, target=(0, 0, 4, 2), sensor=(-3, 0, -2, 1), reach=0)
    # Cover the coarse cell whose centre is (1.5, 0.5): the square [1, 2] x [0, 1].
    cell = np.flatnonzero(np.all(coarse.target_xy == (1.5, 0.5), axis=1))
    verdict = _cell_verdicts(coarse, cell, fine)
    xy = fine.target_xy
    inside = (xy[:, 0] > 1) & (xy[:, 0] < 2) & (xy[:, 1] > 0) & (xy[:, 1] < 1)
    assert np.array_equal(verdict, inside)
    assert verdict.sum() == 16  # 4 x 4 fine points in one coarse cell


def test_points_along_the_target_edge_take_the_nearest_cells_verdict():
    # Target x in [0, 4.4]: the coarse cells with centres 0.5 .. 3.5 hold targets, the
    # strip x in (4, 4.4) has no coarse target centre; its fine points take the verdict of x = 3.5.
    coarse, _ = flat_grid(spacing=1.0, target=(0, 0, 4.4, 1), sensor=(-3, 0, -2, 1), reach=0)
    fine, _ = flat_grid(spacing=0.25, target=(0, 0, 4.4, 1), sensor=(-3, 0, -2, 1), reach=0)
    last = np.flatnonzero(np.isclose(coarse.target_xy[:, 0], 3.5))
    verdict = _cell_verdicts(coarse, last, fine)
    assert np.array_equal(verdict, fine.target_xy[:, 0] > 3.0)
