"""coverage.png: the matplotlib map (title, legend, axes, scale bar, pixels where the
world geometry says they must be, determinism) and the occluder outline behind its
grey shapes, against numbers worked out by hand."""

import io
import struct
import subprocess
import sys
from types import SimpleNamespace

import matplotlib.image
import numpy as np
import pytest
import shapely
import shapely.affinity
from matplotlib.colors import to_rgb
from shapely.geometry import MultiPolygon, Polygon, box

from autoscoop_blender.core.evaluate import evaluate_layout
from autoscoop_blender.core.geom.outline import occluder_outline
from autoscoop_blender.core.geom.raycast import BoxCaster
from autoscoop_blender.core.model.scene import Area, SceneModel
from autoscoop_blender.core.model.sensors import PAPER_CAMERA, SensorSpec
from autoscoop_blender.core.result import MastRecord, Result, SensorRecord
from autoscoop_blender.core.settings import CoverageSettings
from autoscoop_blender.io import figure as cm
from tests.conftest import ROOT
from tests.core.flat import box_mesh

# ---------------------------------------------------------------------- a hand-made plan
#
# Target 100 m x 20 m at (0..100, 0..20), target points on a 1 m grid (centres 0.5 ..
# 99.5), covered left of x = 50: 1000 of 2000 points, 50.0 %, 1,000 m^2 uncovered.
# Sensor area (40..50, 25..35). Footprint: the left half of the road plus a strip
# off the road (0..20, -8..-2). Two masts: n=2 at (45, 30), n=1 at (48, 26). One
# occluder, a building (60..70, 25..35) on white ground. The view box is everything
# but the occluder, 10 m around: x -10..110, y -18..45 (120 m x 63 m); the scale bar
# is the largest 1/2/5 x 10^n m not over 120 / 5 = 24 m: 20 m.
# Cost: 3 per mast, 1 per sensor: 2 x 3 + 1 = 7 >= bound 5, gap (7 - 5) / 7 = 28.6 %.

FOOTPRINT = MultiPolygon([box(0, 0, 50, 20), box(0, -8, 20, -2)])
# Listed out of order: a number taken from the position in the tuple would show.
MASTS = ((2, 45.0, 30.0), (1, 48.0, 26.0))
BUILDING = box(60, 25, 70, 35)
LP = SimpleNamespace(optimizer="lp", rho=0.97, objective="cost", mast_cost=3.0, sensor_cost=1.0)


def _sensor(n, footprint, x=0.0, y=0.0, mast=0):
    return SensorRecord(
        n=n, x=x, y=y, z=7.0, height_m=7.0, pitch_deg=40.0, yaw_deg=0.0, model=PAPER_CAMERA,
        mast=mast, fitness=0.0, epochs=0, covered_target_m2=0.0, footprint_m2=footprint.area,
        footprint=footprint,
    )  # fmt: skip


def _grid_points(nx=100, ny=20):
    gx, gy = np.meshgrid(np.arange(nx) + 0.5, np.arange(ny) + 0.5)
    return np.column_stack([gx.ravel(), gy.ravel(), np.zeros(gx.size)])


def plan(**changes) -> Result:
    points = _grid_points()
    covered = (points[:, 0] < 50).astype(np.int32)
    fields = dict(
        sensors=(_sensor(1, FOOTPRINT, 45.0, 30.0),),
        masts=tuple(MastRecord(n, x, y, 0.0, 7.0, (1,)) for n, x, y in MASTS),
        targets=(("Target_Road", box(0, 0, 100, 20)),),
        sensor_areas=(("SensorArea_1", box(40, 25, 50, 35)),),
        points=points,
        n_visible=covered,
        n_covered=covered,
        cell_m=1.0,
        metrics={
            "coverage_fraction": 0.5,
            "covered_m2": 1000.0,
            "target_area_m2": 2000.0,
            "sensors": 1,
            "masts": 2,
            "objective": 7.0,
            "cost": 7.0,
            "lower_bound": 5.0,
            "gap": 0.2857,
        },  # fmt: skip
        uncovered=({"target": "Target_Road", "m2": 1000.0, "x": 75.0, "y": 10.0},),
        scene="hand_made.blend",
        settings=LP,
        model=PAPER_CAMERA,
        occluder_outlines=(BUILDING,),
    )
    fields.update(changes)
    return Result(**fields)


