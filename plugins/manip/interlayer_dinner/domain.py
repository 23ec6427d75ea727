"""The Dinner domain's task-level model: a compact STRIPS encoding that cost-optimal planners solve in
well under a second at N = 6 (measured during the design).

Objects: the cups and bowls (``obj``), both arms, two rooms, locations: surfaces (the tables ``side`` /
``dinner`` where the tray stands, one place setting ``set_<obj>`` per object: fixed references, never
symbolic free spots) and ``tray``, which is in a room while it stands on a table there. Which of the
tray's slots an object goes to is the pose generator's choice (symbolic choices of
spots blow optimal planning up). Objects stack only on the tray (where stacking helps: a stack rides
along); nothing stacks on a stacked object.
Driving within a room is part of each manipulation step's refinement (the base drives to a sampled
pose, then the arm moves); moving between rooms is ``go`` and costs 100; everything else costs 1.

New pose references (Skolem functions): ``sp_<upper>_<lower>`` (spose), where upper rests on lower
(IsSP). ``Unstackable(sp)`` starts false for every pair (Prop. 1: every stacking allowed) and is learned
from the stackability module's verdicts (``interlayer_dinner.stacking``): when a stack step asks it about
(upper, lower), the failure names (as its objects, bound to ?blocker) every reference it rules out for
those two objects: upper on anything, anything on lower.

Options: ``handoff`` adds handing an object from one hand to the other; ``side_costs`` makes reaching an
object or a place on the robot's left with the right hand (and vice versa) cost CROSS instead of 1
(the paper's conditional costs, compiled into a same-side and a cross-side variant of each action).
"""
from __future__ import annotations

from dataclasses import replace

from interlayer.domain import ActionSpec, DomainSpec, Skolem

GO_COST = 100
CROSS = 3

_HOLD = "(and (Holding ?o ?arm) (not (HandEmpty ?arm)))"

