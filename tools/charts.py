"""The benchmark's charts (matplotlib, headless; a development tool, not the extension)."""

from __future__ import annotations

from pathlib import Path
from typing import Any

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
from matplotlib.ticker import FuncFormatter, NullFormatter  # noqa: E402

SERIES_STYLE = {
    "targeted": ("tab:blue", "o"),
    "cached targeted": ("tab:green", "s"),
    "pointcloud": ("tab:red", "^"),
    "cropping": ("tab:purple", "D"),
}


def speed_accuracy_chart(results: dict[str, Any], path: Path) -> None:
    """Seconds per pose (log) against point disagreement and footprint error, one
    column per scene, one series per method and knob; defaults starred."""
    scenes = list(results["speed_accuracy"])
    fig, axes = plt.subplots(2, len(scenes), figsize=(6.5 * len(scenes), 9), squeeze=False)
    for col, scene in enumerate(scenes):
        rows = results["speed_accuracy"][scene]
        for row_i, (metric, label) in enumerate(
            (("point_disagreement", "target points disagreeing with reference"),
             ("footprint_error", "footprint area error"))
        ):  # fmt: skip
            ax = axes[row_i][col]
            for (series, knob), group in _groups(rows).items():
                color, marker = SERIES_STYLE.get(series, ("gray", "x"))
                xs = [r["s_per_pose"] for r in group]
                ys = [100 * r[metric] for r in group]
                ax.plot(xs, ys, marker=marker, color=color, linestyle="-" if len(group) > 1 else "",
                        label=f"{series} ({knob})", alpha=0.85, zorder=2)  # fmt: skip
                for r, x, y in zip(group, xs, ys):
                    ax.annotate(f"{r['value']}", (x, y), textcoords="offset points",
                                xytext=(4, 4), fontsize=7)  # fmt: skip
                    if r["default"]:
                        ax.plot([x], [y], marker="*", markersize=15, color="gold",
                                markeredgecolor="black", linestyle="", zorder=1)  # fmt: skip
                    if r.get("note") == "paper":
                        ax.plot([x], [y], marker="o", markersize=14, fillstyle="none",
                                color="black", linestyle="", zorder=1)  # fmt: skip
            ax.set_xscale("log")
            ax.set_xlabel("seconds per pose evaluation (log)")
            ax.set_ylabel(f"{label} (%)")
            ax.set_title(f"{scene}: {label}")
            ax.grid(True, which="both", alpha=0.3)
            if row_i == 0 and col == 0:
                ax.legend(fontsize=7, loc="upper right")
    ref = results["reference"]
    fig.suptitle(
        f"Speed against accuracy (reference: {ref['method']} on a {ref['grid_m']} m grid, "
        f"{ref['positions']}); gold star: default, black ring: the paper's pipeline. "
        f"{results['date']}, {results['machine']}",
        fontsize=9,
    )
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)


def _groups(rows: list[dict[str, Any]]) -> dict[tuple[str, str], list[dict[str, Any]]]:
    out: dict[tuple[str, str], list[dict[str, Any]]] = {}
    for r in rows:
        out.setdefault((r["series"], r["knob"]), []).append(r)
    return out


def optimize_chart(results: dict[str, Any], path: Path) -> None:
    """Wall seconds against sensors needed, per optimizer configuration over seeds
    (each seed a dot, the spread as a cross of min-max bars)."""
    fig, ax = plt.subplots(figsize=(8, 5.5))
    configs: dict[str, list[dict[str, Any]]] = {}
    for r in results["optimize"]:
        configs.setdefault(r["config"], []).append(r)
    paper = results.get("default_vs_paper", {})
    if paper.get("paper_wall_s"):
        label = "paper-faithful (pointcloud)"
        if not paper.get("paper_complete", True):
            label += f", unfinished at {paper['paper_coverage']:.1%}"
        configs[label] = [
            {"wall_s": paper["paper_wall_s"], "sensors": paper["paper_sensors"],
             "coverage_fraction": paper["paper_coverage"]}
        ]  # fmt: skip
    for i, (name, rows) in enumerate(configs.items()):
        xs = [r["wall_s"] for r in rows]
        ys = [r["sensors"] for r in rows]
        color = f"C{i}"
        ax.scatter(xs, ys, color=color, alpha=0.6, label=f"{name} ({len(rows)} seed(s))")
        if len(rows) > 1:
            mx, my = sum(xs) / len(xs), sum(ys) / len(ys)
            ax.errorbar([mx], [my], xerr=[[mx - min(xs)], [max(xs) - mx]],
                        yerr=[[my - min(ys)], [max(ys) - my]], color=color, capsize=4)  # fmt: skip
        cov = min(r["coverage_fraction"] for r in rows)
        ax.annotate(f"cov >= {cov:.1%}", (max(xs), max(ys)), textcoords="offset points",
                    xytext=(5, 2), fontsize=7, color=color)  # fmt: skip
    ax.set_xscale("log")
    ax.set_xlabel("wall seconds for the whole optimization (log)")
    ax.set_ylabel("sensors needed for 97 %")
    ax.set_title(f"Optimizer configurations on two_routes ({results['date']}, {results['machine']})",
                 fontsize=9)  # fmt: skip
    ax.grid(True, which="both", alpha=0.3)
    ax.legend(fontsize=8)
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)