def texts(fig) -> list[str]:
    return [t.get_text() for t in fig.texts]


def legend_labels(fig) -> list[str]:
    (legend,) = fig.legends
    return [t.get_text() for t in legend.get_texts()]


class Drawn:
    """The PNG a user gets, decoded, with the figure's world -> pixel transform."""

    def __init__(self, result, **kw):
        self.fig = cm.coverage_figure(result, **kw)
        self.fig.canvas.draw()
        self.ax = self.fig.axes[0]
        self.png = cm.render_png(result, **kw)
        rgba = matplotlib.image.imread(io.BytesIO(self.png), format="png")
        self.img = np.round(rgba[..., :3] * 255).astype(int)

    def at(self, x, y):
        """(R, G, B) 0..255 of the pixel holding world (x, y)."""
        col, row_up = self.ax.transData.transform((x, y))
        return tuple(self.img[int(self.img.shape[0] - row_up), int(col)])

    def px_per_m(self):
        (x0, y0), (x1, y1) = self.ax.transData.transform([(0.0, 0.0), (1.0, 1.0)])
        return x1 - x0, y1 - y0


def rgb255(colour):
    return np.array(to_rgb(colour)) * 255


def close(pixel, expected, tol=2.0):
    return np.abs(np.asarray(pixel, float) - np.asarray(expected, float)).max() <= tol


@pytest.fixture(scope="module")
def drawn():
    return Drawn(plan())


# -------------------------------------------------------------------- title and legend


def test_title_names_the_scene_and_states_the_plan_in_numbers(drawn):
    lines = texts(drawn.fig)
    assert lines[0] == "hand_made.blend"
    assert lines[1] == (
        "1 sensor on 2 masts  ·  coverage 50.0 % of 2,000 m²  ·  "
        "cost 7 ≥ lower bound 5 (gap 28.6 %)"
    )
    assert "lp optimizer, coverage goal 97 %" in lines[2]
    assert "cost = 3 per mast + 1 per sensor" in lines[2]
    assert "camera 80° × 80°, 80 m range" in lines[2]


def test_title_says_when_no_bound_was_proven_and_an_evaluation_has_no_objective():
    fig = cm.coverage_figure(plan(metrics={**plan().metrics, "lower_bound": None, "gap": None}))
    assert texts(fig)[1].endswith("cost 7, no lower bound")
    evaluated = {"coverage_fraction": 0.5, "target_area_m2": 2000.0, "sensors": 1, "masts": 2}
    fig = cm.coverage_figure(plan(metrics=evaluated, settings=SimpleNamespace(method="targeted")))
    assert texts(fig)[1] == "1 sensor on 2 masts  ·  coverage 50.0 % of 2,000 m²"
    assert "bound" not in " ".join(texts(fig)) and "evaluated layout" in texts(fig)[2]


def test_legend_names_every_layer_with_its_count(drawn):
    labels = legend_labels(drawn.fig)
    expected = [
        "target area: roads to watch (2,000 m²)",
        "target covered by a sensor",
        "target not covered: 1,000 m² (50.0 %)",
        "sensor footprints (1)",
        "sensor area: where masts may stand (1)",
        "masts (2), numbered as in\nsensors.csv",
        "occluders: buildings, walls,\ntrees (top view)",
    ]
    assert len(labels) == len(expected)
    for label, start in zip(labels, expected, strict=True):
        assert label.startswith(start), (label, start)


def test_legend_leaves_out_what_the_result_does_not_have():
    bare = plan(occluder_outlines=(), masts=(), sensors=(), sensor_areas=())
    labels = " ".join(legend_labels(cm.coverage_figure(bare)))
    for absent in ("occluders", "masts", "footprints", "sensor area", "covered by a sensor"):
        assert absent not in labels


