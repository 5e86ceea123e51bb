"""Ctrl-C and SIGTERM on the command line: the run ends within ``GRACE_S`` seconds,
exit code 130, no traceback, and a last line that says what was kept.

- ``install()``, the first thing ``__main__`` does, makes SIGINT (Ctrl-C; a terminal
  sends it to every process of the group), SIGTERM (``kill``, ``timeout``, a batch
  system's end of job) and SIGHUP (the terminal closed) raise KeyboardInterrupt in the
  main thread, so that the job's ``finally`` blocks run: temporary files removed,
  worker processes ended.
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
- A C library that calls back into Python (pyproj's logging, say) swallows an
  exception raised in the callback: the interrupt is lost there, with a traceback
  (printed through ``sys.excepthook`` or ``sys.unraisablehook``). So no traceback of
  a KeyboardInterrupt is printed, and ``check()`` raises the interrupt again where it
  must not be missed: before any output is written, and at every progress report.
- ``early_stop(stop)``: inside this block the first interrupt does not raise but calls
  ``stop()``, which asks the work to end soon by itself and keep what it has (the lp
  optimizer's best plan: ``Run.stop_early``); when ``stop()`` returns False (nothing
  to keep yet, or an optimizer that cannot stop early) the interrupt raises as usual.
  ``stopped()`` says whether it was asked. The watchdog then allows ``STOP_GRACE_S``
  for the run to finish and write, and a second interrupt still ends it at once.
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
import socket
import sys
import threading
import time
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from pathlib import Path
from typing import Any

GRACE_S = 3.0
"""Seconds from the first interrupt to the watchdog's exit: the clean-up's budget (the
issue's promise is 5 s, with the interpreter's own exit after it)."""

STOP_GRACE_S = 4.5
"""The same from an interrupt in an ``early_stop`` block: the run finishes its pipeline
(masts, report) and writes its results in this time, or the watchdog ends it (the
issue's limit is 5 s from the signal to the end)."""

EXIT_INTERRUPTED = 130

# Sent to the watchdog by ``finish`` (no signal has the number 0).
_FINISHED = b"\0"

# SIGHUP: the terminal was closed. Each is taken over only where it is not ignored
# already (``nohup``, a shell's background job), as Python itself does for SIGINT.
_SIGNALS = tuple(
    getattr(signal, name) for name in ("SIGINT", "SIGTERM", "SIGHUP") if hasattr(signal, name)
)


class _State:
    installed = False
    hold_depth = 0
    pending = False  # a signal arrived inside held()
    signalled = False  # a signal arrived that ends the work (not an early stop)
    stopper: Callable[[], bool] | None = None  # inside ``early_stop``
    stopped = False  # a signal asked the work to stop early (``early_stop``)
    kept: Callable[[], str] = lambda: "nothing written"  # noqa: E731
    printed = False
    finished: int | None = None  # the exit code, once the command is done
    lock = threading.Lock()
    scratch: set[Path] = set()
    wakeup: tuple[socket.socket, socket.socket] | None = None


def install() -> None:
    """Take over SIGINT and SIGTERM for the command line (main thread only)."""
    if _State.installed or threading.current_thread() is not threading.main_thread():
        return
    # A socket pair rather than a pipe: Windows takes only a socket here.
    read_end, write_end = socket.socketpair()
    write_end.setblocking(False)
    signal.set_wakeup_fd(write_end.fileno(), warn_on_full_buffer=False)
    _State.wakeup = (read_end, write_end)  # kept open for the process's life
    for signum in _SIGNALS:
        if signal.getsignal(signum) is not signal.SIG_IGN:
            signal.signal(signum, _handler)
    unraisable, excepthook = sys.unraisablehook, sys.excepthook

    def quiet_unraisable(u: Any) -> None:
        if not isinstance(u.exc_value, KeyboardInterrupt):
            unraisable(u)

    def quiet_excepthook(kind: type[BaseException], value: BaseException, tb: Any) -> None:
        if not issubclass(kind, KeyboardInterrupt):
            excepthook(kind, value, tb)

    sys.unraisablehook = quiet_unraisable
    sys.excepthook = quiet_excepthook
    threading.Thread(
        target=_watch, args=(read_end,), name="autoscoop-interrupt", daemon=True
    ).start()
    _State.installed = True


def signalled() -> bool:
    """Whether an interrupt arrived (an exception while ending is then the interrupt's)."""
    return _State.signalled


def stopped() -> bool:
    """Whether an interrupt asked the work to stop early and keep what it has
    (``early_stop``)."""
    return _State.stopped


def check() -> None:
    """KeyboardInterrupt if an interrupt came (and may have been swallowed)."""
    if _State.signalled and not _State.hold_depth:
        raise KeyboardInterrupt


def finish(code: int) -> int:
    """The command has ended with ``code``: from here on (the interpreter's own exit,
    bpy's clean-up) interrupts are ignored, since Python's exit puts the default
    actions back and one would kill the process (exit -2) with its work done. The
    watchdog ends the process with ``code`` if that exit takes more than ``GRACE_S``.
    After an interrupt, or with a solve still in its thread, the process ends here
    with ``code``, without the interpreter's exit. Otherwise returns ``code``."""
    _State.finished = code
    if _State.wakeup is not None:
        for signum in _SIGNALS:
            signal.signal(signum, signal.SIG_IGN)
        _State.wakeup[1].send(_FINISHED)
    bound = sys.modules.get("autoscoop_blender.core.optimize.bound")
    solving = bound is not None and bound.solving()
    if solving or _State.signalled or _State.stopped:
        # The interpreter's exit after an interrupt could abort (exit -6, "GIL
        # released ... finalizing"): in HiGHS' clean-up while a cancelled solve still
        # runs in its thread (seen once in CI, SIGINT during the fewest masts' MILP),
        # and in a thread of the workers' start (seen once in CI, SIGINT 1.6 s into
        # an es run with 2 workers). The command's own clean-up has run and its
        # outputs are written, so end here, with ``code``.
        sys.stdout.flush()
        sys.stderr.flush()
        os._exit(code)
    return code


def _handler(signum: int, frame: object) -> None:
    if _State.finished is not None:
        return
    if _State.stopper is not None and not (_State.stopped or _State.signalled):
        # (the stopper only sets a flag: safe to call from here, at any point)
        if _State.stopper():
            _State.stopped = True
            return
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


@contextmanager
def early_stop(stop: Callable[[], bool]) -> Iterator[None]:
    """In this block the first interrupt calls ``stop()`` instead of raising, when that
    returns True (see the module docstring)."""
    _State.stopper = stop
    try:
        yield
    finally:
        _State.stopper = None


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
    # CPython flags a KeyboardInterrupt raised inside exec() of a string (dataclasses
    # make their methods so, at import) as unhandled even once it is caught, and then
    # ends the process by SIGINT (exit -2) instead of with our exit code. Every exec
    # of a string clears that flag first.
    exec("None")
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


def _grace() -> float:
    """Seconds the work has from the first interrupt: longer when it was asked to stop
    early (or may be: the main thread's handler may not have run yet, while C code
    holds it)."""
    return STOP_GRACE_S if _State.stopped or _State.stopper is not None else GRACE_S


def _second_interrupt(data: bytes, counting: bool) -> bool:
    """Whether the watchdog's ``data`` (signal numbers and ``_FINISHED``, in the order
    they came) brings an interrupt after the first one, or after the command's end:
    ``counting`` when one of those came in an earlier read. The end may come in the
    same read as the interrupt that caused it (the main thread can get there before
    this thread runs): that is no second interrupt."""
    for byte in data:
        if byte in _SIGNALS and counting:
            return True
        counting = counting or byte in _SIGNALS or byte == _FINISHED[0]
    return False


def _watch(read_end: socket.socket) -> None:
    """The watchdog thread (module docstring)."""
    first: float | None = None
    while True:
        if first is not None and time.monotonic() >= first + _grace():
            break  # the grace is over
        # Once counting, wake often: the grace depends on the main thread's state.
        ready, _, _ = select.select([read_end], [], [], None if first is None else 0.05)
        if not ready:
            continue
        # (another signal with a Python handler writes its number here too)
        data = bytes(b for b in read_end.recv(64) if b in _SIGNALS or b == _FINISHED[0])
        if not data:
            continue
        if _second_interrupt(data, first is not None):
            break  # at once
        if first is None:
            first = time.monotonic()  # an interrupt's grace, or the exit's own deadline
    if _State.finished is not None:  # stuck in the interpreter's exit: done all the same
        os._exit(_State.finished)
    last_line()
    for path in list(_State.scratch):
        if path.is_dir():
            shutil.rmtree(path, ignore_errors=True)
        else:
            path.unlink(missing_ok=True)
    os._exit(EXIT_INTERRUPTED)
