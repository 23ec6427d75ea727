"""Articulated environment bodies (a cabinet with a drawer, a door, ...) as Pinocchio models.

An ``ArticulatedBody`` is a fixed-base Pinocchio model built from a URDF string, placed in the world,
with 1-DOF joints (prismatic or revolute). Its collision elements (boxes, cylinders) become objects
of a :class:`CollisionWorld` named ``<body>/<link>/<k>``; ``update(cw, values)`` runs forward
kinematics and moves them. Things resting on a link (an object in a drawer) move with it:
``carry(pose, link, from_values, to_values)``.

>>> body = ArticulatedBody("cabinet", urdf_xml, placement)      # doctest: +SKIP
>>> body.add_to(cw, body.zero())                                 # doctest: +SKIP
>>> body.update(cw, [0.25]); body.link_pose([0.25], "drawer")    # doctest: +SKIP
"""

from __future__ import annotations

from dataclasses import dataclass

import coal
import numpy as np
import pinocchio as pin

from .joints import as_matrix, as_se3

__all__ = ["ArticulatedBody", "Shape"]


@dataclass(frozen=True)
class Shape:
    """One collision element: ``kind`` "box" (size = full edges) or "cylinder" (radius, height)."""

    name: str  # <body>/<link>/<k>
    link: str
    kind: str
    size: tuple
    joint: int  # Pinocchio joint the element moves with (0: the body's fixed base)
    local: np.ndarray  # 4x4 pose in that joint's frame


