"""Where a mast may stand: on the ground, not on what stands on it.

A pose is ``height_m`` above the top surface at (x, y) (``coverage.base.place``), so
a sensor area must not offer a position whose top surface is a wall, a roof or a
tree crown: the mast would climb it. This module cuts those positions out of the
sensor areas once, when the scene is made, so that every optimizer's candidate
space and every check of a hand-placed sensor draw from the same areas.

The rule, at a plan point (x, y), over the occluder faces that lie above it (overhangs,
``names.OVERHANG_PROP``, left out: a mast stands under them):

- faces are grouped into *islands*, pieces of mesh joined by shared vertices (the
  terrain, one wall, one tree crown), so that objects merged into one mesh still
  count apart;
- the *ground* is the lowest of the islands' top surfaces there, leaving out buried
  islands (wholly below a larger one: a culvert under the terrain). A wall sunk into
  the terrain, or a building on it, tops out higher than the terrain does;
- a face that rises more than ``STEP_M`` above the ground is *standing* there; a
  position within ``FOOT_M`` (in plan) of a standing face is no mast site;
- faces of a mount object (``names.MOUNT_PROP``: a roof, a gantry, a bridge deck)
  never stand: where one is the top surface, a mast stands on it, over whatever
  stands under it; what stands on a mount (a hut on a roof) still stands.

Each face is judged at its centroid, so a face is standing or not as a whole; the
no-site region is the union of the standing faces' plans, less where a mount face
is on top of them, widened by ``FOOT_M``. Limits, said in the README: a building standing
in a hole cut into the terrain mesh, or walls joined into the terrain mesh as one
piece, read as ground, and a solid standing on nothing at all reads as a raised
ground, since nothing lower lies under it to be the ground.
"""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import shapely
from numpy.typing import NDArray
from scipy.sparse import coo_matrix
from scipy.sparse.csgraph import connected_components
from shapely.geometry.base import BaseGeometry

from ..errors import SceneContractError
from .scene import Exclusion, SceneModel, polygonal_part

F64 = NDArray[np.float64]

# A step a mast base spans: a kerb, or a road surface laid on the terrain. A 0.3 m
# guard wall is higher, and no mast stands on it.
STEP_M = 0.2
# Clearance between a mast and what stands beside it: about a mast foundation's
# radius. It also keeps every site off the exact edge of a wall, where a downward
# ray may land on either the wall's top or the ground.
FOOT_M = 0.25
# Faces whose plan covers less than this many m^2 (walls' sides) have no top to stand on.
_MIN_PLAN_M2 = 1e-9


def mast_sites(scene: SceneModel) -> SceneModel:
    """The scene with its sensor areas cut to where a mast may stand: less the no-mast
    zones (``scene.no_mast``) and less what stands on the ground (module docstring),
    each cut recorded in ``excluded``. An area left with nothing is dropped;
    SceneContractError naming the causes when no area is left."""
    causes: dict[str, BaseGeometry] = {z.name: z.geometry for z in scene.no_mast}
    for name, plan in standing_plans(scene, scene.sensor_union).items():
        causes[name] = shapely.union_all([causes[name], plan]) if name in causes else plan
    if not causes:
        return scene
    everything = shapely.union_all(list(causes.values()))
    kept, excluded = [], []
    for area in scene.sensor_areas:
        for cause, geom in causes.items():
            m2 = float(area.geometry.intersection(geom).area)
            if m2 > 1e-6:
                excluded.append(Exclusion(area.name, cause, m2))
        rest = polygonal_part(area.geometry.difference(everything))
        if rest.area > 1e-6:
            kept.append(replace(area, geometry=rest))
    if not kept:
        what = ", ".join(sorted({e.cause for e in excluded}))
        raise SceneContractError(
            f"{scene.source}: no sensor area has room for a mast: no-mast zones or "
            f"objects standing on the ground cover them all ({what})"
        )
    return replace(scene, sensor_areas=tuple(kept), excluded=tuple(excluded))


def site_blockers(scene: SceneModel, xy: F64) -> list[str | None]:
    """For each plan point (K, 2), local metres: the no-mast zone or the standing
    object (within ``FOOT_M``) that keeps a mast off it, or None: the same rule as
    ``mast_sites``, for sensors placed by hand anywhere."""
    points = shapely.points(np.asarray(xy, dtype=float).reshape(-1, 2))
    causes = {z.name: z.geometry for z in scene.no_mast}
    causes.update(standing_plans(scene, shapely.multipoints(points)))
    return [next((n for n, g in causes.items() if g.intersects(p)), None) for p in points]


