"""The task-planner interface: a planner sees a TaskModel and a symbolic state, returns a plan."""
from __future__ import annotations

import time
from dataclasses import dataclass, field

from .abstraction import TaskModel
from .domain import GroundStep


@dataclass(frozen=True)
class TaskPlanResult:
    # "solved" | "unsolvable" (proved: the state has no plan) | "incomplete" (none found, nothing proved: an
    # incomplete search, out of memory) | "timeout" | "error"
    status: str
    plan: tuple = ()  # GroundSteps over the task planner's view (dropped args restored)
    time: float = 0.0
    reason: str = ""
    cost: float | None = None


@dataclass
class TaskPlanner:
    """Template method (Unified-Planning's solve/_solve): ``plan`` times and checks the call,
    restores dropped arguments and replays the plan symbolically; adapters implement ``_plan``
    returning (status, [(action, task_args), ...], reason, cost)."""

    name: str = "task-planner"
    options: dict = field(default_factory=dict)
    pddl_dir: object = None  # where to write each call's problem as PDDL, if the planner can
    calls: int = 0

    def plan(self, model: TaskModel, state: frozenset, timeout: float) -> TaskPlanResult:
        t0 = time.perf_counter()
        self.calls += 1
        if timeout <= 0:
            return TaskPlanResult("timeout", reason="no time left for the task planner")
        answer = self._plan(model, state, timeout)
        if not (isinstance(answer, tuple) and len(answer) == 4):
            from .contracts import shown
            from .faults import ComponentFailed

            raise ComponentFailed(f"its _plan returned {shown(answer)}, not (status, steps, reason, cost)")
        status, raw, reason, cost = answer
        plan = tuple(model.reintroduce(a, tuple(args)) for a, args in raw)
        if status == "solved":
            problem = check_plan(model, state, plan)
            if problem:
                status, reason = "error", f"the task planner '{self.name}' returned an invalid plan: {problem}"
        return TaskPlanResult(status, plan, time.perf_counter() - t0, reason, cost)

    def _plan(self, model: TaskModel, state: frozenset, timeout: float):  # pragma: no cover
        raise NotImplementedError

    def prepare(self, model: TaskModel) -> None:
        """One-time setup before the run's clock starts (import libraries, translate the domain):
        the time limit then measures planning, not imports."""

    def validate_plan(self, model: TaskModel, state: frozenset, plan) -> str:
        """A second opinion on a final plan ('' if valid); adapters may use their library's validator."""
        return check_plan(model, state, plan)

    def library_check(self, model: TaskModel, state: frozenset, plan) -> str | None:
        """The planner library's own plan validator ('' if valid), independent of the core's replay;
        None when the library has none. ``interlayer validate`` runs it beside the replay."""
        return None


def check_plan(model: TaskModel, state: frozenset, plan) -> str:
    """Replay a plan with the core's own semantics; '' if it reaches the goal, else why not."""
    for i, step in enumerate(plan):
        if not isinstance(step, GroundStep) or step.action not in model.full_actions:
            return f"step {i} is not an action of the domain"
        if not model.applicable(state, step):
            return f"step {i} {step} is not applicable"
        state = model.progress(state, step)
    return "" if model.goal_holds(state) else "the goal does not hold at the end"


@dataclass
class BreadthFirstPlanner(TaskPlanner):
    """The core's own task planner: breadth-first search over the task model's ground actions, with no
    library, so that an install of the core alone solves small domains (docs/plugins.md's tutorial);
    its plans are the shortest. ``max_states`` (expanded states) bounds the work; the time limit only
    cuts it short."""

    name: str = "bfs"

    def _plan(self, model: TaskModel, state: frozenset, timeout: float):
        import itertools

        limit = int(self.options.get("max_states", 100_000))
        deadline = time.monotonic() + timeout
        steps = []  # (action, task args, ground step), in the model's order
        for name, action in model.actions.items():
            for args in itertools.product(*(model.objects_of(t) for _, t in action.parameters)):
                try:
                    steps.append((name, args, model.reintroduce(name, args)))
                except KeyError:  # a dropped parameter without a reference for these arguments
                    continue
        parents = {state: None}
        frontier = [state]
        expanded = 0
        while frontier:
            layer, frontier = frontier, []
            for current in layer:
                if model.goal_holds(current):
                    plan = []
                    while parents[current] is not None:
                        current, step = parents[current]
                        plan.append(step)
                    return "solved", plan[::-1], "", None
                if expanded >= limit:
                    return "incomplete", [], f"breadth-first search expanded max_states = {limit} states", None
                if time.monotonic() > deadline:
                    return "timeout", [], "breadth-first search ran out of time", None
                expanded += 1
                for name, args, step in steps:
                    if model.applicable(current, step):
                        after = model.progress(current, step)
                        if after not in parents:
                            parents[after] = (current, (name, args))
                            frontier.append(after)
        return "unsolvable", [], f"breadth-first search exhausted all {expanded} reachable states", None
