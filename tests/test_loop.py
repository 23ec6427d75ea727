"""Alg. 1 and Alg. 2, branch by branch, with the real Fast Downward task planner.

The geometry here is a scripted test double (it says which refinements fail and why), so each
branch of the loop can be driven on purpose; the Gripper-2D tests exercise the real geometry.
"""

import pytest

from interlayer.abstraction import abstract
from interlayer.domain import ActionSpec, DomainSpec, GroundStep, Problem, Skolem
from interlayer.loop import InterfaceLayer, LoopSettings
from interlayer.refine import NO_CANDIDATES, Candidate, Failure, GiveUp, Infeasible, StepOutcome

SPEC = DomainSpec(
    name="scripted",
    types={"item": None},
    continuous_types=("pose",),
    predicates={"Done": ("item",), "Takeable": ("item",), "IsGP": ("pose", "item"),
                "Obstructs": ("item", "pose", "item")},
    skolems=(Skolem("gp", ("item",), "pose", "IsGP"),),
    geometric=("Obstructs",),
    actions=(ActionSpec(
        "take", (("?x", "item"), ("?p", "pose")),
        "(and (Takeable ?x) (not (Done ?x)) (IsGP ?p ?x) (forall (?o - item) (not (Obstructs ?o ?p ?x))))",
        "(and (Done ?x) (forall (?o - item ?q - pose) (not (Obstructs ?x ?q ?o))))",
        learn={"obstruction": ("(Obstructs ?blocker ?p ?x)",)},
        pose_generator="scripted",
    ),),
)


class ScriptedGeometry:
    """World = the set of items taken. ``script(item, candidate_label, world, calls)`` -> Failure or None."""

    def __init__(self, script):
        self.script, self.calls = script, 0

    def initial_world(self):
        return frozenset()

    def snapshot(self, world):
        return sorted(world)

    def refine_step(self, step, world, candidate, motion):
        self.calls += 1
        failure = self.script(step.args[0], candidate.label, world, self.calls)
        if failure:
            return StepOutcome(False, failure=failure)
        return StepOutcome(True, world | {step.args[0]}, [{"took": step.args[0], "with": candidate.label}])


def generator(labels=("c0", "c1")):
    def gen(problem, step, world, rng):
        for label in labels:
            yield Candidate((label,), {}, f"{label}-{rng.integers(1000)}")
    return gen


def run(script, goal="(Done a)", items=("a", "b", "z"), takeable=("a", "b"), gen=None, host=None, **settings):
    problem = Problem(SPEC, {i: "item" for i in items}, frozenset(("Takeable", t) for t in takeable), goal,
                      ScriptedGeometry(script), {})
    model = abstract(problem)
    task = host["task_planners"].get("fast-downward").factory({})
    translators = [("templates", host["failure_translators"].get("templates").factory)]
    settings = LoopSettings(**{"time_limit": 30.0, **settings})
    layer = InterfaceLayer(model, task, None, {"take": gen or generator()}, translators, settings)
    return layer.solve(), problem.geometry


def events(result, kind):
    return [e for e in result.trace.events if e["type"] == kind]


def by_epoch(result, kind, values):
    """epoch -> the values(event) of the trace's events of ``kind``, in order."""
    out, epoch = {}, 0
    for e in result.trace.events:
        if e["type"] == "reset":
            epoch = e["epoch"]
        if e["type"] == kind:
            out.setdefault(epoch, []).extend(values(e))
    return out


def test_error_free_refinement_needs_no_replanning(host):
    result, _ = run(lambda item, label, world, n: None, host=host)
    assert result.status == "solved" and result.task_planner_calls == 1 and result.replans == 0
    assert [str(s) for s in result.plan] == ["take(a, gp_a)"]


def test_failure_is_learned_and_plan_spliced(host):
    def script(item, label, world, n):  # b stands in the way of a until b is taken
        return Failure("obstruction", ("b",)) if item == "a" and "b" not in world else None

    result, _ = run(script, host=host)
    assert result.status == "solved"
    assert [str(s) for s in result.plan] == ["take(b, gp_b)", "take(a, gp_a)"]
    assert ("Obstructs", "b", "gp_a", "a") in result.learned_facts
    replan = events(result, "replan")[0]
    assert replan["fail_step"] == 0 and replan["prefix"] == []


def test_spliced_plan_is_prefix_plus_new_plan(host):
    """HLPlan[0:failStep] + newPlan (Alg. 1, line 12); Gripper-2D tests show a non-empty prefix."""
    def script(item, label, world, n):
        return Failure("obstruction", ("y",)) if item == "b" and "y" not in world else None

    result, _ = run(script, goal="(and (Done a) (Done b))", items=("a", "b", "y"), takeable=("a", "b", "y"), host=host)
    assert result.status == "solved"
    replans = events(result, "replan")
    assert replans, "expected a replan"
    r = replans[0]
    assert r["plan"][: r["fail_step"]] == r["prefix"] and r["plan"][r["fail_step"]:] == r["new_plan"]
    names = [s.args[0] for s in result.plan]
    assert names.index("y") < names.index("b")


def test_dead_end_update_tries_next_partial_refinement(host):
    """Fig. 4 scenario 2c: the first failure says z (untakeable) blocks a: no plan; the next says b."""
    def script(item, label, world, n):
        if item == "a" and label.startswith("c0"):
            return Failure("obstruction", ("z",))
        if item == "a" and "b" not in world:
            return Failure("obstruction", ("b",))
        return None

    result, _ = run(script, host=host)
    assert result.status == "solved"
    dead = events(result, "dead_end")
    assert dead and dead[0]["facts"] == ["(Obstructs z gp_a a)"]
    assert [str(s) for s in result.plan] == ["take(b, gp_b)", "take(a, gp_a)"]


