"""Collision meshes simplified at load: a mesh of more than MAX_TRIANGLES triangles is checked as its convex
hull. Vendors ship CAD-detailed collision meshes (the TIAGo Pro's: 113,000 triangles, 10,772 in one
fingertip; the PR2's: 5,800 in all), and a check against them costs in proportion. A hull contains its
mesh, so what is collision-free with hulls is collision-free with the meshes too."""
from __future__ import annotations

MAX_TRIANGLES = 1000


def hull_big_meshes(collision_model, limit: int = MAX_TRIANGLES) -> int:
    """Replace every mesh of more than ``limit`` triangles in ``collision_model`` by its convex hull;
    returns how many were replaced."""
    import coal

    n = 0
    for go in collision_model.geometryObjects:
        geom = go.geometry
        if isinstance(geom, coal.BVHModelBase) and geom.num_tris > limit:
            geom.buildConvexHull(True, "Qt")
            go.geometry = geom.convex
            n += 1
    return n
