"""The Python API; the CLI is a thin layer over these functions."""
from __future__ import annotations

import json
import time
from dataclasses import dataclass
from pathlib import Path

from . import config as cfg, contracts, runfolder, shipped
from .abstraction import TaskModel, abstract
from .errors import UserError
from .faults import ComponentFailed, Guarded, PluginFault, blame, blamed
from .loop import InterfaceLayer, Interrupted, LoopSettings
from .names import relabel
from .plugins import PluginHost
from .refine import EpochState, drawn_within
from .result import Result
from .trace import Stats, Trace


def resolve_config(source, overrides=None) -> dict:
    """A resolved config from a TOML path, a problem file, an output folder or a dict."""
    if isinstance(source, dict):
        raw = source
    else:
        path = Path(source)
        if not path.exists():  # a shipped example by name ("gripper2d"), also from an installed wheel
            path = shipped.find("examples", str(source)) or path
        if path.is_dir():
            if not (path / "config.toml").exists():
                raise UserError(f"The folder {path} has no config.toml; give a config file or a folder written by 'interlayer plan --out'.")
            raw = cfg.load_toml(path / "config.toml")
        elif not path.exists():
            hint = (f"; the shipped examples are {', '.join(shipped.names('examples')) or 'not installed'}"
                    if str(path.parent) in (".", "examples") else "")
            raise UserError(f"No such file or folder: {path}{hint}.")
        elif path.suffix == ".toml":
            raw = cfg.load_toml(path)
            file = raw.get("problem", {}).get("file")
            if file and not Path(file).is_absolute():  # relative to the config file
                raw["problem"]["file"] = str((path.parent / file).resolve())
        else:
            raw = {"problem": {"file": str(path.resolve())}}
    config = cfg.merge(cfg.default_config(), raw)
    if isinstance(overrides, dict):  # {"planner.task": "pyperplan"}: values as they are
        overrides = [(k, v) for k, v in overrides.items()]
    for assignment in overrides or ():
        if isinstance(assignment, tuple):
            cfg.set_value(config, *assignment)
        else:
            cfg.apply_override(config, assignment)
    cfg.check(config, None)
    return config


GEOMETRY_METHODS = ("initial_world", "refine_step", "snapshot", "trajectory_json", "validate", "scene_issues",
                    "prepare_export")


def build_problem(host: PluginHost, config: dict):
    """The Problem the config names, its geometry guarded so that its faults name its plugin."""
    params = {k: v for k, v in config["problem"].items() if k not in ("domain", "file")}
    seed = config["planner"]["seed"]
    if config["problem"].get("file"):
        path = Path(config["problem"]["file"])
        if not path.exists():
            raise UserError(f"The problem file {path} does not exist.")
        problem = host.load_problem(path, params, seed)
        if problem is None:
            broken = "".join(f"; the plugin '{p}' failed to load ({why})" for p, why in host.broken.items())
            raise UserError(f"No installed plugin can read the problem file {path}; see 'interlayer plugins' for loaders{broken}.")
        comp = host["domains"].components.get((problem.source or {}).get("domain", problem.domain.name))
    else:
        name = config["problem"].get("domain")
        if not name:
            raise UserError("The config names no problem: set [problem] domain = \"...\" or file = \"...\".")
        comp = host["domains"].get(name)
        cfg.check(config, comp.params)
        with blame(comp.plugin, comp.label):
            problem = contracts.problem(comp.factory({**comp.params, **params}, seed))
    if comp is not None:
        if problem.drawing is None:
            problem.drawing = comp.drawing
        if not isinstance(problem.geometry, Guarded):
            checks = {**dict.fromkeys(GEOMETRY_METHODS), "refine_step": lambda outcome, *_: contracts.step_outcome(outcome)}
            problem.geometry = Guarded(problem.geometry, comp.plugin, f"{comp.label} geometry", checks)
    return problem


def make_planners(host: PluginHost, config: dict, stats: Stats):
    return make_task_planner(host, config), make_motion_planner(host, config, config["planner"]["motion"], stats)


