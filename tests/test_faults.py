"""Faults in plugins are contained and attributed; bad plugins never break the rest of the CLI.

Each test installs a small throwaway plugin through a real entry point (a dist-info on sys.path)."""
import contextlib
import json
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest

from interlayer import api
from interlayer.cli import main
from interlayer.faults import PluginFault
from interlayer.plugins import PluginHost

ROOT = Path(__file__).resolve().parent.parent
EXAMPLE = str(ROOT / "examples" / "gripper2d.toml")

MISSPELT = """
    from interlayer import hookimpl

    @hookimpl
    def interlayer_register_domains(reg):  # 'reg' for 'registry'
        pass
"""


def run_cli(capsys, *args):
    code = main(list(args))
    out, err = capsys.readouterr()
    return code, out, err


def test_a_plugin_failing_validation_is_skipped_and_named(plugin_dir, capsys):
    plugin_dir("il_misspelt", MISSPELT)
    host = PluginHost()
    assert "il_misspelt" in host.broken and "use (registry)" in host.broken["il_misspelt"]
    assert "gripper2d" in host["domains"].names()  # every other plugin still works
    code, out, err = run_cli(capsys, "plugins")
    assert code == 0 and "il_misspelt: failed to load, skipped:" in out and "gripper2d" in out
    code, out, err = run_cli(capsys, "check", EXAMPLE)
    assert code == 0, err


def test_an_unknown_hook_name_is_reported_with_the_nearest_hook(plugin_dir):
    plugin_dir("il_typo_hook", """
        from interlayer import hookimpl

        @hookimpl
        def interlayer_register_domain(registry):
            pass
    """)
    why = PluginHost().broken["il_typo_hook"]
    assert "'interlayer_register_domain' is not an Interlayer hook (did you mean 'interlayer_register_domains'?)" in why


def test_plan_on_a_domain_of_a_plugin_that_failed_to_import_says_why(plugin_dir, capsys):
    plugin_dir("il_shelf", """
        import no_such_module_for_the_shelf
    """)
    code, out, err = run_cli(capsys, "plan", EXAMPLE, "--set", "problem.domain=shelf", "-q")
    assert code == 2
    assert "Unknown domain 'shelf'" in err and "the plugin 'il_shelf' failed to load" in err
    assert "ModuleNotFoundError: No module named 'no_such_module_for_the_shelf'" in err


def test_a_register_hook_that_raises_is_rolled_back(plugin_dir):
    plugin_dir("il_half", """
        from interlayer import hookimpl

        @hookimpl
        def interlayer_register_motion_planners(registry):
            registry.add("half:one", lambda options: None, "registered before the crash")
            raise ValueError("oops")
    """)
    host = PluginHost()
    assert "half:one" not in host["motion_planners"].components
    assert "interlayer_register_motion_planners hook raised ValueError: oops" in host.broken["il_half"]


def test_a_plugin_cannot_take_a_builtin_name_silently(plugin_dir, capsys):
    plugin_dir("il_shadow", """
        from interlayer import hookimpl

        @hookimpl
        def interlayer_register_motion_planners(registry):
            registry.add("interpolate", lambda options: None, "a different planner under a taken name")
    """)
    host = PluginHost()
    assert host["motion_planners"].get("interpolate").plugin == "builtin"
    assert any("'il_shadow' registers the motion planner 'interpolate', which the plugin 'builtin' already provides"
               in w for w in host.warnings)
    code, out, err = run_cli(capsys, "plan", EXAMPLE, "-q", "--set", "planner.motion=interpolate")
    assert code == 0 and "warning: the plugin 'il_shadow' registers" not in err  # -q: no progress lines
    code, out, err = run_cli(capsys, "check", EXAMPLE)
    assert "warning: the plugin 'il_shadow' registers the motion planner 'interpolate'" in err


CRASHING_PLANNER = """
    from interlayer import hookimpl

    @hookimpl
    def interlayer_register_motion_planners(registry):
        def make(options):
            from interlayer.motion import MotionPlanner

            class Crashing(MotionPlanner):
                def _plan(self, space, start, goal, is_valid, time_limit):
                    raise ZeroDivisionError("the planner divided by zero")

            return Crashing(name="crash:planner")

        registry.add("crash:planner", make, "raises")
"""


