"""Independent re-check of a manipulation trajectory.json: continuity (no teleports), joint limits, collisions
with everything (held objects included) at a resolution 5x finer than planning, grasps consistent with
what is held, released objects resting where the gripper put them, and the goal at the end."""
from __future__ import annotations

import math
from dataclasses import replace

import numpy as np

from .scene import REST_GAP, table_top
from .state import RES_ARM, RES_BASE, is_open

FINE_ARM, FINE_BASE = RES_ARM / 5, RES_BASE / 5
POS_TOL, ROT_TOL = 2e-3, math.radians(2)
START_TOL = 1e-6
SPEED_TOL = 0.02  # relative slack on velocity and acceleration limits (discretisation of the timing)
GRIP_TOL = 0.006  # m: between IK waypoints a pull's tool strays a little from the handle


def _pose_close(A, B, pos=POS_TOL, rot=ROT_TOL):
    A, B = np.asarray(A, float), np.asarray(B, float)
    d = np.linalg.inv(A) @ B
    angle = math.acos(max(-1.0, min(1.0, (np.trace(d[:3, :3]) - 1) / 2)))
    return np.linalg.norm(A[:3, 3] - B[:3, 3]) <= pos and angle <= rot


def validate_trajectory(geometry, plan, trajectory, rules=None) -> list[str]:
    """``rules``: a domain's additions (a module or object), each optional: ``event(geometry, world, seg,
    at) -> (world, why)`` for segment kinds this module does not know, ``motion(geometry, world, seg, at)
    -> why`` before each motion, ``rests(geometry, world, obj, P) -> why`` in place of "resting upright on
    the table", and ``goal(geometry, world) -> [why]`` in place of this module's goal check; ``kinds``: segment
    kinds that ``event`` checks even when they carry points (a domain's own motions, e.g. a push)."""
    errors: list[str] = []
    rule = lambda name: getattr(rules, name, None)  # noqa: E731
    robot = geometry.robot
    world = geometry.initial_world()
    init = trajectory.get("initial", {})
    if init and list(init.get("base", [])) != list(world.base):
        errors.append("the trajectory's initial base pose differs from the problem's")
    # the core has checked that steps and plan correspond (interlayer.api.validate)
    for i, (step, data) in enumerate(zip(plan, trajectory.get("steps", []))):
        where = f"step {i} {step}"
        for k, seg in enumerate(data.get("segments", [])):
            kind = seg.get("kind")
            at = f"{where} segment {k} ({kind})"
            why = rule("motion")(geometry, world, seg, at) if "points" in seg and rule("motion") else None
            if why:
                return errors + [why]
            if kind in (getattr(rules, "kinds", None) or ()):
                world, why = rule("event")(geometry, world, seg, at)
                if why:
                    return errors + [why]
            elif "points" in seg and seg.get("body"):
                world, why = _check_pull(geometry, world, seg, at)
                if why:
                    return errors + [why]
            elif "points" in seg:
                world, why = _check_motion(geometry, world, seg, at)
                if why:
                    return errors + [why]
            elif kind == "gripper":
                arm = seg["arm"]
                if seg["command"] == "open":
                    opened, why = _opening(robot, seg, at)
                    if why:
                        return errors + [why]
                    world = world.with_gripper(arm, opened)
                else:
                    if arm in world.held:
                        return errors + [f"{at}: closes the {arm} gripper while it holds {world.held[arm][0]}"]
                    width = seg.get("width", "closed")  # a width: closed around something that is no object (a handle)
                    if width != "closed" and not (isinstance(width, (int, float)) and 0 < width < robot.max_gripper_opening):
                        return errors + [f"{at}: gripper width {width!r} is not a number of metres the gripper can close to"]
                    world = world.with_gripper(arm, width)
                if geometry.in_collision(world):
                    pairs = geometry.cw.collision_pairs(geometry.sync(world))
                    return errors + [f"{at}: the {arm} gripper collides after '{seg['command']}': {_pairs(pairs)}"]
            elif kind == "articulation":
                body = seg.get("body")
                if body not in world.joints:
                    return errors + [f"{at}: unknown articulated body {body!r}"]
                if not np.allclose(seg.get("positions", []), world.joints[body], atol=1e-6):
                    return errors + [f"{at}: claims {body} at {seg.get('positions')} but the motions left it at "
                                     f"{list(world.joints[body])}"]
            elif kind == "grasp":
                arm, obj = seg["arm"], seg["object"]
                if arm in world.held:
                    return errors + [f"{at}: grasps {obj} while the {arm} arm holds {world.held[arm][0]}"]
                if obj not in world.objects:
                    return errors + [f"{at}: grasps {obj}, which is not resting anywhere (held?)"]
                if not is_open(world.grippers[arm]):
                    return errors + [f"{at}: grasps {obj} with a closed gripper"]
                q = geometry.config(world)
                tool = robot.tool_pose(q, arm)
                G = np.asarray(seg["grasp"], float)
                if not _pose_close(tool @ G, world.objects[obj]):
                    return errors + [f"{at}: {obj} is not at the gripper (the claimed grasp puts it "
                                     f"{np.linalg.norm((tool @ G)[:3, 3] - world.objects[obj][:3, 3]):.3f} m away)"]
                tool_in_obj = np.linalg.inv(G)[:3, 3]  # the point between the finger pads, in the object frame
                if not _inside(geometry.specs[obj], tool_in_obj):
                    return errors + [f"{at}: the tool frame is at {np.round(tool_in_obj, 3).tolist()} in {obj}'s frame, "
                                     f"outside the object: not a grasp"]
                width = geometry.grasp_width(obj, G)
                if width > robot.max_gripper_opening:
                    return errors + [f"{at}: {obj} is {width:.3f} m across the fingers, wider than the gripper opens"]
                if width > _width_of(robot, world.grippers[arm]):
                    return errors + [f"{at}: {obj} is {width:.3f} m across the fingers, wider than the {arm} gripper was "
                                     f"opened ({_width_of(robot, world.grippers[arm]):.3f} m)"]
                objects = {n: v for n, v in world.objects.items() if n != obj}
                world = replace(world, objects=objects, held={**world.held, arm: (obj, G)},
                                grippers={**world.grippers, arm: "closed"},
                                riders={k: v for k, v in world.riders.items() if k != obj})
            elif kind == "release":
                arm, obj = seg["arm"], seg["object"]
                if world.held.get(arm, (None,))[0] != obj:
                    return errors + [f"{at}: releases {obj} but the {arm} arm holds "
                                     f"{world.held.get(arm, ('nothing',))[0]}"]
                q = geometry.config(world)
                P = robot.tool_pose(q, arm) @ world.held[arm][1]
                if not _pose_close(P, seg["pose"]):
                    return errors + [f"{at}: {obj} is released away from the gripper (teleported)"]
                why = rule("rests")(geometry, world, obj, P) if rule("rests") else _on_table(geometry, obj, P)
                if why:
                    return errors + [f"{at}: {obj} is released at {np.round(P[:3, 3], 3).tolist()}, {why}"]
                opened, why = _opening(robot, seg, at)
                width = geometry.grasp_width(obj, world.held[arm][1])
                if why or width > _width_of(robot, opened):
                    return errors + [why or f"{at}: the {arm} gripper opens to {_width_of(robot, opened):.3f} m, "
                                            f"narrower than {obj} across the fingers ({width:.3f} m): it does not let go"]
                held = {a: v for a, v in world.held.items() if a != arm}  # release = open the gripper + detach
                world = replace(world, objects={**world.objects, obj: P}, held=held,
                                grippers={**world.grippers, arm: opened})
                if geometry.in_collision(world):
                    pairs = geometry.cw.collision_pairs(geometry.sync(world))
                    return errors + [f"{at}: {obj} released into a collision: {_pairs(pairs)}"]
            elif rule("event"):
                world, why = rule("event")(geometry, world, seg, at)
                if why:
                    return errors + [why]
            else:
                return errors + [f"{at}: unknown segment kind {kind!r}"]
    errors += rule("goal")(geometry, world) if rule("goal") else _check_goal(geometry, world)
    return errors


