"""The two numpy reference casters agree with each other (independent algorithms)."""

import numpy as np

from autoscoop_blender.core.geom.raycast import BoxCaster, FloorCaster, TriangleCaster
from tests.core.flat import box_mesh

BOXES = [((0, 0, 0), (4, 2, 3)), ((10, -5, 0), (11, 5, 6)), ((-8, 3, 1), (-6, 9, 2))]


def test_slab_and_moller_trumbore_agree():
    rng = np.random.default_rng(0)
    n = 4000
    origins = rng.uniform([-15, -10, 0.5], [15, 10, 8], (n, 3))
    dirs = rng.normal(size=(n, 3))
    dirs /= np.linalg.norm(dirs, axis=1, keepdims=True)
    a_d, a_n = BoxCaster(BOXES).cast_normals(origins, dirs, 40.0)
    b_d, b_n = TriangleCaster(*box_mesh(BOXES)).cast_normals(origins, dirs, 40.0)
    assert np.isfinite(a_d).sum() > n // 10
    both = np.isfinite(a_d) & np.isfinite(b_d)
    assert np.array_equal(np.isfinite(a_d), np.isfinite(b_d))
    assert np.allclose(a_d[both], b_d[both], atol=1e-9)
    # Normals face the ray in both.
    assert (np.einsum("ij,ij->i", a_n[both], dirs[both]) <= 0).all()
    assert (np.einsum("ij,ij->i", b_n[both], dirs[both]) <= 0).all()


def test_floor_catches_downward_misses_only():
    inner = BoxCaster(BOXES)
    floor = FloorCaster(inner, -1.0)
    o = np.array([[20.0, 20.0, 5.0], [20.0, 20.0, 5.0], [2.0, 1.0, 10.0]])
    d = np.array([[0.0, 0.0, -1.0], [0.0, 0.0, 1.0], [0.0, 0.0, -1.0]])
    dist, normals = floor.cast_normals(o, d, 100.0)
    assert dist[0] == 6.0 and np.array_equal(normals[0], [0, 0, 1])
    assert np.isinf(dist[1])
    assert dist[2] == 7.0  # the box top comes first
    assert np.isinf(floor.cast(o[:1], d[:1], 5.0)[0])  # beyond max_dist
