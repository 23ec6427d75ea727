"""Pose generators (Sec. IV-B2) for any robot: base poses within the arm's reach, side / top grasps, put-down spots.

* ``pr2:move_base`` instantiates the base-pose reference it drives to. For ``bpfg_<o>_<arm>`` it
  samples base poses from which the arm reaches o (reachmap.py: measured per robot, arm and height;
  from the directions where the hand alone fits), keeping those with a collision-free (fixed
  obstacles) IK solution for some grasp. For ``bpfpd_<o>_<arm>_<loc>`` it samples a put-down
  spot (tloc) in loc near the robot, then base poses from which the arm reaches it, with an IK
  solution for the put-down gripper pose derived from the held grasp; the tloc travels with the world
  to place.
* ``pr2:pick`` yields grasps reachable from the current base: (pre-grasp, grasp, raise) arm vectors.
* ``pr2:place`` yields (lowering, retreat) arm paths for the chosen tloc and a few variants.

All are finite and seeded by ``rng``; they only check static geometry (IK, fixed obstacles).
"""
from __future__ import annotations

import math
from dataclasses import replace

import numpy as np

from interlayer.refine import Candidate, stable_seed

from .grasps import (_bearing, _line, _problem_grasps, _waypoints, _yaw, check_graspable, check_hand_fits, line_ends_clear,
                     grasp_poses)
from .reachmap import around, open_bearings
from .scene import REST_GAP, table_top
from .state import LIFT, PRE_GRASP, pose4, trans, wrap


def pick(problem, step, world, rng, limit: int = 6, grasps=None):
    """``grasps(world, heading, rng) -> [(kind, tool pose)]`` replaces grasp_poses (a domain's own grasps)."""
    obj, arm = step.args[0], step.args[1]
    geometry = problem.geometry
    if world.holder(obj) is not None:
        return
    check_graspable(problem, obj)
    P = world.objects[obj]
    heading = _bearing(world.base, P[0, 3], P[1, 3])
    n = 0
    planned = world.tloc.get(("grasp", obj, arm))
    if planned is not None:  # the grasp move_base checked from this base
        kind, T, wps = planned
        n += 1
        yield Candidate(wps, {step.args[3]: T.tolist()}, f"{kind} grasp, tool yaw {math.degrees(_yaw(T)):.0f} deg")
    offered = grasps(world, heading, rng) if grasps else grasp_poses(geometry, obj, P, heading, _problem_grasps(problem, obj), rng)
    for kind, T in offered:
        wps = _waypoints(geometry, world, arm, T, kind, rng, obj, hand_check=True)
        if wps is None:
            continue
        n += 1
        yield Candidate(wps, {step.args[3]: T.tolist()}, f"{kind} grasp, tool yaw {math.degrees(_yaw(T)):.0f} deg")
        if n >= limit:
            return


def move_base(problem, step, world, rng, limit: int = 6, tries: int = 60, grasps=None):
    to = step.args[0]
    geometry = problem.geometry
    info = geometry.refs.get(to)
    if info is None:  # bp_init
        yield Candidate((tuple(geometry.layout.base),), {to: list(geometry.layout.base)}, "the initial base pose")
        return
    skolem, args = info
    if skolem == "bpfg":
        yield from _bases_for_grasp(problem, world, args[0], args[1], to, rng, limit, tries, grasps)
    else:
        yield from _bases_for_putdown(problem, world, args[0], args[1], args[2], to, rng, limit, tries)


def _base_free(geometry, world, base, tuck=None) -> bool:
    """The robot at ``base`` clear of fixed obstacles; with ``tuck`` (an arm putting something down), also
    with that arm tucked and empty, as the put-down leaves it: the tucked elbow sticks out sideways."""
    w = replace(world, base=tuple(base))
    if not geometry.base_space.within_bounds(base):
        return False
    if tuck is not None and geometry.in_collision(replace(w, held={a: h for a, h in w.held.items() if a != tuck})
                                                  .with_arm(tuck, geometry.robot.home(tuck)), movables=False):
        return False
    return not geometry.in_collision(w, movables=False)


