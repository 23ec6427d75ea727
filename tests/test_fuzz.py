"""Fuzzing (pytest -m robustness): bad input never gives a traceback, valid scenes never an exception.

- malformed configs and problem files (wrong types, missing keys, NaN/inf, negative or huge counts,
  unknown names, truncated files, wrong encodings) exit 0 or 2, and 2 always with one sentence;
- faults injected into every kind of plugin code are reported as that plugin's, in one line;
- generated valid Gripper-2D and Clutter scenes raise nothing, and every solved plan validates.
The counts are printed at the end of the run ("robustness: ...").
"""
import contextlib
import io
import json
import math
import textwrap
from pathlib import Path

import pytest
from conftest import ROBUSTNESS, write_plugin
from hypothesis import HealthCheck, given, settings, strategies as st

from interlayer import api
from interlayer.cli import main

pytestmark = pytest.mark.robustness
ROOT = Path(__file__).resolve().parent.parent
EXAMPLES = {name: (ROOT / "examples" / f"{name}.toml").read_text() for name in ("gripper2d", "pr2_pick", "clutter")}
FUZZ = settings(max_examples=60, deadline=None, derandomize=True, database=None,
                suppress_health_check=[HealthCheck.too_slow, HealthCheck.function_scoped_fixture])


def cli(*args) -> tuple[int, str]:
    err = io.StringIO()
    with contextlib.redirect_stderr(err), contextlib.redirect_stdout(io.StringIO()):
        code = main(list(args))
    return code, err.getvalue()


def assert_one_sentence_or_ok(code, err, what):
    assert "Traceback" not in err and "internal error" not in err, (what, err)
    if code == 2:
        lines = [line for line in err.splitlines() if line.strip() and not line.startswith("warning:")]
        assert len(lines) == 1 and lines[0].startswith("error: ") and lines[0].rstrip().endswith((".", ")")), (what, err)
        ROBUSTNESS["user errors (exit 2, one sentence)"] += 1
    else:
        assert code == 0, (what, code, err)


def toml_value(v) -> str:
    if isinstance(v, bool):
        return "true" if v else "false"
    if isinstance(v, float):
        return "nan" if math.isnan(v) else ("inf" if v == math.inf else "-inf" if v == -math.inf else repr(v))
    if isinstance(v, (list, tuple)):
        return "[" + ", ".join(toml_value(x) for x in v) + "]"
    if isinstance(v, dict):
        return "{" + ", ".join(f"{json.dumps(str(k))} = {toml_value(x)}" for k, x in v.items()) + "}"
    if isinstance(v, int):
        return str(v)
    return json.dumps(str(v))


def to_toml(config: dict) -> str:
    lines = []
    for section, table in config.items():
        if not isinstance(table, dict):
            lines.append(f"{json.dumps(section)} = {toml_value(table)}")
            continue
        lines.append(f"[{json.dumps(section)}]")
        lines += [f"{json.dumps(k)} = {toml_value(v)}" for k, v in table.items() if v is not None]
    return "\n".join(lines) + "\n"


KEYS = ["planner.task", "planner.motion", "planner.seed", "planner.time_limit", "planner.task_timeout",
        "planner.max_traj_count", "planner.max_refine_attempts", "planner.translators", "problem.domain",
        "problem.file", "problem.obstructions", "problem.s_occupied", "problem.objects", "problem.clutter",
        "problem.target_radius", "problem.grasps", "problem.goal", "problem.approach", "pose_generators.pick",
        "task_planner.fast-downward", "task_planner.pyperplan", "motion_planner.time_limit", "motion_planner.ompl"]
VALUES = st.one_of(
    st.booleans(), st.integers(-2**70, 2**70), st.sampled_from([0, -1, 1, 2, 5, 6, 40, 41, 10**9]),
    st.floats(allow_nan=True, allow_infinity=True), st.text(max_size=12),
    st.sampled_from(["gripper2d", "pr2", "fast-downward", "ompl:RRTConnect", "interpolate", "templates", "side"]),
    st.lists(st.one_of(st.integers(), st.text(max_size=6)), max_size=3),
    st.dictionaries(st.text(max_size=6), st.integers(), max_size=2),
)
MUTATION = st.one_of(
    st.tuples(st.just("set"), st.one_of(st.sampled_from(KEYS), st.builds(lambda a, b: f"{a}.{b}",
              st.sampled_from(["planner", "problem", "pose_generators", "plannr", "visualizer"]), st.text(min_size=1, max_size=8))), VALUES),
    st.tuples(st.just("delete"), st.sampled_from(KEYS), st.none()),
    st.tuples(st.just("scalar-section"), st.sampled_from(["planner", "problem", "task_planner", "motion_planner"]), VALUES),
)


