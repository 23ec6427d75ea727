"""The task encoding of pybullet-planning problems: ``pr2-pbjson``, Clutter's encoding with named surfaces.

Like Clutter's (see interlayer_clutter.domain), ``move_base`` is folded into pick and place and
obstructions are learned with two arguments. What it adds:

* ``surf`` objects: the tables, regions, sinks and stoves of the file, and ``<obj>_top`` for objects that
  others stand on (stacking). ``(On ?o ?s)`` says where an object rests; place puts ?o on ?s through
  the references ``bpfpd_<o>_<arm>_<surf>_<slot>`` / ``gpfpd_...``, whose pose generator samples a
  stable placement on that surface (inside its polygon, clear of fixed obstacles and other objects).
* ``place_at_goal`` puts an object at its goal pose (``goal_poses``, "initial" included): references
  ``bpfgp_<o>_<arm>`` / ``gpfgp_<o>_<arm>``; ``(AtGoalPose ?o)`` holds until the object is picked.
  ``(Occupies ?b ?o)``: ?b stands where ?o's goal pose is (read off the start, like ``On``); ?o cannot
  be put there until ?b is picked. Put-downs keep off goal poses, so nothing comes to occupy one later.
  Without it the task planner learns each occupant only after a failed put-down, typically with both
  hands already full of objects whose goal poses are occupied (rearrangement: a permutation of poses).
* ``(NoGrasp ?gp)``: the pick generator found no grasp for the reference ?gp = ``gpfg_<o>_<arm>`` (a
  failure of kind ``no_candidates``). Its candidates are sampled once per object pose in an epoch
  and checked against fixed obstacles only (IK, the arm's and the base's collisions; the base with
  the other arm as it is), so the verdict holds for that arm while ?o stands where it is, whatever
  other objects do; picking ?o with the other arm (the only way it moves) deletes it, and a reset
  forgets it with every learned fact, to be sampled anew. It lets a goal with a choice (hold any one
  of a class) turn to another object or arm instead of giving up. When every grasp of ?o where it
  stands puts the hand into fixed obstacles (``hand_blockers``, a proof over the finite grasp set of a
  box), the pick fails as ``ungraspable``: NoGrasp for both arms, a ``lasting`` fact that no reset
  forgets (?o can only move by a pick), so the task planner proves the goal unreachable if it needs ?o.
* ``(BadGrasp ?o ?pd)``: the grasp ?o is held with cannot put it at its goal pose ?pd = ``gpfgp_<o>_<arm>``,
  and another grasp could (a failure of kind ``held_grasp``: every goal variant puts the hand into a
  fixed obstacle, and a grasp of another side or kind is clear there). Picking ?o again deletes it, so
  the task planner puts ?o down and takes it again (regrasp); the pick generator then offers first the
  grasps that fit at the goal.
* ``(GoalObstructs ?b ?gp)`` / ``(GoalPDObstructs ?b ?pd)``: ?b, standing at its goal pose, was in the way
  of the grasp ?gp (of the put-down at the goal ?pd), learned beside Obstructs / PDObstructs. Picking ?b
  does not forget it: while ?b stands at its goal (AtGoalPose), that pick (put-down) waits, so the task
  planner moves ?o before it puts ?b back (rearrangement: ?b went back to its goal, into the way again,
  replan after replan). Picking ?o forgets its GoalObstructs (its grasps change with its pose).
* kitchen semantics as conditional effects: placing on a sink cleans, placing a clean object on a
  stove cooks.
* ``go_home`` drives the base back to its start and the empty arms to their start configuration
  (``goal_config: "initial"``). It is the plan's last action: it adds ``(AtHome)`` and nothing may
  pick or place after it (a satisficing planner otherwise goes home between picks). ``go_to`` is the
  same for a base pose goal (``goal_config: [x, y, yaw]``): it drives there and adds ``(AtBaseGoal)``.

Only what a file needs is in its domain (no sinks: no cleaning effect; no goal poses: no place_at_goal),
so a holding-only file such as the paper's table grounds like Clutter-N.
"""
from __future__ import annotations

from interlayer.domain import ActionSpec, DomainSpec, Skolem
from interlayer.refine import NO_CANDIDATES

