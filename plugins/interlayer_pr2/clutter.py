"""The paper's cluttered table (Clutter-N, BENCHMARKS.md section 2) and the pybullet-planning JSON loader.

Task-level model (a second DomainSpec, selected by ``scene = "clutter"`` and by JSON problem files),
chosen for Fast Downward's speed with 40 objects (see docs/benchmarks.md):

* ``move_base`` is folded into pick and place: their base-pose references (``bpfg_<o>_<arm>``,
  ``bpfpd_<o>_<arm>_<slot>``) occur only in their own Skolem atom, so the core drops them from the
  task planner's view; the pose generators sample a base pose together with the arm motion, and the
  refinement drives there first (one base segment at the start of the step's trajectory).
* ``Obstructs(?blocker ?gp)`` / ``PDObstructs(?blocker ?pd)``: two arguments, the reference names
  the object and arm (and slot) it is for.
* pick deletes the obstructions the picked object causes and those learned about its own grasps
  (both arms): they described where it stood.
* put-down references are per object and slot (``gpfpd_<o>_<arm>_<slot>``, ``slot`` = s1..sK): the
  slot only gives the task planner K alternatives once a put-down is found obstructed; the concrete
  spot anywhere on the table is sampled by the pose generator.
"""
from __future__ import annotations

import json
import logging
import math
from dataclasses import replace

import numpy as np
from interlayer.domain import ActionSpec, DomainSpec, Problem, Skolem
from interlayer.errors import UserError
from interlayer.refine import Candidate, EpochState, stable_seed

from .scene import REST_GAP, Layout, ObjectSpec, base_limits, table_top
from .world import pose4

log = logging.getLogger("interlayer.pr2")

ARMS = ("left", "right")
CLUTTER_TABLE = {"centre": (1.375, 0.0), "size": (0.95, 1.2), "top": 0.8}
CLUTTER_BASE_LIMITS = ((-1.0, 3.0), (-2.0, 2.0))
RADIUS, HEIGHT = 0.04, 0.2
SLOTS = 2
TORSO = 0.28  # the cubby scene uses 0.2 at a 0.72 m table; the clutter table is 0.08 m higher
BASE_CLEARANCE = 0.34  # m: the base centre keeps this far from the table's edge (half the PR2's footprint)

CLUTTER_DOMAIN = DomainSpec(
    name="pr2-clutter",
    types={"obj": None, "arm": None, "slot": None},
    continuous_types=("bpose", "gpose", "pdpose"),
    predicates={
        "HandEmpty": ("arm",),
        "Other": ("arm", "arm"),
        "Holding": ("obj", "arm"),
        "OnTable": ("obj",),
        "IsBPFG": ("bpose", "obj", "arm"),
        "IsGPFG": ("gpose", "obj", "arm"),
        "IsBPFPD": ("bpose", "obj", "arm", "slot"),
        "IsGPFPD": ("pdpose", "obj", "arm", "slot"),
        "Obstructs": ("obj", "gpose"),
        "PDObstructs": ("obj", "pdpose"),
    },
    skolems=(
        Skolem("bpfg", ("obj", "arm"), "bpose", "IsBPFG", "a base pose from which arm can grasp obj"),
        Skolem("gpfg", ("obj", "arm"), "gpose", "IsGPFG", "a gripper pose grasping obj (with pre-grasp and raise)"),
        Skolem("bpfpd", ("obj", "arm", "slot"), "bpose", "IsBPFPD", "a base pose from which arm can put obj down"),
        Skolem("gpfpd", ("obj", "arm", "slot"), "pdpose", "IsGPFPD", "a gripper pose putting obj down on the table"),
    ),
    geometric=("Obstructs", "PDObstructs"),
    actions=(
        ActionSpec(
            name="pick",
            # ?gp2: the other arm's grasp reference of ?o, only so that the effect forgets what was
            # learned about grasping ?o where it stood.
            parameters=(("?o", "obj"), ("?arm", "arm"), ("?arm2", "arm"), ("?bp", "bpose"), ("?gp", "gpose"),
                        ("?gp2", "gpose")),
            precondition="""(and (HandEmpty ?arm) (OnTable ?o) (IsBPFG ?bp ?o ?arm) (IsGPFG ?gp ?o ?arm)
                                 (Other ?arm ?arm2) (IsGPFG ?gp2 ?o ?arm2)
                                 (forall (?b - obj) (not (Obstructs ?b ?gp))))""",
            effect="""(and (Holding ?o ?arm) (not (HandEmpty ?arm)) (not (OnTable ?o))
                           (forall (?p - gpose) (not (Obstructs ?o ?p)))
                           (forall (?p - pdpose) (not (PDObstructs ?o ?p)))
                           (forall (?b - obj) (and (not (Obstructs ?b ?gp)) (not (Obstructs ?b ?gp2)))))""",
            learn={"obstruction": ("(Obstructs ?blocker ?gp)",)},
            pose_generator="pr2c:pick",
        ),
        ActionSpec(
            name="place",
            parameters=(("?o", "obj"), ("?arm", "arm"), ("?s", "slot"), ("?bp", "bpose"), ("?pd", "pdpose")),
            precondition="""(and (Holding ?o ?arm) (IsBPFPD ?bp ?o ?arm ?s) (IsGPFPD ?pd ?o ?arm ?s)
                                 (forall (?b - obj) (not (PDObstructs ?b ?pd))))""",
            effect="(and (not (Holding ?o ?arm)) (HandEmpty ?arm) (OnTable ?o))",
            learn={"obstruction": ("(PDObstructs ?blocker ?pd)",)},
            pose_generator="pr2c:place",
        ),
    ),
)