@FUZZ
@given(base=st.sampled_from(["gripper2d", "pr2_pick", "clutter"]), mutations=st.lists(MUTATION, min_size=1, max_size=4),
       as_file=st.booleans())
def test_malformed_configs_exit_2_with_one_sentence(tmp_path, base, mutations, as_file):
    import tomllib

    config = tomllib.loads(EXAMPLES[base])
    config.setdefault("planner", {})
    for op, key, value in mutations:
        if op == "scalar-section":
            config[key] = value
            continue
        section, _, name = key.partition(".")
        table = config.setdefault(section, {}) if isinstance(config.get(section, {}), dict) else {}
        if op == "set":
            table[name] = value
        else:
            table.pop(name, None)
    ROBUSTNESS["configs fuzzed"] += 1
    if as_file:
        path = tmp_path / "fuzz.toml"
        path.write_text(to_toml(config), encoding="utf-8", errors="surrogatepass")
        code, err = cli("check", str(path))
    else:
        try:
            api.prepare(config)
            code, err = 0, ""
        except api.UserError as exc:
            code, err = 2, f"error: {exc}"
    assert_one_sentence_or_ok(code, err, mutations)


@FUZZ
@given(base=st.sampled_from(sorted(EXAMPLES)), cut=st.floats(0, 1), encoding=st.sampled_from(
    ["utf-8", "utf-16", "utf-32", "latin-1", "cp1252"]), junk=st.binary(max_size=16), where=st.floats(0, 1))
def test_truncated_and_misencoded_config_files(tmp_path, base, cut, encoding, junk, where):
    text = EXAMPLES[base].replace("#", "# é ", 1)
    data = text[: int(len(text) * cut)].encode(encoding, errors="replace")
    at = int(len(data) * where)
    path = tmp_path / "fuzz.toml"
    path.write_bytes(data[:at] + junk + data[at:])
    ROBUSTNESS["files fuzzed"] += 1
    code, err = cli("check", str(path))
    assert_one_sentence_or_ok(code, err, (base, cut, encoding, junk))


JSON_VALUES = st.recursive(st.one_of(st.none(), st.booleans(), st.integers(), st.floats(allow_nan=False), st.text(max_size=8)),
                           lambda inner: st.one_of(st.lists(inner, max_size=3), st.dictionaries(st.text(max_size=6), inner, max_size=3)),
                           max_leaves=12)


@FUZZ
@given(data=st.one_of(st.fixed_dictionaries({"bodies": JSON_VALUES, "robots": JSON_VALUES, "task": JSON_VALUES}), JSON_VALUES),
       suffix=st.sampled_from([".json", ".JSON", ".txt", ""]), raw=st.one_of(st.none(), st.binary(max_size=64)))
def test_malformed_problem_files(tmp_path, data, suffix, raw):
    path = tmp_path / f"problem{suffix}"
    path.write_bytes(raw if raw is not None else json.dumps(data).encode())
    ROBUSTNESS["files fuzzed"] += 1
    code, err = cli("check", str(path))
    assert code == 2, err
    assert_one_sentence_or_ok(code, err, data)


SHARED_JSON = ROOT.parent / "shared" / "benchmarks" / "pybullet-planning-json"


@pytest.mark.skipif(not SHARED_JSON.is_dir(), reason=f"{SHARED_JSON} (beside the checkout) is absent")
@settings(FUZZ, max_examples=25)
@given(path=st.sampled_from(sorted(p.name for p in SHARED_JSON.glob("*.json")) if SHARED_JSON.is_dir() else ["-"]),
       drop=st.lists(st.sampled_from(["bodies", "robots", "task", "links", "point", "quat", "object_names",
                                      "table_names", "goal_holding", "name", "x", "z"]), min_size=1, max_size=3),
       cut=st.one_of(st.none(), st.floats(0, 1)))
def test_mutated_pybullet_planning_problems(tmp_path, path, drop, cut):
    """Real pybullet-planning problems with keys removed throughout, or truncated."""
    text = (SHARED_JSON / path).read_text()

    def strip(node):
        if isinstance(node, dict):
            return {k: strip(v) for k, v in node.items() if k not in drop}
        if isinstance(node, list):
            return [strip(v) for v in node]
        return node

    out = tmp_path / path
    out.write_text(text[: int(len(text) * cut)] if cut is not None else json.dumps(strip(json.loads(text))))
    ROBUSTNESS["files fuzzed"] += 1
    code, err = cli("check", str(out))
    assert_one_sentence_or_ok(code, err, (path, drop, cut))


