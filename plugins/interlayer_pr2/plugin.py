"""Registers the PR2 pick-and-place domain and its pose generators."""
import math

from interlayer import hookimpl

# Trajectory timing (TOPP-RA): arm joints at most their URDF velocity limits; PR2 domains may accept these keys too.
TIMING = {"arm_acceleration": 1.5,  # rad/s^2, every arm joint
          "base_velocity": [0.5, 0.5, 1.0],  # m/s, m/s, rad/s (x, y, theta; the URDF gives none)
          "base_acceleration": [0.5, 0.5, 1.0]}  # m/s^2, m/s^2, rad/s^2
PARAMS = {"goal": "hold", "grasps": ["side"], "target_radius": 0.035, "clutter": 0, **TIMING}


def make_problem(params, seed):
    problem = _make_problem(params, seed)
    problem.geometry.layout.extra.update(timing(params))
    return problem


def timing(params):
    """The timing keys, checked: positive numbers (three for the base: x, y, theta)."""
    from interlayer.errors import UserError

    out = {}
    for key, n in (("arm_acceleration", 1), ("base_velocity", 3), ("base_acceleration", 3)):
        value = params.get(key, TIMING[key])
        items = value if n > 1 and isinstance(value, list) else [value]
        if len(items) != n or any(isinstance(v, bool) or not isinstance(v, (int, float)) or not 0 < v < math.inf
                                  for v in items):
            what = "a positive number" if n == 1 else "a list of three positive numbers (x, y, theta)"
            raise UserError(f"problem.{key} must be {what}, got {value!r}.")
        out[key] = value
    return out


def _make_problem(params, seed):
    from interlayer.domain import Problem
    from interlayer.errors import UserError

    from .domain import DOMAIN
    from .scene import make_layout
    from .world import ARMS, PR2Geometry

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
    geometry = PR2Geometry(layout)
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
                 params=PARAMS, drawing="interlayer_pr2.draw")


@hookimpl
def interlayer_register_pose_generators(registry):
    generators = "interlayer_pr2.generators:"  # imported when selected

    registry.add("pr2:move_base", generators + "move_base", "base poses in an annulus around the object or put-down spot")
    registry.add("pr2:pick", generators + "pick", "side (and top) grasps with pre-grasp and raise waypoints, by IK")
    registry.add("pr2:place", generators + "place", "the put-down spot chosen by move_base and nearby variants, by IK")

