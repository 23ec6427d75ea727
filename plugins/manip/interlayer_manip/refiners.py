"""The pick / place / move_base refiners of the manipulation geometry (Alg. 2's step refinement):
drives, arm transits, straight tool lines, grasp and release, retreat and tuck."""
from __future__ import annotations

import time
from dataclasses import replace

import numpy as np

from interlayer.refine import Failure, StepOutcome

from .state import World, _failure, _holding, _width, is_open


class Refiners:
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
        if step.action == "pick":  # a lost grasp or a blocked approach fails the step whatever the motions: first (cheap)
            blocked = (self._grasp_lost(w, step.args[1], step.args[0], inner.waypoints[0][-1])
                       or self.approach_blocked(step, world, cand, acc))
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

    def _line(self, w, arm, path, kind, segs, acc):
        """A straight tool line through IK waypoints: with ``planner.cartesian`` = "ik:cartesian" the
        tool follows it between waypoints; with "interpolate", each piece is straight in joint space.
        Checked against fixed obstacles padded by LINE_PADDING only (``tight``), at the validator's resolution."""
        from interlayer.motion import MotionPlan

        planner = self.cartesian or self.approach
        full = [np.asarray(path[0], float)]
        with self.tight():
            for a, b in zip(path, path[1:]):
                res = planner.plan(self.arm_query(w, arm, a, b, f"{kind}", acc))
                if not res.ok:
                    return res
                full += [np.asarray(p, float) for p in res.path[1:]]
            fine = self.fine_ok(w, f"{arm}_arm", full, acc)
        if not fine:
            return MotionPlan(False, reason="the straight line touches an obstacle between two collision checks")
        segs.append(self._segment(kind, f"{arm}_arm", full, _holding(w)))
        return MotionPlan(True, tuple(full))

    def _move_base(self, step, world, cand, motion, acc):
        goal = tuple(float(v) for v in cand.waypoints[0])
        segs = []
        if self.robot.mobile:
            res = self._plan(motion, self.base_query(world, world.base, goal, "move_base", acc), "base", "base", segs,
                             _holding(world), world, acc)
            if not res.ok:
                return _failure(res, "base")
        elif self.base_space.distance(np.asarray(world.base, float), np.asarray(goal, float)) > 1e-9:
            return StepOutcome(False, failure=Failure("unreachable", (), "move_base: the robot's base is fixed"))
        tloc = {}  # what this base pose was chosen for: a put-down spot, or a grasp checked by IK
        if "tloc" in cand.values:
            obj, P = cand.values["tloc"]
            tloc[obj] = np.asarray(P)
        if "grasp" in cand.values:
            key, value = cand.values["grasp"]
            tloc[key] = value
        return StepOutcome(True, replace(world, base=goal, tloc=tloc), segs)

    def _grasp_lost(self, w, arm, obj, grasp) -> StepOutcome | None:
        """The failure of a pick whose grasp (arm vector) does not hold ``obj`` where it stands in ``w``: a
        candidate reused for another pose of the object (plan shortcutting refines a later pick again with
        its old grasp after dropping an earlier move of that object)."""
        if self.grasps(w.with_arm(arm, grasp), arm, obj):
            return None
        return StepOutcome(False, failure=Failure("ik", (), f"the grasp does not hold {obj} where it stands"))

    def _pick(self, step, world, cand, motion, acc):
        obj, arm = step.args[0], step.args[1]
        approach, lift = cand.waypoints
        pre, grasp = approach[0], approach[-1]
        segs, w = [], world
        lost = self._grasp_lost(w, arm, obj, grasp)
        if lost:
            return lost
        res = self._transit(motion, w, arm, w.arms[arm], pre, "pick transit", segs, acc, staged="goal")
        if not res.ok:
            return _failure(res, "pick transit", obj)
        w, stuck = self.set_gripper(w.with_arm(arm, pre), arm, self.grasp_opening(w, arm, obj, grasp), segs,
                                    "opening the gripper at the pre-grasp", obj)
        if stuck:
            return stuck
        res = self._line(w, arm, approach, "approach", segs, acc)
        if not res.ok:
            return _failure(res, "pick approach", obj, start_free=True)
        w = w.with_arm(arm, grasp)
        q = self.sync(w)
        G = np.linalg.inv(self.robot.tool_pose(q, arm)) @ w.objects[obj]
        objects = {k: v for k, v in w.objects.items() if k != obj}
        w = replace(w, objects=objects, held={**w.held, arm: (obj, G)}, grippers={**w.grippers, arm: "closed"},
                    riders={k: v for k, v in w.riders.items() if k != obj})
        segs.append({"kind": "grasp", "arm": arm, "object": obj, "grasp": G.tolist()})
        res = self._line(w, arm, (grasp, *lift), "raise", segs, acc)
        if not res.ok:
            return _failure(res, "pick raise", obj, start_free=True)
        w = w.with_arm(arm, lift[-1])
        if not self.robot.carry_poses(arm):  # no carry postures (a fixed arm): it keeps the lifted pose
            return StepOutcome(True, w, segs)
        carry = self.carry(w, arm, np.random.default_rng(0))
        if carry is None:
            return StepOutcome(False, failure=Failure("ik", (), "no collision-free carry posture"))
        res = self._transit(motion, w, arm, lift[-1], carry, "pick carry", segs, acc, staged="start")
        if not res.ok:
            return _failure(res, "pick carry", obj, start_free=True)
        return StepOutcome(True, w.with_arm(arm, carry), segs)

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
            return _failure(res, "place lower", start_free=True)
        w = w.with_arm(arm, put)
        P = self.object_pose(w, obj)
        opened = self.opening(*w.held[arm])
        held = {a: v for a, v in w.held.items() if a != arm}
        w = replace(w, objects={**w.objects, obj: P}, held=held, grippers={**w.grippers, arm: opened},
                    tloc={k: v for k, v in w.tloc.items() if k != obj})
        with self.tight():  # the end of the lowering line
            stuck = self.in_collision(w) and self._stuck(w, "opening the gripper at the put-down pose")
        if stuck:
            return stuck
        segs.append({"kind": "release", "arm": arm, "object": obj, "pose": P.tolist(), **_width(opened)})
        return self.retreat_and_tuck(motion, w, arm, group, (put, *back), "place", segs, acc)

    def retreat(self, w, arm, path, label, segs, acc):
        """The open hand's straight retreat along ``path``, then the gripper closed: the world after and
        None, or the failure (``label`` names the retreat)."""
        res = self._line(w, arm, path, "retreat", segs, acc)
        if not res.ok:
            return w, _failure(res, label, start_free=True)
        return self.set_gripper(w.with_arm(arm, path[-1]), arm, "closed", segs, "closing the gripper after the retreat")

    def retreat_and_tuck(self, motion, w, arm, group, retreat, what, segs, acc):
        """The open hand's straight retreat along ``retreat``, the gripper closed, the arm tucked: the
        end of every step that lets go of something (``what`` names it in failures)."""
        w, failed = self.retreat(w, arm, retreat, f"{what} retreat", segs, acc)
        if failed:
            return failed
        res = self._plan(motion, self.arm_query(w, arm, retreat[-1], self.robot.home(arm), f"{what} tuck", acc), "transit",
                         group, segs, _holding(w), w, acc)
        if not res.ok:
            return _failure(res, f"{what} tuck", start_free=True)
        return StepOutcome(True, w.with_arm(arm, self.robot.home(arm)), segs)

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
            return StepOutcome(False, failure=Failure("obstruction", tuple(sorted(movables)), f"{what}: blocked",
                                                      start_free=True))
        return StepOutcome(False, failure=Failure("unreachable", (), f"{what}: collides with fixed obstacles"))
