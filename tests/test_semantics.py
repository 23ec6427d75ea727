"""The core's semantics (issue 22, item 9): each test here is made to fail by a mutation of the core
that the rest of the suite let through (named in each docstring), or by removing the behaviour it names.

The geometry is the scripted test double of test_loop.py; the task planner is the real Fast Downward.
"""
import json
from dataclasses import replace
from pathlib import Path

import pytest
from test_bench import fault_plugin  # noqa: F401  (the fixture)
from test_loop import SPEC, ScriptedGeometry, by_epoch, events, generator

from interlayer import api
from interlayer.abstraction import abstract
from interlayer.domain import ActionSpec, DomainSpec, GroundStep, Problem, Skolem
from interlayer.errors import DomainError
from interlayer.loop import InterfaceLayer, LoopSettings
from interlayer.refine import ROBOT_MOVED, Candidate, Failure, StepOutcome

ROOT = Path(__file__).resolve().parent.parent


class RecordingGeometry(ScriptedGeometry):
    """Records (item, world) of every refinement; the script may read the loop's epoch."""

    def __init__(self, script):
        super().__init__(script)
        self.seen = []
        self.layer = None

    def refine_step(self, step, world, candidate, motion):
        self.seen.append((step.args[0], world))
        return super().refine_step(step, world, candidate, motion)


def layer_for(host, script, goal="(Done a)", items=("a", "b", "z"), takeable=("a", "b"), gen=None, task=None,
              **settings):
    geometry = RecordingGeometry(script)
    problem = Problem(SPEC, {i: "item" for i in items}, frozenset(("Takeable", t) for t in takeable), goal, geometry, {})
    task = task or host["task_planners"].get("fast-downward").factory({})
    translators = [("templates", host["failure_translators"].get("templates").factory)]
    layer = InterfaceLayer(abstract(problem), task, None, {"take": gen or generator()}, translators,
                           LoopSettings(**{"time_limit": 10.0, **settings}))
    geometry.layer = layer
    return layer, geometry


def test_a_replan_refines_on_from_the_failing_step_and_its_world(host):
    """Alg. 1, line 13 (pose1 <- pose2; step <- failStep): after a replan at step 1, the error-free
    pass starts at step 1 from the world the prefix left, and the prefix is not refined again.
    Mutation: ``step, prefix, world = 0, {}, world0`` after a replan (refine all over again)."""
    def script(item, label, world, n):  # the second item taken is blocked by y until y is taken
        return Failure("obstruction", ("y",)) if item != "y" and len(world) == 1 and "y" not in world else None

    layer, geometry = layer_for(host, script, goal="(and (Done a) (Done b))", items=("a", "b", "y"),
                                takeable=("a", "b", "y"))
    result = layer.solve()
    assert result.status == "solved", result.reason
    replan = events(result, "replan")[0]
    assert replan["fail_step"] == 1 and len(replan["prefix"]) == 1
    first = replan["prefix"][0]["args"][0]  # the item the kept prefix took
    after = result.trace.events[result.trace.events.index(replan) + 1:]
    refine = next(e for e in after if e["type"] == "refine")
    assert refine["mode"] == "error-free" and refine["from_step"] == 1
    attempts = [e for e in after if e["type"] == "attempt"]
    assert attempts and all(e["step"] >= 1 for e in attempts)
    # the first refinement after the replan (take y) starts from the world where the prefix ended
    calls_before = sum(1 for e in result.trace.events[: result.trace.events.index(replan)]
                       if e["type"] == "attempt" and not e["cached"])
    assert geometry.seen[calls_before] == ("y", frozenset({first}))


def test_a_reset_takes_the_learned_facts_out_of_the_symbolic_state(host):
    """Alg. 1, line 15: facts learned and replanned on in one epoch are not in the state the next
    epoch replans from. Epoch 0 learns (Obstructs b gp_a a) and replans [take b, take a]; take b then
    fails on z (a dead end) and MaxTrajCount resets. Epoch 1 fails take b on y: replanning from the
    initial state without the old fact needs only take a.
    Mutation: keep ``states`` at a reset (drop ``states = self.progress_all(init, self.plan)``)."""
    def script(item, label, world, n):
        if item == "a" and "b" not in world:
            return Failure("obstruction", ("b",))
        if item == "b":
            if geometry.layer.epoch == 0:
                return Failure("obstruction", ("z",))
            if "y" not in world:
                return Failure("obstruction", ("y",))
        return None

    layer, geometry = layer_for(host, script, items=("a", "b", "y", "z"), takeable=("a", "b", "y"), max_traj_count=1)
    result = layer.solve()
    assert result.status == "solved", result.reason
    resets = events(result, "reset")
    assert resets and resets[0]["epoch"] == 1
    replans = by_epoch(result, "replan", lambda e: [e])
    assert replans[1][0]["new_plan"] == [{"action": "take", "args": ["a", "gp_a"]}]
    # and the old fact is learned again in the new epoch, as a fact the state did not hold
    learned = by_epoch(result, "failure", lambda e: e["facts"])
    assert "(Obstructs b gp_a a)" in learned[0] and "(Obstructs b gp_a a)" in learned[1]


