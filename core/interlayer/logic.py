"""A small first-order logic over ground atoms: the PDDL fragment domains write their actions in.

Domains state preconditions, effects and goals as PDDL s-expressions
(``(and (Empty) (forall (?o - block) (not (Obstructs ?o ?gp ?b))))``). The core parses them once into
this AST, which it uses to (1) build the Unified-Planning problem, (2) compute predicate polarities
for Prop. 1 and Def. 1, (3) progress symbolic states for the state update of Alg. 1 (line 9).
A state is a frozenset of ground atoms; an atom is a tuple ``(predicate, arg, ...)``.
"""
from __future__ import annotations

import itertools
from dataclasses import dataclass
from typing import Iterable, Mapping, Union

from .errors import DomainError

Atom = tuple  # (predicate, *objects)


@dataclass(frozen=True)
class Pred:
    name: str
    args: tuple[str, ...]  # variables (?x) or constants


@dataclass(frozen=True)
class Not:
    arg: "Formula"


@dataclass(frozen=True)
class And:
    args: tuple["Formula", ...]


@dataclass(frozen=True)
class Or:
    args: tuple["Formula", ...]


@dataclass(frozen=True)
class Quant:
    kind: str  # "forall" | "exists"
    variables: tuple[tuple[str, str], ...]  # ((?v, type), ...)
    body: "Formula"


@dataclass(frozen=True)
class When:
    cond: "Formula"
    effect: "Formula"


Formula = Union[Pred, Not, And, Or, Quant, When]
TRUE = And(())


def tokenize(text: str) -> list[str]:
    return text.replace("(", " ( ").replace(")", " ) ").split()


def parse_sexpr(text: str):
    tokens = tokenize(text)
    if not tokens:
        raise DomainError("An empty formula was given; write '(and)' for 'true'.")
    pos = 0

    def read():
        nonlocal pos
        if pos >= len(tokens):
            raise DomainError(f"Unbalanced parentheses in formula {text!r}.")
        tok = tokens[pos]
        pos += 1
        if tok == "(":
            out = []
            while pos < len(tokens) and tokens[pos] != ")":
                out.append(read())
            if pos >= len(tokens):
                raise DomainError(f"Unbalanced parentheses in formula {text!r}.")
            pos += 1
            return out
        if tok == ")":
            raise DomainError(f"Unexpected ')' in formula {text!r}.")
        return tok

    expr = read()
    if pos != len(tokens):
        raise DomainError(f"Trailing text after the formula {text!r}.")
    return expr


def _typed_list(items: list, text: str) -> tuple[tuple[str, str], ...]:
    out, pending = [], []
    it = iter(items)
    for tok in it:
        if tok == "-":
            typ = next(it, None)
            if typ is None or not pending:
                raise DomainError(f"Malformed typed variable list in {text!r}.")
            out += [(v, typ) for v in pending]
            pending = []
        else:
            pending.append(tok)
    if pending:
        raise DomainError(f"Variables {pending} have no type in {text!r}; write '(?x - type)'.")
    return tuple(out)


def parse(text: str) -> Formula:
    """Parse a PDDL formula (conditions or effects) into the AST."""

    def build(e) -> Formula:
        if isinstance(e, str):
            raise DomainError(f"Expected a parenthesised formula, found {e!r} in {text!r}.")
        if not e:
            return TRUE
        head = e[0].lower() if isinstance(e[0], str) else None
        if head == "and":
            return And(tuple(build(x) for x in e[1:]))
        if head == "or":
            return Or(tuple(build(x) for x in e[1:]))
        if head == "not":
            if len(e) != 2:
                raise DomainError(f"'not' takes one formula in {text!r}.")
            return Not(build(e[1]))
        if head in ("forall", "exists"):
            if len(e) != 3 or not isinstance(e[1], list):
                raise DomainError(f"Malformed {head} in {text!r}.")
            return Quant(head, _typed_list(e[1], text), build(e[2]))
        if head == "when":
            return When(build(e[1]), build(e[2]))
        if head in ("imply", "=") or not all(isinstance(x, str) for x in e):
            raise DomainError(f"Unsupported construct {e[0]!r} in {text!r}.")
        return Pred(e[0], tuple(e[1:]))

    return build(parse_sexpr(text))


def atoms_with_polarity(f: Formula, positive: bool = True):
    """Yield (Pred, polarity) for every atom occurrence, polarity as in negation normal form."""
    if isinstance(f, Pred):
        yield f, positive
    elif isinstance(f, Not):
        yield from atoms_with_polarity(f.arg, not positive)
    elif isinstance(f, (And, Or)):
        for a in f.args:
            yield from atoms_with_polarity(a, positive)
    elif isinstance(f, Quant):
        yield from atoms_with_polarity(f.body, positive)
    elif isinstance(f, When):
        yield from atoms_with_polarity(f.cond, positive)
        yield from atoms_with_polarity(f.effect, positive)


def effect_literals(f: Formula, positive: bool = True):
    """Yield (Pred, added) for each literal an effect formula can set (conditions excluded)."""
    if isinstance(f, Pred):
        yield f, positive
    elif isinstance(f, Not):
        yield from effect_literals(f.arg, not positive)
    elif isinstance(f, And):
        for a in f.args:
            yield from effect_literals(a, positive)
    elif isinstance(f, Quant):
        yield from effect_literals(f.body, positive)
    elif isinstance(f, When):
        yield from effect_literals(f.effect, positive)


