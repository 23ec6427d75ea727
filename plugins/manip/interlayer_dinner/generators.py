"""Pose generators of the Dinner domain: functions of (problem, step, world, rng), no other state.

Every manipulation candidate is (base pose, arm path 1, arm path 2): the refinement drives there
(OMPL in SE(2)) and then moves the arm. Places are fixed (a place setting, a tray slot, the top of
the lower object): only the base pose, the tool's heading and the grasp kind are sampled.

* ``dinner:go``: base poses near the other room's home pose, free of fixed obstacles (with the
  carried tray, if any).
* ``dinner:pick`` (pick, take_off_tray, unstack): ``pr2``'s base-for-grasp sampler, then its grasp.
* ``dinner:place`` (place, put_on_tray, stack): for stack, the stackability module first (a violation
  is one candidate that fails as "unstackable"); then base poses in an annulus around the place with
  IK for the put-down, its lowering and the retreat.
* ``dinner:pick_tray``: base poses facing the tray's near edge, both hands' approaches by IK.
* ``dinner:place_tray``: the base pose that puts the carried tray at the table's tray spot (jittered)
  and both hands' retreats.
* ``dinner:handoff``: where the robot stands, a hand-over pose of the object in front of its chest
  (jittered), the holding hand's IK there, the other hand's grasp and straight approach, the holding
  hand's retreat.
"""
from __future__ import annotations

import math
from dataclasses import replace

import numpy as np

from interlayer.refine import Candidate
from interlayer_manip.generators import _base_free, _bearing, _fmt, _line, _problem_grasps, _putdown, _waypoints, grasp_poses
from interlayer_manip.state import LIFT, PRE_GRASP, pose4, trans, wrap

from .scene import HOME, TRAY, near_base, tray_spot
from .stacking import stackable
from .world import TRAY_GRIP, base_matrix

EDGE_IN = 0.02  # the tool's centre this far inside the tray's near edge
HAND_Y = 0.14  # each hand this far from the tray's centre line
PRE_TRAY = 0.10  # approach to / retreat from the tray's edge along the tool x axis
ROLL = np.array([[1, 0, 0, 0], [0, 0, -1, 0], [0, 1, 0, 0], [0, 0, 0, 1.0]])  # fingers closing vertically


def go(problem, step, world, rng, limit: int = 6, tries: int = 60):
    geometry = problem.geometry
    hx, hy, ht = HOME[step.args[1]]
    n = 0
    for k in range(tries):
        base = (hx, hy, float(wrap(ht))) if k == 0 else (hx + float(rng.uniform(-0.25, 0.25)), hy + float(rng.uniform(-0.4, 0.4)),
                                            float(wrap(ht + rng.uniform(-0.5, 0.5))))
        if _base_free(geometry, world, base):
            n += 1
            yield Candidate((base,), {}, f"base at {_fmt(base)} in {step.args[1]}")
            if n >= limit:
                return


def pick(problem, step, world, rng, limit: int = 4, tries: int = 60):
    """Base poses in front of the object, then each grasp (side, top) whose straight approach runs into
    no other object (neighbours on a table or the tray block side grasps; the domain learns no
    obstructions)."""
    geometry = problem.geometry
    obj, arm = step.args[0], step.args[1]
    if world.holder(obj) is not None or world.held.get(arm):
        return
    P = world.objects[obj]
    x, y = P[0, 3], P[1, 3]
    n = 0
    for i, base in enumerate([tuple(world.base)] + [near_base(rng, x, y) for _ in range(tries)]):
        if not _base_free(geometry, world, base):
            continue
        w = replace(world, base=base)
        for kind, T in grasp_poses(geometry, obj, P, _bearing(base, x, y), _problem_grasps(problem, obj), rng, n_side=2):
            wps = _waypoints(geometry, w, arm, T, kind, rng, obj)
            if wps is None:
                continue
            with geometry.stats.timer("collision_checking"):  # the approach must be clear: nothing to learn here
                opened = geometry.grasp_opening(w, arm, obj, wps[0][-1])
                blocked = geometry._movables_on_line(w.with_gripper(arm, opened), arm, wps[0], [0.0]) - {obj}
            if blocked:
                continue
            n += 1
            yield Candidate((base, *wps), {}, f"{'stay at' if i == 0 else 'base at'} {_fmt(base)}, {kind} grasp")
            if n >= limit:
                return
            break


def target_pose(geometry, step, world):
    action = step.action.removesuffix("_cross")
    obj = step.args[0]
    if action == "place":
        return geometry.setting_pose(obj)
    return geometry.stack_pose(world, obj, step.args[2])


