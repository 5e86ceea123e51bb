"""One-line progress on stderr: the bar of a long run, the status line of an import."""

from __future__ import annotations

import sys
import time

from autoscoop_blender.core.optimize.base import Progress
from headless import interrupts


class ProgressBar:
    """Redraws one status line at most every ``interval_s``; on a non-terminal
    stream it prints a line per fixed sensor instead."""

    drawing = False
    """Whether a bar is drawn, unfinished, on the terminal's last line (an
    interruption's last line then starts on a line of its own)."""

    def __init__(self, stream=sys.stderr, interval_s: float = 0.2, width: int = 24) -> None:
        self.stream = stream
        self.tty = stream.isatty()
        self.interval = interval_s
        self.width = width
        self.t0 = time.perf_counter()
        self._last = 0.0

    def _line(self, p: Progress) -> str:
        filled = int(round(p.fraction * self.width))
        bar = "#" * filled + "-" * (self.width - filled)
        proof = ""
        if p.bound is not None or p.best is not None:
            best = "-" if p.best is None else f"{p.best:g}"
            proof = f" | best {best} >= bound {p.bound or 0:.2f}"
        return (
            f"[{bar}] coverage {p.coverage:6.2%} of {p.rho:.0%} | sensors {p.sensors:3d} | "
            f"epoch {p.epoch:3d} | {p.phase:<6}{proof} | {time.perf_counter() - self.t0:6.1f} s"
        )

    def update(self, p: Progress) -> None:
        interrupts.check()
        now = time.perf_counter()
        if not self.tty:
            if p.phase in ("fixed", "done"):
                print(self._line(p), file=self.stream, flush=True)
            return
        if p.phase == "search" and now - self._last < self.interval:
            return
        self._last = now
        print("\r" + self._line(p), end="", file=self.stream, flush=True)
        ProgressBar.drawing = True

    def close(self) -> None:
        end_line(self.stream)


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
            print(line, file=self.stream, flush=True)
            self._last = now

    def close(self) -> None:
        end_line(self.stream)
