"""Areas from curve rings: even-odd, validation, local origin."""

import numpy as np
import pytest

from autoscoop_blender.core.errors import SceneContractError
from autoscoop_blender.core.model.scene import area_from_rings, choose_origin


def ring(x0, y0, x1, y1, z=0.0):
    return np.array([(x0, y0, z), (x1, y0, z), (x1, y1, z), (x0, y1, z)], dtype=float)


def test_even_odd_gives_holes_and_islands():
    outer, hole, island = ring(0, 0, 100, 100), ring(20, 20, 80, 80), ring(40, 40, 60, 60)
    geom = area_from_rings("Target_Loop", [outer, hole, island])
    assert geom.area == pytest.approx(100**2 - 60**2 + 20**2)
    assert not geom.contains(__import__("shapely").Point(30, 30))
    assert geom.contains(__import__("shapely").Point(50, 50))


def test_closing_point_and_duplicates_are_tolerated():
    r = ring(0, 0, 10, 10)
    closed = np.vstack([r, r[:1], r[:1]])
    assert area_from_rings("T", [closed]).area == pytest.approx(100.0)


def test_a_ring_following_terrain_is_still_in_the_xy_plane():
    r = ring(0, 0, 200, 20)
    r[:, 2] = [0.0, 6.0, 4.0, -2.0]  # a road over a hill
    assert area_from_rings("T", [r]).area == pytest.approx(4000.0)


@pytest.mark.parametrize(
    "rings, message",
    [
        ([np.array([(0, 0, 0), (10, 10, 0), (10, 0, 0), (0, 10, 0)], float)], "crosses itself"),
        (
            [np.array([(0, 0, 0), (10, 0, 0), (10, 0, 10), (0, 0, 10)], float)],
            "not in the XY plane",
        ),
        ([np.array([(0, 0, 0), (10, 0, 0)], float)], "at least 3 points"),
        ([np.array([(0, 0, 0), (5, 0, 0), (10, 0, 0)], float)], "encloses no area"),
        ([ring(0, 0, 10, 10), ring(0, 0, 10, 10)], "empty"),
        ([], "no splines"),
    ],
)
def test_bad_rings_name_the_curve(rings, message):
    with pytest.raises(SceneContractError, match=rf"^Target_X.*{message}"):
        area_from_rings("Target_X", rings)


def test_local_origin_only_for_large_coordinates():
    small = np.array([[0, 0, 0], [250, 250, 10]], float)
    assert np.array_equal(choose_origin(small), np.zeros(3))
    big = small + [500_000.0, 6_400_000.0, 0.0]
    origin = choose_origin(big)
    assert origin[2] == 0 and np.abs(big[:, :2] - origin[:2]).max() < 1000


def test_the_grid_carries_each_target_areas_requirements():
    from dataclasses import replace

    import shapely

    from autoscoop_blender.core.geom.grid import GroundGrid
    from autoscoop_blender.core.geom.raycast import BoxCaster
    from autoscoop_blender.core.model.scene import Area
    from tests.core.flat import flat_scene

    junction = Area("Target_Junction", shapely.box(0, 0, 4, 4), coverage_k=2, dori="recognise")
    lidar_lane = Area("Target_Lane", shapely.box(10, 0, 12, 4), require="lidar")
    scene = replace(flat_scene(), targets=(junction, lidar_lane))
    grid = GroundGrid(scene, BoxCaster(ground_z=0.0), 1.0, reach_m=10.0)
    assert list(grid.region_k) == [2, 0]
    assert list(grid.region_px_per_m) == [125.0, 0.0]
    assert list(grid.region_kind) == [-1, 1]  # KINDS = camera, lidar, radar
    # Per point through target_region: 16 cells of the junction, 8 of the lane.
    k = grid.region_k[grid.target_region]
    assert list(k) == [2] * 16 + [0] * 8
    again = GroundGrid.from_arrays(grid.arrays(), BoxCaster(ground_z=0.0))
    # Cells are ordered by x first: the junction's, then the lane's; so in a worker.
    assert list(again.region_kind[again.target_region]) == [-1] * 16 + [1] * 8


def test_targets_fingerprint_names_the_targets_in_world_metres():
    """The same targets give the same fingerprint whatever the occluders, the sensor
    areas or the local origin (the world coordinates are what count); another name,
    a target moved by 0.1 m or one more target give another."""
    from dataclasses import replace

    import shapely

    from tests.core.flat import flat_scene

    base = flat_scene(target=(0, 0, 50, 20)).targets_fingerprint()
    assert len(base) == 16 and int(base, 16) >= 0
    with_box = flat_scene(target=(0, 0, 50, 20), boxes=[((5, 5, 0), (6, 6, 3))])
    assert with_box.targets_fingerprint() == base
    assert flat_scene(target=(0, 0, 50, 20), sensor=(-9, -9, -5, -5)).targets_fingerprint() == base
    # Local coordinates 1000 m west of an origin at (1000, 0): the same world place.
    shifted = flat_scene(target=(-1000, 0, -950, 20))
    shifted = replace(shifted, origin=np.array([1000.0, 0.0, 0.0]))
    assert shifted.targets_fingerprint() == base
    assert flat_scene(target=(0.1, 0, 50.1, 20)).targets_fingerprint() != base
    scene = flat_scene(target=(0, 0, 50, 20))
    renamed = replace(scene, targets=(replace(scene.targets[0], name="Target_B"),))
    assert renamed.targets_fingerprint() != base
    more = replace(
        scene,
        targets=(
            *scene.targets,
            replace(scene.targets[0], name="T2", geometry=shapely.box(60, 0, 70, 5)),
        ),
    )
    assert more.targets_fingerprint() != base
