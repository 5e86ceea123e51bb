"""The checkpoint of a long run: one JSON line per fixed sensor, appended as it is fixed.

Line 1 is a header naming what the run depends on (scene fingerprint, model,
settings); every further line is a record from ``core.run.Run``'s ``on_fixed``. A run
interrupted by Ctrl-C or a crash keeps every sensor fixed so far, and ``--resume``
reads them back to go on exactly where it stopped (the records carry the random
generator's state).

Every line is ``{"sha": <16 hex>, "data": <header or record>}``, the hash taken over
``data`` as canonical JSON, so one damaged line is found, named, and never taken for
data. A crash can only cut the *last* line short (it has no newline yet); that line is
dropped on resume. Any other damage stops the resume with an error naming the line and
leaves the file exactly as it was; ``--resume --repair`` keeps the records before the
first damaged line (the whole file is kept beside it as ``checkpoint.jsonl.damaged``).
The file is created or replaced only when the first sensor is fixed, so a command that
fails before that (bad input) never touches an earlier checkpoint. It is never opened
through a symbolic link (``O_NOFOLLOW``): a link named checkpoint.jsonl is refused on
resume, and replaced, not written through, by a fresh start.
"""

from __future__ import annotations

import hashlib
import json
import os
from collections.abc import Sequence
from pathlib import Path
from typing import Any

import numpy as np

from autoscoop_blender.core.errors import InputError
from autoscoop_blender.core.model.scene import SceneModel
from autoscoop_blender.core.model.sensors import SensorModel, SensorPack, SensorSpec
from autoscoop_blender.core.settings import OptimizeSettings, from_mapping
from headless.files import open_no_link, write_files

NAME = "checkpoint.jsonl"


def scene_fingerprint(scene: SceneModel) -> str:
    """A short hash of everything in the scene that the answer depends on."""
    h = hashlib.sha256()
    h.update(np.ascontiguousarray(scene.vertices, dtype=np.float64).tobytes())
    h.update(np.ascontiguousarray(scene.faces, dtype=np.int64).tobytes())
    h.update(np.asarray(scene.origin, dtype=np.float64).tobytes())
    for area in (*scene.targets, *scene.sensor_areas):
        h.update(area.name.encode())
        h.update(area.geometry.wkb)
        h.update(repr(area.height_m).encode())
    return h.hexdigest()[:16]


def checkpoint_header(
    scene: SceneModel,
    model: SensorModel | SensorPack,
    settings: OptimizeSettings,
    existing: Sequence[SensorSpec] = (),
    existing_masts: Sequence[tuple[float, float]] = (),
) -> dict[str, Any]:
    """What a run's answer depends on: the scene (its fingerprint), model (or mixed
    pack: ``models``), settings and the sensors and masts that stand already (only
    when there are any, so that older checkpoints still match)."""
    header: dict[str, Any] = {
        "scene": scene.source,
        "scene_fingerprint": scene_fingerprint(scene),
    }
    if isinstance(model, SensorPack):
        header["models"] = model.to_list(settings.sensor_cost)
    else:
        header["model"] = model.to_dict()
    header["settings"] = settings.to_dict()
    if existing or existing_masts:
        header["existing"] = [s.to_dict() for s in existing]
        header["existing_masts"] = [list(xy) for xy in existing_masts]
    return header


def _settings(stored: Any) -> OptimizeSettings | None:
    """Settings as recorded in a header, read through the schema: a setting missing
    from an older checkpoint ran as its default does, so it reads as the default (at
    any depth). None when they cannot be read (a setting since removed)."""
    try:
        return from_mapping(OptimizeSettings, stored, "checkpoint")
    except InputError:
        return None


RECORD_NUMBERS = ("x", "y", "pitch_deg", "yaw_deg", "fitness")
RECORD_COUNTS = ("n", "epochs", "evaluations")


def _digest(data: Any) -> str:
    text = json.dumps(data, sort_keys=True, separators=(",", ":"), allow_nan=False)
    return hashlib.sha256(text.encode("utf-8")).hexdigest()[:16]


def encode_line(data: Any) -> str:
    """One checkpoint line (with its newline) holding ``data``; ValueError for NaN or inf."""
    return json.dumps({"sha": _digest(data), "data": data}, allow_nan=False) + "\n"


def decode_line(line: bytes) -> Any:
    """The data of one line; ValueError saying what is wrong with it."""
    try:
        doc = json.loads(line.decode("utf-8"))
    except UnicodeDecodeError:
        raise ValueError("not UTF-8 text") from None
    except json.JSONDecodeError as e:
        raise ValueError(f"not JSON ({e.msg})") from None
    if not isinstance(doc, dict) or set(doc) != {"sha", "data"}:
        raise ValueError("not a checkpoint line (no checksum: made by an older AutoSCOOP?)")
    try:
        ok = _digest(doc["data"]) == doc["sha"]
    except ValueError:
        ok = False
    if not ok:
        raise ValueError("checksum does not match: the line was changed or damaged")
    return doc["data"]


