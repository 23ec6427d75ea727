"""Pose generators of pybullet-planning problems (move_base folded in, as in Clutter).

* ``pbjson:pick``: Clutter's pick (stable grasp candidates per object pose, fewest objects in the way
  first).
* ``pbjson:place``: for ``place`` on the one table of a single-table scene, Clutter's put-down sampler;
  otherwise a stable placement on the step's surface: a point inside its polygon
  (the object's whole footprint inside, for tables and regions; its centre over the top of an object
  it is stacked on), clear of fixed obstacles and the goal poses of others, and out of the best
  approaches found so far (Clutter's corridors); spots clear of other objects first, then spots on them
  (a region another object fills: the put-down names it, and the task planner moves it first); for
  ``place_at_goal`` the goal pose itself (and its symmetric yaws). Then a base pose, IK, the lowering
  and the retreat; candidates with fewer objects in the way first.
* ``pbjson:go_home``: the start configuration; ``pbjson:go_to``: the file's base pose goal.
"""
from __future__ import annotations

import itertools
import math
from contextlib import nullcontext
from dataclasses import replace

import numpy as np
from interlayer.refine import Candidate, GiveUp
from interlayer_clutter.samplers import ClutterSampler, _pose_key, fmt, in_corridors, putdown_motion
from interlayer_manip.grasps import once
from interlayer_manip.scene import REST_GAP
from interlayer_manip.state import PRE_GRASP, RES_BASE, pose4, trans, wrap

from .domain import HELD_GRASP, STUCK, UNGRASPABLE
from .scene import apart, distance_to, draw_in, inside, polygon_of

GOAL_GAP, OBJECT_GAP = 0.02, 0.01  # m: a put-down keeps this far from another object's goal pose, from an object


