"""Opening .blend files, and writing results all-or-nothing without ever touching an
input.

The rule for outputs, the same in every command (``check_outputs``, called before any
work): an output that is one of the command's inputs, by any name (the same path, a
symbolic link to it, a hard link, a path through ``..`` or a linked folder), is refused;
so is one that is a folder, and one that exists already unless ``--overwrite`` is given.
Each file is written to a temporary file in its own folder and renamed onto its name
(``write_files``): a reader sees the old file or the new one, never half of one; an
output that is a symbolic link is replaced by the file, never written through; the
temporary files go on every error path (a full disk too).
"""

from __future__ import annotations

import csv
import errno
import io
import json
import os
import sys
import tempfile
from collections.abc import Iterable, Iterator, Sequence
from contextlib import contextmanager
from pathlib import Path
from typing import Any

from autoscoop_blender.core.errors import InputError
from autoscoop_blender.core.model.scene import SceneModel
from autoscoop_blender.scene.factory import BVHFactory
from headless import interrupts


def open_blend(path: str | None) -> str:
    """Open ``path`` in bpy (or keep the file Blender already opened); its path."""
    import bpy

    if path is None:
        if bpy.data.filepath:
            return bpy.data.filepath
        raise InputError("no scene given: pass a .blend file")
    p = Path(path)
    if p.is_dir():
        raise InputError(f"{path}: is a directory, not a .blend file")
    if not p.is_file():
        raise InputError(f"{path}: file not found")
    try:
        # (held: Blender's load handlers run Python, ``interrupts``; quiet: its "Read
        # blend: ..." line on stdout is not ours to print. Not stderr: an interrupt's
        # last line goes there, also while the file loads.)
        with interrupts.held(), quiet_fds((1,)):
            bpy.ops.wm.open_mainfile(filepath=str(p.resolve()))
    except RuntimeError:
        raise InputError(f"{path}: not a readable .blend file") from None
    return str(p)


def load_scene(path: str | None, reach_m: float | None = None) -> tuple[SceneModel, BVHFactory]:
    """Open a .blend and return its SceneModel and the factory of its BVHTree caster;
    with ``reach_m`` (the longest sensor range) occluders no sight line can meet are
    left out."""
    from autoscoop_blender.scene.extract import extract_scene

    open_blend(path)
    scene = extract_scene()
    if reach_m is not None:
        scene = scene.cropped(reach_m)
    return scene, BVHFactory.of(scene)


def blend_bytes() -> bytes:
    """The open Blender file as it stands, saved (compressed) to a temporary folder
    that is gone afterwards, whatever happens; the open file keeps its own path."""
    import bpy

    interrupts.check()
    with tempfile.TemporaryDirectory(prefix="autoscoop-") as tmp:
        blend = Path(tmp) / "scene.blend"
        with interrupts.scratch(Path(tmp)), interrupts.held(), quiet_fds() as chatter:
            # (quiet: Blender's "Info: Saved copy as ..." is not ours to print)
            try:
                bpy.ops.wm.save_as_mainfile(filepath=str(blend), copy=True, compress=True)
            except RuntimeError as e:
                failure: RuntimeError | None = e
            else:
                failure = None
        data = blend.read_bytes() if blend.is_file() else b""
        if failure is not None or not whole_blend(data):
            sys.stderr.write("".join(chatter))
            why = failure or "the file it wrote is cut short: is the disk full?"
            raise InputError(f"Blender could not save the scene ({why})")
        return data


# Blender compresses with zstd's seekable format, whose seek table ends every file
# with this magic number; an uncompressed .blend ends with its "ENDB" block.
_ZSTD_MAGIC = b"\x28\xb5\x2f\xfd"
_SEEKABLE_END = b"\xb1\xea\x92\x8f"


def whole_blend(data: bytes) -> bool:
    """Whether ``data`` is a .blend file written to its end. Blender does not report
    every failed write (a full disk, a file size limit): it leaves a file cut short."""
    if data.startswith(_ZSTD_MAGIC):
        return data.endswith(_SEEKABLE_END)
    return data.startswith(b"BLENDER") and b"ENDB" in data[-32:]


def json_text(data: Any) -> str:
    return json.dumps(data, indent=2, allow_nan=False) + "\n"


def csv_text(header: Sequence[str], rows: Iterable[Sequence[Any]]) -> str:
    buf = io.StringIO()
    writer = csv.writer(buf, lineterminator="\n")
    writer.writerow(header)
    writer.writerows(rows)
    return buf.getvalue()


# O_NOFOLLOW: not on Windows, where a file opened by name is not a link's target.
_NOFOLLOW = getattr(os, "O_NOFOLLOW", 0)


def open_no_link(path: Path, flags: int, doing: str) -> int:
    """``os.open`` that never goes through a symbolic link (the checkpoint and the
    lock are written in place); InputError "<path>: cannot <doing> (<why>)" when it
    cannot open. Returns the file descriptor."""
    try:
        return os.open(path, flags | _NOFOLLOW, 0o666)
    except FileNotFoundError:
        raise
    except OSError as e:
        why = (
            "it is a symbolic link, which AutoSCOOP does not follow"
            if e.errno == errno.ELOOP
            else e.strerror or str(e)
        )
        raise InputError(f"{path}: cannot {doing} ({why})") from None


