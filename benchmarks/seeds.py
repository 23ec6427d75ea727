"""Run one config over several seeds, one process per run, and print medians.

    python benchmarks/seeds.py examples/gripper2d.toml --seeds 10 --set problem.obstructions=5

Each run is `interlayer plan CONFIG --json --set planner.seed=S` in its own process (so import
and warm-up costs are counted as a user would see them in `times.total`, not in wall time).
"""
import argparse
import json
import statistics
import subprocess
import sys


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("config")
    ap.add_argument("--seeds", type=int, default=10)
    ap.add_argument("--set", action="append", default=[])
    args = ap.parse_args()
    rows = []
    for seed in range(args.seeds):
        cmd = [sys.executable, "-m", "interlayer.cli", "plan", args.config, "--json", "-q", "--set", f"planner.seed={seed}"]
        for s in args.set:
            cmd += ["--set", s]
        out = subprocess.run(cmd, capture_output=True, text=True).stdout
        data = json.loads(out)
        data.setdefault("times", {})
        rows.append(data)
        print(f"seed {seed}: {data['status']:10s} total {data['times'].get('total', 0):6.2f} s, "
              f"task-planner calls {data.get('task_planner_calls')}, replans {data.get('replans')} {data.get('reason', '')}",
              file=sys.stderr)
    solved = [r for r in rows if r["status"] == "solved"]
    keys = sorted({k for r in solved for k in r["times"]})
    summary = {"config": args.config, "overrides": args.set, "runs": len(rows), "solved": len(solved)}
    if solved:
        summary["median_times"] = {k: round(statistics.median(r["times"].get(k, 0.0) for r in solved), 3) for k in keys}
        summary["median_task_planner_calls"] = statistics.median(r["task_planner_calls"] for r in solved)
        summary["median_replans"] = statistics.median(r["replans"] for r in solved)
        summary["max_total"] = round(max(r["times"]["total"] for r in solved), 3)
    print(json.dumps(summary, indent=1))


if __name__ == "__main__":
    main()
