"""Pose generators for Gripper-2D (Sec. IV-B2): grasps aligned with block faces, put-down spots.

Each yields ``Candidate(waypoints=(pre_pose, pose))``: the gripper first reaches ``pre_pose``
with the configured motion planner, then moves in a straight line to ``pose``.
"""
from __future__ import annotations

import math

import numpy as np

from interlayer.refine import Candidate, Infeasible

from .world import BLOCK, S_CENTRE, S_SIZE, TABLE

APPROACH = (0.15, 0.3, 0.5, 0.7, 0.9, 1.1, 1.3)  # candidate back-off distances of the pre-pose


def _backoff(pose, d):
    x, y, th = pose
    return (x - d * math.cos(th), y - d * math.sin(th), th)


def _wrap(a):
    return (a + math.pi) % (2 * math.pi) - math.pi


def _approaches(geometry, pose, rng, per_pose=2):
    """Pre-poses behind ``pose`` that are clear of fixed obstacles, nearest first, jittered."""
    out = []
    for d in APPROACH:
        d = d + rng.uniform(-0.02, 0.02)
        pre = _backoff(pose, d)
        with geometry.stats.timer("collision_checking"):
            free = all(geometry.static_free(_backoff(pose, t)) for t in np.arange(0.0, d, 0.02)) and \
                all(geometry.static_free((pre[0] + dx, pre[1] + dy, pre[2]))
                    for dx in (-0.05, 0.05) for dy in (-0.05, 0.05))
        if free:
            out.append(pre)
            if len(out) == per_pose:
                break
    return out


def pick(problem, step, world, rng):
    block = step.args[0]
    geometry = problem.geometry
    bx, by, bth = world.blocks[block]
    sides = list(range(4))
    rng.shuffle(sides)
    found = False
    for k in sides:
        yaw = _wrap(bth + k * math.pi / 2)  # gripper x axis points into the face opposite this side
        grasp = (bx, by, yaw)
        with geometry.stats.timer("collision_checking"):
            free = geometry.static_free(grasp)
        if not free:
            continue
        for pre in _approaches(geometry, grasp, rng):
            found = True
            yield Candidate((pre, grasp), {step.args[2]: grasp}, f"side {k}, pre-grasp at {_fmt(pre)}")
    if not found and block in problem.goal:
        raise Infeasible(f"no face of {block} can be reached by the gripper past the fixed obstacles")


def place(problem, step, world, rng, samples: int = 12):
    block, region = step.args[0], step.args[1]
    geometry = problem.geometry
    gx, gy, gth = world.gripper
    offset = world.blocks[block][2] - gth  # the held block's yaw in the gripper frame
    margin = BLOCK / 2 + 0.01
    n = 0
    for _ in range(samples * 20):
        if n >= samples:
            break
        if region == "S":  # inside S, whatever is there already (PDObstructs is learned)
            half = S_SIZE / 2 - BLOCK / 2 - 0.01
            x, y = S_CENTRE[0] + rng.uniform(-half, half), S_CENTRE[1] + rng.uniform(-half, half)
        else:  # elsewhere on the table, away from S and from other objects
            x, y = rng.uniform(-TABLE + 0.25, TABLE - 0.25, size=2)
            if abs(x - S_CENTRE[0]) < S_SIZE / 2 + margin and abs(y - S_CENTRE[1]) < S_SIZE / 2 + margin:
                continue
        block_pose = (float(x), float(y), float(_wrap(rng.choice([0.0, math.pi / 2]) + rng.uniform(-0.1, 0.1))))
        gripper = (block_pose[0], block_pose[1], _wrap(block_pose[2] - offset))
        with geometry.stats.timer("collision_checking"):
            free = geometry.block_fits(world, block, block_pose, movables=region != "S") and \
                geometry.static_free(gripper)
        if not free:
            continue
        for pre in _approaches(geometry, gripper, rng, per_pose=1):
            n += 1
            yield Candidate((pre, gripper), {"block_pose": block_pose, step.args[3]: gripper},
                            f"{block} at {_fmt(block_pose)}")


def _fmt(p):
    return "(" + ", ".join(f"{v:.2f}" for v in p) + ")"
