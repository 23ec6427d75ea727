"""Grasps for any robot: side / top grasp poses from the tool frame and the gripper's range, the proofs that
an object cannot be grasped (too wide, no room for the hand), and straight-line IK paths (approach, lift).
The pose generators (generators.py) build on them."""
from __future__ import annotations

import math
from dataclasses import replace

import numpy as np

from interlayer.refine import Infeasible

from .state import LIFT, OPEN_CLEARANCE, PRE_GRASP, pose4, rz, trans, wrap

LINE_STEP = 0.05  # m between IK waypoints of straight-line approaches
# m between those of the lift after a grasp: the joint-space line between two IK solutions 5 cm apart strays
# 0.5 mm sideways, and a box lifted from 0.3 mm beside another touched it (move_several_8: blue and red1, each
# blocked the other's every raise); the stray shrinks with the square of the step
LIFT_STEP = 0.01
GRASP_CLEARANCE = 0.001  # the gripper must open at least this much wider than the object
GRASP_DEPTH = 0.04  # m: the deepest a side grasp reaches into an object (tool point to its near face)
# rad: side grasps of a cylinder face up to this far off the heading asked for. A mobile base varies the
# heading itself (it stands elsewhere); a fixed one cannot, and an object near it is reached sideways only:
# radially, the pre-grasp would sit on the base (Panda, Clutter-25: 0 of 76 radial grasps of objects
# within 0.55 m found, 76 of 76 at 1 rad off)
SIDE_SPREAD, FIXED_SPREAD = 0.5, 1.2
# rad: a fixed base, which cannot walk round a crowd to reach an object from its open side, also offers side
# grasps of a cylinder pitched down this far, held near its top: the hand comes from above the neighbours
# instead of between them (Panda, Clutter-25 seed 1: 25 of 25 objects with a free approach; 5 with level grasps)
FIXED_PITCH = 1.0
DOWN = np.array([[0, 0, 1, 0], [0, 1, 0, 0], [-1, 0, 0, 0], [0, 0, 0, 1.0]])  # tool x pointing down


def _problem_grasps(problem, obj=None):
    """Grasp kinds allowed for obj: the layout's, unless its extra "grasps_of" names some for obj."""
    layout = problem.geometry.layout
    return tuple(layout.extra.get("grasps_of", {}).get(obj, layout.grasps))


def grasp_poses(geometry, name, P, heading, kinds, rng, n_side=5):
    """Tool poses grasping object ``name`` at pose P, facing roughly along ``heading`` (world yaw): side
    grasps of a cylinder within SIDE_SPREAD of it (FIXED_SPREAD for a fixed base). Only grasps whose
    closing width fits the gripper are returned."""
    o = geometry.specs[name]
    spread = SIDE_SPREAD if geometry.robot.mobile else FIXED_SPREAD
    opening = geometry.robot.max_gripper_opening
    x, y, z = P[:3, 3]
    yaw_o = math.atan2(P[1, 0], P[0, 0])
    h = o.height
    out = []
    if "side" in kinds:
        zs = z + side_raise(geometry, name)
        if o.shape == "cylinder":
            if 2 * o.size[0] + GRASP_CLEARANCE <= opening:
                offs = [0.0] + [float(v) for v in rng.uniform(-spread, spread, size=n_side - 1)]
                depth = None if geometry.robot.mobile else _pitched_depth(geometry.robot, o.size[0], h, FIXED_PITCH)
                back = trans(-seat(geometry.robot, o.size[0], h), 0, 0)
                for d in offs:  # a fixed base's pitched grasp first: its wide hand passes above the neighbours
                    if depth is not None:
                        out.append(("side", trans(x, y, z + h / 2 - depth) @ rz(heading + d) @ ry(FIXED_PITCH)))
                    out.append(("side", trans(x, y, zs) @ rz(heading + d) @ back))
        else:
            for k in range(4):
                yaw = yaw_o + k * math.pi / 2
                across = o.size[1] if k % 2 == 0 else o.size[0]  # extent along the closing (y) axis
                depth = (o.size[0] if k % 2 == 0 else o.size[1]) / 2  # from the near face to the centre
                if across + GRASP_CLEARANCE <= opening and abs(wrap(yaw - heading)) < math.pi / 2 - 0.2:
                    # a long box is held near its face: the palm stays GRASP_DEPTH from the tool point
                    out.append(("side", trans(x, y, zs) @ rz(yaw) @ trans(-max(0.0, depth - GRASP_DEPTH), 0, 0)))
    if "top" in kinds:
        depth = min(0.03, h / 2)
        zt = z + h / 2 - depth
        if o.shape == "cylinder":
            if 2 * o.size[0] + GRASP_CLEARANCE <= opening:
                out += [("top", trans(x, y, zt) @ rz(heading + d) @ DOWN) for d in (0.0, math.pi / 2)]
        else:
            for k in range(2):
                across = o.size[1] if k == 0 else o.size[0]
                if across + GRASP_CLEARANCE <= opening:
                    out.append(("top", trans(x, y, zt) @ rz(yaw_o + k * math.pi / 2) @ DOWN))
    return out


