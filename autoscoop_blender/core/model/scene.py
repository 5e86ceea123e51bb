"""The scene as plain data: occluder triangles, target areas, sensor areas.

Everything is in *local* metres: world coordinates minus ``SceneModel.origin``. A
georeferenced scene (x = 500,000 m) would lose centimetres in the single-precision
ray caster, so extraction moves the origin near the targets when coordinates are
large; readers and writers convert at the boundary with ``to_local``/``to_world``.

Areas are built from closed rings (one per curve spline) by the even-odd rule: a
ring inside another is a hole, a ring inside that an island again.
"""

from __future__ import annotations

import hashlib
import math
from dataclasses import dataclass, field, replace
from functools import reduce

import numpy as np
import shapely
from numpy.typing import NDArray
from shapely.geometry import LinearRing, MultiPolygon, Polygon
from shapely.geometry.base import BaseGeometry

from ..errors import SceneContractError

# A ring is "in the XY plane" when its best-fit plane tilts at most this much.
MAX_RING_TILT_DEG = 45.0
# Coordinates beyond this many metres get a local origin (float32 keeps ~1 mm here).
LOCAL_ORIGIN_BEYOND_M = 10_000.0


@dataclass(frozen=True)
class Area:
    """A named region in the XY plane (local metres).

    ``z`` is the mean height of the curve's points (used only where the scene has
    no surface at all); ``height_m`` is a sensor area's mast height, if given. A target
    area's requirements, None where it names none (the run's settings apply):
    ``coverage_k`` sensors must cover each of its points; ``dori`` the level of
    ``sensors.DORI_PX_PER_M`` a camera must reach there; ``require`` the sensor kind
    (``sensors.KINDS``) that must cover it.
    """

    name: str
    geometry: BaseGeometry  # Polygon or MultiPolygon, valid, non-empty
    z: float = 0.0
    height_m: float | None = None
    coverage_k: int | None = None
    dori: str | None = None
    require: str | None = None

    @property
    def area_m2(self) -> float:
        return float(self.geometry.area)


@dataclass(frozen=True)
class Exclusion:
    """Part of a sensor area where no mast may stand.

    area: the sensor area's name; cause: the no-mast curve's or the standing
    object's name; m2: how much of the area it takes (causes may overlap, so the
    parts of one area can add up to more than the area lost).
    """

    area: str
    cause: str
    m2: float

    def text(self) -> str:
        return f"{self.area}: {self.m2:,.1f} m^2 no mast site ({self.cause})"


