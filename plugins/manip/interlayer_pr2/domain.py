"""The PR2's task-level model (Fig. 3, ambidextrous): move_base, pick and place with pose references.

Pose references (Skolem functions, App. A), subtyped so that no predicate ranges over all of them:

* ``bpfg_<obj>_<arm>``        (bpose)  base pose for grasping obj with arm        IsBPFG
* ``gpfg_<obj>_<arm>``        (gpose)  gripper pose for grasping obj with arm     IsGPFG
* ``bpfpd_<obj>_<arm>_<loc>`` (bpose)  base pose for putting obj down at loc      IsBPFPD
* ``gpfpd_<obj>_<arm>_<loc>`` (pdpose) gripper pose for putting obj down at loc   IsGPFPD

``loc`` objects are put-down surfaces/regions (``table``: anywhere free on the table, ``goal_spot``);
the concrete target location (tloc) is sampled by the pose generators. ``bp_init`` is the robot's
initial base pose. move_base has no ``?from`` parameter (its effect deletes every RobotAt), so it
grounds linearly in the number of base-pose references, which matters for Clutter-N.
Obstructs / PDObstructs occur only negatively (Prop. 1 default: false) and are learned from
motion-planning failures; picking an object deletes every obstruction it causes. ``NoBase`` (also
negative-only) is learned when a base pose's generator yields nothing (the object fits no spot of the loc)
and forgotten when any object is picked or put down.
"""
from interlayer.domain import ActionSpec, DomainSpec, Skolem
from interlayer.refine import NO_CANDIDATES

DOMAIN = DomainSpec(
    name="pr2",
    types={"obj": None, "arm": None, "loc": None},
    continuous_types=("bpose", "gpose", "pdpose"),
    predicates={
        "RobotAt": ("bpose",),
        "HandEmpty": ("arm",),
        "Holding": ("obj", "arm"),
        "Loose": ("obj",),  # resting on a surface (not held)
        "At": ("obj", "loc"),
        "IsBPFG": ("bpose", "obj", "arm"),
        "IsGPFG": ("gpose", "obj", "arm"),
        "IsBPFPD": ("bpose", "obj", "arm", "loc"),
        "IsGPFPD": ("pdpose", "obj", "arm", "loc"),
        # (blocker, pose): the pose reference already names the object (and the loc) it is for, so the
        # object argument of Fig. 3 is left out: N x 2N + N x 4N groundings instead of N times more.
        "Obstructs": ("obj", "gpose"),
        "PDObstructs": ("obj", "pdpose"),
        # the base pose's generator yielded nothing (e.g. the object fits no spot of the loc) while nothing
        # moved: learned from an empty generator, forgotten when an object is picked or put down
        "NoBase": ("bpose",),
    },
    skolems=(
        Skolem("bpfg", ("obj", "arm"), "bpose", "IsBPFG", "a base pose from which arm can grasp obj"),
        Skolem("gpfg", ("obj", "arm"), "gpose", "IsGPFG", "a gripper pose grasping obj (with pre-grasp and raise)"),
        Skolem("bpfpd", ("obj", "arm", "loc"), "bpose", "IsBPFPD", "a base pose from which arm can put obj down at loc"),
        Skolem("gpfpd", ("obj", "arm", "loc"), "pdpose", "IsGPFPD", "a gripper pose putting obj down at a spot of loc"),
    ),
    geometric=("Obstructs", "PDObstructs", "NoBase"),
    actions=(
        ActionSpec(
            name="move_base",
            parameters=(("?to", "bpose"),),
            precondition="(not (NoBase ?to))",
            effect="(and (forall (?p - bpose) (not (RobotAt ?p))) (RobotAt ?to))",
            learn={NO_CANDIDATES: ("(NoBase ?to)",)},
            pose_generator="pr2:move_base",
        ),
        ActionSpec(
            name="pick",
            parameters=(("?o", "obj"), ("?arm", "arm"), ("?bp", "bpose"), ("?gp", "gpose")),
            precondition="""(and (HandEmpty ?arm) (Loose ?o) (RobotAt ?bp) (IsBPFG ?bp ?o ?arm) (IsGPFG ?gp ?o ?arm)
                                 (forall (?b - obj) (not (Obstructs ?b ?gp))))""",
            effect="""(and (Holding ?o ?arm) (not (HandEmpty ?arm)) (not (Loose ?o))
                           (forall (?l - loc) (not (At ?o ?l)))
                           (forall (?p - gpose) (not (Obstructs ?o ?p)))
                           (forall (?p - pdpose) (not (PDObstructs ?o ?p)))
                           (forall (?p - bpose) (not (NoBase ?p))))""",
            learn={"obstruction": ("(Obstructs ?blocker ?gp)",)},
            pose_generator="pr2:pick",
        ),
        ActionSpec(
            name="place",
            parameters=(("?o", "obj"), ("?arm", "arm"), ("?l", "loc"), ("?bp", "bpose"), ("?pd", "pdpose")),
            precondition="""(and (Holding ?o ?arm) (RobotAt ?bp) (IsBPFPD ?bp ?o ?arm ?l) (IsGPFPD ?pd ?o ?arm ?l)
                                 (forall (?b - obj) (not (PDObstructs ?b ?pd))))""",
            effect="""(and (not (Holding ?o ?arm)) (HandEmpty ?arm) (Loose ?o) (At ?o ?l)
                           (forall (?p - bpose) (not (NoBase ?p))))""",
            learn={"obstruction": ("(PDObstructs ?blocker ?pd)",)},
            pose_generator="pr2:place",
        ),
    ),
)
