"""The ground grid holds cells only within reach of the areas (``core/geom/grid.py``):
its memory against arithmetic on the tiles and chunks, every public answer against a
dense reference worked out here, and footprints that do not depend on what else the
scene holds."""

import math

import numpy as np
import shapely
from scipy import ndimage

from autoscoop_blender.core import budget
from autoscoop_blender.core.coverage.targeted import TargetedEvaluator
from autoscoop_blender.core.geom.grid import GroundGrid
from autoscoop_blender.core.geom.raycast import BoxCaster
from autoscoop_blender.core.model.sensors import PAPER_CAMERA, SensorPose
from autoscoop_blender.core.result import uncovered_parts
from tests.core.flat import areas_scene

TILE, CHUNK = 32, 64  # lattice cells a tile side, flat indices a chunk


def held_mask_by_hand(scene, lattice, g, reach):
    """(nx, ny) the cells of every tile whose ground (its cells' squares) lies within
    ``reach`` of an area: one distance per tile, on a dense mask."""
    x0, y0, nx, ny = lattice
    areas = [a.geometry for a in (*scene.targets, *scene.sensor_areas)]
    mask = np.zeros((nx, ny), dtype=bool)
    for ti in range(math.ceil(nx / TILE)):
        for tj in range(math.ceil(ny / TILE)):
            i0, i1 = ti * TILE, min(ti * TILE + TILE, nx)
            j0, j1 = tj * TILE, min(tj * TILE + TILE, ny)
            ground = shapely.box(x0 + i0 * g, y0 + j0 * g, x0 + i1 * g, y0 + j1 * g)
            if min(ground.distance(a) for a in areas) <= reach:
                mask[i0:i1, j0:j1] = True
    return mask


def held_chunks_mask(scene, lattice, g, reach):
    """(ceil(nx * ny / 64),) the chunks of 64 consecutive flat indices a grid holds:
    those with a cell of ``held_mask_by_hand`` in them."""
    flat = held_mask_by_hand(scene, lattice, g, reach).ravel()
    flat = np.concatenate([flat, np.zeros(-len(flat) % CHUNK, dtype=bool)])
    return flat.reshape(-1, CHUNK).any(axis=1)


def held_by_hand(scene, lattice, g, reach):
    """(nx * ny,) whether the grid holds each cell (its chunk is held)."""
    _, _, nx, ny = lattice
    return np.repeat(held_chunks_mask(scene, lattice, g, reach), CHUNK)[: nx * ny]


def held_chunks_by_hand(scene, lattice, g, reach):
    """How many chunks the grid holds."""
    return int(held_chunks_mask(scene, lattice, g, reach).sum())


def resident(grid):
    """Bytes of the grid's per-cell arrays and its table of chunks."""
    a = grid.arrays()
    per_cell = a.dist.nbytes + a.z.nbytes + a.normal.nbytes + grid._target_ordinal.nbytes
    return per_cell + a.chunk_offset.nbytes


# Two 20 m squares 5 km apart, each with a sensor area inside it.
SQUARE_A, SQUARE_B = shapely.box(0, 0, 20, 20), shapely.box(5000, 0, 5020, 20)
MAST_A, MAST_B = shapely.box(8, 8, 12, 12), shapely.box(5008, 8, 5012, 12)


def test_two_far_squares_hold_a_small_fraction_of_their_bounds():
    scene = areas_scene([SQUARE_A, SQUARE_B], [MAST_A, MAST_B])
    grid = GroundGrid(scene, BoxCaster(ground_z=0.0), 1.0, reach_m=80.0)
    # Bounds (0, 0)-(5020, 20) padded by 80 + 2 m: x0 = y0 = -82, 5184 x 184 cells.
    assert (grid.x0, grid.y0, grid.nx, grid.ny) == (-82.0, -82.0, 5184, 184)
    dense = 5184 * 184 * 24  # dist, z, normal, ordinal over the whole lattice
    # Tiles of 32 m from -82 m. Near A the tiles' distances to [0, 20] along x are
    # 50, 18, 0, 0, 26, 58 m (tiles 0-5; tile 6 is 90 m off), along y the same (tiles
    # 0-5, the last one 24 cells); all within 80 m but tile (5, 5) (82 m). Held cells:
    # rows 0-159 whole, rows 160-191 columns 0-159. Their 24-cell gaps hold no whole
    # chunk, so flat indices 0 to 191 * 184 + 159 = 35,303: chunks 0-551, 552 of them.
    # B mirrors it: tiles 156-161 (58, 26, 0, 0, 18, 50 m) without (156, 5): rows
    # 4992-5023 columns 0-159, rows 5024-5183 whole, flat 918,528 (chunk 14,352) to
    # the last, 953,855 (chunk 14,903): 552 chunks.
    assert held_chunks_by_hand(scene, (-82.0, -82.0, 5184, 184), 1.0, 80.0) == 1104
    assert grid.held_cells == 1104 * 64 == 70_656
    table = math.ceil(5184 * 184 / 64) * 4  # one int32 per chunk of the lattice
    assert resident(grid) == 70_656 * 24 + table == 1_755_360
    assert resident(grid) < 0.08 * dense  # 7.7 % of 22.9 MB
    est = budget.estimate_grid(scene, 1.0, 80.0)
    assert est.grid_cells == 70_656
    per_point = budget.TARGET_POINT_BYTES + budget.TARGET_TREE_BYTES
    assert est.grid_bytes == resident(grid) + grid.n_targets * per_point
    assert grid.n_targets == 2 * 400


