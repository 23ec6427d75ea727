"""``trajopt``: joint-space trajectory optimisation by sequential convex programming (after TrajOpt,
Schulman et al. 2013, which the paper used to refine every action).

Waypoints between the fixed start and goal minimise the sum of squared steps subject to a margin
``safety`` from every obstacle, at each waypoint and at two points of each step. Signed distances
and their gradients come from the query (``MotionQuery.clearances``: Coal distances and Pinocchio
Jacobians for the PR2; finite differences here when a domain gives none). Each iteration
linearises them and solves a QP (proxsuite) with l1 penalties on the violations and a trust region;
the penalty grows while constraints stay violated. Initialisations: the straight line, then lines
through random via points, until the time limit. A trajectory counts only if the query's collision
check passes along it at the space's resolution. With movable objects relaxed (GetMPErrors), the
best trajectory is the one whose collisions name the obstructions.
"""
from __future__ import annotations

import numpy as np

from interlayer import deadline as deadlines
from interlayer.errors import UserError
from interlayer.motion import MotionPlanner, segment_valid


BIG = 1e3  # "unbounded" for the QP (1e20 slows proxsuite down)
PAIRS_PER_POINT = 3  # the closest (body, obstacle) pairs constrained at each point: keeps the QPs small
STEP_SAMPLES = (0.5,)  # where clearances are also required between two waypoints


class TrajOptPlanner(MotionPlanner):
    """Options: ``waypoints`` (per trajectory, ends included), ``safety`` (m), ``inits`` (most
    initialisations per query), ``iterations`` (SCP iterations per initialisation): the work of a
    query, the same on any machine (``time_limit`` is accepted but only the run's time limit cuts a
    query short). Random via points come from the run's seed (``planner.seed``)."""

    counts_work = True

    def __init__(self, time_limit=2.0, waypoints=12, safety=0.02, inits=5, iterations=15, options=None):
        super().__init__(name="trajopt", time_limit=time_limit, options=dict(options or {}))
        self.waypoints, self.safety, self.inits, self.iterations = waypoints, safety, inits, iterations

    def _solve(self, query, relaxed, time_limit):
        if query.clearances is None:
            raise UserError(f"The motion planner 'trajopt' needs signed distances, which the query '{query.label}' "
                            f"does not provide; choose an OMPL planner for this domain.")
        space, is_valid = query.space, query.check(relaxed)
        start = np.asarray(query.start, float)
        goal = start + space.difference(start, query.goal)  # unwrapped: circular coordinates stay continuous
        rng = np.random.default_rng(self.seed)
        problem = _SCP(space, lambda q, m: query.clearances(space.interpolate(q, q, 0.0), not relaxed, m),
                       self.safety, self.iterations)
        for k, corners in enumerate(self._inits(space, start, goal, is_valid, rng)[:self.inits]):
            deadlines.check()
            X = _resample(corners, self.waypoints)
            fallback = X if _valid(space, X, is_valid) else None  # an init may be collision-free already
            for _ in range(2):  # optimise; a collision between waypoints doubles them and goes on
                Y = problem.optimise(X)
                if Y is not None and _valid(space, Y, is_valid):
                    fallback = Y
                if fallback is not None or Y is None:
                    break
                X = _refine(Y)
            if fallback is not None:
                if self.stats is not None:
                    self.stats.count("trajopt_inits", k + 1)
                return [space.interpolate(q, q, 0.0) for q in fallback]
        return None

    def _inits(self, space, start, goal, is_valid, rng, samples=40):
        """Initial polylines: the straight line and lines through random collision-free via points,
        those whose share of colliding states (checked at 4x the space's resolution) is smallest first."""
        candidates = [[start, goal]]
        for _ in range(samples * 5):
            via = np.where(space.circular, start + rng.uniform(-np.pi, np.pi, space.dim),
                           rng.uniform(space.lower, space.upper))
            if is_valid(space.interpolate(via, via, 0.0)):
                candidates.append([start, via, goal])
                if len(candidates) > samples:
                    break
        scored = []
        for i, corners in enumerate(candidates):
            line = space.densify(corners, 4 * space.resolution)
            scored.append((sum(not is_valid(space.interpolate(q, q, 0.0)) for q in line) / len(line), i, corners))
        return [corners for _, _, corners in sorted(scored, key=lambda e: e[:2])]


