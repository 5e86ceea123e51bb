"""The machine a run is on: its physical memory (capped by a cgroup's limit) and the
process's resident memory, for the estimates' refusals (``refusal``) and reports.
Memory in bytes."""

from __future__ import annotations

import os
import sys

# The machine's memory where it cannot be read (neither POSIX sysconf nor Windows).
FALLBACK_MEMORY_BYTES = 8 << 30


def machine_memory_bytes() -> int:
    """Physical memory of the machine, bytes: POSIX ``sysconf`` (page size x physical
    pages), or Windows' ``GlobalMemoryStatusEx``; the smaller limit of a Linux cgroup
    (a container) when there is one; ``FALLBACK_MEMORY_BYTES`` when none can be read."""
    total = 0
    try:
        total = os.sysconf("SC_PAGE_SIZE") * os.sysconf("SC_PHYS_PAGES")
    except (AttributeError, ValueError, OSError):
        total = _windows_memory()
    if total <= 0:
        total = FALLBACK_MEMORY_BYTES
    limit = _cgroup_limit()
    return min(total, limit) if limit else total


def _windows_memory() -> int:
    if sys.platform != "win32":
        return 0
    import ctypes

    class _Status(ctypes.Structure):
        _fields_ = [
            ("dwLength", ctypes.c_ulong),
            ("dwMemoryLoad", ctypes.c_ulong),
            ("ullTotalPhys", ctypes.c_ulonglong),
            ("ullAvailPhys", ctypes.c_ulonglong),
            ("ullTotalPageFile", ctypes.c_ulonglong),
            ("ullAvailPageFile", ctypes.c_ulonglong),
            ("ullTotalVirtual", ctypes.c_ulonglong),
            ("ullAvailVirtual", ctypes.c_ulonglong),
            ("ullAvailExtendedVirtual", ctypes.c_ulonglong),
        ]

    status = _Status()
    status.dwLength = ctypes.sizeof(_Status)
    try:
        windll = ctypes.windll  # type: ignore[attr-defined,unused-ignore]  # Windows only
        ok = windll.kernel32.GlobalMemoryStatusEx(ctypes.byref(status))
    except (AttributeError, OSError):
        return 0
    return int(status.ullTotalPhys) if ok else 0


def _cgroup_limit() -> int:
    """The memory limit of this process's Linux cgroup (v2 or v1), 0 for none."""
    for path in ("/sys/fs/cgroup/memory.max", "/sys/fs/cgroup/memory/memory.limit_in_bytes"):
        try:
            with open(path) as f:
                text = f.read().strip()
        except OSError:
            continue
        if text.isdigit() and int(text) < 1 << 60:  # v1 says "no limit" with ~2^63
            return int(text)
    return 0


def resident_bytes() -> int:
    """What this process holds now (resident set), bytes; 0 where it cannot be read
    (then the check counts the run alone)."""
    try:
        with open("/proc/self/statm") as f:
            return int(f.read().split()[1]) * os.sysconf("SC_PAGE_SIZE")
    except (OSError, ValueError, IndexError, AttributeError):
        pass
    try:
        import resource
    except ImportError:  # Windows
        return 0
    peak = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss
    return int(peak) if sys.platform == "darwin" else int(peak) * 1024  # macOS: bytes
