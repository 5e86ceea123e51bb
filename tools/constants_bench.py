"""``bench constants``: two constants tuned on two_routes, judged on scenes they were
not tuned on (issue 18, part 4).

* the greedy optimizer's mast preference p (a candidate on a mast already used wins if
  it adds at least 1 / (1 + p) of the best): ``core.optimize.greedy.MAST_PREFERENCE``
  (one value, or one per objective), patched in the child process for every objective.
  Swept over ``--preferences`` with the cost objective, and over the fewer
  ``--objective-preferences`` with the ``sensors`` and the ``masts`` objectives. The
  greedy is deterministic: one run per value and scene;
* ``zeta`` (``[fitness] zeta``, Eq. 1 of the ES's fitness: the value of a target point
  covered already): ``--zetas``, each with the ES seeds ``--seed`` .. ``--seed`` +
  ``--seeds`` - 1, since one seed's answer differs from the next's by as much as the
  values of zeta do.

Scenes: two_routes (where both were tuned, for reference), the first ``TILES``
(``--quick``: 1) tiles of full_ground (as ``bench all`` selects them), the next tile of
full_ground on its own (added after the first sweep, as a scene that picked nothing), and
AstaZero_FlexZoneCrossing imported from ``tests/data/xodr`` with ``headless import-xodr``
(defaults). Each run is a whole optimization with everything else at its default (one
process, no workers) in a fresh spawned process, one at a time; it records sensors,
masts, coverage, cost (3 x masts + sensors), the objective's value and the CPU seconds
of the optimization (scene loading not counted). Into ``bench/constants.json``,
written again after every run, so an interrupted sweep keeps what it measured;
``--resume`` keeps the runs already there and runs only the missing ones (with
nothing missing it only recomputes the summary, e.g. after a default changed).

The summary, per greedy objective: for each value the objective's mean ratio to the
scene's best over the scenes where every value ran, on how many scenes it is the best,
and the values that are best on every scene. Per zeta and scene: mean, sample standard
deviation and range of the cost over the seeds; a zeta beats the default on a scene
when its mean cost is lower by more than the larger of the two standard deviations.
"""

from __future__ import annotations

import argparse
import json
import statistics
import tempfile
import time
from collections.abc import Mapping
from dataclasses import asdict, dataclass, fields, replace
from datetime import date
from pathlib import Path
from typing import Any

from autoscoop_blender.core.settings import FitnessParams, OptimizeSettings
from headless.files import json_text
from headless.paths import REPO, SAMPLES
from tools.machine import machine_line
from tools.suite import MODEL, _in_fresh_process, _peak_rss_mb, only_tiles

# Up to 100: the masts keep falling as the preference rises.
PREFERENCES = (
    *(0.0, 0.05, 0.1, 0.2, 0.4, 0.5, 0.6, 0.7, 0.8, 1.0),
    *(1.5, 2.0, 3.0, 5.0, 10.0, 30.0, 100.0),
)
# The sensors and masts objectives: a few values only.
OBJECTIVE_PREFERENCES = (0.0, 0.1, 0.4, 0.6, 1.0)
OTHER_OBJECTIVES = ("sensors", "masts")
ZETAS = (0.02, 0.05, 0.1)
DEFAULT_ZETA = FitnessParams().zeta
SEEDS = 4
# full_ground tiles (``bench all`` runs 3; the ES takes ~25 s a tile here): --quick 1.
TILES = 2
QUICK_TILES = 1
XODR = REPO / "tests" / "data" / "xodr" / "AstaZero_FlexZoneCrossing.xodr"


@dataclass(frozen=True)
class Point:
    """One run: an optimizer with one constant set, under an objective, with a seed
    (the greedy ignores it)."""

    optimizer: str
    constant: str
    value: float
    objective: str
    seed: int


