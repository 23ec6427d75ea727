"""A third-party plugin, as a separate distribution would ship it: a motion planner and a translator.

Its entry point is declared in interlayer_hello-0.1.dist-info/entry_points.txt beside this file.
"""
from interlayer import hookimpl


@hookimpl
def interlayer_register_motion_planners(registry):
    def make(options):
        from interlayer.motion import InterpolatingPlanner

        class Waypoint(InterpolatingPlanner):
            """Goes through the configuration space's centre line first: a detour, but a real planner."""

            def _plan(self, space, start, goal, is_valid, time_limit):
                for path in ([start, goal], [start, (start + goal) / 2 - [0, 0.3, 0], goal]):
                    if all(super(Waypoint, self)._plan(space, a, b, is_valid, time_limit) for a, b in zip(path, path[1:])):
                        return path
                return None

        return Waypoint(name="hello:waypoint", time_limit=options.get("time_limit", 1.0))

    registry.add("hello:waypoint", make, "straight line, or one detour waypoint")


@hookimpl
def interlayer_register_failure_translators(registry):
    def blocked(failure, step, model):
        return {("Blocked", o) for o in failure.objects} & set()  # records nothing; shows the hook

    registry.add("hello:blocked", blocked, "an extra translator (adds no facts)")
