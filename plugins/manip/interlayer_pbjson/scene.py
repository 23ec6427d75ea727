"""Reading a pybullet-planning JSON problem (bodies / robots / task) into a scene: shapes, surfaces,
regions, the robot's start and the goals. Everything the format allows is read; what Interlayer cannot
model is a ``UserError`` naming the field and its value.

Conventions of the format (checked against the preview images): quaternions are ``{w, x, y, z}``;
a box's ``extents`` are half extents; a cylinder is centred on its origin with its axis along the
geom's z; each geom has its own ``point`` / ``quat`` relative to its body; a ``trimesh`` whose file is
not shipped (``filename`` empty) is drawn and collided as the body's ``aabb`` (given in the body frame,
half extents); a sphere of radius 0 is a marker and is skipped. Goal poses are body poses
``[qw, qx, qy, qz, x, y, z]``.
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np
from interlayer.errors import UserError
from interlayer_manip.scene import ObjectSpec

GEOM_TYPES = ("box", "cylinder", "sphere", "trimesh", "mesh")
GOAL_KEYS = ("goal_holding", "goal_regions", "goal_poses", "goal_stackings", "goal_cleaned", "goal_cooked", "goal_config")
ON_TOL = 0.01  # m: an object whose bottom is this close to a surface's height rests on it
FLOOR_TOP = 0.01  # m: a fixed slab whose top is below this is the floor (drawn, not collided with the base)


@dataclass
class Surface:
    """A place objects rest on: a table top, a region, a sink or stove top, or an object's top."""

    name: str
    kind: str  # "table" | "region" | "sink" | "stove" | "top"
    polygon: list  # [(x, y), ...] counter-clockwise, world frame (for "top": in the object's frame)
    z: float  # height of the surface (for "top": above the object's centre)
    body: str | None = None  # the body it belongs to (the object, for "top")
    color: tuple | None = None


@dataclass
class Scene:
    name: str
    fixed: list  # ObjectSpec (one per collision shape)
    objects: list  # ObjectSpec (movable)
    offsets: dict  # object -> (x, y, z, yaw) of its shape in its body frame (goal poses are body poses)
    surfaces: dict  # name -> Surface
    colors: dict  # spec name -> rgba
    floors: list  # names of fixed specs that are the floor
    base: tuple  # (x, y, yaw)
    torso: float | None
    arms: dict  # "left"/"right" -> {joint name: value} from robots[0].conf
    grasps: tuple
    goals: dict
    notes: list = field(default_factory=list)  # approximations made, shown by `interlayer check`
    camera: tuple | None = None  # where the file's camera looks from (relative to the scene's centre)
    body_of: dict = field(default_factory=dict)  # fixed spec -> its body
    floor_objects: list = field(default_factory=list)  # movable objects standing on the floor (floor_object_names)
    floor_fixed: list = field(default_factory=list)  # (name, fixed shape, depth) of those standing in a fixed body


def rotation(q, where) -> np.ndarray:
    try:
        w, x, y, z = (float(q[k]) for k in "wxyz")
    except (KeyError, TypeError, ValueError):
        raise UserError(f"{where} = {q!r} is not a quaternion {{\"w\", \"x\", \"y\", \"z\"}}.") from None
    n = math.sqrt(w * w + x * x + y * y + z * z)
    if not n > 1e-9 or not math.isfinite(n):
        raise UserError(f"{where} = {q!r} is not a rotation (zero or non-finite quaternion).")
    w, x, y, z = w / n, x / n, y / n, z / n
    return np.array([[1 - 2 * (y * y + z * z), 2 * (x * y - z * w), 2 * (x * z + y * w)],
                     [2 * (x * y + z * w), 1 - 2 * (x * x + z * z), 2 * (y * z - x * w)],
                     [2 * (x * z - y * w), 2 * (y * z + x * w), 1 - 2 * (x * x + y * y)]])


