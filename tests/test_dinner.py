"""Dinner-N: the stackability module and its learned facts, costs reaching the (optimal) task planner,
the tray carried through the doorway with what rides on it, and the validator's carry checks."""
import copy
import types
from dataclasses import replace

import numpy as np
import pytest

from interlayer.abstraction import abstract
from interlayer.domain import GroundStep

from interlayer_manip.scene import ObjectSpec


def _problem(n=4, seed=0, **params):
    from interlayer_dinner.plugin import PARAMS, make_problem

    return make_problem({**PARAMS, "objects": n, **params}, seed)


def _spec(name, r, h):
    return ObjectSpec(name, "cylinder", (r, h), (0, 0, 0, 0))


def test_stackability_from_diameters_and_rims():
    from interlayer_dinner.stacking import RIM, stackable

    cup, bowl, big_cup = _spec("c", 0.03, 0.09), _spec("b", 0.043, 0.05), _spec("c2", 0.03 + RIM + 0.003, 0.09)
    kinds = {"c": "cup", "b": "bowl", "c2": "cup", "tray": "tray"}
    assert stackable(cup, bowl, kinds).ok  # a cup fits inside a bowl's rim
    no = stackable(bowl, cup, kinds)
    assert not no.ok and "does not fit inside the rim of c" in no.reason
    assert not stackable(cup, _spec("c3", 0.03, 0.09), {**kinds, "c3": "cup"}).ok  # equal cups do not nest
    assert stackable(cup, big_cup, kinds).ok  # ... a narrower one does (the rim and the clearance to spare)
    assert not stackable(cup, _spec("tray", 0.2, 0.02), kinds).ok  # only cups and bowls stack
    assert not stackable(cup, cup, kinds).ok


def test_scene_cups_fit_bowls_only():
    from interlayer_dinner.stacking import unstackable_pairs

    geometry = _problem(6, seed=3).geometry
    kinds = geometry.kinds
    bad = {(u, lo) for u, lo, _ in unstackable_pairs(geometry.layout.objects, kinds)}
    items = [n for n, k in kinds.items() if k != "tray"]
    good = {(u, lo) for u in items for lo in items if u != lo} - bad
    assert good and all(kinds[u] == "cup" and kinds[lo] == "bowl" for u, lo in good)


def test_unstackable_failure_becomes_facts():
    """A stack that the module rules out fails as "unstackable" (without motion planning), and the learn
    template turns it into Unstackable facts for every pair the module rules out for those two objects."""
    from interlayer.builtin import translate_by_templates
    from interlayer_dinner import generators

    problem = _problem(4)
    geometry = problem.geometry
    model = abstract(problem)
    cup = next(n for n, k in geometry.kinds.items() if k == "cup")
    bowl = next(n for n, k in geometry.kinds.items() if k == "bowl")
    world = geometry.initial_world()
    G = np.eye(4)
    world = replace(world, objects={k: v for k, v in world.objects.items() if k != bowl}, held={"left": (bowl, G)})
    step = GroundStep("stack", (bowl, "left", cup, "room_a", f"sp_{bowl}_{cup}"))
    (cand,) = list(generators.place(problem, step, world, np.random.default_rng(0)))
    out = geometry.refine_step(step, world, cand, motion=None)
    assert not out.ok and out.failure.kind == "unstackable" and out.failure.static
    facts = translate_by_templates(out.failure, step, model)
    assert ("Unstackable", f"sp_{bowl}_{cup}") in facts
    others = [n for n in geometry.kinds if n not in (cup, "tray")]
    assert {("Unstackable", f"sp_{o}_{cup}") for o in others} <= facts  # nothing fits on a cup
    assert all(f[1] != f"sp_{c}_{bowl}" for f in facts for c in geometry.kinds if geometry.kinds[c] == "cup")


@pytest.mark.parametrize("planner", ["fast-downward-bjolp", "symk-opt"])
def test_optimal_plans_use_the_tray_and_cost_the_known_optimum(host, planner):
    """Costs reach the planner: Dinner-2 carries both objects by hand (104 = 2 picks + 100 + 2 places),
    Dinner-4 uses the tray with the cups stacked on the bowls (118); a satisficing planner pays more."""
    if planner == "symk-opt":
        pytest.importorskip("up_symk", reason="up-symk is an optional extra (pip install 'interlayer[symk]')")
    optimal = host["task_planners"].get(planner).factory({})
    for n, cost, tray in ((2, 104, False), (4, 118, True)):
        model = abstract(_problem(n))
        res = optimal.plan(model, model.init, 60)
        assert res.status == "solved" and res.cost == cost == model.cost(res.plan)
        assert any(s.action == "pick_tray" for s in res.plan) == tray
    model = abstract(_problem(4))
    lama = host["task_planners"].get("fast-downward").factory({}).plan(model, model.init, 60)
    assert lama.status == "solved" and lama.cost > 118


