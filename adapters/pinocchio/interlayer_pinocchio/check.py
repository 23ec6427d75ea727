"""What ``interlayer robot check NAME|FILE`` reports about a robot description: it loads the robot (every
name checked against the URDF, the self-collision pairs found) and measures its arms and grippers."""
from __future__ import annotations


def robot_report(name_or_path) -> dict:
    """A JSON-ready summary of the robot ``name_or_path`` (a shipped name or a description file); a bad
    description raises ``UserError`` naming the field."""
    from .robot import Robot

    robot = Robot.load(name_or_path)
    desc = robot.description
    axis = {(1.0, 0.0, 0.0): "+x", (-1.0, 0.0, 0.0): "-x", (0.0, 1.0, 0.0): "+y", (0.0, -1.0, 0.0): "-y",
            (0.0, 0.0, 1.0): "+z", (0.0, 0.0, -1.0): "-z"}
    arms = []
    for a in desc.arms:
        closed, widest = robot.gripper_range(a.name)
        arms.append({
            "name": a.name, "joints": list(a.joints), "tool_frame": a.tool_frame,
            "approach": axis[a.approach], "closing": axis[a.closing].lstrip("+"),
            "reach": round(robot.reach(a.name)[1], 3),
            "gripper": {"joints": [j for j, _ in a.gripper.joints], "closed": round(closed, 4) + 0.0,
                        "open": round(widest, 4) + 0.0, "measured": a.gripper.fingers is not None,
                        # finger joints the URDF declares fixed, moved within their <limit>
                        "fixed_in_urdf": [j for j, _ in a.gripper.joints if j in robot.unfixed_joints]},
        })
    gm = robot.collision_model
    n = len(gm.geometryObjects)
    return {
        "robot": desc.name, "description": str(desc.path), "urdf": str(desc.urdf),
        "srdf": None if desc.srdf is None else str(desc.srdf),
        "dof": int(robot.model.nv) - 3, "base": "planar" if desc.mobile else "fixed",
        "held": {j: v for j, v in desc.hold}, "arms": arms,
        "self_collision": {"source": robot.self_collision_source, "checked": len(gm.collisionPairs),
                           "skipped": _all_pairs(robot) - len(gm.collisionPairs), "geometries": n},
    }


def _all_pairs(robot) -> int:
    """Geometry pairs on different joints: those a robot with no skip list would check."""
    joints = [g.parentJoint for g in robot.collision_model.geometryObjects]
    return sum(1 for i in range(len(joints)) for j in range(i + 1, len(joints)) if joints[i] != joints[j])