def test_max_traj_count_resets_learned_facts_and_reseeds(host):
    def script(item, label, world, n):  # fails (into a dead end) for the first 4 refinements only
        return Failure("obstruction", ("z",)) if n <= 4 else None

    result, _ = run(script, host=host, max_traj_count=1)
    assert result.status == "solved"
    resets = events(result, "reset")
    assert resets and resets[0]["reason"] == "MaxTrajCount reached"
    # after the reset the same plan is refined afresh, with generators reseeded (new samples)
    attempts = events(result, "attempt")
    labels_by_epoch = by_epoch(result, "attempt", lambda e: [e["candidate"]])
    assert set(labels_by_epoch[0]).isdisjoint(labels_by_epoch[1])
    assert len(attempts) >= 5


def test_reset_clears_learned_facts(host):
    """Alg. 1, line 15: after MaxTrajCount the learned facts leave the state (the same failure is
    learned again in the next epoch) and the result no longer reports them."""
    def script(item, label, world, n):  # z (untakeable) blocks a for the first 4 refinements: dead ends
        return Failure("obstruction", ("z",)) if n <= 4 else None

    result, _ = run(script, host=host, max_traj_count=1)
    assert result.status == "solved" and events(result, "reset")
    fact = "(Obstructs z gp_a a)"
    learned_in_epoch = by_epoch(result, "failure", lambda e: e["facts"])
    assert fact in learned_in_epoch[0] and fact in learned_in_epoch[1]
    assert result.learned_facts == []  # the solving epoch learned nothing


def test_plan_longer_than_the_attempt_budget_refines(host):
    """Successful attempts do not count against max_refine_attempts: a 3-step plan refines with a
    budget of 1 (it used to reset forever)."""
    goal = "(and (Done a) (Done b) (Done y))"
    result, _ = run(lambda *a: None, goal=goal, items=("a", "b", "y"), takeable=("a", "b", "y"), host=host,
                    max_refine_attempts=1, time_limit=10.0)
    assert result.status == "solved", result.reason
    assert len(result.plan) == 3 and not events(result, "reset")


def test_attempt_budget_grows_across_epochs(host):
    """Every step's first candidate fails and teaches nothing: with a budget of one failure per step
    the first epoch cannot refine; the next epoch's larger budget can."""
    def script(item, label, world, n):
        return Failure("unreachable") if label.startswith("c0") else None

    goal = "(and (Done a) (Done b))"
    result, _ = run(script, goal=goal, host=host, max_refine_attempts=1, time_limit=10.0)
    assert result.status == "solved", result.reason
    assert len(events(result, "reset")) == 1


class LabelledGeometry(ScriptedGeometry):
    """World = the (item, candidate) pairs taken so far, so the script can see earlier choices."""

    def refine_step(self, step, world, candidate, motion):
        self.calls += 1
        failure = self.script(step.args[0], candidate.label, world, self.calls)
        if failure:
            return StepOutcome(False, failure=failure)
        return StepOutcome(True, world | {(step.args[0], candidate.label[:2])}, [{"took": step.args[0]}])


def test_backtracks_to_an_earlier_step_when_a_generator_is_exhausted(host):
    """Alg. 2, lines 7-10: step 1 refines only if step 0 took its second candidate; every candidate
    of step 1 fails after step 0's first, so TryRefine must go back and advance step 0."""
    def script(item, label, world, n):
        if world and next(iter(world))[1] == "c0":
            return Failure("unreachable")
        return None

    problem = Problem(SPEC, {i: "item" for i in ("a", "b")}, frozenset(("Takeable", t) for t in "ab"),
                      "(and (Done a) (Done b))", LabelledGeometry(script), {})
    task = host["task_planners"].get("fast-downward").factory({})
    translators = [("templates", host["failure_translators"].get("templates").factory)]
    layer = InterfaceLayer(abstract(problem), task, None, {"take": generator()}, translators,
                           LoopSettings(time_limit=10.0, max_traj_count=1))
    result = layer.solve()
    assert result.status == "solved", result.reason
    assert not events(result, "reset") and result.task_planner_calls == 1
    tried = [(e["step"], e["candidate"][:2], e["ok"]) for e in events(result, "attempt") if e["mode"] == "error-free"]
    assert tried == [(0, "c0", True), (1, "c0", False), (1, "c1", False), (0, "c1", True), (1, "c0", True)]


def test_a_reset_reseeds_epoch_state_generators(host):
    """A generator that keeps state (an EpochState) gets a fresh, reseeded instance after a reset."""
    from interlayer.refine import EpochState

    class Sampler(EpochState):
        def __call__(self, problem, step, world, rng):
            for k in range(2):
                yield Candidate((k,), {}, f"c{k}-{self.rng_for(step.args[0]).integers(10**9)}")

    problem = Problem(SPEC, {"a": "item"}, frozenset({("Takeable", "a")}), "(Done a)",
                      ScriptedGeometry(lambda *a: None), {})
    layer = InterfaceLayer(abstract(problem), None, None, {"take": Sampler}, [], LoopSettings())
    step = GroundStep("take", ("a", "gp_a"))
    first = layer.make_generator(0, step, frozenset()).reset_and_get_first().label
    assert layer.make_generator(0, step, frozenset()).reset_and_get_first().label == first  # same epoch
    layer.new_epoch()
    assert layer.make_generator(0, step, frozenset()).reset_and_get_first().label != first


