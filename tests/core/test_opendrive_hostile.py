"""Hostile OpenDRIVE files (issue 33, part 3): the import is bounded and true.

Each class of fault a tester found, with the figures worked out here by hand: a lane
wound 95 times round a tight arc (an annulus, fast), profiles that would ask for
millions of stations, a road of 1e9 m, numbers past what a scene may hold, a planView
that jumps 700 m, broken geometry of every kind. Refusals are one line naming the road
and the figure; nothing runs for minutes.
"""

from __future__ import annotations

import math
import resource
import time
from pathlib import Path

import numpy as np
import pytest
import shapely

from autoscoop_blender.core.errors import InputError
from autoscoop_blender.core.model.sensors import MAX_RANGE_M
from autoscoop_blender.io.opendrive import build as build_module
from autoscoop_blender.io.opendrive import build_import, read_opendrive
from autoscoop_blender.io.opendrive import parse as parse_module
from autoscoop_blender.io.opendrive.build import FLOAT32_GRID_M
from tests.core.test_opendrive import (
    build,
    geometry,
    lane,
    poly,
    road,
    section,
    simple_lanes,
    width,
    write,
    xodr,
)

DATA = Path(__file__).resolve().parents[1] / "data" / "xodr"


def refused(tmp_path: Path, text: str, **kwargs) -> str:  # type: ignore[no-untyped-def]
    """The one-line message of an import that must be refused, in under a second."""
    path = write(tmp_path, text)
    t0 = time.perf_counter()
    with pytest.raises(InputError) as err:
        build_import(read_opendrive(path), **kwargs)
    assert time.perf_counter() - t0 < 1.0
    message = str(err.value)
    assert message.startswith(f"{path}: ") and "\n" not in message
    return message


def line(length: float, x: float = 0.0, y: float = 0.0) -> str:
    return geometry(0, x, y, 0, length, "<line/>")


def union_area(result) -> float:  # type: ignore[no-untyped-def]
    """The targets' union, m^2: each target's rings even-odd (as a scene reads them)."""
    regions = []
    for t in result.targets:
        region = shapely.Polygon()
        for r in t.rings:
            region = region.symmetric_difference(shapely.Polygon(r[:, :2]))
        regions.append(region)
    return float(shapely.union_all(regions).area)


# --- a lane wound round a tight arc: bounded, and the ground it covers -------------


def test_an_arc_wound_95_times_is_fast_and_covers_an_annulus(tmp_path):
    """1 km at curvature 0.6 (radius R = 5/3 m) turns 600 rad: the lanes wind 95.5
    times round the centre. The left lane (0 to 3.5 m) passes the centre and folds:
    the ground it sweeps is the disk of radius max(R, 3.5 - R) = 11/6 m. The right
    lane (0 to -3 m) covers the annulus from R to R + 3 = 14/3 m, 19 pi m^2. Together:
    the disk of 14/3 m. The bands 1 to 6 m beyond: left from 4.5 to 9.5 m, past the
    centre, radii 17/6 to 47/6 m; right radii R + 4 to R + 9 = 32/3 m; less the road's
    disk: the annulus 14/3 to 32/3 m, 92 pi m^2. Chords of 0.05 rad lose
    1 - sin(0.05)/0.05 = 0.04 % of a circle's area: within 0.5 %."""
    text = xodr(
        road("1", 1000.0, geometry(0, 0, 0, 0, 1000.0, '<arc curvature="0.6"/>'), simple_lanes())
    )
    t0 = time.perf_counter()
    result = build(tmp_path, text)
    assert time.perf_counter() - t0 < 15.0  # about 3 s on a busy 2-core box
    r = 5.0 / 3.0
    left, right = math.pi * (3.5 - r) ** 2, math.pi * ((r + 3) ** 2 - r**2)
    assert right == pytest.approx(19 * math.pi)
    assert result.lane_area_m2["driving"] == pytest.approx(left + right, rel=0.005)
    assert result.targets[0].area_m2 == pytest.approx(math.pi * (r + 3) ** 2, rel=0.005)
    assert sum(a.area_m2 for a in result.sensor_areas) == pytest.approx(92 * math.pi, rel=0.005)
    assert len(result.warnings) == 1
    w = result.warnings[0]
    assert w.startswith("road 1: lane 1 ") and "folds over itself" in w and "\n" not in w


