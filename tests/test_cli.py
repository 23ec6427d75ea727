"""The command line: exit codes, --json alone on stdout, clear errors, --out and validate."""
import json
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parent.parent


def cli(*args, cwd=ROOT):
    proc = subprocess.run([sys.executable, "-m", "interlayer.cli", *args], capture_output=True, text=True, cwd=cwd, timeout=300)
    return proc.returncode, proc.stdout, proc.stderr


def test_plan_json_is_alone_on_stdout_and_matches_the_api(tmp_path):
    code, out, err = cli("plan", "examples/gripper2d.toml", "--json", "--out", str(tmp_path / "run"), "--dump-pddl")
    assert code == 0, err
    data = json.loads(out)  # stdout holds exactly one JSON object
    for key in ("status", "reason", "plan", "learned_facts", "replans", "task_planner_calls", "times", "seed", "config"):
        assert key in data
    assert data["status"] == "solved" and "(Obstructs b2 gp_b1 b1)" in data["learned_facts"]
    assert {"total", "task_planning", "motion_planning"} <= set(data["times"])
    assert "task plan #1" in err  # progress goes to stderr
    run = tmp_path / "run"
    for name in ("result.json", "config.toml", "problem.json", "trace.json", "trajectory.json"):
        assert (run / name).exists(), name
    code = {name: o for o, name in (line.split() for line in (run / "pddl" / "objects.txt").read_text().splitlines())}
    fact = f"(obstructs {code['b2']} {code['gp_b1']} {code['b1']})"  # the task planner sees objects by number
    assert (run / "pddl" / "call-002-problem.pddl").read_text().count(fact) == 1
    trace = json.loads((run / "trace.json").read_text())["events"]
    assert {"task_plan", "attempt", "failure", "replan", "refined"} <= {e["type"] for e in trace}
    code, out, err = cli("validate", str(run))
    assert code == 0, err
    code, out, err = cli("plan", str(run), "--json", "-q")  # an output folder rebuilds its problem
    assert code == 0 and json.loads(out)["seed"] == 0


def test_validate_asks_the_task_planners_library_for_a_second_opinion(tmp_path):
    run = tmp_path / "run"
    code, out, err = cli("plan", "examples/gripper2d.toml", "-q", "--out", str(run))
    assert code == 0, err
    code, out, err = cli("validate", str(run), "--json")
    report = json.loads(out)
    assert code == 0 and report["valid"], err
    assert "task plan re-checked by the task planner's library (fast-downward)" in report["checked"]
    result = json.loads((run / "result.json").read_text())
    result["plan"] = result["plan"][1:]  # the first pick dropped: the rest cannot run
    (run / "result.json").write_text(json.dumps(result))
    code, out, err = cli("validate", str(run), "--json")
    violations = json.loads(out)["violations"]
    assert code == 1 and any("UP's validator rejected the plan" in v for v in violations), violations


def test_unsolved_run_still_prints_json_and_exits_1(tmp_path):
    code, out, err = cli("plan", "examples/gripper2d.toml", "--json", "--set", "planner.time_limit=0.5",
                         "--set", "planner.motion=interpolate", "--set", "problem.obstructions=5")
    data = json.loads(out)
    assert code == 1 and data["status"] == "timeout" and data["reason"]


@pytest.mark.parametrize("args, message", [
    (["--set", "planner.task=fast-downwrd"], "Unknown task planner 'fast-downwrd' (did you mean 'fast-downward'?)"),
    (["--set", "planner.motion=ompl:RRTConect"], "did you mean 'ompl:RRTConnect'"),
    (["--set", "planner.tsk=pyperplan"], "Unknown key 'planner.tsk' (did you mean 'task'?)"),
    (["--set", "problem.obstruction=2"], "Unknown key 'problem.obstruction' (did you mean 'obstructions'?)"),
    (["--set", "problem.obstructions=9"], "problem.obstructions must be an integer from 0 to 5"),
    (["--set", "planner.seed=-1"], "planner.seed must be a non-negative integer"),
])
def test_user_errors_exit_2_with_one_sentence(args, message):
    code, out, err = cli("plan", "examples/gripper2d.toml", "--json", *args)
    assert code == 2
    assert message in err and "Traceback" not in err
    assert json.loads(out)["status"] == "error"


def test_malformed_toml_and_missing_files(tmp_path):
    bad = tmp_path / "bad.toml"
    bad.write_text("[planner\ntask = 1\n")
    code, _, err = cli("plan", str(bad))
    assert code == 2 and "is not valid TOML" in err and "Traceback" not in err
    code, _, err = cli("plan", str(tmp_path / "nope.toml"))
    assert code == 2 and "No such file" in err
    scene = tmp_path / "scene.xyz"
    scene.write_text("not a scene")
    code, _, err = cli("plan", str(scene))
    assert code == 2 and "No installed plugin can read" in err


def test_plugins_and_check_commands():
    code, out, _ = cli("plugins", "--json")
    assert code == 0
    names = {p["name"]: p for p in json.loads(out)["plugins"]}
    comps = names["unified-planning"]["components"]["task_planners"]
    assert {"fast-downward", "fast-downward-opt", "pyperplan", "ff"} <= {c["name"] for c in comps if c["available"]}
    code, out, _ = cli("check", "examples/gripper2d.toml", "--json")
    report = json.loads(out)
    assert report["uniform"] is True and "gp_b1" in report["references"]["gp"]
    assert report["geometric_predicates"]["Obstructs"] == {"occurs": "negative", "default": False}


def test_help_is_fast_and_imports_nothing_heavy():
    code = ("import sys, interlayer.cli; interlayer.cli.build_parser(); "
            "heavy = [m for m in ('unified_planning', 'pinocchio', 'coal', 'ompl', 'meshcat', 'numpy') if m in sys.modules]; "
            "print(heavy)")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True).stdout
    assert out.strip() == "[]"
