"""The OpenDRIVE reader and geometry against closed forms and independent quadrature.

Every road here is written as XML in the test; positions, areas and heights are
worked out from the standard's formulas with scipy.integrate.quad, not with the
module's own code (no Fresnel integrals, no sampling rule).
"""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest
from scipy.integrate import quad
from shapely.geometry import Polygon

from autoscoop_blender.core.errors import InputError
from autoscoop_blender.io.opendrive import build_import, read_opendrive
from autoscoop_blender.io.opendrive.build import FLOAT32_GRID_M
from autoscoop_blender.io.opendrive.geometry import ReferenceLine, section_borders


def width(a: float, b: float = 0.0, c: float = 0.0, d: float = 0.0, s: float = 0.0) -> str:
    return f'<width sOffset="{s}" a="{a}" b="{b}" c="{c}" d="{d}"/>'


def lane(lane_id: int, records: str, kind: str = "driving") -> str:
    return f'<lane id="{lane_id}" type="{kind}" level="false">{records}</lane>'


def section(s: float, left: list[str], right: list[str]) -> str:
    out = f'<laneSection s="{s}">'
    if left:
        out += "<left>" + "".join(left) + "</left>"
    out += '<center><lane id="0" type="none" level="false"/></center>'
    if right:
        out += "<right>" + "".join(right) + "</right>"
    return out + "</laneSection>"


def geometry(s: float, x: float, y: float, hdg: float, length: float, kind: str) -> str:
    return f'<geometry s="{s}" x="{x}" y="{y}" hdg="{hdg}" length="{length}">{kind}</geometry>'


def poly(tag: str, s: float, a: float, b: float = 0.0, c: float = 0.0, d: float = 0.0) -> str:
    return f'<{tag} s="{s}" a="{a}" b="{b}" c="{c}" d="{d}"/>'


def road(
    road_id: str,
    length: float,
    geometries: str,
    sections: str,
    *,
    elevation: str = "",
    superelevation: str = "",
    lane_offset: str = "",
    junction: str = "-1",
) -> str:
    return (
        f'<road name="r{road_id}" length="{length}" id="{road_id}" junction="{junction}">'
        f"<planView>{geometries}</planView>"
        f"<elevationProfile>{elevation}</elevationProfile>"
        f"<lateralProfile>{superelevation}</lateralProfile>"
        f"<lanes>{lane_offset}{sections}</lanes></road>"
    )


def xodr(*roads: str, header: str = "", extra: str = "") -> str:
    return (
        '<?xml version="1.0" encoding="UTF-8"?>\n<OpenDRIVE>'
        f'<header revMajor="1" revMinor="6" name="t">{header}</header>'
        + "".join(roads)
        + extra
        + "</OpenDRIVE>"
    )


def write(tmp_path: Path, text: str, name: str = "t.xodr") -> Path:
    path = tmp_path / name
    path.write_text(text, encoding="utf-8")
    return path


def simple_lanes(left: float = 3.5, right: float = 3.0, kind: str = "driving") -> str:
    return section(0.0, [lane(1, width(left), kind)], [lane(-1, width(right), kind)])


def build(tmp_path: Path, text: str, **kwargs):  # type: ignore[no-untyped-def]
    return build_import(read_opendrive(write(tmp_path, text)), **kwargs)


def borders_at(network, s: np.ndarray) -> tuple[np.ndarray, dict[int, np.ndarray]]:  # type: ignore[no-untyped-def]
    """Plan points of the reference line and t of every border at s (one section)."""
    road = network.roads[0]
    x, y, h = ReferenceLine(road.geometries).evaluate(s)
    borders, _ = section_borders(road, road.sections[0], s)
    return np.column_stack([x, y, h]), borders


def mesh_xy(result) -> np.ndarray:  # type: ignore[no-untyped-def]
    return np.concatenate([s.vertices[:, :2] for s in result.surfaces])


LANES_3 = section(
    0.0,
    [lane(1, width(3.5))],
    [lane(-1, width(3.0)), lane(-2, width(1.5), "shoulder")],
)
T_BORDERS = (3.5, 0.0, -3.0, -4.5)


# --- reference lines and lane borders at closed-form positions --------------------


