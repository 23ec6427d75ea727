"""The examples and benchmark suites that ship with Interlayer.

In a built wheel they are package data (``interlayer/examples``, ``interlayer/benchmarks``: the
force-include of pyproject.toml); in a source checkout they are the repository's ``examples/`` and
``benchmarks/``, the only copy in git.
"""
from __future__ import annotations

from importlib import resources
from pathlib import Path

KINDS = ("examples", "benchmarks")


def folder(kind: str) -> Path | None:
    """The folder of shipped ``kind`` files ("examples" or "benchmarks"), or None if there is none."""
    packaged = Path(str(resources.files("interlayer") / kind))
    if packaged.is_dir():
        return packaged
    checkout = Path(__file__).resolve().parents[2] / kind  # core/interlayer/ -> the repository
    return checkout if checkout.is_dir() else None


def names(kind: str) -> list[str]:
    """The names of the shipped ``kind`` files (their .toml stems), sorted."""
    where = folder(kind)
    return sorted(p.stem for p in where.glob("*.toml")) if where else []


def find(kind: str, name: str) -> Path | None:
    """The shipped file that ``name`` means: ``gripper2d``, ``gripper2d.toml`` or, as the README
    writes it, ``examples/gripper2d.toml``; None if ``name`` is not one of them."""
    path = Path(name)
    if path.suffix not in ("", ".toml") or str(path.parent) not in (".", kind):
        return None
    where = folder(kind)
    candidate = where / f"{path.stem}.toml" if where else None
    return candidate if candidate is not None and candidate.is_file() else None
