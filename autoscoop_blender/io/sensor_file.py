"""The sensors file: a model and a list of poses, as JSON.

    {"model": "paper_camera" | {model keys...},
     "sensors": [{"x": .., "y": .., "pitch_deg": .., "yaw_deg": ..,
                  "height_m": .. (optional), "model": .. (optional)}, ...],
     "masts": [{"x": .., "y": ..}, ...] (optional)}

``x``, ``y`` are world metres; ``height_m`` is the mast height above the ground under
the sensor (default: the sensor area's ``height_m`` if it stands in one that has it,
else the model's mount height); angles in degrees as in ``sensors``. ``masts`` are
read only where the file names what stands already (``read_existing``): masts with
free slots.

Every number must be finite: ``x``, ``y`` within ``MAX_COORD_M`` (10,000 km) of the
origin, ``height_m`` in [0, ``MAX_RANGE_M``], ``pitch_deg`` in [-90, 90]. Any other
key is refused, naming the closest known one.
"""

from __future__ import annotations

import json
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from ..core.checks import check_keys, number
from ..core.errors import InputError
from ..core.model.sensors import MAX_COORD_M, MAX_RANGE_M, SensorModel, SensorSpec
from . import result_fields
from .reports import RESULT_SCHEMA

TOP_KEYS = ("model", "sensors", "masts")
SENSOR_KEYS = ("x", "y", "height_m", "pitch_deg", "yaw_deg", "model")
# A result.json (``reports.result_dict``) is a sensors file too: besides ``model`` and
# ``sensors`` it carries the other keys of ``result_fields.RESULT``, and in each sensor
# and mast those of ``SENSOR`` and ``MAST``, which are not read.
RESULT_TOP_KEYS = tuple(k for k in result_fields.RESULT if k not in TOP_KEYS)
# Masts that stand already (``read_existing``); a result.json's carry more keys.
MAST_KEYS = ("x", "y")
RESULT_MAST_KEYS = tuple(k for k in result_fields.MAST if k not in MAST_KEYS)
RESULT_SENSOR_KEYS = tuple(k for k in result_fields.SENSOR if k not in SENSOR_KEYS)


def read_sensors(path: str | Path) -> list[SensorSpec]:
    """Parse a sensors file; InputError naming the file and entry for any fault."""
    p = Path(path)
    return parse_sensors(_load(p), p.name)


@dataclass(frozen=True)
class Standing:
    """What a file says stands already: sensors (world metres; the list may be empty),
    masts with free slots (world x, y) and, for a result.json, the fingerprint of the
    targets it was planned for (``SceneModel.targets_fingerprint``; None: not given)."""

    sensors: list[SensorSpec]
    masts: list[tuple[float, float]]
    targets_fingerprint: str | None = None


def read_existing(path: str | Path) -> Standing:
    """What stands already, from a sensors file or a result.json: its sensors and its
    ``masts`` (each ``{"x": .., "y": ..}``; a result.json's masts are where its
    sensors stand)."""
    p = Path(path)
    data = _load(p)
    specs = parse_sensors(data, p.name, allow_empty=True)
    masts = []
    items = data.get("masts", [])
    if not isinstance(items, list):
        raise InputError(f"{p.name}: 'masts' must be a list of objects with x and y")
    for k, item in enumerate(items, start=1):
        where = f"{p.name}: mast {k}"
        if not isinstance(item, dict):
            raise InputError(f"{where}: expected an object with x and y")
        check_keys(item, MAST_KEYS + RESULT_MAST_KEYS, where, "mast")
        masts.append((_coordinate(item, "x", where), _coordinate(item, "y", where)))
    if not specs and not masts:
        raise InputError(f"{p.name}: neither 'sensors' nor 'masts' lists anything")
    fingerprint = data.get("targets_fingerprint")
    return Standing(specs, masts, fingerprint if isinstance(fingerprint, str) else None)


