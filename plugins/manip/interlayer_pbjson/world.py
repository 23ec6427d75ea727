"""The refinement runtime of pybullet-planning problems: the PR2 geometry with named surfaces, the
robot's start configuration from the file, ``go_home``, and the goal checks the validator runs.

* The arms start where ``robots[0].conf`` puts them; an empty arm that is not tucked is tucked before
  the base drives (an outstretched arm would sweep the tables).
* ``place_at_goal`` refines like ``place`` (the put-down pose is the goal pose).
* ``go_home``: tuck, drive back to the start base pose, then move each empty arm to its start joints;
  ``go_to``: tuck and drive to the file's base pose goal.
* The validator (interlayer_manip.validate, with this domain's rules) asks ``resting_on`` where a released
  object rests and ``goal_violations`` whether the goals hold, replaying the releases for clean / cook.
"""
from __future__ import annotations

import math
from dataclasses import replace

import numpy as np
from interlayer.errors import UserError
from interlayer.refine import Failure, StepOutcome
from interlayer_manip.scene import REST_GAP
from interlayer_manip.validate import upright
from interlayer_manip.state import PADDING, RES_BASE, _failure, _holding, pose4, trans, wrap
from interlayer_manip.world import ManipulationGeometry

from .domain import HELD_GRASP, STUCK, UNGRASPABLE
from .scene import ON_TOL, inside, tops

HOME_TOL = 1e-3  # m / rad: the robot is back at its start configuration
GOAL_POS_TOL, GOAL_YAW_TOL = 0.01, math.radians(5)  # an object is at its goal pose
PUSH_GAP = 0.01  # m: a pushed object is held this far ahead of the first contact with the base (touching collides)
PUSH_CONTACT = 0.02  # m: the validator's test that the base pushes it: moved this much closer, it touches the robot
MAX_CHAIN = 4  # objects one push may move (the pushed one and what it meets head on, in a row)


