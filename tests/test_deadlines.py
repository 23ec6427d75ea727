"""The time limit holds against plugin calls that do not return, and a seed's result does not depend
on the clock: budgets count work, the clock only cuts a run short."""
import hashlib
import json
import os
import subprocess
import sys
import time
from pathlib import Path

import pytest

from interlayer import api

ROOT = Path(__file__).resolve().parent.parent
EXAMPLE = str(ROOT / "examples" / "gripper2d.toml")

HUNG = """
    import time
    from interlayer import hookimpl

    @hookimpl
    def interlayer_register_pose_generators(registry):
        def sleeps(problem, step, world, rng):
            time.sleep(30)  # in C: no Python instruction runs until it returns
            yield from ()

        def loops(problem, step, world, rng):
            end = time.perf_counter() + 30  # busy in Python (bounded, so that a failing test ends)
            while time.perf_counter() < end:
                pass
            yield from ()

        registry.add("hung:sleeps", sleeps, "sleeps")
        registry.add("hung:loops", loops, "loops")

    @hookimpl
    def interlayer_register_motion_planners(registry):
        def make(options):
            from interlayer.motion import MotionPlanner

            class NeverReturns(MotionPlanner):
                def _plan(self, space, start, goal, is_valid, time_limit):
                    time.sleep(30)

            return NeverReturns(name="hung:planner")

        registry.add("hung:planner", make, "never returns")
"""


def _env(folder):
    env = dict(os.environ, PYTHONPATH=os.pathsep.join([str(folder), *sys.path]))
    env.pop("INTERLAYER_DEBUG", None)
    return env


def test_a_busy_looping_generator_is_stopped_and_named(plugin_dir):
    """Python code that never checks the deadline: the supervisor raises in the planning thread."""
    plugin_dir("il_hung", HUNG)
    result = api.solve(EXAMPLE, {"pose_generators.pick": "hung:loops", "planner.time_limit": 1.0})
    assert result.status == "timeout"
    assert "the plugin 'il_hung''s pose generator 'hung:loops' did not return: it was stopped" in result.reason
    assert result.times["total"] < 20  # stopped, not waited for (the loop runs 30 s)
    assert result.trace.events[-1]["type"] == "end"


@pytest.mark.parametrize("overrides, names", [
    (["pose_generators.pick=hung:sleeps"], "the plugin 'il_hung''s pose generator 'hung:sleeps'"),
    (["planner.motion=hung:planner"], "the plugin 'il_hung''s motion planner 'hung:planner' (plan)"),
])
def test_a_call_stuck_in_a_sleep_ends_the_process_with_the_run_written(plugin_dir, tmp_path, overrides, names):
    folder = plugin_dir("il_hung", HUNG)
    out = tmp_path / "run"
    sets = [a for o in overrides for a in ("--set", o)]
    proc = subprocess.run([sys.executable, "-m", "interlayer.cli", "plan", EXAMPLE, "--out", str(out), "--json",
                           "--set", "planner.time_limit=2", *sets], capture_output=True, text=True, env=_env(folder),
                          timeout=100)
    assert proc.returncode == 1, proc.stderr
    assert f"{names} did not return: the process was ended" in proc.stderr
    assert "Traceback" not in proc.stderr
    data = json.loads(proc.stdout)  # --json alone on stdout
    result = json.loads((out / "result.json").read_text())
    assert data["status"] == result["status"] == "timeout" and names in result["reason"]
    events = json.loads((out / "trace.json").read_text())["events"]
    assert events[-1]["type"] == "end" and events[-1]["status"] == "timeout"
    assert result["times"]["total"] < 20  # the call sleeps 30 s


def test_the_deadline_reaches_inside_a_collision_sweep(monkeypatch):
    """A long sweep of collision checks stops at the run's limit: no check starts after it. The eleventh
    check waits for the limit to pass (a state, not a speed: the task planner may take long on a busy
    machine), so the sweep is cut in its middle."""
    from interlayer import deadline
    from interlayer_gripper2d import world

    late = []
    query = world.Gripper2DGeometry.query

    def slowed(self, *args):
        q = query(self, *args)
        valid = q.is_valid

        def is_valid(v):
            late.append(deadline.over())
            end = time.perf_counter() + 60  # bounded, so that a failing test ends
            while len(late) > 10 and not deadline.over() and time.perf_counter() < end:
                pass
            return valid(v)

        q.is_valid = is_valid
        return q

    monkeypatch.setattr(world.Gripper2DGeometry, "query", slowed)
    result = api.solve(EXAMPLE, {"planner.time_limit": 5, "planner.motion": "interpolate"})
    assert result.status == "timeout" and "time limit of 5 s was reached" in result.reason
    assert len(late) > 10 and not any(late)


def _trajectory_digest(result) -> str:
    data = result.problem.geometry.trajectory_json(result.plan, result.refinement)
    return hashlib.sha256(json.dumps(data, default=lambda a: a.tolist()).encode()).hexdigest()


@pytest.mark.slow
def test_a_pr2_run_gives_the_same_trajectory_on_a_slow_machine_and_a_fast_clock(monkeypatch):
    """The same seed on a machine 'loaded' two ways: every collision check slowed down, and the
    Python clock running 10 times faster. Motion queries count work (state checks), so both runs
    refine the same plan into the same trajectory; a wall-clock budget per query would not."""
    from interlayer_manip.world import ManipulationGeometry

    config = {"problem.clutter": 3, "motion_planner.time_limit": 0.05, "planner.seed": 1,
              "planner.time_limit": 6000}
    example = str(ROOT / "examples" / "pr2_pick.toml")
    idle = api.solve(example, config)
    assert idle.status == "solved", idle.reason

    timed = ManipulationGeometry._timed

    def slowed(self, fn, acc):
        def slow(v):
            end = real_clock() + 0.0005  # a collision check 0.5 ms slower: a machine under load
            while real_clock() < end:
                pass
            return fn(v)

        return timed(self, slow, acc)

    real_clock = time.perf_counter
    start = real_clock()
    monkeypatch.setattr(ManipulationGeometry, "_timed", slowed)
    monkeypatch.setattr(time, "perf_counter", lambda: start + 10 * (real_clock() - start))
    loaded = api.solve(example, config)
    monkeypatch.undo()
    assert loaded.status == "solved", loaded.reason
    assert [str(s) for s in loaded.plan] == [str(s) for s in idle.plan]
    assert _trajectory_digest(loaded) == _trajectory_digest(idle)


def test_a_task_planner_timeout_ends_the_run_instead_of_a_dead_end(monkeypatch):
    """A replan that reaches planner.task_timeout would otherwise be taken as a dead end: a path
    decided by the clock. The run ends as a timeout, naming the limit."""
    from interlayer_up import planner as up_planner

    real, calls = up_planner._solve, []

    def solve(*args):
        calls.append(args)
        return real(*args) if len(calls) == 1 else ("timeout", None, "the task planner timed out")

    monkeypatch.setattr(up_planner, "_solve", solve)
    result = api.solve(EXAMPLE, {"planner.task_timeout": 30.0, "planner.time_limit": 600.0})
    assert len(calls) == 2
    assert result.status == "timeout"
    assert "the task planner's call #2 took longer than planner.task_timeout = 30 s" in result.reason
    assert not [e for e in result.trace.events if e["type"] == "dead_end"]
