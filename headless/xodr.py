"""``import-xodr``: an OpenDRIVE file -> a .blend that ``optimize`` runs on unchanged."""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

from autoscoop_blender.core.errors import InputError
from headless import interrupts
from headless.files import blend_bytes, check_outputs, write_files
from headless.progress import StageLine

# Warnings printed one by one; the rest are counted.
SHOWN_WARNINGS = 20


def import_xodr(args: argparse.Namespace) -> int:
    """Import ``args.file`` into an empty scene and save it as ``args.out`` (written
    whole or not at all; an existing file only with ``--overwrite``). Returns 0."""
    import bpy

    from autoscoop_blender.scene.xodr_import import import_xodr, parse_band, parse_lanes

    lanes = parse_lanes(args.lanes)
    band = parse_band(args.band)
    out = Path(args.out)
    if out.suffix.lower() != ".blend":
        raise InputError(f"--out {out}: name a .blend file")
    check_outputs({out: "--out"}, {Path(args.file): "the OpenDRIVE file"}, args.overwrite)
    with interrupts.held():  # Blender's load handlers run Python (``interrupts``)
        bpy.ops.wm.read_factory_settings(use_empty=True)
    line = StageLine(Path(args.file).name)
    try:
        summary = import_xodr(args.file, lanes, band, args.terrain, progress=line)
    finally:
        line.close()
    for w in summary.warnings[:SHOWN_WARNINGS]:
        print(f"warning: {w}", file=sys.stderr)
    if len(summary.warnings) > SHOWN_WARNINGS:
        print(f"warning: ... and {len(summary.warnings) - SHOWN_WARNINGS} more", file=sys.stderr)
    write_files({out: blend_bytes()})
    print(f"{Path(args.file).name}: {summary.text()} -> {out}")
    return 0
