"""Inverse kinematics of an arm's (canonical) tool frame: damped least squares (CLIK) with restarts.

Each arm is solved on a reduced Pinocchio model of its joints (everything else
locked), so an iteration costs one small FK + Jacobian.  The target is moved
into that model's frame through the chain's root link (the link the arm's first
joint hangs from, e.g. the PR2's torso), which makes the result correct for any
base pose and held joint values (torso height) in ``q_start``.
"""

from __future__ import annotations

import math
from typing import Iterable

import numpy as np
import pinocchio as pin
from interlayer import deadline as deadlines

from .gripper import parent_link
from .joints import as_se3, joint_group
from .robot import Robot

__all__ = ["solve_ik", "arm_ik", "ArmIK"]


class ArmIK:
    """Reduced model + solver state for one arm (built once per robot and arm, see :func:`arm_ik`)."""

    def __init__(self, robot: Robot, arm: str):
        full = robot.model
        self.group_name = f"{arm}_arm"
        arm_group = robot.group(self.group_name)
        keep = set(arm_group.joint_ids)
        locked = [j for j in range(1, full.njoints) if j not in keep]
        self.model = pin.buildReducedModel(full, locked, robot.neutral_q())
        self.data = self.model.createData()
        self.group = joint_group(self.model, self.group_name, [full.names[j] for j in arm_group.joint_ids])
        self.tool = self.model.getFrameId(full.frames[robot.tool_frame_id(arm)].name)
        first = full.getFrameId(full.names[arm_group.joint_ids[0]], pin.FrameType.JOINT)
        self.root_frame = full.frames[parent_link(full, first)].name  # the link the chain hangs from
        pin.framesForwardKinematics(self.model, self.data, pin.neutral(self.model))
        self.root_pose = self.data.oMf[self.model.getFrameId(self.root_frame)].copy()  # constant: it is locked
        # Upper bound on |shoulder-pan origin -> tool frame|: sum of the chain's link offsets.
        self.shoulder = self.data.oMi[1].translation.copy()
        self.reach = sum(np.linalg.norm(self.model.jointPlacements[j].translation)
                         for j in range(2, self.model.njoints))
        self.reach += np.linalg.norm(self.model.frames[self.tool].placement.translation)
        self._linear = ~np.asarray(self.group.circular)
        self._q = pin.neutral(self.model)

    def target_in_model(self, robot: Robot, q_start, target) -> pin.SE3:
        """World target -> reduced-model frame, via the chain's root link pose at ``q_start``."""
        root_world = as_se3(robot.frame_pose(q_start, self.root_frame))
        return self.root_pose * root_world.actInv(as_se3(target))

    def clik(self, target: pin.SE3, seed: np.ndarray, tol_pos: float, tol_rot: float,
             max_iters: int = 60, damping: float = 1e-6, max_step: float = 0.5) -> np.ndarray | None:
        """Arm vector reaching ``target`` (reduced-model frame) from ``seed``, or None if not converged."""
        model, data, group, q, fid = self.model, self.data, self.group, self._q, self.tool
        lower, upper, lin = group.lower, group.upper, self._linear
        v = np.array(seed, dtype=float)
        eye = np.eye(6) * damping
        for _ in range(max_iters):
            group.write(q, v)
            pin.computeJointJacobians(model, data, q)  # includes forward kinematics
            current = pin.updateFramePlacement(model, data, fid)
            error_frame = current.actInv(target)  # target seen from the current tool frame
            err = pin.log6(error_frame).vector
            if np.linalg.norm(error_frame.translation) < tol_pos and np.linalg.norm(err[3:]) < tol_rot:
                return group.wrap(v)
            jac = pin.Jlog6(error_frame.inverse()) @ pin.getFrameJacobian(model, data, fid, pin.LOCAL)
            step = jac.T @ np.linalg.solve(jac @ jac.T + eye, err)
            biggest = np.abs(step).max()
            if biggest > max_step:
                step *= max_step / biggest
            moved = v + step
            moved[lin] = np.clip(moved[lin], lower[lin], upper[lin])
            if np.abs(moved - v).max() < 1e-6:  # stuck (local minimum or against a limit)
                return None
            v = moved
        return None


def arm_ik(robot: Robot, arm: str) -> ArmIK:
    """Cached :class:`ArmIK` for ``robot`` and ``arm``."""
    cache = robot.__dict__.setdefault("_arm_ik", {})
    if arm not in cache:
        cache[arm] = ArmIK(robot, arm)
    return cache[arm]


def solve_ik(robot: Robot, arm: str, target, q_start, rng: np.random.Generator | None = None,
             world=None, attempts: int = 20, tol_pos: float = 1e-3, tol_rot: float = math.radians(1.0),
             ignore: Iterable[str] = frozenset(), movables: bool = True,
             max_iters: int = 60) -> np.ndarray | None:
    """Arm joint values putting ``arm``'s tool frame at ``target`` (4x4 world pose), or None.

    Tries the arm configuration of ``q_start`` first, then ``attempts - 1`` random
    seeds.  Solutions are within joint limits (continuous joints wrapped to
    (-pi, pi]) and within ``tol_pos`` metres / ``tol_rot`` radians of the target.
    With ``world``, solutions whose arm or held object collides (checked with
    ``world.in_collision(..., group=arm + "_arm")``, honouring ``ignore`` and
    ``movables``) are rejected.  Targets beyond the arm's reach return None at once.
    """
    ik = arm_ik(robot, arm)
    goal = ik.target_in_model(robot, q_start, target)
    if np.linalg.norm(goal.translation - ik.shoulder) > ik.reach + tol_pos:
        return None
    rng = np.random.default_rng() if rng is None else rng
    full_group = robot.group(ik.group_name)
    ignore = frozenset(ignore)
    seed = full_group.get(q_start)
    for attempt in range(attempts):
        deadlines.check()  # restarts are counted; the run's time limit only cuts them short
        if attempt:
            seed = ik.group.sample(rng)
        solution = ik.clik(goal, seed, tol_pos, tol_rot, max_iters)
        if solution is None:
            continue
        if world is not None and world.in_collision(full_group.set(q_start, solution), ignore=ignore,
                                                    movables=movables, group=ik.group_name):
            continue
        return solution
    return None
