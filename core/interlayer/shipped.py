"""The examples and benchmark suites that ship with Interlayer's distributions.

Each distribution's wheel carries the examples and suites of its domains as package data
(``interlayer_gripper2d/examples/gripper2d.toml``, ``interlayer_manip/benchmarks/table1.toml``: the
force-include of its pyproject.toml), found in the packages of the installed plugins; in a source
checkout they are the repository's ``examples/`` and ``benchmarks/``, the only copy in git.
"""
from __future__ import annotations

import importlib.metadata
import importlib.util
from pathlib import Path

KINDS = ("examples", "benchmarks")


def _plugin_packages() -> list[str]:
    """The top-level packages of the installed plugins (entry points), in discovery order, once each."""
    from .plugins import ENTRY_POINT_GROUP

    out = []
    for ep in importlib.metadata.entry_points(group=ENTRY_POINT_GROUP):
        top = ep.value.partition(":")[0].split(".")[0].strip()
        if top and top not in out:
            out.append(top)
    return out


def folders(kind: str) -> list[Path]:
    """The folders of shipped ``kind`` files ("examples" or "benchmarks"): each installed plugin
    package's ``kind/`` package data, then the source checkout's folder, if any."""
    out = []
    for top in _plugin_packages():
        try:  # the package's folder, without importing it (a broken plugin is reported by discovery)
            spec = importlib.util.find_spec(top)
        except (ImportError, ValueError):
            continue
        for where in (spec.submodule_search_locations or []) if spec else []:
            path = Path(where) / kind
            if path.is_dir() and path not in out:
                out.append(path)
    checkout = Path(__file__).resolve().parents[2] / kind  # core/interlayer/ -> the repository
    if checkout.is_dir() and checkout not in out:
        out.append(checkout)
    return out


def names(kind: str) -> list[str]:
    """The names of the shipped ``kind`` files (their .toml stems), sorted."""
    return sorted({p.stem for where in folders(kind) for p in where.glob("*.toml")})


def find(kind: str, name: str) -> Path | None:
    """The shipped file that ``name`` means: ``gripper2d``, ``gripper2d.toml`` or, as the README
    writes it, ``examples/gripper2d.toml``; None if ``name`` is not one of them."""
    path = Path(name)
    if path.suffix not in ("", ".toml") or str(path.parent) not in (".", kind):
        return None
    for where in folders(kind):
        candidate = where / f"{path.stem}.toml"
        if candidate.is_file():
            return candidate
    return None