def point(p, where) -> np.ndarray:
    try:
        v = np.array([float(p[k]) for k in "xyz"])
    except (KeyError, TypeError, ValueError):
        raise UserError(f"{where} = {p!r} is not a point {{\"x\", \"y\", \"z\"}}.") from None
    if not np.isfinite(v).all():
        raise UserError(f"{where} = {p!r} is not a finite point.")
    return v


def frame(node, where) -> np.ndarray:
    T = np.eye(4)
    T[:3, :3] = rotation(node.get("quat", {"w": 1, "x": 0, "y": 0, "z": 0}), f"{where}.quat")
    T[:3, 3] = point(node.get("point", {"x": 0, "y": 0, "z": 0}), f"{where}.point")
    return T


def _upright(T, shape, size, where):
    """(size, (x, y, z, yaw)) of a shape at T whose one axis is vertical; boxes may lie on any face."""
    R = T[:3, :3]
    j = next((k for k in range(3) if abs(R[2, k]) > 1 - 1e-6), None)
    if j is None or (shape == "cylinder" and j != 2):
        raise UserError(f"{where}.quat tilts the {shape} (no axis vertical); Interlayer supports shapes standing "
                        f"upright or lying on a face (rotations by multiples of 90 degrees about x or y).")
    a = 0 if j != 0 else 1
    yaw = math.atan2(R[1, a], R[0, a])
    if shape == "box":
        b = 3 - j - a
        size = (size[a], size[b], size[j])
    return tuple(float(s) for s in size), (float(T[0, 3]), float(T[1, 3]), float(T[2, 3]), float(yaw))


def _color(geom):
    c = geom.get("color")
    try:
        return tuple(float(c[k]) for k in "rgba")
    except (KeyError, TypeError, ValueError):
        return None


def _aabb_shape(body, T, where):
    """The body's aabb (body frame, half extents) as a box: how a mesh without its file is modelled."""
    box = body.get("aabb")
    if not isinstance(box, dict) or "center" not in box or "extents" not in box:
        raise UserError(f"{where} is a mesh without a mesh file and the body has no 'aabb' to stand for it; "
                        f"give the body an aabb {{\"center\", \"extents\"}} or box/cylinder geoms.")
    c, e = [float(v) for v in box["center"]], [2 * float(v) for v in box["extents"]]
    if len(c) != 3 or len(e) != 3 or min(e) <= 0:
        raise UserError(f"bodies[{body.get('name')}].aabb = {box!r} must have a 3-D center and positive extents.")
    C = T.copy()
    C[:3, 3] = T[:3, :3] @ np.array(c) + T[:3, 3]
    return "box", tuple(e), C


