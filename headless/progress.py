"""A one-line progress bar on stderr for long runs."""

from __future__ import annotations

import sys
import time

from autoscoop_blender.core.optimize.base import Progress


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
        if ProgressBar.drawing:
            print(file=self.stream, flush=True)
            ProgressBar.drawing = False
