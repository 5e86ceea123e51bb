"""The lp optimizer's part builds on Ray (``headless/ray_engine.py``) against the same
run built here (``parts.LocalBuilder``): the same candidates part by part, the same
plan, on a local 2-CPU Ray that the builder starts and shuts down itself.

Ray is an optional extra: these tests are skipped where it is not installed
(``./dev.sh test`` installs ``requirements-ray.txt`` into the Python 3.11 venv).
"""

from __future__ import annotations

import importlib.util
import signal
import subprocess
import sys
from dataclasses import replace

import numpy as np
import pytest
import shapely

from autoscoop_blender.core import budget
from autoscoop_blender.core.candidates import PartCandidates
from autoscoop_blender.core.errors import InputError
from autoscoop_blender.core.model.scene import Area, SceneModel
from autoscoop_blender.core.model.sensors import PAPER_CAMERA
from autoscoop_blender.core.optimize.parts import LocalBuilder
from autoscoop_blender.core.run import Run
from autoscoop_blender.core.settings import OptimizeSettings
from autoscoop_blender.scene.factory import BVHFactory
from headless import ray_engine
from tests.conftest import ROOT
from tests.core.flat import box_mesh
from tests.core.test_lp import drain
from tools.build_extension import pinned_versions

HAS_RAY = importlib.util.find_spec("ray") is not None
needs_ray = pytest.mark.skipif(
    not HAS_RAY, reason="Ray is not installed (pip install -r requirements-ray.txt)"
)

# tests/core/test_parts.py's road (240 m, 600 target points at 2 m, three parts of
# 200), on a ground slab, with the wall that hides a stretch of it: the BVHTree caster,
# built in each Ray worker from the scene's triangles as in a real run.
ROAD = shapely.box(0, -5, 240, 5)
STRIP = shapely.box(0, 8, 240, 12)
BOXES = [((-20.0, -40.0, -1.0), (260.0, 40.0, 0.0)), ((110.0, 6.0, 0.0), (130.0, 7.0, 8.0))]
PART_POINTS = 200


def road() -> SceneModel:
    vertices, faces = box_mesh(BOXES)
    return SceneModel(
        vertices=vertices,
        faces=faces,
        occluders=("Ground", "Wall"),
        targets=(Area("Road", ROAD),),
        sensor_areas=(Area("Strip", STRIP),),
    )


def settings() -> OptimizeSettings:
    return OptimizeSettings(optimizer="lp", grid_m=2.0, position_step_m=4.0, rho=0.9)


class Recorded:
    """A builder's parts as the planner took them, and the most it had out at once."""

    def __init__(self) -> None:
        self.parts: dict[int, PartCandidates] = {}
        self.most_out = 0


def recording(base: type) -> tuple[type, Recorded]:
    """A subclass of the builder class ``base`` that records what it hands out."""
    seen = Recorded()

    class Recording(base):  # type: ignore[valid-type, misc]
        def build(self, k):
            part = yield from super().build(k)
            seen.parts[k] = part
            return part

        def _submit(self) -> None:  # RayBuilder's: the parts out, counted after each
            super()._submit()
            seen.most_out = max(seen.most_out, len(self.submitted))

    return Recording, seen


def same_part(a: PartCandidates, b: PartCandidates) -> None:
    """Every array of the two parts' candidates equal, the matrices entry for entry."""
    for name in ("positions", "position", "orientation", "model"):
        np.testing.assert_array_equal(getattr(a.cands, name), getattr(b.cands, name))
    for x, y in zip(a.cands.angles, b.cands.angles, strict=True):
        np.testing.assert_array_equal(x, y)
    assert a.cands.models == b.cands.models
    ma, mb = a.cands.matrix, b.cands.matrix
    assert ma.shape == mb.shape
    for name in ("data", "indices", "indptr"):
        np.testing.assert_array_equal(getattr(ma, name), getattr(mb, name))
    for name in ("share", "sites", "site_share"):
        np.testing.assert_array_equal(getattr(a, name), getattr(b, name))


