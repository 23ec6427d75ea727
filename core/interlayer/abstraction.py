"""The abstraction of Sec. III and App. A: pose references, their facts, Prop. 1 defaults, Def. 1.

``abstract(problem)`` turns a domain with continuous parameters into a finite symbolic model that
any classical planner can solve: every Skolem function applied to the problem's objects becomes a
reference object, geometric predicates start at their default truth values, and action parameters
that contribute nothing at the task level (trajectory references) are dropped from the planner's
view and reintroduced before refinement.
"""
from __future__ import annotations

import itertools
from dataclasses import dataclass, field

from . import logic
from .domain import ActionSpec, GroundStep, Problem
from .errors import DomainError, closest


@dataclass(frozen=True)
class TaskAction:
    """An action as the task planner sees it (dropped parameters removed)."""

    name: str
    parameters: tuple[tuple[str, str], ...]
    precondition: logic.Formula
    effect: logic.Formula
    cost: int
    dropped: tuple[tuple[str, str, logic.Pred], ...]  # (variable, type, defining atom)


_MEMO = 4096  # entries per memo (each holds a state: a few MB in all)


def _memoised(memo: dict, state: frozenset, step: GroundStep, compute):
    """``compute(state, step)``, once per (state, step) while it stays in ``memo``."""
    key = (state, step)
    out = memo.get(key)
    if out is None:
        out = compute(state, step)
        if len(memo) >= _MEMO:
            memo.clear()
        memo[key] = out
    return out


@dataclass
class TaskModel:
    """Everything the task planner sees; built once per problem."""

    problem: Problem
    types: dict  # type -> parent
    objects: dict  # name -> type, references included
    predicates: dict  # name -> arg types
    actions: dict  # name -> TaskAction
    full_actions: dict  # name -> (params, precondition, effect) with all parameters
    goal: logic.Formula
    static_facts: frozenset  # Skolem facts (always true)
    default_true: frozenset  # geometric atoms true by Prop. 1
    geometric: dict  # predicate -> "positive" | "negative" | "mixed"
    references: dict  # reference -> (skolem name, args)
    reference_of: dict  # (skolem predicate, args...) -> reference
    uniformity: list = field(default_factory=list)  # violations of Def. 1 (empty: uniform)
    parameter_roles: dict = field(default_factory=dict)  # action -> {var: role}
    labels: dict = field(default_factory=dict)  # symbol -> the name a person reads (objects and their references)
    _by_type: dict = field(default_factory=dict)
    _ordinals: dict = field(default_factory=dict)
    # (state, step) -> applicable / progressed state: the model never changes once built, and plan checks
    # and the shortcut pass replay the same prefixes again and again (a fifth of a big file's Python time)
    _applicable: dict = field(default_factory=dict, repr=False, compare=False)
    _progressed: dict = field(default_factory=dict, repr=False, compare=False)

    @property
    def init(self) -> frozenset:
        """The abstract initial state: problem facts, reference facts, Prop. 1 defaults."""
        return frozenset(self.problem.init) | self.static_facts | self.default_true

    def ordinal(self, name):
        """An object's (or reference's) place in the model, what seeds use instead of its name; any
        other value as it is."""
        if not self._ordinals:
            self._ordinals.update({o: f"#{i}" for i, o in enumerate(self.objects)})
        return self._ordinals.get(name, name)

    def objects_of(self, typ: str) -> tuple:
        if typ not in self._by_type:
            self._by_type[typ] = tuple(o for o, t in self.objects.items() if self.is_subtype(t, typ))
        return self._by_type[typ]

    def is_subtype(self, t: str, parent: str) -> bool:
        return _subtype(self.types, t, parent)

    def binding(self, step: GroundStep) -> dict:
        params, _, _ = self.full_actions[step.action]
        return {v: a for (v, _), a in zip(params, step.args)}

    def step_with(self, step: GroundStep, objects: dict) -> GroundStep:
        """``step``'s action with some object parameters bound otherwise (``{"?o": "b2"}``) and every
        reference parameter defined by a Skolem atom over them renamed to match (``gp_b1`` -> ``gp_b2``)."""
        params, pre, _ = self.full_actions[step.action]
        unknown = set(objects) - {v for v, _ in params}
        if unknown:
            raise KeyError(f"action {step.action} has no parameter {', '.join(sorted(unknown))}")
        binding = {**self.binding(step), **objects}
        skolem_preds = {key[0] for key in self.reference_of}
        for p, _ in logic.atoms_with_polarity(pre):
            if p.name in skolem_preds and p.args and p.args[0] in binding:
                ref = self.reference_of.get((p.name, *(binding.get(a, a) for a in p.args[1:])))
                if ref is not None:
                    binding[p.args[0]] = ref
        return GroundStep(step.action, tuple(binding[v] for v, _ in params))

    def applicable(self, state: frozenset, step: GroundStep) -> bool:
        return _memoised(self._applicable, state, step, self._precondition_holds)

    def progress(self, state: frozenset, step: GroundStep) -> frozenset:
        return _memoised(self._progressed, state, step, self._effect_applied)

    def _precondition_holds(self, state: frozenset, step: GroundStep) -> bool:
        _, pre, _ = self.full_actions[step.action]
        return logic.holds(pre, state, self.binding(step), self.objects_of)

    def _effect_applied(self, state: frozenset, step: GroundStep) -> frozenset:
        _, _, eff = self.full_actions[step.action]
        return logic.apply_effect(eff, state, self.binding(step), self.objects_of)

    def goal_holds(self, state: frozenset) -> bool:
        return logic.holds(self.goal, state, {}, self.objects_of)

    def cost(self, plan) -> int:
        """The plan's cost: the sum of its actions' costs (what a cost-optimal planner minimises)."""
        return sum(self.actions[s.action].cost for s in plan)

    def task_args(self, step: GroundStep) -> tuple:
        """The arguments the task planner sees (dropped parameters removed)."""
        binding = self.binding(step)
        return tuple(binding[v] for v, _ in self.actions[step.action].parameters)

    def reintroduce(self, action: str, task_args: tuple) -> GroundStep:
        """Restore dropped parameters (e.g. ``traj_p1_p2``) of a task-planner step."""
        act = self.actions[action]
        binding = {v: a for (v, _), a in zip(act.parameters, task_args)}
        for var, _, atom in act.dropped:
            key = (atom.name, *[binding[a] if a.startswith("?") else a for a in atom.args if a != var])
            binding[var] = self.reference_of[key]
        params, _, _ = self.full_actions[action]
        return GroundStep(action, tuple(binding[v] for v, _ in params))