def side_raise(geometry, name) -> float:
    """How far above its centre a side grasp holds object ``name``: 0, unless the layout gives
    ``extra["side_grasp"] = (low, below_top)``: then a short object is held at least ``low`` above its
    base, but no higher than ``below_top`` under its top (taller ones stay at their centre). Held at its
    centre, a block 8 cm tall puts the PR2's wrist 4 cm over the table, where the wrist link touches it
    at most rolls and the forearm cannot come down to it from above."""
    layout = getattr(geometry, "layout", None)  # a stand-in geometry may give specs and robot alone
    given = None if layout is None else layout.extra.get("side_grasp")
    if given is None:
        return 0.0
    low, below_top = given
    h = geometry.specs[name].height
    return max(0.0, min(low - h / 2, h / 2 - below_top))


def ry(a: float) -> np.ndarray:
    """Rotation by ``a`` about y: a tool x axis pitched down by ``a``."""
    c, s = math.cos(a), math.sin(a)
    return np.array([[c, 0, s, 0], [0, 1, 0, 0], [-s, 0, c, 0], [0, 0, 0, 1.0]])


def _pitched_depth(robot, radius: float, height: float, pitch: float):
    """How far below its top a side grasp of a cylinder pitched down by ``pitch`` holds it: the deepest of
    6 .. 2 cm (the pads' centre below the rim) at which the hand, opened as for the approach, clears the
    cylinder itself, or None.
    It depends on the hand and the cylinder only: measured once per robot and size."""
    def measure():
        cw, q = _hand_opened_for(robot, radius, height)
        return next((d for d in (0.06, 0.05, 0.04, 0.03, 0.02) if d < height / 2 and not any(
            cw.hand_collides(q, a, trans(0, 0, height / 2 - d) @ ry(pitch), movables=True) for a in robot.arms)), None)

    return once(robot, ("pitched_depth", round(radius, 6), round(height, 6), pitch), measure)


def once(owner, key, compute):
    """``compute()``, kept on ``owner`` under ``key``: for what depends only on the owner (a robot, a run's
    geometry) and the key."""
    known = owner.__dict__.setdefault("_once", {})
    if key not in known:
        known[key] = compute()
    return known[key]


def check_graspable(problem, name):
    """Raise Infeasible when no grasp of the allowed kinds fits the gripper and the goal needs the object."""
    geometry = problem.geometry
    o = geometry.specs[name]
    found = fits_gripper(geometry, name, _problem_grasps(problem, name))
    if not found and goal_needs(problem, name):
        width = 2 * o.size[0] if o.shape == "cylinder" else min(o.size[0], o.size[1])
        raise Infeasible(f"{name} is {width:.3f} m wide but the {geometry.robot.description.name} gripper opens only "
                         f"{geometry.robot.max_gripper_opening:.3f} m: no grasp exists")
    return found


def fits_gripper(geometry, name, kinds) -> bool:
    """Some grasp of ``kinds`` of object ``name`` fits the gripper's opening (from any side)."""
    o = geometry.specs[name]
    rng = np.random.default_rng(0)
    return any(grasp_poses(geometry, name, pose4(*o.pose), h, kinds, rng, n_side=1)
               for h in np.linspace(-math.pi, math.pi, 8, endpoint=False))