def _free_bases(geometry, world, arm, P, rng, tries, bearings=(), level=True):
    """The current base, then up to ``tries`` collision-free bases from which ``arm`` reaches the
    object at pose P (at most 20 samples each; a ``level`` grasp's, see reachmap.around), coming from
    one of ``bearings`` (any when empty): an object in a cubby leaves a narrow free sector, and IK, not
    this check, is what costs."""
    yield tuple(world.base)
    if not geometry.robot.mobile:  # a fixed base: where it stands is the only base pose; more grasps are tried there
        if _base_free(geometry, world, world.base):
            yield from (tuple(world.base) for _ in range(tries // 10))
        return
    free = 0
    for _ in range(20 * tries):
        base = around(geometry, arm, rng, *P[:3, 3], bearings, level)
        if _base_free(geometry, world, base):
            yield base
            free += 1
            if free >= tries:
                return


def _bases_for_grasp(problem, world, obj, arm, ref, rng, limit, tries, grasps=None):
    geometry = problem.geometry
    if world.holder(obj) is not None or world.held.get(arm):
        return
    check_graspable(problem, obj)
    P = world.objects[obj]
    x, y = P[0, 3], P[1, 3]
    kinds = _problem_grasps(problem, obj)
    # A stream of its own for each world: the loop seeds a step's generator alike whatever the steps
    # before it did, and bases that fail (a cubby leaves few) would fail again after every backtrack.
    rng = np.random.default_rng([int(rng.integers(2**32)), *stable_seed(world.base, sorted(world.held))])
    n = 0
    # side grasps: from where the arm reaches them, from the directions a side grasp comes from (a domain's
    # own grasps, top grasps: the annulus, any direction)
    side = "side" in kinds and not grasps and geometry.robot.mobile
    bearings = open_bearings(geometry, world, arm, obj, P) if side else ()
    for i, base in enumerate(_free_bases(geometry, world, arm, P, rng, tries, bearings, level=side)):
        if i == 0 and not _base_free(geometry, world, base):
            continue
        w = replace(world, base=base)
        heading = _bearing(base, x, y)
        for kind, T in (grasps(w, heading, rng) if grasps else grasp_poses(geometry, obj, P, heading, kinds, rng, n_side=2)):
            # few IK seeds: most grasps found come from the first, and another base is cheaper than more seeds
            wps = _waypoints(geometry, w, arm, T, kind, rng, obj, attempts=3 if geometry.robot.mobile else 10, hand_check=True)
            if wps is not None:
                n += 1
                # the grasp found here travels with the world to pick, which offers it first
                yield Candidate((base,), {ref: list(base), "grasp": (("grasp", obj, arm), (kind, T, wps))},
                                ("stay at " if i == 0 else "base at ") + _fmt(base))
                if n >= limit:
                    return
                break
    if not n:
        check_hand_fits(problem, world, obj)


def _heading_of_tool(T):
    return _yaw(T)


def _spots(problem, world, obj, loc, rng, tries):
    """Put-down poses of obj (upright, resting) in region loc, away from fixed obstacles; in the
    generic 'table' region also away from other objects and from every other named region."""
    geometry = problem.geometry
    o = geometry.specs[obj]
    xmin, xmax, ymin, ymax = geometry.layout.regions[loc]
    m = (o.size[0] if o.shape == "cylinder" else 0.5 * math.hypot(o.size[0], o.size[1])) + 0.01
    z = table_top(geometry.layout) + o.height / 2 + REST_GAP
    others = {k: v for k, v in geometry.layout.regions.items() if k not in (loc, "table")}
    if xmin + m > xmax - m or ymin + m > ymax - m:  # the object does not fit into the region
        return
    for _ in range(tries):
        x, y = rng.uniform(xmin + m, xmax - m), rng.uniform(ymin + m, ymax - m)
        if math.hypot(x - world.base[0], y - world.base[1]) > geometry.layout.extra.get("reach", 1.2):
            continue
        if loc == "table" and any(a - m <= x <= b + m and c - m <= y <= d + m for a, b, c, d in others.values()):
            continue
        P = pose4(x, y, z, 0.0)
        geometry.sync(world)  # the search may have synced another world between two draws
        hits = geometry.cw.objects_overlap(obj, P)
        if hits & geometry.fixed:
            continue
        if loc == "table":
            if hits or any(math.hypot(x - Q[0, 3], y - Q[1, 3]) < m + 0.06 for Q in world.objects.values()):
                continue
        yield float(x), float(y), float(z)


def _bases_for_putdown(problem, world, obj, arm, loc, ref, rng, limit, tries):
    geometry = problem.geometry
    if world.holder(obj) != arm:
        return
    G = world.held[arm][1]
    top = abs((G[:3, :3].T @ np.array([1.0, 0, 0]))[2]) > 0.7  # tool x along the object's axis: a top grasp
    geometry.sync(world)
    n = 0
    for x, y, z in _spots(problem, world, obj, loc, rng, tries):
        for _ in range(4):
            base = around(geometry, arm, rng, x, y, z, level=not top) if geometry.robot.mobile else tuple(world.base)
            if not _base_free(geometry, world, base, tuck=arm):
                continue
            P, T = _putdown(G, x, y, z, _bearing(base, x, y) + rng.uniform(-0.3, 0.3))
            w = replace(world, base=base)
            with geometry.tight():  # the put-down's own margin (see place)
                reached = geometry.ik(w, arm, T, rng, attempts=4) is not None
            if not reached:
                continue
            n += 1
            yield Candidate((base,), {ref: list(base), "tloc": (obj, P)},
                            f"base at {_fmt(base)} to put {obj} at {_fmt((x, y))}")
            if n >= limit:
                return
            break


def cleared_lowering(geometry, world, arm, obj, opened, lower, back):
    """A put-down's lowering and retreat (IK waypoints from the put-down outwards, found inside
    ``geometry.tight``) whose far ends clear the fully padded fixed obstacles, transits starting and ending
    there: the lowering (``obj`` held), extended if need be (``_extended_lowering``), or None."""
    if not line_ends_clear(geometry, world.with_gripper(arm, opened), arm, (back[-1],), (obj,)):
        return None
    return _extended_lowering(geometry, world, arm, lower)


def _extended_lowering(geometry, world, arm, lower):
    """``lower``, or, when the hand LIFT above the spot is too close to a fixed obstacle for a transit to end
    there (beside a wall taller than the hand), ``lower`` continued back along the tool's approach axis by
    PRE_GRASP, as a pick's approach comes in; None if that end is not clear either."""
    if line_ends_clear(geometry, world, arm, (lower[-1],)):
        return lower
    q = geometry.sync(world.with_arm(arm, lower[-1]))
    U = geometry.robot.tool_pose(q, arm)
    with geometry.tight():
        back = _line(geometry, world, arm, U, lambda d: U @ trans(-d, 0, 0), PRE_GRASP, lower[-1],
                     np.random.default_rng(0), splits=2)
    if back is None or not line_ends_clear(geometry, world, arm, (back[-1],)):
        return None
    return [*lower, *back[1:]]


def _putdown(G, x, y, z, tool_heading):
    """Object pose at (x, y, z) and tool pose for grasp G such that the tool faces ``tool_heading``."""
    P0 = pose4(x, y, z, 0.0)
    T0 = P0 @ np.linalg.inv(G)
    yaw = wrap(tool_heading - _heading_of_tool(T0))
    P = pose4(x, y, z, yaw)
    return P, P @ np.linalg.inv(G)


def place(problem, step, world, rng, variants: int = 4):
    obj, arm, loc = step.args[0], step.args[1], step.args[2]
    geometry = problem.geometry
    if world.holder(obj) != arm:
        return
    G = world.held[arm][1]
    xmin, xmax, ymin, ymax = geometry.layout.regions[loc]
    spots = []
    if obj in world.tloc:
        P = np.asarray(world.tloc[obj])
        x, y, z = P[:3, 3]
        spots.append((x, y, z, _heading_of_tool(P @ np.linalg.inv(G))))
        for _ in range(variants):
            dx, dy = rng.uniform(-0.02, 0.02, size=2) if loc != "table" else rng.uniform(-0.03, 0.03, size=2)
            spots.append((float(np.clip(x + dx, xmin, xmax)), float(np.clip(y + dy, ymin, ymax)), z,
                          spots[0][3] + rng.uniform(-0.3, 0.3)))
    else:  # no spot chosen by move_base (e.g. a custom plan): sample one
        for x, y, z in _spots(problem, world, obj, loc, rng, 40):
            spots.append((x, y, z, _bearing(world.base, x, y)))
            if len(spots) > variants:
                break
    opened = geometry.opening(obj, G)
    for x, y, z, heading in spots:
        P, T = _putdown(G, x, y, z, heading)
        top = abs(T[2, 0]) > 0.7
        back_at = (lambda d: trans(0, 0, d) @ T) if top else (lambda d: T @ trans(-d, 0, 0))
        with geometry.tight():  # the put-down and its lines keep LINE_PADDING from fixed obstacles (not yielding here)
            put = geometry.ik(world, arm, T, rng, attempts=6)
            if put is not None:
                lower = _line(geometry, world, arm, T, lambda d: trans(0, 0, d) @ T, LIFT, put, rng)
                back = _line(geometry, world.with_gripper(arm, opened), arm, T, back_at, PRE_GRASP, put, rng, gripper=opened)
        if put is None or lower is None or back is None:
            continue
        lower = cleared_lowering(geometry, world, arm, obj, opened, lower, back)
        if lower is None:
            continue
        yield Candidate((tuple(reversed(lower)), tuple(back[1:])), {step.args[4]: T.tolist(), "object_pose": P.tolist()},
                        f"{obj} at {_fmt((x, y))}")


def _fmt(p):
    return "(" + ", ".join(f"{v:.2f}" for v in p) + ")"
