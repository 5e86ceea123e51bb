"""Camera pixel density (DORI, issue 16 point 4) against numbers worked out by hand.

The definition (``sensors`` module docstring): px/m = sqrt(pixels per m^2 of the
surface) = sqrt(f_x f_y |d.n| / (r^2 cos^3 t)). On flat ground under a camera h high,
pitched p, looking along +X, a ground point (X, Y) lies at depth D = X cos p + h sin p
along the optical axis and px/m = sqrt(f^2 h / D^3) (f = f_x = f_y), so a level of
P px/m holds up to D_P = (f^2 h / P^2)^(1/3). The pinhole's ground footprint is the
trapezoid X in [h / tan(p + V/2), h / tan(p - V/2)], |Y| <= tan(H/2) D(X); cut at
D <= D_P it has the area

    A = 2 tan(H/2) [cos p (X_e^2 - X_n^2) / 2 + h sin p (X_e - X_n)],
    X_n = h / tan(p + V/2),  X_e = min(h / tan(p - V/2), (D_P - h sin p) / cos p).

For the issue's camera (7 m, pitch 45 deg, 1920 x 1080, 80 deg): f = 960 / tan 40 deg
= 1144.08 px, V = 50.534 deg; D_P = 24.47, 13.36, 8.370, 5.273 m for detect, observe,
recognise, identify; A = 363.46, 158.07, 29.46 and 0 m^2 (identify asks for a depth
nearer than the nearest ground in view, 6.73 m; even straight down from 7 m a 1080p
80 deg camera gives f / 7 = 163 px/m).
"""

from __future__ import annotations

import math
from dataclasses import replace

import numpy as np
import pytest
import shapely

from autoscoop_blender.core.coverage.base import place
from autoscoop_blender.core.coverage.cached import CachedTargetedEvaluator
from autoscoop_blender.core.coverage.pointcloud import PointcloudEvaluator
from autoscoop_blender.core.coverage.reference import reference_footprint_m2
from autoscoop_blender.core.coverage.targeted import TargetedEvaluator
from autoscoop_blender.core.errors import InputError
from autoscoop_blender.core.geom.grid import GroundGrid
from autoscoop_blender.core.geom.raycast import BoxCaster
from autoscoop_blender.core.model.scene import Area, SceneModel
from autoscoop_blender.core.model.sensors import (
    CCTV_CAMERA,
    DORI_PX_PER_M,
    PAPER_CAMERA,
    PRESETS,
    ROADSIDE_LIDAR,
    TRAFFIC_RADAR,
    SensorModel,
    SensorPose,
    frame,
)
from autoscoop_blender.io.config import load_config
from autoscoop_blender.io.sensor_file import parse_sensors
from tests.core.flat import box_mesh

H_M, PITCH = 7.0, 45.0
F_PX = 960.0 / math.tan(math.radians(40.0))  # 1144.08 px, the issue's camera
# Hand-computed footprints (module docstring), m^2, at 7 m and pitch 45 deg.
HAND_M2 = {"detect": 363.46, "observe": 158.07, "recognise": 29.46, "identify": 0.0}


def hand_depth(px_per_m: float, f: float = F_PX, h: float = H_M) -> float:
    """The depth along the optical axis up to which flat ground gets ``px_per_m``."""
    return (f * f * h / px_per_m**2) ** (1.0 / 3.0)


def hand_area(px_per_m, f=F_PX, h=H_M, pitch=PITCH, h_fov=80.0, w=1920, hgt=1080):
    """Closed-form flat-ground footprint of a level (module docstring), m^2."""
    p = math.radians(pitch)
    tu = math.tan(math.radians(h_fov) / 2)
    va = math.atan(hgt / w * tu)
    xn = h / math.tan(p + va)
    xf = h / math.tan(p - va) if p > va else math.inf
    xe = min(xf, (hand_depth(px_per_m, f, h) - h * math.sin(p)) / math.cos(p))
    if xe <= xn:
        return 0.0
    return 2 * tu * (math.cos(p) * (xe**2 - xn**2) / 2 + h * math.sin(p) * (xe - xn))