class PBGeometry(ManipulationGeometry):
    def __init__(self, layout, padding: float = PADDING):
        super().__init__(layout, padding=padding)
        self.surfaces = layout.extra["surfaces"]
        self.goals = layout.extra["goals"]
        self.start_arms = self._start_arms(layout.extra.get("arms", {}))
        self.floor_objects = set(layout.extra.get("floor_objects", ()))
        self.blocked_drives = []  # (from, to) xy of drives floor obstacles blocked: the push sampler clears them
        self._areas = {}  # where the base can drive among the floor obstacles (see base_query)

    def _start_arms(self, conf) -> dict:
        out = {}
        for arm in self.robot.arms:
            g = self.robot.group(f"{arm}_arm")
            given = conf.get(arm, {})
            if not any(j in given for j in g.dof_names):
                out[arm] = tuple(self.robot.home(arm))  # no arm joints in the file: tucked
                continue
            values = []
            for j, lo, hi, circ, tucked in zip(g.dof_names, g.lower, g.upper, g.circular, self.robot.home(arm)):
                v = given.get(j, tucked)
                v = wrap(v) if circ or (lo <= -math.pi + 1e-6 and hi >= math.pi - 1e-6) else v
                if not lo - 1e-6 <= v <= hi + 1e-6:
                    raise UserError(f"robots[0].conf.{j} = {given.get(j)!r} is outside the joint's limits [{lo:.3f}, {hi:.3f}].")
                values.append(float(min(max(v, lo), hi)))
            out[arm] = tuple(values)
        return out

    def initial_world(self):
        w = super().initial_world()
        return replace(w, arms=dict(self.start_arms))

    # -- surfaces and goals ------------------------------------------------------------------------
    def surface(self, name, world):
        """(polygon, height) of surface ``name`` in ``world``; None for the top of an object not resting."""
        s = self.surfaces[name]
        if s.kind != "top":
            return s.polygon, s.z
        P = world.objects.get(s.body)
        if P is None:
            return None
        poly = [tuple((P @ np.array([x, y, 0.0, 1.0]))[:2]) for x, y in s.polygon]
        return poly, float(P[2, 3] + s.z)

    def supports_of(self, obj, P, world, tol=ON_TOL) -> list:
        """Surfaces object ``obj`` at pose P rests on: its bottom at their height, its centre inside."""
        bottom = P[2, 3] - self.specs[obj].height / 2
        out = []
        for name, s in self.surfaces.items():
            if s.body == obj:
                continue
            found = self.surface(name, world)
            if found and abs(bottom - found[1]) <= tol and inside(found[0], P[0, 3], P[1, 3]):
                out.append(name)
        return out

    def goal_centre(self, obj) -> np.ndarray:
        """The pose of obj's shape at its goal pose (goal poses are body poses)."""
        goal = self.goals["poses"][obj]
        if isinstance(goal, str):  # "initial"
            return pose4(*self.specs[obj].pose)
        T = np.asarray(goal, float)
        ox, oy, oz, dyaw = self.layout.extra["offsets"][obj]
        c = T @ np.array([ox, oy, oz, 1.0])
        return pose4(c[0], c[1], c[2], math.atan2(T[1, 0], T[0, 0]) + dyaw)

    def goal_occupants(self, obj, world) -> set:
        """The other objects that obj, put at its goal pose, would touch (raised by its rest gap, so that
        an object it is to stand on does not count)."""
        C = self.layout.extra["goal_centres"][obj].copy()
        C[2, 3] += REST_GAP
        self.sync(world)
        with self.stats.timer("collision_checking"):
            return self.cw.objects_overlap(obj, C) & set(world.objects)

    def symmetry(self, obj) -> float:
        """The yaw period of obj's shape (0: any yaw)."""
        o = self.specs[obj]
        if o.shape == "cylinder":
            return 0.0
        return math.pi / 2 if abs(o.size[0] - o.size[1]) < 1e-3 else math.pi

    def at_goal_pose(self, obj, P) -> bool:
        C = self.layout.extra.get("goal_centres", {}).get(obj)
        C = self.goal_centre(obj) if C is None else C
        if np.linalg.norm(P[:3, 3] - C[:3, 3]) > GOAL_POS_TOL or P[2, 2] < math.cos(GOAL_YAW_TOL):
            return False
        period = self.symmetry(obj)
        if period == 0.0:
            return True
        d = math.atan2(P[1, 0], P[0, 0]) - math.atan2(C[1, 0], C[0, 0])
        return abs((d + period / 2) % period - period / 2) <= GOAL_YAW_TOL

    def resting_on(self, obj, P, world):
        """Why a release of obj at P is not a stable placement (None: it rests on a surface or object)."""
        if not upright(P):
            return "not upright"
        if self.supports_of(obj, P, world, tol=REST_GAP + 0.005):
            return None
        if self.layout.extra.get("goal_centres", {}).get(obj) is not None and self.at_goal_pose(obj, P):
            return None  # the file's own goal pose, whatever is under it
        return "not resting on a table, region, sink, stove or object"

    def goal_violations(self, world, trajectory) -> list[str]:
        g, out = self.goals, []
        if g["holding"] and all(world.holder(o) is None for o in g["holding"]):
            out.append(f"goal not satisfied: {' or '.join(g['holding'])} is not held at the end")
        wanted = [(o, s, g["members"][o]) for o, s in g["on"].items()]
        wanted += [(o, tops(self.surfaces)[b], (o,)) for o, b in g["stackings"].items()]
        for o, s, members in wanted:
            if not any(m in world.objects and s in self.supports_of(m, world.objects[m], world) for m in members):
                out.append(f"goal not satisfied: {' or '.join(members)} does not rest on {s} at the end")
        for o in g["poses"]:
            if o not in world.objects or not self.at_goal_pose(o, world.objects[o]):
                out.append(f"goal not satisfied: {o} is not at its goal pose at the end")
        cleaned, cooked = set(), set()
        w = self.initial_world()
        for step in trajectory.get("steps", []):
            for seg in step.get("segments", []):
                if seg.get("kind") == "release":
                    o, P = seg["object"], np.asarray(seg["pose"], float)
                    kinds = {self.surfaces[s].kind for s in self.supports_of(o, P, w)}
                    if "sink" in kinds:
                        cleaned.add(o)
                    if "stove" in kinds and o in cleaned:
                        cooked.add(o)
        out += [f"goal not satisfied: {o} was never put on a sink (cleaned)" for o in g["cleaned"] if o not in cleaned]
        out += [f"goal not satisfied: {o} was never put on a stove once clean (cooked)" for o in g["cooked"] if o not in cooked]
        if g["home"]:
            if self.base_space.distance(np.asarray(world.base, float), np.asarray(self.layout.base, float)) > HOME_TOL:
                out.append("goal not satisfied: the base is not back at its start pose")
            for arm in self.robot.arms:
                if arm not in world.held and np.max(np.abs(np.subtract(world.arms[arm], self.start_arms[arm]))) > HOME_TOL:
                    out.append(f"goal not satisfied: the {arm} arm is not back at its start configuration")
        if g["base"] and self.base_space.distance(np.asarray(world.base, float), np.asarray(g["base"], float)) > HOME_TOL:
            out.append(f"goal not satisfied: the base is not at the goal pose {list(g['base'])}")
        return out

    # -- refinement --------------------------------------------------------------------------------
    def carry(self, world, arm, rng, seeds: int = 4):
        """The PR2's carry posture, its IK retried with other seeds: a tall box held beside the shoulder
        leaves few solutions, and one seed's restarts miss them (the seeds are fixed: reproducible)."""
        for k in range(seeds):
            sol = super().carry(world, arm, rng if k == 0 else np.random.default_rng(k))
            if sol is not None:
                return sol
        return None

    def refine_step(self, step, world, candidate, motion) -> StepOutcome:
        out = self._goal_blockers(world, self._refine_step(step, world, candidate, motion))
        put_by = candidate.values.get("put_by")
        if step.action != "pick" or put_by is None or out.ok or out.failure is None or out.failure.kind != "obstruction":
            return out
        return replace(out, failure=replace(out.failure, related=self._put_in_the_way(step.args[0], world, out.failure, put_by)))

    @staticmethod
    def _put_in_the_way(obj, world, f, put_by):
        """``f.related`` and, for each blocker that a put-down of this epoch set where it stands, that place step
        failing on obj: the task planner learns (PDObstructs obj pd), so that the put-down waits until obj has
        been picked, instead of setting the blocker down in its way again (rearrangement_18: the same put-down
        in front of the same pick, until the epoch was reset)."""
        def related():
            placed = [(b, put_by(b, world.objects[b])) for b in f.objects if b in world.objects]
            return (*f.related_failures(), *((s, Failure("obstruction", (obj,), f"put-down: sets {b} in the way of picking {obj}"))
                                            for b, s in placed if s is not None))
        return related

    def _goal_blockers(self, world, out) -> StepOutcome:
        """An obstruction naming objects that stand at their goal poses also names them as ``?blocker_at_goal``
        (``?blocker2_at_goal`` among the other arm's blockers): the task planner learns (GoalObstructs b gp),
        which outlives picking b, so that it does not put b back at its goal before the pick it blocked
        (rearrangement: without it, b went back to its goal and blocked that pick again, replan after replan)."""
        f = out.failure
        goals = self.layout.extra.get("goal_centres")
        if out.ok or f is None or f.kind != "obstruction" or not goals:
            return out

        def at_goal(objs):
            return tuple(o for o in objs if o in goals and o in world.objects and self.at_goal_pose(o, world.objects[o]))

        def also():
            found = dict(f.also_objects())
            more = {"?blocker_at_goal": at_goal(f.objects), "?blocker2_at_goal": at_goal(found.get("?blocker2", ()))}
            return {**found, **{k: v for k, v in more.items() if v}}

        def related():  # the chain of blockers' picks (Reach.blocker_chain): their blockers at goal alike
            return tuple((objs, replace(g, also={"?blocker_at_goal": at_goal(g.objects)}) if at_goal(g.objects) else g)
                         for objs, g in f.related_failures())

        return replace(out, failure=replace(f, also=also, related=related if f.related else ()))

    def _refine_step(self, step, world, candidate, motion) -> StepOutcome:
        if HELD_GRASP in candidate.values:  # the put-down generator's verdict: only another grasp fits the goal pose
            return StepOutcome(False, failure=Failure(HELD_GRASP, (), candidate.values[HELD_GRASP]))
        if STUCK in candidate.values:  # the put-down generator's: every put-down it found meets those objects
            # static: no earlier step can move them; backtracking would only re-pick the held object (its
            # other grasps are sampled again in the next epoch)
            objs, why = candidate.values[STUCK]
            return StepOutcome(False, failure=Failure("obstruction", objs, why, static=True))
        if UNGRASPABLE in candidate.values:  # the pick generator's proof: no grasp clears the fixed obstacles
            return StepOutcome(False, failure=Failure(UNGRASPABLE, (), candidate.values[UNGRASPABLE], static=True,
                                                      lasting=True))
        acc = [0.0]
        try:
            drives = step.action in ("go_home", "go_to", "push") or (
                len(candidate.waypoints) == 3 and
                self.base_space.distance(np.asarray(world.base, float), np.asarray(candidate.waypoints[0], float)) > 1e-9)
            segs = []
            if drives and step.action == "pick":
                # the approach check first, with the arms as the tuck leaves them: it is cheap, and a
                # blocked approach fails the step whatever the tuck's motion
                failed = self.approach_blocked(step, self.tucked(world), candidate, acc)
                if failed is not None:
                    return failed
            if drives:
                world, failed = self._tuck(world, motion, segs, acc)
                if failed is not None:
                    return failed
            if step.action == "go_home":
                out = self._go_home(world, motion, acc)
            elif step.action == "push":
                out = self._push(step, world, candidate, motion, acc)
            elif step.action == "go_to":
                w, failed = self.drive(world, candidate.waypoints[0], "go_to drive", out_segs := [], motion, acc)
                out = failed or StepOutcome(True, replace(w, tloc={}), out_segs)
            else:
                if step.action == "place_at_goal":
                    step = replace(step, action="place")
                out = super().refine_step(step, world, candidate, motion)
                if drives and not out.ok and out.failure.kind == "obstruction" and \
                        not out.failure.detail.startswith(f"{step.action} drive"):
                    # past the drive the arms start in their driving postures (tucked, or the carry posture
                    # beside the shoulder), wherever the robot stood before the step (TryRefine's backjumping)
                    out = replace(out, failure=replace(out.failure, start_free=True))
            if out.ok:
                out.segments = segs + out.segments
            return out
        finally:
            self.stats.add_time("collision_checking", acc[0])

    def drive(self, world, base, label, segs, motion, acc, exclude=None):
        """The base driven to ``base``; a drive that floor obstacles block fails as a ``base_obstruction``
        naming them (the task planner learns ``BaseObstructs``, not ``FinalClear``, or ``PushBlocked``)."""
        w, failed = super().drive(world, base, label, segs, motion, acc, exclude)
        if failed is None or failed.failure.kind != "obstruction":
            return w, failed
        hit = tuple(o for o in failed.failure.objects if o in self.floor_objects)
        if not hit:
            return w, failed
        hit = self.one_blocker(world, base, hit)
        self.blocked_drives = [*self.blocked_drives[-15:], (tuple(world.base[:2]), tuple(base[:2]))]
        return w, StepOutcome(False, failure=Failure("base_obstruction", hit, failed.failure.detail))

    def one_blocker(self, world, goal, hit) -> tuple:
        """A randomized planner's relaxed path wanders and runs into more floor obstacles than the way
        needs: the first of ``hit`` whose removal alone lets the flood fill reach ``goal`` from the base,
        if one does (as ``_fewer_blockers`` does for arms); else ``hit``."""
        for o in hit if len(hit) > 1 else ():
            area = self._area(world, world.base, without=o)
            if area is not None and area(float(goal[0]), float(goal[1])):
                return (o,)
        return hit

    def base_query(self, world, start, goal, label, acc):
        """The base's motion query; when the floor obstacles cut ``goal`` off from ``start`` (the loader's
        flood fill of a disk inside the base's footprint: if the disk cannot get there, neither can the
        base), the search among them is skipped: no path is valid, and the motion planner goes straight to
        the path with movables ignored and names what it runs into (a searching planner otherwise spends
        its whole time limit before that)."""
        query = super().base_query(world, start, goal, label, acc)
        if self.floor_objects and self._cut_off(world, start, goal):
            self.stats.count("drives_cut_off_by_floor_obstacles")
            return replace(query, is_valid=lambda v: False)
        return query

    def _cut_off(self, world, start, goal) -> bool:
        area = self._area(world, start)
        return area is not None and not area(float(goal[0]), float(goal[1]))

    def _area(self, world, start, without=None):
        """Where the base can drive from ``start`` among the fixed shapes and the floor obstacles where
        ``world`` has them (but ``without``): the loader's ``reachable_area`` (None: no conclusion)."""
        from .loader import reachable_area
        from .samplers import _spec_at

        floor = tuple(sorted((o, tuple(np.round(P[:2, 3], 4))) for o, P in world.objects.items()
                             if o in self.floor_objects and o != without))
        key = (floor, tuple(np.round(np.asarray(start[:2], float), 2)))
        if key not in self._areas:
            if len(self._areas) > 64:
                self._areas.clear()
            shapes = [*self.layout.fixed, *(_spec_at(self.specs[o], world.objects[o]) for o, _ in floor)]
            self._areas[key] = reachable_area(shapes, start, *self.layout.extra["base_limits"])
        return self._areas[key]

    # -- pushing a floor obstacle with the base ------------------------------------------------------
    def contact_distance(self, world, obj, heading, far: float = 2.0) -> float | None:
        """How far ahead of the base's origin, along ``heading`` (the base facing it), ``obj`` first
        touches the robot as ``world`` has it (bisection to 2 mm); None if it touches at ``far``."""
        P = world.objects[obj]
        x, y = P[0, 3], P[1, 3]

        def touches(d):
            w = replace(world, base=(x - d * math.cos(heading), y - d * math.sin(heading), heading))
            with self.stats.timer("collision_checking"):
                return obj in self.cw.colliding_movables(self.sync(w))
        if touches(far):
            return None
        lo, hi = 0.0, far
        while hi - lo > 0.002:
            mid = (lo + hi) / 2
            lo, hi = (mid, hi) if touches(mid) else (lo, mid)
        return hi

    def push_line(self, world, obj, start, end, fine: float = RES_BASE / 5, movables: bool = True, chain=()):
        """The base driving straight from ``start`` to ``end`` with ``obj`` and the objects of ``chain`` (as
        ``world`` has them) moved rigidly in front of it: (world after, None) or (world, the Failure) naming
        what the robot or an object hits (a movable blocker as an obstruction; with ``movables`` False, only
        fixed obstacles are checked). Checked every ``fine`` m (the validator's resolution by default)."""
        after, why, _, _ = self._sweep(world, (obj, *chain), start, end, fine, movables)
        return after, why

    def _sweep(self, world, objs, start, end, fine, movables):
        """push_line's work: (world after, Failure or None, the last base pose checked clear, the floor
        obstacles only the pushed objects run into there (none: something else failed it))."""
        Bs = {o: np.linalg.inv(base4(start)) @ world.objects[o] for o in objs}
        base = self.robot.group("base")
        moved = set(objs) | {o for o, _ in world.held.values()}
        last = np.asarray(start, float)
        with self.stats.timer("collision_checking"):
            q0 = self.sync(replace(world, base=tuple(start)))
            try:
                for v in self.base_space.densify([np.asarray(start, float), np.asarray(end, float)], fine):
                    poses = {o: base4(v) @ B for o, B in Bs.items()}
                    for o, P in poses.items():
                        self.cw.set_pose(o, P)
                    q = base.set(q0, v)
                    if not self.base_space.within_bounds(v):
                        return world, Failure("unreachable", (), f"push: the base leaves its bounds at {np.round(v, 3).tolist()}"), last, ()
                    ahead = set().union(*(self.cw.objects_overlap(o, P) for o, P in poses.items())) - moved
                    hits = ahead | (self.cw.colliding_movables(q) - moved)
                    if hits & self.fixed or self.cw.in_collision(q, ignore=tuple(world.objects), movables=False):
                        return world, Failure("unreachable", (), f"push: {', '.join(objs)} or the robot runs into a "
                                                                 f"fixed obstacle at base {np.round(v, 3).tolist()}"), last, ()
                    if hits and movables:
                        floor = tuple(sorted(hits)) if hits <= ahead and hits <= self.floor_objects else ()
                        return world, Failure("obstruction", tuple(sorted(hits)), f"push: {', '.join(objs)} or the robot "
                                                                                  f"runs into {', '.join(sorted(hits))}"), last, floor
                    if movables and self.cw.in_collision(q):
                        return world, Failure("unreachable", (), f"push: collision at base {np.round(v, 3).tolist()}"), last, ()
                    last = v
            finally:
                for o in objs:
                    self.cw.set_pose(o, world.objects[o])
                self._synced = None
        objects = {**world.objects, **{o: base4(end) @ B for o, B in Bs.items()}}
        return replace(world, base=tuple(float(v) for v in end), objects=objects), None, last, ()

    def push_pieces(self, world, obj, start, end, fine: float = RES_BASE / 5, movables: bool = True):
        """A push of ``obj`` from base ``start`` to ``end`` in which what the pushed objects run into head-on
        (a resting floor obstacle whose centre lies within the width of the one that meets it, across the
        push) joins them and moves with them from the moment they touch, up to MAX_CHAIN objects in all:
        (world after, Failure or None, [(from, to, the objects pushed, the world at from)] one piece per chain).
        ``movables`` False: other movable objects are not checked (the push sampler's coarse test)."""
        chain, s, pieces, w = (obj,), tuple(start), [], world
        while True:
            after, why, last, floor = self._sweep(w, chain, s, end, fine, True)
            joins = bool(floor) and len(chain) + len(floor) <= MAX_CHAIN and all(self._head_on(w, chain, s, f) for f in floor)
            if why is not None and not joins and not movables and why.kind == "obstruction":
                # movables the coarse test does not ask about (the refinement learns them): on as if clear
                after, why = self.push_line(w, obj, s, end, fine, movables=False, chain=chain[1:])
            if why is None:
                return after, None, [*pieces, (s, tuple(float(v) for v in end), chain, w)]
            if not joins:
                return world, why, pieces
            touch = self._touching(w, chain, s, last, floor, fine)
            if math.dist(touch[:2], s[:2]) > 1e-9:  # (a chain that touches at the start moves as one at once)
                pieces.append((s, touch, chain, w))
                w, _ = self.push_line(w, obj, s, touch, fine, movables=False, chain=chain[1:])
            chain, s = (*chain, *floor), touch

    def _head_on(self, world, chain, base, f) -> bool:
        """Floor obstacle ``f`` stands ahead of one of ``chain`` along the push (the base at ``base``),
        its centre within that object's width across the push: the push meets it face on."""
        return any(ahead_in_line(world.objects[o], self.specs[o], world.objects[f], float(base[2])) is not None
                   for o in chain)

    def _touching(self, world, chain, start, last, floor, step, tol: float = 0.001) -> tuple:
        """The base pose between ``last`` (the chain clear of ``floor``) and the next step along the push
        (``step`` further) where the chain stands less than ``tol`` from touching them: bisection."""
        start = np.asarray(start, float)
        u = np.array([math.cos(start[2]), math.sin(start[2])])
        Bs = {o: np.linalg.inv(base4(start)) @ world.objects[o] for o in chain}
        lo = float((np.asarray(last[:2]) - start[:2]) @ u)
        hi = lo + step

        def at(d):
            return (float(start[0] + d * u[0]), float(start[1] + d * u[1]), float(start[2]))

        def hit(d):
            with self.stats.timer("collision_checking"):
                return any(self.cw.objects_overlap(o, base4(at(d)) @ B) & set(floor) for o, B in Bs.items())
        self.sync(world)
        while hi - lo > tol:
            mid = (lo + hi) / 2
            lo, hi = (lo, mid) if hit(mid) else (mid, hi)
        return at(lo)

    def _push(self, step, world, cand, motion, acc):
        """push(f): drive to the candidate's first base pose (facing f, just short of touching it), then
        straight to its second one, f moving rigidly ahead of the base (and what it meets head on with it,
        one segment per chain)."""
        obj = step.args[0]
        start, end = (tuple(float(v) for v in p) for p in cand.waypoints)
        segs = []
        w, failed = self.drive(world, start, "push drive", segs, motion, acc, exclude=obj)
        if failed:
            return failed
        after, why, pieces = self.push_pieces(w, obj, start, end)
        if why:
            return StepOutcome(False, failure=why)
        for s, e, chain, w in pieces:
            seg = self._segment("push", "base", [s, e], _holding(w))
            seg.update(object=obj, base_T_object=(np.linalg.inv(base4(s)) @ w.objects[obj]).tolist())
            if len(chain) > 1:
                seg["chain"] = [{"object": o, "base_T_object": (np.linalg.inv(base4(s)) @ w.objects[o]).tolist()}
                                for o in chain[1:]]
            segs.append(seg)
        return StepOutcome(True, replace(after, tloc={}), segs)

    def tucked(self, world):
        """``world`` with every empty arm tucked (where :meth:`_tuck` moves them)."""
        return replace(world, arms={a: v if a in world.held else tuple(self.robot.home(a)) for a, v in world.arms.items()})

    def _tuck(self, world, motion, segs, acc):
        """Tuck every empty arm that is not (the start configuration may hold them out)."""
        w = world
        for arm in self.robot.arms:
            if arm in w.held or np.allclose(w.arms[arm], self.robot.home(arm), atol=1e-9):
                continue
            res = self._plan(motion, self.arm_query(w, arm, w.arms[arm], self.robot.home(arm), "tuck", acc), "transit",
                             f"{arm}_arm", segs, _holding(w), w, acc)
            if not res.ok:
                return world, _failure(res, f"{arm} arm tuck")
            w = w.with_arm(arm, self.robot.home(arm))
        return w, None

    def _go_home(self, world, motion, acc):
        segs = []
        w, failed = self.drive(world, self.layout.base, "go_home drive", segs, motion, acc)
        if failed:
            return failed
        for arm in self.robot.arms:
            if arm in w.held or np.allclose(w.arms[arm], self.start_arms[arm], atol=1e-9):
                continue
            res = self._plan(motion, self.arm_query(w, arm, w.arms[arm], self.start_arms[arm], "go_home arm", acc),
                             "transit", f"{arm}_arm", segs, _holding(w), w, acc)
            if not res.ok:
                return _failure(res, f"go_home {arm} arm")
            w = w.with_arm(arm, self.start_arms[arm])
        return StepOutcome(True, replace(w, tloc={}), segs)

    def validate(self, plan, trajectory) -> list[str]:
        """The PR2 validator with this domain's resting places and goals (its ``rules``)."""
        from types import SimpleNamespace

        from interlayer_manip.validate import validate_trajectory

        rules = SimpleNamespace(rests=lambda g, world, obj, P: g.resting_on(obj, P, world),
                                goal=lambda g, world: g.goal_violations(world, trajectory),
                                kinds=("push",), event=check_push)
        return validate_trajectory(type(self)(self.layout, padding=0.0), plan, trajectory, rules=rules)

    # -- output --------------------------------------------------------------------------------------
    def trajectory_json(self, plan, outcomes) -> dict:
        out = super().trajectory_json(plan, outcomes)
        out["domain"] = "pr2-pbjson"
        return out

    def describe(self) -> str:
        from .summary import describe

        return describe(self)

    def draw_scene(self, scene, world=None):
        from .draw import draw_scene

        return draw_scene(self, scene, world)

    def animation_frames(self, scene, trajectory):
        from interlayer_manip import draw

        return draw.animation_frames(self, scene, as_carried(trajectory))


