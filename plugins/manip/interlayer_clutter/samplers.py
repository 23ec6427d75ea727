"""Clutter's pose generators: pick and place with move_base folded in (see domain.py)."""
from __future__ import annotations

import functools
import math
from dataclasses import replace

import numpy as np
from interlayer.refine import Candidate, EpochState
from interlayer_manip.generators import _base_free
from interlayer_manip.grasps import FIXED_SPREAD
from interlayer_manip.reachmap import reaching_base
from interlayer_manip.scene import REST_GAP, base_limits, table_top
from interlayer_manip.state import pose4, wrap


def table_frame(layout) -> tuple:
    """The table top in its own frame: (centre x, centre y, yaw, half length, half width). A layout whose
    table is turned gives it as ``extra["table_frame"]``; else it is the axis-aligned ``regions["table"]``."""
    given = layout.extra.get("table_frame")
    if given is not None:
        return tuple(float(v) for v in given)
    xmin, xmax, ymin, ymax = layout.regions["table"]
    return (xmin + xmax) / 2, (ymin + ymax) / 2, 0.0, (xmax - xmin) / 2, (ymax - ymin) / 2


def in_frame(frame, x, y):
    """World (x, y) in the coordinates (u, v) of ``frame`` (see :func:`table_frame`); arrays too."""
    cx, cy, yaw = frame[:3]
    c, s = math.cos(yaw), math.sin(yaw)
    dx, dy = x - cx, y - cy
    return c * dx + s * dy, c * dy - s * dx


def from_frame(frame, u, v):
    """The inverse of :func:`in_frame`."""
    cx, cy, yaw = frame[:3]
    c, s = math.cos(yaw), math.sin(yaw)
    return cx + c * u - s * v, cy + s * u + c * v


BASE_DRAWS = 20  # draws per base pose of a grasp search's budget, at most (most fall in walls and furniture)
# Clutter's and pybullet-planning's straight lines halve a step that moves the joints too far, up to twice
# (interlayer_manip.generators._line_step: a stretched arm reaching across a table, move_several_32)
LINE_SPLITS = 2


def base_near(geometry, x, y, rng, reach=(0.55, 0.95), heading=None):
    """A base pose facing (x, y) from outside the table, sampled around the table's sides; behind the
    tool when its ``heading`` is fixed (a given object pose and grasp: most sides cannot reach it).
    A fixed-base robot: where it stands."""
    if not geometry.robot.mobile:
        return tuple(geometry.layout.base)
    table = table_frame(geometry.layout)
    (lx, hx), (ly, hy) = base_limits(geometry.layout)
    area = geometry.layout.extra.get("base_area")
    near = _cells_near(geometry.layout, x, y, reach, heading)
    for _ in range(20):
        if near is not None:  # the reachable places in the annulus (or its part behind the tool) alone
            if not len(near[0]):
                return None
            bx, by = near[0][rng.integers(len(near[0]))] + rng.uniform(-near[1] / 2, near[1] / 2, 2)
        else:
            r = rng.uniform(*reach)
            a = rng.uniform(-math.pi, math.pi) if heading is None else heading + math.pi + rng.uniform(-0.8, 0.8)
            bx, by = x + r * math.cos(a), y + r * math.sin(a)
        u, v = in_frame(table, bx, by)
        if abs(u) < table[3] + 0.33 and abs(v) < table[4] + 0.33:
            continue  # the base would stand under the table (in the table's own frame: it may be turned)
        if not (lx <= bx <= hx and ly <= by <= hy) or (area is not None and not area(bx, by)):
            continue  # outside the base's limits, or (a layout that knows it) where the base cannot drive
        yaw = math.atan2(y - by, x - bx) + rng.uniform(-0.35, 0.35)
        return (float(bx), float(by), float(wrap(yaw)))
    return None


