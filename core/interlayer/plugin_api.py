"""Everything a plugin author needs, in one import: ``from interlayer.plugin_api import ...``.

A plugin is a module found through the entry-point group ``interlayer.plugins``; it implements
hooks (``@hookimpl def interlayer_register_domains(registry): ...``, see ``interlayer.hookspecs``)
that register components by name into a ``Registry``. ``docs/plugins.md`` builds a complete
third-party domain plugin step by step with these names.

Domains
    ``DomainSpec`` (types, continuous types, predicates, ``Skolem`` functions, geometric
    predicates, ``ActionSpec`` actions with PDDL preconditions/effects, ``learn`` templates and a
    default pose generator) and a ``Problem`` per instance, whose ``geometry`` implements
    ``Geometry``: ``refine_step`` returns a ``StepOutcome``, ok or with a ``Failure(kind,
    objects)`` whose ``kind`` must be a key of the action's ``learn`` to teach the task planner.
    The domain's ``drawing`` (``Drawing``) lets visualizers draw it. Names read from a user's file
    become symbols through ``Names`` (``Problem.labels`` shows them again).
Pose generators
    ``fn(problem, step, world, rng) -> iterable of Candidate``; raise ``Infeasible`` when a
    reference can never be instantiated (proved), ``GiveUp`` when the generator's own finite search
    shows it will find none for a step the goal needs (not proved: the run ends gave_up). A generator that needs state between calls subclasses
    ``EpochState`` (registered as the class): the loop makes a fresh, reseeded instance per epoch.
    A generator that yields nothing is a failure of kind ``NO_CANDIDATES``: an action's ``learn``
    templates for that kind tell the task planner so (e.g. that the reference has no instance until
    its object moves); the facts are forgotten at the next reset, like every learned fact.
Motion planners
    subclass ``MotionPlanner`` and implement ``_plan(space, start, goal, is_valid, time_limit)``;
    domains describe each query as a ``MotionQuery`` over a ``ConfigSpace``.
Task planners
    subclass ``TaskPlanner`` and implement ``_plan(model, state, timeout)`` over a ``TaskModel``.
Failure translators
    ``fn(failure, step, model) -> set of atoms`` (atoms are tuples ``("Obstructs", "b2", "gp_b1")``;
    ``negated(atom)`` learns an atom false: the loop deletes it).
Robots
    the robot layer is the adapter ``interlayer_pinocchio`` (``Robot.load("panda")``, ``CollisionWorld``,
    ``solve_ik``, ...: its package docstring); core names it needs are here (``Clearance``, ``Stats``).
Versions
    ``API_VERSION`` is the plugin API's version, the core's ``major.minor``: a plugin distribution declares
    the cores it is made for, ``interlayer>=0.2,<0.3``, and discovery skips it under any other.
Errors
    raise ``UserError`` with one plain sentence for bad input (the CLI exits 2); any other exception
    from plugin code is reported as that plugin's fault (``PluginFault``).
"""
from typing import Any, Protocol

from . import hookimpl
from .abstraction import TaskModel
from .apiversion import API_VERSION
from .builtin import translate_by_templates
from .domain import ActionSpec, DomainSpec, GroundStep, Problem, Skolem
from .errors import UserError
from .faults import PluginFault
from .logic import negated
from .motion import Clearance, ConfigSpace, InterpolatingPlanner, MotionPlan, MotionPlanner, MotionQuery, points_valid, segment_valid
from .names import Names
from .planning import TaskPlanner, TaskPlanResult
from .plugins import Registry
from .refine import NO_CANDIDATES, ROBOT_MOVED, Candidate, EpochState, Failure, Geometry, GiveUp, Infeasible, StepOutcome
from .trace import Stats


class Drawing(Protocol):
    """How a domain is drawn (``registry.add(name, factory, drawing="my_plugin.draw")``): a module,
    or any object, with these two functions. ``scene`` is a visualizer scene
    (``interlayer_meshcat.scene.Scene``: ``box``, ``cylinder``, ``label``, ``set_pose``, ...)."""

    def draw_scene(self, geometry: Any, scene: Any, world: dict | None) -> dict | None:
        """Add the static scene and the objects at ``world`` (a ``Geometry.snapshot``; None: the
        initial world). Return {problem object: scene name} for objects to highlight, or None."""

    def animation_frames(self, geometry: Any, scene: Any, trajectory: dict) -> list:
        """Frames of ``trajectory`` (``Geometry.trajectory_json``): dicts scene name -> pose
        (4x4, xyz or xyz+quaternion) plus ``"@step"``: the plan step shown."""


__all__ = [
    "API_VERSION", "hookimpl", "Registry", "UserError", "PluginFault",
    "DomainSpec", "ActionSpec", "Skolem", "Problem", "GroundStep", "TaskModel",
    "Geometry", "Candidate", "StepOutcome", "Failure", "Infeasible", "GiveUp", "EpochState", "ROBOT_MOVED", "NO_CANDIDATES",
    "Drawing",
    "ConfigSpace", "MotionQuery", "MotionPlan", "MotionPlanner", "InterpolatingPlanner", "segment_valid", "points_valid",
    "Clearance", "Stats",
    "TaskPlanner", "TaskPlanResult", "translate_by_templates", "negated", "Names",
]
