"""How the manipulation domains draw themselves in a 3D view (used by the meshcat visualizer).

Two functions with the geometry as first argument (the visualizer finds them as
``interlayer_manip.draw``)::

    draw_scene(geometry, scene, world=None) -> {problem object: scene name}
    animation_frames(geometry, scene, trajectory) -> [{scene name: 4x4 pose, "@step": i}, ...]

``world`` is a snapshot as written by ``ManipulationGeometry.snapshot`` (``World.to_json()``: base, arms,
grippers, objects as 4x4 poses, held objects with their grasp) or ``None`` for the initial world;
``trajectory`` is trajectory.json (per segment a joint trajectory of the base (x, y, theta) or of one
arm, gripper open / close, grasp and release events between). Everything is read defensively: only
``geometry.robot`` (an ``interlayer_pinocchio.Robot``) is required; the object shapes come from
``geometry.layout`` (``fixed`` / ``objects`` specs, ``regions``, ``target``) when it is there.

The robot is added once per scene below the group ``"pr2"``: its links are posed with the base at the
origin and the group carries the base pose, so that a base motion animates one node and an arm
motion only that arm's links (small pages). Movable objects are groups ``"<name>"`` holding
``"<name>/shape"`` and a label. The state shown at each moment is replayed by replay.py.
"""
from __future__ import annotations

import math
import weakref

import numpy as np

from .replay import _bodies, _body_poses, _initial, _mat, _move_joints, _pose4, _State  # noqa: F401 (tests use _State)

COLORS = {
    "table": (0.80, 0.68, 0.52, 1.0),
    "panel": (0.55, 0.56, 0.60, 0.55),  # see-through: the cubby's inside stays visible
    "fixed": (0.55, 0.56, 0.60, 1.0),
    "target": (0.98, 0.78, 0.10, 1.0),
    "movable": [(0.30, 0.50, 0.85, 1.0), (0.35, 0.65, 0.55, 1.0), (0.55, 0.45, 0.80, 1.0), (0.40, 0.60, 0.90, 1.0)],
    "region": (0.20, 0.70, 0.30, 0.45),
    "robot": (0.78, 0.80, 0.84, 1.0),
    "body": (0.62, 0.47, 0.33, 0.45),  # articulated bodies' fixed parts: see-through (a cabinet's inside)
    "body_moving": (0.78, 0.62, 0.42, 1.0),
}
TABLE_TOP_DEFAULT = 0.72
VIEW_DIRECTION = (-0.45, -1.0, 1.0)
# animation: consecutive frames at most this far apart (rad per arm joint, m / rad for the base)
STEP_ARM, STEP_XY, STEP_TH = 0.06, 0.04, 0.08
PAUSE = 4  # frames held at grasp / release / gripper events
GRIPPER_FRAMES = 4  # frames of a gripper opening / closing
ROBOT_MODEL = "visual"  # "visual" (meshes, ~0.35 MB per 3D view at MAX_FACES) or "collision" (~0.18 MB)
MAX_FACES = 300  # decimation of each visual mesh

_robots = weakref.WeakKeyDictionary()  # scene -> PinocchioRobot handle


# ------------------------------------------------------------------ helpers
def _specs(geometry):
    """(fixed specs, movable specs by name) from geometry.layout, [] / {} when absent."""
    layout = getattr(geometry, "layout", None)
    fixed = list(getattr(layout, "fixed", None) or [])
    objects = list(getattr(layout, "objects", None) or [])
    return fixed, {getattr(o, "name", str(i)): o for i, o in enumerate(objects)}


def _table_top(geometry) -> float:
    fixed, _ = _specs(geometry)
    for o in fixed:
        if getattr(o, "name", "") == "table":
            try:
                return float(o.pose[2]) + float(o.size[2]) / 2
            except Exception:
                break
    try:
        from .scene import TABLE_TOP

        return float(TABLE_TOP)
    except Exception:
        return TABLE_TOP_DEFAULT


def _add_shape(scene, name, spec, color, default=("cylinder", (0.03, 0.12))):
    shape = getattr(spec, "shape", None) or default[0]
    size = tuple(getattr(spec, "size", None) or default[1])
    if shape == "box" and len(size) >= 3:
        return scene.box(name, size[:3], None, color), float(size[2])
    if shape == "sphere" and size:
        return scene.sphere(name, size[0], None, color), 2 * float(size[0])
    r, h = (float(size[0]), float(size[1])) if len(size) >= 2 else default[1]
    return scene.cylinder(name, r, h, None, color), h


