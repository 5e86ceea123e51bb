"""The ES's restart toward the gaps, and its patience (core/optimize/es.py)."""

from dataclasses import replace

import numpy as np
import pytest
import shapely

from autoscoop_blender.core.model.sensors import PAPER_CAMERA
from autoscoop_blender.core.optimize.es import EvolutionStrategy
from autoscoop_blender.core.problem import Problem
from autoscoop_blender.core.run import Run
from autoscoop_blender.core.settings import ESParams, OptimizeSettings
from tests.core.flat import box_caster, open_scene

FEW = OptimizeSettings(optimizer="es", rho=0.9, es=ESParams(mu=4, lam=2, max_epochs=2))


def test_a_search_that_finds_nothing_restarts_where_the_gap_can_be_seen():
    """A 2 km strip of mast positions and a 10 m x 10 m target beside its far end: the
    first random parents (4 of ~1000 positions) almost surely see nothing; the restart
    aims them at positions that can see the target, and the goal is met from there."""
    target = shapely.box(1980, 5, 1990, 15)
    scene = open_scene(target, [shapely.box(0, -1, 2000, 1)])
    res = Run(scene, box_caster(), PAPER_CAMERA, FEW).result()
    assert res.metrics["coverage_fraction"] >= 0.9
    assert res.stop_reason.startswith("Reached the goal")
    for s in res.sensors:  # each stands within the camera's reach of the target
        assert target.distance(shapely.Point(s.x, s.y)) <= PAPER_CAMERA.range_m


@pytest.mark.parametrize("patience", [1, 2, 3])
def test_patience_is_the_number_of_fruitless_searches_in_a_row(monkeypatch, patience):
    """A target beyond every camera's range that the reachability probe is made to call
    visible: each search and its restart find nothing, and the run gives up after
    exactly ``patience`` of them, saying so."""
    scene = open_scene(shapely.box(500, 0, 510, 10), [shapely.box(0, -1, 10, 1)])
    settings = replace(FEW, patience=patience)
    problem_cls_reachable = Problem.reachable

    def pretends(self, pose, wanted):
        real = problem_cls_reachable(self, pose, wanted)
        assert len(real) == 0  # truly out of reach
        return np.flatnonzero(wanted)[:1]

    searches = []
    search = EvolutionStrategy._search

    def counted(self, initial):
        searches.append(initial is None)  # True: a random start; False: a restart
        return (yield from search(self, initial))

    monkeypatch.setattr(Problem, "reachable", pretends)
    monkeypatch.setattr(EvolutionStrategy, "_search", counted)
    run = Run(scene, box_caster(), PAPER_CAMERA, settings)
    for _ in run.steps():
        pass
    res = run.result()
    assert res.metrics["sensors"] == 0
    assert res.stop_reason.startswith(f"Stopped short of the goal: {patience} searches")
    assert searches == [True, False] * patience  # each: a random start, then a restart
