"""Which pairs a CollisionWorld query checks, and the broad phase that finds the ones to test (a mixin of
:class:`~interlayer_pinocchio.world.CollisionWorld`: it reads the world's built geometry model, objects and robot).

A query kind (``check`` or ``movables``, a group, the ignored objects, movables or not, a margin) is a
``_Variant``: a boolean mask over the world's pairs, cached per world version. A ``_Slot`` is a copy of
the geometry model with a GeometryData and a naive broadphase manager, one variant's mask applied.
The naive manager tests the bounding boxes of every two geometries it holds, so each slot takes out of
it (``disableCollision`` on its own copy) the geometries that no active pair needs: those of no active
pair at all, and, for an arm's checker, every resting object beyond the arm's reach from where the
checker holds the base (``_far``). Neither changes an answer: a pair whose geometry is left out cannot
collide.
"""

from __future__ import annotations

import math

import numpy as np
import pinocchio as pin

from .distances import _as_q

_MAX_SLOTS = 6
_REACH_SLACK = 0.01  # m beyond the arm's reach (plus the check's margin) that a body must be to be left out


class _Variant:
    """A cached pair-activation mask, the geometries it leaves idle (in no active pair), the security
    margin of its checks; ``version`` ties it to the world state it was built for."""

    __slots__ = ("key", "mask", "idle", "version", "margin")

    def __init__(self, key, mask, idle, version, margin=0.0):
        self.key, self.mask, self.idle, self.version, self.margin = key, mask, idle, version, margin


class _Slot:
    """A copy of the geometry model, its GeometryData and broadphase manager, with one variant's mask
    applied and the geometries it does not need disabled.

    A few slots are kept so that alternating query kinds (e.g. ``in_collision`` and
    ``colliding_movables``) does not re-toggle hundreds of pairs on every call.
    """

    __slots__ = ("gm", "gd", "manager", "variant", "mask", "margin", "far", "off", "n_robot")

    def __init__(self, model, gm, n_robot):
        self.n_robot = n_robot
        self.gm = gm.copy()  # geometries shared; its own disableCollision flags
        self.gd = pin.GeometryData(self.gm)
        self.manager = pin.BroadPhaseManager_NaiveCollisionManager(model, self.gm, self.gd)
        self.variant = None
        self.mask = np.ones(len(gm.collisionPairs), dtype=bool)  # GeometryData starts all-active
        self.margin = 0.0
        self.far = None  # the ``_far`` array applied (identity matters), None for none
        self.off = np.zeros(gm.ngeoms, dtype=bool)

    def apply(self, variant: _Variant, far) -> None:
        flips = np.flatnonzero(self.mask != variant.mask).tolist()
        if len(flips) > len(self.mask) // 3:  # many: one assignment of the whole mask costs less than a call each
            self.gd.activeCollisionPairs = variant.mask.tolist()  # what (de)activateCollisionPair set
        else:
            for k in flips:
                if variant.mask[k]:
                    self.gd.activateCollisionPair(k)
                else:
                    self.gd.deactivateCollisionPair(k)
        if variant.margin != self.margin:  # also widens the broad phase's boxes by as much
            n = self.gm.ngeoms
            self.gd.setSecurityMargins(self.gm, np.full((n, n), variant.margin), True, True)
        off = variant.idle if far is None else variant.idle | far
        objects = self.gm.geometryObjects
        changed = np.flatnonzero(off != self.off).tolist()
        for g in changed:
            objects[g].disableCollision = bool(off[g])  # the manager (un)registers it at its next update
        if changed or self.variant is None:
            # The manager tests its geometries in the order they were registered, and a check stops at
            # its first hit: the robot's links go last, so that a configuration in collision meets the
            # arm-vs-object pairs, where most hits are, before the robot's self pairs (their meshes cost
            # the most to test and rarely touch): 1.1-1.3x on arms near objects, same answers.
            robot = range(self.n_robot)
            for g in robot:
                objects[g].disableCollision = True
            self.manager.update(False)
            for g in robot:
                objects[g].disableCollision = bool(off[g])
            self.manager.update(False)
        self.mask, self.variant, self.margin, self.far, self.off = variant.mask, variant, variant.margin, far, off


