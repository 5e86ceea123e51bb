"""The BVHTree caster as a picklable recipe: for the run here and in worker processes.

A BVHTree does not pickle, so worker processes are sent this factory (the scene's
triangles) and build their own tree. Loading this module imports no bpy: a spawned
worker starts with its parent's ``sys.path``, which by then holds Blender's own
script folders (added when the parent imported bpy). Those contain a pure-Python
``bpy`` package that shadows the pip module, so the worker drops them before its
first ``import bpy``; Blender adds them back itself.
"""

from __future__ import annotations

import sys
from dataclasses import dataclass
from pathlib import Path

import numpy as np
from numpy.typing import NDArray

from ..core.model.scene import SceneModel


def forget_blender_script_paths() -> None:
    """Remove ``<bpy package>/<version>/scripts/...`` folders from ``sys.path``."""
    sys.path[:] = [
        p for p in sys.path if not ("scripts" in Path(p).parts and "bpy" in Path(p).parts)
    ]


@dataclass(frozen=True)
class BVHFactory:
    """Builds the BVHTree caster of a scene's occluders (local metres).

    vertices (V, 3), faces (F, 3); ground_faces (F,) False for overhangs, which the
    caster's ``ground`` leaves out (None: every face is ground).
    """

    vertices: NDArray[np.float64]
    faces: NDArray[np.int32]
    ground_faces: NDArray[np.bool_] | None = None

    @classmethod
    def of(cls, scene: SceneModel) -> BVHFactory:
        return cls(scene.vertices, scene.faces, scene.ground_faces)

    def __call__(self):  # -> BVHCaster (not imported here: see the module docstring)
        if "bpy" not in sys.modules:
            forget_blender_script_paths()
        from .bvh import BVHCaster

        return BVHCaster.from_arrays(self.vertices, self.faces, self.ground_faces)
