"""The candidate set (core.candidates), whole, on a small flat scene with one box.

Every (position, orientation) is evaluated afresh with its own ``targeted`` evaluator
on its own grid, and the candidate set must hold exactly the pairs that cover
something, each once, with exactly those points; the progress reports and the
matrix-size limit are checked against counts made here.
"""

from __future__ import annotations

import numpy as np
import pytest

from autoscoop_blender.core import budget, refusal
from autoscoop_blender.core.candidates import POSITIONS_PER_REPORT, build_candidates
from autoscoop_blender.core.coverage.targeted import TargetedEvaluator
from autoscoop_blender.core.errors import InputError
from autoscoop_blender.core.geom.grid import GroundGrid
from autoscoop_blender.core.geom.raycast import BoxCaster
from autoscoop_blender.core.model.sensors import PAPER_CAMERA
from autoscoop_blender.core.problem import Problem
from autoscoop_blender.core.settings import OptimizeSettings
from tests.core.flat import flat_scene
from tests.core.test_lp import steps

TARGET = (0.0, 0.0, 10.0, 10.0)  # 100 points at grid_m = 1
WALL = ((14.0, 3.0, 0.0), (16.0, 7.0, 5.0))  # between the sensors and the target
SETTINGS = OptimizeSettings(optimizer="greedy", grid_m=1.0, position_step_m=2.0)


def problem(sensor=(20.0, 0.0, 22.0, 2.0), settings=SETTINGS):
    scene = flat_scene(target=TARGET, sensor=sensor, boxes=[WALL])
    return Problem(scene, BoxCaster([WALL], ground_z=0.0), PAPER_CAMERA, settings)


def built(p):
    """(the candidate set, the progress reports yielded on the way)."""
    return steps(build_candidates(p))


def test_every_pose_that_covers_something_is_one_row_with_its_points():
    p = problem()
    cands, _ = built(p)
    # The lattice at 2 m in the 2 m x 2 m area: its four corners, x first.
    assert p.space.positions.tolist() == [[20, 0], [20, 2], [22, 0], [22, 2]]
    # 6 pitches over the model's limits, each with yaws 0, 10, ..., 350.
    pitches = np.linspace(PAPER_CAMERA.pitch_min_deg, PAPER_CAMERA.pitch_max_deg, 6)
    angles = [[pt, float(yaw)] for pt in pitches for yaw in range(0, 360, 10)]
    assert cands.angles[0].tolist() == angles
    caster = BoxCaster([WALL], ground_z=0.0)
    scene = flat_scene(target=TARGET, sensor=(20.0, 0.0, 22.0, 2.0), boxes=[WALL])
    fresh = TargetedEvaluator(GroundGrid(scene, caster, 1.0, reach_m=80.0), caster)
    expected = {}
    for i, (x, y) in enumerate([(20, 0), (20, 2), (22, 0), (22, 2)]):
        for o, (pt, yaw) in enumerate(angles):
            covered = np.sort(fresh.evaluate(PAPER_CAMERA, p.pose(x, y, pt, yaw)).covered)
            if len(covered):
                expected[(i, o)] = covered
    # Some orientations see the target, most do not.
    assert 50 < len(expected) < 4 * len(angles) / 2
    # A pose whose points another pose at its position covers too (more of them, or
    # as many with a lower orientation index) is left out: by plain set inclusion.
    sets = {key: set(v.tolist()) for key, v in expected.items()}

    def beaten(a, b):
        return a[0] == b[0] and (len(sets[b]), -b[1]) > (len(sets[a]), -a[1])

    dominated = {a for a in sets if any(beaten(a, b) and sets[a] <= sets[b] for b in sets)}
    # On a 10 m square most poses see part of what a few others see whole.
    assert len(expected) - len(dominated) == 4 and len(cands) == 4
    assert cands.dominated == len(dominated)
    assert cands.dominated_nonzeros == sum(len(sets[a]) for a in dominated)
    expected = {key: v for key, v in expected.items() if key not in dominated}
    got = list(zip(cands.position.tolist(), cands.orientation.tolist()))
    assert got == sorted(expected)  # each once, by position then orientation
    assert cands.model.tolist() == [0] * len(got) and cands.models == (PAPER_CAMERA,)
    assert cands.matrix.shape == (len(got), 100) and cands.matrix.dtype == np.float32
    assert len(cands) == len(got)
    for c, key in enumerate(got):
        row = cands.matrix[c]
        assert np.array_equal(row.indices, expected[key]) and set(row.data) == {1.0}
        i, o = key
        x, y = [(20, 0), (20, 2), (22, 0), (22, 2)][i]
        assert cands.pose(p, c) == p.pose(x, y, *angles[o])
    assert cands.matrix.nnz == sum(len(v) for v in expected.values())


