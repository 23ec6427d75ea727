"""No silent loops: the interface layer's watch over its own progress.

Alg. 1 resets (clears learned facts, reseeds the generators) whenever no partial refinement leads
to a solvable state. Plugin mistakes make that cycle spin without end: a pose generator that
yields nothing, a failure kind that no ``learn`` template translates, generators that ignore their
``rng`` so every epoch repeats the last. ``ProgressWatch`` notices these and raises ``NoProgress``
with a sentence naming the culprit; the loop ends the run ``gave_up`` with that reason (not
``unsolvable``: nothing was proved).
"""
from __future__ import annotations

from collections import Counter, deque

BARREN_LIMIT = 20  # resets in a row that learned nothing, all blamed on the same culprit
REPEAT_LIMIT = 3  # resets in a row whose epochs tried the same candidates with the same outcomes
# the last RATE_WINDOW resets must have made at least RATE_WINDOW refinement attempts between them: work,
# not seconds, so that the verdict does not depend on the machine's speed or load
RATE_WINDOW = 100
MAX_TRACE_EVENTS = 200_000


class NoProgress(Exception):
    """The loop is not making progress; the message names why."""


class ProgressWatch:
    def __init__(self, model):
        self.model = model
        self.barren: list[set] = []  # culprits of each reset in a row that learned nothing
        self.repeats, self.last_signature = 0, None
        self.same_ends, self.last_end = 0, None  # dead ends in a row after the same facts (with kept ones)
        self.epoch_attempts: deque = deque(maxlen=RATE_WINDOW)  # refinement attempts of each of the last epochs
        self._new_epoch()

    def _new_epoch(self):
        self.culprits: set[str] = set()
        self.signature: list = []
        self.failures: Counter = Counter()
        self.attempts = 0

    # -- observations --------------------------------------------------------------------
    def generator_empty(self, label: str, index: int, step) -> None:
        self.culprits.add(f"the {label} yielded no candidates for step {index} {step}")
        self.signature.append((index, "empty"))

    def attempt(self, index: int, step, candidate, outcome) -> None:
        kind = outcome.failure.kind if outcome.failure else ("ok" if outcome.ok else "failed")
        self.attempts += 1
        self.signature.append((index, candidate.label, repr(candidate.waypoints)[:300], kind))
        if not outcome.ok:
            self.failures[(index, str(step), kind)] += 1

    def untranslated(self, failure, step) -> None:
        """The translators returned no fact at all for this failure."""
        keys = sorted(self.model.problem.domain.action(step.action).learn)
        if failure.kind not in keys:
            self.culprits.add(f"the failure kind '{failure.kind}' of the action '{step.action}' has no translation "
                              f"(its learn keys: {', '.join(keys) or 'none'}); add a learn template for it or "
                              f"report a kind it has")
        else:
            self.culprits.add(f"the '{failure.kind}' failures of the action '{step.action}' translate to no facts "
                              f"(objects: {', '.join(failure.objects) or 'none'})")

    def check_trace(self, events: int) -> None:
        if events > MAX_TRACE_EVENTS:
            raise NoProgress(f"the trace reached {MAX_TRACE_EVENTS} events without a solution; {self._summary()}")

    # -- the decision at each reset ------------------------------------------------------
    def reset(self, learned: int, plan, dead_end: set | None = None) -> None:
        """Called at every reset (Alg. 1, lines 14-17) with the number of facts learned in the epoch and,
        when the epoch ended in a dead end while facts that no action can change were known (lasting ones,
        kept by the loop), the facts it learned of the kinds after which the task planner found no plan:
        REPEAT_LIMIT such ends in a row with the same facts, each epoch with new samples, end the run (what
        sampling could change did not)."""
        self.epoch_attempts.append(self.attempts)
        same = dead_end is not None and dead_end == self.last_end
        self.same_ends, self.last_end = (self.same_ends + 1 if same else 0), dead_end
        signature = (tuple(plan), tuple(self.signature))
        self.repeats = self.repeats + 1 if signature == self.last_signature else 0
        self.last_signature = signature
        if learned:
            self.barren.clear()
        else:
            self.barren.append(set(self.culprits))
        try:
            recent = self.barren[-BARREN_LIMIT:]
            common = set.intersection(*recent) if recent else set()
            repeating = self.repeats + 1 >= REPEAT_LIMIT
            if common and (repeating or len(recent) >= BARREN_LIMIT):
                raise NoProgress(f"no progress in {len(self.barren)} resets in a row: " + "; ".join(sorted(common)))
            if self.same_ends + 1 >= REPEAT_LIMIT:
                shown = ", ".join(sorted(dead_end)[:6]) + (", ..." if len(dead_end) > 6 else "")
                raise NoProgress(f"{REPEAT_LIMIT} epochs in a row, each with new samples, ended in the same dead end: "
                                 f"the task planner found no plan once it had learned {shown or 'no fact besides the lasting ones'}")
            if repeating:
                raise NoProgress(f"the reset cycle repeats the same state: {REPEAT_LIMIT} epochs in a row tried the same "
                                 f"candidates with the same outcomes (do the pose generators use the rng they are "
                                 f"given?); {self._summary()}")
            if len(self.epoch_attempts) == RATE_WINDOW and sum(self.epoch_attempts) < RATE_WINDOW:
                raise NoProgress(f"the loop is spinning: {RATE_WINDOW} resets with {sum(self.epoch_attempts)} "
                                 f"refinement attempts between them; {self._summary()}")
        finally:
            self._new_epoch()

    def _summary(self) -> str:
        if self.culprits:
            return "; ".join(sorted(self.culprits))
        if not self.failures:
            return "the last epoch made no refinement attempt"
        (index, step, kind), n = self.failures.most_common(1)[0]
        return f"the last epoch's most frequent failure: '{kind}' at step {index} {step} ({n} times)"
