"""The results database: SQLite in WAL mode, one row per run, committed as each run finishes.

Several coordinators may share one database: each claims a run (table ``claims``, in a transaction
that also checks ``runs``) before it starts it, so no run is made twice; a claim whose coordinator
is gone (its process on this host has ended) is taken over."""
from __future__ import annotations

import datetime
import json
import os
import socket
import sqlite3
import time
from pathlib import Path

from ..errors import UserError

SCHEMA = """
CREATE TABLE IF NOT EXISTS runs (
    suite TEXT NOT NULL, row TEXT NOT NULL, combo TEXT NOT NULL, seed INTEGER NOT NULL, time_limit REAL NOT NULL,
    config TEXT NOT NULL, overrides TEXT NOT NULL,      -- the config path and the JSON list of --set overrides
    status TEXT NOT NULL, reason TEXT NOT NULL,         -- solved unsolvable gave_up timeout refused error invalid killed
    time_total REAL, wall_time REAL, times TEXT,        -- the planner's total, the process's wall time, the split (JSON)
    plan_length INTEGER, plan_cost REAL, replans INTEGER, task_planner_calls INTEGER,
    peak_memory_mb REAL, versions TEXT, host TEXT, started TEXT, finished TEXT,
    wall TEXT,                                          -- the wait's parts: start-up, planning, export, ... (JSON)
    counts TEXT,                                        -- the work done: motion checks, IK calls, ... (JSON)
    PRIMARY KEY (suite, row, combo, seed, time_limit)
);
CREATE TABLE IF NOT EXISTS rows (
    suite TEXT NOT NULL, row TEXT NOT NULL, position INTEGER NOT NULL, config TEXT NOT NULL, overrides TEXT NOT NULL,
    skipped TEXT NOT NULL,                              -- '' or why the row cannot run here
    paper TEXT NOT NULL,                                -- the published numbers for this row (JSON), if any
    PRIMARY KEY (suite, row)
);
CREATE TABLE IF NOT EXISTS claims (                     -- runs started and not yet recorded in runs
    suite TEXT NOT NULL, row TEXT NOT NULL, combo TEXT NOT NULL, seed INTEGER NOT NULL, time_limit REAL NOT NULL,
    host TEXT NOT NULL, pid INTEGER NOT NULL, claimed TEXT NOT NULL,  -- the coordinator that runs it, and since when
    PRIMARY KEY (suite, row, combo, seed, time_limit)
);
"""
KEY_COLUMNS = ("suite", "row", "combo", "seed", "time_limit")
_WHERE_KEY = " AND ".join(f"{c} = ?" for c in KEY_COLUMNS)
RUN_COLUMNS = ("suite", "row", "combo", "seed", "time_limit", "config", "overrides", "status", "reason", "time_total",
               "wall_time", "times", "plan_length", "plan_cost", "replans", "task_planner_calls", "peak_memory_mb",
               "versions", "host", "started", "finished", "wall", "counts")
JSON_COLUMNS = ("overrides", "times", "versions", "wall", "counts")
ADDED_COLUMNS = ("wall", "counts")  # absent from databases written by older versions


LOCKED_RETRIES = 40  # about 40 s of waiting in all


def connect(path, create: bool = True) -> sqlite3.Connection:
    path = Path(path)
    if not create and not path.exists():
        raise UserError(f"The results database {path} does not exist; create it with 'interlayer bench --db {path}'.")
    if create:
        path.parent.mkdir(parents=True, exist_ok=True)
    for attempt in range(LOCKED_RETRIES + 1):
        con = None
        try:
            con = sqlite3.connect(path, timeout=30, check_same_thread=False)  # a coordinator's threads claim runs
            con.execute("PRAGMA journal_mode=WAL")
            con.executescript(SCHEMA)
            have = {r[1] for r in con.execute("PRAGMA table_info(runs)")}
            for column in ADDED_COLUMNS:
                if column not in have:
                    con.execute(f"ALTER TABLE runs ADD COLUMN {column} TEXT")
            break
        except sqlite3.OperationalError as exc:
            # Switching to WAL while another coordinator sets the same database up fails at once as
            # "locked" (SQLite's busy timeout does not cover it): try again shortly.
            if con is not None:
                con.close()
            if "locked" not in str(exc):
                raise UserError(f"{path} is not an Interlayer results database ({exc}); give another --db path.") from None
            if attempt == LOCKED_RETRIES:
                raise UserError(f"The results database {path} stayed locked by another process; "
                                f"wait for it to finish or give another --db path.") from None
            time.sleep(0.05 * (attempt + 1))
        except sqlite3.DatabaseError as exc:
            raise UserError(f"{path} is not an Interlayer results database ({exc}); give another --db path.") from None
    con.row_factory = sqlite3.Row
    return con


