"""Arm IK: round trips through FK, limits, unreachable targets, collision-aware solutions."""

import math
import time

import numpy as np
import pytest

pin = pytest.importorskip("pinocchio")

from interlayer_pinocchio import CollisionWorld, Robot, solve_ik  # noqa: E402


@pytest.fixture(scope="module")
def robot():
    return Robot.load("pr2")


def pose_error(a, b):
    """(position error m, rotation error rad) between two 4x4 poses."""
    rel = pin.SE3(a).actInv(pin.SE3(b))
    return float(np.linalg.norm(a[:3, 3] - b[:3, 3])), float(np.linalg.norm(pin.log3(rel.rotation)))


@pytest.fixture
def seeds_tried(monkeypatch):
    """Counts the seeds IK descends from (calls of ArmIK.clik): its work, whatever the machine's speed."""
    from interlayer_pinocchio import ik

    count = [0]
    clik = ik.ArmIK.clik

    def counted(self, *args, **kwargs):
        count[0] += 1
        return clik(self, *args, **kwargs)

    monkeypatch.setattr(ik.ArmIK, "clik", counted)
    return count


@pytest.mark.parametrize("arm", ["left", "right"])
def test_ik_round_trip(robot, arm, seeds_tried):
    rng = np.random.default_rng(11 if arm == "left" else 12)
    group = robot.group(f"{arm}_arm")
    failures, times, seeds = 0, [], []
    for _ in range(150):
        q_target = robot.random_q(rng, groups=("base", f"{arm}_arm"))
        target = robot.tool_pose(q_target, arm)
        q_start = robot.random_q(rng, q=q_target, groups=(f"{arm}_arm",))  # same base, other arm conf
        t, seeds_tried[0] = time.perf_counter(), 0
        solution = solve_ik(robot, arm, target, q_start, rng)
        times.append(time.perf_counter() - t)
        seeds.append(seeds_tried[0])
        if solution is None:
            failures += 1
            continue
        assert solution.shape == (7,)
        assert group.within_bounds(solution)
        assert all(-math.pi < solution[i] <= math.pi for i in group.circular_indices)
        pos, rot = pose_error(robot.tool_pose(group.set(q_start, solution), arm), target)
        assert pos <= 1e-3 and rot <= math.radians(1.0)
    print(f"\n{arm}: {failures}/150 failures, median {np.median(times) * 1e3:.2f} ms, "
          f"mean {np.mean(times) * 1e3:.2f} ms, max {np.max(times) * 1e3:.1f} ms; seeds: mean {np.mean(seeds):.2f}")
    assert failures <= 3
    assert np.median(seeds) <= 2 and np.mean(seeds) < 3  # mostly the first seed (the start) converges


def test_ik_prefers_current_configuration(robot):
    """A target already reached by q_start returns (about) the same arm configuration."""
    rng = np.random.default_rng(3)
    q = robot.random_q(rng)
    target = robot.tool_pose(q, "left")
    solution = solve_ik(robot, "left", target, q, rng)
    np.testing.assert_allclose(solution, robot.get(q, "left_arm"), atol=1e-9)


def test_ik_tracks_base_and_torso(robot):
    tall = Robot.load("pr2", torso_height=0.3)
    rng = np.random.default_rng(4)
    q = tall.random_q(rng)
    target = tall.tool_pose(q, "right")
    q_start = tall.set(q, "right_arm", tall.get(tall.default_q(), "right_arm"))
    solution = solve_ik(tall, "right", target, q_start, rng)
    assert solution is not None
    pos, rot = pose_error(tall.tool_pose(tall.set(q_start, "right_arm", solution), "right"), target)
    assert pos <= 1e-3 and rot <= math.radians(1.0)


def test_unreachable_target_fails_fast(robot, seeds_tried):
    q = robot.default_q()
    far = np.eye(4)
    far[:3, 3] = (3.0, 0.0, 1.0)
    assert solve_ik(robot, "left", far, q, np.random.default_rng(0)) is None
    assert seeds_tried[0] == 0  # refused by the reach test, before any descent