def _cells_near(layout, x, y, reach, heading):
    """(centres, cell size) of the layout's reachable base cells (``base_cells``: a walled scene's
    flood fill) in the annulus ``reach`` around (x, y), within 0.8 rad of straight behind ``heading``;
    None when the layout has no such cells. Uniform draws over the annulus mostly land in walls and
    furniture there (95 % for an object in a kitchen's corner), and a search that stops after a fixed
    number of draws then finds no base at all in some epochs."""
    cells = layout.extra.get("base_cells")
    if cells is None:
        return None
    centres, res = cells
    key = (id(centres), float(x), float(y), tuple(reach), heading)
    hit = _NEAR.get(key)
    if hit is None or hit[0] is not centres:  # a search asks about one spot many times
        d = np.hypot(centres[:, 0] - x, centres[:, 1] - y)
        keep = (d >= reach[0]) & (d <= reach[1])
        if heading is not None:  # the direction from the spot to the cell, within 0.8 rad of heading + pi
            a = np.arctan2(centres[:, 1] - y, centres[:, 0] - x)
            keep &= np.abs(np.remainder(a - heading, 2 * math.pi) - math.pi) <= 0.8
        if len(_NEAR) > 512:
            _NEAR.clear()
        hit = _NEAR[key] = (centres, centres[keep])
    return hit[1], res  # (not read back: another thread's solve may clear the cache in between)


_NEAR: dict = {}  # (id of the cells, x, y, reach, heading) -> (the cells, those in the annulus)


def coarse_line(a, b, n=8):
    """n evenly spaced configurations from a (excluded) to b: a rough guess at a transit's sweep."""
    a, b = np.asarray(a, float), np.asarray(b, float)
    return [a + (b - a) * k / n for k in range(1, n + 1)]


def movables_on(geometry, world, arm, path, ignore, gripper="open"):
    """Movable objects the arm (gripper open) touches at the waypoints of ``path``."""
    w = world.with_gripper(arm, gripper) if gripper else world
    hit = set()
    for v in path:
        q = geometry.sync(w.with_arm(arm, v))
        hit |= geometry.cw.colliding_movables(q)
    return hit - set(ignore) - {o for o, _ in world.held.values()}


