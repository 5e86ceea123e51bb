"""``bench constants``: two constants tuned on two_routes, judged on scenes they were
not tuned on (issue 18, part 4).

* ``zeta`` (``[fitness] zeta``, Eq. 1 of the ES's fitness: the value of a target point
  covered already), default 0.02;
* the greedy optimizer's mast preference (a candidate on a mast already used wins if
  it adds at least 1 / (1 + p) of the best), default 0.1: the knob
  ``mast_preference`` where the settings have it, else the module constant
  ``core.optimize.greedy.MAST_PREFERENCE`` patched in the child process.

Scenes: two_routes (where both were tuned, for reference), the first ``TILES``
(``--quick``: 1) tiles of full_ground (as ``bench all`` selects them), and
AstaZero_FlexZoneCrossing imported from ``tests/data/xodr`` with ``headless import-xodr`` (defaults). Each run
is a whole optimization with everything else at its default (ES seed ``--seed``,
one process, no workers) in a fresh spawned process, one at a time; it records
sensors, masts, coverage, cost (the objective's metrics of result.json) and the CPU
seconds of the optimization (scene loading not counted). Into
``bench/constants.json`` (written again after every run, so an interrupted sweep
keeps what it measured) and a table on stdout.
"""

from __future__ import annotations

import argparse
import tempfile
import time
from dataclasses import fields, replace
from datetime import date
from pathlib import Path
from typing import Any

from autoscoop_blender.core.settings import FitnessParams, OptimizeSettings
from headless.devtools.machine import machine_line
from headless.devtools.suite import MODEL, _in_fresh_process, _peak_rss_mb, only_tiles
from headless.files import json_text
from headless.paths import REPO, SAMPLES

ZETAS = (0.0, 0.01, 0.02, 0.05, 0.1)
MAST_PREFERENCES = (0.0, 0.05, 0.1, 0.2, 0.4)
DEFAULT_ZETA = FitnessParams().zeta
DEFAULT_MAST_PREFERENCE = 0.1
# full_ground tiles (``bench all`` runs 3; the ES takes ~25 s a tile here): --quick 1.
TILES = 2
QUICK_TILES = 1
XODR = REPO / "tests" / "data" / "xodr" / "AstaZero_FlexZoneCrossing.xodr"
# (optimizer, constant, values, default)
SWEEPS = (
    ("es", "zeta", ZETAS, DEFAULT_ZETA),
    ("greedy", "mast_preference", MAST_PREFERENCES, DEFAULT_MAST_PREFERENCE),
)


def run(args: argparse.Namespace) -> int:
    out_dir = Path(args.out_dir)
    out_dir.mkdir(parents=True, exist_ok=True)
    path = out_dir / "constants.json"
    tiles = tuple(range(1, (QUICK_TILES if args.quick else TILES) + 1))
    figures: dict[str, Any] = {
        "date": date.today().isoformat(),
        "machine": machine_line(),
        "seed": args.seed,
        "full_ground_tiles": list(tiles),
        "note": (
            "each run: one whole optimization, all else default, in a fresh process, one at "
            "a time; cpu_s: CPU seconds of the optimization (Run), scene loading not counted; "
            "cost = 3 x masts + sensors (the default objective); the ES one seed only"
        ),
        "runs": [],
    }
    with tempfile.TemporaryDirectory() as tmp:
        scenes = _scenes(Path(tmp), tiles)
        for scene, (blend, scene_tiles) in scenes.items():
            for optimizer, constant, values, default in SWEEPS:
                for value in values:
                    row = _in_fresh_process(
                        _point, str(blend), scene_tiles, optimizer, constant, value, args.seed
                    )
                    row = {"scene": scene, "default": value == default, **row}
                    figures["runs"].append(row)
                    print(_line(row), flush=True)
                    figures["summary"] = summary(figures["runs"])
                    path.write_text(json_text(figures))
    print()
    print(table(figures["runs"]))
    for constant, s in figures["summary"].items():
        print(f"{constant}: {s['verdict']}")
    print(f"wrote {path}")
    return 0


def _scenes(tmp: Path, tiles: tuple[int, ...]) -> dict[str, tuple[Path, tuple[int, ...]]]:
    """Scene label -> (.blend, full_ground tiles to keep or ())."""
    import subprocess
    import sys

    blend = tmp / f"{XODR.stem}.blend"
    subprocess.run(
        [sys.executable, "-m", "headless", "import-xodr", str(XODR), "--out", str(blend)],
        cwd=REPO, check=True, capture_output=True,
    )  # fmt: skip
    n = len(tiles)
    return {
        "two_routes": (SAMPLES / "two_routes.blend", ()),
        f"full_ground, {n} tile{'s' if n > 1 else ''}": (SAMPLES / "full_ground.blend", tiles),
        XODR.stem: (blend, ()),
    }