def _draw_bodies(geometry, scene, state, names) -> None:
    """Articulated bodies: one box / cylinder per collision element, below ``bodies/<body>/<link>``."""
    for name, body in _bodies(geometry).items():
        values = state.joints.get(name, tuple(body.zero()))
        poses = body.shape_poses(values)
        for sh in body.shapes:
            color = COLORS["body_moving"] if sh.joint > 0 else COLORS["body"]
            if sh.link == "handle":
                color = COLORS["fixed"]
            sn = f"bodies/{sh.name}"
            if sh.kind == "box":
                scene.box(sn, sh.size, None, color)
            else:
                scene.cylinder(sn, sh.size[0], sh.size[1], None, color)
            scene.set_pose(sn, poses[sh.name])
        names[name] = f"bodies/{name}"


def _robot_handle(geometry, scene):
    h = _robots.get(scene)
    if h is not None:
        return h
    from interlayer_meshcat import add_pinocchio_robot

    robot = geometry.robot
    gm, dirs, kw = robot.collision_model, (), {"color": COLORS["robot"]}
    if ROBOT_MODEL == "visual":
        try:
            gm, dirs = robot.visual_model()
            kw = {"max_faces": MAX_FACES}
        except Exception:
            gm, dirs = robot.collision_model, ()
    h = add_pinocchio_robot(scene, "pr2", robot.model, gm, dirs, q=robot.default_q((0.0, 0.0, 0.0)), **kw)
    if "max_faces" in kw:  # the URDF's material colours (blue / green / red parts) are loud: a grey PR2
        for name in h.names:
            if name is not None:
                try:
                    scene.set_color(name, _link_color(name))
                except Exception:
                    pass
    _robots[scene] = h
    return h


def _link_color(name: str):
    n = name.rsplit("/", 1)[-1]
    if "finger_tip" in n or "head" in n or "laser" in n or "stereo" in n or "high_def" in n:
        return (0.25, 0.26, 0.29, 1.0)
    if "palm" in n or "finger" in n or "wrist_flex" in n or "elbow_flex" in n or "shoulder_lift" in n:
        return (0.42, 0.44, 0.48, 1.0)
    if "upper_arm_link" in n or "forearm_link" in n or "shoulder_pan" in n:
        return (0.62, 0.64, 0.68, 1.0)
    if "base_link" in n:
        return (0.55, 0.57, 0.60, 1.0)
    return COLORS["robot"]


def _robot_poses(handle, state: _State, prefix="pr2") -> dict:
    """Scene poses of the robot at ``state``: links relative to the group, the group at the base."""
    q_local = state.q(base=(0.0, 0.0, 0.0))
    out = handle.robot_frame(q_local)
    out[prefix] = _pose4(state.base[0], state.base[1], 0.0, state.base[2])
    return out


# ------------------------------------------------------------------ drawing
def draw_scene(geometry, scene, world=None) -> dict:
    """Add the table, the fixed obstacles, the goal region, the movable objects (the target gold) and
    the PR2 at ``world`` (snapshot dict; None = initial world). Returns {problem object: scene name}."""
    if world is None:
        world = _initial(geometry)
    fixed, specs = _specs(geometry)
    target = getattr(getattr(geometry, "layout", None), "target", None)
    labels = getattr(getattr(geometry, "layout", None), "extra", {}).get("labels", {})
    top = _table_top(geometry)
    names = {}
    try:
        scene.set_grid(False)
    except Exception:
        pass
    # the visualizer's camera (interlayer_meshcat >= view_direction): from behind the robot's left
    scene.view_direction = VIEW_DIRECTION
    for o in fixed:
        name = getattr(o, "name", "fixed")
        color = COLORS["table"] if name == "table" else COLORS["panel"] if name.startswith("panel") else COLORS["fixed"]
        sn, _ = _add_shape(scene, f"fixed/{name}", o, color, default=("box", (0.1, 0.1, 0.1)))
        T = _mat(getattr(o, "pose", None))
        if T is not None:
            scene.set_pose(sn, T)
        names[name] = sn
    state = _State(geometry, world)
    try:
        _draw_bodies(geometry, scene, state, names)
    except Exception:  # a body that cannot be drawn must not kill the page
        pass
    regions = getattr(getattr(geometry, "layout", None), "regions", None) or {}
    for loc, box in regions.items():
        if loc == "table":
            names[loc] = names.get("table", "fixed/table")
            continue
        try:
            xmin, xmax, ymin, ymax = (float(v) for v in box)
        except (TypeError, ValueError):
            continue
        cx, cy = (xmin + xmax) / 2, (ymin + ymax) / 2
        names[loc] = scene.box(f"regions/{loc}/area", (xmax - xmin, ymax - ymin, 0.003), [cx, cy, top + 0.0015],
                               COLORS["region"])
        scene.label(f"regions/{loc}/label", loc, [cx, cy, top + 0.01], height=0.035, priority=1)

    q = state.q()
    poses = state.object_poses(q)
    others = 0
    for name in sorted(set(specs) | set(poses)):
        spec = specs.get(name)
        if name == target:
            color = COLORS["target"]
        else:
            color = COLORS["movable"][others % len(COLORS["movable"])]
            others += 1
        sn, h = _add_shape(scene, f"{name}/shape", spec, color)
        shown = labels.get(name, name)  # the name a file gave it (interlayer.names)
        scene.label(f"{name}/label", shown, [0, 0, h / 2 + 0.03], height=0.035, priority=2 if name == target else 0)
        T = poses.get(name)
        if T is None and spec is not None:
            T = _mat(getattr(spec, "pose", None))
        if T is not None:
            scene.set_pose(name, T)
        names[name] = sn
    handle = _robot_handle(geometry, scene)
    for k, T in _robot_poses(handle, state).items():
        scene.set_pose(k, T)
    names["pr2"] = "pr2"
    return names


