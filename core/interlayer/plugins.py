"""The plugin manager and the component registries."""
from __future__ import annotations

import importlib.metadata
from dataclasses import dataclass, field
from typing import Callable

import pluggy

from . import hookspecs
from .errors import UserError, closest

ENTRY_POINT_GROUP = "interlayer.plugins"
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


class Registry:
    """Components of one kind, registered by plugins and selected by name from config."""

    def __init__(self, kind: str):
        self.kind = kind
        self.components: dict[str, Component] = {}
        self.current_plugin = ""

    def add(self, name: str, factory: Callable, description: str = "", params: dict | None = None):
        self.components[name] = Component(name, factory, description, self.current_plugin, params=dict(params or {}))

    def unavailable(self, name: str, reason: str, description: str = ""):
        self.components[name] = Component(name, None, description, self.current_plugin, False, reason)

    def names(self, available_only: bool = True) -> list[str]:
        return sorted(n for n, c in self.components.items() if c.available or not available_only)

    def get(self, name: str) -> Component:
        label = self.kind.replace("_", " ")[:-1]
        comp = self.components.get(name)
        if comp is None:
            raise UserError(
                f"Unknown {label} '{name}'{closest(name, self.components)}; available: {', '.join(self.names()) or 'none'}."
            )
        if not comp.available:
            raise UserError(f"The {label} '{name}' is not available here: {comp.reason}.")
        return comp


@dataclass
class PluginInfo:
    name: str
    distribution: str
    version: str
    hooks: list
    components: dict  # kind -> [names]


class PluginHost:
    """A plugin manager with its registries; no global state, so tests can build several."""

    def __init__(self, load_entry_points: bool = True, plugins: tuple = ()):
        self.pm = pluggy.PluginManager("interlayer")
        self.pm.add_hookspecs(hookspecs)
        self.dists: dict[str, tuple[str, str]] = {}
        if load_entry_points:
            for ep in importlib.metadata.entry_points(group=ENTRY_POINT_GROUP):
                if self.pm.get_plugin(ep.name) is not None:
                    continue
                try:
                    module = ep.load()
                except Exception as exc:  # a broken third-party plugin must not break the CLI
                    self.broken = getattr(self, "broken", {})
                    self.broken[ep.name] = f"{type(exc).__name__}: {exc}"
                    continue
                self.pm.register(module, name=ep.name)
                dist = ep.dist
                self.dists[ep.name] = (dist.name, dist.version) if dist else ("?", "?")
        for name, module in plugins:
            self.pm.register(module, name=name)
            self.dists[name] = ("(registered in code)", "")
        self.pm.check_pending()
        self.registries = {kind: Registry(kind) for kind in KINDS}
        self._contributions: dict[str, dict] = {}
        for name, plugin in self.pm.list_name_plugin():
            for kind in KINDS:
                impl = getattr(plugin, f"interlayer_register_{kind}", None)
                if impl is None:
                    continue
                reg = self.registries[kind]
                reg.current_plugin = name
                before = set(reg.components)
                impl(registry=reg)
                self._contributions.setdefault(name, {})[kind] = sorted(set(reg.components) - before)

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
        return self.pm.hook.interlayer_load_problem(path=path, params=params, seed=seed)

    def on_event(self, event):
        self.pm.hook.interlayer_on_event(event=event)