def test_an_exception_in_a_plugin_planner_is_that_plugins(plugin_dir, capsys, monkeypatch):
    plugin_dir("il_crash", CRASHING_PLANNER)
    with pytest.raises(PluginFault) as info:
        api.solve(EXAMPLE, {"planner.motion": "crash:planner"})
    assert info.value.plugin == "il_crash" and isinstance(info.value.__cause__, ZeroDivisionError)
    monkeypatch.delenv("INTERLAYER_DEBUG", raising=False)
    code, out, err = run_cli(capsys, "plan", EXAMPLE, "-q", "--set", "planner.motion=crash:planner")
    assert code == 1 and "Traceback" not in err and "please report" not in err
    line = [l for l in err.splitlines() if l.startswith("error:")]
    assert line == [line[0]] and "the plugin 'il_crash' failed: its motion planner 'crash:planner' (plan) raised " \
        "ZeroDivisionError: the planner divided by zero (at il_crash.py:" in line[0]


def test_interlayer_debug_shows_the_plugins_traceback(plugin_dir, tmp_path):
    folder = plugin_dir("il_crash2", CRASHING_PLANNER.replace("crash:planner", "crash2:planner"))
    env = dict(os.environ, PYTHONPATH=str(folder), INTERLAYER_DEBUG="1")
    proc = subprocess.run([sys.executable, "-m", "interlayer.cli", "plan", EXAMPLE, "-q", "--set",
                           "planner.motion=crash2:planner"], capture_output=True, text=True, env=env, timeout=120)
    assert proc.returncode != 0 and "Traceback" in proc.stderr and "ZeroDivisionError" in proc.stderr
    assert "il_crash2.py" in proc.stderr


def test_a_failing_generator_and_translator_are_attributed(plugin_dir):
    plugin_dir("il_badgen", """
        from interlayer import hookimpl

        @hookimpl
        def interlayer_register_pose_generators(registry):
            def pick(problem, step, world, rng):
                yield from ()
                raise KeyError("grasp table")

            registry.add("badgen:pick", pick, "raises")

        @hookimpl
        def interlayer_register_failure_translators(registry):
            registry.add("badgen:translate", lambda failure, step, model: 1 / 0, "raises")
    """)
    with pytest.raises(PluginFault, match=r"its pose generator 'badgen:pick' raised KeyError: 'grasp table'"):
        api.solve(EXAMPLE, {"pose_generators.pick": "badgen:pick"})
    with pytest.raises(PluginFault, match=r"its failure translator 'badgen:translate' raised ZeroDivisionError"):
        api.solve(EXAMPLE, {"planner.translators": ["templates", "badgen:translate"]})


WRONG_TYPES = """
    from interlayer import hookimpl
    from interlayer.motion import MotionPlanner
    from interlayer.planning import TaskPlanner
    from interlayer.plugin_api import Candidate, EpochState


    def strings(problem, step, world, rng):
        yield "a grasp"

    def dicts(problem, step, world, rng):
        yield {"waypoints": ()}

    def words(problem, step, world, rng):
        yield Candidate(((0.0, 0.1), ("left", "right")), {}, "words")

    def number(problem, step, world, rng):
        return 5

    def numbered(problem, step, world, rng):
        yield Candidate(((0.0, 0.1), (0.0, 0.2)), {}, 7)

    class Remembers(EpochState):
        def __call__(self, problem, step, world, rng):
            return [b"a grasp"]


    class Garbage(TaskPlanner):
        def _plan(self, model, state, timeout):
            return None

    class Sentence:
        def plan(self, model, state, timeout):
            return "pick then place"

    class Done(TaskPlanner):
        def _plan(self, model, state, timeout):
            return "done", [], "", 0


    class Talks(MotionPlanner):
        def plan(self, query, time_limit=None, straight=True):
            return "a path"

    class Flat(MotionPlanner):
        searches = False

        def _plan(self, space, start, goal, is_valid, time_limit):
            return [0.0, 1.0]


    @hookimpl
    def interlayer_register_pose_generators(registry):
        for f in (strings, dicts, words, number, numbered, Remembers):
            registry.add("wrong:" + f.__name__, f, "misbehaves")

    @hookimpl
    def interlayer_register_failure_translators(registry):
        registry.add("wrong:int", lambda failure, step, model: 5, "an int")
        registry.add("wrong:text", lambda failure, step, model: {"Obstructs b2 gp_b1 b1"}, "strings")
        registry.add("wrong:unknown", lambda failure, step, model: {("Nonsense", "b2")}, "an unknown predicate")
        registry.add("wrong:arity", lambda failure, step, model: {("Obstructs", "b2")}, "too few arguments")

    @hookimpl
    def interlayer_register_task_planners(registry):
        registry.add("wrong:none", lambda options: Garbage(name="wrong:none"), "its _plan returns None")
        registry.add("wrong:sentence", lambda options: Sentence(), "returns a string")
        registry.add("wrong:done", lambda options: Done(name="wrong:done"), "an unknown status")

    @hookimpl
    def interlayer_register_motion_planners(registry):
        registry.add("wrong:talks", lambda options: Talks(name="wrong:talks"), "returns a string")
        registry.add("wrong:flat", lambda options: Flat(name="wrong:flat"), "a path of numbers, not configurations")
"""

