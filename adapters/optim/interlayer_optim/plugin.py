"""Registers ``ik:cartesian`` and ``trajopt``."""
import math

from interlayer import hookimpl

CARTESIAN_OPTIONS = {"time_limit": float, "step": float, "rot_step": float, "tolerance": float, "blend": float}
TRAJOPT_OPTIONS = {"time_limit": float, "waypoints": int, "safety": float, "inits": int, "iterations": int}
SHARED = {"time_limit", "simplify", "resolution"}  # [motion_planner] keys meant for every planner


def _options(name, options, known):
    from interlayer.errors import UserError

    unknown = set(options) - set(known) - SHARED
    if unknown:
        raise UserError(f"Unknown option(s) {sorted(unknown)} for motion planner '{name}'; valid: {', '.join(known)}.")
    out = {}
    for key, kind in known.items():
        if key in options:
            value = options[key]
            if isinstance(value, bool) or not isinstance(value, (int, float)) or not 0 < value < math.inf \
                    or (kind is int and value != int(value)):
                raise UserError(f"Option {key} of motion planner '{name}' must be a positive {kind.__name__}, got {value!r}.")
            out[key] = kind(value)
    return out


@hookimpl
def interlayer_register_motion_planners(registry):
    def cartesian(options):
        from .cartesian import CartesianPlanner

        return CartesianPlanner(**_options("ik:cartesian", options, CARTESIAN_OPTIONS), options=options)

    def trajopt(options):
        from .trajopt import TrajOptPlanner

        return TrajOptPlanner(**_options("trajopt", options, TRAJOPT_OPTIONS), options=options)

    registry.add("ik:cartesian", cartesian, "straight end-effector line by differential IK (approach, retreat)")
    registry.add("trajopt", trajopt, "trajectory optimisation: sequential convex programming (proxsuite), multi-init")
