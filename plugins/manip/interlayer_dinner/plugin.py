"""Registers the Dinner-N domain (the paper's Sec. V-C; docs/dinner.md) and its pose generators."""
from interlayer import hookimpl

PARAMS = {"objects": 4, "handoff": False, "side_costs": False, "robot": "pr2"}


def make_problem(params, seed):
    from interlayer.domain import Problem
    from interlayer.errors import UserError

    from interlayer_manip.params import robot_for

    from .domain import make_domain
    from .scene import ROOMS, make_layout
    from .world import DinnerGeometry

    n = params["objects"]
    if isinstance(n, bool) or not isinstance(n, int) or not 2 <= n <= 12 or n % 2:
        raise UserError(f"problem.objects must be an even number of cups and bowls from 2 to 12, got {n!r}.")
    for key in ("handoff", "side_costs"):
        if not isinstance(params[key], bool):
            raise UserError(f"problem.{key} must be true or false, got {params[key]!r}.")
    desc = robot_for(params, "dinner", two_arms=True, mobile=True)  # the tray takes both hands, the rooms a base
    if tuple(a.name for a in desc.arms) != ("left", "right"):
        raise UserError(f"The dinner domain's tray and hand-over are written for two arms named left and right (the "
                        f"robot's left is +y), and the {desc.name}'s are {', '.join(a.name for a in desc.arms)}; "
                        f"choose another problem.robot (e.g. \"pr2\").")
    try:
        layout = make_layout(seed, n)
    except ValueError as exc:
        raise UserError(f"problem.objects={n}: {exc}; use fewer objects or another seed.") from None
    layout.extra["robot"] = params.get("robot", "pr2")
    geometry = DinnerGeometry(layout)
    names = [o.name for o in layout.objects if o.name != "tray"]
    objects = {o: "obj" for o in names}
    objects.update({"left": "arm", "right": "arm", "side": "surface", "dinner": "surface"})
    objects.update({r: "room" for r in ROOMS})
    objects.update({f"set_{o}": "surface" for o in names})
    objects["tray"] = "loc"  # what stands on the tray; the pose generator picks a free slot
    init = {("RobotIn", "room_a"), ("Adjacent", "room_a", "room_b"), ("Adjacent", "room_b", "room_a"),
            ("HandEmpty", "left"), ("HandEmpty", "right"), ("TrayAt", "side"), ("TraySpot", "side"),
            ("TraySpot", "dinner"), ("LocIn", "side", "room_a"), ("LocIn", "dinner", "room_b")}
    init |= {("At", o, "side") for o in names} | {("Clear", o) for o in names}
    init |= {("LocIn", f"set_{o}", "room_b") for o in names} | {("Accepts", f"set_{o}", o) for o in names}
    init.add(("LocIn", "tray", "room_a"))
    if params["side_costs"]:
        init |= geometry.sides(names)
    if params["handoff"]:
        init |= {("Passable", o) for o in geometry.passable(names)}
    goal = "(and " + " ".join(f"(At {o} set_{o})" for o in names) + ")"
    domain = make_domain(handoff=params["handoff"], side_costs=params["side_costs"])
    return Problem(domain, objects, frozenset(init), goal, geometry,
                   {"domain": "dinner", "params": dict(params), "seed": seed, "layout": layout.to_json()},
                   name=f"dinner-{n}")


@hookimpl
def interlayer_register_domains(registry):
    registry.add("dinner", make_problem,
                 "Dinner-N: a PR2 lays out a dinner table in another room (moving between rooms costs 100): a tray "
                 "carried with both hands, stacking checked by a stackability module (objects = N)",
                 params=PARAMS, drawing="interlayer_manip.draw")


@hookimpl
def interlayer_register_pose_generators(registry):
    generators = "interlayer_dinner.generators:"  # imported when selected

    registry.add("dinner:go", generators + "go", "a base pose in the other room (jittered), reached through the doorway")
    registry.add("dinner:pick", generators + "pick", "base pose + grasp of the object (pick, take off the tray, unstack), by IK")
    registry.add("dinner:place", generators + "place",
                 "base pose + put-down at the fixed place (setting, a free tray slot, on top of the lower object), by IK")
    registry.add("dinner:pick_tray", generators + "pick_tray", "base pose facing the tray + both hands on its near edge")
    registry.add("dinner:place_tray", generators + "place_tray",
                 "the base pose that puts the carried tray at its spot on the table, and both hands' retreats")
    registry.add("dinner:handoff", generators + "handoff",
                 "a hand-over pose in front of the robot, the other hand's grasp there (IK) and the first hand's retreat")
