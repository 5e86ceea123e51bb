"""``headless optimize --render`` and ``scene.render_view``: the oblique view shows the
results in their colours, and rendering it leaves no trace in result.blend or in the
open session."""

import bpy
import numpy as np
import pytest

from autoscoop_blender.core.model.sensors import PRESETS
from autoscoop_blender.scene import render_view as rv
from autoscoop_blender.scene import spawn
from headless.cli import build_parser
from tests.cli.conftest import SAMPLES, run_headless

FLAT = SAMPLES / "flat_wall.blend"
SMALL = (480, 300)  # px: enough for 2 px lines, renders in about a second


@pytest.fixture(scope="module")
def runs(tmp_path_factory):
    """flat_wall optimized (greedy, about a second) without and with --render."""
    out = {}
    cfg = tmp_path_factory.mktemp("config") / "goal.toml"
    # greedy reaches 60 % on flat_wall (exit code 0). The sensors objective (mast
    # preference 0.1) keeps the sensors on masts apart, each pyramid seen on its own;
    # the cost objective (1) stacks all three on one mast.
    cfg.write_text('rho = 0.6\nobjective = "sensors"\n')
    for name, extra in (("plain", []), ("render", ["--render"])):
        folder = tmp_path_factory.mktemp(name)
        code, stdout, stderr = run_headless(
            "optimize", FLAT, "--optimizer", "greedy", "--config", cfg, "--workers", 1,
            "--out-dir", folder, *extra,
        )  # fmt: skip
        assert code == 0, stderr
        out[name] = folder, stdout, stderr
    return out


def _pixels(png_path):
    """(H, W, 3) sRGB bytes as floats in [0, 1], top row first."""
    image = bpy.data.images.load(str(png_path))
    w, h = image.size
    px = np.empty(w * h * 4, np.float32)
    image.pixels.foreach_get(px)
    bpy.data.images.remove(image)
    return px.reshape(h, w, 4)[::-1, :, :3]


def _chunk_types(png):
    types, at = [], 8
    while at < len(png):
        size = int.from_bytes(png[at : at + 4], "big")
        types.append(png[at + 4 : at + 8].decode("ascii"))
        at += 12 + size
    return types


def _near(px, rgb_linear, tol):
    """Pixels whose hue and saturation match a linear colour: each is decoded from
    sRGB and divided by its brightest channel, so the light's strength drops out."""
    lin = np.where(px <= 0.04045, px / 12.92, ((px + 0.055) / 1.055) ** 2.4)
    peak = lin.max(axis=-1, keepdims=True)
    ref = np.asarray(rgb_linear, float)
    ref = ref / ref.max()
    return (np.abs(lin / np.maximum(peak, 1e-6) - ref).max(axis=-1) < tol) & (peak[..., 0] > 0.1)


def _footprint_pixels(px):
    return int(_near(px, spawn.FOOTPRINT_RGBA[:3], 0.05).sum())


def _snapshot():
    """What a .blend holds: every datablock by kind and name, each object's type,
    collections and matrix, and the scene's camera, world and render settings."""
    data = {
        kind: sorted(i.name for i in getattr(bpy.data, kind))
        for kind in ("scenes", "objects", "meshes", "cameras", "materials", "worlds",
                     "collections", "images", "lights")
    }  # fmt: skip
    objects = {
        o.name: (
            o.type,
            sorted(c.name for c in o.users_collection),
            np.round(np.array(o.matrix_world), 6).tolist(),
            o.hide_render,
        )
        for o in bpy.data.objects
    }
    scene = bpy.context.scene
    layer = [(c.name, c.exclude) for c in scene.view_layers[0].layer_collection.children]
    camera = scene.camera.name if scene.camera else None
    world = scene.world.name if scene.world else None
    settings = (scene.render.engine, scene.render.resolution_x, scene.render.filepath)
    return data, objects, layer, camera, world, settings


def test_render_flag_is_an_option():
    parser = build_parser()
    assert parser.parse_args(["optimize", "--render"]).render is True
    assert parser.parse_args(["optimize"]).render is False