TRANSLATE = 'planner.translators=["templates", "wrong:{}"]'


@pytest.mark.parametrize("setting, sentence", [
    ("pose_generators.pick=wrong:strings", "its pose generator 'wrong:strings' failed: it yielded str 'a grasp', not a Candidate"),
    ("pose_generators.pick=wrong:dicts", "its pose generator 'wrong:dicts' failed: it yielded dict {'waypoints': ()}, not a Candidate"),
    ("pose_generators.pick=wrong:words", "its pose generator 'wrong:words' failed: it yielded a Candidate whose waypoint 1 "
                                         "is tuple ('left', 'right'), not a configuration (numbers)"),
    ("pose_generators.pick=wrong:number", "its pose generator 'wrong:number' failed: it returned int 5, not Candidates"),
    ("pose_generators.pick=wrong:numbered", "its pose generator 'wrong:numbered' failed: it yielded a Candidate whose "
                                            "label is int 7, not a string"),
    ("pose_generators.pick=wrong:Remembers", "its pose generator 'wrong:Remembers' failed: it yielded bytes b'a grasp', "
                                             "not a Candidate"),
    (TRANSLATE.format("int"), "its failure translator 'wrong:int' failed: it returned int 5, not a set of atoms"),
    (TRANSLATE.format("text"), "its failure translator 'wrong:text' failed: it returned str 'Obstructs b2 gp_b1 b1' "
                               "among its facts, not an atom"),
    (TRANSLATE.format("unknown"), "its failure translator 'wrong:unknown' failed: it returned the fact Nonsense b2, "
                                  "whose predicate 'Nonsense' is not the domain's"),
    (TRANSLATE.format("arity"), "its failure translator 'wrong:arity' failed: it returned the fact Obstructs b2, "
                                "but 'Obstructs' takes 3 arguments"),
    ("planner.task=wrong:none", "its task planner 'wrong:none' (plan) failed: its _plan returned NoneType None, "
                                "not (status, steps, reason, cost)"),
    ("planner.task=wrong:sentence", "its task planner 'wrong:sentence' (plan) failed: it returned str 'pick then place', "
                                    "not a TaskPlanResult"),
    ("planner.task=wrong:done", "its task planner 'wrong:done' (plan) failed: it returned the status 'done', "
                                "not one of solved, unsolvable, incomplete, timeout, error"),
    ("planner.motion=wrong:talks", "its motion planner 'wrong:talks' (plan) failed: it returned str 'a path', not a MotionPlan"),
    ("planner.motion=wrong:flat", "its motion planner 'wrong:flat' (plan) failed: it returned a path whose configuration 0 "
                                  "is ndarray array(0.), not 3 numbers"),
])
def test_a_hooks_answer_of_the_wrong_type_is_its_plugins_fault(plugin_dir, capsys, monkeypatch, setting, sentence):
    """Not "internal error", and not the fault of the component handed the answer (the domain's geometry)."""
    plugin_dir("il_wrong", WRONG_TYPES)
    monkeypatch.delenv("INTERLAYER_DEBUG", raising=False)
    code, out, err = run_cli(capsys, "plan", EXAMPLE, "-q", "--set", setting)
    errors = [line for line in err.splitlines() if line.startswith("error:")]
    assert code == 1 and len(errors) == 1 and "Traceback" not in err, err
    assert errors[0].startswith(f"error: the plugin 'il_wrong' failed: {sentence}"), errors[0]


