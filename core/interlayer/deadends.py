"""States the task planner proved to have no plan, so that the loop never proves the same thing twice.

The task model does not change during a run, so a proof holds for the rest of it: a state met again
(e.g. the same partial refinement failing after a reset, or the same ``earlier`` replanning) needs no
call. Nor does a state that has every atom of a proved one and more atoms only of predicates that occur
only negated in preconditions, conditions and the goal (learned obstructions, Prop. 1's negative
geometric predicates): such an atom can only make an action inapplicable, so every plan from the bigger
state is a plan from the proved one, which has none.
"""
from __future__ import annotations

from . import logic


def forbidding_predicates(model) -> frozenset:
    """Predicates whose every occurrence in a precondition, an effect's condition or the goal is negated."""
    pols: dict[str, set] = {}
    formulas = [model.goal]
    for _, pre, eff in model.full_actions.values():
        formulas += [pre, *_conditions(eff)]
    for f in formulas:
        for p, pol in logic.atoms_with_polarity(f):
            pols.setdefault(p.name, set()).add(pol)
    return frozenset(model.predicates) - {name for name, seen in pols.items() if True in seen}


def _conditions(eff):
    if isinstance(eff, logic.When):
        yield eff.cond
        yield from _conditions(eff.effect)
    elif isinstance(eff, logic.And):
        for a in eff.args:
            yield from _conditions(a)
    elif isinstance(eff, logic.Quant):
        yield from _conditions(eff.body)


class DeadEnds:
    """The states proved to have no plan in this run, each with the task-planner call that proved it."""

    def __init__(self, model):
        self.forbidding = forbidding_predicates(model)
        self.proved: list = []  # (state, call)

    def add(self, state: frozenset, call: int) -> None:
        self.proved.append((state, call))

    def known(self, state: frozenset):
        """The call that proved ``state`` (or a state it only adds forbidding atoms to) has no plan, or None."""
        for proved, call in self.proved:
            if proved <= state and all(a[0] in self.forbidding for a in state - proved):
                return call
        return None