# ---------------------------------------------------------------- animation
def _in_real_time(points, path, fps, heading=None):
    """Positions every 1/fps s along a timed segment (linear between its points, as validated), or
    None when the segment has no usable time stamps."""
    times = [p.get("time_from_start") for p in points]
    if any(not isinstance(t, (int, float)) for t in times) or times[-1] <= 0 or len(path) < 2:
        return None
    P = np.array(path, float)
    if heading is not None:  # unwrap, so that the heading turns the short way between two points
        P[:, heading] = np.unwrap(P[:, heading])
    ts = np.append(np.arange(0.0, times[-1], 1.0 / fps)[1:], times[-1])
    return [np.array([np.interp(t, times, P[:, j]) for j in range(P.shape[1])]) for t in ts]


def _densify_arm(a, b):
    n = max(1, int(math.ceil(float(np.max(np.abs(b - a))) / STEP_ARM))) if len(a) else 1
    return [a + (b - a) * (k / n) for k in range(1, n + 1)]


def _densify_base(a, b):
    dth = (b[2] - a[2] + math.pi) % (2 * math.pi) - math.pi
    n = max(1, int(math.ceil(max(math.hypot(b[0] - a[0], b[1] - a[1]) / STEP_XY, abs(dth) / STEP_TH))))
    return [np.array([a[0] + (b[0] - a[0]) * k / n, a[1] + (b[1] - a[1]) * k / n, a[2] + dth * k / n])
            for k in range(1, n + 1)]


