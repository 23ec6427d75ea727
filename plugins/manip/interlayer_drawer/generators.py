"""Pose generators of the Drawer domain: functions of (problem, step, world, rng), no other state.

* ``drawer:move_base`` instantiates ``bpfo_<drawer>_<arm>`` with base poses in front of / beside the
  drawer from which IK reaches the handle (the grasp travels with the world to open_drawer); other
  base-pose references go to ``pr2:move_base``, except that a grasp of an object still unexposed in
  its drawer yields nothing at once.
* ``drawer:open_drawer`` draws PULLS random pull distances within the joint's limits and the arm's reach
  (stratified: one from each of PULLS equal slices, in random order), keeps those that expose what
  rides in the drawer for a top grasp, and builds, by IK, the approach to the handle, the straight pull
  with the gripper on it, and the retreat.
* ``drawer:pick`` is ``pr2:pick`` for objects that a top grasp can reach (see ``check.exposed``).
"""
from __future__ import annotations

import math
from dataclasses import replace

import numpy as np

from interlayer.refine import Candidate
from interlayer_manip import generators as pr2
from interlayer_manip.state import rz, trans

from .check import exposed
from .world import CABINET, DRAWER_LINK, HANDLE_GRIP, HANDLE_LINK

PULLS = 10
PULL_STEP = 0.02  # m between IK waypoints of the pull (the gripper keeps ~5 mm off the bar between them)
PRE_HANDLE = 0.10  # the approach to the handle starts this far back along the tool x axis
RETREAT = 0.05  # the open gripper backs off the bar this far after the pull (the fingertips clear it)
LIFT = 0.10  # ... and lifts it this far
MIN_PULL = 0.03
MAX_JUMP = 0.5  # rad: a longer joint-space step between two IK waypoints is a different IK branch


def handle_pose(geometry, values) -> np.ndarray:
    """The tool pose on the handle bar's centre (tool x into the cabinet, fingers either side of the bar)."""
    from .scene import HANDLE_OUT, HANDLE_Z

    return geometry.cabinet.link_pose(values, HANDLE_LINK) @ trans(-HANDLE_OUT, 0, HANDLE_Z)


def reachable(geometry, world, obj) -> bool:
    """False if obj rides in the drawer and no top grasp clears the cabinet at the current pull."""
    if obj not in world.riders:
        return True
    body = geometry.cabinet
    d = world.joints[CABINET]
    P0 = body.carry(world.objects[obj], DRAWER_LINK, d, body.zero())
    return bool(exposed(body, d[0], P0, pad=geometry.padding))


def move_base(problem, step, world, rng, limit: int = 6, tries: int = 400):
    geometry = problem.geometry
    info = geometry.refs.get(step.args[0])
    if info is not None and info[0] == "bpfo":
        yield from _bases_for_handle(geometry, world, info[1][0], info[1][1], step.args[0], rng, limit, tries)
        return
    if info is not None and info[0] == "bpfg" and info[1][0] in world.riders:
        obj = info[1][0]
        if not reachable(geometry, world, obj):
            # no grasp yet (the drawer is not open far enough): stay, and let pick find nothing
            yield Candidate((tuple(world.base),), {step.args[0]: list(world.base)}, f"stay ({obj} not exposed)")
            return
        yield from pr2.move_base(problem, step, world, rng, grasps=_rider_grasps(geometry, obj))
        return
    yield from pr2.move_base(problem, step, world, rng)


def _rider_grasps(geometry, obj):
    """Top grasps of an object in the drawer that clear the cabinet (check.exposed), for pr2's samplers."""
    def grasps(world, heading, rng):
        body = geometry.cabinet
        d = world.joints[CABINET]
        P0 = body.carry(world.objects[obj], DRAWER_LINK, d, body.zero())
        yaws = [heading + a for a in np.linspace(0.0, math.pi, 6, endpoint=False)]
        return [("top", T) for T in exposed(body, d[0], P0, pad=geometry.padding, yaws=yaws)]

    return grasps