@pytest.mark.parametrize("max_traj_count", [1, 3])
def test_max_traj_count_bounds_the_refinements_tried_for_one_plan(host, max_traj_count):
    """Alg. 1, line 14: the reset comes after exactly MaxTrajCount partial refinements that led to a
    dead end, not before, and not only once the partial pass runs out (six are on offer here).
    Mutations: ``traj_count > max_traj_count``, ``>= max_traj_count - 1``, the check removed."""
    labels = [f"c{k}" for k in range(6)]

    def script(item, label, world, n):  # in epoch 0 candidate ck is blocked by zk, which nothing can take
        return Failure("obstruction", (f"z{label[1]}",)) if geometry.layer.epoch == 0 else None

    items = ("a", *(f"z{k}" for k in range(6)))
    layer, geometry = layer_for(host, script, items=items, takeable=("a",), gen=generator(labels),
                                max_traj_count=max_traj_count)
    result = layer.solve()
    assert result.status == "solved", result.reason
    resets = events(result, "reset")
    assert len(resets) == 1 and resets[0]["reason"] == "MaxTrajCount reached"
    assert resets[0]["traj_count"] == max_traj_count
    assert len(by_epoch(result, "dead_end", lambda e: [e])[0]) == max_traj_count


def test_a_plan_that_fails_the_final_validation_is_not_reported_solved(host):
    """Alg. 1, line 6 with a check: the task plan returned is validated before the run says solved.
    A task planner that returns a plan whose precondition fails (a is not takeable) in a world where
    every refinement succeeds: the real Fast Downward adapter's validator must refuse it.
    Mutation: the validation in ``InterfaceLayer._solved`` removed."""
    from interlayer.planning import TaskPlanResult

    real = host["task_planners"].get("fast-downward").factory({})

    class Wrong:
        def plan(self, model, state, timeout):
            return TaskPlanResult("solved", (GroundStep("take", ("a", "gp_a")),), 0.0)

        def validate_plan(self, model, state, plan):
            return real.validate_plan(model, state, plan)

    layer, _ = layer_for(host, lambda *a: None, takeable=("b",), task=Wrong())
    with pytest.raises(RuntimeError, match="the final task plan failed validation: .*take"):
        layer.solve()


def test_validate_replays_the_task_plan_itself(tmp_path):
    """``interlayer validate`` replays the plan with the core's semantics, whatever the task planner's
    library says: a plan whose first pick was dropped is refused with the core's own sentence.
    Mutation: the ``check_plan`` replay in ``api.validation`` removed."""
    result = api.solve(str(ROOT / "examples" / "gripper2d.toml"))
    assert result.status == "solved"
    api.write_outputs(result, tmp_path)
    assert api.validation(tmp_path).violations == []
    data = json.loads((tmp_path / "result.json").read_text())
    data["plan"] = data["plan"][1:]
    (tmp_path / "result.json").write_text(json.dumps(data))
    violations = api.validation(tmp_path).violations
    assert any(v.startswith("task plan: step 0 ") and v.endswith("is not applicable") for v in violations), violations


def test_a_run_that_gave_up_is_not_called_unsolvable(fault_plugin, capsys):
    """The watchdog's stop (a pose generator that yields nothing) proves nothing: the run ends
    'gave_up', exit 1, in --json, the explain page, the bench database and its report.
    Mutation: ``NoProgress`` mapped to "unsolvable" in ``InterfaceLayer.solve`` again."""
    from test_bench import suite_file

    from interlayer.bench.report import write_report
    from interlayer.bench.runner import run_suite
    from interlayer.bench.suite import load_suite
    from interlayer.cli import main

    tmp = fault_plugin
    example = str(ROOT / "examples" / "gripper2d.toml")
    empty = "pose_generators.pick=test-empty:pick"
    code = main(["plan", example, "--set", empty, "--json", "--out", str(tmp / "run")])
    out, err = capsys.readouterr()
    data = json.loads(out)
    assert code == 1 and data["status"] == "gave_up", err
    assert "yielded no candidates" in data["reason"]
    assert main(["plan", example, "--set", empty, "-q"]) == 1
    assert "Not solved (gave_up: gave up without a proof that no plan exists): no progress" in capsys.readouterr().err
    assert main(["explain", str(tmp / "run"), "-o", str(tmp / "explain.html")]) == 0
    assert '">gave_up</span>' in (tmp / "explain.html").read_text()
    suite = load_suite(str(suite_file(tmp, "empty", [("empty", example, [empty])], seeds="0", time_limit=30)))
    summary = run_suite(suite, tmp / "r.sqlite", jobs=1, progress=False)
    assert summary["statuses"] == {"gave_up": 1}
    [report] = [p for p in write_report(tmp / "r.sqlite", tmp / "report") if p.suffix == ".md"]
    assert "1 gave_up" in report.read_text()


