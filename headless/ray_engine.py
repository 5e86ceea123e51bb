"""The lp optimizer's part builds on Ray, for grounds that outgrow one machine.

A ground planned in parts (``core/optimize/parts.py``) has each part's candidates built
by ``candidates.build_part``: ray casting through the BVHTree, the heavy work. Here a
``RayBuilder`` (a ``parts.PartBuilder``) has them built by Ray actors instead:

- each actor builds the run's ``Problem`` once, from a picklable ``ProblemSpec`` taken
  from the driver's (the scene's arrays, the caster factory, the models, the settings,
  the standing masts), and then builds any number of parts on it: the grid and the
  BVHTree are built once per worker, not once per part;
- ``ray.util.ActorPool`` hands each part to whichever actor is free, and gives the
  results back in the order the parts were submitted: Ray does the scheduling;
- at most ``workers + 1`` parts are submitted and not yet taken by the planner, so
  the object store (and the driver) never hold every part's matrix at once; a part
  is fetched when the planner asks for it, and released by it before the next;
- ``Problem`` is deterministic and ``build_part`` exact, so every part's candidates
  are the ones ``parts.LocalBuilder`` builds, and the plan is the same.

Ray is an optional extra (``requirements-ray.txt``): the add-on neither ships nor
imports it, and this module imports it only when a builder starts.

Connecting: ``address`` (else ``RAY_ADDRESS``) names a running cluster, which runs on
at the end (this process disconnects); without one a local Ray with ``workers`` CPUs
is started and shut down at the end. Checked by hand against a cluster of ``ray start
--head`` on this machine: the same plan, the code shipped, the cluster left running. The cluster's nodes need this project's Python packages (bpy 5.0.1
and requirements.txt); its own code (``autoscoop_blender``, ``headless``) is sent with
the job (Ray's ``py_modules``).

Interrupts: Ray starts its processes with SIGINT blocked (a Ctrl-C reaches the driver
only), and the builder never waits longer than ``POLL_S`` without yielding. ``close``
kills the actors without waiting for their work and shuts a local Ray down (1.5 s
measured on the loaded 2-core machine, actors busy); a SIGTERM or Ctrl-C during the
builds ended the run with exit 130 in 2.8 and 3.2 s, nothing of Ray left. A driver
killed outright (SIGKILL; the CLI's watchdog's ``os._exit`` when the run overstays its
grace) takes the local Ray's raylet, GCS and workers with it, but Ray's dashboard and
runtime-env agents were seen to stay. ``ray.init`` installs a SIGTERM handler of its
own; the driver's handlers are put back at once, so that ``headless/interrupts.py``
still decides what a SIGTERM does, and a SIGTERM while Ray starts is an interrupt.
"""

from __future__ import annotations

import collections
import importlib
import importlib.util
import logging
import os
import signal
import time
from collections.abc import Generator
from dataclasses import dataclass, replace
from typing import Any

import numpy as np
from numpy.typing import NDArray

from autoscoop_blender.core.candidates import PartCandidates, build_part
from autoscoop_blender.core.errors import AutoscoopError, InputError
from autoscoop_blender.core.model.scene import SceneModel
from autoscoop_blender.core.model.sensors import SensorModel, SensorPack
from autoscoop_blender.core.problem import Problem
from autoscoop_blender.core.run import CasterFactory
from autoscoop_blender.core.settings import OptimizeSettings
from headless.paths import REPO

log = logging.getLogger(__name__)

F64 = NDArray[np.float64]
I64 = NDArray[np.int64]

NEEDS_RAY = "--engine ray needs Ray: pip install -r requirements-ray.txt"
# The longest the builder waits for a part without yielding: the caller's progress
# and its interrupt checks stay that close.
POLL_S = 0.2
# The signals whose handlers ``ray.init`` may replace (``headless/interrupts.py``
# owns them on the command line).
_SIGNALS = tuple(
    getattr(signal, name) for name in ("SIGINT", "SIGTERM", "SIGHUP") if hasattr(signal, name)
)


def ray_module() -> Any:
    """The ``ray`` module; InputError ``NEEDS_RAY`` when it is not installed."""
    if importlib.util.find_spec("ray") is None:
        raise InputError(NEEDS_RAY)
    return importlib.import_module("ray")


@dataclass(frozen=True)
class ProblemSpec:
    """What a ``Problem`` is built from, picklable, to build the same one elsewhere.

    scene: local metres; make_caster: the caster factory (``BVHFactory``: the
    occluders' triangles); model: the model or the pack, as the problem holds it
    (``min_density_per_m2`` applied, which applies again unchanged); settings:
    validated; standing: (M, 2) local metres, the sites where masts stand.
    """

    scene: SceneModel
    make_caster: CasterFactory
    model: SensorModel | SensorPack
    settings: OptimizeSettings
    standing: F64

    @classmethod
    def of(cls, problem: Problem, make_caster: CasterFactory) -> ProblemSpec:
        """The spec of ``problem``, built with ``make_caster``'s caster."""
        space = problem.space
        standing = space.positions[space.standing]
        return cls(problem.scene, make_caster, problem.pack, problem.settings, standing)

    def problem(self) -> Problem:
        """A new Problem equal to the one the spec was taken from (the estimate is
        made for one process: the ES's workers do not come into the lp's)."""
        return Problem(self.scene, self.make_caster(), self.model, self.settings, 1, self.standing)


