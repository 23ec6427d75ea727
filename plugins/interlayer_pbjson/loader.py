"""The pybullet-planning JSON problem format (bodies / robots / task): see that repository's problems/json.

``load_pybullet_json`` reads a file (scene.py), builds the PR2 layout and the ``pr2-pbjson`` task
(domain.py) over it, and maps every goal kind to task-level goals over pose references.
"""
from __future__ import annotations

import json
import logging
import math
import sys

import numpy as np

from interlayer.domain import Problem
from interlayer.errors import UserError
from interlayer_manip.scene import Layout

from .domain import SLOTS, pbjson_domain
from .scene import area, read_scene, top_name

log = logging.getLogger("interlayer.pbjson")
ARMS = ("left", "right")


def looks_like_pybullet_json(path) -> dict | None:
    if path.suffix.lower() != ".json":
        return None
    try:
        data = json.loads(path.read_text())
    except (OSError, ValueError):
        return None
    except RecursionError:  # the file's fault, not this plugin's
        raise UserError(f"{path} is nested too deeply to read as JSON (over {sys.getrecursionlimit()} levels); "
                        f"give a pybullet-planning problem file.") from None
    if not isinstance(data, dict) or not {"bodies", "robots", "task"} <= set(data):
        return None
    return data


def load_pybullet_json(path, data, params, seed) -> Problem:
    """The problem of a pybullet-planning JSON file; a malformed file is a UserError naming what is wrong."""
    if params:
        raise UserError(f"{path.name}: problem parameters {sorted(params)} do not apply to a problem file.")
    try:
        scene = read_scene(data, path.stem)
        return build_problem(scene, {"domain": "pbjson", "file": str(path), "seed": seed})
    except (KeyError, IndexError, TypeError, ValueError, AttributeError) as exc:
        what = f"the key {exc}" if isinstance(exc, KeyError) else f"{type(exc).__name__}: {exc}"
        raise UserError(f"{path.name} is not a pybullet-planning problem Interlayer can read ({what}); "
                        f"check the file against the format's bodies / robots / task fields.") from None


def torso_height(scene) -> float:
    """The torso as the file's conf sets it, raised (never lowered) to Clutter's working height for the
    highest table (the PR2 here holds its torso still while planning). Higher, the carry postures beside
    the shoulder fail with a tall box in hand (measured: every one at 0.3 m on kitchen.json)."""
    from interlayer_clutter.scene import TORSO

    tops = [s.z for s in scene.surfaces.values() if s.kind == "table"] or [0.8]
    work = min(TORSO, max(0.0, TORSO + max(tops) - 0.8))
    start = scene.torso if scene.torso is not None else 0.0
    return float(min(0.33, max(start, work)))


BASE_RADIUS = 0.30  # m: a disk inside the PR2 base's 0.67 m square: where it cannot pass, the robot cannot
BASE_TOP = 0.35  # m: fixed shapes reaching below this height stand in the base's way (walls, legs)


def reachable_limits(fixed, start, xr, yr, res=0.04):
    """The x and y ranges, within (xr, yr), of the base positions reachable from ``start``: a disk of
    BASE_RADIUS flood-filled on a grid among the fixed shapes low enough to hit the base. It errs on the
    reachable side, so no base pose outside is ever reachable (e.g. beyond a room's walls, where base
    poses are collision-free but every drive to them fails)."""
    xs, ys = np.arange(xr[0], xr[1] + 1e-9, res), np.arange(yr[0], yr[1] + 1e-9, res)
    X, Y = np.meshgrid(xs, ys, indexing="ij")
    free = np.ones(X.shape, bool)
    for o in fixed:
        if o.pose[2] - o.height / 2 > BASE_TOP:
            continue
        dx, dy = X - o.pose[0], Y - o.pose[1]
        if o.shape == "cylinder":
            d = np.hypot(dx, dy) - o.size[0]
        else:  # the distance to a rectangle turned by yaw
            c, s = math.cos(o.pose[3]), math.sin(o.pose[3])
            u, v = np.abs(c * dx + s * dy) - o.size[0] / 2, np.abs(c * dy - s * dx) - o.size[1] / 2
            d = np.hypot(np.maximum(u, 0), np.maximum(v, 0)) + np.minimum(np.maximum(u, v), 0)
        free &= d >= BASE_RADIUS
    near = np.hypot(X - start[0], Y - start[1]) <= 2.5 * res
    reach = free & near
    if not reach.any():
        return xr, yr  # the start is too tight for the disk: no conclusion
    while True:
        grown = reach.copy()
        grown[1:] |= reach[:-1]
        grown[:-1] |= reach[1:]
        grown[:, 1:] |= reach[:, :-1]
        grown[:, :-1] |= reach[:, 1:]
        grown &= free
        if (grown == reach).all():
            break
        reach = grown
    i, j = np.nonzero(reach)
    return ((max(xr[0], float(xs[i.min()]) - res), min(xr[1], float(xs[i.max()]) + res)),
            (max(yr[0], float(ys[j.min()]) - res), min(yr[1], float(ys[j.max()]) + res)))


