"""A watch over the planning thread: a plugin call that overruns the time limit is stopped.

Cooperative checks (``deadline.check``) stop well-behaved code at the limit. A pose generator that
sleeps or loops, or a motion planner that never returns, does not check: past the limit plus
``INJECT_AFTER`` the supervisor raises ``DeadlineExceeded`` inside the planning thread (delivered at
its next Python instruction, so a busy Python loop stops), naming the plugin call under way. A call
stuck in C code or in a sleep does not run Python instructions: past ``STOP_AFTER`` the supervisor
hands the run so far to ``on_stuck`` (the CLI writes the run folder and ends the process; the API has
no way to stop a thread and lets the call return).
"""
from __future__ import annotations

import ctypes
import threading
import time

from .deadline import Deadline, DeadlineExceeded

# fractions of the time limit past it, each at least the given seconds
INJECT_AFTER, INJECT_MIN = 0.03, 0.1
STOP_AFTER, STOP_MIN = 0.06, 0.2


def grace(limit: float) -> float:
    """How long past the deadline the supervisor waits before it raises in the planning thread."""
    return max(INJECT_AFTER * limit, INJECT_MIN)


def _async_raise(thread_id: int, exc_type) -> None:
    ctypes.pythonapi.PyThreadState_SetAsyncExc(ctypes.c_ulong(thread_id), ctypes.py_object(exc_type) if exc_type else None)


class Supervisor:
    """Watches one run: ``start()`` from the planning thread, ``stop()`` when the run ends (in a
    ``finally``); ``stopped`` is the plugin call it had to stop ('' if none), ``stuck_result`` a
    function giving the run's Result so far (for ``on_stuck``)."""

    def __init__(self, deadline: Deadline, on_stuck=None, stuck_result=None):
        self.deadline, self.on_stuck, self.stuck_result = deadline, on_stuck, stuck_result
        self.stopped = ""
        self.injected = False
        self._done = threading.Event()
        self._lock = threading.Lock()
        self._target = threading.get_ident()
        self._thread = None

    def start(self) -> "Supervisor":
        self._target = threading.get_ident()
        self._thread = threading.Thread(target=self._watch, name="interlayer-supervisor", daemon=True)
        self._thread.start()
        return self

    def _wait_until(self, fraction: float, least: float) -> bool:
        """Wait until ``fraction`` of the limit (at least ``least`` s) past the deadline; True if the run ended."""
        at = self.deadline.at + max(fraction * self.deadline.limit, least)  # see grace()
        return self._done.wait(max(0.0, at - time.perf_counter()))

    def _watch(self):
        if self._wait_until(INJECT_AFTER, INJECT_MIN):
            return
        with self._lock:
            if self._done.is_set():
                return
            self.stopped = self.deadline.where() or "the interface layer"
            self.injected = True
            _async_raise(self._target, DeadlineExceeded)
        if self.on_stuck is None or self._wait_until(STOP_AFTER, STOP_MIN):
            return
        with self._lock:
            if self._done.is_set():
                return
            self._done.set()  # the planning thread is stuck in C code or a sleep: it does not come back in time
        self.on_stuck(self.stuck_result(self.stopped))

    def stop(self):
        """The run ended: no exception will be raised in the planning thread after this returns."""
        with self._lock:
            self._done.set()
            if self.injected:  # raised but maybe not delivered yet: withdraw it
                _async_raise(self._target, None)
