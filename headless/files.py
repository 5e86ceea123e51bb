"""Opening .blend files and writing results all-or-nothing."""

from __future__ import annotations

import csv
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


def json_text(data: Any) -> str:
    return json.dumps(data, indent=2, allow_nan=False) + "\n"


def csv_text(header: Sequence[str], rows: Iterable[Sequence[Any]]) -> str:
    buf = io.StringIO()
    writer = csv.writer(buf, lineterminator="\n")
    writer.writerow(header)
    writer.writerows(rows)
    return buf.getvalue()


def write_files(contents: dict[Path, str | bytes]) -> None:
    """Write every file or none: all go to temporary files first, then are renamed.

    A destination that cannot be a file is refused before anything is written, and
    a failure while staging leaves every destination untouched.
    """
    for path in contents:
        if path.is_dir():
            raise InputError(f"{path}: is a directory, not a file to write")
    staged: list[tuple[str, Path]] = []
    path = next(iter(contents), Path("."))
    try:
        for path, data in contents.items():
            path.parent.mkdir(parents=True, exist_ok=True)
            fd, tmp = tempfile.mkstemp(prefix=f".{path.name}.", dir=path.parent)
            with os.fdopen(fd, "wb") as f:
                f.write(data.encode("utf-8") if isinstance(data, str) else data)
            os.chmod(tmp, 0o666 & ~_umask())  # mkstemp makes 0600; match open()
            staged.append((tmp, path))
        for tmp, path in staged:
            os.replace(tmp, path)
        staged = []
    except OSError as e:  # a folder the user cannot write, a full disk
        raise InputError(f"{path}: cannot write it ({e.strerror or e})") from None
    finally:
        for tmp, _ in staged:
            Path(tmp).unlink(missing_ok=True)


def _umask() -> int:
    mask = os.umask(0)
    os.umask(mask)
    return mask


@contextmanager
def quiet_fds() -> Iterator[list[str]]:
    """Send file descriptors 1 and 2 to a temporary file (Blender's C code writes to
    them directly, past ``sys.stdout``); yields a list that holds what was written once
    the block has ended."""
    chatter: list[str] = []
    sys.stdout.flush()
    sys.stderr.flush()
    saved = [os.dup(1), os.dup(2)]
    with tempfile.TemporaryFile() as sink:
        os.dup2(sink.fileno(), 1)
        os.dup2(sink.fileno(), 2)
        try:
            yield chatter
        finally:
            sys.stdout.flush()
            sys.stderr.flush()
            os.dup2(saved[0], 1)
            os.dup2(saved[1], 2)
            for fd in saved:
                os.close(fd)
            sink.seek(0)
            chatter.append(sink.read().decode("utf-8", "replace"))