def test_time_limit_is_honoured(host):
    """z (untakeable) always blocks a: every learned fact leads to a dead end, epoch after epoch."""
    result, _ = run(lambda item, label, world, n: Failure("obstruction", ("z",)), host=host, time_limit=1.0)
    assert result.status == "timeout" and "time limit" in result.reason
    assert result.times["total"] < 5


def test_unsolvable_task_level_problem(host):
    result, _ = run(lambda *a: None, goal="(Done z)", host=host)
    assert result.status == "unsolvable" and "no plan" in result.reason


@pytest.mark.parametrize("exc, status", [(Infeasible, "unsolvable"), (GiveUp, "gave_up")])
def test_infeasible_reference_ends_unsolvable_and_a_generator_giving_up_gave_up(host, exc, status):
    """Infeasible: a domain's proof; GiveUp: a generator's own finite search found nothing, no proof."""
    def gen(problem, step, world, rng):
        raise exc("a is too wide for the gripper")
        yield

    result, _ = run(lambda *a: None, gen=gen, host=host)
    assert result.status == status and result.reason == "a is too wide for the gripper"


def test_candidates_are_computed_only_when_the_search_asks_for_them(host):
    drawn = []

    def gen(problem, step, world, rng):
        for label in ("c0", "c1", "c2"):
            drawn.append(label)
            yield Candidate((label,), {}, label)

    result, _ = run(lambda *a: None, gen=gen, host=host)
    assert result.status == "solved" and drawn == ["c0"]


# -- no silent loops (interlayer.watchdog) ------------------------------------------------------
def test_a_generator_that_yields_nothing_is_named_with_its_step(host):
    def empty(problem, step, world, rng):
        return iter(())

    empty.labels = {"take": "pose generator 'scripted:empty'"}
    result, _ = run(lambda *a: None, gen=empty, host=host)
    assert result.status == "gave_up"
    assert "the pose generator 'scripted:empty' yielded no candidates for step 0 take(a, gp_a)" in result.reason
    assert result.reason.startswith("no progress in 3 resets in a row") and result.counts["resets"] == 3


def test_a_failure_kind_without_translation_names_the_kind_and_the_learn_keys(host):
    result, _ = run(lambda item, label, world, n: Failure("unreachabel"), host=host)
    assert result.status == "gave_up"
    assert ("the failure kind 'unreachabel' of the action 'take' has no translation (its learn keys: obstruction)"
            in result.reason)


def test_a_reset_cycle_repeating_the_same_state_is_stopped(host):
    def fixed(problem, step, world, rng):  # ignores its rng: every epoch is the same
        yield Candidate(("c0",), {}, "c0")

    result, _ = run(lambda item, label, world, n: Failure("obstruction", ("z",)), gen=fixed, host=host,
                    max_traj_count=1)
    assert result.status == "gave_up" and "the reset cycle repeats the same state" in result.reason
    assert result.counts["resets"] == 3


def test_resets_without_refinement_work_are_limited():
    """A cycle that changes every epoch yet resets without trying any refinement is stopped, counted in
    work (attempts), not seconds: the same run gives the same verdict on any machine."""
    from interlayer import watchdog

    watch = watchdog.ProgressWatch(None)
    with pytest.raises(watchdog.NoProgress, match="the loop is spinning: 100 resets with 0 refinement attempts"):
        for epoch in range(watchdog.RATE_WINDOW):
            watch.signature.append(epoch)
            watch.reset(learned=1, plan=[])


def test_resets_with_refinement_work_are_not_spinning():
    from interlayer import watchdog

    watch = watchdog.ProgressWatch(None)
    for epoch in range(3 * watchdog.RATE_WINDOW):
        watch.attempt(0, "step", Candidate((epoch,), {}, f"c{epoch}"), StepOutcome(True))
        watch.reset(learned=1, plan=[])


def test_the_trace_size_is_limited(monkeypatch, host):
    from interlayer import watchdog

    monkeypatch.setattr(watchdog, "MAX_TRACE_EVENTS", 30)
    result, _ = run(lambda item, label, world, n: Failure("obstruction", ("z",)), host=host, time_limit=20)
    assert result.status == "gave_up" and "the trace reached 30 events without a solution" in result.reason


def _refined(problem, model, plan):
    """The plan refined by TryRefine (with the candidates each step used), as the loop would."""
    from interlayer.loop import _drain
    from interlayer.refine import Refiner

    layer = InterfaceLayer(model, None, None, {"take": generator()}, [], LoopSettings())
    done = _drain(Refiner(problem.geometry, None, layer.make_generator, 2, lambda: False)
                  .try_refine(plan, 0, frozenset(), {}, partial=False))
    return [done.outcomes[i] for i in range(len(plan))]


def _shortcut(problem, model, plan, outcomes, state):
    from interlayer.shortcut import shortcut
    from interlayer.trace import Stats

    dropped = []
    short, out = shortcut(plan, outcomes, model, state, problem.geometry, None, frozenset(), lambda: False,
                          lambda d, p: dropped.append(d), Stats())
    return short, out, dropped