def test_lanes_wound_without_folding_cover_their_annulus(tmp_path):
    """The same arc with lanes narrower than the radius (1 m left, 3 m right): no
    fold and no warning; the target is the annulus from R - 1 to R + 3 m."""
    arc = geometry(0, 0, 0, 0, 1000.0, '<arc curvature="0.6"/>')
    result = build(tmp_path, xodr(road("1", 1000.0, arc, simple_lanes(1.0, 3.0))))
    r = 5.0 / 3.0
    expect = math.pi * ((r + 3) ** 2 - (r - 1) ** 2)
    assert result.targets[0].area_m2 == pytest.approx(expect, rel=0.005)
    assert result.warnings == []


def test_self_crossing_strips_are_refused_past_their_budget(tmp_path, monkeypatch):
    monkeypatch.setattr(build_module, "MAX_TANGLED_STEPS", 5_000)
    arc = geometry(0, 0, 0, 0, 1000.0, '<arc curvature="0.6"/>')
    message = refused(tmp_path, xodr(road("4", 1000.0, arc, simple_lanes())))
    assert "road 4: lanes whose outlines cross themselves add up to 12,000 steps" in message
    assert "more than the 5,000" in message


# --- the work is sized first: refused up front, naming the road and the figure ------


def test_a_width_cubic_with_a_huge_coefficient_is_refused_up_front(tmp_path):
    """d = 1e6 m^-2: |w''| reaches 6e6 x 100 m = 6e8 1/m; steps of
    sqrt(8 x 5 mm / 6e8) = 8.2 um over 100 m are 1.2e7 stations."""
    lanes = section(0, [lane(1, width(3.5, 0, 0, 1e6))], [lane(-1, width(3.0))])
    message = refused(tmp_path, xodr(road("7", 100.0, line(100.0), lanes)))
    assert "road 7: sampling it takes 1.22e+07 stations" in message
    assert "6e+08 1/m" in message and "50,000 a road may have" in message


def test_a_road_of_1e9_m_is_refused_up_front(tmp_path):
    before = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss
    message = refused(tmp_path, xodr(road("12", 1e9, line(1e9), simple_lanes())))
    assert message.endswith("road 12: length 1e+09 m is beyond the 100 km a road may have")
    # Nothing was allocated for it (it grew to 23 GB before).
    assert resource.getrusage(resource.RUSAGE_SELF).ru_maxrss - before < 100_000  # KiB


def test_lane_sections_spanning_too_far_are_refused(tmp_path):
    sections = section(-2e5, [lane(1, width(3.0))], []) + section(0, [lane(1, width(3.0))], [])
    message = refused(tmp_path, xodr(road("5", 100.0, line(100.0), sections)))
    assert "road 5: its lane sections span 2.001e+05 m (s from -200000)" in message


@pytest.mark.parametrize(
    "road_xml, words",
    [
        # Coordinates past MAX_COORD_M (what a scene point may have).
        (
            road("3", 100.0, line(100.0, x=1e9), simple_lanes()),
            "road 3: reaches 1e+09 m from the file's origin at s=0",
        ),
        # A height past 10 km (float32 keeps a height to 1 mm only within it).
        (
            road("4", 100.0, line(100.0), simple_lanes(), elevation=poly("elevation", 0, 5e7)),
            "road 4: height 5e+07 m at s=0 is beyond",
        ),
        # A lane 1e8 m wide.
        (
            road("5", 100.0, line(100.0), simple_lanes(1e8, 3.0)),
            "road 5: lane 1 is 1e+08 m wide at s=0",
        ),
        # A paramPoly3 with a huge coefficient: x = 1e300 s^3, 8e303 m at s = 20.
        (
            road(
                "6",
                100.0,
                geometry(
                    0,
                    0,
                    0,
                    0,
                    100.0,
                    '<paramPoly3 aU="0" bU="1" cU="0" dU="1e300" aV="0" bV="0" cV="0" dV="0" '
                    'pRange="arcLength"/>',
                ),
                simple_lanes(),
            ),
            "road 6: reaches 8e+303 m from the file's origin at s=20",
        ),
        # A grade of 3 (72 deg) and a superelevation of 1.2 rad (69 deg): a target on
        # them would tilt past the 45 deg a scene allows.
        (
            road("8", 100.0, line(100.0), simple_lanes(), elevation=poly("elevation", 0, 0, 3.0)),
            "road 8: climbs 3 m a metre at s=0 (72 deg)",
        ),
        (
            road(
                "9",
                100.0,
                line(100.0),
                simple_lanes(),
                superelevation=poly("superelevation", 0, 1.2),
            ),
            "road 9: superelevation 1.2 rad at s=0",
        ),
    ],
)
def test_numbers_past_what_a_scene_holds_are_refused_naming_the_road(tmp_path, road_xml, words):
    message = refused(tmp_path, xodr(road_xml))
    assert words in message, message


