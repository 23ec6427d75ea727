"""The Dinner-N scene (docs/dinner.md): two rooms joined by a doorway, a side table in room A
with N cups and bowls (equal numbers, random positions, random names) and a tray, a dinner table in
room B with N place settings.

World frame: the PR2 starts at the origin facing +x, in room A (x > WALL_X). The dividing wall (two
Coal boxes) stands at x = WALL_X with a doorway of DOOR wide around y = 0. The side table is in front
of the robot; the dinner table in room B, its near edge facing the doorway. The tray rests at a fixed
spot of a table, its near edge overhanging the table's edge (OVERHANG) so that both grippers close
around it; its N slots hold one object each, and an object stacked on an object in a slot rides along.
"""
from __future__ import annotations

import math

import numpy as np

from interlayer_manip.scene import REST_GAP, Layout, ObjectSpec

TOP = 0.72  # both tables' top surface
SIDE = ((0.85, 0.1), (0.6, 1.8))  # side table centre (x, y), size (x, y)
DINNER = ((-2.45, 0.0), (0.6, 1.8))  # dinner table, room B
WALL_X, WALL_T, WALL_H, DOOR = -0.9, 0.1, 1.5, 1.2
LIMITS = ((-3.6, 1.6), (-2.2, 2.2))  # the base's workspace (both rooms)
TRAY = (0.36, 0.50, 0.02)  # x (depth), y (width), thickness
OVERHANG = 0.07
CUP = ((0.026, 0.032), 0.09)  # radius range, height
BOWL = ((0.040, 0.044), 0.05)
ROOMS = ("room_a", "room_b")
HOME = {"room_a": (0.0, 0.0, 0.0), "room_b": (-1.55, 0.0, math.pi)}  # where a move between rooms ends (jittered)
NAMES = ("ash", "birch", "cedar", "elm", "fir", "hazel", "larch", "maple", "oak", "pine", "rowan", "yew",
         "alder", "beech", "holly", "lime")


def near_base(rng, x, y) -> tuple:
    """A base pose in front of the table that (x, y) is on (the side facing the doorway's room), turned
    towards (x, y): the robot never walks round a table."""
    if x > WALL_X:
        edge, away = SIDE[0][0] - SIDE[1][0] / 2, -1.0
    else:
        edge, away = DINNER[0][0] + DINNER[1][0] / 2, 1.0
    bx, by = edge + away * float(rng.uniform(0.36, 0.50)), y + float(rng.uniform(-0.4, 0.4))
    return (bx, by, float(math.atan2(y - by, x - bx) + rng.uniform(-0.3, 0.3)))


def tray_spot(table) -> tuple:
    """The tray's pose (x, y, z, yaw) at its fixed spot of ``table`` ("side" or "dinner")."""
    (cx, cy), (sx, _) = SIDE if table == "side" else DINNER
    z = TOP + REST_GAP + TRAY[2] / 2
    if table == "side":  # near edge towards -x (the robot), on the robot's right
        return (cx - sx / 2 - OVERHANG + TRAY[0] / 2, -0.42, z, 0.0)
    return (cx + sx / 2 + OVERHANG - TRAY[0] / 2, -0.6, z, math.pi)  # near edge towards +x (the doorway)


def slot_offsets(n_slots: int) -> list:
    """Slot centres in the tray's frame: one row for up to three, then two rows."""
    rows = 1 if n_slots <= 3 else 2  # (at 10 slots the bowls stand 1 cm apart)
    cols = math.ceil(n_slots / rows)
    xs = [0.04] if rows == 1 else [0.10, -0.02]  # the far row first: the near one is close to the hands
    ys = [TRAY[1] * ((c + 0.5) / cols - 0.5) for c in range(cols)]
    return [(xs[k // cols], ys[k % cols]) for k in range(n_slots)]


def settings(n: int) -> list:
    """Place-setting centres (x, y) along the dinner table's near edge."""
    (cx, cy), (sx, sy) = DINNER
    x = cx + sx / 2 - 0.14
    y0, y1 = cy - 0.2, cy + sy / 2 - 0.08
    return [(x, y0 + (y1 - y0) * (k / max(1, n - 1)) if n > 1 else (y0 + y1) / 2) for k in range(n)]


def make_layout(seed: int, n: int) -> Layout:
    rng = np.random.default_rng(seed)
    names = [str(v) for v in rng.permutation(NAMES)[:n]]
    kinds = {name: ("cup" if k % 2 == 0 else "bowl") for k, name in enumerate(names)}
    (sx0, sy0), (ssx, ssy) = SIDE
    (dx0, dy0), (dsx, dsy) = DINNER
    fixed = [ObjectSpec("side_table", "box", (ssx, ssy, TOP), (sx0, sy0, TOP / 2, 0.0), movable=False),
             ObjectSpec("dinner_table", "box", (dsx, dsy, TOP), (dx0, dy0, TOP / 2, 0.0), movable=False)]
    (_, _), (ylo, yhi) = LIMITS
    for side, (a, b) in (("wall_right", (ylo - 0.3, -DOOR / 2)), ("wall_left", (DOOR / 2, yhi + 0.3))):
        fixed.append(ObjectSpec(side, "box", (WALL_T, b - a, WALL_H), (WALL_X, (a + b) / 2, WALL_H / 2, 0.0), movable=False))
    tray = ObjectSpec("tray", "box", TRAY, tray_spot("side"))
    objects, placed = [], []
    x_lo, x_hi = sx0 - ssx / 2 + 0.06, sx0 - ssx / 2 + 0.32  # within the arms' reach from the near edge
    y_lo, y_hi = -0.10, sy0 + ssy / 2 - 0.06
    for name in names:
        (r_lo, r_hi), h = CUP if kinds[name] == "cup" else BOWL
        r = float(rng.uniform(r_lo, r_hi))
        for _ in range(1000):
            x, y = float(rng.uniform(x_lo + r, x_hi - r)), float(rng.uniform(y_lo + r, y_hi - r))
            if all(math.hypot(x - px, y - py) >= r + pr + 0.045 for px, py, pr in placed):
                break
        else:
            raise ValueError(f"no free spot on the side table for {name}")
        placed.append((x, y, r))
        objects.append(ObjectSpec(name, "cylinder", (r, h), (x, y, TOP + h / 2 + REST_GAP, 0.0)))
    objects.append(tray)
    order = [str(v) for v in rng.permutation(names)]  # which setting each object goes to
    setting_xy = dict(zip(order, settings(n)))
    regions = {"side": (sx0 - ssx / 2, sx0 + ssx / 2, sy0 - ssy / 2, sy0 + ssy / 2),
               "dinner": (dx0 - dsx / 2, dx0 + dsx / 2, dy0 - dsy / 2, dy0 + dsy / 2)}
    for name, (x, y) in setting_xy.items():
        r = 0.05
        regions[f"set_{name}"] = (x - r, x + r, y - r, y + r)
    return Layout(fixed, objects, regions, names[0], "dinner", ("side", "top"),
                  extra={"table_top": TOP, "supports": ("side_table", "dinner_table"), "base_limits": LIMITS,
                         "kinds": {**kinds, "tray": "tray"}, "settings": setting_xy, "slots": slot_offsets(n),
                         "torso_height": 0.2})
