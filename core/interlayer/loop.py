"""Alg. 1: the interface layer's outer loop of refinement, failure translation and replanning."""
from __future__ import annotations

import time
from collections import Counter
from dataclasses import dataclass

from . import deadline as deadlines, logic
from .abstraction import TaskModel
from .domain import GroundStep
from .names import relabel
from .deadline import Deadline, DeadlineExceeded
from .deadends import DeadEnds
from .refine import NO_CANDIDATES, ROBOT_MOVED, EpochState, GiveUp, Infeasible, PoseGenerator, Refinement, Refiner, drawn_within, stable_seed
from .result import Result
from .trace import Stats, Trace
from .watchdog import NoProgress, ProgressWatch


class Interrupted(KeyboardInterrupt):
    """Ctrl-C during a run; ``result`` holds what was done so far (status "interrupted")."""

    def __init__(self, result):
        super().__init__("interrupted")
        self.result = result


# A fact learned this many times in one epoch is not learned again in it: the action that deleted it
# (e.g. picking the blocker) keeps bringing it back (putting the blocker down in the way again), and
# replanning on it once more would only repeat that cycle.
RELEARN_LIMIT = 2
# Task-planner calls one dead end may spend on planning from before earlier steps (InterfaceLayer._replan_earlier)
EARLIER_LIMIT = 3


@dataclass(frozen=True)
class LoopSettings:
    time_limit: float = 600.0
    max_traj_count: int = 10
    max_refine_attempts: int = 8  # failed attempts per plan step in one TryRefine call, x (epoch + 1)
    task_timeout: float = 60.0
    seed: int = 0
    shortcut: bool = True  # drop useless steps after a solve (shortcut.py)


def plan_json(plan) -> list:
    return [s.to_json() for s in plan]


