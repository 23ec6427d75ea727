"""The pr2_pick scene: a PR2 in front of a table with a closed cubby (back and side panels) whose
only access, from the front, is blocked by a cylinder standing in its mouth; distractors elsewhere.
Object poses are (x, y, z_centre, yaw); resting objects float REST_GAP above the table top."""
from __future__ import annotations

import math

import numpy as np

from interlayer_manip.scene import REST_GAP, TABLE_TOP, Layout, ObjectSpec, _radius

TABLE_CENTRE = (0.85, 0.0)
TABLE_SIZE = (0.5, 1.6)  # x depth, y width
# Arm transits to a grasp in the cubby's mouth (and the carry out of it) go through a point this far
# further back along the tool's x axis: the sampling planner then searches in free space (see _transit).
STAGE = 0.05


def make_layout(seed: int, goal: str, grasps, target_radius: float, clutter: int = 0, top: float = TABLE_TOP,
                base=None, extra=None, blocker_radius: float = 0.04, wider: float = 0.0) -> Layout:
    """``clutter`` extra cylinders (c1, c2, ...) stand at random free spots of the table, away from
    the cubby and goal_spot (a first step towards the paper's Clutter-N). ``top``: the table top's
    height (a fixed-base robot's scene puts it at the base's height), ``base``: the robot's, ``extra``:
    more layout keys, ``blocker_radius``: narrower for a gripper that opens less than 9 cm, ``wider``: the
    cubby's widening (m, each side) for a wider hand."""
    def _resting(shape, size, x, y, yaw=0.0):
        h = size[1] if shape == "cylinder" else size[2]
        return (float(x), float(y), top + h / 2 + REST_GAP, float(yaw))

    rng = np.random.default_rng(seed)
    j = lambda s: float(rng.uniform(-s, s))  # noqa: E731
    tx, ty = TABLE_CENTRE
    sx, sy = TABLE_SIZE
    fixed = [ObjectSpec("table", "box", (sx, sy, TABLE_TOP), (tx, ty, top - TABLE_TOP / 2, 0.0), movable=False)]
    # The cubby: inner width 0.24 (y in [-0.12, 0.12]; + 2 x wider), from x = 0.63 to the back panel at x = 1.02.
    ph = 0.30
    z = top + ph / 2 + REST_GAP
    fixed += [
        ObjectSpec("panel_left", "box", (0.40, 0.02, ph), (0.83, 0.13 + wider, z, 0.0), movable=False),
        ObjectSpec("panel_right", "box", (0.40, 0.02, ph), (0.83, -0.13 - wider, z, 0.0), movable=False),
        ObjectSpec("panel_back", "box", (0.02, 0.28 + 2 * wider, ph), (1.04, 0.0, z, 0.0), movable=False),
    ]
    r = target_radius
    objects = [
        ObjectSpec("target", "cylinder", (r, 0.14), _resting("cylinder", (r, 0.14), 0.88 + j(0.005), j(0.005))),
        ObjectSpec("blocker", "cylinder", (blocker_radius, 0.16),
                   _resting("cylinder", (blocker_radius, 0.16), 0.715 + j(0.005), j(0.005))),
        ObjectSpec("can", "cylinder", (0.03, 0.12), _resting("cylinder", (0.03, 0.12), 0.80 + j(0.01), 0.50 + j(0.01))),
        ObjectSpec("box", "box", (0.05, 0.08, 0.14),
                   _resting("box", (0.05, 0.08, 0.14), 0.90 + j(0.01), -0.55 + j(0.01), j(0.3))),
    ]
    regions = {"table": (tx - sx / 2, tx + sx / 2, ty - sy / 2, ty + sy / 2),
               "goal_spot": (0.70, 0.90, -0.40, -0.24)}
    keep_out = [(0.60, 1.08, -0.17 - wider, 0.17 + wider), regions["goal_spot"]]
    for k in range(clutter):
        for _ in range(500):
            r = float(rng.uniform(0.03, 0.04))
            x = float(rng.uniform(tx - sx / 2 + r + 0.02, tx + sx / 2 - r - 0.02))
            y = float(rng.uniform(ty - sy / 2 + r + 0.02, ty + sy / 2 - r - 0.02))
            if any(a - r - 0.03 <= x <= b + r + 0.03 and c - r - 0.03 <= y <= d + r + 0.03 for a, b, c, d in keep_out):
                continue
            if any(math.hypot(x - o.pose[0], y - o.pose[1]) < r + _radius(o) + 0.05 for o in objects):
                continue
            objects.append(ObjectSpec(f"c{k + 1}", "cylinder", (r, 0.12), _resting("cylinder", (r, 0.12), x, y)))
            break
        else:
            raise ValueError(f"no free spot on the table for clutter object {k + 1}")
    layout = Layout(fixed, objects, regions, "target", goal, tuple(grasps), extra={"stage": STAGE, **(extra or {})})
    if base is not None:
        layout.base = tuple(base)
    return layout
