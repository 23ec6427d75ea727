"""The pybullet-planning JSON problem format (bodies / robots / task): see that repository's problems/json."""
from __future__ import annotations

import json
import logging
import math
from dataclasses import replace

import numpy as np
from interlayer.domain import Problem
from interlayer.errors import UserError
from interlayer_clutter.domain import clutter_problem
from interlayer_pr2.scene import Layout, ObjectSpec

log = logging.getLogger("interlayer.pbjson")

UNSUPPORTED_GOALS = ("goal_regions", "goal_poses", "goal_stackings", "goal_cleaned", "goal_cooked")


def _yaw(q) -> float:
    w, x, y, z = q["w"], q["x"], q["y"], q["z"]
    if abs(x) > 1e-6 or abs(y) > 1e-6:
        raise UserError("only upright bodies (rotations about z) are supported in pybullet-planning JSON files")
    return 2 * math.atan2(z, w)


def looks_like_pybullet_json(path) -> dict | None:
    if path.suffix.lower() != ".json":
        return None
    try:
        data = json.loads(path.read_text())
    except (OSError, ValueError):
        return None
    if not isinstance(data, dict) or not {"bodies", "robots", "task"} <= set(data):
        return None
    return data


def load_pybullet_json(path, data, params, seed) -> Problem:
    """The problem of a pybullet-planning JSON file; a malformed file is a UserError naming what is wrong."""
    try:
        return _load_pybullet_json(path, data, params, seed)
    except (KeyError, IndexError, TypeError, ValueError, AttributeError) as exc:
        what = f"the key {exc}" if isinstance(exc, KeyError) else f"{type(exc).__name__}: {exc}"
        raise UserError(f"{path.name} is not a pybullet-planning problem Interlayer can read ({what}); "
                        f"check the file against the format's bodies / robots / task fields.") from None


def _load_pybullet_json(path, data, params, seed) -> Problem:
    task = data["task"]
    unsupported = [k for k in UNSUPPORTED_GOALS if task.get(k)]
    if unsupported or not task.get("goal_holding"):
        raise UserError(f"{path.name}: only 'goal_holding' goals are supported for now; this file asks for "
                        f"{', '.join(unsupported) or 'no goal_holding'} (unsupported: {', '.join(UNSUPPORTED_GOALS)}).")
    if task.get("goal_config"):
        log.warning("%s: goal_config = %r is ignored (the robot need not return to its start configuration)",
                    path.name, task["goal_config"])
    if params:
        raise UserError(f"{path.name}: problem parameters {sorted(params)} do not apply to a problem file.")
    movable = set(task["object_names"])
    tables = set(task.get("table_names", []))
    if len(tables) != 1:
        raise UserError(f"{path.name}: exactly one table is supported for now, got {sorted(tables)}.")
    fixed, objects, top, region = [], [], None, None
    for body in data["bodies"]:
        bp, yaw = body["point"], _yaw(body["quat"])
        B = np.array([[math.cos(yaw), -math.sin(yaw)], [math.sin(yaw), math.cos(yaw)]])
        links = [shape for link in body["links"] for shape in link]
        for k, shape in enumerate(links):
            lp = shape["point"]
            xy = np.array([bp["x"], bp["y"]]) + B @ np.array([lp["x"], lp["y"]])
            z = bp["z"] + lp["z"]
            lyaw = yaw + _yaw(shape["quat"])
            name = body["name"] if len(links) == 1 else f"{body['name']}_{k}"
            if shape["type"] == "box":
                size = tuple(2 * float(e) for e in shape["extents"])
            elif shape["type"] == "cylinder":
                size = (float(shape["radius"]), float(shape["height"]))
            else:
                raise UserError(f"{path.name}: shape type {shape['type']!r} of {body['name']} is not supported")
            spec = ObjectSpec(name, shape["type"], size, (float(xy[0]), float(xy[1]), float(z), float(lyaw)),
                              movable=body["name"] in movable)
            if body["name"] in movable:
                if len(links) != 1:
                    raise UserError(f"{path.name}: movable {body['name']} must be a single shape")
                objects.append(spec)
            else:
                if body["name"] in tables and spec.shape == "box" and (top is None or z + size[2] / 2 > top):
                    top = z + size[2] / 2
                    region = (xy[0] - size[0] / 2, xy[0] + size[0] / 2, xy[1] - size[1] / 2, xy[1] + size[1] / 2)
                    spec = replace(spec, name="table")  # the support the validator and samplers know
                fixed.append(spec)
    if top is None:
        raise UserError(f"{path.name}: the table has no box top")
    robot = data["robots"][0]
    base = (float(robot["point"]["x"]), float(robot["point"]["y"]), _yaw(robot["quat"]))
    grasps = tuple(g.lower() for g in task.get("grasp_types", ["SIDE"]))
    if any(g not in ("side", "top") for g in grasps):
        raise UserError(f"{path.name}: grasp types {grasps} not supported (SIDE, TOP)")
    target = task["goal_holding"]
    if target not in {o.name for o in objects}:
        raise UserError(f"{path.name}: goal_holding {target!r} is not among object_names")
    lo = (min(base[0], region[0]) - 1.5, max(base[0], region[1]) + 1.5)
    hi = (min(base[1], region[2]) - 1.5, max(base[1], region[3]) + 1.5)
    layout = Layout(fixed, objects, {"table": region}, target, "hold", grasps, base=base,
                    extra={"table_top": float(top), "base_limits": (lo, hi),
                           "torso_height": float(min(0.3, max(0.0, 0.2 + top - 0.72)))})
    log.info("%s: the robot's conf is not used (arms start tucked, torso at %.2f m for the table height)",
             path.name, layout.extra["torso_height"])
    return clutter_problem(layout, {"domain": "clutter", "file": str(path), "seed": seed, "layout": layout.to_json()},
                           data.get("name") or path.stem)
