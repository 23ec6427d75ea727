"""Where a fixed-base robot can work: scenes put its base at a table's edge and keep their objects
within the band of distances at which its arm reaches a grasp (measured by IK, cached)."""
from __future__ import annotations

import math

import numpy as np

from .state import pose4

EDGE_GAP = 0.15  # m: a fixed base's origin stands this far in front of the table's edge (its footprint)
_DIRECTIONS = (-0.9, -0.45, 0.0, 0.45, 0.9)  # rad off the base's x axis
_RADII = tuple(round(0.2 + 0.05 * k, 2) for k in range(21))  # 0.2 .. 1.2 m
_VERSION = 4  # bump when the method changes: cached bands of the old one are ignored


def reach_band(desc, arm: str, top: float, height: float, kind: str = "side") -> tuple[float, float]:
    """(nearest, farthest) horizontal distance (m) from the base origin at which ``arm`` reaches a grasp
    of ``kind`` ("side": level, "top": pointing down) ``height`` above a table whose top is at ``top``
    (its edge EDGE_GAP ahead of the base) in at least four of five directions ahead. IK with seeded
    restarts (the same band every run); cached by the robot's description (``desc``) and the heights."""
    from interlayer import cache

    key = cache.digest("reach_band", _VERSION, desc.urdf.read_bytes(), repr(desc), arm, round(top, 4), round(height, 4),
                       kind)
    found = cache.load("reach_band", key)
    if isinstance(found, list) and len(found) == 2:
        return float(found[0]), float(found[1])
    from interlayer_pinocchio import Robot

    band = _measure(Robot(desc), arm, top, height, kind)
    cache.store("reach_band", key, list(band))
    return band


def _measure(robot, arm, top, height, kind):
    from interlayer.errors import UserError
    from interlayer_pinocchio import CollisionWorld, solve_ik

    from .grasps import DOWN

    cw = CollisionWorld(robot)
    cw.add_box("table", (2.0, 3.0, 0.1), pose4(EDGE_GAP + 1.0, 0.0, top - 0.05, 0.0))
    q = robot.set(robot.default_q((0.0, 0.0, 0.0)), f"{arm}_arm", robot.reach_seed(arm))  # the first IK seed
    rng = np.random.default_rng(0)
    z = top + height
    good = []
    for r in _RADII:
        hits = 0
        for a in _DIRECTIONS:
            T = pose4(r * math.cos(a), r * math.sin(a), z, a) @ (DOWN if kind == "top" else np.eye(4))
            hits += solve_ik(robot, arm, T, q, rng=rng, world=cw, attempts=4) is not None
        if hits >= 4:
            good.append(r)
    if not good:
        raise UserError(f"The {robot.description.name}'s arm {arm!r} reaches no {kind} grasp {height:.2f} m above a table "
                        f"at its base's height; a fixed-base robot needs a table within its reach.")
    return min(good), max(good)



def hand_width(robot, arm: str) -> float:
    """The fully opened hand's width (m) along its closing axis, centred on the tool frame: twice the
    farthest corner of its collision geometries' boxes. Scenes with narrow openings leave room for it."""
    import pinocchio as pin

    q = robot.open_gripper(robot.default_q(), arm)
    data, gdata = robot.model.createData(), pin.GeometryData(robot.collision_model)
    pin.updateGeometryPlacements(robot.model, data, robot.collision_model, gdata, q)
    to_tool = np.linalg.inv(robot.tool_pose(q, arm))
    hand = set(robot.gripper_links(arm))
    far = 0.0
    for i, g in enumerate(robot.collision_model.geometryObjects):
        if g.name not in hand:
            continue
        g.geometry.computeLocalAABB()
        lo, hi = np.asarray(g.geometry.aabb_local.min_), np.asarray(g.geometry.aabb_local.max_)
        corners = np.array([[x, y, z, 1.0] for x in (lo[0], hi[0]) for y in (lo[1], hi[1]) for z in (lo[2], hi[2])])
        in_tool = to_tool @ gdata.oMg[i].homogeneous @ corners.T
        far = max(far, float(np.max(np.abs(in_tool[1]))))
    return 2 * far