def scene(targets, boxes=()):
    vertices, faces = box_mesh(list(boxes))
    return SceneModel(
        vertices=vertices,
        faces=faces,
        occluders=tuple(f"Box{k}" for k in range(len(boxes))),
        targets=tuple(targets),
        sensor_areas=(Area("SensorArea", shapely.box(-1, -1, 1, 1)),),
    )


def grid_of(targets, spacing, boxes=(), reach=50.0, target_height_m=0.0):
    caster = BoxCaster(list(boxes), ground_z=0.0)
    grid = GroundGrid(scene(targets, boxes), caster, spacing, target_height_m, reach_m=reach)
    return grid, caster


def camera(level="detect", **kw):
    return replace(CCTV_CAMERA, min_px_per_m=DORI_PX_PER_M[level], **kw).validated("test")


POSE = SensorPose(0.0, 0.0, H_M, H_M, PITCH, 0.0)


def test_hand_numbers_of_the_docstring():
    """The closed form reproduces the figures written above (a typo guard)."""
    for level, area in HAND_M2.items():
        assert hand_area(DORI_PX_PER_M[level]) == pytest.approx(area, abs=0.01)
    assert CCTV_CAMERA.focal_px() == pytest.approx((F_PX, F_PX), rel=1e-5)


def test_px_per_m_matches_a_projected_square():
    """px/m against the pinhole projection of a small square on the surface, counted
    in pixels (the image of each corner: u = f_x left / fwd, v = f_y up / fwd), on the
    ground, on walls and on a slope, on and off the optical axis."""
    model = CCTV_CAMERA
    fx, fy = model.focal_px()
    rng = np.random.default_rng(7)
    s = np.array([0.0, 0.0, 7.0])
    rot = frame(30.0, 20.0)
    normals = [(0, 0, 1), (-1, 0, 0), (0, -1, 0), (-0.6, 0.0, 0.8), (-0.3, 0.4, 0.866)]
    checked = 0
    for n in normals:
        n = np.array(n, float) / np.linalg.norm(n)
        a = np.cross(n, [0.3, 0.7, 0.1])
        a /= np.linalg.norm(a)
        b = np.cross(n, a)
        for _ in range(60):
            p = s + 25 * rng.uniform(-1, 1, 3) * (1, 1, 0.25) + (15, 5, -7)
            d = (p - s) / np.linalg.norm(p - s)
            local = rot @ d
            if not model.in_fov(local[None])[0] or abs(d @ n) < 0.05:
                continue
            e = 1e-4  # a 0.1 mm square centred on p, corners projected to pixels

            def pix(q):
                c = rot @ (q - s)
                return np.array([fx * c[1] / c[0], fy * c[2] / c[0]])

            h = e / 2
            corners = (p - h * a - h * b, p + h * a - h * b, p + h * a + h * b, p - h * a + h * b)
            q = [pix(c) for c in corners]
            px_area = 0.5 * abs(
                sum(q[i][0] * q[i - 1][1] - q[i - 1][0] * q[i][1] for i in range(4))
            )
            expect = math.sqrt(px_area / e**2)
            facing = np.array([abs(d @ n) / np.linalg.norm(p - s) ** 2])
            got = model.px_per_m(local[None], facing)[0]
            assert got == pytest.approx(expect, rel=1e-4)
            checked += 1
    assert checked > 80
    # A surface facing the camera on its axis: the CCTV calculators' f / distance.
    assert model.px_per_m(np.array([[1.0, 0, 0]]), np.array([1 / 20.0**2]))[0] == pytest.approx(
        F_PX / 20.0, rel=1e-6
    )


def _footprint_targeted(model, spacing, box):
    grid, caster = grid_of([Area("T", shapely.box(*box))], spacing)
    return len(TargetedEvaluator(grid, caster).evaluate(model, POSE).covered) * grid.cell_area


def test_recognise_footprint_matches_hand_issue_check():
    """The issue's check: the recognise footprint within 2 % of the closed form
    (29.46 m^2), targeted on a 5 cm grid and pointcloud (its own alpha shape)."""
    model = camera("recognise")
    hand = HAND_M2["recognise"]
    a = _footprint_targeted(model, 0.05, (0, -12, 8, 12))
    assert a == pytest.approx(hand, rel=0.02)
    grid, caster = grid_of([Area("T", shapely.box(0, -12, 8, 12))], 0.1)
    ev = PointcloudEvaluator(grid, caster, oversample=4)
    b = ev.evaluate(model, POSE, outside_band_m=math.inf).footprint_m2
    assert b == pytest.approx(hand, rel=0.02)