class PBSampler(ClutterSampler):
    """Clutter's sampler (its pick and its per-epoch state) with placements on named surfaces."""

    def __init__(self, seed):
        super().__init__(seed)
        self.wanted: dict = {}  # object -> grasps (tool_T_object) that fit at its goal pose, after a regrasp was learned
        self.fitting: dict = {}  # object -> grasps that fit at its goal pose (goal_grasps)
        # (obj, arm) -> (obj's pose key, {other object: (its pose key, whether it was in the way of obj's best grasp)}),
        # from the last ranking of obj's grasps in which the other object stood there
        self.best_hits: dict = {}
        self.put: dict = {}  # object -> [(a pose, the place step whose put-down candidate sets it there)], latest last

    @staticmethod
    def _goal_only(geometry, obj, surf) -> bool:
        """The goal needs obj itself (no other object of a class) on surface surf, a table or region."""
        goals = geometry.goals
        return geometry.surfaces[surf].kind != "top" and any(
            s == surf and goals["members"][o] == (obj,) for o, s in goals["on"].items())

    def __call__(self, problem, step, world, rng):
        if step.action == "pick":
            return self.pick(problem, step, world, rng)
        if step.action == "place_at_goal":
            return self.place_at_goal(problem, step, world, rng)
        return self._noted(step, self.place_on(problem, step, world, rng))

    def _noted(self, step, cands):
        for cand in cands:
            if "object_pose" in cand.values:
                self.put.setdefault(step.args[0], []).append((np.asarray(cand.values["object_pose"]), step))
            yield cand

    def put_by(self, obj, P):
        """The place step (this epoch's) whose put-down sets obj at pose P, or None. Within IK's tolerance: the
        arm that reached the candidate's pose leaves the object up to a millimetre and a degree off it."""
        from interlayer_manip.world import same_place

        return next((step for Q, step in reversed(self.put.get(obj, ())) if same_place(Q, P)), None)

    def pick(self, problem, step, world, rng, limit: int = 5):
        """Clutter's pick; when it finds nothing and no grasp of the object can ever clear the fixed obstacles
        where it stands (``no_grasp_fits``), a candidate that fails as UNGRASPABLE with that proof; for a box of a
        set that block each other's every grasp (``stuck_together``), only that candidate, with that proof."""
        from interlayer_manip.grasps import no_grasp_fits, stuck_sentence

        obj, arm = step.args[0], step.args[1]
        if world.holder(obj) is None and not world.held.get(arm) and obj in self._stuck_together(problem):
            # a set of boxes that block each other's every grasp since the start: none of them ever moves
            members, _, walls = self._at_start(problem)
            yield Candidate((), {UNGRASPABLE: stuck_sentence(problem, members, walls)}, "no grasp")
            return
        found = False
        chain = self.chain(problem, world)
        for cand in super().pick(problem, step, world, rng, limit):
            found = True
            # a blocked pick learns its blockers' own blockers too (Reach.blocker_chain)
            yield replace(cand, values={**cand.values, "chain": chain, "put_by": self.put_by})
        if not found and world.holder(obj) is None and not world.held.get(arm) and self._stuck(problem, world, obj):
            yield Candidate((), {UNGRASPABLE: no_grasp_fits(problem, world, obj)}, "no grasp")

    @classmethod
    def _stuck(cls, problem, world, obj) -> bool:
        """No grasp of ``obj`` can ever clear the fixed obstacles where it stands, or obj is one of a set of boxes
        that block each other's every grasp since the start (a floor obstacle may be pushed)."""
        from interlayer_manip.grasps import hand_blockers

        return obj not in problem.geometry.floor_objects and (
            bool(hand_blockers(problem, world, obj)) or obj in cls._stuck_together(problem))

    @classmethod
    def _stuck_together(cls, problem) -> set:
        """The members of ``stuck_together`` at the start that other members block (those that fixed obstacles
        alone block are ``hand_blockers``' to prove, as before)."""
        members, walled, _ = cls._at_start(problem)
        return set(members) - set(walled)

    @staticmethod
    def _at_start(problem) -> tuple:
        """``stuck_together`` at the start: its members never move, so it holds in every world of the run (the
        facts learned from it outlive resets). Once per run."""
        from interlayer_manip.grasps import stuck_together

        geometry = problem.geometry
        return once(geometry, "stuck_at_start",
                    lambda: stuck_together(problem, geometry.initial_world(), geometry.floor_objects))

    def place_on(self, problem, step, world, rng, tries: int = 60):
        from interlayer_manip.generators import _putdown

        obj, arm, surf = step.args[0], step.args[1], step.args[2]
        geometry = problem.geometry
        if world.holder(obj) != arm:
            return
        if surf == geometry.layout.extra.get("clutter_table"):
            # the paper's kind of scene (one axis-aligned table): Clutter's own put-down sampler, which keeps
            # the target's approach corridors clear
            yield from self.place(problem, replace(step, args=(obj, arm, step.args[3], *step.args[4:])), world, rng)
            return
        found = geometry.surface(surf, world)
        if found is None:
            return
        poly, top = found
        if self._goal_only(geometry, obj, surf):
            # fixed obstacles alone decide it: asked once per run
            why = once(geometry, ("no_putdown", obj, surf), lambda: no_putdown(problem, world, obj, surf))
            if why:  # the goal needs a put-down this planner cannot make: epoch after epoch would search in vain
                raise GiveUp(why)
        G = world.held[arm][1]
        o = geometry.specs[obj]
        z = top + o.height / 2 + REST_GAP
        stacked = geometry.surfaces[surf].kind == "top"
        geometry.sync(world)
        # footprints, not circles around them: rearrangement's goal poses (blocks 12 x 4 cm in rows) cover
        # the whole table with circles, and no spot was left to set a block down on the way
        reserved = [polygon_of(_spec_at(geometry.specs[k], C)) for k, C in geometry.layout.extra["goal_centres"].items()
                    if k != obj]
        below = geometry.surfaces[surf].body  # the object stacked on (kind "top"): not in the way
        others = [polygon_of(_spec_at(geometry.specs[k], Q)) for k, Q in world.objects.items() if k not in (obj, below)]
        corridors = self.corridors_for(world, obj, geometry.layout.target)  # the best approaches found so far
        r = o.size[0] if o.shape == "cylinder" else min(o.size[0], o.size[1]) / 2  # within the footprint at any yaw
        spots, taken = [], []
        for x, y in draw_in(poly, rng, 25 * tries):
            if not inside(poly, x, y, 0.005 if stacked else min(o.size[0], o.size[1]) / 2):
                continue
            if any(distance_to(g, x, y) < r + GOAL_GAP for g in reserved):
                continue  # another object's goal pose, whatever the yaw
            d = min((distance_to(q, x, y) - r for q in others), default=1.0)
            if d < OBJECT_GAP:  # on or against another object: offered after the clear spots, so that a surface that
                # objects fill still has put-downs, whose refinement names them (PDObstructs: moved first)
                if len(taken) < tries:
                    taken.append((d, float(x), float(y)))
                continue
            spots.append((min(d, 0.25) - in_corridors(x, y, corridors) + 0.1 * rng.random(), float(x), float(y)))
            if len(spots) >= tries:
                break
        spots = [(x, y, True) for _, x, y in sorted(spots, key=lambda s: -s[0])]
        spots += [(x, y, False) for _, x, y in sorted(taken, key=lambda s: -s[0])]

        def pose_at(x, y, heading, clear):
            P, _ = _putdown(G, x, y, z, heading)
            footprint = polygon_of(_spec_at(o, P))
            if not stacked and not all(inside(poly, px, py) for px, py in footprint):
                return None
            if not all(apart(footprint, g, GOAL_GAP) for g in reserved) or \
                    (clear and not all(apart(footprint, q, OBJECT_GAP) for q in others)):
                return None  # at this yaw, on another's goal pose or against an object
            return P

        found = False
        for cand in self._putdowns(problem, world, obj, arm, step.args[4], step.args[5],
                                   [(x, y, lambda h, x=x, y=y, c=c: pose_at(x, y, h, c), None) for x, y, c in spots], z, rng,
                                   free=sum(c for _, _, c in spots)):
            found = True
            yield cand
        if found or not self._goal_only(geometry, obj, surf) or o.shape != "box":
            return
        # none: the grid's poses where the held grasp can be let go (putdown_grid), rare ones where the hand fits
        # only at some yaws (between posts), which the random spots, their yaw set by the base's bearing, miss
        def spread():  # fixed obstacles alone decide it: once per run
            fits = [P for P, _, _ in itertools.islice(putdown_grid(problem, world, obj, surf, [G], [arm]), 8 * GRID_SPOTS)]
            return fits[::max(1, len(fits) // GRID_SPOTS)][:GRID_SPOTS]

        grid = once(geometry, ("putdown_grid", obj, surf, arm, tuple(np.round(G[:3, :4].ravel(), 4))), spread)
        yield from self._putdowns(problem, world, obj, arm, step.args[4], step.args[5],
                                  [(float(P[0, 3]), float(P[1, 3]), lambda h, P=P: P, None, True) for P in grid], z, rng)

    def place_at_goal(self, problem, step, world, rng):
        from interlayer_manip.generators import _yaw

        obj, arm = step.args[0], step.args[1]
        geometry = problem.geometry
        if world.holder(obj) != arm:
            return
        geometry.sync(world)
        variants = goal_variants(geometry, obj)
        x, y, z = (float(v) for v in variants[0][:3, 3])
        G = world.held[arm][1]  # the tool's heading at each variant is fixed: the base stands behind it
        found = False
        for cand in self._putdowns(problem, world, obj, arm, step.args[2], step.args[3],
                                   [(x, y, lambda h, P=P: P, _yaw(P @ np.linalg.inv(G))) for P in variants], z, rng,
                                   per_spot=8):
            found = True
            yield cand
        if not found:
            fits = self.regrasps(problem, world, obj, arm, variants)
            if fits:  # refined as a failure of its own kind: the task planner learns (BadGrasp obj goal)
                self.wanted[obj] = fits
                kinds = sorted({_kind(np.linalg.inv(F)) for F in fits})
                yield Candidate((), {HELD_GRASP: f"holding {obj} as it does, the hand hits a fixed obstacle at {obj}'s goal "
                                                 f"pose or the arm reaches it there from no base pose; another "
                                                 f"{' or '.join(kinds)} grasp fits there"}, "regrasp")

    def regrasps(self, problem, world, obj, arm, variants) -> list:
        """Grasps (tool_T_object) of ``obj`` other than the held one that fit at one of the goal pose's
        ``variants`` (``_fits``); empty unless the held grasp fits at no variant (then only a regrasp can put
        ``obj`` there, and nothing changes for a put-down that fails otherwise)."""
        G = world.held[arm][1]
        w = replace(world, held={a: h for a, h in world.held.items() if a != arm})
        if any(_fits(problem, w, obj, arm, P @ np.linalg.inv(G), G) for P in variants):
            return []  # the held grasp fits: the put-down failed for another reason
        return _fitting(problem, w, obj, arm, variants, [G])

    def goal_grasps(self, problem, obj) -> list:
        """The grasps (tool_T_object) of ``obj`` that fit at its goal pose for either arm (``_fitting``),
        asked once per epoch: a pick of an object bound for a goal pose tries them first, so that the
        put-down there needs no regrasp."""
        if obj not in self.fitting:
            geometry = problem.geometry
            w = geometry.initial_world()  # obj away, the arms tucked (as at a drive's end)
            w = replace(w, objects={k: v for k, v in w.objects.items() if k != obj},
                        arms={a: tuple(geometry.robot.home(a)) for a in geometry.robot.arms})
            found = []
            for arm in geometry.robot.arms:
                found += _fitting(problem, w, obj, arm, goal_variants(geometry, obj), found)
            self.fitting[obj] = found
        return self.fitting[obj]

    def ranked_grasps(self, problem, world, obj, arm):
        """Clutter's ranking, with the candidates blocked by an object that waits for obj (``_waiting_for``)
        last, and those whose grasp fits at obj's goal pose (``order_grasps``) first among those with as many
        objects in the way."""
        ranked = super().ranked_grasps(problem, world, obj, arm)
        if not ranked:
            return ranked
        hits = dict(zip(map(id, ranked), self.hit_sets[(obj, arm, id(world))][1]))
        # a grasp of obj that an object waiting for obj blocks waits for a pick that waits for obj (rearrangement_14:
        # block1-5 and block1-1), and the task planner finds no order; grasps with other objects in the way, which it
        # can clear, come first
        mutual = self._waiting_for(world, obj)
        fits = self._goal_fits(problem, obj)
        P = world.objects[obj]
        ranked = sorted(ranked, key=lambda c: (bool(hits[id(c)] & mutual), c[0], bool(fits) and not any(
            _same_grasp(problem.geometry, obj, np.linalg.inv(c[4]) @ P, F) for F in fits), c[1]))
        pose, seen = self.best_hits.get((obj, arm), (None, {}))
        best = hits[id(ranked[0])]
        seen = {**(seen if pose == _pose_key(P) else {}),
                **{o: (_pose_key(Q), o in best) for o, Q in world.objects.items() if o != obj}}
        self.best_hits[(obj, arm)] = (_pose_key(P), seen)
        return ranked

    def _waiting_for(self, world, obj) -> set:
        """The objects whose best grasp for every arm, ranked in this epoch where they and obj stand now, has obj
        in the way."""
        out: dict = {}
        here = _pose_key(world.objects[obj])
        for (b, _), (pose, seen) in self.best_hits.items():
            if b != obj and b in world.objects and _pose_key(world.objects[b]) == pose:
                out[b] = out.get(b, True) and seen.get(obj) == (here, True)
        return {b for b, waits in out.items() if waits}

    def _goal_fits(self, problem, obj):
        return self.wanted.get(obj) or (self.goal_grasps(problem, obj)
                                        if obj in problem.geometry.layout.extra.get("goal_centres", ()) else ())

    def order_grasps(self, problem, obj, P, grasps):
        """The grasps that fit at obj's goal pose first (each base's search keeps the first that IK reaches):
        once a put-down there needed a regrasp, those ``regrasps`` found; before, for an object with a goal
        pose, ``goal_grasps``."""
        fits = self._goal_fits(problem, obj)
        return sorted(grasps, key=lambda g: not any(_same_grasp(problem.geometry, obj, np.linalg.inv(g[1]) @ P, F)
                                                    for F in fits))

    def _putdowns(self, problem, world, obj, arm, bp_ref, pd_ref, spots, z, rng, limit: int = 4, per_spot: int = 4,
                  free: int = 0):
        """Candidates (base, lowering, retreat) for the object poses ``spots`` offers: (x, y, pose(heading),
        the tool's heading if the pose fixes it) with heading the direction from the base to (x, y), the
        object's centre ``z`` above the floor; fewest objects in the way first. The first ``free`` spots are
        clear of other objects: the search goes on through them while every put-down found has one in the way
        (spots on objects, as on a surface they fill, would only find more such put-downs)."""
        geometry = problem.geometry

        overlap = {}  # the objects where the last pose offered stands (putdown_motion asks once per try)

        def clear_of_fixed(pose_at, tight, avoid=frozenset()):
            def at(heading):
                P = pose_at(heading)
                if P is None:
                    return None
                with geometry.stats.timer("collision_checking"), geometry.tight() if tight else nullcontext():
                    if tight:
                        geometry.sync(world)  # the tight world keeps its own placements
                    overlap["hits"] = geometry.cw.objects_overlap(obj, P)
                return None if overlap["hits"] & (geometry.fixed | avoid) else P
            return at

        found = []

        z_spot = z  # a grid pose's bases come from the reach map: the arm reaches it from the side, seldom from the annulus

        def over(objs):  # how far up the hand lifts what it holds until it clears the tops of objs by OVER
            tops = [world.objects[o][2, 3] + geometry.specs[o].height / 2 for o in objs]
            return max(tops) - (z_spot - geometry.specs[obj].height / 2) + OVER

        def search(spots, tries, z=None, off_line=False, avoid=frozenset()):
            for rank, (x, y, pose_at, heading, *grid) in enumerate(spots):
                if rank >= 3 * limit and found and (clear() or not on(rank)):
                    # past the best spots, search on while every put-down found has objects on its lowering or
                    # retreat (rearrangement_18: each such one failed on them, nearly every clear one succeeded)
                    break
                # a pose of putdown_grid: checked with the line padding, as the release is, and let down vertically
                # if need be, as the grid allowed
                tight = bool(grid and grid[0])
                for _ in range(GRID_TRIES if tight else tries if rank < 3 * limit else 2 * tries):
                    tall = over(avoid) if avoid else TALL if tight else 0.0
                    tried = putdown_motion(geometry, world, arm, x, y, clear_of_fixed(pose_at, tight, avoid), rng, heading,
                                           z_spot if tight else z, off_line, tall, avoid, AROUND if avoid else None)
                    if tried is None:
                        continue
                    base, P, T, lower, back, hit, sweep = tried
                    hit |= overlap["hits"]  # objects where it is put
                    found.append(((len(hit), len(sweep)), rank, base, x, y, P, T, lower, back, hit))
                    break
                if (len(found) >= limit and (clear() or not on(rank + 1))) or \
                        (found and found[-1][0] == (0, 0) and len(found) >= 2):
                    break

        def clear():  # a put-down found with nothing where it lowers, lets go and retreats
            return any(not f[0][0] for f in found)

        def on(rank):  # the search may go on to this spot for a clear put-down: one of the first ``free``, within SEARCH_ON
            return rank < min(free, SEARCH_ON * limit)

        search(spots, per_spot)
        if not found and geometry.robot.mobile:
            # none from Clutter's annulus (a spot at the back of a deep table): the best spots again, from
            # bases where the reach map says the arm reaches the spot's height and the base can stand (its
            # flood fill errs on the reachable side: most of those near the table's edge collide with it)
            search(spots[:3 * limit], 3 * per_spot, z)
            if not found:
                # none straight behind a fixed tool heading either: the bases off that line that _fits counts
                # (reachmap.behind), or a grasp judged to fit there would find no put-down (sink_stove_4_40)
                search([s for s in spots[:3 * limit] if s[3] is not None], 3 * per_spot, z, off_line=True)
        found.sort(key=lambda f: (f[0], f[1]))
        # a put-down whose lowering or retreat meets an object that no grasp can ever move (no_grasp_fits) never
        # succeeds: not offered. If that leaves none, one that fails at once naming those objects (the task
        # planner learns PDObstructs without the transit that leads there)
        stuck = {o for f in found for o in f[9] if self._stuck(problem, world, o)}
        kept = [f for f in found if not f[9] & stuck]
        if found and not kept and geometry.robot.mobile:
            # such an object is an obstacle like a fixed one: put-downs that keep clear of it, the hand let down and
            # leaving straight up if need be, coming in from any side of the base (panel: objA into the slot behind
            # objE, the forearm over objE)
            met, found[:] = found[:], []
            search(spots[:3 * limit], 3 * per_spot, z, avoid=frozenset(stuck))
            found.sort(key=lambda f: (f[0], f[1]))
            kept = [f for f in found if not f[9] & stuck]
            found[:] = kept or met
        if found and not kept:
            objs = tuple(sorted(set.union(*(f[9] & stuck for f in found))))
            yield Candidate((), {STUCK: (objs, f"put-down: every one found meets {', '.join(objs)}, which no grasp "
                                               f"can move")}, "blocked put-down")
            return
        for nhit, _, base, x, y, P, T, lower, back, _ in kept[:limit]:
            yield Candidate((base, tuple(reversed(lower)), tuple(back[1:])),
                            {bp_ref: list(base), pd_ref: T.tolist(), "tloc": (obj, P), "object_pose": P.tolist()},
                            f"{obj} at {fmt((x, y))} from base {fmt(base)} ({nhit[0]} + {nhit[1]} objects in the way)")


def go_home(problem, step, world, rng):
    """The one way home: the start base pose (the arms' start joints are the geometry's)."""
    yield Candidate((tuple(problem.geometry.layout.base),), {}, "back to the start configuration")


def go_to(problem, step, world, rng):
    """The one base pose of the file's goal_config [x, y, yaw]."""
    x, y, yaw = problem.geometry.goals["base"]
    base = (x, y, wrap(yaw))  # the files write pi, outside the planner's [-pi, pi) yaw bounds
    yield Candidate((base,), {}, f"to the goal base pose {fmt(base)}")


def _kind(T) -> str:
    """The kind of a tool pose (or of object_T_tool): "top" when its x axis points down."""
    return "top" if abs(T[2, 0]) > 0.7 else "side"


def _same_grasp(geometry, obj, F, H) -> bool:
    """Grasps F and H (tool_T_object) hold ``obj`` the same way: their approach axes and closing lines agree
    in the object's frame (a cylinder's side grasps are all one, whatever their yaw)."""
    A, B = np.linalg.inv(F)[:3, :3], np.linalg.inv(H)[:3, :3]
    if geometry.specs[obj].shape == "cylinder" and _kind(np.linalg.inv(F)) == _kind(np.linalg.inv(H)) == "side":
        return True
    # the same approach axis, and the fingers closing along the same line (a top grasp may turn 90 degrees)
    return float(A[:, 0] @ B[:, 0]) > math.cos(0.5) and abs(float(A[:, 1] @ B[:, 1])) > math.cos(0.5)


def goal_variants(geometry, obj) -> list:
    """obj's goal pose and its turns by the shape's yaw symmetry (a quarter turn for a cylinder: its side
    grasps all look alike, four headings are enough)."""
    C = geometry.layout.extra["goal_centres"][obj]
    period = geometry.symmetry(obj) or math.pi / 2
    yaw = math.atan2(C[1, 0], C[0, 0])
    x, y, z = (float(v) for v in C[:3, 3])
    return [pose4(x, y, z, yaw + k * period) for k in range(int(round(2 * math.pi / period)))]


def _fits(problem, world, obj, arm, T, grasp) -> bool:
    """Tool pose T (with grasp, tool_T_object) can put ``obj`` down: the hand, opened as the grasp needs, clear
    of fixed obstacles at T and where it retreats from, and (a level tool, a mobile base) a base pose clear
    of fixed obstacles from which the reach map says the arm reaches T (it measures level tools: a top
    grasp, or a fixed base's, counts as reached), standing where the put-down's own search stands its bases
    (reachmap.behind: straight behind T, or off that line within SECTOR and NEAR of T)."""
    from interlayer_manip.generators import _base_free, _yaw
    from interlayer_manip.reachmap import base_of, behind

    geometry = problem.geometry
    hand = world.with_gripper(arm, geometry.opening(obj, grasp))
    back = trans(0, 0, PRE_GRASP) @ T if _kind(T) == "top" else T @ trans(-PRE_GRASP, 0, 0)
    with geometry.tight():  # the put-down's own margin; the retreat's far end keeps the full padding
        at = geometry.hand_free(hand, arm, T, (obj,))
    if not (at and geometry.hand_free(hand, arm, back, (obj,))):
        return False
    if _kind(T) == "top" or not geometry.robot.mobile:
        return True
    return any(_base_free(geometry, world, base_of(T[0, 3], T[1, 3], o)) for o in behind(geometry, arm, *T[:3, 3], _yaw(T)))


def _fitting(problem, world, obj, arm, variants, known) -> list:
    """The grasps (tool_T_object) of ``obj`` that fit (``_fits``) at one of the pose ``variants``, other than
    those ``known``: the problem's grasp kinds, from 8 headings (the same draws every call)."""
    from interlayer_manip.generators import _problem_grasps, grasp_poses

    geometry = problem.geometry
    rng = np.random.default_rng(0)
    out = []
    for P in variants:
        for heading in np.linspace(-math.pi, math.pi, 8, endpoint=False):
            for _, T in grasp_poses(geometry, obj, P, heading, _problem_grasps(problem, obj), rng, n_side=1):
                F = np.linalg.inv(T) @ P
                if not any(_same_grasp(geometry, obj, F, H) for H in [*known, *out]) and _fits(problem, world, obj, arm, T, F):
                    out.append(F)
    return out


PUT_GRID, PUT_TURN = 0.0125, math.radians(5)  # m, rad: putdown_grid's object poses
# putdown_grid's poses a put-down search tries after its random spots, at most, and the bases drawn for each (the arm
# reaches such a pose from few: real_regrasp, 2 % of the reach map's bases)
GRID_SPOTS, GRID_TRIES = 12, 24
SEARCH_ON = 6  # a put-down search tries up to this many times its limit of spots while each one found has objects in the way
TALL = 0.3  # m: a vertical lowering and retreat (vertical_putdown) lift the hand over posts this much above the spot
OVER = 0.02  # m: a put-down kept clear of an object no grasp can move lifts what it holds this far over its top
AROUND = math.pi / 2  # rad: a put-down kept clear of an object no grasp can move turns the tool this far from the base's bearing


def _grasps_of(problem, obj, z) -> list:
    """Every grasp (tool_T_object) of ``obj`` the gripper can hold, from 8 headings."""
    from interlayer_manip.grasps import _problem_grasps, grasp_poses

    ref, out = pose4(0.0, 0.0, z, 0.0), []
    for heading in np.linspace(-math.pi, math.pi, 8, endpoint=False):
        for _, T in grasp_poses(problem.geometry, obj, ref, heading, _problem_grasps(problem, obj),
                                np.random.default_rng(0), n_side=1):
            F = np.linalg.inv(T) @ ref
            if not any(np.allclose(F, H, atol=1e-6) for H in out):
                out.append(F)
    return out


def putdown_grid(problem, world, obj, surf, grasps, arms, tally=None):
    """The poses P of box ``obj`` on surface ``surf`` (a grid in the surface's own frame: PUT_GRID apart, every
    PUT_TURN of yaw), with the grasp F and arm, that pass what every put-down there needs: obj's footprint
    inside the surface and obj clear of fixed obstacles, and the hand, opened for F, clear of them where it
    lets go and at each waypoint of a retreat, straight back along its approach (PRE_GRASP) or straight up
    (TALL, its top with the full padding: vertical_putdown), all else with the line padding (LINE_PADDING,
    what the release and the lines keep). Yields (P, F, arm); ``tally`` counts the poses, the releases and
    the obstacles the retreats met."""
    from interlayer_clutter.samplers import from_frame
    from interlayer_manip.grasps import LINE_STEP

    from .scene import oriented_box

    geometry = problem.geometry
    o = geometry.specs[obj]
    tally = {} if tally is None else tally
    tally.update(poses=0, released=0, blockers=set())
    poly, top = geometry.surface(surf, world)
    z = top + o.height / 2 + REST_GAP
    back = [trans(-PRE_GRASP * k / n, 0, 0) for n in [math.ceil(PRE_GRASP / LINE_STEP - 1e-9)] for k in range(1, n + 1)]
    up = [trans(0, 0, TALL * k / n) for n in [math.ceil(TALL / LINE_STEP - 1e-9)] for k in range(1, n + 1)]
    cx, cy, yaw0, hu, hv = oriented_box(poly)
    w = replace(world, held={})
    for u in np.arange(-hu, hu + 1e-9, PUT_GRID):
        for v in np.arange(-hv, hv + 1e-9, PUT_GRID):
            x, y = from_frame((cx, cy, yaw0), u, v)
            for t in np.arange(0.0, (geometry.symmetry(obj) or math.pi) - 1e-9, PUT_TURN):
                P = pose4(float(x), float(y), z, yaw0 + float(t))
                if not all(inside(poly, px, py) for px, py in polygon_of(_spec_at(o, P))):
                    continue
                with geometry.tight(), geometry.stats.timer("collision_checking"):
                    geometry.sync(w)
                    if geometry.cw.objects_overlap(obj, P) & geometry.fixed:
                        continue
                tally["poses"] += 1
                for F in grasps:
                    T = P @ np.linalg.inv(F)
                    for arm in arms:
                        hand = w.with_gripper(arm, geometry.opening(obj, F))
                        with geometry.tight():  # never yield inside it
                            if not geometry.hand_free(hand, arm, T, (obj,)):
                                continue
                            tally["released"] += 1
                            hit = next((T @ B for B in back if not geometry.hand_free(hand, arm, T @ B, (obj,))), None)
                            if hit is not None and len(tally["blockers"]) < 4:
                                tally["blockers"] |= _hand_hits(geometry, hand, arm, hit, obj)
                            lifted = hit is not None and all(geometry.hand_free(hand, arm, B @ T, (obj,)) for B in up)
                        if hit is None or (lifted and geometry.hand_free(hand, arm, up[-1] @ T, (obj,))):
                            yield P, F, arm


def no_putdown(problem, world, obj, surf) -> str:
    """Why no put-down of box ``obj`` on surface ``surf`` can succeed, or "" when one may: no pose of
    putdown_grid passes, with any grasp the gripper can hold (a regrasp could change the held one) and
    either hand. Not a proof (a grid, and the planner's own lowerings and retreats): the caller gives up."""
    geometry = problem.geometry
    o = geometry.specs[obj]
    if o.shape != "box":
        return ""  # a cylinder's side grasps turn freely: no finite set
    grasps = _grasps_of(problem, obj, 0.0)
    if not grasps:
        return ""  # check_graspable names the width
    tally: dict = {}
    if next(putdown_grid(problem, world, obj, surf, grasps, geometry.robot.arms, tally), None) is not None:
        return ""
    where = f"{tally['poses']} poses of {obj} with its footprint inside {surf} and clear of fixed obstacles (a grid: " \
            f"{PUT_GRID * 100:g} cm, {math.degrees(PUT_TURN):g} degrees)"
    if not tally["poses"]:
        return f"{obj} fits nowhere on {surf}: {where}; the goal needs {obj} on {surf}"
    if not tally["released"]:
        return (f"no put-down of {obj} on {surf} leaves the hand clear: at none of {where}, with any grasp the "
                f"gripper can hold, is the hand clear of fixed obstacles; the goal needs {obj} on {surf}")
    return (f"no put-down of {obj} on {surf} has a clear retreat: of {where}, {tally['released']} leave the hand clear "
            f"where it lets go (counting each grasp and hand), but from each the hand's straight "
            f"{PRE_GRASP * 100:g} cm retreat along its approach meets {', '.join(sorted(tally['blockers']))}, and "
            f"its {TALL * 100:g} cm retreat straight up is not clear either (not proved: this planner retreats no "
            f"other way); the goal needs {obj} on {surf}")


def _hand_hits(geometry, hand, arm, T, obj) -> set:
    """The fixed obstacles the hand (opened as in ``hand``) touches with its tool frame at T."""
    return {f for f in geometry.fixed
            if not geometry.hand_free(hand, arm, T, (obj, *(g for g in geometry.fixed if g != f)))}


def _spec_at(spec, P):
    return replace(spec, pose=(float(P[0, 3]), float(P[1, 3]), float(P[2, 3]), math.atan2(P[1, 0], P[0, 0])))


PUSH_LENGTHS = (0.3, 0.6, 0.9, 1.2)  # m: how far a push moves its object


def push(problem, step, world, rng):
    """Pushes of floor obstacle ``f``: the base faces one of f's sides (in f's own frame), drives up to it
    and on straight for one of PUSH_LENGTHS, f moving ahead of it (and the floor obstacles it meets head
    on with it: PBGeometry.push_pieces). Offered only where the base can stand
    and reach (the loader's reachable area), with the robot at the start and both at the end clear of fixed
    obstacles and neither running into one on the way (checked coarsely: the refinement checks the line
    at the validator's resolution). Ranked by the loader's flood fill of the base (a disk) among the fixed
    shapes and the floor obstacles where they stand: first those whose start the base reaches now, then
    those after which the base reaches the most goals of the drives floor obstacles were found blocking,
    then longer ones."""
    from .loader import reachable_area
    from .world import PUSH_GAP, base4

    geometry = problem.geometry
    obj = step.args[0]
    if obj not in world.objects:
        return
    w = geometry.tucked(world)
    P = w.objects[obj]
    yaw = math.atan2(P[1, 0], P[0, 0])
    area = geometry.layout.extra.get("base_area")
    # where the base can drive now, the floor obstacles where they stand: pushes from there first
    limits = geometry.layout.extra["base_limits"]
    now = reachable_area(_floor_shapes(geometry, w), w.base, *limits)
    goals = list(dict.fromkeys(to for _, to in geometry.blocked_drives))
    found = []
    for k in range(4):
        heading = wrap(yaw + k * math.pi / 2)
        d = geometry.contact_distance(w, obj, heading)
        if d is None:
            continue
        d += PUSH_GAP
        u = np.array([math.cos(heading), math.sin(heading)])
        start = (float(P[0, 3] - d * u[0]), float(P[1, 3] - d * u[1]), heading)
        if area is not None and not area(*start[:2]):
            continue
        if geometry.in_collision(replace(w, base=start), movables=False):
            continue
        B = np.linalg.inv(base4(start)) @ P
        for length in PUSH_LENGTHS:
            end = (start[0] + length * u[0], start[1] + length * u[1], heading)
            E = base4(end) @ B
            if (area is not None and not area(*end[:2])) or not geometry.base_space.within_bounds(np.asarray(end)):
                continue
            with geometry.stats.timer("collision_checking"):
                if geometry.cw.objects_overlap(obj, E) & geometry.fixed:
                    continue
            if geometry.in_collision(replace(w, base=end), movables=False):
                continue
            moved, why, pieces = geometry.push_pieces(w, obj, start, end, fine=RES_BASE * 2, movables=False)
            if why:
                continue  # the robot or an object would run into a wall
            after = reachable_area(_floor_shapes(geometry, moved), end, *limits)
            blocked = sum(after is not None and not after(*g) for g in goals)  # goals of blocked drives still cut off
            found.append((now is not None and not now(*start[:2]), blocked, -length, rng.random(), start, end, pieces[-1][2][1:]))
    found.sort(key=lambda c: c[:4])
    for _, _, length, _, start, end, chain in found:
        yield Candidate((start, end), {}, f"push {obj} {-length:.1f} m from base {fmt(start)}"
                                          + (f" (with {', '.join(chain)}, which it meets head on)" if chain else ""))


def _floor_shapes(geometry, world) -> list:
    """The fixed shapes and the floor obstacles where ``world`` has them: what the base's flood fill avoids."""
    return [*geometry.layout.fixed, *(_spec_at(geometry.specs[o], Q) for o, Q in world.objects.items()
                                      if o in geometry.floor_objects)]