# -- scenes ------------------------------------------------------------------------------------------
def clutter_layout(seed: int, n: int, approach: str = "free") -> Layout:
    """Clutter-N: N cylinders (r 0.04, h 0.2) at uniformly random non-overlapping spots (>= 1 cm apart,
    >= 2 cm inside the edge) of a 0.95 x 1.2 table (top z 0.8) centred at (1.375, 0); a random target.
    ``approach = "front"`` keeps the base on the table's near long side (x below its edge at 0.9 m)."""
    rng = np.random.default_rng(seed)
    (cx, cy), (sx, sy), top = CLUTTER_TABLE["centre"], CLUTTER_TABLE["size"], CLUTTER_TABLE["top"]
    fixed = [ObjectSpec("table", "box", (sx, sy, top), (cx, cy, top / 2, 0.0), movable=False)]
    m = RADIUS + 0.02
    pts = []
    while len(pts) < n:
        for _ in range(20000):
            x = float(rng.uniform(cx - sx / 2 + m, cx + sx / 2 - m))
            y = float(rng.uniform(cy - sy / 2 + m, cy + sy / 2 - m))
            if all(math.hypot(x - a, y - b) >= 2 * RADIUS + 0.01 for a, b in pts):
                pts.append((x, y))
                break
        else:  # pragma: no cover - N <= 40 always fits
            raise UserError(f"no room for {n} cylinders on the table")
    z = top + HEIGHT / 2 + REST_GAP
    objects = [ObjectSpec(f"o{i + 1}", "cylinder", (RADIUS, HEIGHT), (x, y, z, 0.0)) for i, (x, y) in enumerate(pts)]
    target = objects[int(rng.integers(n))].name
    regions = {"table": (cx - sx / 2, cx + sx / 2, cy - sy / 2, cy + sy / 2)}
    limits = CLUTTER_BASE_LIMITS
    if approach == "front":
        limits = ((limits[0][0], cx - sx / 2 - BASE_CLEARANCE), limits[1])
    return Layout(fixed, objects, regions, target, "hold", ("side",),
                  extra={"table_top": top, "base_limits": limits, "torso_height": TORSO, "approach": approach})


def clutter_problem(layout: Layout, source: dict, name: str, slots: int = SLOTS) -> Problem:
    from .world import PR2Geometry

    geometry = PR2Geometry(layout)
    names = [o.name for o in layout.objects]
    slot_names = [f"s{k + 1}" for k in range(slots)]
    objects = {o: "obj" for o in names}
    objects.update({a: "arm" for a in ARMS})
    objects.update({s: "slot" for s in slot_names})
    init = {("HandEmpty", a) for a in ARMS} | {("Other", "left", "right"), ("Other", "right", "left")}
    init |= {("OnTable", o) for o in names}
    t = layout.target
    goal = f"(or (Holding {t} left) (Holding {t} right))"
    return Problem(CLUTTER_DOMAIN, objects, frozenset(init), goal, geometry, source, name=name)


