"""Progress in any output (issue 34): the facts of a run's progress in words, the
progress lines in a log at least every ``LOG_INTERVAL_S``, the bar on a terminal, the
estimate line before the heavy work, and the Blender status text in the same words.

A real run of about half a minute to a minute, piped, checks the gaps between its
lines; the rest drives ``ProgressBar`` with a clock of its own."""

from __future__ import annotations

import io
import re
import subprocess
import sys
import time
from dataclasses import replace
from types import SimpleNamespace

import pytest

from autoscoop_blender.core.budget import Estimate
from autoscoop_blender.core.optimize.base import Progress
from autoscoop_blender.io.progress_text import duration, gap, progress_text
from headless.jobs import estimate_text, gap_line, time_text
from headless.progress import LOG_INTERVAL_S, ProgressBar
from tests.conftest import ROOT

LP = Progress(
    "search", 0, 0.0, 0.97, 0, 0, bound=70.0, best=74.0, stage="bounds", part=2, parts=3,
    plan=(35, 13), eta_s=125.0,
)  # fmt: skip
ES = Progress("search", 12, 0.43, 0.97, 3, 500)


def test_every_fact_the_optimizer_gives_is_said():
    assert progress_text(LP, 45.2) == (
        "search: bounds | part 2 of 3 | best 74 (35 sensors on 13 masts) | bound 70 | "
        "gap 5.4% | 45 s, ~2 min 05 s left"
    )
    assert progress_text(LP, 45.2, compact=True) == (
        "search: bounds | part 2/3 | best 74 (35 on 13 masts) | bound 70 | gap 5.4% | "
        "45 s, ~2 min 05 s left"
    )


def test_facts_left_empty_are_left_out():
    """The ES gives no stage, part, plan, bound or time left: its fixed sensors and
    epoch are its progress. lp before its first plan: the stage and the time."""
    assert (
        progress_text(ES, 3725)
        == "search | 12 sensors, coverage 43.00% of 97%, epoch 3 | 1 h 02 min"
    )
    early = Progress("search", 0, 0.0, 0.97, 0, 0, stage="candidates")
    assert progress_text(early, 9.6) == "search: candidates | 10 s"
    # A bound without a plan (ES with --bound): no gap.
    assert progress_text(replace(ES, bound=30.92), 1) == (
        "search | 12 sensors, coverage 43.00% of 97%, epoch 3 | bound 30.92 | 1 s"
    )


@pytest.mark.parametrize(
    ("best", "bound", "want"),
    [(74.0, 70.0, 4 / 74), (70.0, 70.0, 0.0), (None, 70.0, None), (74.0, None, None),
     (float("inf"), 70.0, None), (0.0, 0.0, None)],
)  # fmt: skip
def test_gap(best, bound, want):
    got = gap(replace(LP, best=best, bound=bound))
    assert got == (None if want is None else pytest.approx(want))


def test_durations():
    assert [duration(s) for s in (0, 59.4, 60, 185, 3599, 3600, 7320)] == [
        "0 s", "59 s", "1 min 00 s", "3 min 05 s", "59 min 59 s", "1 h 00 min", "2 h 02 min",
    ]  # fmt: skip


class Clock:
    def __init__(self) -> None:
        self.now = 1000.0

    def __call__(self) -> float:
        return self.now


class Terminal(io.StringIO):
    def isatty(self) -> bool:
        return True


def test_a_log_gets_a_line_every_interval_each_fixed_sensor_and_each_new_stage():
    clock, log = Clock(), io.StringIO()
    bar = ProgressBar(log, t0=clock.now - 3.0, clock=clock, tick_s=None)
    stamps = []
    for k in range(61):  # 30 s of reports every 0.5 s, one stage
        clock.now = 1000.0 + 0.5 * k
        before = log.getvalue().count("\n")
        bar.update(LP)
        if log.getvalue().count("\n") > before:
            stamps.append(clock.now - 1000.0)
    assert stamps == [0.0, 5.0, 10.0, 15.0, 20.0, 25.0, 30.0]
    lines = log.getvalue().splitlines()
    assert lines[0] == progress_text(LP, 3.0) and lines[-1] == progress_text(LP, 33.0)
    # A new stage or part at once; every fixed sensor; the end.
    clock.now += 0.1
    for p in (replace(LP, stage="plans"), replace(LP, stage="plans", part=3)):
        bar.update(p)
    fixed = Progress("fixed", 1, 0.05, 0.97, 0, 1, stage="fixing")
    for p in (fixed, replace(fixed, sensors=2), Progress("done", 2, 0.1, 0.97, 0, 2)):
        bar.update(p)
    new = log.getvalue().splitlines()[len(lines) :]
    assert [line.split(" | ")[0] for line in new] == [
        "search: plans", "search: plans", "fixed: fixing", "fixed: fixing", "done",
    ]  # fmt: skip
    assert "part 3 of 3" in new[1] and "2 sensors" in new[3]
    assert "\r" not in log.getvalue() and "\033" not in log.getvalue()


