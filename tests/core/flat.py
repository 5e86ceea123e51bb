"""Analytic test scenes for the core: flat ground, boxes, no Blender."""

from __future__ import annotations

from functools import partial

import numpy as np
import shapely

from autoscoop_blender.core.geom.grid import GroundGrid
from autoscoop_blender.core.geom.raycast import BoxCaster
from autoscoop_blender.core.model.scene import Area, SceneModel

# Two triangles per face of a unit cube, corners indexed by bits (x, y, z).
_CUBE_FACES = np.array(
    [
        (0, 2, 6),
        (0, 6, 4),
        (1, 5, 7),
        (1, 7, 3),
        (0, 4, 5),
        (0, 5, 1),
        (2, 3, 7),
        (2, 7, 6),
        (0, 1, 3),
        (0, 3, 2),
        (4, 6, 7),
        (4, 7, 5),
    ]
)


def box_mesh(boxes):
    """Vertices (8B, 3) and triangles (12B, 3) of axis-aligned boxes [(lo, hi), ...]."""
    verts, faces = [], []
    for k, (lo, hi) in enumerate(boxes):
        lo, hi = np.asarray(lo, float), np.asarray(hi, float)
        bits = np.array([[(i >> 2) & 1, (i >> 1) & 1, i & 1] for i in range(8)])
        verts.append(lo + bits * (hi - lo))
        faces.append(_CUBE_FACES + 8 * k)
    if not boxes:
        return np.zeros((0, 3)), np.zeros((0, 3), dtype=np.int32)
    return np.concatenate(verts), np.concatenate(faces).astype(np.int32)


def flat_scene(target=(-100.0, -100.0, 100.0, 100.0), sensor=(-1.0, -1.0, 1.0, 1.0), boxes=()):
    """A SceneModel: one box target, one box sensor area, the boxes as occluders.

    The ground itself is the implicit floor at z = 0 (no occluder under the boxes).
    """
    vertices, faces = box_mesh(list(boxes))
    return SceneModel(
        vertices=vertices,
        faces=faces,
        occluders=tuple(f"Box{k}" for k in range(len(boxes))),
        targets=(Area("Target", shapely.box(*target)),),
        sensor_areas=(Area("SensorArea", shapely.box(*sensor)),),
    )


def flat_grid(spacing=0.5, boxes=(), reach=80.0, **scene_kw):
    """(grid, caster) on flat ground z = 0 with optional axis-aligned boxes [(lo, hi)]."""
    caster = BoxCaster(boxes, ground_z=0.0)
    scene = flat_scene(boxes=boxes, **scene_kw)
    return GroundGrid(scene, caster, spacing, reach_m=reach), caster


def box_caster(boxes=(), ground_z=0.0):
    """A caster factory (picklable, for runs with worker processes): axis-aligned
    boxes [(lo, hi)] on a ground plane at ``ground_z``."""
    return partial(BoxCaster, list(boxes), ground_z=ground_z)


def areas_scene(targets, sensors, boxes=()):
    """A SceneModel of polygon targets and sensor areas (named by their order) and
    axis-aligned box occluders [(lo, hi)]."""
    vertices, faces = box_mesh(list(boxes))
    return SceneModel(
        vertices=vertices,
        faces=faces,
        occluders=tuple(f"Box{k}" for k in range(len(boxes))),
        targets=tuple(Area(f"Target_{k}", g) for k, g in enumerate(targets)),
        sensor_areas=tuple(Area(f"SensorArea_{k}", g) for k, g in enumerate(sensors)),
    )


def open_scene(target, sensors):
    """A SceneModel with no occluder: one target geometry, sensor-area geometries."""
    return SceneModel(
        vertices=np.zeros((0, 3)),
        faces=np.zeros((0, 3), dtype=np.int32),
        occluders=(),
        targets=(Area("Target", target),),
        sensor_areas=tuple(Area(f"SensorArea_{k}", g) for k, g in enumerate(sensors)),
    )


def down_camera(range_m):
    """A pinhole camera looking straight down, 60 x 60 deg, no density threshold: on
    flat ground its footprint is the axis-aligned square 2 h tan(30 deg) on a side
    under it (mount height 10 m)."""
    from dataclasses import replace

    from autoscoop_blender.core.model.sensors import PAPER_CAMERA

    return replace(
        PAPER_CAMERA,
        pattern="pinhole",
        h_fov_deg=60.0,
        v_fov_deg=60.0,
        range_m=range_m,
        mount_height_m=10.0,
        pitch_min_deg=90.0,
        pitch_max_deg=90.0,
        min_density_per_m2=0.0,
    )
