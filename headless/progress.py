"""One-line progress on stderr: the bar of a long run, the status line of an import."""

from __future__ import annotations

import math
import sys
import threading
import time
from collections.abc import Callable

from autoscoop_blender.core.optimize.base import Progress
from autoscoop_blender.io.progress_text import progress_text
from headless import interrupts

LOG_INTERVAL_S = 5.0
"""Seconds between progress lines in a log at most (the issue asks for a line at least
every 10 s)."""


class ProgressBar:
    """A run's progress on stderr (``io.progress_text``: stage, part i of n, best plan,
    bound, gap, time spent and left). On a terminal one bar, redrawn at most every
    ``interval_s``. In a log (a pipe, a file) a line per fixed sensor, at every change
    of stage or part, and at least every ``log_interval_s``, each flushed at once:
    while the optimizer works between two reports (building a plan can take it
    seconds), a thread repeats its latest facts with the time (``tick``), checking
    every ``tick_s`` (None: no thread; tests call ``tick`` themselves).

    t0: ``time.perf_counter()`` when the run began (the elapsed time counts from it);
    clock: the time source (tests pass their own).
    """

    drawing = False
    """Whether a bar is drawn, unfinished, on the terminal's last line (an
    interruption's last line then starts on a line of its own)."""

    def __init__(
        self,
        stream=sys.stderr,
        interval_s: float = 0.2,
        width: int = 24,
        log_interval_s: float = LOG_INTERVAL_S,
        t0: float | None = None,
        clock: Callable[[], float] = time.perf_counter,
        tick_s: float | None = 1.0,
    ) -> None:
        self.stream = stream
        self.tty = stream.isatty()
        self.interval = interval_s
        self.log_interval = log_interval_s
        self.width = width
        self.clock = clock
        self.t0 = clock() if t0 is None else t0
        self._last = -math.inf
        self._where: tuple[str, int, int] | None = None
        self._latest: Progress | None = None
        self._lock = threading.Lock()  # the log's lines come from two threads
        self._closed = threading.Event()
        if not self.tty and tick_s is not None:
            threading.Thread(
                target=self._ticks, args=(tick_s,), name="autoscoop-progress", daemon=True
            ).start()

    def _bar(self, p: Progress) -> str:
        filled = int(round(p.fraction * self.width))
        return "[" + "#" * filled + "-" * (self.width - filled) + "]"

    def update(self, p: Progress) -> None:
        interrupts.check()
        if not self.tty:
            with self._lock:
                where = (p.stage, p.part, p.parts)
                moved, self._where, self._latest = where != self._where, where, p
                if p.phase in ("fixed", "done") or moved:
                    self._log(p)
            self.tick()
            return
        now = self.clock()
        if p.phase == "search" and now - self._last < self.interval:
            return
        self._last = now
        line = f"{self._bar(p)} {progress_text(p, now - self.t0, compact=True)}"
        # (erase to the end: the line may be shorter than the one before)
        print("\r" + line + "\033[K", end="", file=self.stream, flush=True)
        ProgressBar.drawing = True

    def tick(self) -> None:
        """In a log: the latest facts again, with the time, when no line came for
        ``log_interval_s``."""
        with self._lock:
            if self._closed.is_set() or self._latest is None:
                return
            if self.clock() - self._last >= self.log_interval:
                self._log(self._latest)

    def _log(self, p: Progress) -> None:
        now = self.clock()
        log_line(self.stream, progress_text(p, now - self.t0))
        self._last = now

    def _ticks(self, tick_s: float) -> None:
        while not self._closed.wait(tick_s):
            self.tick()

    def close(self) -> None:
        with self._lock:  # no line from the thread after this one
            self._closed.set()
        end_line(self.stream)


def log_line(stream, text: str) -> None:
    """``text`` and its newline in one write: ``print`` writes them apart, and an
    interrupt's last line (``interrupts.last_line``, from a signal handler or the
    watchdog thread) came between the two, at the end of a progress line in a CI log."""
    stream.write(text + "\n")
    stream.flush()


def end_line(stream) -> None:
    """End the line a bar or status line left unfinished on the terminal, if any."""
    if ProgressBar.drawing:
        print(file=stream, flush=True)
        ProgressBar.drawing = False


class StageLine:
    """``progress(stage, done, total)`` (an import's) as one status line on stderr:
    redrawn on a terminal; in a log, a line every ``log_interval_s`` (none for work
    shorter than that)."""

    def __init__(self, what: str, stream=sys.stderr, log_interval_s: float = 2.0) -> None:
        self.what = what
        self.stream = stream
        self.tty = stream.isatty()
        self.log_interval = log_interval_s
        self.t0 = self._last = time.perf_counter()

    def __call__(self, stage: str, done: int, total: int) -> None:
        interrupts.check()
        now = time.perf_counter()
        line = f"{self.what}: {stage} {done:,} of {total:,} | {now - self.t0:6.1f} s"
        if self.tty:
            print("\r" + line + "\033[K", end="", file=self.stream, flush=True)
            ProgressBar.drawing = True
        elif now - self._last >= self.log_interval:
            log_line(self.stream, line)
            self._last = now

    def close(self) -> None:
        end_line(self.stream)
