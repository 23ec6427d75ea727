"""The Dinner domain's refinement runtime: the PR2 geometry plus the tray carried with both hands.

Objects on the tray and objects stacked on them are riders (``World.riders``: object -> (support,
slot or "stack")). While the tray is carried (``DinnerWorld.carrying``: object -> its pose in the base
frame) both hands stay closed around the tray's near edge and only the base moves: the tray and its
riders move rigidly with the base, are checked against everything else at every base state, and come
to rest again when the tray is set down. A place-type step (place, put_on_tray, stack) drives to the
sampled base pose (OMPL, SE(2)) and puts the object down at its fixed place; a pick-type step (pick,
take_off_tray, unstack) drives and grasps; ``go`` drives through the doorway to the other room;
``handoff`` passes the object from one hand to the other where the robot stands.
"""
from __future__ import annotations

from dataclasses import dataclass, field, replace

import coal
import numpy as np

from interlayer.domain import GroundStep
from interlayer.motion import MotionQuery
from interlayer.refine import Failure, StepOutcome
from interlayer_manip.scene import REST_GAP, _radius
from interlayer_manip.state import PADDING, World, _failure, _holding, pose4, rz, trans
from interlayer_manip.world import ManipulationGeometry

from .scene import TOP, TRAY

TRAY_GRIP = TRAY[2] + 0.004  # m between the finger pads closed around the tray's edge
TOP_DEPTH = 0.03  # a top grasp's tool point this far below the object's top, at most mid-height (pr2 grasp_poses)
HANDOVER_GAP = 0.01  # m from a top grasp's tool point down to the receiving side grasp's, at mid-height
PICKS = ("pick", "take_off_tray", "unstack")
PLACES = ("place", "put_on_tray", "stack")


@dataclass(frozen=True)
class DinnerWorld(World):
    carrying: dict = field(hash=False, default_factory=dict)  # object -> base_T_object while the tray is carried

    def to_json(self) -> dict:
        out = super().to_json()
        if self.riders:
            out["riders"] = {k: list(v) for k, v in self.riders.items()}
        if self.carrying:
            out["carrying"] = {k: np.asarray(v).tolist() for k, v in self.carrying.items()}
        return out


def _coal_tf(P):
    return coal.Transform3s(np.ascontiguousarray(P[:3, :3]), np.ascontiguousarray(P[:3, 3]))


def base_matrix(base) -> np.ndarray:
    return pose4(base[0], base[1], 0.0, base[2])