class ClutterSampler(EpochState):
    """Clutter's pick and place generators and what they share within one epoch: grasp candidates
    sampled once per (object, arm, object pose) and re-ranked in each world, and the approach
    corridors of the best grasps found so far, which put-downs keep clear of. The loop makes a fresh
    instance at every epoch, so a reset discards both and samples anew."""

    def __init__(self, seed):
        super().__init__(seed)
        self.grasps: dict = {}  # (obj, arm, pose) -> candidates
        self.misses: dict = {}  # (obj, arm, pose) -> fruitless searches so far
        self.corridors: dict = {}  # (obj, arm) -> (obj pose key, footprints of its best grasps there)
        # answers already given (the partial pass repeats the error-free pass's questions), keyed by the
        # world's id and holding the world itself (so that the id is not reused while the entry lives)
        self.rankings: dict = {}  # (obj, arm, id(world)) -> (world, ranked grasps)
        self.hit_sets: dict = {}  # (obj, arm, id(world)) -> (world, the objects on each ranked grasp's approach and raise)
        self.lookaheads: dict = {}  # (obj, arm, id(world)) -> (world, the other arm's question, see _other_arm)
        self.putdowns: dict = {}  # (obj, arm, id(world), random state, corridors) -> (world, put-down candidates)

    def __call__(self, problem, step, world, rng):
        return self.pick(problem, step, world, rng) if step.action == "pick" else self.place(problem, step, world, rng)

    def pick(self, problem, step, world, rng, limit: int = 5):
        """Base pose + side grasp of step's object; candidates ordered by how many objects their
        approach and raise touch (fewest first: fewer obstructions to learn and clear).

        The candidates are stable within the epoch: sampled once per (object, arm, object pose), then
        re-ranked in each call's world. An obstruction learned for the best candidate thus stays true
        of it, and once the task plan has cleared those blockers the same candidate comes first again
        with nothing in its way (fresh samples would bring fresh blockers)."""
        obj, arm = step.args[0], step.args[1]
        bp_ref, gp_ref = step.args[3], step.args[4]
        if world.holder(obj) is not None or world.held.get(arm):
            return
        ranked = self.ranked_grasps(problem, world, obj, arm)
        # put-downs keep clear of these approaches: an object put down there would block this pick again
        self.corridors[(obj, arm)] = (_pose_key(world.objects[obj]), [c[6] for c in ranked[:3]])
        other = self._other_arm(problem, world, obj, arm) if ranked and ranked[0][0][0] else None
        for nhit, _, base, kind, T, wps, _ in ranked[:limit]:
            values = {bp_ref: list(base), gp_ref: T.tolist(), **({"other_arm": other} if other else {})}
            yield Candidate((base, *wps), values,
                            f"{kind} grasp from base {fmt(base)} ({nhit[0]} objects on the approach, {nhit[1]} on the way)")

    def _other_arm(self, problem, world, obj, arm):
        """``other_arm_blocked`` for this question, to call later (when a failure is translated); the
        same function for the same question, so that the candidates carrying it compare equal (the
        refinement cache keys on them)."""
        key = (obj, arm, id(world))
        if self.lookaheads.get(key, (None,))[0] is not world:
            self.lookaheads[key] = (world, functools.partial(self.other_arm_blocked, problem, world, obj, arm))
        return self.lookaheads[key][1]

    def other_arm_blocked(self, problem, world, obj, arm):
        """(arm, base, approach, world to check it in or None) of the other arm's best grasp of obj when
        every one of its grasps has objects in the way; else None. The refinement learns that grasp's
        blockers with this arm's (see ManipulationGeometry.approach_blocked). An other arm that holds an object
        is asked as it will be once it has put that down: out of the way, the arm tucked."""
        other = next((a for a in problem.geometry.robot.arms if a != arm), None)
        if other is None:  # a one-armed robot: no other arm to ask about
            return None
        found = self.best_blocked(problem, world, obj, other)
        return found and (other, *found)

    def best_blocked(self, problem, world, obj, arm):
        """(base, approach, world to check it in or None) of arm's best grasp of obj when every one of its
        grasps has objects in the way; else None. An arm that holds an object is asked as it will be once
        it has put that down: out of the way, the arm tucked."""
        free = _hand_emptied(problem.geometry, world, arm) if world.held.get(arm) else world
        if obj not in free.objects:
            return None
        ranked = self.ranked_grasps(problem, free, obj, arm)
        if not ranked or not ranked[0][0][0]:
            return None
        _, _, base, _, _, wps, _ = ranked[0]
        return base, wps[0], None if free is world else free

    def chain(self, problem, world):
        """``best_blocked`` in ``world`` as a function of (object, arm), the same function for the same
        world (candidates carrying it compare equal): what a failed step's blockers' own picks meet
        (ManipulationGeometry.approach_blocked learns it with the failure)."""
        key = ("chain", id(world))
        if self.lookaheads.get(key, (None,))[0] is not world:
            self.lookaheads[key] = (world, functools.partial(self.best_blocked, problem, world))
        return self.lookaheads[key][1]

    def grasp_candidates(self, problem, world, obj, arm, tries: int = 40):
        """(base, kind, T, waypoints, tool xy path) candidates for picking obj with arm where it stands;
        static checks only (IK, fixed obstacles), so they hold in every world with obj at this pose."""
        from interlayer_manip.generators import (_bearing, _problem_grasps, _waypoints, check_graspable, check_hand_fits,
                                               grasp_poses)

        geometry = problem.geometry
        P = world.objects[obj]
        key = (obj, arm, _pose_key(P))
        if key in self.grasps:
            return self.grasps[key]
        check_graspable(problem, obj)
        misses = self.misses.get(key, 0)
        rng = self.rng_for(*key, misses)  # a function of the epoch and the question only
        x, y = P[0, 3], P[1, 3]
        kinds = _problem_grasps(problem, obj)
        target = obj == geometry.layout.target
        want = 12 if target else 6
        n_bases = 3 * tries if target else tries
        found = []
        # the other arm tucked and nothing held: the candidates must not depend on the world they were asked in
        arms = geometry.robot.arms
        w0 = replace(world, held={}, arms={a: tuple(geometry.robot.home(a)) for a in arms},
                     grippers={a: "closed" for a in arms})
        # the budget counts base poses clear of fixed obstacles, not draws: around an object in a corner most
        # draws hit the walls, and a search cut after a fixed number of draws found nothing in most epochs
        free, draws, tried = 0, 0, set()
        while free < n_bases + 2 * tries and draws < BASE_DRAWS * (n_bases + 2 * tries):
            if free >= n_bases and found:
                break  # past the first bases, only search on while nothing at all was found
            draws += 1
            if (free < n_bases and draws <= BASE_DRAWS * n_bases) or not geometry.robot.mobile:
                base = base_near(geometry, x, y, rng)
            else:  # the annulus found nothing (at the back of a deep table it rarely can): bases where the
                # reach map says the arm reaches and the base can stand
                base = reaching_base(geometry, arm, rng, x, y, P[2, 3])
            if base is None or not _base_free(geometry, w0, base):
                continue
            free += 1
            w = replace(w0, base=base)
            for kind, T in self.order_grasps(problem, obj, P, grasp_poses(geometry, obj, P, _bearing(base, x, y), kinds, rng,
                                                                          n_side=2)):
                if (base, _pose_key(T)) in tried:  # a fixed base draws its straight-on grasp at every turn
                    continue
                tried.add((base, _pose_key(T)))
                wps = _waypoints(geometry, w, arm, T, kind, rng, obj, splits=LINE_SPLITS)
                if wps is None:
                    continue
                wps = _with_hover(geometry, w, arm, T, wps, rng, obj)
                found.append((base, kind, T, wps, _reach_xy(base, T)))
                break
            if len(found) >= want:
                break
        if found:
            self.grasps[key] = found
        else:
            self.misses[key] = misses + 1  # the next call searches with other samples
            check_hand_fits(problem, world, obj)
        return found

    def order_grasps(self, problem, obj, P, grasps):
        """The order in which a grasp search tries the grasps of obj (at pose P) offered at one base: the
        first that IK reaches is that base's candidate. A subclass may prefer some (a regrasp's)."""
        return grasps

    def ranked_grasps(self, problem, world, obj, arm):
        """The candidates ranked in ``world``: ((approach hits, transit-line hits), drive, base, kind,
        T, waypoints, footprint), fewest objects in the way first, then the shortest drive from the
        robot's base (a short drive is planned quicker, often as a straight line)."""
        key = (obj, arm, id(world))
        if self.rankings.get(key, (None,))[0] is world:  # worlds are never mutated, only replaced
            return self.rankings[key][1]
        geometry = problem.geometry
        out = []
        for base, kind, T, wps, xy in self.grasp_candidates(problem, world, obj, arm):
            if not _base_free(geometry, world, base):
                continue
            w = replace(world, base=base)
            with geometry.stats.timer("collision_checking"):
                # exactly the refinement's first check: the approach (hover descent included), densified
                opened = geometry.grasp_opening(w, arm, obj, wps[0][-1])
                hit = geometry._movables_on_line(w.with_gripper(arm, opened), arm, wps[0], [0.0]) - {obj}
                # the raise as the refinement checks it: with obj held (a block lifted 5 cm and drawn back
                # along its approach drags through a neighbour as tall as it; with the hand alone, every
                # candidate looked clear and the first ones all failed there)
                hit |= geometry._movables_on_line(_carrying(w, arm, obj, T), arm, (wps[0][-1], *wps[1]), [0.0])
                # a rough guess at the transit's sweep: the straight joint-space line to the pre-grasp
                sweep = movables_on(geometry, w, arm, coarse_line(w.arms[arm], wps[0][0]), (obj,), gripper=None)
            drive = math.hypot(base[0] - world.base[0], base[1] - world.base[1]) + 0.3 * abs(wrap(base[2] - world.base[2]))
            out.append((((len(hit), len(sweep)), drive, base, kind, T, wps, xy), frozenset(hit)))
        out.sort(key=lambda f: (f[0][0], f[0][1]))
        hits, out = [h for _, h in out], [f for f, _ in out]
        if out:  # none found: the next call searches with other samples (see grasp_candidates)
            self.rankings[key] = (world, out)
            self.hit_sets[key] = (world, hits)
        return out

    def spot_score(self, geometry, world, target, x, y, corridors=()):
        """Larger is better: near the table's edge (few objects between the arm and the spot), far from
        the target and clear of other objects, and never in ``corridors`` (see :meth:`corridors_for`)."""
        table = table_frame(geometry.layout)
        u, v = in_frame(table, x, y)
        edge = min(table[3] - abs(u), table[4] - abs(v))
        d_obj = min((math.hypot(x - Q[0, 3], y - Q[1, 3]) for Q in world.objects.values()), default=1.0)
        Tt = world.objects.get(target)
        d_t = math.hypot(x - Tt[0, 3], y - Tt[1, 3]) if Tt is not None else 1.0
        return min(d_obj, 0.25) + 0.5 * min(d_t, 0.6) - 1.5 * edge - in_corridors(x, y, corridors)

    def corridors_for(self, world, placing, target):
        """(penalty, footprint points) of the best grasps ranked in this epoch of every object still
        standing where they were ranked, except the one being put down: the target's best approach
        costs most, any object's best one (a later step may have to pick it) almost as much."""
        out = []
        for (obj, _), (pose, footprints) in self.corridors.items():
            P = world.objects.get(obj)
            if obj == placing or P is None or _pose_key(P) != pose:
                continue
            for rank, xy in enumerate(footprints):
                weight = 0.5 if rank else (TARGET_CORRIDOR if obj == target else 1.5)
                out.append((weight, np.asarray(xy, float)))
        return out

    def place(self, problem, step, world, rng, limit: int = 4):
        """A free table spot (far from the target and other objects first), a base pose to reach it, and
        the lowering / retreat arm paths."""
        obj, arm = step.args[0], step.args[1]
        bp_ref, pd_ref = step.args[3], step.args[4]
        if world.holder(obj) != arm:
            return
        corridors = self.corridors_for(world, obj, problem.geometry.layout.target)
        # the same question (world, random stream, approaches to keep clear) gets the same answer: the
        # partial pass asks again what the error-free pass asked
        key = (obj, arm, id(world), repr(rng.bit_generator.state), tuple((w, xy.tobytes()) for w, xy in corridors))
        if self.putdowns.get(key, (None,))[0] is not world:
            self.putdowns[key] = (world, self.putdown_candidates(problem, obj, arm, world, rng, corridors, limit))
        for (_, hits, blocks, sweep), _, base, x, y, P, T, lower, back in self.putdowns[key][1]:
            on = ", on a known approach" if blocks else ""
            yield Candidate((base, tuple(reversed(lower)), tuple(back[1:])),
                            {bp_ref: list(base), pd_ref: T.tolist(), "tloc": (obj, P), "object_pose": P.tolist()},
                            f"{obj} at {fmt((x, y))} from base {fmt(base)} ({hits} + {sweep} objects in the way{on})")

    def putdown_candidates(self, problem, obj, arm, world, rng, corridors, limit, tries: int = 80):
        """The ``limit`` best (ordering key, rank, base, x, y, object pose, tool pose, lowering, retreat)
        for putting down obj held in arm."""
        from interlayer_manip.generators import _putdown

        geometry = problem.geometry
        G = world.held[arm][1]
        geometry.sync(world)
        target = geometry.layout.target
        found = []
        good = []  # candidates with nothing on their lowering and retreat, off the known approaches
        offset = 0
        # the roomiest spots first; tighter ones only while none found is both unobstructed and off the
        # known approaches (on a crowded table the roomy spots are often holes left in an approach, or
        # deep between objects, where the arm cannot lower or back out)
        for level in _table_spots(geometry, world, obj, rng, tries):
            spots = sorted(((self.spot_score(geometry, world, target, x, y, corridors), x, y, z) for x, y, z in level),
                           key=lambda s: -s[0])
            for i, (_, x, y, z) in enumerate(spots):
                blocks = in_corridors(x, y, corridors)
                if i >= 3 * limit and (good or (found and i >= 6 * limit)):
                    break  # past the best spots, search on while every spot found is likely blocked; then tighter ones
                for _ in range(4 if i < 3 * limit else 8):
                    tried = putdown_motion(geometry, world, arm, x, y, lambda h, x=x, y=y, z=z: _putdown(G, x, y, z, h)[0], rng)
                    if tried is None:
                        continue
                    base, P, T, lower, back, hit, sweep = tried
                    # a spot on a known approach blocks a later pick for sure: worse than a guessed transit hit;
                    # on the target's best one (the pick the plan ends with) worse than objects in the way too
                    found.append(((blocks >= TARGET_CORRIDOR, len(hit), blocks, len(sweep)), offset + i, base, x, y,
                                  P, T, lower, back))
                    good += [found[-1]] if not hit and not blocks else []
                    break
                if (len(found) >= limit and good) or (len(good) >= 2 and good[-1][0] == (False, 0, 0, 0)):
                    break
            offset += len(spots)
            if good:
                break
        found.sort(key=lambda f: (f[0], f[1]))
        return found[:limit]