def read_body(body, i, movable):
    """[(shape, size, 4x4 pose, colour, where)] of one body; a movable body is one shape."""
    where = f"bodies[{i}] ({body['name']})"
    T = frame(body, where)
    shapes, mesh = [], False
    links = body["links"]
    if not isinstance(links, list) or not all(isinstance(link, list) for link in links):
        raise UserError(f"{where}.links must be a list of lists of geoms.")
    for li, link in enumerate(links):
        # a link has one colour in the previews: its last geom's (e.g. the IKEA tables are red all over)
        color = next((c for c in (_color(g) for g in reversed(link) if isinstance(g, dict)) if c), None)
        for gi, geom in enumerate(link):
            at = f"{where}.links[{li}][{gi}]"
            kind = geom.get("type") if isinstance(geom, dict) else None
            if kind not in GEOM_TYPES:
                raise UserError(f"{at}.type = {kind!r} is not a geom type Interlayer reads ({', '.join(GEOM_TYPES)}).")
            G = T @ frame(geom, at)
            if kind == "box":
                e = [float(v) for v in geom["extents"]]
                if len(e) != 3 or min(e) <= 0:
                    raise UserError(f"{at}.extents = {geom['extents']!r} must be three positive half extents.")
                shapes.append(("box", tuple(2 * v for v in e), G, color, at))
            elif kind == "cylinder":
                r, h = float(geom["radius"]), float(geom["height"])
                if not (r > 0 and h > 0):
                    raise UserError(f"{at}: radius {r} and height {h} must be positive.")
                shapes.append(("cylinder", (r, h), G, color, at))
            elif kind == "sphere":
                r = float(geom["radius"])
                if r > 0:  # a sphere stands in as the cylinder around it
                    shapes.append(("cylinder", (r, 2 * r), G, color, at))
            else:
                if not mesh:
                    shape, size, C = _aabb_shape(body, T, at)
                    shapes.append((shape, size, C, color, at))
                mesh = True
    if not shapes:
        raise UserError(f"{where} has no shape (links hold no box, cylinder or mesh).")
    if movable and len(shapes) > 1:  # a movable object is grasped as one shape: its bounding box
        shape, size, C = _aabb_shape(body, T, f"{where} (a movable body of {len(shapes)} geoms)")
        shapes = [(shape, size, C, shapes[0][3], where)]
    out = []
    for shape, size, G, color, at in shapes:
        size, pose = _upright(G, shape, size, at)
        out.append((shape, size, pose, color, at))
    return T, out, mesh


def polygon_of(spec) -> list:
    """The footprint of a spec (box: its rectangle; cylinder: an octagon around it), counter-clockwise."""
    x, y, _, yaw = spec.pose
    if spec.shape == "box":
        hx, hy = spec.size[0] / 2, spec.size[1] / 2
        pts = [(-hx, -hy), (hx, -hy), (hx, hy), (-hx, hy)]
    else:
        r = spec.size[0]
        pts = [(r * math.cos(k * math.pi / 4), r * math.sin(k * math.pi / 4)) for k in range(8)]
    c, s = math.cos(yaw), math.sin(yaw)
    return [(x + c * px - s * py, y + s * px + c * py) for px, py in pts]


def convex_hull(points) -> list:
    pts = sorted(set((round(float(a), 9), round(float(b), 9)) for a, b in points))
    if len(pts) < 3:
        return pts

    def cross(o, a, b):
        return (a[0] - o[0]) * (b[1] - o[1]) - (a[1] - o[1]) * (b[0] - o[0])

    lower, upper = [], []
    for p in pts:
        while len(lower) >= 2 and cross(lower[-2], lower[-1], p) <= 0:
            lower.pop()
        lower.append(p)
    for p in reversed(pts):
        while len(upper) >= 2 and cross(upper[-2], upper[-1], p) <= 0:
            upper.pop()
        upper.append(p)
    return lower[:-1] + upper[:-1]


def area(poly) -> float:
    return 0.5 * abs(sum(a[0] * b[1] - b[0] * a[1] for a, b in zip(poly, poly[1:] + poly[:1])))


def oriented_box(poly) -> tuple:
    """The smallest rectangle around a convex polygon, in the polygon's own frame: (centre x, centre y,
    yaw, half length, half width), yaw within [-pi/4, pi/4] (a rectangle's sides give its axes, whatever
    the world's)."""
    pts = np.asarray(poly, float)
    best = None
    for (ax, ay), (bx, by) in zip(poly, poly[1:] + poly[:1]):
        if math.hypot(bx - ax, by - ay) < 1e-12:
            continue
        yaw = (math.atan2(by - ay, bx - ax) + math.pi / 4) % (math.pi / 2) - math.pi / 4
        c, s = math.cos(yaw), math.sin(yaw)
        u, v = pts @ np.array([c, s]), pts @ np.array([-s, c])
        size = (u.max() - u.min()) * (v.max() - v.min())
        if best is None or size < best[0] - 1e-12:
            mu, mv = (u.max() + u.min()) / 2, (v.max() + v.min()) / 2
            best = (size, (float(c * mu - s * mv), float(s * mu + c * mv), float(yaw),
                           float(u.max() - u.min()) / 2, float(v.max() - v.min()) / 2))
    return best[1]


