"""Clutter-N (docs/benchmarks.md); the pybullet-planning JSON loader is tested in test_pbjson.py."""
from pathlib import Path

import pytest
from interlayer import api
from interlayer.errors import UserError

ROOT = Path(__file__).resolve().parents[1]
CONFIG = ROOT / "examples" / "clutter.toml"


def _problem(overrides):
    from interlayer.plugins import PluginHost

    host = PluginHost()
    return api.build_problem(host, api.resolve_config(str(CONFIG), overrides))


def test_clutter_scene_matches_the_definition():
    import math

    for n, seed in ((15, 0), (40, 3)):
        problem = _problem([f"problem.objects={n}", f"planner.seed={seed}"])
        layout = problem.geometry.layout
        assert len(layout.objects) == n and layout.target in {o.name for o in layout.objects}
        assert layout.grasps == ("side",) and layout.extra["table_top"] == 0.8
        for o in layout.objects:
            x, y = o.pose[:2]
            assert o.size == (0.04, 0.2)
            assert 1.375 - 0.475 + 0.06 - 1e-9 <= x <= 1.375 + 0.475 - 0.06 + 1e-9
            assert -0.6 + 0.06 - 1e-9 <= y <= 0.6 - 0.06 + 1e-9
        pts = [o.pose[:2] for o in layout.objects]
        assert min(math.dist(a, b) for i, a in enumerate(pts) for b in pts[i + 1:]) >= 0.09 - 1e-9
    a = _problem(["problem.objects=25", "planner.seed=7"]).geometry.layout.to_json()
    b = _problem(["problem.objects=25", "planner.seed=7"]).geometry.layout.to_json()
    assert a == b  # the seed draws the scene


def test_clutter_objects_out_of_range():
    with pytest.raises(UserError, match="problem.objects"):
        _problem(["problem.objects=41"])


def test_clutter15_seed0_solves_and_validates(tmp_path):
    result = api.solve(str(CONFIG), ["problem.objects=15", "planner.seed=0", "planner.time_limit=60"])
    assert result.status == "solved", result.reason
    api.write_outputs(result, tmp_path)
    assert api.validate(tmp_path) == []


@pytest.mark.slow
def test_clutter40_seed0_solves_and_validates(tmp_path):
    result = api.solve(str(CONFIG), ["problem.objects=40", "planner.seed=0", "planner.time_limit=120"])
    assert result.status == "solved", result.reason
    api.write_outputs(result, tmp_path)
    assert api.validate(tmp_path) == []


def test_a_reset_reseeds_the_clutter_pick_generator(host):
    """Alg. 1, line 16: after a reset the pick generator samples other grasps for an object that has
    not moved (its candidates used to be cached on the geometry across epochs)."""
    from interlayer.abstraction import abstract
    from interlayer.domain import GroundStep
    from interlayer.loop import InterfaceLayer, LoopSettings

    config = api.resolve_config(str(CONFIG), ["problem.objects=15", "planner.seed=0"])
    problem = api.build_problem(host, config)
    model = abstract(problem)
    layer = InterfaceLayer(model, None, None, api.generators_for(host, model, config), [], LoopSettings())
    t = problem.geometry.layout.target
    step = GroundStep("pick", (t, "left", "right", f"bpfg_{t}_left", f"gpfg_{t}_left", f"gpfg_{t}_right"))
    world = problem.geometry.initial_world()

    def bases():
        gen = layer.make_generator(0, step, world)
        cands = [gen.reset_and_get_first()]
        while (c := gen.get_next()) is not None:
            cands.append(c)
        return [tuple(c.waypoints[0]) for c in cands]

    first = bases()
    assert first and bases() == first  # stable within an epoch
    layer.new_epoch()
    assert set(bases()).isdisjoint(first)


