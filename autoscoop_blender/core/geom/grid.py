"""The ground lattice: target points and the ground cells a footprint may cover.

An equidistant lattice with spacing ``g`` (default 1 m, the paper's) covers the
targets and sensor areas plus ``reach_m`` (the longest sensor range) around them.
Cell ``(i, j)`` has its centre at ``(x0 + (i + 0.5) g, y0 + (j + 0.5) g)`` and stands
for ``g^2`` of ground. Cells are addressed by their flat index ``i * ny + j``.

Target cells (centres inside a target area) are dropped onto the scene's top surface
at once: they are the target points A_t. Other cells are dropped only when an
evaluator first needs them (a footprint outside the targets), so no ray is cast for
ground nobody looks at. Drops go in batches (``budget.DROP_BATCH``), which bounds the
caster's memory in flight.

The grid's memory and the work on it are estimated before anything is allocated
(``budget.check_grid``): a grid the machine cannot hold is refused in one line.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, replace

import numpy as np
import shapely
from numpy.typing import NDArray
from scipy import ndimage

from .. import budget
from ..errors import InputError, SceneContractError
from ..model.scene import SceneModel
from ..model.sensors import DORI_PX_PER_M, KINDS
from .raycast import FloorCaster, RayCaster

I64 = NDArray[np.int64]
F64 = NDArray[np.float64]


@dataclass(frozen=True)
class GridArrays:
    """A grid as plain arrays and numbers: what a worker process is sent to rebuild it.

    x0, y0: the lattice corner (local m); spacing: cell side (m); nx, ny: cells.
    z_top, drop_len: where drop rays start (local m) and how far they reach;
    floor_z: the implicit floor under the scene. target_cells (N,) flat indices,
    target_region (N,) each one's target area (index into ``scene.targets``), and per
    target area its requirements (``model.scene.Area``): region_k (R,) sensors that
    must see each point (0: the run's setting), region_px_per_m (R,) the pixel density
    a camera must reach (0: none), region_kind (R,) the index in ``sensors.KINDS`` of
    the kind that must see it (-1: any); dist (nx * ny,) float32 distance to
    the nearest target cell centre (m); z (nx * ny,) and normal (nx * ny, 3) float32:
    the surface under each cell as far as dropped (nan: not yet).
    """

    x0: float
    y0: float
    spacing: float
    nx: int
    ny: int
    target_height_m: float
    z_top: float
    drop_len: float
    floor_z: float
    target_cells: I64
    target_region: NDArray[np.int32]
    region_k: NDArray[np.int32]
    region_px_per_m: NDArray[np.float64]
    region_kind: NDArray[np.int8]
    dist: NDArray[np.float32]
    z: NDArray[np.float32]
    normal: NDArray[np.float32]


class GroundGrid:
    """Ground cells with lazily dropped surface heights and normals (local metres).

    Built from a scene (``GroundGrid(scene, caster, ...)``), or from another grid's
    ``arrays()`` in a worker process (``GroundGrid.from_arrays``): the same cells,
    surface and distances, with the worker's own caster for cells not dropped yet.

    check: refuse (InputError) a grid whose estimate (``budget.check_grid``: the grid,
    a full evaluation within ``reach_m``, the reference footprint's grid) the machine
    cannot hold; False when the caller has checked a run that includes it
    (``Problem``).
    """

    def __init__(
        self,
        scene: SceneModel,
        caster: RayCaster,
        spacing: float = 1.0,
        target_height_m: float = 0.0,
        reach_m: float = 0.0,
        *,
        check: bool = True,
    ) -> None:
        if not (math.isfinite(spacing) and spacing > 0):
            raise InputError(f"grid spacing {spacing} must be > 0")
        g = float(spacing)
        if check:
            budget.check_grid(scene, g, reach_m)
        lo_z, hi_z = scene.z_range()
        areas = [a.geometry for a in (*scene.targets, *scene.sensor_areas)]
        x0, y0, nx, ny = budget.grid_shape(shapely.union_all(areas).bounds, g, reach_m)
        n = nx * ny
        cells, region = _target_cells(scene, x0, y0, g, nx, ny)
        if len(cells) == 0:
            names = ", ".join(a.name for a in scene.targets)
            raise SceneContractError(
                f"{names}: target area holds no point of the {g:g} m grid "
                "(smaller than one cell); use a finer --grid"
            )
        outside = np.ones(n, dtype=bool)
        outside[cells] = False
        dist = ndimage.distance_transform_edt(outside.reshape(nx, ny)) * g
        arrays = GridArrays(
            x0=x0,
            y0=y0,
            spacing=g,
            nx=nx,
            ny=ny,
            target_height_m=float(target_height_m),
            z_top=hi_z + 1.0,
            drop_len=hi_z - scene.floor_z() + 2.0,
            floor_z=scene.floor_z(),
            target_cells=cells,
            target_region=region,
            region_k=np.array([a.coverage_k or 0 for a in scene.targets], dtype=np.int32),
            region_px_per_m=np.array(
                [DORI_PX_PER_M[a.dori] if a.dori else 0.0 for a in scene.targets]
            ),
            region_kind=np.array(
                [KINDS.index(a.require) if a.require else -1 for a in scene.targets],
                dtype=np.int8,
            ),
            dist=dist.astype(np.float32).ravel(),
            z=np.full(n, np.nan, dtype=np.float32),
            normal=np.full((n, 3), np.nan, dtype=np.float32),
        )
        self._load(arrays, caster)

    @classmethod
    def from_arrays(cls, arrays: GridArrays, caster: RayCaster) -> GroundGrid:
        """A grid from ``arrays`` (its own copy of the surface) and a caster."""
        grid = cls.__new__(cls)
        grid._load(replace(arrays, z=arrays.z.copy(), normal=arrays.normal.copy()), caster)
        return grid

    def arrays(self) -> GridArrays:
        """This grid as plain arrays (shared, not copied)."""
        return GridArrays(
            x0=self.x0,
            y0=self.y0,
            spacing=self.spacing,
            nx=self.nx,
            ny=self.ny,
            target_height_m=self.target_height_m,
            z_top=self._z_top,
            drop_len=self._drop_len,
            floor_z=self.caster.floor_z,
            target_cells=self.target_cells,
            target_region=self.target_region,
            region_k=self.region_k,
            region_px_per_m=self.region_px_per_m,
            region_kind=self.region_kind,
            dist=self._dist,
            z=self._z,
            normal=self._normal,
        )

    def _load(self, a: GridArrays, caster: RayCaster) -> None:
        # Drops land on the top surface, but not on overhangs (a caster may offer
        # ``ground``: the same scene without them).
        self.caster = FloorCaster(getattr(caster, "ground", caster), a.floor_z)
        self.spacing = a.spacing
        self.cell_area = self.spacing**2
        self.target_height_m = a.target_height_m
        self.drop_rays = 0
        self.x0, self.y0, self.nx, self.ny = a.x0, a.y0, a.nx, a.ny
        self._z_top, self._drop_len = a.z_top, a.drop_len
        self._z, self._normal, self._dist = a.z, a.normal, a.dist
        self.target_cells, self.target_region = a.target_cells, a.target_region
        self.region_k, self.region_px_per_m = a.region_k, a.region_px_per_m
        self.region_kind = a.region_kind
        self._target_ordinal = np.full(a.nx * a.ny, -1, dtype=np.int32)
        self._target_ordinal[a.target_cells] = np.arange(len(a.target_cells))
        self._target_xy: F64 | None = None
        self.ensure_dropped(self.target_cells)
        self.target_z = self._z[self.target_cells].astype(float)
        self.target_normals = self._normal[self.target_cells].astype(float)

    # --- lattice -----------------------------------------------------------------
    @property
    def n_targets(self) -> int:
        return len(self.target_cells)

    @property
    def target_area_m2(self) -> float:
        return self.n_targets * self.cell_area

    def xy(self, cells: I64) -> F64:
        """(K, 2) cell centres."""
        i, j = np.divmod(np.asarray(cells, dtype=np.int64), self.ny)
        g = self.spacing
        return np.stack([self.x0 + (i + 0.5) * g, self.y0 + (j + 0.5) * g], axis=-1)

    @property
    def target_xy(self) -> F64:
        """(N, 2) target cell centres (computed once)."""
        if self._target_xy is None:
            self._target_xy = self.xy(self.target_cells)
        return self._target_xy

    @property
    def target_points(self) -> F64:
        """(N, 3) target points: cell centres on the surface, raised by the target height."""
        return np.column_stack([self.target_xy, self.target_z + self.target_height_m])

    def target_ordinal(self, cells: I64) -> NDArray[np.int32]:
        """Position of each cell in the target arrays, -1 for a non-target cell."""
        return self._target_ordinal[cells]

    def cells_in_disk(self, centre_xy: F64, radius: float) -> I64:
        """Flat indices of lattice cells whose centre lies within ``radius`` of ``centre_xy``."""
        g = self.spacing
        cx, cy = float(centre_xy[0]), float(centre_xy[1])
        i0 = max(int(math.floor((cx - radius - self.x0) / g)), 0)
        i1 = min(int(math.ceil((cx + radius - self.x0) / g)), self.nx - 1)
        j0 = max(int(math.floor((cy - radius - self.y0) / g)), 0)
        j1 = min(int(math.ceil((cy + radius - self.y0) / g)), self.ny - 1)
        if i1 < i0 or j1 < j0:
            return np.zeros(0, dtype=np.int64)
        ii = np.arange(i0, i1 + 1)
        jj = np.arange(j0, j1 + 1)
        dx = self.x0 + (ii + 0.5) * g - cx
        dy = self.y0 + (jj + 0.5) * g - cy
        inside = dx[:, None] ** 2 + dy[None, :] ** 2 <= radius**2
        i, j = np.nonzero(inside)
        return ii[i].astype(np.int64) * self.ny + jj[j]

    def dist_to_target(self, cells: I64) -> F64:
        """(K,) distance from each cell centre to the nearest target cell centre, m."""
        return self._dist[cells].astype(float)

    # --- surface -----------------------------------------------------------------
    def ensure_dropped(self, cells: I64) -> None:
        """Drop the cells whose surface is not known yet onto the top surface."""
        cells = np.asarray(cells, dtype=np.int64)
        todo = cells[np.isnan(self._z[cells])]
        if len(todo) == 0:
            return
        z, normals = self.drop(self.xy(todo))
        self._z[todo] = z
        self._normal[todo] = normals

    def surface(self, cells: I64) -> tuple[F64, F64]:
        """(K,) surface heights and (K, 3) upward unit normals of cells (dropped if needed)."""
        self.ensure_dropped(cells)
        return self._z[cells].astype(float), self._normal[cells].astype(float)

    def drop(self, xy: F64) -> tuple[F64, F64]:
        """Heights (K,) and upward normals (K, 3) of the top surface under points (K, 2),
        cast in batches of ``budget.DROP_BATCH`` (each ray's answer is its own)."""
        xy = np.asarray(xy, dtype=float).reshape(-1, 2)
        batch = budget.DROP_BATCH
        if len(xy) > batch:
            parts = [self.drop(xy[k : k + batch]) for k in range(0, len(xy), batch)]
            return np.concatenate([z for z, _ in parts]), np.concatenate([n for _, n in parts])
        origins = np.column_stack([xy, np.full(len(xy), self._z_top)])
        dirs = np.tile((0.0, 0.0, -1.0), (len(xy), 1))
        dist, normals = self.caster.cast_normals(origins, dirs, self._drop_len)
        self.drop_rays += len(xy)
        # The floor catches every downward ray, so dist is finite.
        z = self._z_top - dist
        normals = normals * np.where(normals[:, 2:3] < 0, -1.0, 1.0)
        return z, normals

    def ground_z(self, xy: F64) -> F64:
        """(K,) height of the ground (the top surface, overhangs left out) under local
        points (K, 2): where masts stand and footprints are draped."""
        return self.drop(xy)[0]


def _target_cells(
    scene: SceneModel, x0: float, y0: float, g: float, nx: int, ny: int
) -> tuple[I64, NDArray[np.int32]]:
    """Flat indices of cells whose centre lies inside a target area, sorted, and the
    index of that area (the first one that holds it)."""
    cells_parts, region_parts = [], []
    taken = np.zeros(nx * ny, dtype=bool)
    for k, area in enumerate(scene.targets):
        minx, miny, maxx, maxy = area.geometry.bounds
        i0 = max(int(math.floor((minx - x0) / g)), 0)
        i1 = min(int(math.ceil((maxx - x0) / g)), nx - 1)
        j0 = max(int(math.floor((miny - y0) / g)), 0)
        j1 = min(int(math.ceil((maxy - y0) / g)), ny - 1)
        ii, jj = np.meshgrid(np.arange(i0, i1 + 1), np.arange(j0, j1 + 1), indexing="ij")
        cand = ii.ravel().astype(np.int64) * ny + jj.ravel()
        i, j = np.divmod(cand, ny)
        inside = shapely.contains_xy(area.geometry, x0 + (i + 0.5) * g, y0 + (j + 0.5) * g)
        new = cand[inside & ~taken[cand]]
        taken[new] = True
        cells_parts.append(new)
        region_parts.append(np.full(len(new), k, dtype=np.int32))
    cells = np.concatenate(cells_parts)
    region = np.concatenate(region_parts)
    order = np.argsort(cells)
    return cells[order], region[order]