def draw_in(poly, rng, n) -> np.ndarray:
    """n points (x, y) drawn uniformly in the smallest box around a convex polygon, in the polygon's own
    frame (see :func:`oriented_box`): as many land inside it however it is turned in the world."""
    from interlayer_clutter.samplers import from_frame

    box = oriented_box(poly)
    return np.column_stack(from_frame(box, rng.uniform(-box[3], box[3], n), rng.uniform(-box[4], box[4], n)))


def inside(poly, x, y, margin=0.0) -> bool:
    """(x, y) lies in the convex counter-clockwise polygon, at least ``margin`` from its edges."""
    for (ax, ay), (bx, by) in zip(poly, poly[1:] + poly[:1]):
        ex, ey = bx - ax, by - ay
        n = math.hypot(ex, ey)
        if n < 1e-12:
            continue
        if (ex * (y - ay) - ey * (x - ax)) / n < margin - 1e-9:
            return False
    return True


def distance_to(poly, x, y) -> float:
    """How far (x, y) lies outside the convex polygon (0 inside it)."""
    if inside(poly, x, y):
        return 0.0
    out = math.inf
    for (ax, ay), (bx, by) in zip(poly, poly[1:] + poly[:1]):
        ex, ey = bx - ax, by - ay
        t = min(1.0, max(0.0, ((x - ax) * ex + (y - ay) * ey) / max(ex * ex + ey * ey, 1e-24)))
        out = min(out, math.hypot(x - ax - t * ex, y - ay - t * ey))
    return out


def apart(a, b, gap=0.0) -> bool:
    """Convex polygons ``a`` and ``b`` are at least ``gap`` apart along the normal of one of their edges
    (then at least ``gap`` apart; near corners this asks a little more than the distance)."""
    for poly in (a, b):
        for (ax, ay), (bx, by) in zip(poly, poly[1:] + poly[:1]):
            n = math.hypot(bx - ax, by - ay)
            if n < 1e-12:
                continue
            nx, ny = (by - ay) / n, (ax - bx) / n
            pa, pb = [px * nx + py * ny for px, py in a], [px * nx + py * ny for px, py in b]
            if min(pb) - max(pa) >= gap or min(pa) - max(pb) >= gap:
                return True
    return False


def _names(task, key, where="task"):
    value = task.get(key) or []
    if not isinstance(value, list) or not all(isinstance(v, str) for v in value):
        raise UserError(f"{where}.{key} = {value!r} must be a list of names.")
    return value


# The collision world's set-up grows with the square of its shapes (measured: 300 bodies 4 s, 600 10 s,
# 2,000 over 100 s and 12 GB): larger files are refused at once, the limit named.
MAX_SHAPES = 500


def _too_large(label, what) -> str:
    return (f"{label}: the scene has {what}; Interlayer plans with at most {MAX_SHAPES} bodies or collision "
            f"shapes (its collision world grows with their square); leave out the bodies far from the task.")


