"""The plugin manager and the component registries."""
from __future__ import annotations

import importlib
import importlib.metadata
from dataclasses import dataclass, field
from typing import Callable

import pluggy

from . import apiversion, hookspecs
from .errors import UserError, closest
from .faults import PluginFault, blame

ENTRY_POINT_GROUP = "interlayer.plugins"
# This repository's distributions (the workspace: its development install of all of them); their plugins load
# first, so that another distribution cannot take their component names.
FIRST_PARTY = frozenset({"interlayer", "interlayer-workspace", "interlayer-up", "interlayer-ompl", "interlayer-coal",
                         "interlayer-pinocchio", "interlayer-optim", "interlayer-meshcat", "interlayer-gripper2d",
                         "interlayer-manip"})
KINDS = ("task_planners", "motion_planners", "domains", "pose_generators", "failure_translators", "visualizers")


@dataclass
class Component:
    name: str
    factory: Callable | None
    description: str = ""
    plugin: str = ""
    available: bool = True
    reason: str = ""
    params: dict = field(default_factory=dict)
    drawing: object = None  # domains: a module (or its dotted name) with draw_scene / animation_frames

    @property
    def label(self) -> str:
        return f"{self.kind_label} '{self.name}'"

    kind_label: str = ""


class Registry:
    """Components of one kind, registered by plugins and selected by name from config."""

    def __init__(self, kind: str):
        self.kind = kind
        self.components: dict[str, Component] = {}
        self.current_plugin = ""
        self.shadowed: list[str] = []  # one sentence per refused duplicate name
        self.broken_plugins: dict[str, str] = {}  # plugin -> why it failed to load (for Unknown-name errors)

    @property
    def label(self) -> str:
        return self.kind.replace("_", " ")[:-1]

    def add(self, name: str, factory: Callable | str, description: str = "", params: dict | None = None, drawing=None):
        """Register a component. ``factory`` may be a ``"module:attribute"`` string, imported when the
        component is first selected: discovering the plugins then imports no domain's libraries.
        Domains may pass ``params`` (accepted problem keys with defaults) and ``drawing`` (a module, or
        its dotted name, with ``draw_scene`` and ``animation_frames``)."""
        self._put(Component(name, factory, description, self.current_plugin, params=dict(params or {}), drawing=drawing))

    def unavailable(self, name: str, reason: str, description: str = ""):
        """Record a component that cannot run here (e.g. a missing optional dependency)."""
        self._put(Component(name, None, description, self.current_plugin, False, reason))

    def _put(self, comp: Component):
        comp.kind_label = self.label
        old = self.components.get(comp.name)
        if old is not None and old.plugin != comp.plugin:  # the first registration keeps the name
            self.shadowed.append(f"the plugin '{comp.plugin}' registers the {self.label} '{comp.name}', which the plugin "
                                 f"'{old.plugin}' already provides; ignored (rename it, e.g. '{comp.plugin}:{comp.name}')")
            return
        self.components[comp.name] = comp

    def names(self, available_only: bool = True) -> list[str]:
        return sorted(n for n, c in self.components.items() if c.available or not available_only)

    def get(self, name: str) -> Component:
        label = self.kind.replace("_", " ")[:-1]
        comp = self.components.get(name)
        if comp is None:
            broken = "".join(f"; the plugin '{p}' failed to load ({why}), so it may be the one missing"
                             for p, why in self.broken_plugins.items())
            raise UserError(
                f"Unknown {label} '{name}'{closest(name, self.components)}; available: {', '.join(self.names()) or 'none'}{broken}."
            )
        if not comp.available:
            raise UserError(f"The {label} '{name}' is not available here: {comp.reason}.")
        if isinstance(comp.factory, str):  # registered by name: imported now
            module, _, attribute = comp.factory.partition(":")
            with blame(comp.plugin, comp.label):
                comp.factory = getattr(importlib.import_module(module), attribute)
        return comp


@dataclass
class PluginInfo:
    name: str
    distribution: str
    version: str
    hooks: list
    components: dict  # kind -> [names]


