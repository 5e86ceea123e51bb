"""The ground lattice: target points and the ground cells a footprint may cover.

An equidistant lattice with spacing ``g`` (default 1 m, the paper's) covers the
targets and sensor areas plus ``reach_m`` (the longest sensor range) around them.
Cell ``(i, j)`` has its centre at ``(x0 + (i + 0.5) g, y0 + (j + 0.5) g)`` and stands
for ``g^2`` of ground. Cells are addressed by their flat index ``i * ny + j``.

Target cells (centres inside a target area) are dropped onto the scene's top surface
at once: they are the target points A_t. Other cells are dropped only when an
evaluator first needs them (a footprint outside the targets), so no ray is cast for
ground nobody looks at.
"""

from __future__ import annotations

import math

import numpy as np
import shapely
from numpy.typing import NDArray
from scipy import ndimage

from .errors import InputError, SceneContractError
from .raycast import FloorCaster, RayCaster
from .scene_model import SceneModel

I64 = NDArray[np.int64]
F64 = NDArray[np.float64]


class GroundGrid:
    """Ground cells with lazily dropped surface heights and normals (local metres)."""

    def __init__(
        self,
        scene: SceneModel,
        caster: RayCaster,
        spacing: float = 1.0,
        target_height_m: float = 0.0,
        reach_m: float = 0.0,
    ) -> None:
        if not (math.isfinite(spacing) and spacing > 0):
            raise InputError(f"grid spacing {spacing} must be > 0")
        self.scene = scene
        # Drops land on the top surface, but not on overhangs (a caster may offer
        # ``ground``: the same scene without them).
        self.caster = FloorCaster(getattr(caster, "ground", caster), scene.floor_z())
        self.spacing = float(spacing)
        self.cell_area = self.spacing**2
        self.target_height_m = float(target_height_m)
        self.drop_rays = 0

        lo_z, hi_z = scene.z_range()
        self._z_top = hi_z + 1.0
        self._drop_len = hi_z - scene.floor_z() + 2.0

        areas = [a.geometry for a in (*scene.targets, *scene.sensor_areas)]
        minx, miny, maxx, maxy = shapely.union_all(areas).bounds
        g = self.spacing
        pad = reach_m + 2 * g
        self.x0 = math.floor((minx - pad) / g) * g
        self.y0 = math.floor((miny - pad) / g) * g
        self.nx = int(math.ceil((maxx + pad - self.x0) / g))
        self.ny = int(math.ceil((maxy + pad - self.y0) / g))
        n = self.nx * self.ny
        self._z = np.full(n, np.nan, dtype=np.float32)
        self._normal = np.full((n, 3), np.nan, dtype=np.float32)

        self._target_ordinal = np.full(n, -1, dtype=np.int32)
        self._target_xy: F64 | None = None
        self.target_cells, self.target_region = self._find_target_cells()
        if len(self.target_cells) == 0:
            names = ", ".join(a.name for a in scene.targets)
            raise SceneContractError(
                f"{names}: target area holds no point of the {g:g} m grid "
                "(smaller than one cell); use a finer --grid"
            )
        self._target_ordinal[self.target_cells] = np.arange(len(self.target_cells))
        self._dist = self._distance_field()
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
        """Heights (K,) and upward normals (K, 3) of the top surface under points (K, 2)."""
        xy = np.asarray(xy, dtype=float).reshape(-1, 2)
        origins = np.column_stack([xy, np.full(len(xy), self._z_top)])
        dirs = np.tile((0.0, 0.0, -1.0), (len(xy), 1))
        dist, normals = self.caster.cast_normals(origins, dirs, self._drop_len)
        self.drop_rays += len(xy)
        # The floor catches every downward ray, so dist is finite.
        z = self._z_top - dist
        normals = normals * np.where(normals[:, 2:3] < 0, -1.0, 1.0)
        return z, normals

    # --- construction ------------------------------------------------------------
    def _find_target_cells(self) -> tuple[I64, NDArray[np.int32]]:
        """Flat indices of cells inside any target area and the index of that area."""
        cells_parts, region_parts = [], []
        taken = np.zeros(self.nx * self.ny, dtype=bool)
        for k, area in enumerate(self.scene.targets):
            cand = self._cells_in_bounds(area.geometry.bounds)
            xy = self.xy(cand)
            inside = shapely.contains_xy(area.geometry, xy[:, 0], xy[:, 1])
            new = cand[inside & ~taken[cand]]
            taken[new] = True
            cells_parts.append(new)
            region_parts.append(np.full(len(new), k, dtype=np.int32))
        cells = np.concatenate(cells_parts)
        region = np.concatenate(region_parts)
        order = np.argsort(cells)
        return cells[order], region[order]

    def _cells_in_bounds(self, bounds: tuple[float, float, float, float]) -> I64:
        g = self.spacing
        minx, miny, maxx, maxy = bounds
        i0 = max(int(math.floor((minx - self.x0) / g)), 0)
        i1 = min(int(math.ceil((maxx - self.x0) / g)), self.nx - 1)
        j0 = max(int(math.floor((miny - self.y0) / g)), 0)
        j1 = min(int(math.ceil((maxy - self.y0) / g)), self.ny - 1)
        ii, jj = np.meshgrid(np.arange(i0, i1 + 1), np.arange(j0, j1 + 1), indexing="ij")
        return (ii.ravel().astype(np.int64) * self.ny + jj.ravel()).astype(np.int64)

    def _distance_field(self) -> NDArray[np.float32]:
        """Distance of every cell centre to the nearest target cell centre, m (flat)."""
        outside = np.ones(self.nx * self.ny, dtype=bool)
        outside[self.target_cells] = False
        d = ndimage.distance_transform_edt(outside.reshape(self.nx, self.ny))
        return (d * self.spacing).astype(np.float32).ravel()