def read_scene(data, label, symbols) -> Scene:
    """The scene of a file. Every body and region gets its symbol from ``symbols`` (an interlayer.names.Names):
    the scene, its goals and everything built on them use the symbols; the file's names are their labels."""
    from collections import Counter

    task, bodies = data["task"], data["bodies"]
    if not isinstance(bodies, list) or not bodies:
        raise UserError(f"{label}: 'bodies' must be a non-empty list of bodies.")
    if len(bodies) > MAX_SHAPES:
        raise UserError(_too_large(label, f"{len(bodies)} bodies"))
    names = [b["name"] for b in bodies]
    dup = sorted(n for n, k in Counter(names).items() if k > 1)
    if dup:
        raise UserError(f"bodies: the name {dup[0]!r} is used by more than one body; body names must be unique.")
    known = set(names)
    movable = _names(task, "object_names")
    on_floor = [n for n in _names(task, "floor_object_names") if n not in movable]
    movable = movable + on_floor  # obstacles on the floor are movable too (pushed or picked: loader.py)
    for key in ("object_names", "table_names", "sink_names", "stove_names", "floor_object_names"):
        for n in _names(task, key):
            if n not in known:
                raise UserError(f"task.{key} names {n!r}, which is not a body of the file.")
    if not _names(task, "object_names") and not isinstance(task.get("goal_config"), list):  # a drive alone needs none (trivial_namo)
        raise UserError("task.object_names is empty: the problem has no movable object.")
    sym = {n: symbols.add(n) for n in names}  # in the file's order: the same file, the same symbols
    role = {n: k for k in ("table", "sink", "stove") for n in _names(task, f"{k}_names")}
    fixed, objects, offsets, colors, floors, notes, surfaces = [], [], {}, {}, [], [], {}
    frames = {}  # movable object -> its body frame at the start (a goal pose may name another object's)
    body_of = {}  # fixed spec -> its body
    for i, body in enumerate(bodies):
        name = sym[body["name"]]
        is_movable = body["name"] in movable
        T, shapes, mesh = read_body(body, i, is_movable)
        if mesh:
            notes.append(f"{body['name']}: mesh without its file, modelled as the body's bounding box")
        specs = []
        for k, (shape, size, pose, color, _) in enumerate(shapes):
            spec_name = name if len(shapes) == 1 else symbols.add(f"{name}_{k}", label=f"{body['name']}_{k}")
            spec = ObjectSpec(spec_name, shape, size, pose, movable=is_movable)
            colors[spec.name] = color
            body_of[spec.name] = name
            specs.append(spec)
        if is_movable:
            objects.append(specs[0])
            frames[body["name"]] = T
            centre = (np.linalg.inv(T) @ np.append(np.array(specs[0].pose[:3]), 1.0))[:3]
            offsets[name] = [*centre.tolist(), specs[0].pose[3] - math.atan2(T[1, 0], T[0, 0])]  # + yaw in the body
            continue
        for spec in specs:
            if spec.shape == "box" and spec.pose[2] + spec.size[2] / 2 < FLOOR_TOP:
                floors.append(spec.name)
        fixed += specs
        if len(fixed) + len(objects) > MAX_SHAPES:
            raise UserError(_too_large(label, f"more than {MAX_SHAPES} collision shapes"))
        if body["name"] in role:
            top = max(specs, key=lambda s: s.pose[2] + s.height / 2)
            surfaces[name] = Surface(name, role[body["name"]], polygon_of(top), top.pose[2] + top.height / 2, name,
                                     colors.get(top.name))
    for i, region in enumerate(task.get("regions") or []):
        where = f"task.regions[{i}]"
        rname = region["name"]
        if not isinstance(rname, str):
            raise UserError(f"{where}.name = {rname!r} must be a string.")
        if rname in sym:
            raise UserError(f"{where}.name = {rname!r} is already the name of a body or region.")
        sym[rname] = rname = symbols.add(rname)
        R = frame(region, where)
        hull = region["hull"]
        try:
            local = np.array([[float(p[0]), float(p[1])] for p in hull])
        except (TypeError, ValueError, IndexError):
            raise UserError(f"{where}.hull = {hull!r} must be a list of [x, y] points.") from None
        if len(local) == 0:
            raise UserError(f"{where}.hull is empty.")
        # the box around the hull's points, as the format's own reader (and its preview images) take it:
        # the files list a rectangle's corners, some with the last one repeated
        (x0, y0), (x1, y1) = local.min(axis=0), local.max(axis=0)
        poly = convex_hull([(R @ np.array([x, y, 0.0, 1.0]))[:2] for x, y in ((x0, y0), (x1, y0), (x1, y1), (x0, y1))])
        if len(poly) < 3 or area(poly) < 1e-6:
            raise UserError(f"{where}.hull = {hull!r} encloses no area.")
        surfaces[rname] = Surface(rname, "region", poly, float(R[2, 3]), None, _color(region))
    goals = _goal_symbols(read_goals(task, frames, {n for n in sym if sym[n] in surfaces}), sym)
    # objects that others rest on, and the stacking targets, get a surface on their top
    specs = {o.name: o for o in objects}
    tops = set(goals["stackings"].values())
    for o in objects:
        bottom = o.pose[2] - o.height / 2
        for other in objects:
            if other is not o and abs(other.pose[2] + other.height / 2 - bottom) < ON_TOL and \
                    inside(polygon_of(other), o.pose[0], o.pose[1]):
                tops.add(other.name)
    for t in sorted(tops):
        s = specs[t]
        top = symbols.add(top_name(t), label=top_name(symbols.label(t)))
        local = polygon_of(ObjectSpec(t, s.shape, s.size, (0.0, 0.0, 0.0, 0.0)))
        surfaces[top] = Surface(top, "top", local, s.height / 2, t, colors.get(t))
    for n in surfaces:
        if n in specs:
            raise UserError(f"task: {n!r} is both a movable object and a surface.")
    on_floor, floor_fixed = [sym[n] for n in on_floor], []
    for name, wall, depth in embedded([o for o in fixed if o.name not in floors], [o for o in objects if o.name in on_floor]):
        # a floor obstacle standing in a wall is part of it (decision_wall_namo_3): no push gets it out
        spec = next(o for o in objects if o.name == name)
        objects.remove(spec)
        on_floor.remove(name)
        fixed.append(ObjectSpec(spec.name, spec.shape, spec.size, spec.pose, movable=False))
        body_of[spec.name] = name
        floor_fixed.append((name, body_of.get(wall, wall), depth))
    robots = data["robots"]
    if not isinstance(robots, list) or len(robots) != 1:
        raise UserError(f"robots: exactly one robot (a PR2) is supported, got {len(robots) if isinstance(robots, list) else robots!r}.")
    base, torso, arms = read_robot(robots[0])
    grasps = task.get("grasp_types") or ["SIDE", "TOP"]
    if not isinstance(grasps, list) or any(str(g).upper() not in ("SIDE", "TOP") for g in grasps):
        raise UserError(f"task.grasp_types = {grasps!r}: Interlayer knows \"SIDE\" and \"TOP\" grasps.")
    camera = None
    if isinstance(data.get("camera"), dict) and isinstance(data["camera"].get("point"), dict):
        centre = np.mean([o.pose[:3] for o in fixed + objects], axis=0)
        camera = tuple(float(v) for v in point(data["camera"]["point"], "camera.point") - centre)
    return Scene(str(task.get("name") or data.get("name") or label), fixed, objects, offsets, surfaces, colors, floors,
                 base, torso, arms, tuple(dict.fromkeys(str(g).lower() for g in grasps)), goals, notes, camera, body_of,
                 on_floor, floor_fixed)


