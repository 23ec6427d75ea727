"""Alg. 2 (TryRefine): a backtracking search over pose-reference instantiations.

The domain supplies a ``Geometry`` runtime (how one action is refined between two poses, with the
motion planner) and pose generators (candidate instantiations of an action's references, each a
tuple of waypoints). This module knows nothing about robots: it orders the search, backtracks,
and in partial-trajectory mode yields each failure with the prefix that was refined before it.
"""
from __future__ import annotations

import zlib
from dataclasses import dataclass, field, replace
from typing import Any, Callable, Iterable, Iterator, Mapping, Protocol

import numpy as np

from . import deadline
from .domain import GroundStep


@dataclass(frozen=True)
class Candidate:
    """One instantiation of an action's references: waypoints plus the values given to references."""

    waypoints: tuple
    values: Mapping[str, Any] = field(default_factory=dict)
    label: str = ""


@dataclass(frozen=True)
class Failure:
    """Why an action could not be refined (the failed geometric preconditions)."""

    kind: str  # a key of the action's learn templates ("obstruction"), or another kind ("ik", "unreachable")
    objects: tuple = ()  # the obstructing objects, for "obstruction" (the templates' ``?blocker``)
    detail: str = ""
    # True when no other instantiation of the earlier steps can change the verdict (a dedicated module's,
    # e.g. stackability from diameters): TryRefine then stops instead of backtracking over them
    static: bool = False
    # True when the facts it teaches hold for the rest of the run whatever any action or reset does (a proof
    # from fixed obstacles, e.g. no grasp of an object clears them): the loop keeps them across resets
    lasting: bool = False
    # objects for the templates' other ``?blocker...`` variables, e.g. {"?blocker2": ("o5",)} (what blocks
    # the other arm's best grasp of the object a pick failed on), or a function giving them: called only
    # when the failure is translated (the partial pass), not for every failed attempt
    also: Mapping[str, tuple] | Callable[[], Mapping[str, tuple]] = field(default_factory=dict, compare=False)
    # failures of the same action with other objects ({parameter: object}, Failure), or of another step
    # (GroundStep, Failure), that the geometry found in the failing step's world without refining them (e.g.
    # what blocks picking each object in the way; the earlier put-down that set a blocker there): translated
    # too (TaskModel.step_with names the references), so that one replan learns a chain of blockers; or a
    # function giving them, called when the failure is translated
    related: tuple | Callable[[], tuple] = field(default=(), compare=False)
    # True when the verdict does not depend on the robot's configuration at the step's start (what the
    # candidate itself reaches is blocked: its goal configuration, its straight lines), so that earlier
    # steps that only moved the robot cannot change it (TryRefine's backjumping, see Refiner)
    start_free: bool = False

    def also_objects(self) -> Mapping[str, tuple]:
        return self.also() if callable(self.also) else self.also

    def related_failures(self) -> tuple:
        return self.related() if callable(self.related) else self.related

    def to_json(self, related: bool = False) -> dict:
        """With ``related``, the related failures too (computed if they are a function: a translated failure's)."""
        out = {"kind": self.kind, "objects": list(self.objects), "detail": self.detail}
        if self.start_free:
            out["start_free"] = True
        if self.also and not callable(self.also):
            out["also"] = {k: list(v) for k, v in self.also.items()}
        if self.related and (related or not callable(self.related)):
            out["related"] = [{**({"step": objs.to_json()} if isinstance(objs, GroundStep) else {"with": dict(objs)}), **f.to_json()}
                              for objs, f in self.related_failures()]
        return out


@dataclass
class StepOutcome:
    """What refining one action produced: the world after it and its trajectory, or a failure."""

    ok: bool
    world: Any = None
    segments: list = field(default_factory=list)
    failure: Failure | None = None
    candidate: Candidate | None = None  # what was refined (set by TryRefine on success)


# The failure kind of a step whose pose generator yielded no candidate at all in this epoch (partial mode
# yields it like a motion failure): an action's ``learn`` templates for it tell the task planner that its
# reference has no instance here, e.g. ``{NO_CANDIDATES: ("(NoGrasp ?gp)",)}``
NO_CANDIDATES = "no_candidates"


class Infeasible(Exception):
    """Raised by a pose generator when a reference can never be instantiated (e.g. no grasp of an
    object fits the gripper): the run ends as unsolvable with this reason."""


class GiveUp(Exception):
    """Raised by a pose generator that knows, without a proof, that it will find no candidate for a step
    the goal needs (a finite search of its own found none): the run ends as gave_up with this reason."""