def goal_needs(problem, obj) -> bool:
    """The goal cannot hold with every fact about ``obj`` as at the start, whatever the other facts are
    (each taken as the goal wants it): only then does an object that cannot be grasped prove the problem
    unsolvable. A goal with a choice (hold any one of a class) does not need any one of its objects."""
    from interlayer import logic

    def best(f, positive=True):  # f's truth with the other facts chosen in its favour (over-approximated)
        if isinstance(f, logic.Pred):
            atom = logic.ground_atom(f, {})
            return (atom in problem.init) == positive if obj in atom[1:] else True
        if isinstance(f, logic.Not):
            return best(f.arg, not positive)
        if isinstance(f, (logic.And, logic.Or)):
            parts = [best(a, positive) for a in f.args]
            return all(parts) if isinstance(f, logic.And) == positive else any(parts)
        return True  # quantifiers, conditional effects: no conclusion

    return not best(logic.parse(problem.goal))


def check_hand_fits(problem, world, obj):
    """Raise Infeasible when the goal needs ``obj`` moved but every grasp of it where it stands puts the
    hand into a fixed obstacle (``hand_blockers``); called when a pick generator found nothing, to say why."""
    if not goal_needs(problem, obj):
        return
    why = no_grasp_fits(problem, world, obj)
    if why:
        raise Infeasible(f"{why}, and the goal needs {obj} moved")


def no_grasp_fits(problem, world, obj) -> str:
    """The sentence saying why no grasp of ``obj`` can ever be taken where it stands (``hand_blockers``), or ""."""
    geometry = problem.geometry
    blockers = hand_blockers(problem, world, obj)
    if not blockers:
        return ""
    return (f"every grasp of {obj} that fits the gripper puts the {geometry.robot.description.name}'s fingers into "
            f"{', '.join(blockers)} where {obj} stands (the gripper opened only {OPEN_CLEARANCE * 100:.0f} cm wider than "
            f"{obj}{_padded(geometry)})")


def _padded(geometry) -> str:
    return f"; planning keeps {geometry.line_padding * 100:.1f} cm from fixed obstacles at a grasp" if geometry.line_padding else ""


def hand_blockers(problem, world, obj) -> tuple:
    """The fixed obstacles that the hand, opened only as wide as the grasp needs, meets at every grasp of
    ``obj`` where it stands, whatever the arm and base do (fixed obstacles never move); () when some grasp
    is clear of them or nothing is proved. Boxes only (their grasps are finitely many), objects not riding
    on an articulated body nor held. A function of obj's pose and the fixed world: computed once per pose."""
    geometry = problem.geometry
    o = geometry.specs[obj]
    if o.shape != "box" or obj in world.riders or world.holder(obj) is not None:
        return ()
    P = world.objects[obj]
    # what else the verdict reads: the robot's base where it decides the grasp's base (top grasps, a fixed
    # base), the articulated bodies' joints (a drawer's front is a fixed obstacle)
    base = world.base if "top" in _problem_grasps(problem, obj) or not geometry.robot.mobile else None
    key = ("hand_blockers", obj, tuple(np.round(P[:3, :4].ravel(), 6)), base,
           tuple(sorted((b, tuple(np.round(v, 6))) for b, v in world.joints.items())))
    return once(geometry, key, lambda: _hand_blockers(problem, world, obj, P))


def _hand_blockers(problem, world, obj, P) -> tuple:
    geometry = problem.geometry
    rng = np.random.default_rng(0)
    poses = _grasp_set(problem, obj, P)
    if not poses:
        return ()  # check_graspable names the width
    ignore = tuple(geometry.fixed) + tuple(world.objects)
    blockers = set()
    robot = geometry.robot
    hands = {}  # arm -> its hand's links (collision pairs name links)
    for a in robot.arms:
        geoms = set(robot.gripper_links(a))
        hands[a] = {robot.model.frames[g.parentFrame].name for g in robot.collision_model.geometryObjects if g.name in geoms}
    with geometry.tight():  # what planning allows at a grasp (the approach and the grasp keep LINE_PADDING)
        for T in poses.values():
            # a base 0.6 m behind the grasp, facing along the approach (a top grasp or a fixed base: where the robot is)
            yaw = _yaw(T) if abs(T[2, 0]) < 0.7 else _bearing(world.base, P[0, 3], P[1, 3])
            base = (float(T[0, 3] - 0.6 * math.cos(yaw)), float(T[1, 3] - 0.6 * math.sin(yaw)), yaw)
            w = replace(world, held={}, base=base if geometry.robot.mobile else world.base)
            opened = geometry.opening(obj, np.linalg.inv(T) @ P)
            found = ((a, geometry.ik(w, a, T, rng, ignore=ignore, gripper=opened)) for a in geometry.robot.arms)
            arm, v = next(((a, v) for a, v in found if v is not None), (None, None))
            if arm is None:
                return ()  # not reached even with nothing in the way: no proof
            q = geometry.sync(w.with_arm(arm, v).with_gripper(arm, opened))
            hits = {b for a, b in geometry.cw.collision_pairs(q, movables=False) if a in hands[arm] and b in geometry.fixed}
            if not hits:
                return ()
            blockers |= hits
    return tuple(sorted(blockers))


