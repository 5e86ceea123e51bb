"""``import-xodr``: an OpenDRIVE file -> a .blend that ``optimize`` runs on unchanged."""

from __future__ import annotations

import argparse
import sys
import tempfile
from pathlib import Path

from autoscoop_blender.core.errors import InputError
from headless.files import quiet_fds, write_files

# Warnings printed one by one; the rest are counted.
SHOWN_WARNINGS = 20


def import_xodr(args: argparse.Namespace) -> int:
    """Import ``args.file`` into an empty scene and save it as ``args.out`` (written
    whole or not at all). Returns 0."""
    import bpy

    from autoscoop_blender.scene.xodr_import import import_xodr, parse_band, parse_lanes

    lanes = parse_lanes(args.lanes)
    band = parse_band(args.band)
    out = Path(args.out)
    if out.suffix.lower() != ".blend":
        raise InputError(f"--out {out}: name a .blend file")
    if out.is_dir():
        raise InputError(f"--out {out}: is a directory, not a file to write")
    bpy.ops.wm.read_factory_settings(use_empty=True)
    summary = import_xodr(args.file, lanes, band, args.terrain)
    for w in summary.warnings[:SHOWN_WARNINGS]:
        print(f"warning: {w}", file=sys.stderr)
    if len(summary.warnings) > SHOWN_WARNINGS:
        print(f"warning: ... and {len(summary.warnings) - SHOWN_WARNINGS} more", file=sys.stderr)
    if out.parent.exists():
        staging = tempfile.TemporaryDirectory(dir=out.parent)
    else:
        staging = tempfile.TemporaryDirectory()
    with staging as tmp:
        blend = Path(tmp) / out.name
        with quiet_fds():  # Blender's "Info: Saved as ..." is not ours to print
            bpy.ops.wm.save_as_mainfile(filepath=str(blend), compress=True)
        write_files({out: blend.read_bytes()})
    print(f"{Path(args.file).name}: {summary.text()} -> {out}")
    return 0