class DinnerGeometry(ManipulationGeometry):
    def __init__(self, layout, padding: float = PADDING):
        super().__init__(layout, padding=padding)
        self.kinds = layout.extra["kinds"]
        self.slots = {f"slot{k + 1}": xy for k, xy in enumerate(layout.extra["slots"])}
        self._radius = {o.name: _radius(o) for o in layout.fixed + layout.objects}
        self._request = coal.CollisionRequest()
        self._fixed_tf = {o.name: _coal_tf(pose4(*o.pose)) for o in layout.fixed}
        self._boxes = {o.name: (o.pose[:2], (o.size[0] / 2 + padding, o.size[1] / 2 + padding)) for o in layout.fixed}

    # -- world ----------------------------------------------------------------------------------
    def initial_world(self) -> DinnerWorld:
        w = super().initial_world()
        return DinnerWorld(w.base, w.arms, w.grippers, w.objects, w.held, w.tloc, w.joints, w.riders)

    def height(self, name) -> float:
        return self.specs[name].height

    def slot_pose(self, world, slot, obj) -> np.ndarray:
        """Where ``obj`` stands in ``slot`` of the tray (resting on it)."""
        dx, dy = self.slots[slot]
        return world.objects["tray"] @ trans(dx, dy, TRAY[2] / 2 + REST_GAP + self.height(obj) / 2)

    def setting_pose(self, obj) -> np.ndarray:
        x, y = self.layout.extra["settings"][obj]
        return pose4(x, y, TOP + REST_GAP + self.height(obj) / 2, 0.0)

    def stack_pose(self, world, upper, lower) -> np.ndarray:
        P = world.objects[lower]
        return trans(P[0, 3], P[1, 3], P[2, 3] + self.height(lower) / 2 + REST_GAP + self.height(upper) / 2)

    def assembly(self, world) -> list:
        """The tray and everything resting on it, directly or stacked."""
        out = ["tray"]
        for name in out:
            out += [o for o, (support, _) in world.riders.items() if support == name and o not in out]
        return out

    def sides(self, names) -> set:
        """Near / NearLoc facts (side_costs): the left or right half of the objects on the side table (the
        robot's left is +y, facing it) and of the place settings (its left is -y, facing the dinner table);
        the tray stands on its right."""
        settings = self.layout.extra["settings"]
        mid_o = float(np.median([self.specs[o].pose[1] for o in names]))
        mid_s = float(np.median([settings[o][1] for o in names]))
        facts = {("NearLoc", "tray", "right")}
        for o in names:
            facts.add(("Near", o, "left" if self.specs[o].pose[1] > mid_o else "right"))
            facts.add(("NearLoc", f"set_{o}", "left" if settings[o][1] < mid_s else "right"))
        return facts

    def passable(self, names) -> set:
        """Objects one hand can take from the other: tall enough that a side grasp at mid-height stays
        below the fingertips of a top grasp. A bowl held from above could only be taken lower down, and
        a hand that low cannot put it down on a table or the tray again (its fingers would hit it)."""
        return {o for o in names if self.height(o) / 2 - min(TOP_DEPTH, self.height(o) / 2) >= HANDOVER_GAP}

    def free_slots(self, world) -> list:
        """The tray's slots with nothing standing in them, in order."""
        taken = {slot for o, (support, slot) in world.riders.items() if support == "tray" and o in world.objects}
        return [s for s in self.slots if s not in taken]

    # -- the carried tray -------------------------------------------------------------------------
    def sync(self, world) -> np.ndarray:
        q = super().sync(world)
        carrying = getattr(world, "carrying", None)
        if carrying:
            B = base_matrix(world.base)
            for name, rel in carrying.items():
                self.cw.set_pose(name, B @ rel)
        return q

    def carried_hits(self, world, base=None, movables=True) -> set:
        """What the carried tray and its riders touch with the base at ``base``: fixed obstacles by name
        and (with ``movables``) resting objects."""
        carrying = world.carrying
        B = base_matrix(world.base if base is None else base)
        others = [n for n in (*self.fixed, *world.objects) if n not in carrying and (movables or n in self.fixed)]
        hits = set()
        for name, rel in carrying.items():
            P = B @ rel
            tf = None
            for o in others:
                if o in hits or self._gap(o, P[:2, 3], world) >= self._radius[name] + 0.05:
                    continue
                tf = tf or _coal_tf(P)
                other = self._fixed_tf.get(o) or _coal_tf(world.objects[o])
                if coal.collide(self.cw.geometry(name), tf, self.cw.geometry(o), other, self._request, coal.CollisionResult()):
                    hits.add(o)
        return hits

    def _gap(self, name, xy, world) -> float:
        """A lower bound of the horizontal distance from xy to object ``name`` (fixed boxes are axis-aligned)."""
        box = self._boxes.get(name)
        if box is not None:
            (cx, cy), (hx, hy) = box
            return max(abs(xy[0] - cx) - hx, abs(xy[1] - cy) - hy)
        return float(np.hypot(*(xy - world.objects[name][:2, 3]))) - self._radius[name]

    def in_collision(self, world, movables=True) -> bool:
        if super().in_collision(world, movables):
            return True
        return bool(getattr(world, "carrying", None)) and bool(self.carried_hits(world, movables=movables))

    def _carry_checker(self, world, movables):
        """is_valid(base) for the robot with the tray: the robot as usual (the carried objects left out:
        they move with it), and the carried objects against everything else."""
        q = self.sync(world)
        robot = self.cw.checker_for("base", q, ignore=tuple(world.carrying), movables=movables)
        space = self.base_space
        return lambda v: space.within_bounds(v) and robot(v) and not self.carried_hits(world, v, movables)

    def base_query(self, world, start, goal, label, acc) -> MotionQuery:
        query = super().base_query(world, start, goal, label, acc)
        if not getattr(world, "carrying", None):
            return query
        q = self.sync(world)
        group, carried = self.robot.group("base"), tuple(world.carrying)

        def movables_at(v):
            return (self.cw.colliding_movables(group.set(q, v), ignore=carried)
                    | (self.carried_hits(world, v) - self.fixed))

        return replace(query, is_valid=self._timed(self._carry_checker(world, True), acc),
                       is_valid_static=self._timed(self._carry_checker(world, False), acc),
                       movables_at=self._timed(movables_at, acc), clearances=None, clear_within=None)

    def fine_ok(self, world, group, path, acc=None) -> bool:
        if group != "base" or not getattr(world, "carrying", None):
            return super().fine_ok(world, group, path, acc)
        check = self._carry_checker(world, True)
        return all(check(v) for v in self.base_space.densify(list(path), self.base_space.resolution / 5))

    # -- refinement --------------------------------------------------------------------------------
    def refine_step(self, step, world, candidate, motion) -> StepOutcome:
        action = step.action.removesuffix("_cross")
        if action == "go":
            acc = [0.0]
            try:
                return self._move_base(step, world, candidate, motion, acc)
            finally:
                self.stats.add_time("collision_checking", acc[0])
        if action == "stack" and "unstackable" in candidate.values:
            return StepOutcome(False, failure=Failure("unstackable", candidate.values["pairs"], candidate.values["unstackable"],
                                                      static=True))
        if action in PICKS:
            return super().refine_step(GroundStep("pick", step.args), world, candidate, motion)
        if action in PLACES:
            out = super().refine_step(GroundStep("place", step.args), world, candidate, motion)
            if out.ok and action != "place":
                obj = step.args[0]
                support = ("tray", candidate.values["slot"]) if action == "put_on_tray" else (step.args[2], "stack")
                out = replace(out, world=replace(out.world, riders={**out.world.riders, obj: support}))
            return out
        acc = [0.0]
        try:
            if action == "pick_tray":
                return self._pick_tray(world, candidate, motion, acc)
            if action == "place_tray":
                return self._place_tray(world, candidate, motion, acc)
            if action == "handoff":
                return self._handoff(step, world, candidate, motion, acc)
        finally:
            self.stats.add_time("collision_checking", acc[0])
        raise ValueError(step.action)

    def _pick_tray(self, world, cand, motion, acc):
        base, *lines = cand.waypoints
        segs = []
        w, failed = self.drive(world, base, "tray drive", segs, motion, acc)
        if failed:
            return failed
        for arm, line in zip(("left", "right"), lines):
            res = self._plan(motion, self.arm_query(w, arm, w.arms[arm], line[0], "tray transit", acc), "transit",
                             f"{arm}_arm", segs, {}, w, acc)
            if not res.ok:
                return _failure(res, f"tray transit ({arm})", "tray")
            w, stuck = self.set_gripper(w.with_arm(arm, line[0]), arm, "open", segs,
                                        "opening the gripper before the tray", "tray")
            if stuck:
                return stuck
            res = self._line(w, arm, line, "approach", segs, acc)
            if not res.ok:
                return _failure(res, f"tray approach ({arm})", "tray")
            w, stuck = self.set_gripper(w.with_arm(arm, line[-1]), arm, TRAY_GRIP, segs,
                                        "closing the gripper around the tray", "tray")
            if stuck:
                return stuck
        names = self.assembly(w)
        Binv = np.linalg.inv(base_matrix(w.base))
        w = replace(w, objects={k: v for k, v in w.objects.items() if k not in names},
                    carrying={k: Binv @ w.objects[k] for k in names})
        segs.append({"kind": "carry", "objects": names})
        return StepOutcome(True, w, segs)

    def _place_tray(self, world, cand, motion, acc):
        base, *retreats = cand.waypoints
        segs = []
        w, failed = self.drive(world, base, "tray drive", segs, motion, acc)
        if failed:
            return failed
        B = base_matrix(w.base)
        poses = {k: B @ rel for k, rel in w.carrying.items()}
        w = replace(w, objects={**w.objects, **poses}, carrying={})
        segs.append({"kind": "set_down", "objects": {k: P.tolist() for k, P in poses.items()}})
        for arm, back in zip(("left", "right"), retreats):
            w, stuck = self.set_gripper(w, arm, "open", segs, "opening the gripper on the tray")
            if stuck:
                return stuck
            w, failed = self.retreat(w, arm, back, f"tray retreat ({arm})", segs, acc)
            if failed:
                return failed
        # a tucked arm folds across the front, where the other arm still reaches: raise the left one
        # beside its shoulder first, tuck the right, then the left
        raised = self.raised(w, "left")
        if raised is None:
            return StepOutcome(False, failure=Failure("ik", (), "no collision-free raised posture for the left arm"))
        for arm, goal in (("left", raised), ("right", self.robot.home("right")), ("left", self.robot.home("left"))):
            res = self._plan(motion, self.arm_query(w, arm, w.arms[arm], goal, "tray tuck", acc), "transit",
                             f"{arm}_arm", segs, {}, w, acc)
            if not res.ok:
                return _failure(res, f"tray tuck ({arm})")
            w = w.with_arm(arm, goal)
        return StepOutcome(True, w, segs)

    def _handoff(self, step, world, cand, motion, acc):
        """The holding hand presents the object, the other hand approaches and closes on it, the first
        opens, retreats and tucks, the receiving arm goes to its carry posture."""
        obj, src, dst = step.args
        hold, approach, retreat = cand.waypoints
        segs, w = [], world
        res = self._plan(motion, self.arm_query(w, src, w.arms[src], hold, "handoff present", acc), "transit",
                         f"{src}_arm", segs, _holding(w), w, acc)
        if not res.ok:
            return _failure(res, "handoff present")
        w = w.with_arm(src, hold)
        res = self._plan(motion, self.arm_query(w, dst, w.arms[dst], approach[0], "handoff transit", acc), "transit",
                         f"{dst}_arm", segs, _holding(w), w, acc)
        if not res.ok:
            return _failure(res, "handoff transit")
        w, stuck = self.set_gripper(w.with_arm(dst, approach[0]), dst, "open", segs,
                                    "opening the receiving gripper", obj)
        if stuck:
            return stuck
        res = self._line(w, dst, approach, "approach", segs, acc)
        if not res.ok:
            return _failure(res, "handoff approach")
        w = w.with_arm(dst, approach[-1])
        q = self.sync(w)
        G = np.linalg.inv(self.robot.tool_pose(q, dst)) @ self.object_pose(w, obj, q)
        w = replace(w, held={dst: (obj, G), **{a: v for a, v in w.held.items() if a != src}},
                    grippers={**w.grippers, dst: "closed", src: "open"})
        if self.in_collision(w):
            return self._stuck(w, "handing over", obj)
        segs.append({"kind": "handover", "object": obj, "from": src, "to": dst, "grasp": G.tolist()})
        out = self.retreat_and_tuck(motion, w, src, f"{src}_arm", retreat, "handoff", segs, acc)
        if not out.ok:
            return out
        w = out.world
        carry = self.carry(w, dst, np.random.default_rng(0))
        if carry is None:
            return StepOutcome(False, failure=Failure("ik", (), "no collision-free carry posture after the handoff"))
        res = self._plan(motion, self.arm_query(w, dst, w.arms[dst], carry, "handoff carry", acc), "transit",
                         f"{dst}_arm", segs, _holding(w), w, acc)
        if not res.ok:
            return _failure(res, "handoff carry")
        return StepOutcome(True, w.with_arm(dst, carry), segs)

    def raised(self, world, arm):
        """An arm vector with the hand raised beside its shoulder (the PR2's carry postures), or None."""
        B = base_matrix(world.base)
        for x, y, z, a in self.robot.carry_poses(arm):
            sol = self.ik(world, arm, B @ trans(x, y, z) @ rz(a), np.random.default_rng(0), movables=True,
                          attempts=10, seed=world.arms[arm])
            if sol is not None:
                return sol
        return None

    # -- output and validation ---------------------------------------------------------------------
    def trajectory_json(self, plan, outcomes) -> dict:
        out = super().trajectory_json(plan, outcomes)
        out["domain"] = "dinner"
        out["format"] += ("; a carry event lists the tray and the objects riding on it, which then move rigidly with "
                          "the base until a set_down event gives their resting poses")
        return out

    def validate(self, plan, trajectory: dict) -> list[str]:
        from interlayer_manip.validate import validate_trajectory

        from . import validate

        return validate_trajectory(type(self)(self.layout, padding=0.0), plan, trajectory, rules=validate)

    def describe(self) -> str:
        """The scene's stackability facts, as the module decides them (``interlayer check``)."""
        from .stacking import unstackable_pairs

        pairs = unstackable_pairs(self.layout.objects, self.kinds)
        n = len([o for o in self.layout.objects if o.name != "tray"])
        return (f"Dinner-{n}: {len(self.slots)} tray slot(s); {n * (n - 1) - len(pairs)} of {n * (n - 1)} ordered pairs "
                f"stack; e.g. " + "; ".join(r for _, _, r in pairs[:3]))

    def draw_scene(self, scene, world=None):
        from interlayer_manip import draw

        names = draw.draw_scene(self, scene, world)
        scene.view_direction = (0.2, -1.0, 1.3)  # from the side: both rooms, the doorway between them
        return names

    def animation_frames(self, scene, trajectory):
        from interlayer_manip import draw

        return draw.animation_frames(self, scene, trajectory)


__all__ = ["DinnerGeometry", "DinnerWorld", "rz"]
