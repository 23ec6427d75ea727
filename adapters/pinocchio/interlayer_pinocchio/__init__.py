"""interlayer_pinocchio -- the robot layer on Pinocchio + Coal: any robot from a description; kinematics, collisions, IK.

Generic robot-world code (no task-planning knowledge).  Importing this package is
cheap: Pinocchio and Coal load on first use of a name below.

Coordinates: ``q`` is Pinocchio's configuration (planar base and continuous
joints stored as cos/sin); a "vector" has one float per DOF (angles in rad).
Poses are 4x4 numpy arrays in metres.  Arms are named by the description.

``Robot.load(name_or_path="pr2", torso_height=None, base_limits=((-5, 5), (-5, 5)), hold=None, base_height=None)``
    a robot from its description (description.py; shipped: robots/*.toml, ``shipped_robots()``); every robot
    has a planar root. ``arms`` (names), ``mobile``, ``description``, ``home(arm)``, ``reach_seed(arm)``,
    ``carry_poses(arm)``, ``torso_height`` (None without a torso), ``base_height`` (the root link's z),
    ``self_collision_source``;
    groups: ``base`` (x, y, theta), ``{arm}_arm`` (the arm's joints), ``{arm}_gripper`` (one DOF driving the
    finger joints). ``group(name) -> JointGroup`` (dof_names, lower, upper, circular, get, set, write,
    sample, wrap, within_bounds); ``get(q, group)``, ``set(q, group, values) -> q``;
    ``q_to_vector(q)``, ``vector_to_q(v)``, ``vector_names``;
    ``neutral_q()``, ``default_q(base=(x, y, th))`` (arms at home), ``random_q(rng, q, groups)``;
    ``tool_frame(arm)`` (the description's), ``tool_frame_id(arm)``, ``tool_pose(q, arm)`` and
    ``tool_jacobian(q, arm)`` (canonical tool frame: x = approach, y = closing), ``frame_pose(q, frame)``,
    ``base_pose(q)``, ``velocity_limits(group)``, ``acceleration_limits(group)``;
    ``gripper_range(arm) -> (closed, widest)`` (m, measured), ``max_gripper_opening`` (smallest widest),
    ``gripper_opening(q, arm)``, ``set_gripper_opening(q, arm, width)``, ``open_gripper(q, arm)``,
    ``close_gripper(q, arm)``; ``gripper_links(arm)``, ``collision_links(group)``, ``moving_joints(group)``;
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
tol_rot=radians(1), ignore=(), movables=True) -> arm vector | None``   (ik.py)

Touching counts as colliding (Coal semantics): rest objects ~1 mm above their support.
Nothing here is thread-safe: give each thread its own Robot and CollisionWorld.
"""

from __future__ import annotations

import importlib

__all__ = ["Robot", "JointGroup", "CollisionWorld", "WorldObject", "Attachment", "solve_ik", "ArticulatedBody",
           "box_link_urdf", "describe", "shipped_robots", "RobotDescription"]

_WHERE = {
    "Robot": "robot", "JointGroup": "joints",
    "describe": "description", "shipped_robots": "description", "RobotDescription": "description",
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
