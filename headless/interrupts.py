"""Ctrl-C and SIGTERM on the command line: the run ends within ``GRACE_S`` seconds,
exit code 130, no traceback, and a last line that says what was kept.

- ``install()``, the first thing ``__main__`` does, makes SIGINT (Ctrl-C; a terminal
  sends it to every process of the group) and SIGTERM (``kill``, ``timeout``, a batch
  system's end of job) raise KeyboardInterrupt in the main thread, so that the job's
  ``finally`` blocks run: temporary files removed, worker processes ended.
- ``held()`` delays them to the end of a block. Blender's own code (``import bpy``,
  opening and saving .blend files) runs Python scripts whose exceptions it prints and
  swallows: an interrupt raised in there would be lost with a traceback, and a bpy
  left half imported crashes the interpreter at exit (exit 139). A group of renames is
  held too, so that the outputs are replaced all or none.
- A watchdog thread is woken by the signal itself (``signal.set_wakeup_fd``: the C
  handler writes to it at once, even while the main thread is inside C code, where a
  Python handler only runs once that code returns). If the process still runs
  ``GRACE_S`` after the first signal, or at a second one, the watchdog removes the
  scratch paths registered (``scratch``), prints the last line and ends the process
  with ``os._exit(130)``.
- ``keep(text)`` or ``keep(callable)``: what an interruption keeps, as the job stands
  (a callable is asked when the line is printed, so it reads the checkpoint then).
  ``last_line()`` prints ``interrupted: <that>`` once, whoever comes first.

Nothing happens until ``install()``: imported as a library (tests, Blender's panel)
these are plain context managers.
"""

from __future__ import annotations

import os
import select
import shutil
import signal
import sys
import threading
import time
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from pathlib import Path

GRACE_S = 3.0
"""Seconds from the first interrupt to the watchdog's exit: the clean-up's budget (the
issue's promise is 5 s, with the interpreter's own exit after it)."""

EXIT_INTERRUPTED = 130

_SIGNALS = (signal.SIGINT, signal.SIGTERM)


class _State:
    installed = False
    hold_depth = 0
    pending = False  # a signal arrived inside held()
    signalled = False  # any signal arrived
    kept: Callable[[], str] = lambda: "nothing written"  # noqa: E731
    printed = False
    lock = threading.Lock()
    scratch: set[Path] = set()


def install() -> None:
    """Take over SIGINT and SIGTERM for the command line (main thread only)."""
    if _State.installed or threading.current_thread() is not threading.main_thread():
        return
    read_end, write_end = os.pipe()
    os.set_blocking(write_end, False)
    signal.set_wakeup_fd(write_end, warn_on_full_buffer=False)
    for signum in _SIGNALS:
        signal.signal(signum, _handler)
    threading.Thread(
        target=_watch, args=(read_end,), name="autoscoop-interrupt", daemon=True
    ).start()
    _State.installed = True


def signalled() -> bool:
    """Whether an interrupt arrived (an exception while ending is then the interrupt's)."""
    return _State.signalled


def _handler(signum: int, frame: object) -> None:
    _State.signalled = True
    if _State.hold_depth:
        _State.pending = True
        return
    raise KeyboardInterrupt


@contextmanager
def held() -> Iterator[None]:
    """Interrupts wait for the end of this block (see the module docstring)."""
    _State.hold_depth += 1
    try:
        yield
    finally:
        _State.hold_depth -= 1
        if _State.hold_depth == 0 and _State.pending:
            _State.pending = False
            raise KeyboardInterrupt


def keep(what: str | Callable[[], str]) -> None:
    """What an interruption from now on keeps (the text after ``interrupted: ``)."""
    _State.kept = what if callable(what) else (lambda: what)


def add_scratch(path: Path) -> None:
    """A temporary file or folder that the watchdog removes if it has to end the
    process (the job's own clean-up removes it otherwise)."""
    _State.scratch.add(path)


def discard_scratch(path: Path) -> None:
    _State.scratch.discard(path)


@contextmanager
def scratch(path: Path) -> Iterator[Path]:
    """``add_scratch`` for the block."""
    add_scratch(path)
    try:
        yield path
    finally:
        discard_scratch(path)


def last_line() -> None:
    """Print ``interrupted: <what is kept>`` on stderr, once."""
    with _State.lock:
        if _State.printed:
            return
        _State.printed = True
        try:
            text = _State.kept()
        except Exception as e:  # a last line must come whatever the state
            text = f"(what was kept could not be read: {e})"
        sys.stderr.write(f"\ninterrupted: {text}\n" if _midline() else f"interrupted: {text}\n")
        sys.stderr.flush()


def _midline() -> bool:
    """Whether a progress bar is drawn on the terminal's last line (not imported here:
    the watchdog may run before the jobs were)."""
    progress = sys.modules.get("headless.progress")
    return bool(progress and progress.ProgressBar.drawing)


def _watch(read_end: int) -> None:
    """The watchdog thread (module docstring)."""
    first: float | None = None
    while True:
        wait = None if first is None else max(first + GRACE_S - time.monotonic(), 0.0)
        ready, _, _ = select.select([read_end], [], [], wait)
        if not ready:
            break  # the grace is over
        got = [b for b in os.read(read_end, 64) if b in _SIGNALS]
        if not got:
            continue
        if first is not None or len(got) > 1:
            break  # a second interrupt: at once
        first = time.monotonic()
    last_line()
    for path in list(_State.scratch):
        if path.is_dir():
            shutil.rmtree(path, ignore_errors=True)
        else:
            path.unlink(missing_ok=True)
    os._exit(EXIT_INTERRUPTED)
