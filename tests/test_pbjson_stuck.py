"""Boxes that block each other's every grasp (``interlayer_manip.grasps.stuck_together``): issue 20's
rearrangement_20, where three blocks 12 x 4 x 8 cm stand side by side and none can be picked first."""
import json

import pytest
from interlayer import api
from test_pbjson import QZ90, _body, _box, load, scene


def _block(name, x, y, quat=None):
    """A block 12 cm long (along x unless turned), 4 cm across, 8 cm tall, on the table."""
    extra = {"quat": quat} if quat else {}
    return _body(name, (x, y, 0.751), [_box((0.06, 0.02, 0.04), (0, 0, 0.04), color=(0, 0, 1))], **extra)


def side_by_side(spacing):
    """Blocks a, b, c side by side, ``spacing`` between their centres (gaps of spacing - 4 cm); hold b. The only
    grasps that fit close across a block's 4 cm, so at each one finger goes between it and a neighbour."""
    data = scene(goal_holding="b")
    data["bodies"] = data["bodies"][:3] + [_block(n, 1.1, y) for n, y in (("a", -spacing), ("b", 0.0), ("c", spacing))]
    data["task"]["object_names"] = ["a", "b", "c"]
    return data


def _stuck(tmp_path, data):
    from interlayer_manip.grasps import stuck_together

    p = load(tmp_path, data)
    return stuck_together(p, p.geometry.initial_world(), p.geometry.floor_objects)[0]


def test_blocks_that_block_each_others_every_grasp_are_proved_unsolvable_naming_them(tmp_path):
    """2.5 cm gaps: every grasp of a and c puts a finger into b, every grasp of b into a and c, so none can be
    picked first and b never moves: unsolvable (a lasting NoGrasp of b for both arms, then the task planner's
    proof), with the sentence naming the three. Mutation: PBSampler.pick without the stuck_together candidate
    (the run then searches until the time limit: 120 s)."""
    data = side_by_side(0.065)
    assert _stuck(tmp_path, data) == ("a", "b", "c")
    path = tmp_path / "three.json"
    path.write_text(json.dumps(data))
    result = api.solve(str(path), ["planner.seed=0", "planner.time_limit=120"])
    assert result.status == "unsolvable", result.reason
    assert ("a, b and c stand so close that every grasp of each that fits the gripper puts the PR2's fingers into "
            "another of them where they stand (the gripper opened only 1 cm wider than the block)") in result.reason


def test_the_same_blocks_2_5_cm_further_apart_are_not_proved_and_b_is_picked(tmp_path):
    """5 cm gaps: the opened hand clears the neighbours, nothing is proved, and the plan validates. Mutation:
    the hand checked opened 1 cm wider still (opening + 0.01 in _grasp_hits): then it is proved, falsely."""
    data = side_by_side(0.09)
    assert _stuck(tmp_path, data) == ()
    path = tmp_path / "apart.json"
    path.write_text(json.dumps(data))
    result = api.solve(str(path), ["planner.seed=0", "planner.time_limit=120"])
    assert result.status == "solved", result.reason
    out = tmp_path / "out"
    api.write_outputs(result, out)
    assert api.validate(out) == []


def test_a_box_blocked_only_by_boxes_that_can_move_is_not_stuck(tmp_path):
    """a's two grasps each put a finger into c1 or c2 (turned a quarter, beside its two ends), but c1 and c2
    can each be picked from their outer side: the fixed point drops a (the planner picks c1, then a: solved
    and validated in 2 task-planner calls, measured). Mutation: stuck_together without its loop (every box
    with a hit at each grasp kept): a is then proved stuck, falsely."""
    data = scene(goal_holding="a")
    data["bodies"] = data["bodies"][:3] + [_block("a", 1.1, 0.0)] + [
        _block(n, 1.1 + s * 0.06, 0.1, quat=QZ90) for n, s in (("c1", -1), ("c2", 1))]
    data["task"]["object_names"] = ["a", "c1", "c2"]
    assert _stuck(tmp_path, data) == ()


@pytest.mark.parametrize("spacing", [0.065, 0.09])
def test_each_box_of_the_stuck_set_has_a_hit_at_every_grasp_for_both_hands(tmp_path, spacing):
    """The verdict's parts: at 2.5 cm gaps every grasp of b meets a and c, of a and c meets b, for each arm;
    at 5 cm the first grasp tried is clear (nothing more is computed). The fingers (finger and tip links) are
    what touches. Mutation: _grasp_hits checking fixed obstacles only (movables=False): nothing is hit."""
    from interlayer_manip.grasps import _grasp_hits

    p = load(tmp_path, side_by_side(spacing))
    w = p.geometry.initial_world()
    hits = {o: _grasp_hits(p, w, o, w.objects[o]) for o in ("a", "b", "c")}
    if spacing > 0.08:
        assert hits == {"a": [], "b": [], "c": []}
        return
    assert [set(h) for arms in hits["b"] for h in arms] == [{"a", "c"}] * 4
    assert all(set(h) == {"b"} for o in ("a", "c") for arms in hits[o] for h in arms), hits


@pytest.mark.parametrize("spacing", [0.065, 0.09])
def test_check_names_the_stuck_blocks(tmp_path, capsys, spacing):
    """``interlayer check`` (which plans nothing, exit 0) prints the proof a pick would make, at 2.5 cm gaps
    only. Mutation: summary.describe without its Stuck line."""
    from interlayer.cli import main

    path = tmp_path / "three.json"
    path.write_text(json.dumps(side_by_side(spacing)))
    assert main(["check", str(path)]) == 0
    out = capsys.readouterr().out
    assert ("Stuck: a, b and c stand so close" in out) == (spacing < 0.08), out