def putdown_motion(geometry, world, arm, x, y, pose_at, rng, heading=None, z=None, off_line=False, tall=0.0,
                   avoid=(), spread=None):
    """One try at putting what ``arm`` holds down at (x, y): a base pose facing the spot (behind the tool
    if its ``heading`` is fixed; with ``z``, the object's height, one the reach map offers, else one of the
    annulus; ``off_line``: see reachmap.reaching_base), the object's pose ``pose_at(tool heading)`` (None:
    none there), IK, the lowering and the retreat (with ``tall``, if the straight ones fail, both straight up
    that far: vertical_putdown; the objects ``avoid`` names are kept clear of as fixed obstacles are) and the
    tool's heading drawn within ``spread`` of the bearing from the base. Returns (base, object pose, tool pose,
    lowering, retreat, movables on the lowering and retreat, movables on the straight joint-space line from the
    arm's posture) or None."""
    from interlayer_manip.generators import LIFT, PRE_GRASP, _line, cleared_lowering, trans

    if z is None or not geometry.robot.mobile:
        base = base_near(geometry, x, y, rng, heading=heading)
    else:
        base = reaching_base(geometry, arm, rng, x, y, z, heading, off_line)
    if base is None or not _base_free(geometry, world, base, tuck=arm):
        return None
    if spread is None:
        spread = 0.3 if geometry.robot.mobile else FIXED_SPREAD  # a fixed base turns the hand, not itself (grasp_poses)
    P = pose_at(math.atan2(y - base[1], x - base[0]) + rng.uniform(-spread, spread))
    if P is None:
        return None
    obj, G = world.held[arm]
    opened = geometry.opening(obj, G)  # only as wide as the grasp needs
    T = P @ np.linalg.inv(G)
    w = replace(world, base=base)
    # IK and lines clear of the objects to avoid; the other movables may be met (hit below: moved first)
    free = {"ignore": tuple(o for o in world.objects if o not in avoid), "movables": True} if avoid else {}
    with geometry.tight():  # the put-down and its lines keep LINE_PADDING from fixed obstacles, their far ends more (below)
        if avoid and not geometry.hand_free(w.with_gripper(arm, opened), arm, T, (obj, *free["ignore"]), movables=True):
            return None  # the hand alone meets what it must avoid: no IK
        put = geometry.ik(w, arm, T, rng, attempts=8 if avoid else 4, **free)
        if put is None:
            return None
        lower = _line(geometry, w, arm, T, lambda d: trans(0, 0, d) @ T, LIFT, put, rng, splits=LINE_SPLITS, **free)
        back = _line(geometry, w.with_gripper(arm, opened), arm, T, lambda d: T @ trans(-d, 0, 0), PRE_GRASP, put, rng,
                     gripper=opened, splits=LINE_SPLITS, **free)
    lower = lower and back and cleared_lowering(geometry, w, arm, obj, opened, lower, back)
    if not lower and tall:
        lower, back = vertical_putdown(geometry, w, arm, obj, opened, T, put, tall, free)
    if not lower:
        return None
    with geometry.stats.timer("collision_checking"):
        hit = movables_on(geometry, w, arm, lower, (), gripper=None)
        hit |= movables_on(geometry, w, arm, back, (), gripper=opened)
        sweep = movables_on(geometry, w, arm, coarse_line(w.arms[arm], lower[-1]), (), gripper=None)
    return base, P, T, lower, back, hit, sweep