def _check_types(spec, typ, where):
    if typ not in spec.types and typ not in spec.continuous_types:
        raise DomainError(f"Unknown type '{typ}' in {where}; declare it in the domain's types.")


def _check_formula(spec, f, where, bound=None):
    """Predicates must be declared with the right arity; with ``bound`` (the variables in scope),
    every variable must be bound by it or by an enclosing quantifier."""
    for pred, _ in logic.atoms_with_polarity(f):
        if pred.name not in spec.predicates:
            raise DomainError(f"Unknown predicate '{pred.name}' in {where}{closest(pred.name, spec.predicates)}; "
                              f"declare it in the domain's predicates.")
        if len(pred.args) != len(spec.predicates[pred.name]):
            raise DomainError(
                f"Predicate '{pred.name}' takes {len(spec.predicates[pred.name])} arguments but "
                f"{len(pred.args)} were given in {where}."
            )
    if bound is not None:
        free = sorted(logic.free_variables(f) - set(bound))
        if free:
            scope = ", ".join(sorted(bound)) or "none"
            raise DomainError(f"The variable '{free[0]}' in {where} is not bound (variables in scope: {scope}); "
                              f"add it to the parameters or quantify it with forall/exists.")


def abstract(problem: Problem) -> TaskModel:
    spec = problem.domain
    types = {t: p for t, p in spec.types.items()}
    for c in spec.continuous_types:
        types.setdefault(c, None)
    objects = dict(problem.objects)
    for o, t in objects.items():
        _check_types(spec, t, f"object '{o}'")

    # References: one per Skolem-function application over the problem's objects (App. A).
    references, reference_of, static = {}, {}, set()
    labels = dict(problem.labels)
    skolem_preds = {}
    for sk in spec.skolems:
        skolem_preds[sk.predicate] = sk
        pools = [[o for o, t in objects.items() if _subtype(types, t, a)] for a in sk.args]
        for combo in itertools.product(*pools):
            ref = "_".join((sk.name, *combo))
            if ref in objects:
                raise DomainError(f"Reference name '{ref}' clashes with an object of the problem.")
            objects[ref] = sk.type
            references[ref] = (sk.name, combo)
            reference_of[(sk.predicate, *combo)] = ref
            static.add((sk.predicate, ref, *combo))
            if problem.labels:  # names that are not symbols: every reference as skolem(its names), alike
                labels[ref] = f"{sk.name}({', '.join(problem.labels.get(c, c) for c in combo)})"

    full_actions, task_actions, roles = {}, {}, {}
    occurrences: dict[str, set] = {}
    added: dict[str, set] = {}
    for act in spec.actions:
        where = f"action '{act.name}'"
        for _, t in act.parameters:
            _check_types(spec, t, where)
        pre, eff = logic.parse(act.precondition), logic.parse(act.effect)
        params = [v for v, _ in act.parameters]
        _check_formula(spec, pre, f"the precondition of {where}", params)
        _check_formula(spec, eff, f"the effect of {where}", params)
        for kind, templates in act.learn.items():
            for tpl in templates:
                f = logic.parse(tpl)  # a failure binds the ?blocker... variables (Failure.objects, .also)
                if not isinstance(f.arg if isinstance(f, logic.Not) else f, logic.Pred):
                    raise DomainError(f"The learn template {tpl!r} of {where} is not one fact or its negation; write "
                                      f"'(P ?x ...)' to learn P true or '(not (P ?x ...))' to learn it false.")
                _check_formula(spec, f, f"{where}, learn[{kind!r}]",
                               [*params, *(v for v in logic.free_variables(f) if v.startswith("?blocker"))])
        full_actions[act.name] = (act.parameters, pre, eff)
        for p, pol in logic.atoms_with_polarity(pre):
            occurrences.setdefault(p.name, set()).add(pol)
        for p, pol in logic.effect_literals(eff):
            added.setdefault(p.name, set()).add(pol)
        task_actions[act.name], roles[act.name] = _task_view(spec, act, pre, eff, skolem_preds)
    goal = logic.parse(problem.goal)
    _check_formula(spec, goal, "the goal", [])
    for pred, _ in logic.atoms_with_polarity(goal):
        for arg in pred.args:
            if not arg.startswith("?") and arg not in objects:
                raise DomainError(f"The goal names '{arg}', which is not an object of the problem{closest(arg, objects)}.")
    for p, pol in logic.atoms_with_polarity(goal):
        occurrences.setdefault(p.name, set()).add(pol)

    # Geometric predicates (declared by the domain): defaults by polarity (Prop. 1), Def. 1 check.
    geometric, uniformity, default_true = {}, [], set()
    for name in spec.geometric:
        if name not in spec.predicates:
            raise DomainError(f"The geometric predicate '{name}' is not declared among the domain's predicates.")
        arg_types = spec.predicates[name]
        if not any(t in spec.continuous_types for t in arg_types):
            raise DomainError(f"The geometric predicate '{name}' has no argument of a continuous type.")
        pols = occurrences.get(name, set())
        form = "mixed" if len(pols) == 2 else ("positive" if pols == {True} else "negative")
        geometric[name] = form
        if form == "mixed":
            uniformity.append(f"{name} occurs both positively and negatively in preconditions or the goal")
        elif (form == "negative" and True in added.get(name, ())) or (form == "positive" and False in added.get(name, ())):
            verb = "adds" if form == "negative" else "deletes"
            uniformity.append(f"an action {verb} {name} although it occurs only {form}ly in preconditions and the goal")
        if form == "positive":
            pools = [[o for o, t in objects.items() if _subtype(types, t, a)] for a in arg_types]
            default_true.update((name, *combo) for combo in itertools.product(*pools))

    return TaskModel(
        problem=problem,
        types=types,
        objects=objects,
        predicates=dict(spec.predicates),
        actions=task_actions,
        full_actions=full_actions,
        goal=goal,
        static_facts=frozenset(static),
        default_true=frozenset(default_true),
        geometric=geometric,
        references=references,
        reference_of=reference_of,
        uniformity=uniformity,
        parameter_roles=roles,
        labels=labels,
    )


