"""IK and grasp helpers of the manipulation geometry: IK from the current base, staging lines out of
narrow places, carry postures, whether the tool holds an object, blocked approaches."""
from __future__ import annotations

import math
from dataclasses import replace

import numpy as np

from interlayer.refine import Failure, StepOutcome

from .state import rz, trans

# how many links of a chain of blockers a blocked pick learns at once (Reach.blocker_chain): the blockers'
# own blockers, and theirs
CHAIN_DEPTH = 2
MIRRORED = np.diag([1.0, -1.0, -1.0, 1.0])  # a tool pose rolled half a turn about its x (approach) axis


class Reach:
    def ik(self, world, arm, target, rng, movables=False, ignore=(), seed=None, attempts=8, gripper=None):
        """Arm vector reaching ``target`` from ``world``'s base (seeded by ``seed``), checked against
        fixed obstacles (and movables if asked), or None."""
        from interlayer_pinocchio import solve_ik

        w = world.with_arm(arm, self.robot.reach_seed(arm) if seed is None else seed)
        if gripper:
            w = w.with_gripper(arm, gripper)
        self.stats.count("ik_calls")
        with self.stats.timer("ik"):  # the sync (the seed configuration) is the solver's set-up
            q = self.sync(w)
            found = solve_ik(self.robot, arm, target, q, rng=rng, world=self.cw, attempts=attempts,
                             ignore=tuple(ignore), movables=movables)
            if found is None and not self.robot.mobile and not world.held.get(arm):
                # a fixed base cannot step round to reach it: the same pose with the fingers swapped (rolled
                # half a turn about the approach axis) may be within the wrist's range; not with an object in
                # the hand, which would roll with it (a cylinder put down upside down)
                found = solve_ik(self.robot, arm, target @ MIRRORED, q, rng=rng, world=self.cw, attempts=attempts,
                                 ignore=tuple(ignore), movables=movables)
            return found

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

    def carry(self, world, arm, rng):
        B = self.robot.base_pose(self.config(world))
        G = world.held[arm][1]
        top = abs((G[:3, :3].T @ np.array([1.0, 0, 0]))[2]) > 0.7  # tool x along the object's axis: a top grasp
        for x, y, z, a in self.robot.carry_poses(arm):
            R = rz(a) if not top else rz(a) @ np.array([[0, 0, 1, 0], [0, 1, 0, 0], [-1, 0, 0, 0], [0, 0, 0, 1.0]])
            T = B @ trans(x, y, z) @ R
            sol = self.ik(world, arm, T, rng, movables=True, attempts=10)
            if sol is not None:
                return sol
        return None

    def grasps(self, world, arm, obj) -> bool:
        """The arm's tool point lies inside ``obj`` and the gripper opens wider than ``obj`` is across the
        fingers (what the validator calls a grasp)."""
        from .validate import _inside

        tool = self.robot.tool_pose(self.sync(world), arm)
        G = np.linalg.inv(tool) @ world.objects[obj]
        return (_inside(self.specs[obj], np.linalg.inv(G)[:3, 3])
                and self.grasp_width(obj, G) <= self.robot.max_gripper_opening)

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

        chain = cand.values.get("chain")
        return StepOutcome(False, failure=Failure("obstruction", blockers, "pick approach: blocked by " + ", ".join(blockers),
                                                  also=also if look is not None else {},
                                                  related=self.blocker_chain(world, obj, blockers, chain) if chain else (),
                                                  start_free=True))

    def blocker_chain(self, world, obj, blockers, chain, depth: int = CHAIN_DEPTH):
        """``Failure.related`` of a pick of obj that ``blockers`` block, as a function called once: for each
        blocker (then each of theirs, ``depth`` links deep) and each arm, the objects on the approach of
        that arm's best grasp of it in ``world`` (``chain(object, arm)``: (base, approach, world or None) or
        None when it is clear, see ClutterSampler.best_blocked), as a failure of picking it with that arm.
        Those are the picks the task planner tries next to clear the way, one replan per link otherwise;
        the facts hold of the grasps the pick generator offers first in this world."""
        memo = []

        def related():
            if memo:
                return memo[0]
            arms = tuple(self.robot.arms)
            out, links, seen, frontier = [], [], {obj}, list(blockers)
            for _ in range(depth):
                nxt = []
                for b in dict.fromkeys(frontier):
                    if b in seen:
                        continue
                    seen.add(b)
                    for arm in arms:
                        with self.stats.timer("pose_generation"):
                            found = chain(b, arm)
                        if found is None:
                            continue
                        base, approach, elsewhere = found
                        with self.stats.timer("collision_checking"):
                            hits = self._approach_blockers(elsewhere or world, b, arm, base, approach, [0.0])
                        if hits:
                            links.append((b, arm, hits))
                            nxt += hits
                frontier = nxt
            # a link that closes a cycle (b's best grasp blocked by an object that waits, through the chain, for
            # b) is left out: the pick generator offers b's grasps past the objects waiting for b first
            # (PBSampler.ranked_grasps), and the task planner would see each waiting for the other, a dead end
            blocked_by = {obj: set(blockers)}
            for b, _, hits in links:
                blocked_by.setdefault(b, set()).update(hits)
            for b, arm, hits in links:
                if not any(_reaches(blocked_by, h, b) for h in hits):
                    other = [a for a in arms if a != arm]
                    out.append(({"?o": b, "?arm": arm, **({"?arm2": other[0]} if other else {})},
                                Failure("obstruction", hits, "pick approach: blocked by " + ", ".join(hits))))
            memo.append(tuple(out))
            return memo[0]

        return related

    def _approach_blockers(self, world, obj, arm, base, approach, acc) -> tuple:
        """The movable objects (obj aside) the arm's ``approach`` from ``base`` touches, sorted."""
        w = replace(world, base=tuple(float(v) for v in base))
        w = w.with_gripper(arm, self.grasp_opening(w, arm, obj, approach[-1]))
        return tuple(sorted(self._movables_on_line(w, arm, approach, acc) - {obj}))


def _reaches(blocked_by, start, goal) -> bool:
    """``goal`` is ``start`` or blocks it, directly or through objects that block each other (``blocked_by``)."""
    todo, seen = [start], set()
    while todo:
        o = todo.pop()
        if o == goal:
            return True
        if o not in seen:
            seen.add(o)
            todo += blocked_by.get(o, ())
    return False
