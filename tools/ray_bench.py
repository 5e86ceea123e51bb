"""Ray's part builds, 1 worker against 2, and what that projects to on a cluster.

``python -m tools.ray_bench [--scene X.blend] [--workers 1,2] [--plan 2]``:
a ground of a few parts at the lp optimizer's defaults (1 m grid, cost; default:
``tests/data/xodr/Town01.xodr`` imported, 3 parts), once per worker count, each in a
process of its own (``headless/ray_engine.py``): first every part's candidates built
by that many Ray actors with nothing else running (the builds' speedup); then, for the
counts in ``--plan``, the whole lp plan with its parts built so: how long the planner
waited for each part and then worked on it (its solve, serial on the driver), and the
plan (with the default time budget cutting the solves, plans may differ from run to
run, whatever builds the parts).

Per part the seconds an actor took to build it and the CPU seconds: on a shared
machine the wall seconds say how much of a core the actor got, the CPU seconds what
the build needs. Peak memory: the driver's own, the largest child's (getrusage: only
the children the driver waited for, i.e. Ray's own processes; the actors are the
raylet's and are not in it), and the sum over the driver's process tree, sampled
every 0.5 s (the actors included; Ray's shared-memory store counted in each process
that maps it): the figure to read.

Then a projection of a 1 km^2 target at 1 m (1,000,000 target points) on 16 and 64
workers from the times measured (``project``). The figures go to ``bench/ray.json``.
"""

from __future__ import annotations

import argparse
import json
import math
import os
import resource
import subprocess
import sys
import tempfile
import threading
import time
from datetime import date
from pathlib import Path
from typing import Any

from headless.paths import REPO
from tools.machine import machine_line

TOWN01 = REPO / "tests" / "data" / "xodr" / "Town01.xodr"
GROUND_POINTS = 1_000_000  # 1 km^2 of target at 1 m
PROJECT_WORKERS = (16, 64)
PART_POINTS_ASSUMED = 20_000


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--scene", help="a .blend (default: Town01.xodr imported)")
    parser.add_argument("--workers", default="1,2", help="worker counts to compare")
    parser.add_argument(
        "--plan", default="2", help="worker counts that also plan the ground (solve times)"
    )
    parser.add_argument("--out", default=str(REPO / "bench" / "ray.json"))
    parser.add_argument("--one", type=int, help=argparse.SUPPRESS)  # a child's run
    parser.add_argument("--json", help=argparse.SUPPRESS)
    args = parser.parse_args(argv)
    planned = {int(x) for x in args.plan.split(",") if x}
    if args.one is not None:
        figures = one_run(args.scene, args.one, args.one in planned)
        Path(args.json).write_text(json.dumps(figures))
        return 0
    with tempfile.TemporaryDirectory(prefix="autoscoop-ray-bench-") as tmp:
        scene = args.scene or str(_import_town01(Path(tmp)))
        runs = []
        for w in (int(x) for x in args.workers.split(",")):
            out = Path(tmp) / f"run{w}.json"
            subprocess.run(
                [sys.executable, "-m", "tools.ray_bench", "--scene", scene,
                 "--one", str(w), "--plan", args.plan, "--json", str(out)],
                cwd=REPO, check=True,
            )  # fmt: skip
            runs.append(json.loads(out.read_text()))
            _print_run(runs[-1])
    plans = [json.dumps(r["plan"], sort_keys=True) for r in runs if "plan" in r]
    figures: dict[str, Any] = {
        "date": date.today().isoformat(),
        "machine": machine_line(),
        "scene": Path(args.scene).name if args.scene else TOWN01.name,
        "runs": runs,
        "same_plan": len(set(plans)) == 1 if len(plans) > 1 else None,
    }
    if len(runs) > 1:
        base, best = runs[0], runs[-1]
        figures["speedup"] = {
            "workers": [base["workers"], best["workers"]],
            "candidate_builds": round(base["builds_s"] / best["builds_s"], 2),
        }
    if any("plan" in r for r in runs):
        figures["projection"] = project(runs)
    _print_summary(figures)
    Path(args.out).write_text(json.dumps(figures, indent=2) + "\n")
    print(f"-> {args.out}")
    return 0


