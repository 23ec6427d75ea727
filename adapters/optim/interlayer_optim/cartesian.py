"""``ik:cartesian``: straight-line end-effector motion by differential inverse kinematics.

The tool moves on the straight line (and the rotation on the geodesic) from its pose at the query's
start to its pose at the query's goal, in steps of ``step`` metres / ``rot_step`` radians. Each step
is reached by damped-least-squares IK on the query's tool Jacobian (``MotionQuery.tool``), with joint
limits and a null-space pull towards the joint-space line from start to goal, so that a redundant
arm (the PR2's 7 joints) ends next to the goal configuration; a last short joint-space blend lands
exactly on it. Every configuration, and the way between two, is collision-checked.
"""
from __future__ import annotations

import math

import numpy as np

from interlayer import deadline as deadlines
from interlayer.errors import UserError
from interlayer.motion import MotionPlanner, segment_valid


def rotation_log(R) -> np.ndarray:
    import pinocchio as pin

    return pin.log3(np.ascontiguousarray(R))


def rotation_exp(w) -> np.ndarray:
    import pinocchio as pin

    return pin.exp3(np.asarray(w, float))


class CartesianPlanner(MotionPlanner):
    """Options: ``step`` (m between IK targets), ``rot_step`` (rad), ``tolerance`` (m from each
    target; rotations within 0.01 rad), ``blend`` (largest joint-space distance of the final blend
    onto the goal configuration)."""

    searches = False  # the tool's straight line: a joint-space line is no answer

    def __init__(self, time_limit=1.0, step=0.005, rot_step=0.02, tolerance=1e-3, blend=0.1, options=None):
        super().__init__(name="ik:cartesian", time_limit=time_limit, options=dict(options or {}))
        self.step, self.rot_step, self.tolerance, self.blend = step, rot_step, tolerance, blend

    def _solve(self, query, relaxed, time_limit):
        if query.tool is None:
            raise UserError(f"The motion planner 'ik:cartesian' needs end-effector kinematics, which the query "
                            f"'{query.label}' does not provide; use it as planner.cartesian (approach and retreat "
                            f"segments) or pick an OMPL planner or trajopt for planner.motion.")
        return self.cartesian_path(query.space, query.start, query.goal, query.tool, query.check(relaxed))

    def cartesian_path(self, space, start, goal, tool, is_valid):
        start, goal = np.asarray(start, float), np.asarray(goal, float)
        (T0, _), (T1, _) = tool(start), tool(goal)
        p0, p1 = T0[:3, 3], T1[:3, 3]
        R0 = T0[:3, :3]
        turn = rotation_log(R0.T @ T1[:3, :3])  # in the start tool frame
        n = max(1, math.ceil(max(np.linalg.norm(p1 - p0) / self.step, np.linalg.norm(turn) / self.rot_step)))
        bias = space.difference(start, goal)
        linear = ~np.asarray(space.circular, bool)
        lower, upper = np.asarray(space.lower, float), np.asarray(space.upper, float)
        path, v = [start], start.copy()
        for k in range(1, n + 1):
            deadlines.check()
            s = k / n
            target_p, target_R = p0 + s * (p1 - p0), R0 @ rotation_exp(s * turn)
            v = self._reach(tool, v, target_p, target_R, start + s * bias, lower, upper, linear)
            if v is None or not segment_valid(space, path[-1], v, is_valid):
                return None
            path.append(v)
        if space.distance(v, goal) > self.blend or not segment_valid(space, v, goal, is_valid):
            return None  # the line ends in another arm configuration than the goal's
        if space.distance(v, goal) > 1e-9:
            path.append(goal)
        return path

    def _reach(self, tool, v, target_p, target_R, rest, lower, upper, linear, iters=30, damping=1e-4):
        """Configuration near ``v`` putting the tool at (target_p, target_R), or None."""
        tol_rot = 0.01
        for _ in range(iters):
            T, J = tool(v)
            err = np.concatenate([target_p - T[:3, 3], T[:3, :3] @ rotation_log(T[:3, :3].T @ target_R)])
            if np.linalg.norm(err[:3]) < self.tolerance and np.linalg.norm(err[3:]) < tol_rot:
                return v
            JJt = J @ J.T + damping * np.eye(6)
            pinv = J.T @ np.linalg.inv(JJt)
            dv = pinv @ err + (np.eye(len(v)) - pinv @ J) @ (0.5 * (rest - v))
            biggest = np.abs(dv).max()
            if biggest > 0.2:
                dv *= 0.2 / biggest
            moved = v + dv
            moved[linear] = np.clip(moved[linear], lower[linear], upper[linear])
            if np.abs(moved - v).max() < 1e-9:
                return None  # stuck against a joint limit
            v = moved
        return None
