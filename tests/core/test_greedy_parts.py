"""Greedy on a ground in parts (``optimize/greedy.py``): one part's candidates held at
a time, never the whole ground's; the goal met by an independent recount; a resumed
run skips the parts it finished."""

from __future__ import annotations

import gc
import math
import weakref

import numpy as np
import pytest

from autoscoop_blender.core import budget
from autoscoop_blender.core.model.sensors import PAPER_CAMERA
from autoscoop_blender.core.optimize import base as base_module
from autoscoop_blender.core.optimize import parts as parts_module
from autoscoop_blender.core.optimize.bound import parts_of
from autoscoop_blender.core.run import Run
from autoscoop_blender.core.settings import OptimizeSettings
from tests.core.flat import box_caster
from tests.core.test_parts import PART_POINTS, WALL, recount, road


@pytest.fixture(autouse=True)
def three_parts(monkeypatch):
    """Parts of ``PART_POINTS`` points (the road: 3 parts) in every test here."""
    monkeypatch.setattr(budget, "PART_POINTS", PART_POINTS)


def greedy(**kw) -> OptimizeSettings:
    return OptimizeSettings(optimizer="greedy", grid_m=2.0, position_step_m=4.0, **kw)


def test_greedy_in_parts_holds_one_part_at_a_time_and_meets_the_goal(monkeypatch):
    """Each part built once, in order, none while the one before is still held, and
    never the whole ground's candidate set; the plan covers rho of the target when
    every sensor is evaluated afresh on a grid of its own."""

    def no_whole_set(problem):
        raise AssertionError("the whole ground's candidates were built")

    monkeypatch.setattr(base_module, "build_candidates", no_whole_set)
    real = parts_module.build_part
    held: list[weakref.ref] = []
    built: list[np.ndarray] = []

    def spy(problem, points, reach_m, *shared):
        gc.collect()
        assert all(ref() is None for ref in held), "a part's candidates outlived it"
        built.append(points)
        part = yield from real(problem, points, reach_m, *shared)
        held.append(weakref.ref(part))
        return part

    monkeypatch.setattr(parts_module, "build_part", spy)
    run = Run(road(), box_caster(WALL), PAPER_CAMERA, greedy(rho=0.9))
    res = run.result()
    assert res.stop_reason.startswith("Reached the goal")
    split = parts_of(run.problem.grid.target_xy, 3)
    assert len(built) == 3
    for k, points in enumerate(built):
        np.testing.assert_array_equal(points, np.flatnonzero(split == k))
    counts = recount(road(), res)
    assert np.count_nonzero(counts >= 1) >= math.ceil(0.9 * len(counts))


def test_greedy_resumed_after_its_parts_builds_none_and_keeps_the_plan(monkeypatch):
    """Resumed from the records of a finished run in parts (each sensor as it was
    fixed), every part already meets its share: none is built, and the seams' prune
    ends with the same plan."""
    s = greedy(rho=0.9)
    records: list[dict] = []
    first = Run(road(), box_caster(WALL), PAPER_CAMERA, s, on_fixed=records.append).result()
    built = []
    real = parts_module.build_part

    def spy(problem, points, reach_m, *shared):
        built.append(points)
        return real(problem, points, reach_m, *shared)

    monkeypatch.setattr(parts_module, "build_part", spy)
    resumed = Run(road(), box_caster(WALL), PAPER_CAMERA, s, resume=records).result()
    assert built == []
    poses = [[(f.x, f.y, f.pitch_deg, f.yaw_deg) for f in r.sensors] for r in (first, resumed)]
    assert poses[0] == poses[1]
    assert resumed.stop_reason.startswith("Reached the goal")
