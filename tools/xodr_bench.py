"""``bench xodr``: each OpenDRIVE file of ``tests/data/xodr`` imported and planned.

Per file: the import's seconds (reading and geometry, and the whole command with
Blender's data and the .blend written), roads, the targets' area (their union, what a
run covers) against the chosen lanes' own areas summed road by road, the sensor areas,
then ``optimize`` with lp (the default) and greedy: sensors, masts, coverage, cost, the
proven lower bound, seconds and the planning process's peak resident memory (its own
``ru_maxrss``; it would count this driver's memory at the fork only were that larger
than anything after the exec). Into ``bench/xodr.json``; the docs' benchmarks quote it.
"""

from __future__ import annotations

import argparse
import json
import os
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
# Each file is planned by the default (lp) and by greedy; both plan the towns in parts
# (Town04: 8, about 27 minutes for lp at its default time limit).
OPTIMIZERS = ("lp", "greedy")


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


def imported_blend(path: Path, tmp: Path) -> Path:
    """``headless import-xodr`` of ``path`` at the defaults into ``tmp``: the .blend."""
    blend = tmp / f"{path.stem}.blend"
    _headless("import-xodr", path, "--out", blend)
    return blend


def _optimize(blend: Path, optimizer: str, out: Path) -> tuple[float, int]:
    """``headless optimize`` of ``blend`` with ``optimizer``: its wall seconds and its
    process's own peak resident memory, bytes (``os.wait4``: the child's rusage)."""
    cmd = [sys.executable, "-m", "headless", "optimize", str(blend), "--optimizer", optimizer]
    t0 = time.perf_counter()
    proc = subprocess.Popen(
        [*cmd, "--out-dir", str(out)],
        cwd=REPO, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, text=True,
    )  # fmt: skip
    assert proc.stderr is not None
    stderr = proc.stderr.read()
    _, status, usage = os.wait4(proc.pid, 0)
    proc.returncode = os.waitstatus_to_exitcode(status)  # reaped here, not by Popen
    if proc.returncode != 0:
        raise RuntimeError(f"{blend.name}: optimize exited {proc.returncode}:\n{stderr[-2000:]}")
    return time.perf_counter() - t0, usage.ru_maxrss * 1024


def _file_row(name: str, tmp: Path) -> dict[str, Any]:
    path = XODR / f"{name}.xodr"
    t0 = time.perf_counter()
    imported = build_import(read_opendrive(path))
    geometry_s = time.perf_counter() - t0
    union = shapely.union_all([area_from_rings(a.name, a.rings) for a in imported.targets])
    bands = shapely.union_all([area_from_rings(a.name, a.rings) for a in imported.sensor_areas])
    t0 = time.perf_counter()
    blend = imported_blend(path, tmp)
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
    for optimizer in OPTIMIZERS:
        out = tmp / f"{name}_{optimizer}"
        seconds, peak = _optimize(blend, optimizer, out)
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
                "peak_rss_gib": round(peak / 2**30, 2),
            }
        )
    return row
