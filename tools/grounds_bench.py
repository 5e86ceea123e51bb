"""Whole grounds planned as a user plans them, with time, memory, coverage and gap.

``python -m tools.grounds_bench [--grounds two_routes,tiles1,...]``: each
ground is planned by the command line at its defaults (``headless optimize X.blend``:
1 m grid, lp, cost), one at a time, in a process of its own, then its plan is
counted again by ``headless coverage``. The grounds:

- ``two_routes``: the sample;
- ``tilesN``: the first N tiles of ``full_ground`` (N = 1, 3, 6 or 12), the other
  tiles' target and sensor-area curves deleted from a copy of the sample;
- ``Town01``, ``Town04``: ``tests/data/xodr/TownXX.xodr`` imported at the defaults
  (``headless import-xodr``).

Per ground: target m^2 and points, parts, wall seconds (the whole command, Blender's
start included), peak resident memory of the planning process (``os.wait4``: its own
``ru_maxrss``; this driver imports neither bpy nor numpy, so nothing large is counted
from before its exec), the plan (sensors, masts, cost), its proven bound and gap,
its coverage and the coverage ``headless coverage`` counts for the written plan. The
figures go to ``bench/grounds.json`` (``--out``) and a table is printed.
"""

from __future__ import annotations

import argparse
import json
import os
import re
import subprocess
import sys
import tempfile
import time
from datetime import date
from pathlib import Path
from typing import Any

from headless.paths import REPO, SAMPLES
from tools.machine import machine_line

GROUNDS = ("two_routes", "tiles1", "tiles3", "tiles6", "tiles12", "Town01", "Town04")
XODR = REPO / "tests" / "data" / "xodr"

# Keeps the targets and sensor areas of full_ground's first N tiles (run by bpy).
ONLY_TILES = """
import sys, bpy
src, out, n = sys.argv[-3], sys.argv[-2], int(sys.argv[-1])
bpy.ops.wm.open_mainfile(filepath=src)
keep = tuple(f"_T{t:02d}_" for t in range(1, n + 1))
for ob in list(bpy.data.objects):
    low = ob.name.lower()
    if (low.startswith("target") or low.startswith("sensorarea")) and not any(
        k in ob.name for k in keep
    ):
        bpy.data.objects.remove(ob, do_unlink=True)
bpy.ops.wm.save_as_mainfile(filepath=out)
"""


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--grounds", default=",".join(GROUNDS), help="comma-separated")
    parser.add_argument("--out", default=str(REPO / "bench" / "grounds.json"))
    parser.add_argument("--keep", help="a folder for the scenes and runs (default: temporary)")
    parser.add_argument(
        "--args", default="", help="more arguments for every optimize run, e.g. '--time-limit 600'"
    )
    args = parser.parse_args(argv)
    names = [g for g in args.grounds.split(",") if g]
    for g in names:
        if g not in GROUNDS:
            parser.error(f"--grounds: {g!r} is none of {', '.join(GROUNDS)}")
    rows = []
    with tempfile.TemporaryDirectory(prefix="grounds-") as tmp:
        work = Path(args.keep or tmp)
        work.mkdir(parents=True, exist_ok=True)
        for name in names:
            row = plan_ground(name, work, args.args.split())
            rows.append(row)
            print(row_text(row), flush=True)
    figures = {
        "date": date.today().isoformat(),
        "machine": machine_line(),
        "load_before": round(os.getloadavg()[0], 1),
        "command": "python -m headless optimize X.blend --out-dir D " + args.args,
        "grounds": rows,
    }
    out = Path(args.out)
    if out.exists():  # keep the grounds not run this time
        old = json.loads(out.read_text()).get("grounds", [])
        ran = {r["ground"] for r in rows}
        figures["grounds"] = [r for r in old if r["ground"] not in ran] + rows
    out.write_text(json.dumps(figures, indent=1) + "\n")
    print(f"-> {out}")
    return 0


def scene_of(name: str, work: Path) -> Path:
    """The .blend of ground ``name``, made in ``work`` where it is not a sample."""
    if name == "two_routes":
        return SAMPLES / "two_routes.blend"
    blend = work / f"{name}.blend"
    if blend.exists():
        return blend
    if name.startswith("tiles"):
        _python("-c", ONLY_TILES, str(SAMPLES / "full_ground.blend"), str(blend), name[5:])
    else:
        _python("-m", "headless", "import-xodr", str(XODR / f"{name}.xodr"), "--out", str(blend))
    return blend


def _python(*args: str) -> None:
    subprocess.run([sys.executable, *args], check=True, capture_output=True, text=True)


def plan_ground(name: str, work: Path, extra: list[str]) -> dict[str, Any]:
    """Plan ground ``name`` with the command line and count its plan again."""
    blend = scene_of(name, work)
    out = work / f"{name}_run"
    cmd = [sys.executable, "-m", "headless", "optimize", str(blend), "--out-dir", str(out)]
    cmd += ["--overwrite", *extra]
    logs = work / f"{name}_stdout.txt", work / f"{name}_stderr.txt"
    t0 = time.perf_counter()
    with logs[0].open("w") as so, logs[1].open("w") as se:
        proc = subprocess.Popen(cmd, stdout=so, stderr=se)
        # wait4: this child's own rusage (ru_maxrss: its peak resident set, KiB)
        _, status, usage = os.wait4(proc.pid, 0)
    wall = time.perf_counter() - t0
    code = os.waitstatus_to_exitcode(status)
    proc.returncode = code  # reaped here, not by Popen
    stdout, stderr = logs[0].read_text(), logs[1].read_text()
    if code not in (0, 3):
        raise RuntimeError(f"{name}: optimize exited {code}:\n{stderr[-2000:]}")
    result = json.loads((out / "result.json").read_text())
    m = result["metrics"]
    counted = out / "recount.json"
    _python(
        "-m", "headless", "coverage", str(blend), "--sensors", str(out / "result.json"),
        "--out", str(counted), "--overwrite",
    )  # fmt: skip
    again = json.loads(counted.read_text())["metrics"]
    parts = re.search(r"in (\d+) parts", stderr)
    return {
        "ground": name,
        "target_m2": m["target_area_m2"],
        "parts": int(parts.group(1)) if parts else 1,
        "wall_s": round(wall, 1),
        "peak_rss_gib": round(usage.ru_maxrss / 2**20, 2),
        "sensors": m["sensors"],
        "masts": m["masts"],
        "cost": m["cost"],
        "lower_bound": m["lower_bound"],
        "gap": m["gap"],
        "sensors_lower_bound": m["sensors_lower_bound"],
        "masts_lower_bound": m["masts_lower_bound"],
        "coverage": m["coverage_fraction"],
        "coverage_recounted": again["coverage_fraction"],
        "stop_reason": result["stop_reason"],
        "last_line": stdout.strip().splitlines()[0] if stdout.strip() else "",
    }


def row_text(r: dict[str, Any]) -> str:
    gap = "" if r["gap"] is None else f", gap {r['gap']:.1%}"
    return (
        f"{r['ground']}: {r['target_m2']:,.0f} m^2 in {r['parts']} part(s): {r['sensors']} "
        f"sensors on {r['masts']} masts, cost {r['cost']:g} >= {r['lower_bound']}{gap}; "
        f"coverage {r['coverage']:.2%} (recounted {r['coverage_recounted']:.2%}); "
        f"{r['wall_s']:.0f} s, peak {r['peak_rss_gib']:.2f} GiB"
    )


if __name__ == "__main__":
    sys.exit(main())
