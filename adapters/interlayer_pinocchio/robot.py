"""PR2 kinematics on Pinocchio: joint groups, vector <-> q conversion, tool frames, gripper.

Two coordinate systems are used on purpose:

* ``q`` -- Pinocchio's configuration (``model.nq`` = 38 floats).  The planar
  root joint is stored as ``(x, y, cos th, sin th)`` and the continuous forearm
  and wrist roll joints as ``(cos a, sin a)``.  Collision checks and forward
  kinematics take ``q``.
* "vector" -- one float per degree of freedom (``model.nv`` = 33 floats), angles
  in radians for continuous joints, ordered like Pinocchio's velocity vector.
  Planners and samplers work in vectors (per group: see :class:`JointGroup`).
"""

from __future__ import annotations

import importlib.metadata
import math
from dataclasses import dataclass
from functools import cached_property
from pathlib import Path
from typing import Sequence

import numpy as np
import pinocchio as pin

__all__ = ["ARMS", "TUCKED_ARMS", "JointGroup", "PR2", "joint_group", "pr2_resources", "as_matrix", "as_se3"]

ARMS = ("left", "right")
_SIDE = {"left": "l", "right": "r"}
ARM_JOINT_SUFFIXES = (
    "shoulder_pan", "shoulder_lift", "upper_arm_roll", "elbow_flex",
    "forearm_roll", "wrist_flex", "wrist_roll",
)
# Joints that open the gripper together (URDF mimics of ``*_gripper_l_finger_joint``).
_GRIPPER_MIMICS = (
    "l_finger", "r_finger", "l_finger_tip", "r_finger_tip", "l_parallel_root", "r_parallel_root",
)

# SRDF group states ``tuck_left_arm`` / ``tuck_right_arm`` (pr2.srdf).  With both
# arms tucked the forearm meshes interpenetrate, so the right shoulder lift is
# lowered by 0.15 rad (1.10728 -> 0.95728): >= 1 cm self-clearance at every
# torso height, everything stays within 4 cm of the base footprint.
TUCKED_ARMS = {
    "left": (0.06024, 1.24853, 1.78907, -1.68339, -1.73434, -0.0962141, -0.0864407),
    "right": (-0.023593, 0.95728, -1.55669, -2.12441, -1.4175, -1.8417, 0.21436),
}


def pr2_resources() -> tuple[Path, Path, tuple[str, ...]]:
    """(urdf, srdf, package_dirs) shipped by the example-robot-data wheel; never hard-coded."""
    dist = importlib.metadata.distribution("example-robot-data")
    share = Path(dist.locate_file("cmeel.prefix/share"))
    robot_dir = share / "example-robot-data" / "robots" / "pr2_description"
    return robot_dir / "urdf" / "pr2.urdf", robot_dir / "srdf" / "pr2.srdf", (str(share),)


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
        out = np.empty(self.dof)
        for qi, di, mult in self._linear:
            out[di] = q[qi] / mult
        for qi, di in self._angular:
            out[di] = math.atan2(q[qi + 1], q[qi])
        return out

    def write(self, q: np.ndarray, values) -> None:
        """Write ``values`` into ``q`` in place (hot path: plain loops beat numpy on 7 floats)."""
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
        # hot path (every collision check of a planner): plain comparisons beat numpy on 7 floats
        return all(lo - tol <= values[i] <= hi + tol for i, lo, hi in self._bounded)

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


