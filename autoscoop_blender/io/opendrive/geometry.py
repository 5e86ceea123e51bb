"""The geometry of a road as ASAM OpenDRIVE defines it, evaluated on arrays of s.

- Reference line (planView): ``line``; ``arc`` (constant curvature); ``spiral`` (a
  clothoid: curvature linear in s from curvStart to curvEnd, positions from Fresnel
  integrals, ``scipy.special.fresnel``, after completing the square of the heading, or
  by Gauss-Legendre quadrature of the heading where the Fresnel arguments would be
  huge, i.e. a nearly constant non-zero curvature); ``poly3`` (v = a + b u + c u^2 +
  d u^3 in the local u, v frame of the start point, s mapped to u by arc length);
  ``paramPoly3`` (u(p), v(p) cubics, p = ds for ``pRange="arcLength"``, ds / length
  for ``normalized``).
- Profiles: cubic records in s (elevation, superelevation, laneOffset) and in ds from
  the lane section's start minus the record's sOffset (lane width, lane border).
- A point at lateral t (metres along the road's left normal, in the tilted road
  plane) lies at t*cos(phi) horizontally and elev + t*sin(phi) in height, phi the
  superelevation (roll, radians).

Not modelled: crossfall and lateral ``shape`` profiles, lane ``<height>`` records
(kerbs, sidewalks raised a few cm) and lane ``level`` flags; the surface is the
plane tilted by the superelevation.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np
from numpy.typing import NDArray
from scipy.special import fresnel

from .parse import Geometry, Lane, LaneSection, Poly, Road

F64 = NDArray[np.float64]

# Gauss-Legendre nodes on [0, 1] for the spiral fallback and arc-length tables.
_GL_X, _GL_W = np.polynomial.legendre.leggauss(8)
_GL_X = (_GL_X + 1.0) / 2.0
_GL_W = _GL_W / 2.0
# Fresnel arguments beyond this lose digits: the heading is integrated instead.
_FRESNEL_MAX_ARG = 1.0e3
# Cells of a poly3 arc-length table: 4,096 keeps a 200 m record at the 5 cm cells it
# has always had, and bounds the work of a record thousands of kilometres long.
_TABLE_CELLS = 4096


def _active(records: Sequence[Poly], s: F64, base: float) -> tuple[F64, F64]:
    """The coefficients (N, 4) of the record active at each s (N,) and ds from its
    start (records sorted by start; before the first record the first applies)."""
    starts = np.array([r.s + base for r in records])
    idx = np.clip(np.searchsorted(starts, s, side="right") - 1, 0, len(records) - 1)
    coef = np.array([(r.a, r.b, r.c, r.d) for r in records])[idx]
    return coef, s - starts[idx]


def eval_polys(records: Sequence[Poly], s: F64, base: float = 0.0) -> F64:
    """The piecewise cubic at s (records sorted by start; before the first record the
    first applies). ``base`` is added to every record's start (a lane section's s)."""
    s = np.asarray(s, dtype=np.float64)
    if not records:
        return np.zeros_like(s)
    if len(records) == 1:  # most profiles: one record, the same arithmetic
        r = records[0]
        ds = s - (r.s + base)
        out: F64 = r.a + ds * (r.b + ds * (r.c + ds * r.d))
        return out
    coef, ds = _active(records, s, base)
    return coef[..., 0] + ds * (coef[..., 1] + ds * (coef[..., 2] + ds * coef[..., 3]))


def eval_poly_slopes(records: Sequence[Poly], s: F64, base: float = 0.0) -> F64:
    """d/ds of the piecewise cubic at s (m/m for an elevation), as ``eval_polys``."""
    s = np.asarray(s, dtype=np.float64)
    if not records:
        return np.zeros_like(s)
    coef, ds = _active(records, s, base)
    return coef[..., 1] + ds * (2.0 * coef[..., 2] + ds * 3.0 * coef[..., 3])


def _cubic(c: Sequence[float], p: F64) -> F64:
    return c[0] + p * (c[1] + p * (c[2] + p * c[3]))


def _dcubic(c: Sequence[float], p: F64) -> F64:
    return c[1] + p * (2.0 * c[2] + p * 3.0 * c[3])


def _spiral_by_quadrature(k0: float, dk: float, ds: F64) -> tuple[F64, F64]:
    """(x, y) of a clothoid from the origin with heading 0, by 8-point Gauss-Legendre
    over cells in which the heading turns at most 0.1 rad. The cells cover what is
    asked for (0 to the largest ds), not the record's length: a record may be far
    longer than the road that uses it, or end before the next one starts."""
    span = float(np.max(ds, initial=0.0))
    # A product, not span ** 2: a Python float power raises on overflow (a station at
    # s = -1e308 asked of a spiral) where the product gives inf and the cells their cap.
    turn = abs(k0) * span + 0.5 * abs(dk) * span * span
    n = int(min(max(np.ceil(turn / 0.1), np.ceil(span / 50.0), 1), 100_000))
    edges = np.linspace(0.0, max(span, 1e-9), n + 1)

    def heading(u: F64) -> F64:
        return k0 * u + 0.5 * dk * u * u

    def integral(a: F64, b: F64) -> tuple[F64, F64]:
        u = a[:, None] + (b - a)[:, None] * _GL_X[None, :]
        th = heading(u)
        w = (b - a)[:, None] * _GL_W[None, :]
        return (np.cos(th) * w).sum(axis=1), (np.sin(th) * w).sum(axis=1)

    cx, cy = integral(edges[:-1], edges[1:])
    cum_x = np.concatenate([[0.0], np.cumsum(cx)])
    cum_y = np.concatenate([[0.0], np.cumsum(cy)])
    cell = np.clip(np.searchsorted(edges, ds, side="right") - 1, 0, n - 1)
    px, py = integral(edges[cell], ds)
    return cum_x[cell] + px, cum_y[cell] + py


def _spiral(k0: float, k1: float, length: float, ds: F64) -> tuple[F64, F64, F64]:
    """Clothoid from the origin, heading 0: (x, y, heading) at ds."""
    dk = (k1 - k0) / length if length > 0 else 0.0
    head = k0 * ds + 0.5 * dk * ds * ds
    m = max(length, 1.0)  # (a product, not m ** 3: a hostile length overflows that)
    if dk == 0.0 or abs(dk) * m * m * m < 1e-12:  # no measurable change: an arc
        if abs(k0) < 1e-15:
            return ds.copy(), np.zeros_like(ds), head
        return np.sin(k0 * ds) / k0, (1.0 - np.cos(k0 * ds)) / k0, head
    scale = np.sqrt(np.pi / abs(dk))
    u0 = k0 / dk
    t0 = u0 / scale
    t1 = (ds + u0) / scale
    if max(abs(t0), float(np.max(np.abs(t1), initial=0.0))) > _FRESNEL_MAX_ARG:
        x, y = _spiral_by_quadrature(k0, dk, ds)
        return x, y, head
    # heading = phi0 + (dk/2) (u + u0)^2 = phi0 + sigma * pi/2 * t^2
    sigma = np.sign(dk)
    phi0 = -(k0 * k0) / (2.0 * dk)
    s1, c1 = fresnel(t1)
    s0, c0 = fresnel(t0)
    dc, dsn = c1 - c0, s1 - s0
    x = scale * (np.cos(phi0) * dc - sigma * np.sin(phi0) * dsn)
    y = scale * (np.sin(phi0) * dc + sigma * np.cos(phi0) * dsn)
    return x, y, head


class ReferenceLine:
    """The planView of one road: ``evaluate(s)`` gives x, y and heading."""

    def __init__(self, geometries: Sequence[Geometry]):
        self.geometries = list(geometries)
        self.starts = np.array([g.s for g in self.geometries])
        # Lines and arcs (most of every real file) are evaluated all at once: their
        # start points, headings (cos, sin as each geometry's own would give) and
        # curvatures (0 for a line or an arc too slight to tell from one).
        g = self.geometries
        self._x = np.array([e.x for e in g])
        self._y = np.array([e.y for e in g])
        self._hdg = np.array([e.hdg for e in g])
        self._cos = np.array([np.cos(e.hdg) for e in g])
        self._sin = np.array([np.sin(e.hdg) for e in g])
        self._k = np.array([e.params[0] if e.kind == "arc" else 0.0 for e in g])
        self._simple = np.array([e.kind in ("line", "arc") for e in g])
        # poly3 arc-length tables, made when first needed (most roads have none).
        self._tables: dict[int, tuple[F64, F64]] = {}

    @staticmethod
    def _arc_length_table(g: Geometry) -> tuple[F64, F64]:
        """(s, u) pairs of a poly3: arc length along v(u) by Gauss-Legendre per cell.
        At most ``_TABLE_CELLS`` cells: 8-point Gauss-Legendre is exact for the
        smooth speed of a cubic on cells far wider than the 5 cm kept for short ones."""
        coef = g.params
        # u runs at most the arc length; extend a little so the table covers the end.
        u_max = max(g.length, 1e-9) * 1.05 + 1.0
        n = int(min(max(np.ceil(u_max / 0.05), 64), _TABLE_CELLS))
        edges = np.linspace(0.0, u_max, n + 1)
        a, b = edges[:-1], edges[1:]
        u = a[:, None] + (b - a)[:, None] * _GL_X[None, :]
        with np.errstate(over="ignore", invalid="ignore"):
            speed = np.sqrt(1.0 + _dcubic(coef, u) ** 2)
            cells = (speed * (b - a)[:, None] * _GL_W[None, :]).sum(axis=1)
        s_tab = np.concatenate([[0.0], np.cumsum(cells)])
        return s_tab, edges

    def _local(self, k: int, ds: F64) -> tuple[F64, F64, F64]:
        g = self.geometries[k]
        p = g.params
        if g.kind == "line":
            return ds.copy(), np.zeros_like(ds), np.zeros_like(ds)
        if g.kind == "arc":
            return _spiral(p[0], p[0], g.length, ds)
        if g.kind == "spiral":
            return _spiral(p[0], p[1], g.length, ds)
        if g.kind == "poly3":
            if k not in self._tables:
                self._tables[k] = self._arc_length_table(g)
            s_tab, u_tab = self._tables[k]
            u = np.interp(ds, s_tab, u_tab)
            return u, _cubic(p, u), np.arctan(_dcubic(p, u))
        # paramPoly3
        q = ds / g.length if (p[8] and g.length > 0) else ds
        cu, cv = p[0:4], p[4:8]
        return _cubic(cu, q), _cubic(cv, q), np.arctan2(_dcubic(cv, q), _dcubic(cu, q))

    def index(self, s: F64, before: bool = False) -> NDArray[np.intp]:
        """The geometry each s falls in: the last one starting at or before s (strictly
        before with ``before``: an s where a geometry starts then belongs to the one
        that ends there). Before the first start, the first."""
        if before:
            k = np.searchsorted(self.starts, s, side="left") - 1
        else:
            k = np.searchsorted(self.starts, s, side="right") - 1
        out: NDArray[np.intp] = np.clip(k, 0, len(self.starts) - 1)
        return out

    def evaluate(self, s: F64, before: bool = False) -> tuple[F64, F64, F64]:
        """x, y, heading of the reference line at s (beyond a geometry's end the
        last one that starts before s is extended; ``before``: see ``index``)."""
        s = np.asarray(s, dtype=np.float64)
        idx = self.index(s, before)
        x = np.empty_like(s)
        y = np.empty_like(s)
        h = np.empty_like(s)
        simple = self._simple[idx]
        with np.errstate(over="ignore", invalid="ignore"):
            if simple.any():
                self._lines_and_arcs(s, idx, simple, x, y, h)
            for k, sel in _groups(idx[~simple]):
                sel = np.flatnonzero(~simple)[sel]
                g = self.geometries[k]
                u, v, dh = self._local(k, s[sel] - g.s)
                c, sn = np.cos(g.hdg), np.sin(g.hdg)
                x[sel] = g.x + c * u - sn * v
                y[sel] = g.y + sn * u + c * v
                h[sel] = g.hdg + dh
        return x, y, h

    def _lines_and_arcs(
        self, s: F64, idx: NDArray[np.intp], simple: NDArray[np.bool_], x: F64, y: F64, h: F64
    ) -> None:
        """``evaluate`` of the stations on lines and arcs, in one pass (the same
        arithmetic as ``_local`` and ``_spiral`` give them one geometry at a time)."""
        sel = np.flatnonzero(simple)
        k = idx[sel]
        ds = s[sel] - self.starts[k]
        kappa = self._k[k]
        bent = np.abs(kappa) >= 1e-15
        u = ds.copy()
        v = np.zeros_like(ds)
        kb, db = kappa[bent], ds[bent]
        u[bent] = np.sin(kb * db) / kb
        v[bent] = (1.0 - np.cos(kb * db)) / kb
        dh = np.where(bent, kappa * ds, 0.0)
        c, sn = self._cos[k], self._sin[k]
        x[sel] = self._x[k] + c * u - sn * v
        y[sel] = self._y[k] + sn * u + c * v
        h[sel] = self._hdg[k] + dh

    def jumps(self) -> list[tuple[float, float]]:
        """(s, metres) where a geometry starts away from where the one before it
        arrives at that s (its end point, or its extension when the next starts
        later): a gap in the planView. NaN metres where either is not finite."""
        if len(self.geometries) < 2:
            return []
        x, y, _ = self.evaluate(self.starts[1:], before=True)
        gx = np.array([g.x for g in self.geometries[1:]])
        gy = np.array([g.y for g in self.geometries[1:]])
        with np.errstate(over="ignore", invalid="ignore"):
            gap = np.hypot(x - gx, y - gy)
        return list(zip(self.starts[1:].tolist(), gap.tolist(), strict=True))

    def turns(self, a: F64, b: F64) -> F64:
        """How far the heading turns (rad, summed absolute) from a to b, for cuts
        [a_i, b_i] that each lie within one geometry (the one ``index(a_i)`` names).

        Exact for lines, arcs and spirals (the integral of |curvature|); for poly3 and
        paramPoly3 the heading is sampled at least every 0.5 m (8 to 4,000 points a
        cut) and its steps are summed, as a heading that turns back and forth counts
        every turn.
        """
        a = np.asarray(a, dtype=np.float64)
        b = np.asarray(b, dtype=np.float64)
        out = np.zeros_like(a)
        idx = self.index(a)
        with np.errstate(over="ignore", invalid="ignore"):
            for k, sel in _groups(idx):
                g = self.geometries[k]
                if g.kind == "line":
                    continue
                if g.kind in ("arc", "spiral"):
                    k0 = g.params[0]
                    k1 = g.params[1] if g.kind == "spiral" else k0
                    dk = (k1 - k0) / g.length if g.length > 0 else 0.0
                    out[sel] = _abs_linear_integral(
                        k0 + dk * (a[sel] - g.s), k0 + dk * (b[sel] - g.s), b[sel] - a[sel]
                    )
                    continue
                for i in sel:
                    m = int(np.clip(np.ceil((b[i] - a[i]) / 0.5), 8, 4000))
                    grid = np.linspace(a[i], b[i], m + 1)
                    _, _, h = self._local(k, grid - g.s)
                    step = np.diff(h)
                    # Wrapped into (-pi, pi]: a heading from arctan2 jumps by 2 pi.
                    step = (step + np.pi) % (2.0 * np.pi) - np.pi
                    out[i] = float(np.abs(step).sum())
        return out


def _groups(idx: NDArray[np.intp]) -> list[tuple[int, NDArray[np.intp]]]:
    """(value, positions) for each distinct value of ``idx``, in one sort: a loop
    over geometries that masks every s for each would be quadratic (20,000
    geometries took seconds)."""
    if not len(idx):
        return []
    order = np.argsort(idx, kind="stable")
    values, first = np.unique(idx[order], return_index=True)
    ends = np.append(first[1:], len(idx))
    return [(int(v), order[a:b]) for v, a, b in zip(values, first, ends, strict=True)]


def _abs_linear_integral(f0: F64, f1: F64, length: F64) -> F64:
    """The integral of |f| over a cut of ``length`` where f runs linearly f0 -> f1."""
    same = f0 * f1 >= 0
    with np.errstate(divide="ignore", invalid="ignore"):
        # A sign change: two triangles, f0^2 + f1^2 over 2 |f1 - f0|, times the length.
        cross = (f0 * f0 + f1 * f1) / (2.0 * np.abs(f1 - f0)) * length
    out: F64 = np.where(same, 0.5 * np.abs(f0 + f1) * length, cross)
    return out


def lane_width(lane: Lane, section_s: float, s: F64) -> F64:
    """The width of a lane with width records at s."""
    return eval_polys(lane.widths, s, base=section_s)


def section_borders(
    road: Road, section: LaneSection, s: F64
) -> tuple[dict[int, F64], dict[int, str]]:
    """Lateral position t of every lane border at s: key 0 the lane reference line
    (laneOffset), key i the outer border of lane i (cumulative widths outward).

    Returns the borders and, per lane, a reason it cannot be built (empty if fine):
    a lane with both width and border records is refused.
    """
    offset = eval_polys(road.lane_offsets, s)
    borders: dict[int, F64] = {0: offset}
    faults: dict[int, str] = {}
    for side, lanes in ((1, section.left), (-1, section.right)):
        inner = offset
        for lane in lanes:
            if lane.widths and lane.borders:
                faults[lane.id] = "has both <width> and <border> records"
            if lane.widths or not lane.borders:
                outer = inner + side * lane_width(lane, section.s, s)
            else:
                value = eval_polys(lane.borders, s, base=section.s)
                # The t of the outer border; written as a distance on the right, take
                # the side's sign.
                if side < 0 and np.all(value >= 0):
                    value = -value
                outer = offset + value
            borders[lane.id] = outer
            inner = outer
    return borders, faults


def second_derivative_bounds(records: Sequence[Poly], lo: F64, hi: F64, base: float) -> F64:
    """A bound of |f''| on each cut [lo_i, hi_i] from the records active there:
    2 |c| + 6 |d| times the farthest distance from the record's start (inf where
    that overflows)."""
    lo = np.asarray(lo, dtype=np.float64)
    hi = np.asarray(hi, dtype=np.float64)
    if not any(r.c or r.d for r in records):  # linear or none: no bend
        return np.zeros_like(lo)
    starts = np.array([r.s + base for r in records])
    c2 = np.array([2.0 * abs(r.c) for r in records])
    d6 = np.array([6.0 * abs(r.d) for r in records])
    last = len(records) - 1
    # The records that reach into the cut: from the one active at lo to the last one
    # starting before hi (the same one, unless records start within a cut).
    k_lo = np.clip(np.searchsorted(starts, lo, side="right") - 1, 0, last)
    k_hi = np.maximum(np.clip(np.searchsorted(starts, hi, side="left") - 1, 0, last), k_lo)

    def at(k: NDArray[np.intp], a: F64, b: F64) -> F64:
        span = np.maximum(np.abs(b - starts[k]), np.abs(a - starts[k]))
        with np.errstate(over="ignore", invalid="ignore"):
            out: F64 = c2[k] + d6[k] * span
        out[np.isnan(out)] = np.inf  # 0 x inf: a span or coefficient overflowed
        return out

    bound = np.maximum(at(k_lo, lo, hi), at(k_hi, lo, hi))
    for i in np.flatnonzero(k_hi - k_lo > 1):  # rare: records closer than a cut
        ks = np.arange(k_lo[i] + 1, k_hi[i])
        more = at(ks, np.full(len(ks), lo[i]), np.full(len(ks), hi[i]))
        bound[i] = max(bound[i], float(more.max()))
    return bound
