"""Joint groups: degrees of freedom moved together, in vector coordinates, and pose conversions.

``q`` is Pinocchio's configuration (planar root and continuous joints as cos/sin); a "vector" has one
float per degree of freedom (see robot.py).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from functools import cached_property
from typing import Sequence

import numpy as np
import pinocchio as pin

__all__ = ["JointGroup", "joint_group", "as_matrix", "as_se3"]


def as_matrix(pose) -> np.ndarray:
    """4x4 float copy of a pose given as a 4x4 array-like or a ``pin.SE3``."""
    if isinstance(pose, pin.SE3):
        return pose.homogeneous.copy()
    mat = np.array(pose, dtype=float)
    if mat.shape != (4, 4):
        raise ValueError(f"pose must be 4x4, got shape {mat.shape}")
    return mat


_EYE3 = np.eye(3)
_ORTHO_TOL = 1e-6 + 1e-5 * _EYE3  # np.allclose's atol + rtol * |expected|


def _det3(m) -> float:
    (a, b, c), (d, e, f), (g, h, i) = m
    return a * (e * i - f * h) - b * (d * i - f * g) + c * (d * h - e * g)


def as_se3(pose) -> pin.SE3:
    """``pin.SE3`` from a 4x4 array-like (or an SE3, copied); rejects non-rigid matrices."""
    if isinstance(pose, pin.SE3):
        return pin.SE3(pose)
    mat = as_matrix(pose)
    rot = mat[:3, :3]
    # np.allclose(rot.T @ rot, I, atol=1e-6) and det >= 0, spelled out: this runs on every object pose update
    if not (np.abs(rot.T @ rot - _EYE3) <= _ORTHO_TOL).all() or _det3(rot.tolist()) < 0:
        raise ValueError("pose rotation is not a rotation matrix")
    return pin.SE3(np.ascontiguousarray(rot), mat[:3, 3].copy())


def _frozen(values) -> np.ndarray:
    arr = np.array(values, dtype=float)
    arr.flags.writeable = False
    return arr


@dataclass(frozen=True, eq=False)
class JointGroup:
    """Degrees of freedom moved together, in vector coordinates (one float per DOF).

    ``circular[i]`` marks an angle on the circle (planar heading, continuous
    joints): it is stored as (cos, sin) in ``q``, reads back wrapped to
    (-pi, pi], and its bounds are (-pi, pi) only nominally -- any angle is valid.
    """

    name: str
    dof_names: tuple[str, ...]
    lower: np.ndarray
    upper: np.ndarray
    circular: tuple[bool, ...]
    joint_ids: tuple[int, ...]  # Pinocchio joints the group drives
    _linear: tuple[tuple[int, int, float], ...]  # (q index, dof index, multiplier)
    _angular: tuple[tuple[int, int], ...]  # (q index of cos, dof index)

    @property
    def dof(self) -> int:
        return len(self.dof_names)

    @property
    def circular_indices(self) -> tuple[int, ...]:
        return tuple(i for i, c in enumerate(self.circular) if c)

    def get(self, q) -> np.ndarray:
        """Group vector read from ``q`` (angles wrapped to (-pi, pi])."""
        out = np.zeros(self.dof)  # (a fixed gripper's DOF is written by no joint: 0)
        for qi, di, mult in self._linear:
            out[di] = q[qi] / mult
        for qi, di in self._angular:
            out[di] = math.atan2(q[qi + 1], q[qi])
        return out

    def write(self, q: np.ndarray, values) -> None:
        """Write ``values`` into ``q`` in place (hot path: plain loops beat numpy on 7 floats)."""
        if type(values) is np.ndarray:
            values = values.tolist()  # Python floats: the same values, read faster than numpy scalars
        for qi, di, mult in self._linear:
            q[qi] = values[di] * mult
        for qi, di in self._angular:
            a = values[di]
            q[qi] = math.cos(a)
            q[qi + 1] = math.sin(a)

    def set(self, q, values) -> np.ndarray:
        """Copy of ``q`` with the group set to ``values``."""
        if len(values) != self.dof:
            raise ValueError(f"{self.name}: expected {self.dof} values, got {len(values)}")
        out = np.array(q, dtype=float)
        self.write(out, values)
        return out

    def within_bounds(self, values, tol: float = 1e-9) -> bool:
        """True if every non-circular value lies within [lower, upper] (+tol)."""
        # hot path (every collision check of a planner): plain comparisons of Python floats beat numpy on 7
        if type(values) is np.ndarray:
            values = values.tolist()
        for i, lo, hi in self._bounded:
            if not lo - tol <= values[i] <= hi + tol:
                return False
        return True

    @cached_property
    def _bounded(self) -> tuple[tuple[int, float, float], ...]:
        """(index, lower, upper) of each non-circular value."""
        return tuple((i, float(self.lower[i]), float(self.upper[i])) for i, c in enumerate(self.circular) if not c)

    def wrap(self, values) -> np.ndarray:
        """Copy with circular entries wrapped to (-pi, pi]."""
        v = np.array(values, dtype=float)
        for i in self.circular_indices:
            v[i] = math.atan2(math.sin(v[i]), math.cos(v[i]))
        return v

    def sample(self, rng: np.random.Generator) -> np.ndarray:
        """Uniform sample within bounds (circular: uniform angle)."""
        return rng.uniform(self.lower, self.upper)


def joint_group(model: pin.Model, name: str, joints: Sequence[str],
                planar_limits=((-5.0, 5.0), (-5.0, 5.0))) -> JointGroup:
    """Group over 1-DOF joints (revolute, prismatic, continuous) and/or a planar joint (x, y, theta)."""
    lower, upper, circular, dof_names, linear, angular, ids = [], [], [], [], [], [], []
    for jname in joints:
        jid = model.getJointId(jname)
        if jid >= model.njoints:
            raise KeyError(f"unknown joint {jname!r}")
        joint = model.joints[jid]
        ids.append(jid)
        if joint.shortname() == "JointModelPlanar":
            for k, (n, (lo, hi)) in enumerate(zip(("x", "y"), planar_limits)):
                linear.append((joint.idx_q + k, len(dof_names), 1.0))
                dof_names.append(n); lower.append(lo); upper.append(hi); circular.append(False)
            angular.append((joint.idx_q + 2, len(dof_names)))
            dof_names.append("theta"); lower.append(-math.pi); upper.append(math.pi); circular.append(True)
        elif joint.nq == 2 and joint.nv == 1:  # continuous (JointModelRUB*): cos, sin
            angular.append((joint.idx_q, len(dof_names)))
            dof_names.append(jname); lower.append(-math.pi); upper.append(math.pi); circular.append(True)
        elif joint.nq == 1:
            linear.append((joint.idx_q, len(dof_names), 1.0))
            dof_names.append(jname); circular.append(False)
            lower.append(model.lowerPositionLimit[joint.idx_q])
            upper.append(model.upperPositionLimit[joint.idx_q])
        else:
            raise NotImplementedError(f"joint {jname} of type {joint.shortname()}")
    return JointGroup(name, tuple(dof_names), _frozen(lower), _frozen(upper), tuple(circular),
                      tuple(ids), tuple(linear), tuple(angular))