def embedded(fixed, objects) -> list:
    """(object, fixed shape, depth) for each of ``objects`` that stands in a fixed shape deeper than the
    sanity check allows (interlayer_manip.sanity.PENETRATION), the deepest shape named."""
    from interlayer_manip.sanity import PENETRATION, penetrations

    deepest = {}
    for i, j, depth in penetrations([*fixed, *objects], [False] * len(fixed) + [True] * len(objects)):
        if depth > PENETRATION and (i < len(fixed)) != (j < len(fixed)):
            f, o = (i, j) if i < len(fixed) else (j, i)
            name = objects[o - len(fixed)].name
            if depth > deepest.get(name, (None, 0.0))[1]:
                deepest[name] = (fixed[f].name, depth)
    return [(o.name, *deepest[o.name]) for o in objects if o.name in deepest]


def _goal_symbols(goals, sym) -> dict:
    """The goals read on the file's names, over their symbols (a class keeps the file's words as its key)."""
    one = sym.get
    out = dict(goals)
    out["holding"] = tuple(map(one, goals["holding"])) if goals["holding"] else goals["holding"]
    out["members"] = {sym.get(o, o): tuple(map(one, m)) for o, m in goals["members"].items()}
    out["on"] = {sym.get(o, o): one(s) for o, s in goals["on"].items()}
    out["stackings"] = {one(o): one(b) for o, b in goals["stackings"].items()}
    out["poses"] = {one(o): p for o, p in goals["poses"].items()}
    out["pose_of"] = {one(o): one(b) for o, b in goals["pose_of"].items()}
    out["cleaned"], out["cooked"] = [one(o) for o in goals["cleaned"]], [one(o) for o in goals["cooked"]]
    return out


