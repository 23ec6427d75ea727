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


def test_a_side_grasp_seats_the_cylinder_clear_of_the_kinovas_palm(tmp_path):
    """The Kinova's palm reaches 0.4 mm into a 0.04 m cylinder centred at its tool point: its side grasps stand
    back from the axis (grasps.seat), so the hand opened for the grasp touches nothing of the object."""
    from types import SimpleNamespace

    from kinova import kinova
    from interlayer_pinocchio import CollisionWorld, Robot, solve_ik
    from interlayer_manip.grasps import grasp_poses, seat
    from interlayer_manip.scene import ObjectSpec
    from interlayer_manip.state import OPEN_CLEARANCE, pose4

    robot = Robot.load(kinova(tmp_path))
    assert seat(robot, 0.04, 0.2) > 0 and seat(Robot.load("pr2"), 0.04, 0.2) == 0.0  # the PR2's grasps as before
    can = ObjectSpec("can", "cylinder", (0.04, 0.2), (0.55, 0.1, 0.1, 0.0))
    P = pose4(*can.pose)
    world = CollisionWorld(robot)
    world.add_cylinder("can", 0.04, 0.2, P, movable=True)
    geometry = SimpleNamespace(specs={"can": can}, robot=robot)
    rng = np.random.default_rng(0)
    q0 = robot.set(robot.default_q(), "arm_arm", [-1.53, 4.49, 0.80, 0.05, 1.01, 0.03])  # docs/robots.md's reach_seed
    reached = 0
    for kind, T in grasp_poses(geometry, "can", P, math.atan2(0.1, 0.55), ("side",), rng, n_side=6):
        sol = solve_ik(robot, "arm", T, q0, rng=np.random.default_rng(1), attempts=8)
        if sol is None:
            continue
        reached += 1
        q = robot.set_gripper_opening(robot.set(q0, "arm_arm", sol), "arm", 0.08 + OPEN_CLEARANCE)
        assert not [pair for pair in world.collision_pairs(q) if "can" in pair], kind
    assert reached >= 3
