"""Alpha shapes of planar point sets, built on the Delaunay triangulation.

The alpha shape of a point set keeps the Delaunay triangles whose circumradius is at
most the alpha radius; their union is the shape (it may have holes and several
parts). A ``Triangulation`` and a mask of kept triangles answer "which lattice points
lie inside" (``Triangulation.locate_kept``) without building the polygon; the polygon
is built only when someone asks for it (``triangles_polygon``, ``alpha_shape``).

The radius limit may vary per triangle: the point-cloud coverage passes a limit
proportional to the local spacing of the ray pattern, so sparse far points and dense
near points are both joined while shadows wider than about two ray spacings stay
open.
"""

from __future__ import annotations

import logging
from dataclasses import dataclass

import numpy as np
import shapely
from numpy.typing import ArrayLike, NDArray
from scipy.spatial import Delaunay, QhullError
from shapely.geometry import Polygon
from shapely.geometry.base import BaseGeometry

log = logging.getLogger(__name__)

F64 = NDArray[np.float64]


def _twice_areas(p: F64) -> F64:
    """(T,) twice the area of each triangle of ``p`` (T, 3, 2), m^2. Written out: numpy 2
    no longer takes 2-vectors in ``np.cross``."""
    u, v = p[:, 1] - p[:, 0], p[:, 2] - p[:, 0]
    return np.abs(u[:, 0] * v[:, 1] - u[:, 1] * v[:, 0])


@dataclass(frozen=True)
class Triangulation:
    """Delaunay triangulation of points (P, 2); ``None`` parts when degenerate."""

    points: F64
    delaunay: Delaunay | None

    @property
    def simplices(self) -> NDArray[np.int32]:
        if self.delaunay is None:
            return np.zeros((0, 3), dtype=np.int32)
        return self.delaunay.simplices

    def circumradii(self) -> F64:
        """(T,) circumradius of each triangle, m (inf for a flat triangle)."""
        p = self.points[self.simplices]
        a = np.linalg.norm(p[:, 1] - p[:, 2], axis=1)
        b = np.linalg.norm(p[:, 0] - p[:, 2], axis=1)
        c = np.linalg.norm(p[:, 0] - p[:, 1], axis=1)
        area2 = _twice_areas(p)
        with np.errstate(divide="ignore", invalid="ignore"):
            return np.where(area2 > 0, a * b * c / (2.0 * area2), np.inf)

    def areas(self) -> F64:
        """(T,) triangle areas, m^2."""
        return 0.5 * _twice_areas(self.points[self.simplices])

    def locate_kept(self, xy: F64, keep: NDArray[np.bool_], cell: float) -> NDArray[np.int_]:
        """(K,) index of the kept triangle holding each query point, -1 for none.

        The queries must be centres of a lattice with spacing ``cell`` (grid cells).
        Each kept triangle visits the lattice centres inside its bounding box, so
        the cost follows the triangles' total area, not a walk through the mesh;
        a point on an edge between two kept triangles takes the lower index.

        Hand-written because it is faster here: ``Delaunay.find_simplex`` plus the
        ``keep`` mask gives the same answers (413,688 points of 36 real pattern
        evaluations on two_routes), but first computes barycentric data for every
        triangle of a triangulation that is searched once: 49 ms against 14 ms per
        call for 50,000 triangles (measured 2026-11-23, 2 cores, one BLAS thread).
        """
        out = np.full(len(xy), -1)
        ids = np.flatnonzero(keep)
        if len(xy) == 0 or len(ids) == 0:
            return out
        lo = xy.min(axis=0) - cell / 2
        q = np.floor((xy - lo) / cell).astype(np.int64)
        shape = q.max(axis=0) + 1
        raster = np.full(shape, -1, dtype=np.int64)
        raster[q[:, 0], q[:, 1]] = np.arange(len(xy))

        p = self.points[self.simplices[ids]]  # (T, 3, 2)
        first = np.ceil((p.min(axis=1) - lo) / cell - 0.5).astype(np.int64)
        last = np.floor((p.max(axis=1) - lo) / cell - 0.5).astype(np.int64)
        first = np.maximum(first, 0)
        last = np.minimum(last, shape - 1)
        size = np.maximum(last - first + 1, 0)
        count = size[:, 0] * size[:, 1]
        tri = np.repeat(np.arange(len(ids)), count)
        if len(tri) == 0:
            return out
        k = np.arange(len(tri)) - np.repeat(np.cumsum(count) - count, count)
        i = first[tri, 0] + k // size[tri, 1]
        j = first[tri, 1] + k % size[tri, 1]
        query = raster[i, j]
        tri, query = tri[query >= 0], query[query >= 0]
        inside = _in_triangle(xy[query], p[tri])
        tri, query = tri[inside], query[inside]
        # Lowest triangle index wins on shared edges: assign in reverse order.
        order = np.argsort(-tri, kind="stable")
        out[query[order]] = ids[tri[order]]
        return out

    def barycentric(self, xy: F64, simplex: NDArray[np.int_]) -> F64:
        """(K, 3) barycentric weights of points in their triangles (simplex >= 0)."""
        p = self.points[self.simplices[simplex]]
        v0, v1, v2 = p[:, 1] - p[:, 0], p[:, 2] - p[:, 0], xy - p[:, 0]
        den = v0[:, 0] * v1[:, 1] - v1[:, 0] * v0[:, 1]
        w1 = (v2[:, 0] * v1[:, 1] - v1[:, 0] * v2[:, 1]) / den
        w2 = (v0[:, 0] * v2[:, 1] - v2[:, 0] * v0[:, 1]) / den
        return np.column_stack([1.0 - w1 - w2, w1, w2])