def test_straight_road_borders_and_mesh(tmp_path):
    x0, y0, h0, length = 10.0, 5.0, 0.3, 80.0
    text = xodr(road("1", length, geometry(0, x0, y0, h0, length, "<line/>"), LANES_3))
    net = read_opendrive(write(tmp_path, text))
    s = np.linspace(0, length, 9)
    ref, borders = borders_at(net, s)
    d, n = np.array([math.cos(h0), math.sin(h0)]), np.array([-math.sin(h0), math.cos(h0)])
    assert np.allclose(ref[:, :2], [x0, y0] + s[:, None] * d, atol=1e-9)
    assert sorted(float(b[0]) for b in borders.values()) == sorted(T_BORDERS)
    # Every mesh vertex on one of the borders (signed distance from the line).
    result = build_import(net, ("driving", "shoulder"))
    rel = mesh_xy(result) - [x0, y0]
    t = rel @ n
    assert np.abs(t[:, None] - np.array(T_BORDERS)[None, :]).min(axis=1).max() < 0.01
    along = rel @ d
    assert along.min() > -1e-6 and along.max() < length + 1e-6
    # Rings are snapped to the float32-exact grid: each vertex moves at most half a
    # cell diagonal, so the area by at most the perimeter (2 L + 2 x 8 m) x that.
    snap = (2 * length + 16.0) * FLOAT32_GRID_M / math.sqrt(2)
    assert sum(a.area_m2 for a in result.targets) == pytest.approx(8.0 * length, abs=snap)


@pytest.mark.parametrize("k", [1 / 50, -1 / 35])
def test_arc_borders_and_mesh(tmp_path, k):
    length = 100.0
    text = xodr(road("1", length, geometry(0, 0, 0, 0, length, f'<arc curvature="{k}"/>'), LANES_3))
    net = read_opendrive(write(tmp_path, text))
    s = np.linspace(0, length, 11)
    ref, borders = borders_at(net, s)
    r = 1 / k
    centre = np.array([0.0, r])
    # Closed form: a point at lateral t lies at radius (R - t) from the centre.
    for tb in T_BORDERS:
        b = next(v for v in borders.values() if abs(v[0] - tb) < 1e-9)
        pts = ref[:, :2] + b[:, None] * np.column_stack([-np.sin(ref[:, 2]), np.cos(ref[:, 2])])
        expect = centre + (r - tb) * np.column_stack([np.sin(k * s), -np.cos(k * s)])
        assert np.abs(pts - expect).max() < 0.01
    result = build_import(net)
    radii = np.hypot(*(mesh_xy(result) - centre).T)
    expected_radii = np.abs(r - np.array(T_BORDERS))
    assert np.abs(radii[:, None] - expected_radii[None, :]).min(axis=1).max() < 0.01


def _spiral_by_quad(x0, y0, h0, k0, k1, length, s):  # type: ignore[no-untyped-def]
    dk = (k1 - k0) / length

    def head(u: float) -> float:
        return h0 + k0 * u + 0.5 * dk * u * u

    xs = [x0 + quad(lambda u: math.cos(head(u)), 0, v, limit=200, epsabs=1e-11)[0] for v in s]
    ys = [y0 + quad(lambda u: math.sin(head(u)), 0, v, limit=200, epsabs=1e-11)[0] for v in s]
    return np.array(xs), np.array(ys), np.array([head(v) for v in s])


@pytest.mark.parametrize(
    "k0, k1",
    [
        (0.0, 0.04),  # from straight into a curve
        (0.01, -0.02),  # curvature changes sign
        (-0.05, -0.01),  # curvStart != 0
        (0.03, 0.03 + 1e-7),  # a nearly constant curvature: Fresnel arguments huge
        (0.02, 0.02),  # no change at all: an arc
    ],
)
def test_clothoid_borders_against_quadrature(tmp_path, k0, k1):
    x0, y0, h0, length = 5.0, -3.0, 1.0, 120.0
    spiral = f'<spiral curvStart="{k0}" curvEnd="{k1}"/>'
    text = xodr(road("1", length, geometry(0, x0, y0, h0, length, spiral), LANES_3))
    net = read_opendrive(write(tmp_path, text))
    s = np.linspace(0, length, 13)
    ref, borders = borders_at(net, s)
    qx, qy, qh = _spiral_by_quad(x0, y0, h0, k0, k1, length, s)
    assert np.abs(ref[:, 2] - qh).max() < 1e-9
    qn = np.column_stack([-np.sin(qh), np.cos(qh)])
    for tb in T_BORDERS:
        b = next(v for v in borders.values() if abs(v[0] - tb) < 1e-9)
        pts = ref[:, :2] + b[:, None] * np.column_stack([-np.sin(ref[:, 2]), np.cos(ref[:, 2])])
        expect = np.column_stack([qx, qy]) + tb * qn
        assert np.abs(pts - expect).max() < 0.01
    # The mesh of the built road has its outer border on the same curve.
    result = build_import(net, ("driving", "shoulder"))
    dense = np.linspace(0, length, 1201)
    dx, dy, dh = _spiral_by_quad(x0, y0, h0, k0, k1, length, dense[::20])
    assert np.allclose(
        ReferenceLine(net.roads[0].geometries).evaluate(dense[::20])[0], dx, atol=0.01
    )
    assert len(result.surfaces[0].faces) > 0