def _subtype(types, t, parent):
    while t is not None:
        if t == parent:
            return True
        t = types.get(t)
    return False


def _task_view(spec, act: ActionSpec, pre, eff, skolem_preds):
    """Drop continuous parameters whose only occurrence is their own Skolem-defining atom."""
    roles, dropped = {}, []
    eff_vars = {a for p, _ in logic.effect_literals(eff) for a in p.args}
    learn_vars = {
        a for tpls in act.learn.values() for tpl in tpls for p, _ in logic.atoms_with_polarity(logic.parse(tpl)) for a in p.args
    }
    pre_atoms = [p for p, _ in logic.atoms_with_polarity(pre)]
    for var, typ in act.parameters:
        if typ not in spec.continuous_types:
            continue
        defining = [p for p in pre_atoms if p.name in skolem_preds and p.args and p.args[0] == var]
        uses = [p for p in pre_atoms if var in p.args]
        if var in eff_vars:
            roles[var] = "free in an effect: kept as an action argument over references (App. A)"
        elif defining and uses == defining[:1] and var not in learn_vars:
            dropped.append((var, typ, defining[0]))
            roles[var] = f"dropped from the task planner's view; reintroduced as {defining[0].name}'s reference"
        elif defining:
            roles[var] = f"Skolemized: ranges over references satisfying {defining[0].name}"
        else:
            roles[var] = "ranges over references of its type"
    drop = {v for v, _, _ in dropped}
    if drop:
        pre = _without(pre, {d[2] for d in dropped})
    params = tuple(p for p in act.parameters if p[0] not in drop)
    return TaskAction(act.name, params, pre, eff, act.cost, tuple(dropped)), roles


def _without(f, atoms):
    if isinstance(f, logic.And):
        return logic.And(tuple(_without(a, atoms) for a in f.args if a not in atoms))
    return f