def _import_town01(tmp: Path) -> Path:
    blend = tmp / "Town01.blend"
    subprocess.run(
        [sys.executable, "-m", "headless", "import-xodr", str(TOWN01), "--out", str(blend)],
        cwd=REPO, check=True, capture_output=True,
    )  # fmt: skip
    return blend


class TreeMemory:
    """The peak of the summed resident memory of this process and all its
    descendants, sampled every ``every_s`` in a thread (Linux ``/proc``)."""

    def __init__(self, every_s: float = 0.5) -> None:
        self.peak = 0
        self.done = threading.Event()
        self.thread = threading.Thread(target=self._watch, args=(every_s,), daemon=True)
        self.thread.start()

    def _watch(self, every_s: float) -> None:
        while not self.done.wait(every_s):
            self.peak = max(self.peak, tree_rss(os.getpid()))

    def stop(self) -> int:
        self.done.set()
        self.thread.join()
        return self.peak


def tree_rss(root: int) -> int:
    """Bytes resident in process ``root`` and its descendants now."""
    children: dict[int, list[int]] = {}
    rss: dict[int, int] = {}
    page = os.sysconf("SC_PAGE_SIZE")
    for stat in Path("/proc").glob("[0-9]*/stat"):
        try:
            fields = stat.read_text().rsplit(")", 1)[1].split()
        except OSError:
            continue
        pid = int(stat.parent.name)
        children.setdefault(int(fields[1]), []).append(pid)
        rss[pid] = int(fields[21]) * page
    total, todo = 0, [root]
    while todo:
        pid = todo.pop()
        total += rss.get(pid, 0)
        todo.extend(children.get(pid, []))
    return total


class _Timing:
    """When the planner asked for each part and got it (``perf_counter``), and when
    the builder was closed."""

    def __init__(self) -> None:
        self.asked: dict[int, float] = {}
        self.got: dict[int, float] = {}
        self.nonzeros: dict[int, int] = {}
        self.closed_at = 0.0


def _timed_builder(factory: Any, workers: int) -> tuple[Any, _Timing]:
    """A RayBuilder of ``workers`` actors that notes its timing."""
    from headless.ray_engine import RayBuilder

    timing = _Timing()

    class Timed(RayBuilder):
        def start(self, problem, parts, reach_m):  # type: ignore[no-untyped-def]
            t0 = time.perf_counter()
            super().start(problem, parts, reach_m)
            self.start_s = time.perf_counter() - t0

        def build(self, k):  # type: ignore[no-untyped-def]
            timing.asked[k] = time.perf_counter()
            part = yield from super().build(k)
            timing.got[k] = time.perf_counter()
            timing.nonzeros[k] = int(part.cands.matrix.nnz)
            return part

        def close(self) -> None:
            if self.actors:
                timing.closed_at = time.perf_counter()
                self.actor_load_s()  # while the actors are there to ask
            super().close()

    return Timed(factory, workers=workers), timing