def test_poly3_follows_its_polynomial(tmp_path):
    a, b, c, d = 0.5, 0.1, 0.002, -1e-5
    u_end = 80.0
    x0, y0, h0 = 3.0, 4.0, -0.7

    def dv(u: float) -> float:
        return b + 2 * c * u + 3 * d * u * u

    def arc(u: float) -> float:
        return quad(lambda w: math.sqrt(1 + dv(w) ** 2), 0, u, epsabs=1e-12)[0]

    length = arc(u_end)
    geo = geometry(0, x0, y0, h0, length, f'<poly3 a="{a}" b="{b}" c="{c}" d="{d}"/>')
    net = read_opendrive(write(tmp_path, xodr(road("1", length, geo, LANES_3))))
    us = np.linspace(0, u_end, 9)
    s = np.array([arc(u) for u in us])
    ref, _ = borders_at(net, s)
    v = a + b * us + c * us**2 + d * us**3
    ch, sh = math.cos(h0), math.sin(h0)
    expect = np.column_stack([x0 + ch * us - sh * v, y0 + sh * us + ch * v])
    assert np.abs(ref[:, :2] - expect).max() < 0.01
    assert np.allclose(ref[:, 2], h0 + np.arctan([dv(u) for u in us]), atol=1e-4)


@pytest.mark.parametrize("prange", ["arcLength", "normalized"])
def test_param_poly3_follows_its_polynomials(tmp_path, prange):
    length = 60.0
    cu = (0.0, 1.0, 0.004, -2e-5)
    cv = (0.0, 0.05, 0.003, -1e-5)
    if prange == "normalized":  # the same curve with p = ds / length
        cu = tuple(k * length**e for e, k in enumerate(cu))
        cv = tuple(k * length**e for e, k in enumerate(cv))
    attrs = " ".join(f'{n}U="{u}" {n}V="{v}"' for n, u, v in zip("abcd", cu, cv, strict=True))
    geo = geometry(0, 1.0, 2.0, 0.4, length, f'<paramPoly3 {attrs} pRange="{prange}"/>')
    net = read_opendrive(write(tmp_path, xodr(road("1", length, geo, LANES_3))))
    s = np.linspace(0, length, 7)
    ref, _ = borders_at(net, s)
    p = s if prange == "arcLength" else s / length
    u = sum(k * p**e for e, k in enumerate(cu))
    v = sum(k * p**e for e, k in enumerate(cv))
    du = sum(e * k * p ** (e - 1) for e, k in enumerate(cu) if e)
    dv = sum(e * k * p ** (e - 1) for e, k in enumerate(cv) if e)
    c, sn = math.cos(0.4), math.sin(0.4)
    assert (
        np.abs(ref[:, :2] - np.column_stack([1 + c * u - sn * v, 2 + sn * u + c * v])).max() < 1e-9
    )
    assert np.allclose(ref[:, 2], 0.4 + np.arctan2(dv, du), atol=1e-12)


# --- area against an independent quadrature --------------------------------------


