"""Top view of the occluders: where buildings, walls and trees stand, as polygons.

The scene model is one triangle soup: terrain, walls, buildings and trees together,
with no object boundaries, and ``SceneModel.ground_faces`` marks only overhangs (a
building's roof is "ground" there, since target points may be dropped onto it). So
what is terrain is decided from the geometry itself:

* every vertex gets its height above the *lowest* surface at its XY (the minimum
  over all triangles whose projection holds it, itself included, of their height
  there);
* a triangle stands up from the terrain when all three of its vertices are more
  than ``min_height_m`` above that lowest surface.

Terrain, a ground plane, and a road surface laid a few centimetres over the terrain
are the lowest surface at their own vertices, so they stay out. A building's roof
stands over its own floor (or over the ground plane under it), a wall's top over
its foot, a canopy over the ground; their projections form the outline. A terrain
triangle over a buried building floor counts as raised only when all its corners
are inside the building, so it adds nothing to the building's outline.

Not drawn: zero-thickness vertical planes (their projection is a line, dropped with
the other degenerate triangles); one-sided roofs floating over no surface at all
(they are the lowest surface there). Drawn although not above the terrain: terrain
over a hollow, e.g. a tunnel's roof, where the tunnel is modelled as a closed solid.
"""

from __future__ import annotations

import numpy as np
import shapely
from numpy.typing import NDArray
from shapely.geometry import Polygon

F64 = NDArray[np.float64]

# A triangle whose corners all stand this much over the lowest surface is an occluder.
OUTLINE_MIN_HEIGHT_M = 0.5
# Outline vertices closer than this to the simplified line are dropped.
OUTLINE_TOLERANCE_M = 0.1
# Triangles whose projection is smaller than this (m^2) are vertical or degenerate.
_MIN_PROJECTED_M2 = 1e-4


def occluder_outline(
    vertices: F64,
    faces: NDArray[np.int32],
    min_height_m: float = OUTLINE_MIN_HEIGHT_M,
    tolerance_m: float = OUTLINE_TOLERANCE_M,
) -> tuple[Polygon, ...]:
    """The top-view outline of what stands up from the terrain (see the module
    docstring): one Polygon (with holes, if any) per connected part, in the XY frame
    and metres of ``vertices`` (V, 3); ``faces`` (F, 3) are triangles into them.
    Parts come largest first; empty when nothing stands up."""
    vertices = np.asarray(vertices, dtype=float)
    faces = np.asarray(faces).reshape(-1, 3)
    if len(faces) == 0:
        return ()
    tri = vertices[faces]  # (F, 3 corners, xyz)
    e1 = tri[:, 1, :2] - tri[:, 0, :2]
    e2 = tri[:, 2, :2] - tri[:, 0, :2]
    area2 = e1[:, 0] * e2[:, 1] - e1[:, 1] * e2[:, 0]  # twice the signed projected area
    flat = np.abs(area2) > 2 * _MIN_PROJECTED_M2
    faces, tri, area2 = faces[flat], tri[flat], area2[flat]
    if len(faces) == 0:
        return ()

    polys = shapely.polygons(tri[:, :, :2])
    used = np.unique(faces)
    # Every (vertex, triangle) pair whose triangle's projection holds the vertex.
    vi, ti = shapely.STRtree(polys).query(
        shapely.points(vertices[used, :2]), predicate="intersects"
    )
    low = np.full(len(vertices), np.inf)
    np.minimum.at(low, used[vi], _z_at(tri[ti], area2[ti], vertices[used[vi], :2]))
    raised = vertices[:, 2] - low > min_height_m
    up = raised[faces].all(axis=1)
    if not up.any():
        return ()

    outline = shapely.union_all(polys[up])
    if tolerance_m > 0:
        outline = outline.simplify(tolerance_m, preserve_topology=True)
    parts = [p for p in shapely.get_parts(outline) if isinstance(p, Polygon) and not p.is_empty]
    parts.sort(key=lambda p: (-p.area, p.bounds))
    return tuple(parts)


def _z_at(tri: F64, area2: F64, xy: F64) -> F64:
    """Heights (K,) of the planes of triangles ``tri`` (K, 3, 3) at points ``xy``
    (K, 2), from barycentric coordinates; ``area2`` (K,) twice their signed
    projected areas (non-zero)."""
    a, b, c = tri[:, 0], tri[:, 1], tri[:, 2]
    x, y = xy[:, 0], xy[:, 1]
    wa = ((b[:, 0] - x) * (c[:, 1] - y) - (b[:, 1] - y) * (c[:, 0] - x)) / area2
    wb = ((c[:, 0] - x) * (a[:, 1] - y) - (c[:, 1] - y) * (a[:, 0] - x)) / area2
    return wa * a[:, 2] + wb * b[:, 2] + (1.0 - wa - wb) * c[:, 2]
