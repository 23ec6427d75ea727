"""PR2 model: vector <-> q conversions, groups, reference configurations, gripper geometry."""

import math
import os
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

pin = pytest.importorskip("pinocchio")
coal = pytest.importorskip("coal")

from interlayer_pinocchio import CollisionWorld, Robot  # noqa: E402


@pytest.fixture(scope="module")
def robot():
    return Robot.load("pr2")


def test_package_import_is_lazy():
    """The CLI imports the package name; that must not pull in pinocchio/coal."""
    code = "import sys, interlayer_pinocchio; print('pinocchio' in sys.modules or 'coal' in sys.modules)"
    adapters = Path(__file__).parents[2] / "adapters"
    env = dict(os.environ, PYTHONPATH=os.pathsep.join(str(adapters / a) for a in ("pinocchio", "coal")))
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, env=env, check=True)
    assert out.stdout.strip() == "False"


def test_model_facts(robot):
    assert (robot.model.nq, robot.model.nv) == (38, 33)
    assert len(robot.vector_names) == robot.model.nv
    assert robot.vector_names[:3] == ("x", "y", "theta")
    arm = robot.group("left_arm")
    assert arm.dof_names[0] == "l_shoulder_pan_joint" and arm.dof_names[-1] == "l_wrist_roll_joint"
    assert arm.circular_indices == (4, 6)  # forearm roll, wrist roll are continuous
    assert robot.group("base").circular == (False, False, True)
    assert np.all(robot.group("base").lower[:2] == [-5.0, -5.0])
    assert robot.group("right_gripper").dof == 1
    assert "torso_lift_joint" not in {n for g in robot.groups.values() for n in g.dof_names}


def test_vector_q_round_trip(robot):
    rng = np.random.default_rng(0)
    for _ in range(200):
        q = robot.random_q(rng, groups=tuple(robot.groups))
        v = robot.q_to_vector(q)
        assert v.shape == (robot.model.nv,)
        np.testing.assert_allclose(robot.vector_to_q(v), q, atol=1e-12)
        # any vector (angles beyond pi too) -> q -> vector gives the wrapped vector back
        v2 = v.copy()
        v2[2] += 4 * math.pi
        v2[robot.vector_names.index("l_forearm_roll_joint")] += 2 * math.pi
        back = robot.q_to_vector(robot.vector_to_q(v2))
        np.testing.assert_allclose(back, v, atol=1e-9)


def test_continuous_joints_wrap(robot):
    q = robot.set(robot.neutral_q(), "left_arm", [0, 0, 0, -0.5, 1.5 * math.pi, -0.5, -3.5 * math.pi])
    vals = robot.get(q, "left_arm")
    assert vals[4] == pytest.approx(-0.5 * math.pi)
    assert vals[6] == pytest.approx(0.5 * math.pi)
    j = robot.model.joints[robot.model.getJointId("l_forearm_roll_joint")]
    assert q[j.idx_q] == pytest.approx(0.0, abs=1e-12) and q[j.idx_q + 1] == pytest.approx(-1.0)
    q = robot.set(q, "base", [1.0, -2.0, 3 * math.pi])
    np.testing.assert_allclose(robot.get(q, "base"), [1.0, -2.0, math.pi], atol=1e-12)
    assert robot.group("left_arm").wrap([0, 0, 0, 0, 7.0, 0, -7.0])[4] == pytest.approx(7.0 - 2 * math.pi)


def test_set_copies_and_keeps_torso(robot):
    q = robot.default_q()
    q2 = robot.set(q, "right_arm", np.zeros(7))
    assert not np.array_equal(q, q2)
    np.testing.assert_allclose(robot.get(q, "right_arm"), robot.home("right"), atol=1e-12)
    torso = robot.model.joints[robot.model.getJointId("torso_lift_joint")].idx_q
    assert q2[torso] == robot.torso_height == 0.2
    with pytest.raises(ValueError):
        robot.set(q, "left_arm", [0.0] * 6)