class PluginHost:
    """A plugin manager with its registries; no global state, so tests can build several.

    A plugin that fails to import, to validate against the hook specifications or to register its
    components is skipped and recorded in ``broken`` (name -> one sentence); the others work."""

    def __init__(self, load_entry_points: bool = True, plugins: tuple = ()):
        self.pm = pluggy.PluginManager("interlayer")
        self.pm.add_hookspecs(hookspecs)
        self.dists: dict[str, tuple[str, str]] = {}
        self.broken: dict[str, str] = {}
        if load_entry_points:
            found = importlib.metadata.entry_points(group=ENTRY_POINT_GROUP)
            dists = {}  # each distribution's (name, version), read once: .name and .version each parse its metadata
            refused = {}  # distribution -> why it is not made for this core (its requirement on interlayer)
            for ep in found:
                if ep.dist is not None and id(ep.dist) not in dists:
                    meta = ep.dist.metadata
                    dists[id(ep.dist)] = (meta["Name"], meta["Version"])
                    refused[id(ep.dist)] = apiversion.mismatch(meta["Name"], meta["Version"], meta.get_all("Requires-Dist"))
            eps = sorted(found, key=lambda ep: apiversion.normal_name(dists.get(id(ep.dist), ("?",))[0]) not in FIRST_PARTY)
            for ep in eps:
                if self.pm.get_plugin(ep.name) is not None or ep.name in self.broken:
                    continue
                dist = dists.get(id(ep.dist), ("?", "?"))
                if refused.get(id(ep.dist)):
                    self.broken[ep.name] = refused[id(ep.dist)]
                    continue
                try:
                    module = ep.load()
                except Exception as exc:  # a broken third-party plugin must not break the CLI
                    self.broken[ep.name] = f"importing {ep.value} raised {type(exc).__name__}: {exc}"
                    continue
                self._register(ep.name, module, dist)
        for name, module in plugins:
            self._register(name, module, ("(registered in code)", ""))
        self.registries = {kind: Registry(kind) for kind in KINDS}
        self._contributions: dict[str, dict] = {}
        for name, plugin in self.pm.list_name_plugin():
            self._register_components(name, plugin)
        for reg in self.registries.values():
            reg.broken_plugins = self.broken

    def _register(self, name: str, module, dist) -> None:
        unknown = [h for h in dir(module) if h.startswith("interlayer_") and not hasattr(hookspecs, h)
                   and callable(getattr(module, h))]
        if unknown:
            hooks = [h for h in dir(hookspecs) if h.startswith("interlayer_")]
            self.broken[name] = f"'{unknown[0]}' is not an Interlayer hook{closest(unknown[0], hooks)}"
            return
        try:
            self.pm.register(module, name=name)
        except pluggy.PluginValidationError as exc:
            self.broken[name] = _validation_sentence(exc)
            return
        self.dists[name] = dist

    def _register_components(self, name: str, plugin) -> None:
        added = {}
        try:
            for kind in KINDS:
                impl = getattr(plugin, f"interlayer_register_{kind}", None)
                if impl is None:
                    continue
                reg = self.registries[kind]
                reg.current_plugin = name
                before = set(reg.components)
                with blame(name, f"interlayer_register_{kind} hook"):
                    impl(registry=reg)
                added[kind] = sorted(set(reg.components) - before)
        except PluginFault as fault:
            for kind, names in added.items():
                for n in names:
                    del self.registries[kind].components[n]
            for kind in KINDS:  # the failing hook's partial registrations too
                reg = self.registries[kind]
                for n in [n for n, c in reg.components.items() if c.plugin == name]:
                    del reg.components[n]
            self.broken[name] = f"its {fault.sentence()}"
            self.pm.unregister(name=name)
            return
        self._contributions[name] = added

    @property
    def warnings(self) -> list[str]:
        """Component names a plugin tried to take from another (each ignored)."""
        return [w for reg in self.registries.values() for w in reg.shadowed]

    def __getitem__(self, kind: str) -> Registry:
        return self.registries[kind]

    def plugins(self) -> list[PluginInfo]:
        out = []
        for name, plugin in self.pm.list_name_plugin():
            hooks = sorted(h.name for h in self.pm.get_hookcallers(plugin) or [])
            dist, version = self.dists.get(name, ("?", "?"))
            out.append(PluginInfo(name, dist, version, hooks, self._contributions.get(name, {})))
        return out

    def load_problem(self, path, params, seed):
        """The first plugin that reads the file builds the Problem (None: no plugin can)."""
        for impl in reversed(self.pm.hook.interlayer_load_problem.get_hookimpls()):
            with blame(impl.plugin_name, "problem loader (interlayer_load_problem)"):
                problem = impl.function(path=path, params=params, seed=seed)
                if problem is not None:
                    from .contracts import problem as checked

                    return checked(problem)
        return None

    def on_event(self, event):
        for impl in self.pm.hook.interlayer_on_event.get_hookimpls():
            with blame(impl.plugin_name, "event observer (interlayer_on_event)"):
                impl.function(event=event)


def _validation_sentence(exc) -> str:
    """pluggy's three-line validation message as one sentence that names the expected parameters."""
    import inspect

    text = str(exc)
    hook = text.split("for hook '", 1)[1].split("'", 1)[0] if "for hook '" in text else ""
    spec = getattr(hookspecs, hook, None)
    if spec is None:
        return text.strip().splitlines()[-1]
    expected = ", ".join(inspect.signature(spec).parameters)
    return f"its {hook} has parameters that are not the hook's: {text.strip().splitlines()[-1]}; use ({expected})"