def test_roads_too_far_apart_for_float32_are_refused_naming_both(tmp_path):
    """Areas are snapped to 2^-9 m, exact in float32 only within 2^15 m = 32.8 km of
    the origin (after the import's shift to the middle): 5,000 km apart is not."""
    text = xodr(
        road("1", 100.0, line(100.0), simple_lanes()),
        road("2", 100.0, line(100.0, x=5e6), simple_lanes()),
    )
    message = refused(tmp_path, text)
    assert "the roads span 5,000 km in x (road 1 at x = " in message
    assert "road 2 at 5,000,100 m)" in message and "32.8 km of the origin" in message


def test_a_header_offset_beyond_a_scenes_offset_is_refused(tmp_path):
    text = xodr(_plain("1"), header='<offset x="5e8" y="0" z="0" hdg="0"/>')
    assert "beyond the 1e+08 m a scene's offset may be" in refused(tmp_path, text)


def test_a_band_beyond_a_sensors_reach_is_refused(tmp_path):
    with pytest.raises(InputError, match=f"at most {MAX_RANGE_M:g} m"):
        build_import(read_opendrive(write(tmp_path, xodr(_plain("1")))), band=(1.0, 5000.0))


def test_a_road_with_more_mesh_points_than_a_road_may_have(tmp_path):
    """100 km at the 20 m step: 5,001 stations; 20 lanes a side: 41 borders."""
    lanes = section(
        0,
        [lane(i, width(3.0)) for i in range(1, 21)],
        [lane(-i, width(3.0)) for i in range(1, 21)],
    )
    message = refused(tmp_path, xodr(road("2", 1e5, line(1e5), lanes)))
    assert "road 2: 205,041 mesh points (5,001 stations x its lane borders)" in message


def test_a_file_with_more_mesh_points_than_an_import_builds(tmp_path, monkeypatch):
    """Two 100 m roads of 2 lanes: 6 stations x 3 borders each."""
    monkeypatch.setattr(build_module, "MAX_POINTS", 30)
    text = xodr(_plain("1"), _plain("2", y=50.0))
    assert "more than 30 mesh points" in refused(tmp_path, text)


def test_a_file_with_too_many_roads_is_refused_before_any_is_read(tmp_path, monkeypatch):
    monkeypatch.setattr(parse_module, "MAX_ROADS", 3)
    stages = []
    path = write(tmp_path, xodr(*[_plain(str(k), y=20.0 * k) for k in range(4)]))
    with pytest.raises(InputError) as err:
        read_opendrive(path, lambda stage, done, total: stages.append(stage))
    assert str(err.value) == (
        f"{path}: 4 roads are more than the 3 an import takes (each becomes a mesh and two "
        "curves in Blender, and more objects make each new one slower: 20,000 roads take "
        "minutes); split the file"
    )
    assert set(stages) == {"reading"}


def test_a_file_too_big_to_read(tmp_path, monkeypatch):
    monkeypatch.setattr(parse_module, "MAX_FILE_BYTES", 100)
    path = write(tmp_path, xodr(_plain("1")))
    with pytest.raises(InputError, match="MiB is more than the 0 MiB an import reads"):
        read_opendrive(path)


# --- a planView that jumps: warned, and no strip invented ---------------------------


def _plain(road_id: str, y: float = 0.0) -> str:
    return road(road_id, 100.0, line(100.0, y=y), simple_lanes())