def test_front_approach_keeps_the_base_on_the_near_side_and_the_target_reachable(host):
    """problem.approach = "front": base poses stay on the table's near long side, and the target is
    an object graspable from there when nothing is in the way (so the scene is solvable)."""
    from interlayer.domain import GroundStep
    from interlayer_clutter.samplers import ClutterSampler

    for seed in (1, 4):
        problem = _problem(["problem.objects=40", f"planner.seed={seed}", "problem.approach=front"])
        layout = problem.geometry.layout
        edge = layout.regions["table"][0]
        assert layout.extra["base_limits"][0][1] <= edge - 0.3
        t = layout.target
        assert problem.goal == f"(or (Holding {t} left) (Holding {t} right))"
        sampler = ClutterSampler([seed])
        world = problem.geometry.initial_world()
        bases = [c.waypoints[0] for arm in ("left", "right")
                 for c in sampler(problem, GroundStep("pick", (t, arm, "x", "bp", "gp", "gp2")), world, None)]
        assert bases and all(b[0] <= edge - 0.3 for b in bases)
    free = _problem(["problem.objects=40", "planner.seed=1"]).geometry.layout
    assert free.extra["base_limits"][0][1] > free.regions["table"][1]  # free: the far side is allowed
    with pytest.raises(UserError, match="problem.approach"):
        _problem(["problem.approach=back"])


def _holding(problem, world, sampler, obj, arm):
    """``world`` with ``obj`` in ``arm``'s hand (carried), grasped as the sampler's best candidate grasps it."""
    from dataclasses import replace

    import numpy as np
    from interlayer.domain import GroundStep

    cand = next(iter(sampler(problem, GroundStep("pick", (obj, arm, "x", "bp", "gp", "gp2")), world, None)))
    G = np.linalg.inv(np.asarray(cand.values["gp"])) @ world.objects[obj]
    world = replace(world, objects={k: v for k, v in world.objects.items() if k != obj}, held={arm: (obj, G)})
    return world.with_arm(arm, problem.geometry.carry(world, arm, np.random.default_rng(0)))


def test_put_downs_keep_clear_of_the_approaches_ranked_in_the_epoch(host):
    """Every object whose grasps the epoch ranked (not only the target) has its best approaches kept
    clear by the put-down sampler: an object put down there would block that pick again (the loop
    used to learn the same obstruction, move the blocker, and put it back in the way, for ever)."""
    import numpy as np
    from interlayer.domain import GroundStep
    from interlayer_clutter.samplers import CORRIDOR, ClutterSampler, _pose_key

    problem = _problem(["problem.objects=15", "planner.seed=0"])
    target = problem.geometry.layout.target
    other, held = [o.name for o in problem.geometry.layout.objects if o.name != target][:2]
    sampler = ClutterSampler([0])
    world = _holding(problem, problem.geometry.initial_world(), sampler, held, "left")
    list(sampler(problem, GroundStep("pick", (other, "right", "left", "bp", "gp", "gp2")), world, None))
    # the standing object's approaches count; those of the object in the hand no longer do
    expected = sampler.corridors[(other, "right")][1]
    corridors = sampler.corridors_for(world, held, target)
    assert len(corridors) == len(expected) and all(np.allclose(xy, f) for (_, xy), f in zip(corridors, expected))

    place = GroundStep("place", (held, "left", "s1", "bp", "pd"))

    def spots():
        return [(c.values["object_pose"][0][3], c.values["object_pose"][1][3])
                for c in sampler(problem, place, world, np.random.default_rng(5))]

    best = spots()[0]
    sampler.corridors[(other, "left")] = (_pose_key(world.objects[other]), [[best]])  # an approach over that spot
    assert all(np.hypot(x - best[0], y - best[1]) >= CORRIDOR for x, y in spots())


def _spots_tried(problem, world, held, arm, corridors, monkeypatch):
    """The put-down sampler's candidates, and (x, y, the nearest other object's distance) of every try."""
    import numpy as np
    from interlayer_clutter import samplers

    tried, motion = [], samplers.putdown_motion

    def spy(geometry, world, arm, x, y, *args, **kw):
        tried.append((x, y, min(np.hypot(x - Q[0, 3], y - Q[1, 3]) for Q in world.objects.values())))
        return motion(geometry, world, arm, x, y, *args, **kw)

    monkeypatch.setattr(samplers, "putdown_motion", spy)
    sampler = samplers.ClutterSampler([0])
    found = sampler.putdown_candidates(problem, held, arm, world, np.random.default_rng(3), corridors, 4)
    return found, tried


ROOMY = 2 * 0.04 + 0.06  # centre distance of the roomiest spots (6 cm edge to edge)


