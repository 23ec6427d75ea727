"""Built-in components: the breadth-first task planner, the interpolating motion planner and the template
failure translator."""
from . import hookimpl, logic
from .domain import GroundStep


@hookimpl
def interlayer_register_task_planners(registry):
    def make(options):
        from .errors import UserError
        from .planning import BreadthFirstPlanner

        unknown = sorted(set(options) - {"max_states"})
        limit = options.get("max_states", 100_000)
        if unknown or not isinstance(limit, int) or isinstance(limit, bool) or limit < 1:
            raise UserError(f"[task_planner.bfs] takes max_states, a positive whole number of states to expand "
                            f"(default 100000); got {', '.join(unknown) or repr(limit)}.")
        return BreadthFirstPlanner(name="bfs", options=dict(options))

    registry.add("bfs", make, "breadth-first search over the ground actions (no library; small problems, shortest plans)")


@hookimpl
def interlayer_register_motion_planners(registry):
    def make(options):
        from .motion import InterpolatingPlanner

        return InterpolatingPlanner(name="interpolate", time_limit=options.get("time_limit", 1.0), options=options)

    registry.add("interpolate", make, "straight line in configuration space, checked at the space's resolution")


def translate_by_templates(failure, step, model):
    """Turn a failure into the facts its action declares in ``learn[kind]`` (e.g. Obstructs): one per
    object bound to the template's ``?blocker...`` variable (``?blocker``: the failure's objects; others:
    ``failure.also``), or one fact for a template without such a variable. A negated template
    (``(not (Reachable ?p))``) gives ``logic.negated`` facts: the loop deletes them from the state. The
    failure's ``related`` failures (the same action with other objects) are translated alike."""
    spec = model.problem.domain.action(step.action)
    templates = spec.learn.get(failure.kind, ())
    binding = model.binding(step)
    also = failure.also_objects() if templates else {}
    facts = set()
    for tpl in templates:
        literal = logic.parse(tpl)
        pred = literal.arg if isinstance(literal, logic.Not) else literal

        def fact(b, negative=pred is not literal):
            atom = logic.ground_atom(pred, b)
            return logic.negated(atom) if negative else atom

        var = next((a for a in pred.args if a.startswith("?blocker")), None)
        if var is None:
            facts.add(fact(binding))
            continue
        for blocker in failure.objects if var == "?blocker" else also.get(var, ()):
            facts.add(fact(dict(binding, **{var: blocker})))
    for objects, other in failure.related_failures() if templates else ():
        facts |= translate_by_templates(other, objects if isinstance(objects, GroundStep) else model.step_with(step, objects),
                                        model)
    return facts


@hookimpl
def interlayer_register_failure_translators(registry):
    registry.add("templates", translate_by_templates,
                 "facts from each action's learn templates: Obstructs / PDObstructs for obstructions, ...")