def test_between_reports_the_latest_facts_come_again():
    """The optimizer may work for seconds between two reports (a plan built on the
    masts' sites): the bar's thread repeats the latest facts with the time."""
    clock, log = Clock(), io.StringIO()
    bar = ProgressBar(log, t0=clock.now, clock=clock, tick_s=None)
    bar.tick()  # nothing reported yet: nothing to say
    bar.update(LP)
    for step in (4.9, 0.2, 1.0, 3.9, 0.1):
        clock.now += step
        bar.tick()
    assert log.getvalue().splitlines() == [
        progress_text(LP, 0.0), progress_text(LP, 5.1), progress_text(LP, 10.1),
    ]  # fmt: skip
    bar.close()
    clock.now += 60
    bar.tick()
    assert len(log.getvalue().splitlines()) == 3


class Writes(io.StringIO):
    """A log that keeps each write apart."""

    def __init__(self) -> None:
        super().__init__()
        self.writes: list[str] = []

    def write(self, text: str) -> int:
        self.writes.append(text)
        return super().write(text)


def test_a_log_line_comes_whole_in_one_write():
    """An interrupt's last line is written from a signal handler or the watchdog
    thread: between a line's text and its newline it ended up at the end of the
    progress line ("... | 2 sinterrupted: ..."). A line and its newline are one
    write, so another write comes before it or after it."""
    clock, log = Clock(), Writes()
    bar = ProgressBar(log, t0=clock.now, clock=clock, tick_s=None)
    bar.update(LP)
    clock.now += 6.0
    bar.tick()
    assert log.writes == [progress_text(LP, 0.0) + "\n", progress_text(LP, 6.0) + "\n"]


def test_the_thread_keeps_a_log_going():
    log = io.StringIO()
    bar = ProgressBar(log, log_interval_s=0.2, tick_s=0.05)
    bar.update(LP)
    time.sleep(1.1)
    bar.close()
    lines = log.getvalue().splitlines()
    assert 4 <= len(lines) <= 7 and all(line.startswith("search: bounds |") for line in lines)


def test_a_terminal_gets_one_bar_redrawn_with_the_same_facts():
    clock, term = Clock(), Terminal()
    bar = ProgressBar(term, t0=clock.now, clock=clock, tick_s=None)
    bar.update(LP)
    clock.now += 0.1  # within interval_s (0.2): not redrawn
    bar.update(replace(LP, best=73.0))
    clock.now += 0.2
    bar.update(replace(LP, best=72.0))
    bar.close()
    draws = term.getvalue().split("\r")[1:]
    assert len(draws) == 2 and term.getvalue().endswith("\n")
    assert draws[1] == (
        "[------------------------] " + progress_text(replace(LP, best=72.0), 0.3, True)
        + "\033[K\n"
    )  # fmt: skip
    assert not ProgressBar.drawing


def test_the_estimate_line_says_what_the_estimate_holds():
    est = Estimate(
        grid_m=1.0, reach_m=80.0, grid_cells=200_000, target_points=16_555, disk_cells=20_000,
        rays_per_evaluation=30_000, grid_bytes=5 << 20, peak_bytes=int(1.7 * (1 << 30)),
        peak_stage="optimizer", optimizer="lp", positions=665, orientations=216,
        nonzeros=40_900_000, parts=3, workers=2,
    )  # fmt: skip
    assert estimate_text(est) == (
        "peak ~1.7 GiB (at the optimizer stage) for lp, 16,555 target points, 665 mast "
        "positions x 216 orientations, ~40.9 M candidate matrix entries, in 3 parts"
    )
    # The candidates at 0.3 s of a core per million entries, 1.2 x in parts (borders
    # built twice): 40.9 M -> 14.7 s.
    assert est.build_s == pytest.approx(40.9 * 0.3 * 1.2)
    assert time_text(est.build_s, 720.0) == (
        "time: candidates ~15 s of one core, the whole run at most 12 min 00 s (its time limit)"
    )
    # A limit shorter than the candidates take does not promise what it cannot keep.
    assert time_text(est.build_s, 1.0) == (
        "time: candidates ~15 s of one core, longer than the time limit (1 s): the run ends "
        "once they are built, with the best plan by then"
    )
    es = replace(est, optimizer="es", orientations=0, nonzeros=0, parts=1, peak_stage="workers")
    assert estimate_text(es) == (
        "peak ~1.7 GiB (at the workers stage) for es, 16,555 target points, 665 mast "
        "positions, 2 processes"
    )