def test_when_the_roomy_spots_lie_on_known_approaches_tighter_ones_are_tried(monkeypatch):
    """The free space is often where a blocker was just picked from, in an approach (or deep between
    objects, where the arm cannot lower or back out): while no roomy spot is both unobstructed and off
    the known approaches, the search goes on with spots of less clearance."""
    import numpy as np
    from interlayer_clutter.samplers import ClutterSampler

    problem = _problem(["problem.objects=15", "planner.seed=0"])
    geometry = problem.geometry
    held = [o.name for o in geometry.layout.objects if o.name != geometry.layout.target][0]
    world = _holding(problem, geometry.initial_world(), ClutterSampler([0]), held, "left")
    xmin, xmax, ymin, ymax = geometry.layout.regions["table"]
    everywhere = [(1.0, np.array([(x, y) for x in np.linspace(xmin, xmax, 40) for y in np.linspace(ymin, ymax, 40)]))]
    found, tried = _spots_tried(problem, world, held, "left", everywhere, monkeypatch)
    assert found and min(d for _, _, d in tried) < ROOMY - 1e-9
    # bounded: once something was found, 6 x the candidates wanted per clearance level (of 3)
    assert len({(x, y) for x, y, _ in tried}) <= 3 * 6 * 4


def test_a_spot_on_the_targets_best_approach_comes_after_spots_with_objects_in_the_way(monkeypatch):
    """Objects in a put-down's way are learned and cleared (or another slot is taken); a spot on the
    target's best approach blocks the pick the plan ends with for sure (Clutter-40 front seed 6: the
    loop put a blocker back there until it reset)."""
    import numpy as np
    from interlayer_clutter import samplers

    problem = _problem(["problem.objects=15", "planner.seed=0"])
    geometry = problem.geometry
    held = [o.name for o in geometry.layout.objects if o.name != geometry.layout.target][0]
    world = _holding(problem, geometry.initial_world(), samplers.ClutterSampler([0]), held, "left")
    xmin, xmax, ymin, ymax = geometry.layout.regions["table"]
    half = np.array([(x, y) for x in np.linspace(xmin, (xmin + xmax) / 2, 20) for y in np.linspace(ymin, ymax, 40)])
    corridor = [(samplers.TARGET_CORRIDOR, half)]
    on_approach, motion = [], samplers.putdown_motion

    def motion_with_a_blocker_off_the_approach(geometry, world, arm, x, y, *args, **kw):
        out = motion(geometry, world, arm, x, y, *args, **kw)
        if out is None:
            return None
        if samplers.in_corridors(x, y, corridor):
            on_approach.append((x, y))
            return out
        return (*out[:5], out[5] | {"in-the-way"}, out[6])

    monkeypatch.setattr(samplers, "putdown_motion", motion_with_a_blocker_off_the_approach)
    found = samplers.ClutterSampler([0]).putdown_candidates(problem, held, "left", world, np.random.default_rng(3),
                                                            corridor, 4)
    assert on_approach and found and all(f[0][:2] == (False, 1) for f in found)


def test_a_roomy_spot_that_is_clear_and_off_the_approaches_ends_the_search(monkeypatch):
    """Tighter spots are only searched while the roomy ones offer nothing good."""
    from interlayer_clutter.samplers import ClutterSampler

    problem = _problem(["problem.objects=15", "planner.seed=0"])
    geometry = problem.geometry
    held = [o.name for o in geometry.layout.objects if o.name != geometry.layout.target][0]
    world = _holding(problem, geometry.initial_world(), ClutterSampler([0]), held, "left")
    found, tried = _spots_tried(problem, world, held, "left", [], monkeypatch)
    assert found[0][0] == (False, 0, 0, 0) and min(d for _, _, d in tried) >= ROOMY - 1e-9


def test_front_put_downs_are_searched_within_reach_of_the_near_side():
    """With the base kept on the near side, spots deeper than an arm can put anything down are not
    offered (every try there failed: IK and base sampling for nothing)."""
    import numpy as np
    from interlayer_clutter.samplers import _table_spots
    from interlayer_manip.scene import base_limits

    problem = _problem(["problem.objects=40", "problem.approach=front", "planner.seed=6"])
    geometry = problem.geometry
    obj = geometry.layout.objects[0].name
    spots = [p for level in _table_spots(geometry, geometry.initial_world(), obj, np.random.default_rng(0), 80)
             for p in level]
    reach = base_limits(geometry.layout)[0][1] + 0.8  # no put-down succeeded farther out (samplers.PUT_REACH)
    assert spots and max(x for x, _, _ in spots) <= reach and max(x for x, _, _ in spots) > reach - 0.1


