"""Registers ``ompl:<Planner>`` for each geometric planner OMPL's Python bindings expose."""
import importlib.util

from interlayer import hookimpl

# The geometric planners bound by ompl 2.0.1's nanobind bindings.
PLANNERS = ("RRTConnect", "RRT", "RRTstar", "PRM", "PRMstar", "KPIECE1", "BKPIECE1", "LBKPIECE1",
            "BITstar", "FMT", "BFMT", "InformedRRTstar", "SORRTstar", "AORRTC")


def _factory(name):
    def make(options):
        from interlayer.errors import UserError

        from .planner import OMPLPlanner

        opts = dict(options)
        unknown = set(opts) - {"time_limit", "simplify", "resolution"}
        if unknown:
            raise UserError(f"Unknown option(s) {sorted(unknown)} for motion planner 'ompl:{name}'; valid: time_limit, simplify.")
        return OMPLPlanner(name, time_limit=float(opts.get("time_limit", 1.0)), simplify=bool(opts.get("simplify", True)),
                           options=opts)

    return make


@hookimpl
def interlayer_register_motion_planners(registry):
    for name in PLANNERS:
        label = f"ompl:{name}"
        if importlib.util.find_spec("ompl") is None:
            registry.unavailable(label, "the Python package 'ompl' is not installed")
        else:
            registry.add(label, _factory(name), f"OMPL geometric planner {name}")
