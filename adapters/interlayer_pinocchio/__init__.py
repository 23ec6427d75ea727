"""interlayer_pinocchio -- a PR2 robot world on Pinocchio + Coal: kinematics, collisions, IK.

Generic robot-world code (no task-planning knowledge).  Importing this package is
cheap: Pinocchio and Coal load on first use of a name below.

Coordinates: ``q`` is Pinocchio's configuration (nq = 38; planar base and
continuous joints stored as cos/sin); a "vector" has one float per DOF (angles
in rad).  Poses are 4x4 numpy arrays in metres.  Arms are ``"left"``/``"right"``.

``PR2(torso_height=0.2, base_limits=((-5, 5), (-5, 5)))``   (robot.py)
    groups: ``base`` (x, y, theta), ``left_arm``/``right_arm`` (7 joints
    shoulder_pan..wrist_roll), ``left_gripper``/``right_gripper`` (finger angle).
    ``group(name) -> JointGroup`` (dof_names, lower, upper, circular, get, set, write,
    sample, wrap, within_bounds); ``get(q, group)``, ``set(q, group, values) -> q``;
    ``q_to_vector(q)``, ``vector_to_q(v)``, ``vector_names``;
    ``neutral_q()``, ``default_q(base=(x, y, th))`` (arms tucked), ``random_q(rng, q, groups)``;
    ``tool_frame(arm)``, ``tool_pose(q, arm)``, ``frame_pose(q, frame)``, ``base_pose(q)``;
    ``max_gripper_opening`` (m, measured: ~0.092), ``gripper_opening(q, arm)``,
    ``set_gripper_opening(q, arm, width)``, ``open_gripper(q, arm)``, ``close_gripper(q, arm)``;
    ``gripper_links(arm)``, ``collision_links(group)``, ``moving_joints(group)``;
    ``visual_model() -> (GeometryModel, package_dirs)``; ``model``, ``collision_model``.

``CollisionWorld(robot)``   (world.py)
    ``add_box(name, size, pose, movable=False, color)`` (size = full edge lengths),
    ``add_cylinder(name, radius, height, pose, ...)``, ``add_mesh(name, path, pose, scale, ...)``,
    ``set_pose``, ``pose(name, q=None)``, ``remove``, ``get(name) -> WorldObject``, ``objects()``,
    ``names()``, ``geometry(name)`` (coal shape); ``WorldObject(name, shape, size, pose, movable,
    color, mesh_path, held_by, grasp)``;
    ``attach(name, arm, q)``, ``detach(name, q)``, ``held() -> (Attachment(name, arm, tool_T_object), ...)``;
    ``in_collision(q, ignore=(), movables=True, group=None) -> bool``,
    ``colliding_movables(q, ignore=()) -> set``, ``collision_pairs(q, ignore=(), movables=True)``,
    ``checker_for(group, q_fixed, ignore=(), movables=True) -> is_valid(vector) -> bool``,
    ``objects_overlap(name, pose, ignore=()) -> set``.

``ArticulatedBody(name, urdf_xml, placement)``   (articulated.py)
    a fixed-base environment body with 1-DOF joints (a drawer, a door): ``joint_names``, ``lower``,
    ``upper``, ``link_pose(values, link)``, ``shape_poses(values)``, ``carry(pose, link, v0, v1)``,
    ``add_to(cw, values, padding)``, ``update(cw, values)``, ``touching(cw, values, objects)``;
    ``box_link_urdf(name, [(size, xyz), ...])`` writes a URDF link of boxes.

``solve_ik(robot, arm, target, q_start, rng=None, world=None, attempts=20, tol_pos=1e-3,
tol_rot=radians(1), ignore=(), movables=True) -> 7-vector | None``   (ik.py)

Touching counts as colliding (Coal semantics): rest objects ~1 mm above their support.
Nothing here is thread-safe: give each thread its own PR2 and CollisionWorld.
"""

from __future__ import annotations

import importlib

__all__ = ["PR2", "JointGroup", "TUCKED_ARMS", "CollisionWorld", "WorldObject", "Attachment", "solve_ik", "ArticulatedBody", "box_link_urdf"]

_WHERE = {
    "PR2": "robot", "JointGroup": "robot", "TUCKED_ARMS": "robot",
    "CollisionWorld": "world", "WorldObject": "world", "Attachment": "world",
    "solve_ik": "ik",
    "ArticulatedBody": "articulated", "box_link_urdf": "articulated",
}


def __getattr__(name: str):
    """Import the heavy submodule only when one of its names is first used."""
    if name in _WHERE:
        value = getattr(importlib.import_module(f".{_WHERE[name]}", __name__), name)
        globals()[name] = value
        return value
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")


def __dir__() -> list[str]:
    return sorted(set(globals()) | set(__all__))
