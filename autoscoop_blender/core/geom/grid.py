"""The ground lattice: target points and the ground cells a footprint may cover.

An equidistant lattice with spacing ``g`` (default 1 m, the paper's) covers the
targets and sensor areas plus ``reach_m`` (the longest sensor range) around them.
Cell ``(i, j)`` has its centre at ``(x0 + (i + 0.5) g, y0 + (j + 0.5) g)`` and stands
for ``g^2`` of ground. Cells are addressed by their flat index ``i * ny + j``.

Only cells a sensor may see a target point from, or that a mast in a sensor area may
look at, are held: those within ``reach_m`` of an area, found at the resolution of
tiles of 32 x 32 cells (``grid_layout.grid_chunks``). A thin network of roads across a
large ground holds a band along the roads, not the lattice over their bounds. Held
cells are stored by chunks of ``grid_layout.GRID_CHUNK`` (64) consecutive flat indices, in
the lattice's order; a table over the whole lattice (one int32 per chunk, int64 past
2^30 cells) gives what to add to a flat index c of each chunk to find its place:
``c + offset[c >> 6]``, one shift, one table entry and one sum. A chunk not held has
an offset so negative that numpy refuses the index, so the common case (every cell
held) costs no test. ``cells_in_disk`` returns held cells only; the other methods
answer for any lattice cell (a cell not held is dropped anew each time it is asked
for).

Distances to the targets are measured when first asked for, whole chunks at a time:
by a distance transform of a window around them, and beyond its margin against a
tree of the targets' border cells (the nearest target cell to a cell outside is
always on the border). Both give the values a distance transform of the whole
lattice gave, exactly, for every cell.

Target cells (centres inside a target area) are dropped onto the scene's top surface
at once: they are the target points A_t. Other cells are dropped only when an
evaluator first needs them (a footprint outside the targets), so no ray is cast for
ground nobody looks at. Drops go in batches (``budget.DROP_BATCH``), which bounds the
caster's memory in flight.

The grid's memory and the work on it are estimated before anything is allocated
(``refusal.check_grid``, from the same chunks): a grid the machine cannot hold is
refused in one line.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, replace
from typing import Any

import numpy as np
import shapely
from numpy.typing import NDArray
from scipy import ndimage
from scipy.spatial import cKDTree

from .. import budget, refusal
from ..errors import InputError, SceneContractError
from ..model.scene import SceneModel
from ..model.sensors import DORI_PX_PER_M, KINDS
from . import grid_layout
from .raycast import FloorCaster, RayCaster

I64 = NDArray[np.int64]
F64 = NDArray[np.float64]

# Chunk c holds flat indices c * CHUNK .. c * CHUNK + CHUNK - 1 (``grid_layout.grid_chunks``).
CHUNK = grid_layout.GRID_CHUNK
SHIFT = CHUNK.bit_length() - 1
assert 1 << SHIFT == CHUNK, "a chunk is a power of two cells"
# Distances are measured on a window this much wider than the cells asked for (m;
# ``GroundGrid._measure``): the tree is left the cells farther than this from every
# target and scattered requests, 14 to 21 % of the cells measured around 100 masts on
# two_routes and Town04 at 1 and 0.5 m (0.07, 0.5 and 1.6 s for 0.1, 0.7 and 2.7 M
# cells).
EDT_MARGIN_M = 64.0


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
    the kind that must see it (-1: any). The cells held: chunk_offset
    (ceil(nx * ny / CHUNK),) int32 or int64 (``grid_layout.chunk_dtype``) per chunk of the
    lattice, added to a flat index c in it to find c's place in the per-cell arrays
    (the dtype's least value for a chunk not held); per held cell (H = held chunks x
    CHUNK): dist (H,) float32 distance to the nearest target cell centre (m), z (H,)
    and normal (H, 3) float32 the surface under it, nan where not measured or dropped
    yet.
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
    chunk_offset: NDArray[np.signedinteger[Any]]
    dist: NDArray[np.float32]
    z: NDArray[np.float32]
    normal: NDArray[np.float32]


class GroundGrid:
    """Ground cells with lazily dropped surface heights and normals (local metres).

    Built from a scene (``GroundGrid(scene, caster, ...)``), or from another grid's
    ``arrays()`` in a worker process (``GroundGrid.from_arrays``): the same cells,
    surface and distances, with the worker's own caster for cells not dropped yet.

    check: refuse (InputError) a grid whose estimate (``refusal.check_grid``: the grid,
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
            refusal.check_grid(scene, g, reach_m)
        lo_z, hi_z = scene.z_range()
        areas = [a.geometry for a in (*scene.targets, *scene.sensor_areas)]
        lattice = grid_layout.grid_shape(shapely.union_all(areas).bounds, g, reach_m)
        x0, y0, nx, ny = lattice
        cells, region = _target_cells(scene, lattice, g)
        if len(cells) == 0:
            names = ", ".join(a.name for a in scene.targets)
            raise SceneContractError(
                f"{names}: target area holds no point of the {g:g} m grid "
                "(smaller than one cell); use a finer --grid"
            )
        # Held chunks in the lattice's order: slot k for the k-th, at k * CHUNK.
        starts, stops = grid_layout.grid_chunks(areas, lattice, g, reach_m)
        chunks = grid_layout.ranges(starts, stops)
        dtype = grid_layout.chunk_dtype(nx, ny)
        offset: NDArray[np.signedinteger[Any]]
        offset = np.full(grid_layout.chunk_count(nx, ny), np.iinfo(dtype).min, dtype=dtype)
        offset[chunks] = (np.arange(len(chunks)) - chunks) * CHUNK
        held = len(chunks) * CHUNK
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
            chunk_offset=offset,
            dist=np.full(held, np.nan, dtype=np.float32),
            z=np.full(held, np.nan, dtype=np.float32),
            normal=np.full((held, 3), np.nan, dtype=np.float32),
        )
        self._load(arrays, caster)

    @classmethod
    def from_arrays(cls, arrays: GridArrays, caster: RayCaster) -> GroundGrid:
        """A grid from ``arrays`` (its own copy of the surface; the distances, the same
        whoever measures them, stay shared) and a caster."""
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
            chunk_offset=self._offset,
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
        self._offset = a.chunk_offset
        # The last disk of ``cells_in_disk`` (read-only) and where its cells are held.
        self._disk: tuple[I64, I64] = (np.zeros(0, dtype=np.int64),) * 2
        self._z, self._normal, self._dist = a.z, a.normal, a.dist
        self.target_cells, self.target_region = a.target_cells, a.target_region
        self.region_k, self.region_px_per_m = a.region_k, a.region_px_per_m
        self.region_kind = a.region_kind
        at = self._at(self.target_cells)
        assert len(at) == 0 or at.min() >= 0, "target points lie in held chunks"
        self._target_ordinal = np.full(len(a.z), -1, dtype=np.int32)
        self._target_ordinal[at] = np.arange(len(a.target_cells))
        self._target_xy: F64 | None = None
        self._border: cKDTree | None = None
        self.ensure_dropped(self.target_cells)
        self.target_z = self._z[at].astype(float)
        self.target_normals = self._normal[at].astype(float)

    @property
    def held_cells(self) -> int:
        """Cells the grid holds arrays for (whole chunks)."""
        return len(self._z)

    def _at(self, cells: I64) -> I64:
        """(K,) where each flat cell index is held in the per-cell arrays; below
        -len(arrays) for a cell not held, so that indexing with it raises IndexError."""
        if cells is self._disk[0]:
            return self._disk[1]
        return cells + self._offset[cells >> SHIFT]

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
        cells = np.asarray(cells, dtype=np.int64)
        at = self._at(cells)
        try:
            return self._target_ordinal[at]
        except IndexError:  # a cell not held: never a target
            held = at >= 0
            out = np.full(len(at), -1, dtype=np.int32)
            out[held] = self._target_ordinal[at[held]]
            return out

    def cells_in_disk(self, centre_xy: F64, radius: float) -> I64:
        """Flat indices (read-only) of the held cells whose centre lies within ``radius``
        of ``centre_xy`` (every cell within reach of an area is held)."""
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
        cells = ii[i].astype(np.int64) * self.ny + jj[j]
        at = cells + self._offset[cells >> SHIFT]
        if len(at) and at.min() < 0:
            held = at >= 0
            cells, at = cells[held], at[held]
        # Its cells are asked about next (target_ordinal, dist_to_target): keep where
        # they are held, and the cells from being changed under it.
        cells.flags.writeable = False
        self._disk = (cells, at)
        return cells

    def dist_to_target(self, cells: I64) -> F64:
        """(K,) distance from each cell centre to the nearest target cell centre, m."""
        cells = np.asarray(cells, dtype=np.int64)
        at = self._at(cells)
        try:
            d = self._dist[at]
        except IndexError:
            out = np.empty(len(cells))
            held = at >= 0
            out[held] = self.dist_to_target(cells[held])
            out[~held] = self._nearest(cells[~held])
            return out
        todo = np.isnan(d)
        if todo.any():
            # Measure whole chunks: a footprint asks for their neighbours next.
            every = np.unique(cells[todo] >> SHIFT)[:, None] << SHIFT
            every = (every + np.arange(CHUNK)).ravel()
            every = every[every < self.nx * self.ny]
            self._dist[every + self._offset[every >> SHIFT]] = self._measure(every)
            d = self._dist[at]
        return d.astype(float)

    def _measure(self, cells: I64) -> NDArray[np.float32]:
        """``_nearest`` of the cells, through a distance transform of a window around
        them where it is small (about 45 ns a cell of the window against 1 to 2 us a
        cell for the tree): the window reaches ``EDT_MARGIN_M`` beyond them, so any
        distance up to that is the window's own; the tree answers the rest."""
        m = max(math.ceil(EDT_MARGIN_M / self.spacing), 16)  # cells
        i, j = np.divmod(cells, self.ny)
        i0, i1 = max(int(i.min()) - m, 0), min(int(i.max()) + m + 1, self.nx)
        j0, j1 = max(int(j.min()) - m, 0), min(int(j.max()) + m + 1, self.ny)
        if (i1 - i0) * (j1 - j0) > 8 * len(cells) + (4 * m) ** 2:
            return self._nearest(cells)
        # The target cells in the window, row by row.
        rows = np.arange(i0, i1) * self.ny
        tc = self.target_cells
        ti, tj = np.divmod(
            tc[grid_layout.ranges(*np.searchsorted(tc, [rows + j0, rows + j1]))], self.ny
        )
        if len(ti) == 0:
            return self._nearest(cells)
        outside = np.ones((i1 - i0, j1 - j0), dtype=bool)
        outside[ti - i0, tj - j0] = False
        d = ndimage.distance_transform_edt(outside)[i - i0, j - j0]
        far = d > m  # a nearer target cell may lie beyond the window
        out = (d * self.spacing).astype(np.float32)
        if far.any():
            out[far] = self._nearest(cells[far])
        return out

    def _nearest(self, cells: I64) -> NDArray[np.float32]:
        """(K,) float32 distance of the cells' centres to the nearest target cell
        centre, m: 0 for a target cell, else to the nearest border target cell (a
        nearer target cell t could not have all four neighbours targets, or the one
        towards the cell would be nearer still). Lattice units, then times the spacing,
        as ``ndimage.distance_transform_edt(...) * g`` would give it."""
        if self._border is None:
            self._border = cKDTree(_border_ij(self.target_cells, self.nx, self.ny))
        i, j = np.divmod(cells, self.ny)
        d, _ = self._border.query(np.column_stack([i, j]).astype(float))
        found = np.searchsorted(self.target_cells, cells)
        found = np.minimum(found, len(self.target_cells) - 1)
        d[self.target_cells[found] == cells] = 0.0
        return (d * self.spacing).astype(np.float32)

    # --- surface -----------------------------------------------------------------
    def ensure_dropped(self, cells: I64) -> None:
        """Drop the held cells whose surface is not known yet onto the top surface
        (a cell not held is dropped when asked for, see ``surface``)."""
        cells = np.asarray(cells, dtype=np.int64)
        at = self._at(cells)
        if len(at) and at.min() < 0:
            cells, at = cells[at >= 0], at[at >= 0]
        todo = np.isnan(self._z[at])
        if todo.any():
            self._drop_into(cells[todo], at[todo])

    def _drop_into(self, cells: I64, at: I64) -> None:
        """Drop held ``cells`` and keep their surface at ``at``."""
        z, normals = self.drop(self.xy(cells))
        self._z[at] = z
        self._normal[at] = normals

    def surface(self, cells: I64) -> tuple[F64, F64]:
        """(K,) surface heights and (K, 3) upward unit normals of cells (dropped if needed)."""
        cells = np.asarray(cells, dtype=np.int64)
        at = self._at(cells)
        try:
            z = self._z[at]
        except IndexError:  # some cells not held: those dropped anew
            held = at >= 0
            zs, normals = np.empty(len(cells)), np.empty((len(cells), 3))
            zs[held], normals[held] = self.surface(cells[held])
            zs[~held], normals[~held] = self.drop(self.xy(cells[~held]))
            return zs, normals
        todo = np.isnan(z)
        if todo.any():
            self._drop_into(cells[todo], at[todo])
            z = self._z[at]
        return z.astype(float), self._normal[at].astype(float)

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
    scene: SceneModel, lattice: tuple[float, float, int, int], g: float
) -> tuple[I64, NDArray[np.int32]]:
    """Flat indices of cells whose centre lies inside a target area, sorted, and the
    index of that area (the first one that holds it). Only the cells of tiles that
    meet an area are tried, ``budget.GRID_RASTER_BATCH`` at a time."""
    x0, y0, nx, ny = lattice
    t = grid_layout.GRID_TILE
    cells_parts, region_parts = [], []
    for k, area in enumerate(scene.targets):
        minx, miny, maxx, maxy = area.geometry.bounds
        i0 = max(int(math.floor((minx - x0) / g)), 0)
        i1 = min(int(math.ceil((maxx - x0) / g)), nx - 1)
        j0 = max(int(math.floor((miny - y0) / g)), 0)
        j1 = min(int(math.ceil((maxy - y0) / g)), ny - 1)
        if i1 < i0 or j1 < j0:
            continue
        window = (i0 // t, j0 // t, i1 // t + 1, j1 // t + 1)
        ti, tj0, tj1 = grid_layout.tile_runs([area.geometry], lattice, g, 0.0, window)
        # Rows of cells of each run, within the area's bounds: i, and j from ja to jb.
        rows = np.minimum(ti * t + t, i1 + 1) - np.maximum(ti * t, i0)
        i = grid_layout.ranges(np.maximum(ti * t, i0), np.minimum(ti * t + t, i1 + 1))
        ja = np.repeat(np.maximum(tj0 * t, j0), rows)
        jb = np.repeat(np.minimum(tj1 * t, j1 + 1), rows)
        if len(i) == 0:
            continue
        shapely.prepare(area.geometry)
        # Batches of whole rows, each ending in the next GRID_RASTER_BATCH cells.
        batch = (np.cumsum(jb - ja) - 1) // budget.GRID_RASTER_BATCH
        cuts = np.flatnonzero(np.diff(batch)) + 1
        for a, b in zip(np.r_[0, cuts], np.r_[cuts, len(i)]):
            n = jb[a:b] - ja[a:b]
            ci = np.repeat(i[a:b], n)
            cj = grid_layout.ranges(ja[a:b], jb[a:b])
            inside = shapely.contains_xy(area.geometry, x0 + (ci + 0.5) * g, y0 + (cj + 0.5) * g)
            cells_parts.append(ci[inside] * ny + cj[inside])
            region_parts.append(np.full(int(inside.sum()), k, dtype=np.int32))
    if not cells_parts:
        return np.zeros(0, dtype=np.int64), np.zeros(0, dtype=np.int32)
    # Areas in order: the first occurrence of a cell is in the first area holding it.
    cells, first = np.unique(np.concatenate(cells_parts), return_index=True)
    return cells.astype(np.int64), np.concatenate(region_parts)[first]


def _border_ij(cells: I64, nx: int, ny: int) -> F64:
    """(B, 2) lattice coordinates (i, j) of the target cells ``cells`` (sorted flat
    indices) that have a non-target cell, or the lattice's edge, among their four
    neighbours."""
    i, j = np.divmod(cells, ny)
    border = (i == 0) | (i == nx - 1) | (j == 0) | (j == ny - 1)
    for step in (1, -1, ny, -ny):
        other = cells + step
        at = np.minimum(np.searchsorted(cells, other), len(cells) - 1)
        border |= cells[at] != other
    return np.column_stack([i[border], j[border]]).astype(float)
