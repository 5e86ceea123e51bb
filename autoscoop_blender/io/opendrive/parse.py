"""Reading a .xodr file into plain records (no geometry is evaluated here).

Every fault of the file itself (not XML, not OpenDRIVE, no road, too big to import,
no road that can be used) is a one-line ``InputError``; a fault of one road (a record
that does not parse or is not finite, an unknown geometry, an extreme spiral) is a
one-line warning naming the road, and the road is left out. When every road is left
out, the error names them and why. Junction connections that name a road the file
does not have are warned about and otherwise ignored (connecting roads are built like
every other road).
"""

from __future__ import annotations

import math
import os
import xml.etree.ElementTree as ET
from collections.abc import Sequence
from dataclasses import dataclass, field

from ...core.errors import InputError
from .progress import Progress, Ticker

# A curvature beyond this (a radius under 0.5 m) is no road: the road is skipped.
MAX_CURVATURE = 2.0
# The largest file read: xml.etree holds about 15 bytes per byte of file (830 MB peak
# for a 54 MB file of 90,000 roads, measured), so 256 MiB is some 4 GB in memory. The
# real files of tests/data/xodr are at most 2 MB.
MAX_FILE_BYTES = 256 << 20
# The most roads an import takes. Each road becomes three Blender objects (a mesh and
# two curves), and Blender makes each new object slower once a file holds some ten
# thousand (measured: 10,000 roads' 30,000 objects in 10 s, 20,000 roads' in 90 s);
# with reading and geometry, 10,000 small roads import in about 40 s. A file with
# more is refused as soon as its XML is read, before any road is looked at.
MAX_ROADS = 10_000
# Reasons shown when every road was skipped; the rest are counted.
SHOWN_REASONS = 3

GEOMETRY_KINDS = ("line", "arc", "spiral", "poly3", "paramPoly3")


@dataclass(frozen=True)
class Poly:
    """A cubic record: value = a + b*ds + c*ds^2 + d*ds^3 with ds = s - ``s``.

    ``s`` is the record's start: absolute for road-level records (elevation,
    superelevation, laneOffset), the ``sOffset`` within its lane section for lane
    width and border records.
    """

    s: float
    a: float
    b: float
    c: float
    d: float


@dataclass(frozen=True)
class Geometry:
    """One planView record: start (s, x, y, hdg), length and its kind's parameters.

    params: line (); arc (curvature,); spiral (curvStart, curvEnd); poly3 (a, b, c, d);
    paramPoly3 (aU, bU, cU, dU, aV, bV, cV, dV, normalized) with normalized 1.0 for
    ``pRange="normalized"`` and 0.0 for ``arcLength``.
    """

    s: float
    x: float
    y: float
    hdg: float
    length: float
    kind: str
    params: tuple[float, ...] = ()


@dataclass(frozen=True)
class Lane:
    """A lane of one lane section: id (positive left, negative right), type, and its
    width records or, instead, its border records (both keyed by sOffset)."""

    id: int
    type: str
    widths: tuple[Poly, ...] = ()
    borders: tuple[Poly, ...] = ()


@dataclass(frozen=True)
class LaneSection:
    """Lanes from ``s`` to the next section: left ordered 1, 2, ...; right -1, -2, ..."""

    s: float
    left: tuple[Lane, ...]
    right: tuple[Lane, ...]


@dataclass(frozen=True)
class Road:
    id: str
    name: str
    length: float
    junction: str
    geometries: tuple[Geometry, ...]
    elevation: tuple[Poly, ...] = ()
    superelevation: tuple[Poly, ...] = ()
    lane_offsets: tuple[Poly, ...] = ()
    sections: tuple[LaneSection, ...] = ()


@dataclass
class OpenDriveNetwork:
    """The roads of a file that parsed, with the header's georeference."""

    path: str
    roads: list[Road]
    geo_reference: str | None = None
    offset: tuple[float, float, float, float] | None = None
    warnings: list[str] = field(default_factory=list)
    junction_roads: dict[str, list[str]] = field(default_factory=dict)