def vertical_putdown(geometry, world, arm, obj, opened, T, put, tall, free=None):
    """(lowering, retreat) both straight up ``tall`` from the put-down at tool pose T (IK ``put``): the hand
    comes down onto the spot and leaves it vertically, as between posts taller than what it holds, where a
    retreat along the approach meets them. Their top ends clear the padded fixed obstacles (transits meet
    there); (None, None) if not. IK seeds of its own: the caller's draws stay as they were. ``free``: _line's
    ignore and movables (see putdown_motion's avoid)."""
    from interlayer_manip.generators import _line, line_ends_clear, trans

    rng = np.random.default_rng(0)
    hand = world.with_gripper(arm, opened)
    free = free or {}
    with geometry.tight():
        lower = _line(geometry, world, arm, T, lambda d: trans(0, 0, d) @ T, tall, put, rng, splits=LINE_SPLITS, **free)
        back = lower and _line(geometry, hand, arm, T, lambda d: trans(0, 0, d) @ T, tall, put, rng, gripper=opened,
                               splits=LINE_SPLITS, **free)
    if not (back and line_ends_clear(geometry, world, arm, (lower[-1],))
            and line_ends_clear(geometry, hand, arm, (back[-1],), (obj,))):
        return None, None
    return lower, back


def _reach_xy(base, T, step=0.05):
    """Points along the arm's footprint over the table: from the tool back towards the base."""
    tx, ty = T[0, 3], T[1, 3]
    bx, by = base[0], base[1]
    d = math.hypot(bx - tx, by - ty)
    n = max(1, int(d / step))
    return [(tx + (bx - tx) * k / n, ty + (by - ty) * k / n) for k in range(n + 1)]