def top_name(obj) -> str:
    """How the top of ``obj`` is named (its symbol may differ: see ``tops``)."""
    return f"{obj}_top"


def tops(surfaces) -> dict:
    """object -> the surface on its top."""
    return {s.body: s.name for s in surfaces.values() if s.kind == "top"}


def read_robot(robot):
    where = "robots[0]"
    T = frame(robot, where)
    if abs(T[2, 2]) < 1 - 1e-6:
        raise UserError(f"{where}.quat tilts the robot; a PR2 base turns about z only.")
    base = (float(T[0, 3]), float(T[1, 3]), float(math.atan2(T[1, 0], T[0, 0])))
    conf = robot.get("conf") or {}
    if not isinstance(conf, dict):
        raise UserError(f"{where}.conf = {conf!r} must map joint names to [value].")
    values = {}
    for joint, v in conf.items():
        try:
            values[joint] = float(v[0] if isinstance(v, list) else v)
        except (TypeError, ValueError, IndexError):
            raise UserError(f"{where}.conf.{joint} = {v!r} is not a joint value [number].") from None
    torso = values.get("torso_lift_joint")
    arms = {arm: {j: v for j, v in values.items() if j.startswith(f"{arm[0]}_") and "gripper" not in j}
            for arm in ("left", "right")}
    return base, torso, arms