def make_clutter_problem(params, seed):
    n = params.get("objects", 15)
    if not isinstance(n, int) or isinstance(n, bool) or not 1 <= n <= 40:
        raise UserError(f"problem.objects must be an integer from 1 to 40 (Clutter-N: 15 to 40), got {n!r}.")
    if params.get("goal", "hold") != "hold" or list(params.get("grasps", ["side"])) != ["side"]:
        raise UserError("The clutter scene's goal is fixed (hold the target, side grasps only): "
                        "leave problem.goal and problem.grasps at their defaults.")
    approach = params.get("approach", "free")
    if approach not in ("free", "front"):
        raise UserError(f"problem.approach must be \"free\" (drive around the table) or \"front\" (stay on its near "
                        f"side), got {approach!r}.")
    layout = clutter_layout(seed, n, approach)
    problem = clutter_problem(layout, {"domain": "pr2", "params": dict(params), "seed": seed}, f"pr2-clutter{n}")
    if approach == "front":
        _reachable_target(problem, np.random.default_rng([seed, n]))
    problem.source["layout"] = layout.to_json()
    return problem


def _reachable_target(problem, rng):
    """Front approach: make the target an object that the PR2 can grasp from the near side when
    nothing is in the way (IK and fixed obstacles only), so that every scene is solvable."""
    layout, geometry = problem.geometry.layout, problem.geometry
    world = geometry.initial_world()
    sampler = ClutterSampler(stable_seed("front", layout.target))
    edge = layout.regions["table"][0]
    near = [o.name for o in layout.objects if o.pose[0] < edge + 0.6]  # beyond this no arm reaches
    for name in [near[k] for k in rng.permutation(len(near))]:
        if any(sampler.grasp_candidates(problem, world, name, arm) for arm in ARMS):
            layout.target = name
            problem.goal = f"(or (Holding {name} left) (Holding {name} right))"
            return
    raise UserError("problem.approach=\"front\": no object of this scene can be grasped from the table's near side; "
                    "choose another planner.seed.")


# -- the pybullet-planning JSON format ----------------------------------------------------------------
UNSUPPORTED_GOALS = ("goal_regions", "goal_poses", "goal_stackings", "goal_cleaned", "goal_cooked")


def _yaw(q) -> float:
    w, x, y, z = q["w"], q["x"], q["y"], q["z"]
    if abs(x) > 1e-6 or abs(y) > 1e-6:
        raise UserError("only upright bodies (rotations about z) are supported in pybullet-planning JSON files")
    return 2 * math.atan2(z, w)


def looks_like_pybullet_json(path) -> dict | None:
    if path.suffix.lower() != ".json":
        return None
    try:
        data = json.loads(path.read_text())
    except (OSError, ValueError):
        return None
    if not isinstance(data, dict) or not {"bodies", "robots", "task"} <= set(data):
        return None
    return data


def load_pybullet_json(path, data, params, seed) -> Problem:
    """The problem of a pybullet-planning JSON file; a malformed file is a UserError naming what is wrong."""
    try:
        return _load_pybullet_json(path, data, params, seed)
    except (KeyError, IndexError, TypeError, ValueError, AttributeError) as exc:
        what = f"the key {exc}" if isinstance(exc, KeyError) else f"{type(exc).__name__}: {exc}"
        raise UserError(f"{path.name} is not a pybullet-planning problem Interlayer can read ({what}); "
                        f"check the file against the format's bodies / robots / task fields.") from None


