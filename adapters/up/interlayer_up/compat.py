"""What the adapter uses of Unified-Planning beyond its shortcuts, checked once when UP is first loaded.

Engines are UP's to subclass: ``PDDLPlanner``'s methods below are the ones a PDDL engine implements or
overrides, and the adapter's engines override ``_solve`` (the engine's process runs in a folder of
ours, by us) and ``_plan_from_str`` (one plan reader). ``Problem``'s properties are overridden for
speed on problems we no longer change (their class is swapped: instances must have a ``__dict__``).
If UP renames or reshapes any of them, the adapter would silently run UP's own code instead, or fail
deep inside a call: ``check`` says so in one sentence instead, naming the supported versions. An
engine whose own ``_solve`` stops reaching PDDLPlanner's through ``super()`` is named after its call
(``bypassed``)."""
from __future__ import annotations

import functools

from interlayer.errors import UserError

# the releases this adapter was checked against (the engines: those whose own code it runs through)
SUPPORTED = {"unified-planning": ">=1.3,<1.4", "up-fast-downward": ">=1.0,<1.1", "up-symk": ">=1.6,<1.7"}

# (module, class.name, the leading parameters it must take, or None for a property), each defined by that
# class itself: a base's may be an abstract stand-in (AbstractProblem.kind raises NotImplementedError)
NEEDED = (
    ("unified_planning.engines.pddl_planner", "PDDLPlanner._solve", ("self", "problem", "heuristic", "timeout", "output_stream")),
    ("unified_planning.engines.pddl_planner", "PDDLPlanner._get_cmd", ("self", "domain_filename", "problem_filename", "plan_filename")),
    ("unified_planning.engines.pddl_planner", "PDDLPlanner._plan_from_file", ("self", "problem", "plan_filename", "get_item_named")),
    ("unified_planning.engines.pddl_planner", "PDDLPlanner._plan_from_str", ("self", "problem", "plan_str", "get_item_named")),
    ("unified_planning.engines.pddl_planner", "PDDLPlanner._result_status", ("self", "problem", "plan", "retval", "log_messages")),
    ("unified_planning.model", "Problem.kind", None),
    ("unified_planning.model.mixins", "InitialStateMixin.initial_values", None),  # Problem's
    ("unified_planning.model.mixins", "InitialStateMixin.explicit_initial_values", None),
)
# set by PDDLPlanner.__init__ and read by our _solve, as UP's own _solve reads them
ENGINE_ATTRIBUTES = ("_needs_requirements", "_rewrite_bool_assignments")


class UnsupportedUnifiedPlanning(UserError):
    """Unified-Planning changed something the adapter relies on: the installed versions are the user's
    to fix (the message is one sentence)."""


def message(name: str, dist: str = "unified-planning") -> str:
    from importlib.metadata import PackageNotFoundError, version

    try:
        release = ".".join(version(dist).split(".")[:2])
    except PackageNotFoundError:
        release = "(unknown version)"
    if dist == "unified-planning":
        supported = f"supports {SUPPORTED[dist]}"
    elif dist in SUPPORTED:
        supported = f"supports {dist} {SUPPORTED[dist]}"
    else:
        supported = f"was checked with {', '.join(f'{d} {r}' for d, r in SUPPORTED.items())}"
    return f"{dist} {release} changed `{name}`: Interlayer's UP adapter {supported}; pin it or update the adapter."


@functools.cache
def check() -> None:
    """Raise UnsupportedUnifiedPlanning naming the first thing in NEEDED that is missing or reshaped."""
    import importlib

    for module, dotted, params in NEEDED:
        owner_name, attr = dotted.split(".")
        owner = getattr(importlib.import_module(module), owner_name, None)
        found = vars(owner).get(attr) if isinstance(owner, type) else None
        if params is None:
            ok = isinstance(found, property)
        else:
            code = getattr(found, "__code__", None)
            ok = code is not None and code.co_varnames[:len(params)] == params
        if not ok:
            raise UnsupportedUnifiedPlanning(message(dotted))
    from unified_planning.model import Problem

    if not Problem.__dictoffset__:  # __slots__ all the way: a problem's class can no longer be swapped
        raise UnsupportedUnifiedPlanning(message("Problem.__dict__"))


def check_engine(engine) -> None:
    for attr in ENGINE_ATTRIBUTES:
        if not hasattr(engine, attr):
            raise UnsupportedUnifiedPlanning(message(f"PDDLPlanner.{attr}"))


def bypassed(engine) -> UnsupportedUnifiedPlanning:
    """The error for a PDDL engine whose ``solve`` did not reach the adapter's ``_solve``."""
    cls = next(c for c in type(engine).__mro__[1:] if "_solve" in vars(c))  # the engine's own, that skipped ours
    return UnsupportedUnifiedPlanning(message(f"{cls.__name__}._solve", cls.__module__.split(".")[0].replace("_", "-")))
