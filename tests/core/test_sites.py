"""Where a mast may stand (core.model.sites), on SceneModels built from numpy boxes.

The core twin of tests/blender/test_mast_sites.py, without Blender: a terrain plane and
boxes, each figure worked out from the boxes' corners. A box's plan widened by FOOT_M
has the area a b + 2 r (a + b) + pi r^2 (r = FOOT_M); shapely's round corners are
polygons, within 0.002 m^2 of the circle. Every box edge lies on a half metre, so that
no test point (whole metres or a stated offset) sits on an edge.
"""

from __future__ import annotations

import math

import numpy as np
import pytest
import shapely

from autoscoop_blender.core.errors import SceneContractError
from autoscoop_blender.core.model.scene import Area, SceneModel
from autoscoop_blender.core.model.sites import (
    FOOT_M,
    STEP_M,
    mast_sites,
    site_blockers,
    standing_plans,
)
from tests.core.flat import box_mesh

WALL = ((-15.5, -2.5, 0.0), (-14.5, 1.5, 3.0))  # 1 m x 4 m, 3 m high
GUARD_WALL = ((-9.5, -8.5, -0.2), (-5.5, -8.3, 0.3))  # 4 m x 0.2 m, sunk, 0.3 m up
CROWN = ((-8.5, -3.5, 3.0), (-6.5, -1.5, 8.0))  # a tree crown, 2 m x 2 m, no trunk
KERB = ((-9.5, 3.5, -0.1), (-5.5, 6.5, 0.15))  # sunk 0.1 m, 0.15 m up: spanned
BUILDING = ((-14.5, -9.5, 0.0), (-10.5, -5.5, 6.0))  # a mount: a 6 m roof
CANOPY = ((-13.5, 3.5, 4.0), (-10.5, 7.5, 5.0))  # an overhang
SENSOR = (-20.0, -10.0, -4.0, 10.0)  # 16 m x 20 m = 320 m^2


def buffered_m2(lo, hi):
    """A box's plan widened by FOOT_M: a b + 2 r (a + b) + pi r^2."""
    a, b = hi[0] - lo[0], hi[1] - lo[1]
    return a * b + 2 * FOOT_M * (a + b) + math.pi * FOOT_M**2


def plane(x0, y0, x1, y1, z=lambda x, y: 0.0):
    """A rectangle as two triangles (counter-clockwise in plan), heights z(x, y)."""
    corners = [(x0, y0), (x1, y0), (x1, y1), (x0, y1)]
    verts = np.array([(x, y, z(x, y)) for x, y in corners], float)
    return verts, np.array([(0, 1, 2), (0, 2, 3)], dtype=np.int32)


def box(lo, hi):
    return box_mesh([(lo, hi)])


def scene_of(objects, sensors=(SENSOR,), mounts=(), overhangs=(), no_mast=()):
    """A SceneModel from {object name: [(vertices, faces), ...]} (the parts of one
    object are one mesh: merged objects), box sensor areas and no-mast zones."""
    verts, faces, owner, ground = [], [], [], []
    base = 0
    for k, (name, parts) in enumerate(objects.items()):
        for v, f in parts:
            verts.append(np.asarray(v, float))
            faces.append(np.asarray(f, np.int32) + base)
            owner += [k] * len(f)
            ground += [name not in overhangs] * len(f)
            base += len(v)
    return SceneModel(
        vertices=np.concatenate(verts),
        faces=np.concatenate(faces).astype(np.int32),
        occluders=tuple(objects),
        targets=(Area("Target", shapely.box(0, -25, 50, 25)),),
        sensor_areas=tuple(Area(f"SensorArea_{k}", shapely.box(*b)) for k, b in enumerate(sensors)),
        ground_faces=np.array(ground, dtype=bool),
        no_mast=tuple(Area(n, shapely.box(*b)) for n, b in no_mast),
        face_object=np.array(owner, dtype=np.int32),
        mounts=tuple(mounts),
    )


def terrain(z=lambda x, y: 0.0):
    return [plane(-60, -60, 60, 60, z)]


