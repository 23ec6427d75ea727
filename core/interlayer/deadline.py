"""The run's deadline, reachable from inside every refinement attempt.

The loop owns one ``Deadline`` per run and makes it current (a context variable: each thread, and so
each concurrent ``solve``, sees its own). Long-running code calls ``check()`` between units of work
(an IK restart, a collision check, a candidate, a planner iteration): once the time limit is over it
raises ``DeadlineExceeded``, which the loop turns into the status "timeout" with the trace kept.
Budgets that decide what a run does count work; the clock only cuts a run short, through here.

``DeadlineExceeded`` derives from ``BaseException`` so that a plugin's ``except Exception`` does not
swallow it (and the fault attribution of ``faults.blame`` lets it through).
"""
from __future__ import annotations

import contextvars
import time
from contextlib import contextmanager


OVER = "the run's time limit is over"


class DeadlineExceeded(BaseException):
    """The run's time limit is over; ``where`` names the plugin call that was running, if any."""

    def __init__(self, message: str = OVER, where: str = ""):
        super().__init__(message)
        self.where = where


class Deadline:
    """``seconds`` from now (``time.perf_counter``). ``calls`` is the stack of plugin calls under way
    (``(plugin, component)``, pushed by ``faults.blame``): the supervisor names the innermost one."""

    def __init__(self, seconds: float):
        self.limit = float(seconds)
        self.start = time.perf_counter()
        self.at = self.start + self.limit
        self.calls: list[tuple[str, str]] = []

    def left(self) -> float:
        return self.at - time.perf_counter()

    def over(self) -> bool:
        return time.perf_counter() > self.at

    def where(self) -> str:
        """The innermost plugin call under way, as 'the plugin 'p''s component', or ''."""
        calls = list(self.calls)  # read from the supervisor's thread: copy first
        if not calls:
            return ""
        plugin, component = calls[-1]
        return f"the plugin '{plugin}''s {component}"

    def check(self) -> None:
        if self.over():
            raise DeadlineExceeded(where=self.where())


_current: contextvars.ContextVar[Deadline | None] = contextvars.ContextVar("interlayer_deadline", default=None)


def current() -> Deadline | None:
    return _current.get()


def check() -> None:
    """Raise ``DeadlineExceeded`` if the current run's time limit is over (nothing outside a run)."""
    d = _current.get()
    if d is not None and time.perf_counter() > d.at:
        raise DeadlineExceeded(where=d.where())


def time_left(default: float = float("inf")) -> float:
    """Seconds left in the current run (``default`` outside a run)."""
    d = _current.get()
    return default if d is None else max(0.0, d.left())


def over() -> bool:
    """Whether the current run's time limit is over (False outside a run)."""
    d = _current.get()
    return d is not None and time.perf_counter() > d.at


@contextmanager
def running(deadline: Deadline):
    """Make ``deadline`` the current one for the block (this thread or task only)."""
    token = _current.set(deadline)
    try:
        yield deadline
    finally:
        _current.reset(token)


@contextmanager
def calling(plugin: str, component: str):
    """Record a plugin call under way on the current deadline (for the supervisor's message)."""
    d = _current.get()
    if d is None:
        yield
        return
    d.calls.append((plugin, component))
    try:
        yield
    finally:
        d.calls.pop()
