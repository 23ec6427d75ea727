"""The Python API; the CLI is a thin layer over these functions."""
from __future__ import annotations

import json
import os
from pathlib import Path

from . import config as cfg
from .abstraction import TaskModel, abstract
from .errors import UserError
from .loop import InterfaceLayer, LoopSettings
from .plugins import PluginHost
from .result import Result
from .trace import Stats, Trace


def resolve_config(source, overrides=None) -> dict:
    """A resolved config from a TOML path, a problem file, an output folder or a dict."""
    if isinstance(source, dict):
        raw = source
    else:
        path = Path(source)
        if path.is_dir():
            if not (path / "config.toml").exists():
                raise UserError(f"The folder {path} has no config.toml; give a config file or a folder written by 'interlayer plan --out'.")
            raw = cfg.load_toml(path / "config.toml")
        elif not path.exists():
            raise UserError(f"No such file or folder: {path}.")
        elif path.suffix == ".toml":
            raw = cfg.load_toml(path)
            file = raw.get("problem", {}).get("file")
            if file and not Path(file).is_absolute():  # relative to the config file
                raw["problem"]["file"] = str((path.parent / file).resolve())
        else:
            raw = {"problem": {"file": str(path.resolve())}}
    config = cfg.merge(cfg.default_config(), raw)
    for assignment in overrides or ():
        cfg.apply_override(config, assignment)
    cfg.check(config, None)
    return config


def build_problem(host: PluginHost, config: dict):
    params = {k: v for k, v in config["problem"].items() if k not in ("domain", "file")}
    seed = config["planner"]["seed"]
    if config["problem"].get("file"):
        path = Path(config["problem"]["file"])
        if not path.exists():
            raise UserError(f"The problem file {path} does not exist.")
        problem = host.load_problem(path, params, seed)
        if problem is None:
            raise UserError(f"No installed plugin can read the problem file {path}; see 'interlayer plugins' for loaders.")
        return problem
    name = config["problem"].get("domain")
    if not name:
        raise UserError("The config names no problem: set [problem] domain = \"...\" or file = \"...\".")
    comp = host["domains"].get(name)
    cfg.check(config, comp.params)
    return comp.factory({**comp.params, **params}, seed)


def make_planners(host: PluginHost, config: dict, stats: Stats):
    p = config["planner"]
    task_comp = host["task_planners"].get(p["task"])
    task = task_comp.factory(dict(config["task_planner"].get(p["task"], {})))
    motion_comp = host["motion_planners"].get(p["motion"])
    family = p["motion"].split(":")[0]
    options = {k: v for k, v in config["motion_planner"].items() if not isinstance(v, dict)}
    options.update(config["motion_planner"].get(family, {}))
    motion = motion_comp.factory(options)
    motion.stats = stats
    return task, motion


def generators_for(host: PluginHost, model: TaskModel, config: dict) -> dict:
    out = {}
    for action in model.problem.domain.actions:
        name = config["pose_generators"].get(action.name, action.pose_generator)
        if name is None:
            raise UserError(f"The action '{action.name}' has no pose generator; set [pose_generators] {action.name} = \"...\".")
        out[action.name] = host["pose_generators"].get(name).factory
    return out


def solve(source, overrides=None, host: PluginHost | None = None, listeners=(), pddl_dir=None) -> Result:
    """Solve a problem: ``source`` is a config path, a problem file, an output folder or a dict.
    ``pddl_dir``: write every task-planner call's problem there as PDDL."""
    config = resolve_config(source, overrides)
    host = host or PluginHost()
    problem = build_problem(host, config)
    model = abstract(problem)
    stats = Stats()
    task, motion = make_planners(host, config, stats)
    task.pddl_dir = pddl_dir
    translators = [(n, host["failure_translators"].get(n).factory) for n in config["planner"]["translators"]]
    p = config["planner"]
    settings = LoopSettings(time_limit=float(p["time_limit"]), max_traj_count=p["max_traj_count"],
                            max_refine_attempts=p["max_refine_attempts"], task_timeout=float(p["task_timeout"]),
                            seed=p["seed"], shortcut=p["shortcut"])
    trace = Trace([host.on_event, *listeners])
    trace.emit("start", problem=problem.name, references=len(model.references), config=config)
    if hasattr(problem.geometry, "stats"):
        problem.geometry.stats = stats
    layer = InterfaceLayer(model, task, motion, generators_for(host, model, config), translators, settings, trace, stats)
    result = layer.solve()
    result.config = config
    return result


