"""Any robot's kinematics on Pinocchio, built from its description: joint groups, vector <-> q, tool frames, gripper.

Two coordinate systems are used on purpose:

* ``q`` -- Pinocchio's configuration (``model.nq`` floats, 38 for the PR2).  The planar
  root joint is stored as ``(x, y, cos th, sin th)`` and the continuous forearm
  and wrist roll joints as ``(cos a, sin a)``.  Collision checks and forward
  kinematics take ``q``.
* "vector" -- one float per degree of freedom (``model.nv`` floats, 33 for the PR2), angles
  in radians for continuous joints, ordered like Pinocchio's velocity vector.
  Planners and samplers work in vectors (per group: see :class:`JointGroup`).
"""

from __future__ import annotations

import math

import numpy as np
import pinocchio as pin

from .joints import JointGroup, _frozen, as_matrix, as_se3, joint_group

__all__ = ["JointGroup", "Robot", "joint_group", "as_matrix", "as_se3"]


class Robot:
    """A robot built from its description (see :mod:`.description`): every robot gets a planar root
    joint (its root link stands at the base pose ``(x, y, theta)``; ``mobile`` says whether it may drive).

    Groups: ``base`` (x, y, theta), ``{arm}_arm`` (the arm's joints) and ``{arm}_gripper`` (one DOF driving
    the finger joints with their multipliers) per arm, ``arm`` being a name of :attr:`arms`.  Joints in
    no group keep their ``q`` values: every helper here writes the held values into fresh configurations.
    Tool poses are those of a canonical frame per arm, fixed to the description's tool frame and rotated
    so that its x axis is the approach axis (out of the hand) and its y axis the closing axis.

    Not thread-safe: it owns one ``pin.Data`` used by the FK helpers.
    """

    @classmethod
    def load(cls, name_or_path="pr2", **overrides) -> "Robot":
        """A shipped robot by name (``"pr2"``) or the description at a path; ``overrides``: see ``__init__``."""
        from .description import describe

        return cls(describe(name_or_path), **overrides)

    def __init__(self, description, torso_height: float | None = None,
                 base_limits: tuple[tuple[float, float], tuple[float, float]] = ((-5.0, 5.0), (-5.0, 5.0)),
                 hold: dict[str, float] | None = None, base_height: float | None = None):
        """``torso_height`` overrides the held value of the description's torso joint, ``hold`` those of
        any held joints, ``base_height`` the description's ``base.height``; ``base_limits`` bound the base's
        x and y (m)."""
        from interlayer.errors import UserError

        from .description import check_names, urdf_text
        from .meshes import hull_big_meshes
        from .selfcollision import skip_pairs

        desc = self.description = description
        self.urdf_path, self.srdf_path, self.package_dirs = desc.urdf, desc.srdf, desc.package_dirs
        text, self.unfixed_joints = urdf_text(desc)  # None: the file as it is
        if text is None:
            self.model, self.collision_model = pin.buildModelsFromUrdf(
                str(desc.urdf), package_dirs=list(desc.package_dirs), root_joint=pin.JointModelPlanar(),
                geometry_types=[pin.GeometryType.COLLISION])
        else:  # the geometries hang on links, which keep their names: read from the file (relative mesh paths)
            self.model = pin.buildModelFromXML(text, pin.JointModelPlanar())
            self.collision_model = pin.buildGeomFromUrdf(self.model, str(desc.urdf), pin.GeometryType.COLLISION,
                                                         package_dirs=list(desc.package_dirs))
        check_names(desc, self.model, self.collision_model)
        hull_big_meshes(self.collision_model)  # before the self-collision pairs are sampled against them
        self.base_height = float(desc.base_height if base_height is None else base_height)
        if self.base_height:  # the root link stands on a mount: the planar joint is placed that high
            self.model.jointPlacements[1] = pin.SE3(np.eye(3), np.array([0.0, 0.0, self.base_height]))
        self.arms = tuple(a.name for a in desc.arms)
        self.mobile = desc.mobile
        self._arm = {a.name: a for a in desc.arms}
        self._tool_frames = {a.name: self._add_tool_frame(i, a) for i, a in enumerate(desc.arms)}
        self.data = self.model.createData()

        held = dict(desc.hold)
        held.update(hold or {})
        if torso_height is not None:
            if desc.torso is None:
                raise UserError(f"{desc.where('robot.torso')}: the {desc.name} has no torso to set the height of")
            held[desc.torso] = torso_height
        self._held = []  # (q index, value) written into every fresh configuration
        for jname, value in held.items():
            jid = self.model.getJointId(jname)
            if jid >= self.model.njoints or self.model.joints[jid].nq != 1:
                raise UserError(f"{desc.where(f'hold.{jname}')}: no single-valued joint {jname!r} in the URDF")
            qi = self.model.joints[jid].idx_q
            lo, hi = self.model.lowerPositionLimit[qi], self.model.upperPositionLimit[qi]
            if not lo <= value <= hi:
                field = "torso_height" if jname == desc.torso else f"hold.{jname}"
                raise UserError(f"{desc.where(field)}: {value} is outside {jname}'s range [{lo:.4g}, {hi:.4g}]")
            self._held.append((qi, float(value)))
        self.torso_height = None if desc.torso is None else float(held[desc.torso])
        self.base_limits = (tuple(map(float, base_limits[0])), tuple(map(float, base_limits[1])))

        self.groups: dict[str, JointGroup] = {
            "base": joint_group(self.model, "base", ["root_joint"], self.base_limits)}
        for k, a in enumerate(desc.arms):
            g = self.groups[f"{a.name}_arm"] = joint_group(self.model, f"{a.name}_arm", list(a.joints))
            self.groups[f"{a.name}_gripper"] = self._gripper_group(a)
            for field, values in (("home", a.home), ("reach_seed", a.reach_seed or a.home)):
                for i, (v, lo, hi, circ) in enumerate(zip(values, g.lower, g.upper, g.circular)):
                    if not circ and not lo - 1e-9 <= v <= hi + 1e-9:
                        raise UserError(f"{desc.where(f'arms[{k}].{field}[{i}]')}: {v} is outside {a.joints[i]}'s "
                                        f"range [{lo:.4g}, {hi:.4g}]")
        self._postures = {a.name: (self._posture(a, a.home), self._posture(a, a.reach_seed or a.home)) for a in desc.arms}
        every_joint = [self.model.names[j] for j in range(1, self.model.njoints)]
        self._all = joint_group(self.model, "all", every_joint, self.base_limits)
        self._neutral = pin.neutral(self.model)
        for j in range(2, self.model.njoints):  # joints in no group rest at 0, or mid-range when 0 is outside
            joint = self.model.joints[j]
            if joint.nq == 1:
                lo, hi = self.model.lowerPositionLimit[joint.idx_q], self.model.upperPositionLimit[joint.idx_q]
                if not lo <= 0.0 <= hi:
                    self._neutral[joint.idx_q] = 0.5 * (lo + hi)
        for qi, value in self._held:
            self._neutral[qi] = value
        self._visual = None
        self.collision_model.addAllCollisionPairs()
        self.self_collision_source = skip_pairs(self)  # removes the pairs never checked
        for obj in self.collision_model.geometryObjects:
            obj.geometry.computeLocalAABB()  # broadphase ignores geometries with an empty AABB

    def _add_tool_frame(self, index: int, arm) -> int:
        """The canonical tool frame of ``arm``: x = approach axis, y = closing axis (the PR2's: identity)."""
        model = self.model
        fid = model.getFrameId(arm.tool_frame)
        x, y = np.array(arm.approach), np.array(arm.closing)
        rot = np.column_stack([x, y, np.cross(x, y)])
        frame = model.frames[fid]
        return model.addFrame(pin.Frame(f"interlayer_tool_{index}", frame.parentJoint, fid,
                                        frame.placement * pin.SE3(rot, np.array(arm.tool_offset, dtype=float)),
                                        pin.FrameType.OP_FRAME))

    # -- groups -----------------------------------------------------------------------------
    def moving_joints(self, group: str) -> frozenset[int]:
        """Joint ids whose world placement changes when ``group`` moves (its joints and descendants)."""
        moving = set(self.group(group).joint_ids)
        for j in range(1, self.model.njoints):  # parents precede children in Pinocchio
            if self.model.parents[j] in moving:
                moving.add(j)
        return frozenset(moving)

    def _gripper_group(self, arm) -> JointGroup:
        """One DOF driving the finger joints, each at its multiplier times the DOF; the DOF's range keeps
        every finger joint within its limits.  No joints (fixed fingers): a DOF driving nothing, range [0, 0]."""
        ids, linear = [], []
        lo, hi = (-np.inf, np.inf) if arm.gripper.joints else (0.0, 0.0)
        for jname, mult in arm.gripper.joints:
            jid = self.model.getJointId(jname)
            joint = self.model.joints[jid]
            if joint.nq != 1:
                from interlayer.errors import UserError

                raise UserError(f"{self.description.where(f'arms.gripper.joints.{jname}')}: {jname!r} is not a "
                                "revolute or prismatic joint")
            a, b = self.model.lowerPositionLimit[joint.idx_q] / mult, self.model.upperPositionLimit[joint.idx_q] / mult
            lo, hi = max(lo, min(a, b)), min(hi, max(a, b))
            ids.append(jid)
            linear.append((joint.idx_q, 0, float(mult)))
        name = arm.gripper.joints[0][0] if arm.gripper.joints else f"{arm.name}_gripper"
        return JointGroup(f"{arm.name}_gripper", (name,), _frozen([lo]), _frozen([hi]), (False,),
                          tuple(ids), tuple(linear), ())

    def arm_of(self, group: str) -> str | None:
        """The arm a group belongs to (``{arm}_arm``, ``{arm}_gripper``; arm names may contain ``_``), or None."""
        return next((a for a in self.arms if group in (f"{a}_arm", f"{a}_gripper")), None)

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

    # -- the description's postures -------------------------------------------------------------
    def home(self, arm: str) -> tuple[float, ...]:
        """The arm's resting / driving posture (arm vector)."""
        return self._postures[arm][0]

    def reach_seed(self, arm: str) -> tuple[float, ...]:
        """The first IK seed for reaching forward at table height (default: home)."""
        return self._postures[arm][1]

    def _posture(self, arm, values) -> tuple[float, ...]:
        """``values`` with a continuous joint's angle outside (-pi, pi] wrapped into it: arm spaces bound those
        joints to [-pi, pi] (Kinova's own home posture has 4.80 rad: a planner refused it as a goal)."""
        circular = self.groups[f"{arm.name}_arm"].circular
        return tuple(math.atan2(math.sin(v), math.cos(v)) if c and not -math.pi < v <= math.pi else float(v)
                     for v, c in zip(values, circular))

    def carry_poses(self, arm: str) -> tuple[tuple[float, float, float, float], ...]:
        """Tool poses (x, y, z, yaw) in the base frame to carry an object in, tried in order (may be empty)."""
        return self._arm[arm].carry

    # -- reference configurations ---------------------------------------------------------
    def neutral_q(self) -> np.ndarray:
        """Every joint at zero (or mid-range), held joints at their values, base at the origin."""
        return self._neutral.copy()

    def default_q(self, base=(0.0, 0.0, 0.0)) -> np.ndarray:
        """Driving configuration: every arm at :meth:`home`, grippers closed."""
        q = self.neutral_q()
        self.groups["base"].write(q, base)
        for arm in self.arms:
            self.groups[f"{arm}_arm"].write(q, self.home(arm))
            g = self.groups[f"{arm}_gripper"]
            g.write(q, [g.lower[0]])
        return q

    def random_q(self, rng: np.random.Generator, q=None, groups=None) -> np.ndarray:
        """``q`` (default: :meth:`default_q`) with ``groups`` (default: the base and every arm) sampled
        uniformly within bounds.  Use instead of ``pin.randomConfiguration``: the planar root has infinite limits.
        """
        out = self.default_q() if q is None else np.array(q, dtype=float)
        for g in groups or ("base",) + tuple(f"{a}_arm" for a in self.arms):
            self.groups[g].write(out, self.groups[g].sample(rng))
        return out

    # -- kinematics ---------------------------------------------------------------------------
    def reach(self, arm: str) -> tuple[np.ndarray, float]:
        """(origin of the arm's first joint in the base frame, at the held joint values; an upper bound on
        the distance from it to the tool frame: the chain's link offsets added up)."""
        from .ik import arm_ik

        q = self.default_q()
        pin.forwardKinematics(self.model, self.data, q)
        first = self.groups[f"{arm}_arm"].joint_ids[0]
        return self.data.oMi[first].translation.copy(), float(arm_ik(self, arm).reach)

    def tool_frame(self, arm: str) -> str:
        """Name of the description's tool frame (between the finger pads)."""
        return self._arm[arm].tool_frame

    def tool_frame_id(self, arm: str) -> int:
        """Id of the canonical tool frame (x = approach, y = closing) in :attr:`model`."""
        return self._tool_frames[arm]

    def tool_pose(self, q, arm: str) -> np.ndarray:
        """World pose (4x4) of ``arm``'s canonical tool frame at ``q`` (x out of the hand, y closing)."""
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
        """(world pose 4x4, 6 x n Jacobian) of ``arm``'s tool frame at ``q``: the frame's linear and
        angular velocity in world axes per arm-joint velocity."""
        fid = self._tool_frames[arm]
        J = pin.computeFrameJacobian(self.model, self.data, np.asarray(q, dtype=float), fid,
                                     pin.ReferenceFrame.LOCAL_WORLD_ALIGNED)
        cols = [self.model.joints[j].idx_v for j in self.groups[f"{arm}_arm"].joint_ids]
        return self.data.oMf[fid].homogeneous.copy(), J[:, cols]

    def velocity_limits(self, group: str) -> np.ndarray:
        """Velocity limit of each joint of ``group`` (rad/s or m/s; the description's, else the URDF's;
        inf if none)."""
        given = dict(self.description.velocity)
        lim = []
        for j in self.group(group).joint_ids:
            joint = self.model.joints[j]
            urdf = list(self.model.velocityLimit[joint.idx_v:joint.idx_v + joint.nv])
            lim += [given[self.model.names[j]]] * joint.nv if self.model.names[j] in given else urdf
        return np.array([v if v < 1e300 else np.inf for v in lim])

    def acceleration_limits(self, group: str) -> np.ndarray:
        """Acceleration limit of each joint of ``group``: the description's, else twice the velocity limit."""
        given = dict(self.description.acceleration)
        vel = self.velocity_limits(group)
        names = [self.model.names[j] for j in self.group(group).joint_ids
                 for _ in range(self.model.joints[j].nv)]
        return np.array([given.get(n, 2.0 * v) for n, v in zip(names, vel)])

    def base_pose(self, q) -> np.ndarray:
        """World pose (4x4) of the root link (z = :attr:`base_height`) from the planar root entries of ``q``."""
        c, s = q[2], q[3]
        return np.array([[c, -s, 0.0, q[0]], [s, c, 0.0, q[1]], [0.0, 0.0, 1.0, self.base_height],
                         [0.0, 0.0, 0.0, 1.0]])

    def collision_links(self, group: str | None = None) -> tuple[str, ...]:
        """Collision geometry names (link name + ``_0``) that move with ``group`` (None: all)."""
        moving = None if group is None else self.moving_joints(group)
        return tuple(g.name for g in self.collision_model.geometryObjects
                     if moving is None or g.parentJoint in moving)

    def gripper_links(self, arm: str) -> tuple[str, ...]:
        """Collision geometries of the hand (the tool frame's parent link and the links below it: palm,
        fingers): a held object may touch them."""
        from .gripper import hand_geometries

        cache = self.__dict__.setdefault("_hand_links", {})
        if arm not in cache:
            cache[arm] = hand_geometries(self.model, self.collision_model, self.model.getFrameId(self.tool_frame(arm)))
        return cache[arm]

    # -- gripper --------------------------------------------------------------------------------
    def _gap_table(self, arm: str) -> tuple[np.ndarray, np.ndarray]:
        from .gripper import pad_gap_table

        cache = self.__dict__.setdefault("_gap_tables", {})
        if arm not in cache:
            cache[arm] = pad_gap_table(self, arm, self._arm[arm].gripper)
        return cache[arm]

    def gripper_range(self, arm: str) -> tuple[float, float]:
        """(closed, widest) gap (m) between ``arm``'s finger pads, the gripper's DOF at its lower and upper
        limit: measured on the finger links' collision geometry along the closing axis, or the description's
        ``opening``.  Closed may be slightly negative (the pads' meshes overlap)."""
        gaps = self._gap_table(arm)[1]
        return float(gaps[0]), float(gaps[-1])

    @property
    def max_gripper_opening(self) -> float:
        """The widest gap (m) every arm's gripper opens to (PR2: about 0.092 m, a 0.10 m object does not fit)."""
        return min(self.gripper_range(arm)[1] for arm in self.arms)

    def gripper_opening(self, q, arm: str) -> float:
        """Pad gap (m) at the gripper DOF stored in ``q`` (may be negative when closed: pads overlap)."""
        dofs, gaps = self._gap_table(arm)
        return float(np.interp(self.groups[f"{arm}_gripper"].get(q)[0], dofs, gaps))

    def set_gripper_opening(self, q, arm: str, width: float) -> np.ndarray:
        """Copy of ``q`` with the pads ``width`` m apart (clipped to [closed, max_gripper_opening])."""
        dofs, gaps = self._gap_table(arm)
        return self.groups[f"{arm}_gripper"].set(q, [float(np.interp(width, gaps, dofs))])  # gap increases

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