def _bases_for_handle(geometry, world, drawer, arm, ref, rng, limit, tries):
    """Base poses (out of the way of the fully open drawer) with an IK solution on the handle, those from
    which the arm can pull the drawer farthest first; the grasp and its pull path go to open_drawer."""
    if world.held.get(arm):
        return
    d0 = [float(v) for v in world.joints[CABINET]]
    H = handle_pose(geometry, d0)
    hx, hy = H[0, 3], H[1, 3]
    body = geometry.cabinet
    sweep = [geometry.with_joints(world, CABINET, [d]) for d in np.linspace(d0[0], body.upper[0], 9)[1:]]
    found = []
    for _ in range(tries):
        # in front of the handle or beside the cabinet (away from the wall behind it)
        r, a = rng.uniform(0.45, 0.85), math.pi + rng.uniform(-1.6, 1.6)
        bx, by = hx + r * math.cos(a), hy + r * math.sin(a)
        base = (float(bx), float(by), float(pr2.wrap(math.atan2(hy - by, hx - bx) + rng.uniform(-0.4, 0.4))))
        # out of the drawer's way: free (arms tucked) wherever the drawer may be pulled
        if not (pr2._base_free(geometry, world, base) and all(pr2._base_free(geometry, s, base) for s in sweep)):
            continue
        w = replace(world, base=base)
        T = H @ rz(rng.uniform(-0.4, 0.4))  # any yaw about the vertical bar grips it
        v = geometry.ik(w.with_gripper(arm, "open"), arm, T, rng, attempts=4)
        approach = None if v is None else _approach(geometry, w, arm, T, v, rng)
        if approach is None:
            continue
        path = _pull_path(geometry, w.with_gripper(arm, HANDLE_GRIP), arm, T, v, d0[0], float(geometry.cabinet.upper[0]), rng)
        if path[-1][-1] - d0[0] < MIN_PULL:
            continue
        found.append((base, T, path, approach))
        if len(found) >= 2 * limit:
            break
    # the inner object's place decides where to stand: first the bases from which the other arm (or
    # this one) also reaches what rides in the drawer at the most pull distances, then the longest pulls
    ranked = sorted(((_reach_riders(geometry, world, base, path, rng), path[-1][-1], i, base, T, path, approach)
                     for i, (base, T, path, approach) in enumerate(found)), key=lambda f: (-f[0], -f[1], f[2]))
    for n, dmax, _, base, T, path, approach in ranked[:limit]:
        yield Candidate((base,), {ref: list(base), "grasp": (("handle", drawer, arm), (T, path, approach))},
                        f"base at {pr2._fmt(base)} for the handle (pulls up to {dmax:.2f} m, reaches the drawer's "
                        f"contents at {n} of {len(REACH_PULLS)} pulls)")


REACH_PULLS = (0.1, 0.2, 0.3, 0.4)


def _reach_riders(geometry, world, base, path, rng) -> int:
    """At how many of REACH_PULLS (up to the pull the path reaches) some arm reaches a top grasp of
    every object riding in the drawer from ``base`` (IK, fixed obstacles)."""
    body = geometry.cabinet
    riders = [o for o, (b, _) in world.riders.items() if b == CABINET and o in world.objects]
    if not riders:
        return 0
    d0 = world.joints[CABINET]
    n = 0
    for d in REACH_PULLS:
        if d > path[-1][-1] + 1e-9:
            break
        w = replace(geometry.with_joints(world, CABINET, [d]), base=base)
        ok = True
        for o in riders:
            P0 = body.carry(world.objects[o], DRAWER_LINK, d0, body.zero())
            grasps = exposed(body, d, P0, pad=geometry.padding, yaws=(0.0, math.pi / 2))
            if not any(geometry.ik(w.with_gripper(a, geometry.opening(o, np.linalg.inv(T) @ w.objects[o])), a, T, rng,
                                   ignore=(o,), attempts=2) is not None for T in grasps for a in geometry.robot.arms):
                ok = False
                break
        n += ok
    return n