def test_the_set_is_built_once_and_reports_progress_every_16_positions():
    # 10 m x 8 m at 1 m: 11 x 9 = 99 positions; reports at 0, 16, ..., 96.
    settings = OptimizeSettings(optimizer="greedy", grid_m=1.0, position_step_m=1.0)
    p = problem(sensor=(20.0, 0.0, 30.0, 8.0), settings=settings)
    assert len(p.space.positions) == 99 and POSITIONS_PER_REPORT == 16
    cands, reports = built(p)
    assert reports == [0, 16, 32, 48, 64, 80, 96]
    assert p.candidates is cands
    again, more = built(p)
    assert again is cands and more == []


def test_no_pose_that_covers_anything_is_an_empty_set():
    """Sensors 190 m east of the target, beyond the 80 m range."""
    cands, _ = built(problem(sensor=(200.0, 0.0, 202.0, 2.0)))
    assert len(cands) == 0 and cands.matrix.shape == (0, 100)
    assert cands.matrix.nnz == 0 and cands.matrix.dtype == np.float32
    for a in (cands.position, cands.orientation, cands.model):
        assert a.dtype == np.int64 and a.shape == (0,)


def test_the_limit_is_the_most_nonzeros_allowed(monkeypatch):
    """The whole matrix's nonzeros are allowed; one fewer stops the build after the
    last position; none stops it at the first position that covers something. (A
    build that stops keeps nothing, so one problem serves the three.)"""
    whole, _ = built(problem())
    total, first = whole.matrix.nnz, int(whole.position[0]) + 1
    p = problem()
    monkeypatch.setattr(budget, "nonzero_limit", lambda optimizer: 0)
    with pytest.raises(InputError, match=rf"after {first} of 4 mast positions, more than the 0 "):
        built(p)
    monkeypatch.setattr(budget, "nonzero_limit", lambda optimizer: total - 1)
    with pytest.raises(InputError) as err:
        built(p)
    text = str(err.value)
    assert f"after 4 of 4 mast positions, more than the {refusal.count_text(total - 1)} " in text
    assert f": {refusal.count_text(total)} after" in text
    assert "the candidate matrix at grid_m = 1 outgrew its estimate (" in text
    assert "through the greedy optimizer: raise grid_m" in text
    # The limit is the one for the problem's optimizer (greedy here).
    asked = []
    monkeypatch.setattr(budget, "nonzero_limit", lambda optimizer: asked.append(optimizer) or total)
    assert built(p)[0].matrix.nnz == total
    assert asked == ["greedy"]


def test_dominated_orientations_by_hand():
    from autoscoop_blender.core.candidates import dominated

    rows = [
        [1, 1, 0, 0, 0],  # 0: inside 2
        [0, 0, 0, 0, 0],  # 1: covers nothing: not a candidate, not dominated
        [1, 1, 1, 0, 0],  # 2: the largest of its kind
        [0, 0, 1, 1, 0],  # 3: overlaps 2, inside nothing
        [0, 0, 1, 1, 0],  # 4: equal to 3: the later one goes
        [0, 0, 0, 0, 1],  # 5: alone
    ]
    got = dominated(np.array(rows, dtype=bool))
    assert got.tolist() == [True, False, False, False, True, False]
    # More than 64 orientations (two words of bits): every one inside the last.
    many = np.zeros((70, 100), dtype=bool)
    for o in range(70):
        many[o, o : o + 3] = True
    many[69, :] = True
    assert dominated(many).tolist() == [True] * 69 + [False]
    assert not dominated(np.zeros((3, 4), dtype=bool)).any()


def test_with_k_2_dominated_candidates_stay():
    """A plan may need a pose and its dominator both when points need two sensors."""
    from dataclasses import replace

    one, _ = built(problem())
    two, _ = built(problem(settings=replace(SETTINGS, coverage_k=2)))
    assert two.dominated == 0 and len(two) == len(one) + one.dominated
    assert two.matrix.nnz == one.matrix.nnz + one.dominated_nonzeros
