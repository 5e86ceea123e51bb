"""``targeted`` coverage with sight lines cached per mast position.

Whether a target point is visible from a mast does not depend on where the sensor
looks, only on where it stands. So for each (model, position, height) every sight
ray is cast at most once, and only when some evaluated orientation needs it (the
point lies in view and over the threshold); its answer is kept. Orientations after
that are pure numpy. An optimizer that revisits positions (the ES does, on a
lattice) casts each ray once instead of once per candidate, and never casts a ray to
a point no candidate looked at.

Two stores per position: the sight-line geometry of the points some allowed
orientation could cover (in range, dense enough at the pattern's densest direction,
inside the depression band the pitch limits allow) is plain numpy and kept in a
bounded LRU, recomputed when evicted; the ray answers are one byte per point and
kept for the whole run.

Answers are identical, bit for bit, to ``TargetedEvaluator`` for poses within the
pitch limits: both use the same per-row arithmetic (``sight_lines``, ``view``,
``clear_sight``) on the same rows.
"""

from __future__ import annotations

import math
from collections import OrderedDict
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from ..geom.grid import GroundGrid
from ..geom.raycast import RayCaster
from ..model.sensors import SensorModel, SensorPose, frame
from .base import (
    SensorCoverage,
    SightLines,
    cells_in_reach,
    clear_sight,
    detects_many,
    pixel_need,
    sight_lines,
    view,
)
from .targeted import TargetedEvaluator

I64 = NDArray[np.int64]


@dataclass(frozen=True)
class _Reach:
    """The cells a position might cover with some allowed orientation, and the
    orientation-free geometry of their sight lines."""

    cells: I64
    ordinal: I64
    lines: SightLines

    @property
    def nbytes(self) -> int:
        lines = self.lines
        arrays = [self.cells, self.ordinal, lines.d, lines.dist, lines.surface]
        if lines.gd is not lines.d:
            arrays.append(lines.gd)
        if lines.facing is not None:
            arrays.append(lines.facing)
        return sum(a.nbytes for a in arrays)


# Ray answers per row of a _Reach: not asked yet, blocked, clear.
_UNKNOWN, _BLOCKED, _CLEAR = -1, 0, 1
# How much wider than the FoV's largest off-axis angle the depression band is (rad).
_BAND_MARGIN_RAD = 1e-6