def animation_frames(geometry, scene, trajectory) -> list:
    """Frames of the whole refined plan: base and arm motions, grippers opening / closing, held objects
    carried with the gripper between grasp and release. Each frame carries ``"@step"``."""
    from interlayer_meshcat.visualizer import FPS as fps  # motions play in real time at the viewer's rate

    handle = _robot_handle(geometry, scene)
    state = _State(geometry, trajectory.get("initial") or _initial(geometry))
    robot = geometry.robot

    def frame(step):
        f = _robot_poses(handle, state)
        f.update(state.object_poses())
        f.update(_body_poses(geometry, state))
        f["@step"] = step
        return f

    steps = trajectory.get("steps") or []
    frames = [frame(0)] * PAUSE
    for i, step in enumerate(steps):
        for seg in step.get("segments") or []:
            kind = seg.get("kind")
            try:
                if "points" in seg:
                    group = seg.get("group", "")
                    path = [np.asarray(p["positions"], float) for p in seg["points"]]
                    if not path:
                        continue
                    if group == "base":
                        cur = np.asarray(state.base, float)
                        timed = _in_real_time(seg["points"], path, fps, heading=2)
                        for v in timed if timed is not None else (
                                v for a, b in zip([cur] + path[:-1], path) for v in _densify_base(a, b)):
                            state.base = tuple(float(x) for x in v)
                            frames.append(frame(i))
                    else:
                        arm = robot.arm_of(group)
                        names = list(seg.get("joint_names") or [])
                        try:
                            dof = list(robot.group(group).dof_names)
                            order = [names.index(n) for n in dof] if names and set(dof) <= set(names) else None
                        except Exception:
                            order = None
                        body = seg.get("body")
                        extra = [names.index(n) for n in names if n.startswith(f"{body}/")] if body else []
                        joints = [p[extra] for p in path] if extra else None
                        if order is not None:
                            path = [p[order] for p in path]
                        cur = np.asarray(state.arms.get(arm, path[0]), float)
                        timed = None if joints else _in_real_time(seg["points"], path, fps)
                        if timed is not None:
                            for v in timed:
                                state.arms[arm] = tuple(float(x) for x in v)
                                frames.append(frame(i))
                            continue
                        jcur = joints[0] if joints else None
                        for k, (a, b) in enumerate(zip([cur] + path[:-1], path)):
                            vs = _densify_arm(a, b)
                            for m, v in enumerate(vs):
                                state.arms[arm] = tuple(float(x) for x in v)
                                if joints:  # a pull: the body's joints move with the arm
                                    j0 = jcur if k == 0 else joints[k - 1]
                                    _move_joints(geometry, state, body, j0 + (joints[k] - j0) * (m + 1) / len(vs))
                                frames.append(frame(i))
                elif kind == "gripper":
                    arm, cmd = seg.get("arm"), seg.get("command")
                    g = robot.group(f"{arm}_gripper")
                    a0 = float(g.get(state.q())[0])
                    width = seg.get("width")
                    a1 = float((g.upper[0] if cmd == "open" else g.lower[0]) if width is None
                               else g.get(robot.set_gripper_opening(state.q(), arm, float(width)))[0])
                    for k in range(1, GRIPPER_FRAMES + 1):
                        state.opening[arm] = a0 + (a1 - a0) * k / GRIPPER_FRAMES
                        frames.append(frame(i))
                    state.opening.pop(arm, None)
                    state.grippers[arm] = (("open" if width is None else ("open", float(width))) if cmd == "open"
                                           else "closed" if width is None else float(width))
                elif kind == "grasp":
                    arm, obj = seg.get("arm"), seg.get("object")
                    state.riders.pop(obj, None)
                    q = state.q()
                    G = seg.get("grasp")
                    if G is not None:
                        G = np.asarray(G, float)
                    elif obj in state.objects:
                        G = np.linalg.inv(robot.tool_pose(q, arm)) @ state.objects[obj]
                    if G is not None:
                        # close the fingers onto the object
                        g = robot.group(f"{arm}_gripper")
                        a0 = float(g.get(q)[0])
                        state.objects.pop(obj, None)
                        state.held[arm] = (obj, G)
                        state.grippers[arm] = "closed"
                        a1 = float(g.get(state.q())[0])
                        state.held.pop(arm)
                        state.objects[obj] = robot.tool_pose(q, arm) @ G
                        for k in range(1, GRIPPER_FRAMES + 1):
                            state.opening[arm] = a0 + (a1 - a0) * k / GRIPPER_FRAMES
                            frames.append(frame(i))
                        state.opening.pop(arm, None)
                        state.objects.pop(obj, None)
                        state.held[arm] = (obj, G)
                    frames += [frame(i)] * PAUSE
                elif kind == "carry":  # the listed objects move with the base from now on
                    Binv = np.linalg.inv(state.base_matrix())
                    for obj in seg.get("objects") or []:
                        if obj in state.objects:
                            state.carrying[obj] = Binv @ state.objects.pop(obj)
                elif kind == "set_down":
                    for obj, P in (seg.get("objects") or {}).items():
                        state.carrying.pop(obj, None)
                        if _mat(P) is not None:
                            state.objects[obj] = _mat(P)
                    frames += [frame(i)] * PAUSE
                elif kind == "release":
                    arm, obj = seg.get("arm"), seg.get("object")
                    P = _mat(seg.get("pose"))
                    if P is None:
                        P = state.object_poses().get(obj)
                    state.held.pop(arm, None)
                    if P is not None:
                        state.objects[obj] = P
                    state.grippers[arm] = "open" if seg.get("width") is None else ("open", float(seg["width"]))
                    frames += [frame(i)] * PAUSE
                elif kind == "handover":  # one hand closes on the object, the other lets go
                    src, dst = seg.get("from"), seg.get("to")
                    state.held[dst] = (state.held.pop(src)[0], np.asarray(seg.get("grasp"), float))
                    state.grippers.update({dst: "closed", src: "open"})
                    frames += [frame(i)] * PAUSE
            except Exception:  # one odd segment must not kill the page
                continue
    frames += [frame(max(0, len(steps) - 1))] * (3 * PAUSE)
    return frames


__all__ = ["draw_scene", "animation_frames"]
