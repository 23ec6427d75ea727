"""Interlayer: combined task and motion planning through a planner-independent interface layer.

Python API::

    import interlayer
    result = interlayer.solve("examples/gripper2d.toml", overrides={"planner.task": "pyperplan"})
    print(result.status, [str(s) for s in result.plan])

Plugin authors: ``interlayer.plugin_api`` holds everything a plugin needs (docs/plugins.md).
"""
import pluggy

hookimpl = pluggy.HookimplMarker("interlayer")

__version__ = "0.2.0"


def solve(config, overrides=None, **kwargs):
    """Solve a problem given a config path, a problem file, a dict, or an output folder;
    ``overrides``: ``["planner.task=pyperplan"]`` or ``{"planner.task": "pyperplan"}``."""
    from .api import solve as _solve

    return _solve(config, overrides=overrides, **kwargs)


__all__ = ["hookimpl", "solve", "__version__"]
