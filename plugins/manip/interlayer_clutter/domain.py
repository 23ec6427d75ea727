"""Clutter's task encoding: the domain ``pr2-clutter`` and a problem over a table layout.

Task-level model (used by Clutter-N and by pybullet-planning JSON files that ask to hold an object),
chosen for Fast Downward's speed with 40 objects (see docs/benchmarks.md):

* ``move_base`` is folded into pick and place: their base-pose references (``bpfg_<o>_<arm>``,
  ``bpfpd_<o>_<arm>_<slot>``) occur only in their own Skolem atom, so the core drops them from the
  task planner's view; the pose generators sample a base pose together with the arm motion, and the
  refinement drives there first (one base segment at the start of the step's trajectory).
* ``Obstructs(?blocker ?gp)`` / ``PDObstructs(?blocker ?pd)``: two arguments, the reference names
  the object and arm (and slot) it is for.
* pick deletes the obstructions the picked object causes and those learned about its own grasps
  (both arms): they described where it stood. A pick whose approach is blocked learns the other arm's
  blockers too (``?blocker2``) when its generator found every grasp of that arm obstructed.
* put-down references are per object and slot (``gpfpd_<o>_<arm>_<slot>``, ``slot`` = s1..sK): the
  slot only gives the task planner K alternatives once a put-down is found obstructed; the concrete
  spot anywhere on the table is sampled by the pose generator.
"""
from __future__ import annotations

from interlayer.domain import ActionSpec, DomainSpec, Problem, Skolem
from interlayer_manip.scene import Layout
from interlayer_manip.params import held_by_some_arm

SLOTS = 2

CLUTTER_DOMAIN = DomainSpec(
    name="pr2-clutter",
    types={"obj": None, "arm": None, "slot": None},
    continuous_types=("bpose", "gpose", "pdpose"),
    predicates={
        "HandEmpty": ("arm",),
        "Other": ("arm", "arm"),
        "Holding": ("obj", "arm"),
        "OnTable": ("obj",),
        "IsBPFG": ("bpose", "obj", "arm"),
        "IsGPFG": ("gpose", "obj", "arm"),
        "IsBPFPD": ("bpose", "obj", "arm", "slot"),
        "IsGPFPD": ("pdpose", "obj", "arm", "slot"),
        "Obstructs": ("obj", "gpose"),
        "PDObstructs": ("obj", "pdpose"),
    },
    skolems=(
        Skolem("bpfg", ("obj", "arm"), "bpose", "IsBPFG", "a base pose from which arm can grasp obj"),
        Skolem("gpfg", ("obj", "arm"), "gpose", "IsGPFG", "a gripper pose grasping obj (with pre-grasp and raise)"),
        Skolem("bpfpd", ("obj", "arm", "slot"), "bpose", "IsBPFPD", "a base pose from which arm can put obj down"),
        Skolem("gpfpd", ("obj", "arm", "slot"), "pdpose", "IsGPFPD", "a gripper pose putting obj down on the table"),
    ),
    geometric=("Obstructs", "PDObstructs"),
    actions=(
        ActionSpec(
            name="pick",
            # ?gp2: the other arm's grasp reference of ?o, so that the effect forgets what was learned
            # about grasping ?o where it stood, and a failed pick learns what blocks the other arm too.
            parameters=(("?o", "obj"), ("?arm", "arm"), ("?arm2", "arm"), ("?bp", "bpose"), ("?gp", "gpose"),
                        ("?gp2", "gpose")),
            precondition="""(and (HandEmpty ?arm) (OnTable ?o) (IsBPFG ?bp ?o ?arm) (IsGPFG ?gp ?o ?arm)
                                 (Other ?arm ?arm2) (IsGPFG ?gp2 ?o ?arm2)
                                 (forall (?b - obj) (not (Obstructs ?b ?gp))))""",
            effect="""(and (Holding ?o ?arm) (not (HandEmpty ?arm)) (not (OnTable ?o))
                           (forall (?p - gpose) (not (Obstructs ?o ?p)))
                           (forall (?p - pdpose) (not (PDObstructs ?o ?p)))
                           (forall (?b - obj) (and (not (Obstructs ?b ?gp)) (not (Obstructs ?b ?gp2)))))""",
            learn={"obstruction": ("(Obstructs ?blocker ?gp)", "(Obstructs ?blocker2 ?gp2)")},
            pose_generator="clutter:pick",
        ),
        ActionSpec(
            name="place",
            parameters=(("?o", "obj"), ("?arm", "arm"), ("?s", "slot"), ("?bp", "bpose"), ("?pd", "pdpose")),
            precondition="""(and (Holding ?o ?arm) (IsBPFPD ?bp ?o ?arm ?s) (IsGPFPD ?pd ?o ?arm ?s)
                                 (forall (?b - obj) (not (PDObstructs ?b ?pd))))""",
            effect="(and (not (Holding ?o ?arm)) (HandEmpty ?arm) (OnTable ?o))",
            learn={"obstruction": ("(PDObstructs ?blocker ?pd)",)},
            pose_generator="clutter:place",
        ),
    ),
)



def clutter_problem(layout: Layout, source: dict, name: str, slots: int = SLOTS, robot=None) -> Problem:
    from interlayer_manip.world import ManipulationGeometry

    geometry = ManipulationGeometry(layout, robot=robot)
    names = [o.name for o in layout.objects]
    slot_names = [f"s{k + 1}" for k in range(slots)]
    objects = {o: "obj" for o in names}
    arms = geometry.robot.arms
    objects.update({a: "arm" for a in arms})
    objects.update({s: "slot" for s in slot_names})
    # Other: each arm and another (a one-armed robot's arm is its own "other": pick's ?gp2 is then ?gp)
    init = {("HandEmpty", a) for a in arms} | {("Other", a, b) for a in arms for b in arms if a != b or len(arms) == 1}
    init |= {("OnTable", o) for o in names}
    t = layout.target
    goal = held_by_some_arm(t, arms)
    return Problem(CLUTTER_DOMAIN, objects, frozenset(init), goal, geometry, source, name=name)
