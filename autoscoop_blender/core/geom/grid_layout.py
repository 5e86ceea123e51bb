"""The ground grid's layout (``geom.grid.GroundGrid``), computed without the grid: the
lattice's shape over the areas' bounds and reach, and which of its cells are held, by
tiles and chunks of flat indices. Lengths in metres; cells in lattice indices."""

from __future__ import annotations

import math
from collections.abc import Sequence

import numpy as np
import shapely
from numpy.typing import NDArray
from shapely.geometry.base import BaseGeometry

from ..model.scene import Area

I64 = NDArray[np.int64]

# The grid holds only the cells a sensor may see a target point from or a mast in a
# sensor area may look at (``grid_chunks``): those in tiles of GRID_TILE x GRID_TILE
# lattice cells whose ground lies within reach of an area, stored by chunks of
# GRID_CHUNK consecutive flat indices (a run of one lattice row, or the end of one and
# the start of the next), found from the flat index by a shift and one table entry
# (``GroundGrid``).
GRID_TILE = 32
GRID_CHUNK = 64


def grid_shape(
    bounds: Sequence[float], spacing: float, reach_m: float
) -> tuple[float, float, int, int]:
    """(x0, y0, nx, ny): the lattice corner (m) and cell counts of a ground grid of
    ``spacing`` (m) over ``bounds`` (minx, miny, maxx, maxy; m) plus ``reach_m`` and
    two cells around them. ``GroundGrid`` is built on exactly this lattice."""
    minx, miny, maxx, maxy = (float(b) for b in bounds)
    g = float(spacing)
    pad = reach_m + 2 * g
    x0 = math.floor((minx - pad) / g) * g
    y0 = math.floor((miny - pad) / g) * g
    nx = int(math.ceil((maxx + pad - x0) / g))
    ny = int(math.ceil((maxy + pad - y0) / g))
    return x0, y0, nx, ny