def test_a_domain_or_loader_returning_no_problem_is_its_plugins_fault(plugin_dir, capsys, tmp_path):
    plugin_dir("il_noproblem", """
        from interlayer import hookimpl

        @hookimpl
        def interlayer_register_domains(registry):
            registry.add("noproblem", lambda params, seed: "a problem", "returns a string")

        @hookimpl
        def interlayer_load_problem(path, params, seed):
            return {"objects": []} if path.suffix == ".noproblem" else None
    """)
    (tmp_path / "noproblem.toml").write_text('[problem]\ndomain = "noproblem"\n')
    code, out, err = run_cli(capsys, "plan", str(tmp_path / "noproblem.toml"), "-q")
    assert code == 1 and "error: the plugin 'il_noproblem' failed: its domain 'noproblem' failed: it returned str " \
        "'a problem', not a Problem" in err
    (tmp_path / "scene.noproblem").write_text("")
    code, out, err = run_cli(capsys, "plan", str(tmp_path / "scene.noproblem"), "-q")
    assert code == 1 and "error: the plugin 'il_noproblem' failed: its problem loader (interlayer_load_problem) " \
        "failed: it returned dict {'objects': []}, not a Problem" in err


def test_a_geometry_returning_no_step_outcome_is_the_domains_fault(monkeypatch, capsys):
    from interlayer_gripper2d.world import Gripper2DGeometry

    monkeypatch.setattr(Gripper2DGeometry, "refine_step", lambda self, step, world, candidate, motion: (True, world))
    code, out, err = run_cli(capsys, "plan", EXAMPLE, "-q")
    assert code == 1 and "error: the plugin 'gripper2d' failed: its domain 'gripper2d' geometry (refine_step) failed: " \
        "it returned tuple (True, " in err and "not a StepOutcome" in err


def test_validate_says_when_the_trajectory_was_not_rechecked(tmp_path, capsys, plugin_dir):
    """A domain without a trajectory validator: 'valid' must not claim the trajectory was re-checked."""
    plugin_dir("il_novalidate", """
        from interlayer import hookimpl

        @hookimpl
        def interlayer_register_domains(registry):
            from interlayer_gripper2d.plugin import PARAMS, make_problem

            def make(params, seed):
                problem = make_problem(params, seed)
                problem.geometry.validate = None  # this domain ships no trajectory validator
                del problem.geometry.validate
                return problem

            registry.add("g2d-novalidate", make, "Gripper-2D without its validator", params=PARAMS)
    """)
    import interlayer_gripper2d.world as world

    monkeypatch_validate = world.Gripper2DGeometry.validate
    try:
        del world.Gripper2DGeometry.validate
        out = tmp_path / "run"
        code, _, err = run_cli(capsys, "plan", EXAMPLE, "-q", "--out", str(out), "--set", "problem.domain=g2d-novalidate")
        assert code == 0, err
        code, _, err = run_cli(capsys, "validate", str(out))
        assert code == 0 and "trajectory NOT re-checked: the domain 'gripper2d' has no trajectory validator" in err
        assert "trajectory re-checked by the domain" not in err
    finally:
        world.Gripper2DGeometry.validate = monkeypatch_validate
    code, _, err = run_cli(capsys, "validate", str(out))
    assert code == 0 and "trajectory re-checked by the domain" in err


def test_a_crashing_task_planner_process_is_reported(monkeypatch):
    """pyperplan runs in a forked child: a child that dies is an error of that planner, not a hang."""
    from interlayer_up import planner as up_planner

    def die(*args):
        os._exit(3)

    monkeypatch.setattr(up_planner, "_solve", die)  # narrowly scoped: the child's work replaced by a crash
    with pytest.raises(PluginFault, match=r"the plugin 'unified-planning' failed: its task planner 'pyperplan' failed: "
                                          r"the task planner process 'pyperplan' died \(exit code 3\)"):
        api.solve(EXAMPLE, ["planner.task=pyperplan"])


def test_a_task_planner_engine_that_fails_is_not_a_dead_end(capsys):
    """Fast Downward rejecting its search string used to read as 'no plan for the initial state'."""
    code, out, err = run_cli(capsys, "plan", EXAMPLE, "-q", "--set", 'task_planner.fast-downward.search="bogus("')
    assert code == 1 and "no plan" not in err
    assert "its task planner 'fast-downward' failed: the engine 'fast-downward' failed (INTERNAL_ERROR): " in err


