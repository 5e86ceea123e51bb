"""Progress of a long import: ``progress(stage, done, total)`` callbacks, throttled.

A caller (the CLI's progress line, the Blender operator's status bar) passes one
function; each stage reports its own unit (bytes read, roads, areas). Calls come at the
start and end of a stage and, between, whenever ``INTERVAL_S`` has passed since the
last, so a stage that takes long is heard from at least every second or so (as long
as each unit of work, one road, is short: the import's limits see to that).
"""

from __future__ import annotations

import time
from collections.abc import Callable

# (stage, done, total): e.g. ("roads", 1200, 5000).
Progress = Callable[[str, int, int], None]

# Seconds between calls within a stage: often enough for a progress bar, rare enough
# to cost nothing (a call per road would be 90,000 calls for a big file).
INTERVAL_S = 0.25


class Ticker:
    """Reports one stage of ``total`` units to ``progress`` (None: reports nothing)."""

    def __init__(self, progress: Progress | None, stage: str, total: int) -> None:
        self.progress = progress
        self.stage = stage
        self.total = total
        self.last = time.perf_counter()
        self.done_units = 0
        self.reported = 0
        if progress is not None:
            progress(stage, 0, total)

    def __call__(self, done: int) -> None:
        """``done`` units are finished: report it if ``INTERVAL_S`` has passed."""
        self.done_units = done
        if self.progress is None:
            return
        now = time.perf_counter()
        if now - self.last >= INTERVAL_S:
            self.last = now
            self.reported = done
            self.progress(self.stage, done, self.total)

    def done(self) -> None:
        """The stage is finished: report ``total`` of ``total`` (once)."""
        if self.progress is not None and self.reported != self.total:
            self.reported = self.total
            self.progress(self.stage, self.total, self.total)