def stuck_together(problem, world, pushed=()) -> tuple:
    """(members, walled, walls): the movable boxes that block each other's every grasp where they stand, the largest
    set S such that every grasp of each member that fits the gripper puts the hand, opened as that grasp
    needs, into a fixed obstacle or another member, for either arm, wherever the arm and base are (the hand
    alone, at the grasp); those members that fixed obstacles alone block so (``hand_blockers``' kind); the
    fixed obstacles met.
    Objects move only by being picked, so no member can ever be picked first: none ever moves. Boxes only
    (their grasps are finitely many; a cylinder's turn freely), none riding, held or in ``pushed`` (moved
    otherwise); none with articulated bodies (their links move). A function of the poses, computed once each."""
    geometry = problem.geometry
    if geometry.bodies:
        return (), (), ()
    key = ("stuck_together", tuple(sorted((o, tuple(np.round(P[:3, :4].ravel(), 6))) for o, P in world.objects.items())),
           tuple(sorted(world.riders)), tuple(sorted(o for o, _ in world.held.values())), tuple(sorted(pushed)))
    return once(geometry, key, lambda: _stuck_together(problem, world, set(pushed)))


def _stuck_together(problem, world, pushed) -> tuple:
    geometry = problem.geometry
    held = {o for o, _ in world.held.values()}
    hits = {}  # object -> for each grasp, for each arm: what the hand touches there
    for obj, P in world.objects.items():
        if geometry.specs[obj].shape != "box" or obj in world.riders or obj in held or obj in pushed:
            continue
        grasps = _grasp_hits(problem, world, obj, P)
        if grasps:
            hits[obj] = grasps
    members = set(hits)
    while True:  # drop a member with a grasp that only non-members (they may move) block for some arm
        out = {o for o in members if not all(all(h & geometry.fixed or h & (members - {o}) for h in arms)
                                             for arms in hits[o])}
        if not out:
            walled = {o for o in members if all(all(h & geometry.fixed for h in arms) for arms in hits[o])}
            walls = {f for o in members for arms in hits[o] for h in arms for f in h & geometry.fixed}
            return tuple(sorted(members)), tuple(sorted(walled)), tuple(sorted(walls))
        members -= out


def _grasp_hits(problem, world, obj, P) -> list:
    """For each grasp of ``obj`` at pose P (the finite set ``_grasp_set``), for each arm: the fixed obstacles
    and movables that the hand alone, opened as the grasp needs, touches with its tool frame at the grasp,
    with the padding planning allows there (``tight``); [] as soon as one is clear (the usual answer)."""
    geometry = problem.geometry
    out = []
    with geometry.tight():
        for T in _grasp_set(problem, obj, P).values():
            out.append([])
            for a in geometry.robot.arms:
                hits = geometry.hand_hits(world.with_gripper(a, geometry.opening(obj, np.linalg.inv(T) @ P)), a, T,
                                          (obj,), movables=True)
                if not hits:
                    return []
                out[-1].append(frozenset(hits))
    return out


