"""Registers the PR2 pick-and-place domain and its pose generators."""
from interlayer import hookimpl
from interlayer_manip.params import TIMING, held_by_some_arm, robot_for, timing

PARAMS = {"goal": "hold", "grasps": ["side"], "target_radius": 0.035, "clutter": 0, "robot": "pr2", **TIMING}


def make_problem(params, seed):
    problem = _make_problem(params, seed)
    problem.geometry.layout.extra.update(timing(params))
    return problem


def _make_problem(params, seed):
    from interlayer.errors import UserError
    from interlayer_manip.params import fixed_placement
    from interlayer_manip.placement import hand_width
    from interlayer_manip.state import OPEN_CLEARANCE, PADDING
    from interlayer_manip.world import load_robot

    from .scene import make_layout

    goal = params["goal"]
    if goal not in ("hold", "place", "tidy"):
        raise UserError(f"problem.goal must be \"hold\", \"place\" or \"tidy\", got {goal!r}.")
    grasps = params["grasps"]
    if not isinstance(grasps, list) or not grasps or any(g not in ("side", "top") for g in grasps):
        raise UserError(f"problem.grasps must be a non-empty list of \"side\" and \"top\", got {grasps!r}.")
    r = params["target_radius"]
    if not isinstance(r, (int, float)) or isinstance(r, bool) or not 0.01 <= r <= 0.1:
        raise UserError(f"problem.target_radius must be a number of metres from 0.01 to 0.1, got {r!r}.")
    n = params["clutter"]
    if not isinstance(n, int) or isinstance(n, bool) or not 0 <= n <= 12:
        raise UserError(f"problem.clutter must be an integer from 0 to 12 (extra cylinders on the table), got {n!r}.")
    desc = robot_for(params, "pr2")
    where = {"extra": {"robot": params.get("robot", "pr2")}}
    if not desc.mobile:  # the robot stands at the table's near edge (x = 0.6), mounted at its top's height
        kind = "top" if "top" in grasps else "side"
        base_x, reach = fixed_placement(desc, 0.6, 0.88, 0.0, 0.14 - 0.03 if kind == "top" else 0.07, kind)  # the target
        where = {"top": 0.0, "base": (base_x, 0.0, 0.0), "extra": {**where["extra"], "table_top": 0.0, "reach": reach}}
    robot = load_robot(desc, where["extra"])
    # the blocker must fit the gripper (opened OPEN_CLEARANCE wider), or nothing clears the cubby's mouth
    blocker = min(0.04, (robot.max_gripper_opening - OPEN_CLEARANCE) / 2)
    # ... and the cubby (inside: 0.12 m each side of its axis) the open hand, kept PADDING from its panels
    # (+ 5 mm: the objects' jitter)
    wider = max(0.0, max(hand_width(robot, a) for a in robot.arms) / 2 + PADDING + 0.005 - 0.12)
    try:
        layout = make_layout(seed, goal, grasps, float(r), n, blocker_radius=blocker, wider=wider, **where)
    except ValueError as exc:
        raise UserError(f"problem.clutter={n}: {exc}; use fewer.") from None
    return cubby_problem(layout, robot, goal, {"domain": "pr2", "params": dict(params), "seed": seed},
                         name=f"pr2-{goal}" + (f"-clutter{n}" if n else ""))


def cubby_problem(layout, robot, goal: str, source: dict, name: str):
    """The cubby pick's task model (domain.py) over ``layout`` for ``robot``: every object of the layout stands
    on the table; ``goal`` "hold" (some arm holds ``layout.target``), "place" (the target in the region
    goal_spot) or "tidy" (... and every hand empty). ``source`` names the domain that rebuilds the problem."""
    from interlayer.domain import Problem
    from interlayer_manip.world import ManipulationGeometry

    from .domain import DOMAIN

    geometry = ManipulationGeometry(layout, robot=robot)
    arms = geometry.robot.arms
    objects = {o.name: "obj" for o in layout.objects}
    objects.update({a: "arm" for a in arms})
    objects.update({loc: "loc" for loc in layout.regions})
    objects["bp_init"] = "bpose"
    # reference name -> (skolem, args), so that move_base's generator knows what a base pose is for
    names = [o.name for o in layout.objects]
    for o in names:
        for a in arms:
            geometry.refs[f"bpfg_{o}_{a}"] = ("bpfg", (o, a))
            for loc in layout.regions:
                geometry.refs[f"bpfpd_{o}_{a}_{loc}"] = ("bpfpd", (o, a, loc))
    init = {("RobotAt", "bp_init")} | {("HandEmpty", a) for a in arms}
    init |= {("Loose", o) for o in names} | {("At", o, "table") for o in names}
    t = layout.target
    empty = " ".join(f"(HandEmpty {a})" for a in arms)
    goal_formula = {"hold": held_by_some_arm(t, arms),
                    "place": f"(At {t} goal_spot)",
                    # ... and nothing left in the hands: the blocker must be put down somewhere
                    "tidy": f"(and (At {t} goal_spot) {empty})"}[goal]
    return Problem(DOMAIN, objects, frozenset(init), goal_formula, geometry, {**source, "layout": layout.to_json()},
                   name=name)


@hookimpl
def interlayer_register_domains(registry):
    registry.add("pr2", make_problem,
                 "a robot (problem.robot, default the PR2) picks a cylinder from a cubby whose mouth another cylinder "
                 "blocks (Fig. 3 actions, every arm)",
                 params=PARAMS, drawing="interlayer_manip.draw")


@hookimpl
def interlayer_register_pose_generators(registry):
    generators = "interlayer_manip.generators:"  # imported when selected

    registry.add("pr2:move_base", generators + "move_base",
                 "base poses from which the arm reaches the object or put-down spot (reachmap.py), by IK")
    registry.add("pr2:pick", generators + "pick", "side (and top) grasps with pre-grasp and raise waypoints, by IK")
    registry.add("pr2:place", generators + "place", "the put-down spot chosen by move_base and nearby variants, by IK")

