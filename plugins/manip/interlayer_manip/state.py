"""The manipulation layer's world model: the World state (base, arm vectors, grippers, resting and
held objects, articulated joints), pose helpers and the constants every module of the layer shares."""
from __future__ import annotations

import math
from dataclasses import dataclass, field, replace

import numpy as np

from interlayer.refine import Failure, StepOutcome

RES_ARM = 0.02  # rad between collision checks when planning an arm (the validator checks 5x finer)
# Planning keeps this far from fixed obstacles (their boxes are padded), so that contacts missed
# between two checks at RES_ARM (the fingertips move up to ~1.6 cm per 0.02 rad) are not real ones;
# the validator uses the unpadded scene.
PADDING = 0.015
# The straight tool lines of grasps and put-downs (approach, raise, lower, retreat) and the grasp and put-down
# configurations they end at are short and checked at the validator's resolution (Refiners._line): they keep
# only this far from fixed obstacles (ManipulationGeometry.tight), so that a grasp beside a wall that clears
# it by a few mm is not shut out by PADDING; the transits and drives that meet them keep PADDING.
LINE_PADDING = 0.003
RES_BASE = 0.01  # m / rad between collision checks when planning the base
# Paths are checked in blocks of FINE_BLOCK points, each block at once by its middle point with a margin
# where it is clear (interlayer.motion.points_valid); MARGIN_SLACK (m) covers Coal's distance tolerance.
MARGIN_SLACK = 1e-4
PRE_GRASP = 0.20  # back-off of the pre-grasp along the tool x axis (approach and retreat length)
LIFT = 0.05  # raise after grasping / height above the put-down spot
OPEN_CLEARANCE = 0.01  # m: a gripper about to grasp or let go opens this much wider than the object (5 mm a side)
FOLLOWS = 1e3  # the velocity / acceleration "limit" of a joint driven by the hand (a drawer's slide)


def rz(a: float) -> np.ndarray:
    c, s = math.cos(a), math.sin(a)
    return np.array([[c, -s, 0, 0], [s, c, 0, 0], [0, 0, 1, 0], [0, 0, 0, 1.0]])


def trans(x, y, z) -> np.ndarray:
    T = np.eye(4)
    T[:3, 3] = (x, y, z)
    return T


def pose4(x, y, z, yaw) -> np.ndarray:
    return trans(x, y, z) @ rz(yaw)


def wrap(a):
    return (a + math.pi) % (2 * math.pi) - math.pi


def is_open(state) -> bool:
    """A gripper state open for grasping or letting go: "open" (fully) or ("open", width in metres)."""
    return state == "open" or (isinstance(state, (tuple, list)) and len(state) == 2 and state[0] == "open")


@dataclass(frozen=True)
class World:
    base: tuple
    arms: dict = field(hash=False)  # arm -> its joint values
    grippers: dict = field(hash=False)  # arm -> "open" (fully) | ("open", width) | "closed" | width (closed on a handle)
    objects: dict = field(hash=False)  # name -> 4x4 pose of objects that are not held
    held: dict = field(hash=False)  # arm -> (object, tool_T_object 4x4)
    # what the last move_base chose its base pose for: object -> put-down pose (4x4), or
    # ("grasp", object, arm) -> (kind, tool pose, waypoints) of a grasp IK found from that base
    tloc: dict = field(hash=False, default_factory=dict)
    # articulated environment bodies: body -> joint values; objects resting on their links move with
    # them: object -> (body, link)
    joints: dict = field(hash=False, default_factory=dict)
    riders: dict = field(hash=False, default_factory=dict)

    def holder(self, name):
        return next((a for a, (o, _) in self.held.items() if o == name), None)

    def with_arm(self, arm, values) -> "World":
        return replace(self, arms={**self.arms, arm: tuple(float(v) for v in values)})

    def with_gripper(self, arm, state) -> "World":
        return replace(self, grippers={**self.grippers, arm: state})

    def to_json(self) -> dict:
        return {"base": list(self.base), "arms": {a: list(v) for a, v in self.arms.items()},
                "grippers": dict(self.grippers), "objects": {k: np.asarray(v).tolist() for k, v in self.objects.items()},
                "held": {a: {"object": o, "grasp": np.asarray(g).tolist()} for a, (o, g) in self.held.items()},
                **({"joints": {b: list(v) for b, v in self.joints.items()}} if self.joints else {})}


def _width(state) -> dict:
    """The "width" field of a gripper event for ``state``: none when fully open or closed."""
    if isinstance(state, str):
        return {}
    return {"width": float(state[1] if is_open(state) else state)}


def _holding(world):
    return {a: o for a, (o, _) in world.held.items()}


def _failure(plan, phase, exclude=None, start_free=False) -> StepOutcome:
    """An obstruction failure names the movables in the way (never the object being picked); ``start_free``:
    the motion did not start where the step started (a straight line of the candidate's own, a motion from
    its end), so the verdict does not depend on the robot's start; nor does a goal that collides."""
    blockers = tuple(o for o in plan.obstructions if o != exclude)
    if blockers:
        return StepOutcome(False, failure=Failure("obstruction", blockers, f"{phase}: {plan.reason}",
                                                  start_free=start_free or plan.goal_blocked))
    return StepOutcome(False, failure=Failure("unreachable", (), f"{phase}: {plan.reason}"))

