"""A run's progress in words: the command line's progress lines and bar and the Blender
operator's status text say the same facts in the same words.

The facts of a ``Progress``, each shown only when the optimizer gave it: the stage
(phase, and the optimizer's own stage), part i of n, the sensors fixed and their
coverage (the ES and greedy fix them one by one; lp at the end), the best plan so far
(objective, sensors, masts), the proven bound, the gap, the time spent and the
optimizer's estimate of the time left.
"""

from __future__ import annotations

import math

from ..core.optimize.base import Progress


def progress_facts(p: Progress, elapsed_s: float, compact: bool = False) -> list[str]:
    """The facts of ``p`` as short phrases, in order; ``elapsed_s``: seconds since
    the run began; ``compact``: shorter words, for a bar on one terminal line."""
    facts = [f"{p.phase}: {p.stage}" if p.stage else p.phase]
    if p.parts:
        facts.append(f"part {p.part}/{p.parts}" if compact else f"part {p.part} of {p.parts}")
    # An optimizer without stages (the ES, greedy) shows its progress by the sensors
    # it fixes; lp fixes its plan at the end, and "0 sensors" before would mislead.
    if p.sensors or not p.stage:
        epoch = f", epoch {p.epoch}" if p.epoch else ""
        facts.append(f"{p.sensors} sensors, coverage {p.coverage:.2%} of {p.rho:.0%}{epoch}")
    if p.best is not None:
        plan = ""
        if p.plan is not None:
            sensors, masts = p.plan
            plan = f" ({sensors}{'' if compact else ' sensors'} on {masts} masts)"
        facts.append(f"best {number(p.best)}{plan}")
    if p.bound is not None:
        facts.append(f"bound {number(p.bound)}")
    g = gap(p)
    if g is not None:
        facts.append(f"gap {g:.1%}")
    left = "" if p.eta_s is None else f", ~{duration(p.eta_s)} left"
    facts.append(duration(elapsed_s) + left)
    return facts


def progress_text(p: Progress, elapsed_s: float, compact: bool = False) -> str:
    """``progress_facts`` on one line."""
    return " | ".join(progress_facts(p, elapsed_s, compact))


def gap(p: Progress) -> float | None:
    """(best - bound) / best, the share the best plan may lie above the optimum; None
    without both (or without a finite, positive best)."""
    if p.best is None or p.bound is None or not math.isfinite(p.best) or p.best <= 0:
        return None
    return max(p.best - p.bound, 0.0) / p.best


def number(value: float) -> str:
    """74, 70.5, 30.92: at most two decimals, none that are 0; inf as "inf"."""
    if not math.isfinite(value):
        return str(value)
    return f"{value:,.2f}".rstrip("0").rstrip(".")


def duration(seconds: float) -> str:
    """12 s, 3 min 05 s, 1 h 02 min."""
    s = max(int(round(seconds)), 0)
    if s < 60:
        return f"{s} s"
    if s < 3600:
        return f"{s // 60} min {s % 60:02d} s"
    return f"{s // 3600} h {s % 3600 // 60:02d} min"
