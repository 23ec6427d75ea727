"""Limits and reproducibility: the time limit holds inside planners, runs repeat byte for byte."""
import hashlib
import json
import os
import subprocess
import sys
from pathlib import Path

from interlayer import api

ROOT = Path(__file__).resolve().parent.parent
EXAMPLE = str(ROOT / "examples" / "gripper2d.toml")


def digest(out: Path) -> str:
    plan = json.loads((out / "result.json").read_text())["plan"]
    return hashlib.sha256(json.dumps(plan).encode() + (out / "trajectory.json").read_bytes()).hexdigest()


def test_same_seed_and_config_give_identical_plan_and_trajectory_in_two_processes(tmp_path):
    """OMPL's own RNG included: RRTConnect paths differ between processes unless it is seeded."""
    args = ["plan", EXAMPLE, "-q", "--set", "planner.seed=3"]
    env = {k: v for k, v in os.environ.items() if k != "PYTHONHASHSEED"}
    procs = [subprocess.Popen([sys.executable, "-m", "interlayer.cli", *args, "--out", str(tmp_path / f"run{i}")],
                              env={**env, "PYTHONHASHSEED": str(i)}, stderr=subprocess.PIPE, text=True)
             for i in range(2)]
    for p in procs:
        assert p.wait(timeout=300) == 0, p.stderr.read()
    assert digest(tmp_path / "run0") == digest(tmp_path / "run1")


SLOW_PLANNER = """
    import time
    from interlayer import hookimpl

    @hookimpl
    def interlayer_register_motion_planners(registry):
        def make(options):
            from interlayer.motion import MotionPlanner

            class UsesItsTime(MotionPlanner):
                \"\"\"Like a sampling planner on a hard query: searches until its time limit, finds nothing.\"\"\"

                def _plan(self, space, start, goal, is_valid, time_limit):
                    time.sleep(time_limit)
                    return None

            return UsesItsTime(name="slow:planner", time_limit=options.get("time_limit", 1.0))

        registry.add("slow:planner", make, "uses all of its time")
"""


def test_the_time_limit_holds_with_time_spent_inside_motion_planners(plugin_dir):
    plugin_dir("il_slowplanner", SLOW_PLANNER)
    limit = 3.0
    result = api.solve(EXAMPLE, {"planner.motion": "slow:planner", "planner.time_limit": limit,
                                 "motion_planner.time_limit": 5.0})
    assert result.status == "timeout"
    assert result.times["total"] <= 1.1 * limit, result.times
