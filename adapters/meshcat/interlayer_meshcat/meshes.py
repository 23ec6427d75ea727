"""Small numpy mesh utilities (no meshcat import).

* :func:`capsule_mesh` - triangulated capsule along z.
* :func:`simplify_mesh` - vertex-clustering decimation to a face budget.
* :func:`load_mesh` - any assimp-readable mesh file (STL/DAE/OBJ/...) as
  ``(vertices, faces)`` arrays via coal's mesh loader.
* :func:`coal_to_arrays` - vertices/faces of a coal ``BVHModel``/``Convex``.
"""

from __future__ import annotations

import numpy as np

__all__ = ["capsule_mesh", "simplify_mesh", "load_mesh", "coal_to_arrays", "mesh_bbox"]


def capsule_mesh(radius: float, length: float, segments: int = 24, rings: int = 6):
    """Capsule with its axis along z: cylinder part of ``length`` (coal's
    ``2*halfLength``) capped by hemispheres; centred at the origin.
    Returns ``(vertices float32 Nx3, faces uint32 Mx3)``."""
    h = length / 2.0
    # latitude angles from the north pole to the south pole, duplicated equator
    lat_top = np.linspace(0.0, np.pi / 2, rings + 1)
    lat_bot = np.linspace(np.pi / 2, np.pi, rings + 1)
    rows = [(np.sin(a), np.cos(a), +h) for a in lat_top] + [(np.sin(a), np.cos(a), -h) for a in lat_bot]
    theta = np.linspace(0.0, 2 * np.pi, segments, endpoint=False)
    verts = []
    for s, c, off in rows:
        for t in theta:
            verts.append((radius * s * np.cos(t), radius * s * np.sin(t), radius * c + off))
    verts = np.asarray(verts, dtype=np.float32)
    faces = []
    nrow = len(rows)
    for i in range(nrow - 1):
        for j in range(segments):
            a = i * segments + j
            b = i * segments + (j + 1) % segments
            c = (i + 1) * segments + j
            d = (i + 1) * segments + (j + 1) % segments
            faces.append((a, c, b))
            faces.append((b, c, d))
    faces = np.asarray(faces, dtype=np.int64)
    # drop degenerate faces at the poles (all pole vertices coincide)
    return _weld(verts, faces)


def _weld(vertices, faces, tol: float = 1e-9):
    """Merge coincident vertices and drop degenerate/duplicate faces."""
    v = np.asarray(vertices, dtype=np.float64)
    key = np.round(v / max(tol, 1e-12)).astype(np.int64)
    _, first, inv = np.unique(key, axis=0, return_index=True, return_inverse=True)
    inv = inv.reshape(-1)
    f = inv[np.asarray(faces, dtype=np.int64)]
    ok = (f[:, 0] != f[:, 1]) & (f[:, 1] != f[:, 2]) & (f[:, 0] != f[:, 2])
    f = f[ok]
    return v[first].astype(np.float32), f.astype(np.uint32)


def simplify_mesh(vertices, faces, max_faces: int):
    """Vertex-clustering decimation: returns ``(V, F)`` with at most
    ``max_faces`` faces (coarser grids until the budget is met). Cheap and
    robust, not pretty; good enough for thumbnails of robot links."""
    V = np.asarray(vertices, dtype=np.float64)
    F = np.asarray(faces, dtype=np.int64)
    if len(F) <= max_faces or len(V) == 0:
        return V.astype(np.float32), F.astype(np.uint32)
    vmin = V.min(axis=0)
    diag = float(np.linalg.norm(V.max(axis=0) - vmin)) or 1.0

    def cluster(cell):
        key = np.floor((V - vmin) / cell).astype(np.int64)
        _, inv, counts = np.unique(key, axis=0, return_inverse=True, return_counts=True)
        inv = inv.reshape(-1)
        nv = len(counts)
        newv = np.zeros((nv, 3))
        np.add.at(newv, inv, V)
        newv /= counts[:, None]
        f = inv[F]
        ok = (f[:, 0] != f[:, 1]) & (f[:, 1] != f[:, 2]) & (f[:, 0] != f[:, 2])
        f = f[ok]
        if len(f):
            # remove duplicate faces (same vertex set)
            _, idx = np.unique(np.sort(f, axis=1), axis=0, return_index=True)
            f = f[np.sort(idx)]
        return newv, f

    lo, hi = 0.0, diag
    best = cluster(hi)
    for _ in range(14):
        mid = 0.5 * (lo + hi)
        v, f = cluster(mid)
        if len(f) <= max_faces:
            best, hi = (v, f), mid
        else:
            lo = mid
    v, f = best
    used = np.unique(f.reshape(-1))
    remap = np.full(len(v), -1, dtype=np.int64)
    remap[used] = np.arange(len(used))
    return v[used].astype(np.float32), remap[f].astype(np.uint32)


def coal_to_arrays(geometry):
    """``(vertices float64 Nx3, faces int64 Mx3)`` of a coal BVHModel or Convex
    (already scaled: pinocchio applies ``meshScale`` when it loads meshes)."""
    if hasattr(geometry, "tri_indices"):
        V = np.array(geometry.vertices(), dtype=np.float64).reshape(-1, 3)
        n = geometry.num_tris
        tri = geometry.tri_indices
    elif hasattr(geometry, "polygons"):
        V = np.array(geometry.points(), dtype=np.float64).reshape(-1, 3)
        n = geometry.num_polygons
        tri = geometry.polygons
    else:
        raise TypeError(f"not a triangle geometry: {type(geometry).__name__}")
    F = np.empty((n, 3), dtype=np.int64)
    for i in range(n):
        t = tri(i)
        F[i, 0], F[i, 1], F[i, 2] = t[0], t[1], t[2]
    return V, F


def load_mesh(path, scale=1.0):
    """Read a mesh file with coal/assimp; returns ``(vertices, faces)``, scaled."""
    import coal  # lazy: heavy

    s = np.broadcast_to(np.asarray(scale, dtype=np.float64), (3,)).copy()
    bvh = coal.MeshLoader().load(str(path), s)
    return coal_to_arrays(bvh)


def mesh_bbox(vertices):
    v = np.asarray(vertices, dtype=np.float64).reshape(-1, 3)
    if len(v) == 0:
        return None
    return np.stack([v.min(axis=0), v.max(axis=0)])