class ArticulatedBody:
    """A fixed-base articulated environment body; joint values are one float per joint (m or rad)."""

    def __init__(self, name: str, urdf_xml: str, placement=np.eye(4)):
        self.name = name
        self.placement = as_matrix(placement)
        self.model = pin.buildModelFromXML(urdf_xml)
        self.data = self.model.createData()
        gm = pin.buildGeomFromUrdfString(self.model, urdf_xml, pin.GeometryType.COLLISION)
        self.joint_names = tuple(self.model.names[j] for j in range(1, self.model.njoints))
        if any(self.model.joints[j].nq != 1 for j in range(1, self.model.njoints)):
            raise ValueError(f"{name}: only 1-DOF joints (prismatic, revolute) are supported")
        self.lower = np.array(self.model.lowerPositionLimit, dtype=float)
        self.upper = np.array(self.model.upperPositionLimit, dtype=float)
        self.shapes: list[Shape] = []
        counts: dict = {}
        for go in gm.geometryObjects:
            link = self.model.frames[go.parentFrame].name
            k = counts[link] = counts.get(link, -1) + 1
            geom = go.geometry
            if isinstance(geom, coal.Box):
                kind, size = "box", tuple(float(2 * h) for h in geom.halfSide)
            elif isinstance(geom, coal.Cylinder):
                kind, size = "cylinder", (float(geom.radius), float(2 * geom.halfLength))
            else:
                raise ValueError(f"{name}: collision geometry of {link} must be a box or a cylinder")
            self.shapes.append(Shape(f"{name}/{link}/{k}", link, kind, size, int(go.parentJoint),
                                     go.placement.homogeneous.copy()))

    # -- kinematics ---------------------------------------------------------------------------
    def zero(self) -> np.ndarray:
        return np.zeros(self.model.nq)

    def check(self, values) -> np.ndarray:
        v = np.asarray(values, dtype=float).reshape(-1)
        if v.shape != (self.model.nq,):
            raise ValueError(f"{self.name}: expected {self.model.nq} joint values, got {v.shape[0]}")
        if np.any(v < self.lower - 1e-9) or np.any(v > self.upper + 1e-9):
            raise ValueError(f"{self.name}: joint values {v.tolist()} outside [{self.lower.tolist()}, {self.upper.tolist()}]")
        return v

    def _fk(self, values) -> None:
        pin.forwardKinematics(self.model, self.data, self.check(values))

    def link_pose(self, values, link: str) -> np.ndarray:
        """World pose (4x4) of ``link`` at joint ``values``."""
        fid = self.model.getFrameId(link)
        if fid >= self.model.nframes:
            raise KeyError(f"{self.name}: unknown link {link!r}")
        self._fk(values)
        return self.placement @ pin.updateFramePlacement(self.model, self.data, fid).homogeneous

    def shape_poses(self, values) -> dict:
        """World pose (4x4) of every collision element at joint ``values``."""
        self._fk(values)
        return {s.name: self.placement @ self.data.oMi[s.joint].homogeneous @ s.local for s in self.shapes}

    def moving_shapes(self, joint: str | None = None) -> list[Shape]:
        """Elements that move when ``joint`` (default: any joint) moves."""
        if joint is None:
            return [s for s in self.shapes if s.joint > 0]
        jid = self.model.getJointId(joint)
        return [s for s in self.shapes if s.joint > 0 and jid in self.model.supports[s.joint]]

    def carry(self, pose, link: str, from_values, to_values) -> np.ndarray:
        """Where a pose fixed to ``link`` goes when the joints move from ``from_values`` to ``to_values``."""
        return self.link_pose(to_values, link) @ np.linalg.inv(self.link_pose(from_values, link)) @ as_matrix(pose)

    # -- collision world -----------------------------------------------------------------------
    def add_to(self, cw, values, padding: float = 0.0, only=None, skip=(), color=(0.6, 0.5, 0.4, 1.0)) -> None:
        """Add the collision elements (all, or those named in ``only``, minus ``skip``) to ``cw`` as fixed
        objects grown by ``padding`` on every side."""
        poses = self.shape_poses(values)
        for s in self.shapes:
            if (only is not None and s.name not in only) or s.name in skip:
                continue
            if s.kind == "box":
                cw.add_box(s.name, tuple(v + 2 * padding for v in s.size), poses[s.name], color=color)
            else:
                cw.add_cylinder(s.name, s.size[0] + padding, s.size[1] + 2 * padding, poses[s.name], color=color)

    def update(self, cw, values) -> None:
        """Move the elements in ``cw`` to joint ``values`` (cheap: no rebuild)."""
        poses = self.shape_poses(values)
        for s in self.shapes:
            if s.joint > 0:
                cw.set_pose(s.name, poses[s.name])

    def touching(self, cw, values, objects, shapes=None) -> set:
        """Which of ``objects`` (names in ``cw``, not held) the moving elements touch at ``values``."""
        poses = self.shape_poses(values)
        request, hits = coal.CollisionRequest(), set()
        for s in shapes or self.moving_shapes():
            tf = _tf(poses[s.name])
            geom = cw.geometry(s.name)
            for name in objects:
                if name in hits:
                    continue
                result = coal.CollisionResult()
                if coal.collide(geom, tf, cw.geometry(name), _tf(cw.pose(name)), request, result):
                    hits.add(name)
        return hits


def _tf(T) -> coal.Transform3s:
    se3 = as_se3(T)
    return coal.Transform3s(se3.rotation, se3.translation)


def box_link_urdf(name: str, boxes, origin=None) -> str:
    """A URDF ``<link>`` with one box collision element per ``(size, (x, y, z))`` in ``boxes``."""
    parts = [f'<link name="{name}">']
    for size, xyz in boxes:
        parts.append(f'<collision><origin xyz="{xyz[0]:.6g} {xyz[1]:.6g} {xyz[2]:.6g}"/>'
                     f'<geometry><box size="{size[0]:.6g} {size[1]:.6g} {size[2]:.6g}"/></geometry></collision>')
    parts.append('<inertial><mass value="1"/><inertia ixx="0.01" iyy="0.01" izz="0.01" ixy="0" ixz="0" iyz="0"/></inertial>')
    parts.append("</link>")
    return "".join(parts)