SLOTS = 2
HELD_GRASP = "held_grasp"  # the failure kind of a put-down at the goal that another grasp could do (BadGrasp)
UNGRASPABLE = "ungraspable"  # the failure kind of a pick of an object that no grasp can take where it stands
STUCK = "stuck"  # a candidate's value: (objects, sentence) of a put-down that only objects no grasp can move block


def pbjson_domain(tops: bool, goal_poses: bool, sinks: bool, stoves: bool, home: bool, go_to: bool = False,
                  floor: bool = False) -> DomainSpec:
    preds = {
        "HandEmpty": ("arm",), "Other": ("arm", "arm"), "Holding": ("obj", "arm"), "Resting": ("obj",),
        "On": ("obj", "surf"),
        "IsBPFG": ("bpose", "obj", "arm"), "IsGPFG": ("gpose", "obj", "arm"),
        "IsBPFPD": ("bpose", "obj", "arm", "surf", "slot"), "IsGPFPD": ("pdpose", "obj", "arm", "surf", "slot"),
        "Obstructs": ("obj", "gpose"), "PDObstructs": ("obj", "pdpose"), "NoGrasp": ("gpose",),
    }
    # with floor obstacles, ``item``s are what the gripper can hold (pose references exist for them only),
    # ``floor`` obstacles the ones it cannot; both are ``obj``s (they obstruct alike); floor obstacles of
    # either kind are ``Pushable`` (an item: until it is picked)
    it = "item" if floor else "obj"
    skolems = [
        Skolem("bpfg", (it, "arm"), "bpose", "IsBPFG", "a base pose from which arm can grasp obj"),
        Skolem("gpfg", (it, "arm"), "gpose", "IsGPFG", "a gripper pose grasping obj (with pre-grasp and raise)"),
        Skolem("bpfpd", (it, "arm", "surf", "slot"), "bpose", "IsBPFPD", "a base pose from which arm can put obj on surf"),
        Skolem("gpfpd", (it, "arm", "surf", "slot"), "pdpose", "IsGPFPD", "a gripper pose putting obj on a stable spot of surf"),
    ]
    pick_pre = ["(HandEmpty ?arm)", "(Resting ?o)", "(IsBPFG ?bp ?o ?arm)", "(IsGPFG ?gp ?o ?arm)", "(Other ?arm ?arm2)",
                "(IsGPFG ?gp2 ?o ?arm2)", "(forall (?b - obj) (not (Obstructs ?b ?gp)))", "(not (NoGrasp ?gp))"]
    pick_eff = ["(Holding ?o ?arm)", "(not (HandEmpty ?arm))", "(not (Resting ?o))", "(forall (?s - surf) (not (On ?o ?s)))",
                "(forall (?p - gpose) (not (Obstructs ?o ?p)))", "(forall (?p - pdpose) (not (PDObstructs ?o ?p)))",
                "(forall (?b - obj) (and (not (Obstructs ?b ?gp)) (not (Obstructs ?b ?gp2))))", "(not (NoGrasp ?gp2))"]
    place_pre = ["(Holding ?o ?arm)", "(IsBPFPD ?bp ?o ?arm ?s ?sl)", "(IsGPFPD ?pd ?o ?arm ?s ?sl)",
                 "(forall (?b - obj) (not (PDObstructs ?b ?pd)))"]
    place_eff = ["(not (Holding ?o ?arm))", "(HandEmpty ?arm)", "(Resting ?o)", "(On ?o ?s)"]
    if tops:  # nothing is picked from under another object; an object's top holds only while it rests
        preds["TopOf"] = ("surf", "obj")
        pick_pre.append("(forall (?s - surf) (or (not (TopOf ?s ?o)) (forall (?b - obj) (not (On ?b ?s)))))")
        place_pre.append("(forall (?x - obj) (or (not (TopOf ?s ?x)) (Resting ?x)))")
    if sinks:
        preds.update({"Sink": ("surf",), "Cleaned": ("obj",)})
        place_eff.append("(when (Sink ?s) (Cleaned ?o))")
    if stoves:
        preds.update({"Stove": ("surf",), "Cooked": ("obj",)})
        preds.setdefault("Cleaned", ("obj",))
        place_eff.append("(when (and (Stove ?s) (Cleaned ?o)) (Cooked ?o))")
    final = "go_home" if home else "go_to" if go_to else None  # the last action, and the fact it adds
    done = {"go_home": "AtHome", "go_to": "AtBaseGoal"}.get(final)
    if done:
        preds[done] = ()
        pick_pre.append(f"(not ({done}))")
        place_pre.append(f"(not ({done}))")
    if floor:  # obstacles standing on the floor (floor_object_names): what blocks the base is learned from drives
        preds.update({"BaseObstructs": ("obj", "bpose"), "FinalClear": ("obj",), "PushBlocked": ("obj", "obj"),
                      "Pushable": ("obj",), "InLine": ("obj", "obj")})
        pick_pre.append("(forall (?f - obj) (not (BaseObstructs ?f ?bp)))")
        place_pre.append("(forall (?f - obj) (not (BaseObstructs ?f ?bp)))")
        pick_eff += ["(forall (?p - bpose) (not (BaseObstructs ?o ?p)))", "(FinalClear ?o)",
                     "(forall (?x - obj) (not (PushBlocked ?o ?x)))", "(not (Pushable ?o))"]
    drive_learn = {"base_obstruction": ("(BaseObstructs ?blocker ?bp)",)} if floor else {}
    if goal_poses:
        preds.update({"AtGoalPose": ("obj",), "HasGoalPose": ("obj",), "IsBPFGP": ("bpose", "obj", "arm"),
                      "IsGPFGP": ("pdpose", "obj", "arm")})
        skolems += [Skolem("bpfgp", (it, "arm"), "bpose", "IsBPFGP", "a base pose from which arm can put obj at its goal pose"),
                    Skolem("gpfgp", (it, "arm"), "pdpose", "IsGPFGP", "a gripper pose putting obj at its goal pose")]
        preds.update({"Occupies": ("obj", "obj"), "BadGrasp": ("obj", "pdpose"), "GoalObstructs": ("obj", "gpose"),
                      "GoalPDObstructs": ("obj", "pdpose")})
        # an obstruction by an object at its goal pose comes back when that object is put there again: while
        # it stands there, the pick (the put-down at the goal) it blocked waits
        pick_pre.append("(forall (?b - obj) (or (not (GoalObstructs ?b ?gp)) (not (AtGoalPose ?b))))")
        pick_eff += ["(not (AtGoalPose ?o))", "(forall (?x - obj) (not (Occupies ?o ?x)))",
                     "(forall (?p - pdpose) (not (BadGrasp ?o ?p)))",  # a new grasp
                     "(forall (?b - obj) (and (not (GoalObstructs ?b ?gp)) (not (GoalObstructs ?b ?gp2))))"]
    actions = [
        ActionSpec(
            name="pick",
            # ?gp2: the other arm's grasp reference of ?o (as in Clutter's pick: forgotten by the effect,
            # learned by a failure)
            parameters=(("?o", it), ("?arm", "arm"), ("?arm2", "arm"), ("?bp", "bpose"), ("?gp", "gpose"),
                        ("?gp2", "gpose")),
            precondition=f"(and {' '.join(pick_pre)})", effect=f"(and {' '.join(pick_eff)})",
            learn={"obstruction": ("(Obstructs ?blocker ?gp)", "(Obstructs ?blocker2 ?gp2)",
                                   *(("(GoalObstructs ?blocker_at_goal ?gp)", "(GoalObstructs ?blocker2_at_goal ?gp2)")
                                     if goal_poses else ())),
                   NO_CANDIDATES: ("(NoGrasp ?gp)",), UNGRASPABLE: ("(NoGrasp ?gp)", "(NoGrasp ?gp2)"), **drive_learn},
            pose_generator="pbjson:pick"),
        ActionSpec(
            name="place",
            parameters=(("?o", it), ("?arm", "arm"), ("?s", "surf"), ("?sl", "slot"), ("?bp", "bpose"), ("?pd", "pdpose")),
            precondition=f"(and {' '.join(place_pre)})", effect=f"(and {' '.join(place_eff)})",
            learn={"obstruction": ("(PDObstructs ?blocker ?pd)",), **drive_learn}, pose_generator="pbjson:place"),
    ]
    if goal_poses:
        actions.append(ActionSpec(
            name="place_at_goal",
            parameters=(("?o", it), ("?arm", "arm"), ("?bp", "bpose"), ("?pd", "pdpose")),
            precondition=f"""(and (Holding ?o ?arm) (HasGoalPose ?o) (IsBPFGP ?bp ?o ?arm) (IsGPFGP ?pd ?o ?arm)
                                  (forall (?b - obj) (and (not (PDObstructs ?b ?pd)) (not (Occupies ?b ?o))))
                                  (not (BadGrasp ?o ?pd))
                                  (forall (?b - obj) (or (not (GoalPDObstructs ?b ?pd)) (not (AtGoalPose ?b))))
                                  {f'(not ({done}))' if done else ''}
                                  {'(forall (?f - obj) (not (BaseObstructs ?f ?bp)))' if floor else ''})""",
            effect="(and (not (Holding ?o ?arm)) (HandEmpty ?arm) (Resting ?o) (AtGoalPose ?o))",
            learn={"obstruction": ("(PDObstructs ?blocker ?pd)", "(GoalPDObstructs ?blocker_at_goal ?pd)"),
                   HELD_GRASP: ("(BadGrasp ?o ?pd)",), **drive_learn},
            pose_generator="pbjson:place"))
    if done:
        clear = " (forall (?f - obj) (FinalClear ?f))" if floor else ""
        actions.append(ActionSpec(name=final, parameters=(), precondition=f"(and (not ({done})){clear})", effect=f"({done})",
                                  learn={"base_obstruction": ("(not (FinalClear ?blocker))",)} if floor else {},
                                  pose_generator=f"pbjson:{final}"))
    if floor:
        # the base pushes ?f along a straight line (the pose generator picks it): whatever ?f blocked, it no
        # longer does; what it blocks where it ends up is learned again from the failures it causes there. A
        # push may carry along the floor obstacles ?f meets head on (InLine, from the start poses): their drive
        # facts are forgotten too, and relearned where they still block a drive
        moved = """(FinalClear ?x) (forall (?p - bpose) (not (BaseObstructs ?x ?p)))
                   (forall (?y - obj) (and (not (PushBlocked ?x ?y)) (not (PushBlocked ?y ?x))))"""
        actions.append(ActionSpec(
            name="push", parameters=(("?f", "obj"),),
            precondition=f"(and (Pushable ?f) (Resting ?f) (forall (?b - obj) (not (PushBlocked ?b ?f))){f' (not ({done}))' if done else ''})",
            effect=f"""(and (forall (?p - bpose) (not (BaseObstructs ?f ?p))) (FinalClear ?f)
                          (forall (?p - gpose) (not (Obstructs ?f ?p))) (forall (?p - pdpose) (not (PDObstructs ?f ?p)))
                          (forall (?x - obj) (not (PushBlocked ?f ?x)))
                          (forall (?x - obj) (when (InLine ?f ?x) (and {moved}))))""",
            # no push of ?f: every side of it is against a wall or out of the base's reach (fixed obstacles
            # only: true while ?f stands there, forgotten at a reset)
            learn={"base_obstruction": ("(PushBlocked ?blocker ?f)",), "obstruction": ("(PushBlocked ?blocker ?f)",),
                   NO_CANDIDATES: ("(not (Pushable ?f))",)},
            pose_generator="pbjson:push"))
    return DomainSpec(
        name="pr2-pbjson",
        types={"obj": None, "arm": None, "surf": None, "slot": None, **({"item": "obj", "floor": "obj"} if floor else {})},
        continuous_types=("bpose", "gpose", "pdpose"),
        predicates=preds,
        skolems=tuple(skolems),
        geometric=("Obstructs", "PDObstructs", "NoGrasp", *(("BadGrasp", "GoalObstructs", "GoalPDObstructs") if goal_poses else ()),
                   *(("BaseObstructs",) if floor else ())),
        actions=tuple(actions),
    )