def site_scene(no_mast=()):
    """The terrain, and one of each kind of object, in a 16 m x 20 m sensor area."""
    return scene_of(
        {
            "Terrain": terrain(),
            "Wall": [box(*WALL)],
            "GuardWall": [box(*GUARD_WALL)],
            "Crown": [box(*CROWN)],
            "Kerb": [box(*KERB)],
            "Building": [box(*BUILDING)],
            "Canopy": [box(*CANOPY)],
        },
        mounts=("Building",),
        overhangs=("Canopy",),
        no_mast=no_mast,
    )


def test_what_stands_on_the_ground_is_cut_out_and_reported():
    scene = mast_sites(site_scene())
    got = {e.cause: e.m2 for e in scene.excluded}
    assert {e.area for e in scene.excluded} == {"SensorArea_0"}
    # The wall, the sunk 0.3 m guard wall and the crown; not the 0.15 m kerb, the
    # terrain, the mount or the overhang.
    assert got == {
        "Wall": pytest.approx(buffered_m2(*WALL), abs=2e-3),
        "GuardWall": pytest.approx(buffered_m2(*GUARD_WALL), abs=2e-3),
        "Crown": pytest.approx(buffered_m2(*CROWN), abs=2e-3),
    }
    (area,) = scene.sensor_areas
    assert area.geometry.area == pytest.approx(320.0 - sum(got.values()), abs=1e-6)


def test_standing_plans_are_the_plans_widened_by_the_foot():
    scene = site_scene()
    plans = standing_plans(scene, shapely.box(*SENSOR))
    assert set(plans) == {"Wall", "GuardWall", "Crown"}
    for name, (lo, hi) in {"Wall": WALL, "GuardWall": GUARD_WALL, "Crown": CROWN}.items():
        assert plans[name].area == pytest.approx(buffered_m2(lo, hi), abs=2e-3)
        # Exactly FOOT_M around the box, in plan: the bounds grow by FOOT_M.
        assert plans[name].bounds == pytest.approx(
            (lo[0] - FOOT_M, lo[1] - FOOT_M, hi[0] + FOOT_M, hi[1] + FOOT_M), abs=1e-9
        )


def test_the_step_a_mast_base_spans():
    """A box on the terrain whose top is h above it stands when h > STEP_M, not at
    STEP_M itself (box_mesh's corners lo + (hi - lo) are exact from lo = 0)."""
    lo, hi = (-9.5, 3.5, 0.0), (-5.5, 6.5, 0.0)
    for h, stands in [(0.15, False), (STEP_M, False), (STEP_M + 0.01, True)]:
        scene = scene_of({"Terrain": terrain(), "Step": [box(lo, (*hi[:2], h))]})
        assert set(standing_plans(scene, shapely.box(*SENSOR))) == ({"Step"} if stands else set())


def test_nothing_below_a_solid_on_nothing_reads_as_a_raised_ground():
    """A crown with no terrain under it is the ground there (docstring's limit); over
    the terrain, both its top and its bottom stand, so its whole plan is cut."""
    assert standing_plans(scene_of({"Crown": [box(*CROWN)]}), shapely.box(*SENSOR)) == {}
    over = scene_of({"Terrain": terrain(), "Crown": [box(*CROWN)]})
    assert standing_plans(over, shapely.box(*SENSOR))["Crown"].area == pytest.approx(
        buffered_m2(*CROWN), abs=2e-3
    )


def test_the_overhang_and_the_mount_are_no_cause_but_would_be_unmarked():
    """Marked, the canopy and the building are no cause; unmarked, each would be: the
    canopy floats 4 m up, the building's roof is 6 m above the terrain."""
    parts = {"Terrain": terrain(), "Building": [box(*BUILDING)], "Canopy": [box(*CANOPY)]}
    where = shapely.box(*SENSOR)
    marked = scene_of(parts, mounts=("Building",), overhangs=("Canopy",))
    assert standing_plans(marked, where) == {}
    plain = standing_plans(scene_of(parts), where)
    assert {n: g.area for n, g in plain.items()} == {
        "Building": pytest.approx(buffered_m2(*BUILDING), abs=2e-3),
        "Canopy": pytest.approx(buffered_m2(*CANOPY), abs=2e-3),
    }


