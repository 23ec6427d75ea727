"""Motion queries of the manipulation geometry: the planners' MotionQuery for an arm or the base,
collision checks of states, lines and paths (at the planning and the validator's resolution)."""
from __future__ import annotations

import math
import time

import numpy as np

from interlayer.motion import BLOCK as FINE_BLOCK
from interlayer.motion import Clearance, MotionQuery, points_valid

from .state import MARGIN_SLACK


class MotionQueries:
    def _timed(self, fn, acc):
        def wrapped(v):
            t0 = time.perf_counter()
            try:
                return fn(v)
            finally:
                acc[0] += time.perf_counter() - t0
        return wrapped

    def arm_query(self, world, arm, start, goal, label, acc) -> MotionQuery:
        q = self.sync(world)
        group = self.robot.group(f"{arm}_arm")
        held = {o for o, _ in world.held.values()}
        valid = self.cw.checker_for(f"{arm}_arm", q)
        static = self.cw.checker_for(f"{arm}_arm", q, movables=False)

        def movables_at(v):
            return self.cw.colliding_movables(group.set(q, v)) - held

        def tool(v):
            return self.robot.tool_jacobian(group.set(q, v), arm)

        return MotionQuery(self.arm_space[arm], np.asarray(start, float), np.asarray(goal, float),
                           is_valid=self._timed(lambda v: group.within_bounds(v) and valid(v), acc),
                           is_valid_static=self._timed(lambda v: group.within_bounds(v) and static(v), acc),
                           movables_at=self._timed(movables_at, acc), label=label,
                           clearances=self._clearances(q, f"{arm}_arm", acc), tool=tool)

    def base_query(self, world, start, goal, label, acc) -> MotionQuery:
        q = self.sync(world)
        group = self.robot.group("base")
        space = self.base_space
        valid = self.cw.checker_for("base", q)
        static = self.cw.checker_for("base", q, movables=False)
        return MotionQuery(space, np.asarray(start, float), np.asarray(goal, float),
                           is_valid=self._timed(lambda v: space.within_bounds(v) and valid(v), acc),
                           is_valid_static=self._timed(lambda v: space.within_bounds(v) and static(v), acc),
                           movables_at=self._timed(lambda v: self.cw.colliding_movables(group.set(q, v)), acc),
                           label=label, clearances=self._clearances(q, "base", acc),
                           clear_within=self._clear_within(q, "base", acc))

    def _clear_within(self, q, group_name, acc):
        """MotionQuery.clear_within (``_certificate``). Given for the base only: its drives mostly run in
        the open (r040: a fifth of the checks, half the time), while an arm among clutter is rarely clear
        by the 7 cm a block needs, and a check with a margin costs about three plain ones."""
        def clear_within(radius, relaxed):
            clear = self._certificate(q, group_name, radius, movables=not relaxed)
            return clear and self._timed(clear, acc)

        return clear_within

    def _certificate(self, q, group_name, radius, movables=True):
        """A check that the group's bodies are clear of everything by the distance they can move within
        ``radius`` of its argument (``CollisionWorld.motion_bound``): then all of that is collision-free.
        None for a group without a bound."""
        margin = self.cw.motion_bound(group_name) * radius + MARGIN_SLACK
        return self.cw.checker_for(group_name, q, movables=movables, margin=margin) if math.isfinite(margin) else None

    def _clearances(self, q, group_name, acc):
        """Signed distances with analytic gradients (Coal + Pinocchio Jacobians) for trajopt."""
        group = self.robot.group(group_name)

        def clearances(v, movables, margin):
            t0 = time.perf_counter()
            found = self.cw.clearances(group.set(q, v), group_name, margin, movables=movables)
            acc[0] += time.perf_counter() - t0
            return {k: Clearance(d, g) for k, (d, g) in found.items()}

        return clearances

    def static_path_ok(self, world, arm, path, ignore=()) -> bool:
        """The piecewise-straight arm path avoids fixed obstacles (checked at RES_ARM)."""
        with self.stats.timer("collision_checking"):  # the sync (the robot's configuration) is the check's set-up
            q = self.sync(world)
            group = self.robot.group(f"{arm}_arm")
            check = self.cw.checker_for(f"{arm}_arm", q, ignore=tuple(ignore), movables=False)
            return all(check(v) for v in self.arm_space[arm].densify(list(path)) if group.within_bounds(v))

    def in_collision(self, world, movables=True) -> bool:
        with self.stats.timer("collision_checking"):
            return self.cw.in_collision(self.sync(world), movables=movables)

    def hand_free(self, world, arm, T, ignore=(), movables=False) -> bool:
        """The hand alone (opened as in ``world``) with its tool frame at ``T`` touches no fixed obstacle
        (nor movables, if asked): a grasp that fails this needs no IK."""
        with self.stats.timer("collision_checking"):
            return not self.cw.hand_collides(self.sync(world), arm, T, ignore, movables)

    def hand_hits(self, world, arm, T, ignore=(), movables=False) -> set:
        """The fixed obstacles (and movables, if asked) that ``hand_free`` finds the hand touching."""
        with self.stats.timer("collision_checking"):
            return self.cw.hand_hits(self.sync(world), arm, T, ignore, movables)

    def fine_ok(self, world, group, path, acc=None) -> bool:
        """The path is collision-free at the validator's resolution (5x finer than planning).

        Its points are taken FINE_BLOCK at a time (``points_valid``): no point of a block is more than
        FINE_BLOCK // 2 steps from the middle one, so if the middle one is clear of everything by the
        distance a body can move in that many steps (``CollisionWorld.motion_bound``), the whole block
        is collision-free."""
        q = self.sync(world)
        check = self.cw.checker_for(group, q)
        space = self.base_space if group == "base" else self.arm_space[self.robot.arm_of(group)]
        t0 = time.perf_counter()
        step = space.resolution / 5
        ok = points_valid(space.densify(list(path), step), check, self._certificate(q, group, step * (FINE_BLOCK // 2)))
        if acc is not None:
            acc[0] += time.perf_counter() - t0
        return ok

    def _movables_on_line(self, w, arm, path, acc) -> set:
        """Movables the arm touches along the piecewise-straight ``path`` (at the planning resolution)."""
        q = self.sync(w)
        group = self.robot.group(f"{arm}_arm")
        held = {o for o, _ in w.held.values()}
        t0 = time.perf_counter()
        hit = set()
        for v in self.arm_space[arm].densify([np.asarray(p, float) for p in path]):
            hit |= self.cw.colliding_movables(group.set(q, v))
        acc[0] += time.perf_counter() - t0
        return hit - held
