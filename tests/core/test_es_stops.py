"""The ES's outer loop (core/optimize/es.py): its restart toward the gaps, its
patience, its stops and what it fixes, on real scenes and with scripted searches."""

from dataclasses import replace

import numpy as np
import pytest
import shapely

from autoscoop_blender.core.model.sensors import PAPER_CAMERA
from autoscoop_blender.core.optimize import es as es_module
from autoscoop_blender.core.optimize.base import FixedSensor, Solution, StopReason
from autoscoop_blender.core.optimize.es import EvolutionStrategy
from autoscoop_blender.core.problem import Problem
from autoscoop_blender.core.run import Run
from autoscoop_blender.core.settings import ESParams, OptimizeSettings
from tests.core.flat import box_caster, open_scene
from tests.core.test_lp import steps

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


# ---------------------------------------------------------------- the outer loop, scripted

# A 60 m x 10 m target 10 m north of a 60 m strip of mast positions, a 2 m grid.
STRIP = open_scene(shapely.box(0, 10, 60, 20), [shapely.box(0, -1, 60, 1)])
LEFT = (0.0, 0.0, 40.0, 90.0)  # looks north at the target's west end
RIGHT = (60.0, 0.0, 40.0, 90.0)  # and at its east end
AWAY = (30.0, 0.0, 40.0, 270.0)  # looks south: sees nothing


def _problem(**settings):
    base = OptimizeSettings(optimizer="es", rho=1.0, grid_m=2.0, patience=2, seed=5)
    return Problem(STRIP, box_caster()(), PAPER_CAMERA, replace(base, **settings))


def _script(monkeypatch, poses, gaps=lambda coarse: np.zeros((1, 4)), ref=0.0):
    """Each search returns the next of ``poses`` (x, y, pitch, yaw) as evaluated, after
    3 epochs and 7 evaluations; the restart's population is ``gaps(coarse)``; the
    reference footprint (which sets the gain below which a search restarts) ``ref``.
    Returns the log: ("search", random start?) and ("gaps", coarse) in order."""
    log, left = [], iter(poses)

    def search(self, initial):
        log.append(("search", initial is None))
        pose = self.problem.pose(*next(left))
        cov, fit = self._evaluate(pose)
        return pose, cov, fit, 3, 7
        yield  # a generator, as the real one

    def gap_population(self, coarse):
        log.append(("gaps", coarse))
        return gaps(coarse)

    monkeypatch.setattr(EvolutionStrategy, "_search", search)
    monkeypatch.setattr(EvolutionStrategy, "_gap_population", gap_population)
    monkeypatch.setattr(es_module, "reference_footprint_m2", lambda model, grid_m: ref)
    return log


def _solve(problem, solution=None):
    solution = solution or Solution(np.zeros(problem.n_targets, bool), need=problem.need)
    es = EvolutionStrategy()
    res, reports = steps(es.solve(problem, solution))
    assert res is solution  # the solution comes back, filled in
    return es, res, reports


def _evaluated(problem, pose):
    """``pose`` (x, y, pitch, yaw) evaluated as the ES does."""
    return problem.evaluate(problem.pose(*pose), problem.settings.fitness.band_m)


def _seen(problem, pose):
    return _evaluated(problem, pose).covered


def test_patience_counts_fruitless_searches_in_a_row(monkeypatch):
    """LEFT is fixed; AWAY twice (its search and the restart) is one fruitless search;
    RIGHT is fixed and starts the count again; two more fruitless ones end the run
    at patience 2 with LEFT and RIGHT."""
    problem = _problem()
    log = _script(monkeypatch, [LEFT, AWAY, AWAY, RIGHT, AWAY, AWAY, AWAY, AWAY])
    es, res, reports = _solve(problem)
    assert [(s.pose.x, s.pose.yaw_deg) for s in res.sensors] == [(0.0, 90.0), (60.0, 90.0)]
    assert res.stop_reason == StopReason.gave_up(2)
    assert [kind for kind, _ in log].count("search") == 8
    # Each sensor as found: its pose's points, its fitness, 3 epochs, 7 evaluations.
    first = res.sensors[0]
    assert set(first.seen) == set(_seen(problem, LEFT)) == set(first.newly)
    assert first.fitness > 0 and (first.epochs, first.evaluations) == (3, 7)
    assert set(res.sensors[1].newly) == set(_seen(problem, RIGHT)) - set(first.seen)
    fixed = [r for r in reports if r.phase == "fixed"]
    assert [r.fixed for r in fixed] == res.sensors and {r.rho for r in fixed} == {1.0}
    # What was spent: one evaluation per (scripted) search, and its sight rays (the
    # same evaluations in the same order on a fresh problem: a position's sight lines
    # are cast once).
    fresh = _problem()
    spent = [_evaluated(fresh, p).rays for p in (LEFT, AWAY, AWAY, RIGHT) + (AWAY,) * 4]
    assert res.evaluations == 8 and res.sight_rays == sum(spent) > spent[-1]
    # What a resumed run needs: the generator's state after the last sensor.
    assert res.state == {"rng_state": np.random.default_rng(5).bit_generator.state}


def test_the_restart_is_kept_when_it_finds_more(monkeypatch):
    """The random start finds nothing, the restart LEFT: LEFT is fixed; one sensor at
    most, so the run stops there, saying so."""
    problem = _problem(max_sensors=1)
    log = _script(monkeypatch, [AWAY, LEFT])
    _, res, _ = _solve(problem)
    assert [s.pose.x for s in res.sensors] == [0.0]
    assert res.stop_reason == StopReason.sensor_limit(1)
    assert log == [("search", True), ("gaps", True), ("search", False)]


