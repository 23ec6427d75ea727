"""A run folder (``interlayer plan --out DIR``): checked before planning, written as one consistent
set, and read back with one sentence naming the file for anything damaged."""
from __future__ import annotations

import contextlib
import json
import os
import signal
import threading
from pathlib import Path

from .errors import UserError

REWRITE = "rewrite the folder with 'interlayer plan --out'"


# ----------------------------------------------------------------------------- before planning
def check_writable(path, what: str, folder: bool) -> None:
    """Raise a UserError now, before any planning, if ``path`` (a folder to create or fill, or a
    file to write) cannot be written: it is a file where a folder is wanted (or the reverse), it
    lies below a regular file, or its nearest existing folder is not writable."""
    p = Path(path)
    if p.exists():
        if folder and not p.is_dir():
            raise UserError(f"{what} {p} is a file, not a folder; give a folder name.")
        if not folder and p.is_dir():
            raise UserError(f"{what} {p} is a folder; give a file name.")
        target = p if folder else p.parent
        if not os.access(target, os.W_OK | os.X_OK) or (not folder and not os.access(p, os.W_OK)):
            raise UserError(f"{what} {p} is not writable; give a path you can write to.")
        return
    parent = p.parent
    while not parent.exists() and parent != parent.parent:
        parent = parent.parent
    if not parent.is_dir():
        raise UserError(f"{what} {p} lies below {parent}, which is a file, not a folder; give another path.")
    if not os.access(parent, os.W_OK | os.X_OK):
        raise UserError(f"{what} {p} cannot be created: {parent} is not writable; give a path you can write to.")


# ------------------------------------------------------------------------------------ writing
@contextlib.contextmanager
def signals_deferred():
    """SIGINT, SIGTERM and SIGHUP wait until the block ends (then reach the handlers they would have
    met: KeyboardInterrupt in 'interlayer'), so that a folder is never left half written. Does
    nothing outside the main thread."""
    if threading.current_thread() is not threading.main_thread():
        yield
        return
    caught, saved = [], {}
    for sig in (signal.SIGINT, signal.SIGTERM, getattr(signal, "SIGHUP", None)):
        if sig is not None:
            saved[sig] = signal.signal(sig, lambda s, f: caught.append(s))
    try:
        yield
    finally:
        for sig, handler in saved.items():
            signal.signal(sig, handler)
    for sig in dict.fromkeys(caught):
        signal.raise_signal(sig)


def write_set(out: Path, files: dict, last: str = "result.json") -> None:
    """Write ``files`` (name -> text, a function giving it when its turn comes, or None to remove a
    stale file) into ``out`` as one set:
    each to a temporary name first, ``last`` removed first and renamed into place last, so a
    reader never sees ``last`` beside files of another run (a folder without it is unfinished)."""
    try:
        out.mkdir(parents=True, exist_ok=True)
    except OSError as exc:
        raise UserError(f"Cannot create the output folder {out}: {exc.strerror}.") from None
    with signals_deferred():
        tmp = {}
        try:
            for name, text in files.items():
                if text is not None:
                    tmp[name] = out / f".{name}.tmp"
                    tmp[name].write_text(text() if callable(text) else text)
            with contextlib.suppress(FileNotFoundError):
                (out / last).unlink()
            for name in sorted(files, key=lambda n: n == last):
                if files[name] is None:
                    with contextlib.suppress(FileNotFoundError):
                        (out / name).unlink()
                else:
                    os.replace(tmp[name], out / name)
        except OSError as exc:
            for t in tmp.values():
                with contextlib.suppress(OSError):
                    t.unlink()
            raise UserError(f"Cannot write into the output folder {out}: {exc.strerror}.") from None


# ------------------------------------------------------------------------------------ reading
def read_json(path: Path, required: bool = True):
    """The JSON object in ``path``; None if it is absent and not ``required``."""
    if not path.exists():
        if required:
            raise UserError(f"{path.parent} has no {path.name}; give a folder written by 'interlayer plan --out'.")
        return None
    try:
        data = json.loads(path.read_text())
    except (OSError, UnicodeDecodeError, json.JSONDecodeError, RecursionError) as exc:
        why = "nested too deeply" if isinstance(exc, RecursionError) else str(exc)
        raise UserError(f"{path} is not a readable JSON file ({why}); {REWRITE}.") from None
    if not isinstance(data, dict):
        raise UserError(f"{path} does not hold a JSON object; {REWRITE}.")
    return data


def damaged(path: Path, what: str) -> UserError:
    return UserError(f"{path} is damaged: {what}; {REWRITE}.")


def _check_steps(path: Path, steps, key: str) -> None:
    if not isinstance(steps, list):
        raise damaged(path, f"'{key}' is not a list")
    for i, s in enumerate(steps):
        if not (isinstance(s, dict) and isinstance(s.get("action"), str) and isinstance(s.get("args"), list)
                and all(isinstance(a, str) for a in s["args"])):
            raise damaged(path, f"{key}[{i}] is not an action with a list of argument names")


def read_result(out) -> dict:
    path = Path(out) / "result.json"
    data = read_json(path)
    if not isinstance(data.get("status"), str):
        raise damaged(path, "it has no status")
    _check_steps(path, data.get("plan", []), "plan")
    number = (int, float, type(None))
    for key, kind in (("reason", (str, type(None))), ("times", dict), ("learned_facts", list), ("replans", number),
                      ("task_planner_calls", number)):
        if key in data and (not isinstance(data[key], kind) or isinstance(data[key], bool)):
            raise damaged(path, f"'{key}' has the wrong type")
    if any(not isinstance(v, number) or isinstance(v, bool) for v in data.get("times", {}).values()):
        raise damaged(path, "'times' holds something other than numbers of seconds")
    return data


def read_trace(out, required: bool = True) -> list | None:
    path = Path(out) / "trace.json"
    data = read_json(path, required)
    if data is None:
        return None
    events = data.get("events")
    if not isinstance(events, list):
        raise damaged(path, "it has no list of events")
    for i, e in enumerate(events):
        if not (isinstance(e, dict) and isinstance(e.get("type"), str)):
            raise damaged(path, f"event {i} is not an object with a type")
    return events


def read_trajectory(out, required: bool = True) -> dict | None:
    path = Path(out) / "trajectory.json"
    data = read_json(path, required)
    if data is not None:
        _check_steps(path, data.get("steps"), "steps")
    return data


@contextlib.contextmanager
def reading(path: Path):
    """Data of ``path`` used in a shape the reader did not expect: the file's fault, named."""
    try:
        yield
    except (KeyError, IndexError, TypeError, ValueError, AttributeError) as exc:
        raise damaged(Path(path), f"unexpected content ({type(exc).__name__}: {exc})") from None
