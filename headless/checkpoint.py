"""The checkpoint of a long run: one JSON line per fixed sensor, appended as it is fixed.

Line 1 is a header naming what the run depends on (scene fingerprint, model,
settings); every further line is a record from ``core.run.Run``'s ``on_fixed``. A run
interrupted by Ctrl-C or a crash keeps every sensor fixed so far, and ``--resume``
reads them back to go on exactly where it stopped (the records carry the random
generator's state).
"""

from __future__ import annotations

import hashlib
import json
import os
from pathlib import Path
from typing import Any

import numpy as np

from autoscoop_blender.core.errors import InputError
from autoscoop_blender.core.model.scene import SceneModel
from autoscoop_blender.core.model.sensors import SensorModel
from autoscoop_blender.core.settings import OptimizeSettings, from_mapping

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
    scene: SceneModel, model: SensorModel, settings: OptimizeSettings
) -> dict[str, Any]:
    """What a run's answer depends on: the scene (its fingerprint), model and settings."""
    return {
        "scene": scene.source,
        "scene_fingerprint": scene_fingerprint(scene),
        "model": model.to_dict(),
        "settings": settings.to_dict(),
    }


def _settings(stored: Any) -> OptimizeSettings | None:
    """Settings as recorded in a header, read through the schema: a setting missing
    from an older checkpoint ran as its default does, so it reads as the default (at
    any depth). None when they cannot be read (a setting since removed)."""
    try:
        return from_mapping(OptimizeSettings, stored, "checkpoint")
    except InputError:
        return None


class Checkpoint:
    """Append-only JSON-lines file in the output folder; ``header`` as made by
    ``checkpoint_header``."""

    def __init__(self, out_dir: Path, header: dict[str, Any]) -> None:
        self.path = out_dir / NAME
        self.header = header

    def start(self) -> None:
        """Begin a fresh checkpoint (any old one is replaced)."""
        self.path.parent.mkdir(parents=True, exist_ok=True)
        self.path.write_text(json.dumps(self.header) + "\n", encoding="utf-8")

    def resume(self) -> list[dict[str, Any]]:
        """The records of an earlier run with the same header; InputError otherwise."""
        if not self.path.is_file():
            raise InputError(f"{self.path}: no checkpoint to resume from")
        parsed = []
        for line in self.path.read_text(encoding="utf-8").splitlines():
            try:
                parsed.append(json.loads(line))
            except json.JSONDecodeError:
                break  # a crash can cut the last line short: keep the complete ones
        if not parsed:
            raise InputError(f"{self.path}: empty checkpoint")
        header, records = parsed[0], parsed[1:]
        differs = {
            "a different scene": header.get("scene_fingerprint")
            != self.header["scene_fingerprint"],
            "a different model": header.get("model") != self.header["model"],
            "different settings": _settings(header.get("settings", {}))
            != _settings(self.header["settings"]),
        }
        for what, differ in differs.items():
            if differ:
                raise InputError(
                    f"{self.path}: made with {what}; run without --resume to start again"
                )
        # Rewrite without any torn line, so appends follow complete records.
        self.path.write_text(
            "".join(json.dumps(r) + "\n" for r in [header, *records]), encoding="utf-8"
        )
        return records

    def append(self, record: dict[str, Any]) -> None:
        with self.path.open("a", encoding="utf-8") as f:
            f.write(json.dumps(record) + "\n")
            f.flush()
            os.fsync(f.fileno())