class Geometry(Protocol):
    """The domain's refinement runtime (``Problem.geometry``). Optional methods:
    ``trajectory_json(plan, outcomes) -> dict`` (written to ``trajectory.json``: ``{"initial":
    snapshot, "steps": [{"action", "args", "segments"}, ...]}``, one entry per plan step) and
    ``validate(plan, trajectory) -> list of violations`` (used by ``interlayer validate``) and
    ``moved(before, after) -> set of object names`` (the objects whose pose differs between two
    worlds, and ``ROBOT_MOVED`` when the robot's own configuration does: TryRefine then skips
    backtracking that cannot move an obstruction, see ``Refiner``) and ``prepare_export()`` (called
    before planning when the run will be written: start what ``trajectory_json`` needs, so that it
    overlaps planning). A geometry with a ``cartesian``
    attribute gets the motion planner named by ``planner.cartesian`` there, for its straight-line
    end-effector segments."""

    def initial_world(self) -> Any:
        """The low-level state at the start: any value; worlds are never mutated, only replaced."""

    def refine_step(self, step: GroundStep, world: Any, candidate: Candidate, motion) -> StepOutcome:
        """Refine ``step`` from ``world`` through ``candidate.waypoints`` with the ``motion``
        planner: ``StepOutcome(True, new_world, segments)`` or ``StepOutcome(False,
        failure=Failure(kind, objects))``; ``kind`` selects the action's ``learn`` templates."""

    def snapshot(self, world: Any) -> dict:
        """A JSON-able picture of ``world`` (written into failure events and drawn by visualizers)."""


class _RobotMoved:
    """What ``Geometry.moved`` returns, beside object names, when the robot itself moved (its base,
    arms, grippers): not a string, so that no object's name can be mistaken for it."""

    def __repr__(self):
        return "ROBOT_MOVED"


ROBOT_MOVED = _RobotMoved()


class PoseGenerator:
    """resetAndGetFirst / getNext over a finite, seeded stream of candidates (Sec. IV-B2)."""

    def __init__(self, factory: Callable[[np.random.Generator], Iterable[Candidate]], seed):
        self._factory, self._seed = factory, seed
        self._it: Iterator[Candidate] | None = None
        self.index = -1

    def reset_and_get_first(self) -> Candidate | None:
        self._it, self.index = iter(self._factory(np.random.default_rng(self._seed))), -1
        return self.get_next()

    def get_next(self) -> Candidate | None:
        if self._it is None:
            return self.reset_and_get_first()
        self.index += 1
        return next(self._it, None)


class EpochState:
    """Base class for a pose generator that keeps state between calls, e.g. candidates sampled once
    and re-ranked in every world, so that an obstruction learned for a candidate stays true of it.

    Register the class itself as the generator. The loop makes a fresh instance at every epoch,
    seeded for that epoch (``self.seed``), so a reset (Alg. 1, line 16) discards the state and
    reseeds it; one instance serves every action registered with the same class. Calls are
    ``instance(problem, step, world, rng)``, like a plain generator function. Keep generator state
    here and nowhere else (never on the geometry): the refinement cache and the paper's
    completeness argument depend on it."""

    ordinal = None  # set by the loop: an object's or reference's place in the task model (TaskModel.ordinal)

    def __init__(self, seed):
        self.seed = seed

    def rng_for(self, *key) -> np.random.Generator:
        """A random generator that depends only on this epoch's seed and ``key``, where an object or a
        reference counts by its place in the task model, not its name (names are data)."""
        if self.ordinal is not None:
            key = [self.ordinal(k) if isinstance(k, str) else k for k in key]
        return np.random.default_rng([*self.seed, *stable_seed(*key)])

    def __call__(self, problem, step, world, rng) -> Iterable[Candidate]:
        raise NotImplementedError


def fingerprint(candidate: Candidate):
    """A hashable copy of a candidate's waypoints, values and label (arrays by their bytes)."""
    def freeze(v):
        if isinstance(v, np.ndarray):
            return (v.dtype.str, v.shape, v.tobytes())
        if isinstance(v, (list, tuple)):
            return tuple(freeze(x) for x in v)
        if isinstance(v, Mapping):
            return tuple(sorted((str(k), freeze(x)) for k, x in v.items()))
        return v

    return freeze(candidate.waypoints), freeze(candidate.values), candidate.label


def drawn_within(make_items, context):
    """The items of ``make_items()`` drawn one at a time, each computed inside a fresh ``context()``
    (a timer, a fault attribution); a ``None`` item ends them. Past the run's time limit, the next
    draw raises ``DeadlineExceeded``."""
    with context():
        items = iter(make_items())
    while True:
        deadline.check()
        with context():
            item = next(items, None)
        if item is None:
            return
        yield item


def stable_seed(*parts) -> list[int]:
    return [zlib.crc32(str(p).encode()) for p in parts]


@dataclass
class PartialRefinement:
    """One yield of partial-trajectory mode (Alg. 2, line 14)."""

    outcomes: dict  # step index -> StepOutcome, for the refined prefix
    world: Any  # the world where the prefix ends (pose2 in Alg. 1)
    fail_step: int
    failure: Failure
    candidate: Candidate