def test_shortcut_drops_steps_the_plan_does_not_need():
    """A step that the goal does not need and whose removal still refines is dropped; a step that a
    learned obstruction makes necessary is kept; later steps keep the pose values they had."""
    problem = Problem(SPEC, {i: "item" for i in "aby"}, frozenset(("Takeable", t) for t in "aby"), "(Done a)",
                      ScriptedGeometry(lambda *a: None), {})
    model = abstract(problem)
    plan = [GroundStep("take", ("b", "gp_b")), GroundStep("take", ("y", "gp_y")), GroundStep("take", ("a", "gp_a"))]
    outcomes = _refined(problem, model, plan)
    short, out, dropped = _shortcut(problem, model, plan, outcomes, model.init)
    assert short == plan[2:] and len(out) == 1 and out[0].world == frozenset({"a"}) and dropped
    assert out[0].candidate == outcomes[2].candidate
    learned = model.init | {("Obstructs", "b", "gp_a", "a")}  # b stood in a's way: taking b stays
    short, _, _ = _shortcut(problem, model, plan, outcomes, learned)
    assert short == [plan[0], plan[2]]


def test_shortcut_keeps_a_step_whose_removal_does_not_refine():
    def script(item, label, world, n):  # a can be taken only once b is gone: geometry, not learned
        return Failure("unreachable") if item == "a" and "b" not in world else None

    problem = Problem(SPEC, {i: "item" for i in "ab"}, frozenset(("Takeable", t) for t in "ab"), "(Done a)",
                      ScriptedGeometry(script), {})
    model = abstract(problem)
    plan = [GroundStep("take", ("b", "gp_b")), GroundStep("take", ("a", "gp_a"))]
    outcomes = _refined(problem, model, plan)
    short, out, dropped = _shortcut(problem, model, plan, outcomes, model.init)
    assert short == plan and out == outcomes and not dropped


def test_shortcut_does_not_retry_a_removal_that_leaves_a_known_obstruction_in_place():
    """Dropping take(b) fails (b is in a's way); once take(y) is dropped, that removal is not tried
    again: the re-refinement that failed on b is not repeated."""
    blocked = []

    def script(item, label, world, n):
        if item == "a" and "b" not in world:
            blocked.append(n)
            return Failure("obstruction", ("b",))
        return None

    problem = Problem(SPEC, {i: "item" for i in "aby"}, frozenset(("Takeable", t) for t in "aby"), "(Done a)",
                      ScriptedGeometry(script), {})
    model = abstract(problem)
    plan = [GroundStep("take", ("b", "gp_b")), GroundStep("take", ("y", "gp_y")), GroundStep("take", ("a", "gp_a"))]
    outcomes = _refined(problem, model, plan)
    short, _, dropped = _shortcut(problem, model, plan, outcomes, model.init)
    assert short == [plan[0], plan[2]] and dropped == [[plan[1]]]
    assert len(blocked) == 1


def test_shortcut_is_optional(host):
    result, _ = run(lambda *a: None, host=host)
    assert result.counts["plan_length_before_shortcut"] == result.counts["plan_length"] == 1
    result, _ = run(lambda *a: None, host=host, shortcut=False)
    assert "plan_length" not in result.counts


def test_shortcut_compares_worlds_structurally():
    """Once a redone step leaves the world as it was, shortcutting keeps the rest of the refinement."""
    from dataclasses import dataclass

    import numpy as np
    from interlayer.shortcut import same

    @dataclass(frozen=True)
    class W:
        base: tuple
        objects: dict

    a = W((1.0, 2.0, 0.5), {"o": np.eye(4), "p": ("grasp", np.ones(3))})
    assert same(a, W((1.0, 2.0, 0.5), {"o": np.eye(4), "p": ("grasp", np.ones(3))}))
    assert not same(a, W((1.0, 2.0, 0.6), {"o": np.eye(4), "p": ("grasp", np.ones(3))}))
    assert not same(a, W((1.0, 2.0, 0.5), {"o": np.eye(4)}))
    assert not same(a, W((1.0, 2.0, 0.5), {"o": 2 * np.eye(4), "p": ("grasp", np.ones(3))}))


def test_the_refinement_cache_keys_on_the_candidate_not_its_index(host):
    """A generator with epoch state may order its candidates differently from one call to the next:
    the partial pass must refine the candidate it is given, not reuse the outcome of the candidate
    that had the same index in the error-free pass."""
    from interlayer.refine import EpochState

    class Reordering(EpochState):
        calls = 0

        def __call__(self, problem, step, world, rng):
            self.calls += 1
            for label in ("c0", "c1") if self.calls == 1 else ("c1", "c0"):
                yield Candidate((label,), {}, label)

    def script(item, label, world, n):  # z (untakeable) blocks the candidate c0 only
        return Failure("obstruction", ("z",)) if label == "c0" else None

    result, _ = run(script, gen=Reordering, host=host, max_refine_attempts=1, time_limit=10.0)
    assert result.status == "solved", result.reason
    partial = [(e["candidate"], e["ok"]) for e in events(result, "attempt") if e["mode"] == "partial"]
    assert partial and partial[0] == ("c1", True)


def test_a_refinement_completed_in_the_partial_pass_is_taken(host):
    """The partial pass may be offered candidates the error-free pass was not (epoch state changed in
    between); when they refine every step, that is a solution: no replan, no reset."""
    from interlayer.refine import EpochState

    class Reordering(EpochState):
        calls = 0

        def __call__(self, problem, step, world, rng):
            self.calls += 1
            yield Candidate(("c0",), {}, "c0") if self.calls == 1 else Candidate(("c1",), {}, "c1")

    def script(item, label, world, n):
        return Failure("obstruction", ("z",)) if label == "c0" else None

    result, _ = run(script, gen=Reordering, host=host, time_limit=10.0)
    assert result.status == "solved", result.reason
    assert result.task_planner_calls == 1 and not events(result, "reset")
    assert [(e["mode"], e["candidate"], e["ok"]) for e in events(result, "attempt")] == [
        ("error-free", "c0", False), ("partial", "c1", True)]


