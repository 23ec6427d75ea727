"""The results database: SQLite in WAL mode, one row per run, committed as each run finishes."""
from __future__ import annotations

import json
import sqlite3
from pathlib import Path

from ..errors import UserError

SCHEMA = """
CREATE TABLE IF NOT EXISTS runs (
    suite TEXT NOT NULL, row TEXT NOT NULL, combo TEXT NOT NULL, seed INTEGER NOT NULL, time_limit REAL NOT NULL,
    config TEXT NOT NULL, overrides TEXT NOT NULL,      -- the config path and the JSON list of --set overrides
    status TEXT NOT NULL, reason TEXT NOT NULL,         -- solved unsolvable timeout error invalid killed
    time_total REAL, wall_time REAL, times TEXT,        -- the planner's total, the process's wall time, the split (JSON)
    plan_length INTEGER, plan_cost REAL, replans INTEGER, task_planner_calls INTEGER,
    peak_memory_mb REAL, versions TEXT, host TEXT, started TEXT, finished TEXT,
    wall TEXT,                                          -- the wait's parts: start-up, planning, export, ... (JSON)
    PRIMARY KEY (suite, row, combo, seed, time_limit)
);
CREATE TABLE IF NOT EXISTS rows (
    suite TEXT NOT NULL, row TEXT NOT NULL, position INTEGER NOT NULL, config TEXT NOT NULL, overrides TEXT NOT NULL,
    skipped TEXT NOT NULL,                              -- '' or why the row cannot run here
    paper TEXT NOT NULL,                                -- the published numbers for this row (JSON), if any
    PRIMARY KEY (suite, row)
);
"""
RUN_COLUMNS = ("suite", "row", "combo", "seed", "time_limit", "config", "overrides", "status", "reason", "time_total",
               "wall_time", "times", "plan_length", "plan_cost", "replans", "task_planner_calls", "peak_memory_mb",
               "versions", "host", "started", "finished", "wall")
JSON_COLUMNS = ("overrides", "times", "versions", "wall")


def connect(path, create: bool = True) -> sqlite3.Connection:
    path = Path(path)
    if not create and not path.exists():
        raise UserError(f"The results database {path} does not exist; create it with 'interlayer bench --db {path}'.")
    if create:
        path.parent.mkdir(parents=True, exist_ok=True)
    try:
        con = sqlite3.connect(path, timeout=30)
        con.execute("PRAGMA journal_mode=WAL")
        con.executescript(SCHEMA)
        if "wall" not in {r[1] for r in con.execute("PRAGMA table_info(runs)")}:  # a database from before
            con.execute("ALTER TABLE runs ADD COLUMN wall TEXT")
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
    """One run, in its own transaction: an interrupted sweep never leaves half a row."""
    values = [json.dumps(run.get(c)) if c in JSON_COLUMNS else run.get(c) for c in RUN_COLUMNS]
    with con:
        con.execute(f"INSERT OR REPLACE INTO runs ({', '.join(RUN_COLUMNS)}) VALUES ({', '.join('?' * len(RUN_COLUMNS))})",
                    values)


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
