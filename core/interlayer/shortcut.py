"""Plan shortcutting after a solve (beyond the paper).

Alg. 1 keeps every refined prefix verbatim when it replans, so a solved plan can hold steps that
turned out useless: an object moved for an obstruction that a later replan went around, a base
move followed by another. This drops such steps. A removal is tried when the shorter plan is still
valid symbolically (from the initial state plus the facts learned in the solving epoch, so a known
obstruction is not shortcut away); it is kept when every later step refines again with the pose
values it had (one motion-planning call per step, no new sampling), the prefix before it unchanged;
once a redone step leaves the world as it was in the original refinement, the rest is kept as is.
"""
from __future__ import annotations

from collections.abc import Mapping
from dataclasses import fields, is_dataclass, replace
from itertools import combinations

import numpy as np

from .planning import check_plan

MAX_TRIES = 8  # removals that reach the motion planner: bounds the extra work, not the time


def removals(plan, model, state) -> list[tuple[int, ...]]:
    """Sets of step indices to try dropping, most promising first: pairs of steps on a shared object
    (a pick and its put-down) and single steps, those whose removal leaves the final symbolic state
    unchanged (a move followed by another, an object picked and put back) before the others."""
    pairs = [(i, j) for i, j in combinations(range(len(plan)), 2) if set(plan[i].args) & set(plan[j].args)]
    final = _final(model, state, plan)

    def order(drop):
        return (_final(model, state, [s for k, s in enumerate(plan) if k not in drop]) != final, -len(drop))

    return sorted(pairs + [(i,) for i in range(len(plan))], key=order)


def _final(model, state, plan):
    for step in plan:
        if not model.applicable(state, step):
            return None
        state = model.progress(state, step)
    return state


def unneeded_steps(plan, model, state) -> list[int]:
    """Greedy action elimination (symbolic, before any refinement): drop a step together with the later
    steps it alone enabled (an object picked for nothing and its put-down) while the rest still
    applies from ``state`` and reaches the goal. A satisficing planner's detours would otherwise each
    cost motion planning, and their failures replanning. Returns the indices dropped."""
    kept = list(range(len(plan)))
    i = 0
    while i < len(kept):
        s, rest = state, []
        for k in kept[:i]:
            s = model.progress(s, plan[k])
        for k in kept[i + 1:]:
            if model.applicable(s, plan[k]):
                s = model.progress(s, plan[k])
                rest.append(k)
        if model.goal_holds(s):
            kept = kept[:i] + rest
        else:
            i += 1
    return [k for k in range(len(plan)) if k not in kept]


def shortcut(plan, outcomes, model, state, geometry, motion, world0, out_of_time, on_accept, stats):
    """Greedily drop removable steps; returns (plan, outcomes), refined and valid."""
    plan, outcomes = list(plan), list(outcomes)
    tries = 0
    in_the_way: set = set()  # objects a failed re-refinement ran into: removals of steps moving them fail too
    changed = True
    while changed and tries < MAX_TRIES and not out_of_time():
        changed = False
        for drop in removals(plan, model, state):
            if out_of_time() or tries >= MAX_TRIES:
                break
            if any(in_the_way.intersection(plan[k].args) for k in drop):
                continue
            keep = [k for k in range(len(plan)) if k not in drop]
            shorter = [plan[k] for k in keep]
            if check_plan(model, state, shorter):
                continue
            tries += 1
            first = min(drop)
            world = outcomes[first - 1].world if first else world0
            redone = _refine_again(geometry, motion, [(plan[k], outcomes[k]) for k in keep[first:]], world, stats)
            if not isinstance(redone, list):
                if redone is not None and redone.kind == "obstruction":
                    in_the_way.update(redone.objects)
                continue
            on_accept([plan[k] for k in drop], shorter)
            plan, outcomes = shorter, outcomes[:first] + redone
            changed = True
            break
    return plan, outcomes


def _refine_again(geometry, motion, steps, world, stats):
    """Each (step, original outcome) refined again from ``world`` with its candidate, until the world
    is what it was originally: the new outcomes, or the first failure (a ``Failure`` or None)."""
    out = []
    for k, (step, original) in enumerate(steps):
        stats.count("shortcut_attempts")
        with stats.timer("motion_planning"):
            outcome = geometry.refine_step(step, world, original.candidate, motion)
        if not outcome.ok:
            return outcome.failure
        out.append(replace(outcome, candidate=original.candidate))
        world = outcome.world
        if same(world, original.world):
            return out + [o for _, o in steps[k + 1:]]
    return out


def same(a, b) -> bool:
    """Structural equality of two worlds (dataclasses, mappings, sequences, arrays, numbers)."""
    if is_dataclass(a) and type(a) is type(b):
        return all(same(getattr(a, f.name), getattr(b, f.name)) for f in fields(a))
    if isinstance(a, Mapping) and isinstance(b, Mapping):
        return a.keys() == b.keys() and all(same(a[k], b[k]) for k in a)
    if isinstance(a, (np.ndarray, float)) or isinstance(b, (np.ndarray, float)):
        try:
            return np.shape(a) == np.shape(b) and bool(np.allclose(a, b, rtol=0.0, atol=1e-9))
        except TypeError:
            return False
    if isinstance(a, (list, tuple)) and isinstance(b, (list, tuple)):
        return len(a) == len(b) and all(same(x, y) for x, y in zip(a, b))
    return a == b
