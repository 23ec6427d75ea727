"""Robots from descriptions (interlayer_pinocchio.description, robot.py): the shipped PR2 reproduces the
hard-coded PR2 class it replaced."""

from pathlib import Path

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


# -- descriptions: errors name their field ----------------------------------------------------------------

PANDA = Path(__file__).parents[2] / "adapters" / "pinocchio" / "interlayer_pinocchio" / "robots" / "panda.toml"


def _variant(tmp_path, old, new, name="robot.toml"):
    text = PANDA.read_text()
    assert old in text, old
    path = tmp_path / name
    path.write_text(text.replace(old, new))
    return path


@pytest.mark.parametrize("old, new, message", [
    ('"panda_joint3", ', '"panda_joint_3", ', "robot.toml: arms[0].joints[2]: no joint 'panda_joint_3' in the URDF"),
    ('tool_frame = "panda_hand_tcp"', 'tool_frame = "panda_hand_foo"',
     "robot.toml: arms[0].tool_frame: no frame 'panda_hand_foo' in the URDF (frames with 'panda': "),
    ('approach = "+z"', 'approach = "+w"', "robot.toml: arms[0].approach: '+w' is not an axis"),
    ('closing = "y"', 'closing = "z"', "robot.toml: arms[0].closing: must be perpendicular to the approach axis"),
    ('urdf = "example-robot-data:panda_description/urdf/panda.urdf"', 'urdf = "nowhere/panda.urdf"',
     "robot.toml: robot.urdf: no file "),
    ('panda_finger_joint2 = 1.0', 'panda_finger_joint9 = 1.0',
     "robot.toml: arms[0].gripper.joints.panda_finger_joint9: no joint 'panda_finger_joint9' in the URDF"),
    ('kind = "fixed"', 'kind = "wheels"', "robot.toml: base.kind: 'wheels' is not a base kind"),
    ('home = [0.0, -0.785398, ', 'home = [-0.785398, ', "robot.toml: arms[0].home: give 7 numbers, not 6"),
])
def test_a_description_error_names_its_field(tmp_path, old, new, message):
    from interlayer.errors import UserError

    with pytest.raises(UserError) as info:
        Robot.load(_variant(tmp_path, old, new))
    assert str(info.value).startswith(message), str(info.value)
    assert "\n" not in str(info.value)


def test_an_unknown_robot_name_lists_the_shipped_ones():
    from interlayer.errors import UserError

    with pytest.raises(UserError, match=r"unknown robot 'pandaa' \(did you mean 'panda'\?\).*shipped robots are .*pr2"):
        Robot.load("pandaa")


# -- self-collision pairs sampled when the description gives none ----------------------------------------

def _link_pairs(robot):
    objs = robot.collision_model.geometryObjects
    return {frozenset(robot.model.frames[objs[i].parentFrame].name for i in (cp.first, cp.second))
            for cp in robot.collision_model.collisionPairs}


def test_self_collision_pairs_are_sampled_without_an_srdf_and_cached(tmp_path, monkeypatch):
    from interlayer_pinocchio import selfcollision

    monkeypatch.setenv("INTERLAYER_CACHE_DIR", str(tmp_path / "cache"))
    path = _variant(tmp_path, 'srdf = "example-robot-data:panda_description/srdf/panda.srdf"\n', "")
    robot = Robot.load(path)
    assert robot.self_collision_source == "sampled"
    sampled = _link_pairs(robot)
    with_srdf = _link_pairs(Robot.load("panda"))
    # adjacent links (also through the geometry-less panda_link8) and the hand's own parts are never checked
    for a, b in (("panda_link0", "panda_link1"), ("panda_link7", "panda_hand"), ("panda_hand", "panda_leftfinger")):
        assert frozenset((a, b)) not in sampled
    # links that can meet are: the hand and the base, the fingers and the shoulder; close to the SRDF's choice
    for a, b in (("panda_hand", "panda_link0"), ("panda_leftfinger", "panda_link1"), ("panda_link1", "panda_link7")):
        assert frozenset((a, b)) in sampled
    assert len(sampled ^ with_srdf) <= 4, sorted(map(sorted, sampled ^ with_srdf))
    assert len(list((tmp_path / "cache" / "selfcollision").rglob("*.json"))) == 1

    def no_sampling(*args, **kwargs):
        raise AssertionError("sampled again: the cache was not read")

    monkeypatch.setattr(selfcollision, "sampled_skips", no_sampling)
    assert _link_pairs(Robot.load(path)) == sampled


