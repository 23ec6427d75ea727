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
from interlayer.names import Names
from interlayer_manip.sanity import resting_on
from interlayer_manip.scene import Layout

from .domain import SLOTS, pbjson_domain
from .scene import area, oriented_box, read_scene, tops

log = logging.getLogger("interlayer.pbjson")
ARMS = ("left", "right")
SLOT_NAMES = tuple(f"s{k + 1}" for k in range(SLOTS))
# m: side grasps hold a short object at least 5 cm above its base and at most 3 cm below its top (where
# pybullet-planning's PR2 grasps hold it: pr2_utils.SIDE_HEIGHT_OFFSET); see interlayer_manip.grasps.side_raise
SIDE_GRASP = (0.05, 0.03)


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
        symbols = task_symbols()
        scene = read_scene(data, path.stem, symbols)
        return build_problem(scene, {"domain": "pbjson", "file": str(path), "seed": seed}, symbols)
    except (KeyError, IndexError, TypeError, ValueError, AttributeError) as exc:
        what = f"the key {exc}" if isinstance(exc, KeyError) else f"{type(exc).__name__}: {exc}"
        raise UserError(f"{path.name} is not a pybullet-planning problem Interlayer can read ({what}); "
                        f"check the file against the format's bodies / robots / task fields.") from None


def task_symbols():
    """The symbols of this encoding's own objects (the arms, the slots) taken first, so that a file's
    names (``left``, ``s1``, ``On``, ``table 1``...) get symbols of their own (interlayer.names)."""
    symbols = Names.for_domain(pbjson_domain(tops=True, goal_poses=True, sinks=True, stoves=True, home=True, go_to=True,
                                           floor=True))
    for name in (*ARMS, *SLOT_NAMES):
        if symbols.add(name) != name:
            raise AssertionError(f"the encoding's own object {name!r} is not a free symbol")
    return symbols


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


class ReachableArea:
    """The base positions reachable from the start, on a grid (see :func:`reachable_area`). Called with
    (x, y), it says whether a base may stand there: the area, not its axis-aligned box, so that in a
    room turned in the world the corners of that box beyond the walls are not offered."""

    def __init__(self, xs, ys, reach, res):
        self.xs, self.ys, self.res = xs, ys, res
        self.reach, self.grown = reach, _grown(reach)  # one cell more: the grid errs on the reachable side

    def limits(self, xr, yr):
        i, j = np.nonzero(self.reach)
        xs, ys, res = self.xs, self.ys, self.res
        return ((max(xr[0], float(xs[i.min()]) - res), min(xr[1], float(xs[i.max()]) + res)),
                (max(yr[0], float(ys[j.min()]) - res), min(yr[1], float(ys[j.max()]) + res)))

    def __call__(self, x, y) -> bool:
        i, j = int(round((x - self.xs[0]) / self.res)), int(round((y - self.ys[0]) / self.res))
        return 0 <= i < len(self.xs) and 0 <= j < len(self.ys) and bool(self.grown[i, j])

    @property
    def cells(self):
        """(centres of the reachable cells, cell size): where the base samplers draw from."""
        i, j = np.nonzero(self.reach)
        return np.column_stack([self.xs[i], self.ys[j]]), self.res


def reachable_area(fixed, start, xr, yr, res=0.04):
    """The base positions, within (xr, yr), reachable from ``start``: a disk of BASE_RADIUS flood-filled
    on a grid among the fixed shapes low enough to hit the base; None when the start is too tight for the
    disk (no conclusion). It errs on the reachable side, so no base pose outside is ever reachable (e.g.
    beyond a room's walls, where base poses are collision-free but every drive to them fails)."""
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
        return None
    while True:
        grown = _grown(reach) & free
        if (grown == reach).all():
            break
        reach = grown
    return ReachableArea(xs, ys, reach, res)


def _grown(mask):
    """The grid mask and its four neighbours of every cell in it."""
    grown = mask.copy()
    grown[1:] |= mask[:-1]
    grown[:-1] |= mask[1:]
    grown[:, 1:] |= mask[:, :-1]
    grown[:, :-1] |= mask[:, 1:]
    return grown


def reachable_limits(fixed, start, xr, yr, res=0.04):
    """The x and y ranges, within (xr, yr), of :func:`reachable_area` (all of them: no conclusion)."""
    area = reachable_area(fixed, start, xr, yr, res)
    return (xr, yr) if area is None else area.limits(xr, yr)


