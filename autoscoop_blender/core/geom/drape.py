"""Footprints as meshes that follow the terrain: triangulation and draping.

A footprint is a (Multi)Polygon in XY. To show it on hilly ground it is cut into
triangles no larger than a grid cell, whose corners are then set on the ground. The
core drapes every footprint before a result leaves it (``core/result.py``), so the
Blender glue only builds meshes from the arrays and never casts a ray.
"""

from __future__ import annotations

import math
from collections.abc import Callable

import numpy as np
import shapely
from numpy.typing import NDArray
from shapely.geometry.base import BaseGeometry

F64 = NDArray[np.float64]
I32 = NDArray[np.int32]

# Grid cell (m) that bounds every triangle edge so the mesh can follow the terrain.
DRAPE_CELL_M = 2.0


def drape(
    geom: BaseGeometry, ground_z: Callable[[F64], F64], cell_m: float = DRAPE_CELL_M
) -> tuple[F64, I32]:
    """A (Multi)Polygon in XY as a mesh on the ground: vertices (V, 3) and
    counter-clockwise triangles (T, 3); ``ground_z(xy (K, 2)) -> z (K,)`` gives the
    height under each vertex (same frame and units as ``geom``)."""
    xy, tris = triangulate_footprint(geom, cell_m)
    z = np.asarray(ground_z(xy), dtype=float).reshape(-1) if len(xy) else np.zeros(0)
    if z.shape != (len(xy),):
        raise ValueError(f"ground_z returned shape {z.shape} for {len(xy)} points")
    return np.column_stack([xy, z]), tris


def triangulate_footprint(geom: BaseGeometry, cell_m: float = DRAPE_CELL_M) -> tuple[F64, I32]:
    """Triangles covering a (Multi)Polygon in world XY (m), small enough to drape.

    The region is cut along a world-aligned ``cell_m`` grid, so the mesh has interior
    vertices every ``cell_m`` and follows terrain inside, not only along the outline.
    Cells wholly inside become two triangles; each cut cell has its edges split to at
    most ``cell_m`` and is triangulated by shapely's constrained Delaunay
    triangulation (holes stay holes). No triangle edge is longer than a cell's
    diagonal. Returns vertices (V, 2) and counter-clockwise triangles (T, 3) indexing
    them; vertices shared by neighbouring triangles are merged.
    """
    polys = shapely.get_parts(geom)
    polys = polys[(shapely.get_type_id(polys) == 3) & (shapely.area(polys) > 0)]
    if len(polys) == 0:
        return np.zeros((0, 2)), np.zeros((0, 3), dtype=np.int32)
    region = shapely.union_all(polys) if len(polys) > 1 else polys[0]

    minx, miny, maxx, maxy = region.bounds
    x0, y0 = math.floor(minx / cell_m) * cell_m, math.floor(miny / cell_m) * cell_m
    nx, ny = max(1, math.ceil((maxx - x0) / cell_m)), max(1, math.ceil((maxy - y0) / cell_m))
    gx, gy = np.meshgrid(x0 + cell_m * np.arange(nx), y0 + cell_m * np.arange(ny))
    gx, gy = gx.ravel(), gy.ravel()
    cells = shapely.box(gx, gy, gx + cell_m, gy + cell_m)

    shapely.prepare(region)
    inside = shapely.contains_properly(region, cells)
    edge = shapely.intersects(region, cells) & ~inside
    pieces = shapely.get_parts(shapely.intersection(cells[edge], region))
    pieces = pieces[(shapely.get_type_id(pieces) == 3) & (shapely.area(pieces) > 1e-12)]
    pieces = shapely.segmentize(pieces, cell_m)

    tris = shapely.get_parts(shapely.constrained_delaunay_triangles(pieces))
    corners = shapely.get_coordinates(tris).reshape(-1, 4, 2)[:, :3]  # rings are closed
    # Full cells are two triangles each; no need to ask the triangulator.
    full = np.stack([gx[inside], gy[inside]], -1)[:, None, :]
    sq = cell_m * np.array([[[0, 0], [1, 0], [1, 1]], [[0, 0], [1, 1], [0, 1]]], float)
    corners = np.concatenate([corners, (full[:, None] + sq[None]).reshape(-1, 3, 2)])

    e1, e2 = corners[:, 1] - corners[:, 0], corners[:, 2] - corners[:, 0]
    cross = e1[:, 0] * e2[:, 1] - e1[:, 1] * e2[:, 0]
    corners = corners[np.abs(cross) > 1e-12]
    flip = cross[np.abs(cross) > 1e-12] < 0
    corners[flip] = corners[flip][:, ::-1]  # all counter-clockwise: normals up
    if len(corners) == 0:
        return np.zeros((0, 2)), np.zeros((0, 3), dtype=np.int32)

    flat = corners.reshape(-1, 2)
    first, inverse = _merge_points(flat)
    return flat[first], inverse.reshape(-1, 3).astype(np.int32)


def _merge_points(xy: F64, tol_m: float = 1e-6) -> tuple[NDArray[np.intp], NDArray[np.intp]]:
    """Indices of one representative per distinct point (on a ``tol_m`` lattice) and,
    per point, the index of its representative in that list."""
    k = np.round((xy - xy.min(axis=0)) / tol_m).astype(np.int64)
    span = k.max(axis=0) + 1
    if float(span[0]) * float(span[1]) < 2**62:
        # One int64 key per point: a 1-D unique is several times faster than axis=0.
        _, first, inverse = np.unique(k[:, 0] * span[1] + k[:, 1], True, True)
    else:
        _, first, inverse = np.unique(k, axis=0, return_index=True, return_inverse=True)
    return first, inverse.reshape(-1)
