"""Motion planning as the interface layer needs it: plan, or say which movable objects are in the way.

A domain describes each query (a ``MotionQuery``); any ``MotionPlanner`` answers it. The base
class implements the paper's GetMPErrors (Sec. II-B): when no collision-free path exists, plan
again with movable objects ignored and report the movable objects that relaxed path collides with.
"""
from __future__ import annotations

import math
import time
from dataclasses import dataclass, field
from typing import Callable

import numpy as np

from . import deadline as deadlines


@dataclass(frozen=True)
class ConfigSpace:
    """A configuration space: ``se2`` (x, y, theta) or ``vector`` (joint values).

    ``circular[i]`` marks angles that wrap around (theta, continuous joints); their bounds are
    ignored. ``resolution`` is the largest step between collision checks along a path.
    """

    kind: str
    lower: tuple
    upper: tuple
    circular: tuple
    resolution: float = 0.02

    @property
    def dim(self) -> int:
        return len(self.lower)

    def difference(self, a, b) -> np.ndarray:
        d = np.asarray(b, float) - np.asarray(a, float)
        for i, c in enumerate(self.circular):
            if c:
                d[i] = (d[i] + math.pi) % (2 * math.pi) - math.pi
        return d

    def distance(self, a, b) -> float:
        return float(np.linalg.norm(self.difference(a, b)))

    def interpolate(self, a, b, t: float) -> np.ndarray:
        q = np.asarray(a, float) + t * self.difference(a, b)
        for i, c in enumerate(self.circular):
            if c:
                q[i] = (q[i] + math.pi) % (2 * math.pi) - math.pi
        return q

    def within_bounds(self, q) -> bool:
        return all(c or lo - 1e-9 <= v <= hi + 1e-9 for v, lo, hi, c in zip(q, self.lower, self.upper, self.circular))

    def densify(self, path, resolution: float | None = None) -> list[np.ndarray]:
        """Waypoints no further apart than ``resolution`` (both ends included)."""
        res = resolution or self.resolution
        out = [np.asarray(path[0], float)]
        circular = [i for i, c in enumerate(self.circular) if c]
        for a, b in zip(path, path[1:]):
            d = self.difference(a, b)
            n = max(1, math.ceil(float(np.linalg.norm(d)) / res))
            # interpolate(a, b, k / n) for k = 1..n, all at once (collision checks walk these points)
            points = np.asarray(a, float) + (np.arange(1, n + 1) / n)[:, None] * d
            if circular:
                points[:, circular] = (points[:, circular] + math.pi) % (2 * math.pi) - math.pi
            out += list(points)
        return out


@dataclass(frozen=True)
class Clearance:
    """Signed distance (m, negative when penetrating) from a moving body to one obstacle, and its
    gradient with respect to the configuration (None: the planner takes finite differences)."""

    distance: float
    gradient: np.ndarray | None = None


