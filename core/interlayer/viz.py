"""Pictures of a run, through the registered visualizer (the meshcat adapter by default)."""
from __future__ import annotations

from .errors import UserError
from .plugins import PluginHost


def _visualizer(name: str, host: PluginHost | None = None):
    host = host or PluginHost()
    return host["visualizers"].get(name).factory({})


def write_plan_html(out_dir, path, visualizer: str = "meshcat") -> None:
    """One self-contained HTML page animating the refined plan of OUT_DIR."""
    _visualizer(visualizer).plan_page(out_dir, path)


def write_explain_html(out_dir, path, visualizer: str = "meshcat") -> None:
    """A page explaining the search of OUT_DIR: task plans, failures, learned facts, timings."""
    _visualizer(visualizer).explain_page(out_dir, path)


def live_view(result, visualizer: str = "meshcat") -> None:
    viz = _visualizer(visualizer)
    if not hasattr(viz, "live"):
        raise UserError(f"The visualizer '{visualizer}' has no live view; write a page with 'interlayer viz OUT_DIR'.")
    viz.live(result)


def live_stream(visualizer: str = "meshcat", host: str = "127.0.0.1"):
    """A trace listener streaming the run into the visualizer's live viewer (``plan --viz``): told the
    problem by ``prepared(problem)``, then every event; ``finish(result)`` shows the result, ``close()``
    stops its server."""
    viz = _visualizer(visualizer)
    if not hasattr(viz, "stream"):
        raise UserError(f"The visualizer '{visualizer}' has no live view; write a page with 'interlayer viz OUT_DIR'.")
    return viz.stream(host=host)
