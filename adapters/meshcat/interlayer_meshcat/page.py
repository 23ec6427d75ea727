"""Assemble self-contained HTML report pages with embedded 3D views.

Two ways to embed a :class:`~.scene.Scene`:

* :func:`scene_iframe` - ``<iframe srcdoc="...">`` holding the scene's full
  standalone page. Isolated and simple, but every iframe carries its own copy
  of the ~850 KB viewer JS.
* :func:`scene_embed` - a ``<div>`` plus a small script; :func:`html_page`
  then inlines the viewer JS **once** in ``<head>`` for all embeds. Viewers are
  created lazily when scrolled into view (browsers cap live WebGL contexts at
  ~16 per page; more views than that still work but the oldest contexts may
  be dropped by the browser).

Nothing here imports meshcat; only ``.scene`` does.
"""

from __future__ import annotations

import itertools
from html import escape
from pathlib import Path

from . import _viewer

__all__ = ["html_page", "scene_iframe", "scene_embed", "write_page", "escape"]

_BASE_CSS = """
body { font-family: system-ui, -apple-system, "Segoe UI", Roboto, sans-serif; margin: 1.5em;
       color: #1d232b; background: #fff; line-height: 1.4; }
h1, h2, h3 { line-height: 1.2; }
.il-scene { position: relative; display: inline-block; border: 1px solid #ccd3dc;
            border-radius: 4px; overflow: hidden; vertical-align: top; background: #eef1f5; }
.il-scene > .il-pane { width: 100%; height: 100%; }
.il-scene .dg.main { font-size: 11px; }
iframe.il-scene-frame { border: 1px solid #ccd3dc; border-radius: 4px; vertical-align: top; }
"""

_ids = itertools.count(1)


def html_page(title: str, body_html: str, extra_css: str = "", *, head_html: str = "",
              base_css: bool = True) -> str:
    """A complete HTML5 document. ``title`` is escaped; ``body_html``,
    ``extra_css`` and ``head_html`` are inserted verbatim. If ``body_html``
    contains :func:`scene_embed` output, the meshcat viewer JS and the
    mount helper are inlined once in ``<head>``."""
    needs_viewer = _viewer.EMBED_MARKER in body_html
    viewer = ""
    if needs_viewer:
        viewer = f"<script>\n{_viewer.viewer_js()}\n</script>\n<script>\n{_viewer.BOOT_JS}\n</script>\n"
    css = (_BASE_CSS if base_css else "") + (extra_css or "")
    body_html = _viewer.unique_blobs(body_html)
    return f"""<!DOCTYPE html>
<html lang="en">
<head>
<meta charset="utf-8">
<meta name="viewport" content="width=device-width, initial-scale=1">
<title>{escape(title)}</title>
<style>{css}</style>
{viewer}{head_html}
</head>
<body>
{body_html}
</body>
</html>
"""


def _scene_html(scene_or_html) -> str:
    if isinstance(scene_or_html, str):
        return scene_or_html
    if hasattr(scene_or_html, "html"):
        return scene_or_html.html()
    raise TypeError("expected a Scene or an HTML string")


def scene_iframe(scene_or_html, width=480, height=360, *, title: str = "3D view",
                 css_class: str = "il-scene-frame", lazy: bool = True) -> str:
    """``<iframe srcdoc=...>`` embedding a Scene (or a standalone page string).
    ``width``/``height`` are pixels (int) or CSS lengths (str). The srcdoc is
    attribute-escaped (``& < > " '``)."""
    doc = escape(_scene_html(scene_or_html), quote=True)
    w = f"{width}px" if isinstance(width, (int, float)) else str(width)
    h = f"{height}px" if isinstance(height, (int, float)) else str(height)
    loading = ' loading="lazy"' if lazy else ""
    return (f'<iframe class="{escape(css_class)}" title="{escape(title)}" style="width:{w};height:{h}"'
            f'{loading} srcdoc="{doc}"></iframe>')


def scene_embed(scene, width=480, height=360, *, element_id: str | None = None,
                controls: bool = False, lazy: bool = True, camera=None) -> str:
    """A ``<div>`` viewer for ``scene`` sharing the page-wide viewer JS (use
    inside :func:`html_page`). ``camera=(position, target)`` overrides the
    scene's camera. The recorded commands are snapshotted now."""
    eid = element_id or f"il-scene-{next(_ids)}"
    w = f"{width}px" if isinstance(width, (int, float)) else str(width)
    h = f"{height}px" if isinstance(height, (int, float)) else str(height)
    cam = camera if camera is not None else scene.camera_or_auto()
    blobs, refs = _viewer.shared_commands(scene.packed_commands())
    call = _viewer.mount_call(eid, refs, cam, controls=controls, fit=True, lazy=lazy, labels=scene.labels())
    return (f'<div class="il-scene" {_viewer.EMBED_MARKER}="1" style="width:{w};height:{h}">'
            f'<div class="il-pane" id="{escape(eid)}" style="width:100%;height:100%"></div></div>\n'
            f"{blobs}<script>{call}</script>")


def write_page(path, html: str) -> Path:
    """Write ``html`` as UTF-8 to ``path`` (parents created); returns the Path."""
    p = Path(path)
    p.parent.mkdir(parents=True, exist_ok=True)
    p.write_text(html, encoding="utf-8")
    return p
