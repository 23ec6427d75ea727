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
        for a, b in zip(path, path[1:]):
            n = max(1, math.ceil(self.distance(a, b) / res))
            out += [self.interpolate(a, b, k / n) for k in range(1, n + 1)]
        return out


@dataclass
class MotionQuery:
    """One motion-planning problem. ``is_valid`` checks everything; ``is_valid_static`` ignores
    movable objects; ``movables_at`` names the movable objects in collision at a configuration."""

    space: ConfigSpace
    start: np.ndarray
    goal: np.ndarray
    is_valid: Callable[[np.ndarray], bool]
    is_valid_static: Callable[[np.ndarray], bool]
    movables_at: Callable[[np.ndarray], set]
    label: str = ""


@dataclass(frozen=True)
class MotionPlan:
    ok: bool
    path: tuple = ()
    obstructions: tuple = ()  # movable objects on the relaxed path (GetMPErrors)
    reason: str = ""
    time: float = 0.0


@dataclass
class MotionPlanner:
    """Template method: ``plan`` validates the query, times it and extracts errors; a planner
    plugin implements only ``_plan`` (return a list of configurations, or None)."""

    name: str = "planner"
    time_limit: float = 1.0
    stats: object = None
    options: dict = field(default_factory=dict)
    deadline: float | None = None  # time.perf_counter() at which the run's time limit ends (set by the loop)
    seed: int = 0  # the run's seed (set by the loop): a randomized planner derives its RNG seeds from it

    def plan(self, query: MotionQuery, time_limit: float | None = None) -> MotionPlan:
        t0 = time.perf_counter()
        limit = self.time_limit if time_limit is None else time_limit
        if self.deadline is not None:
            limit = max(0.0, min(limit, self.deadline - t0))
        space = query.space
        start_ok, goal_ok = query.is_valid(query.start), query.is_valid(query.goal)
        path = None
        if start_ok and goal_ok and space.within_bounds(query.goal):
            path = self._plan(space, query.start, query.goal, query.is_valid, limit)
        if path is not None:
            return MotionPlan(True, tuple(np.asarray(p, float) for p in path), time=time.perf_counter() - t0)
        # GetMPErrors: relax the movable objects and see what the relaxed path runs into.
        if not (query.is_valid_static(query.start) and query.is_valid_static(query.goal)):
            return MotionPlan(False, reason="start or goal collides with fixed obstacles", time=time.perf_counter() - t0)
        if self.deadline is not None:
            limit = max(0.0, min(limit, self.deadline - time.perf_counter()))
        relaxed = self._plan(space, query.start, query.goal, query.is_valid_static, limit)
        if relaxed is None:
            return MotionPlan(False, reason="no path even with movable objects ignored", time=time.perf_counter() - t0)
        blockers: set = set()
        for q in space.densify(relaxed):
            blockers |= query.movables_at(q)
        reason = "blocked by " + ", ".join(sorted(blockers)) if blockers else "planner found no path in time"
        return MotionPlan(False, obstructions=tuple(sorted(blockers)), reason=reason, time=time.perf_counter() - t0)

    def _plan(self, space: ConfigSpace, start, goal, is_valid, time_limit):  # pragma: no cover
        raise NotImplementedError

    def prepare(self) -> None:
        """One-time setup before the run's clock starts (e.g. importing the planning library)."""


def segment_valid(space: ConfigSpace, a, b, is_valid) -> bool:
    """Whether the straight segment a-b is valid at the space's resolution."""
    return all(is_valid(q) for q in space.densify([a, b]))


class InterpolatingPlanner(MotionPlanner):
    """A straight line in configuration space, checked at the space's resolution."""

    def _plan(self, space, start, goal, is_valid, time_limit):
        return [start, goal] if segment_valid(space, start, goal, is_valid) else None
