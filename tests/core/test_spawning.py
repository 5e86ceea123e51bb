"""ES worker processes' start (``parallel.WorkerPool``): the main process acts on
signals only once every child has been sent its start-up data, and the file that
brings it is left nowhere."""

from __future__ import annotations

import signal
import subprocess
import sys
import tempfile
import threading
import time
from pathlib import Path

import pytest

from autoscoop_blender.core.model.sensors import PAPER_CAMERA
from autoscoop_blender.core.optimize.parallel import _spawning
from autoscoop_blender.core.run import Run
from tests.conftest import ROOT
from tests.core.flat import box_caster
from tests.core.test_optimize import BOX, FAST, road_scene


class Interrupted(Exception):
    pass


def _raise(signum, _frame):
    raise Interrupted(signum)


@pytest.mark.skipif(not hasattr(signal, "pthread_sigmask"), reason="POSIX only")
@pytest.mark.parametrize("signum", [signal.SIGINT, signal.SIGTERM])
def test_a_signal_another_thread_takes_is_acted_on_after_the_block(signum):
    """Another thread takes the signal (the main thread blocks it in the block), and
    Python would run the handler in the main thread at its next instruction: in the
    middle of sending a child its data, before."""
    before = signal.signal(signum, _raise)
    go = threading.Event()
    taker = threading.Thread(target=lambda: (go.wait(), signal.raise_signal(signum)))
    taker.start()  # before the block: its own mask lets the signal in
    reached_the_end = False
    try:
        with pytest.raises(Interrupted) as raised:
            with _spawning():
                go.set()
                taker.join()
                sum(range(100_000))  # many instructions, each a chance to run the handler
                reached_the_end = True
        assert reached_the_end
        assert raised.value.args == (signum,)
        assert signal.getsignal(signum) is _raise
    finally:
        signal.signal(signum, before)


@pytest.mark.skipif(not hasattr(signal, "pthread_sigmask"), reason="POSIX only")
def test_no_signal_no_raise_and_the_handlers_are_put_back():
    before = [signal.getsignal(s) for s in (signal.SIGINT, signal.SIGTERM)]
    with _spawning():
        pass
    assert [signal.getsignal(s) for s in (signal.SIGINT, signal.SIGTERM)] == before


def _gone(path: Path, seconds: float = 60) -> bool:
    end = time.monotonic() + seconds
    while path.exists() and time.monotonic() < end:
        time.sleep(0.05)
    return not path.exists()


def test_the_start_up_file_is_removed_once_the_workers_have_it():
    r = Run(road_scene(), box_caster([BOX]), PAPER_CAMERA, FAST, workers=2)
    inputs_file = r.optimizer.pool.inputs_file
    try:
        assert inputs_file.parent == Path(tempfile.gettempdir())
        assert _gone(inputs_file)
        # ... and the workers are up: an empty chunk comes back from one
        fits, rays = r.optimizer.pool.submit(0, [], []).result(timeout=60)
        assert fits == [] and rays == 0
    finally:
        r.close()


def test_shutdown_leaves_no_executor_thread_running():
    """The executors' manager threads are joined: one left running closes its wakeup
    pipe while the interpreter's exit hook writes to it (EBADF traceback at exit)."""
    r = Run(road_scene(), box_caster([BOX]), PAPER_CAMERA, FAST, workers=2)
    managers = [e._executor_manager_thread for e in r.optimizer.pool.executors]
    assert len(managers) == 2 and all(t is not None and t.is_alive() for t in managers)
    r.close()
    assert not any(t.is_alive() for t in managers)


KILLED = """
import os, signal
from autoscoop_blender.core.model.sensors import PAPER_CAMERA
from autoscoop_blender.core.run import Run
from tests.core.flat import box_caster
from tests.core.test_optimize import BOX, FAST, road_scene
r = Run(road_scene(), box_caster([BOX]), PAPER_CAMERA, FAST, workers=2)
print(r.optimizer.pool.inputs_file, flush=True)
os.kill(os.getpid(), signal.SIGKILL)
"""


@pytest.mark.skipif(sys.platform == "win32", reason="SIGKILL")
def test_a_killed_main_process_leaves_no_start_up_file():
    """SIGKILL runs none of the main process's clean-up: its workers remove the file."""
    proc = subprocess.run(
        [sys.executable, "-c", KILLED], cwd=ROOT, capture_output=True, text=True, timeout=120
    )
    assert proc.returncode == -signal.SIGKILL, proc.stderr
    assert _gone(Path(proc.stdout.strip()))