def test_a_hut_on_a_mount_stands_and_a_pillar_under_a_deck_stands_beside_it():
    """A 0.5 m hut on the building's roof stands (the ground is the terrain, 6.5 m below
    its top; the roof, 0.5 m below the hut's top, is not on top there); a mast stands on the deck of a mount above a 4 m pillar, and the pillar counts
    only where it sticks out beside the deck (x from -16.5 to -16.0).

    Faces are judged at their centroids: the roof's two triangles (split along the
    diagonal from its (-14.5, -9.5) corner) have theirs at (-11.83, -8.17) and
    (-13.17, -6.83), both under the hut, so no part of the roof counts as on top.
    The deck's are at (-17.5, -8.83) and (-18.5, -8.17), where the deck is on top."""
    hut = ((-13.5, -8.5, 6.0), (-11.5, -6.5, 6.5))
    deck = ((-19.5, -9.5, 4.0), (-16.5, -7.5, 5.0))
    pillar = ((-18.5, -9.0, 0.0), (-16.0, -8.0, 4.0))
    scene = scene_of(
        {
            "Terrain": terrain(),
            "Building": [box(*BUILDING)],
            "Hut": [box(*hut)],
            "Deck": [box(*deck)],
            "Pillar": [box(*pillar)],
        },
        mounts=("Building", "Deck"),
    )
    plans = standing_plans(scene, shapely.box(*SENSOR))
    assert set(plans) == {"Hut", "Pillar"}
    assert plans["Hut"].area == pytest.approx(buffered_m2(*hut), abs=2e-3)
    beside = ((-16.5, -9.0), (-16.0, -8.0))
    assert plans["Pillar"].area == pytest.approx(buffered_m2(*beside), abs=2e-3)
    assert plans["Pillar"].bounds == pytest.approx((-16.75, -9.25, -15.75, -7.75), abs=1e-9)


def test_two_objects_merged_into_one_mesh_count_apart():
    """A wall and the terrain merged into one object: the wall is its own island, so it
    stands, under the merged object's name. Joined to the terrain by a vertex (one
    piece), it reads as ground (docstring's limit)."""
    merged = scene_of({"Merged": [*terrain(), box(*WALL)]})
    plans = standing_plans(merged, shapely.box(*SENSOR))
    assert {n: g.area for n, g in plans.items()} == {
        "Merged": pytest.approx(buffered_m2(*WALL), abs=2e-3)
    }
    # A triangle with no plan (a terrain corner and a wall corner, twice) shares a
    # vertex with each: one island, topped by the wall's roof.
    tv, tf = terrain()[0]
    wv, wf = box(*WALL)
    corner = 4 + int(np.flatnonzero((wv == WALL[0]).all(axis=1))[0])
    faces = np.concatenate([tf, wf + 4, [[0, corner, corner]]]).astype(np.int32)
    one = scene_of({"Merged": [(np.concatenate([tv, wv]), faces)]})
    assert standing_plans(one, shapely.box(*SENSOR)) == {}


def slope(x, y):
    return 0.1 * x + 0.05 * y


def test_on_a_sloping_terrain_the_step_is_measured_from_the_terrain_below():
    """Terrain z = 0.1 x + 0.05 y (two triangles about 120 m across). Two 1 m boxes sunk 1 m: High,
    centred on (-10, 0) where the terrain is at -1.0, tops out 0.3 m above that; Low,
    centred on (-10, 5) where it is at -0.75, 0.1 m. Their roof triangles' centroids
    lie 1/6 m from the centre in x and y: the terrain there differs from the centre's
    by at most 0.1/6 + 0.05/6 = 0.025 m, so High clears STEP_M and Low does not."""
    high = ((-10.5, -0.5, -2.0), (-9.5, 0.5, -0.7))
    low = ((-10.5, 4.5, -1.75), (-9.5, 5.5, -0.65))
    # The terrain's corners are off square, so that no term of the plane's height
    # vanishes for its triangles' edges.
    corners = [(-60.0, -55.0), (58.0, -60.0), (60.0, 57.0), (-57.0, 60.0)]
    verts = np.array([(x, y, slope(x, y)) for x, y in corners])
    tilted = (verts, np.array([(0, 1, 2), (0, 2, 3)], dtype=np.int32))
    scene = scene_of({"Terrain": [tilted], "High": [box(*high)], "Low": [box(*low)]})
    plans = standing_plans(scene, shapely.box(*SENSOR))
    assert {n: g.area for n, g in plans.items()} == {
        "High": pytest.approx(buffered_m2(*high), abs=2e-3)
    }
    # On flat terrain at z = -1 both would stand (Low's top is 0.35 m up).
    flat = scene_of(
        {"Terrain": terrain(lambda x, y: -1.0), "High": [box(*high)], "Low": [box(*low)]}
    )
    assert set(standing_plans(flat, shapely.box(*SENSOR))) == {"High", "Low"}