def build_problem(scene, source) -> Problem:
    from .world import PBGeometry

    spots = scene.surfaces
    tables = [s for s in spots.values() if s.kind == "table"]
    # the single table's box: Clutter's base sampler keeps the base off it (several tables: a box far away,
    # and the base is kept off the tables by collision checks alone)
    clutter_table, table = None, (1e9, 1e9, 1e9, 1e9)
    if len(tables) == 1:
        xs, ys = [p[0] for p in tables[0].polygon], [p[1] for p in tables[0].polygon]
        table = (min(xs), max(xs), min(ys), max(ys))
        placing = any(scene.goals[k] for k in ("on", "stackings", "poses", "cleaned", "cooked"))
        if not placing and abs(area(tables[0].polygon) - (table[1] - table[0]) * (table[3] - table[2])) < 1e-6:
            clutter_table = tables[0].name  # the paper's kind of scene: Clutter's put-down sampler applies as it is
    pts = [scene.base[:2]] + ([scene.goals["base"][:2]] if scene.goals["base"] else []) + [p for o in scene.fixed + scene.objects if o.name not in scene.floors
                              for p in [o.pose[:2]]]
    lo = (min(p[0] for p in pts) - 1.2, max(p[0] for p in pts) + 1.2)
    hi = (min(p[1] for p in pts) - 1.2, max(p[1] for p in pts) + 1.2)
    lo, hi = reachable_limits([o for o in scene.fixed if o.name not in scene.floors], scene.base, lo, hi)
    goals = scene.goals
    main_top = max((s.z for s in tables), default=0.8)
    torso = torso_height(scene)
    if scene.torso is not None and torso > scene.torso + 1e-9:
        log.info("torso raised from %.3f (robots[0].conf) to %.3f m to reach surfaces at %.2f m", scene.torso, torso,
                 max((s.z for s in spots.values()), default=main_top))
    extra = {"table_top": float(main_top), "base_limits": (lo, hi), "torso_height": torso, "torso_conf": scene.torso,
             "supports": tuple(o.name for o in scene.fixed if any(_body(o.name, s) for s in spots.values())),
             "surfaces": spots, "colors": scene.colors, "offsets": scene.offsets, "arms": scene.arms, "goals": goals,
             "clutter_table": clutter_table, "camera": scene.camera, "notes": scene.notes,
             "floors": [o for o in scene.fixed if o.name in scene.floors]}  # drawn, not collided with
    # the target (Clutter's samplers search harder for its grasps and keep put-downs out of its way): the
    # object to hold, else the one object a goal places
    placed = list(dict.fromkeys([*(m for o in goals["on"] for m in goals["members"][o]), *goals["stackings"], *goals["poses"]]))
    held = goals["holding"] or ()
    target = held[0] if len(held) == 1 else None if held else (placed[0] if len(placed) == 1 else None)
    layout = Layout([o for o in scene.fixed if o.name not in scene.floors], list(scene.objects), {"table": table}, target,
                    "pbjson", scene.grasps, base=scene.base, extra=extra)
    geometry = PBGeometry(layout)
    extra["goal_centres"] = {o: geometry.goal_centre(o) for o in goals["poses"]}
    names = [o.name for o in scene.objects]
    slots = [f"s{k + 1}" for k in range(SLOTS)]
    kinds = {s.kind for s in spots.values()}
    domain = pbjson_domain(tops="top" in kinds, goal_poses=bool(goals["poses"]), sinks="sink" in kinds,
                           stoves="stove" in kinds, home=goals["home"], go_to=bool(goals["base"]))
    objects = {o: "obj" for o in names}
    objects.update({a: "arm" for a in ARMS})
    objects.update({s: "slot" for s in slots})
    objects.update({s: "surf" for s in spots})
    clash = sorted(set(names) & set(ARMS + tuple(slots)))
    if clash:
        raise UserError(f"task.object_names: {clash[0]!r} is a name Interlayer reserves (arms, slots); rename the body.")
    init = {("HandEmpty", a) for a in ARMS} | {("Other", "left", "right"), ("Other", "right", "left")}
    init |= {("Resting", o) for o in names}
    world = geometry.initial_world()
    if geometry.in_collision(world):
        pairs = sorted({b for a, b in geometry.cw.collision_pairs(geometry.sync(world))})
        raise UserError(f"robots[0]: the PR2 at its start (point, quat and conf) collides with {', '.join(pairs)}; "
                        f"move it or change its conf.")
    for o in names:
        for s in geometry.supports_of(o, world.objects[o], world):
            init.add(("On", o, s))
    for s in spots.values():
        if s.kind == "top":
            init.add(("TopOf", s.name, s.body))
        elif s.kind in ("sink", "stove"):
            init.add(("Sink" if s.kind == "sink" else "Stove", s.name))
    for o in goals["poses"]:
        init.add(("HasGoalPose", o))
        if geometry.at_goal_pose(o, world.objects[o]):
            init.add(("AtGoalPose", o))
        init |= {("Occupies", b, o) for b in geometry.goal_occupants(o, world)}
    parts = []
    if goals["holding"]:  # any one of the objects named, in either hand
        parts.append(f"(or {' '.join(f'(Holding {t} {a})' for t in goals['holding'] for a in ARMS)})")
    parts += [_any(f"(On {m} {s})" for m in goals["members"][o]) for o, s in goals["on"].items()]
    parts += [f"(On {o} {top_name(b)})" for o, b in goals["stackings"].items()]
    parts += [f"(AtGoalPose {o})" for o in goals["poses"]]
    parts += [f"(Cleaned {o})" for o in goals["cleaned"]] + [f"(Cooked {o})" for o in goals["cooked"]]
    if goals["home"]:
        parts.append("(AtHome)")
    if goals["base"]:
        parts.append("(AtBaseGoal)")
    source = {**source, "layout": layout.to_json()}
    return Problem(domain, objects, frozenset(init), f"(and {' '.join(parts)})", geometry, source, name=scene.name)


def _any(atoms):
    atoms = list(atoms)
    return atoms[0] if len(atoms) == 1 else f"(or {' '.join(atoms)})"


def _body(spec_name, surface):
    """The body a fixed spec belongs to when it is part of ``surface``'s body (specs are <body> or <body>_<k>)."""
    b = surface.body
    if b is None or surface.kind == "top":
        return None
    return b if spec_name == b or (spec_name.startswith(f"{b}_") and spec_name[len(b) + 1:].isdigit()) else None