def one_run(scene_path: str, workers: int, plan: bool) -> dict[str, Any]:
    """The candidate builds of every part of the scene at the defaults, by
    ``workers`` Ray actors with nothing else running; then, with ``plan``, the whole
    lp plan with its parts built so (the solves' times and the plan). The figures."""
    import bpy  # noqa: F401  (before the caster's mathutils)
    import numpy as np

    from autoscoop_blender.core.optimize.bound import parts_of
    from autoscoop_blender.core.optimize.parts import part_count
    from autoscoop_blender.core.problem import Problem
    from autoscoop_blender.core.run import Run
    from autoscoop_blender.io.config import load_config
    from headless.files import load_scene

    memory = TreeMemory()
    load_before = round(os.getloadavg()[0], 1)
    settings, model = load_config(None)
    reach = max(m.range_m for m in getattr(model, "models", (model,)))
    scene, factory = load_scene(scene_path, reach)
    t0 = time.perf_counter()
    problem = Problem(scene, factory(), model, settings)
    problem_s = time.perf_counter() - t0
    n = part_count(problem)
    split = parts_of(problem.grid.target_xy, n)
    parts = [np.flatnonzero(split == k) for k in range(n)]
    builder, timing = _timed_builder(factory, workers)
    try:
        builder.start(problem, parts, reach)
        for k in range(n):
            gen = builder.build(k)
            while True:
                try:
                    next(gen)
                except StopIteration:
                    break
    finally:
        builder.close()
    figures: dict[str, Any] = {
        "workers": workers,
        "target_points": int(problem.n_targets),
        "problem_s": round(problem_s, 2),
        "ray_start_s": round(builder.start_s, 2),
        "actor_problem_s": [round(s, 2) for s in builder.load_s],
        "builds_s": round(timing.got[n - 1] - timing.asked[0], 2),
        "parts": [
            {
                "part": k + 1,
                "points": len(parts[k]),
                "nonzeros": timing.nonzeros[k],
                "build_s": round(builder.build_s[k], 2),
                "build_cpu_s": round(builder.build_cpu_s[k], 2),
            }
            for k in range(n)
        ],
        # The machine's 1-minute load before and after the builds (and after the plan).
        "load_average": [load_before, round(os.getloadavg()[0], 1)],
    }
    del problem
    if plan:
        t0 = time.perf_counter()
        builder, timing = _timed_builder(factory, workers)
        run = Run(scene, factory, model, settings, part_builder=builder)
        result = run.result()
        figures["plan_wall_s"] = round(time.perf_counter() - t0, 2)
        ks = sorted(timing.got)
        for i, k in enumerate(ks):
            until = timing.asked[ks[i + 1]] if i + 1 < len(ks) else timing.closed_at
            figures["parts"][k]["waited_s"] = round(timing.got[k] - timing.asked[k], 2)
            figures["parts"][k]["solve_s"] = round(until - timing.got[k], 2)
        m = result.metrics
        keys = ("sensors", "masts", "cost", "lower_bound", "coverage_fraction")
        figures["plan"] = {key: m[key] for key in keys}
        figures["load_average"].append(round(os.getloadavg()[0], 1))
    figures["peak_rss_driver_mib"] = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss >> 10
    children = resource.getrusage(resource.RUSAGE_CHILDREN).ru_maxrss >> 10
    figures["peak_rss_largest_child_mib"] = children
    figures["peak_rss_tree_mib"] = memory.stop() >> 20
    return figures


