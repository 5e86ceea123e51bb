"""Ray casting behind one small protocol, so the core never touches Blender.

``cast(origins (N, 3), dirs (N, 3) unit, max_dist float or (N,))`` returns the hit
distance (N,) in metres, ``inf`` for a miss within ``max_dist``. ``cast_normals``
also returns the unit surface normals (N, 3), turned to face the ray (nan on a miss).

Implementations here are exact numpy references for tests and small scenes; the
production caster wraps Blender's BVHTree (``autoscoop_blender.scene.bvh``).
"""

from __future__ import annotations

from typing import Protocol

import numpy as np
from numpy.typing import ArrayLike, NDArray

F64 = NDArray[np.float64]


class RayCaster(Protocol):
    def cast(self, origins: F64, dirs: F64, max_dist: ArrayLike) -> F64: ...

    def cast_normals(self, origins: F64, dirs: F64, max_dist: ArrayLike) -> tuple[F64, F64]: ...


def _facing(normals: F64, dirs: F64) -> F64:
    """Normals flipped where needed so that they face against the rays."""
    sign = np.where(np.einsum("ij,ij->i", normals, dirs) > 0, -1.0, 1.0)
    return normals * sign[:, None]


class TriangleCaster:
    """Brute-force Moller-Trumbore over all triangles; exact, for small scenes.

    vertices (V, 3), faces (F, 3) int, local metres. Cost is N x F, so keep F small.
    """

    def __init__(self, vertices: F64, faces: NDArray[np.int_]) -> None:
        tri = np.asarray(vertices, dtype=float)[np.asarray(faces, dtype=int)]
        self.v0 = tri[:, 0]
        self.e1 = tri[:, 1] - tri[:, 0]
        self.e2 = tri[:, 2] - tri[:, 0]
        n = np.cross(self.e1, self.e2)
        self.normals = n / np.maximum(np.linalg.norm(n, axis=1, keepdims=True), 1e-300)

    def cast_normals(self, origins: F64, dirs: F64, max_dist: ArrayLike) -> tuple[F64, F64]:
        o = np.asarray(origins, dtype=float)
        d = np.asarray(dirs, dtype=float)
        lim = np.broadcast_to(np.asarray(max_dist, dtype=float), (len(o),))
        best = np.full(len(o), np.inf)
        which = np.full(len(o), -1)
        if len(self.v0) == 0:
            return best, np.full((len(o), 3), np.nan)
        for s in range(0, len(o), 2048):
            oo, dd = o[s : s + 2048, None, :], d[s : s + 2048, None, :]
            p = np.cross(dd, self.e2[None])
            det = np.einsum("ntk,tk->nt", p, self.e1)
            with np.errstate(divide="ignore", invalid="ignore"):
                inv = 1.0 / det
                tv = oo - self.v0[None]
                u = np.einsum("ntk,ntk->nt", tv, p) * inv
                q = np.cross(tv, self.e1[None])
                v = np.einsum("ntk,ntk->nt", np.broadcast_to(dd, q.shape), q) * inv
                t = np.einsum("tk,ntk->nt", self.e2, q) * inv
            ok = (np.abs(det) > 1e-12) & (u >= 0) & (v >= 0) & (u + v <= 1) & (t > 0)
            t = np.where(ok & (t <= lim[s : s + 2048, None]), t, np.inf)
            k = np.argmin(t, axis=1)
            best[s : s + 2048] = t[np.arange(len(k)), k]
            which[s : s + 2048] = k
        normals = np.full((len(o), 3), np.nan)
        hit = np.isfinite(best)
        normals[hit] = _facing(self.normals[which[hit]], d[hit])
        return best, normals

    def cast(self, origins: F64, dirs: F64, max_dist: ArrayLike) -> F64:
        return self.cast_normals(origins, dirs, max_dist)[0]