@dataclass
class Refinement:
    outcomes: dict  # step index -> StepOutcome, for every step


class Refiner:
    """Runs TryRefine for one problem; ``make_generator(i, step, world)`` builds the PoseGenerator
    of step i, ``on_attempt`` observes each motion-planning attempt.

    ``max_attempts`` bounds the *failed* motion-planning attempts per plan step in one TryRefine
    call (successes and cached outcomes are free; a generator that yields no candidate at all counts as
    one failure), so the budget scales with the plan's length and a plan whose every step refines is
    never cut off; the loop raises it at every epoch.

    Backjumping (error-free mode, geometries with ``moved``; conflict-directed): when every candidate
    of a step failed on obstructions by named objects, only an earlier step that moved one of them,
    or moved the robot where a failure depended on the robot's start (not ``Failure.start_free``), can
    change the verdict: the search jumps back to the latest such step, passing over the others (their
    other instantiations would leave the blockers where they are and be paid for again, transit by
    transit), and that step inherits the failures as its own; with none, the call ends there and the
    partial pass that follows learns the obstructions. A step with any other failure backtracks to the
    step before it (Alg. 2). A start-free conflict is also remembered (a nogood): when the step jumped
    back to, or one after it, succeeds again leaving those objects where they stood, the later step
    would fail the same way, so that success counts as a failure of its own step (the steps between
    are not refined for it); met KNOWN_LIMIT times, it ends the call. ``on_backjump`` observes each jump
    (``known``: the step that met a nogood). Partial mode keeps the paper's full backtracking."""

    def __init__(self, geometry, motion, make_generator, max_attempts: int, out_of_time, on_attempt=None, stats=None,
                 on_backjump=None):
        from .trace import Stats

        self.geometry, self.motion = geometry, motion
        self.stats = stats or Stats()
        self.make_generator = make_generator
        self.max_attempts = max_attempts
        self.out_of_time = out_of_time
        self.on_attempt = on_attempt or (lambda **kw: None)
        self.on_backjump = on_backjump or (lambda **kw: None)
        self._cache: dict = {}

    def clear_cache(self):
        self._cache.clear()

    def _culprit(self, conflict, worlds, start: int, i: int) -> int:
        """The latest step before ``i`` (not before ``start``) whose other instantiations could change
        the exhausted step i's failures (``conflict``: the objects they named and whether all were
        start-free, or None: any step could), ``start - 1`` when none could."""
        moved = getattr(self.geometry, "moved", None)
        if conflict is None or moved is None:
            return i - 1
        blocked, start_free = conflict
        for k in range(i - 1, start - 1, -1):
            changed = moved(worlds[k], worlds[k + 1])
            if blocked & changed or (not start_free and ROBOT_MOVED in changed):
                return k
        return start - 1

    def _known_failure(self, nogoods, k: int, world):
        """The nogood that step k's success ending in ``world`` meets: every candidate of its later step j
        failed, start-free, on objects that stand in ``world`` where they stood then, and no step between k
        and j moved them (a step's candidates move the same objects, in other ways); else None."""
        for nogood in nogoods:
            j, c, blocked, failed_in, _ = nogood
            if c <= k < j and not (blocked & self.geometry.moved(failed_in, world)):
                return nogood
        return None

    def try_refine(self, plan: list[GroundStep], step: int, world0, prefix: dict, partial: bool):
        """Alg. 2. A generator: yields PartialRefinement in partial mode; its return value
        (StopIteration.value) is a Refinement, or None when the search failed or ran out."""
        n = len(plan)
        worlds, outcomes = {step: world0}, dict(prefix)
        chain: list = []  # what was refined at each step from `step`: with world0, what step i's world depends on
        gens = {step: self.make_generator(step, plan[step], world0)} if step < n else {}
        drawn = {step: 0}  # candidates each live generator yielded
        i, failures = step, {}
        # step -> (the objects its failures and those of the steps that jumped back to it named, whether all
        # were start-free) since its generator was made, or None once one was no obstruction (see _obstructions)
        blockers: dict = {}
        # (step j, its culprit c, the objects, the world at j): step j failed on those objects, start-free, and
        # the steps between c and j did not move them; a step from c on that leaves them so dooms step j
        nogoods: list = []
        while step <= i < n:  # line 4
            if self.out_of_time():
                return None
            gen = gens[i]
            cand = gen.get_next()
            if cand is None and not drawn.get(i):  # nothing to instantiate the step's references with
                if partial:
                    yield PartialRefinement({k: v for k, v in outcomes.items() if k < i}, worlds[i], i,
                                            Failure(NO_CANDIDATES, detail=f"the pose generator of {plan[i].action} "
                                                                          f"yielded no candidate"),
                                            Candidate((), {}, "no candidate"))
                # an empty generator is futile work like a failed attempt and counts as one: else each
                # backtrack re-refines the earlier steps' successes (free) and asks it again, without end
                failures[i] = failures.get(i, 0) + 1
                if failures[i] >= self.max_attempts:
                    return None
            if cand is None:  # lines 7-10: generator exhausted, backtrack
                back = i - 1
                if not partial:  # conflict-directed: to the latest step that can change the failures
                    conflict = blockers.get(i)  # None: no candidate at all, or a failure of another kind
                    back = self._culprit(conflict, worlds, step, i)
                    if back < i - 1:
                        self.on_backjump(step=i, to=back if back >= step else None, objects=sorted(conflict[0]),
                                         start_free=conflict[1], skipped=list(range(max(back, step - 1) + 1, i)))
                    if back < step:
                        return None
                    blockers[back] = _merged(blockers.get(back, _NONE_YET), conflict)
                    if conflict is not None and conflict[1]:  # start-free: a nogood (see _known_failure)
                        nogoods.append([i, back, conflict[0], worlds[i], 0])
                for k in range(back + 1, i + 1):
                    del gens[k]
                del chain[max(back - step, 0):]
                for k in range(max(back, step), i):
                    outcomes.pop(k, None)
                i = back
                continue
            # an outcome depends on the candidate itself and the world it starts from, not on the
            # candidate's place in its generator's stream (a generator's state may reorder it)
            key = (tuple(plan[step : i + 1]), tuple(chain), fingerprint(cand), id(world0))
            outcome = self._cache.get(key)
            cached = outcome is not None
            if not cached:
                if failures.get(i, 0) >= self.max_attempts:
                    return None  # this step's budget is spent: let the loop replan or reset
                with self.stats.timer("motion_planning"):  # IK and collision checks may be split out inside
                    outcome = self.geometry.refine_step(plan[i], worlds[i], cand, self.motion)
                self._cache[key] = outcome
                if not outcome.ok:
                    failures[i] = failures.get(i, 0) + 1
            drawn[i] = drawn.get(i, 0) + 1
            self.on_attempt(step=i, candidate=cand, outcome=outcome, partial=partial, cached=cached)
            known = self._known_failure(nogoods, i, outcome.world) if outcome.ok and nogoods else None
            if known is not None:  # a success that leaves a later step's blockers where they failed it
                j, blocked = known[0], known[2]
                known[4] += 1
                again = known[4] >= KNOWN_LIMIT  # the earlier steps keep leaving them there: learn it instead
                self.on_backjump(step=j, to=None if again else i, objects=sorted(blocked), start_free=True,
                                 skipped=list(range(i + 1, j)), known=i)
                if again:
                    return None
                if not cached:
                    failures[i] = failures.get(i, 0) + 1
                blockers[i] = _merged(blockers.get(i, _NONE_YET), (blocked, True))
            elif outcome.ok:  # line 12
                outcomes[i], worlds[i + 1] = replace(outcome, candidate=cand), outcome.world
                chain.append(key[2])
                i += 1
                if i < n:
                    gens[i] = self.make_generator(i, plan[i], worlds[i])
                    blockers.pop(i, None)
                    drawn[i] = 0
            else:
                blockers[i] = _obstructions(outcome.failure, blockers.get(i, _NONE_YET))
            if partial and not outcome.ok and outcome.failure is not None:  # lines 13-14
                prefix_out = {k: v for k, v in outcomes.items() if k < i}
                yield PartialRefinement(prefix_out, worlds[i], i, outcome.failure, cand)
            if not outcome.ok and outcome.failure is not None and outcome.failure.static:
                return None
            # line 15: the next iteration draws the next candidate of step i
        if i >= n:  # lines 16-17
            return Refinement(outcomes)
        return None


_NONE_YET = (frozenset(), True)  # a step's conflict before any failure
# A nogood met this often in one error-free pass ends it: the steps before keep leaving the blockers where
# the later step failed on them (a put-down at a goal pose, whatever its grasp), and the partial pass that
# follows learns the obstruction instead of the search re-refining them to the budget's end
KNOWN_LIMIT = 2


def _obstructions(failure, so_far):
    """``so_far`` with ``failure``: the objects named and whether every failure was start-free; None
    once a failure was not an obstruction by named objects (then any earlier step may be the cause)."""
    if so_far is None or failure is None or failure.kind != "obstruction" or not failure.objects:
        return None
    return so_far[0] | set(failure.objects), so_far[1] and failure.start_free


def _merged(a, b):
    """Two conflicts as one (None, any step may be the cause, absorbs)."""
    return None if a is None or b is None else (a[0] | b[0], a[1] and b[1])