def grid_chunks(
    geometries: Sequence[BaseGeometry],
    lattice: tuple[float, float, int, int],
    spacing: float,
    reach_m: float,
) -> tuple[I64, I64]:
    """The chunks a ground grid holds, as sorted, disjoint ranges [starts, stops) of
    chunk indices (chunk c: flat cells c * GRID_CHUNK to c * GRID_CHUNK + GRID_CHUNK - 1).

    lattice: (x0, y0, nx, ny) of ``grid_shape``. A chunk is held when one of its cells
    lies in a tile (``tile_runs``) whose ground is within ``reach_m`` (m) of one of
    ``geometries``: every cell whose centre is within reach of an area. Computed from
    the geometry alone, so the estimate and the grid count the same chunks.
    """
    x0, y0, nx, ny = lattice
    ti, tj0, tj1 = tile_runs(geometries, lattice, spacing, reach_m)
    t = GRID_TILE
    # Each tile run is a run of cells in each of its GRID_TILE lattice rows.
    rows = np.minimum(ti * t + t, nx) - ti * t
    i = ranges(ti * t, ti * t + rows)
    lo = i * ny + np.repeat(tj0 * t, rows)
    hi = i * ny + np.repeat(np.minimum(tj1 * t, ny), rows)
    return merged(lo // GRID_CHUNK, (hi - 1) // GRID_CHUNK + 1)


def chunk_count(nx: int, ny: int) -> int:
    """Chunks of ``GRID_CHUNK`` flat indices over a lattice of nx x ny cells: the
    grid's table entries."""
    return -(-nx * ny // GRID_CHUNK)


def chunk_dtype(nx: int, ny: int) -> type[np.int32] | type[np.int64]:
    """The dtype of the grid's table over a lattice of nx x ny cells: int32 while a
    flat index plus the least int32 stays below minus the cells held (at most the
    lattice's, rounded up to a chunk), so that numpy refuses it as an index; int64
    beyond (2^30 cells)."""
    return np.int32 if 2 * nx * ny + GRID_CHUNK < 2**31 else np.int64


def tile_runs(
    geometries: Sequence[BaseGeometry],
    lattice: tuple[float, float, int, int],
    spacing: float,
    distance: float,
    window: tuple[int, int, int, int] | None = None,
) -> tuple[I64, I64, I64]:
    """Tiles of GRID_TILE x GRID_TILE lattice cells whose ground (the cells' squares,
    clipped to the lattice) lies within ``distance`` (m) of one of ``geometries``, as
    runs along j: (ti, tj0, tj1), tiles (ti, tj0) to (ti, tj1 - 1), sorted, adjacent
    runs joined. Tile (ti, tj) holds cells i = ti T .. ti T + T - 1, j likewise.

    lattice: (x0, y0, nx, ny); window: (ti0, tj0, ti1, tj1), only the tiles
    ti0 <= ti < ti1, tj0 <= tj < tj1 (default: all). A quadtree over the tiles: a
    square of tiles farther than ``distance`` is dropped whole, one whose centre lies
    within ``distance`` less its half diagonal is taken whole, others are split, so
    the work follows the border of what is taken, not the lattice's size.
    """
    x0, y0, nx, ny = lattice
    g, t = float(spacing), GRID_TILE
    nti, ntj = -(-nx // t), -(-ny // t)
    wi0, wj0, wi1, wj1 = window or (0, 0, nti, ntj)
    wi1, wj1 = min(wi1, nti), min(wj1, ntj)
    parts = shapely.get_parts(np.asarray(geometries, dtype=object))
    none = np.zeros(0, dtype=np.int64)
    if wi1 <= wi0 or wj1 <= wj0 or len(parts) == 0:
        return none, none, none
    tree = shapely.STRtree(parts)
    size = 1 << max(0, math.ceil(math.log2(max(wi1 - wi0, wj1 - wj0))))
    ti, tj = np.array([wi0], dtype=np.int64), np.array([wj0], dtype=np.int64)
    whole: list[tuple[I64, I64, I64]] = []  # squares taken whole: (ti, tj, side)
    while len(ti):
        ia, ib = ti * t, np.minimum(np.minimum(ti + size, wi1) * t, nx)
        ja, jb = tj * t, np.minimum(np.minimum(tj + size, wj1) * t, ny)
        xa, xb, ya, yb = x0 + ia * g, x0 + ib * g, y0 + ja * g, y0 + jb * g
        near = tree.query(shapely.box(xa, ya, xb, yb), predicate="dwithin", distance=distance)
        hit = np.unique(near[0])
        ti, tj, xa, xb, ya, yb = ti[hit], tj[hit], xa[hit], xb[hit], ya[hit], yb[hit]
        if size == 1:
            whole.append((ti, tj, np.ones(len(ti), dtype=np.int64)))
            break
        room = distance - 0.5 * np.hypot(xb - xa, yb - ya)
        full = np.zeros(len(ti), dtype=bool)
        if (room >= 0).any():
            k = np.flatnonzero(room >= 0)
            centres = shapely.points(0.5 * (xa[k] + xb[k]), 0.5 * (ya[k] + yb[k]))
            inner = tree.query(centres, predicate="dwithin", distance=room[k])
            full[k[np.unique(inner[0])]] = True
        whole.append((ti[full], tj[full], np.full(int(full.sum()), size, dtype=np.int64)))
        size //= 2
        ti, tj = ti[~full], tj[~full]
        ti = np.concatenate([ti, ti + size, ti, ti + size])
        tj = np.concatenate([tj, tj, tj + size, tj + size])
        inside = (ti < wi1) & (tj < wj1)
        ti, tj = ti[inside], tj[inside]
    si, sj, side = (np.concatenate(a) for a in zip(*whole))
    # A square of side s: s runs, one per tile row.
    height = np.minimum(si + side, wi1) - si
    ri = ranges(si, si + height)
    r0 = np.repeat(sj, height)
    r1 = np.repeat(np.minimum(sj + side, wj1), height)
    order = np.lexsort((r0, ri))
    ri, r0, r1 = ri[order], r0[order], r1[order]
    # Join runs that touch in the same tile row (r1 of one is r0 of the next).
    new = np.ones(len(ri), dtype=bool)
    new[1:] = (ri[1:] != ri[:-1]) | (r0[1:] != r1[:-1])
    last = np.append(np.flatnonzero(new)[1:] - 1, len(ri) - 1)
    return ri[new], r0[new], r1[last]


def ranges(starts: I64, stops: I64) -> I64:
    """The integers of each range [starts, stops), concatenated in order."""
    n = np.maximum(np.asarray(stops) - np.asarray(starts), 0)
    offset = np.repeat(np.asarray(starts) - (np.cumsum(n) - n), n)
    return np.arange(int(n.sum()), dtype=np.int64) + offset


def merged(starts: I64, stops: I64) -> tuple[I64, I64]:
    """Ranges [starts, stops) joined where they overlap or touch: sorted, disjoint."""
    if len(starts) == 0:
        return starts.astype(np.int64), stops.astype(np.int64)
    order = np.argsort(starts, kind="stable")
    lo, hi = starts[order], np.maximum.accumulate(stops[order])
    new = np.ones(len(lo), dtype=bool)
    new[1:] = lo[1:] > hi[:-1]
    last = np.append(np.flatnonzero(new)[1:] - 1, len(lo) - 1)
    return lo[new].astype(np.int64), hi[last].astype(np.int64)


def areas_bounds(areas: Sequence[Area]) -> tuple[float, float, float, float]:
    """(minx, miny, maxx, maxy) of the areas together, m."""
    b = np.array([a.geometry.bounds for a in areas], dtype=float).reshape(-1, 4)
    return float(b[:, 0].min()), float(b[:, 1].min()), float(b[:, 2].max()), float(b[:, 3].max())
