"""A robot whose tool axis is not x (the Panda's hand approaches along its z): the grasp code's tool poses,
reached by IK, put the fingers towards the object and the open hand around it."""
import math

import numpy as np
import pytest

pytest.importorskip("pinocchio")


def test_panda_reaches_the_grasp_codes_poses_fingers_first():
    from types import SimpleNamespace

    from interlayer_pinocchio import CollisionWorld, Robot, solve_ik
    from interlayer_manip.generators import grasp_poses
    from interlayer_manip.scene import ObjectSpec
    from interlayer_manip.state import pose4

    robot = Robot.load("panda")
    can = ObjectSpec("can", "cylinder", (0.03, 0.12), (0.5, 0.1, 0.12, 0.0))  # within its reach, sideways too
    P = pose4(*can.pose)
    geometry = SimpleNamespace(specs={"can": can}, robot=robot)  # what grasp_poses reads of a geometry
    grasps = grasp_poses(geometry, "can", P, math.atan2(0.1, 0.5), ("side", "top"), np.random.default_rng(0), n_side=1)
    assert {kind for kind, _ in grasps} == {"side", "top"}
    world = CollisionWorld(robot)
    world.add_cylinder("can", 0.03, 0.12, P, movable=True)
    q0 = robot.default_q()
    for kind, T in grasps:
        sol = solve_ik(robot, "arm", T, q0, rng=np.random.default_rng(1))
        assert sol is not None, kind
        q = robot.open_gripper(robot.set(q0, "arm_arm", sol), "arm")
        reached = robot.tool_pose(q, "arm")
        assert np.linalg.norm(reached[:3, 3] - T[:3, 3]) < 1e-3  # solve_ik's tolerances: 1 mm, 1 degree
        assert np.arccos(np.clip((np.trace(reached[:3, :3].T @ T[:3, :3]) - 1) / 2, -1, 1)) < math.radians(1)
        hand, tcp = (robot.frame_pose(q, f)[:3, 3] for f in ("panda_hand", "panda_hand_tcp"))
        assert (tcp - hand) @ T[:3, 0] > 0.09, kind  # the approach axis points out of the hand, to the can
        assert not world.in_collision(q), (kind, world.collision_pairs(q))  # the open hand around the can