def same_file(a: Path, b: Path) -> bool:
    """Whether two paths name one file: the same inode when both exist (a hard link,
    a symbolic link, another spelling), else the same real path."""
    try:
        if a.exists() and b.exists():
            return os.path.samefile(a, b)
    except OSError:
        pass
    return os.path.normcase(os.path.realpath(a)) == os.path.normcase(os.path.realpath(b))


def check_outputs(
    outputs: dict[Path, str],
    inputs: dict[Path, str],
    overwrite: bool,
    kept: Iterable[Path] = (),
    advice: str = "name another file",
) -> None:
    """Refuse, with one line, outputs that would land on an input or on each other,
    folders, and (unless ``overwrite``) files that exist already; see the module
    docstring. Nothing is written.

    outputs, inputs: path -> how the command line named it (e.g. ``--out``, "the
    scene"); kept: outputs this command may replace without ``overwrite`` (a
    checkpoint resumed, the run's lock); advice: how to choose another output.
    """
    for out, flag in outputs.items():
        for inp, what in inputs.items():
            if same_file(out, inp):
                raise InputError(f"{out} ({flag}): is {what} ({inp}), an input; {advice}")
        if out.is_dir():
            raise InputError(f"{out} ({flag}): is a folder, not a file to write; {advice}")
        if os.path.lexists(out) and not out.is_file():
            # A device (/dev/null), a pipe, a link to one: a rename would put a file
            # in its place.
            raise InputError(f"{out} ({flag}): is not a regular file; {advice}")
    names = list(outputs)
    for k, out in enumerate(names):
        for other in names[k + 1 :]:
            if same_file(out, other):
                raise InputError(
                    f"{out} ({outputs[out]}) and {other} ({outputs[other]}) are one file; {advice}"
                )
    if overwrite:
        return
    spare = set(kept)
    existing = [out for out in outputs if out not in spare and os.path.lexists(out)]
    if existing:
        shown = ", ".join(str(p) for p in existing[:3])
        more = f" and {len(existing) - 3} more" if len(existing) > 3 else ""
        verb, them = ("exists", "it") if len(existing) == 1 else ("exist", "them")
        raise InputError(f"{shown}{more}: {verb} already; --overwrite replaces {them}, or {advice}")


def write_files(contents: dict[Path, str | bytes]) -> None:
    """Write every file or none: all go to temporary files first, then are renamed.

    A destination that cannot be a file is refused before anything is written, and
    a failure while staging (a full disk) leaves every destination untouched and no
    temporary file behind; an interrupt waits for the renames to end.
    """
    interrupts.check()  # nothing is written once interrupted
    for path in contents:
        if path.is_dir():
            raise InputError(f"{path}: is a directory, not a file to write")
    staged: list[tuple[Path, Path]] = []
    scratch: list[Path] = []
    path = next(iter(contents), Path("."))
    try:
        for path, data in contents.items():
            path.parent.mkdir(parents=True, exist_ok=True)
            fd, name = tempfile.mkstemp(prefix=f".{path.name}.", dir=path.parent)
            staged.append((Path(name), path))  # before the write, which may fail
            scratch.append(Path(name))
            interrupts.add_scratch(Path(name))
            with os.fdopen(fd, "wb") as f:
                f.write(data.encode("utf-8") if isinstance(data, str) else data)
            os.chmod(name, 0o666 & ~_umask())  # mkstemp makes 0600; match open()
        with interrupts.held():
            for tmp, path in staged:
                os.replace(tmp, path)
            staged = []
    except OSError as e:  # a folder the user cannot write, a full disk
        raise InputError(f"{path}: cannot write it ({e.strerror or e})") from None
    finally:
        for tmp, _ in staged:
            tmp.unlink(missing_ok=True)
        for tmp in scratch:
            interrupts.discard_scratch(tmp)


def _umask() -> int:
    mask = os.umask(0)
    os.umask(mask)
    return mask


@contextmanager
def quiet_fds(fds: tuple[int, ...] = (1, 2)) -> Iterator[list[str]]:
    """Send file descriptors ``fds`` (1 and 2: stdout and stderr) to a temporary file
    (Blender's C code writes to them directly, past ``sys.stdout``); yields a list that
    holds what was written once the block has ended."""
    chatter: list[str] = []
    sys.stdout.flush()
    sys.stderr.flush()
    saved = [os.dup(fd) for fd in fds]
    with tempfile.TemporaryFile() as sink:
        for fd in fds:
            os.dup2(sink.fileno(), fd)
        try:
            yield chatter
        finally:
            sys.stdout.flush()
            sys.stderr.flush()
            for fd, kept in zip(fds, saved):
                os.dup2(kept, fd)
                os.close(kept)
            sink.seek(0)
            chatter.append(sink.read().decode("utf-8", "replace"))
