"""Alpha shapes of planar point sets, built on the Delaunay triangulation.

The alpha shape of a point set keeps the Delaunay triangles whose circumradius is at
most the alpha radius; their union is the shape (it may have holes and several
parts). ``AlphaShape`` keeps the triangulation so that "which query points lie inside"
is one ``find_simplex`` call, and builds the polygon only when someone asks for it.

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
        area2 = np.abs(np.cross(p[:, 1] - p[:, 0], p[:, 2] - p[:, 0]))
        with np.errstate(divide="ignore", invalid="ignore"):
            return np.where(area2 > 0, a * b * c / (2.0 * area2), np.inf)

    def areas(self) -> F64:
        """(T,) triangle areas, m^2."""
        p = self.points[self.simplices]
        return 0.5 * np.abs(np.cross(p[:, 1] - p[:, 0], p[:, 2] - p[:, 0]))

    def locate(self, xy: F64) -> NDArray[np.int_]:
        """(K,) index of the triangle holding each query point, -1 outside the hull."""
        if self.delaunay is None or len(xy) == 0:
            return np.full(len(xy), -1)
        return self.delaunay.find_simplex(np.asarray(xy, dtype=float))

    def barycentric(self, xy: F64, simplex: NDArray[np.int_]) -> F64:
        """(K, 3) barycentric weights of points in their triangles (simplex >= 0)."""
        assert self.delaunay is not None
        t = self.delaunay.transform[simplex]
        b = np.einsum("kij,kj->ki", t[:, :2], xy - t[:, 2])
        return np.column_stack([b, 1.0 - b.sum(axis=1)])


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