def test_default_configuration_is_collision_free_and_compact():
    for height in (0.0, 0.1, 0.2, 0.31):
        robot = Robot.load("pr2", torso_height=height)
        world = CollisionWorld(robot)
        q = robot.default_q(base=(1.0, 2.0, 0.3))
        assert not world.in_collision(q), world.collision_pairs(q)
        np.testing.assert_allclose(robot.get(q, "base"), [1.0, 2.0, 0.3])
    robot = Robot.load("pr2")
    q = robot.default_q()
    # tucked arms stay near the footprint (base is ~0.67 m square): good for driving
    for arm in ("left", "right"):
        assert np.all(np.abs(robot.tool_pose(q, arm)[:2, 3]) < 0.4)


def test_tool_pose_matches_pinocchio(robot):
    rng = np.random.default_rng(1)
    q = robot.random_q(rng)
    data = robot.model.createData()
    pin.framesForwardKinematics(robot.model, data, q)
    for arm, frame in (("left", "l_gripper_tool_frame"), ("right", "r_gripper_tool_frame")):
        assert robot.tool_frame(arm) == frame
        expected = data.oMf[robot.model.getFrameId(frame)].homogeneous
        np.testing.assert_allclose(robot.tool_pose(q, arm), expected, atol=1e-12)
    np.testing.assert_allclose(robot.base_pose(q), robot.frame_pose(q, "base_footprint"), atol=1e-12)


def test_max_gripper_opening_is_measured_and_consistent(robot):
    """Cross-check the vertex-based pad gap with coal.distance between the two finger-tip meshes."""
    width = robot.max_gripper_opening
    assert 0.085 < width < 0.095
    q = robot.open_gripper(robot.neutral_q(), "left")
    gm = robot.collision_model
    gd = pin.GeometryData(gm)
    data = robot.model.createData()
    pin.forwardKinematics(robot.model, data, q)
    pin.updateGeometryPlacements(robot.model, data, gm, gd)
    a, b = (gm.getGeometryId(f"l_gripper_{s}_finger_tip_link_0") for s in "lr")
    tf = [coal.Transform3s(gd.oMg[i].rotation, gd.oMg[i].translation) for i in (a, b)]
    dist = coal.distance(gm.geometryObjects[a].geometry, tf[0], gm.geometryObjects[b].geometry, tf[1],
                         coal.DistanceRequest(), coal.DistanceResult())
    assert dist == pytest.approx(width, abs=2e-4)
    assert robot.gripper_opening(q, "left") == pytest.approx(width)
    assert robot.gripper_opening(robot.close_gripper(q, "left"), "left") < 0.0  # pads overlap slightly


def test_cylinder_graspability_follows_opening(robot):
    """A vertical cylinder centred on the open tool frame fits iff its diameter < max opening."""
    q = robot.open_gripper(robot.neutral_q(), "left")
    tool = robot.tool_pose(q, "left")
    for diameter, fits in ((0.085, True), (0.09, True), (0.095, False), (0.10, False)):
        world = CollisionWorld(robot)
        world.add_cylinder("can", diameter / 2, 0.2, tool, movable=True)
        assert world.in_collision(q) is (not fits), (diameter, world.collision_pairs(q))


def test_set_gripper_opening_round_trip(robot):
    q = robot.neutral_q()
    for width in (0.0, 0.03, 0.06, 0.09):
        q2 = robot.set_gripper_opening(q, "right", width)
        assert robot.gripper_opening(q2, "right") == pytest.approx(width, abs=2e-4)
        angle = robot.get(q2, "right_gripper")[0]
        for name in ("r_finger", "l_finger_tip", "r_finger_tip"):
            joint = robot.model.joints[robot.model.getJointId(f"r_gripper_{name}_joint")]
            assert q2[joint.idx_q] == pytest.approx(angle)
    capped = robot.set_gripper_opening(q, "right", 0.5)
    assert robot.get(capped, "right_gripper")[0] == pytest.approx(robot.group("right_gripper").upper[0])


def test_visual_model_for_viewers(robot):
    visual, package_dirs = robot.visual_model()
    assert visual.ngeoms > robot.collision_model.ngeoms
    assert all(Path(d).is_dir() for d in package_dirs)
    meshes = [g.meshPath for g in visual.geometryObjects if g.meshPath.lower().endswith((".dae", ".stl"))]
    assert meshes and all(Path(p).is_file() for p in meshes)
    assert robot.visual_model()[0] is visual  # loaded once