def make_task_planner(host: PluginHost, config: dict):
    name = config["planner"]["task"]
    comp = host["task_planners"].get(name)
    with blame(comp.plugin, comp.label):
        task = comp.factory(dict(config["task_planner"].get(name, {})))
    return _TaskPlannerGuard(task, comp)


def make_motion_planner(host: PluginHost, config: dict, name: str, stats: Stats):
    """The motion planner ``name`` with ``[motion_planner]`` options and its family's section
    (e.g. ``[motion_planner.trajopt]``), its faults attributed to its plugin."""
    comp = host["motion_planners"].get(name)
    options = {k: v for k, v in config["motion_planner"].items() if not isinstance(v, dict)}
    options.update(config["motion_planner"].get(name.split(":")[0], {}))
    with blame(comp.plugin, comp.label):
        motion = comp.factory(options)
    motion.stats = stats
    motion.seed = config["planner"]["seed"]
    # its answers are checked here, so that a wrong one is this plugin's fault, not the domain's that asked
    return Guarded(motion, comp.plugin, comp.label, {"plan": lambda res, query, *_: contracts.motion_plan(res, query)})


class _TaskPlannerGuard(Guarded):
    """A task planner whose exceptions, answers of the wrong type and answers with status "error"
    name its plugin."""

    def __init__(self, task, comp):
        checks = {"plan": lambda res, model, *_: contracts.task_result(res, model), "validate_plan": None,
                  "library_check": None}
        super().__init__(task, comp.plugin, comp.label, checks)

    def plan(self, model, state, timeout):
        plugin, component, _ = self._guard
        res = self.__getattr__("plan")(model, state, timeout)
        if res.status == "error":
            raise PluginFault(plugin, component, ComponentFailed(res.reason))
        return res


def generators_for(host: PluginHost, model: TaskModel, config: dict) -> dict:
    """Action name -> its pose generator, its faults attributed to its plugin; each carries
    ``labels`` (action -> "pose generator 'name'") for the loop's reports."""
    out, classes = {}, {}
    for action in model.problem.domain.actions:
        name = config["pose_generators"].get(action.name, action.pose_generator)
        if name is None:
            raise UserError(f"The action '{action.name}' has no pose generator; set [pose_generators] {action.name} = \"...\".")
        comp = host["pose_generators"].get(name)
        if isinstance(comp.factory, type) and issubclass(comp.factory, EpochState):
            # one guarded subclass per class: the actions it serves still share one instance per epoch
            if comp.factory not in classes:
                classes[comp.factory] = _guarded_epoch_state(comp.factory, comp.plugin)
            out[action.name] = classes[comp.factory]
        else:
            out[action.name] = _generator(comp)
        out[action.name].labels[action.name] = comp.label
    return out


def _generator(comp):
    """A pose generator's candidates, each computed when the search asks for it (a plain generator
    depends only on its arguments), its faults attributed."""

    def candidates(problem, step, world, rng):
        def checked():  # lazily: each item is checked as it is drawn, inside the blame
            return map(contracts.candidate, contracts.iterable(comp.factory(problem, step, world, rng), "Candidates"))

        yield from drawn_within(checked, lambda: blame(comp.plugin, comp.label))

    candidates.labels = {}
    return candidates


def _guarded_epoch_state(cls, plugin: str):
    # listed at once: the instance's state changes as it draws, so drawing order must not depend on the search
    def __call__(self, problem, step, world, rng):
        with blame(plugin, self.labels.get(step.action, f"pose generator '{cls.__name__}'")):
            items = contracts.iterable(cls.__call__(self, problem, step, world, rng), "Candidates")
            return [contracts.candidate(item) for item in items]

    return type(cls.__name__, (cls,), {"__call__": __call__, "labels": {}, "__qualname__": cls.__qualname__})


