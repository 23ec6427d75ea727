"""Every shipped robot description: it loads, rests without self-collision, and its gripper's measured opening
is the gap its fingers really leave around an object held at the tool point."""
import re
from pathlib import Path

import numpy as np
import pinocchio as pin
import pytest

from interlayer_pinocchio import CollisionWorld, Robot, shipped_robots, solve_ik

pytestmark = pytest.mark.filterwarnings("ignore::DeprecationWarning")

# Widest opening (m) of each shipped gripper, measured once on its collision geometry (robot.gripper_range) and
# bounded by what its maker states: PR2 90 mm, Panda 80 mm, PAL gripper (TIAGo Pro) 80 mm; the UR5 "gripper" of
# example-robot-data is two fixed boxes 55 mm apart (the URDF's own numbers, measured below).
OPENING = {"PR2": (0.085, 0.095), "Panda": (0.075, 0.085), "UR5": (0.054, 0.056), "TIAGo Pro": (0.075, 0.085)}


@pytest.fixture(scope="module", params=shipped_robots())
def robot(request):
    return Robot.load(request.param)


def test_the_shipped_robots_are_the_four_of_the_issue():
    assert {"pr2", "ur5_gripper", "tiago"} <= set(shipped_robots())


def test_a_shipped_robot_rests_at_home_without_self_collision(robot):
    """Every pair of links is checked at home but those the SRDF disables, adjacent links, the parts of one hand
    and pairs touching with every joint at zero (the URDF's own structure: wheels in the base, head on the
    torso).  A sampled skip list would hide a collision at home: it skips the pairs colliding at home."""
    from interlayer_pinocchio.gripper import parent_link

    model = robot.model
    gm = pin.buildGeomFromUrdf(model, str(robot.urdf_path), pin.GeometryType.COLLISION,
                               package_dirs=list(robot.package_dirs))
    gm.addAllCollisionPairs()
    if robot.srdf_path is not None:
        pin.removeCollisionPairs(model, gm, str(robot.srdf_path))
    objs = gm.geometryObjects
    with_geometry = {g.parentFrame for g in objs}

    def above(fid):  # the nearest link above with collision geometry
        up = parent_link(model, fid)
        while up and up not in with_geometry:
            up = parent_link(model, up)
        return up

    hands = [set(robot.gripper_links(arm)) for arm in robot.arms]
    def skipped(a, b):
        return above(a.parentFrame) == b.parentFrame or above(b.parentFrame) == a.parentFrame or any(
            {a.name, b.name} <= hand for hand in hands)

    data, gd = model.createData(), pin.GeometryData(gm)
    pin.computeCollisions(model, data, gm, gd, pin.neutral(model), False)
    doomed = [(cp.first, cp.second) for k, cp in enumerate(gm.collisionPairs)  # (indices: the vector shifts)
              if gd.collisionResults[k].isCollision() or skipped(objs[cp.first], objs[cp.second])]
    for i, j in doomed:
        gm.removeCollisionPair(pin.CollisionPair(i, j))
    data, gd = model.createData(), pin.GeometryData(gm)
    q = robot.default_q()
    pin.computeCollisions(model, data, gm, gd, q, False)
    hits = [(objs[p.first].name, objs[p.second].name) for k, p in enumerate(gm.collisionPairs)
            if gd.collisionResults[k].isCollision()]
    assert not hits
    for arm in robot.arms:
        np.testing.assert_allclose(robot.group(f"{arm}_arm").wrap(robot.home(arm)),
                                   robot.group(f"{arm}_arm").get(q), atol=1e-9)


def test_the_widest_opening_is_measured_and_plausible(robot):
    lo, hi = OPENING[robot.description.name]
    for arm in robot.arms:
        closed, widest = robot.gripper_range(arm)
        assert lo <= widest <= hi and closed <= widest
        q = robot.open_gripper(robot.default_q(), arm)
        assert robot.gripper_opening(q, arm) == pytest.approx(widest)


