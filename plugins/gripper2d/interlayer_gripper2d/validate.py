"""Independent re-check of a Gripper-2D trajectory: continuity, collisions, grasps, goal."""
from __future__ import annotations

import math

import numpy as np

from .world import BLOCK, S_CENTRE, S_SIZE, SPACE, World

FINE = 0.002  # m / rad between checked configurations, 5x finer than planning


def validate_trajectory(geometry, plan, trajectory) -> list[str]:
    errors = []
    init = trajectory.get("initial", {})
    world = geometry.initial_world()
    if init and (list(init.get("gripper", [])) != list(world.gripper)):
        errors.append("the trajectory's initial gripper pose differs from the problem's")
    # the core has checked that steps and plan correspond (interlayer.api.validate)
    for i, (step, data) in enumerate(zip(plan, trajectory.get("steps", []))):
        where = f"step {i} {step}"
        for seg in data.get("segments", []):
            kind = seg.get("kind")
            if kind in ("transit", "approach", "retreat"):
                path = [np.asarray(q, float) for q in seg["path"]]
                if not path or SPACE.distance(path[0], world.gripper) > 1e-6:
                    errors.append(f"{where} {kind}: the path does not start where the gripper is (a jump)")
                    return errors
                if seg.get("holding") != world.held:
                    errors.append(f"{where} {kind}: claims to hold {seg.get('holding')} but holds {world.held}")
                for q in SPACE.densify(path, FINE):
                    if not SPACE.within_bounds(q):
                        errors.append(f"{where} {kind}: configuration {np.round(q, 3).tolist()} leaves the table")
                        return errors
                    hit = geometry.hits(world, q, first=False)
                    if hit:
                        errors.append(f"{where} {kind}: collision with {', '.join(sorted(hit))} at {np.round(q, 3).tolist()}")
                        return errors
                world = world.move_gripper(path[-1])
            elif kind == "grasp":
                b = seg["object"]
                if world.held is not None:
                    errors.append(f"{where}: grasps {b} while holding {world.held}")
                    return errors
                bx, by, bth = world.blocks[b]
                gx, gy, gth = world.gripper
                aligned = abs(((gth - bth) / (math.pi / 2)) - round((gth - bth) / (math.pi / 2))) < 1e-3
                if math.hypot(gx - bx, gy - by) > 1e-3 or not aligned:
                    errors.append(f"{where}: the gripper is not at a face-aligned grasp of {b}")
                    return errors
                world = World(world.gripper, world.blocks, b)
            elif kind == "release":
                b = seg["object"]
                if world.held != b:
                    errors.append(f"{where}: releases {b} but holds {world.held}")
                    return errors
                if SPACE.distance(seg["pose"], world.blocks[b]) > 1e-6:
                    errors.append(f"{where}: {b} is released away from the gripper (teleported)")
                    return errors
                world = World(world.gripper, world.blocks, None)
    goal_block = "b1"
    x, y, _ = world.blocks[goal_block]
    inside = abs(x - S_CENTRE[0]) <= (S_SIZE - BLOCK) / 2 + 1e-6 and abs(y - S_CENTRE[1]) <= (S_SIZE - BLOCK) / 2 + 1e-6
    if world.held == goal_block or not inside:
        errors.append(f"goal not satisfied: {goal_block} is not resting inside S at the end")
    return errors
