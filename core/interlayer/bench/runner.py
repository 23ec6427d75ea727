"""Run a suite: every run in its own process group with a hard wall-clock limit and a memory cap,
solved runs re-checked by the validator, one database row committed per finished run.

Runs go to a local pool of ``jobs`` processes, or to a Dask cluster (``dask://HOST:PORT``); either
way only this (the coordinating) process writes the database.
"""
from __future__ import annotations

import datetime
import json
import os
import signal
import socket
import subprocess
import sys
import tempfile
import threading
import time
from pathlib import Path

from . import db
from ..errors import UserError
from .suite import Suite, mark_skipped

STATUSES = ("solved", "unsolvable", "gave_up", "timeout", "refused", "error", "invalid", "killed")
DEFAULT_MEMORY_MB = 4096

_live: set = set()  # worker processes running now (killed on Ctrl-C)
_live_lock = threading.Lock()
_stopping = threading.Event()  # set on Ctrl-C: no new run starts


def default_grace(time_limit: float) -> float:
    """Seconds past planner.time_limit before the run's process group is killed (imports, outputs)."""
    return 30.0 + 0.1 * time_limit


def _now() -> str:
    return datetime.datetime.now(datetime.timezone.utc).isoformat(timespec="seconds")


def _kill_group(proc) -> None:
    try:
        os.killpg(proc.pid, signal.SIGKILL)
    except (ProcessLookupError, PermissionError):
        pass


def _isolated(spec: dict, hard_limit: float):
    """Run the worker on ``spec`` in a new session (its own process group); kill the group at the limit.
    Returns (return code, stdout, stderr, wall seconds, killed at the limit)."""
    cmd = [sys.executable, "-m", "interlayer.bench.worker", json.dumps(spec)]
    start = time.monotonic()
    with _live_lock:
        if _stopping.is_set():
            raise KeyboardInterrupt
        proc = subprocess.Popen(cmd, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, start_new_session=True)
        _live.add(proc)
    try:
        out, err = proc.communicate(timeout=hard_limit)
        over = False
    except subprocess.TimeoutExpired:
        _kill_group(proc)
        out, err = proc.communicate()
        over = True
    finally:
        _kill_group(proc)  # whatever the run left behind (e.g. a task-planner process)
        with _live_lock:
            _live.discard(proc)
    return proc.returncode, out, err, time.monotonic() - start, over


def _outcome(rc, out, err, over, hard_limit, spec) -> dict:
    if over:
        return {"status": "timeout", "reason": f"killed at the hard wall-clock limit of {hard_limit:.0f} s "
                                               f"(planner.time_limit {spec['time_limit']:g} s)"}
    if rc < 0:
        name = signal.Signals(-rc).name if -rc in signal.Signals._value2member_map_ else str(-rc)
        return {"status": "killed", "reason": f"the run died of {name} (memory cap {spec['memory_mb']} MB)"}
    lines = [line for line in out.splitlines() if line.startswith("{")]
    if lines:
        try:
            return json.loads(lines[-1])
        except json.JSONDecodeError:
            pass
    tail = [line for line in err.strip().splitlines() if line.strip()][-1:] or [f"exit code {rc} and no result"]
    return {"status": "error", "reason": tail[0][-500:]}