def test_target_area_matches_quadrature(tmp_path):
    """Line, arc, spiral; cubic widths over two records and two lane sections; a cubic
    laneOffset and a constant superelevation (plan widths shrink by cos(phi))."""
    k_arc = 1 / 40
    pieces = [("line", 30.0, 0.0, 0.0), ("arc", 50.0, k_arc, k_arc), ("spiral", 40.0, k_arc, -0.01)]
    geos, s0, x, y, h = "", 0.0, 0.0, 0.0, 0.0
    for kind, length, k0, k1 in pieces:
        tag = {"line": "<line/>", "arc": f'<arc curvature="{k0}"/>'}.get(
            kind, f'<spiral curvStart="{k0}" curvEnd="{k1}"/>'
        )
        geos += geometry(s0, x, y, h, length, tag)
        qx, qy, qh = _spiral_by_quad(x, y, h, k0, k1, length, [length])
        x, y, h, s0 = float(qx[0]), float(qy[0]), float(qh[0]), s0 + length
    total = s0
    # Section 1 (s 0..70): lane 1 widens, lane -1 has two width records; section 2.
    w1 = (3.0, 0.02, 0.0, -2e-6)
    wm1a, wm1b = (3.5, 0.0, 0.0, 0.0), (3.5, 0.0, 4e-4, -5e-6)
    w2 = (3.2, -0.01, 1e-4, 0.0)
    off = (0.2, 0.01, -1e-4, 1e-7)
    phi = 0.05
    sec1 = section(
        0.0,
        [lane(1, width(*w1))],
        [lane(-1, width(*wm1a) + width(*wm1b, s=25.0)), lane(-2, width(2.0), "shoulder")],
    )
    sec2 = section(70.0, [lane(1, width(*w2))], [lane(-1, width(*w2))])
    text = xodr(
        road(
            "7",
            total,
            geos,
            sec1 + sec2,
            lane_offset=poly("laneOffset", 0, *off),
            superelevation=poly("superelevation", 0, phi),
        )
    )
    result = build(tmp_path, text)

    def cubic(c, u):  # type: ignore[no-untyped-def]
        return c[0] + c[1] * u + c[2] * u * u + c[3] * u**3

    def kappa(s: float) -> float:
        if s < 30:
            return 0.0
        if s < 80:
            return k_arc
        return k_arc + (-0.01 - k_arc) * (s - 80) / 40

    def strip(s: float, t_in: float, t_out: float) -> float:
        """d(area)/ds of a strip between lateral t_in and t_out (plan metres)."""
        a, b = sorted((t_in * math.cos(phi), t_out * math.cos(phi)))
        return (b - a) - kappa(s) * (b * b - a * a) / 2

    def lanes_at(s: float) -> float:
        o = cubic(off, s)
        if s < 70:
            wm1 = cubic(wm1a, s) if s < 25 else cubic(wm1b, s - 25)
            return strip(s, o, o + cubic(w1, s)) + strip(s, o, o - wm1)
        w = cubic(w2, s - 70)
        return strip(s, o, o + w) + strip(s, o, o - w)

    expect = sum(
        quad(lanes_at, a, b, epsabs=1e-9, limit=200)[0]
        for a, b in [(0, 25), (25, 30), (30, 70), (70, 80), (80, total)]
    )
    got = sum(t.area_m2 for t in result.targets)
    assert got == pytest.approx(expect, rel=0.005)
    assert result.lane_area_m2["driving"] == pytest.approx(expect, rel=0.005)
    # The rings say the same area (exterior minus holes, even-odd).
    rings = result.targets[0].rings
    even_odd = Polygon()
    for r in rings:
        even_odd = even_odd.symmetric_difference(Polygon(r[:, :2]))
    assert even_odd.area == pytest.approx(got, rel=1e-9)


# --- elevation, superelevation, rings on the surface ------------------------------


def test_superelevated_slope_surface_and_target_heights(tmp_path):
    length, a, b, phi = 60.0, 2.0, 0.03, 0.06
    text = xodr(
        road(
            "3",
            length,
            geometry(0, 0, 0, 0, length, "<line/>"),
            simple_lanes(3.5, 3.0),
            elevation=poly("elevation", 0, a, b, 1e-4, -1e-6),
            superelevation=poly("superelevation", 0, phi),
        )
    )
    result = build(tmp_path, text, terrain="none")

    def z_at(x: np.ndarray, y: np.ndarray) -> np.ndarray:
        # plan y = t cos(phi); height = elev(s) + t sin(phi)
        return a + b * x + 1e-4 * x**2 - 1e-6 * x**3 + y * math.tan(phi)

    v = result.surfaces[0].vertices
    assert np.abs(v[:, 2] - z_at(v[:, 0], v[:, 1])).max() < 1e-6
    assert v[:, 1].max() == pytest.approx(3.5 * math.cos(phi), abs=1e-9)
    for ring in result.targets[0].rings:
        assert np.abs(ring[:, 2] - z_at(ring[:, 0], ring[:, 1])).max() < 0.005
    # Sensor areas without terrain: flat at the mean height of the outer borders.
    band = result.sensor_areas[0]
    zs = np.concatenate([r[:, 2] for r in band.rings])
    assert np.ptp(zs) == 0.0 and abs(zs[0] - (a + b * 30)) < 1.0
    assert result.ground is None