def plan(args: argparse.Namespace) -> list[Point]:
    """The runs of a sweep, scene by scene within each line: the greedy with the cost
    objective, the ES seed by seed, then the greedy with the other objectives (so an
    interrupted sweep has whole seeds and the deciding figures first)."""
    prefs = _values(args, "preferences", PREFERENCES)
    other = _values(args, "objective_preferences", OBJECTIVE_PREFERENCES)
    zetas = _values(args, "zetas", ZETAS)
    seeds = range(args.seed, args.seed + (getattr(args, "seeds", None) or SEEDS))
    greedy = [Point("greedy", "mast_preference", v, "cost", args.seed) for v in prefs]
    es = [[Point("es", "zeta", z, "cost", s) for z in zetas] for s in seeds]
    others = [
        Point("greedy", "mast_preference", v, o, args.seed) for o in OTHER_OBJECTIVES for v in other
    ]
    return [p for line in (greedy, *es, others) if line for p in line]


def _values(args: argparse.Namespace, name: str, default: tuple[float, ...]) -> tuple[float, ...]:
    given = getattr(args, name, None)
    return default if given is None else tuple(given)


def run(args: argparse.Namespace) -> int:
    out_dir = Path(args.out_dir)
    out_dir.mkdir(parents=True, exist_ok=True)
    path = out_dir / "constants.json"
    tiles = tuple(range(1, (QUICK_TILES if args.quick else TILES) + 1))
    kept = json.loads(path.read_text())["runs"] if args.resume and path.exists() else []
    kept = [r for r in kept if "seed" in r and "objective" in r]  # not the older rows
    figures: dict[str, Any] = {
        "date": date.today().isoformat(),
        "machine": machine_line(),
        "full_ground_tiles": [list(tiles), [len(tiles) + 1]],
        "note": (
            "each run: one whole optimization, all else default, in a fresh process, one at "
            "a time; cpu_s: CPU seconds of the optimization (Run), scene loading not counted; "
            "cost = 3 x masts + sensors; objective: the value of the run's objective; the "
            "greedy is deterministic (its seed plays no part), the ES one run per seed"
        ),
        "runs": kept,
    }
    done = {_key(r) for r in kept}
    with tempfile.TemporaryDirectory() as tmp:
        scenes = _scenes(Path(tmp), tiles)
        for point in plan(args):
            for scene, (blend, scene_tiles) in scenes.items():
                if (scene, *asdict(point).values()) in done:
                    continue
                row = _in_fresh_process(_point, str(blend), scene_tiles, point)
                row = {"scene": scene, **row}
                figures["runs"].append(row)
                print(_line(row), flush=True)
                figures["summary"] = summary(figures["runs"])
                path.write_text(json_text(figures))
    figures["summary"] = summary(figures["runs"])
    path.write_text(json_text(figures))
    print()
    print(table(figures["runs"]))
    print()
    print(zeta_table(figures["summary"]))
    for name, s in figures["summary"].items():
        print(f"{name}: {s['verdict']}")
    print(f"wrote {path}")
    return 0


def _key(row: Mapping[str, Any]) -> tuple[Any, ...]:
    return tuple(row[k] for k in ("scene", *(f.name for f in fields(Point))))


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
        f"full_ground, tile {n + 1}": (SAMPLES / "full_ground.blend", (n + 1,)),
        XODR.stem: (blend, ()),
    }


def settings_for(point: Point) -> OptimizeSettings:
    """The default settings with the point's optimizer, objective, seed and constant
    (``zeta``, or the greedy's ``mast_preference`` if the settings have that knob)."""
    settings = OptimizeSettings(optimizer=point.optimizer, objective=point.objective)
    settings = replace(settings, seed=point.seed)
    if point.constant == "zeta":
        return replace(settings, fitness=replace(settings.fitness, zeta=point.value))
    if point.constant in {f.name for f in fields(OptimizeSettings)}:
        return replace(settings, **{point.constant: point.value})
    return settings


def set_mast_preference(value: float) -> None:
    """Patch the greedy's module constant to ``value`` for every objective (it is read
    at each pick). A knob in the settings, if there were one, would decide instead."""
    from autoscoop_blender.core.optimize import greedy

    old = greedy.MAST_PREFERENCE
    greedy.MAST_PREFERENCE = {k: value for k in old} if isinstance(old, Mapping) else value


def default_mast_preference(objective: str) -> float:
    from autoscoop_blender.core.optimize import greedy

    p = greedy.MAST_PREFERENCE
    return p[objective] if isinstance(p, Mapping) else p


