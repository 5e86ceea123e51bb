"""Faults from outside and their traces: the main process killed outright, two runs into
one folder, a damaged checkpoint, a rejected command, a run short of its goal."""

import json
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest

from autoscoop_blender.core.errors import InputError
from headless.lock import OutDirLock
from tests.cli.conftest import SAMPLES, live_processes, run_headless
from tests.conftest import ROOT

FLAT = SAMPLES / "flat_wall.blend"

linux_only = pytest.mark.skipif(not Path("/proc/self/stat").exists(), reason="reads /proc")


def children_of(pid: int) -> set[int]:
    """Live processes whose parent is ``pid`` (from /proc)."""
    return live_processes(1, pid)


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


def terminated(main: subprocess.Popen, when) -> str:
    """SIGTERM to ``main`` once ``when()`` holds; its stderr, after checking that it
    exited with 130, printed no traceback and left none of its processes running."""
    try:
        assert wait_for(when, 120), main.stderr
        helpers = children_of(main.pid)
        main.send_signal(signal.SIGTERM)
        _, stderr = main.communicate(timeout=60)
        assert main.returncode == 130, stderr
        assert "Traceback" not in stderr and "leaked" not in stderr, stderr
        assert wait_for(lambda: not any(alive(p) for p in helpers), 15)
        return stderr
    finally:
        if main.poll() is None:
            main.kill()


@linux_only
def test_sigterm_ends_a_run_as_ctrl_c_does(tmp_path):
    # ``kill`` or ``timeout`` once sensors are fixed: they are kept, as after Ctrl-C.
    out = tmp_path / "run"
    checkpoint = out / "checkpoint.jsonl"

    def fixed() -> int:
        return len(checkpoint.read_bytes().splitlines()) - 1 if checkpoint.exists() else 0

    stderr = terminated(start_optimize(out), lambda: fixed() >= 1)
    assert f"interrupted: {fixed()} sensor(s) kept in {checkpoint}" in stderr
    # While the workers are being spawned (their start-up data half sent): no worker
    # is left with a truncated pickle, none keeps running.
    main = start_optimize(tmp_path / "early")
    terminated(main, lambda: len(children_of(main.pid)) >= 2)


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


SMALL = 'optimizer = "es"\nrho = 0.6\n[es]\nmu = 8\nlam = 4\nmax_epochs = 4\n'


@pytest.fixture(scope="module")
def finished(tmp_path_factory):
    """A small ES run that fixed several sensors: (config, out dir, checkpoint bytes)."""
    tmp = tmp_path_factory.mktemp("finished")
    cfg = tmp / "small.toml"
    cfg.write_text(SMALL)
    out = tmp / "run"
    code, _, stderr = run_headless("optimize", FLAT, "--config", cfg, "--out-dir", out)
    assert code == 0, stderr
    lines = (out / "checkpoint.jsonl").read_bytes().splitlines(keepends=True)
    assert len(lines) >= 4
    return cfg, out, (out / "checkpoint.jsonl").read_bytes()


def copy_run(finished, tmp_path) -> Path:
    _, out, data = finished
    mine = tmp_path / "run"
    mine.mkdir()
    (mine / "checkpoint.jsonl").write_bytes(data)
    return mine


@pytest.mark.parametrize(
    "bad, message",
    [
        (["--workers", "0"], "--workers 0: must be at least 1"),
        (["--seed", "-1"], "seed (--seed) = -1 is out of range"),
        (["--config", "MU"], "mu must be an integer, got 40.5"),
        (["--repair"], "--repair: only with --resume"),
    ],
)
def test_a_rejected_command_leaves_the_checkpoint_as_it_was(finished, tmp_path, bad, message):
    out = copy_run(finished, tmp_path)
    mu = tmp_path / "mu.toml"
    mu.write_text('optimizer = "es"\n[es]\nmu = 40.5\n')
    args = [str(mu) if a == "MU" else a for a in bad]
    code, _, stderr = run_headless("optimize", FLAT, "--out-dir", out, *args)
    assert code == 2 and message in stderr and len(stderr.strip().splitlines()) == 1, stderr
    assert (out / "checkpoint.jsonl").read_bytes() == finished[2]
    assert sorted(p.name for p in out.iterdir()) == ["checkpoint.jsonl"]


