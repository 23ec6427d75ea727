"""Sec. III / App. A: references, their facts, Prop. 1 defaults, Def. 1 uniformity, dropped arguments."""
import pytest

from interlayer.abstraction import abstract
from interlayer.domain import ActionSpec, DomainSpec, GroundStep, Problem, Skolem
from interlayer.errors import DomainError
from interlayer_gripper2d.plugin import make_problem


@pytest.fixture(scope="module")
def model():
    return abstract(make_problem({"obstructions": 1, "s_occupied": False}, 0))


def test_one_reference_per_skolem_application(model):
    refs = set(model.references)
    assert {"gp_b1", "gp_b2", "pdp_b1_S", "pdp_b1_free", "pdp_b2_S", "pdp_b2_free"} <= refs
    assert "traj_gp_b2_pdp_b2_free" in refs  # Skolem functions over references
    assert ("IsGP", "gp_b1", "b1") in model.static_facts
    assert ("IsPDP", "pdp_b2_free", "b2", "free") in model.static_facts
    assert ("IsGP", "gp_b1", "b1") in model.init


def test_negative_only_geometric_predicates_default_false(model):
    assert model.geometric == {"Obstructs": "negative", "PDObstructs": "negative"}
    assert not any(a[0] in ("Obstructs", "PDObstructs") for a in model.init)
    assert model.uniformity == []


def test_trajectory_arguments_dropped_and_reintroduced(model):
    assert [v for v, _ in model.actions["pick"].parameters] == ["?b", "?p1", "?gp"]
    step = model.reintroduce("pick", ("b1", "init_pose", "gp_b1"))
    assert step == GroundStep("pick", ("b1", "init_pose", "gp_b1", "traj_init_pose_gp_b1"))
    assert model.task_args(step) == ("b1", "init_pose", "gp_b1")


def _toy_domain(precondition, effect, goal="(Done a)"):
    spec = DomainSpec(
        name="toy", types={"item": None}, continuous_types=("pose",),
        predicates={"Done": ("item",), "IsGP": ("pose", "item"), "Reachable": ("pose", "item")},
        skolems=(Skolem("gp", ("item",), "pose", "IsGP"),), geometric=("Reachable",),
        actions=(ActionSpec("take", (("?x", "item"), ("?p", "pose")), precondition, effect),),
    )
    return Problem(spec, {"a": "item", "b": "item"}, frozenset(), goal, None, {})


def test_positive_only_predicate_defaults_true():
    m = abstract(_toy_domain("(and (IsGP ?p ?x) (Reachable ?p ?x))", "(Done ?x)"))
    assert m.geometric["Reachable"] == "positive"
    assert ("Reachable", "gp_a", "a") in m.init and ("Reachable", "gp_b", "b") in m.init
    assert m.uniformity == []


def test_non_uniform_domains_are_reported():
    m = abstract(_toy_domain("(and (IsGP ?p ?x) (not (Reachable ?p ?x)))", "(and (Done ?x) (Reachable ?p ?x))"))
    assert any("adds Reachable" in v for v in m.uniformity)
    m = abstract(_toy_domain("(and (IsGP ?p ?x) (Reachable ?p ?x))", "(Done ?x)", goal="(and (Done a) (not (Reachable gp_a a)))"))
    assert any("both positively and negatively" in v for v in m.uniformity)


def test_unknown_predicate_is_a_clear_domain_error():
    with pytest.raises(DomainError, match="Unknown predicate 'Dome'"):
        abstract(_toy_domain("(and (IsGP ?p ?x) (Dome ?x))", "(Done ?x)"))


def test_a_step_is_applied_to_a_state_once_and_the_replays_reuse_it(monkeypatch):
    """Plan checks and the shortcut pass replay the same prefixes: the model evaluates a precondition and
    progresses a state once per (state, step), and the answers are those of the logic itself."""
    from interlayer import logic
    from interlayer.planning import check_plan
    from interlayer.shortcut import unneeded_steps

    model = abstract(make_problem({"obstructions": 1, "s_occupied": False}, 0))
    plan = [model.reintroduce("pick", ("b2", "init_pose", "gp_b2")),
            model.reintroduce("place", ("b2", "free", "gp_b2", "pdp_b2_free")),
            model.reintroduce("pick", ("b1", "pdp_b2_free", "gp_b1")),
            model.reintroduce("place", ("b1", "S", "gp_b1", "pdp_b1_S"))]
    calls = {"holds": 0, "apply_effect": 0}
    for name in calls:
        def counted(*args, _f=getattr(logic, name), _n=name):
            calls[_n] += 1
            return _f(*args)
        monkeypatch.setattr(logic, name, counted)
    assert check_plan(model, model.init, plan) == ""
    first = dict(calls)
    assert first["holds"] >= len(plan) and first["apply_effect"] == len(plan)
    assert check_plan(model, model.init, plan) == ""  # the same replay: every step from the memo, the goal again
    assert calls == {"holds": first["holds"] + 1, "apply_effect": first["apply_effect"]}
    assert unneeded_steps(plan, model, model.init) == []  # each step enables the next
    assert calls["apply_effect"] < 2 * first["apply_effect"]  # the prefixes it replays come from the memo
    state = model.init
    for step in plan:  # the memo's answers are the logic's own
        _, pre, eff = model.full_actions[step.action]
        assert model.applicable(state, step) is logic.holds(pre, state, model.binding(step), model.objects_of)
        after = model.progress(state, step)
        assert after == logic.apply_effect(eff, state, model.binding(step), model.objects_of)
        state = after