def _drain(gen: Generator[Any, None, Any]) -> Any:
    """The return value of a generator run to its end."""
    while True:
        try:
            next(gen)
        except StopIteration as done:
            return done.value


class PartWorker:
    """A Ray actor's state: one Problem, built when the actor starts, and the parts
    built on it. An error the problem raises (a refusal of its estimate, say) is kept
    and raised by each build, so it reaches the driver as the task's error."""

    def __init__(self, spec: ProblemSpec) -> None:
        t0 = time.perf_counter()
        self.problem: Problem | None = None
        self.error: AutoscoopError | None = None
        try:
            self.problem = spec.problem()
        except AutoscoopError as e:
            self.error = e
        self.load_s = time.perf_counter() - t0

    def loaded(self) -> float:
        """Seconds the problem took to build."""
        return self.load_s

    def build(self, points: I64, reach_m: float) -> tuple[PartCandidates, float, float]:
        """The part's candidates (``candidates.build_part``), the seconds they took and
        the CPU seconds (less than the seconds where the worker shares its CPU)."""
        if self.error is not None:
            raise self.error
        assert self.problem is not None
        t0, cpu0 = time.perf_counter(), time.process_time()
        part = _drain(build_part(self.problem, points, reach_m))
        return part, time.perf_counter() - t0, time.process_time() - cpu0


def _writable(part: PartCandidates) -> PartCandidates:
    """``part`` with arrays of its own. Ray hands large arrays back as read-only views
    of its shared-memory object store; the planner's code may change an array in
    place, and a copy lets the store free the object as soon as it is taken."""

    def own(a: Any) -> Any:
        return a if a.flags.writeable else a.copy()

    c = part.cands
    matrix = c.matrix
    matrix.data, matrix.indices, matrix.indptr = (
        own(matrix.data),
        own(matrix.indices),
        own(matrix.indptr),
    )
    cands = replace(
        c,
        positions=own(c.positions),
        angles=tuple(own(a) for a in c.angles),
        position=own(c.position),
        orientation=own(c.orientation),
        model=own(c.model),
    )
    return replace(
        part,
        cands=cands,
        share=own(part.share),
        sites=own(part.sites),
        site_share=own(part.site_share),
    )


