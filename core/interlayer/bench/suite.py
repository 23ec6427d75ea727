"""Benchmark suites: rows (a config + overrides + seeds) crossed with planner combinations.

A suite file (TOML)::

    name = "mine"
    seeds = "0-9"                 # every row's default; a row may set its own
    time_limit = 120              # seconds per run (planner.time_limit); a row may set its own
    combo = ["planner.task=ff,fast-downward"]   # optional: each key's values are crossed
    [quick]                       # what --quick uses
    seeds = "0-1"
    time_limit = 30

    [[rows]]
    name = "Gripper-2D k=5"
    config = "../examples/gripper2d.toml"      # relative to the suite file
    set = ["problem.obstructions=5"]
    paper = { solved = 100, mean_time = 32 }   # optional published numbers (percent, seconds)

Configs and overrides are all the core knows about a row: the domain comes from the config.

A suite may instead run every file of a folder the user gives (``--problems DIR``): ``problems =
"*.json"`` (a glob) in place of ``[[rows]]`` makes one row per matching file, named by the file's stem,
in name order (``benchmarks/pbjson-folder.toml``: a checkout of pybullet-planning's problems/json).
"""
from __future__ import annotations

import itertools
from dataclasses import dataclass, field
from pathlib import Path

from .. import shipped
from ..errors import UserError

QUICK = {"seeds": "0-1", "time_limit": 60.0}


@dataclass
class Row:
    name: str
    config: str  # absolute path
    overrides: list
    seeds: list
    time_limit: float
    paper: dict = field(default_factory=dict)
    skipped: str = ""  # why the row cannot run on this machine, or ''


@dataclass
class Suite:
    name: str
    path: str
    rows: list
    combos: list  # [(label, [overrides])]
    time_limit: float  # the suite's; a row's own is Row.time_limit


def parse_seeds(text) -> list[int]:
    """'0-9', '0,3,5-7', 7 or [1, 2] -> a sorted list of seeds."""
    if isinstance(text, int):
        return [text]
    if isinstance(text, list):
        return sorted({int(s) for s in text})
    out = set()
    try:
        for part in str(text).split(","):
            a, _, b = part.strip().partition("-")
            out.update(range(int(a), int(b) + 1) if b else [int(a)])
    except ValueError:
        raise UserError(f"Cannot read the seeds '{text}'; write them like 0-9 or 0,3,5-7.") from None
    if not out:
        raise UserError(f"The seeds '{text}' name no seed; write them like 0-9 or 0,3,5-7.")
    return sorted(out)


def parse_combos(specs) -> list[tuple[str, list]]:
    """['planner.task=ff,fast-downward', 'planner.motion=ompl:PRM,ompl:RRTConnect'] -> their cross product."""
    axes = []
    for spec in specs:
        key, eq, values = spec.partition("=")
        if not eq or not key.strip() or not values.strip():
            raise UserError(f"The combination '{spec}' is not KEY=VALUE[,VALUE...]; write e.g. --combo planner.task=ff,fast-downward.")
        axes.append([f"{key.strip()}={v.strip()}" for v in values.split(",") if v.strip()])
    return [(" ".join(c) or "default", list(c)) for c in itertools.product(*axes)]


def find_suite(name: str) -> Path:
    path = Path(name)
    if path.suffix == ".toml" or path.exists():
        if not path.exists():
            raise UserError(f"The suite file {path} does not exist.")
        return path
    local = Path.cwd() / "benchmarks" / f"{name}.toml"  # a suite of the current folder wins over a shipped one
    if local.exists():
        return local
    found = shipped.find("benchmarks", name)
    if found:
        return found
    local_names = {p.stem for p in (Path.cwd() / "benchmarks").glob("*.toml")}
    known = sorted(local_names | set(shipped.names("benchmarks")))
    raise UserError(f"Unknown suite '{name}'; give a suite file (.toml) or one of: {', '.join(known) or 'none found'}.")