@pytest.mark.parametrize("section_at_jump", [False, True])
def test_a_planview_jump_is_warned_and_not_bridged(tmp_path, section_at_jump):
    """Two 100 m lines, the second starting 700 m beyond where the first ends. The
    lanes (3.5 m left, 3 m right) cover 2 x 100 x 6.5 = 1,300 m^2; bridged, the quad
    across the jump would have added some 700 x 6.5 m^2. The same when a lane section
    starts at the jump."""
    plan = geometry(0, 0, 0, 0, 100.0, "<line/>") + geometry(100, 800, 0, 0, 100.0, "<line/>")
    lanes = simple_lanes()
    if section_at_jump:
        lanes += section(100.0, [lane(1, width(3.5))], [lane(-1, width(3.0))])
    result = build(tmp_path, xodr(road("9", 200.0, plan, lanes)))
    assert result.warnings == [
        "road 9: the planView jumps 700 m at s=100 (the geometry there starts away from "
        "where the one before it ends); the lanes are cut there, not bridged"
    ]
    snap = 2 * (2 * 100 + 2 * 6.5) * FLOAT32_GRID_M
    assert sum(t.area_m2 for t in result.targets) == pytest.approx(1300.0, abs=snap)
    assert result.lane_area_m2["driving"] == pytest.approx(1300.0, rel=1e-9)
    # No triangle of the road's mesh spans the gap (steps are at most 20 m).
    mesh = result.surfaces[0]
    tri = mesh.vertices[mesh.faces][:, :, :2]
    assert np.linalg.norm(tri - np.roll(tri, 1, axis=1), axis=2).max() < 25.0
    # The sensor bands stop there too: 5 m wide, both sides, 200 m in all.
    assert sum(a.area_m2 for a in result.sensor_areas) == pytest.approx(2 * 5 * 200, rel=1e-6)


def test_a_gap_under_the_tolerance_is_bridged_silently(tmp_path):
    plan = geometry(0, 0, 0, 0, 100.0, "<line/>") + geometry(100, 100.05, 0, 0, 100.0, "<line/>")
    result = build(tmp_path, xodr(road("9", 200.0, plan, simple_lanes())))
    assert result.warnings == []
    assert result.lane_area_m2["driving"] == pytest.approx(200.05 * 6.5, rel=1e-4)


# --- broken numbers are named as such ------------------------------------------------


@pytest.mark.parametrize(
    "geo, words",
    [
        (geometry(0, "nan", 0, 0, 30.0, "<line/>"), "<geometry> x='nan' is not finite"),
        (geometry(0, 0, "inf", 0, 30.0, "<line/>"), "<geometry> y='inf' is not finite"),
        (geometry(0, 0, 0, "nan", 30.0, "<line/>"), "<geometry> hdg='nan' is not finite"),
        (geometry(0, 0, 0, "-inf", 30.0, "<line/>"), "<geometry> hdg='-inf' is not finite"),
        (geometry("nan", 0, 0, 0, 30.0, "<line/>"), "<geometry> s='nan' is not finite"),
        (geometry(0, 0, 0, 0, "inf", "<line/>"), "<geometry> length='inf' is not finite"),
        (geometry(0, 0, 0, 0, -30.0, "<line/>"), "geometry at s=0 has negative length -30"),
        (
            geometry(0, 0, 0, 0, 30.0, "<clothoid/>"),
            "geometry at s=0 holds <clothoid>, not a known geometry",
        ),
        (geometry(0, 0, 0, 0, 30.0, ""), "geometry at s=0 holds nothing, not a known geometry"),
        ("", "no planView geometry"),
        (
            geometry(0, 0, 0, 0, 30.0, '<paramPoly3 aU="0" bU="1" pRange="arcLength"/>'),
            "<paramPoly3> has no 'cU'",
        ),
        (
            geometry(
                0,
                0,
                0,
                0,
                30.0,
                '<paramPoly3 aU="0" bU="nan" cU="0" dU="0" aV="0" bV="0" cV="0" dV="0"/>',
            ),
            "<paramPoly3> bU='nan' is not finite",
        ),
        (
            geometry(
                0,
                0,
                0,
                0,
                30.0,
                '<paramPoly3 aU="0" bU="1" cU="0" dU="0" aV="0" bV="0" cV="0" dV="0" '
                'pRange="degrees"/>',
            ),
            "paramPoly3 at s=0 has pRange 'degrees'",
        ),
        (
            geometry(0, 0, 0, 0, 30.0, '<arc curvature="inf"/>'),
            "<arc> curvature='inf' is not finite",
        ),
    ],
)
def test_every_broken_geometry_names_its_road_and_problem(tmp_path, geo, words):
    path = write(tmp_path, xodr(road("3", 30.0, geo, simple_lanes())))
    with pytest.raises(InputError) as err:
        read_opendrive(path)
    assert str(err.value) == f"{path}: no road could be used: road 3: {words}"