def open_drawer(problem, step, world, rng, limit: int = PULLS):
    geometry = problem.geometry
    drawer, arm, hg_ref, pull_ref = step.args[0], step.args[1], step.args[3], step.args[4]
    if world.held.get(arm):
        return
    body = geometry.cabinet
    d0 = float(world.joints[CABINET][0])
    planned = world.tloc.get(("handle", drawer, arm))
    if planned is None:  # no base chosen for this handle grasp (a custom plan): try from here
        T = handle_pose(geometry, [d0])
        v = geometry.ik(world.with_gripper(arm, "open"), arm, T, rng, attempts=8)
        if v is None:
            return
        approach = _approach(geometry, world, arm, T, v, rng)
        if approach is None:
            return
        path = _pull_path(geometry, world.with_gripper(arm, HANDLE_GRIP), arm, T, v, d0, float(body.upper[0]), rng)
    else:
        T, path, approach = planned
    lo, hi = d0 + MIN_PULL, float(path[-1][-1])  # bounded by the joint's limit and by the arm's reach
    if hi <= lo:
        return
    edges = np.linspace(lo, hi, limit + 1)
    pulls = [float(rng.uniform(a, b)) for a, b in zip(edges, edges[1:])]
    riders = [o for o, (b, _) in world.riders.items() if b == CABINET and o in world.objects]
    for d in (pulls[i] for i in rng.permutation(len(pulls))):
        wd = geometry.with_joints(world, CABINET, [d])
        if not all(reachable(geometry, wd, o) for o in riders):
            continue  # the drawer is opened to take out what is in it
        k = max(i for i, p in enumerate(path) if p[-1] <= d + 1e-9)
        Td = body.carry(T, HANDLE_LINK, [d0], [d])
        u = geometry.ik(world.with_gripper(arm, HANDLE_GRIP), arm, Td, rng, seed=path[k][:7], attempts=2)
        if u is None or geometry.arm_space[arm].distance(u, path[k][:7]) > MAX_JUMP:
            continue
        pull = [*path[:k + 1], np.append(u, d)] if d - path[k][-1] > 1e-6 else path[:k + 1]
        wd = wd.with_gripper(arm, "open")
        back = pr2._line(geometry, wd, arm, Td, lambda s: Td @ trans(-s, 0, 0), RETREAT, u, rng, (), "open")
        if back is None:
            continue
        Tb = Td @ trans(-RETREAT, 0, 0)  # then up, clear of the drawer, so that the arm can tuck
        up = pr2._line(geometry, wd, arm, Tb, lambda s: trans(0, 0, s) @ Tb, LIFT, back[-1], rng, (), "open")
        retreat = back + up[1:] if up is not None else back
        yield Candidate((approach, tuple(pull), tuple(retreat)), {pull_ref: d, hg_ref: T.tolist()}, f"pull {d:.3f} m")


def _approach(geometry, world, arm, T, v, rng):
    """IK waypoints from PRE_HANDLE behind the handle grasp T to T (arm vector v there), or None."""
    wo = world.with_gripper(arm, "open")
    back = pr2._line(geometry, wo, arm, T, lambda s: T @ trans(-s, 0, 0), PRE_HANDLE, v, rng, (), "open")
    if back is None or not geometry.static_path_ok(wo, arm, back):
        return None
    return tuple(reversed(back))


def _pull_path(geometry, world, arm, T, v, d0, d, rng):
    """Arm vectors (each with the drawer's joint value appended) keeping the tool at T on the handle
    while the drawer slides from d0 towards d; IK at every PULL_STEP, each seeded by the previous one.
    Ends where IK first fails (at least the start)."""
    body, space = geometry.cabinet, geometry.arm_space[arm]
    n = max(1, math.ceil((d - d0) / PULL_STEP - 1e-9))
    out = [np.append(v, d0)]
    for k in range(1, n + 1):
        dk = d0 + (d - d0) * k / n
        u = geometry.ik(world, arm, body.carry(T, HANDLE_LINK, [d0], [dk]), rng, seed=out[-1][:7], attempts=2)
        if u is None or space.distance(u, out[-1][:7]) > MAX_JUMP:
            break
        out.append(np.append(u, dk))
    return out


def pick(problem, step, world, rng):
    obj = step.args[0]
    if obj not in world.riders:
        yield from pr2.pick(problem, step, world, rng)
    elif reachable(problem.geometry, world, obj):
        yield from pr2.pick(problem, step, world, rng, grasps=_rider_grasps(problem.geometry, obj))


__all__ = ["move_base", "open_drawer", "pick"]