def write_outputs(result: Result, out_dir) -> Path:
    """OUT_DIR: result.json, config.toml (with its seed), problem.json, trace.json, trajectory.json."""
    out = Path(out_dir)
    try:
        out.mkdir(parents=True, exist_ok=True)
    except OSError as exc:
        raise UserError(f"Cannot create the output folder {out}: {exc.strerror}.") from None
    _write(out / "result.json", result.to_json())
    (out / "config.toml").write_text(cfg.to_toml(result.config))
    problem = result.problem
    _write(out / "problem.json", {"name": problem.name, "source": problem.source, "objects": dict(problem.objects),
                                  "init": sorted(" ".join(a) for a in problem.init), "goal": problem.goal})
    _write(out / "trace.json", result.trace.to_json())
    if result.solved and hasattr(problem.geometry, "trajectory_json"):
        _write(out / "trajectory.json", problem.geometry.trajectory_json(result.plan, result.refinement))
    return out


def _write(path: Path, data) -> None:
    tmp = path.with_suffix(path.suffix + ".tmp")
    tmp.write_text(json.dumps(data, indent=1, default=_json_default))
    os.replace(tmp, path)


def _json_default(o):
    import numpy as np

    if isinstance(o, np.ndarray):
        return o.tolist()
    if isinstance(o, (np.floating, np.integer)):
        return o.item()
    if hasattr(o, "to_json"):
        return o.to_json()
    raise TypeError(f"not JSON serialisable: {type(o).__name__}")


def validate(out_dir, host: PluginHost | None = None) -> list[str]:
    """Independent check of a solved run: the task plan is replayed symbolically from the
    abstract initial state, and the domain re-checks the written trajectory. Returns violations."""
    from .domain import GroundStep
    from .planning import check_plan

    out = Path(out_dir)
    for name in ("result.json", "config.toml"):
        if not (out / name).exists():
            raise UserError(f"{out} has no {name}; give a folder written by 'interlayer plan --out'.")
    result = json.loads((out / "result.json").read_text())
    if result.get("status") != "solved":
        return [f"the run did not solve the problem (status {result.get('status')}): nothing to validate"]
    config = resolve_config(out)
    host = host or PluginHost()
    problem = build_problem(host, config)
    model = abstract(problem)
    plan = [GroundStep(s["action"], tuple(s["args"])) for s in result["plan"]]
    violations = []
    why = check_plan(model, model.init, plan)
    if why:
        violations.append(f"task plan: {why}")
    if not (out / "trajectory.json").exists():
        return violations + ["no trajectory.json: the geometric refinement cannot be checked"]
    trajectory = json.loads((out / "trajectory.json").read_text())
    mismatch = _steps_mismatch(plan, trajectory.get("steps", []))
    if mismatch:
        return violations + [mismatch]
    if hasattr(problem.geometry, "validate"):
        violations += problem.geometry.validate(plan, trajectory)
    return violations


def _steps_mismatch(plan, steps) -> str:
    """The trajectory must hold one entry per plan step, for the same action: '' if it does."""
    if len(steps) != len(plan):
        return f"the trajectory has {len(steps)} steps but the plan has {len(plan)}"
    for i, (step, data) in enumerate(zip(plan, steps)):
        if data.get("action") != step.action or list(data.get("args", [])) != list(step.args):
            return f"step {i} {step}: the trajectory's step is {data.get('action')}({', '.join(data.get('args', []))})"
    return ""