class PR2:
    """The PR2 of example-robot-data with a planar base and a torso held at a fixed height.

    Groups: ``base`` (x, y, theta), ``left_arm`` / ``right_arm`` (7 joints,
    shoulder_pan ... wrist_roll), ``left_gripper`` / ``right_gripper`` (1 DOF:
    the finger joint angle in rad, applied to all six mimic joints).  The torso,
    head and laser tilt are in no group: they keep their ``q`` values, and every
    helper here writes the configured torso height into fresh configurations.

    Not thread-safe: it owns one ``pin.Data`` used by the FK helpers.
    """

    def __init__(self, torso_height: float = 0.2,
                 base_limits: tuple[tuple[float, float], tuple[float, float]] = ((-5.0, 5.0), (-5.0, 5.0))):
        urdf, srdf, package_dirs = pr2_resources()
        self.urdf_path, self.srdf_path, self.package_dirs = urdf, srdf, package_dirs
        self.model, self.collision_model = pin.buildModelsFromUrdf(
            str(urdf), package_dirs=list(package_dirs), root_joint=pin.JointModelPlanar(),
            geometry_types=[pin.GeometryType.COLLISION])
        self.data = self.model.createData()
        self.collision_model.addAllCollisionPairs()
        pin.removeCollisionPairs(self.model, self.collision_model, str(srdf))
        for obj in self.collision_model.geometryObjects:
            obj.geometry.computeLocalAABB()  # broadphase ignores geometries with an empty AABB

        torso = self.model.joints[self.model.getJointId("torso_lift_joint")]
        lo, hi = self.model.lowerPositionLimit[torso.idx_q], self.model.upperPositionLimit[torso.idx_q]
        if not lo <= torso_height <= hi:
            raise ValueError(f"torso_height {torso_height} outside [{lo}, {hi}]")
        self.torso_height = float(torso_height)
        self._torso_q = torso.idx_q
        self.base_limits = (tuple(map(float, base_limits[0])), tuple(map(float, base_limits[1])))

        self.groups: dict[str, JointGroup] = {
            "base": joint_group(self.model, "base", ["root_joint"], self.base_limits)}
        for arm in ARMS:
            s = _SIDE[arm]
            self.groups[f"{arm}_arm"] = joint_group(
                self.model, f"{arm}_arm", [f"{s}_{j}_joint" for j in ARM_JOINT_SUFFIXES])
            self.groups[f"{arm}_gripper"] = self._gripper_group(arm)
        every_joint = [self.model.names[j] for j in range(1, self.model.njoints)]
        self._all = joint_group(self.model, "all", every_joint, self.base_limits)
        self._tool_frames = {arm: self.model.getFrameId(f"{_SIDE[arm]}_gripper_tool_frame") for arm in ARMS}
        self._visual = None

    # -- groups -----------------------------------------------------------------------------
    def moving_joints(self, group: str) -> frozenset[int]:
        """Joint ids whose world placement changes when ``group`` moves (its joints and descendants)."""
        moving = set(self.group(group).joint_ids)
        for j in range(1, self.model.njoints):  # parents precede children in Pinocchio
            if self.model.parents[j] in moving:
                moving.add(j)
        return frozenset(moving)

    def _gripper_group(self, arm: str) -> JointGroup:
        """One DOF (finger angle) driving the six mimic joints.

        The URDF gives ``*_r_parallel_root_joint`` multiplier -1, which would leave its
        [0, 0.548] limit; that link has no geometry, so it simply gets +angle like the others.
        """
        s = _SIDE[arm]
        names = [f"{s}_gripper_{j}_joint" for j in _GRIPPER_MIMICS]
        ids = [self.model.getJointId(n) for n in names]
        qidx = [self.model.joints[j].idx_q for j in ids]
        lo, hi = self.model.lowerPositionLimit[qidx[0]], self.model.upperPositionLimit[qidx[0]]
        return JointGroup(f"{arm}_gripper", (names[0],), _frozen([lo]), _frozen([hi]), (False,),
                          tuple(ids), tuple((qi, 0, 1.0) for qi in qidx), ())

    def group(self, name: str) -> JointGroup:
        try:
            return self.groups[name]
        except KeyError:
            raise KeyError(f"unknown group {name!r}; known: {sorted(self.groups)}") from None

    def get(self, q, group: str) -> np.ndarray:
        return self.group(group).get(q)

    def set(self, q, group: str, values) -> np.ndarray:
        return self.group(group).set(q, values)

    # -- vector <-> q -------------------------------------------------------------------------
    @property
    def vector_names(self) -> tuple[str, ...]:
        """Names of the ``model.nv`` vector entries (base: x, y, theta; then joint names)."""
        return self._all.dof_names

    def q_to_vector(self, q) -> np.ndarray:
        """Full configuration -> one float per DOF (angles wrapped to (-pi, pi])."""
        return self._all.get(q)

    def vector_to_q(self, vector) -> np.ndarray:
        """One float per DOF -> Pinocchio ``q`` (angles become cos/sin)."""
        if len(vector) != self.model.nv:
            raise ValueError(f"expected {self.model.nv} values, got {len(vector)}")
        q = pin.neutral(self.model)
        self._all.write(q, vector)
        return q

    # -- reference configurations ---------------------------------------------------------
    def neutral_q(self) -> np.ndarray:
        """All joints at zero (arms stretched forward), torso at ``torso_height``, base at origin."""
        q = pin.neutral(self.model)
        q[self._torso_q] = self.torso_height
        return q

    def default_q(self, base=(0.0, 0.0, 0.0)) -> np.ndarray:
        """Driving configuration: both arms tucked (:data:`TUCKED_ARMS`), grippers closed."""
        q = self.neutral_q()
        self.groups["base"].write(q, base)
        for arm in ARMS:
            self.groups[f"{arm}_arm"].write(q, TUCKED_ARMS[arm])
        return q

    def random_q(self, rng: np.random.Generator, q=None,
                 groups=("base", "left_arm", "right_arm")) -> np.ndarray:
        """``q`` (default: :meth:`default_q`) with ``groups`` sampled uniformly within bounds.

        Use instead of ``pin.randomConfiguration``: the planar root has infinite limits.
        """
        out = self.default_q() if q is None else np.array(q, dtype=float)
        for g in groups:
            self.groups[g].write(out, self.groups[g].sample(rng))
        return out

    # -- kinematics ---------------------------------------------------------------------------
    def tool_frame(self, arm: str) -> str:
        """Name of the tool frame (between the finger pads, x pointing out of the gripper)."""
        return f"{_SIDE[arm]}_gripper_tool_frame"

    def tool_pose(self, q, arm: str) -> np.ndarray:
        """World pose (4x4) of ``{l,r}_gripper_tool_frame`` at ``q``."""
        fid = self._tool_frames[arm]
        pin.forwardKinematics(self.model, self.data, np.asarray(q, dtype=float))
        return pin.updateFramePlacement(self.model, self.data, fid).homogeneous.copy()

    def frame_pose(self, q, frame: str) -> np.ndarray:
        """World pose (4x4) of any URDF link/frame at ``q``."""
        fid = self.model.getFrameId(frame)
        if fid >= self.model.nframes:
            raise KeyError(f"unknown frame {frame!r}")
        pin.forwardKinematics(self.model, self.data, np.asarray(q, dtype=float))
        return pin.updateFramePlacement(self.model, self.data, fid).homogeneous.copy()

    def tool_jacobian(self, q, arm: str) -> tuple[np.ndarray, np.ndarray]:
        """(world pose 4x4, 6 x 7 Jacobian) of ``arm``'s tool frame at ``q``: the frame's linear and
        angular velocity in world axes per arm-joint velocity."""
        fid = self._tool_frames[arm]
        J = pin.computeFrameJacobian(self.model, self.data, np.asarray(q, dtype=float), fid,
                                     pin.ReferenceFrame.LOCAL_WORLD_ALIGNED)
        cols = [self.model.joints[j].idx_v for j in self.groups[f"{arm}_arm"].joint_ids]
        return self.data.oMf[fid].homogeneous.copy(), J[:, cols]

    def velocity_limits(self, group: str) -> np.ndarray:
        """The URDF's velocity limit of each joint of ``group`` (rad/s or m/s; inf if none)."""
        lim = []
        for j in self.group(group).joint_ids:
            joint = self.model.joints[j]
            lim += list(self.model.velocityLimit[joint.idx_v:joint.idx_v + joint.nv])
        return np.array([v if v < 1e300 else np.inf for v in lim])

    @staticmethod
    def base_pose(q) -> np.ndarray:
        """World pose (4x4) of ``base_footprint`` (z = 0) from the planar root entries of ``q``."""
        c, s = q[2], q[3]
        return np.array([[c, -s, 0.0, q[0]], [s, c, 0.0, q[1]], [0.0, 0.0, 1.0, 0.0], [0.0, 0.0, 0.0, 1.0]])

    def collision_links(self, group: str | None = None) -> tuple[str, ...]:
        """Collision geometry names (link name + ``_0``) that move with ``group`` (None: all)."""
        moving = None if group is None else self.moving_joints(group)
        return tuple(g.name for g in self.collision_model.geometryObjects
                     if moving is None or g.parentJoint in moving)

    def gripper_links(self, arm: str) -> tuple[str, ...]:
        """Collision geometries of the hand (palm, fingers, finger tips): a held object may touch them."""
        return tuple(g.name for g in self.collision_model.geometryObjects
                     if g.name.startswith(f"{_SIDE[arm]}_gripper_"))

    # -- gripper --------------------------------------------------------------------------------
    @cached_property
    def _pad_gap_table(self) -> tuple[np.ndarray, np.ndarray]:
        """Finger angle -> pad gap samples, measured on the collision meshes (see max_gripper_opening)."""
        s = "l"
        group = self.groups["left_gripper"]
        angles = np.linspace(group.lower[0], group.upper[0], 56)
        palm = self.model.getFrameId(f"{s}_gripper_palm_link")
        geoms = {side: self.collision_model.geometryObjects[
            self.collision_model.getGeometryId(f"{s}_gripper_{side}_finger_tip_link_0")] for side in "lr"}
        verts = {side: np.array(g.geometry.vertices()) for side, g in geoms.items()}
        gaps = []
        for a in angles:
            q = group.set(self.neutral_q(), [a])
            pin.framesForwardKinematics(self.model, self.data, q)
            palm_inv = self.data.oMf[palm].inverse()
            y = {}
            for side, g in geoms.items():
                m = palm_inv * self.data.oMi[g.parentJoint] * g.placement  # mesh -> palm frame
                y[side] = verts[side] @ m.rotation[1] + m.translation[1]
            gaps.append(y["l"].min() - y["r"].max())
        return angles, np.array(gaps)

    @property
    def max_gripper_opening(self) -> float:
        """Largest gap (m) between the inner finger-pad surfaces, finger joint at its upper limit.

        Measured, not quoted: the two finger-tip collision meshes are placed by FK at
        the limit (0.548 rad) and expressed in the palm frame, whose y axis is the
        closing direction.  The tips stay parallel to the palm (tip joint = -finger
        joint), so the gap is min y over the left-tip vertices minus max y over the
        right-tip vertices; it agrees with ``coal.distance`` between the two tip meshes.
        About 0.092 m: a 0.10 m wide object does not fit.
        """
        return float(self._pad_gap_table[1][-1])

    def gripper_opening(self, q, arm: str) -> float:
        """Pad gap (m) at the finger angle stored in ``q`` (negative when closed: pads overlap ~2 mm)."""
        angles, gaps = self._pad_gap_table
        return float(np.interp(self.groups[f"{arm}_gripper"].get(q)[0], angles, gaps))

    def set_gripper_opening(self, q, arm: str, width: float) -> np.ndarray:
        """Copy of ``q`` with the pads ``width`` m apart (clipped to [closed, max_gripper_opening])."""
        angles, gaps = self._pad_gap_table
        angle = float(np.interp(width, gaps, angles))  # gap is increasing in the angle
        return self.groups[f"{arm}_gripper"].set(q, [angle])

    def open_gripper(self, q, arm: str) -> np.ndarray:
        g = self.groups[f"{arm}_gripper"]
        return g.set(q, [g.upper[0]])

    def close_gripper(self, q, arm: str) -> np.ndarray:
        g = self.groups[f"{arm}_gripper"]
        return g.set(q, [g.lower[0]])

    # -- visuals ------------------------------------------------------------------------------
    def visual_model(self) -> tuple[pin.GeometryModel, tuple[str, ...]]:
        """(visual GeometryModel, package_dirs), loaded on first call, for viewers (meshcat...)."""
        if self._visual is None:
            self._visual = pin.buildGeomFromUrdf(self.model, str(self.urdf_path), pin.GeometryType.VISUAL,
                                                 package_dirs=list(self.package_dirs))
        return self._visual, self.package_dirs
