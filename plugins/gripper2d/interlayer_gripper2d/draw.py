"""How Gripper-2D draws itself in a 3D view (used by the meshcat visualizer).

Two functions with the geometry as first argument, so they can be attached to
:class:`~.world.Gripper2DGeometry` as methods unchanged::

    draw_scene(geometry, scene, world=None) -> {object name: scene name}
    animation_frames(geometry, scene, trajectory) -> [{scene name: 4x4 pose, "@step": i}, ...]

``scene`` is an ``interlayer_meshcat.Scene``-like object; only its generic
methods are used (``box``, ``label``, ``set_pose``, ``set_grid``). ``world`` is
a snapshot as written by ``Gripper2DGeometry.snapshot`` (``World.to_json()``)
or ``None`` for the initial world. The 2D shapes are extruded ``HEIGHT`` and
stand on the table top (z = 0).

Nothing here imports meshcat; numpy only.
"""
from __future__ import annotations

import math

import numpy as np

from .world import BLOCK, HEIGHT, S_CENTRE, S_SIZE, TABLE, block_shapes, gripper_shapes

GOAL_BLOCK = "b1"
COLORS = {
    "table": (0.93, 0.90, 0.84, 1.0),
    "wall": (0.55, 0.56, 0.58, 1.0),
    "region": (0.20, 0.70, 0.30, 0.35),
    "gripper": (0.25, 0.27, 0.32, 1.0),
    "goal": (0.98, 0.78, 0.10, 1.0),
    "other": [(0.30, 0.50, 0.85, 1.0), (0.45, 0.65, 0.90, 1.0), (0.35, 0.45, 0.75, 1.0), (0.50, 0.55, 0.95, 1.0)],
    "clutter": (0.60, 0.45, 0.75, 1.0),
}
# frames of the animation: at most this far (m / rad) apart; pauses at grasp / release
STEP_XY, STEP_TH, PAUSE = 0.035, 0.12, 4


def _pose(x, y, th, z=HEIGHT / 2) -> np.ndarray:
    c, s = math.cos(th), math.sin(th)
    return np.array([[c, -s, 0, x], [s, c, 0, y], [0, 0, 1, z], [0, 0, 0, 1.0]])


def _block_color(name: str, index: int):
    if name == GOAL_BLOCK:
        return COLORS["goal"]
    if name.startswith("b"):
        return COLORS["other"][index % len(COLORS["other"])]
    return COLORS["clutter"]


def draw_scene(geometry, scene, world=None) -> dict:
    """Add the table, the walls, region S, the blocks and the gripper at ``world``
    (a snapshot dict; None = initial world). Returns {problem object: scene name
    to highlight}."""
    layout = geometry.layout
    if world is None:
        world = geometry.initial_world().to_json()
    scene.set_grid(False)
    scene.box("table", (2 * TABLE, 2 * TABLE, 0.02), [0, 0, -0.0101], COLORS["table"])
    for name, (cx, cy, sx, sy) in layout.walls.items():
        scene.box(f"walls/{name}", (sx, sy, HEIGHT), [cx, cy, HEIGHT / 2], COLORS["wall"])
    scene.box("S/area", (S_SIZE, S_SIZE, 0.004), [S_CENTRE[0], S_CENTRE[1], 0.002], COLORS["region"])
    scene.label("S/label", "S", [S_CENTRE[0], S_CENTRE[1] - S_SIZE / 2 - 0.07, 0.01], height=0.06)
    names = {"S": "S/area"}
    (shape,) = block_shapes()
    for i, name in enumerate(sorted(world["blocks"])):
        scene.box(f"{name}/box", shape.dims, None, _block_color(name, i))
        scene.label(f"{name}/label", name, [0, 0, HEIGHT / 2 + 0.02], height=0.05)
        scene.set_pose(name, _pose(*world["blocks"][name]))
        names[name] = f"{name}/box"
    for part, s in zip(("palm", "finger_l", "finger_r"), gripper_shapes()):
        scene.box(f"gripper/{part}", s.dims, s.local, COLORS["gripper"])
    scene.set_pose("gripper", _pose(*world["gripper"]))
    names["gripper"] = "gripper"
    return names


def _interpolate(path):
    """Waypoints of an SE(2) path at most STEP_XY / STEP_TH apart (first point excluded)."""
    out = []
    for a, b in zip(path[:-1], path[1:]):
        a, b = np.asarray(a, float), np.asarray(b, float)
        dth = (b[2] - a[2] + math.pi) % (2 * math.pi) - math.pi
        n = max(1, int(math.ceil(max(np.hypot(*(b[:2] - a[:2])) / STEP_XY, abs(dth) / STEP_TH))))
        for k in range(1, n + 1):
            u = k / n
            out.append((a[0] + u * (b[0] - a[0]), a[1] + u * (b[1] - a[1]), a[2] + u * dth))
    return out


def animation_frames(geometry, scene, trajectory) -> list:
    """Frames of the whole refined plan: the gripper along every segment, a held
    block carried rigidly. Each frame also carries ``"@step"`` (the plan step it
    shows), which the visualizer strips before animating."""
    init = trajectory["initial"]
    gripper = tuple(init["gripper"])
    blocks = {k: tuple(v) for k, v in init["blocks"].items()}
    held, offset = init.get("held"), None

    def grasp_offset(name):
        gx, gy, gth = gripper
        bx, by, bth = blocks[name]
        c, s = math.cos(-gth), math.sin(-gth)
        return c * (bx - gx) - s * (by - gy), s * (bx - gx) + c * (by - gy), bth - gth

    if held:
        offset = grasp_offset(held)

    def frame(step):
        f = {"gripper": _pose(*gripper), "@step": step}
        for name, p in blocks.items():
            f[name] = _pose(*p)
        return f

    frames = [frame(0)] * PAUSE
    for i, step in enumerate(trajectory.get("steps", [])):
        for seg in step.get("segments", []):
            kind = seg.get("kind")
            if "path" in seg:
                for q in _interpolate(seg["path"]):
                    gripper = q
                    if held:
                        dx, dy, dth = offset
                        c, s = math.cos(q[2]), math.sin(q[2])
                        blocks[held] = (q[0] + c * dx - s * dy, q[1] + s * dx + c * dy, q[2] + dth)
                    frames.append(frame(i))
            elif kind == "grasp":
                held = seg["object"]
                offset = grasp_offset(held)
                frames += [frame(i)] * PAUSE
            elif kind == "release":
                if seg.get("pose") is not None:
                    blocks[seg["object"]] = tuple(seg["pose"])
                held, offset = None, None
                frames += [frame(i)] * PAUSE
    frames += [frame(max(0, len(trajectory.get("steps", [])) - 1))] * (3 * PAUSE)
    return frames


__all__ = ["draw_scene", "animation_frames", "BLOCK"]