def test_a_hanging_task_planner_process_is_killed_at_its_limit(monkeypatch):
    from interlayer_up import planner as up_planner

    monkeypatch.setattr(up_planner, "_solve", lambda *args: time.sleep(600))
    t0 = time.perf_counter()
    result = api.solve(EXAMPLE, ["planner.task=pyperplan", "planner.time_limit=2"])
    assert time.perf_counter() - t0 < 10
    assert result.status == "timeout"
    calls = [e for e in result.trace.events if e["type"] == "task_plan"]
    assert calls[0]["status"] == "timeout" and "the task planner 'pyperplan' timed out" in calls[0]["reason"]


@pytest.mark.parametrize("sig", ["SIGINT", "SIGTERM", "SIGHUP"])  # Ctrl-C; kill, timeout, CI; a closed terminal
def test_a_signal_during_plan_writes_the_trace_and_exits_130(plugin_dir, tmp_path, sig):
    folder = plugin_dir("il_slow", """
        import sys, time
        from interlayer import hookimpl

        @hookimpl
        def interlayer_register_pose_generators(registry):
            def pick(problem, step, world, rng):
                print("generating", file=sys.stderr, flush=True)
                time.sleep(60)
                yield from ()

            registry.add("slow:pick", pick, "sleeps")
    """)
    out = tmp_path / "run"
    env = dict(os.environ, PYTHONPATH=os.pathsep.join([str(folder), os.environ.get("PYTHONPATH", "")]))  # this checkout first
    env.pop("INTERLAYER_DEBUG", None)
    # A shell's background job (CI run with `&`) starts with SIGINT ignored, and so would the CLI:
    # give it the default disposition, as in a terminal.
    proc = subprocess.Popen([sys.executable, "-m", "interlayer.cli", "plan", EXAMPLE, "--out", str(out),
                             "--set", "pose_generators.pick=slow:pick"], stderr=subprocess.PIPE, text=True, env=env,
                            preexec_fn=lambda: signal.signal(signal.SIGINT, signal.SIG_DFL))
    for line in proc.stderr:
        if "generating" in line:
            break
    proc.send_signal(getattr(signal, sig))
    err = proc.stderr.read()
    assert proc.wait(timeout=60) == 130, err
    assert "Traceback" not in err and "interrupted" in err
    events = json.loads((out / "trace.json").read_text())["events"]
    assert events[-1]["type"] == "end" and events[-1]["status"] == "interrupted"
    assert any(e["type"] == "task_plan" for e in events)
    assert json.loads((out / "result.json").read_text())["status"] == "interrupted"
    assert not (out / "trajectory.json").exists()


@pytest.mark.skipif(not Path("/proc/self/task").exists(), reason="reads a process's children from /proc")
def test_a_signal_to_the_whole_group_stops_a_task_planner_child_without_its_traceback(tmp_path):
    # `timeout` and a terminal's Ctrl-C signal the whole process group: the forked task-planner child too
    env = {k: v for k, v in os.environ.items() if k != "INTERLAYER_DEBUG"}
    proc = subprocess.Popen([sys.executable, "-m", "interlayer.cli", "plan", EXAMPLE, "-q", "--out", str(tmp_path / "run"),
                             "--set", "problem.obstructions=5", "--set", "planner.task=pyperplan",
                             "--set", "planner.time_limit=300"], stderr=subprocess.PIPE, text=True, env=env,
                            start_new_session=True)
    children = Path(f"/proc/{proc.pid}/task/{proc.pid}/children")

    def child_at_work():  # a child that has used 50 ms of CPU: inside the engine (a state, not a time)
        for pid in children.read_text().split():
            with contextlib.suppress(OSError):
                if sum(int(v) for v in Path(f"/proc/{pid}/stat").read_text().rsplit(")", 1)[1].split()[11:13]) >= 5:
                    return True
        return False

    while proc.poll() is None and not child_at_work():
        time.sleep(0.005)
    assert proc.poll() is None, "the run ended before its task planner's process started"
    os.killpg(proc.pid, signal.SIGTERM)
    err = proc.communicate(timeout=60)[1]
    assert proc.returncode == 130, err
    assert "Traceback" not in err and "interrupted" in err, err