@dataclass(frozen=True)
class SceneModel:
    """What the core needs of a scene (local metres).

    vertices: (V, 3) float64; faces: (F, 3) int32 triangles into ``vertices``.
    crs, crs_offset: the scene's georeference (``names.CRS_PROP``, checked; None: the
    scene names no CRS) and offset (x, y, z, hdg). They place the scene's *world*
    metres (local + ``origin``) in the CRS; the core never uses them.
    """

    vertices: NDArray[np.float64]
    faces: NDArray[np.int32]
    occluders: tuple[str, ...]
    targets: tuple[Area, ...]
    sensor_areas: tuple[Area, ...]
    origin: NDArray[np.float64] = field(default_factory=lambda: np.zeros(3))
    source: str = ""
    warnings: tuple[str, ...] = ()
    # (F,) False for faces of overhangs (bridges, canopies): they occlude, but target
    # points and masts are not dropped onto them. None: every face is ground.
    ground_faces: NDArray[np.bool_] | None = None
    crs: str | None = None
    crs_offset: tuple[float, float, float, float] = (0.0, 0.0, 0.0, 0.0)
    # Where masts may not stand (``names.NO_MAST_RE`` curves): already cut out of
    # ``sensor_areas``, kept to be shown and reported.
    no_mast: tuple[Area, ...] = ()
    # (F,) index into ``occluders`` of each face's object, and the objects masts may
    # stand on (``names.MOUNT_PROP``); face_object None: objects unknown, nothing is
    # judged to stand on the ground (``sites``).
    face_object: NDArray[np.int32] | None = None
    mounts: tuple[str, ...] = ()
    # What ``sites.mast_sites`` cut out of the sensor areas, and why.
    excluded: tuple[Exclusion, ...] = ()

    def targets_fingerprint(self) -> str:
        """16 hex digits that tell one ground's plan from another's: each target
        area's name, plan area and world bounds, rounded (to 0.01 m^2 and 0.01 m) so
        that the same areas read from the same file agree whatever local origin or
        crop a run chose. Occluders and sensor areas do not count: a building added
        or a band of mast sites widened leave what stands where it stood."""
        h = hashlib.sha256()
        ox, oy = (float(v) for v in self.origin[:2])
        for area in sorted(self.targets, key=lambda a: a.name):
            minx, miny, maxx, maxy = area.geometry.bounds
            bounds = (minx + ox, miny + oy, maxx + ox, maxy + oy)
            h.update(area.name.encode())
            h.update(f"{area.geometry.area:.2f}".encode())
            h.update(",".join(f"{v:.2f}" for v in bounds).encode())
        return h.hexdigest()[:16]

    def cropped(self, reach_m: float) -> SceneModel:
        """The scene without occluders that no sight line can meet: faces whose nearest
        point (in plan) lies farther than ``reach_m`` (the longest sensor range) from
        every sensor area, and not over a target (drops need the ground there).

        A sight line is at least as long as its plan, so a face kept by its plan
        distance is never one a sensor could reach. The distance is exact (GEOS,
        triangle to polygon), not to a buffered outline, whose chords cut up to
        r (1 - cos(pi / 32)) = 0.4 m off an 80 m reach; buffers 1 m wider and narrower
        only sort out, by bounding box, the faces that are surely in or out (all but
        2,310 of full_ground's 107,024: 0.24 s instead of 1.4 s).
        """
        if len(self.faces) == 0:
            return self
        tri = self.vertices[self.faces][:, :, :2]
        lo, hi = tri.min(axis=1), tri.max(axis=1)
        boxes = shapely.box(lo[:, 0], lo[:, 1], hi[:, 0], hi[:, 1])
        outer, inner = (self.sensor_union.buffer(reach_m + d) for d in (1.0, -1.0))
        shapely.prepare(outer)
        shapely.prepare(inner)
        maybe = shapely.intersects(outer, boxes)
        keep = maybe & shapely.contains(inner, boxes)
        edge = np.flatnonzero(maybe & ~keep)
        keep[edge] = shapely.dwithin(_plans(tri[edge]), self.sensor_union, reach_m)
        target = self.target_union
        shapely.prepare(target)
        over = np.flatnonzero(~keep & shapely.intersects(target, boxes))
        keep[over] = shapely.intersects(target, _plans(tri[over]))
        if keep.all():
            return self
        ground = None if self.ground_faces is None else self.ground_faces[keep]
        owner = None if self.face_object is None else self.face_object[keep]
        return replace(self, faces=self.faces[keep], ground_faces=ground, face_object=owner)

    @property
    def target_union(self) -> BaseGeometry:
        return shapely.union_all([a.geometry for a in self.targets])

    @property
    def sensor_union(self) -> BaseGeometry:
        return shapely.union_all([a.geometry for a in self.sensor_areas])

    def z_range(self) -> tuple[float, float]:
        """(lowest, highest) z of occluders and area curves, local metres."""
        zs = [a.z for a in (*self.targets, *self.sensor_areas)]
        if len(self.vertices):
            zs += [float(self.vertices[:, 2].min()), float(self.vertices[:, 2].max())]
        return min(zs), max(zs)

    def floor_z(self) -> float:
        """Height of the implicit floor under the scene, local metres.

        Rays that miss every occluder land here: at the lowest occluder, or, in a
        scene with no occluder at all, at the mean height of the target curves.
        """
        if len(self.vertices):
            return float(self.vertices[:, 2].min())
        return float(np.mean([a.z for a in self.targets]))

    def to_local(self, xyz: NDArray[np.float64]) -> NDArray[np.float64]:
        return np.asarray(xyz, dtype=float) - self.origin[: np.shape(xyz)[-1]]

    def to_world(self, xyz: NDArray[np.float64]) -> NDArray[np.float64]:
        return np.asarray(xyz, dtype=float) + self.origin[: np.shape(xyz)[-1]]


def choose_origin(points_xyz: NDArray[np.float64]) -> NDArray[np.float64]:
    """(3,) local origin: zero for ordinary scenes, else the bbox centre rounded to km."""
    if len(points_xyz) == 0:
        return np.zeros(3)
    lo, hi = points_xyz.min(axis=0), points_xyz.max(axis=0)
    if max(np.abs(lo[:2]).max(), np.abs(hi[:2]).max()) <= LOCAL_ORIGIN_BEYOND_M:
        return np.zeros(3)
    centre = np.round((lo + hi) / 2 / 1000.0) * 1000.0
    return np.array([centre[0], centre[1], 0.0])