def test_side_costs_make_cross_reaching_dearer(host):
    """side_costs: picking an object on the robot's left with the right hand costs 3, so the optimal
    Dinner-2 plan uses the hand on each object's side."""
    from interlayer_dinner.domain import make_domain

    model = abstract(_problem(2, side_costs=True))
    assert model.actions["pick_cross"].cost == 3 and model.actions["pick"].cost == 1
    res = host["task_planners"].get("fast-downward-bjolp").factory({}).plan(model, model.init, 60)
    near = {f[1]: f[2] for f in model.init if f[0] == "Near"}
    at = {f[1][4:]: f[2] for f in model.init if f[0] == "NearLoc" and f[1].startswith("set_")}
    a, b = sorted(near)
    # one trip, one object per hand: 104 plus 2 for each pick or place on the other hand's side
    best = min(104 + 2 * sum((near[o] != arm) + (at[o] != arm) for o, arm in ((a, x), (b, y)))
               for x, y in (("left", "right"), ("right", "left")))
    assert res.status == "solved" and res.cost == model.cost(res.plan) == best
    assert "handoff" in {a.name for a in make_domain(handoff=True).actions}


def test_handoff_makes_side_cost_plans_cheaper(host):
    """With side costs, picking with the near hand, handing over and placing with the other (1 + 1 + 1)
    beats reaching across (1 + 3): the optimal Dinner-2 plan hands an object over and costs 1 less."""
    bjolp = host["task_planners"].get("fast-downward-bjolp").factory({})
    costs = {}
    for handoff in (False, True):
        model = abstract(_problem(2, side_costs=True, handoff=handoff))
        res = bjolp.plan(model, model.init, 60)
        assert res.status == "solved"
        costs[handoff] = res.cost
    assert costs[True] == costs[False] - 1 and any(s.action == "handoff" for s in res.plan)
    # a bowl held from above cannot be handed over (the receiving grasp would be too low to put it down)
    kinds = model.problem.geometry.kinds
    assert {f[1] for f in model.init if f[0] == "Passable"} == {o for o, k in kinds.items() if k == "cup"}


@pytest.fixture(scope="module")
def tray_run(host):
    """A cup in a tray slot from the start; the PR2 picks the tray up with both hands, drives through the
    doorway and sets it down on the dinner table (pick_tray, go, place_tray refined for real)."""
    from interlayer_dinner import generators
    from interlayer_dinner.scene import make_layout
    from interlayer_dinner.world import DinnerGeometry
    from interlayer_manip.scene import REST_GAP

    layout = make_layout(0, 4)
    cup = next(o for o in layout.objects if layout.extra["kinds"][o.name] == "cup")
    tray = layout.obj("tray")
    dx, dy = layout.extra["slots"][0]
    cup.pose = (tray.pose[0] + dx, tray.pose[1] + dy, tray.pose[2] + tray.size[2] / 2 + REST_GAP + cup.size[1] / 2, 0.0)
    geometry = DinnerGeometry(layout)
    geometry._initial_riders[cup.name] = ("tray", "slot1")
    problem = types.SimpleNamespace(geometry=geometry, goal="")
    motion = host["motion_planners"].get("ompl:RRTConnect").factory({"time_limit": 2.0})
    motion.seed = 0
    plan = [GroundStep("pick_tray", ("side", "room_a")), GroundStep("go", ("room_a", "room_b")),
            GroundStep("place_tray", ("dinner", "room_b"))]
    gens = {"pick_tray": generators.pick_tray, "go": generators.go, "place_tray": generators.place_tray}
    world, outcomes = geometry.initial_world(), []
    for step in plan:
        for cand in gens[step.action](problem, step, world, np.random.default_rng(1)):
            out = geometry.refine_step(step, world, cand, motion)
            if out.ok:
                break
        assert out.ok, (step, out.failure)
        outcomes.append(out)
        world = out.world
    return geometry, cup.name, plan, outcomes, geometry.trajectory_json(plan, outcomes)


def _check(geometry, plan, trajectory):
    from interlayer_dinner import validate
    from interlayer_manip.validate import validate_trajectory

    rules = types.SimpleNamespace(event=validate.event, motion=validate.motion, rests=validate.rests,
                                  goal=lambda geometry, world: [])  # the objects stay in room A
    return validate_trajectory(type(geometry)(geometry.layout, padding=0.0), plan, trajectory, rules=rules)


