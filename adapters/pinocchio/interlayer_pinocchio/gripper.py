"""A gripper's hand and opening, found from the model: the hand's collision geometries and the table of
pad gap (m) against the gripper's one DOF."""
from __future__ import annotations

import numpy as np
import pinocchio as pin

__all__ = ["hand_geometries", "pad_gap_table", "parent_link"]

_SAMPLES = 56  # DOF values at which the gap is measured (interpolated in between)


def parent_link(model, fid: int) -> int:
    """The BODY frame (link) above frame ``fid`` in the URDF's tree (0 at the root)."""
    while fid:
        fid = model.frames[fid].parentFrame
        if model.frames[fid].type == pin.FrameType.BODY:
            return fid
    return 0


def _link_frames(model, geometry_model) -> set:
    return {g.parentFrame for g in geometry_model.geometryObjects}


def hand_geometries(model, geometry_model, tool_fid: int) -> tuple[str, ...]:
    """Collision geometries of the hand: those of the first link at or above the tool frame that has
    collision geometry (PR2: the palm; Panda: panda_hand) and of every link below it (fingers)."""
    with_geometry = _link_frames(model, geometry_model)
    root = tool_fid if model.frames[tool_fid].type == pin.FrameType.BODY else parent_link(model, tool_fid)
    while root and root not in with_geometry:
        root = parent_link(model, root)

    def below_root(fid):
        while fid:
            if fid == root:
                return True
            fid = model.frames[fid].parentFrame
        return False

    return tuple(g.name for g in geometry_model.geometryObjects if root and below_root(g.parentFrame))


def _points(geometry) -> np.ndarray:
    """Points whose hull is the geometry: a mesh's vertices, a convex's points, else its local box's corners."""
    import coal

    if isinstance(geometry, coal.BVHModelBase):
        return np.array(geometry.vertices())
    if isinstance(geometry, coal.ConvexBase):
        return np.array(geometry.points())
    geometry.computeLocalAABB()
    box = geometry.aabb_local
    return np.array([[x, y, z] for x in (box.min_[0], box.max_[0]) for y in (box.min_[1], box.max_[1])
                     for z in (box.min_[2], box.max_[2])])


def pad_gap_table(robot, arm: str, gripper) -> tuple[np.ndarray, np.ndarray]:
    """(DOF values, pad gaps) from the gripper's lower to its upper limit.

    With ``gripper.opening``: linear between its two gaps.  With ``gripper.fingers``: measured on the two
    finger links' collision geometry placed by FK and expressed in the canonical tool frame, whose y axis
    is the closing direction: the gap is the distance between the two fingers' point sets along y (the
    inner surfaces; negative when they overlap).  With parallel pads it agrees with ``coal.distance``.
    """
    group = robot.group(f"{arm}_gripper")
    lo, hi = float(group.lower[0]), float(group.upper[0])
    if gripper.opening is not None:
        return np.array([lo, hi]), np.array(gripper.opening, dtype=float)
    model, data, gm = robot.model, robot.model.createData(), robot.collision_model
    tool = robot.tool_frame_id(arm)
    fingers = []
    for link in gripper.fingers:
        fid = model.getFrameId(link)
        fingers.append([(g, _points(g.geometry)) for g in gm.geometryObjects if g.parentFrame == fid])
    dofs = np.linspace(lo, hi, _SAMPLES)
    gaps = []
    for v in dofs:
        q = group.set(robot.neutral_q(), [v])
        pin.framesForwardKinematics(model, data, q)
        tool_inv = data.oMf[tool].inverse()
        ys = []
        for parts in fingers:
            y = []
            for g, pts in parts:
                m = tool_inv * data.oMi[g.parentJoint] * g.placement  # geometry -> tool frame
                y.append(pts @ m.rotation[1] + m.translation[1])
            ys.append(np.concatenate(y))
        a, b = ys
        gaps.append(max(a.min() - b.max(), b.min() - a.max()))  # whichever finger is on +y
    return dofs, np.array(gaps)