REACH = DomainSpec(
    name="scripted-reach",
    types={"item": None},
    continuous_types=("pose",),
    predicates={"Done": ("item",), "Near": ("item",), "IsGP": ("pose", "item"), "Reachable": ("pose",)},
    skolems=(Skolem("gp", ("item",), "pose", "IsGP"),),
    geometric=("Reachable",),  # occurs only positively: true by default (Prop. 1)
    actions=(
        ActionSpec("take", (("?x", "item"), ("?p", "pose")), "(and (not (Done ?x)) (IsGP ?p ?x) (Reachable ?p))",
                   "(Done ?x)", learn={"unreachable": ("(not (Reachable ?p))",)}, pose_generator="scripted"),
        # the long way round (two steps), without the reach
        ActionSpec("walk", (("?x", "item"),), "(not (Near ?x))", "(Near ?x)", pose_generator="scripted"),
        ActionSpec("fetch", (("?x", "item"), ("?p", "pose")), "(and (not (Done ?x)) (Near ?x) (IsGP ?p ?x))",
                   "(Done ?x)", pose_generator="scripted"),
    ),
)


def test_a_default_true_fact_learned_false_is_deleted_from_the_state(host, tmp_path):
    """A learn template may be negated: take(a) fails as unreachable, the translator returns
    (not (Reachable gp_a)), the loop deletes it from the state at the failing step, and the task
    planner turns to the longer walk and fetch. The trace, result and explain page show the deletion.
    Mutations: the deletion not applied (``state = states[f] | true``); a negated template ignored; the
    translators' contract refusing negated atoms."""
    from interlayer import logic
    from interlayer.cli import main

    def script(item, label, world, n):
        return Failure("unreachable") if label.startswith("take") else None

    def gen(problem, step, world, rng):
        yield Candidate((step.action,), {}, f"{step.action}-{rng.integers(1000)}")

    problem = Problem(REACH, {"a": "item"}, frozenset(), "(Done a)", ScriptedGeometry(script), {})
    task = host["task_planners"].get("fast-downward").factory({})
    translators = api.translators_for(host, {"planner": {"translators": ["templates"]}})  # with the hook's contract
    layer = InterfaceLayer(abstract(problem), task, None, {"take": gen, "walk": gen, "fetch": gen}, translators,
                           LoopSettings(time_limit=10.0))
    result = layer.solve()
    assert result.status == "solved", result.reason
    assert [str(s) for s in result.plan] == ["walk(a)", "fetch(a, gp_a)"]
    assert events(result, "task_plan")[0]["plan"] == [{"action": "take", "args": ["a", "gp_a"]}]
    assert result.learned_facts == [logic.negated(("Reachable", "gp_a"))]
    assert result.to_json()["learned_facts"] == ["(not (Reachable gp_a))"]
    assert ("Reachable", "gp_a") in layer.model.init and ("Reachable", "gp_a") not in layer.with_learned(layer.model.init)
    [failure] = events(result, "failure")
    assert failure["facts"] == ["(not (Reachable gp_a))"]
    out = api.write_outputs(result, tmp_path / "run")
    assert main(["explain", str(out), "-o", str(tmp_path / "explain.html")]) == 0
    assert "(not (Reachable gp_a))" in (tmp_path / "explain.html").read_text()


def test_a_learn_template_must_be_one_literal():
    bad = ActionSpec("take", (("?x", "item"), ("?p", "pose")), "(and (IsGP ?p ?x) (Reachable ?p))", "(Done ?x)",
                     learn={"unreachable": ("(and (not (Reachable ?p)) (Done ?x))",)})
    spec = replace(REACH, actions=(bad,))
    with pytest.raises(DomainError, match="is not one fact or its negation"):
        abstract(Problem(spec, {"a": "item"}, frozenset(), "(Done a)", ScriptedGeometry(None), {}))