class _RoadFault(Exception):
    """A record of one road that cannot be used: the road is skipped."""


# Longest text of the file quoted in a message (a value, an id, a type): a message
# stays one short line whatever the file holds.
SHOWN_CHARS = 40


def shown(text: str) -> str:
    """``text`` as a message quotes it: control characters escaped (no line break
    gets into a one-line message), at most ``SHOWN_CHARS`` characters."""
    out = "".join(c if c.isprintable() else repr(c)[1:-1] for c in text)
    return out if len(out) <= SHOWN_CHARS else out[: SHOWN_CHARS - 3] + "..."


def _num(el: ET.Element, name: str, default: float | None = None) -> float:
    raw = el.get(name)
    if raw is None:
        if default is None:
            raise _RoadFault(f"<{el.tag}> has no '{name}'")
        return default
    try:
        value = float(raw)
    except ValueError:
        raise _RoadFault(f"<{el.tag}> {name}='{shown(raw)}' is not a number") from None
    if not math.isfinite(value):
        raise _RoadFault(f"<{el.tag}> {name}='{shown(raw)}' is not finite")
    return value


def _poly(el: ET.Element, s_name: str) -> Poly:
    return Poly(
        _num(el, s_name, 0.0),
        _num(el, "a", 0.0),
        _num(el, "b", 0.0),
        _num(el, "c", 0.0),
        _num(el, "d", 0.0),
    )


def _polys(parent: ET.Element | None, tag: str, s_name: str = "s") -> tuple[Poly, ...]:
    if parent is None:
        return ()
    recs = [_poly(e, s_name) for e in parent.findall(tag)]
    return tuple(sorted(recs, key=lambda p: p.s))


def _geometry(el: ET.Element) -> Geometry:
    s, x, y = _num(el, "s"), _num(el, "x"), _num(el, "y")
    hdg, length = _num(el, "hdg"), _num(el, "length")
    if length < 0:
        raise _RoadFault(f"geometry at s={s:g} has negative length {length:g}")
    kinds = [c for c in el if c.tag in GEOMETRY_KINDS]
    if not kinds:
        tags = [f"<{shown(str(c.tag))}>" for c in el[:3]]
        found = ", ".join(tags + (["..."] if len(el) > 3 else [])) or "nothing"
        raise _RoadFault(f"geometry at s={s:g} holds {found}, not a known geometry")
    kind = kinds[0]
    params: tuple[float, ...] = ()
    if kind.tag == "arc":
        params = (_num(kind, "curvature"),)
        if abs(params[0]) > MAX_CURVATURE:
            raise _RoadFault(
                f"arc at s={s:g} has curvature {params[0]:g} 1/m (radius under "
                f"{1 / MAX_CURVATURE:g} m)"
            )
    elif kind.tag == "spiral":
        params = (_num(kind, "curvStart"), _num(kind, "curvEnd"))
        if max(abs(params[0]), abs(params[1])) > MAX_CURVATURE:
            raise _RoadFault(
                f"spiral at s={s:g} has curvature {params[0]:g} to {params[1]:g} 1/m "
                f"(radius under {1 / MAX_CURVATURE:g} m)"
            )
    elif kind.tag == "poly3":
        params = tuple(_num(kind, k) for k in "abcd")
    elif kind.tag == "paramPoly3":
        coeffs = [_num(kind, f"{k}U") for k in "abcd"] + [_num(kind, f"{k}V") for k in "abcd"]
        prange = kind.get("pRange", "normalized")
        if prange not in ("arcLength", "normalized"):
            raise _RoadFault(f"paramPoly3 at s={s:g} has pRange '{shown(prange)}'")
        params = (*coeffs, 1.0 if prange == "normalized" else 0.0)
    return Geometry(s, x, y, hdg, length, kind.tag, params)