class CachedTargetedEvaluator:
    """``targeted`` with per-position sight-line caching (same results, fewer rays).

    ``max_bytes`` bounds the geometry kept (56 bytes a row, about 3,300 rows a
    position for the paper camera); the least recently used positions are recomputed
    when needed again, without casting any ray. The default, 2 GiB, holds every
    position of a 200,000 m^2 target (12 tiles of ``full_ground``: 28 million rows):
    evicting positions an ES revisits costs more than it saves (3 tiles under a
    112 MB bound recomputed 36,000 positions instead of 2,000, a third of the run).
    """

    method = "targeted"

    def __init__(self, grid: GroundGrid, caster: RayCaster, max_bytes: int = 2 << 30) -> None:
        self.grid = grid
        self.caster = caster
        self.max_bytes = max_bytes
        self._direct = TargetedEvaluator(grid, caster)
        self._reach: OrderedDict[tuple, _Reach] = OrderedDict()
        self._answers: dict[tuple, NDArray[np.int8]] = {}
        self._bytes = 0
        self.extra_rays = 0  # rays cast outside evaluate() (reachability)

    @property
    def positions(self) -> int:
        """Distinct (model, position, band) keys seen so far."""
        return len(self._answers)

    def evaluate(
        self,
        model: SensorModel,
        pose: SensorPose,
        outside_band_m: float | None = None,
        visibility: bool = False,
    ) -> SensorCoverage:
        full = outside_band_m is not None and math.isinf(outside_band_m)
        in_limits = model.pitch_min_deg <= pose.pitch_deg <= model.pitch_max_deg
        if visibility or full or not in_limits:
            # Reports and out-of-limit poses: nothing to share, ask directly.
            return self._direct.evaluate(model, pose, outside_band_m, visibility)

        reach, answers = self._position(model, pose, outside_band_m)
        px_need = pixel_need(self.grid, model, reach.ordinal)
        rot = frame(pose.pitch_deg, pose.yaw_deg)
        _, density, need = view(model, rot, reach.lines, px_need)
        rays = self._ask(pose, reach, answers, need)
        covered = need & (answers == _CLEAR)
        is_target = reach.ordinal >= 0
        cov_t = covered & is_target
        return SensorCoverage(
            pose=pose,
            model=model,
            method=self.method,
            covered=reach.ordinal[cov_t],
            chi=density[cov_t],
            visible=None,
            outside=reach.cells[covered & ~is_target],
            footprint_m2=None,
            rays=rays,
            _cells=reach.cells[covered],
        )

    def cover_many(
        self, model: SensorModel, pose: SensorPose, rots: NDArray[np.float64]
    ) -> tuple[NDArray[np.bool_], NDArray[np.int64]]:
        """Which target points each of O orientations ``rots`` (O, 3, 3) covers from the
        pose's position: (O, K) bool over the K target ordinals also returned. Same
        per-point answers as ``evaluate`` for each orientation; rays only to points
        some orientation needs and nothing has asked about yet."""
        reach, answers = self._position(model, pose, None)
        px_need = pixel_need(self.grid, model, reach.ordinal)
        need = detects_many(model, rots, reach.lines, px_need)
        self.extra_rays += self._ask(pose, reach, answers, need.any(axis=0))
        return need & (answers == _CLEAR), reach.ordinal

    def reachable(
        self, model: SensorModel, pose: SensorPose, wanted: NDArray[np.bool_]
    ) -> NDArray[np.int64]:
        """Target ordinals among ``wanted`` (N,) bool that some orientation within the
        pitch limits might cover from the pose's position: in range, dense enough at
        the pattern's densest direction, in the depression band, in line of sight.
        An upper bound (the FoV is not tested as a whole); rays only to wanted points.
        """
        reach, answers = self._position(model, pose, None)
        is_wanted = np.zeros(len(reach.cells), dtype=bool)
        targets = reach.ordinal >= 0
        is_wanted[targets] = wanted[reach.ordinal[targets]]
        self.extra_rays += self._ask(pose, reach, answers, is_wanted)
        return reach.ordinal[is_wanted & (answers == _CLEAR)]

    def _position(
        self, model: SensorModel, pose: SensorPose, outside_band_m: float | None
    ) -> tuple[_Reach, NDArray[np.int8]]:
        """The pose's position: its reach and its ray answers so far (one per row)."""
        key = (model, pose.x, pose.y, pose.z, outside_band_m)
        reach = self._get_reach(key, model, pose.position, outside_band_m)
        answers = self._answers.setdefault(key, np.full(len(reach.cells), _UNKNOWN, np.int8))
        return reach, answers

    def _ask(
        self, pose: SensorPose, reach: _Reach, answers: NDArray[np.int8], rows: NDArray[np.bool_]
    ) -> int:
        """Cast a sight ray to each of ``rows`` (bool over the reach) not asked before and
        keep its answer; returns the number of rays cast."""
        ask = np.flatnonzero(rows & (answers == _UNKNOWN))
        clear = clear_sight(self.caster, pose.position, reach.lines, ask)
        answers[ask] = np.where(clear, _CLEAR, _BLOCKED)
        return len(ask)

    def _get_reach(
        self, key: tuple, model: SensorModel, s: NDArray[np.float64], outside_band_m: float | None
    ) -> _Reach:
        entry = self._reach.get(key)
        if entry is not None:
            self._reach.move_to_end(key)
            return entry
        entry = self._compute(model, s, outside_band_m)
        self._reach[key] = entry
        self._bytes += entry.nbytes
        while self._bytes > self.max_bytes and len(self._reach) > 1:
            _, old = self._reach.popitem(last=False)
            self._bytes -= old.nbytes
        return entry

    def _compute(
        self, model: SensorModel, s: NDArray[np.float64], outside_band_m: float | None
    ) -> _Reach:
        cells, ordinal = cells_in_reach(self.grid, s, model.range_m, outside_band_m)
        lines = sight_lines(self.grid, s, cells, pixels=model.resolution_px is not None)
        # Could any allowed orientation cover the point? In range, dense enough at
        # the pattern's densest direction, within the reachable depression band. The
        # band is a hair (1e-6 rad) wider than the FoV: arcsin's rounding must not drop
        # a point on a corner ray that the FoV test (its own 1e-9 tolerance) keeps.
        reach = math.radians(model.max_off_axis_deg()) + _BAND_MARGIN_RAD
        depression = -np.arcsin(np.clip(lines.d[:, 2], -1.0, 1.0))
        band = (depression >= math.radians(model.pitch_min_deg) - reach) & (
            depression <= math.radians(model.pitch_max_deg) + reach
        )
        best_density = model.max_rays_per_sr() * lines.surface * (1 + 1e-9)
        maybe = (
            (lines.dist > 1e-9)
            & (lines.dist <= model.range_m)
            & band
            & (best_density >= model.min_density_per_m2)
        )
        # And sharp enough at the FoV's corner, where a pixel spans the least. (With a
        # target height the density is measured along another line than the FoV's, so
        # only the points the model can never cover are left out there.)
        px_need = pixel_need(self.grid, model, ordinal)
        if px_need is not None:
            maybe &= np.isfinite(px_need)
            if model.resolution_px is not None and lines.facing is not None and lines.gd is lines.d:
                best_px = np.sqrt(model.max_px_per_sr() * lines.facing) * (1 + 1e-6)
                maybe &= best_px >= px_need
        rows = np.flatnonzero(maybe)
        return _Reach(cells[rows], ordinal[rows], lines.subset(rows))
