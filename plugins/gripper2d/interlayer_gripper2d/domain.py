"""Gripper-2D's task-level model: pick2D and place2D of Sec. III with pose references."""
from interlayer.domain import ActionSpec, DomainSpec, Skolem

DOMAIN = DomainSpec(
    name="gripper2d",
    types={"block": None, "region": None},
    continuous_types=("pose", "traj"),
    predicates={
        "Empty": (),
        "Holding": ("block",),
        "InRegion": ("block", "region"),
        "Allowed": ("block", "region"),  # static: S is only for the goal block, free space for any
        "GripperAt": ("pose",),
        "IsGP": ("pose", "block"),
        "IsPDP": ("pose", "block", "region"),
        "IsMP": ("traj", "pose", "pose"),
        "Obstructs": ("block", "pose", "block"),
        "PDObstructs": ("block", "pose", "block", "region"),
    },
    skolems=(
        Skolem("gp", ("block",), "pose", "IsGP", "a grasping pose for the block"),
        Skolem("pdp", ("block", "region"), "pose", "IsPDP", "a put-down pose for the block in the region"),
        Skolem("traj", ("pose", "pose"), "traj", "IsMP", "a motion plan between two poses"),
    ),
    geometric=("Obstructs", "PDObstructs"),
    actions=(
        ActionSpec(
            name="pick",
            parameters=(("?b", "block"), ("?p1", "pose"), ("?gp", "pose"), ("?t", "traj")),
            precondition="""(and (Empty) (GripperAt ?p1) (IsGP ?gp ?b) (IsMP ?t ?p1 ?gp)
                                 (forall (?o - block) (not (Obstructs ?o ?gp ?b))))""",
            effect="""(and (Holding ?b) (not (Empty)) (not (GripperAt ?p1)) (GripperAt ?gp)
                           (forall (?r - region) (not (InRegion ?b ?r)))
                           (forall (?o - block ?p - pose) (not (Obstructs ?b ?p ?o)))
                           (forall (?o - block ?p - pose ?r - region) (not (PDObstructs ?b ?p ?o ?r))))""",
            learn={"obstruction": ("(Obstructs ?blocker ?gp ?b)",)},
            pose_generator="gripper2d:pick",
        ),
        ActionSpec(
            name="place",
            parameters=(("?b", "block"), ("?r", "region"), ("?p1", "pose"), ("?pdp", "pose"), ("?t", "traj")),
            precondition="""(and (Holding ?b) (Allowed ?b ?r) (GripperAt ?p1) (IsPDP ?pdp ?b ?r) (IsMP ?t ?p1 ?pdp)
                                 (forall (?o - block) (not (PDObstructs ?o ?pdp ?b ?r))))""",
            effect="""(and (not (Holding ?b)) (Empty) (InRegion ?b ?r) (not (GripperAt ?p1)) (GripperAt ?pdp))""",
            learn={"obstruction": ("(PDObstructs ?blocker ?pdp ?b ?r)",)},
            pose_generator="gripper2d:place",
        ),
    ),
)
