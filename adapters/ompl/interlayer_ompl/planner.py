"""OMPL's geometric planners behind interlayer's MotionPlanner (exact solutions only)."""
from __future__ import annotations

import functools
import logging
import math
import threading
import zlib

import numpy as np

from interlayer import deadline as deadlines
from interlayer.motion import MotionPlanner, points_valid

# Planners that keep improving until the time limit unless a cost threshold says "any path will do".
OPTIMIZING = {"RRTstar", "PRM", "PRMstar", "BITstar", "FMT", "BFMT", "InformedRRTstar", "SORRTstar", "AORRTC"}
# Planners (and the path simplifier) that check edges only through MotionValidator.checkMotion(s1, s2),
# so that the query's own segment check (a block of points at a time, see MotionQuery.clear_within)
# can replace OMPL's point-by-point one; others keep OMPL's.
EDGE_CHECKED = {"RRTConnect", "RRT", "PRM", "PRMstar", "RRTstar"}
# A query's budget is work, not seconds, so that its verdict does not depend on the machine's load:
# this many new state validity checks per second of the configured time limit (about what one
# second buys on an idle machine for the PR2's arms; the run's own time limit still cuts a query short).
CHECKS_PER_SECOND = 10000
# Planners that grow their roadmap in a thread of their own: it cannot call Python (the termination
# condition above, the validity check) while solve() holds the GIL, so they keep OMPL's own clock,
# cut to the run's time left: their results depend on the machine's load (and on thread timing anyway).
THREADED = {"PRM", "PRMstar", "LazyPRM", "LazyPRMstar", "SPARS", "SPARStwo"}
# OMPL seeds every RNG it makes (planners', samplers', the simplifier's) from one process-wide
# generator, and its Python bindings reach none of them (RNG.setLocalSeed is for RNGs one holds): a
# query reseeds that generator and makes its RNGs under this lock, so threads' queries do not draw
# each other's seeds. Reentrant: a planner built on this one may plan inside its own query.
_SEEDING = threading.RLock()


def _ompl():
    from ompl import base as ob, geometric as og, util as ou

    ou.setLogLevel(_log_level(ou))
    return ob, og


def _log_level(ou):
    """OMPL logs to stdout at DEBUG level by default, and its errors ("Unable to sample any valid
    states") are part of a search that goes on: shown only when the ``interlayer`` logger is verbose
    (``interlayer plan -v``)."""
    return ou.LogLevel.LOG_WARN if logging.getLogger("interlayer.ompl").isEnabledFor(logging.INFO) else ou.LogLevel.LOG_NONE