def project(runs: list[dict[str, Any]]) -> dict[str, Any]:
    """A 1 km^2 target at 1 m (``GROUND_POINTS``) on 16 and 64 workers, from the
    times measured: a part's build time B (CPU seconds on one actor) and its solve
    time S (on the driver: the planner's work between receiving the part and asking
    for the next), means over the parts measured.

    Two ways to cut it: in parts of ``PART_POINTS_ASSUMED`` points (``budget.
    PART_POINTS``), B and S scaled by points (linear: a part's LP may well grow
    faster); and in parts the size the planner cut the measured ground into (a dense
    ground is cut by ``budget.PART_NONZEROS`` rather than by points), B and S as
    measured. Assumed: the driver solves the parts one after another while the
    actors build the next ones (no part waits for a free actor when B / W < S);
    setup (Ray's start, the actors' problems) as measured, paid once; the network,
    the driver's fetch of each part and the final pruning are not modelled; S is
    what the default time budget allowed (240 s a part, shared). With P parts and W
    workers the builds end after about ceil(P / W) B and the solves need P S after
    the first part's B, so the run takes about setup + max(B + P S, ceil(P / W) B + S);
    in one process (``LocalBuilder``), P (B + S).
    """
    built = [p for r in runs for p in r["parts"]]
    solved = [p for r in runs for p in r["parts"] if "solve_s" in p]
    points = sum(p["points"] for p in built) / len(built)
    # A build's CPU seconds: its time on a core of its own (a cluster's worker),
    # whatever else this shared machine ran meanwhile.
    build_s = sum(p["build_cpu_s"] for p in built) / len(built)
    solve_s = sum(p["solve_s"] for p in solved) / len(solved)
    solve_points = sum(p["points"] for p in solved) / len(solved)
    setup = max(r["ray_start_s"] + max(r["actor_problem_s"] or [0.0]) for r in runs)
    cuts = {
        "parts_of_20000_points": (
            PART_POINTS_ASSUMED,
            build_s * PART_POINTS_ASSUMED / points,
            solve_s * PART_POINTS_ASSUMED / solve_points,
        ),
        "parts_as_measured": (round(points), build_s, solve_s),
    }
    out: dict[str, Any] = {"target_points": GROUND_POINTS, "setup_s": round(setup, 1)}
    for name, (size, b, s) in cuts.items():
        n = math.ceil(GROUND_POINTS / size)
        case: dict[str, Any] = {
            "parts": n,
            "part_points": size,
            "build_s_per_part": round(b, 1),
            "solve_s_per_part": round(s, 1),
            "one_process_s": round(n * (b + s)),
        }
        for w in PROJECT_WORKERS:
            solves, builds = b + n * s, math.ceil(n / w) * b + s
            case[f"workers_{w}_s"] = round(setup + max(solves, builds))
            case[f"workers_{w}_bound_by"] = "solves" if solves >= builds else "builds"
        out[name] = case
    return out


def _print_run(r: dict[str, Any]) -> None:
    print(
        f"{r['workers']} worker(s): {r['target_points']:,} target points in "
        f"{len(r['parts'])} parts; problem {r['problem_s']:.1f} s here, Ray started in "
        f"{r['ray_start_s']:.1f} s, the actors' problems {r['actor_problem_s']} s; every "
        f"part's candidates in {r['builds_s']:.1f} s; peak RSS: driver "
        f"{r['peak_rss_driver_mib']} MiB, largest child {r['peak_rss_largest_child_mib']} "
        f"MiB, process tree {r['peak_rss_tree_mib']} MiB"
    )
    for p in r["parts"]:
        solve = ""
        if "solve_s" in p:
            solve = f"; in the plan waited {p['waited_s']:.1f} s, solved in {p['solve_s']:.1f} s"
        print(
            f"  part {p['part']}: {p['points']:,} points, {p['nonzeros']:,} nonzeros, "
            f"built in {p['build_s']:.1f} s{solve}"
        )
    if "plan" in r:
        print(f"  plan in {r['plan_wall_s']:.1f} s: {r['plan']}", flush=True)


def _print_summary(f: dict[str, Any]) -> None:
    for r in f["runs"]:
        cpu = sum(p["build_cpu_s"] for p in r["parts"])
        print(
            f"{r['workers']} worker(s): candidates of every part in {r['builds_s']:.0f} s, "
            f"{cpu:.0f} CPU s (about {cpu / r['builds_s']:.2f} cores busy); load "
            f"{r['load_average']}"
        )
    if "speedup" in f:
        s = f["speedup"]
        print(
            f"speedup of the candidate builds, {s['workers'][0]} -> {s['workers'][1]} "
            f"workers: x{s['candidate_builds']}"
        )
    if "projection" not in f:
        return
    p = f["projection"]
    for name, c in p.items():
        if not isinstance(c, dict):
            continue
        line = ", ".join(
            f"{w} workers ~{c[f'workers_{w}_s']:,} s (bound by {c[f'workers_{w}_bound_by']})"
            for w in PROJECT_WORKERS
        )
        print(
            f"1 km^2 at 1 m, {name}: {c['parts']} parts of {c['part_points']:,} points, "
            f"build {c['build_s_per_part']} s and solve {c['solve_s_per_part']} s a part; "
            f"one process ~{c['one_process_s']:,} s; {line}"
        )


if __name__ == "__main__":
    sys.exit(main())
