"""TaskModel + symbolic state -> a Unified-Planning problem (built once, cloned per call).

The task planner sees every object as ``o<k>``, numbered in the model's order, never by its name: a
planner breaks ties by names (Fast Downward picks the other arm when two objects' names sort the other
way), so a renamed copy of a problem would be searched differently. ``name_of`` maps back."""
from __future__ import annotations

from interlayer import logic


class UPProblemBuilder:
    def __init__(self, model):
        from unified_planning import shortcuts as up

        self.up = up
        self.model = model
        self.types = {}
        for t in _type_order(model.types):
            parent = model.types.get(t)
            self.types[t] = up.UserType(t, self.types[parent] if parent else None)
        # Only what the planner's view uses: dropped references (traj_p1_p2) and their facts
        # would otherwise dominate the PDDL that UP writes for every call.
        used = _used_predicates(model)
        self.fluents = {
            name: up.Fluent(name, up.BoolType(), **{f"a{i}": self.types[t] for i, t in enumerate(arg_types)})
            for name, arg_types in model.predicates.items() if name in used
        }
        needed = {t for name in used for t in model.predicates[name]}
        needed |= {t for a in model.actions.values() for _, t in a.parameters}
        kept = [(name, t) for name, t in model.objects.items()
                if any(model.is_subtype(t, n) or model.is_subtype(n, t) for n in needed)]
        width = len(str(max(0, len(kept) - 1)))  # the same length: they sort in the model's order
        self.objects = {name: up.Object(f"o{k:0{width}d}", self.types[t]) for k, (name, t) in enumerate(kept)}
        self.name_of = {o.name: name for name, o in self.objects.items()}
        problem = up.Problem(model.problem.name)
        for f in self.fluents.values():
            problem.add_fluent(f, default_initial_value=False)
        problem.add_objects(list(self.objects.values()))
        costs = {}
        for act in model.actions.values():
            ua = up.InstantaneousAction(act.name, **{v.lstrip("?"): self.types[t] for v, t in act.parameters})
            scope = {v: ua.parameter(v.lstrip("?")) for v, _ in act.parameters}
            pre = self.expr(act.precondition, scope)
            if not pre.is_true():
                ua.add_precondition(pre)
            for fluent_expr, value, cond, forall in self.effects(act.effect, scope, up.TRUE(), ()):
                ua.add_effect(fluent_expr, value, cond, forall=forall)
            problem.add_action(ua)
            costs[ua] = up.Int(act.cost)
        problem.add_goal(self.expr(model.goal, {}))
        if any(a.cost != 1 for a in model.actions.values()):
            problem.add_quality_metric(up.MinimizeActionCosts(costs))
        self.base = problem
        self.action_names = {a.name: a for a in problem.actions}

    def expr(self, f, scope):
        up = self.up
        if isinstance(f, logic.Pred):
            return self.fluents[f.name](*[self.term(a, scope) for a in f.args])
        if isinstance(f, logic.Not):
            return up.Not(self.expr(f.arg, scope))
        if isinstance(f, logic.And):
            return up.And(*[self.expr(a, scope) for a in f.args]) if f.args else up.TRUE()
        if isinstance(f, logic.Or):
            return up.Or(*[self.expr(a, scope) for a in f.args]) if f.args else up.FALSE()
        if isinstance(f, logic.Quant):
            variables = [up.Variable(v.lstrip("?"), self.types[t]) for v, t in f.variables]
            inner = dict(scope, **{v: var for (v, _), var in zip(f.variables, variables)})
            body = self.expr(f.body, inner)
            return up.Forall(body, *variables) if f.kind == "forall" else up.Exists(body, *variables)
        raise ValueError(f"unsupported condition {f}")

    def effects(self, f, scope, cond, forall):
        """Flatten an effect formula into (fluent, value, condition, forall-variables)."""
        up = self.up
        if isinstance(f, logic.Pred):
            yield self.expr(f, scope), up.TRUE(), cond, forall
        elif isinstance(f, logic.Not) and isinstance(f.arg, logic.Pred):
            yield self.expr(f.arg, scope), up.FALSE(), cond, forall
        elif isinstance(f, logic.And):
            for a in f.args:
                yield from self.effects(a, scope, cond, forall)
        elif isinstance(f, logic.Quant) and f.kind == "forall":
            variables = [up.Variable(v.lstrip("?"), self.types[t]) for v, t in f.variables]
            inner = dict(scope, **{v: var for (v, _), var in zip(f.variables, variables)})
            yield from self.effects(f.body, inner, cond, (*forall, *variables))
        elif isinstance(f, logic.When):
            c = self.expr(f.cond, scope)
            yield from self.effects(f.effect, scope, c if cond.is_true() else up.And(cond, c), forall)
        else:
            raise ValueError(f"unsupported effect {f}")

    def term(self, arg, scope):
        if arg.startswith("?"):
            return scope[arg]
        return self.objects[arg]

    def problem_for(self, state: frozenset):
        problem = self.base.clone()
        for atom in state:
            fl = self.fluents.get(atom[0])
            if fl is not None and all(o in self.objects for o in atom[1:]):
                problem.set_initial_value(fl(*[self.objects[o] for o in atom[1:]]), True)
        return problem


def _used_predicates(model) -> set:
    used = set()
    for a in model.actions.values():
        for f in (a.precondition, a.effect):
            used |= {p.name for p, _ in logic.atoms_with_polarity(f)}
    used |= {p.name for p, _ in logic.atoms_with_polarity(model.goal)}
    return used


def _type_order(types: dict) -> list:
    order, seen = [], set()

    def visit(t):
        if t in seen or t is None:
            return
        visit(types.get(t))
        seen.add(t)
        order.append(t)

    for t in types:
        visit(t)
    return order
