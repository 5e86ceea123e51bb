"""``bench xodr``: each OpenDRIVE file of ``tests/data/xodr`` imported and planned.

Per file: the import's seconds (reading and geometry, and the whole command with
Blender's data and the .blend written), roads, the targets' area (their union, what a
run covers) against the chosen lanes' own areas summed road by road, the sensor areas,
then ``optimize`` with each optimizer asked for: sensors, masts, coverage, cost, the
proven lower bound and seconds. Into ``bench/xodr.json``; the README quotes it.
"""

from __future__ import annotations

import argparse
import json
import subprocess
import sys
import tempfile
import time
from datetime import date
from pathlib import Path
from typing import Any

import shapely

from autoscoop_blender.core.errors import SceneContractError
from autoscoop_blender.core.model.scene import area_from_rings
from autoscoop_blender.io.georef import check_crs
from autoscoop_blender.io.opendrive import build_import, read_opendrive
from headless.files import json_text
from headless.paths import REPO
from tools.machine import machine_line

XODR = REPO / "tests" / "data" / "xodr"
FILES = ("AstaZero_FlexZoneCrossing", "AstaZero_GaragePlanHighRes", "Town01", "Town04")
# lp on the two towns needs more than a bench should wait for (its candidate matrix
# grows with the target: Town04's is ~26 times FlexZoneCrossing's); greedy plans them.
OPTIMIZERS = {
    "AstaZero_FlexZoneCrossing": ("lp", "greedy"),
    "AstaZero_GaragePlanHighRes": ("lp", "greedy"),
}


def run(args: argparse.Namespace) -> int:
    rows = []
    with tempfile.TemporaryDirectory() as tmp:
        for name in FILES:
            rows.append(_file_row(name, Path(tmp)))
            print(json.dumps(rows[-1]), flush=True)
    figures = {"date": date.today().isoformat(), "machine": machine_line(), "files": rows}
    out_dir = Path(args.out_dir)
    out_dir.mkdir(parents=True, exist_ok=True)
    (out_dir / "xodr.json").write_text(json_text(figures))
    return 0


def _usable(crs: str | None) -> bool:
    """Whether the header's geoReference is a CRS the outputs can use."""
    try:
        return check_crs(crs, "bench", "geoReference") is not None
    except SceneContractError:
        return False


def _headless(*args: Any) -> subprocess.CompletedProcess[str]:
    return subprocess.run(
        [sys.executable, "-m", "headless", *map(str, args)],
        cwd=REPO, capture_output=True, text=True, check=True,
    )  # fmt: skip


def _file_row(name: str, tmp: Path) -> dict[str, Any]:
    path = XODR / f"{name}.xodr"
    t0 = time.perf_counter()
    imported = build_import(read_opendrive(path))
    geometry_s = time.perf_counter() - t0
    union = shapely.union_all([area_from_rings(a.name, a.rings) for a in imported.targets])
    bands = shapely.union_all([area_from_rings(a.name, a.rings) for a in imported.sensor_areas])
    blend = tmp / f"{name}.blend"
    t0 = time.perf_counter()
    _headless("import-xodr", path, "--out", blend)
    command_s = time.perf_counter() - t0
    row: dict[str, Any] = {
        "file": path.name,
        "import_geometry_s": round(geometry_s, 2),
        "import_command_s": round(command_s, 2),
        "roads": len(imported.surfaces),
        "targets": len(imported.targets),
        "target_m2": round(union.area, 1),
        "lanes_m2": round(sum(imported.lane_area_m2.values()), 1),
        "sensor_areas": len(imported.sensor_areas),
        "sensor_area_m2": round(bands.area, 1),
        "crs": _usable(imported.crs),
        "warnings": len(imported.warnings),
        "runs": [],
    }
    for optimizer in OPTIMIZERS.get(name, ("greedy",)):
        out = tmp / f"{name}_{optimizer}"
        t0 = time.perf_counter()
        _headless("optimize", blend, "--optimizer", optimizer, "--out-dir", out)
        seconds = time.perf_counter() - t0
        m = json.loads((out / "result.json").read_text())["metrics"]
        row["runs"].append(
            {
                "optimizer": optimizer,
                "sensors": m["sensors"],
                "masts": m["masts"],
                "coverage": m["coverage_fraction"],
                "cost": m["cost"],
                "lower_bound": m["lower_bound"],
                "optimize_s": round(m["wall_s"], 1),
                "command_s": round(seconds, 1),
            }
        )
    return row
