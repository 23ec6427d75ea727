"""Motion planners compared inside the full TAMP loop: success, time, path length, trajectory duration,
learned obstructions, validity. Medians over seeds; one row per (problem, planner).

    python benchmarks/motion.py --seeds 3 gripper2d:1 gripper2d:3 cubby
    python benchmarks/motion.py --planners ompl:RRTConnect trajopt --seeds 2 gripper2d:2

Problems: ``gripper2d:K`` (Gripper-2D with K obstructions), ``cubby`` (examples/pr2_pick.toml),
``clutter:N`` (Clutter-N). Planners: any ``planner.motion`` name; ``ik:cartesian+X`` is X with
``planner.cartesian=ik:cartesian``.
"""
import argparse
import statistics
import sys
import tempfile
import time

import numpy as np

from interlayer import api, shipped

PLANNERS = ["ompl:RRTConnect", "ompl:BITstar", "trajopt", "ik:cartesian+ompl:RRTConnect"]


def problem_args(name):
    kind, _, n = name.partition(":")
    if kind == "gripper2d":
        return shipped.find("examples", "gripper2d"), [f"problem.obstructions={n or 1}"]
    if kind == "cubby":
        return shipped.find("examples", "pr2_pick"), []
    if kind == "clutter":
        return shipped.find("examples", "clutter"), [f"problem.objects={n or 25}"]
    raise SystemExit(f"unknown problem {name!r}: use gripper2d:K, cubby or clutter:N")


def measure(traj):
    """(joint-space path length, trajectory duration or None) summed over motion segments."""
    length, duration = 0.0, 0.0
    timed = True
    for step in traj["steps"]:
        for seg in step["segments"]:
            pts = seg.get("points") or [{"positions": p} for p in seg.get("path", [])]
            q = np.array([p["positions"] for p in pts], float)
            if len(q) > 1:
                d = np.diff(q, axis=0)
                if seg.get("group") == "base" or "path" in seg:
                    d[:, 2] = (d[:, 2] + np.pi) % (2 * np.pi) - np.pi
                length += float(np.linalg.norm(d, axis=1).sum())
            if pts and "time_from_start" in pts[-1]:
                duration += pts[-1]["time_from_start"]
            elif len(q) > 1:
                timed = False
    return length, (duration if timed else None)


def run(config, overrides):
    import json

    t0 = time.perf_counter()
    result = api.solve(config, overrides)
    wall = time.perf_counter() - t0
    row = {"solved": result.status == "solved", "time": wall, "learned": len(result.learned_facts), "valid": None,
           "length": None, "duration": None}
    if row["solved"]:
        with tempfile.TemporaryDirectory() as tmp:
            out = api.write_outputs(result, tmp)
            row["valid"] = api.validate(out) == []
            row["length"], row["duration"] = measure(json.loads((out / "trajectory.json").read_text()))
    return row


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("problems", nargs="+")
    ap.add_argument("--planners", nargs="+", default=PLANNERS)
    ap.add_argument("--seeds", type=int, default=3)
    ap.add_argument("--time-limit", type=float, default=120.0)
    args = ap.parse_args()
    print("| problem | planner | solved | median time (s) | median path length | median duration (s) | "
          "median learned facts | valid |")
    print("|---|---|---|---|---|---|---|---|")
    for name in args.problems:
        config, base = problem_args(name)
        for planner in args.planners:
            over = list(base) + [f"planner.time_limit={args.time_limit}"]
            if planner.startswith("ik:cartesian+"):
                over += ["planner.cartesian=ik:cartesian", f"planner.motion={planner.split('+', 1)[1]}"]
            else:
                over += [f"planner.motion={planner}"]
            rows = [run(config, over + [f"planner.seed={s}"]) for s in range(args.seeds)]
            ok = [r for r in rows if r["solved"]]

            def med(key):
                vals = [r[key] for r in ok if r[key] is not None]
                return f"{statistics.median(vals):.2f}" if vals else "-"

            valid = sum(bool(r["valid"]) for r in ok)
            print(f"| {name} | {planner} | {len(ok)}/{len(rows)} | {med('time')} | {med('length')} | {med('duration')} | "
                  f"{med('learned')} | {valid}/{len(ok)} |", flush=True)


if __name__ == "__main__":
    sys.exit(main())