@needs_ray
def test_ray_builds_the_same_parts_and_the_plan_is_the_same(monkeypatch):
    """One local 2-CPU Ray, started by a first builder (``first``), for all of it:

    - ``first`` builds the parts asked for as they are built here, whichever are
      skipped: none before the first asked for is built, one skipped after it is
      built and dropped;
    - the road planned in 3 parts with its parts built here and by a second builder
      on that Ray (``second``, which did not start it): each part's candidates equal
      array for array, the same plan sensor for sensor and the same bound; no more
      than workers + 1 parts out at once;
    - ``second``'s close() leaves the Ray running, ``first``'s shuts it down; the
      process's SIGTERM handler is its own again (``ray.init`` sets one).
    """
    import ray

    from autoscoop_blender.core.candidates import build_part
    from autoscoop_blender.core.optimize.bound import parts_of
    from autoscoop_blender.core.problem import Problem

    monkeypatch.delenv("RAY_ADDRESS", raising=False)  # a local Ray, whatever the shell says
    # Only the driver splits the ground: the actors are given each part's points.
    monkeypatch.setattr(budget, "PART_POINTS", PART_POINTS)
    scene = road()
    factory = BVHFactory.of(scene)
    local_cls, local = recording(LocalBuilder)
    here = Run(scene, factory, PAPER_CAMERA, settings(), part_builder=local_cls()).result()
    assert "3 parts" in here.metrics["bound_scope"]

    def mine(signum, frame):  # a handler of the process's own, as the command line has
        raise KeyboardInterrupt

    before = signal.signal(signal.SIGTERM, mine)
    first = ray_engine.RayBuilder(factory, workers=2)
    try:
        problem = Problem(scene, factory(), PAPER_CAMERA, settings())
        split = parts_of(problem.grid.target_xy, 4)
        parts = [np.flatnonzero(split == k) for k in range(4)]
        first.start(problem, parts, PAPER_CAMERA.range_m)
        assert first.started_ray and first.connected
        assert signal.getsignal(signal.SIGTERM) is mine
        for k in (1, 3):
            same_part(
                drain(first.build(k)), drain(build_part(problem, parts[k], PAPER_CAMERA.range_m))
            )
        assert sorted(first.build_s) == [1, 2, 3]  # 0 never built, 2 built and dropped
        first.end_actors()  # their CPUs for the second builder's actors; the Ray stays

        ray_cls, remote = recording(ray_engine.RayBuilder)
        second = ray_cls(factory, workers=2)
        there = Run(scene, factory, PAPER_CAMERA, settings(), part_builder=second).result()
        assert not second.connected and not second.actors and ray.is_initialized()
        second.close()  # again: nothing happens
    finally:
        first.close()
        first.close()
        signal.signal(signal.SIGTERM, before)
    assert not ray.is_initialized()
    assert sorted(remote.parts) == sorted(local.parts) == [0, 1, 2]
    for k in local.parts:
        same_part(remote.parts[k], local.parts[k])
    assert 1 <= remote.most_out <= 2 + 1
    assert sorted(second.build_s) == [0, 1, 2]

    def poses(result):
        return [(s.x, s.y, s.z, s.pitch_deg, s.yaw_deg, s.model) for s in result.sensors]

    assert poses(there) == poses(here) and len(poses(here)) > 0
    for key in ("sensors", "masts", "cost", "lower_bound", "sensors_lower_bound"):
        assert there.metrics[key] == here.metrics[key], key
    np.testing.assert_array_equal(there.n_covered, here.n_covered)


def test_a_workers_refusal_reaches_the_driver_as_it_is():
    """A problem an actor cannot build (here: settings its own Problem refuses) makes
    each of its builds raise that InputError, which Ray passes on to the driver."""
    spec = ray_engine.ProblemSpec(
        road(), BVHFactory.of(road()), PAPER_CAMERA, settings(), np.zeros((0, 2))
    )
    worker = ray_engine.PartWorker(replace(spec, settings=replace(spec.settings, grid_m=-1.0)))
    with pytest.raises(InputError):
        worker.build(np.arange(10), 80.0)
    ok = ray_engine.PartWorker(spec)
    part, seconds, cpu_s = ok.build(np.arange(50), PAPER_CAMERA.range_m)
    assert part.cands.matrix.shape[1] == 50 and seconds >= 0 and cpu_s >= 0


def test_without_ray_the_engine_says_how_to_get_it(monkeypatch):
    """No Ray installed: one line that names the requirements file, before any work."""
    real = importlib.util.find_spec
    monkeypatch.setattr(
        importlib.util, "find_spec", lambda name, *a: None if name == "ray" else real(name, *a)
    )
    with pytest.raises(InputError) as e:
        ray_engine.RayBuilder(BVHFactory.of(road()), workers=2)
    assert str(e.value) == "--engine ray needs Ray: pip install -r requirements-ray.txt"
    assert "\n" not in str(e.value)


def test_the_add_on_neither_ships_nor_imports_ray():
    """Ray is not among the wheels the extension bundles, and loading the add-on's
    code (core and the lp planner with its part builders) imports no ray."""
    assert "ray" not in pinned_versions()
    code = (
        "import sys, autoscoop_blender, autoscoop_blender.core.run, "
        "autoscoop_blender.core.optimize.parts; sys.exit('ray' in sys.modules)"
    )
    subprocess.run([sys.executable, "-c", code], cwd=ROOT, check=True)