class InterfaceLayer:
    """Refines task plans into motion plans, learning geometric facts from failures."""

    def __init__(self, model: TaskModel, task_planner, motion_planner, generators, translators,
                 settings: LoopSettings, trace: Trace | None = None, stats: Stats | None = None, on_stuck=None):
        self.model = model
        self.geometry = model.problem.geometry
        self.task_planner = task_planner
        self.motion = motion_planner
        self.generators = generators  # action name -> factory(problem, step, world, rng)
        self.translators = translators  # list of (name, fn(failure, step, model) -> set of atoms)
        self.settings = settings
        self.trace = trace or Trace()
        self.stats = stats or Stats()
        self.epoch = 0  # bumped by every MaxTrajCount reset: reseeds the pose generators
        self._epoch_states: dict = {}  # EpochState class -> its instance for this epoch
        self.learned: list = []  # facts learned in this epoch (a reset clears them)
        # facts of ``lasting`` failures (proofs from what never moves) and those failures' sentences: every
        # epoch starts with them
        self.kept: list = []
        self.kept_why: list = []
        self.times_learned: Counter = Counter()  # fact -> how often it was learned in this epoch
        self.task_calls = 0
        self.dead_ends = DeadEnds(model)  # states proved to have no plan: never proved twice
        self.replans = 0
        self.watch = ProgressWatch(model)
        self.plan: list = []
        self.on_stuck = on_stuck  # called with the run so far when a plugin call cannot be stopped (supervisor.py)
        self.dropped: list = []  # steps the shortcutting dropped from the refined plan, in order

    # -- pieces -----------------------------------------------------------------------------
    def _time_left(self) -> float:
        return self.deadline.left()

    def _out_of_time(self) -> bool:
        return self.deadline.over()

    def call_task_planner(self, state: frozenset, from_step: int):
        """callClassicalPlanner (Alg. 1, lines 2 and 10), always with a timeout; a state an earlier call
        proved to have no plan (deadends.py) gets that answer without a call."""
        proved = self.dead_ends.known(state)
        if proved is not None:
            self.stats.count("known_dead_ends")
            self.trace.emit("known_dead_end", from_step=from_step, state_size=len(state), proved_by=proved)
            self.last_task_status, self.last_task_reason = "unsolvable", f"task-planner call #{proved} proved it has no plan"
            return None
        self.task_calls += 1
        from .supervisor import grace

        # ends a little before the run's deadline: stopping a planner's process takes time too
        left = max(0.0, self._time_left() - grace(self.settings.time_limit))
        with self.stats.timer("task_planning"):
            res = self.task_planner.plan(self.model, state, min(self.settings.task_timeout, left))
        plan, dropped = list(res.plan), []
        if res.status == "solved":
            from .shortcut import unneeded_steps

            drop = unneeded_steps(plan, self.model, state)
            dropped = [s for k, s in enumerate(plan) if k in drop]
            plan = [s for k, s in enumerate(plan) if k not in drop]
        self.trace.emit("task_plan", call=self.task_calls, from_step=from_step, status=res.status, state_size=len(state),
                        plan=plan_json(plan), time=round(res.time, 4), reason=res.reason,
                        cost=self.model.cost(self.plan[:from_step] + plan) if res.status == "solved" else None,
                        unneeded=plan_json(dropped))
        if res.status == "error":
            raise RuntimeError(res.reason)
        if res.status == "timeout":  # the clock only cuts a run short: a timed-out call is no dead end
            if self.settings.task_timeout < left:
                raise DeadlineExceeded(f"the task planner's call #{self.task_calls} took longer than "
                                       f"planner.task_timeout = {self.settings.task_timeout:g} s")
            raise DeadlineExceeded(where="the task planner")
        self.last_task_status, self.last_task_reason = res.status, res.reason
        if res.status == "unsolvable":
            self.dead_ends.add(state, self.task_calls)
        return plan if res.status == "solved" else None

    def make_generator(self, index: int, step: GroundStep, world) -> PoseGenerator:
        factory = self._generator(step.action)
        problem = self.model.problem

        def candidates(rng):  # drawn one at a time: TryRefine often needs only the first few
            n = 0
            for cand in drawn_within(lambda: factory(problem, step, world, rng),
                                     lambda: self.stats.timer("pose_generation")):
                n += 1
                yield cand
            if not n:
                label = getattr(factory, "labels", {}).get(step.action, f"pose generator of '{step.action}'")
                self.watch.generator_empty(label, index, step)

        args = map(self.model.ordinal, step.args)  # by their place, not their names: a renamed copy draws alike
        return PoseGenerator(candidates, stable_seed(self.settings.seed, self.epoch, index, step.action, *args))

    def _generator(self, action: str):
        """The action's generator function; an ``EpochState`` subclass gets one fresh instance per
        epoch, shared by every action it serves (Alg. 1, line 16: reset with a new random seed)."""
        factory = self.generators[action]
        if not (isinstance(factory, type) and issubclass(factory, EpochState)):
            return factory
        if factory not in self._epoch_states:
            state = factory(stable_seed(self.settings.seed, self.epoch, factory.__qualname__))
            state.ordinal = self.model.ordinal
            self._epoch_states[factory] = state
        return self._epoch_states[factory]

    def new_epoch(self):
        """Alg. 1, lines 15-16: forget the learned facts and reseed the pose generators."""
        self.epoch += 1
        self._epoch_states.clear()
        self.learned = list(self.kept)
        self.times_learned.clear()

    def _keep(self, facts, why: str) -> None:
        """Keep ``facts`` (of a ``lasting`` failure, explained by ``why``) for the rest of the run."""
        self.kept += [a for a in facts if a not in self.kept]
        if why and why not in self.kept_why:
            self.kept_why.append(why)

    def _without_plan(self):
        """The end of a run whose task planner found no plan from the start with the kept facts."""
        known = "; ".join(self.kept_why) or ", ".join(map(logic.literal_str, self.kept))
        if self.last_task_status == "unsolvable":
            return "unsolvable", f"the task planner proved that no plan exists with what no action can change: {known}", None
        return "gave_up", f"the task planner found no plan with what no action can change ({known}) without proving that none exists ({self.last_task_reason})", None

    def translate(self, failure, step: GroundStep) -> tuple[set, set]:
        """The atoms the translators learned true and those they learned false (``logic.negated``)."""
        true, false = set(), set()
        for _, fn in self.translators:
            for fact in fn(failure, step, self.model):
                if isinstance(fact, logic.Not):
                    false.add(logic.ground_atom(fact.arg, {}))
                else:
                    true.add(fact)
        return true, false

    def with_learned(self, state: frozenset) -> frozenset:
        """``state`` with this epoch's learned facts: deletions applied, additions added."""
        gone = {logic.ground_atom(f.arg, {}) for f in self.learned if isinstance(f, logic.Not)}
        return (state - gone) | {f for f in self.learned if not isinstance(f, logic.Not)}

    def progress_all(self, state: frozenset, plan) -> list:
        """Symbolic states before each step of ``plan`` and after the last one."""
        states = [state]
        for s in plan:
            states.append(self.model.progress(states[-1], s))
        return states

    def _replan_earlier(self, partial, facts, true, false, states, world0):
        """A dead end at the failing step (e.g. an object in hand that can be put down nowhere): plan again
        with the same facts from before an earlier step that moved an object, latest first, while no step
        in between moved an object the facts name (they were learned where those stood, and hold there
        too). ``(plan, step, state)``, or ``(None, fail step, None)`` when there is none. Needs the
        geometry's ``moved``; at most EARLIER_LIMIT task-planner calls."""
        f = partial.fail_step
        moved = getattr(self.geometry, "moved", None)
        if moved is None:
            return None, f, None
        named = {a for fact in facts for a in _atom(fact)[1:]}
        calls = 0
        for g in range(f - 1, -1, -1):
            changed = moved(_world_at(partial.outcomes, g, world0), _world_at(partial.outcomes, g + 1, world0))
            if changed & named:
                break  # before this step the facts' objects stood elsewhere
            if not changed - {ROBOT_MOVED}:
                continue  # it only moved the robot: planning from before it changes nothing
            state = (states[g] - false) | true
            self.trace.emit("earlier", step=f, from_step=g, action=str(self.plan[g]))
            plan = self.call_task_planner(state, g)
            if plan is not None:
                return plan, g, state
            calls += 1
            if calls >= EARLIER_LIMIT or self._out_of_time():
                break
        return None, f, None

    def _on_attempt(self, step, candidate, outcome, partial, cached):
        self.stats.count("refinement_attempts")
        self.watch.attempt(step, self.plan[step], candidate, outcome)
        self.trace.emit("attempt", mode="partial" if partial else "error-free", step=step,
                        action=str(self.plan[step]), candidate=candidate.label, ok=outcome.ok, cached=cached,
                        failure=outcome.failure.to_json() if outcome.failure else None)

    def _on_backjump(self, step, to, objects, start_free, skipped, known=None):
        self.stats.count("backjumps" if known is None else "nogoods_met")
        self.trace.emit("backjump", step=step, action=str(self.plan[step]), to=to, objects=objects,
                        start_free=start_free, skipped=skipped, **({"known": known} if known is not None else {}))

    def _shortcut(self, init, world0, outcomes):
        """Drop steps the solved plan does not need (beyond the paper; see shortcut.py)."""
        from .shortcut import shortcut

        def accepted(dropped, shorter):
            self.dropped += dropped
            self.trace.emit("shortcut", dropped=plan_json(dropped), plan=plan_json(shorter))

        before = len(self.plan)
        self.plan, outcomes = shortcut(self.plan, outcomes, self.model, self.with_learned(init), self.geometry,
                                       self.motion, world0, self._cut, accepted, self.stats)
        self.stats.count("plan_length_before_shortcut", before)
        self.stats.count("plan_length", len(self.plan))
        # one summary where the steps are counted: the log, result.json and the explain page print it
        self.trace.emit("shortened", refined=before, dropped=plan_json(self.dropped), plan=plan_json(self.plan))
        return outcomes

    def _solved(self, init, world0, done):
        self.trace.emit("refined", steps=len(self.plan))
        outcomes = [done.outcomes[i] for i in range(len(self.plan))]
        if self.settings.shortcut:
            outcomes = self._shortcut(init, world0, outcomes)
        with self.stats.timer("validation"):  # the plan returned, shortcut or not
            why = self.task_planner.validate_plan(self.model, init, self.plan)
        if why:
            raise RuntimeError(f"the final task plan failed validation: {why}")
        self.deadline.check()  # found after the limit: a loaded machine must not turn a timeout into a solve
        return "solved", "", outcomes

    def _cut(self) -> bool:
        """For work that must not be cut short with a different result (the shortcut): past the
        limit the run ends as a timeout."""
        self.deadline.check()
        return False

    # -- Alg. 1 -----------------------------------------------------------------------------
    def solve(self) -> Result:
        from .supervisor import Supervisor

        self.deadline = Deadline(self.settings.time_limit)
        supervisor = Supervisor(self.deadline, self.on_stuck, self._stuck_result)
        try:
            with deadlines.running(self.deadline):
                supervisor.start()
                try:
                    status, reason, refinement = self._run()
                except Infeasible as exc:  # a domain's own proof that a reference has no instance
                    status, reason, refinement = "unsolvable", str(exc), None
                except (NoProgress, GiveUp) as exc:  # nothing proved: the loop (watchdog, exhausted budget) or a
                    # generator (its own finite search) stopped the run
                    known = f"; what no action can change: {'; '.join(self.kept_why)}" if self.kept_why else ""
                    status, reason, refinement = "gave_up", f"{exc}{known}", None
                except DeadlineExceeded as exc:
                    status, reason, refinement = "timeout", self._timeout_reason(exc, supervisor.stopped), None
        except DeadlineExceeded as exc:  # the supervisor's, delivered while the run was ending
            status, reason, refinement = "timeout", self._timeout_reason(exc, supervisor.stopped), None
        except KeyboardInterrupt:
            status, reason, refinement = "interrupted", "interrupted by the user (Ctrl-C)", None
        finally:
            supervisor.stop()
        result = self._result(status, reason, refinement)
        if status == "interrupted":
            raise Interrupted(result)
        return result

    def _timeout_reason(self, exc: DeadlineExceeded, stopped: str) -> str:
        limit = f"the time limit of {self.settings.time_limit:g} s"
        if stopped:
            return f"{limit} was reached and {stopped} did not return: it was stopped"
        if exc.args and exc.args[0] != deadlines.OVER:
            return f"{exc.args[0]}; the run stops there"
        where = f" inside {exc.where}" if exc.where else ""
        return f"{limit} was reached{where} before a refinement was found"

    def _stuck_result(self, stopped: str) -> Result:
        """The run so far, for a supervisor that cannot stop the call under way (from its thread)."""
        return self._result("timeout", f"the time limit of {self.settings.time_limit:g} s was reached and {stopped} "
                                       f"did not return: the process was ended", None)

    def _result(self, status, reason, refinement) -> Result:
        reason = relabel(reason, getattr(self.model, "labels", None))  # a domain's sentence, in the file's names
        self.stats.times["total"] = time.perf_counter() - self.deadline.start
        accounted = sum(v for k, v in self.stats.times.items() if k not in ("total", "interface"))
        self.stats.times["interface"] = max(0.0, self.stats.times["total"] - accounted)
        self.trace.emit("end", status=status, reason=reason)
        solved = status == "solved"
        return Result(status=status, reason=reason, plan=list(self.plan) if solved else [],
                      plan_cost=self.model.cost(self.plan) if solved else None,
                      learned_facts=list(self.learned), replans=self.replans, task_planner_calls=self.task_calls,
                      times=dict(self.stats.times), counts=dict(self.stats.counts), seed=self.settings.seed,
                      refinement=refinement, trace=self.trace, problem=self.model.problem, model=self.model,
                      shortcut_dropped=list(self.dropped) if solved else [])

    def _run(self):
        init = self.model.init
        self.plan = []
        plan = self.call_task_planner(init, 0)  # line 2
        if plan is None and (self.last_task_status == "timeout" or self._out_of_time()):
            return "timeout", f"the task planner found no plan for the initial state within the time limit of {self.settings.time_limit:g} s", None
        if plan is None and self.last_task_status == "incomplete":  # no plan found, none proved impossible
            return "gave_up", f"the task planner found no plan for the initial state without proving that none exists ({self.last_task_reason})", None
        if plan is None:
            return "unsolvable", "the task planner proved that the initial state has no plan", None
        self.plan, states = plan, self.progress_all(init, plan)
        world0 = self.geometry.initial_world()
        step, prefix, world = 0, {}, world0  # line 3
        refiner = Refiner(self.geometry, self.motion, self.make_generator, self.settings.max_refine_attempts,
                          self._out_of_time, self._on_attempt, self.stats, self._on_backjump)
        while not self._out_of_time():  # line 4
            refiner.clear_cache()
            self.trace.emit("refine", mode="error-free", from_step=step, plan=plan_json(self.plan), epoch=self.epoch)
            done = _drain(refiner.try_refine(self.plan, step, world, prefix, partial=False))  # line 5
            if done is not None:
                return self._solved(init, world0, done)  # line 6
            if self._out_of_time():
                break
            self.trace.emit("refine", mode="partial", from_step=step, plan=plan_json(self.plan), epoch=self.epoch)
            traj_count, new_plan, ends = 0, None, set()  # ends: predicates of the facts after which no plan was found
            for partial in _with_result(refiner.try_refine(self.plan, step, world, prefix, partial=True)):  # lines 7-8
                if isinstance(partial, Refinement):
                    # a generator with epoch state may offer other candidates than in the error-free pass
                    # (e.g. put-downs kept off an approach ranked since): one of them refined every step
                    return self._solved(init, world0, partial)
                f = partial.fail_step
                true, false = self.translate(partial.failure, self.plan[f])
                if not true and not false and partial.failure.kind != NO_CANDIDATES:  # (the watch saw that one)
                    self.watch.untranslated(partial.failure, self.plan[f])
                if partial.failure.lasting:
                    self._keep(sorted(true) + [logic.negated(a) for a in sorted(false)], partial.failure.detail)
                true, false = true - states[f], false & states[f]  # only what changes the state
                facts = sorted(true) + [logic.negated(a) for a in sorted(false)]
                shown = [logic.literal_str(a) for a in facts]
                if not facts:
                    continue  # nothing new to tell the task planner: try the next failure
                if all(self.times_learned[a] >= RELEARN_LIMIT for a in facts):
                    self.trace.emit("recurring", step=f, action=str(self.plan[f]), limit=RELEARN_LIMIT, facts=shown)
                    continue  # learned and undone again and again in this epoch: try the next failure
                traj_count += 1
                state = (states[f] - false) | true  # line 9
                self.learned += [a for a in facts if a not in self.learned]
                self.times_learned.update(facts)
                self.trace.emit("failure", step=f, action=str(self.plan[f]), candidate=partial.candidate.label,
                                failure=partial.failure.to_json(related=True), facts=shown, world=self.geometry.snapshot(partial.world))
                new_plan, g = self.call_task_planner(state, f), f  # line 10
                if new_plan is None and not self._out_of_time():  # beyond the paper: plan from before the steps
                    new_plan, g, state = self._replan_earlier(partial, facts, true, false, states, world0)
                if new_plan is not None:  # lines 11-13
                    self.replans += 1
                    old = self.plan
                    self.plan = old[:g] + new_plan
                    states = states[:g] + self.progress_all(state, new_plan)
                    step, prefix = g, {k: v for k, v in partial.outcomes.items() if k < g}
                    world = partial.world if g == f else _world_at(partial.outcomes, g, world0)
                    self.trace.emit("replan", fail_step=f, prefix=plan_json(old[:g]), new_plan=plan_json(new_plan),
                                    plan=plan_json(self.plan), **({"from_step": g} if g < f else {}))
                    break
                self.trace.emit("dead_end", step=f, facts=shown, status=self.last_task_status)
                ends.update(_predicate(a) for a in facts)
                if traj_count >= self.settings.max_traj_count or self._out_of_time():
                    break
            if new_plan is None and not self._out_of_time():  # lines 14-17
                # the dead end's kind of facts, all those the epoch learned: the same each epoch whatever order
                # the task planner tried them in
                same = {logic.literal_str(a) for a in self.learned if a not in self.kept and _predicate(a) in ends}
                dead_end = traj_count < self.settings.max_traj_count
                self.new_epoch()
                refiner.max_attempts = self.settings.max_refine_attempts * (self.epoch + 1)
                self.trace.emit("reset", epoch=self.epoch, traj_count=traj_count,
                                reason="MaxTrajCount reached" if traj_count >= self.settings.max_traj_count
                                else "no partial refinement led to a solvable state")
                self.stats.count("resets")
                if self.kept:  # the plan may need what is now known impossible: plan again with the kept facts
                    fresh = self.call_task_planner(self.with_learned(init), 0)
                    if fresh is None:
                        return self._without_plan()
                    self.plan = fresh
                states = self.progress_all(self.with_learned(init), self.plan)  # learned facts cleared, kept ones kept
                step, prefix, world = 0, {}, world0
                self.watch.reset(traj_count, self.plan, same if dead_end and self.kept else None)
            self.watch.check_trace(len(self.trace.events))
        return "timeout", f"the time limit of {self.settings.time_limit:g} s was reached before a refinement was found", None


def _atom(literal):
    """The ground atom (a tuple) of a learned fact, also of a ``logic.negated`` one."""
    return logic.ground_atom(literal.arg, {}) if isinstance(literal, logic.Not) else literal


def _world_at(outcomes: dict, k: int, world0):
    """The world before step k of a refined prefix that starts at step 0 in ``world0``."""
    return outcomes[k - 1].world if k else world0


def _predicate(literal) -> str:
    return _atom(literal)[0]


def _with_result(gen):
    """The items of a TryRefine generator, then its return value if that is a Refinement."""
    value = yield from gen
    if isinstance(value, Refinement):
        yield value


def _drain(gen):
    """Run a TryRefine generator in error-free mode to its return value."""
    try:
        while True:
            next(gen)
    except StopIteration as stop:
        return stop.value