def place(problem, step, world, rng, limit: int = 4, tries: int = 60):
    geometry = problem.geometry
    obj, arm = step.args[0], step.args[1]
    if world.holder(obj) != arm:
        return
    if step.action.startswith("stack"):
        verdict = stackable(geometry.specs[obj], geometry.specs[step.args[2]], geometry.kinds)
        if not verdict.ok:  # the stackability module says no: one candidate, refined as that failure
            pairs = violations(geometry, obj, step.args[2])
            yield Candidate((), {"unstackable": verdict.reason, "pairs": pairs}, f"unstackable: {verdict.reason}")
            return
    if step.action.startswith("put_on_tray"):  # the first free slots, nearest the robot first
        for slot in geometry.free_slots(world)[:2]:
            yield from _put(problem, step, world, rng, geometry.slot_pose(world, slot, obj), {"slot": slot}, limit, tries)
        return
    yield from _put(problem, step, world, rng, target_pose(geometry, step, world), {}, limit, tries)


def _put(problem, step, world, rng, P, values, limit, tries):
    geometry = problem.geometry
    obj, arm = step.args[0], step.args[1]
    G = world.held[arm][1]
    x, y, z = (float(v) for v in P[:3, 3])
    n = 0
    for _ in range(tries):
        base = near_base(rng, x, y)
        if not _base_free(geometry, world, base, tuck=arm):
            continue
        Q, T = _putdown(G, x, y, z, _bearing(base, x, y) + rng.uniform(-0.3, 0.3))
        w = replace(world, base=base)
        put = geometry.ik(w, arm, T, rng, attempts=4)
        if put is None:
            continue
        lower = _line(geometry, w, arm, T, lambda d: trans(0, 0, d) @ T, LIFT, put, rng)
        top = abs(T[2, 0]) > 0.7
        back_at = (lambda d: trans(0, 0, d) @ T) if top else (lambda d: T @ trans(-d, 0, 0))
        opened = geometry.opening(obj, G)
        back = _line(geometry, w.with_gripper(arm, opened), arm, T, back_at, PRE_GRASP, put, rng, gripper=opened)
        if lower is None or back is None:
            continue
        n += 1
        yield Candidate((base, tuple(reversed(lower)), tuple(back[1:])), {"tloc": (obj, Q), **values},
                        f"base at {_fmt(base)}, {obj} at {_fmt((x, y, z))}")
        if n >= limit:
            return


def violations(geometry, upper, lower) -> tuple:
    """The stack references the module rules out once it has measured ``upper`` and ``lower``: ``upper``
    on any object, and any object on ``lower``."""
    names = [n for n in geometry.specs if geometry.kinds.get(n) != "tray"]
    pairs = {(upper, x) for x in names} | {(x, lower) for x in names}
    return tuple(sorted(f"sp_{u}_{lo}" for u, lo in pairs if u != lo
                        and not stackable(geometry.specs[u], geometry.specs[lo], geometry.kinds).ok))


def tray_grips(P) -> dict:
    """Tool poses of both hands on the near edge of the tray at pose P (tool x into the tray)."""
    return {arm: P @ trans(-TRAY[0] / 2 + EDGE_IN, s * HAND_Y, 0.0) @ ROLL for arm, s in (("left", 1), ("right", -1))}


def _base_of(B) -> tuple:
    return (float(B[0, 3]), float(B[1, 3]), float(math.atan2(B[1, 0], B[0, 0])))


def pick_tray(problem, step, world, rng, limit: int = 4, tries: int = 40):
    geometry = problem.geometry
    P = world.objects["tray"]
    grips = tray_grips(P)
    n = 0
    for k in range(tries):
        d, dy, dyaw = (0.68, 0.0, 0.0) if k == 0 else (rng.uniform(0.58, 0.78), rng.uniform(-0.08, 0.08), rng.uniform(-0.2, 0.2))
        base = _base_of(P @ trans(-d, dy, 0.0) @ pose4(0, 0, 0, dyaw))
        if not _base_free(geometry, world, base):
            continue
        w = replace(world, base=base)
        lines = []
        for arm in ("left", "right"):  # the right arm's IK with the left hand already on the tray
            T = grips[arm]
            g = geometry.ik(w, arm, T, rng, ignore=("tray",), gripper="open", attempts=6)
            line = g is not None and _line(geometry, w, arm, T, lambda s, T=T: T @ trans(-s, 0, 0), PRE_TRAY, g, rng,
                                           ("tray",), "open")
            if not line:
                break
            lines.append(tuple(reversed(line)))
            w = w.with_arm(arm, line[0]).with_gripper(arm, TRAY_GRIP)
        if len(lines) == 2 and not geometry.in_collision(w):
            n += 1
            yield Candidate((base, *lines), {}, f"base at {_fmt(base)} facing the tray")
            if n >= limit:
                return


