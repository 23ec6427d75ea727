"""PR2 geometry: the refinement runtime of the pr2 domain (interlayer.refine.Geometry).

World state: base (x, y, theta), both arm vectors, gripper states, resting object poses (4x4),
held objects per arm with their grasp (tool_T_object), and the put-down spot (tloc) chosen by the
move_base that precedes a place. One PR2 + CollisionWorld per geometry, synced lazily to the world
being refined. Arm motions are planned in the 7-D joint space of the arm (the continuous forearm and
wrist roll bounded to [-pi, pi]), base motions in SE(2) with the arms in their driving posture.

Every action returns its arm to a driving posture: tucked when empty, a carry posture (the hand
raised beside the shoulder) when holding, so that move_base never sweeps an outstretched arm.
"""
from __future__ import annotations

import math
import time
from dataclasses import dataclass, field, replace

import numpy as np

from interlayer.motion import BLOCK as FINE_BLOCK
from interlayer.motion import Clearance, ConfigSpace, InterpolatingPlanner, MotionQuery, points_valid
from interlayer.refine import ROBOT_MOVED, Failure, StepOutcome
from interlayer.trace import Stats

from .plugin import TIMING  # defaults, overridden by the problem keys of the same names (layout.extra)
from .scene import Layout, base_limits

ARMS = ("left", "right")
RES_ARM = 0.02  # rad between collision checks when planning an arm (the validator checks 5x finer)
# Planning keeps this far from fixed obstacles (their boxes are padded), so that contacts missed
# between two checks at RES_ARM (the fingertips move up to ~1.6 cm per 0.02 rad) are not real ones;
# the validator uses the unpadded scene.
PADDING = 0.015
RES_BASE = 0.01  # m / rad between collision checks when planning the base
# Paths are checked in blocks of FINE_BLOCK points, each block at once by its middle point with a margin
# where it is clear (interlayer.motion.points_valid); MARGIN_SLACK (m) covers Coal's distance tolerance.
MARGIN_SLACK = 1e-4
PRE_GRASP = 0.20  # back-off of the pre-grasp along the tool x axis (approach and retreat length)
LIFT = 0.05  # raise after grasping / height above the put-down spot
OPEN_CLEARANCE = 0.01  # m: a gripper about to grasp or let go opens this much wider than the object (5 mm a side)
FOLLOWS = 1e3  # the velocity / acceleration "limit" of a joint driven by the hand (a drawer's slide)
# First IK seed for reaching forward at table height (elbow up, measured typical solutions)
REACH_SEED = {"left": (-0.4, -0.25, 3.3, -1.53, 2.75, -1.2, 0.0), "right": (0.4, -0.25, -3.3, -1.53, -2.75, -1.2, 0.0)}
# Carry postures (tool position in the base frame, yaw away from the body): tried in order.
CARRY = ((0.35, 0.45, 1.15, 0.3), (0.30, 0.50, 1.10, 0.5), (0.40, 0.40, 1.20, 0.1), (0.25, 0.55, 1.20, 0.7))


def rz(a: float) -> np.ndarray:
    c, s = math.cos(a), math.sin(a)
    return np.array([[c, -s, 0, 0], [s, c, 0, 0], [0, 0, 1, 0], [0, 0, 0, 1.0]])


def trans(x, y, z) -> np.ndarray:
    T = np.eye(4)
    T[:3, 3] = (x, y, z)
    return T


def pose4(x, y, z, yaw) -> np.ndarray:
    return trans(x, y, z) @ rz(yaw)


def wrap(a):
    return (a + math.pi) % (2 * math.pi) - math.pi


def is_open(state) -> bool:
    """A gripper state open for grasping or letting go: "open" (fully) or ("open", width in metres)."""
    return state == "open" or (isinstance(state, (tuple, list)) and len(state) == 2 and state[0] == "open")


@dataclass(frozen=True)
class World:
    base: tuple
    arms: dict = field(hash=False)  # arm -> 7 floats
    grippers: dict = field(hash=False)  # arm -> "open" (fully) | ("open", width) | "closed" | width (closed on a handle)
    objects: dict = field(hash=False)  # name -> 4x4 pose of objects that are not held
    held: dict = field(hash=False)  # arm -> (object, tool_T_object 4x4)
    # what the last move_base chose its base pose for: object -> put-down pose (4x4), or
    # ("grasp", object, arm) -> (kind, tool pose, waypoints) of a grasp IK found from that base
    tloc: dict = field(hash=False, default_factory=dict)
    # articulated environment bodies: body -> joint values; objects resting on their links move with
    # them: object -> (body, link)
    joints: dict = field(hash=False, default_factory=dict)
    riders: dict = field(hash=False, default_factory=dict)

    def holder(self, name):
        return next((a for a, (o, _) in self.held.items() if o == name), None)

    def with_arm(self, arm, values) -> "World":
        return replace(self, arms={**self.arms, arm: tuple(float(v) for v in values)})

    def with_gripper(self, arm, state) -> "World":
        return replace(self, grippers={**self.grippers, arm: state})

    def to_json(self) -> dict:
        return {"base": list(self.base), "arms": {a: list(v) for a, v in self.arms.items()},
                "grippers": dict(self.grippers), "objects": {k: np.asarray(v).tolist() for k, v in self.objects.items()},
                "held": {a: {"object": o, "grasp": np.asarray(g).tolist()} for a, (o, g) in self.held.items()},
                **({"joints": {b: list(v) for b, v in self.joints.items()}} if self.joints else {})}


