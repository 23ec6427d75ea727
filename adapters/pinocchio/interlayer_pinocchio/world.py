"""Robot + environment collision checking on Pinocchio/Coal.

One ``pin.GeometryModel`` holds the robot's collision meshes followed by the
environment objects (attached to the universe, or to a wrist joint while held).
It lists every pair that could ever matter: SRDF-filtered robot self pairs,
robot x object and object x object.  A query only *activates* the pairs it
needs (a cached boolean mask per kind of query, pairs.py), then one C++ call runs FK,
geometry placement, the naive broadphase (AABB test of every pair of the geometries
the query needs; the DynamicAABBTreeArray manager gave wrong answers) and the narrow
phase, stopping at the first hit.

Contact semantics are Coal's: touching (distance 0) counts as collision, so an
object resting exactly on a table collides with it once held -- place objects
with a small gap (e.g. 1 mm) or pass the support in ``ignore``.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Callable, Iterable, Sequence

import coal
import numpy as np
import pinocchio as pin

from .distances import Distances, _as_q, _transform
from .joints import as_se3
from .pairs import Pairs, _Slot, _Variant
from .robot import Robot

__all__ = ["CollisionWorld", "WorldObject", "Attachment"]

DEFAULT_COLOR = (0.7, 0.7, 0.7, 1.0)


@dataclass(frozen=True, eq=False)
class WorldObject:
    """Snapshot of an environment object (for listing and viewers).

    ``size``: box -> full edge lengths (x, y, z); cylinder -> (radius, height),
    axis along local z; mesh -> scale.  ``pose`` is the world pose of the shape
    centre (mesh: its origin); for a held object it is the pose at attach time
    and ``grasp`` is its (fixed) pose in the tool frame.
    """

    name: str
    shape: str
    size: tuple[float, ...]
    pose: np.ndarray
    movable: bool
    color: tuple[float, float, float, float]
    mesh_path: str | None = None
    held_by: str | None = None
    grasp: np.ndarray | None = None


@dataclass(frozen=True, eq=False)
class Attachment:
    """An object held by an arm: ``tool_T_object`` is its pose in the tool frame."""

    name: str
    arm: str
    tool_T_object: np.ndarray


class _Obj:
    """Mutable internal record of one object."""

    __slots__ = ("name", "shape", "size", "geometry", "pose", "movable", "color", "mesh_path",
                 "held_by", "grasp", "gid")

    def __init__(self, name, shape, size, geometry, pose, movable, color, mesh_path=None):
        self.name, self.shape, self.size, self.geometry = name, shape, size, geometry
        self.pose: pin.SE3 = pose  # world pose while not held
        self.movable, self.color, self.mesh_path = movable, color, mesh_path
        self.held_by: str | None = None
        self.grasp: pin.SE3 | None = None  # tool_T_object while held
        self.gid = -1  # index in the combined GeometryModel


class CollisionWorld(Distances, Pairs):
    """Environment objects around a :class:`Robot`, held objects, and collision queries on full ``q``."""

    def __init__(self, robot: Robot):
        self.robot = robot
        self._model = robot.model
        self._data = robot.model.createData()
        self._objects: dict[str, _Obj] = {}
        self._version = 0  # bumped by add/remove/attach/detach: masks depend on it
        self._poses = 0  # bumped when set_pose moves an object: what an arm can reach depends on it
        self._far_cache = {}
        self._needs_build = True
        self._variants: dict[tuple, _Variant] = {}
        self._slots: list[_Slot] = []  # most recently used first
        self._request = coal.CollisionRequest()
        self._local_boxes = {}  # id(geometry) -> (its local AABB's corners, geometry)
        self._bounds = {}  # group -> (version, motion_bound)
        self._supported = {}  # group -> which joints each of its joints supports (Pairs._below)
        self._hands = {}  # (arm, finger angle) -> [(hand geometry, its pose in the tool frame)]
        self._arms = robot.arms
        self._tool_joint = {arm: robot.model.frames[robot.tool_frame_id(arm)].parentJoint for arm in robot.arms}
        names = [g.name for g in robot.collision_model.geometryObjects]
        self._link_names = tuple(robot.model.frames[g.parentFrame].name
                                 for g in robot.collision_model.geometryObjects)
        self._gripper = {arm: np.isin(names, robot.gripper_links(arm)) for arm in robot.arms}

    # -- objects ------------------------------------------------------------------------------
    def add_box(self, name: str, size: Sequence[float], pose, movable: bool = False,
                color=DEFAULT_COLOR) -> None:
        """Box with full edge lengths ``size`` = (x, y, z), centred at ``pose``."""
        sx, sy, sz = (float(s) for s in size)
        self._add(_Obj(name, "box", (sx, sy, sz), coal.Box(sx, sy, sz), as_se3(pose), movable, tuple(color)))

    def add_cylinder(self, name: str, radius: float, height: float, pose, movable: bool = False,
                     color=DEFAULT_COLOR) -> None:
        """Cylinder (axis = local z, full ``height``) centred at ``pose``."""
        geom = coal.Cylinder(float(radius), float(height))
        self._add(_Obj(name, "cylinder", (float(radius), float(height)), geom, as_se3(pose), movable,
                       tuple(color)))

    def add_mesh(self, name: str, path: str, pose, scale=(1.0, 1.0, 1.0), movable: bool = False,
                 color=DEFAULT_COLOR) -> None:
        """Triangle mesh file (STL, OBJ, DAE... via assimp), mesh origin at ``pose``."""
        geom = coal.MeshLoader().load(str(path), np.asarray(scale, dtype=float))
        self._add(_Obj(name, "mesh", tuple(map(float, scale)), geom, as_se3(pose), movable, tuple(color),
                       str(path)))

    def _add(self, obj: _Obj) -> None:
        if obj.name in self._objects:
            raise ValueError(f"object {obj.name!r} already exists")
        obj.geometry.computeLocalAABB()  # the broadphase skips geometries without an AABB
        self._objects[obj.name] = obj
        self._structure_changed()

    def remove(self, name: str) -> None:
        del self._objects[self._get(name).name]
        self._structure_changed()

    def _get(self, name: str) -> _Obj:
        try:
            return self._objects[name]
        except KeyError:
            raise KeyError(f"unknown object {name!r}") from None

    def __contains__(self, name: str) -> bool:
        return name in self._objects

    def names(self) -> tuple[str, ...]:
        return tuple(self._objects)

    def set_pose(self, name: str, pose) -> None:
        """Move a (not held) object; cheap, no rebuild."""
        obj = self._get(name)
        if obj.held_by is not None:
            raise ValueError(f"{name!r} is held by the {obj.held_by} arm; detach it first")
        new = as_se3(pose)
        if new == obj.pose:  # sync() sets every object's pose again
            return
        obj.pose = new
        self._poses += 1
        if not self._needs_build:
            self._place(obj)

    def pose(self, name: str, q=None) -> np.ndarray:
        """World pose (4x4); a held object needs the configuration ``q``."""
        obj = self._get(name)
        if obj.held_by is None:
            return obj.pose.homogeneous.copy()
        if q is None:
            raise ValueError(f"{name!r} is held by the {obj.held_by} arm: pass q")
        return self.robot.tool_pose(q, obj.held_by) @ obj.grasp.homogeneous

    def get(self, name: str) -> WorldObject:
        obj = self._get(name)
        return WorldObject(obj.name, obj.shape, obj.size, obj.pose.homogeneous.copy(), obj.movable,
                           obj.color, obj.mesh_path, obj.held_by,
                           None if obj.grasp is None else obj.grasp.homogeneous.copy())

    def objects(self) -> list[WorldObject]:
        return [self.get(n) for n in self._objects]

    def geometry(self, name: str):
        """The Coal geometry of an object (shared, do not modify)."""
        return self._get(name).geometry

    # -- held objects -------------------------------------------------------------------------
    def attach(self, name: str, arm: str, q) -> None:
        """Grasp: keep the object's current pose relative to ``arm``'s tool frame at ``q``.

        From now on it moves with the gripper and is checked against the environment,
        the other held object and every robot link except this hand (palm, fingers).
        """
        obj = self._get(name)
        if arm not in self._arms:
            raise ValueError(f"arm must be one of {self._arms}")
        if obj.held_by is not None:
            raise ValueError(f"{name!r} is already held by the {obj.held_by} arm")
        if any(o.held_by == arm for o in self._objects.values()):
            raise ValueError(f"the {arm} arm already holds an object")
        tool = as_se3(self.robot.tool_pose(q, arm))
        obj.grasp = tool.actInv(obj.pose)
        obj.held_by = arm
        self._holding_changed(obj)

    def detach(self, name: str, q) -> None:
        """Release: the object stays where the gripper holds it at ``q``."""
        obj = self._get(name)
        if obj.held_by is None:
            raise ValueError(f"{name!r} is not held")
        obj.pose = as_se3(self.robot.tool_pose(q, obj.held_by)) * obj.grasp
        obj.held_by, obj.grasp = None, None
        self._holding_changed(obj)

    def held(self) -> tuple[Attachment, ...]:
        return tuple(Attachment(o.name, o.held_by, o.grasp.homogeneous.copy())
                     for o in self._objects.values() if o.held_by is not None)

    # -- collision queries --------------------------------------------------------------------
    def in_collision(self, q, ignore: Iterable[str] = frozenset(), movables: bool = True,
                     group: str | None = None) -> bool:
        """Robot (+ held objects) vs environment, robot self-collision and held vs robot.

        ``movables=False`` drops movable objects (the relaxed check used to find
        obstructions); ``ignore`` names objects to skip entirely; ``group`` restricts
        the check to pairs whose relative pose that group can change (see ``checker_for``).
        """
        slot = self._use(("check", group, frozenset(ignore), bool(movables)))
        return pin.computeCollisions(self._model, self._data, slot.manager, _as_q(q), True)

    def colliding_movables(self, q, ignore: Iterable[str] = frozenset()) -> set[str]:
        """Names of non-held movable objects touched by the robot or a held object at ``q``."""
        key = ("movables", None, frozenset(ignore), True)
        q = _as_q(q)
        if not pin.computeCollisions(self._model, self._data, self._use(key).manager, q, True):
            return set()  # the usual answer, for the price of one check (collecting the pairs costs more)
        pairs = self._colliding_pairs(q, key)
        return {self._gm.geometryObjects[b].name for _, b in pairs}

    def collision_pairs(self, q, ignore: Iterable[str] = frozenset(),
                        movables: bool = True) -> list[tuple[str, str]]:
        """Every colliding (robot link or held object, object or robot link) pair, for diagnostics."""
        return [(self._label(a), self._label(b))
                for a, b in self._colliding_pairs(q, ("check", None, frozenset(ignore), bool(movables)))]

    def checker_for(self, group: str, q_fixed, ignore: Iterable[str] = frozenset(),
                    movables: bool = True, margin: float = 0.0) -> Callable[[Sequence[float]], bool]:
        """Fast ``is_valid(vector) -> bool`` for planning ``group`` with the rest of ``q_fixed`` frozen.

        Writes the group vector into a private copy of ``q_fixed`` and checks only
        pairs whose relative pose the group can change: for an arm, its links and
        held object against everything else; for ``base``, the whole robot and held
        objects against the environment (self pairs are rigid then).  Pairs that
        cannot change are assumed fine, so ``q_fixed`` itself should be valid.
        Object poses are read live; the checker follows add/remove/attach/detach.
        Not re-entrant: shares the world's Pinocchio data. With a ``margin`` (m), bodies closer than
        that count as colliding (see ``motion_bound``).
        """
        g = self.robot.group(group)
        key = ("check", group, frozenset(ignore), bool(movables)) + ((float(margin),) if margin else ())
        write, compute = g.write, pin.computeCollisions
        model, data, q = self._model, self._data, np.array(q_fixed, dtype=float)

        def acquire():  # the bodies out of the arm's reach from q_fixed are left out of the broad phase
            slot = self._use(key, self._far(group, q, float(margin)))
            cache[:] = slot, slot.variant, slot.far, self._poses
            return slot

        cache = []
        acquire()

        def is_valid(values) -> bool:
            slot, variant, far, poses = cache
            if slot.variant is not variant or slot.far is not far or variant.version != self._version \
                    or poses != self._poses:
                slot = acquire()  # another query took the slot, or the world changed
            write(q, values)
            return not compute(model, data, slot.manager, q, True)

        return is_valid

    def objects_overlap(self, name: str, pose, ignore: Iterable[str] = frozenset()) -> set[str]:
        """Objects (not held, not ignored) that object ``name`` placed at ``pose`` would touch."""
        obj = self._get(name)
        skip = frozenset(ignore) | {name}
        tf = _transform(as_se3(pose))
        hits = set()
        for other in self._objects.values():
            if other.held_by is not None or other.name in skip:
                continue
            result = coal.CollisionResult()
            if coal.collide(obj.geometry, tf, other.geometry, _transform(other.pose), self._request, result):
                hits.add(other.name)
        return hits

    # -- internals ----------------------------------------------------------------------------
    def _structure_changed(self) -> None:
        self._needs_build = True
        self._version += 1

    def _holding_changed(self, obj: _Obj) -> None:
        self._version += 1
        if not self._needs_build:
            self._place(obj)

    def _place(self, obj: _Obj) -> None:
        """Put ``obj``'s geometry on the universe or, while held, on the wrist joint."""
        for gm in [self._gm] + [slot.gm for slot in self._slots]:
            go = gm.geometryObjects[obj.gid]
            if obj.held_by is None:
                go.parentJoint, go.parentFrame, go.placement = 0, 0, obj.pose
            else:
                fid = self.robot.tool_frame_id(obj.held_by)
                go.parentJoint, go.parentFrame = self._tool_joint[obj.held_by], fid
                go.placement = self._model.frames[fid].placement * obj.grasp  # joint_T_tool * tool_T_object

    def _build(self) -> None:
        """(Re)create the combined geometry model, its pairs, data and broadphase manager."""
        robot_gm = self.robot.collision_model
        gm = pin.GeometryModel()
        for go in robot_gm.geometryObjects:
            gm.addGeometryObject(go)
        n_robot = len(robot_gm.geometryObjects)
        for obj in self._objects.values():
            obj.gid = gm.addGeometryObject(pin.GeometryObject(obj.name, 0, 0, obj.pose, obj.geometry))
        pairs = [(cp.first, cp.second) for cp in robot_gm.collisionPairs]
        n = gm.ngeoms
        pairs += [(a, b) for a in range(n_robot) for b in range(n_robot, n)]
        pairs += [(a, b) for a in range(n_robot, n) for b in range(a + 1, n)]
        for a, b in pairs:
            gm.addCollisionPair(pin.CollisionPair(a, b))
        self._gm, self._n_robot = gm, n_robot
        self._pa = np.array([p[0] for p in pairs], dtype=int)
        self._pb = np.array([p[1] for p in pairs], dtype=int)
        self._robot_joint = np.array([go.parentJoint for go in robot_gm.geometryObjects], dtype=int)
        self._needs_build = False
        self._variants.clear()
        self._slots = []
        for obj in self._objects.values():
            self._place(obj)