def _point(blend: str, tiles: tuple[int, ...], point: Point) -> dict[str, Any]:
    """One optimization in this (spawned) process: its figures."""
    from autoscoop_blender.core.run import Run
    from autoscoop_blender.scene.factory import BVHFactory, forget_blender_script_paths
    from headless.files import load_scene

    forget_blender_script_paths()  # a spawned child: the pip bpy must win
    if point.constant == "mast_preference":
        set_mast_preference(point.value)
    scene, _ = load_scene(blend)
    scene = only_tiles(scene, tiles)
    scene = scene.cropped(MODEL.range_m)
    cpu = time.process_time()
    res = Run(scene, BVHFactory.of(scene), MODEL, settings_for(point)).result()
    cpu = time.process_time() - cpu
    m = res.metrics
    return {
        **asdict(point),
        "sensors": m["sensors"],
        "masts": m["masts"],
        "coverage_fraction": m["coverage_fraction"],
        "cost": m["cost"],
        "objective_value": m["objective"],
        "target_m2": m["target_area_m2"],
        "stop_reason": res.stop_reason,
        "cpu_s": round(cpu, 2),
        "wall_s": m["wall_s"],
        "peak_rss_mb": _peak_rss_mb(),
    }


def _is_default(r: Mapping[str, Any]) -> bool:
    if r["constant"] == "zeta":
        return r["value"] == DEFAULT_ZETA
    return r["value"] == default_mast_preference(r["objective"])


def _line(r: Mapping[str, Any]) -> str:
    mark = "*" if _is_default(r) else " "
    return (
        f"{r['scene'][:26]:<27}{r['optimizer']:<7}{r['objective']:<8}"
        f"{r['constant']:>16} = {r['value']:<5g}{mark}{r['seed']:>5}"
        f"{r['sensors']:>6}{r['masts']:>6}{100 * r['coverage_fraction']:>9.2f}"
        f"{r['cost']:>7g}{r['cpu_s']:>8.1f}"
    )


def table(runs: list[dict[str, Any]]) -> str:
    head = (
        f"{'scene':<27}{'opt':<7}{'obj':<8}{'constant':>16}   {'value':<6}{'seed':>5}"
        f"{'sens':>6}{'masts':>6}{'cover %':>9}{'cost':>7}{'CPU s':>8}"
    )
    return "\n".join([head, "-" * len(head), *map(_line, runs), "(* the default)"])


def zeta_table(s: Mapping[str, Any]) -> str:
    """Cost per scene and zeta over the seeds: mean +- standard deviation [min-max]."""
    z = s.get("zeta")
    if not z:
        return ""
    lines = [f"zeta, cost over {z['seeds']} seeds: mean +- sd [min-max]"]
    for scene, per in z["scenes"].items():
        cells = [
            f"{v}: {c['mean']:.1f} +- {c['sd']:.1f} [{c['min']:g}-{c['max']:g}]"
            for v, c in per.items()
        ]
        lines.append(f"  {scene[:26]:<27}" + ";  ".join(cells))
    return "\n".join(lines)


def summary(runs: list[dict[str, Any]]) -> dict[str, Any]:
    """The greedy per objective (``greedy, cost`` ...) and zeta (see the module
    docstring); a part with too few runs to judge is left out."""
    out: dict[str, Any] = {}
    for objective in ("cost", *OTHER_OBJECTIVES):
        rows = [r for r in runs if r["optimizer"] == "greedy" and r["objective"] == objective]
        part = greedy_summary(rows, objective)
        if part:
            out[f"greedy, {objective}"] = part
    part = zeta_summary([r for r in runs if r["constant"] == "zeta"])
    if part:
        out["zeta"] = part
    return out