BASE = DomainSpec(
    name="dinner",
    types={"obj": None, "arm": None, "room": None, "loc": None, "surface": "loc"},
    continuous_types=("spose",),
    predicates={
        "RobotIn": ("room",), "Adjacent": ("room", "room"),
        "HandEmpty": ("arm",), "Holding": ("obj", "arm"), "HoldingTray": (),
        "At": ("obj", "loc"), "LocIn": ("loc", "room"), "Accepts": ("surface", "obj"),
 "TrayAt": ("surface",), "TraySpot": ("surface",),
        "Clear": ("obj",), "On": ("obj", "obj"),
        "Near": ("obj", "arm"), "NearLoc": ("loc", "arm"),  # on that arm's side (side_costs)
        "IsSP": ("spose", "obj", "obj"), "Unstackable": ("spose",),
        "Passable": ("obj",),  # one hand can take it from the other (handoff; DinnerGeometry.passable)
    },
    skolems=(Skolem("sp", ("obj", "obj"), "spose", "IsSP", "where the first object rests when stacked on the second"),),
    geometric=("Unstackable",),
    actions=(
        ActionSpec("go", (("?from", "room"), ("?to", "room")), "(and (RobotIn ?from) (Adjacent ?from ?to))",
                   "(and (not (RobotIn ?from)) (RobotIn ?to))", cost=GO_COST, pose_generator="dinner:go"),
        ActionSpec("pick", (("?o", "obj"), ("?arm", "arm"), ("?l", "surface"), ("?r", "room")),
                   "(and (HandEmpty ?arm) (At ?o ?l) (Clear ?o) (LocIn ?l ?r) (RobotIn ?r))",
                   "(and (Holding ?o ?arm) (not (HandEmpty ?arm)) (not (At ?o ?l)))", pose_generator="dinner:pick"),
        ActionSpec("place", (("?o", "obj"), ("?arm", "arm"), ("?l", "surface"), ("?r", "room")),
                   "(and (Holding ?o ?arm) (Accepts ?l ?o) (LocIn ?l ?r) (RobotIn ?r))",
                   "(and (At ?o ?l) (HandEmpty ?arm) (not (Holding ?o ?arm)))", pose_generator="dinner:place"),
        ActionSpec("put_on_tray", (("?o", "obj"), ("?arm", "arm"), ("?r", "room")),
                   "(and (Holding ?o ?arm) (LocIn tray ?r) (RobotIn ?r))",
                   "(and (At ?o tray) (HandEmpty ?arm) (not (Holding ?o ?arm)))",
                   pose_generator="dinner:place"),
        ActionSpec("take_off_tray", (("?o", "obj"), ("?arm", "arm"), ("?r", "room")),
                   "(and (HandEmpty ?arm) (At ?o tray) (Clear ?o) (LocIn tray ?r) (RobotIn ?r))",
                   "(and (Holding ?o ?arm) (not (HandEmpty ?arm)) (not (At ?o tray)))",
                   pose_generator="dinner:pick"),
        ActionSpec("stack", (("?o", "obj"), ("?arm", "arm"), ("?lower", "obj"), ("?r", "room"), ("?sp", "spose")),
                   """(and (Holding ?o ?arm) (IsSP ?sp ?o ?lower) (not (Unstackable ?sp)) (At ?lower tray) (Clear ?lower)
                           (LocIn tray ?r) (RobotIn ?r))""",
                   "(and (On ?o ?lower) (not (Clear ?lower)) (HandEmpty ?arm) (not (Holding ?o ?arm)))",
                   learn={"unstackable": ("(Unstackable ?blocker)",)}, pose_generator="dinner:place"),
        ActionSpec("unstack", (("?o", "obj"), ("?arm", "arm"), ("?lower", "obj"), ("?r", "room")),
                   "(and (HandEmpty ?arm) (On ?o ?lower) (At ?lower tray) (LocIn tray ?r) (RobotIn ?r))",
                   "(and (Holding ?o ?arm) (not (HandEmpty ?arm)) (not (On ?o ?lower)) (Clear ?lower))",
                   pose_generator="dinner:pick"),
        ActionSpec("pick_tray", (("?t", "surface"), ("?r", "room")),
                   "(and (HandEmpty left) (HandEmpty right) (TrayAt ?t) (LocIn ?t ?r) (RobotIn ?r))",
                   "(and (HoldingTray) (not (HandEmpty left)) (not (HandEmpty right)) (not (TrayAt ?t)) (not (LocIn tray ?r)))", pose_generator="dinner:pick_tray"),
        ActionSpec("place_tray", (("?t", "surface"), ("?r", "room")),
                   "(and (HoldingTray) (TraySpot ?t) (LocIn ?t ?r) (RobotIn ?r))",
                   "(and (not (HoldingTray)) (HandEmpty left) (HandEmpty right) (TrayAt ?t) (LocIn tray ?r))", pose_generator="dinner:place_tray"),
    ),
)

HANDOFF = ActionSpec("handoff", (("?o", "obj"), ("?from", "arm"), ("?to", "arm")),
                     "(and (Holding ?o ?from) (HandEmpty ?to) (Passable ?o))",
                     "(and (not (Holding ?o ?from)) (HandEmpty ?from) (Holding ?o ?to) (not (HandEmpty ?to)))",
                     pose_generator="dinner:handoff")

# what decides an action's side: the object's place on the side table (pick), else the slot, setting or
# the lower object's place
SIDED = {"pick": "(Near ?o ?arm)", "take_off_tray": "(Near ?o ?arm)", "unstack": "(Near ?lower ?arm)",
         "place": "(NearLoc ?l ?arm)", "put_on_tray": "(NearLoc tray ?arm)", "stack": "(Near ?lower ?arm)"}


def make_domain(handoff: bool = False, side_costs: bool = False) -> DomainSpec:
    actions = list(BASE.actions)
    if side_costs:
        sided = []
        for a in actions:
            if a.name in SIDED:
                cond = SIDED[a.name]
                sided.append(replace(a, precondition=f"(and {a.precondition} {cond})"))
                sided.append(replace(a, name=f"{a.name}_cross", precondition=f"(and {a.precondition} (not {cond}))",
                                     cost=CROSS))
            else:
                sided.append(a)
        actions = sided
    if handoff:
        actions.append(HANDOFF)
    return replace(BASE, actions=tuple(actions))