TOWN04 = Path(__file__).resolve().parents[1] / "data" / "xodr" / "Town04.xodr"


def test_town04_height_matches_its_elevation_polynomial():
    import xml.etree.ElementTree as ET

    root = ET.parse(TOWN04).getroot()

    def pick() -> tuple[str, float, float, float]:
        """A road, and the middle of one of its straight geometries where the road is
        above 3 m and sloping: (road id, plan x, plan y, height by the polynomial)."""
        for el in root.findall("road"):
            recs = sorted(el.findall("elevationProfile/elevation"), key=lambda e: float(e.get("s")))
            for g in el.findall("planView/geometry"):
                if g.find("line") is None:
                    continue
                s = float(g.get("s")) + 0.5 * float(g.get("length"))
                rec = [e for e in recs if float(e.get("s")) <= s][-1]
                c = [float(rec.get(k)) for k in "abcd"]
                ds = s - float(rec.get("s"))
                z = c[0] + c[1] * ds + c[2] * ds**2 + c[3] * ds**3
                slope = c[1] + 2 * c[2] * ds + 3 * c[3] * ds**2
                if z > 3.0 and abs(slope) > 0.005:
                    hdg, u = float(g.get("hdg")), s - float(g.get("s"))
                    px = float(g.get("x")) + u * math.cos(hdg)
                    py = float(g.get("y")) + u * math.sin(hdg)
                    return el.get("id"), px, py, z
        raise AssertionError("Town04 has no straight sloping road above 3 m")

    road_id, px, py, z = pick()
    result = build_import(read_opendrive(TOWN04), ("driving",))
    mesh = next(m for m in result.surfaces if m.road_id == road_id)
    tri = mesh.vertices[mesh.faces]
    p = np.array([px, py]) - result.shift[:2]
    a, b, c = tri[:, 0, :2], tri[:, 1, :2], tri[:, 2, :2]

    def cross(u: np.ndarray, v: np.ndarray) -> np.ndarray:
        return u[:, 0] * v[:, 1] - u[:, 1] * v[:, 0]

    den = cross(b - a, c - a)
    l1, l2 = cross(p - a, c - a) / den, cross(b - a, p - a) / den
    inside = (l1 >= -1e-9) & (l2 >= -1e-9) & (l1 + l2 <= 1 + 1e-9)
    assert inside.any()
    k = int(np.flatnonzero(inside)[0])
    height = (1 - l1[k] - l2[k]) * tri[k, 0, 2] + l1[k] * tri[k, 1, 2] + l2[k] * tri[k, 2, 2]
    assert z > 3.0
    assert height == pytest.approx(z, abs=0.01)


# --- sensor areas, ground, georeference -------------------------------------------