class PR2Geometry:
    """Refinement runtime of the pr2 domain."""

    def __init__(self, layout: Layout, padding: float = PADDING):
        from interlayer_pinocchio import PR2, CollisionWorld

        self.layout = layout
        self.padding = padding
        self.robot = PR2(torso_height=layout.extra.get("torso_height", 0.2), base_limits=base_limits(layout))
        self.cw = CollisionWorld(self.robot)
        for o in layout.fixed + layout.objects:
            T = pose4(*o.pose)
            if o.shape == "box":
                size = o.size
                if not o.movable and padding:  # fixed obstacles grow by `padding` (supports not upwards:
                    # objects rest on them and are put down onto them)
                    up = 0 if o.name in layout.extra.get("supports", ("table",)) else 2 * padding
                    size = (size[0] + 2 * padding, size[1] + 2 * padding, size[2] + up)
                self.cw.add_box(o.name, size, T, movable=o.movable)
            else:
                self.cw.add_cylinder(o.name, o.size[0], o.size[1], T, movable=o.movable)
        self.specs = {o.name: o for o in layout.objects}
        self.fixed = {o.name for o in layout.fixed}
        self.approach = InterpolatingPlanner(name="interpolate")
        self.cartesian = None  # planner.cartesian, set by the run: the approach and retreat lines' planner
        self.stats = Stats()
        self.refs = {}  # reference name -> (skolem, args): filled by make_problem
        self.bodies = {}  # articulated environment bodies (interlayer_pinocchio.ArticulatedBody): add_body
        self._initial_joints, self._initial_riders = {}, {}
        self._synced = None
        self._exporting = False  # prepare_export: segments are timed as they are made
        lo, hi = base_limits(layout)
        self.base_space = ConfigSpace("se2", (lo[0], hi[0], -math.pi), (lo[1], hi[1], math.pi), (False, False, True), RES_BASE)
        # Arm spaces: the continuous forearm / wrist roll joints are treated as bounded to [-pi, pi]
        # without wrap-around, so that every interpolation agrees: OMPL's (a RealVectorStateSpace
        # interpolates linearly), the core's densify (validator, straight lines) and a controller
        # reading trajectory.json (linear in joint values).
        self.arm_space = {}
        for arm in ARMS:
            g = self.robot.group(f"{arm}_arm")
            self.arm_space[arm] = ConfigSpace("vector", tuple(g.lower), tuple(g.upper), (False,) * g.dof, RES_ARM)

    def scene_issues(self) -> list:
        """Interpenetrating, floating and buried objects at their initial poses (see sanity.py)."""
        from .sanity import scene_issues

        return scene_issues(self.layout.fixed, self.layout.objects, self.layout.extra.get("floors", ()),
                            self._initial_riders)

    # -- world ----------------------------------------------------------------------------------
    def initial_world(self) -> World:
        from interlayer_pinocchio import TUCKED_ARMS

        return World(tuple(self.layout.base), {a: tuple(TUCKED_ARMS[a]) for a in ARMS}, {a: "closed" for a in ARMS},
                     {o.name: pose4(*o.pose) for o in self.layout.objects}, {},
                     joints=dict(self._initial_joints), riders=dict(self._initial_riders))

    def add_body(self, body, values, riders=(), exact_links=()) -> None:
        """Add an articulated body at joint ``values``; ``riders`` are (object, link) pairs of objects
        resting on its links. Planning pads its elements like fixed obstacles, except ``exact_links``
        (a handle the gripper closes around)."""
        self.bodies[body.name] = body
        values = tuple(float(v) for v in body.check(values))
        self._initial_joints[body.name] = values
        for obj, link in riders:
            self._initial_riders[obj] = (body.name, link)
        pad = 0.0 if not self.padding else self.padding
        exact = [s for s in body.shapes if s.link in exact_links]
        body.add_to(self.cw, values, padding=pad, skip=[s.name for s in exact])
        body.add_to(self.cw, values, only=[s.name for s in exact])
        self._synced = None

    def with_joints(self, world: World, name, values) -> World:
        """``world`` with body ``name`` at joint ``values``; resting objects on its links move along."""
        body = self.bodies[name]
        old = world.joints[name]
        values = tuple(float(v) for v in values)
        objects = dict(world.objects)
        for obj, (b, link) in world.riders.items():
            if b == name and obj in objects:
                objects[obj] = body.carry(objects[obj], link, old, values)
        return replace(world, joints={**world.joints, name: values}, objects=objects)

    def snapshot(self, world: World) -> dict:
        return world.to_json()

    def moved(self, before: World, after: World) -> set:
        """Objects whose pose differs between two worlds (picked up or put down in between),
        articulated bodies whose joints do, and ``ROBOT_MOVED`` if the PR2's base, arms or grippers do."""
        out = set()
        for a, b in ((before.objects, after.objects), (before.joints, after.joints)):
            out |= {o for o in a.keys() | b.keys() if o not in a or o not in b or not np.array_equal(a[o], b[o])}
        if (not np.array_equal(before.base, after.base) or before.grippers != after.grippers
                or any(not np.array_equal(before.arms[a], after.arms[a]) for a in before.arms)):
            out.add(ROBOT_MOVED)
        return out

    def config(self, world: World) -> np.ndarray:
        r = self.robot
        q = r.default_q(world.base)
        for arm in ARMS:
            r.group(f"{arm}_arm").write(q, world.arms[arm])  # in place: this runs at every sync
            g = world.grippers[arm]
            if g == "open":
                q = r.open_gripper(q, arm)
            elif is_open(g):
                q = r.set_gripper_opening(q, arm, g[1])
            elif not isinstance(world.grippers[arm], str):  # closed around something that is no object (a handle)
                q = r.set_gripper_opening(q, arm, float(world.grippers[arm]))
            elif arm in world.held:
                q = r.set_gripper_opening(q, arm, max(0.0, self.grasp_width(world.held[arm][0], world.held[arm][1])))
            else:
                q = r.close_gripper(q, arm)
        return q

    def grasp_width(self, name, G) -> float:
        """The object's extent along the tool's closing (y) axis for grasp G (tool_T_object)."""
        o = self.specs[name]
        if o.shape == "cylinder":
            return 2 * o.size[0]
        y_in_obj = np.linalg.inv(G)[:3, :3] @ np.array([0.0, 1.0, 0.0])
        return float(sum(abs(y_in_obj[i]) * o.size[i] for i in range(3)))

    def opening(self, name, G):
        """The gripper state for grasping or letting go of ``name`` with grasp G (tool_T_object): open as
        wide as the object is across the fingers plus OPEN_CLEARANCE (fully, if that is wider), so that
        the fingers fit beside it where a fully opened hand would not."""
        width = self.grasp_width(name, G) + OPEN_CLEARANCE
        return "open" if width >= self.robot.max_gripper_opening else ("open", width)

    def grasp_opening(self, world, arm, name, grasp):
        """The opening for grasping ``name`` (resting in ``world``) with the arm at vector ``grasp``."""
        T = self.robot.tool_pose(self.config(world.with_arm(arm, grasp)), arm)
        return self.opening(name, np.linalg.inv(T) @ world.objects[name])

    def object_pose(self, world: World, name, q=None) -> np.ndarray:
        arm = world.holder(name)
        if arm is None:
            return world.objects[name]
        q = self.config(world) if q is None else q
        return self.robot.tool_pose(q, arm) @ world.held[arm][1]

    def sync(self, world: World) -> np.ndarray:
        """Make the collision world match ``world``; returns its configuration."""
        last = self._synced
        if world is last:
            return self._synced_q.copy()
        if last is not None and world.arms is last.arms and world.grippers is last.grippers and world.held is last.held:
            q = self._synced_q.copy()  # only the base moved (replace(world, base=...)): base samplers do this a lot
            self.robot.group("base").write(q, world.base)
        else:
            q = self.config(world)
        self._synced_q = q.copy()
        if world.joints is not (last.joints if last is not None else None):
            for name, values in world.joints.items():
                self.bodies[name].update(self.cw, values)
        if last is not None and world.objects is last.objects and world.held is last.held:
            # the same resting objects and grasps (World.with_arm / with_gripper / replace(base=...)
            # share these dicts): nothing in the collision world changes
            self._synced = world
            return q
        cw = self.cw
        want = {o: (a, G) for a, (o, G) in world.held.items()}
        for att in cw.held():
            w = want.get(att.name)
            if w is None or w[0] != att.arm or not np.allclose(w[1], att.tool_T_object, atol=1e-9):
                cw.detach(att.name, q)
        attached = {att.name for att in cw.held()}
        for name, T in world.objects.items():
            if name not in want:
                cw.set_pose(name, T)
        for name, (arm, G) in want.items():
            if name not in attached:
                cw.set_pose(name, self.robot.tool_pose(q, arm) @ G)
                cw.attach(name, arm, q)
        self._synced = world
        return q

    # -- queries ---------------------------------------------------------------------------------
    def _timed(self, fn, acc):
        def wrapped(v):
            t0 = time.perf_counter()
            try:
                return fn(v)
            finally:
                acc[0] += time.perf_counter() - t0
        return wrapped

    def arm_query(self, world, arm, start, goal, label, acc) -> MotionQuery:
        q = self.sync(world)
        group = self.robot.group(f"{arm}_arm")
        held = {o for o, _ in world.held.values()}
        valid = self.cw.checker_for(f"{arm}_arm", q)
        static = self.cw.checker_for(f"{arm}_arm", q, movables=False)

        def movables_at(v):
            return self.cw.colliding_movables(group.set(q, v)) - held

        def tool(v):
            return self.robot.tool_jacobian(group.set(q, v), arm)

        return MotionQuery(self.arm_space[arm], np.asarray(start, float), np.asarray(goal, float),
                           is_valid=self._timed(lambda v: group.within_bounds(v) and valid(v), acc),
                           is_valid_static=self._timed(lambda v: group.within_bounds(v) and static(v), acc),
                           movables_at=self._timed(movables_at, acc), label=label,
                           clearances=self._clearances(q, f"{arm}_arm", acc), tool=tool)

    def base_query(self, world, start, goal, label, acc) -> MotionQuery:
        q = self.sync(world)
        group = self.robot.group("base")
        space = self.base_space
        valid = self.cw.checker_for("base", q)
        static = self.cw.checker_for("base", q, movables=False)
        return MotionQuery(space, np.asarray(start, float), np.asarray(goal, float),
                           is_valid=self._timed(lambda v: space.within_bounds(v) and valid(v), acc),
                           is_valid_static=self._timed(lambda v: space.within_bounds(v) and static(v), acc),
                           movables_at=self._timed(lambda v: self.cw.colliding_movables(group.set(q, v)), acc),
                           label=label, clearances=self._clearances(q, "base", acc),
                           clear_within=self._clear_within(q, "base", acc))

    def _clear_within(self, q, group_name, acc):
        """MotionQuery.clear_within (``_certificate``). Given for the base only: its drives mostly run in
        the open (r040: a fifth of the checks, half the time), while an arm among clutter is rarely clear
        by the 7 cm a block needs, and a check with a margin costs about three plain ones."""
        def clear_within(radius, relaxed):
            clear = self._certificate(q, group_name, radius, movables=not relaxed)
            return clear and self._timed(clear, acc)

        return clear_within

    def _certificate(self, q, group_name, radius, movables=True):
        """A check that the group's bodies are clear of everything by the distance they can move within
        ``radius`` of its argument (``CollisionWorld.motion_bound``): then all of that is collision-free.
        None for a group without a bound."""
        margin = self.cw.motion_bound(group_name) * radius + MARGIN_SLACK
        return self.cw.checker_for(group_name, q, movables=movables, margin=margin) if math.isfinite(margin) else None

    def _clearances(self, q, group_name, acc):
        """Signed distances with analytic gradients (Coal + Pinocchio Jacobians) for trajopt."""
        group = self.robot.group(group_name)

        def clearances(v, movables, margin):
            t0 = time.perf_counter()
            found = self.cw.clearances(group.set(q, v), group_name, margin, movables=movables)
            acc[0] += time.perf_counter() - t0
            return {k: Clearance(d, g) for k, (d, g) in found.items()}

        return clearances

    def static_path_ok(self, world, arm, path, ignore=()) -> bool:
        """The piecewise-straight arm path avoids fixed obstacles (checked at RES_ARM)."""
        with self.stats.timer("collision_checking"):  # the sync (the robot's configuration) is the check's set-up
            q = self.sync(world)
            group = self.robot.group(f"{arm}_arm")
            check = self.cw.checker_for(f"{arm}_arm", q, ignore=tuple(ignore), movables=False)
            return all(check(v) for v in self.arm_space[arm].densify(list(path)) if group.within_bounds(v))

    def in_collision(self, world, movables=True) -> bool:
        with self.stats.timer("collision_checking"):
            return self.cw.in_collision(self.sync(world), movables=movables)

    def hand_free(self, world, arm, T, ignore=(), movables=False) -> bool:
        """The hand alone (opened as in ``world``) with its tool frame at ``T`` touches no fixed obstacle
        (nor movables, if asked): a grasp that fails this needs no IK."""
        with self.stats.timer("collision_checking"):
            return not self.cw.hand_collides(self.sync(world), arm, T, ignore, movables)

    def ik(self, world, arm, target, rng, movables=False, ignore=(), seed=None, attempts=8, gripper=None):
        """Arm vector reaching ``target`` from ``world``'s base (seeded by ``seed``), checked against
        fixed obstacles (and movables if asked), or None."""
        from interlayer_pinocchio import solve_ik

        w = world.with_arm(arm, REACH_SEED[arm] if seed is None else seed)
        if gripper:
            w = w.with_gripper(arm, gripper)
        with self.stats.timer("ik"):  # the sync (the seed configuration) is the solver's set-up
            q = self.sync(w)
            return solve_ik(self.robot, arm, target, q, rng=rng, world=self.cw, attempts=attempts,
                            ignore=tuple(ignore), movables=movables)

    # -- refinement --------------------------------------------------------------------------------
    def refine_step(self, step, world: World, candidate, motion) -> StepOutcome:
        acc = [0.0]
        try:
            if step.action in ("pick", "place") and len(candidate.waypoints) == 3:
                # move_base folded into pick / place (the clutter encoding): (base, arm path 1, arm path 2)
                return self._drive_then(step, world, candidate, motion, acc)
            if step.action == "move_base":
                return self._move_base(step, world, candidate, motion, acc)
            if step.action == "pick":
                return self._pick(step, world, candidate, motion, acc)
            if step.action == "place":
                return self._place(step, world, candidate, motion, acc)
            raise ValueError(step.action)
        finally:
            self.stats.add_time("collision_checking", acc[0])

    def _drive_then(self, step, world, cand, motion, acc):
        base = tuple(float(v) for v in cand.waypoints[0])
        inner = type(cand)(tuple(cand.waypoints[1:]), cand.values, cand.label)
        w = replace(world, base=base)
        if step.action == "pick":  # a blocked approach fails the step whatever the motions: check it first (cheap)
            blocked = self.approach_blocked(step, world, cand, acc)
            if blocked is not None:
                return blocked
        segs = []
        _, failed = self.drive(world, base, f"{step.action} drive", segs, motion, acc,
                               step.args[0] if step.action == "pick" else None)
        if failed:
            return failed
        if step.action == "place" and "tloc" in cand.values:
            obj, P = cand.values["tloc"]
            w = replace(w, tloc={obj: np.asarray(P)})
        out = self._pick(step, w, inner, motion, acc) if step.action == "pick" else self._place(step, w, inner, motion, acc)
        if out.ok:
            out.segments = segs + out.segments
        elif out.failure is not None and out.failure.kind == "obstruction" and "transit" in out.failure.detail:
            out = self._fewer_blockers(step, w, inner, out, acc)
        return out

    def grasps(self, world, arm, obj) -> bool:
        """The arm's tool point lies inside ``obj`` (what the validator calls a grasp)."""
        from .validate import _inside

        tool = self.robot.tool_pose(self.sync(world), arm)
        return _inside(self.specs[obj], (np.linalg.inv(world.objects[obj]) @ tool)[:3, 3])

    def approach_blocked(self, step, world, cand, acc) -> StepOutcome | None:
        """A folded pick's approach, from the candidate's base, checked against the movable objects:
        the failure naming the objects in the way, or None.

        A candidate may carry ``values["other_arm"]``, a function giving (arm, base, approach, world or
        None) of the other arm's best grasp when every grasp of that arm has something in the way (else
        None): its blockers in this world (or the one given: the other arm's object put down) are the
        failure's ``?blocker2`` objects, what refining the pick with that arm would report first, learned
        without a task-planner call that only switches arms. They are found when the loop translates the
        failure, not at every failed attempt."""
        obj, arm = step.args[0], step.args[1]
        blockers = self._approach_blockers(world, obj, arm, cand.waypoints[0], cand.waypoints[1], acc)
        if not blockers:
            return None
        look = cand.values.get("other_arm")

        def also():
            with self.stats.timer("pose_generation"):
                found = look()
            if found is None:
                return {}
            other, base, approach, elsewhere = found
            with self.stats.timer("collision_checking"):
                more = self._approach_blockers(elsewhere or world, obj, other, base, approach, [0.0])
            return {"?blocker2": more} if more else {}

        return StepOutcome(False, failure=Failure("obstruction", blockers, "pick approach: blocked by " + ", ".join(blockers),
                                                  also=also if look is not None else {}))

    def _approach_blockers(self, world, obj, arm, base, approach, acc) -> tuple:
        """The movable objects (obj aside) the arm's ``approach`` from ``base`` touches, sorted."""
        w = replace(world, base=tuple(float(v) for v in base))
        w = w.with_gripper(arm, self.grasp_opening(w, arm, obj, approach[-1]))
        return tuple(sorted(self._movables_on_line(w, arm, approach, acc) - {obj}))

    def drive(self, world, base, label, segs, motion, acc, exclude=None):
        """The base driven to ``base`` (an SE(2) path planned around everything; no segment if it is
        there already): the world there and None, or ``world`` and the failure."""
        base = tuple(float(v) for v in base)
        if self.base_space.distance(np.asarray(world.base, float), np.asarray(base, float)) > 1e-9:
            res = self._plan(motion, self.base_query(world, world.base, base, label, acc), "base", "base", segs,
                             _holding(world), world, acc)
            if not res.ok:
                return world, _failure(res, label, exclude)
        return replace(world, base=base), None

    def _movables_on_line(self, w, arm, path, acc) -> set:
        """Movables the arm touches along the piecewise-straight ``path`` (at the planning resolution)."""
        q = self.sync(w)
        group = self.robot.group(f"{arm}_arm")
        held = {o for o, _ in w.held.values()}
        t0 = time.perf_counter()
        hit = set()
        for v in self.arm_space[arm].densify([np.asarray(p, float) for p in path]):
            hit |= self.cw.colliding_movables(group.set(q, v))
        acc[0] += time.perf_counter() - t0
        return hit - held

    def _fewer_blockers(self, step, w, cand, out, acc):
        """A randomized planner's relaxed path wanders through the clutter and names many blockers; if
        the straight joint-space line to the transit's goal avoids fixed obstacles and runs into fewer
        movables, report those instead (they suffice to clear a path)."""
        arm = step.args[1]
        goal = cand.waypoints[0][0]
        q = self.sync(w)
        group = self.robot.group(f"{arm}_arm")
        static = self.cw.checker_for(f"{arm}_arm", q, movables=False)
        held = {o for o, _ in w.held.values()}
        blockers = set()
        t0 = time.perf_counter()
        try:
            for v in self.arm_space[arm].densify([np.asarray(w.arms[arm], float), np.asarray(goal, float)]):
                if not (group.within_bounds(v) and static(v)):
                    return out
                blockers |= self.cw.colliding_movables(group.set(q, v)) - held
        finally:
            acc[0] += time.perf_counter() - t0
        blockers.discard(step.args[0] if step.action == "pick" else None)
        if blockers and len(blockers) < len(out.failure.objects):
            return StepOutcome(False, failure=Failure("obstruction", tuple(sorted(blockers)),
                                                      out.failure.detail.split(":")[0] + ": the straight line is blocked by "
                                                      + ", ".join(sorted(blockers))))
        return out

    def _plan(self, planner, query, kind, group, segments, holding, world=None, acc=None, retries=2):
        """Plan; a path is then re-checked at the validator's resolution (RES / 5) and planned again
        (up to ``retries`` times) if that finds a contact the planner stepped over."""
        for attempt in range(retries + 1):
            res = planner.plan(query, straight=attempt == 0)
            if not res.ok or world is None or self.fine_ok(world, group, res.path, acc):
                break
            self.stats.count("fine_check_replans")
        else:
            from interlayer.motion import MotionPlan

            res = MotionPlan(False, reason="every path touched an obstacle between two collision checks")
        if res.ok:
            segments.append(self._segment(kind, group, res.path, holding))
        return res

    def _transit(self, motion, w, arm, start, goal, label, segs, acc, staged=None):
        """An arm transit. ``staged`` ("start" or "goal") names an end in a narrow place (a grasp in a
        cubby's mouth): the path first tried goes along the tool's x axis from that end to a staging
        point behind it (the layout's "stage", in m; 0: off), so that the search runs in free space; then
        the plain query."""
        from interlayer.motion import MotionPlan

        group = f"{arm}_arm"
        stage = self.layout.extra.get("stage", 0.0)
        if staged and stage:
            end = np.asarray(goal if staged == "goal" else start, float)
            line = self._staging(w, arm, end, stage)  # from the end outwards
            if line is not None and self.fine_ok(w, group, line, acc):
                a, b = (start, line[-1]) if staged == "goal" else (line[-1], goal)
                res = self._plan(motion, self.arm_query(w, arm, a, b, label, acc), "transit", group, [],
                                 _holding(w), w, acc)
                if res.ok:
                    path = (*res.path, *line[-2::-1]) if staged == "goal" else (*line[:-1], *res.path)
                    segs.append(self._segment("transit", group, path, _holding(w)))
                    return MotionPlan(True, path)
                if res.obstructions:
                    return res
        return self._plan(motion, self.arm_query(w, arm, start, goal, label, acc), "transit", group, segs,
                          _holding(w), w, acc)

    def _staging(self, w, arm, v, stage):
        """Arm vectors from ``v`` to the tool ``stage`` further back along its x axis, or None:
        IK in steps of 5 cm, each seeded by the last, free of everything."""
        from interlayer_pinocchio import solve_ik

        q = self.sync(w.with_arm(arm, v))
        T = self.robot.tool_pose(q, arm)
        group = self.robot.group(f"{arm}_arm")
        n = max(1, math.ceil(stage / 0.05 - 1e-9))
        line = [np.asarray(v, float)]
        for k in range(1, n + 1):
            with self.stats.timer("ik"):
                u = solve_ik(self.robot, arm, T @ trans(-stage * k / n, 0, 0), group.set(q, line[-1]),
                             rng=np.random.default_rng(0), world=self.cw, attempts=1)
            if u is None or self.arm_space[arm].distance(u, line[-1]) > 0.35:
                return None
            line.append(u)
        return line

    def fine_ok(self, world, group, path, acc=None) -> bool:
        """The path is collision-free at the validator's resolution (5x finer than planning).

        Its points are taken FINE_BLOCK at a time (``points_valid``): no point of a block is more than
        FINE_BLOCK // 2 steps from the middle one, so if the middle one is clear of everything by the
        distance a body can move in that many steps (``CollisionWorld.motion_bound``), the whole block
        is collision-free."""
        q = self.sync(world)
        check = self.cw.checker_for(group, q)
        space = self.base_space if group == "base" else self.arm_space[group.split("_")[0]]
        t0 = time.perf_counter()
        step = space.resolution / 5
        ok = points_valid(space.densify(list(path), step), check, self._certificate(q, group, step * (FINE_BLOCK // 2)))
        if acc is not None:
            acc[0] += time.perf_counter() - t0
        return ok

    def limits(self, group) -> tuple[np.ndarray, np.ndarray]:
        """(velocity, acceleration) limits per joint of ``group`` that trajectories respect."""
        timing = {**TIMING, **{k: v for k, v in self.layout.extra.items() if k in TIMING}}
        if group == "base":
            return np.array(timing["base_velocity"], float), np.array(timing["base_acceleration"], float)
        return self.robot.velocity_limits(group), np.full(7, float(timing["arm_acceleration"]))

    def _segment(self, kind, group, path, holding):
        """A motion segment; its points get their timing when the plan is written (``timed``)."""
        names = ["x", "y", "theta"] if group == "base" else list(self.robot.group(group).dof_names)
        points = [{"positions": [float(v) for v in p]} for p in path]
        segment = {"kind": kind, "group": group, "joint_names": names, "points": points, "holding": holding}
        if self._exporting:  # timed by the worker while the run goes on
            from interlayer_optim.timing import prefetch

            prefetch(*self._timing_args(segment))
        return segment

    def prepare_export(self):
        """The run's trajectory will be written: a worker process times segments as they are made."""
        from interlayer_optim.timing import start_worker

        start_worker()
        self._exporting = True

    def timed(self, segment) -> dict:
        """``segment`` with TOPP-RA timing: positions (densified to the planning resolution),
        velocities, accelerations and time_from_start within :meth:`limits`."""
        from interlayer_optim.timing import time_parameterize

        path, vmax, amax, step = self._timing_args(segment)
        with self.stats.timer("timing"):
            points = time_parameterize(path, vmax, amax, step=step)
        if segment["group"] == "base":
            for p in points:
                p["positions"][2] = wrap(p["positions"][2])
        return {**segment, "points": points}

    def _timing_args(self, segment):
        """What :meth:`timed` asks TOPP-RA: the path, the velocity and acceleration limits, the step."""
        group = segment["group"]
        space = self.base_space if group == "base" else self.arm_space[group.split("_")[0]]
        path = [np.asarray(p["positions"], float) for p in segment["points"]]
        if group == "base":  # unwrap the heading, so that the timing follows the short way round
            raw, path = path, path[:1]
            for p in raw[1:]:
                path.append(path[-1] + space.difference(path[-1], p))
        vmax, amax = self.limits(group)
        extra = len(path[0]) - len(vmax)
        if extra > 0:  # a pull: the articulated body's joints follow the hand; the arm's limits bind
            vmax, amax = np.append(vmax, [FOLLOWS] * extra), np.append(amax, [FOLLOWS] * extra)
        return path, vmax, amax, space.resolution

    def _line(self, w, arm, path, kind, segs, acc):
        """A straight tool line through IK waypoints: with ``planner.cartesian`` = "ik:cartesian" the
        tool follows it between waypoints; with "interpolate", each piece is straight in joint space."""
        from interlayer.motion import MotionPlan

        planner = self.cartesian or self.approach
        full = [np.asarray(path[0], float)]
        for a, b in zip(path, path[1:]):
            res = planner.plan(self.arm_query(w, arm, a, b, f"{kind}", acc))
            if not res.ok:
                return res
            full += [np.asarray(p, float) for p in res.path[1:]]
        if not self.fine_ok(w, f"{arm}_arm", full, acc):
            return MotionPlan(False, reason="the straight line touches an obstacle between two collision checks")
        segs.append(self._segment(kind, f"{arm}_arm", full, _holding(w)))
        return MotionPlan(True, tuple(full))

    def _move_base(self, step, world, cand, motion, acc):
        goal = tuple(float(v) for v in cand.waypoints[0])
        segs = []
        res = self._plan(motion, self.base_query(world, world.base, goal, "move_base", acc), "base", "base", segs,
                         _holding(world), world, acc)
        if not res.ok:
            return _failure(res, "base")
        tloc = {}  # what this base pose was chosen for: a put-down spot, or a grasp checked by IK
        if "tloc" in cand.values:
            obj, P = cand.values["tloc"]
            tloc[obj] = np.asarray(P)
        if "grasp" in cand.values:
            key, value = cand.values["grasp"]
            tloc[key] = value
        return StepOutcome(True, replace(world, base=goal, tloc=tloc), segs)

    def _pick(self, step, world, cand, motion, acc):
        obj, arm = step.args[0], step.args[1]
        approach, lift = cand.waypoints
        pre, grasp = approach[0], approach[-1]
        segs, w = [], world
        if not self.grasps(w.with_arm(arm, grasp), arm, obj):
            # a candidate reused for another pose of the object (plan shortcutting refines a later pick
            # again with its old grasp after dropping an earlier move of that object)
            return StepOutcome(False, failure=Failure("ik", (), f"the grasp does not reach {obj} where it stands"))
        res = self._transit(motion, w, arm, w.arms[arm], pre, "pick transit", segs, acc, staged="goal")
        if not res.ok:
            return _failure(res, "pick transit", obj)
        w, stuck = self.set_gripper(w.with_arm(arm, pre), arm, self.grasp_opening(w, arm, obj, grasp), segs,
                                    "opening the gripper at the pre-grasp", obj)
        if stuck:
            return stuck
        res = self._line(w, arm, approach, "approach", segs, acc)
        if not res.ok:
            return _failure(res, "pick approach", obj)
        w = w.with_arm(arm, grasp)
        q = self.sync(w)
        G = np.linalg.inv(self.robot.tool_pose(q, arm)) @ w.objects[obj]
        objects = {k: v for k, v in w.objects.items() if k != obj}
        w = replace(w, objects=objects, held={**w.held, arm: (obj, G)}, grippers={**w.grippers, arm: "closed"},
                    riders={k: v for k, v in w.riders.items() if k != obj})
        segs.append({"kind": "grasp", "arm": arm, "object": obj, "grasp": G.tolist()})
        res = self._line(w, arm, (grasp, *lift), "raise", segs, acc)
        if not res.ok:
            return _failure(res, "pick raise", obj)
        w = w.with_arm(arm, lift[-1])
        carry = self.carry(w, arm, np.random.default_rng(0))
        if carry is None:
            return StepOutcome(False, failure=Failure("ik", (), "no collision-free carry posture"))
        res = self._transit(motion, w, arm, lift[-1], carry, "pick carry", segs, acc, staged="start")
        if not res.ok:
            return _failure(res, "pick carry", obj)
        return StepOutcome(True, w.with_arm(arm, carry), segs)

    def carry(self, world, arm, rng):
        sg = 1.0 if arm == "left" else -1.0
        B = self.robot.base_pose(self.config(world))
        G = world.held[arm][1]
        top = abs((G[:3, :3].T @ np.array([1.0, 0, 0]))[2]) > 0.7  # tool x along the object's axis: a top grasp
        for x, y, z, a in CARRY:
            R = rz(sg * a) if not top else rz(sg * a) @ np.array([[0, 0, 1, 0], [0, 1, 0, 0], [-1, 0, 0, 0], [0, 0, 0, 1.0]])
            T = B @ trans(x, sg * y, z) @ R
            sol = self.ik(world, arm, T, rng, movables=True, attempts=10)
            if sol is not None:
                return sol
        return None

    def _place(self, step, world, cand, motion, acc):
        obj, arm = step.args[0], step.args[1]
        lower, back = cand.waypoints
        above, put = lower[0], lower[-1]
        group, segs, w = f"{arm}_arm", [], world
        res = self._plan(motion, self.arm_query(w, arm, w.arms[arm], above, "place transit", acc), "transit", group,
                         segs, _holding(w), w, acc)
        if not res.ok:
            return _failure(res, "place transit")
        w = w.with_arm(arm, above)
        res = self._line(w, arm, lower, "lower", segs, acc)
        if not res.ok:
            return _failure(res, "place lower")
        w = w.with_arm(arm, put)
        P = self.object_pose(w, obj)
        opened = self.opening(*w.held[arm])
        held = {a: v for a, v in w.held.items() if a != arm}
        w = replace(w, objects={**w.objects, obj: P}, held=held, grippers={**w.grippers, arm: opened},
                    tloc={k: v for k, v in w.tloc.items() if k != obj})
        if self.in_collision(w):
            return self._stuck(w, "opening the gripper at the put-down pose")
        segs.append({"kind": "release", "arm": arm, "object": obj, "pose": P.tolist(), **_width(opened)})
        return self.retreat_and_tuck(motion, w, arm, group, (put, *back), "place", segs, acc)

    def retreat(self, w, arm, path, label, segs, acc):
        """The open hand's straight retreat along ``path``, then the gripper closed: the world after and
        None, or the failure (``label`` names the retreat)."""
        res = self._line(w, arm, path, "retreat", segs, acc)
        if not res.ok:
            return w, _failure(res, label)
        return self.set_gripper(w.with_arm(arm, path[-1]), arm, "closed", segs, "closing the gripper after the retreat")

    def retreat_and_tuck(self, motion, w, arm, group, retreat, what, segs, acc):
        """The open hand's straight retreat along ``retreat``, the gripper closed, the arm tucked: the
        end of every step that lets go of something (``what`` names it in failures)."""
        from interlayer_pinocchio import TUCKED_ARMS

        w, failed = self.retreat(w, arm, retreat, f"{what} retreat", segs, acc)
        if failed:
            return failed
        res = self._plan(motion, self.arm_query(w, arm, retreat[-1], TUCKED_ARMS[arm], f"{what} tuck", acc), "transit",
                         group, segs, _holding(w), w, acc)
        if not res.ok:
            return _failure(res, f"{what} tuck")
        return StepOutcome(True, w.with_arm(arm, TUCKED_ARMS[arm]), segs)

    # -- articulated bodies ------------------------------------------------------------------------
    def pull_states(self, world, arm, body, path, fine=1):
        """(world, arm vector, joint values) along a pull: ``path`` holds arm vectors followed by the
        body's joint values, interpolated together (steps of RES_ARM / RES_BASE, divided by ``fine``)."""
        n = len(self.robot.group(f"{arm}_arm").dof_names)
        space = self.arm_space[arm]
        for k, (a, b) in enumerate(zip(path, path[1:])):
            a, b = np.asarray(a, float), np.asarray(b, float)
            steps = max(1, math.ceil(max(space.distance(a[:n], b[:n]) / RES_ARM,
                                         float(np.max(np.abs(b[n:] - a[n:]))) / RES_BASE) * fine))
            for i in range(0 if k == 0 else 1, steps + 1):
                p = a + (b - a) * (i / steps)
                yield self.with_joints(world, body, p[n:]).with_arm(arm, p[:n]), p[:n], p[n:]

    def pull_hits(self, world, body, ignore=(), robot=True) -> tuple[set, bool]:
        """(movables in the way, whether something fixed is) at ``world``: the robot and held objects
        (unless ``robot`` is False), the body's moving elements and the objects riding on them, against
        everything else."""
        q = self.sync(world)
        b = self.bodies[body]
        riders = {o for o, (name, _) in world.riders.items() if name == body}
        held = {o for o, _ in world.held.values()}
        others = [o for o in world.objects if o not in riders and o not in ignore]
        hit, fixed = set(), False
        with self.stats.timer("collision_checking"):
            if robot:
                hit = self.cw.colliding_movables(q) - held - set(ignore)
                fixed = self.cw.in_collision(q, movables=False)
            hit |= b.touching(self.cw, world.joints[body], others)
            for o in riders & world.objects.keys():
                hit |= self.cw.objects_overlap(o, world.objects[o]) & set(others)
        return hit, fixed

    def sweep_blockers(self, world, body, values) -> set:
        """Movables that the body's moving elements (and what rides on them) run into when its joints go
        straight from their values in ``world`` to ``values`` (checked every RES_BASE): whatever the arm
        does, such a pull is blocked, so check this first (cheap)."""
        a, b = np.asarray(world.joints[body], float), np.asarray(values, float)
        n = max(1, math.ceil(float(np.max(np.abs(b - a))) / RES_BASE))
        for k in range(1, n + 1):
            hit, _ = self.pull_hits(self.with_joints(world, body, a + (b - a) * k / n), body, robot=False)
            if hit:
                return hit
        return set()

    def pull(self, step, world, arm, body, link, path, segs, kind="pull", fine=1) -> StepOutcome:
        """Drag ``link`` of ``body`` with the gripper along ``path`` (arm vector + joint values per point;
        see pull_states), checked at every state; appends the segment (joint_names: the arm's joints,
        then "<body>/<joint>")."""
        last = world
        for w, _, _ in self.pull_states(world, arm, body, path, fine):
            hit, fixed = self.pull_hits(w, body)
            if hit:
                return StepOutcome(False, failure=Failure("obstruction", tuple(sorted(hit)),
                                                          f"{kind}: the arm or {body} runs into " + ", ".join(sorted(hit))))
            if fixed:
                return StepOutcome(False, failure=Failure("unreachable", (), f"{kind}: collides with fixed obstacles"))
            last = w
        b = self.bodies[body]
        names = list(self.robot.group(f"{arm}_arm").dof_names) + [f"{body}/{j}" for j in b.joint_names]
        seg = self._segment(kind, f"{arm}_arm", [np.asarray(p, float) for p in path], _holding(world))
        seg.update(joint_names=names, body=body, link=link)
        segs.append(seg)
        return StepOutcome(True, last, segs)

    def set_gripper(self, w, arm, state, segs, what, exclude=None):
        """The arm's gripper set to ``state`` ("open", ("open", width), "closed" or a width in metres: closed
        on a handle) where it is: the new world and None, or the failure if the fingers then collide
        (``what`` names the moment). The event records the width unless fully open or closed."""
        w = w.with_gripper(arm, state)
        if self.in_collision(w):
            return w, self._stuck(w, what, exclude)
        segs.append({"kind": "gripper", "arm": arm, "command": "open" if is_open(state) else "close", **_width(state)})
        return w, None

    def _stuck(self, w, what, exclude=None):
        q = self.sync(w)
        movables = self.cw.colliding_movables(q) - {o for o, _ in w.held.values()} - {exclude}
        if movables:
            return StepOutcome(False, failure=Failure("obstruction", tuple(sorted(movables)), f"{what}: blocked"))
        return StepOutcome(False, failure=Failure("unreachable", (), f"{what}: collides with fixed obstacles"))

    # -- output and validation ---------------------------------------------------------------------
    def trajectory_json(self, plan, outcomes) -> dict:
        return {"domain": "pr2", "frame": "world, metres / radians; base joints x, y, theta",
                "format": "per segment a trajectory_msgs/JointTrajectory (joint_names, points with positions and "
                          "time_from_start); gripper open/close, grasp (attach) and release (detach) events between",
                "initial": self.initial_world().to_json(),
                "steps": [{"action": s.action, "args": list(s.args),
                           "segments": [self.timed(seg) if "points" in seg else seg for seg in o.segments]}
                          for s, o in zip(plan, outcomes)]}

    def validate(self, plan, trajectory: dict) -> list[str]:
        from .validate import validate_trajectory

        return validate_trajectory(type(self)(self.layout, padding=0.0), plan, trajectory)


def _width(state) -> dict:
    """The "width" field of a gripper event for ``state``: none when fully open or closed."""
    if isinstance(state, str):
        return {}
    return {"width": float(state[1] if is_open(state) else state)}


def _holding(world):
    return {a: o for a, (o, _) in world.held.items()}


def _failure(plan, phase, exclude=None) -> StepOutcome:
    """An obstruction failure names the movables in the way (never the object being picked)."""
    blockers = tuple(o for o in plan.obstructions if o != exclude)
    if blockers:
        return StepOutcome(False, failure=Failure("obstruction", blockers, f"{phase}: {plan.reason}"))
    return StepOutcome(False, failure=Failure("unreachable", (), f"{phase}: {plan.reason}"))