def _load_pybullet_json(path, data, params, seed) -> Problem:
    task = data["task"]
    unsupported = [k for k in UNSUPPORTED_GOALS if task.get(k)]
    if unsupported or not task.get("goal_holding"):
        raise UserError(f"{path.name}: only 'goal_holding' goals are supported for now; this file asks for "
                        f"{', '.join(unsupported) or 'no goal_holding'} (unsupported: {', '.join(UNSUPPORTED_GOALS)}).")
    if task.get("goal_config"):
        log.warning("%s: goal_config = %r is ignored (the robot need not return to its start configuration)",
                    path.name, task["goal_config"])
    if params:
        raise UserError(f"{path.name}: problem parameters {sorted(params)} do not apply to a problem file.")
    movable = set(task["object_names"])
    tables = set(task.get("table_names", []))
    if len(tables) != 1:
        raise UserError(f"{path.name}: exactly one table is supported for now, got {sorted(tables)}.")
    fixed, objects, top, region = [], [], None, None
    for body in data["bodies"]:
        bp, yaw = body["point"], _yaw(body["quat"])
        B = np.array([[math.cos(yaw), -math.sin(yaw)], [math.sin(yaw), math.cos(yaw)]])
        links = [shape for link in body["links"] for shape in link]
        for k, shape in enumerate(links):
            lp = shape["point"]
            xy = np.array([bp["x"], bp["y"]]) + B @ np.array([lp["x"], lp["y"]])
            z = bp["z"] + lp["z"]
            lyaw = yaw + _yaw(shape["quat"])
            name = body["name"] if len(links) == 1 else f"{body['name']}_{k}"
            if shape["type"] == "box":
                size = tuple(2 * float(e) for e in shape["extents"])
            elif shape["type"] == "cylinder":
                size = (float(shape["radius"]), float(shape["height"]))
            else:
                raise UserError(f"{path.name}: shape type {shape['type']!r} of {body['name']} is not supported")
            spec = ObjectSpec(name, shape["type"], size, (float(xy[0]), float(xy[1]), float(z), float(lyaw)),
                              movable=body["name"] in movable)
            if body["name"] in movable:
                if len(links) != 1:
                    raise UserError(f"{path.name}: movable {body['name']} must be a single shape")
                objects.append(spec)
            else:
                if body["name"] in tables and spec.shape == "box" and (top is None or z + size[2] / 2 > top):
                    top = z + size[2] / 2
                    region = (xy[0] - size[0] / 2, xy[0] + size[0] / 2, xy[1] - size[1] / 2, xy[1] + size[1] / 2)
                    spec = replace(spec, name="table")  # the support the validator and samplers know
                fixed.append(spec)
    if top is None:
        raise UserError(f"{path.name}: the table has no box top")
    robot = data["robots"][0]
    base = (float(robot["point"]["x"]), float(robot["point"]["y"]), _yaw(robot["quat"]))
    grasps = tuple(g.lower() for g in task.get("grasp_types", ["SIDE"]))
    if any(g not in ("side", "top") for g in grasps):
        raise UserError(f"{path.name}: grasp types {grasps} not supported (SIDE, TOP)")
    target = task["goal_holding"]
    if target not in {o.name for o in objects}:
        raise UserError(f"{path.name}: goal_holding {target!r} is not among object_names")
    lo = (min(base[0], region[0]) - 1.5, max(base[0], region[1]) + 1.5)
    hi = (min(base[1], region[2]) - 1.5, max(base[1], region[3]) + 1.5)
    layout = Layout(fixed, objects, {"table": region}, target, "hold", grasps, base=base,
                    extra={"table_top": float(top), "base_limits": (lo, hi),
                           "torso_height": float(min(0.3, max(0.0, 0.2 + top - 0.72)))})
    log.info("%s: the robot's conf is not used (arms start tucked, torso at %.2f m for the table height)",
             path.name, layout.extra["torso_height"])
    return clutter_problem(layout, {"domain": "pr2", "file": str(path), "seed": seed, "layout": layout.to_json()},
                           data.get("name") or path.stem)


# -- pose generators (move_base folded in) --------------------------------------------------------------
def _base_near(geometry, x, y, rng, reach=(0.55, 0.95)):
    """A base pose facing (x, y) from outside the table, sampled around the table's sides."""
    from .generators import wrap

    xmin, xmax, ymin, ymax = geometry.layout.regions["table"]
    (lx, hx), (ly, hy) = base_limits(geometry.layout)
    for _ in range(20):
        r, a = rng.uniform(*reach), rng.uniform(-math.pi, math.pi)
        bx, by = x + r * math.cos(a), y + r * math.sin(a)
        if xmin - 0.33 < bx < xmax + 0.33 and ymin - 0.33 < by < ymax + 0.33:
            continue  # the base would stand under the table
        if not (lx <= bx <= hx and ly <= by <= hy):
            continue
        yaw = math.atan2(y - by, x - bx) + rng.uniform(-0.35, 0.35)
        return (float(bx), float(by), float(wrap(yaw)))
    return None


def _coarse(a, b, n=8):
    a, b = np.asarray(a, float), np.asarray(b, float)
    return [a + (b - a) * k / n for k in range(1, n + 1)]


