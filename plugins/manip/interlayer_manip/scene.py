"""Scene layouts of the manipulation domains: fixed bodies, movable objects and named regions.

Units: metres, radians. World z is up; the support surface is at ``table_top(layout)`` (TABLE_TOP
unless the scene says otherwise). Objects stand upright; an object pose is (x, y, z_centre, yaw).
Resting objects float REST_GAP above their support, because touching counts as colliding in Coal.
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field

TABLE_TOP = 0.72  # m: the support height of a layout that names none (the cubby's table)
REST_GAP = 0.002
BASE_START = (0.0, 0.0, 0.0)
BASE_LIMITS = ((-1.0, 2.5), (-2.0, 2.0))


@dataclass
class ObjectSpec:
    name: str
    shape: str  # "cylinder" | "box"
    size: tuple  # cylinder: (radius, height); box: (sx, sy, sz)
    pose: tuple  # (x, y, z_centre, yaw)
    movable: bool = True

    @property
    def height(self) -> float:
        return self.size[1] if self.shape == "cylinder" else self.size[2]

    def to_json(self):
        return {"name": self.name, "shape": self.shape, "size": list(self.size), "pose": list(self.pose),
                "movable": self.movable}


@dataclass
class Layout:
    fixed: list  # ObjectSpec, movable=False (table, cubby panels)
    objects: list  # ObjectSpec, movable
    regions: dict  # loc name -> (xmin, xmax, ymin, ymax) on the table top ("table" = the whole top)
    target: str
    goal: str  # "hold" | "place"
    grasps: tuple
    base: tuple = BASE_START
    extra: dict = field(default_factory=dict)

    def to_json(self):
        return {"fixed": [o.to_json() for o in self.fixed], "objects": [o.to_json() for o in self.objects],
                "regions": self.regions, "target": self.target, "goal": self.goal, "grasps": list(self.grasps),
                "base": list(self.base)}

    def obj(self, name) -> ObjectSpec:
        return next(o for o in self.fixed + self.objects if o.name == name)


def table_top(layout) -> float:
    """The support surface height of a layout (TABLE_TOP unless the scene says otherwise)."""
    return float(layout.extra.get("table_top", TABLE_TOP))


def base_limits(layout):
    return layout.extra.get("base_limits", BASE_LIMITS)


def _radius(o: ObjectSpec) -> float:
    return o.size[0] if o.shape == "cylinder" else 0.5 * math.hypot(o.size[0], o.size[1])