def test_sensor_bands_minus_every_road_and_ground(tmp_path):
    a = road("A", 200.0, geometry(0, 0, 0, 0, 200.0, "<line/>"), simple_lanes(3.5, 3.5))
    b = road("B", 200.0, geometry(0, 100, -100, math.pi / 2, 200.0, "<line/>"), simple_lanes(3, 3))
    result = build(tmp_path, xodr(a, b), band=(1.0, 6.0))
    areas = {s.name: s for s in result.sensor_areas}
    assert set(areas) == {"SensorArea_roadA", "SensorArea_roadB"}
    # A: two 5 m strips, 200 m long, less B's 6 m wide surface crossing each.
    assert areas["SensorArea_roadA"].area_m2 == pytest.approx(2 * 5 * 200 - 2 * 5 * 6, rel=1e-6)
    assert areas["SensorArea_roadB"].area_m2 == pytest.approx(2 * 5 * 200 - 2 * 5 * 7, rel=1e-6)
    for area in result.sensor_areas:
        for ring in area.rings:
            assert len(ring) >= 3 and np.all(ring[:, 2] == result.ground.vertices[0, 2])
    g = result.ground
    assert g is not None and g.vertices[0, 2] == pytest.approx(-0.05)
    lo, hi = g.vertices[:, :2].min(axis=0), g.vertices[:, :2].max(axis=0)
    assert np.allclose(lo, [-20, -120]) and np.allclose(hi, [220, 120])
    assert {t.name for t in result.targets} == {"Target_driving_roadA", "Target_driving_roadB"}
    assert result.targets[0].lane_types == ("driving",)
    # Surfaces: counter-clockwise triangles seen from above.
    for m in [*result.surfaces, g]:
        p = m.vertices[m.faces][:, :, :2]
        u, v = p[:, 1] - p[:, 0], p[:, 2] - p[:, 0]
        cross = u[:, 0] * v[:, 1] - u[:, 1] * v[:, 0]  # numpy 2 has no 2-D np.cross
        assert m.faces.dtype == np.int32 and np.all(cross > 0)


def test_band_on_a_road_end_to_end_with_another_has_no_overlap(tmp_path):
    a = road("1", 50.0, geometry(0, 0, 0, 0, 50.0, "<line/>"), simple_lanes(3.5, 3.5))
    # A band narrower than 1 m^2 after subtraction is dropped entirely.
    tiny = build(tmp_path, xodr(a), band=(0.0, 0.001))
    assert tiny.sensor_areas == []
    full = build(tmp_path, xodr(a), band=(0.0, 2.0))
    assert full.sensor_areas[0].area_m2 == pytest.approx(200.0, rel=1e-6)


def test_georeference_offset_and_shift(tmp_path):
    header = (
        "<geoReference><![CDATA[ +proj=utm +zone=33 +datum=WGS84 ]]></geoReference>"
        '<offset x="1000.5" y="-20" z="3" hdg="0.25"/>'
    )
    x0, y0 = 431_234.0, 6_402_777.0
    text = xodr(
        road("9", 40.0, geometry(0, x0, y0, 0.0, 40.0, "<line/>"), simple_lanes()),
        header=header,
    )
    net = read_opendrive(write(tmp_path, text))
    assert net.geo_reference == "+proj=utm +zone=33 +datum=WGS84"
    assert net.offset == (1000.5, -20.0, 3.0, 0.25)
    result = build_import(net)
    assert np.allclose(result.shift, [431_000.0, 6_403_000.0, 0.0])
    assert result.crs == net.geo_reference
    v = result.surfaces[0].vertices
    assert np.abs(v).max() < 1000.0
    # The vertex at the road start on the reference line, taken to the CRS.
    k = int(np.argmin(np.hypot(v[:, 0] - (x0 - 431_000.0), v[:, 1] - (y0 - 6_403_000.0))))
    x, y, z, h = result.crs_offset
    px, py = v[k, 0], v[k, 1]
    crs = (math.cos(h) * px - math.sin(h) * py + x, math.sin(h) * px + math.cos(h) * py + y)
    expect = (
        math.cos(0.25) * x0 - math.sin(0.25) * y0 + 1000.5,
        math.sin(0.25) * x0 + math.cos(0.25) * y0 - 20.0,
    )
    assert np.allclose(crs, expect, atol=1e-6)
    assert z == 3.0


def test_no_georeference_gives_none_and_zero_offset(tmp_path):
    text = xodr(
        road("1", 10.0, geometry(0, 0, 0, 0, 10.0, "<line/>"), simple_lanes()),
        header="<geoReference>  </geoReference>",
    )
    result = build(tmp_path, text)
    assert result.crs is None and result.crs_offset == (0.0, 0.0, 0.0, 0.0)
    assert np.all(result.shift == 0)


# --- defects: a warning naming the road, the road or lane skipped ------------------


def _good(road_id: str = "1", y: float = 0.0) -> str:
    return road(road_id, 30.0, geometry(0, 0, y, 0, 30.0, "<line/>"), simple_lanes())