HOVER = 0.18  # the pre-grasp is approached from this far above: over the other cylinders' tops


def _with_hover(geometry, world, arm, T, wps, rng, obj):
    """Prefix the approach with a vertical descent from HOVER above the pre-grasp, so that the free
    transit ends above the clutter and only the descent and the approach run between objects
    (obstructions learned from a failure then name the objects really in the way)."""
    from interlayer_manip.generators import _line
    from interlayer_manip.state import PRE_GRASP, trans

    approach, lift = wps
    pre_T = T @ trans(-PRE_GRASP, 0, 0)
    opened = geometry.opening(obj, np.linalg.inv(T) @ world.objects[obj])
    down = _line(geometry, world.with_gripper(arm, opened), arm, pre_T, lambda d: trans(0, 0, d) @ pre_T, HOVER,
                 approach[0], rng, (obj,), opened, LINE_SPLITS)
    if down is None or not geometry.static_path_ok(world.with_gripper(arm, opened), arm, down, (obj,)):
        return wps
    return tuple(reversed(down)) + tuple(approach[1:]), lift


CORRIDOR = 0.15  # m: put-down spots keep this far from the footprint of the target's best approaches
TARGET_CORRIDOR = 2.0  # the penalty of a spot on the target's best approach (see ClutterSampler.corridors_for)