# The bound chart's panels a row, at most.
BOUND_COLUMNS = 4
# Each optimizer's colour in every panel of the bound chart (the others': the next).
BOUND_COLOURS = {"es": "C0", "greedy": "C1", "lp": "C2"}


def bound_chart(results: dict[str, Any], path: Path) -> None:
    """Objective against wall seconds per optimizer, one panel per scene (at most
    ``BOUND_COLUMNS`` a row), each titled with the day it was measured: each run's
    plan as a point; for lp, its best plan and its proven lower bound as they rise
    and fall during the run, and the final bound as a line."""
    section = results.get("bound", {})
    scenes = section.get("scenes", {})
    if not scenes:
        return
    measured = section.get("measured", {})
    cols = min(BOUND_COLUMNS, len(scenes))
    n_rows = -(-len(scenes) // cols)
    fig, axes = plt.subplots(n_rows, cols, figsize=(5.2 * cols, 4.4 * n_rows), squeeze=False)
    for ax in axes.ravel()[len(scenes) :]:
        ax.set_visible(False)
    for ax, (scene, rows) in zip(axes.ravel(), scenes.items()):
        cost_rows = [r for r in rows if r["objective_kind"] == "cost"]
        for i, r in enumerate(cost_rows):
            colour = BOUND_COLOURS.get(r["config"], f"C{len(BOUND_COLOURS) + i}")
            ax.scatter([r["wall_s"]], [r["cost"]], color=colour, s=40, zorder=3,
                       label=f"{r['config']}: {r['sensors']} sensors, {r['masts']} masts")  # fmt: skip
            ax.annotate(f"{r['cost']:g}", (r["wall_s"], r["cost"]), textcoords="offset points",
                        xytext=(5, 3), fontsize=8)  # fmt: skip
            trace = r.get("trace") or []
            plans = [p for p in trace if p[1] is not None]
            if plans:
                t = [p[0] for p in plans] + [r["wall_s"]]
                best = [p[1] for p in plans] + [r["cost"]]
                ax.step(t, best, where="post", color=colour, lw=1, alpha=0.7)
            proven = [(p[0], p[2]) for p in trace if p[2]]  # a bound of 0 proves nothing
            if proven:
                ax.step([p[0] for p in proven] + [r["wall_s"]],
                        [p[1] for p in proven] + [r["lower_bound"]], where="post",
                        color=colour, lw=1, ls=":",
                        label=f"{r['config']}: bound so far")  # fmt: skip
        bounds = [r["lower_bound"] for r in cost_rows if r["lower_bound"] is not None]
        if bounds:
            best_bound = max(bounds)
            ax.axhline(best_bound, color="k", ls="--", lw=1,
                       label=f"proven lower bound {best_bound:g}")  # fmt: skip
        ax.set_xscale("log")
        # Seconds as plain numbers at the powers of ten, from 1 s at most (a run of a
        # few seconds gets no power of ten of its own to label otherwise).
        ax.set_xlim(left=min(1.0, ax.get_xlim()[0]))
        ax.xaxis.set_major_formatter(FuncFormatter(lambda v, _: f"{v:g}"))
        ax.xaxis.set_minor_formatter(NullFormatter())
        ax.set_xlabel("wall seconds (log)")
        ax.set_ylabel("cost = 3 x masts + sensors")
        when = measured.get(scene, {}).get("date") or section.get("date")
        ax.set_title(f"{scene} ({when})", fontsize=10)
        ax.grid(True, which="both", alpha=0.3)
        ax.legend(fontsize=7)
    fig.suptitle("Objective against time, with the proven bound (each panel: the day it "
                 "was measured)", fontsize=10)  # fmt: skip
    fig.tight_layout()
    fig.savefig(path, dpi=100)
    plt.close(fig)
