"""The (O) / (N) property of a drawer scene, checked on a fine grid of pull distances and base poses.

* ``blocked(d)``: the drawer (its moving elements and the inner object riding in it), pulled out by d,
  touches the outer object (exact geometry, Coal).
* ``exposed(d)``: some top grasp of the inner object, with its 0.2 m vertical approach, keeps the
  PR2's open gripper clear of the cabinet. The gripper is its bounding box in the tool frame (measured
  from the PR2's collision meshes), so "exposed" is conservative; the (N) scenes keep the inner object
  MARGIN_N (5 cm) further in than the first exposed pull, more than the box exceeds the real gripper.
* (O): some pull d with nothing blocked up to d and the inner object exposed, and some base pose on a
  grid (5 cm, 8 headings) in front of the cabinet from which IK reaches the grasp and the pre-grasp with
  the robot touching nothing (the outer object included).
* (N): every pull short of the outer object leaves the inner object unexposed (no base pose can help).
"""
from __future__ import annotations

import math
from dataclasses import dataclass, replace

import coal
import numpy as np

from .scene import INNER, PULL_MAX

GRID_PULL = 0.005  # m between checked pull distances
GRID_BASE = 0.05  # m between checked base positions
HEADINGS = 8
# the open PR2 gripper's bounding box in its tool frame (x out of the fingers), swept up by the approach
GRIPPER_LO, GRIPPER_HI = np.array([-0.152, -0.092, -0.029]), np.array([0.004, 0.092, 0.029])
APPROACH = 0.20


@dataclass
class Report:
    variant: str
    holds: bool
    pulls_free: float  # the drawer opens this far without touching the outer object
    first_exposed: float | None  # the smallest pull exposing the inner object (None: none up to 0.4 m)
    witness: tuple | None  # (pull, base) reaching the inner object without moving the outer one
    bases_checked: int

    def summary(self) -> str:
        exp = "never" if self.first_exposed is None else f"from {self.first_exposed:.3f} m"
        s = (f"Drawer ({self.variant}): the drawer opens {self.pulls_free:.3f} m before it touches the outer object; "
             f"the inner object is exposed for a top grasp {exp} (grid {GRID_PULL * 1000:.0f} mm)")
        if self.variant == "N" and self.holds:
            s += "; no pull short of the outer object exposes it, so no base pose can reach it"
        if self.variant == "O":
            if self.witness:
                d, b = self.witness
                s += f"; reached without moving the outer object at pull {d:.3f} m from base ({b[0]:.2f}, {b[1]:.2f}, {b[2]:.2f})"
            else:
                s += f"; no base pose of {self.bases_checked} on the grid reaches it"
        return s + (": (O) holds" if self.holds and self.variant == "O" else ": (N) holds" if self.holds
                    else f": ({self.variant}) does NOT hold")


def top_grasps(P, yaws=(0.0, math.pi / 2, math.pi / 4, -math.pi / 4)):
    """Tool poses of top grasps of a cylinder at P (as interlayer_manip.generators.grasp_poses builds them)."""
    from interlayer_manip.grasps import DOWN
    from interlayer_manip.state import rz, trans

    depth = min(0.03, INNER[1] / 2)
    x, y, z = P[:3, 3]
    return [trans(x, y, z + INNER[1] / 2 - depth) @ rz(a) @ DOWN for a in yaws]


def _sweep_box(pad):
    lo = GRIPPER_LO - pad
    lo[0] -= APPROACH
    hi = GRIPPER_HI + pad
    return coal.Box(*(hi - lo)), (hi + lo) / 2


def exposed(body, d, P, pad=0.0, yaws=None) -> list:
    """Top-grasp tool poses of the inner object (at P when the drawer is closed) whose gripper box and
    approach sweep, at pull d, touch no element of ``body``."""
    from interlayer_pinocchio.articulated import _tf

    box, centre = _sweep_box(pad)
    Pd = body.carry(P, "drawer", body.zero(), [d])
    poses = body.shape_poses([d])
    shapes = [(_geom(s), _tf(poses[s.name])) for s in body.shapes]
    req = coal.CollisionRequest()
    out = []
    for T in top_grasps(Pd) if yaws is None else top_grasps(Pd, yaws):
        C = T.copy()
        C[:3, 3] = T[:3, :3] @ centre + T[:3, 3]
        tf = _tf(C)
        if not any(coal.collide(box, tf, g, gtf, req, coal.CollisionResult()) for g, gtf in shapes):
            out.append(T)
    return out