def translators_for(host: PluginHost, config: dict) -> list:
    out = []
    for name in config["planner"]["translators"]:
        comp = host["failure_translators"].get(name)
        out.append((name, blamed(_checked_translator(comp.factory), comp.plugin, comp.label)))
    return out


def _checked_translator(translate):
    def facts(failure, step, model):
        return contracts.facts(translate(failure, step, model), model)

    return facts


@dataclass
class Prepared:
    """Everything a run needs, built and checked before the loop starts (``interlayer check`` stops here)."""

    config: dict
    problem: object
    model: TaskModel
    task: object
    motion: object
    generators: dict
    translators: list
    stats: Stats
    cartesian: object = None  # planner.cartesian, for a geometry with a ``cartesian`` attribute
    scene_issues: list = ()  # ("error" | "warning", sentence): the domain's own check of its scene


def scene_issues(problem) -> list:
    """The domain's sentences about its scene at the initial poses (``geometry.scene_issues()``,
    optional): ("error", ...) for scenes no plan can start from, ("warning", ...) for doubtful ones."""
    check = getattr(problem.geometry, "scene_issues", None)
    return [(str(kind), relabel(str(sentence), problem.labels)) for kind, sentence in check()] if callable(check) else []


def prepare(source, overrides=None, host: PluginHost | None = None) -> Prepared:
    """Resolve the config, build the problem, abstract it and select every named component: each
    mistake a run would meet (unknown names, bad domain declarations, plugins that failed to load)
    is raised here as a UserError."""
    config = resolve_config(source, overrides)
    host = host or PluginHost()
    problem = build_problem(host, config)
    model = abstract(problem)
    stats = Stats()
    task, motion = make_planners(host, config, stats)
    cartesian = make_motion_planner(host, config, config["planner"]["cartesian"], stats)
    return Prepared(config, problem, model, task, motion, generators_for(host, model, config),
                    translators_for(host, config), stats, cartesian, scene_issues(problem))


def solve(source, overrides=None, host: PluginHost | None = None, listeners=(), pddl_dir=None,
          origin: float | None = None, on_stuck=None, export: bool = False) -> Result:
    """Solve a problem: ``source`` is a config path, a problem file, an output folder or a dict;
    ``overrides`` a list of ``"section.key=value"`` strings or a dict ``{"section.key": value}``.
    ``pddl_dir``: write every task-planner call's problem there as PDDL. ``listeners``: functions
    called with every trace event (one with a ``prepared(problem)`` method is first told the problem).
    ``origin``: where the
    result's wall time starts (``time.perf_counter()`` clock; default: now). ``on_stuck(result)``: called
    from another thread with the run so far (status "timeout") when a plugin call overruns the time
    limit and cannot be stopped (stuck in C code or a sleep); the CLI writes it and ends the process.
    Without it such a run ends when the call returns. ``export``: the result will be written
    (``write_outputs``): a geometry with ``prepare_export()`` is told before planning starts, so that
    its trajectory's export can overlap planning (e.g. the PR2's timing, in a worker process).

    Raises ``UserError`` for bad input, ``PluginFault`` for an exception in a plugin's code and
    ``Interrupted`` (a ``KeyboardInterrupt`` whose ``result`` holds the run so far) on Ctrl-C."""
    origin = time.perf_counter() if origin is None else origin
    host = host or PluginHost()
    run = prepare(source, overrides, host)
    config, problem, model, stats = run.config, run.problem, run.model, run.stats
    errors = [sentence for kind, sentence in run.scene_issues if kind == "error"]
    if errors:  # e.g. two objects in one another: no plan can start there
        more = f" ({len(errors) - 1} more: see 'interlayer check')" if len(errors) > 1 else ""
        raise UserError(errors[0][:-1] + more + ".")
    if export and hasattr(problem.geometry, "prepare_export"):  # as early as can be: it overlaps the rest
        problem.geometry.prepare_export()
    run.task.pddl_dir = pddl_dir
    p = config["planner"]
    settings = LoopSettings(time_limit=float(p["time_limit"]), max_traj_count=p["max_traj_count"],
                            max_refine_attempts=p["max_refine_attempts"], task_timeout=float(p["task_timeout"]),
                            seed=p["seed"], shortcut=p["shortcut"])
    if hasattr(run.task, "prepare"):  # imports and translation before the clock starts
        run.task.prepare(model)
    if hasattr(run.motion, "prepare"):
        run.motion.prepare()
    for listener in listeners:  # e.g. a live viewer, which draws the problem before the run starts
        if hasattr(listener, "prepared"):
            listener.prepared(problem)
    trace = Trace([host.on_event, *listeners])
    for warning in [*host.warnings, *(sentence for kind, sentence in run.scene_issues if kind != "error")]:
        trace.emit("warning", message=warning)
    trace.emit("start", problem=problem.name, references=len(model.references), config=config, names=model.labels)
    if hasattr(problem.geometry, "stats"):
        problem.geometry.stats = stats
    if hasattr(problem.geometry, "cartesian"):  # the domain plans straight-line end-effector segments
        problem.geometry.cartesian = run.cartesian

    def stuck(result):
        _clocked(result, origin)
        result.config = config
        on_stuck(result)

    layer = InterfaceLayer(model, run.task, run.motion, run.generators, run.translators, settings, trace, stats,
                           on_stuck=stuck if on_stuck else None)
    try:
        result = layer.solve()
    except Interrupted as stop:
        _clocked(stop.result, origin)
        stop.result.config = config
        raise
    _clocked(result, origin)
    result.config = config
    return result


