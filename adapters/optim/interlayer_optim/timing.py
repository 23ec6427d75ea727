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

A run that will write its trajectory can time it while it plans (``start_worker``, then ``prefetch``
each path as it is made): a worker process imports toppra and times the paths on another core, and
``time_parameterize`` takes its answers. Same code, same inputs: the same timing as in this process.
"""
from __future__ import annotations

import atexit
import functools
import logging
import os
import pickle
import queue
import struct
import subprocess
import sys
import threading

import numpy as np


CORNER = 0.3  # rad: a sharper turn between two chords of the path is a stop


def time_parameterize(points, vmax, amax, step: float = 0.02) -> list[dict]:
    """``trajectory_msgs``-like points ``{positions, velocities, accelerations, time_from_start}``
    along the polyline ``points`` (an n x dof array), rest to rest, within ``|velocity| <= vmax`` and
    ``|acceleration| <= amax`` per joint. Kept in the user's cache (``interlayer.cache``): the same
    path timed again, e.g. by a run repeated with the same seed, needs no TOPP-RA (nor its import).
    A path sent to the worker (``prefetch``) is the worker's to time: its answer is waited for."""
    job = _job(points, vmax, amax, step)
    timed = _worker.result(job) if _running() and _worker.sent(job) else None
    return _cached(*job) if timed is None else timed


def _job(points, vmax, amax, step) -> tuple:
    P = np.asarray(points, float)
    dof = P.shape[1]
    vmax, amax = np.broadcast_to(np.asarray(vmax, float), (dof,)), np.broadcast_to(np.asarray(amax, float), (dof,))
    return P, vmax, amax, float(step)


def _cached(P, vmax, amax, step) -> list[dict]:
    from interlayer import cache

    key = cache.digest(_code_version(), P.shape, P.tobytes(), vmax.tobytes(), amax.tobytes(), step)
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


# -- the worker: timing on another core while the run plans ------------------------------------------

def start_worker() -> None:
    """Start (once per process) a worker process that imports toppra now and times the paths ``prefetch``
    sends it: the trajectory's timing then overlaps planning instead of following it. It ends with
    this process; if it fails, ``time_parameterize`` times in this process (the same result)."""
    global _worker
    if not _running():
        try:
            _worker = _Worker()
        except OSError:  # e.g. no Python to start: timed in this process, as without a worker
            _worker = None


def prefetch(points, vmax, amax, step: float = 0.02) -> None:
    """Have the worker time this path now (``time_parameterize``'s arguments); nothing without a worker."""
    if _running():
        _worker.submit(_job(points, vmax, amax, step))


_worker = None


def _running() -> bool:
    return _worker is not None and _worker.pid == os.getpid() and not _worker.dead  # a forked child: not its own


class _Worker:
    """The caller's side: jobs go down the worker's stdin from a writer thread (planning never waits for
    the pipe), answers come up its stdout to a reader thread; an answer is found by the path's content
    (the same path made twice is timed once) and unpacked afresh for each caller, who may change it."""

    def __init__(self):
        code = f"import sys; sys.path[:] = {sys.path!r}; from interlayer_optim.timing import _serve; _serve()"
        # Its own session: Ctrl-C reaches only this process, which may still need the worker to write the run.
        self.proc = subprocess.Popen([sys.executable, "-c", code], stdin=subprocess.PIPE, stdout=subprocess.PIPE,
                                     stderr=subprocess.DEVNULL, start_new_session=True)
        self.pid, self.dead, self.stopped = os.getpid(), False, False  # stopped: by this process
        self.ids: dict = {}  # job key -> its number
        self.answers: dict = {}  # number -> the pickled timed points, or None (the worker failed on it)
        self.changed = threading.Condition()
        self.outbox = queue.SimpleQueue()
        for target in (self._write, self._read):
            threading.Thread(target=target, name="timing-worker", daemon=True).start()
        atexit.register(self.stop)

    def sent(self, job) -> bool:
        with self.changed:
            return _key(job) in self.ids

    def submit(self, job) -> int:
        key = _key(job)
        with self.changed:
            if key in self.ids:
                return self.ids[key]
            n = self.ids[key] = len(self.ids)
        self.outbox.put(_frame((n, job)))
        return n

    def result(self, job) -> list[dict] | None:
        """The timed points of a job sent, waiting for the worker; None if it cannot answer."""
        n = self.submit(job)
        with self.changed:
            self.changed.wait_for(lambda: n in self.answers or self.dead)
            answer = self.answers.get(n)
        return None if answer is None else pickle.loads(answer)

    def _write(self) -> None:
        while (data := self.outbox.get()) is not None:
            try:
                self.proc.stdin.write(data)
                self.proc.stdin.flush()
            except (OSError, ValueError):  # it stopped
                break
        self._failed()

    def _read(self) -> None:
        try:
            while (answer := _receive(self.proc.stdout)) is not None:
                n, timed = answer
                with self.changed:
                    self.answers[n] = timed
                    self.changed.notify_all()
        except (OSError, ValueError, EOFError, pickle.UnpicklingError):
            pass
        if not self.stopped:
            try:
                code = self.proc.wait(timeout=5)
            except subprocess.TimeoutExpired:
                code = None
            logging.getLogger("interlayer").warning(
                "the trajectory timing process stopped (exit code %s); this process times the trajectory itself.", code)
        self._failed()

    def _failed(self) -> None:
        with self.changed:
            self.dead = True
            self.changed.notify_all()

    def stop(self) -> None:
        """Nothing it still has to do is needed once this process ends: it is killed, not waited for."""
        if os.getpid() != self.pid:  # a forked child leaving: the worker is its parent's
            return
        self.stopped = True
        self._failed()
        self.outbox.put(None)
        if self.proc.poll() is None:
            self.proc.kill()
            self.proc.wait()


def _key(job) -> tuple:
    return (job[0].shape, *(a.tobytes() for a in job[:3]), job[3])


def _frame(message) -> bytes:
    data = pickle.dumps(message, protocol=pickle.HIGHEST_PROTOCOL)
    return struct.pack("<Q", len(data)) + data


def _receive(stream):
    """The next message, or None at the end of the stream."""
    head = stream.read(8)
    if len(head) < 8:
        return None
    return pickle.loads(stream.read(struct.unpack("<Q", head)[0]))


def _serve() -> None:
    """The worker process: import toppra at once, then time each job (through the cache, as this
    process would) until its input ends. Its stdout carries only answers: stray prints go nowhere."""
    out = os.fdopen(os.dup(1), "wb")
    os.dup2(os.open(os.devnull, os.O_WRONLY), 1)
    _toppra_module()
    while (job := _receive(sys.stdin.buffer)) is not None:
        n, args = job
        try:
            timed = pickle.dumps(_cached(*args), protocol=pickle.HIGHEST_PROTOCOL)
        except Exception:  # answered None: the caller times it itself, and meets the error there
            timed = None
        out.write(_frame((n, timed)))
        out.flush()