class RayBuilder:
    """A ``parts.PartBuilder`` whose parts are built by Ray actors (module docstring).

    make_caster: the run's caster factory (picklable: ``BVHFactory``); workers: actors,
    one CPU each (None: the local Ray's CPUs, or the cluster's); address: a running
    Ray cluster to use (None: ``RAY_ADDRESS``, else a local Ray is started).
    InputError ``NEEDS_RAY`` at once when Ray is not installed.

    ``build_s`` and ``build_cpu_s`` (part -> seconds, CPU seconds an actor took to
    build it) and ``load_s`` (each actor's seconds to build its problem) are there for
    benchmarks.
    """

    def __init__(
        self, make_caster: CasterFactory, workers: int | None = None, address: str | None = None
    ) -> None:
        ray_module()
        if workers is not None and workers < 1:
            raise InputError(f"--workers {workers}: must be at least 1")
        self.make_caster = make_caster
        self.workers = workers
        self.address = address or os.environ.get("RAY_ADDRESS") or None
        self.started_ray = False  # whether this builder started the local Ray it uses
        self.connected = False  # whether this builder called ray.init (start or connect)
        self.actors: list[Any] = []
        self.pool: Any = None
        self.parts: list[I64] = []
        self.reach_m = 0.0
        self.next_part: int | None = None  # the next part to submit
        self.submitted: collections.deque[int] = collections.deque()  # not yet taken
        self.build_s: dict[int, float] = {}
        self.build_cpu_s: dict[int, float] = {}
        self.load_s: list[float] = []

    @property
    def window(self) -> int:
        """Parts submitted and not yet taken, at most: one for each actor to work on
        while the planner solves, and the next in line."""
        return len(self.actors) + 1

    def start(self, problem: Problem, parts: list[I64], reach_m: float) -> None:
        """Start Ray (or connect) and the actors, which begin building their problem;
        the parts are submitted from the first one the planner asks for (a resumed
        run skips the parts it finished)."""
        ray = ray_module()
        from ray.util.actor_pool import ActorPool

        self.parts, self.reach_m = parts, reach_m
        self._connect(ray)
        cpus = int(ray.cluster_resources().get("CPU", 1))
        n = self.workers or cpus
        if n > cpus:
            # An actor that never gets a CPU would hold its parts for ever.
            log.warning("%d Ray workers asked for, the cluster has %d CPUs: %d", n, cpus, cpus)
            n = max(cpus, 1)
        spec = ray.put(ProblemSpec.of(problem, self.make_caster))
        actor = ray.remote(num_cpus=1, max_restarts=0)(PartWorker)
        self.actors = [actor.remote(spec) for _ in range(n)]
        self.pool = ActorPool(self.actors)

    def _connect(self, ray: Any) -> None:
        """``ray.init``: to the cluster at ``address``, else a new local Ray; nothing
        when Ray is up already in this process (a test's, a notebook's)."""
        if ray.is_initialized():
            return
        from ray.job_config import JobConfig

        kw: dict[str, Any] = {"logging_level": logging.ERROR, "log_to_driver": False}
        if self.address is None:
            # The workers import the project from this checkout, wherever the
            # command was started.
            kw.update(address="local", num_cpus=self.workers or os.cpu_count() or 1)
            kw.update(include_dashboard=False, job_config=JobConfig(code_search_path=[str(REPO)]))
        else:
            # The project's own code goes with the job, so a cluster's nodes need only
            # its dependencies installed.
            modules = [importlib.import_module(m) for m in ("autoscoop_blender", "headless")]
            kw.update(address=self.address, runtime_env={"py_modules": modules})
        saved = {s: signal.getsignal(s) for s in _SIGNALS}
        # Set first: a local Ray interrupted while it starts is shut down by close().
        self.started_ray, self.connected = self.address is None, True
        try:
            ray.init(**kw)
        except SystemExit:
            # Ray's own SIGTERM handler, in force while it starts: an interrupt.
            raise KeyboardInterrupt from None
        except (ConnectionError, ValueError, RuntimeError) as e:
            where = f"the Ray cluster at {self.address}" if self.address else "a local Ray"
            raise InputError(f"--engine ray: cannot start or reach {where} ({e})") from None
        finally:
            for s, handler in saved.items():
                if handler is not None:
                    signal.signal(s, handler)

    def build(self, k: int) -> Generator[int, None, PartCandidates]:
        """Part k's candidates, built by an actor; yields k every ``POLL_S`` while they
        are not there. A part submitted that the planner skipped is dropped."""
        ray = ray_module()
        if self.next_part is None:
            self.next_part = k
        if k < self.next_part and k not in self.submitted:
            raise ValueError(f"part {k} was asked for after the parts after it")
        while True:
            self._submit()
            j = self.submitted[0]
            try:
                part, seconds, cpu_s = self.pool.get_next(timeout=POLL_S)
            except TimeoutError:
                yield k
                continue
            except ray.exceptions.RayTaskError as e:
                if isinstance(e.cause, AutoscoopError):
                    raise e.cause from None
                raise
            except ray.exceptions.RayError as e:  # an actor or its node gone, memory
                raise AutoscoopError(
                    f"--engine ray: part {j + 1} was lost while it was built "
                    f"({type(e).__name__}; the worker's log is in Ray's session folder)"
                ) from None
            self.submitted.popleft()
            self.build_s[j], self.build_cpu_s[j] = seconds, cpu_s
            if j == k:
                return _writable(part)
            log.debug("part %d was built and not asked for: dropped", j + 1)

    def _submit(self) -> None:
        """Submit parts in order until ``window`` are out."""
        assert self.next_part is not None
        while self.next_part < len(self.parts) and len(self.submitted) < self.window:
            k = self.next_part
            self.pool.submit(lambda a, p: a.build.remote(p, self.reach_m), self.parts[k])
            self.submitted.append(k)
            self.next_part += 1

    def actor_load_s(self) -> list[float]:
        """Each actor's seconds to build its problem (waits for them: benchmarks)."""
        ray = ray_module()
        if not self.load_s and self.actors:
            self.load_s = ray.get([a.loaded.remote() for a in self.actors])
        return self.load_s

    def end_actors(self) -> None:
        """Kill the actors: their work in progress is dropped, nothing is waited for,
        and their CPUs are free for others at once."""
        if self.actors:
            ray = importlib.import_module("ray")
            for a in self.actors:
                try:
                    ray.kill(a, no_restart=True)
                except Exception:  # already gone with its node: nothing to end
                    pass
        self.actors, self.pool = [], None
        self.submitted.clear()

    def close(self) -> None:
        """End the actors and shut down a local Ray this builder started; from a
        cluster it connected to this process disconnects, and the cluster runs on; a
        Ray someone else started or connected to is left as it is. Safe to call
        twice."""
        self.end_actors()
        if self.connected:
            self.started_ray = self.connected = False
            importlib.import_module("ray").shutdown()