class MovingGeometry(ScriptedGeometry):
    """World = the items taken, and taking an item is what moves it."""

    def moved(self, before, after):
        return set(before ^ after)


def first_pass(result):
    """(step, ok) of the attempts of the first error-free TryRefine call."""
    out = []
    for e in result.trace.events:
        if e["type"] == "refine" and e["mode"] == "partial":
            return out
        if e["type"] == "attempt":
            out.append((e["step"], e["ok"]))
    return out


@pytest.mark.parametrize("blocker, backtracks", [("z", False), ("taken", True)])
def test_error_free_refinement_backtracks_only_into_steps_that_moved_a_blocker(host, blocker, backtracks):
    """The second item taken is always obstructed: by z, which no step moves (re-taking the first item
    another way cannot help: the pass ends and the partial pass learns), or by the first item, which
    the first step moved (backtrack into it, as Alg. 2 does)."""
    def script(item, label, world, n):
        if len(world) == 1:
            return Failure("obstruction", ("z",) if blocker == "z" else tuple(world))
        return None

    problem = Problem(SPEC, {i: "item" for i in "abz"}, frozenset(("Takeable", t) for t in "ab"), "(and (Done a) (Done b))",
                      MovingGeometry(script), {})
    task = host["task_planners"].get("fast-downward").factory({})
    translators = [("templates", host["failure_translators"].get("templates").factory)]
    layer = InterfaceLayer(abstract(problem), task, None, {"take": generator()}, translators, LoopSettings(time_limit=2.0))
    attempts = first_pass(layer.solve())
    assert attempts[:3] == [(0, True), (1, False), (1, False)]
    assert (attempts[3:4] == [(0, True)]) == backtracks


MOVABLE = DomainSpec(
    name="scripted-shift",
    types={"item": None},
    continuous_types=("pose",),
    predicates={"Done": ("item",), "IsGP": ("pose", "item"), "Obstructs": ("item", "pose", "item")},
    skolems=(Skolem("gp", ("item",), "pose", "IsGP"),),
    geometric=("Obstructs",),
    actions=(
        ActionSpec("take", (("?x", "item"), ("?p", "pose")),
                   "(and (not (Done ?x)) (IsGP ?p ?x) (forall (?o - item) (not (Obstructs ?o ?p ?x))))",
                   "(Done ?x)", learn={"obstruction": ("(Obstructs ?blocker ?p ?x)",)}, pose_generator="scripted"),
        # moving an object elsewhere undoes what was learned about it (it may come back in the way)
        ActionSpec("shift", (("?x", "item"),), "(not (Done ?x))",
                   "(forall (?o - item ?q - pose) (not (Obstructs ?x ?q ?o)))", pose_generator="scripted"),
    ),
)


def test_a_fact_learned_again_and_again_in_an_epoch_is_not_replanned_on(host):
    """b stands in a's way however often it is shifted: the loop would learn (Obstructs b gp_a a),
    shift b, and learn it again for ever within one epoch. After RELEARN_LIMIT learnings it tries
    the other failures instead, and resets when none teaches anything new."""
    from interlayer.loop import RELEARN_LIMIT

    problem = Problem(MOVABLE, {"a": "item", "b": "item"}, frozenset(), "(Done a)",
                      ScriptedGeometry(lambda item, *a: Failure("obstruction", ("b",)) if item == "a" else None), {})
    task = host["task_planners"].get("fast-downward").factory({})
    translators = [("templates", host["failure_translators"].get("templates").factory)]
    layer = InterfaceLayer(abstract(problem), task, None, {"take": generator(), "shift": generator()}, translators,
                           LoopSettings(time_limit=5.0))
    result = layer.solve()
    assert result.status == "timeout"
    assert events(result, "recurring") and events(result, "reset")
    learned = by_epoch(result, "failure", lambda e: e["facts"])
    counts = [facts.count("(Obstructs b gp_a a)") for facts in learned.values()]
    assert max(counts) == RELEARN_LIMIT and len(counts) >= 2  # the last epoch may end early (time limit)


def test_steps_the_goal_does_not_need_are_dropped_from_a_task_plan(host):
    """Greedy action elimination: a satisficing task planner's detour (taking b, which nothing needs)
    is dropped before refinement; a step the goal needs is kept. The planner here is a stub that
    returns a fixed plan: this test is about what the loop does with a plan."""
    from interlayer.planning import TaskPlanResult
    from interlayer.shortcut import unneeded_steps

    problem = Problem(SPEC, {i: "item" for i in "ab"}, frozenset(("Takeable", t) for t in "ab"), "(Done a)",
                      ScriptedGeometry(lambda *a: None), {})
    model = abstract(problem)
    detour = [GroundStep("take", ("b", "gp_b")), GroundStep("take", ("a", "gp_a"))]
    assert unneeded_steps(detour, model, model.init) == [0]
    assert unneeded_steps(detour[1:], model, model.init) == []

    class Detouring:
        def plan(self, model, state, timeout):
            return TaskPlanResult("solved", detour, 0.0)

        def validate_plan(self, model, state, plan):
            return ""

    layer = InterfaceLayer(model, Detouring(), None, {"take": generator()}, [], LoopSettings(time_limit=5.0))
    result = layer.solve()
    assert result.status == "solved" and [str(s) for s in result.plan] == ["take(a, gp_a)"]
    assert events(result, "task_plan")[0]["unneeded"] == [{"action": "take", "args": ["b", "gp_b"]}]
    assert result.counts["refinement_attempts"] == 1


