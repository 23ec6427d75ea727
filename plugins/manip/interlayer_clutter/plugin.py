"""Registers Clutter-N (the paper's cluttered table) and its pose generators."""
from interlayer import hookimpl

PARAMS = {"objects": 15, "approach": "free", "robot": "pr2"}


def make_problem(params, seed):
    from interlayer_manip.params import timing

    from .scene import make_clutter_problem

    problem = make_clutter_problem(params, seed)
    problem.geometry.layout.extra.update(timing(params))
    return problem


@hookimpl
def interlayer_register_domains(registry):
    from interlayer_manip.params import TIMING

    registry.add("clutter", make_problem,
                 "the paper's cluttered table (Clutter-N): a robot (problem.robot, default the PR2) must hold one of N "
                 "cylinders, clearing those in the way",
                 params={**PARAMS, **TIMING}, drawing="interlayer_manip.draw")


@hookimpl
def interlayer_register_pose_generators(registry):
    sampler = "interlayer_clutter.samplers:ClutterSampler"  # imported when selected
    registry.add("clutter:pick", sampler, "clutter: base pose + side grasp (move_base folded in), fewest objects in the way first")
    registry.add("clutter:place", sampler, "clutter: a free table spot far from the target and others + base pose, by IK")
