"""How a domain plugin declares its task-level model (Sec. III, App. A).

A domain states object types, the continuous types whose values the planner only sees as pose
references, the Skolem functions that name those references, predicates, and actions whose
preconditions and effects are PDDL formulas over both. The core derives everything else: the
reference symbols, their always-true facts, Prop. 1 defaults, and the task planner's view.
"""
from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any, Mapping


@dataclass(frozen=True)
class Skolem:
    """A Skolem function ``name(args) -> type`` reified as references ``name_arg1_arg2``.

    Each reference gets the always-true fact ``(predicate ref arg1 arg2 ...)`` (e.g.
    ``IsGP(gp_b1, b1)``). Arguments may be object types or continuous types declared earlier.
    """

    name: str
    args: tuple[str, ...]
    type: str
    predicate: str
    description: str = ""


@dataclass(frozen=True)
class ActionSpec:
    """An action with continuous-typed parameters.

    ``learn`` maps a motion-failure kind (``"obstruction"``, ``"ik"``, ...) to fact templates over
    the action's parameters plus the failure's own variables (``?blocker`` for each obstructing
    object; ``?blocker2`` etc. for each object of ``Failure.also`` under that name), e.g.
    ``{"obstruction": "(Obstructs ?blocker ?gp ?b)"}``.
    ``pose_generator`` names the registered generator that instantiates the action's references.
    """

    name: str
    parameters: tuple[tuple[str, str], ...]
    precondition: str
    effect: str
    cost: int = 1
    learn: Mapping[str, tuple[str, ...]] = field(default_factory=dict)
    pose_generator: str | None = None


@dataclass(frozen=True)
class DomainSpec:
    name: str
    types: Mapping[str, str | None]  # object type -> parent type (None: top level)
    continuous_types: tuple[str, ...]  # pose, trajectory, location: values are references
    predicates: Mapping[str, tuple[str, ...]]  # name -> argument types
    skolems: tuple[Skolem, ...]
    actions: tuple[ActionSpec, ...]
    # Predicates over references whose truth the task level cannot know (Obstructs, ...): they
    # start at Prop. 1 defaults and are learned from motion-planning failures.
    geometric: tuple[str, ...] = ()

    def action(self, name: str) -> ActionSpec:
        for a in self.actions:
            if a.name == name:
                return a
        raise KeyError(name)


@dataclass(frozen=True)
class GroundStep:
    """One action of a task plan, over objects and references (the full argument list)."""

    action: str
    args: tuple[str, ...]

    def __str__(self) -> str:
        return f"{self.action}({', '.join(self.args)})"

    def to_json(self) -> dict:
        return {"action": self.action, "args": list(self.args)}


@dataclass
class Problem:
    """A problem instance: the symbolic part for the task planner and the geometric runtime.

    ``geometry`` is the domain's refinement runtime (see ``interlayer.refine.Geometry``).
    ``source`` is what is needed to rebuild the problem later (domain name + parameters, or a
    file's contents), written to ``OUT_DIR/problem.json``. ``drawing`` is how visualizers draw it:
    a module, or its dotted name, with ``draw_scene(geometry, scene, world)`` and
    ``animation_frames(geometry, scene, trajectory)``; by default the one its domain registered.
    ``labels`` maps an object's symbol to the name a person gave it, where the two differ (names read
    from a user's file: see ``interlayer.names``); whatever a person reads shows the names.
    """

    domain: DomainSpec
    objects: Mapping[str, str]  # name -> type (original objects and explicit references)
    init: frozenset  # non-geometric facts of the initial state
    goal: str
    geometry: Any
    source: Mapping[str, Any]
    name: str = "problem"
    drawing: Any = None
    labels: Mapping[str, str] = field(default_factory=dict)
