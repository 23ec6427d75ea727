"""Self-collision pairs never checked: the description's SRDF and ``skip`` list, else computed by sampling
as MoveIt's setup assistant does, and cached (``interlayer.cache``, keyed by the URDF's content and the
description).

Sampling: pairs of adjacent links (one hangs from the other by one joint), pairs in collision at the
default configuration or in nearly every sample (they always touch), and pairs never in collision in
``SAMPLES`` random configurations (they cannot reach each other) are skipped; the rest are checked.
"""
from __future__ import annotations

import numpy as np
import pinocchio as pin

__all__ = ["skip_pairs", "sampled_skips", "SAMPLES"]

SAMPLES = 2000
ALWAYS = 0.95  # a pair in collision in this share of the samples always touches
_VERSION = 1  # bump when the method changes: cached answers of the old one are ignored


def skip_pairs(robot) -> str:
    """Remove the pairs never checked from ``robot.collision_model`` (all pairs added); their source:
    ``"srdf"``, ``"listed"``, ``"srdf+listed"`` or ``"sampled"``."""
    desc, model, gm = robot.description, robot.model, robot.collision_model
    sources = []
    if desc.srdf is not None:
        pin.removeCollisionPairs(model, gm, str(desc.srdf))
        sources.append("srdf")
    if desc.skip is not None:
        _remove(robot, {frozenset(p) for p in desc.skip})
        sources.append("listed")
    if sources:
        return "+".join(sources)
    _remove(robot, {frozenset(p) for p in _cached_skips(robot)})
    return "sampled"


def _link(model, geometry) -> str:
    return model.frames[geometry.parentFrame].name


def _remove(robot, skip: set) -> None:
    model, gm = robot.model, robot.collision_model
    objs = gm.geometryObjects
    doomed = [(cp.first, cp.second) for cp in gm.collisionPairs
              if frozenset((_link(model, objs[cp.first]), _link(model, objs[cp.second]))) in skip]
    for a, b in doomed:  # (the vector's elements shift as pairs go: copy their indices first)
        gm.removeCollisionPair(pin.CollisionPair(a, b))


def _cached_skips(robot) -> list[list[str]]:
    from interlayer import cache

    desc = robot.description
    key = cache.digest("selfcollision", _VERSION, SAMPLES, ALWAYS, desc.urdf.read_bytes(), desc.hold,
                       tuple((a.joints, a.gripper.joints) for a in desc.arms))
    found = cache.load("selfcollision", key)
    if isinstance(found, list):
        return found
    skips = sampled_skips(robot)
    cache.store("selfcollision", key, skips)
    return skips


def sampled_skips(robot, samples: int = SAMPLES, seed: int = 0) -> list[list[str]]:
    """Link pairs (sorted names) to skip, found by sampling ``samples`` configurations (see the module)."""
    from .gripper import parent_link

    model, gm = robot.model, robot.collision_model
    objs = gm.geometryObjects
    pairs = {}  # link pair -> indices of its geometry pairs
    for k, cp in enumerate(gm.collisionPairs):
        pairs.setdefault(tuple(sorted((_link(model, objs[cp.first]), _link(model, objs[cp.second])))), []).append(k)
    adjacent = set()  # a link and the nearest link above it that has geometry (links without any are skipped)
    with_geometry = {g.parentFrame for g in objs}
    for g in objs:
        up = parent_link(model, g.parentFrame)
        while up and up not in with_geometry:
            up = parent_link(model, up)
        if up:
            adjacent.add(frozenset((model.frames[g.parentFrame].name, model.frames[up].name)))
    data, gd = model.createData(), pin.GeometryData(gm)

    def colliding(q) -> set:
        pin.computeCollisions(model, data, gm, gd, q, False)
        hit = {k for k in range(len(gm.collisionPairs)) if gd.collisionResults[k].isCollision()}
        return {p for p, ks in pairs.items() if hit.intersection(ks)}

    at_default = colliding(robot.default_q())
    rng = np.random.default_rng(seed)
    movable = [g for name, g in robot.groups.items() if name != "base"]
    counts = dict.fromkeys(pairs, 0)
    for _ in range(samples):
        q = robot.neutral_q()
        for g in movable:
            g.write(q, g.sample(rng))
        for p in colliding(q):
            counts[p] += 1
    skip = [p for p in pairs if frozenset(p) in adjacent or p in at_default
            or counts[p] == 0 or counts[p] >= ALWAYS * samples]
    return sorted(list(p) for p in skip)