def test_negative_width_lane_is_skipped_with_a_warning(tmp_path):
    lanes = section(0.0, [lane(1, width(3.5))], [lane(-1, width(3.0, -0.2))])
    bad = road("5", 30.0, geometry(0, 0, 0, 0, 30.0, "<line/>"), lanes)
    result = build(tmp_path, xodr(bad))
    assert len(result.warnings) == 1
    assert (
        result.warnings[0].startswith("road 5: lane -1") and "negative width" in result.warnings[0]
    )
    assert result.lane_area_m2["driving"] == pytest.approx(3.5 * 30, rel=1e-6)


def test_zero_width_and_none_lanes_and_missing_lane_offset_are_silent(tmp_path):
    lanes = section(
        0.0,
        [lane(1, width(3.5)), lane(2, width(0.0)), lane(3, width(2.0), "none")],
        [lane(-1, width(3.0))],
    )
    result = build(tmp_path, xodr(road("2", 30.0, geometry(0, 0, 0, 0, 30.0, "<line/>"), lanes)))
    assert result.warnings == []
    assert result.lane_area_m2["driving"] == pytest.approx(6.5 * 30, rel=1e-6)
    # The none lane is no surface: the mesh spans 3.5 m left, 3 m right.
    v = result.surfaces[0].vertices
    assert v[:, 1].max() == pytest.approx(3.5) and v[:, 1].min() == pytest.approx(-3.0)


@pytest.mark.parametrize(
    "kind, words",
    [
        ('<spiral curvStart="0.0" curvEnd="5.0"/>', "radius under 0.5 m"),
        ('<spiral curvStart="nan" curvEnd="0.1"/>', "not finite"),
        ('<arc curvature="-3"/>', "radius under 0.5 m"),
        ('<clothoid a="1"/>', "not a known geometry"),
        ('<arc curvature="abc"/>', "not a number"),
    ],
)
def test_bad_geometry_skips_the_road(tmp_path, kind, words):
    bad = road("13", 30.0, geometry(0, 0, 50, 0, 30.0, kind), simple_lanes())
    result = build(tmp_path, xodr(_good(), bad))
    assert [s.road_id for s in result.surfaces] == ["1"]
    assert len(result.warnings) == 1
    w = result.warnings[0]
    assert w.startswith("road 13: ") and words in w and w.endswith("road skipped") and "\n" not in w


def test_a_spiral_starting_at_minus_1e308_is_asked_for_without_overflow(tmp_path):
    # Found by the fuzzer: the planView's jump check evaluates the spiral at its own
    # start, 1e308 m before the line's, and squaring that span overflowed a Python
    # float. The station is outside the road's lanes, so the road imports unwarned.
    plan = geometry(0.0, 0, 0, 0, 0.5, '<arc curvature="0.0"/>') + geometry(
        -1e308, 0, 0, 0, 0.5, '<spiral curvStart="0.0" curvEnd="0.25"/>'
    )
    result = build(tmp_path, xodr(road("1", 1.0, plan, simple_lanes())))
    assert result.warnings == []
    assert [s.road_id for s in result.surfaces] == ["1"]


def test_broken_junction_link_is_named(tmp_path):
    junction = (
        '<junction id="40" name="j"><connection id="0" incomingRoad="1" '
        'connectingRoad="99" contactPoint="start"/></junction>'
    )
    result = build(tmp_path, xodr(_good(), extra=junction))
    assert len(result.warnings) == 1
    assert result.warnings[0].startswith("junction 40: ") and "road 99" in result.warnings[0]
    assert len(result.surfaces) == 1


def test_junction_connecting_roads_are_built(tmp_path):
    conn = road(
        "7",
        20.0,
        geometry(0, 30, 0, 0, 20.0, '<arc curvature="0.05"/>'),
        simple_lanes(),
        junction="40",
    )
    junction = (
        '<junction id="40"><connection id="0" incomingRoad="1" connectingRoad="7"/></junction>'
    )
    result = build(tmp_path, xodr(_good(), conn, extra=junction))
    assert result.warnings == []
    assert {t.name for t in result.targets} == {"Target_driving_road1", "Target_driving_road7"}


