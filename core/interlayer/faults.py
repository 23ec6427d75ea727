"""Faults in plugin code, attributed to the plugin and component that raised them.

Plugins run inside the loop (planners, generators, translators, the domain's geometry). An
exception there is a bug of that plugin, not of Interlayer: ``blame`` turns it into a
``PluginFault`` naming the plugin and the component, which the CLI prints as one sentence (the
traceback with ``INTERLAYER_DEBUG=1``). ``UserError`` (bad input), ``Infeasible`` (a reference can
never be instantiated), ``KeyboardInterrupt`` and ``DeadlineExceeded`` pass through unchanged.
"""
from __future__ import annotations

import functools
from contextlib import contextmanager

from .deadline import calling
from .errors import UserError


class PluginFault(Exception):
    """An exception raised inside a plugin's code; ``__cause__`` is the original exception."""

    def __init__(self, plugin: str, component: str, cause: BaseException):
        super().__init__(f"{type(cause).__name__}: {cause}")
        self.plugin, self.component, self.cause = plugin, component, cause

    def sentence(self) -> str:
        if isinstance(self.cause, ComponentFailed):
            return f"{self.component} failed: {self.cause}"
        where = _innermost_frame(self.cause)
        return f"{self.component} raised {type(self.cause).__name__}: {_one_line(self.cause)}{where}"

    def __str__(self) -> str:
        return f"the plugin '{self.plugin}' failed: its {self.sentence()}"


class ComponentFailed(Exception):
    """A component reported its own failure (e.g. a task planner's status "error"); no traceback to show."""


def _one_line(exc) -> str:
    text = str(exc).strip().splitlines()
    return text[0] if text else "(no message)"


def _innermost_frame(exc) -> str:
    tb = exc.__traceback__
    while tb is not None and tb.tb_next is not None:
        tb = tb.tb_next
    if tb is None:
        return ""
    code = tb.tb_frame.f_code
    return f" (at {code.co_filename.rsplit('/', 1)[-1]}:{tb.tb_lineno} in {code.co_name})"


def _passes_through(exc) -> bool:
    from .refine import GiveUp, Infeasible

    return isinstance(exc, (UserError, Infeasible, GiveUp, PluginFault))


@contextmanager
def blame(plugin: str, component: str):
    """Attribute any unexpected exception raised in the block to ``plugin``'s ``component``."""
    try:
        with calling(plugin, component):  # named if the run's supervisor has to stop it
            yield
    except Exception as exc:
        if _passes_through(exc):
            raise
        raise PluginFault(plugin, component, exc) from exc


def blamed(fn, plugin: str, component: str):
    """``fn`` with its exceptions attributed to ``plugin``'s ``component``."""

    @functools.wraps(fn)
    def call(*args, **kwargs):
        with blame(plugin, component):
            return fn(*args, **kwargs)

    return call


class Guarded:
    """A plugin object whose listed methods attribute their exceptions to the plugin; every other
    attribute is the object's own (read and written through). ``methods`` names them, or maps each to
    a check of its answer, ``check(answer, *args)`` (``interlayer.contracts``), whose ComponentFailed
    is the plugin's fault too."""

    def __init__(self, obj, plugin: str, component: str, methods):
        checks = dict(methods) if isinstance(methods, dict) else dict.fromkeys(methods)
        object.__setattr__(self, "_obj", obj)
        object.__setattr__(self, "_guard", (plugin, component, checks))

    def __getattr__(self, name):
        if name in ("_obj", "_guard"):  # not yet set (copying, unpickling): no recursion
            raise AttributeError(name)
        value = getattr(self._obj, name)
        plugin, component, checks = self._guard
        if name not in checks or not callable(value):
            return value
        check = checks[name]
        if check is None:
            return blamed(value, plugin, f"{component} ({name})")

        def checked(*args, **kwargs):
            with blame(plugin, f"{component} ({name})"):
                return check(value(*args, **kwargs), *args)

        return checked

    def __setattr__(self, name, value):
        setattr(self._obj, name, value)