@dataclass
class MotionQuery:
    """One motion-planning problem. ``is_valid`` checks everything; ``is_valid_static`` ignores
    movable objects; ``movables_at`` names the movable objects in collision at a configuration.

    Optional, for planners that need more than collision checks:

    * ``clearances(q, movables, margin)``: ``{pair name: Clearance}`` for every (moving body,
      obstacle) pair closer than ``margin`` at ``q`` (movable obstacles only if ``movables``), used by
      optimising planners (``trajopt``);
    * ``tool(q)``: ``(pose, jacobian)`` of the end effector: its 4x4 world pose and the 6 x dim
      Jacobian of its (linear, angular) velocity in world axes, used by Cartesian planners;
    * ``clear_within(radius, relaxed)``: a check ``clear(q)`` that is true only if every configuration
      within ``radius`` (configuration-space distance) of ``q`` is valid (``is_valid_static`` if
      ``relaxed``), e.g. the bodies clear of each other by a margin that bounds how far they move; a
      path is then checked a block of points at a time (see ``points_valid``).
    """

    space: ConfigSpace
    start: np.ndarray
    goal: np.ndarray
    is_valid: Callable[[np.ndarray], bool]
    is_valid_static: Callable[[np.ndarray], bool]
    movables_at: Callable[[np.ndarray], set]
    label: str = ""
    clearances: Callable[[np.ndarray, bool, float], dict] | None = None
    tool: Callable[[np.ndarray], tuple] | None = None
    clear_within: Callable[[float, bool], Callable[[np.ndarray], bool] | None] | None = None

    def check(self, relaxed: bool) -> Callable[[np.ndarray], bool]:
        return self.is_valid_static if relaxed else self.is_valid

    def certificate(self, relaxed: bool) -> Callable[[np.ndarray], bool] | None:
        """``clear_within`` for a block of BLOCK points at the space's resolution (None if not given)."""
        if self.clear_within is None:
            return None
        return self.clear_within(self.space.resolution * (BLOCK // 2), relaxed)

    def segment_checker(self, relaxed: bool) -> Callable[[np.ndarray, np.ndarray], bool]:
        """``ok(a, b)``: the straight segment a-b is valid at the space's resolution (``a`` itself
        is not checked), a block of points at a time where the certificate allows."""
        check, clear, space = self.check(relaxed), self.certificate(relaxed), self.space
        return lambda a, b: points_valid(space.densify([a, b])[1:], check, clear)


@dataclass(frozen=True)
class MotionPlan:
    ok: bool
    path: tuple = ()
    obstructions: tuple = ()  # movable objects on the relaxed path (GetMPErrors)
    reason: str = ""
    time: float = 0.0
    goal_blocked: bool = False  # the obstructions collide with the goal itself: any start fails on them


@dataclass
class MotionPlanner:
    """Template method: ``plan`` validates the query, tries the straight line, times it and extracts
    errors; a planner plugin implements only ``_plan`` (return a list of configurations, or None)."""

    name: str = "planner"
    time_limit: float = 1.0
    stats: object = None
    options: dict = field(default_factory=dict)
    seed: int = 0  # the run's seed (set by the loop): a randomized planner derives its RNG seeds from it
    # A planner that searches (sampling, optimisation): a collision-free straight line answers without
    # the search, and so does a goal that collides with movables (see ``plan``). False for planners
    # that draw one path of a fixed shape (a straight line, a tool line): they are quick anyway.
    searches = True
    # A planner whose budget counts work (``time_limit`` converted to iterations or checks) gets the
    # configured limit unchanged, so that its verdict does not depend on the time left; it must check
    # the run's deadline itself (``interlayer.deadline``). Others get at most the time left.
    counts_work = False

    def plan(self, query: MotionQuery, time_limit: float | None = None, straight: bool = True) -> MotionPlan:
        """``straight=False``: run the search even if the straight line is collision-free (a caller
        that found it touching an obstacle between two checks asks for another path)."""
        deadlines.check()
        t0 = time.perf_counter()
        limit = self.time_limit if time_limit is None else time_limit
        if not self.counts_work:
            limit = min(limit, deadlines.time_left())
        space, start, goal = query.space, query.start, query.goal
        start_ok, goal_ok = query.is_valid(start), query.is_valid(goal)
        path = None
        if start_ok and goal_ok and space.within_bounds(goal):
            if self.searches and straight and query.segment_checker(False)(start, goal):
                path = [start, goal]  # no planner needed (a sampling planner takes long to find it)
            else:
                path = self._solve(query, False, limit)
                deadlines.check()
        if path is not None:
            return MotionPlan(True, tuple(np.asarray(p, float) for p in path), time=time.perf_counter() - t0)
        # GetMPErrors: relax the movable objects and see what the relaxed path runs into.
        if not (query.is_valid_static(start) and query.is_valid_static(goal)):
            return MotionPlan(False, reason="start or goal collides with fixed obstacles", time=time.perf_counter() - t0)
        relaxed = None
        if self.searches and query.segment_checker(True)(start, goal):
            relaxed = [start, goal]
        elif self.searches and not goal_ok and space.within_bounds(goal):
            # Decided early: every path ends in the goal, so what collides with it obstructs; a relaxed
            # path through a narrow passage (into a shelf) would cost the planner's whole time limit.
            blockers = query.movables_at(goal)
            if blockers:
                return MotionPlan(False, obstructions=tuple(sorted(blockers)), time=time.perf_counter() - t0,
                                  reason="the goal configuration collides with " + ", ".join(sorted(blockers)),
                                  goal_blocked=True)
        if relaxed is None:
            if not self.counts_work:
                limit = min(limit, deadlines.time_left())
            relaxed = self._solve(query, True, limit)
        deadlines.check()  # a search cut by the run's deadline decides nothing
        if relaxed is None:
            return MotionPlan(False, reason="no path even with movable objects ignored", time=time.perf_counter() - t0)
        dense = space.densify(relaxed)
        blockers: set = set()
        for q in dense:
            blockers |= query.movables_at(q)
        if not blockers and start_ok and goal_ok and space.within_bounds(goal) and all(map(query.is_valid, dense)):
            # the first search ran out of time; the relaxed one found a path that avoids the movables too
            return MotionPlan(True, tuple(np.asarray(p, float) for p in relaxed), time=time.perf_counter() - t0)
        reason = "blocked by " + ", ".join(sorted(blockers)) if blockers else "planner found no path in time"
        return MotionPlan(False, obstructions=tuple(sorted(blockers)), reason=reason, time=time.perf_counter() - t0)

    def _solve(self, query: MotionQuery, relaxed: bool, time_limit: float):
        """A path for ``query`` (movable objects ignored if ``relaxed``) or None. Planners that need
        more of the query than its validity check (clearances, tool kinematics) override this."""
        return self._plan(query.space, query.start, query.goal, query.check(relaxed), time_limit)

    def _plan(self, space: ConfigSpace, start, goal, is_valid, time_limit):  # pragma: no cover
        raise NotImplementedError

    def prepare(self) -> None:
        """One-time setup before the run's clock starts (e.g. importing the planning library)."""


def segment_valid(space: ConfigSpace, a, b, is_valid) -> bool:
    """Whether the straight segment a-b is valid at the space's resolution."""
    return all(map(_checked(is_valid), space.densify([a, b])))


def _checked(is_valid):
    """``is_valid`` that first checks the run's deadline (a long sweep of collision checks stops at it)."""
    def valid(q):
        deadlines.check()
        return is_valid(q)

    return valid


BLOCK, WAIT = 5, 2  # see points_valid


def points_valid(points, is_valid, clear=None, block: int = BLOCK, wait: int = WAIT) -> bool:
    """Whether every configuration of ``points`` (consecutive points of a path, evenly spaced) is valid.

    With ``clear``, a check certifying every configuration within ``block // 2`` spacings of its
    argument, the points are taken ``block`` at a time and a block whose middle point is clear needs no
    other check; next to an obstacle (the middle point not clear) the block's points are checked one
    by one, and so are those of the next ``wait`` blocks (they are probably near it too)."""
    is_valid = _checked(is_valid)
    if clear is None:
        return all(map(is_valid, points))
    waiting = 0
    for k in range(0, len(points), block):
        part = points[k:k + block]
        if not waiting:
            if clear(part[len(part) // 2]):
                continue
            waiting = wait
        else:
            waiting -= 1
        if not all(map(is_valid, part)):
            return False
    return True


class InterpolatingPlanner(MotionPlanner):
    """A straight line in configuration space, checked at the space's resolution."""

    searches = False

    def _plan(self, space, start, goal, is_valid, time_limit):
        return [start, goal] if segment_valid(space, start, goal, is_valid) else None
