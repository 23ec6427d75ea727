"""Reads pybullet-planning JSON problem files (bodies / robots / task) and registers their pose generators."""
from interlayer import hookimpl


@hookimpl
def interlayer_load_problem(path, params, seed):
    """The problem of a pybullet-planning JSON file; None for anything else."""
    from .loader import load_pybullet_json, looks_like_pybullet_json

    data = looks_like_pybullet_json(path)
    if data is None:
        return None
    return load_pybullet_json(path, data, params, seed)


@hookimpl
def interlayer_register_pose_generators(registry):
    samplers = "interlayer_pbjson.samplers:"  # imported when selected

    registry.add("pbjson:pick", samplers + "PBSampler", "pybullet-planning files: Clutter's pick (base pose + grasp, fewest objects in the way first)")
    registry.add("pbjson:place", samplers + "PBSampler", "pybullet-planning files: a stable spot on the step's surface or region, "
                                            "or the goal pose, + base pose, by IK")
    registry.add("pbjson:go_home", samplers + "go_home", "pybullet-planning files: the robot's start configuration (goal_config)")
    registry.add("pbjson:go_to", samplers + "go_to", "pybullet-planning files: the base pose goal (goal_config: [x, y, yaw])")
    registry.add("pbjson:push", samplers + "push", "pybullet-planning files: the base pushes a floor obstacle straight "
                                                   "ahead (a side of it, a length), off the drives it blocked")