def area_from_rings(name: str, rings: list[NDArray[np.float64]]) -> BaseGeometry:
    """Polygon or MultiPolygon from closed rings (each (K, 3), local metres), even-odd.

    Raises SceneContractError naming ``name`` for a ring that is too short, crosses
    itself, is not in the XY plane, or an area that comes out empty.
    """
    polys = []
    for k, ring in enumerate(rings):
        label = name if len(rings) == 1 else f"{name} (spline {k + 1})"
        pts = _dedupe(np.asarray(ring, dtype=float), dims=3)
        if len(pts) < 3:
            raise SceneContractError(f"{label}: a closed curve needs at least 3 points")
        tilt = _tilt_deg(pts)
        if tilt is not None and tilt > MAX_RING_TILT_DEG:
            raise SceneContractError(
                f"{label}: curve is not in the XY plane (tilted {tilt:.0f} deg)"
            )
        xy = _dedupe(pts, dims=2)[:, :2]
        if len(xy) < 3 or np.linalg.svd(xy - xy.mean(axis=0), compute_uv=False)[-1] <= 1e-9:
            raise SceneContractError(f"{label}: curve encloses no area (points on a line)")
        lr = LinearRing(xy)
        if not lr.is_simple:
            raise SceneContractError(f"{label}: curve crosses itself")
        poly = Polygon(lr)
        polys.append(poly)
    if not polys:
        raise SceneContractError(f"{name}: curve has no splines")
    geom = reduce(lambda a, b: a.symmetric_difference(b), polys)
    geom = shapely.make_valid(geom)
    geom = polygonal_part(geom)
    if geom.is_empty or geom.area <= 1e-9:
        raise SceneContractError(f"{name}: the area inside the curves is empty")
    return geom


def _dedupe(pts: NDArray[np.float64], dims: int) -> NDArray[np.float64]:
    """Drop consecutive points equal in their first ``dims`` coordinates, and a
    closing point equal to the first."""
    if len(pts) == 0:
        return pts
    keep = np.ones(len(pts), dtype=bool)
    keep[1:] = np.linalg.norm(np.diff(pts[:, :dims], axis=0), axis=1) > 1e-9
    pts = pts[keep]
    if len(pts) > 1 and np.linalg.norm(pts[0, :dims] - pts[-1, :dims]) <= 1e-9:
        pts = pts[:-1]
    return pts


def _tilt_deg(pts: NDArray[np.float64]) -> float | None:
    """Angle between the ring's Newell normal and +Z, degrees; None when the ring has
    no net area to define a plane (a figure eight, or points on a line)."""
    nxt = np.roll(pts, -1, axis=0)
    n = np.array(
        [
            np.sum((pts[:, 1] - nxt[:, 1]) * (pts[:, 2] + nxt[:, 2])),
            np.sum((pts[:, 2] - nxt[:, 2]) * (pts[:, 0] + nxt[:, 0])),
            np.sum((pts[:, 0] - nxt[:, 0]) * (pts[:, 1] + nxt[:, 1])),
        ]
    )
    norm = float(np.linalg.norm(n))
    if norm <= 1e-9:
        return None
    return math.degrees(math.acos(min(1.0, abs(n[2]) / norm)))


def _plans(tri: NDArray[np.float64]) -> NDArray[np.object_]:
    """Triangles (T, 3, 2) as polygons in plan; a wall's is a flat sliver, which is
    fine for distances and intersections (they look at its edges and inside)."""
    return shapely.polygons(np.concatenate([tri, tri[:, :1]], axis=1))


def polygonal_part(geom: BaseGeometry) -> BaseGeometry:
    """Only the polygons of a geometry (make_valid may add stray lines or points)."""
    if isinstance(geom, (Polygon, MultiPolygon)):
        return geom
    parts = [g for g in getattr(geom, "geoms", []) if isinstance(g, (Polygon, MultiPolygon))]
    return shapely.union_all(parts) if parts else Polygon()


def random_points(geom: BaseGeometry, n: int, rng: np.random.Generator) -> NDArray[np.float64]:
    """(n, 2) points drawn uniformly inside a polygonal geometry (rejection sampling)."""
    minx, miny, maxx, maxy = geom.bounds
    fill = geom.area / max((maxx - minx) * (maxy - miny), 1e-12)
    out: list[NDArray[np.float64]] = []
    got = 0
    while got < n:
        batch = max(16, int((n - got) / max(fill, 1e-3) * 1.2))
        xy = rng.uniform((minx, miny), (maxx, maxy), (batch, 2))
        xy = xy[shapely.contains_xy(geom, xy[:, 0], xy[:, 1])]
        out.append(xy)
        got += len(xy)
    return np.concatenate(out)[:n]
