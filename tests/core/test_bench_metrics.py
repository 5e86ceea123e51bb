"""The benchmark's error measure: a method's verdict at a reference point is its grid
cell's verdict (worked by hand on two flat grids)."""

import json

import numpy as np

from tests.core.flat import flat_grid
from tools.suite import _cell_verdicts, paper_figures


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


def test_an_unfinished_paper_run_reports_what_its_checkpoint_holds(tmp_path):
    header = {"scene_fingerprint": "f", "model": {}, "settings": {}}
    records = [
        {"n": 1, "coverage": 0.05, "wall_s": 160.0, "rays_cast": 27_000_000},
        {"n": 2, "coverage": 0.08, "wall_s": 400.0, "rays_cast": 55_000_000},
    ]
    lines = [json.dumps(r) for r in (header, *records)]
    (tmp_path / "checkpoint.jsonl").write_text("\n".join(lines) + "\n")
    fig = paper_figures(tmp_path)
    assert fig["paper_complete"] is False and fig["paper_masts"] is None
    assert (fig["paper_sensors"], fig["paper_coverage"]) == (2, 0.08)
    assert (fig["paper_wall_s"], fig["paper_rays_cast"]) == (400.0, 55_000_000)
    assert "missing" in paper_figures(tmp_path / "none")["paper_source"]