def test_the_tray_carries_its_riders_through_the_doorway(tray_run):
    from interlayer_dinner.scene import WALL_X

    geometry, cup, plan, outcomes, _ = tray_run
    carried = outcomes[0].world
    assert set(carried.carrying) == {"tray", cup} and cup not in carried.objects
    after = outcomes[2].world
    assert after.base[0] < WALL_X and after.objects["tray"][0, 3] < WALL_X  # through the doorway
    rel = np.linalg.inv(after.objects["tray"]) @ after.objects[cup]
    rel0 = np.linalg.inv(geometry.initial_world().objects["tray"]) @ geometry.initial_world().objects[cup]
    assert np.allclose(rel, rel0, atol=1e-9)  # the cup did not move on the tray
    assert not after.carrying and after.riders[cup] == ("tray", "slot1")


def test_validator_accepts_the_carry_and_rejects_a_dropped_rider(tray_run):
    geometry, cup, plan, _, trajectory = tray_run
    assert _check(geometry, plan, trajectory) == []
    dropped = copy.deepcopy(trajectory)
    carry = next(s for s in dropped["steps"][0]["segments"] if s["kind"] == "carry")
    carry["objects"].remove(cup)  # the cup stays behind while the tray leaves under it
    (why,) = _check(geometry, plan, dropped)
    assert f"{cup} rest(s) on the tray but is not carried with it" in why
    slid = copy.deepcopy(trajectory)
    down = next(s for s in slid["steps"][2]["segments"] if s["kind"] == "set_down")
    down["objects"][cup][0][3] += 0.05  # the cup slid on the tray
    (why,) = _check(geometry, plan, slid)
    assert f"{cup} is set down away from where the carried tray held it" in why
    arm = copy.deepcopy(trajectory)  # an arm moving while both hands hold the tray
    seg = next(s for s in trajectory["steps"][0]["segments"] if s.get("group") == "left_arm")
    arm["steps"][1]["segments"].insert(0, copy.deepcopy(seg))
    assert "moves while both hands carry the tray" in _check(geometry, plan, arm)[0]


@pytest.fixture(scope="module")
def handoff_run(host):
    """Dinner-2 with handoff: the right hand picks a cup from the side table and hands it to the left
    (pick, handoff refined for real, with the problem's own generators)."""
    from interlayer_dinner import generators

    problem = _problem(2, seed=0, handoff=True)
    geometry = problem.geometry
    cup = next(n for n, k in geometry.kinds.items() if k == "cup")
    motion = host["motion_planners"].get("ompl:RRTConnect").factory({"time_limit": 2.0})
    motion.seed = 0
    plan = [GroundStep("pick", (cup, "right", "side", "room_a")), GroundStep("handoff", (cup, "right", "left"))]
    gens = {"pick": generators.pick, "handoff": generators.handoff}
    world, outcomes = geometry.initial_world(), []
    for step in plan:
        out = None
        for cand in gens[step.action](problem, step, world, np.random.default_rng(1)):
            out = geometry.refine_step(step, world, cand, motion)
            if out.ok:
                break
        assert out is not None and out.ok, (step, out and out.failure)
        outcomes.append(out)
        world = out.world
    return geometry, cup, plan, outcomes, geometry.trajectory_json(plan, outcomes)


def test_handoff_passes_the_object_to_the_other_hand_and_validates(handoff_run):
    geometry, cup, plan, outcomes, trajectory = handoff_run
    after = outcomes[1].world
    assert after.holder(cup) == "left" and "right" not in after.held and cup not in after.objects
    assert np.allclose(after.arms["right"], geometry.robot.home("right")) and after.grippers["right"] == "closed"
    kinds = [s["kind"] for s in trajectory["steps"][1]["segments"]]
    assert "handover" in kinds and kinds.index("handover") < len(kinds) - 1
    assert _check(geometry, plan, trajectory) == []
    far = copy.deepcopy(trajectory)  # the left hand claims the cup where the right hand does not hold it
    seg = next(s for s in far["steps"][1]["segments"] if s["kind"] == "handover")
    seg["grasp"][2][3] += 0.05
    assert "is not at the left gripper" in _check(geometry, plan, far)[0]
    early = copy.deepcopy(trajectory)  # the handover before the left hand has come to the cup
    segs = early["steps"][1]["segments"]
    k = next(i for i, s in enumerate(segs) if s["kind"] == "handover")
    segs.insert(2, segs.pop(k))
    assert _check(geometry, plan, early)


@pytest.mark.slow
def test_dinner_example_solves_with_the_tray_and_validates(tmp_path):
    """The example end to end (~45 s): the optimal Dinner-4 plan uses the tray, costs 118, and the
    independent validator accepts its trajectory."""
    from interlayer import api

    from conftest import ROOT

    res = api.solve(str(ROOT / "examples" / "dinner.toml"))
    assert res.solved and res.plan_cost == 118 and any(s.action == "pick_tray" for s in res.plan)
    api.write_outputs(res, tmp_path)
    assert api.validate(tmp_path) == []