def test_the_ur5_opening_is_the_gap_between_its_finger_boxes():
    import coal

    robot = Robot.load("ur5_gripper")
    gm, gd = robot.collision_model, pin.GeometryData(robot.collision_model)
    q = robot.default_q()
    pin.updateGeometryPlacements(robot.model, robot.data, gm, gd, q)
    a, b = (gm.getGeometryId(n) for n in ("tool0_0", "tool0_1"))  # the two finger boxes of tool0
    res = coal.DistanceResult()
    coal.distance(gm.geometryObjects[a].geometry, gd.oMg[a], gm.geometryObjects[b].geometry, gd.oMg[b],
                  coal.DistanceRequest(), res)
    assert robot.gripper_range("arm") == pytest.approx((res.min_distance, res.min_distance), abs=1e-6)
    # fixed fingers: the gripper's one DOF drives nothing, opening and closing leave the gap as it is
    assert robot.set_gripper_opening(q, "arm", 0.03) == pytest.approx(q)
    assert robot.gripper_opening(robot.close_gripper(q, "arm"), "arm") == pytest.approx(res.min_distance)


def _side_grasp(robot, arm, q0):
    """An arm configuration putting the tool frame level, approaching along the base's +x, somewhere ahead of
    the arm's shoulder (IK, seeded), with the gripper open."""
    shoulder = robot.frame_pose(q0, robot.model.names[robot.group(f"{arm}_arm").joint_ids[0]])[:3, 3]
    rng = np.random.default_rng(0)
    for dx in (0.45, 0.55, 0.35, 0.65):
        for dz in (0.0, -0.15, 0.15, -0.3):
            T = np.eye(4)
            T[:3, 3] = (shoulder[0] + dx, shoulder[1], shoulder[2] + dz)
            v = solve_ik(robot, arm, T, q0, rng=rng, attempts=10)
            if v is not None:
                return robot.open_gripper(robot.set(q0, f"{arm}_arm", v), arm), T
    raise AssertionError(f"{robot.description.name}: no level side grasp ahead of the {arm} arm")


def test_an_object_as_wide_as_the_opening_fits_between_the_fingers_at_the_tool_point(robot):
    """The tool point lies between the pads and the closing axis joins them: an upright cylinder centred
    at the tool point fits when it is a little narrower than the measured opening, and is hit when a
    little wider (the description's tool frame, tool_offset, approach and closing axes, and opening)."""
    arm = robot.arms[-1]
    q, T = _side_grasp(robot, arm, robot.default_q())
    widest = robot.gripper_opening(q, arm)
    for radius, hits in ((widest / 2 - 0.004, False), (widest / 2 + 0.004, True)):
        world = CollisionWorld(robot)
        world.add_cylinder("can", radius, 0.06, T, movable=True)
        assert world.in_collision(q) is hits, (robot.description.name, radius, world.collision_pairs(q))
        if hits:  # hit by the hand, not by anything else of the robot
            hand = {robot.model.frames[g.parentFrame].name for g in robot.collision_model.geometryObjects
                    if g.name in robot.gripper_links(arm)}
            assert {a for a, _ in world.collision_pairs(q)} <= hand


def test_a_base_height_lifts_the_whole_robot():
    low, high = Robot.load("ur5_gripper"), Robot.load("ur5_gripper", base_height=0.75)
    q = low.default_q()
    np.testing.assert_allclose(high.tool_pose(q, "arm")[:3, 3] - low.tool_pose(q, "arm")[:3, 3], (0, 0, 0.75))
    assert high.base_pose(q)[2, 3] == 0.75


@pytest.mark.parametrize("edit, field", [
    (("tool_offset = [0.0, 0.0, 0.04]", "tool_offset = [0.0, 0.04]"), "arms[0].tool_offset: give 3 numbers"),
    (("kind = \"fixed\"", "kind = \"fixed\"\nheight = \"high\""), "base.height: must be a number"),
    (("opening = [0.055, 0.055]", "opening = [0.055, 0.055]\n[arms.gripper.joints]\nwrist_3_joint = 0"),
     "arms[0].gripper.joints: give each finger joint with a non-zero multiplier"),
])
def test_a_bad_tool_offset_height_or_fixed_gripper_names_its_field(tmp_path, edit, field):
    from interlayer.errors import UserError
    from interlayer_pinocchio import describe

    text = (Path(describe("ur5_gripper").path)).read_text()
    assert edit[0] in text
    bad = tmp_path / "ur5.toml"
    bad.write_text(text.replace(edit[0], edit[1]))
    with pytest.raises(UserError, match=re.escape(f"ur5.toml: {field}")):
        describe(bad)
