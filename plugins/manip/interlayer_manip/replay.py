"""The robot and the objects at one moment of a plan, replayed from a snapshot or from trajectory.json
(what draw.py shows): base, arms, grippers, objects, held and carried objects, articulated bodies' joints.
Read defensively: only ``geometry.robot`` is required."""
from __future__ import annotations

import math

import numpy as np

def _pose4(x, y, z, yaw=0.0) -> np.ndarray:
    c, s = math.cos(yaw), math.sin(yaw)
    return np.array([[c, -s, 0, x], [s, c, 0, y], [0, 0, 1, z], [0, 0, 0, 1.0]])


def _mat(T):
    try:
        M = np.asarray(T, dtype=float)
    except (TypeError, ValueError):
        return None
    if M.shape == (4, 4):
        return M
    if M.shape == (4,):  # (x, y, z, yaw)
        return _pose4(*M)
    return None


class _State:
    """The robot and object state replayed from trajectory.json / a snapshot."""

    def __init__(self, geometry, world):
        self.g = geometry
        self.robot = geometry.robot
        world = world or {}
        self.base = tuple(float(v) for v in (world.get("base") or (0.0, 0.0, 0.0)))[:3]
        self.arms = {a: tuple(float(v) for v in vals) for a, vals in (world.get("arms") or {}).items()}
        self.grippers = dict(world.get("grippers") or {})
        self.objects = {}
        for k, v in (world.get("objects") or {}).items():
            M = _mat(v)
            if M is not None:
                self.objects[k] = M
        self.held = {}  # arm -> (object, tool_T_object)
        for arm, h in (world.get("held") or {}).items():
            try:
                self.held[arm] = (h["object"], np.asarray(h["grasp"], float))
            except (KeyError, TypeError, ValueError):
                pass
        self.opening = {}  # arm -> finger angle override while a gripper moves
        # articulated bodies (geometry.bodies): joint values, and the objects resting on their links
        self.joints = {b: tuple(float(x) for x in v) for b, v in (world.get("joints") or {}).items()}
        self.riders = dict(getattr(_initial_world(geometry), "riders", {}) or {})
        # objects moving rigidly with the base (a tray carried with both hands): object -> base_T_object
        self.carrying = {k: M for k, v in (world.get("carrying") or {}).items() if (M := _mat(v)) is not None}

    def base_matrix(self):
        x, y, th = self.base
        return _pose4(x, y, 0.0, th)

    def q(self, base=None):
        r = self.robot
        q = r.default_q(self.base if base is None else base)
        for arm, vals in self.arms.items():
            try:
                q = r.set(q, f"{arm}_arm", vals)
            except Exception:
                pass
        for arm in r.arms:
            try:
                g = self.grippers.get(arm)
                if arm in self.opening:
                    q = r.group(f"{arm}_gripper").set(q, [self.opening[arm]])
                elif g == "open":
                    q = r.open_gripper(q, arm)
                elif isinstance(g, (list, tuple)) and g[0] == "open":  # opened as wide as a grasp needs
                    q = r.set_gripper_opening(q, arm, float(g[1]))
                elif isinstance(g, (int, float)):  # closed around a handle
                    q = r.set_gripper_opening(q, arm, float(g))
                elif arm in self.held:
                    q = r.set_gripper_opening(q, arm, max(0.0, self._width(arm)))
                else:
                    q = r.close_gripper(q, arm)
            except Exception:
                pass
        return q

    def _width(self, arm) -> float:
        name, G = self.held[arm]
        fn = getattr(self.g, "grasp_width", None)
        if fn is not None:
            try:
                return float(fn(name, G))
            except Exception:
                pass
        return 0.06

    def object_poses(self, q=None) -> dict:
        out = dict(self.objects)
        if self.carrying:
            B = self.base_matrix()
            out.update({k: B @ rel for k, rel in self.carrying.items()})
        if self.held:
            q = self.q() if q is None else q
            for arm, (name, G) in self.held.items():
                try:
                    out[name] = self.robot.tool_pose(q, arm) @ G
                except Exception:
                    pass
        return out


def _initial_world(geometry):
    fn = getattr(geometry, "initial_world", None)
    try:
        return fn() if fn is not None else None
    except Exception:
        return None


def _bodies(geometry) -> dict:
    return dict(getattr(geometry, "bodies", None) or {})


def _body_poses(geometry, state) -> dict:
    """Scene poses of the moving elements of every articulated body at the state's joint values."""
    out = {}
    for name, body in _bodies(geometry).items():
        values = state.joints.get(name)
        if values is None:
            continue
        poses = body.shape_poses(values)
        out.update({f"bodies/{sh.name}": poses[sh.name] for sh in body.moving_shapes()})
    return out


def _move_joints(geometry, state, body, values) -> None:
    """Set a body's joints; objects resting on its links move along."""
    b = _bodies(geometry).get(body)
    old = state.joints.get(body)
    values = tuple(float(v) for v in values)
    if b is not None and old is not None:
        for obj, (name, link) in state.riders.items():
            if name == body and obj in state.objects:
                state.objects[obj] = b.carry(state.objects[obj], link, old, values)
    state.joints[body] = values


def _initial(geometry):
    fn = getattr(geometry, "initial_world", None)
    if fn is not None:
        try:
            w = fn()
            return w.to_json() if hasattr(w, "to_json") else w
        except Exception:
            pass
    return {"base": list(getattr(getattr(geometry, "layout", None), "base", (0.0, 0.0, 0.0)))}