def test_a_damaged_checkpoint_stops_the_resume_until_repair_is_asked(finished, tmp_path):
    cfg, _, data = finished
    out = copy_run(finished, tmp_path)
    lines = data.splitlines(keepends=True)
    lines[2] = lines[2].replace(b'"epochs": ', b'"epochs": 1')  # sensor 2's record
    damaged = b"".join(lines)
    (out / "checkpoint.jsonl").write_bytes(damaged)
    code, _, stderr = run_headless("optimize", FLAT, "--config", cfg, "--out-dir", out, "--resume")
    assert code == 2 and "line 3 is damaged" in stderr and "--repair" in stderr, stderr
    assert (out / "checkpoint.jsonl").read_bytes() == damaged  # left exactly as it was
    assert not (out / "result.json").exists()

    code, _, stderr = run_headless(
        "optimize", FLAT, "--config", cfg, "--out-dir", out, "--resume", "--repair"
    )
    assert code == 0 and "resuming after 1 fixed sensor" in stderr, stderr
    assert (out / "checkpoint.jsonl.damaged").read_bytes() == damaged
    # Resumed from sensor 1, it reaches the same answer as the run that was not damaged.
    assert (out / "sensors.csv").read_text() == (finished[1] / "sensors.csv").read_text()
    assert len((out / "checkpoint.jsonl").read_bytes().splitlines()) == len(lines)


def test_a_second_run_into_a_busy_folder_is_refused(finished, tmp_path):
    cfg, _, _ = finished
    out = tmp_path / "busy"
    first = start_optimize(out)
    try:
        assert wait_for(lambda: (out / ".autoscoop.lock").exists()
                        and (out / ".autoscoop.lock").read_text() == str(first.pid), 120)  # fmt: skip
        code, _, stderr = run_headless("optimize", FLAT, "--config", cfg, "--out-dir", out)
        assert code == 2, stderr
        assert f"another AutoSCOOP run (process {first.pid}) is writing there" in stderr
    finally:
        first.kill()
        first.wait(10)
    # Killed, its lock is taken over (and its checkpoint, if it had fixed a sensor by
    # then, is replaced only when asked).
    again = ("--overwrite",) if (out / "checkpoint.jsonl").exists() else ()
    code, _, stderr = run_headless("optimize", FLAT, "--config", cfg, "--out-dir", out, *again)
    assert code == 0 and f"took over the lock of run {first.pid}" in stderr, stderr


def test_a_run_short_of_its_goal_says_so_in_its_exit_code(tmp_path):
    cfg = tmp_path / "capped.toml"
    cfg.write_text("max_sensors = 1\n" + SMALL)
    code, stdout, stderr = run_headless(
        "optimize", FLAT, "--config", cfg, "--out-dir", tmp_path / "o"
    )
    result = json.loads((tmp_path / "o" / "result.json").read_text())
    assert code == 3 and result["metrics"]["sensors"] == 1
    assert result["metrics"]["coverage_fraction"] < 0.6
    assert "short of the goal" in stderr and "exit code 3" in stderr
    assert "Stopped short of the goal at the sensor limit (max_sensors = 1)." in stdout


@pytest.mark.parametrize("where", ["/proc/autoscoop_out", "/sys/autoscoop_out"])
def test_an_output_folder_nobody_can_write_is_one_line(tmp_path, where):
    """(Read-only even for root, so the test holds wherever it runs.)"""
    sensors = SAMPLES / "two_routes_sensors.json"
    scene = SAMPLES / "two_routes.blend"
    code, _, stderr = run_headless("coverage", scene, "--sensors", sensors, "--out",
                                   f"{where}/c.json")  # fmt: skip
    assert code == 2 and stderr.startswith(f"error: {where}/c.json: cannot write it"), stderr
    assert len(stderr.strip().splitlines()) == 1 and "Traceback" not in stderr
    code, _, stderr = run_headless("optimize", FLAT, "--out-dir", where)
    assert code == 2 and stderr.strip().splitlines()[-1].startswith(f"error: {where}"), stderr
    assert "Traceback" not in stderr


@pytest.mark.parametrize(
    ("change", "what"),
    [
        ("scene", "a different scene"),
        ("model", "a different model"),
        ("settings", "different settings"),
    ],
)
def test_a_checkpoint_of_another_scene_model_or_settings_is_refused(
    finished, tmp_path, change, what
):
    """--resume with anything the answer depends on changed: one line naming it, and
    the checkpoint left byte for byte."""
    cfg, _, data = finished
    mine = copy_run(finished, tmp_path)
    scene = SAMPLES / "two_routes.blend" if change == "scene" else FLAT
    if change == "model":
        cfg = tmp_path / "lidar.toml"
        cfg.write_text('model = "roadside_lidar"\n' + SMALL)
    elif change == "settings":
        cfg = tmp_path / "rho.toml"
        cfg.write_text(SMALL.replace("rho = 0.6", "rho = 0.7"))
    code, _, stderr = run_headless(
        "optimize", scene, "--config", cfg, "--out-dir", mine, "--resume"
    )
    assert code == 2, stderr
    assert stderr.strip().splitlines()[-1] == (
        f"error: {mine / 'checkpoint.jsonl'}: made with {what}; run without --resume to start again"
    )
    assert (mine / "checkpoint.jsonl").read_bytes() == data