def _opening(robot, seg, at):
    """(gripper state, '') of an open or release event: fully open, or open to its "width"; or (None, why)."""
    if "width" not in seg:
        return "open", ""
    width = seg["width"]
    if not isinstance(width, (int, float)) or not 0 < width <= robot.max_gripper_opening + 1e-9:
        return None, f"{at}: gripper width {width!r} is not a number of metres the gripper can open to"
    return ("open", float(width)), ""


def _width_of(robot, state) -> float:
    """How far apart the pads of an open gripper are."""
    return robot.max_gripper_opening if state == "open" else float(state[1])


def _on_table(geometry, obj, P) -> str:
    """'' if an object at P rests upright on the table, else why not."""
    spec = geometry.specs[obj]
    bottom = P[2, 3] - spec.height / 2
    xmin, xmax, ymin, ymax = geometry.layout.regions["table"]
    on_table = xmin <= P[0, 3] <= xmax and ymin <= P[1, 3] <= ymax
    top = table_top(geometry.layout)
    if not (upright(P) and on_table and top <= bottom <= top + REST_GAP + 0.005):
        return "not resting upright on the table"
    return ""


def upright(P) -> bool:
    return P[2, 2] > math.cos(math.radians(2))


def _check_motion(geometry, world, seg, at):
    robot = geometry.robot
    group_name = seg.get("group")
    if group_name == "base":
        space, names, fine = geometry.base_space, ["x", "y", "theta"], FINE_BASE
    elif group_name == f"{robot.arm_of(group_name)}_arm":
        arm = robot.arm_of(group_name)
        space, names, fine = geometry.arm_space[arm], list(robot.group(group_name).dof_names), FINE_ARM
    else:
        return world, f"{at}: unknown joint group {group_name!r}"
    if list(seg.get("joint_names", [])) != names:
        return world, f"{at}: joint names {seg.get('joint_names')} are not the {group_name} joints"
    holding = {a: o for a, (o, _) in world.held.items()}
    if seg.get("holding", holding) != holding:
        return world, f"{at}: claims to hold {seg.get('holding')} but holds {holding}"
    points = seg["points"]
    if not points:
        return world, f"{at}: an empty trajectory"
    times = [p["time_from_start"] for p in points]
    if any(b < a for a, b in zip(times, times[1:])):
        return world, f"{at}: time stamps go backwards"
    path = [np.asarray(p["positions"], float) for p in points]
    if any(len(p) != len(names) for p in path):
        return world, f"{at}: a point has the wrong number of positions"
    current = np.asarray(world.base if group_name == "base" else world.arms[arm], float)
    if space.distance(path[0], current) > START_TOL:
        return world, (f"{at}: starts at {np.round(path[0], 3).tolist()} but the {group_name} is at "
                       f"{np.round(current, 3).tolist()} (a teleport)")
    group = robot.group(group_name)

    def limits(q):
        if group_name != "base" and not group.within_bounds(q):
            bad = [f"{n}={v:.3f} not in [{lo:.3f}, {hi:.3f}]" for n, v, lo, hi, c in
                   zip(names, q, group.lower, group.upper, group.circular) if not c and not lo - 1e-9 <= v <= hi + 1e-9]
            return f"{at}: joint limit violated: {', '.join(bad)}"
        if group_name == "base" and not space.within_bounds(q):
            return f"{at}: the base leaves the workspace at {np.round(q, 3).tolist()}"
        return None

    for q in path:  # waypoints first: a bad waypoint is named even if the way there collides
        why = limits(q)
        if why:
            return world, why
    for q in space.densify(path, fine):
        why = limits(q)
        if why:
            return world, why
        w = replace(world, base=tuple(q)) if group_name == "base" else world.with_arm(arm, q)
        if geometry.in_collision(w):
            pairs = geometry.cw.collision_pairs(geometry.sync(w))
            return world, f"{at}: collision {_pairs(pairs)} at {np.round(q, 3).tolist()}"
    why = _check_timing(geometry, space, group_name, names, points, path, at)
    if why:
        return world, why
    last = path[-1]
    world = replace(world, base=tuple(float(v) for v in last)) if group_name == "base" else world.with_arm(arm, last)
    return world, None