CHOICE = DomainSpec(
    name="scripted-choice",
    types={"item": None},
    continuous_types=("pose",),
    predicates={"Done": ("item",), "Takeable": ("item",), "IsGP": ("pose", "item"), "NoCandidate": ("pose",)},
    skolems=(Skolem("gp", ("item",), "pose", "IsGP"),),
    geometric=("NoCandidate",),
    actions=(
        ActionSpec("take", (("?x", "item"), ("?p", "pose")),
                   "(and (Takeable ?x) (not (Done ?x)) (IsGP ?p ?x) (not (NoCandidate ?p)))", "(Done ?x)",
                   learn={NO_CANDIDATES: ("(NoCandidate ?p)",)}, pose_generator="scripted"),
        ActionSpec("ready", (("?x", "item"),), "(not (Takeable ?x))", "(Takeable ?x)", pose_generator="scripted"),
    ),
)


def test_an_empty_generator_teaches_a_fact_and_a_goal_with_a_choice_moves_on(host):
    """Hold a or b: the shortest plan takes a, whose generator yields nothing; the fact the action learns
    for that (NoCandidate gp_a) sends the task planner to b. Without it the run gave up.
    Mutation: the partial pass no longer yields the no_candidates failure (refine.py)."""
    def gen(problem, step, world, rng):
        if step.args[0] != "a":
            yield Candidate(("c0",), {}, f"c0-{rng.integers(1000)}")

    problem = Problem(CHOICE, {"a": "item", "b": "item"}, frozenset({("Takeable", "a")}), "(or (Done a) (Done b))",
                      ScriptedGeometry(lambda *a: None), {})
    model = abstract(problem)
    task = host["task_planners"].get("fast-downward").factory({})
    translators = [("templates", host["failure_translators"].get("templates").factory)]
    layer = InterfaceLayer(model, task, None, {"take": gen, "ready": gen}, translators, LoopSettings(time_limit=30.0))
    result = layer.solve()
    assert [str(s) for s in result.plan] == ["ready(b)", "take(b, gp_b)"], result.reason
    assert ("NoCandidate", "gp_a") in result.learned_facts
    [failure] = events(result, "failure")
    assert failure["failure"]["kind"] == NO_CANDIDATES and failure["action"] == "take(a, gp_a)"


def test_a_task_planner_without_a_proof_ends_the_run_gave_up(host):
    """An incomplete search that finds no plan for the initial state proves nothing: 'gave_up' with its
    reason, never 'unsolvable'. Mutation: loop.py's 'incomplete' branch removed (then: unsolvable)."""
    from interlayer.planning import TaskPlanner

    class Incomplete(TaskPlanner):
        def _plan(self, model, state, timeout):
            return "incomplete", [], "the search gave up (enforced hill-climbing is incomplete)", None

    problem = Problem(SPEC, {"a": "item"}, frozenset({("Takeable", "a")}), "(Done a)", ScriptedGeometry(lambda *a: None), {})
    layer = InterfaceLayer(abstract(problem), Incomplete(), None, {"take": generator()}, [], LoopSettings(time_limit=30.0))
    result = layer.solve()
    assert result.status == "gave_up"
    assert result.reason == ("the task planner found no plan for the initial state without proving that none exists "
                             "(the search gave up (enforced hill-climbing is incomplete))")


def test_a_generator_that_yields_nothing_counts_against_the_step_budget(host):
    """Step 1's generator yields nothing whatever step 0 did, and step 0 has many candidates that all
    refine: without counting the empty generator as a failure, the error-free pass re-refines step 0
    (successes are free) once per candidate before it gives up; with it, the pass stops once the
    step's budget is spent."""
    def gen(problem, step, world, rng):
        if not world:  # the first item taken (either), then nothing for the second
            yield from (Candidate((k,), {}, f"c{k}") for k in range(30))

    result, _ = run(lambda *a: None, goal="(and (Done a) (Done b))", gen=gen, host=host, max_refine_attempts=3,
                    time_limit=3.0)
    assert result.status != "solved"
    assert first_pass(result) == [(0, True)] * 3


def test_a_lasting_failure_is_kept_across_resets_and_its_proof_ends_the_run_unsolvable(host):
    """A failure marked ``lasting`` (a proof from what never moves: here z, which nothing can take, stands in
    a's way) teaches facts every epoch starts with: after the dead end and its reset the task planner, given
    them, proves the goal unreachable, and the reason is the failure's own sentence. Mutation: new_epoch
    clears the kept facts (the run then cycles until the watch gives up)."""
    result, _ = run(lambda item, label, world, n: Failure("obstruction", ("z",), "z is bolted down in front of a",
                                                          lasting=True), host=host)
    assert result.status == "unsolvable", result.reason
    assert "no plan exists with what no action can change: z is bolted down in front of a" in result.reason
    assert result.counts["resets"] == 1


def test_the_same_dead_end_with_lasting_facts_three_epochs_in_a_row_gives_up_naming_both(host):
    """b is in a's way (a sampled fact, forgotten at each reset); z, which nothing can take, is in b's way
    (lasting). Each epoch learns that b blocks a again and ends in a dead end after an obstruction: after
    three epochs with the same obstructions the run gives up, naming them and the lasting sentence. Mutation: the watch's
    same-dead-end rule removed (the run then cycles until the time limit)."""
    def script(item, label, world, n):
        if item == "b":
            return Failure("obstruction", ("z",), "z is bolted down in front of b", lasting=True)
        return Failure("obstruction", ("b",)) if "b" not in world else None

    result, _ = run(script, host=host, time_limit=60)
    assert result.status == "gave_up", result.reason
    assert "3 epochs in a row, each with new samples, ended in the same dead end" in result.reason
    assert "(Obstructs b gp_a a)" in result.reason and "z is bolted down in front of b" in result.reason
    assert result.counts["resets"] == 3