class RobotGeometry(ScriptedGeometry):
    """World = (items taken, where the robot stands): taking an item with candidate cK leaves the
    robot at K. The second item can be taken only from where taking the first with c1 left the
    robot (z, which no step moves, is in the way from anywhere else)."""

    def initial_world(self):
        return frozenset(), None

    def snapshot(self, world):
        return [sorted(world[0]), world[1]]

    def refine_step(self, step, world, candidate, motion):
        taken, at = world
        self.seen.append((len(taken), candidate.label[:2], at))
        if len(taken) == 1 and at != "c1":
            return StepOutcome(False, failure=Failure("obstruction", ("z",)))
        return StepOutcome(True, (taken | {step.args[0]}, candidate.label[:2]), [])

    def moved(self, before, after):
        return set(before[0] ^ after[0]) | ({ROBOT_MOVED} if before[1] != after[1] else set())


def test_backjumping_counts_the_robots_own_moves(host):
    """Every candidate of the second step fails on z, which no step moved; but the first step moved
    the robot, and from where its other candidate leaves it the second succeeds: the error-free pass
    must backtrack into the first step (Alg. 2) rather than end and learn an obstruction the task
    planner cannot undo.
    Mutation: ``ROBOT_MOVED`` ignored in ``Refiner._futile`` (today's main: only objects count)."""
    geometry = RobotGeometry(None)
    geometry.seen = []
    problem = Problem(SPEC, {i: "item" for i in "abz"}, frozenset(("Takeable", t) for t in "ab"), "(and (Done a) (Done b))",
                      geometry, {})
    task = host["task_planners"].get("fast-downward").factory({})
    translators = [("templates", host["failure_translators"].get("templates").factory)]
    result = InterfaceLayer(abstract(problem), task, None, {"take": generator()}, translators,
                            LoopSettings(time_limit=10.0)).solve()
    assert result.status == "solved", result.reason
    assert not events(result, "failure") and result.task_planner_calls == 1
    assert geometry.seen == [(0, "c0", None), (1, "c0", "c0"), (1, "c1", "c0"), (0, "c1", None), (1, "c0", "c1")]


class JumpGeometry:
    """World = (the (item, candidate) pairs taken, where the robot stands): every take moves the robot. ``script(item, label, world)`` -> Failure or None."""

    def __init__(self, script, pose=None):
        self.script, self.seen = script, []
        self.pose = pose or (lambda item, label: label)  # where a take leaves the item

    def initial_world(self):
        return frozenset(), None

    def snapshot(self, world):
        return sorted(world[0])

    def refine_step(self, step, world, candidate, motion):
        item, label = step.args[0], candidate.label
        self.seen.append((item, label))
        failure = self.script(item, label, world[0])
        if failure:
            return StepOutcome(False, failure=failure)
        return StepOutcome(True, (world[0] | {(item, self.pose(item, label))}, (item, label)), [])

    def moved(self, before, after):
        return {i for i, _ in before[0] ^ after[0]} | ({ROBOT_MOVED} if before[1] != after[1] else set())


def _refine(script, items="abc", pose=None):
    """TryRefine's error-free pass over [take a, take b, take c] (candidates c0, c1 each): its result, the
    attempts (item, candidate) in order and the backjumps it reported."""
    from interlayer.loop import _drain
    from interlayer.refine import PoseGenerator, Refiner

    geometry, jumps = JumpGeometry(script, pose), []

    def make_generator(i, step, world):
        return PoseGenerator(lambda rng: (Candidate((k,), {}, k) for k in ("c0", "c1")), [i])

    plan = [GroundStep("take", (x, f"gp_{x}")) for x in items]
    refiner = Refiner(geometry, None, make_generator, 8, lambda: False, on_backjump=lambda **kw: jumps.append(kw))
    done = _drain(refiner.try_refine(plan, 0, geometry.initial_world(), {}, partial=False))
    return done, geometry.seen, jumps


def test_a_start_free_obstruction_passes_over_steps_that_only_moved_the_robot():
    """Every candidate of take c fails on z whatever the robot's start (``Failure.start_free``); take a and
    take b moved the robot and their own items, never z: their other candidates cannot help, so the
    error-free pass ends at once (the partial pass learns the obstruction) instead of refining them again.
    Mutation: ``start_free`` ignored in ``Refiner._culprit`` (every step that moved the robot is a culprit)."""
    done, seen, jumps = _refine(lambda item, label, world: Failure("obstruction", ("z",), start_free=True)
                                if item == "c" else None)
    assert done is None
    assert seen == [("a", "c0"), ("b", "c0"), ("c", "c0"), ("c", "c1")]
    assert jumps == [{"step": 2, "to": None, "objects": ["z"], "start_free": True, "skipped": [0, 1]}]
    # the same obstruction from a motion that starts where the robot stands: take b's other candidate first
    _, seen, _ = _refine(lambda item, label, world: Failure("obstruction", ("z",)) if item == "c" else None)
    assert seen[4:6] == [("b", "c1"), ("c", "c0")]