def folder_rows(path: Path, pattern, problems) -> list[dict]:
    """A folder suite's rows: one per file of ``problems`` matching ``pattern``, named by its stem."""
    if not isinstance(pattern, str) or not pattern.strip():
        raise UserError(f"The suite {path}: problems must be a file pattern such as \"*.json\".")
    if problems is None:
        raise UserError(f"The suite '{path.stem}' runs every {pattern} file of a folder: give the folder with --problems DIR.")
    folder = Path(problems).expanduser()
    if not folder.is_dir():
        raise UserError(f"The problems folder {folder} does not exist; give --problems an existing folder of {pattern} files.")
    files = sorted(f for f in folder.glob(pattern) if f.is_file())
    if not files:
        raise UserError(f"The problems folder {folder} holds no {pattern} file; give --problems the folder that has them.")
    return [{"name": f.stem, "config": str(f.resolve())} for f in files]


def load_suite(name: str, quick: bool = False, seeds=None, time_limit=None, combos=(), overrides=(),
               problems=None) -> Suite:
    """The suite, with --quick / --seeds / --time-limit / --combo / --set / --problems applied (the CLI's
    options win)."""
    from ..config import load_toml

    path = find_suite(name)
    data = load_toml(path)
    if "problems" in data:
        data["rows"] = folder_rows(path, data["problems"], problems)
    elif problems is not None:
        raise UserError(f"The suite '{path.stem}' has its own rows; --problems DIR is for a suite that runs a folder "
                        f"(one whose file sets problems = \"*.json\", e.g. pbjson-folder).")
    if not isinstance(data.get("rows"), list) or not data["rows"]:
        raise UserError(f"The suite {path} has no [[rows]]; add at least one row with a name and a config.")
    quick_cfg = {**QUICK, **data.get("quick", {})} if quick else {}
    limit = _seconds(path, "the suite", data.get("time_limit", 120))
    forced = time_limit or quick_cfg.get("time_limit")  # --time-limit and --quick win over every row's own
    rows = []
    for i, r in enumerate(data["rows"]):
        if "name" not in r or "config" not in r:
            raise UserError(f"Row {i + 1} of the suite {path} needs a name and a config.")
        row_seeds = seeds if seeds is not None else quick_cfg.get("seeds") or r.get("seeds", data.get("seeds", "0-9"))
        sets = r.get("set", [])
        if isinstance(sets, str) or not all(isinstance(s, str) for s in sets):
            raise UserError(f"The row '{r['name']}' of {path}: set must be a list of \"key=value\" strings.")
        row_limit = forced or _seconds(path, f"the row '{r['name']}'", r.get("time_limit", limit))
        rows.append(Row(r["name"], str((path.parent / r["config"]).resolve()), list(sets),
                        parse_seeds(row_seeds), float(row_limit), dict(r.get("paper", {}))))
    names = [r.name for r in rows]
    if len(set(names)) != len(names):
        raise UserError(f"The suite {path} has two rows with the same name; give every row its own name.")
    combo_specs = list(combos) or list(data.get("combo", []))
    crossed = parse_combos(combo_specs)
    if overrides:  # part of the combination's name, so that runs with other --set values are not taken as done
        crossed = [(" ".join([*([label] if sets else []), *overrides]), [*sets, *overrides]) for label, sets in crossed]
    return Suite(str(data.get("name", path.stem)), str(path), rows, crossed, float(forced or limit))


def _seconds(path, what, value) -> float:
    if isinstance(value, bool) or not isinstance(value, (int, float)) or value <= 0:
        raise UserError(f"The suite {path}: {what}'s time_limit must be a positive number of seconds, got {value!r}.")
    return float(value)


def mark_skipped(suite: Suite) -> None:
    """A row whose config is missing or whose domain is not installed is skipped, with the reason."""
    from .. import api, config as cfg
    from ..plugins import PluginHost

    host = PluginHost()

    def check(overrides):
        config = api.resolve_config(row.config, overrides)
        domain = config["problem"].get("domain")
        if domain and not config["problem"].get("file"):
            cfg.check(config, host["domains"].get(domain).params)
        elif config["problem"].get("file") and not Path(config["problem"]["file"]).exists():
            raise UserError(f"the problem file {config['problem']['file']} does not exist")

    for row in suite.rows:
        try:
            check(row.overrides)
        except UserError as exc:
            row.skipped = str(exc).rstrip(".").replace(f"{Path.cwd()}/", "")
            continue
        for label, sets in suite.combos:  # a bad --combo or --set is the user's error, not the row's
            try:
                check([*row.overrides, *sets])
            except UserError as exc:
                raise UserError(f"The combination '{label}' does not fit the row '{row.name}': {exc}") from None