def build_problem(scene, source, symbols) -> Problem:
    from .world import PBGeometry

    spots = scene.surfaces
    tables = [s for s in spots.values() if s.kind == "table"]
    # the single table's box: Clutter's base sampler keeps the base off it (several tables: a box far away,
    # and the base is kept off the tables by collision checks alone)
    clutter_table, table, table_frame = None, (1e9, 1e9, 1e9, 1e9), None
    if len(tables) == 1:
        xs, ys = [p[0] for p in tables[0].polygon], [p[1] for p in tables[0].polygon]
        table = (min(xs), max(xs), min(ys), max(ys))
        table_frame = oriented_box(tables[0].polygon)  # the table's own frame: it may stand turned
        placing = any(scene.goals[k] for k in ("on", "stackings", "poses", "cleaned", "cooked"))
        if not placing and abs(area(tables[0].polygon) - 4 * table_frame[3] * table_frame[4]) < 1e-6:
            clutter_table = tables[0].name  # the paper's kind of scene: Clutter's put-down sampler applies as it is
    pts = [scene.base[:2]] + ([scene.goals["base"][:2]] if scene.goals["base"] else []) + [p for o in scene.fixed + scene.objects if o.name not in scene.floors
                              for p in [o.pose[:2]]]
    lo = (min(p[0] for p in pts) - 1.2, max(p[0] for p in pts) + 1.2)
    hi = (min(p[1] for p in pts) - 1.2, max(p[1] for p in pts) + 1.2)
    reach = reachable_area([o for o in scene.fixed if o.name not in scene.floors], scene.base, lo, hi)
    lo, hi = (lo, hi) if reach is None else reach.limits(lo, hi)
    goals = scene.goals
    main_top = max((s.z for s in tables), default=0.8)
    torso = torso_height(scene)
    if scene.torso is not None and torso > scene.torso + 1e-9:
        log.info("torso raised from %.3f (robots[0].conf) to %.3f m to reach surfaces at %.2f m", scene.torso, torso,
                 max((s.z for s in spots.values()), default=main_top))
    standing = resting_on([o for o in scene.fixed if o.name not in scene.floors], scene.objects)
    extra = {"table_top": float(main_top), "base_limits": (lo, hi), "base_cells": None if reach is None else reach.cells,
             "torso_height": torso, "torso_conf": scene.torso,
             # the surfaces' shapes, and any shape an object stands on (a table the file does not name): the
             # planner pads them sideways only, or an object picked off one would start in its padding
             "supports": tuple(o.name for o in scene.fixed if any(_body(scene, o.name, s) for s in spots.values())
                               or o.name in standing),
             "surfaces": spots, "colors": scene.colors, "offsets": scene.offsets, "arms": scene.arms, "goals": goals,
             "clutter_table": clutter_table, "table_frame": table_frame, "base_area": reach, "camera": scene.camera,
             "notes": scene.notes, "floors": [o for o in scene.fixed if o.name in scene.floors],  # drawn, not collided with
             "body_of": scene.body_of, "labels": symbols.labels, "floor_objects": list(scene.floor_objects),
             "floor_fixed": list(scene.floor_fixed), "side_grasp": SIDE_GRASP}
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
    slots = list(SLOT_NAMES)
    kinds = {s.kind for s in spots.values()}
    domain = pbjson_domain(tops="top" in kinds, goal_poses=bool(goals["poses"]), sinks="sink" in kinds,
                           stoves="stove" in kinds, home=goals["home"], go_to=bool(goals["base"]),
                           floor=bool(scene.floor_objects))
    # a floor obstacle the gripper can hold is picked like any object (an item) or pushed; any other one is pushed
    handled = floor_handling(geometry)
    extra["floor_handling"] = handled
    objects = {o: "floor" if handled.get(o) == "push" else "item" if handled else "obj" for o in names}
    objects.update({a: "arm" for a in ARMS})
    objects.update({s: "slot" for s in slots})
    objects.update({s: "surf" for s in spots})
    init = {("HandEmpty", a) for a in ARMS} | {("Other", "left", "right"), ("Other", "right", "left")}
    init |= {("Resting", o) for o in names}
    init |= {("Pushable", o) for o in handled}
    init |= {("InLine", f, g) for f, g in in_line(geometry, handled)}
    init |= {("FinalClear", o) for o in names} if handled else set()  # nothing blocks the final drive until it fails
    world = geometry.initial_world()
    if geometry.in_collision(world):
        pairs = sorted({b for a, b in geometry.cw.collision_pairs(geometry.sync(world))})
        raise UserError(f"robots[0]: the PR2 at its start (point, quat and conf) collides with "
                        f"{', '.join(symbols.label(p) for p in pairs)}; "
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
    parts += [f"(On {o} {tops(spots)[b]})" for o, b in goals["stackings"].items()]
    parts += [f"(AtGoalPose {o})" for o in goals["poses"]]
    parts += [f"(Cleaned {o})" for o in goals["cleaned"]] + [f"(Cooked {o})" for o in goals["cooked"]]
    if goals["home"]:
        parts.append("(AtHome)")
    if goals["base"]:
        parts.append("(AtBaseGoal)")
    source = {**source, "layout": layout.to_json()}
    return Problem(domain, objects, frozenset(init), f"(and {' '.join(parts)})", geometry, source, name=scene.name,
                   labels=symbols.labels)


def floor_handling(geometry) -> dict:
    """Floor obstacle -> "pick" when a grasp of the file's kinds fits the gripper (the width proof of every
    object; it may be pushed too, e.g. where the arm cannot reach it), else "push" (the base pushes it; the
    files give no masses, so size is the only limit)."""
    from interlayer_manip.grasps import fits_gripper

    kinds = geometry.layout.grasps
    return {o: "pick" if fits_gripper(geometry, o, kinds) else "push" for o in geometry.layout.extra["floor_objects"]}


def in_line(geometry, floor) -> list:
    """Pairs (f, g) of the ``floor`` obstacles where g stands in line with f, within the longest push, along
    one of f's sides (a push of f meets it head on and carries it along: PBGeometry.push_pieces)."""
    from interlayer_manip.scene import _radius
    from interlayer_manip.state import pose4

    from .samplers import PUSH_LENGTHS
    from .world import ahead_in_line

    poses = {o: pose4(*geometry.specs[o].pose) for o in floor}
    out = []
    for f, P in poses.items():
        o = geometry.specs[f]
        for g, Q in poses.items():
            reach = max(PUSH_LENGTHS) + _radius(o) + _radius(geometry.specs[g])
            if g != f and any((ahead_in_line(P, o, Q, o.pose[3] + k * math.pi / 2) or reach + 1) <= reach for k in range(4)):
                out.append((f, g))
    return out


def _any(atoms):
    atoms = list(atoms)
    return atoms[0] if len(atoms) == 1 else f"(or {' '.join(atoms)})"


def _body(scene, spec_name, surface):
    """The body a fixed spec belongs to when it is part of ``surface``'s body."""
    b = surface.body
    if b is None or surface.kind == "top":
        return None
    return b if scene.body_of.get(spec_name) == b else None