def settings_for(optimizer: str, constant: str, value: float) -> OptimizeSettings:
    """The default settings with ``optimizer`` and one constant set (``zeta``, or the
    greedy's ``mast_preference`` if the settings have that knob)."""
    settings = OptimizeSettings(optimizer=optimizer)
    if constant == "zeta":
        return replace(settings, fitness=replace(settings.fitness, zeta=value))
    if constant in {f.name for f in fields(OptimizeSettings)}:
        return replace(settings, **{constant: value})
    return settings


def _point(
    blend: str, tiles: tuple[int, ...], optimizer: str, constant: str, value: float, seed: int
) -> dict[str, Any]:
    """One optimization in this (spawned) process: its figures."""
    from autoscoop_blender.core.optimize import greedy
    from autoscoop_blender.core.run import Run
    from autoscoop_blender.scene.factory import BVHFactory, forget_blender_script_paths
    from headless.files import load_scene

    forget_blender_script_paths()  # a spawned child: the pip bpy must win
    settings = replace(settings_for(optimizer, constant, value), seed=seed)
    if constant == "mast_preference":
        # Without the knob the module constant decides (read at each pick); with it,
        # the settings do and this changes nothing.
        greedy.MAST_PREFERENCE = value
    scene, _ = load_scene(blend)
    scene = only_tiles(scene, tiles)
    scene = scene.cropped(MODEL.range_m)
    cpu = time.process_time()
    res = Run(scene, BVHFactory.of(scene), MODEL, settings).result()
    cpu = time.process_time() - cpu
    m = res.metrics
    return {
        "optimizer": optimizer,
        "constant": constant,
        "value": value,
        "sensors": m["sensors"],
        "masts": m["masts"],
        "coverage_fraction": m["coverage_fraction"],
        "cost": m["cost"],
        "objective": m["objective"],
        "target_m2": m["target_area_m2"],
        "stop_reason": res.stop_reason,
        "cpu_s": round(cpu, 2),
        "wall_s": m["wall_s"],
        "peak_rss_mb": _peak_rss_mb(),
    }


def _line(r: dict[str, Any]) -> str:
    mark = "*" if r["default"] else " "
    return (
        f"{r['scene']:<28}{r['optimizer']:<7}{r['constant']:>16} = {r['value']:<5g}{mark}"
        f"{r['sensors']:>6}{r['masts']:>6}{100 * r['coverage_fraction']:>9.2f}"
        f"{r['cost']:>7g}{r['cpu_s']:>8.1f}"
    )


def table(runs: list[dict[str, Any]]) -> str:
    head = (
        f"{'scene':<28}{'opt':<7}{'constant':>16}   {'value':<6}{'sens':>6}{'masts':>6}"
        f"{'cover %':>9}{'cost':>7}{'CPU s':>8}"
    )
    return "\n".join([head, "-" * len(head), *map(_line, runs), "(* the default)"])


def summary(runs: list[dict[str, Any]]) -> dict[str, Any]:
    """Per constant and value: the cost summed over the scenes, the mean of cost over
    the default's cost scene by scene, and on how many scenes it is the cheapest (ties
    count for each); the verdict names the value with the lowest mean ratio, the
    default on ties, over the scenes where every value has run."""
    out: dict[str, Any] = {}
    for _, constant, values, default in SWEEPS:
        rows = [r for r in runs if r["constant"] == constant]
        scenes = [
            s
            for s in dict.fromkeys(r["scene"] for r in rows)
            if {r["value"] for r in rows if r["scene"] == s} == set(values)
        ]
        if not scenes:
            continue
        cost = {(r["scene"], r["value"]): r["cost"] for r in rows}
        best = {s: min(cost[s, v] for v in values) for s in scenes}
        per_value = {}
        for v in values:
            per_value[f"{v:g}"] = {
                "total_cost": sum(cost[s, v] for s in scenes),
                "mean_cost_vs_default": round(
                    sum(cost[s, v] / cost[s, default] for s in scenes) / len(scenes), 4
                ),
                "cheapest_on": sum(cost[s, v] == best[s] for s in scenes),
            }
        winner = min(
            values, key=lambda v: (per_value[f"{v:g}"]["mean_cost_vs_default"], v != default)
        )
        verdict = (
            f"the default {default:g} holds"
            if winner == default
            else f"{winner:g} beats the default {default:g} "
            f"(mean cost {per_value[f'{winner:g}']['mean_cost_vs_default']:.3f} of the default's)"
        )
        out[constant] = {
            "scenes": scenes,
            "default": default,
            "values": per_value,
            "winner": winner,
            "verdict": f"{verdict} on {len(scenes)} scene{'s' if len(scenes) > 1 else ''}",
        }
    return out