def test_backjumping_goes_back_to_the_step_that_moved_the_blocker():
    """take c fails on a (start-free) while a was taken with c0: conflict-directed backjumping goes from
    take c straight back to take a (which moved a), passing over take b's other candidate, and the
    search goes on from there (Alg. 2 with the failure's culprits).
    Mutation: ``back = i - 1`` always in ``Refiner.try_refine`` (chronological backtracking)."""
    done, seen, jumps = _refine(lambda item, label, world: Failure("obstruction", ("a",), start_free=True)
                                if item == "c" and ("a", "c0") in world else None)
    assert done is not None and [done.outcomes[i].candidate.label for i in range(3)] == ["c1", "c0", "c0"]
    assert seen == [("a", "c0"), ("b", "c0"), ("c", "c0"), ("c", "c1"), ("a", "c1"), ("b", "c0"), ("c", "c0")]
    assert jumps == [{"step": 2, "to": 0, "objects": ["a"], "start_free": True, "skipped": [1]}]


def test_a_step_jumped_back_to_inherits_the_failures_that_sent_the_search_there():
    """take c fails on a and b (start-free) while both were taken with c0: the search goes back to take b
    (it moved b), whose other candidate fails on z, which nothing moved. take b's own failures then say
    nothing before it can help, but the ones it inherited from take c name a, which take a moved: the
    search goes back to take a, and take a's other candidate solves.
    Mutation: no ``blockers[back] = _merged(...)`` (a step forgets the failures it was sent back for)."""
    def script(item, label, world):
        if item == "c" and {("a", "c0"), ("b", "c0")} <= world:
            return Failure("obstruction", ("a", "b"), start_free=True)
        if item == "b" and label == "c1":
            return Failure("obstruction", ("z",), start_free=True)
        return None

    done, seen, _ = _refine(script)
    assert done is not None and [done.outcomes[i].candidate.label for i in range(3)] == ["c1", "c0", "c0"]
    assert seen == [("a", "c0"), ("b", "c0"), ("c", "c0"), ("c", "c1"), ("b", "c1"), ("a", "c1"), ("b", "c0"), ("c", "c0")]


def test_a_success_that_leaves_the_blockers_where_they_were_is_known_to_fail():
    """take a puts a at the same place whatever its candidate (a goal pose); take c fails on a there,
    start-free. Backjumping goes back to take a; its other candidate succeeds but leaves a where take c
    failed on it, so take b and take c are not refined again for it (a nogood): the pass ends.
    Mutation: ``_known_failure`` returns None (no nogoods)."""
    done, seen, jumps = _refine(lambda item, label, world: Failure("obstruction", ("a",), start_free=True)
                                if item == "c" else None, pose=lambda item, label: "goal" if item == "a" else label)
    assert done is None
    assert seen == [("a", "c0"), ("b", "c0"), ("c", "c0"), ("c", "c1"), ("a", "c1")]
    assert jumps[1] == {"step": 2, "to": 0, "objects": ["a"], "start_free": True, "skipped": [1], "known": 0}


def test_a_nogood_met_again_ends_the_pass():
    """take a puts a at the same place whatever its candidate; take c fails on a there, start-free; take
    a's other candidate fails on q from where the robot stood, so the search goes back over take x, then
    take w. Each time take a's first candidate leaves a where take c failed on it; the second time in
    this pass ends it (the partial pass learns the obstruction) rather than refine on to the budget's end.
    Mutation: ``KNOWN_LIMIT`` = 3."""
    def script(item, label, world):
        if item == "c":
            return Failure("obstruction", ("a",), start_free=True)
        return Failure("obstruction", ("q",)) if item == "a" and label == "c1" else None

    done, seen, jumps = _refine(script, items="wxabc", pose=lambda item, label: "goal" if item == "a" else label)
    assert done is None
    assert seen == [("w", "c0"), ("x", "c0"), ("a", "c0"), ("b", "c0"), ("c", "c0"), ("c", "c1"), ("a", "c1"),
                    ("x", "c1"), ("a", "c0"), ("a", "c1"), ("w", "c1"), ("x", "c0"), ("a", "c0")]
    assert jumps[-1] == {"step": 4, "to": None, "objects": ["a"], "start_free": True, "skipped": [3], "known": 2}