def test_site_blockers_name_what_keeps_a_mast_off_each_point():
    scene = site_scene(no_mast=(("NoMast_Gate", (-19.5, 7.5, -16.5, 9.5)),))
    points = {
        (-15.0, 0.0): "Wall",  # on it
        (-14.3, 0.0): "Wall",  # 0.2 m east of its east face: within FOOT_M
        (-14.2, 0.0): None,  # 0.3 m east
        (-15.0, 1.7): "Wall",  # 0.2 m north of its north face
        (-14.3, 1.7): None,  # 0.283 m from its corner: the widening is round
        (-7.5, -2.5): "Crown",  # under the crown
        (-7.5, -8.4): "GuardWall",
        (-7.5, -8.0): None,  # 0.3 m north of the guard wall
        (-7.5, 5.0): None,  # on the kerb
        (-12.5, -7.5): None,  # on the mount's roof
        (-12.0, 5.5): None,  # under the overhang
        (-18.0, 8.5): "NoMast_Gate",
        (-30.0, 0.0): None,  # open terrain, outside the sensor area
    }
    xy = np.array(list(points), float)
    assert site_blockers(scene, xy) == list(points.values())
    assert site_blockers(site_scene(), xy[0]) == ["Wall"]  # one point as (2,)


def test_no_mast_zones_and_standing_objects_cut_every_sensor_area():
    """Area 0 is the 320 m^2 west area; area 1 (-3..-1 x 0..2, 4 m^2) lies wholly in
    the no-mast zone Square and is dropped; area 2 (-3..-1 x 3..4, 2 m^2) keeps the
    0.5 m^2 north of Square's edge at y = 3.75. The zone Strip (-22..-18 x 8..9.5)
    reaches 3 m^2 into area 0, Corner (-21..-19.5 x 9.5..11) 0.25 m^2. The wall lies in
    area 0 only."""
    scene = scene_of(
        {"Terrain": terrain(), "Wall": [box(*WALL)]},
        sensors=(SENSOR, (-3.0, 0.0, -1.0, 2.0), (-3.0, 3.0, -1.0, 4.0)),
        no_mast=(
            ("Strip", (-22.0, 8.0, -18.0, 9.5)),
            ("Corner", (-21.0, 9.5, -19.5, 11.0)),
            ("Square", (-3.5, -0.5, -0.5, 3.75)),
        ),
    )
    out = mast_sites(scene)
    got = {(e.area, e.cause): e.m2 for e in out.excluded}
    assert got == {
        ("SensorArea_0", "Strip"): pytest.approx(3.0, abs=1e-9),
        ("SensorArea_0", "Corner"): pytest.approx(0.25, abs=1e-9),
        ("SensorArea_0", "Wall"): pytest.approx(buffered_m2(*WALL), abs=2e-3),
        ("SensorArea_1", "Square"): pytest.approx(4.0, abs=1e-9),
        ("SensorArea_2", "Square"): pytest.approx(1.5, abs=1e-9),
    }
    assert [a.name for a in out.sensor_areas] == ["SensorArea_0", "SensorArea_2"]
    west, east = out.sensor_areas
    assert west.geometry.area == pytest.approx(320.0 - 3.25 - buffered_m2(*WALL), abs=2e-3)
    assert east.geometry.equals(shapely.box(-3.0, 3.75, -1.0, 4.0))
    assert out.no_mast == scene.no_mast and out.targets == scene.targets