def _check_timing(geometry, space, group_name, names, points, path, at):
    """Velocities and accelerations within the limits: the reported ones, and those implied by the
    positions and time stamps (a chord run faster than the limit is too fast whatever is claimed)."""
    vmax, amax = geometry.limits(group_name)
    vtol, atol = vmax * (1 + SPEED_TOL) + 1e-6, amax * (1 + SPEED_TOL) + 1e-6
    times = np.array([p["time_from_start"] for p in points], float)
    for k in range(len(path) - 1):
        step, dt = np.abs(space.difference(path[k], path[k + 1])), times[k + 1] - times[k]
        if (step > 1e-9).any() and (dt <= 0 or (step > vtol * dt).any()):
            j = int(np.argmax(step / vtol))
            speed = "instantly" if dt <= 0 else f"at {step[j] / dt:.3f}"
            return (f"{at}: too fast between points {k} and {k + 1}: {names[j]} moves {speed} "
                    f"(limit {vmax[j]:.3f}) per second")
    for key, limit, tol, word in (("velocities", vmax, vtol, "velocity"), ("accelerations", amax, atol, "acceleration")):
        for k, p in enumerate(points):
            if key not in p:
                continue
            value = np.abs(np.asarray(p[key], float))
            if len(value) != len(names):
                return f"{at}: point {k} has {len(value)} {key} for {len(names)} joints"
            if (value > tol).any():
                j = int(np.argmax(value / tol))
                return f"{at}: point {k}: {names[j]} {word} {value[j]:.3f} exceeds its limit {limit[j]:.3f}"
    if all("velocities" in p for p in points):
        # From velocity v0 to v1 in dt with |acceleration| <= a, a joint moves (v0 + v1) / 2 dt, give or
        # take at most a dt^2 / 4; and its velocity changes by at most a dt.
        v = np.array([p["velocities"] for p in points], float)
        for k in range(len(points) - 1):
            dt = times[k + 1] - times[k]
            if dt <= 0:
                continue
            change = np.abs(v[k + 1] - v[k])
            off = np.abs(space.difference(path[k], path[k + 1]) - (v[k] + v[k + 1]) / 2 * dt)
            if (change > atol * dt).any() or (off > atol * dt * dt / 4 + 1e-6).any():
                j = int(np.argmax(np.maximum(change / (atol * dt), off / (atol * dt * dt / 4 + 1e-6))))
                return (f"{at}: {names[j]} accelerates faster than its limit {amax[j]:.3f} between points {k} and "
                        f"{k + 1} (its positions, velocities and times need more)")
    return None


