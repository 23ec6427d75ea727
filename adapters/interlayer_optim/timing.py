"""Time-optimal timing of a joint path under velocity and acceleration limits (TOPP-RA, ``toppra``).

The geometric path is the piecewise-linear one the planner checked for collisions. It is cut at its
corners (where the direction turns by more than ``CORNER``; a controller must stop there), each
piece densified (``step`` apart), a cubic spline through those points time-parameterised by TOPP-RA
from rest to rest, and the result reported at the path's own points: the same positions, and so the
same collision checks between them, with ``time_from_start``, velocities and accelerations a
controller can follow (between two points, the average speed and the change of velocity per second
stay within the limits, as they do everywhere along the timing). Where
TOPP-RA reports a numerical failure, that piece is timed chord by chord with the time-optimal
rest-to-rest trapezoid instead (exact for straight lines, slower elsewhere).
"""
from __future__ import annotations

import functools

import numpy as np


CORNER = 0.3  # rad: a sharper turn between two chords of the path is a stop


def time_parameterize(points, vmax, amax, step: float = 0.02) -> list[dict]:
    """``trajectory_msgs``-like points ``{positions, velocities, accelerations, time_from_start}``
    along the polyline ``points`` (an n x dof array), rest to rest, within ``|velocity| <= vmax`` and
    ``|acceleration| <= amax`` per joint. Kept in the user's cache (``interlayer.cache``): the same
    path timed again, e.g. by a run repeated with the same seed, needs no TOPP-RA (nor its import)."""
    from interlayer import cache

    P = np.asarray(points, float)
    dof = P.shape[1]
    vmax, amax = np.broadcast_to(np.asarray(vmax, float), (dof,)), np.broadcast_to(np.asarray(amax, float), (dof,))
    key = cache.digest(_code_version(), P.shape, P.tobytes(), vmax.tobytes(), amax.tobytes(), float(step))
    timed = cache.load("timing", key)
    if timed is None:
        timed = _time_parameterize(P, vmax, amax, step)
        cache.store("timing", key, timed)
    return timed


@functools.cache
def _code_version() -> tuple:
    """What the timing depends on besides its inputs: this module's code, toppra's and numpy's versions."""
    import importlib.metadata
    from pathlib import Path

    try:
        toppra = importlib.metadata.version("toppra")
    except importlib.metadata.PackageNotFoundError:
        toppra = None
    return Path(__file__).read_bytes(), toppra, np.__version__


def _time_parameterize(P, vmax, amax, step) -> list[dict]:
    dof = P.shape[1]
    keep = [0] + [i for i in range(1, len(P)) if np.linalg.norm(P[i] - P[i - 1]) > 1e-9]
    P = P[keep]
    if len(P) < 2:
        return [_point(P[0], np.zeros(dof), np.zeros(dof), 0.0)]
    out = []
    for piece in _pieces(P):
        try:
            dense, vertices = _dense(piece, step)
            timed = _toppra(dense, vmax, amax, vertices)
        except RuntimeError:
            timed = _trapezoids(piece, step, vmax, amax)
        t0 = out[-1]["time_from_start"] if out else 0.0
        for p in timed[1 if out else 0:]:
            p["time_from_start"] = float(round(p["time_from_start"] + t0, 6))
            out.append(p)
    return out


def _pieces(P):
    """The polyline cut at its corners."""
    d = np.diff(P, axis=0)
    d /= np.linalg.norm(d, axis=1, keepdims=True)
    cuts = [0] + [i for i in range(1, len(P) - 1) if float(d[i - 1] @ d[i]) < np.cos(CORNER)] + [len(P) - 1]
    return [P[a:b + 1] for a, b in zip(cuts, cuts[1:])]


def _trapezoids(P, step, vmax, amax):
    """Rest-to-rest time-optimal timing of each chord (bang-coast-bang in the chord's parameter)."""
    out = [_point(P[0], np.zeros(len(vmax)), np.zeros(len(vmax)), 0.0)]
    for a, b in zip(P, P[1:]):
        delta = np.abs(b - a)
        moving = delta > 1e-12
        v, acc = np.min(vmax[moving] / delta[moving]), np.min(amax[moving] / delta[moving])  # in chord fraction
        ramp = v / acc
        duration = 2 * ramp + (1 - v * ramp) / v if v * ramp < 1 else 2 * np.sqrt(1 / acc)
        out.append(_point(b, np.zeros(len(vmax)), np.zeros(len(vmax)), out[-1]["time_from_start"] + duration))
    return out