def test_a_wall_and_a_zone_that_overlap_are_both_reported_and_cut_once():
    """A zone over the wall's north half (-16..-14 x 0..2, 4 m^2): each cause is
    reported whole, and the area loses their union: the zone plus the widened wall
    less their overlap, the wall's widened plan north of y = 0 inside the zone
    (x -15.75..-14.25, y 0..1.75, with two rounded corners: 1.5 x 1.75 less
    (4 - pi) r^2 / 4 twice)."""
    scene = scene_of(
        {"Terrain": terrain(), "Wall": [box(*WALL)]},
        no_mast=(("Zone", (-16.0, 0.0, -14.0, 2.0)),),
    )
    out = mast_sites(scene)
    got = {e.cause: e.m2 for e in out.excluded}
    assert got == {
        "Zone": pytest.approx(4.0, abs=1e-9),
        "Wall": pytest.approx(buffered_m2(*WALL), abs=2e-3),
    }
    overlap = 1.5 * 1.75 - 2 * (4 - math.pi) * FOOT_M**2 / 4
    lost = 4.0 + buffered_m2(*WALL) - overlap
    assert out.sensor_areas[0].geometry.area == pytest.approx(320.0 - lost, abs=2e-3)


def test_no_room_anywhere_is_an_error_naming_the_causes():
    scene = scene_of(
        {"Terrain": terrain(), "Wall": [box(*WALL)]},
        sensors=((-15.5, -1.0, -14.5, 1.0),),  # on the wall's top
        no_mast=(("Far", (40.0, 40.0, 41.0, 41.0)),),
    )
    with pytest.raises(SceneContractError, match=r"no sensor area has room for a mast.*\(Wall\)"):
        mast_sites(scene)
    # Two causes, named in order.
    both = scene_of(
        {"Terrain": terrain(), "Wall": [box(*WALL)]},
        sensors=((-15.5, -1.0, -14.5, 1.0), (30.0, 30.0, 31.0, 31.0)),
        no_mast=(("Square", (29.0, 29.0, 32.0, 32.0)),),
    )
    with pytest.raises(SceneContractError, match=r"cover them all \(Square, Wall\)$"):
        mast_sites(both)


def test_nothing_to_judge_leaves_the_scene_as_it_is():
    bare = scene_of({"Terrain": terrain(), "Wall": [box(*WALL)]})
    # Objects unknown: nothing is judged to stand; no zones: the very scene back.
    unknown = SceneModel(
        vertices=bare.vertices,
        faces=bare.faces,
        occluders=bare.occluders,
        targets=bare.targets,
        sensor_areas=bare.sensor_areas,
    )
    assert mast_sites(unknown) is unknown
    assert standing_plans(unknown, shapely.box(*SENSOR)) == {}
    # Nothing standing near the area (the wall is 10 m east of a small area).
    away = scene_of({"Terrain": terrain(), "Wall": [box(*WALL)]}, sensors=((-40, -1, -30, 1),))
    assert mast_sites(away) is away
    assert standing_plans(bare, shapely.Polygon()) == {}
    assert site_blockers(away, np.array([[-35.0, 0.0]])) == [None]


def test_only_objects_within_the_foot_of_where_are_looked_at():
    """standing_plans(where) names the objects standing within FOOT_M of ``where``.
    (A fresh scene for each call: see the test below.)"""
    assert set(standing_plans(site_scene(), shapely.Point(-14.3, 0.0))) == {"Wall"}
    assert standing_plans(site_scene(), shapely.Point(-14.2, 0.0)) == {}
    # The wall is 0.5 m north of this box; the guard wall and the crown reach into it.
    assert set(standing_plans(site_scene(), shapely.box(-16.0, -9.0, -6.0, -3.0))) == {
        "GuardWall",
        "Crown",
    }
    # A strip 0.2 m west of the crown (and over the kerb, which does not stand) ...
    assert set(standing_plans(site_scene(), shapely.box(-9.0, -3.0, -8.7, 5.0))) == {"Crown"}
    # ... and 0.3 m west of it.
    assert standing_plans(site_scene(), shapely.box(-9.0, -3.0, -8.8, 5.0)) == {}


def test_judging_sites_leaves_the_scene_alone():
    """A scene with an overhang has a ground_faces array; asking about one point must
    not change it, nor the answer to the next question (the crown stands whatever was
    asked before; in an extracted scene the same array feeds the ground caster)."""
    scene = site_scene()
    before = scene.ground_faces.copy()
    assert site_blockers(scene, np.array([[-15.0, 0.0]])) == ["Wall"]
    assert site_blockers(scene, np.array([[-7.5, -2.5]])) == ["Crown"]
    assert np.array_equal(scene.ground_faces, before)