class OMPLPlanner(MotionPlanner):
    """``ompl:<Planner>``: options ``time_limit`` (s per query: a budget of ``CHECKS_PER_SECOND``
    state checks per second, the same on any machine), ``simplify`` (bool)."""

    counts_work = True

    def __init__(self, planner: str, time_limit: float = 1.0, simplify: bool = True, options=None):
        super().__init__(name=f"ompl:{planner}", time_limit=time_limit, options=dict(options or {}))
        self.planner = planner
        self.simplify = simplify
        self.queries = 0

    def _seed_rng(self):
        """OMPL's planners draw from RNGs seeded by a process-wide generator: reset it for every
        query, from the run's seed and the query's number, so runs repeat exactly in any process."""
        from ompl import util as ou

        self.queries += 1
        ou.setLogLevel(ou.LogLevel.LOG_NONE)  # OMPL warns that reseeding after first use is not deterministic:
        ou.RNG.setSeed(zlib.crc32(f"{self.seed}:{self.queries}".encode()) or 1)  # it is, for RNGs made after it
        ou.setLogLevel(_log_level(ou))

    def prepare(self):
        _ompl()

    def _space(self, space):
        ob, _ = _ompl()
        if space.kind == "se2":
            s = ob.SE2StateSpace()
            bounds = ob.RealVectorBounds(2)
            for i in range(2):
                bounds.setLow(i, float(space.lower[i]))
                bounds.setHigh(i, float(space.upper[i]))
            s.setBounds(bounds)
            return s
        s = ob.RealVectorStateSpace(space.dim)
        bounds = ob.RealVectorBounds(space.dim)
        for i in range(space.dim):
            lo, hi = (-math.pi, math.pi) if space.circular[i] else (space.lower[i], space.upper[i])
            bounds.setLow(i, float(lo))
            bounds.setHigh(i, float(hi))
        s.setBounds(bounds)
        return s

    def _solve(self, query, relaxed, time_limit):
        clear = query.certificate(relaxed) if self.planner in EDGE_CHECKED else None
        return self._plan(query.space, query.start, query.goal, query.check(relaxed), time_limit, clear)

    def _plan(self, space, start, goal, is_valid, time_limit, clear=None):
        """``clear``: the query's certificate (MotionQuery.certificate); with it, edges are checked a
        block of points at a time (``points_valid``) instead of by OMPL, state by state."""
        with _SEEDING:
            return self._query(space, start, goal, is_valid, time_limit, clear)

    def _query(self, space, start, goal, is_valid, time_limit, clear):
        ob, og = _ompl()
        ompl_space = self._space(space)
        se2 = space.kind == "se2"
        dim = space.dim

        if se2:
            def values(s):
                return s.getX(), s.getY(), s.getYaw()

            def to_state(q):
                st = ompl_space.allocState()
                st.setXY(float(q[0]), float(q[1]))
                # OMPL's SO2 bounds are [-pi, pi): a yaw of exactly pi (a base turned half round, as files
                # give it) is "out of bounds", and every query from or to it fails
                st.setYaw((float(q[2]) + math.pi) % (2 * math.pi) - math.pi)
                return st
        else:
            def values(s):  # index, never iterate: iterating an OMPL state segfaults
                return tuple([s[i] for i in range(dim)])

            def to_state(q):
                st = ompl_space.allocState()
                for i in range(dim):
                    st[i] = float(q[i])
                return st

        def to_vec(s):
            return np.array(values(s))

        # The world does not change during one query, and OMPL checks many states again (rope
        # shortcutting retries the same segments: a third of its checks on the PR2): ask each state once.
        known = {}
        budget = max(1, round(float(time_limit) * CHECKS_PER_SECOND))
        stop: list = []  # the run's deadline (or the supervisor) stopped the query: raised after OMPL returns

        def valid_at(key):
            ok = known.get(key)
            if ok is None:
                if stop:
                    return False
                try:
                    ok = known[key] = bool(is_valid(np.array(key)))  # must be a Python bool
                except BaseException as exc:  # never through OMPL's C++ frames: kept, raised after solve
                    stop.append(exc)
                    return False
            return ok

        asked = [0]

        def done():  # OMPL's termination condition: the work budget spent or the run's time over
            if not stop and deadlines.over():
                stop.append(deadlines.DeadlineExceeded())
            asked[0] += 1  # iterations count too: one that checks no new state (an invalid goal) is work
            return bool(stop) or len(known) >= budget or asked[0] >= budget

        def valid(s):
            return valid_at(values(s))

        self._seed_rng()
        setup = og.SimpleSetup(ompl_space)
        setup.setStateValidityChecker(valid)
        setup.setStartAndGoalStates(to_state(start), to_state(goal))
        si = setup.getSpaceInformation()
        si.setStateValidityCheckingResolution(max(1e-4, space.resolution / ompl_space.getMaximumExtent()))
        if clear is not None:
            def edge_ok(a, b):  # the states on a-b, a excluded, through the same memo
                return points_valid(space.densify([a, b])[1:], lambda p: valid_at(tuple(p.tolist())), clear)

            edges = _edge_validator()(si, values, edge_ok)  # kept alive while OMPL uses it
            si.setMotionValidator(edges)
        planner_cls = getattr(og, self.planner)
        setup.setPlanner(planner_cls(si))
        if self.planner in OPTIMIZING:
            objective = ob.PathLengthOptimizationObjective(si)
            objective.setCostThreshold(ob.Cost(float("inf")))
            setup.setOptimizationObjective(objective)
        if self.planner in THREADED:
            setup.solve(float(min(time_limit, deadlines.time_left())))
        else:
            setup.solve(ob.PlannerTerminationCondition(done))
        if stop:
            raise stop[0]
        if self.stats is not None:
            self.stats.count("motion_checks", len(known))
        if not setup.haveExactSolutionPath():  # an approximate solution is not a path
            return None
        path = setup.getSolutionPath()
        if self.simplify:  # bounded by iterations, not by time: the same path under any load
            # Rope shortcutting: on the PR2 arm about as short as simplifyMax's paths, for a half to a
            # fifth of its collision checks (pr2_pick seeds 0-3)
            setup.getPathSimplifier().ropeShortcutPath(path)
            if stop:
                raise stop[0]
        out = [to_vec(path.getState(i)) for i in range(path.getStateCount())]
        # the ends as the query gave them (a yaw of pi, not OMPL's -pi: the same pose, the caller's numbers)
        out[0], out[-1] = np.array(start, float), np.array(goal, float)
        return out


@functools.cache
def _edge_validator():
    from ompl import base as ob

    class EdgeValidator(ob.MotionValidator):
        """checkMotion(s1, s2) by ``edge_ok(a, b)``, each edge once (rope shortcutting asks again)."""

        def __init__(self, si, values, edge_ok):
            super().__init__(si)
            self._values, self._ok, self._known = values, edge_ok, {}

        def checkMotion(self, s1, s2):
            a, b = self._values(s1), self._values(s2)
            ok = self._known.get((a, b))
            if ok is None:
                ok = self._known[(a, b)] = bool(self._ok(np.array(a), np.array(b)))
            return ok

    return EdgeValidator