def _check_pull(geometry, world, seg, at):
    """An arm dragging a link of an articulated body: the arm's joints and the body's move together, the
    gripper (closed around the link's handle) keeps its pose on the link, and nothing collides: the
    robot, the body's moving elements and the objects riding on them, at every fine step."""
    robot = geometry.robot
    body = seg["body"]
    b = geometry.bodies.get(body)
    group_name = seg.get("group", "")
    if b is None or body not in world.joints:
        return world, f"{at}: unknown articulated body {body!r}"
    arm = robot.arm_of(group_name)
    if group_name != f"{arm}_arm":
        return world, f"{at}: a pull must move an arm, not {group_name!r}"
    names = list(robot.group(group_name).dof_names) + [f"{body}/{j}" for j in b.joint_names]
    if list(seg.get("joint_names", [])) != names:
        return world, f"{at}: joint names {seg.get('joint_names')} are not {names}"
    if isinstance(world.grippers[arm], str) or arm in world.held:
        return world, f"{at}: the {arm} gripper pulls {body} while {world.grippers[arm]} (it must be closed on the handle)"
    path = [np.asarray(p["positions"], float) for p in seg.get("points", [])]
    if not path or any(len(p) != len(names) for p in path):
        return world, f"{at}: empty, or a point has the wrong number of positions"
    n = len(names) - len(b.joint_names)
    current = np.concatenate([np.asarray(world.arms[arm], float), np.asarray(world.joints[body], float)])
    if np.max(np.abs(path[0] - current)) > START_TOL:
        return world, f"{at}: starts at {np.round(path[0], 3).tolist()} but the arm and {body} are at {np.round(current, 3).tolist()}"
    for p in path:
        if not robot.group(group_name).within_bounds(p[:n]) or np.any(p[n:] < b.lower - 1e-9) or np.any(p[n:] > b.upper + 1e-9):
            return world, f"{at}: joint limit violated at {np.round(p, 3).tolist()}"
    link = seg.get("link")
    grip = None
    last = world
    for w, v, values in geometry.pull_states(world, arm, body, path, fine=5):
        q = geometry.config(w)
        link_T_tool = np.linalg.inv(b.link_pose(values, link)) @ robot.tool_pose(q, arm)
        if grip is None:
            grip = link_T_tool
        elif not _pose_close(grip, link_T_tool, pos=GRIP_TOL, rot=math.radians(3)):
            return world, (f"{at}: the gripper slips on {body}'s {link} by "
                           f"{np.linalg.norm(grip[:3, 3] - link_T_tool[:3, 3]):.3f} m at {body} {np.round(values, 3).tolist()}")
        hit, fixed = geometry.pull_hits(w, body)
        if hit or fixed:
            what = ", ".join(sorted(hit)) or _pairs(geometry.cw.collision_pairs(geometry.sync(w), movables=False))
            return world, f"{at}: collision with {what} at {body} {np.round(values, 3).tolist()}"
        last = w
    return last, None


def _check_goal(geometry, world) -> list[str]:
    layout = geometry.layout
    t = layout.target
    if layout.goal == "hold":
        if world.holder(t) is None:
            return [f"goal not satisfied: {t} is not held at the end"]
        return []
    if world.holder(t) is not None:
        return [f"goal not satisfied: {t} is still held at the end"]
    if layout.goal == "tidy" and world.held:
        return [f"goal not satisfied: {', '.join(o for o, _ in world.held.values())} still held at the end"]
    xmin, xmax, ymin, ymax = layout.regions["goal_spot"]
    x, y = world.objects[t][0, 3], world.objects[t][1, 3]
    if not (xmin <= x <= xmax and ymin <= y <= ymax):
        return [f"goal not satisfied: {t} rests at ({x:.3f}, {y:.3f}), outside goal_spot"]
    return []


def _inside(spec, p, tol=0.005) -> bool:
    if spec.shape == "cylinder":
        return math.hypot(p[0], p[1]) <= spec.size[0] + tol and abs(p[2]) <= spec.size[1] / 2 + tol
    return all(abs(p[i]) <= spec.size[i] / 2 + tol for i in range(3))


def _pairs(pairs):
    return ", ".join(f"{a}-{b}" for a, b in sorted(set(pairs))) or "(none listed)"