def stuck_sentence(problem, members, walls=()) -> str:
    """Why no member of ``members`` (``stuck_together``) can ever be picked; ``walls``: the fixed obstacles
    some of their grasps meet."""
    geometry = problem.geometry
    names = f"{', '.join(members[:-1])} and {members[-1]}" if len(members) > 1 else members[0]
    padded = _padded(geometry) if walls else ""
    walls = f" or into {', '.join(walls)}" if walls else ""
    return (f"{names} stand so close that every grasp of each that fits the gripper puts the "
            f"{geometry.robot.description.name}'s fingers into another of them{walls} where they stand "
            f"(the gripper opened only {OPEN_CLEARANCE * 100:.0f} cm wider than the block{padded}), so none of them "
            f"can be picked first and none can ever move")


def _grasp_set(problem, obj, P) -> dict:
    """Every tool pose grasping ``obj`` at pose P that the pick generators can offer, for a box: its side and top
    grasps from 8 headings (each within a quarter turn of one), deduplicated."""
    rng = np.random.default_rng(0)
    poses = {}
    for heading in np.linspace(-math.pi, math.pi, 8, endpoint=False):
        for _, T in grasp_poses(problem.geometry, obj, P, heading, _problem_grasps(problem, obj), rng, n_side=1):
            poses[tuple(np.round(T[:3, :4].ravel(), 6))] = T
    return poses


def _waypoints(geometry, world, arm, T, kind, rng, obj, attempts=10, hand_check=False, splits=0):
    """(approach, raise) for grasping ``obj`` at tool pose T: ``approach`` is a list of IK solutions
    along the straight line from the pre-grasp (PRE_GRASP behind T along the tool x axis) to T, each
    seeded by the next one; ``raise`` lifts the grasp by LIFT, then withdraws it by PRE_GRASP (back
    along the approach for side grasps, further up for top grasps), out of shelves and cubbies. None if
    IK fails, the joint path strays, or a piece of it hits a fixed obstacle (the gripper opened as the
    grasp needs). ``attempts``: IK seeds for the grasp. ``hand_check``: first reject, without IK, a grasp
    or pre-grasp whose hand alone (opened as the grasp needs) touches a fixed obstacle. The grasp and the
    lines keep LINE_PADDING from fixed obstacles (``geometry.tight``); their far ends, where the transits
    start and end, the full padding."""
    opened = geometry.opening(obj, np.linalg.inv(T) @ world.objects[obj])
    with geometry.tight():
        wps = _tool_lines(geometry, world, arm, T, kind, rng, obj, opened, attempts, hand_check, splits)
    if wps is None or not line_ends_clear(geometry, world.with_gripper(arm, opened), arm, (wps[0][0], wps[1][-1]), (obj,)):
        return None
    return wps


def line_ends_clear(geometry, world, arm, ends, ignore=()) -> bool:
    """The far ends of straight tool lines found inside ``geometry.tight`` clear the fully padded fixed
    obstacles: transits start or end there."""
    return all(geometry.static_path_ok(world, arm, [v], ignore) for v in ends)


def _tool_lines(geometry, world, arm, T, kind, rng, obj, opened, attempts, hand_check, splits):
    ignore = (obj,)
    if hand_check:
        hand = world.with_gripper(arm, opened)
        if not (geometry.hand_free(hand, arm, T, ignore) and
                geometry.hand_free(hand, arm, T @ trans(-PRE_GRASP, 0, 0), ignore)):
            return None
    grasp = geometry.ik(world, arm, T, rng, ignore=ignore, gripper=opened, attempts=attempts)
    if grasp is None:
        return None
    line = _line(geometry, world, arm, T, lambda d: T @ trans(-d, 0, 0), PRE_GRASP, grasp, rng, ignore, opened, splits)
    if line is None or not geometry.static_path_ok(world.with_gripper(arm, opened), arm, line, ignore):
        return None
    up = _line(geometry, world, arm, T, lambda d: trans(0, 0, d) @ T, LIFT, grasp, rng, ignore, opened, splits, LIFT_STEP)
    if up is None:
        return None
    U = trans(0, 0, LIFT) @ T
    back_at = (lambda d: trans(0, 0, d) @ U) if kind == "top" else (lambda d: U @ trans(-d, 0, 0))
    back = _line(geometry, world, arm, U, back_at, PRE_GRASP, up[-1], rng, ignore, opened, splits)
    if back is None:
        return None
    lift = up + back[1:]
    if not geometry.static_path_ok(world.with_gripper(arm, opened), arm, lift, ignore):
        return None
    return tuple(reversed(line)), tuple(lift[1:])