def test_ik_with_world_rejects_collisions_unless_ignored(robot):
    """Grasp pose around a floating can: closed fingers collide with it unless it is ignored."""
    world = CollisionWorld(robot)
    can = np.eye(4)
    can[:3, 3] = (0.65, 0.2, 0.9)
    world.add_cylinder("can", 0.03, 0.15, can, movable=True)
    q = robot.default_q()
    target = can.copy()  # tool x forward (approach), z up along the can axis
    rng = np.random.default_rng(5)
    assert solve_ik(robot, "left", target, q, rng, world=world, attempts=10) is None
    solution = solve_ik(robot, "left", target, q, rng, world=world, ignore={"can"})
    assert solution is not None
    q_grasp = robot.set(q, "left_arm", solution)
    assert not world.in_collision(q_grasp, ignore={"can"})
    assert world.in_collision(q_grasp)
    # open fingers around a 6 cm can: no contact, so no ignore needed
    q_open = robot.open_gripper(q, "left")
    solution = solve_ik(robot, "left", target, q_open, rng, world=world)
    assert solution is not None
    assert not world.in_collision(robot.set(q_open, "left_arm", solution))


def _textbook_clik(ik, target, seed, tol_pos, tol_rot, max_iters=60, damping=1e-6, max_step=0.5):
    """ArmIK.clik as written with numpy's public functions: the reference its fast loop must equal."""
    model, data, group, q, fid = ik.model, ik.data, ik.group, ik._q, ik.tool
    lin = ~np.asarray(group.circular)
    v = np.array(seed, dtype=float)
    for _ in range(max_iters):
        group.write(q, v)
        pin.computeJointJacobians(model, data, q)
        error_frame = pin.updateFramePlacement(model, data, fid).actInv(target)
        err = pin.log6(error_frame).vector
        if np.linalg.norm(error_frame.translation) < tol_pos and np.linalg.norm(err[3:]) < tol_rot:
            return group.wrap(v)
        jac = pin.Jlog6(error_frame.inverse()) @ pin.getFrameJacobian(model, data, fid, pin.LOCAL)
        step = jac.T @ np.linalg.solve(jac @ jac.T + np.eye(6) * damping, err)
        if np.abs(step).max() > max_step:
            step *= max_step / np.abs(step).max()
        moved = v + step
        moved[lin] = np.clip(moved[lin], group.lower[lin], group.upper[lin])
        if np.abs(moved - v).max() < 1e-6:
            return None
        v = moved
    return None


@pytest.mark.parametrize("solver", ["gufunc", "public"])
def test_ik_iterations_give_the_textbook_floats_bit_for_bit(robot, solver, monkeypatch):
    """The IK loop skips numpy's wrappers for speed, not its arithmetic: from the same seeds it returns
    exactly the floats (or the failures) of the plain formula, so a faster IK changes no plan; also with
    the public np.linalg.solve it falls back to where numpy lacks the private gufunc."""
    from interlayer_pinocchio import ik as ik_module
    from interlayer_pinocchio.ik import arm_ik

    if solver == "public":
        monkeypatch.setattr(ik_module, "_solve1", ik_module._public_solve1)

    rng = np.random.default_rng(7)
    for arm in robot.arms:
        ik = arm_ik(robot, arm)
        outcomes = set()
        for i in range(40):
            seed, v = ik.group.sample(rng), ik.group.sample(rng)
            ik.group.write(ik._q, v)
            pin.framesForwardKinematics(ik.model, ik.data, ik._q)
            target = ik.data.oMf[ik.tool].copy()
            if i % 2:  # half of them out of reach or against a limit: the failures must agree too
                target.translation += rng.normal(0.0, 0.3, 3)
            want = _textbook_clik(ik, target, seed, 1e-3, math.radians(1.0))
            got = ik.clik(target, seed, 1e-3, math.radians(1.0))
            assert (got is None) == (want is None), (arm, i)
            if want is not None:
                assert np.array_equal(got, want), (arm, i, got - want)
            outcomes.add(want is None)
        assert outcomes == {True, False}  # both kinds were compared
