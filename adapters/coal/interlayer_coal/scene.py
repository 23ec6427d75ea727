"""A collision scene of named primitive shapes and queries for a moving rigid body.

Poses are 4x4 homogeneous transforms; ``planar(x, y, theta, z)`` builds one for 2D domains.
Each object is static or movable; a query reports which movable objects a body touches, which is
what the interface layer turns into ``Obstructs`` facts.
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import coal
import numpy as np


def planar(x: float, y: float, theta: float, z: float = 0.0) -> np.ndarray:
    c, s = math.cos(theta), math.sin(theta)
    return np.array([[c, -s, 0, x], [s, c, 0, y], [0, 0, 1, z], [0, 0, 0, 1.0]])


def _transform(T: np.ndarray) -> coal.Transform3s:
    return coal.Transform3s(np.ascontiguousarray(T[:3, :3]), np.ascontiguousarray(T[:3, 3]))


@dataclass
class Shape:
    """A primitive with a pose relative to its body: kind "box" (full sizes) or "cylinder"."""

    kind: str
    dims: tuple
    local: np.ndarray

    def geometry(self):
        if self.kind == "box":
            return coal.Box(*self.dims)
        if self.kind == "cylinder":
            return coal.Cylinder(*self.dims)
        raise ValueError(self.kind)

    @property
    def radius(self) -> float:
        """Bounding-sphere radius about the shape's own centre, for a cheap pre-filter."""
        if self.kind == "box":
            return 0.5 * math.sqrt(sum(d * d for d in self.dims))
        r, h = self.dims
        return math.sqrt(r * r + 0.25 * h * h)


class Body:
    """Shapes that move together (a gripper with fingers, a held block)."""

    def __init__(self, shapes: list[Shape]):
        self.shapes = shapes
        self.objects = [coal.CollisionObject(s.geometry()) for s in shapes]
        self.radii = [s.radius for s in shapes]

    def place(self, T: np.ndarray) -> list[np.ndarray]:
        centres = []
        for shape, obj in zip(self.shapes, self.objects):
            W = T @ shape.local
            obj.setTransform(_transform(W))
            centres.append(W[:3, 3])
        return centres


class CollisionScene:
    """Named bodies; ``margin`` pads every collision test (plan with a margin, validate without)."""

    def __init__(self, margin: float = 0.0):
        self.bodies: dict[str, Body] = {}
        self.poses: dict[str, np.ndarray] = {}
        self.movable: dict[str, bool] = {}
        self._request = coal.CollisionRequest()
        self._request.security_margin = margin
        self.margin = margin
        self._index = None  # flat arrays of every shape's centre and radius, rebuilt lazily
        self._reach = {}  # id(body) -> (body, margin, squared centre distances below which shapes may touch)

    def add(self, name: str, shapes: list[Shape], pose: np.ndarray, movable: bool) -> None:
        self.bodies[name] = Body(shapes)
        self.movable[name] = movable
        self._reach = {}
        self.set_pose(name, pose)

    def set_pose(self, name: str, pose: np.ndarray) -> None:
        self.poses[name] = np.asarray(pose, float)
        self.bodies[name].place(self.poses[name])
        self._index = None

    def names(self, movable: bool | None = None) -> list[str]:
        return [n for n, m in self.movable.items() if movable is None or m == movable]

    def _build_index(self):
        owners, objects, centres, radii = [], [], [], []
        for name, body in self.bodies.items():
            for shape, obj, r in zip(body.shapes, body.objects, body.radii):
                owners.append(name)
                objects.append(obj)
                centres.append((self.poses[name] @ shape.local)[:3, 3])
                radii.append(r)
        self._index = (owners, objects, np.array(centres).reshape(-1, 3), np.array(radii))

    def hits(self, body: Body, pose: np.ndarray, skip=(), movables: bool = True, first: bool = False) -> set:
        """Names of scene objects that ``body`` at ``pose`` collides with (stop at one if ``first``)."""
        if self._index is None:
            self._build_index()
        owners, objects, centres, radii = self._index
        mine = np.array(body.place(pose))
        cached = self._reach.get(id(body))
        if cached is None or cached[0] is not body or cached[1] != self.margin:  # fixed until a body is added
            reach = (np.array(body.radii)[:, None] + radii[None, :] + self.margin) ** 2  # (a planner's hot path)
            cached = self._reach[id(body)] = (body, self.margin, reach)
        reach = cached[2]
        d = mine[:, None, :] - centres[None, :, :]
        close = np.nonzero(np.einsum("ijk,ijk->ij", d, d) <= reach)
        found = set()
        for i, j in zip(*close):
            name = owners[j]
            if name in found or name in skip or (not movables and self.movable[name]):
                continue
            if coal.collide(body.objects[i], objects[j], self._request, coal.CollisionResult()):
                found.add(name)
                if first:
                    break
        return found

    def distances(self, body: Body, pose: np.ndarray, margin: float, skip=(), movables: bool = True) -> dict:
        """Signed distances (negative when penetrating; the scene's own margin is not subtracted) from
        each shape of ``body`` at ``pose`` to each scene shape closer than ``margin``:
        ``{(body shape index, object name, scene shape index): distance}``."""
        if self._index is None:
            self._build_index()
        owners, objects, centres, radii = self._index
        mine = np.array(body.place(pose))
        reach = (np.array(body.radii)[:, None] + radii[None, :] + margin) ** 2
        d = mine[:, None, :] - centres[None, :, :]
        close = np.nonzero(np.einsum("ijk,ijk->ij", d, d) <= reach)
        request, out = coal.DistanceRequest(), {}
        for i, j in zip(*close):
            name = owners[j]
            if name in skip or (not movables and self.movable[name]):
                continue
            dist = coal.distance(body.objects[i], objects[j], request, coal.DistanceResult())
            if dist < margin:
                out[int(i), name, int(j)] = float(dist)
        return out

    def bodies_collide(self, a: Body, pose_a, b: Body, pose_b) -> bool:
        a.place(pose_a)
        b.place(pose_b)
        return any(coal.collide(oa, ob, self._request, coal.CollisionResult()) for oa in a.objects for ob in b.objects)
