"""Registers the Gripper-2D domain and its pose generators."""
from interlayer import hookimpl

PARAMS = {"obstructions": 1, "s_occupied": False}


def make_problem(params, seed):
    from interlayer.domain import Problem
    from interlayer.errors import UserError

    from .domain import DOMAIN
    from .world import Gripper2DGeometry, make_layout

    k = params["obstructions"]
    if not isinstance(k, int) or isinstance(k, bool) or not 0 <= k <= 5:
        raise UserError(f"problem.obstructions must be an integer from 0 to 5 (blocks that fit the corridor), got {k!r}.")
    if not isinstance(params["s_occupied"], bool):
        raise UserError(f"problem.s_occupied must be true or false, got {params['s_occupied']!r}.")
    layout = make_layout(k, params["s_occupied"])
    blocks = sorted(layout.blocks)
    objects = {b: "block" for b in blocks}
    objects.update({"S": "region", "free": "region", "init_pose": "pose"})
    # Without ("Allowed", b2, "S") a planner may park b2 in S: picking b2 later deletes the learned
    # PDObstructs(b2, ...) facts and putting it back re-creates the obstruction unseen (the paper's
    # unmodelled side effects of put-down), so the loop could cycle.
    allowed = {("Allowed", b, "free") for b in blocks} | {("Allowed", "b1", "S")}
    init = frozenset({("Empty",), ("GripperAt", "init_pose")} | allowed)
    return Problem(DOMAIN, objects, init, "(InRegion b1 S)", Gripper2DGeometry(layout),
                   {"domain": "gripper2d", "params": dict(params), "seed": seed, "layout": layout.to_json()},
                   name=f"gripper2d-k{k}")


@hookimpl
def interlayer_register_domains(registry):
    registry.add("gripper2d", make_problem, "the paper's Fig. 2: b1 at the end of a corridor behind k obstructing blocks",
                 params=PARAMS, drawing="interlayer_gripper2d.draw")


@hookimpl
def interlayer_register_pose_generators(registry):
    generators = "interlayer_gripper2d.generators:"  # imported when selected

    registry.add("gripper2d:pick", generators + "pick", "face-aligned grasps with straight-line approaches")
    registry.add("gripper2d:place", generators + "place", "put-down spots in S or elsewhere on the table")