@pytest.mark.parametrize(
    "lanes_xml, words",
    [
        (simple_lanes("nan", 3.0), "<width> a='nan' is not finite"),
        (section(0, [lane(1, width(3.5, "inf"))], []), "<width> b='inf' is not finite"),
        (section("nan", [lane(1, width(3.5))], []), "<laneSection> s='nan' is not finite"),
    ],
)
def test_broken_lane_numbers_name_their_road(tmp_path, lanes_xml, words):
    path = write(tmp_path, xodr(road("3", 30.0, line(30.0), lanes_xml)))
    with pytest.raises(InputError) as err:
        read_opendrive(path)
    assert str(err.value) == f"{path}: no road could be used: road 3: {words}"


def test_a_broken_road_length_names_its_road(tmp_path):
    path = write(tmp_path, xodr(road("3", -30.0, line(30.0), simple_lanes())))
    with pytest.raises(InputError) as err:
        read_opendrive(path)
    assert str(err.value) == f"{path}: no road could be used: road 3: length -30 m is negative"


def test_many_broken_roads_are_counted_after_the_first_three(tmp_path):
    roads = [road(str(k), 30.0, geometry(0, "nan", 0, 0, 30.0, "<line/>"), "") for k in range(5)]
    path = write(tmp_path, xodr(*roads))
    with pytest.raises(InputError) as err:
        read_opendrive(path)
    assert str(err.value) == (
        f"{path}: no road could be used: road 0: <geometry> x='nan' is not finite; road 1: "
        "<geometry> x='nan' is not finite; road 2: <geometry> x='nan' is not finite "
        "(and 2 more)"
    )


def test_skipped_roads_are_named_when_no_lane_of_the_type_is_left(tmp_path):
    broken = road("3", 30.0, geometry(0, "nan", 0, 0, 30.0, "<line/>"), simple_lanes())
    walk = road("4", 30.0, line(30.0, y=40), simple_lanes(kind="sidewalk"))
    message = refused(tmp_path, xodr(broken, walk))
    assert message.endswith(
        "no lane of type driving (the file has: sidewalk); roads skipped: road 3: "
        "<geometry> x='nan' is not finite"
    )


def test_roads_that_parse_but_cannot_be_built_are_named(tmp_path):
    text = xodr(road("3", 0.0, line(30.0), simple_lanes()), road("4", 30.0, line(30.0), ""))
    message = refused(tmp_path, text)
    assert message.endswith(
        "no road could be built: road 3: its lane sections cover none of its length (0 m); "
        "road 4: no lane section"
    )


# --- progress, and the real files unchanged -----------------------------------------


def test_progress_reports_every_stage_in_order(tmp_path, monkeypatch):
    from autoscoop_blender.io.opendrive import progress as progress_module

    monkeypatch.setattr(progress_module, "INTERVAL_S", 0.0)  # every unit
    calls: list[tuple[str, int, int]] = []
    path = write(tmp_path, xodr(*[_plain(str(k), y=20.0 * k) for k in range(5)]))
    net = read_opendrive(path, lambda *a: calls.append(a))
    build_import(net, progress=lambda *a: calls.append(a))
    stages = [c[0] for c in calls]
    order = ["reading", "parsing", "sizing", "roads", "targets", "sensor areas"]
    assert [s for k, s in enumerate(stages) if k == 0 or stages[k - 1] != s] == order
    for stage in order[1:]:
        # Every road counted, in order (a big road is heard from between its lanes).
        done = [d for s, d, t in calls if s == stage]
        assert done == sorted(done) and sorted(set(done)) == [0, 1, 2, 3, 4, 5]
        assert {t for s, d, t in calls if s == stage} == {5}


def test_progress_is_heard_at_least_every_second(tmp_path):
    """1,500 small roads: a few seconds of work, called between units at least every
    ``INTERVAL_S`` = 0.25 s, so never near a second without a call (1.5 s allows for a
    busy machine)."""
    roads = [_plain(str(k), y=20.0 * k) for k in range(1500)]
    times: list[float] = []
    path = write(tmp_path, xodr(*roads))
    net = read_opendrive(path, lambda *a: times.append(time.perf_counter()))
    build_import(net, progress=lambda *a: times.append(time.perf_counter()))
    assert times[-1] - times[0] > 1.0
    assert len(times) > 2 * 6  # each stage's start and end, and calls between
    assert np.diff(times).max() < 1.5


