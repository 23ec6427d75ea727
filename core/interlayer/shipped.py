"""The examples and benchmark suites that ship with Interlayer's distributions.

Each distribution's wheel carries the examples and suites of its domains as package data
(``interlayer_gripper2d/examples/gripper2d.toml``, ``interlayer_manip/benchmarks/table1.toml``: the
force-include of its pyproject.toml), found in the file lists of the installed plugin distributions; in a source
checkout they are the repository's ``examples/`` and ``benchmarks/``, the only copy in git.
"""
from __future__ import annotations

import importlib.metadata
from pathlib import Path

KINDS = ("examples", "benchmarks")


def folders(kind: str) -> list[Path]:
    """The folders of shipped ``kind`` files ("examples" or "benchmarks"): each installed plugin
    distribution's ``<package>/kind/`` package data (from its file list, so a distribution's domains may
    keep their files in any of its packages), then the source checkout's folder, if any."""
    from .plugins import ENTRY_POINT_GROUP

    out, seen = [], set()
    for ep in importlib.metadata.entry_points(group=ENTRY_POINT_GROUP):
        if ep.dist is None or ep.dist.name in seen:
            continue
        seen.add(ep.dist.name)
        for file in ep.dist.files or ():
            if len(file.parts) == 3 and file.parts[1] == kind and file.suffix == ".toml":
                where = Path(str(ep.dist.locate_file(file))).parent
                if where.is_dir() and where not in out:
                    out.append(where)
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