def place_tray(problem, step, world, rng, limit: int = 4, tries: int = 30):
    geometry = problem.geometry
    rel = world.carrying.get("tray")
    if rel is None:
        return
    x, y, z, yaw = tray_spot(step.args[0])
    q = geometry.config(world)
    B0inv = np.linalg.inv(base_matrix(world.base))
    tools = {arm: B0inv @ geometry.robot.tool_pose(q, arm) for arm in ("left", "right")}  # they stay in the base frame
    n = 0
    for k in range(tries):
        dx, dy, dyaw = (0.0, 0.0, 0.0) if k == 0 else (rng.uniform(-0.01, 0.02), rng.uniform(-0.05, 0.05), rng.uniform(-0.1, 0.1))
        P = pose4(x + dx * math.cos(yaw), y + dy, z, yaw + dyaw)
        base = _base_of(P @ np.linalg.inv(rel))
        w = replace(world, base=base)
        tucked = replace(w, objects={**w.objects, **{k: base_matrix(base) @ r for k, r in world.carrying.items()}},
                         carrying={}, arms={a: geometry.robot.home(a) for a in geometry.robot.arms},
                         grippers={"left": "closed", "right": "closed"})
        if not geometry.base_space.within_bounds(base) or geometry.in_collision(w) or geometry.in_collision(tucked):
            continue
        B = base_matrix(base)
        backs = []
        for arm in ("left", "right"):
            T = B @ tools[arm]
            line = _line(geometry, w.with_gripper(arm, "open"), arm, T, lambda s, T=T: T @ trans(-s, 0, 0), PRE_TRAY,
                         np.asarray(world.arms[arm]), rng, ("tray",), "open")
            if not line:
                break
            backs.append(tuple(line))
        if len(backs) == 2:
            n += 1
            yield Candidate((base, *backs), {}, f"base at {_fmt(base)}: the tray at {_fmt((P[0, 3], P[1, 3]))}")
            if n >= limit:
                return



HANDOVER = (0.55, 0.0, 1.05)  # the object's centre in the base frame: in front of the chest, above the tables
HANDOVER_DROP = 0.005  # a side grasp of an object held from above: this far below its centre
HANDOVER_LINE = 0.10  # approach and retreat length at the hand-over (PRE_GRASP's 0.20 rarely has IK so close)


def handoff(problem, step, world, rng, limit: int = 4, tries: int = 30):
    geometry = problem.geometry
    obj, src, dst = step.args
    if world.holder(obj) != src or world.held.get(dst):
        return
    G = world.held[src][1]
    B, yaw = base_matrix(world.base), world.base[2]
    s = 1.0 if dst == "left" else -1.0  # the holding hand points towards the receiving side, which reaches across
    top_held = abs((G[:3, :3].T @ np.array([1.0, 0, 0]))[2]) > 0.7  # the holding hand covers the object's top
    kinds = ("side",) if top_held else tuple(k for k in _problem_grasps(problem, obj) if k in ("side", "top"))
    n = 0
    for k in range(tries):
        d = np.zeros(3) if k == 0 else rng.uniform(-0.08, 0.08, size=3)
        x, y, z = (B @ np.array([*(np.add(HANDOVER, d)), 1.0]))[:3]
        P, T = _putdown(G, x, y, z, yaw + s * rng.uniform(0.2, 0.8))
        hold = geometry.ik(world, src, T, rng, movables=True, seed=world.arms[src], attempts=4)
        if hold is None:
            continue
        w = world.with_arm(src, hold)
        # the receiving hand comes from its own side
        offered = grasp_poses(geometry, obj, P, yaw - s * rng.uniform(0.9, 1.5), kinds, rng, n_side=3)
        if top_held:  # below the holding fingers, which swing out when they open
            offered = [(kind, trans(0, 0, -HANDOVER_DROP) @ Tg) for kind, Tg in offered]
        for kind, Tg in offered:
            grasp = geometry.ik(w, dst, Tg, rng, movables=True, ignore=(obj,), gripper="open", attempts=4)
            line = grasp is not None and _line(geometry, w, dst, Tg, lambda e, Tg=Tg: Tg @ trans(-e, 0, 0),
                                               HANDOVER_LINE, grasp, rng, (obj,), "open")
            if not line:
                continue
            handed = replace(w.with_arm(dst, grasp), held={dst: (obj, np.linalg.inv(Tg) @ P)},
                             grippers={src: "open", dst: "closed"})
            if geometry.in_collision(handed):  # the opening fingers of the holding hand swing into the other hand
                continue
            back_at = (lambda e: trans(0, 0, e) @ T) if top_held else (lambda e: T @ trans(-e, 0, 0))
            back = _line(geometry, handed, src, T, back_at, HANDOVER_LINE, hold, rng, (obj,), "open")
            if not back:
                continue
            n += 1
            yield Candidate((tuple(hold), tuple(reversed(line)), tuple(back)), {},
                            f"{obj} handed over at {_fmt((x, y, z))}, {kind} grasp by the {dst} hand")
            if n >= limit:
                return
            break