# -------------------------------------------------------------------- axes and scale


def test_axes_are_world_metres_east_and_north_at_equal_scale(drawn):
    ax = drawn.ax
    assert ax.get_xlim() == pytest.approx((-10.0, 110.0))
    assert ax.get_ylim() == pytest.approx((-18.0, 45.0))
    assert ax.get_xlabel() == "x east [m]" and ax.get_ylabel() == "y north [m]"
    sx, sy = drawn.px_per_m()
    assert sx == pytest.approx(sy, rel=1e-3)  # equal aspect, north up (sy > 0)
    assert sy > 0
    # The axes box has the view's aspect: no blank strip beside the map.
    bbox = ax.get_window_extent()
    assert bbox.width / bbox.height == pytest.approx(120 / 63, rel=1e-3)


def test_the_image_is_the_requested_width_and_the_png_is_what_the_figure_draws(drawn):
    width, height = struct.unpack(">II", drawn.png[16:24])
    assert drawn.png[:8] == b"\x89PNG\r\n\x1a\n" and width == 1200
    assert drawn.img.shape[:2] == (height, width)
    canvas = np.asarray(drawn.fig.canvas.buffer_rgba())[..., :3].astype(int)
    np.testing.assert_array_equal(canvas, drawn.img)


def test_scale_bar_is_20_m_long_and_says_so(drawn):
    (bar,) = [a for a in drawn.ax.artists if hasattr(a, "size_bar")]
    assert bar.txt_label.get_text() == "20 m"
    (rect,) = bar.size_bar.get_children()
    assert rect.get_width() == pytest.approx(20.0)
    # In the picture: the longest run of black pixels in the lower-left corner of the
    # map is 20 m long.
    sx, _ = drawn.px_per_m()
    bbox = drawn.ax.get_window_extent()
    h = drawn.img.shape[0]
    # (inside the frame: the axes' own black spines are left out)
    corner = drawn.img[
        int(h - bbox.y0 - 60) : int(h - bbox.y0 - 4), int(bbox.x0 + 4) : int(bbox.x0 + 300)
    ]
    black = np.all(corner < 40, axis=2)
    longest = max(_longest_run(row) for row in black)
    assert abs(longest - 20 * sx) <= 2


def _longest_run(mask):
    best = run = 0
    for v in mask:
        run = run + 1 if v else 0
        best = max(best, run)
    return best


@pytest.mark.parametrize(
    "width_m, length, label",
    [(120.0, 20.0, "20 m"), (250.0, 50.0, "50 m"), (40.0, 5.0, "5 m"), (1000.0, 200.0, "200 m"),
     (5000.0, 1000.0, "1 km"), (12000.0, 2000.0, "2 km"), (3.0, 0.5, "0.5 m")],
)  # fmt: skip
def test_scale_bar_lengths(width_m, length, label):
    assert cm.scale_bar_length(width_m) == pytest.approx(length)
    assert cm.length_label(cm.scale_bar_length(width_m)) == label
    assert cm.length_label(2500.0) == "2.5 km"


# --------------------------------------------------------------------------- pixels


def test_footprint_is_translucent_blue_over_the_road_and_over_white(drawn):
    a = cm.FOOTPRINT_ALPHA
    on_road = (1 - a) * rgb255(cm.TARGET_FILL) + a * rgb255(cm.FOOTPRINT_FILL)
    off_road = (1 - a) * rgb255(cm.BACKGROUND) + a * rgb255(cm.FOOTPRINT_FILL)
    for x, y in [(25.0, 10.0), (5.0, 15.0), (44.0, 4.0)]:
        assert close(drawn.at(x, y), on_road), (x, y, drawn.at(x, y))
    assert close(drawn.at(10.0, -5.0), off_road), drawn.at(10.0, -5.0)
    # Blue dominates, and the footprint is not the uncovered colour.
    r, g, b = drawn.at(10.0, -5.0)
    assert b > r and b > g


