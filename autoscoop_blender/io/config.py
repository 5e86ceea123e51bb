"""The optimize config file (TOML): settings and the sensor model.

Top-level keys are the knobs of ``core.settings.OptimizeSettings`` plus ``model`` (a
preset name or a table of model keys) or ``models``, a mixed pack: a list of such
models, each table with an optional ``sensor_cost`` (``core.model.sensors.SensorPack``),
e.g. ``models = ["paper_camera", {preset = "roadside_lidar", sensor_cost = 4}]``; the
tables ``[es]`` and ``[fitness]`` hold
those groups' knobs. What a key means and which values it takes is defined once, in
``core/settings.py``.
"""

from __future__ import annotations

import tomllib
from pathlib import Path

from ..core.errors import InputError
from ..core.model.sensors import PAPER_CAMERA, SensorModel, SensorPack
from ..core.settings import OptimizeSettings


def load_config(path: str | Path | None) -> tuple[OptimizeSettings, SensorModel | SensorPack]:
    """Settings and sensor model (a pack when the file gives ``models``) from a TOML
    file (the defaults without one); InputError naming the file and the key for
    anything wrong in it."""
    if path is None:
        return OptimizeSettings(), PAPER_CAMERA
    p = Path(path)
    if not p.is_file():
        raise InputError(f"{path}: config file not found")
    try:
        data = tomllib.loads(p.read_text(encoding="utf-8"))
    except (tomllib.TOMLDecodeError, UnicodeDecodeError) as e:
        raise InputError(f"{p.name}: not valid TOML ({e})") from None
    except (ValueError, RecursionError) as e:  # an integer too long to read, nesting too deep
        raise InputError(f"{p.name}: not readable TOML ({str(e).splitlines()[0]})") from None
    if "model" in data and "models" in data:
        raise InputError(f"{p.name}: give either model or models, not both")
    model: SensorModel | SensorPack
    if "models" in data:
        model = SensorPack.from_spec(data.pop("models"), f"{p.name}: models")
    else:
        model = SensorModel.from_spec(data.pop("model", "paper_camera"), f"{p.name}: model")
    return OptimizeSettings.from_mapping(data, p.name), model
