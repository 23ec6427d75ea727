"""Distances between the robot and its world, for CollisionWorld (a mixin: it reads the world's built
geometry model, objects and robot): motion bounds, signed clearances with their gradients, and whether a
hand at a tool pose touches an object (no IK needed)."""

from __future__ import annotations

import math
from typing import Iterable

import coal
import numpy as np
import pinocchio as pin

__all__ = ["Distances"]


class Distances:
    """The distance queries of :class:`~interlayer_pinocchio.world.CollisionWorld`."""

    def motion_bound(self, group: str) -> float:
        """How much (m) the distance between the two bodies of any pair that ``group``'s checker checks
        can shrink per unit of group-vector distance (joint-space Euclidean, rad or m), anywhere: so a
        configuration clear of everything by ``margin`` has every configuration within ``margin / bound``
        of it collision-free. Infinite for joint types it does not know.

        A pair's relative pose changes only through the group joints between its bodies, and a point
        moved by revolute joint i moves at most rho_i per rad, rho_i bounding its distance from the
        joint's origin: the joint offsets down the chain to the body's joint plus the body's bounding
        sphere (held objects included). Cauchy-Schwarz turns sum(rho_i |dq_i|) into a bound on |dq|.
        A planar joint moves a point at most |d(x, y)| + rho |d theta|."""
        if self._needs_build:
            self._build()
        cached = self._bounds.get(group)
        if cached is not None and cached[0] == self._version:  # held objects change it
            return cached[1]
        model, supports = self._model, self._model.supports
        bodies = [(go.parentJoint, np.linalg.norm(go.placement.act(go.geometry.aabb_center)) + go.geometry.aabb_radius)
                  for go in self._gm.geometryObjects if go.parentJoint > 0]  # robot links and held objects
        total = 0.0
        for i in self.robot.group(group).joint_ids:
            rho = 0.0
            for j, extent in bodies:
                chain = list(supports[j])
                if i in chain:
                    offsets = sum(np.linalg.norm(model.jointPlacements[k].translation) for k in chain[chain.index(i) + 1:])
                    rho = max(rho, offsets + extent)
            kind = model.joints[i].shortname()
            if kind == "JointModelPlanar":
                total += 1.0 + rho * rho  # (|d(x, y)| + rho |d theta|)^2 <= (1 + rho^2) |d(x, y, theta)|^2
            elif kind.startswith("JointModelR"):  # revolute: RX..RZ, unbounded RUB*, RevoluteUnaligned
                total += rho * rho
            else:
                total = math.inf
        self._bounds[group] = (self._version, math.sqrt(total))
        return self._bounds[group][1]

    def clearances(self, q, group: str, margin: float, movables: bool = True,
                   ignore: Iterable[str] = frozenset()) -> dict[str, tuple[float, np.ndarray]]:
        """Signed distance and its gradient (w.r.t. ``group``'s vector) for every pair closer than
        ``margin`` of a body ``group`` moves (robot link or held object) and an environment object or
        a robot link it may collide with (the SRDF's pairs, including pairs of the group's own links):
        ``{"link|other": (distance, gradient)}``. Robot links are taken as their convex hulls (signed
        distances need convex shapes), so they are a little more conservative than the collision checks."""
        if self._needs_build:
            self._build()
        q = _as_q(q)
        model, data, gm = self._model, self._data, self._gm
        cols = self._group_columns(group)
        pin.computeJointJacobians(model, data, q)  # also forward kinematics
        moving = self.robot.moving_joints(group)
        skip = frozenset(ignore)
        # (name, geometry, world pose, robot geometry id or None, joint it moves with or None)
        bodies, others = [], []
        for obj in self._objects.values():
            if obj.held_by is not None:
                joint = self._tool_joint[obj.held_by]
                if joint in moving:
                    bodies.append((obj.name, obj.geometry, data.oMi[joint] * gm.geometryObjects[obj.gid].placement,
                                   None, joint))
            elif obj.name not in skip and (movables or not obj.movable):
                others.append((obj.name, obj.geometry, obj.pose, None, None))
        for gid, hull in self._hulls().items():
            go = gm.geometryObjects[gid]
            entry = (self._link_names[gid], hull, data.oMi[go.parentJoint] * go.placement, gid, go.parentJoint)
            if go.parentJoint in moving:
                bodies.append(entry)
            else:
                others.append(entry[:4] + (None,))
        if not bodies:
            return {}
        others = bodies + others  # a pair of two moving links counts once (i < j)
        olo, ohi = self._boxes([o[1] for o in others], [o[2] for o in others])
        blo, bhi = olo[:len(bodies)], ohi[:len(bodies)]  # the moving bodies come first
        apart = np.maximum(np.maximum(blo[:, None] - ohi[None], olo[None] - bhi[:, None]), 0.0)
        gap = np.linalg.norm(apart, axis=2)  # a lower bound on the distance: world AABBs apart
        pairs = self._self_pairs()
        request, out, jacobians = coal.DistanceRequest(), {}, {}

        def point_jacobian(joint, point):
            if joint is None:
                return 0.0
            if joint not in jacobians:
                jacobians[joint] = pin.getJointJacobian(model, data, joint, pin.ReferenceFrame.LOCAL_WORLD_ALIGNED)[:, cols]
            J = jacobians[joint]
            return J[:3] - pin.skew(point - data.oMi[joint].translation) @ J[3:]  # velocity of that point

        for i, j in zip(*np.nonzero(gap < margin)):
            name, geom, pose, gid, joint = bodies[i]
            oname, ogeom, opose, ogid, ojoint = others[j]
            if j <= i and j < len(bodies):
                continue
            robot_pair = gid is not None and ogid is not None
            if (robot_pair and (min(gid, ogid), max(gid, ogid)) not in pairs) or \
                    (ogid is not None) != robot_pair or (ojoint is not None and not robot_pair):
                continue  # not an SRDF pair; held object vs robot (the hand touches it); held vs held
            result = coal.DistanceResult()
            d = coal.distance(geom, _transform(pose), ogeom, _transform(opose), request, result)
            if d >= margin:
                continue
            # d grows as the other body's nearest point moves along the normal and this one's against it
            grad = result.normal @ (point_jacobian(ojoint, result.getNearestPoint2())
                                    - point_jacobian(joint, result.getNearestPoint1()))
            out[f"{name}|{oname}"] = (float(d), np.asarray(grad, float))
        if group == "base":  # the planar joint's velocity is in the base frame; the vector is (x, y, theta)
            c, s_ = q[2], q[3]
            R = np.array([[c, s_, 0.0], [-s_, c, 0.0], [0.0, 0.0, 1.0]])
            out = {k: (d, grad @ R) for k, (d, grad) in out.items()}
        return out

    def _group_columns(self, group: str) -> list[int]:
        cols = []
        for j in self.robot.group(group).joint_ids:
            joint = self._model.joints[j]
            cols += list(range(joint.idx_v, joint.idx_v + joint.nv))
        return cols

    def _boxes(self, geometries, poses):
        """World axis-aligned boxes (lower and upper corners, n x 3 each) around ``geometries`` at ``poses``."""
        lo, hi = np.empty((len(poses), 3)), np.empty((len(poses), 3))
        for k, (geom, pose) in enumerate(zip(geometries, poses)):
            local = self._local_boxes.get(id(geom))
            if local is None or local[1] is not geom:
                box = geom.aabb_local
                corners = np.array([[x, y, z] for x in (box.min_[0], box.max_[0]) for y in (box.min_[1], box.max_[1])
                                    for z in (box.min_[2], box.max_[2])])
                local = self._local_boxes[id(geom)] = (corners, geom)
            world = local[0] @ pose.rotation.T + pose.translation
            lo[k], hi[k] = world.min(axis=0), world.max(axis=0)
        return lo, hi

    def _self_pairs(self) -> frozenset:
        """The robot's self-collision pairs the SRDF keeps, as (smaller, larger) geometry ids."""
        cache = self.robot.__dict__.setdefault("_self_pairs", [])
        if not cache:
            cache.append(frozenset((min(p.first, p.second), max(p.first, p.second))
                                   for p in self.robot.collision_model.collisionPairs))
        return cache[0]

    def _hulls(self) -> dict:
        """Convex hulls of the robot's collision meshes (built once per robot)."""
        cache = self.robot.__dict__.setdefault("_hulls", {})
        if not cache:
            for gid, go in enumerate(self.robot.collision_model.geometryObjects):
                geom = go.geometry
                if isinstance(geom, coal.BVHModelBase):
                    geom.buildConvexHull(True, "Qt")
                    geom = geom.convex
                geom.computeLocalAABB()
                cache[gid] = geom
        return cache

    def hand_collides(self, q, arm: str, tool_pose, ignore: Iterable[str] = frozenset(),
                      movables: bool = False) -> bool:
        """Whether ``arm``'s hand (palm and fingers, opened as in ``q``) with its tool frame at ``tool_pose``
        touches an environment object that is not held or ignored (movable ones only if ``movables``).
        No IK: any arm configuration that reaches that tool pose puts the hand there, so a grasp whose
        hand collides needs no IK to be rejected."""
        return next(self._hand_touches(q, arm, tool_pose, ignore, movables), None) is not None

    def hand_hits(self, q, arm: str, tool_pose, ignore: Iterable[str] = frozenset(), movables: bool = False) -> set[str]:
        """The names of all the objects that ``hand_collides`` would find touched."""
        return set(self._hand_touches(q, arm, tool_pose, ignore, movables))

    def _hand_touches(self, q, arm, tool_pose, ignore, movables):
        """The objects the hand touches (see ``hand_collides``), a name at a time (a name may repeat)."""
        if self._needs_build:
            self._build()
        T = np.asarray(tool_pose, dtype=float)
        skip = frozenset(ignore)
        others = [o for o in self._objects.values()
                  if o.held_by is None and o.name not in skip and (movables or not o.movable)]
        if not others:
            return
        geoms, rels, centres, radii = self._hand(q, arm)
        mine = centres @ T[:3, :3].T + T[:3, 3]
        theirs = np.array([o.pose.act(o.geometry.aabb_center) for o in others])
        reach = radii[:, None] + np.array([o.geometry.aabb_radius for o in others])[None, :]
        d = mine[:, None, :] - theirs[None, :, :]
        close = np.einsum("ijk,ijk->ij", d, d) <= reach * reach  # bounding spheres: most pairs are far apart
        if not close.any():
            return
        tool = pin.SE3(np.ascontiguousarray(T[:3, :3]), T[:3, 3].copy())  # a tool pose: rigid by construction
        for i, j in zip(*np.nonzero(close)):
            o = others[j]
            if coal.collide(geoms[i], _transform(tool * rels[i]), o.geometry, _transform(o.pose), self._request,
                            coal.CollisionResult()):
                yield o.name

    def _hand(self, q, arm: str) -> tuple:
        """The hand's geometries, their poses in the tool frame, their bounding-sphere centres in the
        tool frame and radii, for the finger angles of ``q``."""
        fingers = self.robot.group(f"{arm}_gripper").get(q)
        key = (arm, tuple(np.round(fingers, 9)))
        cache = self._hands
        if key not in cache:
            q = _as_q(q)
            model, data = self._model, self._data
            pin.forwardKinematics(model, data, q)
            fid = self.robot.tool_frame_id(arm)
            tool = pin.updateFramePlacement(model, data, fid)
            gm = self.robot.collision_model
            geoms = [go.geometry for go, hand in zip(gm.geometryObjects, self._gripper[arm]) if hand]
            rels = [tool.actInv(data.oMi[go.parentJoint] * go.placement)
                    for go, hand in zip(gm.geometryObjects, self._gripper[arm]) if hand]
            for g in geoms:
                g.computeLocalAABB()
            cache[key] = (geoms, rels, np.array([r.act(g.aabb_center) for g, r in zip(geoms, rels)]),
                          np.array([g.aabb_radius for g in geoms]))
        return cache[key]


def _as_q(q) -> np.ndarray:
    return q if isinstance(q, np.ndarray) and q.dtype == np.float64 else np.asarray(q, dtype=float)


def _transform(pose: pin.SE3) -> coal.Transform3s:
    return coal.Transform3s(pose.rotation, pose.translation)
