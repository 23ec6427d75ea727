"""The ``interlayer bench`` and ``interlayer report`` subcommands (registered by interlayer.cli)."""
from __future__ import annotations

import json
import sys

from ..errors import UserError


def _log(msg: str) -> None:
    print(msg, file=sys.stderr, flush=True)


def cmd_bench(args) -> int:
    from .runner import DEFAULT_MEMORY_MB, run_suite
    from .suite import load_suite, parse_seeds

    if args.jobs is not None and args.jobs < 1:
        raise UserError(f"--jobs must be at least 1, got {args.jobs}.")
    if args.time_limit is not None and args.time_limit <= 0:
        raise UserError(f"--time-limit must be a positive number of seconds, got {args.time_limit:g}.")
    seeds = parse_seeds(args.seeds) if args.seeds else None
    suite = load_suite(args.suite, quick=args.quick, seeds=seeds, time_limit=args.time_limit, combos=args.combo,
                       overrides=args.set, problems=args.problems)
    summary = run_suite(suite, args.db, jobs=args.jobs, executor=args.executor,
                        memory_mb=args.memory_limit or DEFAULT_MEMORY_MB, grace=args.grace, keep_runs=args.keep_runs,
                        progress=not args.json)
    counts = ", ".join(f"{n} {s}" for s, n in sorted(summary["statuses"].items())) or "nothing new"
    _log(f"{'interrupted: ' if summary['interrupted'] else ''}ran {summary['ran']} run(s): {counts}; "
         f"results in {args.db} ('interlayer report {args.db} --out DIR' makes the tables and plots)")
    if args.json:
        print(json.dumps({"suite": suite.name, "db": str(args.db), **summary}))
    from ..cli import EXIT_INTERRUPTED, EXIT_OK

    return EXIT_INTERRUPTED if summary["interrupted"] else EXIT_OK


def cmd_report(args) -> int:
    from .report import write_report

    paths = write_report(args.db, args.out, doc=args.doc)
    _log("Wrote " + ", ".join(str(p) for p in paths))
    if args.json:
        print(json.dumps({"files": [str(p) for p in paths]}))
    return 0


def add_commands(sub) -> None:
    b = sub.add_parser("bench", help="run a benchmark suite over seeds and planner combinations into a SQLite database")
    b.add_argument("--suite", default="table1",
                   help="a suite name from benchmarks/ (table1, clutter, gripper2d) or a suite .toml file (default table1)")
    b.add_argument("--db", required=True, metavar="FILE.sqlite", help="the results database (created; re-runs skip finished runs)")
    b.add_argument("--problems", metavar="DIR",
                   help="the folder whose files a folder suite runs (pbjson-folder: a checkout of pybullet-planning's problems/json)")
    b.add_argument("--quick", action="store_true", help="2 seeds per row with short time limits")
    b.add_argument("--seeds", metavar="SEEDS", help="seeds for every row, e.g. 0-9 or 0,3,5-7")
    b.add_argument("--time-limit", type=float, metavar="SECONDS", help="planner.time_limit of every run")
    b.add_argument("--jobs", type=int, metavar="K", help="runs at a time on this machine (default: one per core)")
    b.add_argument("--executor", default="local", metavar="local|dask://HOST:PORT",
                   help="run locally (default) or on an existing Dask cluster")
    b.add_argument("--combo", action="append", default=[], metavar="KEY=V1,V2",
                   help="planner combinations to cross with every row, e.g. planner.task=ff,fast-downward (repeatable)")
    b.add_argument("--set", action="append", default=[], metavar="KEY=VALUE", help="override a config value in every run")
    b.add_argument("--memory-limit", type=float, metavar="MB", help="address-space cap per run (default 4096 MB)")
    b.add_argument("--grace", type=float, metavar="SECONDS",
                   help="seconds past the time limit before a run is killed (default 30 + 10%% of the limit)")
    b.add_argument("--keep-runs", metavar="DIR", help="keep every run's output folder (for viz / validate) under DIR")
    b.add_argument("--json", action="store_true", help="print a JSON summary to stdout, no progress bar")
    b.set_defaults(func=cmd_bench)

    r = sub.add_parser("report", help="Table I / Fig. 7 style report (Markdown, HTML, PNG) from a bench database")
    r.add_argument("db", metavar="DB.sqlite")
    r.add_argument("--out", required=True, metavar="DIR", help="writes DIR/report.md, DIR/report.html and the PNGs")
    r.add_argument("--doc", metavar="FILE.md",
                   help="also put the tables and plots into FILE.md between its BENCH-REPORT markers")
    r.add_argument("--json", action="store_true")
    r.set_defaults(func=cmd_report)