def run_one(spec: dict) -> dict:
    """One run, start to finish (on this machine or a Dask worker): the database row as a dict."""
    started = _now()
    limit = spec["time_limit"]
    hard = limit + (spec["grace"] if spec.get("grace") is not None else default_grace(limit))
    with tempfile.TemporaryDirectory(prefix="interlayer-bench-") as tmp:
        out_dir = spec.get("keep_dir") or str(Path(tmp) / "run")
        rc, out, err, wall, over = _isolated({**spec, "out": out_dir}, hard)
        res = _outcome(rc, out, err, over, hard, spec)
        if res.get("status") not in STATUSES:
            res = {"status": "error", "reason": f"the worker reported the unknown status {res.get('status')!r}"}
        parts = {**(res.get("wall") or {}), "process": round(wall, 3)}  # the run's own split, as seen from here
        if res["status"] == "solved":  # counted only once the independent validator agrees
            vspec = {"validate": out_dir, "memory_mb": spec["memory_mb"]}
            vrc, vout, verr, vwall, vover = _isolated(vspec, 60 + hard)
            parts["validation"] = round(vwall, 3)
            check = _outcome(vrc, vout, verr, vover, 60 + hard, {**spec, **vspec})
            if check["status"] != "valid":
                res["status"], res["reason"] = "invalid", f"the validator says: {check['reason']}"
    times = res.get("times") or {}
    return {**{k: spec[k] for k in ("suite", "row", "combo", "seed", "time_limit", "config")},
            "overrides": spec["overrides"], "status": res["status"], "reason": res.get("reason", ""),
            "time_total": times.get("total"), "wall_time": round(wall, 3), "times": times,
            "plan_length": res.get("plan_length"), "plan_cost": res.get("plan_cost"), "replans": res.get("replans"),
            "task_planner_calls": res.get("task_planner_calls"), "peak_memory_mb": res.get("peak_memory_mb"),
            "versions": res.get("versions"), "host": socket.gethostname(), "started": started, "finished": _now(),
            "wall": parts, "counts": res.get("counts")}


def plan_runs(suite: Suite, done: set, memory_mb, grace, keep_runs) -> list[dict]:
    specs = []
    for row in suite.rows:
        if row.skipped:
            continue
        for label, combo in suite.combos:
            for seed in row.seeds:
                if (row.name, label, seed, row.time_limit) in done:
                    continue
                overrides = [*row.overrides, *combo, f"planner.seed={seed}", f"planner.time_limit={row.time_limit:g}"]
                keep = None
                if keep_runs:
                    slug = "".join(c if c.isalnum() else "_" for c in f"{row.name}_{label}")
                    keep = str(Path(keep_runs).resolve() / suite.name / slug / f"seed{seed}")
                specs.append({"suite": suite.name, "row": row.name, "combo": label, "seed": seed,
                              "time_limit": row.time_limit, "config": row.config, "overrides": overrides,
                              "memory_mb": memory_mb, "grace": grace, "keep_dir": keep})
    return specs


def _limits(suite: Suite) -> str:
    """'120 s', or '120 s; cubby 300 s' when rows set their own."""
    own = [f"{r.name} {r.time_limit:g} s" for r in suite.rows if r.time_limit != suite.time_limit and not r.skipped]
    return "; ".join([f"{suite.time_limit:g} s", *own])


def _local(specs, jobs, claim):
    """Each run as a thread of the pool gets to it, if ``claim(spec)`` (None for a run not claimed)."""
    from concurrent.futures import ThreadPoolExecutor, as_completed  # threads only wait on the run processes

    def claimed_run(spec):
        return run_one(spec) if claim(spec) else None

    pool = ThreadPoolExecutor(max_workers=jobs)
    try:
        for fut in as_completed([pool.submit(claimed_run, s) for s in specs]):
            yield fut.result()
    finally:
        with _live_lock:
            _stopping.set()
            for proc in list(_live):
                _kill_group(proc)
        pool.shutdown(wait=True, cancel_futures=True)
        _stopping.clear()


def _dask(specs, address):
    try:
        from distributed import Client, as_completed
    except ImportError:
        raise UserError("--executor dask://... needs the 'distributed' package: pip install 'interlayer[bench]'.") from None
    try:
        client = Client(address, timeout="10s")
    except (OSError, TimeoutError) as exc:
        raise UserError(f"Cannot reach the Dask scheduler at {address} ({exc}); start one with 'dask scheduler' "
                        "or check the address.") from None
    futures = client.map(run_one, specs, pure=False)  # the workers need interlayer and the configs' paths
    try:
        for fut in as_completed(futures):
            yield fut.result()
    finally:
        client.cancel(futures)
        client.close()


