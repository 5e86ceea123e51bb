"""The sensors file: a model and a list of poses, as JSON.

    {"model": "paper_camera" | {model keys...},
     "sensors": [{"x": .., "y": .., "pitch_deg": .., "yaw_deg": ..,
                  "height_m": .. (optional), "model": .. (optional)}, ...]}

``x``, ``y`` are world metres; ``height_m`` is the mast height above the ground under
the sensor (default: the sensor area's ``height_m`` if it stands in one that has it,
else the model's mount height); angles in degrees as in ``sensors``.
"""

from __future__ import annotations

import json
import math
from pathlib import Path
from typing import Any

from ..core.errors import InputError
from ..core.model.sensors import SensorModel, SensorSpec


def read_sensors(path: str | Path) -> list[SensorSpec]:
    """Parse a sensors file; InputError naming the file and entry for any fault."""
    p = Path(path)
    if not p.is_file():
        raise InputError(f"{p}: sensors file not found")
    try:
        data = json.loads(p.read_text(encoding="utf-8"))
    except (json.JSONDecodeError, UnicodeDecodeError) as e:
        raise InputError(f"{p.name}: not valid JSON ({e})") from None
    return parse_sensors(data, p.name)


def parse_sensors(data: Any, label: str) -> list[SensorSpec]:
    """Sensors from already-decoded JSON ``data``; ``label`` names it in errors."""
    if not isinstance(data, dict):
        raise InputError(f"{label}: expected an object with 'model' and 'sensors'")
    items = data.get("sensors")
    if not isinstance(items, list) or not items:
        raise InputError(f"{label}: 'sensors' must be a non-empty list")
    default = SensorModel.from_spec(data["model"], f"{label}: model") if "model" in data else None
    specs = []
    for k, item in enumerate(items, start=1):
        where = f"{label}: sensor {k}"
        if not isinstance(item, dict):
            raise InputError(f"{where}: expected an object with x, y, pitch_deg, yaw_deg")
        if "model" in item:
            model = SensorModel.from_spec(item["model"], f"{where}: model")
        elif default is not None:
            model = default
        else:
            raise InputError(f"{where}: no model (give 'model' at the top or per sensor)")
        x, y = _number(item, "x", where), _number(item, "y", where)
        pitch, yaw = _number(item, "pitch_deg", where), _number(item, "yaw_deg", where)
        if not -90.0 <= pitch <= 90.0:
            raise InputError(f"{where}: pitch_deg {pitch} not in [-90, 90]")
        height = _number(item, "height_m", where) if "height_m" in item else None
        if height is not None and height < 0:
            raise InputError(f"{where}: height_m {height} must be >= 0")
        specs.append(SensorSpec(model, x, y, height, pitch, yaw % 360.0))
    return specs


def _number(item: dict[str, Any], key: str, where: str) -> float:
    if key not in item:
        raise InputError(f"{where}: missing {key}")
    v = item[key]
    if isinstance(v, bool) or not isinstance(v, (int, float)):
        raise InputError(f"{where}: {key} must be a number, got {v!r}")
    if not math.isfinite(v):
        raise InputError(f"{where}: {key} is {v}")
    return float(v)
