"""The Drawer (O) / Drawer (N) scene (docs/drawer.md): a cabinet with one drawer, an object
in the drawer, a second object on a low stand in front of it, a side table to put things on.

World frame: the PR2 starts at the origin facing +x. The cabinet's front is at x = FRONT, centred on
y = 0; its drawer is a prismatic joint pulling towards -x, 0 to 0.4 m. Cabinet coordinates ("body
frame") have x = 0 at the front, +x inwards. The drawer's front plate carries a vertical bar handle.

The seed draws the inner object's place in the drawer, which fixes the pull needed to expose it for a
top grasp (``need``), and the outer object's place on the stand, which fixes the pull at which the
drawer's front plate meets it (``block``): (O) block >= need + MARGIN_O, (N) block <= need - MARGIN_N.
``interlayer_drawer.check`` verifies the property on a fine grid.
"""
from __future__ import annotations


import numpy as np

from interlayer_manip.scene import REST_GAP, Layout, ObjectSpec

FRONT = 1.0  # x of the cabinet's front face
DEPTH, WIDTH, HEIGHT = 0.52, 0.60, 0.76  # cabinet outside
CAVITY = (0.555, 0.72)  # z range of the drawer's opening
PULL_MAX = 0.40
BOTTOM = 0.575  # z of the drawer's inner bottom
PLATE = 0.02  # front plate thickness (body x in [-PLATE, 0] when closed)
BAR = (0.02, 0.02, 0.12)  # the handle bar (x, y, z), its centre at body x = -HANDLE_OUT
HANDLE_OUT = 0.07
HANDLE_Z = 0.64
STAND = (0.16, 0.16, 0.45)  # the low stand in front of the drawer (top at z 0.45)
INNER = (0.03, 0.12)  # radius, height
OUTER = (0.04, 0.22)
BASE_LIMITS = ((-1.0, 2.0), (-2.0, 2.0))
TABLE_TOP = 0.72
TABLE = ((0.35, -1.05), (0.5, 0.6))  # side table centre (x, y), size (x, y)
MARGIN_O, MARGIN_N = 0.08, 0.05  # (O): the outer object this much beyond the first exposing pull, (N): short of it


def cabinet_urdf() -> str:
    """The cabinet as a URDF: fixed carcass, drawer on a prismatic joint, handle fixed to the drawer."""
    from interlayer_pinocchio import box_link_urdf

    d, w, h = DEPTH, WIDTH, HEIGHT
    lo, hi = CAVITY
    carcass = [((d, 0.02, h), (d / 2, w / 2 - 0.01, h / 2)), ((d, 0.02, h), (d / 2, -w / 2 + 0.01, h / 2)),
               ((0.02, w, h), (d - 0.01, 0, h / 2)), ((d, w - 0.04, h - hi), (d / 2, 0, (hi + h) / 2)),
               ((d - 0.02, w - 0.04, lo), (d / 2 - 0.01, 0, lo / 2))]
    inner_w, length, wall = w - 0.08, d - 0.06, 0.10
    drawer = [((PLATE, w - 0.06, 0.15), (-PLATE / 2, 0, 0.64)),
              ((length, inner_w, 0.01), (length / 2, 0, BOTTOM - 0.005)),
              ((length, 0.01, wall), (length / 2, inner_w / 2 - 0.005, BOTTOM + wall / 2)),
              ((length, 0.01, wall), (length / 2, -inner_w / 2 + 0.005, BOTTOM + wall / 2)),
              ((0.01, inner_w, wall), (length - 0.005, 0, BOTTOM + wall / 2))]
    mount_x = -(PLATE + HANDLE_OUT - BAR[0] / 2) / 2 - PLATE / 2
    mount_len = HANDLE_OUT - BAR[0] / 2 - PLATE
    handle = [(BAR, (-HANDLE_OUT, 0, HANDLE_Z)),
              ((mount_len, 0.02, 0.015), (mount_x, 0, HANDLE_Z + BAR[2] / 2 - 0.0075)),
              ((mount_len, 0.02, 0.015), (mount_x, 0, HANDLE_Z - BAR[2] / 2 + 0.0075))]
    return ('<robot name="cabinet">' + box_link_urdf("carcass", carcass) + box_link_urdf("drawer", drawer)
            + box_link_urdf("handle", handle)
            + '<joint name="drawer_joint" type="prismatic"><parent link="carcass"/><child link="drawer"/>'
              f'<axis xyz="-1 0 0"/><limit lower="0" upper="{PULL_MAX}" effort="100" velocity="0.5"/></joint>'
            + '<joint name="handle_joint" type="fixed"><parent link="drawer"/><child link="handle"/></joint>'
            + "</robot>")


