"""Articulated environment bodies in the manipulation geometry (a drawer, a door): adding them,
moving their joints with what rides on them, and pulls that drag a link with the gripper."""
from __future__ import annotations

import math
from dataclasses import replace

import numpy as np

from interlayer.refine import Failure, StepOutcome

from .state import RES_ARM, RES_BASE, World, _holding


class Articulated:
    def add_body(self, body, values, riders=(), exact_links=()) -> None:
        """Add an articulated body at joint ``values``; ``riders`` are (object, link) pairs of objects
        resting on its links. Planning pads its elements like fixed obstacles, except ``exact_links``
        (a handle the gripper closes around)."""
        self.bodies[body.name] = body
        values = tuple(float(v) for v in body.check(values))
        self._initial_joints[body.name] = values
        for obj, link in riders:
            self._initial_riders[obj] = (body.name, link)
        pad = 0.0 if not self.padding else self.padding
        exact = [s for s in body.shapes if s.link in exact_links]
        body.add_to(self.cw, values, padding=pad, skip=[s.name for s in exact])
        body.add_to(self.cw, values, only=[s.name for s in exact])
        self._synced = None

    def with_joints(self, world: World, name, values) -> World:
        """``world`` with body ``name`` at joint ``values``; resting objects on its links move along."""
        body = self.bodies[name]
        old = world.joints[name]
        values = tuple(float(v) for v in values)
        objects = dict(world.objects)
        for obj, (b, link) in world.riders.items():
            if b == name and obj in objects:
                objects[obj] = body.carry(objects[obj], link, old, values)
        return replace(world, joints={**world.joints, name: values}, objects=objects)

    def pull_states(self, world, arm, body, path, fine=1):
        """(world, arm vector, joint values) along a pull: ``path`` holds arm vectors followed by the
        body's joint values, interpolated together (steps of RES_ARM / RES_BASE, divided by ``fine``)."""
        n = len(self.robot.group(f"{arm}_arm").dof_names)
        space = self.arm_space[arm]
        for k, (a, b) in enumerate(zip(path, path[1:])):
            a, b = np.asarray(a, float), np.asarray(b, float)
            steps = max(1, math.ceil(max(space.distance(a[:n], b[:n]) / RES_ARM,
                                         float(np.max(np.abs(b[n:] - a[n:]))) / RES_BASE) * fine))
            for i in range(0 if k == 0 else 1, steps + 1):
                p = a + (b - a) * (i / steps)
                yield self.with_joints(world, body, p[n:]).with_arm(arm, p[:n]), p[:n], p[n:]

    def pull_hits(self, world, body, ignore=(), robot=True) -> tuple[set, bool]:
        """(movables in the way, whether something fixed is) at ``world``: the robot and held objects
        (unless ``robot`` is False), the body's moving elements and the objects riding on them, against
        everything else."""
        q = self.sync(world)
        b = self.bodies[body]
        riders = {o for o, (name, _) in world.riders.items() if name == body}
        held = {o for o, _ in world.held.values()}
        others = [o for o in world.objects if o not in riders and o not in ignore]
        hit, fixed = set(), False
        with self.stats.timer("collision_checking"):
            if robot:
                hit = self.cw.colliding_movables(q) - held - set(ignore)
                fixed = self.cw.in_collision(q, movables=False)
            hit |= b.touching(self.cw, world.joints[body], others)
            for o in riders & world.objects.keys():
                hit |= self.cw.objects_overlap(o, world.objects[o]) & set(others)
        return hit, fixed

    def sweep_blockers(self, world, body, values) -> set:
        """Movables that the body's moving elements (and what rides on them) run into when its joints go
        straight from their values in ``world`` to ``values`` (checked every RES_BASE): whatever the arm
        does, such a pull is blocked, so check this first (cheap)."""
        a, b = np.asarray(world.joints[body], float), np.asarray(values, float)
        n = max(1, math.ceil(float(np.max(np.abs(b - a))) / RES_BASE))
        for k in range(1, n + 1):
            hit, _ = self.pull_hits(self.with_joints(world, body, a + (b - a) * k / n), body, robot=False)
            if hit:
                return hit
        return set()

    def pull(self, step, world, arm, body, link, path, segs, kind="pull", fine=1) -> StepOutcome:
        """Drag ``link`` of ``body`` with the gripper along ``path`` (arm vector + joint values per point;
        see pull_states), checked at every state; appends the segment (joint_names: the arm's joints,
        then "<body>/<joint>")."""
        last = world
        for w, _, _ in self.pull_states(world, arm, body, path, fine):
            hit, fixed = self.pull_hits(w, body)
            if hit:
                return StepOutcome(False, failure=Failure("obstruction", tuple(sorted(hit)),
                                                          f"{kind}: the arm or {body} runs into " + ", ".join(sorted(hit))))
            if fixed:
                return StepOutcome(False, failure=Failure("unreachable", (), f"{kind}: collides with fixed obstacles"))
            last = w
        b = self.bodies[body]
        names = list(self.robot.group(f"{arm}_arm").dof_names) + [f"{body}/{j}" for j in b.joint_names]
        seg = self._segment(kind, f"{arm}_arm", [np.asarray(p, float) for p in path], _holding(world))
        seg.update(joint_names=names, body=body, link=link)
        segs.append(seg)
        return StepOutcome(True, last, segs)
