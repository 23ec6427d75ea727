"""Robots from descriptions (interlayer_pinocchio.description, robot.py): the shipped PR2 reproduces the
hard-coded PR2 class it replaced."""

import numpy as np
import pytest

pin = pytest.importorskip("pinocchio")

from interlayer_pinocchio import Robot  # noqa: E402

# Computed with the hard-coded PR2 class (PR2(torso_height=0.25), before robots/pr2.toml replaced it):
# random_q(np.random.default_rng(7), groups=(base, arms, grippers)) three times; per configuration and
# arm the tool frame's position and rotation (row-major), rounded to 1e-6.
OLD_PR2_TOOL_POSES = [
    (0, "left", [0.924519, 4.053624, 0.671768],
     [-0.429337, -0.069576, -0.900461, -0.57532, -0.747488, 0.332067, -0.696187, 0.660622, 0.280895]),
    (0, "right", [1.822368, 4.302277, 0.629893],
     [-0.700987, -0.302223, 0.645971, 0.122302, 0.841408, 0.526378, -0.702609, 0.447988, -0.552853]),
    (1, "left", [5.563008, -3.159293, 1.624733],
     [0.466984, 0.446991, -0.762971, 0.380615, 0.677205, 0.629703, 0.798159, -0.58446, 0.146112]),
    (1, "right", [4.723258, -2.769584, 0.641617],
     [0.628488, 0.775499, -0.060028, 0.402868, -0.390568, -0.82774, -0.665357, 0.496042, -0.557891]),
    (2, "left", [3.871945, -2.989544, 0.616435],
     [-0.527699, -0.835398, 0.153765, 0.781329, -0.548392, -0.297978, 0.333254, -0.037102, 0.942107]),
    (2, "right", [3.056605, -3.70346, 0.285768],
     [-0.521694, 0.612391, -0.59398, 0.059151, -0.668594, -0.741271, -0.851079, -0.421852, 0.312578]),
]
OLD_PR2_GRIPPER_LINKS = ("l_gripper_palm_link_0", "l_gripper_l_finger_link_0", "l_gripper_l_finger_tip_link_0",
                         "l_gripper_r_finger_link_0", "l_gripper_r_finger_tip_link_0")


def test_pr2_description_reproduces_the_old_pr2():
    robot = Robot.load("pr2", torso_height=0.25)
    assert robot.arms == ("left", "right") and robot.mobile
    assert (robot.model.nq, robot.model.nv) == (38, 33)
    rng = np.random.default_rng(7)
    groups = ("base", "left_arm", "right_arm", "left_gripper", "right_gripper")
    configs = [robot.random_q(rng, groups=groups) for _ in range(3)]
    for k, arm, xyz, rot in OLD_PR2_TOOL_POSES:
        T = robot.tool_pose(configs[k], arm)
        np.testing.assert_allclose(T[:3, 3], xyz, atol=2e-6)
        np.testing.assert_allclose(T[:3, :3].ravel(), rot, atol=2e-6)
    # the measured gripper, the hand, the SRDF's self-collision pairs and the torso as before
    assert robot.max_gripper_opening == pytest.approx(0.09201195103363911, abs=1e-9)
    q = robot.group("left_gripper").set(robot.default_q(), [0.3])
    assert robot.gripper_opening(q, "left") == pytest.approx(0.051818417739825165, abs=1e-9)
    assert robot.gripper_links("left") == OLD_PR2_GRIPPER_LINKS
    assert len(robot.collision_model.collisionPairs) == 239 and robot.self_collision_source == "srdf"
    assert robot.torso_height == 0.25
    assert robot.tool_frame("right") == "r_gripper_tool_frame"