def test_border_records_match_the_same_widths(tmp_path):
    def with_records(left: str, right: str) -> str:
        lanes = section(0.0, [lane(1, left)], [lane(-1, right)])
        return xodr(road("4", 30.0, geometry(0, 0, 0, 0, 30.0, "<line/>"), lanes))

    border = '<border sOffset="0" a="{}" b="{}" c="0" d="0"/>'
    by_width = build(tmp_path, with_records(width(3.0, 0.02), width(2.5)))
    by_border = build(tmp_path, with_records(border.format(3.0, 0.02), border.format(-2.5, 0)))
    assert by_border.warnings == []
    assert np.allclose(by_border.surfaces[0].vertices, by_width.surfaces[0].vertices)
    mixed = build(
        tmp_path,
        xodr(_good("1", 40.0)).replace("</OpenDRIVE>", "")
        + road(
            "4",
            30.0,
            geometry(0, 0, 0, 0, 30.0, "<line/>"),
            section(0.0, [lane(1, width(3.0) + border.format(3.0, 0))], []),
        )
        + "</OpenDRIVE>",
    )
    assert len(mixed.warnings) == 1 and mixed.warnings[0].startswith("road 4: lane 1")
    assert [s.road_id for s in mixed.surfaces] == ["1"]


# --- files that are not OpenDRIVE, arguments that make no sense -------------------


@pytest.mark.parametrize(
    "name, content, words",
    [
        ("a.svg", '<svg xmlns="http://www.w3.org/2000/svg"><rect/></svg>', "(root element <svg>)"),
        ("a.txt", "just some text\nover two lines", "not XML"),
        ("a.xodr", "<OpenDRIVE><header/><road id='1'>", "not XML"),
        ("b.xodr", "<OpenDRIVE><header/></OpenDRIVE>", "has no <road>"),
    ],
)
def test_not_opendrive_is_a_one_line_error(tmp_path, name, content, words):
    path = write(tmp_path, content, name)
    with pytest.raises(InputError) as err:
        read_opendrive(path)
    msg = str(err.value)
    assert msg.startswith(f"{path}: ") and words in msg and "\n" not in msg


def test_missing_file_and_directory(tmp_path):
    with pytest.raises(InputError, match="no such file"):
        read_opendrive(tmp_path / "nope.xodr")
    with pytest.raises(InputError, match="is a directory"):
        read_opendrive(tmp_path)


@pytest.mark.parametrize(
    "kwargs, words",
    [
        ({"band": (-1.0, 5.0)}, "0 <= inner < outer"),
        ({"band": (3.0, 3.0)}, "0 <= inner < outer"),
        ({"terrain": "hills"}, "'flat' or 'none'"),
        ({"lane_types": ("driving", "motorway")}, "'motorway' is not an OpenDRIVE lane type"),
        ({"lane_types": ("biking",)}, "no lane of type biking"),
    ],
)
def test_bad_arguments(tmp_path, kwargs, words):
    net = read_opendrive(write(tmp_path, xodr(_good())))
    with pytest.raises(InputError) as err:
        build_import(net, **kwargs)
    assert words in str(err.value) and "\n" not in str(err.value)


def test_lane_types_match_case_insensitively(tmp_path):
    lanes = section(0.0, [lane(1, width(3.5), "Driving")], [lane(-1, width(2.0), "SHOULDER")])
    result = build(
        tmp_path,
        xodr(road("1", 30.0, geometry(0, 0, 0, 0, 30.0, "<line/>"), lanes)),
        lane_types=("DRIVING", "shoulder"),
    )
    assert sorted(t.name for t in result.targets) == [
        "Target_driving_road1",
        "Target_shoulder_road1",
    ]
    assert result.lane_area_m2 == pytest.approx({"driving": 105.0, "shoulder": 60.0})


def test_tight_constant_arc_area_is_sampled_finely(tmp_path):
    """No profile varies here, so only the turn rule keeps chords close to the arc:
    the annulus sectors' closed-form area within 0.5 %."""
    r, theta = 30.0, 1.8 * math.pi
    geo = geometry(0, 0, 0, 0, r * theta, f'<arc curvature="{1 / r}"/>')
    result = build(tmp_path, xodr(road("1", r * theta, geo, simple_lanes(3.5, 4.0))))
    # Left lane: radii r - 3.5 .. r; right lane: r .. r + 4.
    expect = theta / 2 * ((r * r - (r - 3.5) ** 2) + ((r + 4.0) ** 2 - r * r))
    assert result.targets[0].area_m2 == pytest.approx(expect, rel=0.005)
    assert result.lane_area_m2["driving"] == pytest.approx(expect, rel=0.005)