# -- faults injected into every kind of plugin code ---------------------------------------------
FAULTY = '''
    import os
    from interlayer import hookimpl

    FAULT = {"where": None, "exc": None}


    def fail(where):
        if FAULT["where"] == where:
            raise FAULT["exc"](f"injected into the {where}")


    @hookimpl
    def interlayer_register_domains(registry):
        fail("domain registration")
        from interlayer_gripper2d.plugin import PARAMS, make_problem

        def make(params, seed):
            fail("domain factory")
            problem = make_problem(params, seed)
            refine = problem.geometry.refine_step

            def refine_step(*args):
                fail("geometry")
                return refine(*args)

            problem.geometry.refine_step = refine_step
            return problem

        registry.add("faulty", make, "Gripper-2D with faults", params=PARAMS)


    @hookimpl
    def interlayer_register_motion_planners(registry):
        def make(options):
            from interlayer.motion import InterpolatingPlanner

            class Planner(InterpolatingPlanner):
                def _plan(self, *args):
                    fail("motion planner")
                    return super()._plan(*args)

            return Planner(name="faulty:motion")

        registry.add("faulty:motion", make, "interpolate, with faults")


    @hookimpl
    def interlayer_register_task_planners(registry):
        def make(options):
            from interlayer_up.plugin import _factory

            planner = _factory("fast-downward", {})({})
            plan = planner._plan

            def faulty(*args):
                fail("task planner")
                return plan(*args)

            planner._plan = faulty
            return planner

        registry.add("faulty:task", make, "Fast Downward, with faults")


    @hookimpl
    def interlayer_register_pose_generators(registry):
        from interlayer_gripper2d import generators

        def pick(*args):
            fail("pose generator")
            yield from generators.pick(*args)

        registry.add("faulty:pick", pick, "Gripper-2D's pick, with faults")


    @hookimpl
    def interlayer_register_failure_translators(registry):
        def translate(failure, step, model):
            fail("failure translator")
            return set()

        registry.add("faulty:translate", translate, "no facts, with faults")


    @hookimpl
    def interlayer_on_event(event):
        if event["type"] == "refine":
            fail("event observer")
'''
WHERE = {"domain registration": 2, "domain factory": 1, "geometry": 1, "motion planner": 1, "task planner": 1,
         "pose generator": 1, "failure translator": 1, "event observer": 1}
COMPONENT = {"domain registration": "interlayer_register_domains hook", "domain factory": "domain 'faulty'",
             "geometry": "domain 'faulty' geometry (refine_step)", "motion planner": "motion planner 'faulty:motion' (plan)",
             "task planner": "task planner 'faulty:task'", "pose generator": "pose generator 'faulty:pick'",
             "failure translator": "failure translator 'faulty:translate'", "event observer": "event observer"}


@pytest.fixture(scope="module")
def faulty(tmp_path_factory):
    import importlib
    import sys

    folder = write_plugin(tmp_path_factory.mktemp("faulty"), "il_faulty", textwrap.dedent(FAULTY))
    sys.path.insert(0, str(folder))
    importlib.invalidate_caches()
    import il_faulty

    yield il_faulty
    sys.path.remove(str(folder))
    sys.modules.pop("il_faulty", None)


@pytest.mark.parametrize("where", sorted(WHERE))
@settings(FUZZ, max_examples=3)
@given(exc=st.sampled_from([ValueError, KeyError, RuntimeError, ZeroDivisionError,
                                                                    AssertionError, TypeError, IndexError, AttributeError]))
def test_faults_injected_into_plugins_are_attributed(faulty, tmp_path, where, exc):
    faulty.FAULT.update(where=where, exc=exc)
    try:
        code, err = cli("plan", str(ROOT / "examples" / "gripper2d.toml"), "-q", "--out", str(tmp_path / "run"),
                        "--set", "problem.domain=faulty", "--set", "planner.motion=faulty:motion",
                        "--set", "planner.task=faulty:task", "--set", "pose_generators.pick=faulty:pick",
                        "--set", 'planner.translators=["templates", "faulty:translate"]')
    finally:
        faulty.FAULT.update(where=None, exc=None)
    ROBUSTNESS["faults injected"] += 1
    assert "Traceback" not in err and "internal error" not in err, err
    lines = [line for line in err.splitlines() if line.startswith("error:")]
    assert code == WHERE[where] and len(lines) == 1, (where, exc, code, err)
    assert "'il_faulty' failed" in lines[0] and COMPONENT[where] in lines[0] and exc.__name__ in lines[0], lines[0]


