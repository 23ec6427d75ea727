"""The stackability module (paper Sec. IV: "general geometric preconditions of actions, e.g.
stackability, which are determined by dedicated modules").

The task planner's initial specification allows every stacking; the stack action's refinement asks
this module first, and a violation is a failure of kind ``"unstackable"`` that the stack action's
learn template translates into ``Unstackable(sp_<upper>_<lower>)``, exactly as a motion-planning
obstruction becomes ``Obstructs``. The rule, from diameters: the upper object's footprint must rest
inside the lower object's rim (its diameter less the rim's wall on both sides), with CLEARANCE to
spare, and the lower object must be an open vessel (a cup or a bowl, not the tray).
"""
from __future__ import annotations

from dataclasses import dataclass

RIM = 0.004  # m: the wall of a cup's or bowl's rim
CLEARANCE = 0.002  # m between the upper object's footprint and the inside of the rim, on each side
VESSELS = ("cup", "bowl")


@dataclass(frozen=True)
class Verdict:
    ok: bool
    reason: str


def stackable(upper, lower, kinds: dict) -> Verdict:
    """Can ``upper`` (an ObjectSpec) rest on ``lower``? ``kinds``: object name -> cup / bowl / tray."""
    ku, kl = kinds.get(upper.name), kinds.get(lower.name)
    if upper.name == lower.name:
        return Verdict(False, f"{upper.name} cannot be stacked on itself")
    if kl not in VESSELS or ku not in VESSELS:
        return Verdict(False, f"only cups and bowls stack ({upper.name} is a {ku}, {lower.name} a {kl})")
    d_up, rim = 2 * upper.size[0], 2 * (lower.size[0] - RIM)
    if d_up + 2 * CLEARANCE > rim:
        return Verdict(False, f"{upper.name} ({ku}, {1000 * d_up:.0f} mm across) does not fit inside the rim of "
                              f"{lower.name} ({kl}, {1000 * rim:.0f} mm inside)")
    return Verdict(True, f"{upper.name} ({1000 * d_up:.0f} mm) fits inside the rim of {lower.name} ({1000 * rim:.0f} mm)")


def unstackable_pairs(specs, kinds) -> list[tuple[str, str, str]]:
    """(upper, lower, reason) for every pair of the scene's cups and bowls that cannot stack."""
    items = [s for s in specs if kinds.get(s.name) in VESSELS]
    return [(u.name, lo.name, v.reason) for u in items for lo in items if u is not lo
            for v in [stackable(u, lo, kinds)] if not v.ok]