# A small scene for the dense reference: a slanted quadrilateral and a box that
# overlaps it (cells in both belong to the first), a sensor area apart from them, and
# a 3 m box on the ground.
SLANTED = shapely.Polygon([(0, 0), (40, 12), (37, 22), (-3, 10)])
OVERLAP = shapely.box(30, 0, 50, 8)
SENSOR = shapely.box(100, -50, 104, -46)
BLOCK = ((20.0, 20.0, 0.0), (26.0, 26.0, 3.0))
REACH = 30.0


def small_scene():
    return areas_scene([SLANTED, OVERLAP], [SENSOR], boxes=[BLOCK])


class DenseReference:
    """What the grid answered when it held every cell, worked out cell by cell: the
    lattice, target cells and areas, ordinals, distances to the nearest target centre
    and the surface under each centre."""

    def __init__(self, g):
        # Bounds (-3, -50)-(104, 22), padded by reach + 2 g.
        pad = REACH + 2 * g
        self.x0 = math.floor((-3 - pad) / g) * g
        self.y0 = math.floor((-50 - pad) / g) * g
        self.nx = math.ceil((104 + pad - self.x0) / g)
        self.ny = math.ceil((22 + pad - self.y0) / g)
        i, j = np.divmod(np.arange(self.nx * self.ny), self.ny)
        self.cx, self.cy = self.x0 + (i + 0.5) * g, self.y0 + (j + 0.5) * g
        in_slanted = shapely.contains_xy(SLANTED, self.cx, self.cy)
        in_overlap = shapely.contains_xy(OVERLAP, self.cx, self.cy)
        self.targets = np.flatnonzero(in_slanted | in_overlap)
        self.region = np.where(in_slanted[self.targets], 0, 1)
        self.ordinal = np.full(self.nx * self.ny, -1)
        self.ordinal[self.targets] = np.arange(len(self.targets))
        tx, ty = self.cx[self.targets], self.cy[self.targets]
        # Brute force over every target centre, m, kept as float32 (as the grid does).
        nearest = [((tx - x) ** 2 + (ty - y) ** 2).min() for x, y in zip(self.cx, self.cy)]
        self.dist = np.sqrt(nearest).astype(np.float32).astype(float)
        on_block = (self.cx > 20) & (self.cx < 26) & (self.cy > 20) & (self.cy < 26)
        self.z = np.where(on_block, 3.0, 0.0)

    def disk(self, centre, radius):
        d2 = (self.cx - centre[0]) ** 2 + (self.cy - centre[1]) ** 2
        return np.flatnonzero(d2 <= radius**2)


def test_every_answer_is_the_dense_grids():
    caster = BoxCaster(boxes=[BLOCK], ground_z=0.0)
    scene = small_scene()
    areas = shapely.union_all([SLANTED, OVERLAP, SENSOR])
    for g in (1.0, 0.5):
        ref = DenseReference(g)
        grid = GroundGrid(scene, caster, g, reach_m=REACH)
        assert (grid.x0, grid.y0, grid.nx, grid.ny) == (ref.x0, ref.y0, ref.nx, ref.ny)
        assert np.array_equal(grid.target_cells, ref.targets)
        assert np.array_equal(grid.target_region, ref.region)
        assert np.array_equal(grid.target_z, np.zeros(len(ref.targets)))
        lattice = (ref.x0, ref.y0, ref.nx, ref.ny)
        held = held_by_hand(scene, lattice, g, REACH)
        assert not held.all()  # some corners are let go
        chunks = held_chunks_by_hand(scene, lattice, g, REACH)
        assert grid.held_cells == budget.estimate_grid(scene, g, REACH).grid_cells == chunks * 64
        # A worker's copy answers the same (its own surface, the distances shared).
        worker = GroundGrid.from_arrays(grid.arrays(), caster)
        # Centres: in the sensor area, on the targets, on the block, beyond reach.
        centres = [(102, -48), (20, 10), (45, 4), (23, 23), (-30, -75), (130, 50), (60, -45)]
        for centre in centres:
            for radius in (REACH, 12.5):
                cells = grid.cells_in_disk(np.array(centre, dtype=float), radius)
                disk = ref.disk(centre, radius)
                # Only held cells, and every cell within reach of an area among them.
                assert np.array_equal(cells, disk[held[disk]])
                near = shapely.dwithin(areas, shapely.points(ref.cx[disk], ref.cy[disk]), REACH)
                assert np.isin(disk[near], cells).all()
                for gr in (grid, worker):
                    assert np.array_equal(gr.target_ordinal(cells), ref.ordinal[cells])
                    assert np.array_equal(gr.dist_to_target(cells), ref.dist[cells])
                    z, normals = gr.surface(cells)
                    assert np.array_equal(z, ref.z[cells])
                    assert np.array_equal(normals, np.tile((0.0, 0.0, 1.0), (len(cells), 1)))
                    xy = np.column_stack([ref.cx[cells], ref.cy[cells]])
                    assert np.array_equal(gr.xy(cells), xy)
        # Cells not held (none is ever in a disk) still get the dense grid's answers,
        # dropped anew each time.
        out = np.flatnonzero(~held)[::7]
        assert np.array_equal(grid.target_ordinal(out), np.full(len(out), -1))
        assert np.array_equal(grid.dist_to_target(out), ref.dist[out])
        rays = grid.drop_rays
        grid.ensure_dropped(out)
        assert grid.drop_rays == rays
        z, _ = grid.surface(out)
        assert np.array_equal(z, ref.z[out]) and grid.drop_rays == rays + len(out)


