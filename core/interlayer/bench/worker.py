"""One benchmark run in its own process: ``python -m interlayer.bench.worker SPEC_JSON``.

Caps its own address space (``resource.setrlimit``) before importing anything heavy, dies with its
process group when the coordinator goes away, and prints one JSON object to stdout. With
``"validate": OUT_DIR`` in the spec it runs the project's validator on a finished run instead.
"""
from __future__ import annotations

import json
import os
import platform
import resource
import signal
import sys
import threading
import time


def cap_memory(megabytes) -> None:
    if megabytes:
        limit = int(megabytes * 2**20)
        resource.setrlimit(resource.RLIMIT_AS, (limit, limit))


def die_with_parent() -> None:
    """An orphaned run (the coordinator was killed) must not run on: kill the whole process group."""
    parent = os.getppid()

    def watch():
        while os.getppid() == parent:
            time.sleep(0.5)
        os.killpg(os.getpgrp(), signal.SIGKILL)

    threading.Thread(target=watch, daemon=True).start()


def peak_memory_mb() -> float:
    """Peak resident memory of this process and of its children (e.g. a task planner's), in MB."""
    own = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss
    children = resource.getrusage(resource.RUSAGE_CHILDREN).ru_maxrss
    return round(max(own, children) / 1024, 1)  # ru_maxrss is in KiB on Linux


def versions(host) -> dict:
    """Python, interlayer, every loaded plugin's distribution and the dependencies these declare."""
    import importlib.metadata as md
    import re

    from .. import __version__

    out = {"python": platform.python_version(), "interlayer": __version__}
    dists = ["interlayer"] + [dist for dist, version in host.dists.values() if version]
    for dist in dict.fromkeys(dists):
        try:
            out.setdefault(dist, md.version(dist))
            requires = md.requires(dist) or ()
        except md.PackageNotFoundError:
            continue
        for req in requires:
            name = re.split(r"[ ;<>=!~\[(]", req)[0]
            if "extra ==" in req or name in out:
                continue
            try:
                out[name] = md.version(name)
            except md.PackageNotFoundError:
                pass
    commit = _git_commit()
    if commit:
        out["commit"] = commit
    return out


def _git_commit() -> str:
    """The source checkout's commit (with '+' when it has local changes), or '' when not run from one: an
    installed wheel in a folder of some other repository must not record that repository's commit."""
    import subprocess
    from pathlib import Path

    checkout = Path(__file__).resolve().parents[3]  # core/interlayer/bench/ -> the repository
    if not (checkout / ".git").exists():
        return ""
    here = str(checkout)
    try:
        head = subprocess.run(["git", "-C", here, "rev-parse", "--short", "HEAD"], capture_output=True, text=True,
                              timeout=10).stdout.strip()
        dirty = subprocess.run(["git", "-C", here, "status", "--porcelain", "--untracked-files=no"],
                               capture_output=True, text=True, timeout=10).stdout.strip()
    except (OSError, subprocess.SubprocessError):
        return ""
    return f"{head}{'+' if dirty else ''}" if head else ""


def plan(spec: dict) -> dict:
    from .. import api
    from ..errors import UserError
    from ..plugins import PluginHost
    from ..trace import process_start

    try:
        host = PluginHost()
        result = api.solve(spec["config"], overrides=spec["overrides"], host=host, origin=process_start())
        if spec.get("out"):
            api.write_outputs(result, spec["out"])
    except UserError as exc:  # the problem or config refused (what 'interlayer check' says), not a crash
        return {"status": "refused", "reason": str(exc)}
    data = result.to_json()
    return {"status": result.status, "reason": result.reason, "times": data["times"], "wall": data["wall"],
            "counts": data["counts"],
            "plan_length": len(result.plan) if result.solved else None,
            "plan_cost": result.plan_cost,
            "replans": result.replans, "task_planner_calls": result.task_planner_calls, "versions": versions(host)}


def validate(out_dir: str) -> dict:
    from .. import api

    violations = api.validate(out_dir)
    return {"status": "valid" if not violations else "invalid", "reason": "; ".join(violations[:3])}


def main(argv=None) -> int:
    spec = json.loads((argv or sys.argv[1:])[0])
    cap_memory(spec.get("memory_mb"))
    die_with_parent()
    try:
        out = validate(spec["validate"]) if spec.get("validate") else plan(spec)
    except MemoryError:
        out = {"status": "killed", "reason": f"exceeded the memory cap of {spec.get('memory_mb')} MB"}
    except Exception as exc:  # recorded as the run's error; the sweep goes on
        out = {"status": "error", "reason": f"{type(exc).__name__}: {exc}"}
    if out["status"] == "error" and "MemoryError" in out["reason"]:  # a MemoryError contained further down
        out = {"status": "killed", "reason": f"exceeded the memory cap of {spec.get('memory_mb')} MB ({out['reason']})"}
    out["peak_memory_mb"] = peak_memory_mb()
    print(json.dumps(out), flush=True)
    return 0


if __name__ == "__main__":
    from ..cli import exit_after

    exit_after(main)
