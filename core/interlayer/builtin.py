"""Built-in components: the interpolating motion planner and the template failure translator."""
from . import hookimpl, logic


@hookimpl
def interlayer_register_motion_planners(registry):
    def make(options):
        from .motion import InterpolatingPlanner

        return InterpolatingPlanner(name="interpolate", time_limit=options.get("time_limit", 1.0), options=options)

    registry.add("interpolate", make, "straight line in configuration space, checked at the space's resolution")


def translate_by_templates(failure, step, model):
    """Turn a failure into the facts its action declares in ``learn[kind]`` (e.g. Obstructs)."""
    spec = model.problem.domain.action(step.action)
    templates = spec.learn.get(failure.kind, ())
    binding = model.binding(step)
    facts = set()
    for tpl in templates:
        pred = logic.parse(tpl)
        blockers = failure.objects if "?blocker" in pred.args else (None,)
        for blocker in blockers:
            b = dict(binding, **({"?blocker": blocker} if blocker else {}))
            facts.add(logic.ground_atom(pred, b))
    return facts


@hookimpl
def interlayer_register_failure_translators(registry):
    registry.add("templates", translate_by_templates,
                 "facts from each action's learn templates: Obstructs / PDObstructs for obstructions, ...")
