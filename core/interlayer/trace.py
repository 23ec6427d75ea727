"""Timings and the trace of a run: every decision of the loop, for 'why did it do that?'."""
from __future__ import annotations

import os
import time
from contextlib import contextmanager

_IMPORTED = time.perf_counter()


def process_start() -> float:
    """When this process started, on the ``time.perf_counter`` clock: from ``/proc`` on Linux (the
    interpreter's start-up and every import included), else when interlayer was imported."""
    try:
        with open("/proc/self/stat") as f:
            after_name = f.read().rsplit(")", 1)[1].split()
        age = time.clock_gettime(time.CLOCK_BOOTTIME) - int(after_name[19]) / os.sysconf("SC_CLK_TCK")
    except (OSError, ValueError, IndexError, AttributeError):  # not Linux
        return _IMPORTED
    return time.perf_counter() - max(0.0, age)


class Stats:
    """Wall-clock seconds per category and counters. Categories nest; totals are exclusive."""

    def __init__(self):
        self.times: dict[str, float] = {}
        self.counts: dict[str, int] = {}
        self._stack: list[list] = []

    @contextmanager
    def timer(self, category: str):
        start = time.perf_counter()
        self._stack.append([category, 0.0])
        try:
            yield
        finally:
            _, inner = self._stack.pop()
            spent = time.perf_counter() - start
            self.times[category] = self.times.get(category, 0.0) + spent - inner
            if self._stack:
                self._stack[-1][1] += spent

    def count(self, name: str, n: int = 1):
        self.counts[name] = self.counts.get(name, 0) + n

    def add_time(self, category: str, seconds: float):
        """Time measured elsewhere (e.g. collision checks inside motion planning)."""
        self.times[category] = self.times.get(category, 0.0) + seconds
        if self._stack:  # charged to the enclosing category's exclusive time as well
            self._stack[-1][1] += seconds


class Trace:
    """An append-only list of events, each a JSON-able dict with a time stamp ``t``."""

    def __init__(self, listeners=()):
        self.start = time.perf_counter()
        self.events: list[dict] = []
        self.listeners = list(listeners)

    def emit(self, type_: str, **data) -> dict:
        event = {"t": round(time.perf_counter() - self.start, 4), "type": type_, **data}
        self.events.append(event)
        for listener in self.listeners:
            listener(event)
        return event

    def to_json(self) -> dict:
        return {"events": self.events}