def ahead_in_line(P, spec, Q, heading) -> float | None:
    """How far ahead of object ``spec`` at pose P the centre of pose Q stands along ``heading``, when it
    stands ahead and within the object's width across that direction (a push along ``heading`` meets it
    face on); else None."""
    u = np.array([math.cos(heading), math.sin(heading)])
    across = np.array([-u[1], u[0]])
    if spec.shape == "cylinder":
        half = spec.size[0]
    else:
        half = (abs(float(P[:2, 0] @ across)) * spec.size[0] + abs(float(P[:2, 1] @ across)) * spec.size[1]) / 2
    d = Q[:2, 3] - P[:2, 3]
    ahead = float(d @ u)
    return ahead if ahead > 0 and abs(float(d @ across)) <= half else None


def base4(b) -> np.ndarray:
    """The 4x4 pose of the base frame at (x, y, yaw), on the floor."""
    return pose4(float(b[0]), float(b[1]), 0.0, float(b[2]))


def as_carried(trajectory) -> dict:
    """``trajectory`` with each push drawn as the viewer draws a carried tray: the objects taken along with
    the base ("carry"), the base's drive, the object left where it ends ("set_down")."""
    steps = []
    for step in trajectory.get("steps") or []:
        segs = []
        for seg in step.get("segments") or []:
            if seg.get("kind") != "push":
                segs.append(seg)
                continue
            moved = [(seg["object"], seg["base_T_object"]), *((c["object"], c["base_T_object"]) for c in seg.get("chain") or [])]
            end = base4(seg["points"][-1]["positions"])
            segs += [{"kind": "carry", "objects": [o for o, _ in moved]}, {**seg, "kind": "base"},
                     {"kind": "set_down", "objects": {o: (end @ np.asarray(B, float)).tolist() for o, B in moved}}]
        steps.append({**step, "segments": segs})
    return {**trajectory, "steps": steps}