# m: how far beyond the base's limits a put-down can be reached (lowering a side-grasped cylinder onto the
# table; measured on the front scenes: 1 of 362 tries succeeded farther out, from base_near's 0.95 m)
PUT_REACH = 0.8


def _table_spots(geometry, world, obj, rng, tries):
    """Upright resting poses of obj anywhere on the table, clear of fixed obstacles, in lists of
    decreasing clearance from every other object (edge to edge: 6, 4, 2.5 cm). With 40 objects on the
    table roomy spots are rare: many points are drawn at once (vectorized); the caller stops taking
    lists once it has what it needs (the draws do not depend on how many it takes)."""
    o = geometry.specs[obj]
    table = table_frame(geometry.layout)
    m = o.size[0] + 0.02
    z = table_top(geometry.layout) + o.height / 2 + REST_GAP
    n = max(tries, 40) * 25
    # drawn in the table's own frame, within PUT_REACH of the base's limits (beyond, no base pose puts
    # anything down): the corners of those limits, in the table's frame, bound the spots
    (lx, hx), (ly, hy) = base_limits(geometry.layout)
    cu, cv = in_frame(table, np.array([lx, hx, hx, lx]), np.array([ly, ly, hy, hy]))
    u0, u1 = max(-table[3] + m, cu.min() - PUT_REACH), min(table[3] - m, cu.max() + PUT_REACH)
    v0, v1 = max(-table[4] + m, cv.min() - PUT_REACH), min(table[4] - m, cv.max() + PUT_REACH)
    pts = np.column_stack(from_frame(table, rng.uniform(u0, u1, n), rng.uniform(v0, v1, n)))
    reach = geometry.layout.extra.get("reach")
    if reach is not None:  # a fixed base (see clutter_layout): only where its arm reaches, near and far (the free
        # spots of a crowded band are mostly nearer than it, where no put-down succeeds)
        bx, by = geometry.layout.base[:2]
        d = np.hypot(pts[:, 0] - bx, pts[:, 1] - by)
        pts = pts[(d <= reach) & (d >= geometry.layout.extra.get("reach_near", 0.0))]
        n = len(pts)
    others = np.array([Q[:2, 3] for Q in world.objects.values()]).reshape(-1, 2)
    d = np.min(np.linalg.norm(pts[:, None, :] - others[None, :, :], axis=2), axis=1) if len(others) else np.full(n, 9.0)
    for gap in (0.06, 0.04, 0.025):
        ok = (d >= 2 * o.size[0] + gap)
        level = []
        for x, y in pts[ok][:tries]:
            with geometry.stats.timer("collision_checking"):
                hits = geometry.cw.objects_overlap(obj, pose4(float(x), float(y), z, table[2]))
            if not hits & geometry.fixed:
                level.append((float(x), float(y), z))
        yield level
        d = np.where(ok, -1.0, d)  # already offered