def greedy_summary(rows: list[dict[str, Any]], objective: str) -> dict[str, Any]:
    """Per value: the objective's mean ratio to the scene's best, on how many scenes it
    is the best (ties count for each); the winner has the lowest mean ratio (the
    default, then the smaller value, on ties), over the scenes where every value ran."""
    values = sorted({r["value"] for r in rows})
    scenes = [
        s
        for s in dict.fromkeys(r["scene"] for r in rows)
        if {r["value"] for r in rows if r["scene"] == s} == set(values)
    ]
    if len(values) < 2 or not scenes:
        return {}
    default = default_mast_preference(objective)
    got = {(r["scene"], r["value"]): r["objective_value"] for r in rows}
    best = {s: min(got[s, v] for v in values) for s in scenes}
    per_value = {
        f"{v:g}": {
            "total": sum(got[s, v] for s in scenes),
            "mean_vs_best": round(sum(got[s, v] / best[s] for s in scenes) / len(scenes), 4),
            "best_on": sum(got[s, v] == best[s] for s in scenes),
        }
        for v in values
    }
    winner = min(values, key=lambda v: (per_value[f"{v:g}"]["mean_vs_best"], v != default, v))
    everywhere = [v for v in values if per_value[f"{v:g}"]["best_on"] == len(scenes)]
    n = f"{len(scenes)} scene{'s' if len(scenes) > 1 else ''}"
    verdict = (
        f"{winner:g} is the best on average over {n} "
        f"({per_value[f'{winner:g}']['mean_vs_best']:.3f} of each scene's best"
    )
    if default in values:
        verdict += f"; the default {default:g}: {per_value[f'{default:g}']['mean_vs_best']:.3f}"
    verdict += "); best on every scene: " + (
        ", ".join(f"{v:g}" for v in everywhere) if everywhere else "none"
    )
    return {
        "scenes": scenes,
        "default": default,
        "values": per_value,
        "winner": winner,
        "best_everywhere": everywhere,
        "verdict": verdict,
    }


def zeta_summary(rows: list[dict[str, Any]]) -> dict[str, Any]:
    """Per scene and zeta: the cost's mean, sample standard deviation, range over the
    seeds that ran for every zeta there; a zeta beats the default on a scene when its
    mean is lower by more than the larger standard deviation of the two."""
    values = sorted({r["value"] for r in rows})
    per_scene: dict[str, dict[str, Any]] = {}
    n_seeds = 0
    for scene in dict.fromkeys(r["scene"] for r in rows):
        here = [r for r in rows if r["scene"] == scene]
        seeds = set.intersection(*({r["seed"] for r in here if r["value"] == v} for v in values))
        if len(seeds) < 2:
            continue
        n_seeds = max(n_seeds, len(seeds))
        per_scene[scene] = {}
        for v in values:
            cost = [r["cost"] for r in here if r["value"] == v and r["seed"] in seeds]
            per_scene[scene][f"{v:g}"] = {
                "seeds": len(cost),
                "mean": round(statistics.mean(cost), 2),
                "sd": round(statistics.stdev(cost), 2),
                "min": min(cost),
                "max": max(cost),
                "sensors_mean": _mean(here, v, seeds, "sensors"),
                "masts_mean": _mean(here, v, seeds, "masts"),
            }
    if not per_scene or len(values) < 2 or DEFAULT_ZETA not in values:
        return {}
    d = f"{DEFAULT_ZETA:g}"
    beats = {
        f"{v:g}": [
            s
            for s, per in per_scene.items()
            if per[d]["mean"] - per[f"{v:g}"]["mean"] > max(per[d]["sd"], per[f"{v:g}"]["sd"])
        ]
        for v in values
        if v != DEFAULT_ZETA
    }
    everywhere = [v for v, s in beats.items() if len(s) == len(per_scene)]
    verdict = (
        f"{' and '.join(everywhere)} beat{'s' if len(everywhere) == 1 else ''} the default "
        f"{d} beyond the seed spread on all {len(per_scene)} scenes"
        if everywhere
        else f"no zeta beats the default {d} beyond the seed spread on all "
        f"{len(per_scene)} scenes: it holds"
    )
    return {
        "default": DEFAULT_ZETA,
        "seeds": n_seeds,
        "scenes": per_scene,
        "beats_default_on": beats,
        "verdict": verdict,
    }


def _mean(rows: list[dict[str, Any]], value: float, seeds: set[int], key: str) -> float:
    return round(
        statistics.mean(r[key] for r in rows if r["value"] == value and r["seed"] in seeds), 2
    )
