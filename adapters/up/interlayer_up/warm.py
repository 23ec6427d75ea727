"""The caller's side of ``fd_worker.py``: one warm Fast Downward process per driver, kept for the run.

``WarmDriver.run`` takes the command line that up-fast-downward built and answers as Unified-Planning's
``run_command`` does: (timed out, (stdout, stderr), exit code)."""
from __future__ import annotations

import atexit
import json
import logging
import os
import select
import signal
import subprocess
import sys
import threading
import time
from pathlib import Path

WORKER = str(Path(__file__).with_name("fd_worker.py"))
START_TIMEOUT = 60.0  # importing the driver and the translator takes about 0.1 s
STOP_GRACE = 5.0  # how long the worker has to report a started or a stopped request

log = logging.getLogger("interlayer")


class WorkerFailed(Exception):
    """The warm process stopped or did not answer (the message is one sentence)."""


class WarmDriver:
    def __init__(self, script: str):
        self.script = script  # .../downward/fast-downward.py
        self.proc: subprocess.Popen | None = None
        self.broken = False  # it could not start: the driver runs per call instead
        self.requests = 0  # answered so far
        self._buffer = b""
        self._ready = False  # it said so (spawned, not yet ready: False)
        self._lock = threading.RLock()  # one request (or start) at a time: threads share the driver

    @property
    def alive(self) -> bool:
        return self.proc is not None and self.proc.poll() is None

    def spawn(self) -> None:
        """Start the process without waiting for it to be ready (``start`` waits): it imports the driver
        on another core while the caller goes on (e.g. imports Unified-Planning)."""
        with self._lock:
            if self.alive or self.broken:
                return
            if self.proc is not None:
                log.warning("the warm Fast Downward process had stopped (exit code %s); starting a new one.",
                            self.proc.returncode)
            self.close()
            # Its own session, as Unified-Planning runs the driver: Ctrl-C reaches only us, and we stop it.
            self.proc = subprocess.Popen([sys.executable, WORKER, str(Path(self.script).parent)], stdin=subprocess.PIPE,
                                         stdout=subprocess.PIPE, stderr=subprocess.PIPE, start_new_session=True)
            self._buffer, self._ready = b"", False

    def start(self) -> None:
        with self._lock:
            self._start()

    def _start(self) -> None:
        if self.alive and self._ready:
            return
        if self.broken:
            raise WorkerFailed("the warm Fast Downward process could not start before")
        try:
            self.spawn()
            ready = self._answer(time.monotonic() + START_TIMEOUT).get("ready") is True
        except WorkerFailed:
            self.broken = True
            raise
        except (OSError, ValueError, TimeoutError) as exc:
            ready = False
            why = f" ({exc})" if str(exc) else ""
        else:
            why = ""
        if not ready:
            self.close()
            self.broken = True
            raise WorkerFailed(f"the warm Fast Downward process did not start{why}")
        self._ready = True

    def run(self, cmd: list, cwd: str, timeout: float | None):
        """Run the driver command ``cmd`` (``[python, fast-downward.py, ...]``) in ``cwd``."""
        with self._lock:
            self.start()
            deadline = None if timeout is None else time.monotonic() + timeout
            try:
                self.proc.stdin.write((json.dumps({"argv": [str(c) for c in cmd], "cwd": cwd}) + "\n").encode())
                self.proc.stdin.flush()
            except OSError:
                raise WorkerFailed(self._stopped()) from None
            timed_out = False
            try:
                child = self._answer(time.monotonic() + STOP_GRACE)["pid"]  # at once: it forks and answers
                try:
                    code = self._answer(deadline)["exit"]
                except TimeoutError:
                    timed_out = True
                    kill_group(child)
                    code = self._answer(time.monotonic() + STOP_GRACE)["exit"]
            except BaseException as exc:  # Ctrl-C, or the worker gone: start afresh next time (the request
                self.close()  # ends with the worker: at the end of its input, or when the worker dies)
                if isinstance(exc, TimeoutError):
                    raise WorkerFailed("the warm Fast Downward process did not answer in time") from None
                raise
        self.requests += 1
        return timed_out, (_read(cwd, "stdout.txt"), _read(cwd, "stderr.txt")), code

    def _answer(self, deadline: float | None) -> dict:
        """The worker's next JSON line; TimeoutError at ``deadline``, WorkerFailed if it stopped."""
        out = self.proc.stdout.fileno()
        while b"\n" not in self._buffer:
            left = None if deadline is None else max(0.0, deadline - time.monotonic())
            if not select.select([out], [], [], left)[0]:
                raise TimeoutError
            chunk = os.read(out, 65536)
            if not chunk:
                raise WorkerFailed(self._stopped())
            self._buffer += chunk
        line, self._buffer = self._buffer.split(b"\n", 1)
        return json.loads(line)

    def _stopped(self) -> str:
        try:
            code = self.proc.wait(timeout=STOP_GRACE)
        except subprocess.TimeoutExpired:
            code = None
        last = [line for line in self.proc.stderr.read().decode(errors="replace").splitlines() if line.strip()][-1:] \
            if code is not None else []
        why = f" ({last[0].strip()})" if last else ""
        self.close()
        return f"the warm Fast Downward process stopped unexpectedly (exit code {code}){why}"

    def close(self) -> None:
        proc, self.proc = self.proc, None
        if proc is None:
            return
        if proc.poll() is None:
            try:
                proc.stdin.close()  # it ends at the end of its input
                proc.wait(timeout=STOP_GRACE)
            except (OSError, subprocess.TimeoutExpired):
                kill_group(proc.pid)
                proc.wait()
        for stream in (proc.stdin, proc.stdout, proc.stderr):
            try:
                stream.close()
            except OSError:
                pass


def kill_group(pid: int) -> None:
    try:
        os.killpg(pid, signal.SIGKILL)
    except (ProcessLookupError, PermissionError):
        pass


def _read(cwd: str, name: str) -> list:
    try:
        return [Path(cwd, name).read_text(errors="replace")]
    except OSError:
        return []


_drivers: dict = {}
_drivers_lock = threading.Lock()


def driver_for(script: str) -> WarmDriver:
    """The process-wide warm driver of ``script`` (closed at exit), shared by threads: it runs one
    request at a time, each in the folder its caller names."""
    with _drivers_lock:
        if script not in _drivers:
            _drivers[script] = WarmDriver(script)
        return _drivers[script]


@atexit.register
def _close_all() -> None:
    for driver in _drivers.values():
        driver.close()