class _Progress:
    """A tqdm bar on stderr with solved/failed counts and an ETA, and one line per finished run."""

    def __init__(self, total: int, enabled: bool):
        self.counts = {"solved": 0, "failed": 0}
        self.bar = None
        if enabled:
            try:
                from tqdm import tqdm

                self.bar = tqdm(total=total, unit="run", file=sys.stderr, dynamic_ncols=True, smoothing=0)
            except ImportError:
                pass

    def update(self, r: dict) -> None:
        self.counts["solved" if r["status"] == "solved" else "failed"] += 1
        t = r["time_total"] if r["time_total"] is not None else r["wall_time"]
        line = (f"{r['row']} [{r['combo']}] seed {r['seed']}: {r['status']} in {t:.1f} s"
                + (f" ({r['reason'][:120]})" if r["status"] != "solved" and r["reason"] else ""))
        if self.bar is not None:
            self.bar.write(line, file=sys.stderr)
            self.bar.set_postfix(self.counts, refresh=False)
            self.bar.update(1)
        else:
            print(line, file=sys.stderr, flush=True)

    def close(self):
        if self.bar is not None:
            self.bar.close()


def run_suite(suite: Suite, db_path, jobs: int | None = None, executor: str = "local",
              memory_mb: float = DEFAULT_MEMORY_MB, grace: float | None = None, keep_runs=None,
              progress: bool = True, log=lambda msg: print(msg, file=sys.stderr, flush=True)) -> dict:
    """Run every (row, combination, seed) of the suite that the database does not hold yet, and that
    no other running coordinator of the database has claimed. Returns {"ran": N, "statuses": {...},
    "skipped_rows": {row: why}, "interrupted": bool, "claimed_elsewhere": N}."""
    if executor != "local" and not executor.startswith("dask://"):
        raise UserError(f"Unknown executor '{executor}'; use 'local' or 'dask://HOST:PORT'.")
    con = db.connect(db_path)
    mark_skipped(suite)
    db.record_rows(con, suite.name, suite.rows)
    skipped = {r.name: r.skipped for r in suite.rows if r.skipped}
    for name, why in skipped.items():
        log(f"skipped row {name}: {why}")
    specs = plan_runs(suite, db.finished_keys(con, suite.name), memory_mb, grace, keep_runs)
    total = sum(len(r.seeds) for r in suite.rows if not r.skipped) * len(suite.combos)
    log(f"suite {suite.name}: {total - len(specs)} of {total} runs already in {db_path}, {len(specs)} to run "
        f"(planner.time_limit {_limits(suite)})")
    summary = {"ran": 0, "statuses": {}, "skipped_rows": skipped, "interrupted": False, "claimed_elsewhere": 0}
    if not specs:
        return summary
    lock, claimer, elsewhere = threading.Lock(), db.me(), {}

    def claim(spec) -> bool:
        """Whether this coordinator is to make the run (another may have claimed or finished it)."""
        with lock:
            holder = db.claim(con, tuple(spec[c] for c in db.KEY_COLUMNS), claimer)
        if holder not in (None, "finished"):
            elsewhere[(spec["row"], spec["combo"], spec["seed"])] = holder
        return holder is None

    if executor.startswith("dask://"):  # claimed as submitted: the cluster's queue is this coordinator's
        specs = [s for s in specs if claim(s)]
        results = _dask(specs, "tcp://" + executor[len("dask://"):] if "://" not in executor[7:] else executor[7:])
    else:
        results = _local(specs, max(1, jobs or os.cpu_count() or 1), claim)
    bar = _Progress(len(specs), progress)
    try:
        for run in results:
            if run is None:  # claimed or finished by another coordinator first
                continue
            with lock:
                db.record_run(con, run)
            summary["ran"] += 1
            summary["statuses"][run["status"]] = summary["statuses"].get(run["status"], 0) + 1
            bar.update(run)
    except KeyboardInterrupt:
        summary["interrupted"] = True
    finally:
        results.close()
        bar.close()
        with lock:
            db.release(con, claimer)
        con.close()
    if elsewhere:
        holders = sorted({f"pid {pid} on {host}" for host, pid in elsewhere.values()})
        log(f"{len(elsewhere)} run(s) left to the coordinator(s) that claimed them first ({', '.join(holders)})")
    summary["claimed_elsewhere"] = len(elsewhere)
    return summary