# -- valid scenes: no exception, every solved plan validates ------------------------------------
def solve_and_validate(tmp_path, config, overrides, label):
    result = api.solve(config, overrides)
    ROBUSTNESS[f"{label} scenes"] += 1
    if result.solved:
        out = tmp_path / f"run-{ROBUSTNESS[f'{label} scenes']}"
        api.write_outputs(result, out)
        violations = api.validate(out)
        assert violations == [], (overrides, violations)
        ROBUSTNESS[f"{label} plans validated"] += 1
    else:
        assert result.status in ("timeout", "unsolvable", "gave_up") and result.reason
        ROBUSTNESS[f"{label} not solved ({result.status}: {result.reason[:100]}; {overrides})"] += 1


@settings(FUZZ, max_examples=8)
@given(obstructions=st.integers(0, 3), s_occupied=st.booleans(), seed=st.integers(0, 10**6),
       motion=st.sampled_from(["interpolate", "ompl:RRTConnect", "ompl:PRM"]))
def test_valid_gripper2d_scenes_solve_into_valid_plans(tmp_path, obstructions, s_occupied, seed, motion):
    solve_and_validate(tmp_path, str(ROOT / "examples" / "gripper2d.toml"),
                       {"problem.obstructions": obstructions, "problem.s_occupied": s_occupied, "planner.seed": seed,
                        "planner.motion": motion, "planner.time_limit": 60.0}, "Gripper-2D")


@settings(FUZZ, max_examples=3)
@given(objects=st.integers(1, 8), seed=st.integers(0, 10**6))
def test_valid_clutter_scenes_solve_into_valid_plans(tmp_path, objects, seed):
    solve_and_validate(tmp_path, str(ROOT / "examples" / "clutter.toml"),
                       {"problem.objects": objects, "planner.seed": seed, "planner.time_limit": 90.0}, "Clutter")


# -- the validator accepts no invalid plan ------------------------------------------------------
@pytest.fixture(scope="module")
def solved_fig2(tmp_path_factory):
    out = tmp_path_factory.mktemp("fig2") / "run"
    result = api.solve(str(ROOT / "examples" / "gripper2d.toml"))
    assert result.solved, result.reason
    api.write_outputs(result, out)
    assert api.validate(out) == []
    return out


@settings(FUZZ, max_examples=20)
@given(kind=st.sampled_from(["wall waypoint", "jump", "drop grasp", "drop step", "swap steps"]), pick=st.integers(0, 10**6),
       shift=st.floats(0.05, 0.5))
def test_the_validator_rejects_corrupted_runs(solved_fig2, tmp_path, kind, pick, shift):
    import shutil

    out = tmp_path / "run"
    shutil.copytree(solved_fig2, out, dirs_exist_ok=True)
    result, trajectory = json.loads((out / "result.json").read_text()), json.loads((out / "trajectory.json").read_text())
    steps = trajectory["steps"]
    paths = [seg for s in steps for seg in s["segments"] if seg.get("kind") == "transit"]
    wall = json.loads((out / "problem.json").read_text())["source"]["layout"]["walls"]["wall_end"]
    if kind == "wall waypoint":
        seg = paths[pick % len(paths)]
        seg["path"].insert(1, [wall[0], wall[1], 0.0])
    elif kind == "jump":
        seg = paths[pick % len(paths)]
        seg["path"][-1] = [seg["path"][-1][0] + shift, seg["path"][-1][1], seg["path"][-1][2]]
    elif kind == "drop grasp":
        s = [s for s in steps if any(seg.get("kind") == "grasp" for seg in s["segments"])][pick % 2]
        s["segments"] = [seg for seg in s["segments"] if seg.get("kind") != "grasp"]
    elif kind == "drop step":
        k = pick % len(steps)
        del steps[k], result["plan"][k]
    else:
        k = pick % (len(steps) - 1)
        steps[k], steps[k + 1] = steps[k + 1], steps[k]
        result["plan"][k], result["plan"][k + 1] = result["plan"][k + 1], result["plan"][k]
    (out / "result.json").write_text(json.dumps(result))
    (out / "trajectory.json").write_text(json.dumps(trajectory))
    ROBUSTNESS["corrupted runs given to the validator"] += 1
    violations = api.validate(out)
    assert violations, (kind, pick, shift)
    ROBUSTNESS["corrupted runs rejected"] += 1
