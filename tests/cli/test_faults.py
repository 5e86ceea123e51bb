"""Faults from outside: the main process killed outright, two runs into one folder."""

import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest

from autoscoop_blender.core.errors import InputError
from headless.lock import OutDirLock
from tests.cli.conftest import SAMPLES
from tests.conftest import ROOT

FLAT = SAMPLES / "flat_wall.blend"

linux_only = pytest.mark.skipif(not Path("/proc/self/stat").exists(), reason="reads /proc")


def children_of(pid: int) -> set[int]:
    """Live processes whose parent is ``pid`` (from /proc)."""
    out = set()
    for stat in Path("/proc").glob("[0-9]*/stat"):
        try:
            fields = stat.read_text().rsplit(")", 1)[1].split()
        except OSError:
            continue
        if int(fields[1]) == pid and fields[0] != "Z":
            out.add(int(stat.parent.name))
    return out


def alive(pid: int) -> bool:
    try:
        state = Path(f"/proc/{pid}/stat").read_text().rsplit(")", 1)[1].split()[0]
    except OSError:
        return False
    return state != "Z"


def wait_for(condition, seconds: float) -> bool:
    end = time.monotonic() + seconds
    while time.monotonic() < end:
        if condition():
            return True
        time.sleep(0.1)
    return condition()


def start_optimize(out: Path, *extra: str) -> subprocess.Popen:
    """A paper-faithful run with two workers: long enough to be killed in the middle."""
    return subprocess.Popen(
        [sys.executable, "-m", "headless", "optimize", str(FLAT), "--optimizer", "es",
         "--workers", "2", "--out-dir", str(out), *extra],
        cwd=ROOT, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, text=True,
    )  # fmt: skip


@linux_only
def test_workers_die_with_a_killed_parent(tmp_path):
    main = start_optimize(tmp_path / "run")
    try:
        # Two workers and multiprocessing's resource tracker.
        assert wait_for(lambda: len(children_of(main.pid)) >= 3, 120), main.stderr
        helpers = children_of(main.pid)
        os.kill(main.pid, signal.SIGKILL)
        main.wait(10)
        assert wait_for(lambda: not any(alive(p) for p in helpers), 15), [
            Path(f"/proc/{p}/cmdline").read_text() for p in helpers if alive(p)
        ]
    finally:
        if main.poll() is None:
            main.kill()


def test_a_second_run_into_a_locked_folder_is_refused(tmp_path):
    with OutDirLock(tmp_path / "out"):
        with pytest.raises(InputError, match=rf"another AutoSCOOP run \(process {os.getpid()}\)"):
            with OutDirLock(tmp_path / "out"):
                pass
    with OutDirLock(tmp_path / "out") as again:  # released at the end of the first
        assert again.stale_pid is None


def test_the_lock_of_a_killed_run_is_taken_over(tmp_path):
    holder = subprocess.Popen(
        [sys.executable, "-c", "import sys, time; from headless.lock import OutDirLock\n"
         "from pathlib import Path\nwith OutDirLock(Path(sys.argv[1])):\n"
         "    print('locked', flush=True); time.sleep(60)", str(tmp_path)],
        cwd=ROOT, stdout=subprocess.PIPE, text=True,
    )  # fmt: skip
    try:
        assert holder.stdout.readline().strip() == "locked"
        with pytest.raises(InputError, match=rf"process {holder.pid}\)"):
            OutDirLock(tmp_path).__enter__()
        holder.kill()
        holder.wait(10)
        with OutDirLock(tmp_path) as lock:
            assert lock.stale_pid == holder.pid
    finally:
        holder.kill()
