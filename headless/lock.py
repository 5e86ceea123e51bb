"""One run per output folder: a lock held for as long as the run writes there.

The lock is the operating system's lock on ``<out_dir>/.autoscoop.lock`` (``flock`` on
POSIX, ``msvcrt.locking`` on Windows). The system releases it when the process ends,
however it ends, so a lock left by a killed run is never in the way: the file stays,
the next run takes the lock over and says so. The file holds the owner's process id,
for the message a second run gets.
"""

from __future__ import annotations

import os
import sys
from pathlib import Path
from types import TracebackType
from typing import IO

from autoscoop_blender.core.errors import InputError
from headless.files import open_no_link

NAME = ".autoscoop.lock"


def _try_lock(f: IO[bytes]) -> bool:
    """Take the lock on the open file without waiting; False when another holds it."""
    try:
        if sys.platform == "win32":
            import msvcrt

            f.seek(0)
            msvcrt.locking(f.fileno(), msvcrt.LK_NBLCK, 1)
        else:
            import fcntl

            fcntl.flock(f.fileno(), fcntl.LOCK_EX | fcntl.LOCK_NB)
    except OSError:
        return False
    return True


class OutDirLock:
    """``with OutDirLock(out_dir) as lock:`` InputError when another run holds it;
    ``lock.stale_pid``: the process id of an ended run whose lock was taken over."""

    def __init__(self, out_dir: Path) -> None:
        self.path = out_dir / NAME
        self.stale_pid: int | None = None
        self._file: IO[bytes] | None = None

    def __enter__(self) -> OutDirLock:
        try:
            self.path.parent.mkdir(parents=True, exist_ok=True)
        except OSError as e:
            raise InputError(f"{self.path.parent}: cannot write there ({e.strerror})") from None
        # Never through a link: the lock is truncated and written below.
        fd = open_no_link(self.path, os.O_RDWR | os.O_CREAT, "take the run's lock")
        f = os.fdopen(fd, "r+b")
        f.seek(0)
        owner = f.read().decode("ascii", "replace").strip()
        if not _try_lock(f):
            f.close()
            raise InputError(
                f"{self.path.parent}: another AutoSCOOP run (process {owner or '?'}) is "
                "writing there; wait for it to end or choose another --out-dir"
            )
        self.stale_pid = int(owner) if owner.isdigit() else None
        f.seek(0)
        f.truncate()
        f.write(str(os.getpid()).encode("ascii"))
        f.flush()
        self._file = f
        return self

    def __exit__(
        self,
        kind: type[BaseException] | None,
        value: BaseException | None,
        tb: TracebackType | None,
    ) -> None:
        if self._file is not None:
            self._file.seek(0)
            self._file.truncate()  # an unlocked, empty file: nobody's
            self._file.close()  # closing releases the lock
            self._file = None
