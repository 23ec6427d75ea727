"""The formula language domains write in: parsing, polarity (Prop. 1), state progression."""
import pytest

from interlayer import logic
from interlayer.errors import DomainError


def objects_of(t):
    return {"block": ("b1", "b2"), "pose": ("p1", "p2")}[t]


def test_parse_and_polarity():
    f = logic.parse("(and (Empty) (not (Held ?b)) (forall (?o - block) (not (Obstructs ?o ?p ?b))))")
    pols = {(p.name, pol) for p, pol in logic.atoms_with_polarity(f)}
    assert pols == {("Empty", True), ("Held", False), ("Obstructs", False)}


def test_double_negation_is_positive():
    f = logic.parse("(not (and (A) (not (B))))")
    assert {(p.name, pol) for p, pol in logic.atoms_with_polarity(f)} == {("A", False), ("B", True)}


@pytest.mark.parametrize("text", ["(and (A)", "(A))", "", "(forall (?x) (A ?x))", "(imply (A) (B))"])
def test_malformed_formulas_are_domain_errors(text):
    with pytest.raises(DomainError):
        logic.parse(text)


def test_holds_with_quantifiers():
    state = frozenset({("Obstructs", "b2", "p1", "b1")})
    f = logic.parse("(forall (?o - block) (not (Obstructs ?o ?p ?b)))")
    assert not logic.holds(f, state, {"?p": "p1", "?b": "b1"}, objects_of)
    assert logic.holds(f, state, {"?p": "p2", "?b": "b1"}, objects_of)
    assert logic.holds(logic.parse("(exists (?o - block) (Obstructs ?o p1 b1))"), state, {}, objects_of)


def test_apply_effect_forall_delete_and_conditional_add():
    state = frozenset({("Obstructs", "b2", "p1", "b1"), ("Obstructs", "b2", "p2", "b1"), ("Empty",)})
    eff = logic.parse("(and (Held ?b) (not (Empty)) (forall (?o - block ?p - pose) (not (Obstructs ?b ?p ?o)))"
                      " (when (Empty) (WasEmpty)))")
    out = logic.apply_effect(eff, state, {"?b": "b2"}, objects_of)
    assert out == frozenset({("Held", "b2"), ("WasEmpty",)})


def test_a_forall_that_only_deletes_matches_the_state_as_grounding_would():
    """Deletes under forall are matched against the state (not ground for every object): the same
    result as grounding them, quantified variables ranging over their type only, repeated variables
    bound once, free ones by the binding."""
    state = frozenset({("Obstructs", "b1", "p1", "b2"), ("Obstructs", "b1", "p2", "b2"),
                       ("Obstructs", "p1", "p1", "b2"),  # "p1" is no block: stays
                       ("Obstructs", "b2", "p1", "b1"),  # another ?b: stays
                       ("Same", "b1", "b1"), ("Same", "b1", "b2"), ("Empty",)})
    eff = logic.parse("(and (forall (?o - block ?p - pose) (and (not (Obstructs ?o ?p ?b)) (not (Other ?o))))"
                      " (forall (?o - block) (not (Same ?o ?o))))")
    out = logic.apply_effect(eff, state, {"?b": "b2"}, objects_of)
    assert out == frozenset({("Obstructs", "p1", "p1", "b2"), ("Obstructs", "b2", "p1", "b1"), ("Same", "b1", "b2"),
                             ("Empty",)})
    grounded = set()  # what grounding every binding deletes
    for o in objects_of("block"):
        grounded |= {("Same", o, o)} | {("Obstructs", o, p, "b2") for p in objects_of("pose")}
    assert out == state - grounded