def _movables_on(geometry, world, arm, path, ignore, gripper="open"):
    """Movable objects the arm (gripper open) touches at the waypoints of ``path``."""
    w = world.with_gripper(arm, gripper) if gripper else world
    hit = set()
    for v in path:
        q = geometry.sync(w.with_arm(arm, v))
        hit |= geometry.cw.colliding_movables(q)
    return hit - set(ignore) - {o for o, _ in world.held.values()}


class ClutterSampler(EpochState):
    """Clutter's pick and place generators and what they share within one epoch: grasp candidates
    sampled once per (object, arm, object pose) and re-ranked in each world, and the target's best
    approach corridors that put-downs keep clear of. The loop makes a fresh instance at every epoch,
    so a reset discards both and samples anew."""

    def __init__(self, seed):
        super().__init__(seed)
        self.grasps: dict = {}  # (obj, arm, pose) -> candidates
        self.misses: dict = {}  # (obj, arm, pose) -> fruitless searches so far
        self.corridors: dict = {}  # arm -> [(base, approach xy points)] of the target's best grasps

    def __call__(self, problem, step, world, rng):
        return self.pick(problem, step, world, rng) if step.action == "pick" else self.place(problem, step, world, rng)

    def pick(self, problem, step, world, rng, limit: int = 5):
        """Base pose + side grasp of step's object; candidates ordered by how many objects their
        approach and raise touch (fewest first: fewer obstructions to learn and clear).

        The candidates are stable within the epoch: sampled once per (object, arm, object pose), then
        re-ranked in each call's world. An obstruction learned for the best candidate thus stays true
        of it, and once the task plan has cleared those blockers the same candidate comes first again
        with nothing in its way (fresh samples would bring fresh blockers)."""
        obj, arm = step.args[0], step.args[1]
        bp_ref, gp_ref = step.args[3], step.args[4]
        geometry = problem.geometry
        if world.holder(obj) is not None or world.held.get(arm):
            return
        ranked = self.ranked_grasps(problem, world, obj, arm)
        if obj == geometry.layout.target:  # the put-down sampler keeps clear of its best approaches
            self.corridors[arm] = [(c[2], c[6]) for c in ranked[:3]]
        for nhit, _, base, kind, T, wps, _ in ranked[:limit]:
            yield Candidate((base, *wps), {bp_ref: list(base), gp_ref: T.tolist()},
                            f"{kind} grasp from base {_fmt(base)} ({nhit[0]} objects on the approach, {nhit[1]} on the way)")

    def grasp_candidates(self, problem, world, obj, arm, tries: int = 40):
        """(base, kind, T, waypoints, tool xy path) candidates for picking obj with arm where it stands;
        static checks only (IK, fixed obstacles), so they hold in every world with obj at this pose."""
        from .generators import _bearing, _problem_grasps, _waypoints, check_graspable, grasp_poses

        geometry = problem.geometry
        P = world.objects[obj]
        key = (obj, arm, tuple(np.round(P[:3, :4].ravel(), 4)))
        if key in self.grasps:
            return self.grasps[key]
        check_graspable(problem, obj)
        misses = self.misses.get(key, 0)
        rng = self.rng_for(*key, misses)  # a function of the epoch and the question only
        x, y = P[0, 3], P[1, 3]
        kinds = _problem_grasps(problem, obj)
        target = obj == geometry.layout.target
        want = 12 if target else 6
        n_bases = 3 * tries if target else tries
        found = []
        from interlayer_pinocchio import TUCKED_ARMS

        # the other arm tucked and nothing held: the candidates must not depend on the world they were asked in
        w0 = replace(world, held={}, arms={a: tuple(TUCKED_ARMS[a]) for a in ARMS}, grippers={a: "closed" for a in ARMS})
        for i in range(n_bases + 2 * tries):
            if i >= n_bases and found:
                break  # past the first bases, only search on while nothing at all was found
            base = _base_near(geometry, x, y, rng)
            if base is None or not _base_free(geometry, w0, base):
                continue
            w = replace(w0, base=base)
            for kind, T in grasp_poses(geometry, obj, P, _bearing(base, x, y), kinds, rng, n_side=2):
                wps = _waypoints(geometry, w, arm, T, kind, rng, ignore=(obj,))
                if wps is None:
                    continue
                wps = _with_hover(geometry, w, arm, T, wps, rng, obj)
                found.append((base, kind, T, wps, _reach_xy(base, T)))
                break
            if len(found) >= want:
                break
        if found:
            self.grasps[key] = found
        else:
            self.misses[key] = misses + 1  # the next call searches with other samples
        return found

    def ranked_grasps(self, problem, world, obj, arm):
        """The candidates ranked in ``world``: ((approach hits, transit-line hits), index, base, kind,
        T, waypoints, footprint), fewest objects in the way first."""
        geometry = problem.geometry
        out = []
        for idx, (base, kind, T, wps, xy) in enumerate(self.grasp_candidates(problem, world, obj, arm)):
            if not _base_free(geometry, world, base):
                continue
            w = replace(world, base=base)
            with geometry.stats.timer("collision_checking"):
                # exactly the refinement's first check: the approach (hover descent included), densified
                hit = geometry._movables_on_line(w.with_gripper(arm, "open"), arm, wps[0], [0.0]) - {obj}
                hit |= _movables_on(geometry, w, arm, list(wps[1]), (obj,))
                # a rough guess at the transit's sweep: the straight joint-space line to the pre-grasp
                sweep = _movables_on(geometry, w, arm, _coarse(w.arms[arm], wps[0][0]), (obj,), gripper=None)
            out.append(((len(hit), len(sweep)), idx, base, kind, T, wps, xy))
        out.sort(key=lambda f: (f[0], f[1]))
        return out

    def spot_score(self, geometry, world, target, x, y):
        """Larger is better: near the table's edge (few objects between the arm and the spot, and an object
        there stands in few other approaches), far from the target and clear of other objects, and never
        in the corridor the arm will reach through for the target (its best grasps, see pick)."""
        xmin, xmax, ymin, ymax = geometry.layout.regions["table"]
        edge = min(x - xmin, xmax - x, y - ymin, ymax - y)
        d_obj = min((math.hypot(x - Q[0, 3], y - Q[1, 3]) for Q in world.objects.values()), default=1.0)
        Tt = world.objects.get(target)
        d_t = math.hypot(x - Tt[0, 3], y - Tt[1, 3]) if Tt is not None else 1.0
        penalty = 0.0
        for cands in self.corridors.values():
            for rank, (_, xy) in enumerate(cands):
                if any(math.hypot(x - a, y - b) < CORRIDOR for a, b in xy):
                    penalty = max(penalty, 2.0 if rank == 0 else 0.5)
        return min(d_obj, 0.25) + 0.5 * min(d_t, 0.6) - 1.5 * edge - penalty

    def place(self, problem, step, world, rng, limit: int = 4, tries: int = 80):
        """A free table spot (far from the target and other objects first), a base pose to reach it, and
        the lowering / retreat arm paths."""
        from .generators import LIFT, PRE_GRASP, _line, _putdown, trans

        obj, arm = step.args[0], step.args[1]
        bp_ref, pd_ref = step.args[3], step.args[4]
        geometry = problem.geometry
        if world.holder(obj) != arm:
            return
        G = world.held[arm][1]
        spots = []
        geometry.sync(world)
        for x, y, z in _table_spots(geometry, world, obj, rng, tries):
            spots.append((self.spot_score(geometry, world, geometry.layout.target, x, y), x, y, z))
        spots.sort(key=lambda s: -s[0])
        found = []
        for rank, (_, x, y, z) in enumerate(spots):
            if rank >= 3 * limit and found:
                break  # past the best spots, only search on while nothing at all was found
            for _ in range(4 if rank < 3 * limit else 8):
                base = _base_near(geometry, x, y, rng)
                if base is None or not _base_free(problem.geometry, world, base):
                    continue
                P, T = _putdown(G, x, y, z, math.atan2(y - base[1], x - base[0]) + rng.uniform(-0.3, 0.3))
                w = replace(world, base=base)
                put = geometry.ik(w, arm, T, rng, attempts=4)
                if put is None:
                    continue
                lower = _line(geometry, w, arm, T, lambda d, T=T: trans(0, 0, d) @ T, LIFT, put, rng)
                back = _line(geometry, w.with_gripper(arm, "open"), arm, T, lambda d, T=T: T @ trans(-d, 0, 0), PRE_GRASP, put,
                             rng, gripper="open")
                if lower is None or back is None:
                    continue
                with geometry.stats.timer("collision_checking"):
                    hit = _movables_on(geometry, w, arm, lower, (), gripper=None)
                    hit |= _movables_on(geometry, w, arm, back, ())
                    sweep = _movables_on(geometry, w, arm, _coarse(w.arms[arm], lower[-1]), (), gripper=None)
                found.append(((len(hit), len(sweep)), rank, base, x, y, P, T, lower, back))
                break
            if len(found) >= limit or (found and found[-1][0] == (0, 0) and len(found) >= 2):
                break
        found.sort(key=lambda f: (f[0], f[1]))
        for nhit, _, base, x, y, P, T, lower, back in found:
            yield Candidate((base, tuple(reversed(lower)), tuple(back[1:])),
                            {bp_ref: list(base), pd_ref: T.tolist(), "tloc": (obj, P), "object_pose": P.tolist()},
                            f"{obj} at {_fmt((x, y))} from base {_fmt(base)} ({nhit[0]} + {nhit[1]} objects in the way)")


