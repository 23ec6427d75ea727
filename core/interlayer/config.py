"""Configuration: TOML files, ``--set key=value`` overrides, strict checking with suggestions."""
from __future__ import annotations

import copy
import json
import math
import tomllib
from pathlib import Path

from .errors import UserError, closest

PLANNER_DEFAULTS = {
    "task": "fast-downward",
    "motion": "ompl:RRTConnect",
    "cartesian": "interpolate",  # straight end-effector segments (approach, retreat): or "ik:cartesian"
    "seed": 0,
    "time_limit": 120.0,
    "task_timeout": 60.0,
    "max_traj_count": 10,
    "max_refine_attempts": 8,  # failed attempts per plan step in one TryRefine call (x epoch + 1)
    "translators": ["templates"],
    "shortcut": True,
}
SECTIONS = ("problem", "planner", "task_planner", "motion_planner", "pose_generators", "visualizer")


def default_config() -> dict:
    return {"problem": {}, "planner": copy.deepcopy(PLANNER_DEFAULTS), "task_planner": {}, "motion_planner": {},
            "pose_generators": {}}


def load_toml(path: Path) -> dict:
    try:
        with open(path, "rb") as fh:
            return tomllib.load(fh)
    except tomllib.TOMLDecodeError as exc:
        raise UserError(f"The config file {path} is not valid TOML ({exc}); fix the syntax at that spot.") from None
    except UnicodeDecodeError as exc:
        raise UserError(f"The config file {path} is not UTF-8 text (byte {exc.start}); save it as UTF-8.") from None
    except OSError as exc:
        raise UserError(f"Cannot read the config file {path}: {exc.strerror}.") from None
    except RecursionError:
        raise UserError(f"The config file {path} is nested too deeply to read; flatten its values.") from None


def parse_value(text: str):
    """A --set value: TOML/JSON literal when it parses (numbers, booleans, lists), else a string."""
    try:
        return tomllib.loads(f"v = {text}")["v"]
    except (tomllib.TOMLDecodeError, RecursionError):
        return text


def apply_override(config: dict, assignment: str) -> None:
    if "=" not in assignment:
        raise UserError(f"The override '{assignment}' has no '='; write it as --set section.key=value.")
    key, value = assignment.split("=", 1)
    set_value(config, key, parse_value(value.strip()))


def set_value(config: dict, key: str, value) -> None:
    """Set ``section.key`` (dotted) to ``value``, creating sub-tables as needed."""
    parts = str(key).strip().split(".")
    if len(parts) < 2:
        raise UserError(f"The override key '{key}' needs a section, e.g. planner.task or problem.obstructions.")
    node = config
    for p in parts[:-1]:
        node = node.setdefault(p, {})
        if not isinstance(node, dict):
            raise UserError(f"The override key '{key}' goes through '{p}', which is not a section.")
    node[parts[-1]] = value


def merge(base: dict, extra: dict) -> dict:
    out = copy.deepcopy(base)
    for k, v in extra.items():
        if isinstance(v, dict) and isinstance(out.get(k), dict):
            out[k] = merge(out[k], v)
        else:
            out[k] = copy.deepcopy(v)
    return out


def check(config: dict, domain_params: dict | None) -> None:
    """Unknown sections and keys are errors that name the key and the nearest valid one."""
    for section in config:
        if section not in SECTIONS:
            raise UserError(f"Unknown config section '[{section}]'{closest(section, SECTIONS)}; valid: {', '.join(SECTIONS)}.")
        if not isinstance(config[section], dict):
            raise UserError(f"'{section}' must be a table ([{section}] with keys), got {config[section]!r}.")
    for section in ("task_planner", "pose_generators"):
        for key, value in config.get(section, {}).items():
            wanted = dict if section == "task_planner" else str
            if not isinstance(value, wanted):
                what = f"a table ([{section}.{key}])" if wanted is dict else "a pose generator's name"
                raise UserError(f"{section}.{key} must be {what}, got {value!r}.")
    for key in config.get("planner", {}):
        if key not in PLANNER_DEFAULTS:
            raise UserError(f"Unknown key 'planner.{key}'{closest(key, PLANNER_DEFAULTS)}; valid: {', '.join(PLANNER_DEFAULTS)}.")
    if domain_params is not None:
        allowed = {"domain", "file", *domain_params}
        for key in config.get("problem", {}):
            if key not in allowed:
                raise UserError(f"Unknown key 'problem.{key}'{closest(key, allowed)}; this domain accepts: {', '.join(sorted(allowed))}.")
    for key in ("domain", "file"):
        value = config.get("problem", {}).get(key)
        if value is not None and (not isinstance(value, str) or not value or "\0" in value):
            raise UserError(f"problem.{key} must be a non-empty string, got {value!r}.")
    p = config["planner"]
    for key in ("task", "motion", "cartesian"):
        if not isinstance(p[key], str):
            raise UserError(f"planner.{key} must be a planner's name (a string), got {p[key]!r}; see 'interlayer plugins'.")
    if not isinstance(p["translators"], list) or not all(isinstance(t, str) for t in p["translators"]):
        raise UserError(f"planner.translators must be a list of translator names, got {p['translators']!r}.")
    for key in ("seed", "max_traj_count", "max_refine_attempts"):
        if not isinstance(p[key], int) or isinstance(p[key], bool) or p[key] < 0:
            raise UserError(f"planner.{key} must be a non-negative integer, got {p[key]!r}.")
    if not isinstance(p["shortcut"], bool):
        raise UserError(f"planner.shortcut must be true or false, got {p['shortcut']!r}.")
    limits = {f"planner.{key}": p[key] for key in ("time_limit", "task_timeout")}
    motion = config.get("motion_planner", {})
    for name, table in [("motion_planner", motion), *((f"motion_planner.{k}", v) for k, v in motion.items() if isinstance(v, dict))]:
        if "time_limit" in table:
            limits[f"{name}.time_limit"] = table["time_limit"]
    for key, value in limits.items():
        if not isinstance(value, (int, float)) or isinstance(value, bool) or not 0 < value < math.inf:
            raise UserError(f"{key} must be a positive, finite number of seconds, got {value!r}.")


def to_toml(config: dict) -> str:
    """Write a resolved config back as TOML (the subset we use: tables of scalars and lists)."""
    lines = []

    def emit(prefix, table):
        scalars = {k: v for k, v in table.items() if not isinstance(v, dict)}
        if scalars or not table:
            lines.append(f"[{prefix}]")
            lines.extend(f"{_key(k)} = {json.dumps(v)}" for k, v in scalars.items())
            lines.append("")
        for k, v in table.items():
            if isinstance(v, dict):
                emit(f"{prefix}.{_key(k)}", v)

    for section, table in config.items():
        emit(section, table)
    return "\n".join(lines)


def _key(k: str) -> str:
    return k if k.replace("_", "").replace("-", "").isalnum() else json.dumps(k)
