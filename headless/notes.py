"""Notes that repeat, summed up: a piece of a sensor area where no mast may stand is
one note for each object standing there (1,586 on an imported town of 40,000 m^2).
At most ``SHOWN`` are printed; past that, one line sums them up and every one goes to
a notes file written with the results (``optimize``: notes.txt in the output folder;
``coverage``: OUT.notes.txt beside --out)."""

from __future__ import annotations

from collections.abc import Iterable, Sequence
from pathlib import Path

from autoscoop_blender.core.model.scene import Exclusion

SHOWN = 3
"""Notes printed before the rest are summed up in one line."""

NAME = "notes.txt"
"""The notes file of an optimize run, in its output folder."""


def beside(out: Path) -> Path:
    """The notes file of ``coverage --out OUT.json``: OUT.notes.txt."""
    return out.with_name(out.stem + ".notes.txt")


def exclusion_lines(excluded: Sequence[Exclusion], no_mast: Iterable[str], path: Path) -> list[str]:
    """What to print of ``excluded`` (``SceneModel.excluded``), without "note: ": each
    one when they are at most ``SHOWN``, else the first ``SHOWN`` and a line that
    counts them by cause, sums their m^2 and names ``path``. no_mast: the names of
    the no-mast zones (the other causes are objects standing on the ground)."""
    lines = [e.text() for e in excluded[:SHOWN]]
    if len(excluded) <= SHOWN:
        return lines
    zones = set(no_mast)
    in_zones = sum(e.cause in zones for e in excluded)
    kinds = [
        (len(excluded) - in_zones, "under objects standing on the ground"),
        (in_zones, "in no-mast zones"),
    ]
    why = ", ".join(f"{n:,} {what}" for n, what in kinds if n)
    # Causes may overlap, so this sum can exceed the area lost (``Exclusion``).
    m2 = sum(e.m2 for e in excluded)
    lines.append(
        f"{len(excluded):,} sensor-area pieces with no mast site ({m2:,.1f} m^2 in all; "
        f"{why}): the first {SHOWN} above, every one in {path} with the results"
    )
    return lines


def exclusion_file(excluded: Sequence[Exclusion]) -> str | None:
    """The notes file's text: every note of ``excluded``, one a line; None when they
    were all printed (``exclusion_lines``)."""
    if len(excluded) <= SHOWN:
        return None
    return "".join(f"note: {e.text()}\n" for e in excluded)
