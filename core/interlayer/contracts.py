"""What each plugin hook must hand back, checked where the core receives it.

A value of the wrong type would otherwise fail later, in the next component (a domain's geometry
handed a Candidate of strings) or in the core itself ("internal error"), and be blamed there. Each
check raises ``ComponentFailed`` with one sentence; called inside the hook's ``blame``, that becomes
the hook's plugin's ``PluginFault``."""
from __future__ import annotations

import numbers
from collections.abc import Iterable, Mapping

import numpy as np

from .faults import ComponentFailed

TASK_STATUSES = ("solved", "unsolvable", "incomplete", "timeout", "error")


def shown(value) -> str:
    """A short description of a value of the wrong kind: its type and a clipped repr."""
    text = repr(value)
    return f"{type(value).__name__} {text if len(text) <= 60 else text[:57] + '...'}"


def problem(value):
    """A domain's factory or a problem loader's answer: a Problem."""
    from .domain import Problem

    if not isinstance(value, Problem):
        raise ComponentFailed(f"it returned {shown(value)}, not a Problem")
    return value


def candidate(item):
    """A pose generator's item: a Candidate whose waypoints are configurations (numbers, or
    sequences of them, nested: a waypoint may be a path), ``values`` a mapping, ``label`` a string."""
    from .refine import Candidate

    if not isinstance(item, Candidate):
        raise ComponentFailed(f"it yielded {shown(item)}, not a Candidate")
    if not isinstance(item.waypoints, (tuple, list)):
        raise ComponentFailed(f"it yielded a Candidate whose waypoints are {shown(item.waypoints)}, not a tuple")
    for i, waypoint in enumerate(item.waypoints):
        if not _numbers(waypoint):
            raise ComponentFailed(f"it yielded a Candidate whose waypoint {i} is {shown(waypoint)}, "
                                  f"not a configuration (numbers)")
    if not isinstance(item.values, Mapping):
        raise ComponentFailed(f"it yielded a Candidate whose values are {shown(item.values)}, not a mapping")
    if not isinstance(item.label, str):
        raise ComponentFailed(f"it yielded a Candidate whose label is {shown(item.label)}, not a string")
    return item


def _numbers(value) -> bool:
    if isinstance(value, numbers.Real) and not isinstance(value, bool):
        return True
    if isinstance(value, np.ndarray):
        return value.dtype.kind in "iuf" or (value.dtype.kind == "O" and all(map(_numbers, value.flat)))
    if isinstance(value, (tuple, list)):
        try:
            kind = np.asarray(value).dtype.kind  # one call for a regular array of numbers
        except ValueError:  # ragged: element by element
            kind = "O"
        return kind in "iuf" or all(map(_numbers, value))
    return False


def iterable(value, what: str):
    """A generator's or translator's answer must be iterable (a string is not a collection)."""
    if isinstance(value, (str, bytes)) or not isinstance(value, Iterable):
        raise ComponentFailed(f"it returned {shown(value)}, not {what}")
    return value


def facts(value, model) -> set:
    """A failure translator's answer: atoms ``("Pred", "obj", ...)`` of the domain's predicates, or such
    atoms ``logic.negated`` (facts learned false)."""
    from .logic import Not, Pred

    out = set()
    for literal in iterable(value, "a set of atoms"):
        negative = isinstance(literal, Not) and isinstance(literal.arg, Pred)
        atom = (literal.arg.name, *literal.arg.args) if negative else literal
        if not (isinstance(atom, tuple) and atom and all(isinstance(a, str) for a in atom)):
            raise ComponentFailed(f"it returned {shown(atom)} among its facts, not an atom (a tuple of names, "
                                  f"e.g. ('Obstructs', 'b2', 'gp_b1', 'b1'))")
        arity = model.predicates.get(atom[0])
        if arity is None:
            raise ComponentFailed(f"it returned the fact {' '.join(atom)}, whose predicate '{atom[0]}' is not the domain's")
        if len(arity) != len(atom) - 1:
            raise ComponentFailed(f"it returned the fact {' '.join(atom)}, but '{atom[0]}' takes {len(arity)} arguments")
        out.add(literal)
    return out


def task_result(res, model):
    """A task planner's answer: a TaskPlanResult with a known status and, if solved, ground steps."""
    from .domain import GroundStep
    from .planning import TaskPlanResult

    if not isinstance(res, TaskPlanResult):
        raise ComponentFailed(f"it returned {shown(res)}, not a TaskPlanResult")
    if res.status not in TASK_STATUSES:
        raise ComponentFailed(f"it returned the status {res.status!r}, not one of {', '.join(TASK_STATUSES)}")
    if res.status == "solved":
        for i, step in enumerate(iterable(res.plan, "a plan")):
            if not isinstance(step, GroundStep):
                raise ComponentFailed(f"it returned a plan whose step {i} is {shown(step)}, not a GroundStep")
    return res


def motion_plan(res, query):
    """A motion planner's answer: a MotionPlan; if ok, a path of configurations of the query's space."""
    from .motion import MotionPlan

    if not isinstance(res, MotionPlan):
        raise ComponentFailed(f"it returned {shown(res)}, not a MotionPlan")
    if res.ok:
        dim = getattr(getattr(query, "space", None), "dim", None)
        for i, q in enumerate(iterable(res.path, "a path")):
            if not _numbers(q) or (dim is not None and np.shape(q) != (dim,)):
                raise ComponentFailed(f"it returned a path whose configuration {i} is {shown(q)}, "
                                      f"not {dim if dim is not None else 'a vector of'} numbers")
    if not all(isinstance(o, str) for o in iterable(res.obstructions, "obstructions")):
        raise ComponentFailed(f"it returned the obstructions {shown(res.obstructions)}, not object names")
    return res


def step_outcome(outcome):
    """A geometry's refinement of a step: a StepOutcome; a failed one carries a Failure (or None)."""
    from .refine import Failure, StepOutcome

    if not isinstance(outcome, StepOutcome):
        raise ComponentFailed(f"it returned {shown(outcome)}, not a StepOutcome")
    if not outcome.ok and outcome.failure is not None and not isinstance(outcome.failure, Failure):
        raise ComponentFailed(f"it returned a failed StepOutcome whose failure is {shown(outcome.failure)}, not a Failure")
    return outcome