def turned(lo, hi, deg, about):
    """A box's mesh turned by ``deg`` about the vertical line through ``about``."""
    v, f = box(lo, hi)
    c, s = math.cos(math.radians(deg)), math.sin(math.radians(deg))
    x, y = v[:, 0] - about[0], v[:, 1] - about[1]
    v = np.column_stack([about[0] + c * x - s * y, about[1] + s * x + c * y, v[:, 2]])
    return v, f


def test_a_wall_at_an_angle_is_cut_by_its_own_plan():
    """The 1 m x 4 m wall turned 30 deg about its centre: its widened plan has the same
    area, and a point 0.2 m off its long side (along the side's normal) is blocked,
    0.3 m off is not. Its sides are vertical faces at an angle: no plan, no top."""
    centre = (-15.0, -0.5)
    scene = lambda: scene_of(  # noqa: E731 (a fresh scene per question)
        {"Terrain": terrain(), "Wall": [turned(*WALL, 30.0, centre)]}
    )
    plans = standing_plans(scene(), shapely.box(*SENSOR))
    assert {n: g.area for n, g in plans.items()} == {
        "Wall": pytest.approx(buffered_m2(*WALL), abs=2e-3)
    }
    # The long side's outward normal, turned 30 deg from +x.
    n = np.array([math.cos(math.radians(30)), math.sin(math.radians(30))])
    for off, blocked in [(0.2, "Wall"), (0.3, None)]:
        p = np.array(centre) + (0.5 + off) * n
        assert site_blockers(scene(), p[None]) == [blocked]


def test_ground_faces_none_reads_every_face_as_ground():
    """An extracted scene with no overhang has ground_faces None: the same causes as
    with an all-True mask."""
    s = site_scene()
    keep = np.array([n != "Canopy" for n in np.array(s.occluders)[s.face_object]])
    idx = {n: k for k, n in enumerate(s.occluders)}
    bare = SceneModel(
        vertices=s.vertices,
        faces=s.faces[keep],
        occluders=s.occluders,
        targets=s.targets,
        sensor_areas=s.sensor_areas,
        face_object=s.face_object[keep],
        mounts=s.mounts,
    )
    assert bare.ground_faces is None and idx["Canopy"] not in bare.face_object
    out = mast_sites(bare)
    assert {e.cause: e.m2 for e in out.excluded} == {
        "Wall": pytest.approx(buffered_m2(*WALL), abs=2e-3),
        "GuardWall": pytest.approx(buffered_m2(*GUARD_WALL), abs=2e-3),
        "Crown": pytest.approx(buffered_m2(*CROWN), abs=2e-3),
    }


def test_the_order_of_objects_and_faces_does_not_matter():
    """The terrain listed last, the boxes in reverse, each mesh's faces reversed: the
    same causes and areas."""
    objects = {
        "Canopy": [box(*CANOPY)],
        "Building": [box(*BUILDING)],
        "Kerb": [box(*KERB)],
        "Crown": [box(*CROWN)],
        "GuardWall": [box(*GUARD_WALL)],
        "Wall": [box(*WALL)],
        "Terrain": terrain(),
    }
    flipped = {n: [(v, f[::-1]) for v, f in parts] for n, parts in objects.items()}
    for parts in (objects, flipped):
        scene = scene_of(parts, mounts=("Building",), overhangs=("Canopy",))
        got = {e.cause: e.m2 for e in mast_sites(scene).excluded}
        assert got == {
            "Wall": pytest.approx(buffered_m2(*WALL), abs=2e-3),
            "GuardWall": pytest.approx(buffered_m2(*GUARD_WALL), abs=2e-3),
            "Crown": pytest.approx(buffered_m2(*CROWN), abs=2e-3),
        }