def test_moved_names_the_objects_a_step_picked_or_put_down_and_the_robots_moves():
    """What backjumping in TryRefine asks the PR2 geometry (refine.Refiner)."""
    from dataclasses import replace

    problem = _problem(["problem.objects=15", "planner.seed=0"])
    world = problem.geometry.initial_world()
    a, b = list(world.objects)[:2]
    picked = replace(world, objects={k: v for k, v in world.objects.items() if k != a})
    moved = replace(picked, objects={**picked.objects, b: world.objects[b] + 0.01})
    assert problem.geometry.moved(world, world) == set()
    assert problem.geometry.moved(world, picked) == {a}
    assert problem.geometry.moved(world, moved) == {a, b}
    # a put-down within IK's tolerance of the same pose (another grasp's, at a goal pose) is the same place
    P = world.objects[b].copy()
    P[:3, 3] += 0.0015
    assert problem.geometry.moved(world, replace(world, objects={**world.objects, b: P})) == set()
    # the robot's own moves count too (TryRefine's backjumping): its base, an arm, a gripper
    from interlayer.refine import ROBOT_MOVED

    x, y, yaw = world.base
    assert problem.geometry.moved(world, replace(world, base=(x + 0.1, y, yaw))) == {ROBOT_MOVED}
    arm = next(iter(world.arms))
    assert problem.geometry.moved(world, world.with_arm(arm, [v + 0.1 for v in world.arms[arm]])) == {ROBOT_MOVED}
    assert problem.geometry.moved(world, world.with_gripper(arm, "open")) == {ROBOT_MOVED}


R040 = ROOT.parent / "shared" / "benchmarks" / "pybullet-planning-json" / "srivastava_table_r040.json"


@pytest.mark.skipif(not R040.is_file(), reason=f"{R040} (beside the checkout) is absent")
def test_a_blocked_pick_in_the_papers_scene_fails_before_any_motion_is_planned():
    """srivastava_table_r040.json starts with the arms out, so a pick's drive begins with a tuck motion
    plan; a blocked approach fails the step whatever that motion, so it is checked first (the motion
    planner here is None: planning anything would raise)."""
    from interlayer.domain import GroundStep
    from interlayer.plugins import PluginHost
    from interlayer_clutter.samplers import ClutterSampler

    problem = api.build_problem(PluginHost(), api.resolve_config(str(R040), []))
    geometry, world = problem.geometry, problem.geometry.initial_world()
    t = geometry.layout.target
    step = GroundStep("pick", (t, "left", "right", f"bpfg_{t}_left", f"gpfg_{t}_left", f"gpfg_{t}_right"))
    cand = next(iter(ClutterSampler([0])(problem, step, world, None)))
    out = geometry.refine_step(step, world, cand, None)
    assert not out.ok and out.failure.kind == "obstruction" and out.failure.detail.startswith("pick approach")
    assert out.failure.start_free  # checked from the candidate's base: where the robot stood does not matter


def test_failures_of_a_candidates_own_motions_do_not_depend_on_the_robots_start():
    """What TryRefine's backjumping reads (``Failure.start_free``): a relaxed transit from where the step
    started may be blocked elsewhere from another start; a goal configuration that collides, a straight
    line of the candidate's own are blocked from any start."""
    from interlayer.motion import MotionPlan
    from interlayer_manip.state import _failure

    path = MotionPlan(False, obstructions=("o1",), reason="blocked by o1")
    assert not _failure(path, "place transit").failure.start_free
    assert _failure(path, "place lower", start_free=True).failure.start_free
    goal = MotionPlan(False, obstructions=("o1",), reason="the goal configuration collides with o1", goal_blocked=True)
    assert _failure(goal, "place transit").failure.start_free


