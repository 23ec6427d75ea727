"""Clutter-N benchmark (BENCHMARKS.md section 2): one `interlayer plan` process per run, sequentially.

    python benchmarks/clutter.py --objects 15 25 40 --seeds 0-19 --time-limit 120

Every solved run is checked with `interlayer validate`; a run counts as solved only if it validates.
Runs whose OUT_DIR already has result.json are not run again (delete the folder to redo one), so an
interrupted benchmark resumes where it stopped. Prints a table per N and writes it into
docs/benchmarks.md (between the CLUTTER markers) with the command and the date.
"""
from __future__ import annotations

import argparse
import datetime
import json
import statistics
import subprocess
import sys
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
CONFIG = ROOT / "examples" / "clutter.toml"
DOC = ROOT / "docs" / "benchmarks.md"
BEGIN, END = "<!-- CLUTTER-TABLE BEGIN -->", "<!-- CLUTTER-TABLE END -->"
SPLIT = ("task_planning", "pose_generation", "ik", "collision_checking", "motion_planning")


def seeds(text: str) -> list[int]:
    out = []
    for part in text.split(","):
        a, _, b = part.partition("-")
        out += list(range(int(a), int(b) + 1)) if b else [int(a)]
    return out


def run(n, seed, limit, out_root: Path, interlayer: str) -> dict:
    out = out_root / f"n{n}_s{seed}"
    res_file = out / "result.json"
    if not res_file.exists():
        cmd = [interlayer, "plan", str(CONFIG), "--json", "--out", str(out), "--set", f"problem.objects={n}",
               "--set", f"planner.seed={seed}", "--set", f"planner.time_limit={limit}"]
        t0 = time.perf_counter()
        proc = subprocess.run(cmd, capture_output=True, text=True, timeout=limit + 300, check=False)
        wall = time.perf_counter() - t0
        if not res_file.exists():
            out.mkdir(parents=True, exist_ok=True)
            res_file.write_text(json.dumps({"status": "error", "reason": proc.stderr[-2000:], "times": {"total": wall}}))
    result = json.loads(res_file.read_text())
    valid_file = out / "validate.txt"
    if result.get("status") == "solved" and not valid_file.exists():
        proc = subprocess.run([interlayer, "validate", str(out)], capture_output=True, text=True, check=False)
        valid_file.write_text(f"rc={proc.returncode}\n{proc.stdout}{proc.stderr}")
    valid = valid_file.exists() and valid_file.read_text().startswith("rc=0")
    return {"n": n, "seed": seed, "status": result.get("status"), "valid": valid, "reason": result.get("reason", ""),
            "times": result.get("times", {}), "replans": result.get("replans", 0),
            "calls": result.get("task_planner_calls", 0)}


def med(xs):
    return statistics.median(xs) if xs else float("nan")


def table(rows, limit) -> str:
    lines = ["| N | runs | solved (validated) | median / mean / max time, s | time split (medians, s): task / poses / IK / "
             "collision / motion | replans (median / max) | task-planner calls (median / max) |",
             "|---|---|---|---|---|---|---|"]
    for n in sorted({r["n"] for r in rows}):
        rs = [r for r in rows if r["n"] == n]
        ok = [r for r in rs if r["status"] == "solved" and r["valid"]]
        # unsolved runs count at the time limit in the time statistics
        ts = [r["times"].get("total", limit) if r in ok else limit for r in rs]
        split = " / ".join(f"{med([r['times'].get(k, 0.0) for r in rs]):.2f}" for k in SPLIT)
        lines.append(f"| {n} | {len(rs)} | {len(ok)} ({100 * len(ok) / len(rs):.0f}%) | {med(ts):.1f} / "
                     f"{statistics.mean(ts):.1f} / {max(ts):.1f} | {split} | {med([r['replans'] for r in rs]):.0f} / "
                     f"{max(r['replans'] for r in rs)} | {med([r['calls'] for r in rs]):.0f} / {max(r['calls'] for r in rs)} |")
    return "\n".join(lines)


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--objects", type=int, nargs="+", default=[15, 25, 40])
    ap.add_argument("--seeds", default="0-19", help="e.g. 0-19 or 0,3,5-7")
    ap.add_argument("--time-limit", type=float, default=120)
    ap.add_argument("--out", type=Path, default=Path("/tmp/interlayer-clutter-bench"), help="OUT_DIRs go here")
    ap.add_argument("--no-doc", action="store_true", help="do not write docs/benchmarks.md")
    args = ap.parse_args(argv)
    interlayer = str(Path(sys.executable).with_name("interlayer"))
    rows = []
    for n in args.objects:
        for s in seeds(args.seeds):
            r = run(n, s, args.time_limit, args.out / f"t{args.time_limit:g}", interlayer)
            rows.append(r)
            print(f"N={n} seed={s}: {r['status']}{' (validated)' if r['valid'] else ''} in "
                  f"{r['times'].get('total', float('nan')):.1f} s, {r['calls']} task-planner calls, "
                  f"{r['replans']} replans {'' if r['status'] == 'solved' else r['reason'][:100]}", flush=True)
    text = table(rows, args.time_limit)
    failures = [f"- N={r['n']} seed {r['seed']}: {r['status']}{'' if r['status'] != 'solved' else ' but did not validate'}"
                f": {r['reason'][:160]}" for r in rows if not (r["status"] == "solved" and r["valid"])]
    cmd = ("python benchmarks/clutter.py --objects " + " ".join(map(str, args.objects)) +
           f" --seeds {args.seeds} --time-limit {args.time_limit:g}")
    block = (f"{BEGIN}\nCommand: `{cmd}` (run {datetime.date.today().isoformat()}, one process per run, sequential, "
             f"on a 2-core machine shared with other work). Unsolved runs count at the time limit.\n\n{text}\n\n"
             + ("Runs not solved:\n" + "\n".join(failures) + "\n" if failures else "") + END)
    print(text)
    if not args.no_doc:
        doc = DOC.read_text() if DOC.exists() else "# Benchmarks\n"
        if BEGIN in doc and END in doc:
            doc = doc[: doc.index(BEGIN)] + block + doc[doc.index(END) + len(END):]
        else:
            doc += "\n" + block + "\n"
        DOC.write_text(doc)


if __name__ == "__main__":
    main()
