"""interlayer_meshcat: meshcat adapter for Interlayer.

Writes self-contained animated 3D HTML pages (no server, nothing fetched from
the network) and can mirror the same scene into a live meshcat viewer.

Importing this package is cheap: meshcat, numpy and pinocchio are imported
only when one of the names below is first used (PEP 562 lazy attributes).

    from interlayer_meshcat import Scene, add_pinocchio_robot
    scene = Scene("demo")
    scene.box("table", (1.0, 0.6, 0.05), [0.6, 0, 0.7], "brown")
    scene.animate([{"cup": [0.5, 0, 0.8 + 0.01 * i]} for i in range(20)], fps=10)
    scene.write_html("demo.html")
"""

from __future__ import annotations

import importlib

__all__ = [
    "Scene", "HtmlScene", "SceneRecorder", "as_pose", "as_rgba",
    "PinocchioRobot", "add_pinocchio_robot", "robot_frame",
    "html_page", "scene_iframe", "scene_embed", "write_page",
]

_LAZY = {
    "Scene": "scene", "HtmlScene": "scene", "SceneRecorder": "scene", "as_pose": "scene",
    "as_rgba": "scene",
    "PinocchioRobot": "robot", "add_pinocchio_robot": "robot", "robot_frame": "robot",
    "html_page": "page", "scene_iframe": "page", "scene_embed": "page", "write_page": "page",
}


def __getattr__(name):
    mod = _LAZY.get(name)
    if mod is None:
        raise AttributeError(f"module 'interlayer_meshcat' has no attribute {name!r}")
    value = getattr(importlib.import_module(f".{mod}", __name__), name)
    globals()[name] = value
    return value


def __dir__():
    return sorted(list(globals()) + __all__)