def check_push(geometry, world, seg, at):
    """The validator's check of a push segment: a straight forward drive of the base (its heading fixed),
    the object touching the base's front at the start and moving rigidly with it, each object of the
    segment's ``chain`` touching one before it and moving so too, nothing colliding at the validator's
    resolution, velocities and accelerations within the base's limits."""
    from interlayer_manip.validate import _check_timing, _pose_close

    obj = seg.get("object")
    if seg.get("kind") != "push" or seg.get("group") != "base" or obj not in world.objects:
        return world, f"{at}: a push must drive the base against a resting object, not {seg.get('group')!r} / {obj!r}"
    if list(seg.get("joint_names", [])) != ["x", "y", "theta"]:
        return world, f"{at}: joint names {seg.get('joint_names')} are not the base's"
    points = seg.get("points") or []
    path = [np.asarray(p["positions"], float) for p in points]
    if not path or any(len(p) != 3 for p in path):
        return world, f"{at}: empty, or a point has the wrong number of positions"
    if geometry.base_space.distance(path[0], np.asarray(world.base, float)) > 1e-6:
        return world, f"{at}: starts at {np.round(path[0], 3).tolist()} but the base is at {np.round(world.base, 3).tolist()}"
    B = np.asarray(seg.get("base_T_object"), float)
    if not _pose_close(base4(path[0]) @ B, world.objects[obj]):
        return world, f"{at}: {obj} is not where the push starts it (teleported)"
    chain = [(c.get("object"), np.asarray(c.get("base_T_object"), float)) for c in seg.get("chain") or []]
    for o, C in chain:
        if o not in world.objects or o == obj or o in {h for h, _ in world.held.values()} or C.shape != (4, 4):
            return world, f"{at}: the chain names {o!r}, not another resting object"
        if not _pose_close(base4(path[0]) @ C, world.objects[o]):
            return world, f"{at}: {o} is not where the push starts it (teleported)"
    d = path[-1][:2] - path[0][:2]
    h = path[0][2]
    if any(abs(wrap(p[2] - h)) > 1e-6 for p in path) or abs(-math.sin(h) * d[0] + math.cos(h) * d[1]) > 1e-6 or \
            math.cos(h) * d[0] + math.sin(h) * d[1] < 0 or \
            any(abs(-math.sin(h) * (p[0] - path[0][0]) + math.cos(h) * (p[1] - path[0][1])) > 1e-6 for p in path):
        return world, f"{at}: a push drives the base straight forward, heading fixed"
    q0 = geometry.sync(world)
    geometry.cw.set_pose(obj, base4(path[0]) @ trans(-PUSH_CONTACT, 0.0, 0.0) @ B)
    touching = obj in geometry.cw.colliding_movables(q0)
    geometry.cw.set_pose(obj, world.objects[obj])
    geometry._synced = None
    if not touching:
        return world, f"{at}: {obj} is more than {PUSH_CONTACT * 100:.0f} cm ahead of the robot: the base does not push it"
    before = [obj]
    for o, C in chain:  # each touches one before it: moved towards the base, it overlaps one
        with geometry.stats.timer("collision_checking"):
            touching = geometry.cw.objects_overlap(o, base4(path[0]) @ trans(-PUSH_CONTACT, 0.0, 0.0) @ C) & set(before)
        if not touching:
            return world, f"{at}: {o} is more than {PUSH_CONTACT * 100:.0f} cm ahead of {', '.join(before)}: nothing pushes it"
        before.append(o)
    after, why = geometry.push_line(world, obj, path[0], path[-1], chain=tuple(o for o, _ in chain))
    if why:
        return world, f"{at}: {why.detail}"
    why = _check_timing(geometry, geometry.base_space, "base", ["x", "y", "theta"], points, path, at)
    return (world, why) if why else (after, None)
