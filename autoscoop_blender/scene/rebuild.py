"""Rebuilding the BVHTree caster in a worker process (imports no bpy at load time).

A spawned worker starts with its parent's ``sys.path``, which by then holds Blender's
own script folders (added when the parent imported bpy). Those contain a pure-Python
``bpy`` package that shadows the pip module, so the worker must drop them before its
first ``import bpy``; Blender adds them back itself.
"""

from __future__ import annotations

import sys
from pathlib import Path

import numpy as np
from numpy.typing import NDArray


def forget_blender_script_paths() -> None:
    """Remove ``<bpy package>/<version>/scripts/...`` folders from ``sys.path``."""
    sys.path[:] = [
        p for p in sys.path if not ("scripts" in Path(p).parts and "bpy" in Path(p).parts)
    ]


def rebuild_bvh(
    vertices: NDArray[np.float64], faces: NDArray[np.int32], ground: NDArray[np.int32] | None
):
    """A BVHCaster over the given triangles (and ``ground`` faces, if any)."""
    if "bpy" not in sys.modules:
        forget_blender_script_paths()
    from .bvh import BVHCaster

    caster = BVHCaster(vertices, faces)
    if ground is not None:
        caster.ground = BVHCaster(vertices, ground)
    return caster