def check_record(record: Any, n: int) -> None:
    """ValueError unless ``record`` is the ``n``-th fixed sensor's record."""
    if not isinstance(record, dict):
        raise ValueError("a record must be a JSON object")
    for key in RECORD_NUMBERS + RECORD_COUNTS:
        value = record.get(key)
        if isinstance(value, bool) or not isinstance(value, (int, float)):
            raise ValueError(f"record {key} must be a number, got {value!r}")
        if not abs(value) < 1e15:  # NaN, inf and ints too big for a float fail here too
            raise ValueError(f"record {key} must be finite and below 1e15, got {value!r:.20}")
    for key in RECORD_COUNTS:
        if not isinstance(record[key], int) or record[key] < 0:
            raise ValueError(f"record {key} must be a count, got {record[key]!r}")
    if record["n"] != n:
        raise ValueError(f"record of sensor {record['n']} where sensor {n} belongs")


class Checkpoint:
    """Append-only JSON-lines file in the output folder; ``header`` as made by
    ``checkpoint_header``."""

    def __init__(self, out_dir: Path, header: dict[str, Any]) -> None:
        self.path = out_dir / NAME
        self.header = header
        self._started = False
        self._valid_bytes: int | None = None  # resume: where the complete lines end

    def start(self) -> None:
        """Begin a fresh checkpoint (any old one, or a link of that name, is replaced)."""
        write_files({self.path: encode_line(self.header)})
        self._started = True

    def _read(self) -> bytes:
        """The file's bytes, not through a link; InputError saying why not."""
        try:
            fd = open_no_link(self.path, os.O_RDONLY, "read it")
        except FileNotFoundError:
            raise InputError(f"{self.path}: no checkpoint to resume from") from None
        with os.fdopen(fd, "rb") as f:
            try:
                return f.read()
            except IsADirectoryError:
                raise InputError(f"{self.path}: is a folder, not a checkpoint") from None

    def kept_text(self, optimizer: str) -> str:
        """What an interruption keeps, as the file stands now (one line's words)."""
        if not self._started:
            earlier = " (the checkpoint there is as it was)" if os.path.lexists(self.path) else ""
            later = " (lp fixes its sensors once its plan is done)" if optimizer == "lp" else ""
            return f"nothing kept: no sensor had been fixed yet{later}{earlier}"
        try:
            lines = self._read().count(b"\n")
        except InputError as e:
            return f"the checkpoint cannot be read back ({e})"
        fixed = max(lines - 1, 0)
        return (
            f"{fixed} sensor(s) kept in {self.path}; the same command with --resume goes "
            "on from them"
        )

    def resume(self, repair: bool = False) -> list[dict[str, Any]]:
        """The records of an earlier run with the same header; InputError otherwise.

        Reads only: the file changes when the next record is appended (a cut-short last
        line is dropped then), or here with ``repair`` (see the module docstring).
        """
        raw = self._read()
        lines = raw.splitlines(keepends=True)
        if lines and not lines[-1].endswith(b"\n"):
            lines.pop()  # cut short by a crash while it was written
        parsed: list[Any] = []
        damaged = False
        for number, line in enumerate(lines, start=1):
            try:
                data = decode_line(line)
                if number == 1 and not isinstance(data, dict):
                    raise ValueError("the header must be a JSON object")
                if number > 1:
                    check_record(data, number - 1)
            except ValueError as e:
                if not repair:
                    kept = max(number - 2, 0)
                    raise InputError(
                        f"{self.path}: line {number} is damaged: {e}; the file is left as it "
                        f"was; --resume --repair keeps the {kept} record(s) before it"
                    ) from None
                if number == 1:
                    raise InputError(
                        f"{self.path}: line 1 (the header) is damaged: {e}; nothing to keep, "
                        "run without --resume"
                    ) from None
                damaged = True
                break
            parsed.append(data)
        if not parsed:
            raise InputError(f"{self.path}: empty checkpoint")
        header, records = parsed[0], parsed[1:]
        differs = {
            "a different scene": header.get("scene_fingerprint")
            != self.header["scene_fingerprint"],
            "a different model": header.get("model") != self.header.get("model")
            or header.get("models") != self.header.get("models"),
            "different settings": _settings(header.get("settings", {}))
            != _settings(self.header["settings"]),
            "different existing sensors": header.get("existing") != self.header.get("existing")
            or header.get("existing_masts") != self.header.get("existing_masts"),
        }
        for what, differ in differs.items():
            if differ:
                raise InputError(
                    f"{self.path}: made with {what}; run without --resume to start again"
                )
        if damaged:
            self._keep_prefix(raw, lines[: len(parsed)])
        self.header = header
        self._valid_bytes = sum(len(line) for line in lines[: len(parsed)])
        self._started = True
        return records

    def _keep_prefix(self, raw: bytes, lines: list[bytes]) -> None:
        """Keep ``lines`` only, the whole file saved beside it first."""
        damaged = self.path.with_name(NAME + ".damaged")
        write_files({damaged: raw})
        write_files({self.path: b"".join(lines)})

    def append(self, record: dict[str, Any]) -> None:
        """Add one fixed sensor's record (the file is started or trimmed first)."""
        if not self._started:
            self.start()
        line = encode_line(record)
        try:
            fd = open_no_link(self.path, os.O_RDWR, "write it")
        except FileNotFoundError:
            raise InputError(f"{self.path}: cannot write it (removed during the run)") from None
        with os.fdopen(fd, "r+b") as f:
            if self._valid_bytes is not None:
                f.truncate(self._valid_bytes)  # drop a line a crash cut short
                self._valid_bytes = None
            f.seek(0, os.SEEK_END)
            f.write(line.encode("utf-8"))
            f.flush()
            os.fsync(f.fileno())
