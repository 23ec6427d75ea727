"""Registers the Drawer (O) / (N) domain (the paper's Sec. V-A; docs/drawer.md) and its pose generators."""
from interlayer import hookimpl

PARAMS = {"variant": "O", "robot": "pr2"}


def make_problem(params, seed):
    from interlayer.domain import Problem
    from interlayer.errors import UserError
    from interlayer_manip.params import held_by_some_arm, robot_for
    from interlayer_manip.state import OPEN_CLEARANCE
    from interlayer_manip.world import load_robot

    from .domain import DOMAIN
    from .scene import BASE_LIMITS, OUTER, make_layout
    from .world import DrawerGeometry

    variant = params["variant"]
    if variant not in ("O", "N"):
        raise UserError(f"problem.variant must be \"O\" (the outer object may stay) or \"N\" (it must be moved), "
                        f"got {variant!r}.")
    desc = robot_for(params, "pr2-drawer", mobile=True)  # the drawer's contents are reached from several sides
    name = params.get("robot", "pr2")
    robot = load_robot(desc, {"robot": name, "base_limits": BASE_LIMITS})
    # the outer object must fit the gripper (opened OPEN_CLEARANCE wider), or (N) has no plan
    layout = make_layout(seed, variant, outer_radius=min(OUTER[0], (robot.max_gripper_opening - OPEN_CLEARANCE) / 2))
    layout.extra["robot"] = name
    geometry = DrawerGeometry(layout, robot=robot)
    names = [o.name for o in layout.objects]
    objects = {o: "obj" for o in names}
    arms = geometry.robot.arms
    objects.update({a: "arm" for a in arms})
    objects.update({loc: "loc" for loc in layout.regions})
    objects["top_drawer"] = "drawer"
    objects["bp_init"] = "bpose"
    for a in arms:
        geometry.refs[f"bpfo_top_drawer_{a}"] = ("bpfo", ("top_drawer", a))
        for o in names:
            geometry.refs[f"bpfg_{o}_{a}"] = ("bpfg", (o, a))
            for loc in layout.regions:
                geometry.refs[f"bpfpd_{o}_{a}_{loc}"] = ("bpfpd", (o, a, loc))
    init = {("RobotAt", "bp_init"), ("In", "inner", "top_drawer")} | {("HandEmpty", a) for a in arms}
    init |= {("Loose", o) for o in names}
    goal = held_by_some_arm("inner", arms)
    return Problem(DOMAIN, objects, frozenset(init), goal, geometry,
                   {"domain": "pr2-drawer", "params": dict(params), "seed": seed, "layout": layout.to_json()},
                   name=f"drawer-{variant}")


@hookimpl
def interlayer_register_domains(registry):
    registry.add("pr2-drawer", make_problem,
                 "Drawer (O)/(N): a mobile robot (problem.robot, default the PR2) opens a drawer (a prismatic joint) and takes out the object in it; an object "
                 "on a stand in front stops the drawer (variant = \"N\": it must be moved first)", params=PARAMS)


@hookimpl
def interlayer_register_pose_generators(registry):
    generators = "interlayer_drawer.generators:"  # imported when selected

    registry.add("drawer:move_base", generators + "move_base", "base poses reaching the drawer's handle; else pr2:move_base")
    registry.add("drawer:open_drawer", generators + "open_drawer",
                 "random pull distances (stratified within the joint's limits), straight pull on the handle by IK")
    registry.add("drawer:pick", generators + "pick", "pr2:pick, once the object in the drawer is exposed for a top grasp")