# The union of each real file's targets (ImportSummary.target_m2) before the import was
# bounded (commit 6255d35): unchanged but for FlexZoneCrossing, where 4 folded lanes of
# its junction now count the ground they cover (it lies under its neighbours: 8e-6 m^2).
REAL_TARGET_M2 = {
    "AstaZero_FlexZoneCrossing": 4170.0070177366,
    "AstaZero_GaragePlanHighRes": 826.7985421539379,
    "Town01": 22784.740340266657,
    "Town04": 108708.18286233845,
}


@pytest.mark.parametrize("name", sorted(REAL_TARGET_M2))
def test_real_files_keep_their_target_area(name):
    result = build_import(read_opendrive(DATA / f"{name}.xodr"))
    assert union_area(result) == pytest.approx(REAL_TARGET_M2[name], rel=1e-8)


# --- what the file says is quoted short and on one line; work stays near linear -----


def test_ids_types_and_values_are_quoted_short_and_on_one_line(tmp_path):
    """An id with a line break (&#10; survives XML's attribute normalisation), a value
    of 100,000 characters, 20 made-up lane types: the messages stay one short line."""
    long_value = "1" * 50_000 + "x" + "1" * 50_000
    bad_id = road("a&#10;b", 30.0, geometry(0, long_value, 0, 0, 30.0, "<line/>"), simple_lanes())
    kinds = [lane(-i, width(3.0), f"kind{i}") for i in range(1, 21)]
    odd = road("c", 30.0, line(30.0, y=40), section(0, [], kinds))
    message = refused(tmp_path, xodr(bad_id, odd))
    assert "\n" not in message and len(message) < 400
    assert "kind1, kind10, kind11, kind12, kind13, kind14, kind15, kind16 and 12 more" in message
    assert (
        "roads skipped: road a\\nb: <geometry> x='1111111111111111111111111111111111111...' "
        in (message)
    )


def test_roads_stacked_on_one_another_stay_near_linear(tmp_path):
    """1,000 copies of one road: each band meets all the others' surfaces. Merging
    those band by band was quadratic (2,000 took 12 s); now a few seconds."""
    text = xodr(*[_plain(str(k)) for k in range(1000)])
    t0 = time.perf_counter()
    result = build(tmp_path, text)
    assert time.perf_counter() - t0 < 20.0
    # Each road's own band is 2 x 5 x 100 m^2; its own lanes 650 m^2.
    assert {round(a.area_m2, 6) for a in result.sensor_areas} == {1000.0}
    assert union_area(result) == pytest.approx(650.0, abs=0.01)


def test_a_road_of_20000_geometries_is_evaluated_at_once(tmp_path):
    """20,000 lines of 2 m: seconds, not the quadratic minute of masking every
    station for every geometry."""
    plan = "".join(geometry(2.0 * k, 2.0 * k, 0, 0, 2.0, "<line/>") for k in range(20_000))
    t0 = time.perf_counter()
    result = build(tmp_path, xodr(road("1", 40_000.0, plan, simple_lanes())))
    assert time.perf_counter() - t0 < 20.0
    assert result.lane_area_m2["driving"] == pytest.approx(40_000 * 6.5, rel=1e-9)


@pytest.mark.parametrize(
    "limit, words",
    [
        ("MAX_GEOMETRIES", "4 planView geometries are more than the 3 an import builds"),
        ("MAX_SECTIONS", "4 lane sections are more than the 3 an import builds"),
        ("MAX_LANES", "8 lanes (counted in every lane section) are more than the 3"),
    ],
)
def test_files_with_too_many_records_are_refused_up_front(tmp_path, monkeypatch, limit, words):
    monkeypatch.setattr(build_module, limit, 3)
    text = xodr(*[_plain(str(k), y=20.0 * k) for k in range(4)])
    assert words in refused(tmp_path, text)


def test_a_planview_that_jumps_at_every_geometry_is_refused(tmp_path, monkeypatch):
    """Twelve 2 m lines each starting 1 m past where the one before ends: eleven
    jumps, more than the file may have (each stays a part through every merge)."""
    monkeypatch.setattr(build_module, "MAX_JUMPS", 10)
    plan = "".join(geometry(2.0 * k, 3.0 * k, 0, 0, 2.0, "<line/>") for k in range(12))
    message = refused(tmp_path, xodr(road("1", 24.0, plan, simple_lanes())))
    assert message.endswith(
        "its planViews jump more than 10 times (road 1 alone 11 times): a broken export, "
        "not a road network"
    )