def _in_triangle(xy: F64, corners: F64) -> NDArray[np.bool_]:
    """(K,) whether points (K, 2) lie in triangles (K, 3, 2), edges included."""
    a, b, c = corners[:, 0], corners[:, 1], corners[:, 2]

    def side(p, q, r):
        return (q[:, 0] - p[:, 0]) * (r[:, 1] - p[:, 1]) - (q[:, 1] - p[:, 1]) * (r[:, 0] - p[:, 0])

    d1, d2, d3 = side(a, b, xy), side(b, c, xy), side(c, a, xy)
    has_neg = (d1 < 0) | (d2 < 0) | (d3 < 0)
    has_pos = (d1 > 0) | (d2 > 0) | (d3 > 0)
    return ~(has_neg & has_pos)


def triangulate(points: ArrayLike) -> Triangulation:
    """Delaunay triangulation of points (P, 2); empty when fewer than 3 points or all
    collinear (a degenerate cloud has no area, and the caller gets no triangles)."""
    pts = np.asarray(points, dtype=float).reshape(-1, 2)
    if len(pts) < 3:
        return Triangulation(pts, None)
    try:
        return Triangulation(pts, Delaunay(pts))
    except QhullError:
        log.info("alpha shape: %d points are collinear or coincident; no area", len(pts))
        return Triangulation(pts, None)


def alpha_mask(tri: Triangulation, radius_limit: ArrayLike) -> NDArray[np.bool_]:
    """(T,) triangles whose circumradius is within ``radius_limit`` (scalar or (T,))."""
    return tri.circumradii() <= np.asarray(radius_limit, dtype=float)


def union_triangles(corners: F64) -> BaseGeometry:
    """Union of non-overlapping triangles (K, 3, 2) as a (Multi)Polygon (empty: none)."""
    if len(corners) == 0:
        return Polygon()
    polys = shapely.polygons(np.concatenate([corners, corners[:, :1]], axis=1))
    # Triangles of one triangulation form a coverage (no overlaps): the fast union.
    return shapely.coverage_union_all(polys)


def triangles_polygon(tri: Triangulation, keep: NDArray[np.bool_]) -> BaseGeometry:
    """Union of the kept triangles of a triangulation as a (Multi)Polygon."""
    return union_triangles(tri.points[tri.simplices[keep]])


def alpha_shape(points: ArrayLike, alpha_radius: float) -> BaseGeometry:
    """The classic alpha shape of points (P, 2) for one alpha radius, as a polygon."""
    tri = triangulate(points)
    return triangles_polygon(tri, alpha_mask(tri, alpha_radius))
