"""End-to-end tests of the pr2 domain: examples/pr2_pick.toml with both goals, the learned
obstruction, trajectory.json's shape, the validator, and the infeasible-width case."""
import json
from pathlib import Path

import pytest

from interlayer.api import solve, validate, write_outputs

EXAMPLE = Path(__file__).resolve().parents[1] / "examples" / "pr2_pick.toml"
FAST = ["planner.time_limit=90", "planner.task=fast-downward", "planner.motion=ompl:RRTConnect"]


@pytest.fixture(scope="module")
def hold_run(tmp_path_factory):
    result = solve(EXAMPLE, FAST + ["planner.seed=2"])
    out = write_outputs(result, tmp_path_factory.mktemp("pr2_hold"))
    return result, out


@pytest.fixture(scope="module")
def place_run(tmp_path_factory):
    result = solve(EXAMPLE, FAST + ["planner.seed=2", "problem.goal=place"])
    out = write_outputs(result, tmp_path_factory.mktemp("pr2_place"))
    return result, out


def test_hold_solves_validates_and_learns_the_obstruction(hold_run):
    result, out = hold_run
    assert result.status == "solved", result.reason
    learned = {" ".join(a) for a in result.learned_facts}
    assert any(f.startswith("Obstructs blocker gpfg_target_") for f in learned), learned
    events = json.loads((out / "trace.json").read_text())["events"]
    failures = [e for e in events if e["type"] == "failure"]
    assert failures and all(e["failure"]["kind"] == "obstruction" for e in failures)
    assert "blocker" in failures[0]["failure"]["objects"]
    assert any(s.action == "pick" and s.args[0] == "blocker" for s in result.plan)  # the blocker is moved first
    assert result.plan[-1].action == "pick" and result.plan[-1].args[0] == "target"
    assert validate(out) == []
    for key in ("task_planning", "motion_planning", "ik", "collision_checking", "interface", "total"):
        assert key in result.times


def test_place_solves_and_validates(place_run):
    result, out = place_run
    assert result.status == "solved", result.reason
    last = result.plan[-1]
    assert last.action == "place" and last.args[:3] == ("target", last.args[1], "goal_spot")
    assert validate(out) == []


def test_trajectory_json_shape(hold_run):
    result, out = hold_run
    traj = json.loads((out / "trajectory.json").read_text())
    assert traj["domain"] == "pr2" and len(traj["steps"]) == len(result.plan)
    kinds = set()
    for step, data in zip(result.plan, traj["steps"]):
        assert data["action"] == step.action and data["args"] == list(step.args)
        for seg in data["segments"]:
            kinds.add(seg["kind"])
            if "points" in seg:  # a trajectory_msgs/JointTrajectory
                assert seg["group"] in ("base", "left_arm", "right_arm")
                n = len(seg["joint_names"])
                if seg["group"] == "base":
                    assert seg["joint_names"] == ["x", "y", "theta"]
                times = [p["time_from_start"] for p in seg["points"]]
                assert times[0] == 0 and times == sorted(times)
                assert all(len(p["positions"]) == n for p in seg["points"])
    assert {"base", "transit", "approach", "raise", "gripper", "grasp"} <= kinds


def test_width_infeasible_is_unsolvable_quickly():
    result = solve(EXAMPLE, FAST + ["problem.target_radius=0.05"])
    assert result.status == "unsolvable"
    assert "0.100 m wide" in result.reason and "0.092 m" in result.reason and "no grasp exists" in result.reason
    assert result.task_planner_calls == 1 and not result.counts.get("refinement_attempts")  # before any motion


def test_unknown_problem_key_is_rejected():
    from interlayer.errors import UserError

    with pytest.raises(UserError, match="problem.colour"):
        solve(EXAMPLE, ["problem.colour=red"])


def test_task_model_is_small_and_uniform():
    from interlayer.api import build_problem, resolve_config
    from interlayer.abstraction import abstract
    from interlayer.plugins import PluginHost

    config = resolve_config(EXAMPLE, ["problem.clutter=6"])
    model = abstract(build_problem(PluginHost(), config))
    assert model.uniformity == []
    assert model.geometric == {"Obstructs": "negative", "PDObstructs": "negative", "NoBase": "negative"}
    objs = [o for o, t in model.objects.items() if t == "obj"]
    assert len(objs) == 10
    # 2 arms: bpfg + gpfg per (obj, arm), bpfpd + gpfpd per (obj, arm, loc) with 2 locs
    assert len(model.references) == 10 * 2 * 2 + 10 * 2 * 2 * 2
    assert [p for p, _ in model.actions["move_base"].parameters] == ["?to"]