class _SCP:
    """The penalty SCP of one trajectory (fixed ends)."""

    def __init__(self, space, clearances, safety, iterations):
        self.space, self.clearances, self.safety, self.iterations = space, clearances, safety, iterations
        self.lower = np.where(space.circular, -np.inf, space.lower)
        self.upper = np.where(space.circular, np.inf, space.upper)
        self._key, self._terms = None, None  # the last trajectory's terms (evaluated twice per step)
        self._ends = None  # pair -> required distance where the trajectory's ends are closer than safety

    def terms(self, X, margin):
        """Linearised clearance terms: (rows, distances - required distances, gradients) at waypoints
        and step midpoints; a row is ((waypoint index, weight), ...) of the interior waypoints the
        point depends on. A pair closer than ``safety`` at an end of the trajectory, which no
        optimisation can change, is only required not to get closer than there."""
        n = len(X)
        if self._ends is None:
            self._ends = {}
            for q in (X[0], X[-1]):
                for key, c in self.clearances(q, self.safety).items():
                    self._ends[key] = min(self._ends.get(key, self.safety), c.distance)
        rows, dist, grads = [], [], []
        points = [((i, 1.0),) for i in range(1, n - 1)]
        points += [((i, 1 - f), (i + 1, f)) for i in range(n - 1) for f in STEP_SAMPLES]
        for row in points:
            q = sum(w * X[i] for i, w in row)
            near = sorted(((c.distance - self._ends.get(key, self.safety), key, c)
                           for key, c in self.clearances(q, margin).items()), key=lambda e: e[0])
            for excess, key, c in near[:PAIRS_PER_POINT]:
                g = c.gradient if c.gradient is not None else self._gradient(q, key, c.distance, margin)
                rows.append(tuple((i, w) for i, w in row if 0 < i < n - 1))
                dist.append(excess)
                grads.append(np.asarray(g, float))
        return rows, np.array(dist), grads

    def _gradient(self, q, key, d, margin, h=1e-3):
        g = np.zeros(len(q))
        for j in range(len(q)):
            dq = q.copy()
            dq[j] += h
            c = self.clearances(dq, margin + 1.0).get(key)
            g[j] = 0.0 if c is None else (c.distance - d) / h
        return g

    def terms_cached(self, X):
        key = X.tobytes()
        if self._key != key:
            self._key, self._terms = key, self.terms(X, 1.5 * self.safety)
        return self._terms

    def optimise(self, X):
        import proxsuite

        X = np.array(X, float)
        n, dim = X.shape
        m = (n - 2) * dim
        if m == 0:
            return X
        # smoothness: sum of squared steps, as 0.5 x'Hx + c'x over the interior waypoints
        D = np.zeros((n - 1, n))
        D[np.arange(n - 1), np.arange(n - 1)], D[np.arange(n - 1), np.arange(1, n)] = -1.0, 1.0
        L = np.kron(D, np.eye(dim))
        Li, Lb = L[:, dim:-dim], L[:, list(range(dim)) + list(range(m + dim, m + 2 * dim))]
        ends = np.concatenate([X[0], X[-1]])
        H_x, c_x = 2 * Li.T @ Li, 2 * Li.T @ (Lb @ ends)

        def smooth(Y):
            return float(np.sum(np.diff(Y, axis=0) ** 2))

        mu, trust = 300.0, 0.3
        rows, d, grads = self.terms_cached(X)
        merit = smooth(X) + mu * np.maximum(0.0, -d).sum()
        for _ in range(self.iterations):
            deadlines.check()
            k = len(d)
            x0 = X[1:-1].ravel()
            H = np.zeros((m + k, m + k))
            H[:m, :m] = H_x + 1e-6 * np.eye(m)
            H[m:, m:] = 1e-3 * np.eye(k)  # a little curvature on the slacks: proxsuite converges much faster
            g = np.concatenate([c_x, np.full(k, mu)])
            C = np.zeros((k, m + k))  # -g.x - t <= excess - g.x0
            for j, (row, gj) in enumerate(zip(rows, grads)):
                for i, w in row:
                    C[j, (i - 1) * dim:i * dim] = -w * gj
                C[j, m + j] = -1.0
            u = d + C[:, :m] @ x0
            lo = np.concatenate([np.maximum(x0 - trust, np.tile(self.lower, n - 2)), np.zeros(k)])
            hi = np.concatenate([np.minimum(x0 + trust, np.tile(self.upper, n - 2)), np.full(k, BIG)])
            qp = proxsuite.proxqp.dense.QP(m + k, 0, k, True)
            qp.settings.eps_abs = 1e-5
            qp.settings.verbose = False
            qp.init(H, g, None, None, C if k else None, np.full(k, -BIG) if k else None, u if k else None, lo, hi)
            qp.solve()
            if qp.results.info.status != proxsuite.proxqp.QPSolverOutput.PROXQP_SOLVED:
                trust *= 0.5  # numerically infeasible or not converged: a smaller step
                if trust < 1e-3:
                    break
                continue
            x = qp.results.x[:m]
            model = smooth(np.vstack([X[0], x.reshape(-1, dim), X[-1]])) + mu * qp.results.x[m:].sum()
            Y = np.vstack([X[0], x.reshape(-1, dim), X[-1]])
            rows_y, d_y, grads_y = self.terms_cached(Y)
            merit_y = smooth(Y) + mu * np.maximum(0.0, -d_y).sum()
            predicted = merit - model
            if predicted > 1e-9 and (merit - merit_y) > 0.1 * predicted:
                X, rows, d, grads, merit = Y, rows_y, d_y, grads_y, merit_y
                trust = min(1.0, trust * 1.5)
                if predicted < 1e-4 and (d >= 0).all():
                    return X
            else:
                trust *= 0.5
            if trust < 1e-3 or predicted <= 1e-9:
                if (d >= 0).all():  # converged with every margin kept
                    return X
                mu, trust = mu * 10, 0.3  # stuck too close: press harder
                if mu > 1e5:
                    break
                merit = smooth(X) + mu * np.maximum(0.0, -d).sum()
        return X  # the caller's collision check decides (the hulls here are coarser than the checked shapes)


def _valid(space, X, is_valid) -> bool:
    path = [space.interpolate(q, q, 0.0) for q in X]
    return all(segment_valid(space, a, b, is_valid) for a, b in zip(path, path[1:]))


def _resample(points, n):
    """``n`` points evenly spaced along the polyline through ``points``."""
    P = np.asarray(points, float)
    s = np.concatenate([[0.0], np.cumsum(np.linalg.norm(np.diff(P, axis=0), axis=1))])
    if s[-1] <= 0:
        return np.repeat(P[:1], n, axis=0)
    t = np.linspace(0.0, s[-1], n)
    return np.stack([np.interp(t, s, P[:, j]) for j in range(P.shape[1])], axis=1)


def _refine(X):
    """Twice the waypoints: the midpoints inserted."""
    out = [X[0]]
    for a, b in zip(X, X[1:]):
        out += [(a + b) / 2, b]
    return np.array(out)