@pytest.mark.parametrize("level", ["detect", "observe"])
def test_lower_levels_match_hand(level):
    a = _footprint_targeted(camera(level), 0.1, (0, -25, 25, 25))
    assert a == pytest.approx(HAND_M2[level], rel=0.02)


def test_identify_is_out_of_reach_on_the_ground_from_7_m():
    assert _footprint_targeted(camera("identify"), 0.1, (-10, -10, 10, 10)) == 0.0


def test_levels_nest_and_stop_at_the_hand_depth():
    """Each level's footprint inside the lower one's, strictly smaller, and every
    covered point no deeper than the level's hand depth (the grid's half cell)."""
    grid, caster = grid_of([Area("T", shapely.box(-5, -25, 25, 25))], 0.25)
    ev = TargetedEvaluator(grid, caster)
    xy = grid.xy(grid.target_cells)
    depth = xy[:, 0] * math.cos(math.radians(PITCH)) + H_M * math.sin(math.radians(PITCH))
    previous = None
    for level in ("detect", "observe", "recognise"):
        cov = set(ev.evaluate(camera(level), POSE).covered.tolist())
        assert cov
        assert depth[list(cov)].max() <= hand_depth(DORI_PX_PER_M[level]) + 1e-9
        if previous is not None:
            assert cov < previous
        previous = cov


def test_dori_area_covered_only_nearer_the_camera():
    """A 4K camera (f = 2288 px) reaches identify on the ground to the depth
    (2288.17^2 x 7 / 250^2)^(1/3) = 8.370 m. A target area with dori = "identify" is
    covered out to there and no further; the same area without dori (the model's own
    level, detect) is covered far beyond; a neighbouring area without dori keeps it."""
    uhd = replace(camera("detect"), resolution_px=(3840, 2160)).validated("4K")
    f = 1920 / math.tan(math.radians(40))
    d_identify = hand_depth(250.0, f)
    assert d_identify == pytest.approx(8.370, abs=1e-3)
    gate = Area("Gate", shapely.box(0, -10, 30, 0), dori="identify")
    road = Area("Road", shapely.box(0, 0, 30, 10))
    grid, caster = grid_of([gate, road], 0.25)
    depth_of = lambda o: (  # noqa: E731
        grid.xy(grid.target_cells[o])[:, 0] * math.cos(math.radians(PITCH))
        + H_M * math.sin(math.radians(PITCH))
    )
    for ev in (TargetedEvaluator(grid, caster), PointcloudEvaluator(grid, caster, oversample=2)):
        cov = ev.evaluate(uhd, POSE).covered
        in_gate = grid.target_region[cov] == 0
        slack = 0.5 if ev.method == "pointcloud" else 1e-9  # the alpha shape's edge
        assert in_gate.sum() > 50
        assert depth_of(cov[in_gate]).max() <= d_identify + slack
        assert depth_of(cov[~in_gate]).max() > d_identify + 5  # the road: detect
    # Without dori the gate is covered as deep as the road.
    plain, caster2 = grid_of([Area("Gate", gate.geometry), road], 0.25)
    cov = TargetedEvaluator(plain, caster2).evaluate(uhd, POSE).covered
    assert depth_of(cov[plain.target_region[cov] == 0]).max() > d_identify + 5
    # And the issue's 1080p camera cannot identify there at all from 7 m.
    assert not np.any(
        grid.target_region[TargetedEvaluator(grid, caster).evaluate(camera(), POSE).covered] == 0
    )