def test_top_grasps_allowed(tmp_path):
    result = solve(EXAMPLE, FAST + ["planner.seed=0", 'problem.grasps=["side","top"]'])
    assert result.status == "solved", result.reason
    assert validate(write_outputs(result, tmp_path)) == []


@pytest.mark.slow
def test_tidy_puts_the_blocker_down_on_the_table(tmp_path):
    result = solve(EXAMPLE, FAST + ["planner.seed=2", "problem.goal=tidy", "planner.time_limit=120"])
    assert result.status == "solved", result.reason
    assert any(s.action == "place" and s.args[0] == "blocker" for s in result.plan)
    assert validate(write_outputs(result, tmp_path)) == []


@pytest.mark.slow
def test_ten_objects_task_planner_calls_stay_fast(tmp_path):
    result = solve(EXAMPLE, FAST + ["planner.seed=0", "problem.clutter=6"])
    assert result.status == "solved", result.reason
    calls = [e["time"] for e in result.trace.events if e["type"] == "task_plan"]
    assert max(calls[1:] or [0]) < 1.0, calls  # the first call includes the planner's start-up
    assert validate(write_outputs(result, tmp_path)) == []


def test_move_base_samples_afresh_in_another_world():
    """The loop seeds a step's generator alike in every world; the bases tried for a grasp must still
    differ when the steps before left the robot elsewhere, or a backtrack retries the same failures."""
    from dataclasses import replace

    import numpy as np

    from interlayer.api import prepare
    from interlayer.domain import GroundStep
    from interlayer_manip.generators import move_base

    run = prepare(EXAMPLE, ["planner.seed=0"])
    world = run.problem.geometry.initial_world()
    step = GroundStep("move_base", ("bpfg_blocker_right",))
    firsts = []
    for base in ((0.85, 0.0, 0.0), (0.85, 0.1, 0.0)):  # both inside the table: no "stay" candidate
        cand = next(iter(move_base(run.problem, step, replace(world, base=base), np.random.default_rng(7))))
        firsts.append(cand.waypoints[0])
    assert firsts[0] != firsts[1]


def test_a_grasp_whose_hand_hits_a_panel_is_rejected_without_ik():
    """The hand alone at the tool pose is checked first: inside a cubby panel no IK is tried; at the
    target in the cubby the hand is free and IK runs as before."""
    import numpy as np

    from interlayer.api import prepare
    from interlayer_manip.generators import _waypoints
    from interlayer_manip.state import pose4

    run = prepare(EXAMPLE, ["planner.seed=0"])
    geo = run.problem.geometry
    world = geo.initial_world()
    in_panel = pose4(0.83, 0.13, 0.87, 0.0)  # the tool in panel_left
    at_target = world.objects["target"]
    open_hand = world.with_gripper("left", "open")
    assert not geo.hand_free(open_hand, "left", in_panel, ignore=("target",))
    assert geo.hand_free(open_hand, "left", at_target, ignore=("target",))
    assert not geo.hand_free(open_hand, "left", at_target, movables=True)  # the target itself is in the hand
    calls = []

    class Counting:  # the geometry, counting its IK calls
        def __getattr__(self, name):
            return getattr(geo, name)

        def ik(self, *a, **k):
            calls.append(1)
            return geo.ik(*a, **k)

    rng = np.random.default_rng(0)
    assert _waypoints(Counting(), world, "left", in_panel, "side", rng, "target", hand_check=True) is None
    assert calls == []
    _waypoints(Counting(), world, "left", in_panel, "side", rng, "target")
    assert calls  # without the check, IK is tried


def test_a_base_only_move_keeps_the_synced_configuration_exact():
    """sync() reuses the last configuration when only the base moved; it must equal config()."""
    from dataclasses import replace

    import numpy as np

    from interlayer.api import prepare

    geo = prepare(EXAMPLE, ["planner.seed=0"]).problem.geometry
    world = geo.initial_world().with_gripper("left", "open")
    geo.sync(world)
    for base in ((0.1, 0.2, 0.3), (-0.5, 1.0, -3.0)):
        moved = replace(world, base=base)
        assert np.array_equal(geo.sync(moved), geo.config(moved))