def finished_keys(con, suite: str) -> set:
    return {tuple(r) for r in con.execute("SELECT row, combo, seed, time_limit FROM runs WHERE suite = ?", (suite,))}


def record_rows(con, suite: str, rows) -> None:
    with con:
        for i, row in enumerate(rows):
            con.execute("INSERT OR REPLACE INTO rows VALUES (?, ?, ?, ?, ?, ?, ?)",
                        (suite, row.name, i, row.config, json.dumps(row.overrides), row.skipped, json.dumps(row.paper)))


def record_run(con, run: dict) -> None:
    """One run, in its own transaction with the end of its claim: an interrupted sweep never leaves half a row."""
    values = [json.dumps(run.get(c)) if c in JSON_COLUMNS else run.get(c) for c in RUN_COLUMNS]
    with con:
        con.execute(f"INSERT OR REPLACE INTO runs ({', '.join(RUN_COLUMNS)}) VALUES ({', '.join('?' * len(RUN_COLUMNS))})",
                    values)
        con.execute(f"DELETE FROM claims WHERE {_WHERE_KEY}", [run[c] for c in KEY_COLUMNS])


def me() -> tuple:
    """This coordinator, as a claim names it: (host, pid)."""
    return socket.gethostname(), os.getpid()


def claim(con, key: tuple, claimer: tuple):
    """Claim the run ``key`` (suite, row, combo, seed, time_limit) for ``claimer`` (host, pid), atomically:
    None if it is now the claimer's; "finished" if the database holds it; else the (host, pid) of the
    running coordinator that claimed it first."""
    con.execute("BEGIN IMMEDIATE")  # the write lock from the first read: two claimers cannot both see it free
    try:
        if con.execute(f"SELECT 1 FROM runs WHERE {_WHERE_KEY}", key).fetchone():
            holder = "finished"
        else:
            row = con.execute(f"SELECT host, pid, claimed FROM claims WHERE {_WHERE_KEY}", key).fetchone()
            holder = (row[0], row[1]) if row is not None else None
            if holder is not None and (holder == tuple(claimer) or not _running(*holder, row[2])):
                holder = None  # ours already, or its coordinator is gone: retaken
            if holder is None:
                now = datetime.datetime.now(datetime.timezone.utc).isoformat(timespec="seconds")
                con.execute("INSERT OR REPLACE INTO claims VALUES (?, ?, ?, ?, ?, ?, ?, ?)", (*key, *claimer, now))
        con.commit()
    except BaseException:
        con.rollback()
        raise
    return holder


def release(con, claimer: tuple) -> None:
    """Drop ``claimer``'s claims of runs it did not finish (an interrupted sweep): others may take them."""
    with con:
        con.execute("DELETE FROM claims WHERE host = ? AND pid = ?", tuple(claimer))


def _running(host: str, pid: int, claimed: str) -> bool:
    """Whether the coordinator (host, pid) that claimed a run at ``claimed`` may still run: not if no
    process has its pid, or if the one that has it started after the claim (the pid was reused). A
    process of another host cannot be asked."""
    if host != socket.gethostname():
        return True
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    except PermissionError:  # alive, someone else's
        pass
    started = _start_time(pid)
    try:
        claim_time = datetime.datetime.fromisoformat(claimed).timestamp()
    except (TypeError, ValueError):
        return True
    return started is None or started <= claim_time + 2  # claim times are whole seconds, boot time too


def _start_time(pid: int) -> float | None:
    """When process ``pid`` started, in seconds since the epoch (Linux's /proc); None if unknown."""
    try:
        fields = Path(f"/proc/{pid}/stat").read_text().rsplit(")", 1)[1].split()
        boot = next(int(line.split()[1]) for line in Path("/proc/stat").read_text().splitlines()
                    if line.startswith("btime "))
        return boot + int(fields[19]) / os.sysconf("SC_CLK_TCK")  # field 22, starttime, in clock ticks
    except (OSError, ValueError, IndexError, StopIteration):
        return None


def load(con) -> tuple[list[dict], list[dict]]:
    """All runs and all suite rows as dicts, JSON columns decoded."""
    runs = []
    for r in con.execute("SELECT * FROM runs ORDER BY suite, row, combo, seed"):
        d = dict(r)
        for c in JSON_COLUMNS:
            d[c] = json.loads(d[c]) if d[c] else None
        runs.append(d)
    rows = []
    for r in con.execute("SELECT * FROM rows ORDER BY suite, position"):
        d = dict(r)
        d["overrides"], d["paper"] = json.loads(d["overrides"]), json.loads(d["paper"])
        rows.append(d)
    return runs, rows
