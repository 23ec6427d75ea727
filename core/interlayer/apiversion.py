"""The plugin-API version: a plugin distribution declares the cores it is made for (``interlayer>=0.2,<0.3``
in its requirements), and plugin discovery skips a plugin whose distribution excludes the running core.

The core installs with numpy and pluggy only, so the requirement is read with a small parser of the
specifiers a plugin writes (``>=``, ``<``, ``==`` with ``.*``, ``!=``, ``<=``, ``>``, ``~=``) rather than
``packaging``; a requirement it cannot read is not held against the plugin.
"""
from __future__ import annotations

import re

from . import __version__

# The plugin API changes with the core's minor version (0.x): a plugin made for this API declares
# interlayer>=0.2,<0.3 (docs/plugins.md).
API_VERSION = ".".join(__version__.split(".")[:2])

_REQUIREMENT = re.compile(r"^\s*([A-Za-z0-9][A-Za-z0-9._-]*)\s*(\[[^\]]*\])?\s*(\(?)([^;()]*)\)?\s*(?:;(.*))?$")
_CLAUSE = re.compile(r"^(~=|==|!=|<=|>=|<|>)\s*([0-9]+(?:\.[0-9]+)*)(\.\*)?$")


def normal_name(name: str) -> str:
    """A distribution's name as pip compares it (``Interlayer_UP`` -> ``interlayer-up``)."""
    return re.sub(r"[-_.]+", "-", name).lower()


def _release(version: str) -> tuple[int, ...] | None:
    """The release numbers of a version (``0.2.0`` -> (0, 2, 0)); None if it does not start with them."""
    match = re.match(r"^\s*v?([0-9]+(?:\.[0-9]+)*)", version)
    return tuple(int(p) for p in match.group(1).split(".")) if match else None


def _pad(a: tuple, b: tuple) -> tuple[tuple, tuple]:
    n = max(len(a), len(b))
    return a + (0,) * (n - len(a)), b + (0,) * (n - len(b))


def _holds(version: tuple, op: str, bound: tuple, wildcard: bool) -> bool:
    if wildcard:  # ==0.2.* / !=0.2.*: the version's leading numbers
        same = version[:len(bound)] + (0,) * (len(bound) - len(version)) == bound
        return same if op == "==" else not same
    if op == "~=":  # ~=0.2.1: >=0.2.1 and ==0.2.*
        return _holds(version, ">=", bound, False) and _holds(version, "==", bound[:-1], True)
    v, b = _pad(version, bound)
    return {"==": v == b, "!=": v != b, "<=": v <= b, ">=": v >= b, "<": v < b, ">": v > b}[op]


def core_specifier(requirements) -> str | None:
    """The specifier (``>=0.2,<0.3``) of the requirement on ``interlayer`` among a distribution's
    requirement strings (``importlib.metadata.requires``), or None if it has none; requirements
    that hold only with an extra are not the distribution's own."""
    for text in requirements or ():
        match = _REQUIREMENT.match(text)
        if not match or normal_name(match.group(1)) != "interlayer":
            continue
        if match.group(5) and "extra" in match.group(5):
            continue
        return match.group(4).strip()
    return None


def admits(specifier: str, version: str = __version__) -> bool:
    """Whether ``version`` satisfies ``specifier`` (``>=0.2,<0.3``); True when either cannot be read."""
    release = _release(version)
    clauses = [c.strip() for c in specifier.split(",") if c.strip()]
    parsed = [_CLAUSE.match(c) for c in clauses]
    if release is None or not all(parsed):
        return True
    return all(_holds(release, m.group(1), tuple(int(p) for p in m.group(2).split(".")), bool(m.group(3)))
               for m in parsed)


def mismatch(dist: str, dist_version: str, requirements, version: str = __version__) -> str:
    """One sentence when the distribution ``dist`` requires another core than ``version``, else ''."""
    specifier = core_specifier(requirements)
    if not specifier or admits(specifier, version):
        return ""
    return (f"{dist} {dist_version} requires interlayer{specifier}, but interlayer {version} is installed; "
            f"upgrade it to a release made for this core (pip install -U {dist}) "
            f"or install such a core (pip install 'interlayer{specifier}')")