HAND = DomainSpec(
    name="scripted-hand",
    types={"item": None},
    continuous_types=("pose",),
    predicates={"Done": ("item",), "Free": (), "Held": ("item",), "IsPD": ("pose", "item"),
                "Obstructs": ("item", "pose")},
    skolems=(Skolem("pd", ("item",), "pose", "IsPD"),),
    geometric=("Obstructs",),
    actions=(
        ActionSpec("grab", (("?x", "item"),), "(and (Free) (not (Done ?x)))", "(and (Held ?x) (not (Free)))",
                   pose_generator="scripted"),
        # the put-down moves the item: what was learned about it standing in the way no longer holds; the
        # facts name the blocker and the pose, not the item in hand (they hold wherever it is)
        ActionSpec("put", (("?x", "item"), ("?p", "pose")),
                   "(and (Held ?x) (IsPD ?p ?x) (forall (?o - item) (not (Obstructs ?o ?p))))",
                   "(and (Done ?x) (Free) (not (Held ?x)) (forall (?q - pose) (not (Obstructs ?x ?q))))",
                   learn={"obstruction": ("(Obstructs ?blocker ?p)",)}, pose_generator="scripted"),
    ),
)


class HandGeometry:
    """World = the (item, action) pairs done; an item moves when it is grabbed or put. ``blocked(item, world)``
    -> the items in the way of putting ``item`` down."""

    def __init__(self, blocked):
        self.blocked = blocked

    def initial_world(self):
        return frozenset()

    def snapshot(self, world):
        return sorted(world)

    def refine_step(self, step, world, candidate, motion):
        item = step.args[0]
        blockers = self.blocked(item, world) if step.action == "put" else ()
        if blockers:
            return StepOutcome(False, failure=Failure("obstruction", tuple(blockers)))
        return StepOutcome(True, world | {(item, step.action)}, [])

    def moved(self, before, after):
        return {i for i, _ in before ^ after}


def _hand_run(host, blocked, goal="(Done a)", first=None, until=None, spec=HAND, init=frozenset({("Free",)}), also=None):
    """``first``: the first task plan (a stub gives it; the real planner every later one); ``until``: the
    kind of trace event after which the run is interrupted (its result then); ``also``: a translator run
    after the domain's own."""
    from interlayer.loop import Interrupted
    from interlayer.planning import TaskPlanResult
    from interlayer.trace import Trace

    def stop(event):
        if event["type"] == until:
            raise KeyboardInterrupt

    problem = Problem(spec, {"a": "item", "b": "item"}, init, goal, HandGeometry(blocked), {})
    task = host["task_planners"].get("fast-downward").factory({})
    if first is not None:
        real = task

        class FirstFixed:
            calls = 0

            def plan(self, model, state, timeout):
                self.calls += 1
                return TaskPlanResult("solved", first, 0.0) if self.calls == 1 else real.plan(model, state, timeout)

            def validate_plan(self, model, state, plan):
                return real.validate_plan(model, state, plan)

        task = FirstFixed()
    translators = [("templates", host["failure_translators"].get("templates").factory)] + ([("also", also)] if also else [])
    gens = {"grab": generator(), "put": generator()}
    layer = InterfaceLayer(abstract(problem), task, None, gens, translators, LoopSettings(time_limit=30.0),
                           trace=Trace([stop]))
    try:
        return layer.solve()
    except Interrupted as stopped:
        return stopped.result


def test_a_dead_end_with_an_item_in_hand_plans_again_from_before_it_was_grabbed(host):
    """b stands where a goes down. Learned with a in the (only) hand, that is a dead end: b cannot be
    moved while a is held. The facts name b, which grabbing a did not move, so they hold before that
    step too: the loop plans again from there (grab b and put it away first) instead of resetting.
    Mutation: ``_replan_earlier`` returning no plan (Alg. 1 as written: dead ends, resets, timeout)."""
    def blocked(item, world):
        return ("b",) if item == "a" and ("b", "put") not in world else ()

    result = _hand_run(host, blocked)
    assert result.status == "solved", result.reason
    assert [str(s) for s in result.plan] == ["grab(b)", "put(b, pd_b)", "grab(a)", "put(a, pd_a)"]
    assert not events(result, "reset") and not events(result, "dead_end")
    earlier = events(result, "earlier")
    assert [(e["step"], e["from_step"], e["action"]) for e in earlier] == [(1, 0, "grab(a)")]
    replan = events(result, "replan")[0]
    assert replan["fail_step"] == 1 and replan["from_step"] == 0 and replan["prefix"] == []


def test_a_dead_end_whose_facts_delete_an_atom_plans_again_from_before_it_too(host):
    """As above, and a translator also learns an atom false (``logic.negated``, as the plugin API allows):
    the objects the facts name are read off the deleted atom too, and the loop plans again from before
    grab(a). Mutation: ``_atom`` returning a negated fact's ``Pred`` as it stands (the run then raises
    "'Pred' object is not subscriptable")."""
    import dataclasses

    from interlayer import logic

    def blocked(item, world):
        return ("b",) if item == "a" and ("b", "put") not in world else ()

    spec = dataclasses.replace(HAND, predicates={**HAND.predicates, "Lit": ("item",)})
    result = _hand_run(host, blocked, spec=spec, init=frozenset({("Free",), ("Lit", "b")}),
                       also=lambda failure, step, model: {logic.negated(("Lit", "b"))})
    assert result.status == "solved", result.reason
    assert [str(s) for s in result.plan] == ["grab(b)", "put(b, pd_b)", "grab(a)", "put(a, pd_a)"]
    assert [(e["step"], e["from_step"]) for e in events(result, "earlier")] == [(1, 0)]
    assert "(not (Lit b))" in events(result, "failure")[0]["facts"]