def test_the_terrain_is_read_where_it_is_not_where_its_plane_runs_on():
    """A terrain of two planes: the south-east half (x > y) flat at z = 0, the
    north-west half sloping down to -60 m at (-60, 60) (z = 0.5 (x - y) there). A box
    sunk 0.5 m, 0.5 m up, in the flat half at (-7, -9): it stands. The sloping half's
    plane, run on to the box, would be 0.5 (-7 + 9) = 1 m up there, above the box's
    top: the height at a point comes only from the faces over it."""
    verts = np.array([(-60, -60, 0), (60, -60, 0), (60, 60, 0), (-60, 60, -60)], float)
    valley = (verts, np.array([(0, 1, 2), (0, 2, 3)], dtype=np.int32))
    low = ((-7.5, -9.5, -0.5), (-6.5, -8.5, 0.5))
    plans = standing_plans(
        scene_of({"Terrain": [valley], "Low": [box(*low)]}), shapely.box(*SENSOR)
    )
    assert {n: g.area for n, g in plans.items()} == {
        "Low": pytest.approx(buffered_m2(*low), abs=2e-3)
    }


def test_exactly_the_foot_away_is_no_site():
    """Within FOOT_M includes FOOT_M: points exactly 0.25 m off each of the wall's four
    sides (sums exact in binary) are blocked."""
    for p in [(-14.25, 0.0), (-15.75, 0.0), (-15.0, 1.75), (-15.0, -2.75)]:
        assert site_blockers(site_scene(), np.array([p])) == ["Wall"], p


def test_a_sensor_area_anywhere_in_the_plane():
    """The same wall, moved to the south-east (x 20.5..21.5, y -32.5..-28.5), in a
    sensor area there: every coordinate of one sign, none near the other's values."""
    wall = ((20.5, -32.5, 0.0), (21.5, -28.5, 3.0))
    scene = scene_of(
        {"Terrain": terrain(), "Wall": [box(*wall)]}, sensors=((15.0, -40.0, 30.0, -20.0),)
    )
    got = {e.cause: e.m2 for e in mast_sites(scene).excluded}
    assert got == {"Wall": pytest.approx(buffered_m2(*wall), abs=2e-3)}


def test_no_faces_near_where_is_nothing_standing():
    """No terrain, one wall, asked 10 m away: no face to judge at all."""
    scene = scene_of({"Wall": [box(*WALL)]})
    assert standing_plans(scene, shapely.box(-40.0, -1.0, -30.0, 1.0)) == {}
    assert site_blockers(scene_of({"Wall": [box(*WALL)]}), np.array([[-35.0, 0.0]])) == [None]


def test_a_box_buried_elsewhere_does_not_lower_the_ground_under_a_kerb():
    """The terrain, the 0.15 m kerb, then a culvert buried 1 m deep (top at -1 m) 10 m
    away: at the kerb the ground is still the terrain, so the kerb does not stand; the
    culvert's own faces lie below the terrain and stand nowhere."""
    culvert = ((-19.5, -9.5, -2.0), (-17.5, -7.5, -1.0))
    scene = scene_of({"Terrain": terrain(), "Kerb": [box(*KERB)], "Culvert": [box(*culvert)]})
    assert standing_plans(scene, shapely.box(*SENSOR)) == {}


def test_a_culvert_under_the_terrain_does_not_make_the_terrain_stand():
    """A box buried 1 to 2 m under the centroid (-20, 20) of a terrain triangle lies
    wholly below the (larger) terrain: it is not the ground there, so the terrain
    stays ground and nothing stands."""
    culvert = ((-21.0, 19.0, -2.0), (-19.0, 21.0, -1.0))
    scene = scene_of(
        {"Terrain": terrain(), "Culvert": [box(*culvert)]}, sensors=((-30, 10, -10, 30),)
    )
    assert standing_plans(scene, shapely.box(-30, 10, -10, 30)) == {}


def test_a_small_hut_on_a_mount_roof_stands():
    """A 1 m x 1 m hut on the mount's roof covers neither roof triangle's centroid: the
    roof is on top of nothing there, so the hut still stands (1 + 2 r 2 + pi r^2)."""
    hut = ((-13.5, -8.5, 6.0), (-12.5, -7.5, 8.0))
    scene = scene_of(
        {"Terrain": terrain(), "Building": [box(*BUILDING)], "Hut": [box(*hut)]},
        mounts=("Building",),
    )
    got = standing_plans(scene, shapely.box(*SENSOR))
    assert set(got) == {"Hut"}
    assert got["Hut"].area == pytest.approx(1.0 + 4 * FOOT_M + math.pi * FOOT_M**2, abs=2e-3)
