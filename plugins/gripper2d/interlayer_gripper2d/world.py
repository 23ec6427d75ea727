"""Gripper-2D geometry: the scene generator, collision checks and the refinement of pick / place.

Units are metres and radians. The table is the square [-1, 1]^2; the gripper moves in SE(2). A
grasp pose puts the gripper frame at the block's centre, its x axis pointing into one block face,
fingers on either side; every action is (transit with the chosen motion planner, straight-line
approach, grasp or release, straight-line retreat).
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field, replace

import numpy as np

from interlayer.motion import ConfigSpace, InterpolatingPlanner, MotionQuery
from interlayer.refine import Failure, StepOutcome
from interlayer.trace import Stats
from interlayer_coal.scene import Body, CollisionScene, Shape, planar

BLOCK = 0.10  # block side
HEIGHT = 0.05  # extrusion of every 2D shape
FINGER, CLEAR = 0.015, 0.01  # finger thickness; clearance between an open finger and the block
HALF_SPAN = BLOCK / 2 + CLEAR + FINGER  # half the gripper's width: 0.075
CORRIDOR_WIDTH = 2 * HALF_SPAN + 0.03  # room for the gripper, not for passing a block: 0.18
WALL = 0.04
SLOT = 0.15  # corridor length per block
TABLE = 1.0  # half side of the table
S_CENTRE, S_SIZE = (-0.55, -0.55), 0.20  # goal region: room for one block
SPACE = ConfigSpace("se2", (-TABLE, -TABLE, -math.pi), (TABLE, TABLE, math.pi), (False, False, True), 0.01)


def gripper_shapes() -> list[Shape]:
    finger_len = BLOCK * 0.9
    fy = BLOCK / 2 + CLEAR + FINGER / 2
    palm_x = -BLOCK / 2 - 0.005 - 0.02
    return [
        Shape("box", (0.04, 2 * HALF_SPAN, HEIGHT), planar(palm_x, 0, 0)),
        Shape("box", (finger_len, FINGER, HEIGHT), planar(-BLOCK / 2 + finger_len / 2 - 0.005, fy, 0)),
        Shape("box", (finger_len, FINGER, HEIGHT), planar(-BLOCK / 2 + finger_len / 2 - 0.005, -fy, 0)),
    ]


def block_shapes() -> list[Shape]:
    return [Shape("box", (BLOCK, BLOCK, HEIGHT), np.eye(4))]


@dataclass(frozen=True)
class World:
    """The low-level state: gripper pose, block poses, the held block and its pose in the gripper."""

    gripper: tuple
    blocks: dict = field(hash=False)
    held: str | None = None

    def to_json(self) -> dict:
        return {"gripper": list(self.gripper), "blocks": {k: list(v) for k, v in self.blocks.items()}, "held": self.held}

    def move_gripper(self, q) -> "World":
        """The gripper at q; a held block keeps its pose relative to the gripper."""
        blocks = self.blocks
        if self.held:
            gx, gy, gth = self.gripper
            bx, by, bth = blocks[self.held]
            c, s = math.cos(q[2] - gth), math.sin(q[2] - gth)
            rx, ry = bx - gx, by - gy
            blocks = dict(blocks)
            blocks[self.held] = (q[0] + c * rx - s * ry, q[1] + s * rx + c * ry, bth + q[2] - gth)
        return World(tuple(float(v) for v in q), blocks, self.held)


@dataclass
class Layout:
    obstructions: int
    walls: dict  # name -> (cx, cy, sx, sy)
    blocks: dict  # name -> (x, y, theta)
    gripper: tuple
    corridor: tuple  # (xmin, xmax, ymin, ymax) inside the walls

    def to_json(self):
        return {"obstructions": self.obstructions, "walls": self.walls, "blocks": self.blocks, "gripper": self.gripper,
                "corridor": self.corridor, "S": {"centre": S_CENTRE, "size": S_SIZE}}


def make_layout(obstructions: int, s_occupied: bool = False) -> Layout:
    """b1 at the closed end of a dead-end corridor, b2..b(k+1) in front of it towards the mouth;
    with ``s_occupied`` a block ``c1`` already stands in S, so placing b1 there fails too."""
    k = obstructions
    length = SLOT * (k + 1) + 0.05
    x_end, y = 0.9, 0.45
    x_mouth = x_end - length
    half = CORRIDOR_WIDTH / 2
    walls = {
        "wall_top": ((x_mouth + x_end + WALL) / 2, y + half + WALL / 2, length + WALL, WALL),
        "wall_bottom": ((x_mouth + x_end + WALL) / 2, y - half - WALL / 2, length + WALL, WALL),
        "wall_end": (x_end + WALL / 2, y, WALL, CORRIDOR_WIDTH + 2 * WALL),
    }
    blocks = {f"b{i + 1}": (x_end - SLOT / 2 - 0.02 - i * SLOT, y, 0.0) for i in range(k + 1)}
    if s_occupied:
        blocks["c1"] = (S_CENTRE[0], S_CENTRE[1], 0.0)
    return Layout(k, walls, blocks, (-0.5, 0.1, 0.0), (x_mouth, x_end, y - half, y + half))


class Gripper2DGeometry:
    """The refinement runtime of Gripper-2D (interlayer.refine.Geometry)."""

    def __init__(self, layout: Layout, margin: float = 0.004):
        self.layout = layout
        self._walls = frozenset(layout.walls)
        self.scene = CollisionScene(margin)  # planning keeps 4 mm away; the validator uses no margin
        for name, (cx, cy, sx, sy) in layout.walls.items():
            self.scene.add(name, [Shape("box", (sx, sy, HEIGHT), np.eye(4))], planar(cx, cy, 0), movable=False)
        for name, pose in layout.blocks.items():
            self.scene.add(name, block_shapes(), planar(*pose), movable=True)
        self.gripper = Body(gripper_shapes())
        self.held_body = Body(block_shapes())
        self.approach = InterpolatingPlanner(name="interpolate")
        self.cartesian = None  # planner.cartesian, set by the run: the approach and retreat planner
        self.stats = Stats()  # the run's, set by it: the generators' collision checks are timed there
        self._synced = None

    # -- world and collision checks ---------------------------------------------------------
    def initial_world(self) -> World:
        return World(tuple(self.layout.gripper), dict(self.layout.blocks))

    def snapshot(self, world: World) -> dict:
        return world.to_json()

    def sync(self, world: World) -> None:
        if world.blocks is not self._synced:  # a reference, not an id: ids of dead worlds are reused
            for name, pose in world.blocks.items():
                if self._synced is None or self._synced.get(name) != pose:
                    self.scene.set_pose(name, planar(*pose))
            self._synced = world.blocks

    def hits(self, world: World, q, movables=True, first=True, skip=()) -> set:
        self.sync(world)
        T = planar(*q)
        skip = {world.held, *skip} if world.held else set(skip)
        found = self.scene.hits(self.gripper, T, skip, movables, first)
        if world.held and not (first and found):
            dx, dy, dth = self._grasp_offset(world)
            found |= self.scene.hits(self.held_body, T @ planar(dx, dy, dth), skip, movables, first)
        return found

    def _grasp_offset(self, world):
        """The held block's pose in the gripper frame."""
        gx, gy, gth = world.gripper
        bx, by, bth = world.blocks[world.held]
        c, s = math.cos(-gth), math.sin(-gth)
        return c * (bx - gx) - s * (by - gy), s * (bx - gx) + c * (by - gy), bth - gth

    def query(self, world: World, start, goal, label: str) -> MotionQuery:
        in_table = SPACE.within_bounds
        return MotionQuery(
            SPACE, np.asarray(start, float), np.asarray(goal, float),
            is_valid=lambda q: in_table(q) and not self.hits(world, q),
            is_valid_static=lambda q: in_table(q) and not self.hits(world, q, movables=False),
            movables_at=lambda q: self.hits(world, q, first=False) - self._walls,
            label=label,
            clearances=lambda q, movables, margin: self.clearances(world, q, movables, margin),
            tool=_planar_tool,
        )

    def clearances(self, world: World, q, movables: bool, margin: float) -> dict:
        """Signed distances of the gripper (and held block) to the scene, less the planning margin;
        no gradients (planners take finite differences in x, y, theta)."""
        from interlayer.motion import Clearance

        self.sync(world)
        T = planar(*q)
        skip = {world.held} if world.held else set()
        margin += self.scene.margin
        found = {("gripper", *k): d for k, d in self.scene.distances(self.gripper, T, margin, skip, movables).items()}
        if world.held:
            dx, dy, dth = self._grasp_offset(world)
            held = self.scene.distances(self.held_body, T @ planar(dx, dy, dth), margin, skip, movables)
            found.update({("held", *k): d for k, d in held.items()})
        return {"|".join(map(str, k)): Clearance(d - self.scene.margin) for k, d in found.items()}

    def static_free(self, q) -> bool:
        return not self.scene.hits(self.gripper, planar(*q), movables=False, first=True)

    def block_fits(self, world: World, name: str, pose, movables: bool) -> bool:
        self.sync(world)
        return not self.scene.hits(self.held_body, planar(*pose), {name}, movables, True)

    # -- refinement of one action ----------------------------------------------------------
    def refine_step(self, step, world: World, candidate, motion) -> StepOutcome:
        pre, at = candidate.waypoints
        picking = step.action == "pick"
        block = step.args[0]
        w = world
        segments = []
        transit = motion.plan(self.query(w, w.gripper, pre, f"{step.action} transit"))
        if not transit.ok:
            return _failure(transit, "transit")
        segments.append({"kind": "transit", "path": [list(q) for q in transit.path], "holding": w.held})
        w = w.move_gripper(pre)
        line = self.cartesian or self.approach
        approach = line.plan(self.query(w, pre, at, f"{step.action} approach"))
        if not approach.ok:
            return _failure(approach, "approach")
        segments.append({"kind": "approach", "path": [list(q) for q in approach.path], "holding": w.held})
        w = w.move_gripper(at)
        if picking:
            w = replace(w, held=block)
            segments.append({"kind": "grasp", "object": block})
        else:  # the block rests where the gripper put it
            w = replace(w, held=None)
            segments.append({"kind": "release", "object": block, "pose": list(w.blocks[block])})
        retreat = line.plan(self.query(w, at, pre, f"{step.action} retreat"))
        if not retreat.ok:
            return _failure(retreat, "retreat")
        segments.append({"kind": "retreat", "path": [list(q) for q in retreat.path], "holding": w.held})
        return StepOutcome(True, w.move_gripper(pre), segments)

    # -- output and validation ----------------------------------------------------------------
    def trajectory_json(self, plan, outcomes) -> dict:
        return {"domain": "gripper2d", "frame": "table, metres / radians (x, y, theta)",
                "initial": self.initial_world().to_json(),
                "steps": [{"action": s.action, "args": list(s.args), "segments": o.segments} for s, o in zip(plan, outcomes)]}

    def validate(self, plan, trajectory: dict) -> list[str]:
        from .validate import validate_trajectory

        return validate_trajectory(Gripper2DGeometry(self.layout, margin=0.0), plan, trajectory)


def _planar_tool(q):
    """The gripper frame is the configuration: pose, and the Jacobian of (linear, angular) velocity."""
    J = np.zeros((6, 3))
    J[0, 0] = J[1, 1] = J[5, 2] = 1.0
    return planar(*q), J


def _failure(plan, phase) -> StepOutcome:
    if plan.obstructions:
        return StepOutcome(False, failure=Failure("obstruction", plan.obstructions, f"{phase}: {plan.reason}"))
    return StepOutcome(False, failure=Failure("unreachable", (), f"{phase}: {plan.reason}"))