def in_corridors(x, y, corridors) -> float:
    """The summed penalties of the corridors (see ClutterSampler.corridors_for) that (x, y) lies in."""
    return sum(weight for weight, xy in corridors if np.min(np.hypot(xy[:, 0] - x, xy[:, 1] - y)) < CORRIDOR)


def _hand_emptied(geometry, world, arm):
    """``world`` with ``arm``'s object put down where nothing is (far below the floor: where it will go is
    not known yet) and the arm tucked."""
    obj = world.held[arm][0]
    return replace(world, held={a: h for a, h in world.held.items() if a != arm},
                   objects={**world.objects, obj: pose4(0.0, 0.0, -10.0, 0.0)},
                   arms={**world.arms, arm: tuple(geometry.robot.home(arm))}, grippers={**world.grippers, arm: "closed"})


def _carrying(world, arm, obj, T):
    """``world`` with ``arm`` holding obj by the grasp whose tool pose is T (where obj stands), closed."""
    G = np.linalg.inv(T) @ world.objects[obj]
    return replace(world, objects={k: v for k, v in world.objects.items() if k != obj}, held={**world.held, arm: (obj, G)},
                   grippers={**world.grippers, arm: "closed"})


def _pose_key(P):
    return tuple(np.round(np.asarray(P)[:3, :4].ravel(), 4))


def fmt(p):
    """A point or pose for a candidate's label."""
    return "(" + ", ".join(f"{v:.2f}" for v in p) + ")"