def test_listed_skip_pairs_are_never_checked(tmp_path):
    path = _variant(tmp_path, 'srdf = "example-robot-data:panda_description/srdf/panda.srdf"\n', "")
    path.write_text(path.read_text() + '\n[self_collision]\nskip = [["panda_link0", "panda_link1"], '
                    '["panda_hand", "panda_link0"]]\n')
    robot = Robot.load(path)
    assert robot.self_collision_source == "listed"
    pairs = _link_pairs(robot)
    assert frozenset(("panda_hand", "panda_link0")) not in pairs and frozenset(("panda_link0", "panda_link1")) not in pairs
    assert frozenset(("panda_hand", "panda_link1")) in pairs


# -- a tool axis other than x: the Panda approaches along its hand's z --------------------------------------

def test_panda_canonical_tool_frame_points_out_of_the_hand():
    robot = Robot.load("panda")
    assert robot.arms == ("arm",) and not robot.mobile
    rng = np.random.default_rng(3)
    for _ in range(5):
        q = robot.random_q(rng)
        T = robot.tool_pose(q, "arm")
        tcp = robot.frame_pose(q, "panda_hand_tcp")
        hand = robot.frame_pose(q, "panda_hand")
        np.testing.assert_allclose(T[:3, 3], tcp[:3, 3], atol=1e-12)  # same point, turned
        np.testing.assert_allclose(T[:3, 0], tcp[:3, 2], atol=1e-12)  # x = the hand's z: out of the hand
        np.testing.assert_allclose(T[:3, 1], tcp[:3, 1], atol=1e-12)  # y = the closing axis
        out = (tcp[:3, 3] - hand[:3, 3]) / np.linalg.norm(tcp[:3, 3] - hand[:3, 3])
        assert out @ T[:3, 0] > 0.999
    closed, widest = robot.gripper_range("arm")
    assert abs(closed) < 1e-3 and widest == pytest.approx(0.08, abs=1e-3)  # two fingers of 0.04 m
    assert robot.gripper_links("arm")[0] == "panda_hand_0"
    assert {g.split("_")[1] for g in robot.gripper_links("arm")} == {"hand", "leftfinger", "rightfinger"}


def test_the_robot_layers_public_names_are_documented():
    """A robot plugin imports the robot layer's names from the package (docs/plugins.md lists them)."""
    import interlayer_optim.timing
    import interlayer_pinocchio

    doc = (Path(__file__).parents[2] / "docs" / "plugins.md").read_text()
    for name in interlayer_pinocchio.__all__:
        obj = getattr(interlayer_pinocchio, name)
        assert (obj.__doc__ or "").strip(), f"{name} has no docstring"
        assert f"`{name}" in doc, f"{name} is not in docs/plugins.md's robot layer table"
    assert callable(interlayer_optim.timing.time_parameterize)
    assert "`interlayer_optim.timing.time_parameterize(" in doc and "`interlayer_meshcat.add_pinocchio_robot(" in doc


def test_held_joint_overrides_are_checked_against_the_urdf():
    from interlayer.errors import UserError

    with pytest.raises(UserError, match=r"^pr2.toml: torso_height: 0.5 is outside torso_lift_joint's range \[0, 0.31\]$"):
        Robot.load("pr2", torso_height=0.5)
    with pytest.raises(UserError, match=r"^panda.toml: robot.torso: the Panda has no torso"):
        Robot.load("panda", torso_height=0.2)
    with pytest.raises(UserError, match=r"^panda.toml: hold.panda_joint4: 0.5 is outside panda_joint4's range \[-3.072, -0.0698\]$"):
        Robot.load("panda", hold={"panda_joint4": 0.5})


def test_reach_and_group_arms(tmp_path):
    robot = Robot.load("panda")
    shoulder, radius = robot.reach("arm")
    np.testing.assert_allclose(shoulder, [0.0, 0.0, 0.333], atol=1e-9)  # panda_joint1 above the base
    rng = np.random.default_rng(0)
    for _ in range(50):  # an upper bound: no configuration puts the tool farther
        assert np.linalg.norm(robot.tool_pose(robot.random_q(rng, groups=("arm_arm",)), "arm")[:3, 3] - shoulder) <= radius
    assert robot.arm_of("arm_arm") == robot.arm_of("arm_gripper") == "arm" and robot.arm_of("base") is None
    named = Robot.load(_variant(tmp_path, 'name = "arm"', 'name = "the_arm"'))  # names are data: "_" included
    assert named.arms == ("the_arm",) and named.arm_of("the_arm_gripper") == "the_arm"
    assert named.group("the_arm_arm").dof == 7


