"""Registers the "meshcat" visualizer (``interlayer viz``, ``interlayer explain``,
``interlayer plan --viz``). Import-light: the work lives in :mod:`.visualizer`,
imported only when the factory is called."""
from interlayer import hookimpl


def factory(options=None):
    from .visualizer import MeshcatVisualizer

    return MeshcatVisualizer(**dict(options or {}))


@hookimpl
def interlayer_register_visualizers(registry):
    registry.add("meshcat", factory,
                 "self-contained 3D HTML pages (plan animation, explanation of every replan) and a live meshcat viewer")
