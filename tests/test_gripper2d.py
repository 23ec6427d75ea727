"""The paper's running example end to end with real planners (Fast Downward / pyperplan, OMPL)."""
import json

import pytest

from interlayer import api


def solve(example, *overrides):
    return api.solve(example, overrides=list(overrides))


def test_fig2_example_learns_obstruction_and_moves_b2_first(gripper_example, tmp_path):
    result = solve(gripper_example)
    assert result.status == "solved", result.reason
    assert ("Obstructs", "b2", "gp_b1", "b1") in result.learned_facts
    steps = [str(s) for s in result.plan]
    picks = [s.args[0] for s in result.plan if s.action == "pick"]
    assert picks.index("b2") < picks.index("b1"), steps
    assert result.plan[-1].action == "place" and result.plan[-1].args[:2] == ("b1", "S")
    first = [e for e in result.trace.events if e["type"] == "task_plan"][0]
    assert [s["action"] for s in first["plan"]] == ["pick", "place"]  # the naive plan came first
    out = api.write_outputs(result, tmp_path / "run")
    assert api.validate(out) == []


@pytest.mark.parametrize("override", ["planner.task=pyperplan", "planner.task=ff", "planner.motion=ompl:PRM",
                                      "planner.task=fast-downward-opt"])
def test_planner_combinations_solve(gripper_example, override):
    result = solve(gripper_example, override)
    assert result.status == "solved", result.reason


def test_partial_failure_at_a_later_step_keeps_the_prefix(gripper_example, tmp_path):
    result = solve(gripper_example, "problem.s_occupied=true")
    assert result.status == "solved", result.reason
    assert ("PDObstructs", "c1", "pdp_b1_S", "b1", "S") in result.learned_facts
    later = [e for e in result.trace.events if e["type"] == "replan" and e["fail_step"] > 0]
    assert later, "a failure after step 0 should keep the refined prefix"
    for e in later:
        assert e["plan"][: e["fail_step"]] == e["prefix"] and len(e["prefix"]) == e["fail_step"]
    assert api.validate(api.write_outputs(result, tmp_path / "run")) == []


def test_validator_rejects_corrupted_trajectories(gripper_example, tmp_path):
    out = api.write_outputs(solve(gripper_example), tmp_path / "run")
    good = json.loads((out / "trajectory.json").read_text())

    def corrupt(mutate):
        data = json.loads(json.dumps(good))
        mutate(data)
        (out / "trajectory.json").write_text(json.dumps(data))
        return api.validate(out)

    # a waypoint inside the corridor wall
    wall = json.loads((out / "problem.json").read_text())["source"]["layout"]["walls"]["wall_top"]
    def into_wall(d):
        seg = d["steps"][0]["segments"][0]
        seg["path"].insert(1, [wall[0], wall[1], 0.0])
    assert any("collision with wall_top" in v for v in corrupt(into_wall))

    # a teleport: the second step's transit starts somewhere else
    def jump(d):
        d["steps"][1]["segments"][0]["path"][0][0] += 0.3
    assert any("does not start where the gripper is" in v for v in corrupt(jump))

    # the goal block never released in S
    def drop_last(d):
        d["steps"][-1]["segments"] = d["steps"][-1]["segments"][:2]
    assert any("goal not satisfied" in v for v in corrupt(drop_last))


def test_five_obstruction_chain(gripper_example):
    result = solve(gripper_example, "problem.obstructions=5")
    assert result.status == "solved", result.reason
    picks = [s.args[0] for s in result.plan if s.action == "pick"]
    assert picks.index("b6") < picks.index("b5") < picks.index("b1")


def test_the_generators_collision_checks_are_timed_as_collision_checking(gripper_example):
    """Pose generation in Gripper-2D is mostly collision checks (approach lines, put-down spots):
    they count as collision checking, as in the PR2 domains, and the split still adds up."""
    result = solve(gripper_example)
    assert result.status == "solved", result.reason
    t = result.times
    assert t["collision_checking"] > 0
    assert abs(sum(v for k, v in t.items() if k != "total") - t["total"]) < 1e-9