def _reach_xy(base, T, step=0.05):
    """Points along the arm's footprint over the table: from the tool back towards the base."""
    tx, ty = T[0, 3], T[1, 3]
    bx, by = base[0], base[1]
    d = math.hypot(bx - tx, by - ty)
    n = max(1, int(d / step))
    return [(tx + (bx - tx) * k / n, ty + (by - ty) * k / n) for k in range(n + 1)]


HOVER = 0.18  # the pre-grasp is approached from this far above: over the other cylinders' tops


def _with_hover(geometry, world, arm, T, wps, rng, obj):
    """Prefix the approach with a vertical descent from HOVER above the pre-grasp, so that the free
    transit ends above the clutter and only the descent and the approach run between objects
    (obstructions learned from a failure then name the objects really in the way)."""
    from .generators import _line
    from .world import PRE_GRASP, trans

    approach, lift = wps
    pre_T = T @ trans(-PRE_GRASP, 0, 0)
    down = _line(geometry, world.with_gripper(arm, "open"), arm, pre_T, lambda d: trans(0, 0, d) @ pre_T, HOVER,
                 approach[0], rng, (obj,), "open")
    if down is None or not geometry.static_path_ok(world.with_gripper(arm, "open"), arm, down, (obj,)):
        return wps
    return tuple(reversed(down)) + tuple(approach[1:]), lift


