"""Worker processes that score ES populations: built from arrays, not from a run.

Each worker gets the problem's grid as arrays (``Problem.worker_inputs``), the model,
the settings and a caster factory (a picklable callable that builds the ray caster in
the worker, since a BVHTree does not pickle), through a file the pool writes once
(``WorkerPool``). It rebuilds the grid and the coverage
evaluator from them, keeps the fitness state of the sensors fixed so far, and scores
poses the main process has already placed on the ground. Scoring is exact, so the
answer is the same with 1 or N workers.

One executor per worker, so the main process knows which worker holds which fixed
sensors: each is sent only the sensors fixed since its last chunk.
"""

from __future__ import annotations

import multiprocessing
import multiprocessing.connection
import os
import pickle
import signal
import tempfile
import threading
from collections.abc import Callable, Iterator, Sequence
from concurrent.futures import Future, ProcessPoolExecutor
from contextlib import contextmanager
from dataclasses import dataclass
from pathlib import Path

import numpy as np
from numpy.typing import NDArray

from ..coverage.evaluator import Evaluator, make_evaluator
from ..geom.grid import GroundGrid
from ..geom.raycast import RayCaster
from ..model.sensors import SensorModel, SensorPose
from ..problem import WorkerInputs, point_need
from ..settings import FitnessParams
from .fitness import FixedSensors, fitness

# A fixed sensor as workers are told of it: the target ordinals it covers and its mast
# position (local x, y).
FixedMark = tuple[NDArray[np.int64], tuple[float, float]]


@dataclass
class _Worker:
    """A worker process's state: its grid, evaluator and the fitness state."""

    grid: GroundGrid
    evaluator: Evaluator
    model: SensorModel
    params: FitnessParams
    fixed: FixedSensors


_WORKER: _Worker | None = None


def _die_with_parent(inputs_file: Path) -> None:
    """End this worker as soon as the process that started it is gone, even when it was
    killed (SIGKILL runs no clean-up, and the executor would wait for work forever);
    remove the pool's ``inputs_file`` first, which that process could not."""
    parent = multiprocessing.parent_process()
    if parent is None:
        return

    def watch() -> None:
        multiprocessing.connection.wait([parent.sentinel])
        inputs_file.unlink(missing_ok=True)
        os._exit(1)

    threading.Thread(target=watch, name="autoscoop-parent-watch", daemon=True).start()


def _start(inputs_file: str) -> None:
    """A worker's start: its state from the pickled (WorkerInputs, caster factory)."""
    global _WORKER
    _die_with_parent(Path(inputs_file))
    _after_spawn()
    with open(inputs_file, "rb") as f:
        inputs, make_caster = pickle.load(f)
    caster = make_caster()
    grid = GroundGrid.from_arrays(inputs.grid, caster)
    evaluator = make_evaluator(inputs.settings, grid, caster, inputs.settings.cache)
    need = point_need(grid, inputs.settings.coverage_k)
    fixed = FixedSensors(np.zeros(grid.n_targets, dtype=bool), need=need)
    _WORKER = _Worker(grid, evaluator, inputs.model, inputs.settings.fitness, fixed)


def _score(poses: Sequence[SensorPose], fixed_since: list[FixedMark]) -> tuple[list[float], int]:
    """f_s of each pose once the sensors fixed since the last chunk are marked; and
    the sight rays cast."""
    w = _WORKER
    assert w is not None
    for seen, position in fixed_since:
        w.fixed.mark(seen, position)
    fits, rays = [], 0
    for pose in poses:
        cov = w.evaluator.evaluate(w.model, pose, outside_band_m=w.params.band_m)
        rays += cov.rays
        fits.append(fitness(w.grid, cov, w.fixed, w.params).f_s)
    return fits, rays


def _started() -> None:
    """A first task: it makes an executor spawn its process."""


# Ctrl-C in a terminal goes to every process of the group, SIGTERM from ``timeout`` too.
_INTERRUPTS = (signal.SIGINT, signal.SIGTERM)