def cabinet_placement() -> np.ndarray:
    T = np.eye(4)
    T[0, 3] = FRONT
    return T


def inner_interior():
    """Body-frame x, y range of the inner object's centre (inside the drawer's walls)."""
    r = INNER[0]
    return (0.05 + r, 0.24), (-(WIDTH - 0.08) / 2 + 0.02 + r, (WIDTH - 0.08) / 2 - 0.02 - r)


def make_layout(seed: int, variant: str, outer_radius: float = OUTER[0]) -> Layout:
    """A seeded (O) or (N) scene; ``need`` / ``block`` (pull distances) go into ``layout.extra``.
    ``outer_radius``: narrower for a gripper that opens less than 9 cm (the outer object must be picked)."""
    from interlayer_pinocchio import ArticulatedBody
    from interlayer_manip.state import PADDING, pose4

    from .check import first_exposed

    body = ArticulatedBody("cabinet", cabinet_urdf(), cabinet_placement())
    rng = np.random.default_rng(seed)
    (x0, x1), (y0, y1) = inner_interior()
    r_o = outer_radius
    z_inner = BOTTOM + INNER[1] / 2 + REST_GAP
    for _ in range(200):
        xi, yi = float(rng.uniform(x0, x1)), float(rng.uniform(y0, y1))
        P = pose4(FRONT + xi, yi, z_inner, 0.0)
        exact, padded = first_exposed(body, P), first_exposed(body, P, pad=PADDING)
        if exact is None or padded is None:
            continue
        lo, hi = (padded + MARGIN_O, PULL_MAX - 0.01) if variant == "O" else (0.06, exact - MARGIN_N)
        if lo < hi:
            break
    else:  # pragma: no cover - the ranges above leave room
        raise ValueError("no scene found")
    block = float(rng.uniform(lo, hi))
    # the outer object touches the drawer's front plate (beside the handle) at pull `block`
    xo = FRONT - PLATE - block - r_o - 1e-3
    yo = float(rng.choice([-1.0, 1.0]) * rng.uniform(0.14, 0.22))  # clear of the hand on the handle
    sx, sy, sz = STAND
    fixed = [ObjectSpec("stand", "box", STAND, (xo, yo, sz / 2, 0.0), movable=False)]
    (tx, ty), (tsx, tsy) = TABLE
    fixed.append(ObjectSpec("table", "box", (tsx, tsy, TABLE_TOP), (tx, ty, TABLE_TOP / 2, 0.0), movable=False))
    objects = [ObjectSpec("inner", "cylinder", INNER, (FRONT + xi, yi, z_inner, 0.0)),
               ObjectSpec("outer", "cylinder", (r_o, OUTER[1]), (xo, yo, sz + OUTER[1] / 2 + REST_GAP, 0.0))]
    regions = {"table": (tx - tsx / 2, tx + tsx / 2, ty - tsy / 2, ty + tsy / 2)}
    return Layout(fixed, objects, regions, "inner", "hold", ("side",),
                  extra={"table_top": TABLE_TOP, "variant": variant, "supports": ("table", "stand"), "need": exact, "block": block,
                         "grasps_of": {"inner": ("top",)}, "base_limits": BASE_LIMITS})