def test_the_restart_probes_coarse_then_fine_then_gives_up(monkeypatch):
    """No coarse position sees a gap: every position is probed; none either: a search
    that found nothing ends the run (out of sight); one that found a little is
    fixed still."""
    problem = _problem(max_sensors=1)

    def fine_only(coarse):
        return None if coarse else np.zeros((1, 4))

    log = _script(monkeypatch, [AWAY, LEFT], gaps=fine_only)
    _, res, _ = _solve(problem)
    assert log == [("search", True), ("gaps", True), ("gaps", False), ("search", False)]
    assert [s.pose.x for s in res.sensors] == [0.0]
    log = _script(monkeypatch, [AWAY], gaps=lambda coarse: None)
    _, res, _ = _solve(_problem())
    assert log == [("search", True), ("gaps", True), ("gaps", False)]
    assert res.sensors == []
    assert res.stop_reason == StopReason.out_of_sight("position in the sensor areas")
    # LEFT's points are fewer than the gain asked for (a huge reference footprint),
    # no restart can be aimed: LEFT is fixed all the same.
    log = _script(monkeypatch, [LEFT], gaps=lambda coarse: None, ref=1e9)
    _, res, _ = _solve(_problem(max_sensors=1))
    assert [s.pose.x for s in res.sensors] == [0.0] and len(log) == 3


@pytest.mark.parametrize("extra, restarts", [(0, False), (1, True)])
def test_a_search_restarts_below_a_hundredth_of_the_reference_footprint(
    monkeypatch, extra, restarts
):
    """min_gain = round(0.01 x reference footprint / cell area (4 m^2)): set to LEFT's
    own count n, LEFT is enough; at n + 1 the search restarts."""
    problem = _problem(max_sensors=1)
    n = len(_seen(problem, LEFT))
    assert problem.grid.cell_area == 4.0 and n > 10
    log = _script(monkeypatch, [LEFT, LEFT], ref=(n + extra) * 4.0 / 0.01)
    _solve(problem)
    assert (("gaps", True) in log) == restarts


def test_at_k2_a_point_seen_once_is_still_wanted(monkeypatch):
    """Every point needed twice: LEFT a second time adds its points again, and is
    fixed (at k = 1 it would add nothing)."""
    problem = _problem(coverage_k=2, max_sensors=2)
    _script(monkeypatch, [LEFT, LEFT])
    _, res, _ = _solve(problem)
    assert [s.pose.x for s in res.sensors] == [0.0, 0.0]
    assert set(res.sensors[1].newly) == set(_seen(problem, LEFT))


def test_a_resumed_run_starts_from_the_sensors_and_the_state_it_was_given(monkeypatch):
    """A sensor that stood already is marked with all it sees (not just its new
    points); the generator goes on from the state saved. The goal is met: no search."""
    problem = _problem(rho=0.01)
    seen = _seen(problem, LEFT)
    start = Solution(np.zeros(problem.n_targets, bool), need=problem.need)
    start.fix(FixedSensor(problem.pose(*LEFT), 1.0, 0, 0, seen[:2], seen))
    start.state = {"rng_state": np.random.default_rng(99).bit_generator.state}
    log = _script(monkeypatch, [])
    es, res, _ = _solve(problem, start)
    assert log == [] and res.stop_reason == StopReason.reached(0.01)
    assert np.flatnonzero(es.fixed.counts).tolist() == sorted(seen.tolist())
    assert es.fixed.positions == [(0.0, 0.0)]
    assert len(es.log) == 1 and es.log[0][0] is seen and es.log[0][1] == (0.0, 0.0)
    assert es.rng.bit_generator.state == start.state["rng_state"]
    # A sensor with no ``seen`` is marked with its new points.
    start = Solution(np.zeros(problem.n_targets, bool), need=problem.need)
    start.fix(FixedSensor(problem.pose(*LEFT), 1.0, 0, 0, seen[:2]))
    es, _, _ = _solve(problem, start)
    assert np.flatnonzero(es.fixed.counts).tolist() == sorted(seen[:2].tolist())


def test_the_search_reports_each_evaluation(monkeypatch):
    """A real search (4 parents, 2 offspring, at most 2 epochs): a "search" report per
    evaluation, its epoch rising from 0, then one "fixed" per sensor; all at rho."""
    problem = _problem(max_sensors=1, es=ESParams(mu=4, lam=2, max_epochs=2))
    _, res, reports = _solve(problem)
    search = [r for r in reports if r.phase == "search"]
    assert [r.phase for r in reports[len(search) :]] == ["fixed"]
    assert {r.rho for r in reports} == {1.0}
    epochs = [r.epoch for r in search]
    assert epochs[:4] == [0] * 4 and epochs == sorted(epochs) and epochs[-1] >= 1
    assert len(search) == res.evaluations - 1  # and the winner evaluated once more


def test_an_optimizer_holds_its_pool_until_closed():
    class Pool:
        workers, shut = 2, 0

        def shutdown(self):
            self.shut += 1

    pool = Pool()
    es = EvolutionStrategy(pool)
    assert es.pool is pool
    es.close()
    es.close()
    assert es.pool is None and pool.shut == 1