def _line(geometry, world, arm, T, at, length, start, rng, ignore=(), gripper=None, splits=0, step=LINE_STEP,
          movables=False):
    """IK solutions for at(0) = T, at(step), ..., at(length), each seeded by the previous one (with
    ``splits``, a step that moves the joints too far is split that many times, see _line_step), clear of
    fixed obstacles (and of the movables not in ``ignore``, if ``movables``)."""
    n = max(1, math.ceil(length / step - 1e-9))
    out = [start]
    for k in range(1, n + 1):
        steps = _line_step(geometry, world, arm, at, length * (k - 1) / n, length * k / n, out[-1], rng, ignore, gripper,
                           splits, movables)
        if steps is None:
            return None
        out += steps
    return out


def _line_step(geometry, world, arm, at, d0, d1, prev, rng, ignore, gripper, splits: int, movables=False):
    """IK solutions from ``prev`` (at d0) to at(d1): one, or, when the joints move more than 0.35 rad
    on the way, the halves' (at most ``splits`` times). The joints of a nearly stretched arm move fast
    but continuously, so halving the step halves their move; a jump to another IK branch does not
    shrink. Without the split, side grasps across a table's width failed their approach line."""
    v = geometry.ik(world, arm, at(d1), rng, ignore=ignore, seed=prev, attempts=2, gripper=gripper,
                    **({"movables": True} if movables else {}))
    if v is None:
        return None
    if geometry.arm_space[arm].distance(v, prev) <= 0.35:
        return [v]
    if not splits:
        return None
    half = _line_step(geometry, world, arm, at, d0, (d0 + d1) / 2, prev, rng, ignore, gripper, splits - 1, movables)
    rest = half and _line_step(geometry, world, arm, at, (d0 + d1) / 2, d1, half[-1], rng, ignore, gripper, splits - 1,
                               movables)
    return half + rest if rest else None


def _bearing(base, x, y):
    return math.atan2(y - base[1], x - base[0])


def _yaw(T):
    x = T[:3, 0]
    if abs(x[2]) > 0.7:  # pointing down: use the closing axis
        return math.atan2(T[1, 1], T[0, 1]) - math.pi / 2
    return math.atan2(x[1], x[0])


SEAT_GAP = 0.001  # m: a side-grasped cylinder clears the hand, opened for it, by this much
SEAT_STEP, SEAT_MAX = 0.002, 0.03  # m: the tool point backs off from the axis in these steps, at most this far


def _hand_opened_for(robot, radius: float, height: float, gap: float = 0.0):
    """A collision world holding a cylinder (grown by ``gap``) at the origin, and a configuration whose hands
    are opened for it as an approach opens them (OPEN_CLEARANCE wider than the cylinder)."""
    from interlayer_pinocchio import CollisionWorld

    cw = CollisionWorld(robot)
    cw.add_cylinder("c", radius + gap, height + 2 * gap, np.eye(4), movable=True)
    q = robot.default_q()
    for a in robot.arms:
        q = robot.set_gripper_opening(q, a, 2 * radius + OPEN_CLEARANCE)
    return cw, q


def seat(robot, radius: float, height: float) -> float:
    """How far behind a side-grasped cylinder's axis the tool point stands (m) so that every arm's hand,
    opened OPEN_CLEARANCE wider than the cylinder, clears it by SEAT_GAP: 0 for a hand whose palm is far
    enough behind its tool point (PR2, Panda, UR5, TIAGo); the Kinova's palm reaches 0.4 mm into a 0.04 m
    cylinder centred at its tool point, so every such grasp touched the object it was about to pick.
    It depends on the hand and the cylinder only: measured once per robot and size."""
    def measure():
        cw, q = _hand_opened_for(robot, radius, height, SEAT_GAP)
        steps = [k * SEAT_STEP for k in range(int(round(SEAT_MAX / SEAT_STEP)) + 1)]
        # none clear within SEAT_MAX: the grasp at the axis, as before (its approach will say what it touches)
        return next((b for b in steps if not any(cw.hand_collides(q, a, trans(-b, 0, 0), movables=True)
                                                 for a in robot.arms)), 0.0)

    return once(robot, ("seat", round(radius, 6), round(height, 6)), measure)
