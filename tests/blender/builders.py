"""Small scene builders for tests: curves, boxes and planes made through bpy.data."""

from __future__ import annotations

import bpy


def curve(name, rings, cyclic=True, kind="POLY", z=0.0, collection=None):
    """A curve object with one spline per ring of (x, y) or (x, y, z) points."""
    data = bpy.data.curves.new(name, "CURVE")
    data.dimensions = "3D"
    for ring in rings:
        pts = [(p[0], p[1], p[2] if len(p) > 2 else z) for p in ring]
        if kind == "BEZIER":
            sp = data.splines.new("BEZIER")
            sp.bezier_points.add(len(pts) - 1)
            for bp, p in zip(sp.bezier_points, pts):
                bp.co = p
                bp.handle_left_type = bp.handle_right_type = "VECTOR"
        else:
            sp = data.splines.new(kind)
            sp.points.add(len(pts) - 1)
            for sp_pt, p in zip(sp.points, pts):
                sp_pt.co = (*p, 1.0)
        sp.use_cyclic_u = cyclic
    obj = bpy.data.objects.new(name, data)
    (collection or bpy.context.scene.collection).objects.link(obj)
    return obj


def rect(x0, y0, x1, y1):
    return [(x0, y0), (x1, y0), (x1, y1), (x0, y1)]


def mesh(name, verts, faces, collection=None):
    data = bpy.data.meshes.new(name)
    data.from_pydata([tuple(v) for v in verts], [], [tuple(f) for f in faces])
    data.update()
    obj = bpy.data.objects.new(name, data)
    (collection or bpy.context.scene.collection).objects.link(obj)
    return obj


def box(name, lo, hi, collection=None):
    """Axis-aligned closed box from corner ``lo`` to corner ``hi`` (outward normals)."""
    (x0, y0, z0), (x1, y1, z1) = lo, hi
    v = [
        (x0, y0, z0),
        (x1, y0, z0),
        (x1, y1, z0),
        (x0, y1, z0),
        (x0, y0, z1),
        (x1, y0, z1),
        (x1, y1, z1),
        (x0, y1, z1),
    ]
    f = [(0, 3, 2, 1), (4, 5, 6, 7), (0, 1, 5, 4), (1, 2, 6, 5), (2, 3, 7, 6), (3, 0, 4, 7)]
    return mesh(name, v, f, collection)


def plane(name, x0, y0, x1, y1, z=0.0, collection=None):
    return mesh(
        name, [(x0, y0, z), (x1, y0, z), (x1, y1, z), (x0, y1, z)], [(0, 1, 2, 3)], collection
    )


def flat_wall_scene():
    """The flat_wall sample's contract geometry, built in the current file."""
    plane("Ground", -60, -60, 60, 60)
    curve("Target_Area", [rect(0, -25, 50, 25)])
    curve("SensorArea_1", [rect(-12, -4, -4, 4)])
    box("Wall", (10.0, -2.0, 0.0), (10.3, 8.0, 3.0))