def free_variables(f: Formula) -> set:
    """The variables (``?x``) of a formula not bound by one of its own quantifiers."""
    if isinstance(f, Pred):
        return {a for a in f.args if a.startswith("?")}
    if isinstance(f, Not):
        return free_variables(f.arg)
    if isinstance(f, (And, Or)):
        return set().union(*(free_variables(a) for a in f.args))
    if isinstance(f, Quant):
        return free_variables(f.body) - {v for v, _ in f.variables}
    if isinstance(f, When):
        return free_variables(f.cond) | free_variables(f.effect)
    return set()


def substitute(args: Iterable[str], binding: Mapping[str, str]) -> tuple[str, ...]:
    return tuple(binding.get(a, a) for a in args)


def holds(f: Formula, state: frozenset, binding: Mapping[str, str], objects_of) -> bool:
    """Evaluate a condition in a state; objects_of(type) lists the objects of a type."""
    if isinstance(f, Pred):
        return (f.name, *substitute(f.args, binding)) in state
    if isinstance(f, Not):
        return not holds(f.arg, state, binding, objects_of)
    if isinstance(f, And):
        return all(holds(a, state, binding, objects_of) for a in f.args)
    if isinstance(f, Or):
        return any(holds(a, state, binding, objects_of) for a in f.args)
    if isinstance(f, Quant):
        test = all if f.kind == "forall" else any
        return test(holds(f.body, state, b, objects_of) for b in _bindings(f.variables, binding, objects_of))
    raise DomainError(f"'when' is only allowed in effects, found in a condition: {f}.")


def _bindings(variables, binding, objects_of):
    names = [v for v, _ in variables]
    for combo in itertools.product(*(objects_of(t) for _, t in variables)):
        yield {**binding, **dict(zip(names, combo))}


def apply_effect(f: Formula, state: frozenset, binding, objects_of) -> frozenset:
    """Progress a state through an effect: deletes first, then adds (PDDL semantics)."""
    adds, dels = set(), set()
    by_name: dict = {}  # the state's atoms per predicate, built on first use

    def collect(e, b, positive=True):
        if isinstance(e, Pred):
            (adds if positive else dels).add((e.name, *substitute(e.args, b)))
        elif isinstance(e, Not):
            collect(e.arg, b, not positive)
        elif isinstance(e, And):
            for a in e.args:
                collect(a, b, positive)
        elif isinstance(e, Quant):
            deleted = _deleted_literals(e.body, positive)
            if deleted is not None:
                # only deletes: match them against the state rather than ground them for every object
                if not by_name:
                    for atom in state:
                        by_name.setdefault(atom[0], []).append(atom)
                dels.update(_matching(deleted, dict(e.variables), b, by_name, objects_of))
                return
            for bb in _bindings(e.variables, b, objects_of):
                collect(e.body, bb, positive)
        elif isinstance(e, When):
            if holds(e.cond, state, b, objects_of):
                collect(e.effect, b, positive)
        else:
            raise DomainError(f"Unsupported effect {e}.")

    collect(f, binding)
    return frozenset((state - dels) | adds)


def _deleted_literals(e, positive):
    """The predicates an effect deletes if it only deletes (literals under ``and``), else None."""
    if isinstance(e, Pred):
        return None if positive else [e]
    if isinstance(e, Not):
        return _deleted_literals(e.arg, not positive)
    if isinstance(e, And):
        out = []
        for a in e.args:
            found = _deleted_literals(a, positive)
            if found is None:
                return None
            out += found
        return out
    return None


def _matching(preds, variables, binding, by_name, objects_of):
    """The atoms of the state (``by_name``) that ``preds`` ground to, the quantified ``variables``
    ranging over the objects of their types."""
    typed = {}
    for p in preds:
        for atom in by_name.get(p.name, ()):
            if len(atom) != len(p.args) + 1:
                continue
            bound = {}
            for arg, value in zip(p.args, atom[1:]):
                if arg in variables:
                    if bound.setdefault(arg, value) != value:
                        break
                    kind = variables[arg]
                    if kind not in typed:
                        typed[kind] = set(objects_of(kind))
                    if value not in typed[kind]:
                        break
                elif binding.get(arg, arg) != value:
                    break
            else:
                yield atom


def ground_atom(p: Pred, binding: Mapping[str, str]) -> Atom:
    return (p.name, *substitute(p.args, binding))


def atom_str(atom: Atom) -> str:
    return "(" + " ".join(atom) + ")"


def negated(atom: Atom) -> Not:
    """The literal "``atom`` is false": what a translator returns to delete a fact (e.g. to correct a
    geometric atom that Prop. 1 made true by default)."""
    return Not(Pred(atom[0], tuple(atom[1:])))


def literal_str(literal) -> str:
    """An atom, or a ``negated`` atom, as PDDL: ``(P a b)`` or ``(not (P a b))``."""
    if isinstance(literal, Not):
        return f"(not {atom_str(ground_atom(literal.arg, {}))})"
    return atom_str(literal)


def parse_atom(text: str) -> Atom:
    f = parse(text)
    if not isinstance(f, Pred):
        raise DomainError(f"Expected a single ground atom like '(Obstructs b2 gp_b1 b1)', got {text!r}.")
    return (f.name, *f.args)
