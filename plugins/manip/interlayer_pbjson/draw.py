"""How a pybullet-planning scene is drawn: the PR2 package's drawing, in the file's own colours, with its
floor and its regions (translucent, in their colours), seen from the file's camera side."""
from __future__ import annotations

import math

import numpy as np


def draw_scene(geometry, scene, world=None) -> dict:
    from interlayer_manip import draw
    from interlayer_manip.state import pose4

    names = draw.draw_scene(geometry, scene, world)
    extra = geometry.layout.extra
    colors = extra.get("colors", {})
    for spec in geometry.layout.fixed + geometry.layout.objects:
        c = colors.get(spec.name)
        if c is not None and spec.name in names:
            scene.set_color(names[spec.name], c)
    for spec in extra.get("floors", []):
        names[spec.name] = scene.box(f"fixed/{spec.name}", spec.size, pose4(*spec.pose), colors.get(spec.name))
    labels = extra.get("labels", {})
    for s in geometry.surfaces.values():
        centre = np.mean(np.array(s.polygon), axis=0)
        if s.kind != "region":  # a place to put things (washer, stove...): the plan names it
            scene.label(f"surfaces/{s.name}/label", labels.get(s.name, s.name), [centre[0], centre[1], s.z + 0.01], height=0.035, priority=1)
            continue
        (ax, ay), (bx, by), (cx, cy) = s.polygon[:3]
        size = (math.hypot(bx - ax, by - ay), math.hypot(cx - bx, cy - by), 0.003)
        T = pose4(centre[0], centre[1], s.z + 0.0015, math.atan2(by - ay, bx - ax))
        names[s.name] = scene.box(f"regions/{s.name}/area", size, T, s.color or draw.COLORS["region"])
        scene.label(f"regions/{s.name}/label", labels.get(s.name, s.name), [centre[0], centre[1], s.z + 0.01], height=0.035, priority=1)
    camera = extra.get("camera")
    if camera is not None:
        scene.view_direction = tuple(camera)
    return names
