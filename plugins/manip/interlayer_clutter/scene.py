"""The paper's cluttered table (Clutter-N, docs/benchmarks.md): the scene generator."""
from __future__ import annotations

import math

import numpy as np
from interlayer.errors import UserError
from interlayer.refine import stable_seed
from interlayer_manip.params import held_by_some_arm, robot_for
from interlayer_manip.placement import EDGE_GAP, reach_band
from interlayer_manip.scene import REST_GAP, Layout, ObjectSpec
from interlayer_manip.state import OPEN_CLEARANCE
from interlayer_manip.world import load_robot

from .domain import clutter_problem
from .samplers import ClutterSampler

CLUTTER_TABLE = {"centre": (1.375, 0.0), "size": (0.95, 1.2), "top": 0.8}
CLUTTER_BASE_LIMITS = ((-1.0, 3.0), (-2.0, 2.0))
RADIUS, HEIGHT = 0.04, 0.2
TORSO = 0.28  # the cubby scene uses 0.2 at a 0.72 m table; the clutter table is 0.08 m higher
BASE_CLEARANCE = 0.34  # m: the base centre keeps this far from the table's edge (half the PR2's footprint)


def clutter_layout(seed: int, n: int, approach: str = "free", reach=None, radius: float = RADIUS) -> Layout:
    """Clutter-N: N cylinders (r 0.04, h 0.2) at uniformly random non-overlapping spots (>= 1 cm apart,
    >= 2 cm inside the edge) of a 0.95 x 1.2 table (top z 0.8) centred at (1.375, 0); a random target.
    ``approach = "front"`` keeps the base on the table's near long side (x below its edge at 0.9 m).
    ``reach`` = (near, far), a fixed-base robot's: it stands at the middle of the near edge, mounted at the
    top's height (z = 0), and the cylinders stand between near and far from it. ``radius``: the cylinders'
    (narrower for a gripper that opens less than 9 cm)."""
    rng = np.random.default_rng(seed)
    (cx, cy), (sx, sy), top = CLUTTER_TABLE["centre"], CLUTTER_TABLE["size"], CLUTTER_TABLE["top"]
    base = (cx - sx / 2 - EDGE_GAP, cy, 0.0)
    fixed = [ObjectSpec("table", "box", (sx, sy, top), (cx, cy, top / 2 if reach is None else -top / 2, 0.0), movable=False)]
    if reach is not None:
        top = 0.0
    m = radius + 0.02
    pts = []
    while len(pts) < n:
        for _ in range(20000):
            x = float(rng.uniform(cx - sx / 2 + m, cx + sx / 2 - m))
            y = float(rng.uniform(cy - sy / 2 + m, cy + sy / 2 - m))
            if reach is not None and not reach[0] <= math.hypot(x - base[0], y - base[1]) <= reach[1]:
                continue
            if all(math.hypot(x - a, y - b) >= 2 * radius + 0.01 for a, b in pts):
                pts.append((x, y))
                break
        else:  # pragma: no cover - N <= 40 always fits
            raise UserError(f"no room for {n} cylinders on the table")
    z = top + HEIGHT / 2 + REST_GAP
    objects = [ObjectSpec(f"o{i + 1}", "cylinder", (radius, HEIGHT), (x, y, z, 0.0)) for i, (x, y) in enumerate(pts)]
    target = objects[int(rng.integers(n))].name
    regions = {"table": (cx - sx / 2, cx + sx / 2, cy - sy / 2, cy + sy / 2)}
    limits = CLUTTER_BASE_LIMITS
    if approach == "front":
        limits = ((limits[0][0], cx - sx / 2 - BASE_CLEARANCE), limits[1])
    layout = Layout(fixed, objects, regions, target, "hold", ("side",),
                    extra={"table_top": top, "base_limits": limits, "torso_height": TORSO, "approach": approach})
    if reach is not None:
        layout.base, layout.extra["reach"], layout.extra["reach_near"] = base, reach[1], reach[0]
    return layout


def make_clutter_problem(params, seed):
    n = params.get("objects", 15)
    if not isinstance(n, int) or isinstance(n, bool) or not 1 <= n <= 40:
        raise UserError(f"problem.objects must be an integer from 1 to 40 (Clutter-N: 15 to 40), got {n!r}.")
    approach = params.get("approach", "free")
    if approach not in ("free", "front"):
        raise UserError(f"problem.approach must be \"free\" (drive around the table) or \"front\" (stay on its near "
                        f"side), got {approach!r}.")
    desc = robot_for(params, "clutter")
    reach = None
    if not desc.mobile:  # the cylinders stand where the arm reaches a side grasp of them (with 5 cm to spare)
        near, far = reach_band(desc, desc.arms[0].name, 0.0, HEIGHT / 2, "side")
        reach = (near + 0.05, far - 0.05)
    robot = load_robot(desc, {"torso_height": TORSO, "base_limits": CLUTTER_BASE_LIMITS})
    # cylinders that fit the gripper (opened OPEN_CLEARANCE wider)
    radius = min(RADIUS, (robot.max_gripper_opening - OPEN_CLEARANCE) / 2)
    layout = clutter_layout(seed, n, approach, reach, radius)
    layout.extra["robot"] = params.get("robot", "pr2")
    problem = clutter_problem(layout, {"domain": "clutter", "params": dict(params), "seed": seed}, f"clutter{n}", robot=robot)
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
        if any(sampler.grasp_candidates(problem, world, name, arm) for arm in geometry.robot.arms):
            layout.target = name
            problem.goal = held_by_some_arm(name, geometry.robot.arms)
            return
    raise UserError("problem.approach=\"front\": no object of this scene can be grasped from the table's near side; "
                    "choose another planner.seed.")