@contextmanager
def _spawning() -> Iterator[None]:
    """Start worker processes in this block: they come up deaf to Ctrl-C and SIGTERM
    until they have read what the pipe brings them (``_after_spawn``), and this process
    acts on either only at the end of the block.

    A spawned process is sent its start-up data through a pipe by the main thread,
    which keeps the pipe's reading end open itself: a child ended by an interrupt before
    it has read everything would leave a long write blocked for ever. So the interrupts
    are blocked in this thread while the children are made: a child inherits the
    blocked mask through its exec, and the new interpreter leaves it so. This process
    still gets them through its other threads, and Python runs its handlers in the main
    thread whichever thread took the signal: an exception raised there while a child is
    being sent its data closes the pipe half-written, and the child dies on an
    ``EOFError`` traceback (CI, 2026-11-28). So in the block the handlers only note
    the signals, and the process's own handlers run after it. The block is short: the
    pipe brings a file name (``WorkerPool``). Only POSIX can block signals, and only
    the main thread sets handlers: elsewhere this holds nothing.
    """
    if not hasattr(signal, "pthread_sigmask"):
        yield
        return
    noted: list[int] = []
    in_main = threading.current_thread() is threading.main_thread()
    # None: a handler not set from Python (an embedding's), which could not be put back.
    handlers = (
        {s: h for s in _INTERRUPTS if (h := signal.getsignal(s)) is not None} if in_main else {}
    )
    for s in handlers:
        signal.signal(s, lambda n, _frame: noted.append(n))
    signal.pthread_sigmask(signal.SIG_BLOCK, _INTERRUPTS)
    try:
        yield
    finally:
        for s, handler in handlers.items():
            signal.signal(s, handler)
        signal.pthread_sigmask(signal.SIG_UNBLOCK, _INTERRUPTS)
        for n in dict.fromkeys(noted):  # each once, in the order they came
            # The handler itself, not the signal again: a watcher of the signals
            # (``signal.set_wakeup_fd``) would count a second one.
            now = signal.getsignal(n)
            if callable(now):
                now(n, None)
            elif now == signal.SIG_DFL:
                signal.raise_signal(n)


def _after_spawn() -> None:
    """In a worker that has read its start-up data: Ctrl-C is ignored (the main
    process decides, and ends the workers), SIGTERM ends it (the executor's own
    clean-up terminates workers with it); then both are unblocked (``_spawning``)."""
    if hasattr(signal, "pthread_sigmask"):
        signal.signal(signal.SIGINT, signal.SIG_IGN)
        signal.signal(signal.SIGTERM, signal.SIG_DFL)
        signal.pthread_sigmask(signal.SIG_UNBLOCK, _INTERRUPTS)


class WorkerPool:
    """``workers`` processes (spawned: a forked Blender is not safe) that score poses.

    The start-up data (the grid's arrays and the scene's triangles: megabytes) is
    pickled once into a temporary file, and the processes are spawned with its name
    alone, deaf to interrupts (``_spawning``): a spawn then writes a few hundred bytes
    to its pipe and takes milliseconds, where a child reading megabytes while it
    imports numpy took seconds, and an interrupt waited for it. The processes load the
    file while the main process goes on; it is removed once all have it, at
    ``shutdown``, or by the workers when the main process was killed.
    """

    def __init__(
        self, inputs: WorkerInputs, make_caster: Callable[[], RayCaster], workers: int
    ) -> None:
        fd, name = tempfile.mkstemp(prefix="autoscoop-workers-", suffix=".pickle")
        self.inputs_file = Path(name)
        self.executors: list[ProcessPoolExecutor] = []
        try:
            with os.fdopen(fd, "wb") as f:
                pickle.dump((inputs, make_caster), f, protocol=pickle.HIGHEST_PROTOCOL)
            spawn = multiprocessing.get_context("spawn")
            self.executors = [
                ProcessPoolExecutor(
                    max_workers=1, mp_context=spawn, initializer=_start, initargs=(name,)
                )
                for _ in range(workers)
            ]
            with _spawning():
                started = [executor.submit(_started) for executor in self.executors]
        except BaseException:  # interrupted: no process or file is left behind
            self.shutdown()
            raise

        def one_started(_future: Future) -> None:  # (the executors' threads call it)
            if all(f.done() for f in started):  # (two may both see it: unlink is idempotent)
                self.inputs_file.unlink(missing_ok=True)

        for future in started:
            future.add_done_callback(one_started)
        self.synced = [0] * workers  # entries of the fixed log each worker has been sent

    @property
    def workers(self) -> int:
        return len(self.executors)

    def submit(self, k: int, poses: Sequence[SensorPose], fixed_log: list[FixedMark]) -> Future:
        """Score ``poses`` on worker ``k``, first bringing its fixed sensors up to date;
        the future gives (fitness per pose, sight rays cast)."""
        since = fixed_log[self.synced[k] :]
        self.synced[k] = len(fixed_log)
        return self.executors[k].submit(_score, list(poses), since)

    def shutdown(self) -> None:
        """End the processes now: work still queued or running is dropped (an ended or
        interrupted search needs none of it), so this never waits for a chunk."""
        for executor in self.executors:
            # The executor's own processes: it can only wait for them to finish
            # (``kill_workers`` comes in Python 3.14). And its manager thread, which
            # ``shutdown(wait=False)`` forgets: left running, it closes its wakeup pipe
            # while the interpreter's exit hook writes to it (EBADF traceback, CI
            # 2026-11-29), so it is joined once the processes are gone.
            processes = list((executor._processes or {}).values())
            # (typeshed calls it a ``_ThreadWakeup``; it is the thread)
            manager: threading.Thread | None = executor._executor_manager_thread  # type: ignore[assignment]
            executor.shutdown(wait=False, cancel_futures=True)
            for process in processes:
                process.kill()
            for process in processes:
                process.join()
            if manager is not None:
                manager.join()
        self.inputs_file.unlink(missing_ok=True)