@pytest.mark.parametrize(
    "model",
    [
        PAPER_CAMERA,
        ROADSIDE_LIDAR,
        TRAFFIC_RADAR,
        replace(CCTV_CAMERA, resolution_px=None, min_px_per_m=0.0),
    ],
    ids=["paper_camera", "lidar", "radar", "pinhole_without_resolution"],
)
@pytest.mark.parametrize("evaluator", ["targeted", "cached", "pointcloud"])
def test_no_resolution_cannot_cover_a_dori_point(model, evaluator):
    """A model without a resolution covers the plain area and nothing of the one that
    asks for detect, the lowest level."""
    grid, caster = grid_of(
        [
            Area("Plain", shapely.box(0, -30, 40, 0)),
            Area("Dori", shapely.box(0, 0, 40, 30), dori="detect"),
        ],
        1.0,
        reach=max(model.range_m, 50.0),
    )
    pitch = min(max(20.0, model.pitch_min_deg), model.pitch_max_deg)
    pose = SensorPose(0.0, 0.0, 7.0, 7.0, pitch, 0.0)
    ev = {
        "targeted": TargetedEvaluator(grid, caster),
        "cached": CachedTargetedEvaluator(grid, caster),
        "pointcloud": PointcloudEvaluator(grid, caster),
    }[evaluator]
    cov = ev.evaluate(model, pose).covered
    assert np.sum(grid.target_region[cov] == 0) > 20
    assert not np.any(grid.target_region[cov] == 1)
    if evaluator == "cached":
        assert len(ev.reachable(model, pose, np.ones(grid.n_targets, bool))) > 0
        got = ev.reachable(model, pose, grid.target_region == 1)
        assert len(got) == 0


BOXES = [((8, -3, 0), (9, 3, 2.5)), ((15, 4, 0), (17, 9, 4)), ((-12, -8, 0), (-9, -2, 3))]


@pytest.mark.parametrize("target_height_m", [0.0, 0.5])
def test_targeted_and_cached_agree_bit_for_bit(target_height_m):
    """Occluders, three target areas (none, recognise, identify), a 4K and a 1080p
    camera, many orientations per position: the same points and chi, bit for bit, also
    through cover_many; the cached one casts fewer rays."""
    targets = [
        Area("Plain", shapely.box(-30, -30, 30, 0)),
        Area("Rec", shapely.box(-30, 0, 0, 30), dori="recognise"),
        Area("Ident", shapely.box(0, 0, 30, 30), dori="identify"),
    ]
    grid, caster = grid_of(targets, 0.5, BOXES, target_height_m=target_height_m)
    uhd = replace(camera("detect"), resolution_px=(3840, 2160)).validated("4K")
    direct, cached = TargetedEvaluator(grid, caster), CachedTargetedEvaluator(grid, caster)
    rng = np.random.default_rng(5)
    rays_direct = rays_cached = 0
    regions = set()
    for x, y in np.round(rng.uniform(-20, 20, (4, 2))):
        for model in (uhd, camera("observe")):
            rots, singles = [], []
            for _ in range(8):
                pitch = rng.uniform(model.pitch_min_deg, model.pitch_max_deg)
                pose = place(grid, x, y, 4.0, pitch, rng.uniform(0, 360))
                a, b = direct.evaluate(model, pose), cached.evaluate(model, pose)
                assert np.array_equal(a.covered, b.covered)
                assert np.array_equal(a.chi, b.chi)
                rays_direct += a.rays
                rays_cached += b.rays
                regions |= set(grid.target_region[a.covered].tolist())
                rots.append(frame(pose.pitch_deg, pose.yaw_deg))
                singles.append(np.sort(a.covered))
            many, ordinal = cached.cover_many(model, pose, np.array(rots))
            for row, single in zip(many, singles):
                assert np.array_equal(np.sort(ordinal[row]), single)
    assert regions == {0, 1, 2}  # every requirement was met somewhere
    assert rays_cached < rays_direct


def test_reference_footprint_is_the_best_hand_footprint_over_pitch():
    """reference_footprint_m2 (the largest over the pitch range, 1 deg steps) for the
    observe level against the closed form's maximum over the same pitches."""
    model = camera("observe")
    pitches = np.arange(model.pitch_min_deg, model.pitch_max_deg + 1e-9, 1.0)
    hand = max(hand_area(62.0, pitch=p) for p in pitches)
    assert reference_footprint_m2(model, 0.25) == pytest.approx(hand, rel=0.02)


# --- fields, files and validation -------------------------------------------------


