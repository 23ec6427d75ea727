"""Registers the domain ``panda_shelf``: the scene below, on the manipulation layer (``interlayer_manip``) with the
cubby pick's task model and pose generators. The robot is a description (``problem.robot``, default "panda")."""
from interlayer import hookimpl

PARAMS = {"goal": "target", "robot": "panda"}

# The Panda stands at the origin on a table whose top is z = 0. Boxes: name -> (size x, y, z), (x, y, yaw).
SHELF = {  # fixed: a roof, two sides and a back around the target
    "roof": ((0.32, 0.44, 0.02), (0.68, 0.0, 0.25)),
    "side_left": ((0.32, 0.02, 0.24), (0.68, 0.21, 0.12)),
    "side_right": ((0.32, 0.02, 0.24), (0.68, -0.21, 0.12)),
    "back": ((0.02, 0.44, 0.24), (0.85, 0.0, 0.12)),
}
BOXES = {  # movable, resting on the table
    "target": ((0.05, 0.05, 0.12), (0.66, 0.0, 0.0)),
    "blocker": ((0.05, 0.36, 0.14), (0.37, 0.0, 0.0)),  # across the shelf's mouth
    "other": ((0.05, 0.05, 0.12), (0.15, 0.45, 0.0)),
}
# xmin, xmax, ymin, ymax: "table" is the table's top in front of the robot, the goal region is on the right
REGIONS = {"table": (0.10, 0.90, -0.70, 0.70), "goal_spot": (0.30, 0.50, -0.50, -0.30)}


def layout(goal: str):
    from interlayer_manip.scene import REST_GAP, Layout, ObjectSpec

    fixed = [ObjectSpec("table", "box", (1.3, 1.6, 0.05), (0.35, 0.0, -0.025 - REST_GAP, 0.0), movable=False)]
    fixed += [ObjectSpec(n, "box", size, (x, y, z, 0.0), movable=False) for n, (size, (x, y, z)) in SHELF.items()]
    objects = [ObjectSpec(n, "box", size, (x, y, size[2] / 2 + REST_GAP, yaw))
               for n, (size, (x, y, yaw)) in BOXES.items()]
    return Layout(fixed, objects, dict(REGIONS), goal, "place", ("side", "top"), extra={"table_top": 0.0})


def make_problem(params, seed):
    from interlayer.errors import UserError
    from interlayer_manip.params import robot_for
    from interlayer_manip.world import load_robot
    from interlayer_pr2.plugin import cubby_problem

    if params["goal"] not in BOXES:
        raise UserError(f"problem.goal must be one of {', '.join(BOXES)} (the box to put into goal_spot), "
                        f"got {params['goal']!r}.")
    scene = layout(params["goal"])
    scene.extra["robot"] = params["robot"]
    return cubby_problem(scene, load_robot(robot_for(params, "panda_shelf"), scene.extra), "place",
                         {"domain": "panda_shelf", "params": dict(params), "seed": seed},
                         name=f"panda-shelf-{params['goal']}")


@hookimpl
def interlayer_register_domains(registry):
    registry.add("panda_shelf", make_problem,
                 "a Franka Panda (problem.robot) takes a box out of a shelf past a blocker into a goal region",
                 params=PARAMS, drawing="interlayer_manip.draw")