class Pairs:
    """Pair masks, slots and the broad phase of :class:`~interlayer_pinocchio.world.CollisionWorld`."""

    def _variant(self, key) -> _Variant:
        if self._needs_build:
            self._build()
        v = self._variants.get(key)
        if v is None or v.version != self._version:
            if v is not None or len(self._variants) > 64:
                self._variants = {k: x for k, x in self._variants.items() if x.version == self._version}
            mask = self._mask(*key[:4])
            idle = np.ones(self._gm.ngeoms, dtype=bool)
            idle[self._pa[mask]] = idle[self._pb[mask]] = False
            v = self._variants[key] = _Variant(key, mask, idle, self._version, *key[4:])
        return v

    def _use(self, key, far=None):
        """A slot whose GeometryData has ``key``'s pair mask active and ``far``'s geometries left out
        (reused, else least recently used)."""
        v = self._variant(key)
        slots = self._slots
        for i, slot in enumerate(slots):
            if slot.variant is v and slot.far is far:
                break
        else:
            if len(slots) < _MAX_SLOTS:
                slot = _Slot(self._model, self._gm, self._n_robot)
                slots.append(slot)
            else:
                slot = slots[-1]
            slot.apply(v, far)
            i = slots.index(slot)
        if i:
            slots.insert(0, slots.pop(i))
        return slot

    def _far(self, group: str, q, margin: float = 0.0):
        """For an arm's checker at ``q`` (the base held there): the resting objects no body moving with
        the arm can reach, as a boolean array over the geometries (cached per world state); None for a
        group that can reach anywhere (the base) or has a joint other than revolute ones."""
        if self._needs_build:
            self._build()
        reach = self._reach(group)
        if reach is None:
            return None
        root, radius = reach
        pin.forwardKinematics(self._model, self._data, _as_q(q))
        centre = self._data.oMi[root].translation  # a revolute joint's origin: every moving body stays within radius
        key = (group, tuple(centre.tolist()), margin, self._version, self._poses)
        cached = self._far_cache.get(key)
        if cached is not None:
            return cached
        gids, lo, hi = self._resting_boxes()
        gap = np.linalg.norm(np.maximum(np.maximum(lo - centre, centre - hi), 0.0), axis=1)
        far = np.zeros(self._gm.ngeoms, dtype=bool)
        far[gids[gap > radius + margin + _REACH_SLACK]] = True
        if len(self._far_cache) > 64:
            self._far_cache.clear()
        self._far_cache[key] = far
        return far

    def _resting_boxes(self):
        """(geometry ids, lower corners, upper corners) of the world boxes of the objects not held."""
        key = (self._version, self._poses)
        cached = self._bounds.get("resting")
        if cached is None or cached[0] != key:
            resting = [o for o in self._objects.values() if o.held_by is None]
            lo, hi = self._boxes([o.geometry for o in resting], [o.pose for o in resting])
            cached = self._bounds["resting"] = (key, (np.array([o.gid for o in resting], dtype=int), lo, hi))
        return cached[1]

    def _reach(self, group: str):
        """(root joint, radius): the group's joints all hang below its first, revolute, joint ``root``, and
        no point of a body moving with them (robot link or held object) is further than ``radius`` from
        that joint's origin (the chain's joint offsets plus the body's bounding sphere). None otherwise."""
        cached = self._bounds.get(("reach", group))
        if cached is not None and cached[0] == self._version:
            return cached[1]
        model, supports = self._model, self._model.supports
        joints = self.robot.group(group).joint_ids
        root = joints[0]
        out = None
        if all(root in supports[j] for j in joints) and all(
                model.joints[j].shortname().startswith("JointModelR") for j in joints):
            radius = 0.0
            for go in self._gm.geometryObjects:
                j = go.parentJoint
                if j > 0 and root in supports[j]:
                    chain = list(supports[j])
                    offsets = 0.0
                    for k in chain[chain.index(root) + 1:]:
                        offsets += np.linalg.norm(model.jointPlacements[k].translation)
                        kind = model.joints[k].shortname()
                        if kind.startswith("JointModelP"):  # a prismatic joint below (fingers) slides this far
                            i = model.joints[k].idx_q
                            offsets += max(abs(model.lowerPositionLimit[i]), abs(model.upperPositionLimit[i]))
                        elif not kind.startswith("JointModelR"):
                            radius = math.inf  # a joint it cannot bound: leave nothing out
                    extent = np.linalg.norm(go.placement.act(go.geometry.aabb_center)) + go.geometry.aabb_radius
                    radius = max(radius, offsets + extent)
            out = (root, float(radius)) if math.isfinite(radius) else None
        self._bounds[("reach", group)] = (self._version, out)
        return out

    def _mask(self, mode: str, group: str | None, ignore: frozenset, movables: bool) -> np.ndarray:
        """Which pairs a query checks; see ``in_collision`` / ``colliding_movables`` for the rules."""
        unknown = ignore - self._objects.keys()
        if unknown:
            raise KeyError(f"ignore names unknown objects: {sorted(unknown)}")
        n, nr = self._gm.ngeoms, self._n_robot
        held = np.full(n, -1)  # index into robot.arms of the holding arm
        movable = np.zeros(n, dtype=bool)
        ignored = np.zeros(n, dtype=bool)
        joint = np.zeros(n, dtype=int)  # parent joint, for "moves with group"
        joint[:nr] = self._robot_joint
        for obj in self._objects.values():
            movable[obj.gid] = obj.movable
            ignored[obj.gid] = obj.name in ignore
            if obj.held_by is not None:
                held[obj.gid] = self._arms.index(obj.held_by)
                joint[obj.gid] = self._tool_joint[obj.held_by]
        is_held = held >= 0
        a, b = self._pa, self._pb
        robot_a, robot_b = a < nr, b < nr
        # holder_hand[k]: pair k is (robot geom a, held object b) and a belongs to the holding hand
        holder_hand = np.zeros(len(a), dtype=bool)
        for i, arm in enumerate(self._arms):
            sel = robot_a & ~robot_b & (held[b] == i)
            holder_hand[sel] = self._gripper[arm][a[sel]]
        if mode == "check":
            obstacle = ~is_held & ~ignored & (movables | ~movable)
            self_pair = robot_a & robot_b
            robot_obj = robot_a & ~robot_b & ~ignored[b] & np.where(is_held[b], ~holder_hand, obstacle[b])
            held_ok = is_held & ~ignored
            obj_obj = ~robot_a & ((held_ok[a] & (obstacle[b] | held_ok[b])) | (held_ok[b] & obstacle[a]))
            mask = self_pair | robot_obj | obj_obj
        elif mode == "movables":
            target = movable & ~is_held & ~ignored
            held_ok = is_held & ~ignored
            robot_obj = robot_a & ~robot_b & target[b]
            obj_obj = ~robot_a & ((held_ok[a] & target[b]) | (held_ok[b] & target[a]))
            mask = robot_obj | obj_obj
        else:
            raise ValueError(mode)
        if group is not None:
            # A pair can only change if a group joint lies on the kinematic path between
            # its two geometries, i.e. in exactly one of their supports (root -> parent
            # joint; empty for the environment).  Moving the base thus skips self pairs.
            below = self._below(group)[joint]
            mask &= (below[a] != below[b]).any(axis=1)
        return mask

    def _below(self, group: str) -> np.ndarray:
        """``[j, k]``: the group's k-th joint supports joint j (lies on its path from the root); the
        universe's row is all False. Fixed by the robot's model: built once per group."""
        table = self._supported.get(group)
        if table is None:
            group_joints = self.robot.group(group).joint_ids
            supports = self._model.supports
            table = np.zeros((self._model.njoints, len(group_joints)), dtype=bool)
            for i in range(1, self._model.njoints):
                support = set(supports[i])
                table[i] = [j in support for j in group_joints]
            self._supported[group] = table
        return table

    def _colliding_pairs(self, q, key) -> list[tuple[int, int]]:
        """(geom a, geom b) pairs in collision: broadphase candidates, then exact narrow phase."""
        slot = self._use(key)
        callback = pin.CollisionCallBackCollect(slot.gm, slot.gd)
        pin.computeCollisions(self._model, self._data, slot.manager, callback, _as_q(q))
        out = []
        for k in sorted(set(callback.pair_indexes)):
            if pin.computeCollision(slot.gm, slot.gd, k):
                a, b = int(self._pa[k]), int(self._pb[k])
                if a >= self._n_robot and self._holder(a) is None and self._holder(b) is not None:
                    a, b = b, a  # held object first
                out.append((a, b))
        return out

    def _holder(self, gid: int) -> str | None:
        """Arm holding object geometry ``gid`` (None if not held)."""
        return self._objects[self._gm.geometryObjects[gid].name].held_by

    def _label(self, gid: int) -> str:
        return self._link_names[gid] if gid < self._n_robot else self._gm.geometryObjects[gid].name