def test_render_writes_a_view_of_the_results(runs):
    plain, _, _ = runs["plain"]
    folder, _, stderr = runs["render"]
    assert not (plain / "result_view.png").exists()
    png = folder / "result_view.png"
    data = png.read_bytes()
    assert data[:8] == b"\x89PNG\r\n\x1a\n"
    assert "tEXt" not in _chunk_types(data)  # no metadata: the user's file path, the date
    # Timed, and Blender's chatter (EGL warnings, "Saved: ...") kept off the terminal.
    assert "result_view.png: 1600 x 1000 px, Workbench" in stderr
    assert "EGL" not in stderr and "Saved:" not in stderr

    px = _pixels(png)
    assert px.shape == (1000, 1600, 3)
    total = px.shape[0] * px.shape[1]
    # Footprint outlines in spawn's footprint colour (about 19k px here).
    assert _footprint_pixels(px) > 3000
    # The coverage map in its palette: flat_wall leaves the far side of the wall red.
    red = spawn.COVERAGE_PALETTE[0, :3]
    assert _near(px, red, 0.05).sum() > 0.01 * total
    # Not blank: no colour takes most of the picture, and there are many colours.
    colours, counts = np.unique((px * 255).round().astype(np.uint8).reshape(-1, 3),
                                axis=0, return_counts=True)  # fmt: skip
    assert counts.max() < 0.5 * total and len(colours) > 1000


def test_render_leaves_result_blend_as_without_it(runs):
    snapshots = []
    for name in ("plain", "render"):
        folder, _, _ = runs[name]
        written = [p.name for p in folder.iterdir() if p.suffix != ".png"]
        assert sorted(n for n in written if n != ".autoscoop.lock") == [
            "checkpoint.jsonl", "result.blend", "result.json", "sensors.csv",
            "sensors_local.geojson",
        ]  # fmt: skip
        bpy.ops.wm.open_mainfile(filepath=str(folder / "result.blend"))
        snapshots.append(_snapshot())
    assert snapshots[0] == snapshots[1]
    data, objects, _, camera, _, _ = snapshots[1]
    assert camera is None and data["scenes"] == ["Scene"] and not data["images"]
    assert not [n for n in objects if n.startswith(rv.VIEW_NAME)]


def test_render_view_leaves_the_session_as_it_was(runs):
    folder, _, _ = runs["plain"]
    bpy.ops.wm.open_mainfile(filepath=str(folder / "result.blend"))
    scene = bpy.context.scene
    before = _snapshot()
    png = rv.render_view(scene, SMALL)
    assert png[:8] == b"\x89PNG\r\n\x1a\n"
    assert _snapshot() == before
    assert bpy.context.scene == scene and scene.camera is None


def test_hidden_footprints_are_not_drawn(runs, tmp_path):
    """The footprint colour in the view comes from the footprints: hide their group
    (as the panel's toggle does) and it is gone."""
    folder, _, _ = runs["plain"]
    bpy.ops.wm.open_mainfile(filepath=str(folder / "result.blend"))
    scene = bpy.context.scene
    counts = []
    for hide in (False, True):
        bpy.data.collections[spawn.FOOTPRINTS_COLLECTION].hide_render = hide
        path = tmp_path / f"hide_{hide}.png"
        path.write_bytes(rv.render_view(scene, SMALL))
        counts.append(_footprint_pixels(_pixels(path)))
    assert counts[0] > 300 and counts[1] < counts[0] / 20


@pytest.mark.parametrize("preset", [None, "roadside_lidar"])
def test_sensors_are_drawn_as_dark_pyramids(runs, tmp_path, preset):
    """The sensors show (as spawn's cameras or as 360 deg lidars); hiding their group
    hides them."""
    folder, _, _ = runs["plain"]
    bpy.ops.wm.open_mainfile(filepath=str(folder / "result.blend"))
    sensors = bpy.data.collections[spawn.SENSORS_COLLECTION]
    if preset is not None:
        for cam in sensors.objects:
            cam[spawn.MODEL_PROP] = PRESETS[preset].to_dict()
    dark = []
    for hide in (False, True):
        sensors.hide_render = hide
        path = tmp_path / f"hide_{hide}.png"
        path.write_bytes(rv.render_view(bpy.context.scene, SMALL))
        dark.append(int((_pixels(path).max(axis=-1) < 0.2).sum()))
    assert dark[0] > 100 and dark[1] < dark[0] / 10


def test_render_view_needs_results():
    bpy.ops.wm.open_mainfile(filepath=str(FLAT))
    with pytest.raises(ValueError, match="no results"):
        rv.render_view(bpy.context.scene, SMALL)