class BoxCaster:
    """Axis-aligned boxes (slab method) plus an optional infinite ground plane z = z0.

    boxes: (B, 2, 3) with [min corner, max corner] per box, local metres.
    """

    def __init__(self, boxes: ArrayLike = (), ground_z: float | None = None) -> None:
        self.boxes = np.asarray(boxes, dtype=float).reshape(-1, 2, 3)
        self.ground_z = ground_z

    def cast_normals(self, origins: F64, dirs: F64, max_dist: ArrayLike) -> tuple[F64, F64]:
        o = np.asarray(origins, dtype=float)
        d = np.asarray(dirs, dtype=float)
        lim = np.broadcast_to(np.asarray(max_dist, dtype=float), (len(o),))
        best = np.full(len(o), np.inf)
        normals = np.full((len(o), 3), np.nan)
        with np.errstate(divide="ignore", invalid="ignore"):
            inv = 1.0 / d
            for lo, hi in self.boxes:
                t1, t2 = (lo - o) * inv, (hi - o) * inv
                tmin, tmax = np.minimum(t1, t2), np.maximum(t1, t2)
                t_in = np.nanmax(tmin, axis=1)
                t_out = np.nanmin(tmax, axis=1)
                # Entering hit, or the exit face for a ray starting inside the box.
                t = np.where(t_in > 0, t_in, t_out)
                ok = (t_out >= np.maximum(t_in, 0)) & (t > 0) & (t <= lim) & (t < best)
                axis = np.where(
                    t_in[:, None] > 0,
                    np.nanargmax(tmin, axis=1)[:, None],
                    np.nanargmin(tmax, axis=1)[:, None],
                )[:, 0]
                n = np.zeros((len(o), 3))
                n[np.arange(len(o)), axis] = 1.0
                best = np.where(ok, t, best)
                normals[ok] = n[ok]
            if self.ground_z is not None:
                t = (self.ground_z - o[:, 2]) / d[:, 2]
                ok = (t > 0) & (t <= lim) & (t < best)
                best = np.where(ok, t, best)
                normals[ok] = (0.0, 0.0, 1.0)
        hit = np.isfinite(best)
        normals[hit] = _facing(normals[hit], d[hit])
        return best, normals

    def cast(self, origins: F64, dirs: F64, max_dist: ArrayLike) -> F64:
        return self.cast_normals(origins, dirs, max_dist)[0]


class FloorCaster:
    """Another caster plus an infinite floor at z = ``floor_z`` under the scene.

    The floor catches rays that miss every occluder (a terrain smaller than the area,
    or a scene with no occluder at all), so every downward ray finds ground.
    """

    def __init__(self, inner: RayCaster, floor_z: float) -> None:
        self.inner = inner
        self.floor_z = float(floor_z)

    def cast_normals(self, origins: F64, dirs: F64, max_dist: ArrayLike) -> tuple[F64, F64]:
        dist, normals = self.inner.cast_normals(origins, dirs, max_dist)
        lim = np.broadcast_to(np.asarray(max_dist, dtype=float), (len(dist),))
        miss = ~np.isfinite(dist) & (dirs[:, 2] < 0)
        if miss.any():
            t = (self.floor_z - origins[miss, 2]) / dirs[miss, 2]
            ok = (t > 0) & (t <= lim[miss])
            idx = np.flatnonzero(miss)[ok]
            dist[idx] = t[ok]
            normals[idx] = (0.0, 0.0, 1.0)
        return dist, normals

    def cast(self, origins: F64, dirs: F64, max_dist: ArrayLike) -> F64:
        return self.cast_normals(origins, dirs, max_dist)[0]


def inside_solid(caster: RayCaster, points: F64, max_hits: int = 64) -> NDArray[np.bool_]:
    """(K,) whether points (K, 3) lie inside closed geometry, or under an open surface
    such as the terrain: an odd number of surfaces crossed going straight up."""
    pts = np.asarray(points, dtype=float).reshape(-1, 3).copy()
    crossings = np.zeros(len(pts), dtype=int)
    active = np.arange(len(pts))
    up = np.array([0.0, 0.0, 1.0])
    for _ in range(max_hits):
        if len(active) == 0:
            break
        t = caster.cast(pts[active], np.tile(up, (len(active), 1)), 1e7)
        hit = np.isfinite(t)
        active = active[hit]
        crossings[active] += 1
        pts[active, 2] += t[hit] + 1e-3  # step just past the surface
    return crossings % 2 == 1