def test_a_footprint_does_not_depend_on_the_other_square():
    # Near each square, a sensor covers the same points and the same ground outside
    # the target whether the other square, 5 km away, is in the scene or not.
    both = areas_scene([SQUARE_A, SQUARE_B], [MAST_A, MAST_B])
    caster = BoxCaster(ground_z=0.0)
    far = TargetedEvaluator(GroundGrid(both, caster, 1.0, reach_m=80.0), caster)
    for square, mast, x in ((SQUARE_A, MAST_A, 10.0), (SQUARE_B, MAST_B, 5010.0)):
        alone = TargetedEvaluator(
            GroundGrid(areas_scene([square], [mast]), caster, 1.0, reach_m=80.0), caster
        )
        for pitch, yaw in ((30.0, 0.0), (45.0, 120.0), (60.0, 250.0)):
            pose = SensorPose(x, 10.0, 6.0, 6.0, pitch, yaw)
            a = far.evaluate(PAPER_CAMERA, pose, outside_band_m=math.inf, visibility=True)
            b = alone.evaluate(PAPER_CAMERA, pose, outside_band_m=math.inf, visibility=True)
            assert len(a.covered) > 50
            assert np.array_equal(far.grid.target_xy[a.covered], alone.grid.target_xy[b.covered])
            assert np.array_equal(a.chi, b.chi)
            assert np.array_equal(far.grid.target_xy[a.visible], alone.grid.target_xy[b.visible])
            assert np.array_equal(far.grid.xy(a.outside), alone.grid.xy(b.outside))
            assert a.footprint_m2 == b.footprint_m2 and a.rays == b.rays


def dense_parts(grid, uncovered, scene):
    """``uncovered_parts`` as it was: ``ndimage.label`` over the whole lattice."""
    mask = np.zeros(grid.nx * grid.ny, dtype=bool)
    mask[grid.target_cells[uncovered]] = True
    labels, count = ndimage.label(mask.reshape(grid.nx, grid.ny), structure=np.ones((3, 3)))
    flat = labels.ravel()[grid.target_cells]
    parts = []
    for k in range(1, count + 1):
        members = np.flatnonzero(flat == k)
        cx, cy = scene.to_world(grid.target_xy[members].mean(axis=0))
        region = int(np.bincount(grid.target_region[members]).argmax())
        name = scene.targets[region].name
        parts.append({"target": name, "m2": len(members) * grid.cell_area, "x": cx, "y": cy})
    return [
        {**p, "x": round(float(p["x"]), 2), "y": round(float(p["y"]), 2)}
        for p in sorted(parts, key=lambda p: -p["m2"])
    ]


def test_uncovered_parts_are_the_dense_labels():
    scene = small_scene()
    grid = GroundGrid(scene, BoxCaster(boxes=[BLOCK], ground_z=0.0), 1.0, reach_m=REACH)
    rng = np.random.default_rng(3)
    xy = grid.target_xy
    cases = [
        rng.random(grid.n_targets) < 0.3,  # many patches, some of one point, of equal m^2
        np.abs(xy[:, 0] - 20) < 4,  # one band across both areas
        (np.abs(xy[:, 0] - xy[:, 1]) < 1.0) | (xy[:, 0] > 45),  # a diagonal, touching corners
        np.ones(grid.n_targets, dtype=bool),
    ]
    for uncovered in cases:
        got = uncovered_parts(grid, uncovered, scene)
        assert got == dense_parts(grid, uncovered, scene)
        assert len(got) >= 1
    assert uncovered_parts(grid, np.zeros(grid.n_targets, dtype=bool), scene) == []