def test_uncovered_points_are_the_warning_colour(drawn):
    for x, y in [(75.2, 10.3), (50.6, 0.7), (99.0, 19.0), (60.0, 5.0)]:
        assert drawn.at(x, y) == tuple(np.round(rgb255(cm.UNCOVERED)).astype(int)), (x, y)
    assert not close(drawn.at(25.0, 10.0), rgb255(cm.UNCOVERED), tol=60)


def test_occluder_is_grey_where_the_building_stands(drawn):
    grey = tuple(np.round(rgb255(cm.OCCLUDER_FILL)).astype(int))
    assert grey[0] == grey[1] == grey[2]
    for x, y in [(65.0, 30.0), (61.5, 26.5), (68.5, 33.5)]:
        assert drawn.at(x, y) == grey, (x, y)
    assert drawn.at(72.3, 31.7) == (255, 255, 255)  # beside it: plain ground
    assert drawn.at(105.3, 42.3) == (255, 255, 255)


def test_sensor_area_is_light_violet(drawn):
    assert close(drawn.at(41.5, 33.5), rgb255(cm.SENSOR_AREA_FILL))


def test_masts_are_numbered_discs_where_the_masts_stand(drawn):
    marks = {t.get_text(): t for t in drawn.ax.texts if t.get_gid() and "mast" in t.get_gid()}
    assert sorted(marks) == ["1", "2"]
    fill = rgb255(cm.MAST_FILL)
    for n, x, y in MASTS:
        mark = marks[str(n)]
        assert mark.get_position() == (x, y)
        # The disc is drawn there: dark pixels around the point, none 3 m west.
        col, row_up = drawn.ax.transData.transform((x, y))
        row, col = int(drawn.img.shape[0] - row_up), int(col)
        disc = drawn.img[row - 5 : row + 6, col - 5 : col + 6]
        assert np.all(np.abs(disc - fill) <= 2, axis=2).mean() > 0.3, n
        assert not close(drawn.at(x - 3.0, y), fill, tol=30)


def test_the_largest_gap_is_labelled_with_its_area(drawn):
    labels = [t for t in drawn.ax.texts if t.get_text().endswith("m²")]
    assert [t.get_text() for t in labels] == ["1,000 m²"]
    assert labels[0].xy == (75.0, 10.0)


# ----------------------------------------------------------------------- k coverage
#
# k = 2 on the same road: columns x < 25 covered by 0 sensors, 25..50 by 1, 50..75 by
# 2, 75..100 by 3 (3 counts as "2 or more"): 25 % each, 50 % covered twice or more.


