"""Registers the PR2 pick-and-place domain and its pose generators."""
from interlayer import hookimpl
from interlayer_manip.params import TIMING, timing

PARAMS = {"goal": "hold", "grasps": ["side"], "target_radius": 0.035, "clutter": 0, **TIMING}


def make_problem(params, seed):
    problem = _make_problem(params, seed)
    problem.geometry.layout.extra.update(timing(params))
    return problem


def _make_problem(params, seed):
    from interlayer.domain import Problem
    from interlayer.errors import UserError
    from interlayer_manip.state import ARMS
    from interlayer_manip.world import ManipulationGeometry

    from .domain import DOMAIN
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
    try:
        layout = make_layout(seed, goal, grasps, float(r), n)
    except ValueError as exc:
        raise UserError(f"problem.clutter={n}: {exc}; use fewer.") from None
    geometry = ManipulationGeometry(layout)
    objects = {o.name: "obj" for o in layout.objects}
    objects.update({a: "arm" for a in ARMS})
    objects.update({loc: "loc" for loc in layout.regions})
    objects["bp_init"] = "bpose"
    # reference name -> (skolem, args), so that move_base's generator knows what a base pose is for
    names = [o.name for o in layout.objects]
    for o in names:
        for a in ARMS:
            geometry.refs[f"bpfg_{o}_{a}"] = ("bpfg", (o, a))
            for loc in layout.regions:
                geometry.refs[f"bpfpd_{o}_{a}_{loc}"] = ("bpfpd", (o, a, loc))
    init = {("RobotAt", "bp_init")} | {("HandEmpty", a) for a in ARMS}
    init |= {("Loose", o) for o in names} | {("At", o, "table") for o in names}
    t = layout.target
    goal_formula = {"hold": f"(or (Holding {t} left) (Holding {t} right))",
                    "place": f"(At {t} goal_spot)",
                    # ... and nothing left in the hands: the blocker must be put down somewhere
                    "tidy": f"(and (At {t} goal_spot) (HandEmpty left) (HandEmpty right))"}[goal]
    return Problem(DOMAIN, objects, frozenset(init), goal_formula, geometry,
                   {"domain": "pr2", "params": dict(params), "seed": seed, "layout": layout.to_json()},
                   name=f"pr2-{goal}" + (f"-clutter{n}" if n else ""))


@hookimpl
def interlayer_register_domains(registry):
    registry.add("pr2", make_problem,
                 "a PR2 picks a cylinder from a cubby whose mouth another cylinder blocks (Fig. 3 actions, both arms)",
                 params=PARAMS, drawing="interlayer_manip.draw")


@hookimpl
def interlayer_register_pose_generators(registry):
    generators = "interlayer_manip.generators:"  # imported when selected

    registry.add("pr2:move_base", generators + "move_base", "base poses in an annulus around the object or put-down spot")
    registry.add("pr2:pick", generators + "pick", "side (and top) grasps with pre-grasp and raise waypoints, by IK")
    registry.add("pr2:place", generators + "place", "the put-down spot chosen by move_base and nearby variants, by IK")

