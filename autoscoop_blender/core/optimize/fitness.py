"""The paper's fitness of a candidate sensor (Eq. 1-5), given the sensors fixed so far.

Eq. 1, coverage:   f_ca = sum chi(i) over target points the candidate newly covers
                        (with k-coverage: covers while they are below their k)
                        + zeta for each target point it covers that is covered already
                        + sum tau(j) over footprint cells outside the targets
Eq. 2, decay:      tau(j) = exp(-d_pp(j)^2 / (2 theta_tau^2)),  d_pp = distance to the
                   nearest target point
Eq. 3, distance:   f_ds = f_ca / z * sum_i exp(-d_sensor(i)^2 / (2 theta^2))
Eq. 4, seamless:   f_sc = f_ca / z * sum_i exp(-d_sensor_area(i)^2 / (2 theta^2))
Eq. 5, total:      f_s = w_ca f_ca                            (first sensor)
                   f_s = w_ca f_ca + w_ds f_ds + w_sc f_sc    (later sensors)

Choices where the paper is silent or ambiguous:

* ``zeta`` (overlap constant) = 0.02 points/m^2 per already covered point. The paper
  says overlap is penalised relative to new coverage and calls zeta a constant. A
  small positive value keeps f_ca >= 0, so the multiplicative Eq. 3 and 4 keep their
  sign, and still prefers seamless overlap to nothing; it must stay far below the
  density of a new point (>= 1.727 for the paper camera, so one new point outweighs
  86 overlapped ones), or overlap drowns the small gains that close the last gaps
  (with 0.1 the ES stalled near 95 % on two_routes).
* ``z`` in Eq. 3 and 4 is the number of sensors fixed so far and the sums run over
  them: the terms are f_ca times the *mean* closeness to the fixed sensors. d_sensor(i)
  is the horizontal distance from the candidate's mast to fixed sensor i; Eq. 3 thus
  rewards standing on an existing mast (fewer masts), as the paper's clustering wants.
* d_sensor_area(i) is the horizontal distance from the centroid of the candidate's
  footprint (the target and band cells it covers) to fixed sensor i: footprints next
  to the existing sensors close gaps (seamless coverage).
* The paper writes one theta for Eq. 2 to 4, but they measure different things:
  footprint cells beside a road (metres) and distances between masts (tens of
  metres). ``theta_tau_m`` = 2 m for Eq. 2 (footprint spilling about a lane width
  beside the road still counts), ``theta_m`` = 20 m for Eq. 3 and 4 (about half a
  camera footprint's reach). Outside cells count only within the band where
  tau >= 0.05 (d_pp <= 2.45 theta_tau); beyond it tau is negligible and no ray is
  cast for it. Likewise the sums of Eq. 3 and 4 run over the fixed sensors within
  6 theta (120 m), found in a bucket index: a sensor farther away adds under 1.5e-8,
  and the full sums would make each candidate's cost grow with the sensors fixed.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np
from numpy.typing import NDArray

from ..coverage.base import SensorCoverage
from ..geom.grid import GroundGrid
from ..settings import TAU_FLOOR, FitnessParams

F64 = NDArray[np.float64]

# Eq. 3 and 4 count fixed sensors within this many theta: exp(-6^2 / 2) = 1.5e-8.
CLOSENESS_CUTOFF = 6.0


@dataclass
class FixedSensors:
    """What the fitness needs of the sensors fixed so far.

    covered: (N,) bool over the grid's target points, covered to their k (``need``,
    (N,), default 1 each; ``counts``: sensors fixed that cover each point);
    positions: (z, 2) masts, local XY; n_covered: how many of ``covered`` are set
    (counted once, then kept by ``mark``, so that progress reports need not count N
    points after every evaluation).
    """

    covered: NDArray[np.bool_]
    positions: list[tuple[float, float]] = field(default_factory=list)
    need: NDArray[np.int32] | None = None
    n_covered: int = field(init=False)
    counts: NDArray[np.int32] = field(init=False)
    _bucket_m: float = field(default=0.0, repr=False)
    _buckets: dict[tuple[int, int], list[int]] = field(default_factory=dict, repr=False)
    _around: dict[tuple[int, int], F64] = field(default_factory=dict, repr=False)
    _indexed: int = field(default=0, repr=False)

    def __post_init__(self) -> None:
        if self.need is None:
            self.need = np.ones(len(self.covered), dtype=np.int32)
        self.counts = np.where(self.covered, self.need, 0).astype(np.int32)
        self.n_covered = int(np.count_nonzero(self.covered))

    @property
    def short(self) -> NDArray[np.bool_]:
        """(N,) the points still below their k."""
        assert self.need is not None
        return self.counts < self.need

    def add(self, cov: SensorCoverage) -> NDArray[np.int64]:
        """Fix a sensor; returns the target ordinals it newly covers to their k."""
        return self.mark(cov.covered, (cov.pose.x, cov.pose.y))

    def mark(self, seen: NDArray[np.int64], position: tuple[float, float]) -> NDArray[np.int64]:
        """Fix a sensor at ``position`` (local XY) that covers target ordinals ``seen``;
        returns those it brings to their k."""
        assert self.need is not None
        newly = seen[self.counts[seen] == self.need[seen] - 1]
        self.counts[seen] += 1
        self.covered[newly] = True
        self.positions.append(position)
        self.n_covered += len(newly)
        return newly

    def near(self, x: float, y: float, radius: float) -> F64:
        """(k, 2) the fixed positions within ``radius`` of (x, y), in the order fixed.

        Looked up in square buckets of side ``radius`` (the 3 x 3 around (x, y)), so a
        candidate's cost does not grow with the number of sensors fixed so far. Each
        bucket keeps the positions of its 3 x 3 neighbourhood as one array until a
        sensor is fixed in it: candidates outnumber fixed sensors a thousandfold.
        Hand-written because it is faster: ``scipy.spatial.cKDTree.query_ball_point``
        with the same order and filter gives the same arrays but took 12.0 us a call
        against 5.2 us here (70 fixed masts, 1,400 queries after each; 2026-11-23).
        """
        if self._bucket_m != radius:
            self._bucket_m, self._buckets, self._around, self._indexed = radius, {}, {}, 0
        for k in range(self._indexed, len(self.positions)):
            i, j = self._bucket(*self.positions[k])
            self._buckets.setdefault((i, j), []).append(k)
            for di in (-1, 0, 1):
                for dj in (-1, 0, 1):
                    self._around.pop((i + di, j + dj), None)
        self._indexed = len(self.positions)
        key = self._bucket(x, y)
        xy = self._around.get(key)
        if xy is None:
            i, j = key
            ids = sorted(
                k
                for di in (-1, 0, 1)
                for dj in (-1, 0, 1)
                for k in self._buckets.get((i + di, j + dj), ())
            )
            xy = self._around[key] = np.array(
                [self.positions[k] for k in ids], dtype=float
            ).reshape(-1, 2)
        return xy[np.hypot(xy[:, 0] - x, xy[:, 1] - y) <= radius]

    def _bucket(self, x: float, y: float) -> tuple[int, int]:
        return math.floor(x / self._bucket_m), math.floor(y / self._bucket_m)


@dataclass(frozen=True)
class Fitness:
    """The terms of Eq. 5 for one candidate, and how many points it adds."""

    f_s: float
    f_ca: float
    f_ds: float
    f_sc: float
    new_points: int


def fitness(
    grid: GroundGrid, cov: SensorCoverage, fixed: FixedSensors, params: FitnessParams
) -> Fitness:
    """Eq. 1-5 for candidate coverage ``cov`` (evaluated with the ``band_m`` band). A
    covered point counts as new while it is below its k (k = 1: not covered yet);
    ``new_points`` counts those."""
    assert fixed.need is not None
    new = fixed.counts[cov.covered] < fixed.need[cov.covered]
    f_cov = float(cov.chi[new].sum()) + params.zeta * float((~new).sum())
    d_pp = grid.dist_to_target(cov.outside)
    tau = np.exp(-(d_pp**2) / (2 * params.theta_tau_m**2))
    f_ca = f_cov + float(tau[tau >= TAU_FLOOR].sum())

    z = len(fixed.positions)
    if z == 0:
        return Fitness(params.w_ca * f_ca, f_ca, 0.0, 0.0, int(new.sum()))
    f_ds = f_ca / z * _closeness(fixed, cov.pose.x, cov.pose.y, params.theta_m)
    f_sc = 0.0
    n_cells = len(cov.covered) + len(cov.outside)
    if n_cells:
        total = grid.target_xy[cov.covered].sum(axis=0) + grid.xy(cov.outside).sum(axis=0)
        cx, cy = total / n_cells
        f_sc = f_ca / z * _closeness(fixed, cx, cy, params.theta_m)
    f_s = params.w_ca * f_ca + params.w_ds * f_ds + params.w_sc * f_sc
    return Fitness(f_s, f_ca, f_ds, f_sc, int(new.sum()))


def _closeness(fixed: FixedSensors, x: float, y: float, theta: float) -> float:
    """sum_i exp(-d_i^2 / (2 theta^2)) over the fixed sensors i, d_i their distance to
    (x, y). Sensors beyond CLOSENESS_CUTOFF theta are left out: each would add less
    than 1.5e-8, and summing over all of them costs every candidate O(sensors)."""
    near = fixed.near(x, y, CLOSENESS_CUTOFF * theta)
    d2 = (near[:, 0] - x) ** 2 + (near[:, 1] - y) ** 2
    return float(np.exp(-d2 / (2 * theta**2)).sum())
