"""Where a mobile robot stands to reach an object with one arm: the cells (distance, bearing in the base's
frame) from which the arm reaches a level grasp at a given height and the pre-grasp behind it, measured
by IK once per robot, arm and height (cached). A one-arm robot whose shoulder is on one side of its base,
or whose arm reaches far but folds badly, is offered bases where its arm works, not the PR2's annulus."""
from __future__ import annotations

import math

import numpy as np

from .state import PRE_GRASP, pose4, rz, trans, wrap as _wrap

_RADII = tuple(round(0.3 + 0.05 * k, 2) for k in range(19))  # 0.3 .. 1.2 m from the base origin to the grasp
_BEARINGS = tuple(round(-1.2 + 0.15 * k, 2) for k in range(17))  # rad off the base's x axis
JITTER = (0.025, 0.075)  # half a cell (m, rad): samples spread over the whole cell
AHEAD = 0.3  # rad
BEARING_STEP = math.pi / 12  # rad between the approach directions tried
SECTOR, NEAR = 0.8, 0.95  # rad off straight behind a fixed tool heading, m from it: Clutter's annulus (base_near)
_VERSION = 1  # bump when the method changes: cached maps of the old one are ignored


def reach_cells(robot, arm: str, z: float) -> tuple[tuple[float, float], ...]:
    """(distance, bearing) cells from which ``arm`` reaches a level tool pose ``z`` above the floor facing
    along the bearing, and the same pose PRE_GRASP nearer (the approach's start): IK with seeded restarts,
    only the robot's own body in the way. Heights are rounded to 5 cm; the same cells every run."""
    from interlayer import cache

    z = round(z / 0.05) * 0.05
    desc = robot.description
    q0 = robot.default_q((0.0, 0.0, 0.0))
    memo = robot.__dict__.setdefault("_reach_cells", {})
    if (arm, z) in memo:
        return memo[arm, z]
    key = cache.digest("reach_cells", _VERSION, desc.urdf.read_bytes(), repr(desc), arm, round(z, 4),
                       np.round(q0, 6).tolist(), robot.reach_seed(arm), PRE_GRASP)
    found = cache.load("reach_cells", key)
    if not isinstance(found, list):
        found = _measure(robot, arm, z, q0)
        cache.store("reach_cells", key, found)
    memo[arm, z] = cells = tuple((float(r), float(a)) for r, a in found)
    return cells


def _measure(robot, arm, z, q0):
    from interlayer_pinocchio import CollisionWorld, solve_ik

    cw = CollisionWorld(robot)
    q = robot.set(q0, f"{arm}_arm", robot.reach_seed(arm))
    rng = np.random.default_rng(0)
    cells = []
    for r in _RADII:
        for a in _BEARINGS:
            grasp = solve_ik(robot, arm, pose4(r * math.cos(a), r * math.sin(a), z, a), q, rng=rng, world=cw, attempts=4)
            if grasp is None:
                continue
            near = r - PRE_GRASP
            if solve_ik(robot, arm, pose4(near * math.cos(a), near * math.sin(a), z, a), robot.set(q, f"{arm}_arm", grasp),
                        rng=rng, world=cw, attempts=2) is not None:
                cells.append([r, a])
    return cells


def base_near(rng, cells, x, y, bearings=()):
    """A base pose (x, y, yaw) from which the object at (x, y) lies in a random one of ``cells``, seen along
    one of ``bearings`` (world directions from the base to the object, each BEARING_STEP wide; any
    direction when empty). Cells with the object ahead (within AHEAD of the base's heading) come first, as
    the PR2's annulus had it: the arm's transits stay short and a second arm out of the way."""
    cells = [c for c in cells if abs(c[1]) <= AHEAD + 1e-9] or cells
    r, a = cells[int(rng.integers(len(cells)))]
    r, a = r + rng.uniform(-JITTER[0], JITTER[0]), a + rng.uniform(-JITTER[1], JITTER[1])
    if bearings:
        bearing = bearings[int(rng.integers(len(bearings)))] + rng.uniform(-BEARING_STEP / 2, BEARING_STEP / 2)
    else:
        bearing = rng.uniform(-math.pi, math.pi)
    bx, by = x - r * math.cos(bearing), y - r * math.sin(bearing)
    return float(bx), float(by), float(_wrap(bearing - a))


def annulus(rng, x, y, rmin=0.45, rmax=0.80):
    """A base pose 0.45 to 0.80 m from (x, y), facing it (+- 0.3 rad): the PR2's annulus."""
    r, a = rng.uniform(rmin, rmax), rng.uniform(-math.pi, math.pi)
    bx, by = x + r * math.cos(a), y + r * math.sin(a)
    return (float(bx), float(by), float(_wrap(math.atan2(y - by, x - bx) + rng.uniform(-0.3, 0.3))))


