"""The result of a run: the same data for the Python API and for ``--json``."""
from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

from . import logic


# What a status that is not "solved" says, in a phrase for the CLI's summary and the explain page
MEANING = {
    "unsolvable": "proved to have no plan",
    "gave_up": "gave up without a proof that no plan exists",
    "timeout": "the time limit was reached",
    "interrupted": "interrupted",
}


@dataclass
class Result:
    # "solved" | "unsolvable" (proved: no task plan for the initial state, or a domain's Infeasible) |
    # "gave_up" (the loop stopped itself without a proof: the watchdog) | "timeout" | "interrupted"
    status: str
    reason: str = ""
    plan: list = field(default_factory=list)  # GroundSteps
    plan_cost: float | None = None  # the sum of the plan's action costs (solved runs)
    learned_facts: list = field(default_factory=list)  # atoms and logic.negated atoms, in the order learned
    replans: int = 0
    task_planner_calls: int = 0
    times: dict = field(default_factory=dict)
    wall: dict = field(default_factory=dict)  # the wait: startup, planning, export, writing, other, total (s)
    origin: float | None = None  # where ``wall`` starts, on the perf_counter clock (the process's start for the CLI)
    counts: dict = field(default_factory=dict)
    seed: int = 0
    config: dict = field(default_factory=dict)
    shortcut_dropped: list = field(default_factory=list)  # GroundSteps refined, then dropped as not needed
    refinement: Any = None  # domain trajectory (per step), when solved
    trace: Any = None
    problem: Any = None
    model: Any = None

    @property
    def solved(self) -> bool:
        return self.status == "solved"

    def to_json(self) -> dict:
        return {
            "status": self.status,
            "reason": self.reason,
            "plan": [s.to_json() for s in self.plan],
            "plan_cost": self.plan_cost,
            "learned_facts": [logic.literal_str(a) for a in self.learned_facts],
            "shortcut": {"refined_steps": len(self.plan) + len(self.shortcut_dropped),
                         "dropped": [s.to_json() for s in self.shortcut_dropped]} if self.solved else None,
            "replans": self.replans,
            "task_planner_calls": self.task_planner_calls,
            "times": {k: round(v, 4) for k, v in self.times.items()},
            "wall": {k: round(v, 4) for k, v in self.wall.items()},
            "counts": self.counts,
            "seed": self.seed,
            "config": self.config,
            # symbol -> the name a person gave it, where they differ (plan args are symbols: interlayer.names)
            "names": dict(getattr(self.model, "labels", None) or {}),
        }