def _load(p: Path) -> Any:
    """The decoded JSON of a file; InputError naming the file for any fault."""
    if p.is_dir():
        raise InputError(f"{p}: is a directory, not a sensors file")
    if not p.is_file():
        raise InputError(f"{p}: sensors file not found")
    try:
        text = p.read_text(encoding="utf-8")
    except OSError as e:
        raise InputError(f"{p}: cannot read the sensors file ({e.strerror})") from None
    except UnicodeDecodeError as e:
        raise InputError(f"{p.name}: not valid JSON ({e})") from None
    try:
        data = json.loads(text)
    except json.JSONDecodeError as e:
        raise InputError(f"{p.name}: not valid JSON ({e})") from None
    except ValueError as e:  # an integer of more than 4300 digits
        raise InputError(f"{p.name}: not valid JSON ({str(e).split(';')[0]})") from None
    except RecursionError:
        raise InputError(f"{p.name}: not valid JSON (nested too deeply)") from None
    return data


def parse_sensors(data: Any, label: str, allow_empty: bool = False) -> list[SensorSpec]:
    """Sensors from already-decoded JSON ``data``; ``label`` names it in errors.

    Unknown keys are refused with the closest known one (a misspelt ``heigth_m``
    would otherwise be ignored); a result.json's own keys are allowed in one.
    allow_empty: an empty (or missing) ``sensors`` list is no error.
    """
    if not isinstance(data, dict):
        raise InputError(f"{label}: expected an object with 'model' and 'sensors'")
    is_result = data.get("schema") == RESULT_SCHEMA
    check_keys(data, TOP_KEYS + RESULT_TOP_KEYS if is_result else TOP_KEYS, label, "top-level")
    items = data.get("sensors", [] if allow_empty else None)
    if not isinstance(items, list) or not (items or allow_empty):
        raise InputError(f"{label}: 'sensors' must be a non-empty list")
    default = SensorModel.from_spec(data["model"], f"{label}: model") if "model" in data else None
    sensor_keys = SENSOR_KEYS + RESULT_SENSOR_KEYS if is_result else SENSOR_KEYS
    specs = []
    for k, item in enumerate(items, start=1):
        where = f"{label}: sensor {k}"
        if not isinstance(item, dict):
            raise InputError(f"{where}: expected an object with x, y, pitch_deg, yaw_deg")
        check_keys(item, sensor_keys, where, "sensor")
        if "model" in item:
            model = SensorModel.from_spec(item["model"], f"{where}: model")
        elif default is not None:
            model = default
        else:
            raise InputError(f"{where}: no model (give 'model' at the top or per sensor)")
        x, y = _coordinate(item, "x", where), _coordinate(item, "y", where)
        pitch = number(_get(item, "pitch_deg", where), "pitch_deg", where)
        if not -90.0 <= pitch <= 90.0:
            raise InputError(f"{where}: pitch_deg {pitch} not in [-90, 90]")
        yaw = number(_get(item, "yaw_deg", where), "yaw_deg", where) % 360.0
        height = None
        if "height_m" in item:
            height = number(
                item["height_m"], "height_m", where, 0.0, MAX_RANGE_M,
                " m (the mast height; no sensor reaches the ground from higher)",
            )  # fmt: skip
        # -1e-20 % 360 rounds to 360.0: keep yaw in [0, 360).
        specs.append(SensorSpec(model, x, y, height, pitch, 0.0 if yaw >= 360.0 else yaw))
    return specs


def _get(item: dict[str, Any], key: str, where: str) -> Any:
    if key not in item:
        raise InputError(f"{where}: missing {key}")
    return item[key]


def _coordinate(item: dict[str, Any], key: str, where: str) -> float:
    return number(
        _get(item, key, where), key, where, -MAX_COORD_M, MAX_COORD_M,
        " m (world coordinates within 10,000 km of the origin)",
    )  # fmt: skip