def test_fields_round_trip_and_old_models_write_what_they_did():
    d = CCTV_CAMERA.to_dict()
    assert d["resolution_px"] == [1920, 1080] and d["min_px_per_m"] == 25.0
    assert SensorModel.from_spec(d, "x") == CCTV_CAMERA
    assert PRESETS["cctv_camera"] is CCTV_CAMERA
    for model in (PAPER_CAMERA, ROADSIDE_LIDAR, TRAFFIC_RADAR):
        assert "resolution_px" not in model.to_dict()
        assert "min_px_per_m" not in model.to_dict()
    named = SensorModel.from_spec({"preset": "cctv_camera", "min_px_per_m": "Recognize"}, "x")
    assert named.min_px_per_m == 125.0
    assert hash(named) == hash(SensorModel.from_spec(named.to_dict(), "x"))


def test_sensors_file_and_toml_accept_the_keys(tmp_path):
    spec = {
        "kind": "camera", "h_fov_deg": 80, "v_fov_deg": 50.534, "range_m": 50,
        "mount_height_m": 7, "pitch_min_deg": 15, "pitch_max_deg": 60, "rays_h": 192,
        "rays_v": 108, "min_density_per_m2": 0, "pattern": "pinhole",
        "resolution_px": [1920, 1080], "min_px_per_m": "recognise",
    }  # fmt: skip
    specs = parse_sensors(
        {"model": spec, "sensors": [{"x": 0, "y": 0, "pitch_deg": 40, "yaw_deg": 0}]}, "s.json"
    )
    assert specs[0].model == camera("recognise")
    cfg = tmp_path / "c.toml"
    cfg.write_text(
        '[model]\npreset = "cctv_camera"\nresolution_px = [3840, 2160]\nmin_px_per_m = 62\n'
    )
    _, model = load_config(cfg)
    assert model.resolution_px == (3840, 2160) and model.min_px_per_m == 62.0
    cfg.write_text('[model]\npreset = "roadside_lidar"\nmin_px_per_m = "detect"\n')
    with pytest.raises(InputError, match=r"c.toml: model: min_px_per_m 25 needs resolution_px"):
        load_config(cfg)


@pytest.mark.parametrize(
    "override, message",
    [
        ({"resolution_px": [1920]}, r"resolution_px must be \[width, height\]"),
        ({"resolution_px": "1920x1080"}, r"resolution_px must be \[width, height\]"),
        ({"resolution_px": [1920.5, 1080]}, r"resolution_px width must be a whole number"),
        ({"resolution_px": [0, 1080]}, r"resolution_px width 0 must be in \[1, 50,000\]"),
        ({"resolution_px": [1920, 60_000]}, r"resolution_px height 60000 must be in"),
        ({"resolution_px": [True, 1080]}, r"resolution_px width must be a number"),
        ({"resolution_px": [float("nan"), 1080]}, r"resolution_px width is nan"),
        ({"min_px_per_m": -1}, r"min_px_per_m -1 must be in \[0, 10,000\]"),
        ({"min_px_per_m": float("inf")}, r"min_px_per_m is inf"),
        ({"min_px_per_m": "ident"}, r"min_px_per_m must be px/m or a DORI level"),
        ({"min_px_per_m": None}, r"min_px_per_m must be a number"),
        ({"h_fov_deg": 60}, r"give square pixels at v_fov_deg 35.98, not 50.534"),
        ({"kind": "lidar"}, r"need kind camera with pattern pinhole, got kind lidar"),
        (
            {"pattern": "angular"},
            r"need kind camera with pattern pinhole, got kind camera with pattern angular",
        ),
        ({"resolution_px": None}, r"min_px_per_m 25 needs resolution_px"),
    ],
)
def test_validation_is_one_line(override, message):
    with pytest.raises(InputError, match=message) as err:
        SensorModel.from_spec({"preset": "cctv_camera", **override}, "f.json: model")
    assert str(err.value).startswith("f.json: model: ") and "\n" not in str(err.value)


def test_pixel_keys_refused_on_other_presets():
    for name in ("paper_camera", "roadside_lidar", "traffic_radar"):
        with pytest.raises(InputError, match="need kind camera with pattern pinhole"):
            SensorModel.from_spec({"preset": name, "resolution_px": [1920, 1080]}, "m")