@pytest.mark.skipif(not R040.is_file(), reason=f"{R040} (beside the checkout) is absent")
def test_a_blocked_pick_learns_what_blocks_the_other_arm_too():
    """The target of the paper's scene is blocked for both arms: the failed left pick also names the
    right arm's blockers (its best grasp's approach, every right grasp being obstructed), and the
    template translator turns them into Obstructs facts about the right arm's grasp reference."""
    from interlayer.abstraction import abstract
    from interlayer.builtin import translate_by_templates
    from interlayer.domain import GroundStep
    from interlayer.plugins import PluginHost
    from interlayer_clutter.samplers import ClutterSampler

    problem = api.build_problem(PluginHost(), api.resolve_config(str(R040), []))
    geometry, world = problem.geometry, problem.geometry.initial_world()
    t = geometry.layout.target
    step = GroundStep("pick", (t, "left", "right", f"bpfg_{t}_left", f"gpfg_{t}_left", f"gpfg_{t}_right"))
    sampler = ClutterSampler([0])
    cand = next(iter(sampler(problem, step, world, None)))
    failure = geometry.refine_step(step, world, cand, None).failure
    assert callable(failure.also) and "also" not in failure.to_json()  # found when translated, not before
    right = sampler.ranked_grasps(problem, world, t, "right")
    assert right[0][0][0] > 0  # every right grasp has something on its approach
    blockers = failure.also_objects()["?blocker2"]
    assert blockers and set(blockers) <= {o.name for o in geometry.layout.objects} - {t}
    facts = translate_by_templates(failure, step, abstract(problem))
    assert facts == ({("Obstructs", b, f"gpfg_{t}_left") for b in failure.objects}
                     | {("Obstructs", b, f"gpfg_{t}_right") for b in blockers})


def test_equally_clear_grasps_come_nearest_to_the_robot_first():
    """Among pick candidates with as many objects in the way, the shortest drive comes first."""
    import math
    from dataclasses import replace

    from interlayer_clutter.samplers import ClutterSampler
    from interlayer_manip.state import wrap

    problem = _problem(["problem.objects=15", "planner.seed=0"])
    world = problem.geometry.initial_world()
    sampler = ClutterSampler([0])
    for base in ((0.3, 0.0, 0.0), (2.4, 0.0, math.pi)):
        ranked = sampler.ranked_grasps(problem, replace(world, base=base), problem.geometry.layout.target, "left")
        clear = [math.dist(f[2][:2], base[:2]) + 0.3 * abs(wrap(f[2][2] - base[2])) for f in ranked if f[0] == ranked[0][0]]
        assert len(clear) >= 3 and clear == sorted(clear)


def test_the_sampler_answers_a_repeated_question_from_memory(host):
    """The partial pass asks the generators what the error-free pass asked (same world, same random
    stream): the ranking of grasps and the put-down search are not computed twice."""
    from dataclasses import replace

    import numpy as np
    from interlayer.domain import GroundStep
    from interlayer_clutter.samplers import ClutterSampler

    problem = _problem(["problem.objects=15", "planner.seed=0"])
    sampler = ClutterSampler([0])
    world = problem.geometry.initial_world()
    target = problem.geometry.layout.target
    ranked = sampler.ranked_grasps(problem, world, target, "left")
    assert sampler.ranked_grasps(problem, world, target, "left") is ranked
    assert sampler.ranked_grasps(problem, replace(world), target, "left") is not ranked  # another world
    held = _holding(problem, world, sampler, target, "left")
    place = GroundStep("place", (target, "left", "s1", "bp", "pd"))
    first = [c.label for c in sampler(problem, place, held, np.random.default_rng(5))]
    computed = sampler.putdown_candidates
    sampler.putdown_candidates = None  # asking again must not search again
    assert first and [c.label for c in sampler(problem, place, held, np.random.default_rng(5))] == first
    sampler.putdown_candidates = computed
    assert [c.label for c in sampler(problem, place, held, np.random.default_rng(6))] != first


def test_a_pick_whose_grasp_misses_the_object_fails():
    """Plan shortcutting refines a later pick again with its old candidate after dropping an earlier
    move of the same object: the grasp then closes on air, which the validator rejects. The pick's
    refinement fails instead (before any motion is planned: the motion planner here is None)."""
    from dataclasses import replace

    from interlayer.domain import GroundStep
    from interlayer_clutter.samplers import ClutterSampler

    problem = _problem(["problem.objects=15", "planner.seed=0"])
    geometry, world = problem.geometry, problem.geometry.initial_world()
    t = geometry.layout.target
    step = GroundStep("pick", (t, "left", "right", f"bpfg_{t}_left", f"gpfg_{t}_left", f"gpfg_{t}_right"))
    cand = next(iter(ClutterSampler([0])(problem, step, world, None)))
    world = replace(world, base=tuple(cand.waypoints[0]))  # no drive needed
    assert geometry.grasps(world.with_arm("left", cand.waypoints[1][-1]), "left", t)
    P = world.objects[t].copy()
    P[:2, 3] += 0.1
    out = geometry.refine_step(step, replace(world, objects={**world.objects, t: P}), cand, None)
    assert not out.ok and "does not hold" in out.failure.detail