def _clocked(result: Result, origin: float) -> None:
    """The wait so far: start-up (imports, plugins, the scene and robot, the task planner's start) and planning."""
    planning = result.times.get("total", 0.0)
    result.origin = origin
    result.wall = {"startup": max(0.0, time.perf_counter() - planning - origin), "planning": planning}


def write_outputs(result: Result, out_dir) -> Path:
    """OUT_DIR: result.json, config.toml (with its seed), problem.json, trace.json, trajectory.json,
    written as one set (result.json last; a stale trajectory.json of an earlier run removed)."""
    out = Path(out_dir)
    start = time.perf_counter()
    problem = result.problem
    trajectory = None
    if result.solved and hasattr(problem.geometry, "trajectory_json"):  # e.g. timing by TOPP-RA
        trajectory = problem.geometry.trajectory_json(result.plan, result.refinement)
    exported = time.perf_counter()

    def result_json():  # last, with the wait it completes
        _account(result, start, exported)
        return _dumps(result.to_json())

    runfolder.write_set(out, {
        "config.toml": cfg.to_toml(result.config),
        "problem.json": _dumps({"name": problem.name, "source": problem.source, "objects": dict(problem.objects),
                                "init": sorted(" ".join(a) for a in problem.init), "goal": problem.goal}),
        "trace.json": _dumps(result.trace.to_json()),
        "trajectory.json": None if trajectory is None else _dumps(trajectory),
        "result.json": result_json})
    return out


def _account(result: Result, start: float, exported: float) -> None:
    """``result.wall`` completed: export, writing, the rest (between the parts) and the total so far."""
    now = time.perf_counter()
    wall = {k: v for k, v in result.wall.items() if k in ("startup", "planning")}
    wall.update(export=exported - start, writing=now - exported)
    if result.origin is not None:
        wall["total"] = now - result.origin
        wall["other"] = max(0.0, wall["total"] - sum(v for k, v in wall.items() if k != "total"))
    result.wall = wall


def _dumps(data) -> str:
    return json.dumps(data, indent=1, default=_json_default)


def _json_default(o):
    import numpy as np

    if isinstance(o, np.ndarray):
        return o.tolist()
    if isinstance(o, (np.floating, np.integer)):
        return o.item()
    if hasattr(o, "to_json"):
        return o.to_json()
    raise TypeError(f"not JSON serialisable: {type(o).__name__}")