def around(geometry, arm, rng, x, y, z, bearings=(), level=True):
    """A base pose from which ``arm`` reaches a level grasp at (x, y, z) and its pre-grasp (reach_cells)
    coming from one of ``bearings``, or one of the annulus when no cell of the map reaches that height or
    the grasp is not ``level`` (a top grasp, a domain's own grasps: the map does not measure them)."""
    cells = reach_cells(geometry.robot, arm, z) if level else ()
    return base_near(rng, cells, x, y, bearings) if cells else annulus(rng, x, y)


def standing(geometry, arm, x, y, z, heading=None, spread=0.0) -> list:
    """The (distance, bearing, world direction) of each cell of ``reach_cells(arm, z)`` from which the base,
    seeing (x, y) along that world direction (every BEARING_STEP / 3; with ``heading``, a tool heading fixed
    by the object's pose and grasp, only within ``spread`` of it), stands within its limits and where it
    can drive (the layout's ``base_area``, when it knows one). Cached per question: a search asks about
    one spot often."""
    from .scene import base_limits

    layout = geometry.layout
    key = (id(layout), arm, round(z / 0.05), float(x), float(y), heading, spread)
    hit = _STANDING.get(key)
    if hit is None or hit[0] is not layout:
        (lx, hx), (ly, hy) = base_limits(layout)
        area = layout.extra.get("base_area")
        step = BEARING_STEP / 3
        ways = np.arange(-math.pi, math.pi, step) if heading is None else \
            heading + step * np.arange(-math.floor(spread / step), math.floor(spread / step) + 1)
        out = []
        for r, a in reach_cells(geometry.robot, arm, z):
            for b in ways:
                bx, by = x - r * math.cos(b), y - r * math.sin(b)
                if lx <= bx <= hx and ly <= by <= hy and (area is None or area(bx, by)):
                    out.append((r, a, float(b)))
        if len(_STANDING) > 512:
            _STANDING.clear()
        hit = _STANDING[key] = (layout, out)
    return hit[1]


_STANDING: dict = {}  # (id of the layout, arm, height, x, y, heading, spread) -> (the layout, the cells that stand)


def behind(geometry, arm, x, y, z, heading) -> list:
    """The :func:`standing` options for a tool heading fixed by the object's pose and grasp: straight behind
    the tool at any distance, or off that line within SECTOR when NEAR (Clutter's annulus: beside a
    table's end straight behind stands nowhere). A judgement of whether a grasp fits there (pbjson's _fits)
    counts these, and a put-down's last search draws from them (reaching_base's ``off_line``), so that a
    grasp judged to fit finds its base."""
    return [o for o in standing(geometry, arm, x, y, z, heading, SECTOR) if o[2] == heading or o[0] <= NEAR]


def reaching_base(geometry, arm, rng, x, y, z, heading=None, off_line=False):
    """A base pose from which ``arm`` reaches a level grasp at (x, y, z) and its pre-grasp, drawn from
    :func:`standing` (None: no cell stands anywhere the base can); with a fixed tool ``heading`` and
    ``off_line``, from the options of :func:`behind` off straight behind the tool. An annulus that faces the
    spot misses what lies at the back of a deep table: the arm reaches it from 1.0-1.1 m, the shoulder
    turned to it."""
    options = standing(geometry, arm, x, y, z, heading)
    if off_line and heading is not None:
        options = [o for o in behind(geometry, arm, x, y, z, heading) if o[2] != heading]
    if not options:
        return None
    r, a, b = options[int(rng.integers(len(options)))]
    r, a = r + rng.uniform(-JITTER[0], JITTER[0]), a + rng.uniform(-JITTER[1], JITTER[1])
    if heading is None:
        b += rng.uniform(-BEARING_STEP / 6, BEARING_STEP / 6)
    return base_of(x, y, (r, a, b))


def base_of(x, y, option) -> tuple:
    """The base pose of a :func:`standing` option (distance, bearing, world direction) for the spot (x, y)."""
    r, a, b = option
    return float(x - r * math.cos(b)), float(y - r * math.sin(b)), float(_wrap(b - a))


def open_bearings(geometry, world, arm, obj, P):
    """The directions (world yaw, BEARING_STEP apart) along which the hand alone, opened for ``obj``,
    reaches a level grasp of it at P and its pre-grasp without touching a fixed obstacle: a cubby's mouth
    leaves a narrow fan of them, and a base elsewhere costs IK in vain."""
    out = []
    for b in np.arange(-math.pi, math.pi, BEARING_STEP):
        T = P @ rz(b - math.atan2(P[1, 0], P[0, 0]))
        hand = world.with_gripper(arm, geometry.opening(obj, np.linalg.inv(T) @ P))
        with geometry.tight():  # the grasp's own margin; the pre-grasp, where the transit ends, keeps the full padding
            at = geometry.hand_free(hand, arm, T, (obj,))
        if at and geometry.hand_free(hand, arm, T @ trans(-PRE_GRASP, 0, 0), (obj,)):
            out.append(float(b))
    return out
