"""Plan shortcutting after a solve (beyond the paper).

Alg. 1 keeps every refined prefix verbatim when it replans, so a solved plan can hold steps that
turned out useless: an object moved for an obstruction that a later replan went around, a base
move followed by another. This drops such steps: a removal is tried when the shorter plan is still
valid symbolically (from the initial state plus the facts learned in the solving epoch, so a known
obstruction is never "shortcut" away), and kept only if TryRefine refines the shorter plan from the
first changed step, with the refined prefix before it unchanged.
"""
from __future__ import annotations

from itertools import combinations

from .planning import check_plan


def removals(plan) -> list[tuple[int, ...]]:
    """Sets of step indices to try dropping, largest first: pairs of steps on a shared object (a
    pick and its put-down) and single steps."""
    pairs = [(i, j) for i, j in combinations(range(len(plan)), 2) if set(plan[i].args) & set(plan[j].args)]
    return pairs + [(i,) for i in range(len(plan))]


MAX_TRIES = 12  # removals that reach refinement: a bound on the extra motion planning, not on time


def shortcut(plan, outcomes, model, state, refiner, world0, drain, out_of_time, on_try, on_accept):
    """Greedily drop removable steps; returns (plan, outcomes), refined and valid."""
    plan, outcomes = list(plan), list(outcomes)
    tried: set = set()
    changed = True
    while changed and len(tried) < MAX_TRIES and not out_of_time():
        changed = False
        for drop in removals(plan):
            if out_of_time() or len(tried) >= MAX_TRIES:
                break
            shorter = [s for k, s in enumerate(plan) if k not in drop]
            if tuple(shorter) in tried or check_plan(model, state, shorter):
                continue
            tried.add(tuple(shorter))
            on_try(shorter)
            first = min(drop)
            world = outcomes[first - 1].world if first else world0
            refiner.clear_cache()
            done = drain(refiner.try_refine(shorter, first, world, dict(enumerate(outcomes[:first])), partial=False))
            if done is None:
                continue
            on_accept([plan[k] for k in drop], shorter)
            plan, outcomes = shorter, [done.outcomes[i] for i in range(len(shorter))]
            changed = True
            break
    return plan, outcomes