def standing_plans(scene: SceneModel, where: BaseGeometry) -> dict[str, BaseGeometry]:
    """Object name -> the plan region, widened by ``FOOT_M``, where it stands on the
    ground (module docstring), for the objects that stand within ``FOOT_M`` of
    ``where`` (a polygon or points, local metres)."""
    if scene.face_object is None or len(scene.faces) == 0 or where.is_empty:
        return {}
    region = where.buffer(FOOT_M)
    tri = scene.vertices[scene.faces]
    plan = tri[:, :, :2]
    # A copy: the scene's own array feeds its ground caster.
    use = np.ones(len(tri), dtype=bool) if scene.ground_faces is None else scene.ground_faces.copy()
    minx, miny, maxx, maxy = region.bounds
    lo, hi = plan.min(axis=1), plan.max(axis=1)
    use &= (hi[:, 0] >= minx) & (lo[:, 0] <= maxx) & (hi[:, 1] >= miny) & (lo[:, 1] <= maxy)
    near = np.flatnonzero(use)
    # Islands over every face, walls' sides too: they join a box's top to its bottom.
    island = _islands(scene.faces[near])
    e1, e2 = plan[near, 1] - plan[near, 0], plan[near, 2] - plan[near, 0]
    flat = np.abs(e1[:, 0] * e2[:, 1] - e1[:, 1] * e2[:, 0]) > 2 * _MIN_PLAN_M2
    faces, island = near[flat], island[flat]
    polys = shapely.polygons(np.concatenate([plan[faces], plan[faces, :1]], axis=1))
    shapely.prepare(region)
    inside = shapely.intersects(region, polys)
    faces, island, polys = faces[inside], island[inside], polys[inside]
    if len(faces) == 0:
        return {}

    centre = plan[faces].mean(axis=1)
    at, on = shapely.STRtree(polys).query(shapely.points(centre), predicate="intersects")
    z = _height_at(tri[faces[on]], centre[at])
    ground = _ground(at, island[on], z, _extent(plan[faces], island), len(faces))
    highest = np.full(len(faces), -np.inf)
    np.maximum.at(highest, at, z)
    own = np.empty(len(faces))
    itself = at == on  # each centroid lies inside its own face
    own[at[itself]] = z[itself]
    mount = np.isin(scene.face_object[faces], _mount_ids(scene))
    standing = (own > ground + STEP_M) & ~mount
    if not standing.any():
        return {}
    # A mount on top carries the mast over what stands under it (a pillar under a
    # deck), not over what stands on it (a hut on a roof).
    on_mount = shapely.union_all(polys[mount & (own >= highest - 1e-6)])
    under = np.zeros(len(faces), dtype=bool)
    under[at[mount[on] & (z > own[at] + 1e-6)]] = True
    out: dict[str, BaseGeometry] = {}
    owner = scene.face_object[faces]
    for obj in np.unique(owner[standing]):
        mine = standing & (owner == obj)
        plan_of = shapely.union_all(
            [
                shapely.union_all(polys[mine & ~under]),
                shapely.union_all(polys[mine & under]).difference(on_mount),
            ]
        )
        if plan_of.area > 1e-6:
            out[scene.occluders[int(obj)]] = plan_of.buffer(FOOT_M)
    return out


def _ground(
    point: NDArray[np.int64], island: NDArray[np.int64], z: F64, extent: F64, n: int
) -> F64:
    """(n,) the ground at each of n points, from the faces over them: ``point``,
    ``island`` and ``z`` per (point, face) pair; extent: (islands,) plan size.

    The ground is the lowest top of the islands there, leaving out buried ones: an
    island that lies wholly below a larger one (a culvert under the terrain). A
    smaller one wholly above (a tree crown over the terrain) buries nothing."""
    width = int(island.max()) + 1
    keys, top = _group_max(point * width + island, z)
    _, low = _group_max(point * width + island, -z)
    bottom = -low
    at, isl = keys // width, keys % width
    # Every pair (r, s) of islands over the same point (keys are sorted by point).
    first = np.searchsorted(at, at, side="left")
    size = np.searchsorted(at, at, side="right") - first
    r = np.repeat(np.arange(len(at)), size)
    s = first[r] + np.arange(len(r)) - np.repeat(np.cumsum(size) - size, size)
    buried = np.zeros(len(at), dtype=bool)
    buried[r[(top[r] < bottom[s] - 1e-6) & (extent[isl[s]] > extent[isl[r]])]] = True
    ground = np.full(n, np.inf)
    np.minimum.at(ground, at[~buried], top[~buried])
    return ground


def _extent(plan: F64, island: NDArray[np.int64]) -> F64:
    """(islands,) plan area of each island's bounding box, m^2, from its faces (F, 3, 2)."""
    width = int(island.max()) + 1
    lo = np.full((width, 2), np.inf)
    hi = np.full((width, 2), -np.inf)
    np.minimum.at(lo, island, plan.min(axis=1))
    np.maximum.at(hi, island, plan.max(axis=1))
    size = np.where(np.isfinite(hi - lo), hi - lo, 0.0)
    return size[:, 0] * size[:, 1]


def _mount_ids(scene: SceneModel) -> NDArray[np.int64]:
    return np.array([k for k, n in enumerate(scene.occluders) if n in scene.mounts], dtype=int)


def _islands(faces: NDArray[np.int32]) -> NDArray[np.int64]:
    """(F,) island label of each face (F, 3): faces sharing a vertex are one island."""
    n = len(faces)
    verts, inverse = np.unique(faces.ravel(), return_inverse=True)
    rows = np.repeat(np.arange(n), 3)
    cols = n + inverse
    size = n + len(verts)
    graph = coo_matrix((np.ones(len(rows)), (rows, cols)), shape=(size, size))
    _, labels = connected_components(graph, directed=False)
    return labels[:n].astype(np.int64)


def _height_at(tri: F64, xy: F64) -> F64:
    """(K,) height of the planes of triangles (K, 3, 3) over plan points (K, 2)."""
    e1, e2 = tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0]
    d = xy - tri[:, 0, :2]
    det = e1[:, 0] * e2[:, 1] - e1[:, 1] * e2[:, 0]
    u = (d[:, 0] * e2[:, 1] - d[:, 1] * e2[:, 0]) / det
    v = (e1[:, 0] * d[:, 1] - e1[:, 1] * d[:, 0]) / det
    return tri[:, 0, 2] + u * e1[:, 2] + v * e2[:, 2]


def _group_max(keys: NDArray[np.int64], values: F64) -> tuple[NDArray[np.int64], F64]:
    """The distinct keys, sorted, and the largest value under each."""
    order = np.lexsort((values, keys))
    keys, values = keys[order], values[order]
    last = np.r_[keys[1:] != keys[:-1], True]
    return keys[last], values[last]