def test_the_cubby_transit_goes_through_the_staging_point():
    """With the layout's "stage", a pick transit into the cubby searches to a point behind the
    pre-grasp and ends with the straight tool line from there; without it, it searches to the pre-grasp."""
    from dataclasses import replace

    import numpy as np

    from interlayer.api import prepare
    from interlayer.domain import GroundStep
    from interlayer.motion import InterpolatingPlanner
    from interlayer_manip.generators import move_base
    from interlayer_manip.state import trans

    run = prepare(EXAMPLE, ["planner.seed=0"])
    geo = run.problem.geometry
    world = geo.initial_world()
    moved = world.objects["blocker"].copy()
    moved[1, 3] += 0.45  # the blocker put aside on the table
    world = replace(world, objects={**world.objects, "blocker": moved})
    cand = next(iter(move_base(run.problem, GroundStep("move_base", ("bpfg_target_left",)), world,
                               np.random.default_rng(0))))
    world = replace(world, base=cand.waypoints[0])
    pre = np.asarray(cand.values["grasp"][1][2][0][0], float)  # (kind, T, (approach, lift)): the pre-grasp
    goals = []

    class Spy(InterpolatingPlanner):
        def plan(self, query, time_limit=None, straight=True):
            goals.append(np.asarray(query.goal, float))
            return super().plan(query, time_limit, straight)

    start = np.asarray(world.arms["left"], float)
    for stage in (0.05, 0.0):
        goals.clear()
        geo.layout.extra["stage"] = stage
        geo._transit(Spy(), world, "left", start, pre, "pick transit", [], [0.0], staged="goal")
        assert goals, "the transit asked the planner nothing"
        if not stage:
            assert np.allclose(goals[0], pre)
            continue
        T = geo.robot.tool_pose(geo.sync(world.with_arm("left", goals[0])), "left")
        P = geo.robot.tool_pose(geo.sync(world.with_arm("left", pre)), "left")
        assert np.allclose(P @ trans(-stage, 0, 0), T, atol=3e-3)  # 5 cm behind, along the tool's x axis


def test_the_blockwise_fine_check_agrees_with_checking_every_point():
    """fine_ok certifies a block of points by its middle one, checked with a margin that covers how far
    any body moves within the block. Paths of one block whose middle point grazes an obstacle (the
    cubby, the table, the robot itself) are accepted exactly when every point is collision-free; on
    free paths most points are checked only through their block's middle one; along an obstacle, the
    margin is not tried at every block."""
    import numpy as np

    from interlayer.api import prepare
    from interlayer.motion import BLOCK as FINE_BLOCK

    geo = prepare(EXAMPLE, ["planner.seed=0"]).problem.geometry
    world = geo.initial_world()
    rng = np.random.default_rng(1)
    plain_checks = []
    checker_for = geo.cw.checker_for

    margin_checks = []

    def counting_checker_for(*args, margin=0.0, **kw):
        check = checker_for(*args, margin=margin, **kw)
        counts = margin_checks if margin else plain_checks
        return lambda v: counts.append(1) or check(v)

    geo.cw.checker_for = counting_checker_for
    outcomes = {True: 0, False: 0}
    points = free_points = near = 0
    for group in ("right_arm", "left_arm"):
        arm, g = group.split("_")[0], geo.robot.group(group)
        space = geo.arm_space[arm]
        step = space.resolution / 5
        check = checker_for(group, geo.sync(world))
        samples = [rng.uniform(g.lower, g.upper) for _ in range(200)]
        free = [v for v in samples if check(v)]
        hit = [v for v in samples if not check(v)]
        for f0, c0 in zip(free, hit):  # bisect to an obstacle's surface, then back off a little
            f, c = f0, c0
            for _ in range(30):
                mid = (f + c) / 2
                f, c = (mid, c) if check(mid) else (f, mid)
            mid = f + (f0 - c0) / np.linalg.norm(f0 - c0) * rng.uniform(0, 2 * FINE_BLOCK * step)
            u = rng.normal(size=7)
            u *= (FINE_BLOCK // 2) * step / np.linalg.norm(u)
            a, b = mid - u, mid + u
            if not (check(mid) and g.within_bounds(a) and g.within_bounds(b)):
                continue
            expected = all(map(check, space.densify([a, b], step)))
            del plain_checks[:]
            assert geo.fine_ok(world.with_arm(arm, a), group, [a, b]) is expected
            outcomes[expected] += 1
            if expected and len(plain_checks) == FINE_BLOCK:  # free, but too close to certify at once:
                del margin_checks[:]  # back and forth along it, the margin is tried only now and then
                assert geo.fine_ok(world.with_arm(arm, a), group, [a, b] * 6)
                near += 1
                assert len(margin_checks) <= 0.5 * len(space.densify([a, b] * 6, step)) / FINE_BLOCK
        for a in free[:8]:  # free paths: most points certified by their block's middle point
            b = a + 0.05 * (np.clip(a + rng.uniform(-0.3, 0.3, 7), g.lower, g.upper) - a)
            dense = space.densify([a, b], step)
            if all(map(check, dense)):
                del plain_checks[:]
                assert geo.fine_ok(world.with_arm(arm, a), group, [a, b])
                points, free_points = points + len(dense), free_points + len(plain_checks)
    assert outcomes[True] > 10 and outcomes[False] > 10 and near > 3  # every kind of grazing path was tried
    assert points > 50 and free_points < 0.5 * points