def _lanes(side: ET.Element | None, sign: int) -> tuple[Lane, ...]:
    if side is None:
        return ()
    lanes = []
    for el in side.findall("lane"):
        try:
            lane_id = int(el.get("id", ""))
        except ValueError:
            raise _RoadFault(f"lane id '{shown(el.get('id', ''))}' is not an integer") from None
        if lane_id * sign <= 0:
            raise _RoadFault(f"lane {lane_id} is on the wrong side of the centre lane")
        lanes.append(
            Lane(
                lane_id,
                shown(el.get("type", "none")),
                _polys(el, "width", "sOffset"),
                _polys(el, "border", "sOffset"),
            )
        )
    lanes.sort(key=lambda ln: abs(ln.id))
    ids = [abs(ln.id) for ln in lanes]
    if ids != list(range(1, len(lanes) + 1)):
        raise _RoadFault(f"lane ids {sorted(ln.id for ln in lanes)} are not consecutive")
    return tuple(lanes)


def _road(el: ET.Element, road_id: str) -> Road:
    length = _num(el, "length")
    if length < 0:
        raise _RoadFault(f"length {length:g} m is negative")
    plan = el.find("planView")
    geoms = [_geometry(g) for g in plan.findall("geometry")] if plan is not None else []
    if not geoms:
        raise _RoadFault("no planView geometry")
    geoms.sort(key=lambda g: g.s)
    lanes_el = el.find("lanes")
    sections = []
    if lanes_el is not None:
        for sec in lanes_el.findall("laneSection"):
            sections.append(
                LaneSection(
                    _num(sec, "s", 0.0),
                    _lanes(sec.find("left"), 1),
                    _lanes(sec.find("right"), -1),
                )
            )
    sections.sort(key=lambda sec: sec.s)
    lateral = el.find("lateralProfile")
    return Road(
        id=road_id,
        name=el.get("name", ""),
        length=length,
        junction=el.get("junction", "-1"),
        geometries=tuple(geoms),
        elevation=_polys(el.find("elevationProfile"), "elevation"),
        superelevation=_polys(lateral, "superelevation"),
        lane_offsets=_polys(lanes_el, "laneOffset"),
        sections=tuple(sections),
    )


def _header(root: ET.Element) -> tuple[str | None, tuple[float, float, float, float] | None]:
    header = root.find("header")
    if header is None:
        return None, None
    geo = header.find("geoReference")
    text = "".join(geo.itertext()).strip() if geo is not None else ""
    offset = None
    off = header.find("offset")
    if off is not None:
        try:
            offset = (
                _num(off, "x", 0.0),
                _num(off, "y", 0.0),
                _num(off, "z", 0.0),
                _num(off, "hdg", 0.0),
            )
        except _RoadFault as exc:
            raise InputError(f"header offset: {exc}") from None
    return text or None, offset


def skipped_reasons(warnings: Sequence[str]) -> str:
    """The first ``SHOWN_REASONS`` warnings about skipped roads, without their
    "; road skipped", joined by "; " (and how many more): for a one-line error."""
    skipped = [w for w in warnings if w.startswith("road ") and w.endswith("skipped")]
    reasons = [w.removesuffix("; road skipped").removesuffix("; skipped") for w in skipped]
    text = "; ".join(reasons[:SHOWN_REASONS])
    if len(reasons) > SHOWN_REASONS:
        text += f" (and {len(reasons) - SHOWN_REASONS:,} more)"
    return text


