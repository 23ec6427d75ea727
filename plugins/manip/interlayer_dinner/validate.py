"""The Dinner domain's additions to the PR2 validator (``interlayer_manip.validate``, ``rules``): what a
released object rests on (a table, the tray, or a cup or bowl it fits on, by the stackability module),
the carried tray (everything resting on it is carried with it, nothing moves relative to it, only the
base moves meanwhile), and the goal (every object at its place setting)."""
from __future__ import annotations

import math
from dataclasses import replace

import numpy as np

from interlayer_manip.scene import REST_GAP
from interlayer_manip.validate import _inside, _pose_close, upright
from interlayer_manip.state import is_open

from .scene import TOP, TRAY
from .stacking import stackable
from .world import base_matrix

TOL = 0.005
SETTING_TOL = 0.02


def support_of(geometry, objects, obj, P):
    """(what obj at P rests on, '' or why not): a table, the tray or another object."""
    if not upright(P):
        return None, "not upright"
    bottom = P[2, 3] - geometry.specs[obj].height / 2
    x, y = P[0, 3], P[1, 3]
    for f in geometry.layout.fixed:
        if f.name.endswith("table"):
            (cx, cy), (sx, sy) = f.pose[:2], f.size[:2]
            if abs(x - cx) <= sx / 2 and abs(y - cy) <= sy / 2 and 0 <= bottom - TOP <= REST_GAP + TOL:
                return f.name, ""
    for name, Q in objects.items():
        if name == obj:
            continue
        top = Q[2, 3] + geometry.specs[name].height / 2
        if not 0 <= bottom - top <= REST_GAP + TOL:
            continue
        local = np.linalg.inv(Q) @ np.array([x, y, Q[2, 3], 1.0])
        if name == "tray":
            if abs(local[0]) <= TRAY[0] / 2 and abs(local[1]) <= TRAY[1] / 2:
                return name, ""
        elif math.hypot(local[0], local[1]) <= geometry.specs[name].size[0]:
            verdict = stackable(geometry.specs[obj], geometry.specs[name], geometry.kinds)
            return (name, "") if verdict.ok else (name, f"on {name}, which it does not fit: {verdict.reason}")
    return None, "resting on nothing (not on a table, the tray or an object it fits on)"


def rests(geometry, world, obj, P) -> str:
    _, why = support_of(geometry, world.objects, obj, P)
    return why


def riders(geometry, objects, support) -> set:
    """Objects resting on ``support``, directly or on each other."""
    out, frontier = set(), {support}
    while frontier:
        found = {o for o, P in objects.items() if o not in out and o != support
                 and support_of(geometry, objects, o, P)[0] in frontier}
        out |= found
        frontier = found
    return out


def motion(geometry, world, seg, at) -> str:
    if world.carrying and seg.get("group") != "base":
        return f"{at}: the {seg.get('group')} moves while both hands carry the tray"
    return ""


def event(geometry, world, seg, at):
    kind = seg.get("kind")
    robot = geometry.robot
    if kind == "carry":
        names = list(seg.get("objects") or [])
        if "tray" not in names or "tray" not in world.objects:
            return world, f"{at}: carries {names}, not the resting tray"
        q = geometry.config(world)
        P = world.objects["tray"]
        for arm in ("left", "right"):
            width = world.grippers[arm]
            if isinstance(width, str) or arm in world.held:
                return world, f"{at}: the {arm} gripper is {width}, not closed around the tray's edge"
            tool_in_tray = (np.linalg.inv(P) @ robot.tool_pose(q, arm))[:3, 3]
            if not _inside(geometry.specs["tray"], tool_in_tray):
                return world, f"{at}: the {arm} gripper is not at the tray ({np.round(tool_in_tray, 3).tolist()} in its frame)"
        on_tray = riders(geometry, world.objects, "tray")
        left = sorted(on_tray - set(names))
        if left:
            return world, f"{at}: {', '.join(left)} rest(s) on the tray but is not carried with it (it would fall off)"
        extra = sorted(set(names) - on_tray - {"tray"})
        if extra:
            return world, f"{at}: {', '.join(extra)} is carried with the tray but does not rest on it"
        Binv = np.linalg.inv(base_matrix(world.base))
        return replace(world, objects={k: v for k, v in world.objects.items() if k not in names},
                       carrying={k: Binv @ world.objects[k] for k in names}), ""
    if kind == "set_down":
        poses = {k: np.asarray(v, float) for k, v in (seg.get("objects") or {}).items()}
        if set(poses) != set(world.carrying):
            return world, f"{at}: sets down {sorted(poses)} but carries {sorted(world.carrying)}"
        B = base_matrix(world.base)
        for name, rel in world.carrying.items():
            if not _pose_close(B @ rel, poses[name]):
                return world, f"{at}: {name} is set down away from where the carried tray held it (it moved on the tray)"
        objects = {**world.objects, **poses}
        support, why = support_of(geometry, objects, "tray", poses["tray"])
        if why or support not in ("side_table", "dinner_table"):
            return world, f"{at}: the tray is set down {why or 'on ' + str(support)}, not on a table"
        w = replace(world, objects=objects, carrying={})
        if geometry.in_collision(w):
            return world, f"{at}: the tray is set down into a collision"
        return w, ""
    if kind == "handover":
        return handover(geometry, world, seg, at)
    return world, f"{at}: unknown segment kind {kind!r}"


def handover(geometry, world, seg, at):
    """One hand closes on the object the other holds (where it holds it), the other opens."""
    robot = geometry.robot
    obj, src, dst = seg.get("object"), seg.get("from"), seg.get("to")
    if world.held.get(src, (None,))[0] != obj or src == dst:
        return world, f"{at}: hands {obj} over from the {src} arm, which holds {world.held.get(src, ('nothing',))[0]}"
    if dst in world.held or not is_open(world.grippers.get(dst)):
        return world, f"{at}: the {dst} gripper takes {obj} but is not open and empty"
    q = geometry.config(world)
    G = np.asarray(seg.get("grasp"), float)
    if not _pose_close(robot.tool_pose(q, dst) @ G, robot.tool_pose(q, src) @ world.held[src][1]):
        return world, f"{at}: {obj} is not at the {dst} gripper (the claimed grasp does not put it where the {src} hand holds it)"
    if not _inside(geometry.specs[obj], np.linalg.inv(G)[:3, 3]):
        return world, f"{at}: the {dst} tool frame is outside {obj}: not a grasp"
    if geometry.grasp_width(obj, G) > robot.max_gripper_opening:
        return world, f"{at}: {obj} is wider than the {dst} gripper opens"
    w = replace(world, held={dst: (obj, G), **{a: v for a, v in world.held.items() if a != src}},
                grippers={**world.grippers, dst: "closed", src: "open"})
    if geometry.in_collision(w):
        return world, f"{at}: the handover of {obj} collides"
    return w, ""


def goal(geometry, world) -> list:
    errors = []
    if world.carrying:
        errors.append("goal not satisfied: the tray is still carried at the end")
    for obj, (x, y) in geometry.layout.extra["settings"].items():
        P = world.objects.get(obj)
        if P is None:
            errors.append(f"goal not satisfied: {obj} is held at the end")
            continue
        support, _ = support_of(geometry, world.objects, obj, P)
        if support != "dinner_table" or math.hypot(P[0, 3] - x, P[1, 3] - y) > SETTING_TOL:
            errors.append(f"goal not satisfied: {obj} rests at ({P[0, 3]:.3f}, {P[1, 3]:.3f}) on {support}, "
                          f"not at its setting ({x:.3f}, {y:.3f})")
    return errors