def _geom(shape):
    return coal.Box(*shape.size) if shape.kind == "box" else coal.Cylinder(shape.size[0], shape.size[1])


def first_exposed(body, P, pad=0.0):
    for d in np.arange(0.0, PULL_MAX + 1e-9, GRID_PULL):
        if exposed(body, float(d), P, pad):
            return float(d)
    return None


def pulls_free(body, outer_geom, outer_pose, inner_geom, P):
    """The largest grid pull up to which neither the drawer nor the inner object touches the outer one."""
    from interlayer_pinocchio.articulated import _tf

    req = coal.CollisionRequest()
    otf = _tf(outer_pose)
    free = 0.0
    for d in np.arange(0.0, PULL_MAX + 1e-9, GRID_PULL):
        poses = body.shape_poses([float(d)])
        hit = any(coal.collide(_geom(s), _tf(poses[s.name]), outer_geom, otf, req, coal.CollisionResult())
                  for s in body.moving_shapes())
        Pd = body.carry(P, "drawer", body.zero(), [float(d)])
        hit = hit or coal.collide(inner_geom, _tf(Pd), outer_geom, otf, req, coal.CollisionResult())
        if hit:
            break
        free = float(d)
    return free


def check_property(geometry, want_witness=True) -> Report:
    """Check (O) or (N) (``geometry.layout.extra["variant"]``) for a DrawerGeometry built with padding 0."""
    layout = geometry.layout
    variant = layout.extra["variant"]
    body = geometry.cabinet
    specs = {o.name: o for o in layout.objects}
    P = geometry.initial_world().objects["inner"]
    Q = geometry.initial_world().objects["outer"]
    o = specs["outer"]
    free = pulls_free(body, coal.Cylinder(o.size[0], o.size[1]), Q, coal.Cylinder(*specs["inner"].size), P)
    first = first_exposed(body, P)
    if variant == "N":
        holds = first is None or first > free
        return Report(variant, holds, free, first, None, 0)
    if first is None or first > free:
        return Report(variant, False, free, first, None, 0)
    witness, n = (_witness(geometry, first, free, P) if want_witness else ((None, None), 0))
    return Report(variant, witness[0] is not None if want_witness else True, free, first,
                  witness if witness[0] is not None else None, n)


def _witness(geometry, first, free, P):
    """(pull, base) on the grid from which the right or left arm reaches a top grasp and its pre-grasp."""
    from interlayer_manip.generators import _base_free
    from interlayer_manip.state import trans

    rng = np.random.default_rng(0)
    world0 = geometry.initial_world()
    n = 0
    for d in np.arange(first, free + 1e-9, 4 * GRID_PULL):
        w = geometry.with_joints(world0, "cabinet", [float(d)])
        grasps = exposed(geometry.cabinet, float(d), P)
        Pd = w.objects["inner"]
        x, y = Pd[0, 3], Pd[1, 3]
        for r in np.arange(0.45, 0.85, GRID_BASE):
            for a in np.linspace(-math.pi, math.pi, 24, endpoint=False):
                bx, by = x + r * math.cos(a), y + r * math.sin(a)
                for k in range(HEADINGS // 4):
                    yaw = math.atan2(y - by, x - bx) + (k - (HEADINGS // 4 - 1) / 2) * 0.3
                    base = (float(bx), float(by), float(yaw))
                    if not _base_free(geometry, w, base):
                        continue
                    n += 1
                    wb = replace(w, base=base)
                    for arm in geometry.robot.arms:
                        for T in grasps:
                            wo = wb.with_gripper(arm, geometry.opening("inner", np.linalg.inv(T) @ Pd))
                            v = geometry.ik(wo, arm, T, rng, movables=True, ignore=("inner",), attempts=3)
                            if v is None:
                                continue
                            pre = geometry.ik(wo, arm, trans(0, 0, APPROACH) @ T, rng,
                                              movables=True, seed=v, attempts=3)
                            if pre is not None:
                                return (float(d), base), n
    return (None, None), n