def test_the_blender_status_text_says_the_same():
    from autoscoop_blender.ops import status_text

    assert status_text(LP, 45.2, "lp", False) == (
        f"AutoSCOOP: {progress_text(LP, 45.2)}  -  Esc to stop with the best plan"
    )
    assert status_text(LP, 45.2, "lp", True).endswith("  -  stopping: Esc again to cancel")
    assert status_text(ES, 1.0, "es", False).endswith(" | 1 s  -  Esc to cancel")


LINE_GAP_S = 10.0


def test_a_piped_run_prints_a_line_at_least_every_10_s(tmp_path):
    """two_routes at a 1.5 m grid (lp, 27 s here on a quiet machine, 2026-11-26; the
    2 m grid once took 30-40 s, now 10 s, too short to need the lines): stderr
    is a pipe; no gap between its lines, from the start to the end, exceeds 10 s; the
    estimate comes before the first progress line, and the lines carry the best plan,
    the bound and the gap once the lp has them."""
    start = time.monotonic()
    proc = subprocess.Popen(
        [sys.executable, "-m", "headless", "optimize", "--grid", "1.5",
         "--out-dir", tmp_path / "out"],
        cwd=ROOT, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, text=True,
    )  # fmt: skip
    stamps, lines = [0.0], []
    assert proc.stderr is not None
    for line in proc.stderr:
        stamps.append(time.monotonic() - start)
        lines.append(line.rstrip("\n"))
    assert proc.wait(timeout=600) == 0, "\n".join(lines)
    stamps.append(time.monotonic() - start)
    gaps = [b - a for a, b in zip(stamps, stamps[1:])]
    assert max(gaps) <= LINE_GAP_S, list(zip(gaps, ["(start)"] + lines))
    assert stamps[-1] > 2 * LOG_INTERVAL_S  # (long enough to have needed the lines)
    progress = [k for k, line in enumerate(lines) if line.startswith(("search", "fixed"))]
    (estimate,) = [k for k, line in enumerate(lines) if line.startswith("estimate: ")]
    assert estimate < progress[0]
    assert re.match(r"estimate: peak ~[\d.]+ [MG]iB \(at the \w+ stage\) for lp, ", lines[estimate])
    proofs = [line for line in lines if " | bound " in line and " | gap " in line]
    assert proofs and all(" | best " in line for line in proofs)


def _with(**metrics):
    """A stand-in for a Result: what ``gap_line`` reads."""
    base = {"gap": 0.15, "masts": 29, "sensors": 73, "masts_lower_bound": 26,
            "sensors_lower_bound": 58, "existing_masts": 0, "existing_sensors": 0}  # fmt: skip
    return SimpleNamespace(metrics=base | metrics)


def test_the_gap_line_says_the_fewest_masts_and_sensors_against_the_plans():
    assert gap_line(_with()) == (
        "no plan on the candidate set has fewer than 26 masts or fewer than 58 sensors; "
        "this one has 29 and 73"
    )
    # With masts standing, the bounds and the counts are the new ones'.
    assert gap_line(_with(existing_masts=2, existing_sensors=3, masts_lower_bound=1)) == (
        "no plan on the candidate set has fewer than 1 new mast or fewer than 58 new "
        "sensors; this one has 27 and 70"
    )
    # A count with nothing proven of it is left out; no line at a gap of 0 or no proof.
    assert gap_line(_with(masts_lower_bound=0)) == (
        "no plan on the candidate set has fewer than 58 sensors; this one has 73"
    )
    assert gap_line(_with(gap=0.0)) is None
    assert gap_line(_with(gap=None, masts_lower_bound=None, sensors_lower_bound=None)) is None


def test_the_gap_line_says_whether_a_cheaper_plan_could_keep_the_masts():
    head = "no plan on the candidate set has fewer than 26 masts or fewer than 58 sensors; "
    # As many sensors on its masts as it has: the masts must change.
    assert gap_line(_with(sensors_on_masts_lower_bound=73)) == (
        head + "this one has 29 and 73; none on its masts has fewer sensors: a plan with "
        "fewer needs other masts"
    )
    # Fewer: a plan on the same masts might do with fewer sensors.
    assert gap_line(_with(sensors_on_masts_lower_bound=70)) == (
        head + "this one has 29 and 73; on its masts a plan needs at least 70 sensors"
    )
    # With sensors standing, the plan's new sensors against the new ones' bound.
    standing = _with(existing_sensors=3, sensors_on_masts_lower_bound=70)
    assert gap_line(standing).endswith(
        "this one has 29 and 70; none on its masts has fewer sensors: a plan with fewer needs "
        "other masts"
    )
    assert gap_line(_with(sensors_on_masts_lower_bound=None)) == head + "this one has 29 and 73"