def test_gripper_opening_given_and_limits_overridden(tmp_path):
    path = _variant(tmp_path, 'fingers = ["panda_leftfinger", "panda_rightfinger"]', "opening = [0.01, 0.09]")
    path.write_text(path.read_text() + "\n[limits]\nvelocity = { panda_joint1 = 1.5 }\n"
                    "acceleration = { panda_joint2 = 7.0 }\n")
    robot = Robot.load(path)
    assert robot.gripper_range("arm") == (0.01, 0.09)  # the pad gap at the DOF's limits, linear between
    q = robot.set_gripper_opening(robot.default_q(), "arm", 0.05)
    assert robot.get(q, "arm_gripper")[0] == pytest.approx(0.02) and robot.gripper_opening(q, "arm") == pytest.approx(0.05)
    vel, acc = robot.velocity_limits("arm_arm"), robot.acceleration_limits("arm_arm")
    assert vel[0] == 1.5 and vel[1] == pytest.approx(2.175)  # given, else the URDF's
    assert acc[0] == 3.0 and acc[1] == 7.0 and acc[2] == pytest.approx(4.35)  # given, else twice the velocity


# -- a hand whose URDF fixes its fingers (example-robot-data's Kinova) ------------------------------------

from kinova import kinova as _kinova  # noqa: E402  (tests/kinova.py)


def test_finger_joints_the_urdf_fixes_move_when_the_gripper_names_them(tmp_path):
    fixed = Robot.load(_kinova(tmp_path, joints=""))
    assert fixed.gripper_range("arm")[0] == fixed.gripper_range("arm")[1] == pytest.approx(0.122, abs=0.002)
    robot = Robot.load(_kinova(tmp_path))
    assert robot.model.nv == fixed.model.nv + 2  # the two finger joints
    closed, wide = robot.gripper_range("arm")
    assert wide == pytest.approx(0.122, abs=0.002) and closed < 0.0  # open as the URDF draws them; they close
    q = robot.set_gripper_opening(robot.default_q(), "arm", 0.09)
    assert robot.gripper_opening(q, "arm") == pytest.approx(0.09, abs=1e-3)
    hand = {g.parentJoint for g in robot.collision_model.geometryObjects if "finger" in g.name}
    assert hand == set(robot.group("arm_gripper").joint_ids)  # the fingers ride on the joints made movable


def test_a_fixed_finger_joint_without_limits_is_refused_naming_it(tmp_path):
    from interlayer.errors import UserError
    from interlayer_pinocchio import describe

    source = describe(_kinova(tmp_path)).urdf.read_text()
    start = source.index('<joint name="j2s6s200_joint_finger_1"')
    limit = source.index("<limit", start)
    (tmp_path / "kinova.urdf").write_text(source[:limit] + source[source.index("/>", limit) + 2:])
    with pytest.raises(UserError) as info:
        Robot.load(_kinova(tmp_path, urdf="kinova.urdf"))
    assert str(info.value).startswith("kinova.toml: arms[0].gripper.joints.j2s6s200_joint_finger_1: the URDF declares "
                                      "'j2s6s200_joint_finger_1' fixed and gives it no <limit"), str(info.value)


def test_home_angles_of_continuous_joints_are_wrapped_into_the_arm_space(tmp_path):
    robot = Robot.load(_kinova(tmp_path))
    home = robot.home("arm")  # Kinova's own home: 4.80 and 4.20 rad on continuous joints 1 and 4
    assert home[0] == pytest.approx(4.80 - 2 * np.pi) and home[3] == pytest.approx(4.20 - 2 * np.pi)
    assert home[1:3] == (2.92, 1.00)  # revolute joints keep their values (joint 2's range is [0.82, 5.46])
    g = robot.group("arm_arm")
    assert all(lo <= v <= hi for v, lo, hi in zip(home, g.lower, g.upper))
    np.testing.assert_allclose(robot.tool_pose(robot.default_q(), "arm"),
                               robot.tool_pose(robot.set(robot.default_q(), "arm_arm", [4.80, 2.92, 1.00, 4.20, 1.44, 1.32]), "arm"), atol=1e-12)