def _parse_xml(name: str, progress: Progress | None) -> ET.Element:
    """The root element; read in 1 MiB pieces so a big file reports progress."""
    try:
        size = os.path.getsize(name)
    except OSError as exc:
        raise InputError(f"{name}: cannot be read ({exc.strerror or exc})") from None
    if size > MAX_FILE_BYTES:
        raise InputError(
            f"{name}: {size / 2**20:,.0f} MiB is more than the {MAX_FILE_BYTES >> 20} MiB "
            "an import reads (its XML tree would take about 15 times that in memory)"
        )
    tick = Ticker(progress, "reading", size)
    parser = ET.XMLParser()
    done = 0
    try:
        with open(name, "rb") as fh:
            while chunk := fh.read(1 << 20):
                parser.feed(chunk)
                done += len(chunk)
                tick(done)
            root = parser.close()
        tick.done()
        return root
    except OSError as exc:
        raise InputError(f"{name}: cannot be read ({exc.strerror or exc})") from None
    except ET.ParseError as exc:
        raise InputError(f"{name}: not an OpenDRIVE file (not XML: {exc})") from None


def read_opendrive(
    path: str | os.PathLike[str], progress: Progress | None = None
) -> OpenDriveNetwork:
    """Parse an OpenDRIVE file. One-line ``InputError`` "<path>: <problem>" when the
    file cannot be used at all (also: beyond ``MAX_FILE_BYTES`` or ``MAX_ROADS``, or
    no road usable: then the error names the first roads and why); per-road faults
    become warnings and skip the road. ``progress(stage, done, total)`` is called
    while the file is read ("reading", bytes) and its roads parsed ("parsing", roads).
    """
    name = os.fspath(path)
    if not os.path.exists(name):
        raise InputError(f"{name}: no such file")
    if os.path.isdir(name):
        raise InputError(f"{name}: is a directory, not an OpenDRIVE file")
    root = _parse_xml(name, progress)
    tag = root.tag.rpartition("}")[2]
    if tag != "OpenDRIVE":
        raise InputError(f"{name}: not an OpenDRIVE file (root element <{tag}>)")
    road_els = root.findall("road")
    if not road_els:
        raise InputError(f"{name}: the OpenDRIVE file has no <road>")
    if len(road_els) > MAX_ROADS:
        raise InputError(
            f"{name}: {len(road_els):,} roads are more than the {MAX_ROADS:,} an import "
            "takes (each becomes a mesh and two curves in Blender, and more objects make "
            "each new one slower: 20,000 roads take minutes); split the file"
        )
    try:
        geo, offset = _header(root)
    except InputError as exc:
        raise InputError(f"{name}: {exc}") from None
    warnings: list[str] = []
    roads: list[Road] = []
    seen: set[str] = set()
    all_ids = {r.get("id", "") for r in road_els}
    tick = Ticker(progress, "parsing", len(road_els))
    for k, el in enumerate(road_els):
        # Ids name objects and fill messages: shown as a message would quote them.
        road_id = shown(el.get("id") or f"#{k}")
        if road_id in seen:
            warnings.append(f"road {road_id}: a second road with this id; skipped")
            continue
        seen.add(road_id)
        try:
            roads.append(_road(el, road_id))
        except _RoadFault as exc:
            warnings.append(f"road {road_id}: {exc}; road skipped")
        tick(k + 1)
    if not roads:
        raise InputError(f"{name}: no road could be used: {skipped_reasons(warnings)}")
    junction_roads: dict[str, list[str]] = {}
    for junc in root.findall("junction"):
        jid = shown(junc.get("id", "?"))
        members = junction_roads.setdefault(jid, [])
        for conn in junc.findall("connection"):
            for attr in ("incomingRoad", "connectingRoad"):
                rid = conn.get(attr)
                if rid is None:
                    continue
                if rid not in all_ids:
                    warnings.append(
                        f"junction {jid}: connection {shown(conn.get('id', '?'))} names road "
                        f"{shown(rid)} ({attr}), which the file does not have; link ignored"
                    )
                elif attr == "connectingRoad" and rid not in members:
                    members.append(rid)
    tick.done()
    return OpenDriveNetwork(name, roads, geo, offset, warnings, junction_roads)