def test_a_dead_end_does_not_plan_from_before_a_step_that_moved_what_the_facts_name(host):
    """b was put down where it blocks a (the first plan: grab b, put b, grab a, put a, and b can never
    be grabbed again): the fact about b holds only since b's put-down, so the loop plans again from
    before grab(a), and never from before b moved (there the fact would be false).
    Mutation: the ``changed & named`` stop removed (it then plans from before put(b) too)."""
    def blocked(item, world):
        return ("b",) if item == "a" and ("b", "put") in world else ()

    first = [GroundStep("grab", ("b",)), GroundStep("put", ("b", "pd_b")), GroundStep("grab", ("a",)),
             GroundStep("put", ("a", "pd_a"))]
    result = _hand_run(host, blocked, goal="(and (Done a) (Done b))", first=first, until="dead_end")
    assert result.status == "interrupted"
    earlier = events(result, "earlier")
    assert earlier and {(e["step"], e["from_step"]) for e in earlier} == {(3, 2)}


def test_a_dead_end_met_again_is_not_proved_again(host, capsys):
    """z (untakeable) blocks a in the first two epochs: the same state, proved to have no plan in epoch 0,
    comes back after the reset; its answer is known, no task-planner call, and the log says which call
    proved it. Mutations: ``call_task_planner`` without the ``dead_ends.known`` lookup (a second proof, no
    known_dead_end event); the cli's ``known_dead_end`` line removed."""
    from interlayer.cli import progress_printer

    def script(item, label, world, n):
        return Failure("obstruction", ("z",)) if n <= 4 else None

    result, _ = run(script, host=host, max_traj_count=1)
    assert result.status == "solved" and len(events(result, "reset")) == 2
    proofs = [e["call"] for e in events(result, "task_plan") if e["status"] == "unsolvable"]
    assert proofs == [2] and result.task_planner_calls == 2
    assert [(e["from_step"], e["proved_by"]) for e in events(result, "known_dead_end")] == [(0, 2)]
    assert result.counts["known_dead_ends"] == 1
    capsys.readouterr()
    show = progress_printer(False)
    for e in events(result, "known_dead_end"):
        show(e)
    assert "the state from step 0 has no plan: task-planner call #2 proved it" in capsys.readouterr().err


def test_a_state_with_more_obstructions_than_a_dead_end_is_one(host):
    """Epoch 0 proves that a state where z blocks a has no plan; in epoch 1 z and b block a: more atoms of
    Obstructs, which occurs only negated in preconditions, so the bigger state has no plan either, without
    a call. Mutation: ``DeadEnds.known`` matching equal states only (then a second proof is made)."""
    def script(item, label, world, n):
        if n <= 2:
            return Failure("obstruction", ("z",))
        return Failure("obstruction", ("z", "b")) if n <= 4 else None

    result, _ = run(script, host=host, max_traj_count=1)
    assert result.status == "solved"
    facts = by_epoch(result, "failure", lambda e: e["facts"])
    assert facts[1] == ["(Obstructs b gp_a a)", "(Obstructs z gp_a a)"]
    assert [e["call"] for e in events(result, "task_plan") if e["status"] == "unsolvable"] == [2]
    assert [e["proved_by"] for e in events(result, "known_dead_end")] == [2]


def test_only_atoms_that_can_only_forbid_actions_extend_a_known_dead_end():
    """Obstructs occurs only negated; Takeable and IsGP only positively, Done both ways (precondition and
    goal). Mutation: ``forbidding_predicates`` returning every predicate (a takeable z would then be
    called a dead end)."""
    from interlayer.deadends import DeadEnds

    problem = Problem(SPEC, {"a": "item", "z": "item"}, frozenset({("Takeable", "a")}), "(Done a)",
                      ScriptedGeometry(lambda *a: None), {})
    model = abstract(problem)
    dead = DeadEnds(model)
    assert dead.forbidding == {"Obstructs"}
    proved = model.init | {("Obstructs", "z", "gp_a", "a")}
    dead.add(proved, 7)
    assert dead.known(proved) == 7 and dead.known(proved | {("Obstructs", "a", "gp_z", "z")}) == 7
    assert dead.known(proved | {("Takeable", "z")}) is None  # z could now be taken out of the way
    assert dead.known(model.init) is None  # fewer obstructions: no proof


def test_an_effect_condition_that_reads_a_predicate_positively_makes_it_no_forbidding_one():
    """An action that adds something when an obstruction holds can use it: Obstructs is then no longer
    one that only forbids. Mutation: ``forbidding_predicates`` without the effects' conditions."""
    import dataclasses

    from interlayer.deadends import forbidding_predicates

    take = dataclasses.replace(SPEC.actions[0], effect="(and (Done ?x) (forall (?o - item) (when (Obstructs ?o ?p ?x) (Takeable ?o))))")
    spec = dataclasses.replace(SPEC, actions=(take,))
    problem = Problem(spec, {"a": "item", "z": "item"}, frozenset({("Takeable", "a")}), "(Done a)",
                      ScriptedGeometry(lambda *a: None), {})
    assert forbidding_predicates(abstract(problem)) == set()