def k_plan(**changes):
    points = _grid_points()
    n = (points[:, 0] // 25).astype(np.int32)
    return plan(n_covered=n, n_visible=n, **changes)


def test_k_coverage_colours_points_by_their_count():
    d = Drawn(k_plan(), k_required=2)
    colours = cm.k_colours(2)
    assert len(colours) == 3 and colours[0] == cm.UNCOVERED and len(set(colours)) == 3
    expected = [np.round(rgb255(c)).astype(int) for c in (colours[0], colours[1], colours[2])]
    for x, level in [(10.3, 0), (30.3, 1), (60.3, 2), (90.3, 2)]:
        assert tuple(d.at(x, 10.3)) == tuple(expected[level]), (x, level)
    assert "covered by ≥ 2 sensors: 50.0 %" in texts(d.fig)[1]
    labels = legend_labels(d.fig)
    assert "target covered by 0 sensors (25.0 %)" in labels
    assert "target covered by 1 sensor (25.0 %)" in labels
    assert "target covered by 2 sensors or more (50.0 %)" in labels
    assert not any(label.startswith("target not covered") for label in labels)


def test_k_is_read_from_the_settings_when_not_given():
    settings = SimpleNamespace(**vars(LP), k=3)
    labels = legend_labels(cm.coverage_figure(k_plan(settings=settings)))
    assert "target covered by 3 sensors or more (25.0 %)" in labels
    assert "target covered by 2 sensors (25.0 %)" in labels
    plain = legend_labels(cm.coverage_figure(k_plan()))
    assert not any("covered by 2" in label for label in plain)


# ----------------------------------------------------------------- robustness, bytes


def test_same_result_same_bytes_and_no_software_stamp():
    first, second = cm.render_png(plan()), cm.render_png(plan())
    assert first == second
    assert b"Software" not in first and b"matplotlib" not in first.lower()


def test_an_empty_result_still_renders_a_map():
    empty = Result(
        sensors=(), masts=(), targets=(), sensor_areas=(), points=np.zeros(0),
        n_visible=np.zeros(0, np.int32), n_covered=np.zeros(0, np.int32), cell_m=1.0,
    )  # fmt: skip
    png = cm.render_png(empty)
    assert png[:8] == b"\x89PNG\r\n\x1a\n"
    assert texts(cm.coverage_figure(empty))[1] == "0 sensors on 0 masts  ·  coverage 0.0 %"


def test_points_and_counts_must_match():
    with pytest.raises(ValueError):
        cm.render_png(plan(n_covered=np.zeros(3, np.int32)))


def test_a_far_away_scene_keeps_its_coordinates_on_the_axes():
    """Georeferenced: x = 500,000 m. The map is drawn where the scene is, with plain
    tick labels (no offset), and the same pixels as at the origin."""
    dx, dy = 500_000.0, 4_000_000.0

    def moved(g):
        return shapely.affinity.translate(g, dx, dy)

    far = plan(
        sensors=(_sensor(1, moved(FOOTPRINT), 45.0 + dx, 30.0 + dy),),
        masts=tuple(MastRecord(n, x + dx, y + dy, 0.0, 7.0, (1,)) for n, x, y in MASTS),
        targets=(("Target_Road", moved(box(0, 0, 100, 20))),),
        sensor_areas=(("SensorArea_1", moved(box(40, 25, 50, 35))),),
        points=_grid_points() + (dx, dy, 0.0),
        uncovered=({"target": "Target_Road", "m2": 1000.0, "x": 75.0 + dx, "y": 10.0 + dy},),
        occluder_outlines=(moved(BUILDING),),
    )
    d = Drawn(far)
    assert d.ax.get_xlim() == pytest.approx((dx - 10.0, dx + 110.0))
    labels = [t.get_text() for t in d.ax.get_xticklabels()]
    assert any(label.startswith("5000") for label in labels), labels
    assert d.ax.xaxis.get_offset_text().get_text() == ""
    grey = tuple(np.round(rgb255(cm.OCCLUDER_FILL)).astype(int))
    assert d.at(65.0 + dx, 30.0 + dy) == grey
    assert d.at(75.2 + dx, 10.3 + dy) == tuple(np.round(rgb255(cm.UNCOVERED)).astype(int))


def test_the_addon_side_imports_no_matplotlib():
    """The add-on registers without matplotlib: importing the report modules (and the
    pipeline's core) must not pull it in; only drawing does."""
    code = (
        "import sys, autoscoop_blender.io.figure, autoscoop_blender.core.result; "
        "sys.exit('matplotlib' in sys.modules)"
    )
    subprocess.run([sys.executable, "-c", code], check=True, cwd=ROOT)


# ------------------------------------------------------------------ occluder outline


def _ground(half=40.0, z=0.0, cells=1):
    """A square ground grid of (cells x cells) quads at height z (or z(x, y))."""
    xs = np.linspace(-half, half, cells + 1)
    gx, gy = np.meshgrid(xs, xs)
    zz = z(gx, gy) if callable(z) else np.full(gx.shape, z)
    verts = np.column_stack([gx.ravel(), gy.ravel(), zz.ravel()])
    idx = np.arange(len(verts)).reshape(cells + 1, cells + 1)
    a, b, c, d = (
        idx[:-1, :-1].ravel(),
        idx[:-1, 1:].ravel(),
        idx[1:, 1:].ravel(),
        idx[1:, :-1].ravel(),
    )
    faces = np.concatenate([np.column_stack([a, b, c]), np.column_stack([a, c, d])])
    return verts, faces.astype(np.int32)


def _merge(*meshes):
    verts, faces, offset = [], [], 0
    for v, f in meshes:
        verts.append(v)
        faces.append(f + offset)
        offset += len(v)
    return np.concatenate(verts), np.concatenate(faces).astype(np.int32)


def test_outline_of_a_box_on_a_ground_plane_is_its_footprint():
    # Box 10 m x 6 m x 4 m standing on a 80 m x 80 m plane (two triangles).
    ground = _ground()
    house = box_mesh([((5.0, -3.0, 0.0), (15.0, 3.0, 4.0))])
    (outline,) = occluder_outline(*_merge(ground, house))
    assert outline.area == pytest.approx(60.0)
    assert outline.symmetric_difference(box(5, -3, 15, 3)).area < 1e-9
    # The ground plane alone, or the box alone lying flat (0.3 m high), draws nothing.
    assert occluder_outline(*ground) == ()
    kerb = box_mesh([((5.0, -3.0, 0.0), (15.0, 3.0, 0.3))])
    assert occluder_outline(*_merge(ground, kerb)) == ()


def test_outline_leaves_hilly_terrain_and_a_road_surface_out():
    def hills(x, y):
        return 6.0 * np.exp(-((x - 10) ** 2 + y**2) / 200.0) - 3.0 * np.exp(-(x**2) / 50.0)

    terrain = _ground(cells=40, z=hills)
    assert occluder_outline(*terrain) == ()
    # A road mesh laid 5 cm over the terrain is not an occluder either.
    road_v, road_f = _ground(half=10.0, cells=10, z=lambda x, y: hills(x, y) + 0.05)
    assert occluder_outline(*_merge(terrain, (road_v, road_f))) == ()


def test_outline_of_a_building_sunk_into_sloping_terrain_is_its_footprint():
    """The sample scenes' buildings: floor 0.5 m under the lowest ground point, on a
    slope, on a 2 m terrain grid whose triangles cross the building's walls."""

    def slope(x, y):
        return 0.2 * x + 0.1 * y

    terrain = _ground(half=40.0, cells=40, z=slope)
    lo, hi = (3.3, -4.7), (17.1, 5.9)
    floor = slope(lo[0], lo[1]) - 0.5
    house = box_mesh([((*lo, floor), (*hi, floor + 8.0))])
    (outline,) = occluder_outline(*_merge(terrain, house))
    assert outline.symmetric_difference(box(*lo, *hi)).area < 1e-6


def test_outline_draws_walls_and_canopies_over_the_ground_and_drops_vertical_planes():
    ground = _ground()
    wall = box_mesh([((-20.0, 10.0, -0.4), (0.0, 10.3, 3.0))])  # 20 m x 0.3 m
    # A canopy: an octahedron, radius 3 m, centred 5 m over (20, 20); its top view
    # is a square with diagonals of 6 m: 18 m^2.
    c = np.array([20.0, 20.0, 5.0])
    canopy_v = c + np.array([[3, 0, 0], [-3, 0, 0], [0, 3, 0], [0, -3, 0], [0, 0, 2], [0, 0, -2]])
    canopy_f = np.array(
        [[0, 2, 4], [2, 1, 4], [1, 3, 4], [3, 0, 4], [2, 0, 5], [1, 2, 5], [3, 1, 5], [0, 3, 5]]
    )
    # A zero-thickness vertical plane (a fence drawn as one quad) projects to a line.
    fence_v = np.array(
        [[-30.0, -30.0, 0.0], [-10.0, -30.0, 0.0], [-10.0, -30.0, 2.0], [-30.0, -30.0, 2.0]]
    )
    fence_f = np.array([[0, 1, 2], [0, 2, 3]])
    parts = occluder_outline(*_merge(ground, wall, (canopy_v, canopy_f), (fence_v, fence_f)))
    assert len(parts) == 2
    assert parts[0].area == pytest.approx(18.0) and parts[0].centroid.coords[0] == pytest.approx(
        (20.0, 20.0)
    )
    assert parts[1].symmetric_difference(box(-20.0, 10.0, 0.0, 10.3)).area < 1e-9


def test_outline_of_empty_or_all_vertical_meshes_is_empty():
    assert occluder_outline(np.zeros((0, 3)), np.zeros((0, 3), np.int32)) == ()
    fence_v = np.array([[0.0, 0.0, 0.0], [5.0, 0.0, 0.0], [5.0, 0.0, 2.0]])
    assert occluder_outline(fence_v, np.array([[0, 1, 2]], np.int32)) == ()


def test_an_evaluated_result_carries_the_outline_in_world_coordinates():
    """finish_layout fills Result.occluder_outlines: a hut on the implicit floor of a
    scene whose local origin is (500 km, 4000 km)."""
    hut = ((30.0, 8.0, 0.0), (34.0, 12.0, 4.0))
    origin = np.array([500_000.0, 4_000_000.0, 0.0])
    vertices, faces = box_mesh([hut])
    scene = SceneModel(
        vertices=vertices,
        faces=faces,
        occluders=("Hut",),
        targets=(Area("Target_Road", box(0, -7, 60, 7)),),
        sensor_areas=(Area("SensorArea_N", box(0, 10, 60, 14)),),
        origin=origin,
    )
    spec = SensorSpec(PAPER_CAMERA, 500_020.0, 4_000_012.0, 7.0, 40.0, 270.0)
    result = evaluate_layout(scene, BoxCaster([hut], ground_z=0.0), [spec], CoverageSettings())
    (outline,) = result.occluder_outlines
    assert outline.symmetric_difference(box(500_030, 4_000_008, 500_034, 4_000_012)).area < 1e-6
    fig = cm.coverage_figure(result)
    assert "occluders: buildings, walls,\ntrees (top view)" in legend_labels(fig)


def test_a_polygon_with_a_hole_keeps_the_hole_open():
    """A courtyard building: the yard inside is not grey."""
    ring = Polygon(box(60, 25, 70, 35).exterior.coords, [box(63, 28, 67, 32).exterior.coords])
    d = Drawn(plan(occluder_outlines=(ring,)))
    assert d.at(65.3, 31.3) == (255, 255, 255)
    assert d.at(61.0, 26.0) == tuple(np.round(rgb255(cm.OCCLUDER_FILL)).astype(int))


def test_a_users_matplotlib_settings_do_not_change_the_picture():
    """Inside Blender a user's matplotlibrc may set anything: the map is drawn and
    saved in matplotlib's default style all the same."""
    import matplotlib

    plain = cm.render_png(plan())
    odd = {"axes.facecolor": "black", "savefig.facecolor": "red", "font.size": 30,
           "savefig.bbox": "tight", "lines.linewidth": 9, "axes.grid": False}  # fmt: skip
    with matplotlib.rc_context(odd):
        assert cm.render_png(plan()) == plain


@pytest.mark.parametrize("size", [(20.0, 600.0), (2000.0, 15.0)])
def test_tall_and_wide_scenes_keep_equal_scale_and_the_legend_beside_the_map(size):
    w, h = size
    result = plan(
        targets=(("Target", box(0, 0, w, h)),), sensor_areas=(), sensors=(), masts=(),
        points=np.array([[w / 2, h / 2, 0.0]]), n_covered=np.zeros(1, np.int32),
        n_visible=np.zeros(1, np.int32), uncovered=(), occluder_outlines=(),
    )  # fmt: skip
    d = Drawn(result)
    sx, sy = d.px_per_m()
    assert sx == pytest.approx(sy, rel=1e-3)
    assert d.ax.get_xlim() == pytest.approx((-10.0, w + 10.0))
    assert d.ax.get_ylim() == pytest.approx((-10.0, h + 10.0))
    (legend,) = d.fig.legends
    renderer = d.fig.canvas.get_renderer()
    assert legend.get_window_extent(renderer).x0 > d.ax.get_window_extent().x1
    assert d.img.shape[1] == 1200 and d.img.shape[0] <= 1.6 * 1200


def test_too_narrow_an_image_is_refused():
    with pytest.raises(ValueError, match="width_px"):
        cm.render_png(plan(), width_px=500)