CORRIDOR = 0.15  # m: put-down spots keep this far from the footprint of the target's best approaches


def _base_free(geometry, world, base):
    from .generators import _base_free as free

    return free(geometry, world, base)


def _table_spots(geometry, world, obj, rng, tries, want=12):
    """Upright resting poses of obj anywhere on the table, clear of fixed obstacles and >= 6 cm
    (edge to edge) from every other object. With 40 objects on the table such spots are rare: many
    points are drawn at once (vectorized), and when fewer than ``want`` pass, the clearance shrinks
    (4, then 2.5 cm) for the remaining ones."""
    o = geometry.specs[obj]
    xmin, xmax, ymin, ymax = geometry.layout.regions["table"]
    m = o.size[0] + 0.02
    z = table_top(geometry.layout) + o.height / 2 + REST_GAP
    n = max(tries, 40) * 25
    far = min(xmax - m, base_limits(geometry.layout)[0][1] + 0.95)  # beyond the arm's reach from any base pose
    pts = np.column_stack([rng.uniform(xmin + m, far, n), rng.uniform(ymin + m, ymax - m, n)])
    others = np.array([Q[:2, 3] for Q in world.objects.values()]).reshape(-1, 2)
    d = np.min(np.linalg.norm(pts[:, None, :] - others[None, :, :], axis=2), axis=1) if len(others) else np.full(n, 9.0)
    out = 0
    for gap in (0.06, 0.04, 0.025):
        ok = (d >= 2 * o.size[0] + gap)
        for x, y in pts[ok][:tries]:
            with geometry.stats.timer("collision_checking"):
                hits = geometry.cw.objects_overlap(obj, pose4(float(x), float(y), z, 0.0))
            if hits & geometry.fixed:
                continue
            out += 1
            yield float(x), float(y), z
        if out >= want:
            return
        d = np.where(ok, -1.0, d)  # already offered


def _fmt(p):
    return "(" + ", ".join(f"{v:.2f}" for v in p) + ")"