@dataclass
class Validation:
    violations: list  # one sentence each; empty: valid
    checked: list  # what was checked, e.g. "task plan replayed symbolically"


def validate(out_dir, host: PluginHost | None = None) -> list[str]:
    """Independent check of a solved run: the task plan is replayed symbolically from the
    abstract initial state, and the domain re-checks the written trajectory. Returns violations."""
    return validation(out_dir, host).violations


def validation(out_dir, host: PluginHost | None = None) -> Validation:
    """``validate`` with a list of what could be checked (a domain may have no trajectory validator)."""
    from .domain import GroundStep
    from .planning import check_plan

    out = Path(out_dir)
    result = read_run(out)
    if result.get("status") != "solved":
        return Validation([f"the run did not solve the problem (status {result.get('status')}): nothing to validate"], [])
    config = resolve_config(out)
    host = host or PluginHost()
    problem = build_problem(host, config)
    model = abstract(problem)
    plan = [GroundStep(s["action"], tuple(s["args"])) for s in result["plan"]]
    violations, checked = [], ["task plan replayed symbolically"]
    why = check_plan(model, model.init, plan)
    if why:
        violations.append(f"task plan: {why}")
    library_check = getattr(make_task_planner(host, config), "library_check", None)  # duck-typed planners may lack it
    why = library_check(model, model.init, plan) if library_check else None
    if why is not None:
        checked.append(f"task plan re-checked by the task planner's library ({config['planner']['task']})")
        if why:
            violations.append(f"task plan: {why}")
    if not (out / "trajectory.json").exists():
        return Validation(violations + ["no trajectory.json: the geometric refinement cannot be checked"], checked)
    trajectory = runfolder.read_trajectory(out)
    mismatch = _steps_mismatch(plan, trajectory["steps"])
    if mismatch:
        return Validation(violations + [mismatch], checked)
    checked.append("trajectory steps match the plan")
    if hasattr(problem.geometry, "validate"):
        try:
            violations += [relabel(v, problem.labels) for v in problem.geometry.validate(plan, trajectory)]  # in the file's names
        except PluginFault as fault:  # the validator choked on the file's content: the file is damaged
            if not isinstance(fault.cause, (KeyError, IndexError, TypeError, ValueError, AttributeError)):
                raise
            raise runfolder.damaged(out / "trajectory.json", f"the domain's validator cannot read it ({fault.sentence()})") from None
        checked.append("trajectory re-checked by the domain")
    else:
        checked.append(f"trajectory NOT re-checked: the domain '{problem.domain.name}' has no trajectory validator")
    return Validation(violations, checked)


def read_run(out_dir) -> dict:
    """The result.json of a folder written by 'interlayer plan --out' (checked to be one)."""
    out = Path(out_dir)
    if not out.is_dir():
        raise UserError(f"No such folder: {out}; give a folder written by 'interlayer plan --out'.")
    for name in ("result.json", "config.toml"):
        if not (out / name).exists():
            raise UserError(f"{out} has no {name}; give a folder written by 'interlayer plan --out'.")
    return runfolder.read_result(out)


def read_trajectory(out_dir) -> dict:
    """The trajectory.json of a solved run's folder; a UserError for any other folder."""
    out = Path(out_dir)
    result = read_run(out)
    if result.get("status") != "solved":
        raise UserError(f"The run in {out} did not solve its problem (status {result.get('status')}), so it has no "
                        f"trajectory; give the folder of a solved run.")
    return runfolder.read_trajectory(out)


def _steps_mismatch(plan, steps) -> str:
    """The trajectory must hold one entry per plan step, for the same action: '' if it does."""
    if len(steps) != len(plan):
        return f"the trajectory has {len(steps)} steps but the plan has {len(plan)}"
    for i, (step, data) in enumerate(zip(plan, steps)):
        if data.get("action") != step.action or list(data.get("args", [])) != list(step.args):
            return f"step {i} {step}: the trajectory's step is {data.get('action')}({', '.join(data.get('args', []))})"
    return ""