def read_goals(task, frames, surfaces) -> dict:
    """The goals of the file. An object entry of goal_holding / goal_regions may be a class: the start of
    several objects' names (``"blue"`` for ``blue1-1``, ``blue2-1``): any one of them does (the format's
    ``exists_*`` problems); goal_holding may list several entries, holding any one object of them does."""
    objects = set(frames)

    def obj(value, where):
        if value not in objects:
            raise UserError(f"{where} = {value!r} is not a movable object (task.object_names).")
        return value

    def members(value, where):
        if isinstance(value, str) and value in objects:
            return (value,)
        found = tuple(sorted(o for o in objects if isinstance(value, str) and value and o.startswith(value)))
        if not found:
            raise UserError(f"{where} = {value!r} is neither a movable object nor the start of one's name "
                            f"(a class); name one of task.object_names.")
        return found

    def mapping(key):
        value = task.get(key) or {}
        if not isinstance(value, dict):
            raise UserError(f"task.{key} = {value!r} must map object names to values.")
        return value

    holding = task.get("goal_holding")
    if holding is False or holding == []:  # how the *namo* files write "nothing to hold"
        holding = None
    if holding is not None and not isinstance(holding, (str, list)):
        raise UserError(f"task.goal_holding = {holding!r} must be an object's name, a class or a list of them.")
    goals = {"holding": None, "holding_as": holding, "members": {}}
    if holding is not None:
        entries = holding if isinstance(holding, list) else [holding]
        goals["holding"] = tuple(dict.fromkeys(o for i, e in enumerate(entries)
                                               for o in members(e, "task.goal_holding" + (f"[{i}]" if isinstance(holding, list) else ""))))
    goals["on"] = {}
    for o, s in mapping("goal_regions").items():
        goals["members"][o] = members(o, f"task.goal_regions key {o!r}")
        if s not in surfaces:
            raise UserError(f"task.goal_regions.{o} = {s!r} is not a table, sink, stove or region of the file.")
        goals["on"][o] = s
    goals["stackings"] = {}
    for o, below in mapping("goal_stackings").items():
        obj(o, f"task.goal_stackings key {o!r}")
        obj(below, f"task.goal_stackings.{o}")
        if below == o:
            raise UserError(f"task.goal_stackings.{o} = {below!r}: an object cannot stand on itself.")
        goals["stackings"][o] = below
    goals["poses"], goals["pose_of"] = {}, {}
    for o, pose in mapping("goal_poses").items():
        obj(o, f"task.goal_poses key {o!r}")
        if pose == "initial":
            goals["poses"][o] = "initial"
            continue
        if isinstance(pose, str) and pose in objects:  # where that object stands at the start (``replace``)
            goals["poses"][o], goals["pose_of"][o] = frames[pose].copy(), pose
            continue
        try:
            qw, qx, qy, qz, x, y, z = (float(v) for v in pose)
        except (TypeError, ValueError):
            raise UserError(f"task.goal_poses.{o} = {pose!r} must be \"initial\", another object's name or "
                            f"[qw, qx, qy, qz, x, y, z].") from None
        T = np.eye(4)
        T[:3, :3] = rotation({"w": qw, "x": qx, "y": qy, "z": qz}, f"task.goal_poses.{o}")
        T[:3, 3] = (x, y, z)
        if T[2, 2] < 1 - 1e-6:
            raise UserError(f"task.goal_poses.{o} = {pose!r} is not upright; objects are put down upright.")
        goals["poses"][o] = T
    for key in ("goal_cleaned", "goal_cooked"):
        goals[key[5:]] = [obj(o, f"task.{key}") for o in _names(task, key)]
    if goals["cleaned"] and not _names(task, "sink_names"):
        raise UserError(f"task.goal_cleaned = {goals['cleaned']!r} but the file has no sink (task.sink_names).")
    if goals["cooked"] and not _names(task, "stove_names"):
        raise UserError(f"task.goal_cooked = {goals['cooked']!r} but the file has no stove (task.stove_names).")
    config = task.get("goal_config")
    goals["home"], goals["base"] = config == "initial", None
    if isinstance(config, list):  # a base pose to drive to (the *namo* files)
        try:
            x, y, yaw = (float(v) for v in config)
        except (TypeError, ValueError):
            raise UserError(f"task.goal_config = {config!r}: a base pose goal is [x, y, yaw].") from None
        goals["base"] = (x, y, yaw)
    elif config not in (None, "initial"):
        raise UserError(f"task.goal_config = {config!r}: give \"initial\" (the robot returns to its start) or a base "
                        f"pose [x, y, yaw].")
    twice = set(goals["on"]) & set(goals["stackings"]) | (set(goals["on"]) | set(goals["stackings"])) & set(goals["poses"])
    if twice:
        o = sorted(twice)[0]
        raise UserError(f"task: {o!r} has two placement goals (goal_regions, goal_stackings, goal_poses); keep one.")
    if goals["holding"] and set(goals["holding"]) <= set(goals["on"]) | set(goals["stackings"]) | set(goals["poses"]):
        raise UserError(f"task.goal_holding = {holding!r} must also rest somewhere by another goal; keep one.")
    if not any((goals["holding"], goals["on"], goals["stackings"], goals["poses"], goals["cleaned"], goals["cooked"], goals["home"],
                goals["base"])):
        raise UserError(f"task: the file has no goal ({', '.join(GOAL_KEYS)} are all empty).")
    return goals
