"""The Drawer domain's task-level model: the PR2's move_base / pick / place plus open_drawer.

New pose references (Skolem functions):

* ``bpfo_<drawer>_<arm>`` (bpose) a base pose from which arm can reach the drawer's handle   IsBPFO
* ``hg_<drawer>_<arm>``   (hpose) the handle grasp (dropped from the task planner's view)    IsHG
* ``pull_<drawer>``       (pull)  the pull distance, sampled at random within the joint's limits  IsPull

A drawer or what rides in it running into an object while it is pulled, or the arm on its way to the
handle doing so, is learned as ``PullObstructs(blocker, pull_<drawer>)``; picking the blocker deletes
it. An object in a drawer can only be picked once that drawer is open.
"""
from dataclasses import replace

from interlayer.domain import ActionSpec, DomainSpec, Skolem
from interlayer_pr2.domain import DOMAIN as PR2

_pick = PR2.action("pick")
_place = PR2.action("place")

DOMAIN = DomainSpec(
    name="pr2-drawer",
    types={**PR2.types, "drawer": None},
    continuous_types=(*PR2.continuous_types, "hpose", "pull"),
    predicates={
        **PR2.predicates,
        "In": ("obj", "drawer"),
        "Open": ("drawer",),
        "IsBPFO": ("bpose", "drawer", "arm"),
        "IsHG": ("hpose", "drawer", "arm"),
        "IsPull": ("pull", "drawer"),
        "PullObstructs": ("obj", "pull"),
    },
    skolems=(
        *PR2.skolems,
        Skolem("bpfo", ("drawer", "arm"), "bpose", "IsBPFO", "a base pose from which arm can reach the drawer's handle"),
        Skolem("hg", ("drawer", "arm"), "hpose", "IsHG", "the gripper closed around the drawer's handle"),
        Skolem("pull", ("drawer",), "pull", "IsPull", "how far the drawer is pulled out (random within its limits)"),
    ),
    geometric=(*PR2.geometric, "PullObstructs"),
    actions=(
        replace(PR2.action("move_base"), pose_generator="drawer:move_base"),
        ActionSpec(
            name="open_drawer",
            parameters=(("?d", "drawer"), ("?arm", "arm"), ("?bp", "bpose"), ("?hg", "hpose"), ("?p", "pull")),
            precondition="""(and (HandEmpty ?arm) (not (Open ?d)) (RobotAt ?bp) (IsBPFO ?bp ?d ?arm) (IsHG ?hg ?d ?arm)
                                 (IsPull ?p ?d) (forall (?b - obj) (not (PullObstructs ?b ?p))))""",
            effect="(Open ?d)",
            learn={"obstruction": ("(PullObstructs ?blocker ?p)",)},
            pose_generator="drawer:open_drawer",
        ),
        ActionSpec(
            name="pick",
            parameters=_pick.parameters,
            precondition=f"""(and {_pick.precondition.strip()[4:-1]}
                                  (forall (?d - drawer) (or (not (In ?o ?d)) (Open ?d))))""",
            effect=f"""(and {_pick.effect.strip()[4:-1]}
                            (forall (?d - drawer) (not (In ?o ?d)))
                            (forall (?p - pull) (not (PullObstructs ?o ?p))))""",
            learn=_pick.learn,
            pose_generator="drawer:pick",
        ),
        _place,
    ),
)