@functools.cache
def _toppra_module():
    """toppra, imported once, without what a run never uses: its plotting helpers' matplotlib.pyplot
    (a third of the import; toppra's modules get a stand-in that imports it if a plot is drawn), and
    its search for optional solvers on disk at every TOPPRA instance (one answer per process)."""
    import sys
    import types

    class _Pyplot(types.ModuleType):
        def __getattr__(self, name):
            import importlib

            return getattr(importlib.import_module("matplotlib.pyplot"), name)

    stand_in = "matplotlib.pyplot" not in sys.modules
    if stand_in:
        sys.modules["matplotlib.pyplot"] = _Pyplot("matplotlib.pyplot")
    try:
        import toppra
        import toppra.solverwrapper
    finally:
        if stand_in:
            del sys.modules["matplotlib.pyplot"]
    toppra.solverwrapper.available_solvers = functools.cache(toppra.solverwrapper.available_solvers)
    toppra.setup_logging("ERROR")
    return toppra


@functools.lru_cache(maxsize=64)
def _constraints(vmax: tuple, amax: tuple):
    """The joint velocity and acceleration constraints (the same for every path of a robot's group)."""
    from toppra import constraint

    vmax, amax = np.array(vmax), np.array(amax)
    return [constraint.JointVelocityConstraint(np.stack([-vmax, vmax], axis=1)),
            constraint.JointAccelerationConstraint(np.stack([-amax, amax], axis=1))]


def _toppra(P, vmax, amax, report):
    """The timed points of the dense path ``P`` at the indices ``report`` (its own points)."""
    toppra = _toppra_module()
    import toppra.algorithm as algo

    dof = P.shape[1]
    s = np.concatenate([[0.0], np.cumsum(np.linalg.norm(np.diff(P, axis=0), axis=1))])
    midpoint = len(P) == 2
    if midpoint:  # a spline needs three points: add the midpoint (not reported)
        P, s = np.array([P[0], (P[0] + P[1]) / 2, P[1]]), np.array([0.0, s[1] / 2, s[1]])
    path = toppra.SplineInterpolator(s, P, bc_type="natural")
    grid = np.unique(np.concatenate([s, (s[1:] + s[:-1]) / 2]))  # the points themselves, and midpoints
    instance = algo.TOPPRA(_constraints(tuple(vmax.tolist()), tuple(amax.tolist())), path, gridpoints=grid,
                           parametrizer="ParametrizeConstAccel")
    sdd, sd, _ = instance.compute_parameterization(0.0, 0.0)
    if sd is None:
        raise RuntimeError("TOPP-RA found no feasible timing for the path")
    sd = np.maximum(sd, 0.0)
    # constant path acceleration between grid points: dt = 2 ds / (sd_i + sd_i+1)
    ds = np.diff(grid)
    speed_sum = sd[:-1] + sd[1:]
    dt = np.where(speed_sum > 1e-12, 2 * ds / np.maximum(speed_sum, 1e-12), np.sqrt(2 * ds / np.maximum(np.abs(sdd), 1e-12)))
    t = np.concatenate([[0.0], np.cumsum(dt)])
    knots = [0, 2] if midpoint else list(report)  # the reported points are knots: exactly on the checked path
    s = s[knots]
    at = np.searchsorted(grid, s)
    dq, ddq = path(s, 1), path(s, 2)
    sdd_at = np.concatenate([sdd, [sdd[-1] if len(sdd) else 0.0]])[at]
    out = []
    for k, i in enumerate(at):
        vel = dq[k] * sd[i]
        acc = dq[k] * sdd_at[k] + ddq[k] * sd[i] ** 2
        out.append(_point(P[knots[k]], vel, acc, t[i]))
    out[0]["velocities"] = out[-1]["velocities"] = [0.0] * dof
    return out


def _point(q, v, a, t):
    return {"positions": [float(x) for x in q], "velocities": [float(x) for x in v],
            "accelerations": [float(x) for x in a], "time_from_start": float(round(t, 6))}


def _dense(P, step):
    """The polyline with points inserted at most ``step`` apart, and the indices of its own points."""
    out, vertices = [P[0]], [0]
    for a, b in zip(P, P[1:]):
        n = max(1, int(np.ceil(np.linalg.norm(b - a) / step)))
        out += [a + (b - a) * k / n for k in range(1, n + 1)]
        vertices.append(len(out) - 1)
    return np.array(out), vertices
