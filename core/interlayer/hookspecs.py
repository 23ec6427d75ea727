"""Hook specifications: what a plugin can contribute. Every hook is prefixed ``interlayer_``.

Plugins implement hooks with ``@interlayer.hookimpl`` and are found through the entry-point group
``interlayer.plugins`` (the built-in plugins use it too). Components are registered by name into
registries and then selected by name from a config file.
"""
import pluggy

hookspec = pluggy.HookspecMarker("interlayer")


@hookspec
def interlayer_register_task_planners(registry):
    """Register task planners: ``registry.add(name, factory, description)``.

    ``factory(options: dict) -> interlayer.planning.TaskPlanner``; ``registry.unavailable(name,
    reason)`` records one that cannot run here (e.g. a missing engine).

    :param registry: the task-planner registry.
    """


@hookspec
def interlayer_register_motion_planners(registry):
    """Register motion planners: ``factory(options: dict) -> interlayer.motion.MotionPlanner``.

    :param registry: the motion-planner registry.
    """


@hookspec
def interlayer_register_domains(registry):
    """Register domains: ``factory(params: dict, seed: int) -> interlayer.domain.Problem``.

    ``registry.add(name, factory, description, params={key: default})``: ``params`` lists the
    problem keys the domain accepts, so configs are checked strictly.

    :param registry: the domain registry.
    """


@hookspec
def interlayer_register_pose_generators(registry):
    """Register pose generators by name (e.g. ``gripper2d:pick``).

    ``factory(problem, step, world, rng) -> iterable of interlayer.refine.Candidate``: a finite,
    seeded stream of instantiations of the step's references. An action names its default
    generator; ``[pose_generators] action = "name"`` in a config overrides it.

    :param registry: the pose-generator registry.
    """


@hookspec
def interlayer_register_failure_translators(registry):
    """Register failure translators: ``fn(failure, step, model) -> set of atoms``.

    Every translator named in ``planner.translators`` is applied to each motion-planning failure and
    the union of their facts is added to the state at the failing step (Alg. 1, line 9); a
    ``logic.negated(atom)`` in the set deletes ``atom`` from it instead.

    :param registry: the failure-translator registry.
    """


@hookspec
def interlayer_register_visualizers(registry):
    """Register visualizers: ``factory(options) -> object`` with ``plan_page(out_dir, path)`` (a 3D
    animation of the refined plan), ``explain_page(out_dir, path)`` (the search explained) and
    optionally ``stream(host)`` (for ``plan --viz``: a trace listener with ``prepared(problem)``,
    ``finish(result)`` and ``close()`` that shows the run in a live viewer served on ``host``) and
    ``live(result)`` (a live viewer of a result).

    :param registry: the visualizer registry.
    """


@hookspec(firstresult=True)
def interlayer_load_problem(path, params, seed):
    """Load a problem file this plugin understands, or return None to let another plugin try.

    First result wins: the first plugin that claims the file format builds the Problem.

    :param path: a ``pathlib.Path`` to the file.
    :param params: problem parameters from the config or ``--set problem.key=value``.
    :param seed: the run's seed.
    """


@hookspec(firstresult=True)
def interlayer_check_robot(path):
    """Load a robot description and report what it found (``interlayer robot check``), or return None.

    First result wins. The report is a JSON-ready dict (the robot layer's: its URDF, DOF, base, arms with
    their chains, tool frames, reach and gripper range, the self-collision pairs skipped); a bad
    description raises ``interlayer.errors.UserError`` naming the file and the field.

    :param path: a shipped robot's name (``"panda"``) or the path of a description file (``.toml``).
    """


@hookspec
def interlayer_on_event(event):
    """Observe every trace event of a run as it happens (progress displays, logging).

    :param event: a dict with at least ``t`` (seconds since start) and ``type``.
    """
