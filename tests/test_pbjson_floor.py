"""Floor obstacles of pybullet-planning files (``floor_object_names``, issue 20 item 4): a drive they block
is a failure the task planner learns from (``BaseObstructs``, not ``FinalClear``), and the base pushes an
obstacle the gripper cannot hold out of the way; the validator re-checks the push."""
import copy
import json

import numpy as np
import pytest
from interlayer import api, logic
from test_pbjson import _body, _box, load, scene

WALL_H = 0.2  # half height: walls 0.4 m tall stop the base


def corridor(box=(0.05, 0.3, 0.4), spare=True):
    """A corridor 1.1 m wide (walls along x at y = +-0.55, from x = -2 to 0.6) opening into a room; the PR2
    at its west end; floor box ``blocker`` (half extents ``box``: 0.1 deep, 0.6 across) stands across it at
    x = 0 (the base, 0.67 m wide, passes on neither side); the goal is a base pose in the room. ``spare``:
    another floor box in the room's far corner, in nobody's way."""
    data = scene()
    conf = data["robots"][0]["conf"]
    wall = [_box((1.3, 0.01, WALL_H), (0.0, 0.0, WALL_H))]
    bodies = [_body("north", (-0.7, 0.56, 0.0), wall), _body("south", (-0.7, -0.56, 0.0), wall),
              _body("west", (-2.0, 0.0, 0.0), [_box((0.01, 0.55, WALL_H), (0.0, 0.0, WALL_H))]),
              _body("blocker", (0.0, 0.0, 0.001), [_box(box, (0.0, 0.0, box[2]), color=(1, 0, 0))])]
    floor = ["blocker"]
    if spare:
        bodies.append(_body("spare", (2.2, -1.6, 0.001), [_box((0.05, 0.3, 0.4), (0.0, 0.0, 0.4), color=(1, 0, 0))]))
        floor.append("spare")
    task = {**data["task"], "object_names": [], "table_names": [], "sink_names": [], "stove_names": [], "regions": [],
            "floor_object_names": floor, "goal_config": [1.5, 0.8, 0.0], "goal_holding": False}
    return {"name": "corridor", "bodies": bodies, "task": task,
            "robots": [{"name": "pr2", "point": {"x": -1.4, "y": 0.0, "z": 0.0}, "quat": {"w": 1.0, "x": 0.0, "y": 0.0, "z": 0.0},
                        "conf": conf}]}


def test_check_lists_each_floor_obstacle_and_what_the_robot_can_do_with_it(tmp_path, capsys):
    from interlayer.cli import main

    data = corridor()
    data["bodies"].append(_body("stick", (1.8, 1.6, 0.001), [_box((0.02, 0.02, 0.3), (0.0, 0.0, 0.3), color=(1, 0, 0))]))
    data["task"]["floor_object_names"].append("stick")
    path = tmp_path / "corridor.json"
    path.write_text(json.dumps(data))
    assert main(["check", str(path)]) == 0
    out = capsys.readouterr().out
    assert "floor obstacles (3)" in out
    assert "blocker: box 0.100x0.600x0.800 m at (0.000, 0.000), yaw 0 deg: push with the base" in out
    assert "stick: box 0.040x0.040x0.600 m at (1.800, 1.600), yaw 0 deg: pick (a grasp fits the gripper) or push" in out
    p = load(tmp_path, data)
    assert p.objects["blocker"] == "floor" and p.objects["stick"] == "item"  # only items have grasp references
    assert {("Pushable", "blocker"), ("Pushable", "stick")} <= p.init


def solved(tmp, name, data):
    """``data`` solved (seed 0) and written: (result, its run folder, its trajectory or None)."""
    path = tmp / f"{name}.json"
    path.write_text(json.dumps(data))
    result = api.solve(str(path), ["planner.seed=0", "planner.time_limit=120"])
    out = tmp / "out"
    if result.status == "solved":
        api.write_outputs(result, out)
    return result, out, json.loads((out / "trajectory.json").read_text()) if out.is_dir() else None


@pytest.fixture(scope="module")
def pushed(tmp_path_factory):
    """The corridor solved (seed 0) and written: (result, its run folder, its trajectory)."""
    return solved(tmp_path_factory.mktemp("pushed"), "corridor", corridor())


def test_a_floor_box_in_the_way_is_pushed_out_of_it_and_only_that_one(pushed):
    """The final drive fails on the box (a base obstruction: the path planned with movables ignored runs
    into it), the task planner learns (not (FinalClear blocker)), pushes it and drives; the spare box, in
    nobody's way, is never pushed. The validator re-checks the push."""
    result, out, traj = pushed
    assert result.status == "solved", result.reason
    assert [s.action for s in result.plan][-1] == "go_to"
    pushes = [s.args for s in result.plan if s.action == "push"]
    assert pushes and set(pushes) == {("blocker",)}
    assert "(not (FinalClear blocker))" in [logic.literal_str(f) for f in result.learned_facts]
    # the flood fill saw the goal cut off by the box: no search among the floor obstacles was run for it
    assert result.counts.get("drives_cut_off_by_floor_obstacles", 0) >= 1
    assert api.validate(out) == []
    segs = [s for step in traj["steps"] for s in step["segments"] if s["kind"] == "push"]
    assert segs and {s["object"] for s in segs} == {"blocker"}


def _tampered(out, traj, tmp_path, edit, every=False):
    """The validator's errors on the run ``out`` with its first push segment (``every``: each one) edited."""
    bad = copy.deepcopy(traj)
    segs = [s for step in bad["steps"] for s in step["segments"] if s["kind"] == "push"]
    for seg in segs if every else segs[:1]:
        edit(seg)
    target = tmp_path / "bad"
    target.mkdir(parents=True)
    for f in out.iterdir():
        if f.is_file():
            (target / f.name).write_bytes(f.read_bytes())
    (target / "trajectory.json").write_text(json.dumps(bad))
    return api.validate(target)


def test_the_validator_rejects_a_push_that_does_not_touch_or_that_turns(pushed, tmp_path):
    _, out, traj = pushed

    def away(seg):  # the object held 10 cm further ahead: the base no longer touches it
        B = np.asarray(seg["base_T_object"])
        B[0, 3] += 0.10
        seg["base_T_object"] = B.tolist()

    errors = _tampered(out, traj, tmp_path / "a", away)
    assert errors and "not where the push starts it" in errors[0]

    def turn(seg):  # the base turns while pushing
        for p in seg["points"][len(seg["points"]) // 2:]:
            p["positions"][2] += 0.2

    errors = _tampered(out, traj, tmp_path / "b", turn)
    assert errors and "straight forward" in errors[0]


def test_the_validator_wants_the_base_against_what_it_pushes(tmp_path):
    """A push whose object stands 10 cm ahead of the base (moved rigidly, but nothing touches it) is refused;
    the same push from against it passes, and leaves the object where the base took it."""
    from dataclasses import replace

    from interlayer_pbjson.world import PUSH_GAP, base4, check_push

    g = load(tmp_path, corridor(spare=False)).geometry
    g = type(g)(g.layout, padding=0.0)  # as the validator builds it
    w = g.tucked(g.initial_world())
    d = g.contact_distance(w, "blocker", 0.0)
    assert d is not None and 0.3 < d < 0.5  # the PR2's base front, 0.1 m box: about 0.34 + 0.05

    def push_from(gap):
        start = (-d - gap, 0.0, 0.0)
        world = replace(w, base=start)
        seg = g._segment("push", "base", [start, (start[0] + 0.5, 0.0, 0.0)], {})
        seg["points"] = [{**p, "time_from_start": 5.0 * k} for k, p in enumerate(seg["points"])]
        seg.update(object="blocker", base_T_object=(np.linalg.inv(base4(start)) @ world.objects["blocker"]).tolist())
        return check_push(g, world, seg, "push")

    after, why = push_from(PUSH_GAP)
    assert why is None and np.allclose(after.objects["blocker"][:3, 3], (0.5, 0.0, 0.401))
    _, why = push_from(0.10)
    assert why and "does not push it" in why


def test_a_floor_obstacle_standing_in_a_wall_stays_fixed_and_check_says_so(tmp_path, capsys):
    """decision_wall_namo_3's posts stand 9 cm inside the wall pieces they fill the gaps of: no push gets
    one out, so it is part of the wall (not an error about interpenetrating objects)."""
    from interlayer.cli import main

    data = corridor(spare=False)
    data["bodies"].append(_body("stuck", (-0.7, 0.56, 0.001), [_box((0.05, 0.05, 0.4), (0.0, 0.0, 0.4), color=(1, 0, 0))]))
    data["task"]["floor_object_names"].append("stuck")
    p = load(tmp_path, data)
    assert "stuck" in p.geometry.fixed and "stuck" not in p.objects and p.objects["blocker"] == "floor"
    path = tmp_path / "stuck.json"
    path.write_text(json.dumps(data))
    assert main(["check", str(path)]) == 0
    out = capsys.readouterr().out
    assert "floor obstacles (2)" in out and "stuck: nothing (it stands 60 mm inside north: kept fixed as part of it)" in out


def test_the_animation_moves_the_pushed_box_with_the_base(pushed):
    from interlayer_meshcat import Scene

    result, _, traj = pushed
    g = result.problem.geometry
    scene = Scene("corridor")
    g.draw_scene(scene, None)
    frames = g.animation_frames(scene, traj)
    xs = [f["blocker"][0, 3] for f in frames if "blocker" in f]
    end = [s for step in traj["steps"] for s in step["segments"] if s["kind"] == "push"][-1]
    assert xs[0] == pytest.approx(0.0) and len(set(np.round(xs, 3))) > 10  # it slides, not jumps
    B = np.asarray(end["base_T_object"])
    x, y, th = end["points"][-1]["positions"]
    assert xs[-1] == pytest.approx(x + np.cos(th) * B[0, 3] - np.sin(th) * B[1, 3], abs=1e-6)


def test_of_the_floor_obstacles_a_wandering_drive_names_the_one_in_the_way_is_kept(tmp_path):
    """A relaxed path may run into obstacles the way does not need moved: when the flood fill reaches the
    goal with one of them gone, that one alone is named."""
    g = load(tmp_path, corridor()).geometry
    w = g.initial_world()
    goal = (1.5, 0.8, 0.0)
    assert g._cut_off(w, w.base, goal)
    assert g.one_blocker(w, goal, ("spare", "blocker")) == ("blocker",)
    assert g.one_blocker(w, goal, ("spare",)) == ("spare",)  # nothing better to say


def two_rows():
    """The corridor with two boards across it, ``near`` (x = 0) and ``far`` (x = 0.25, 0.15 m behind it):
    pushed alone, ``near`` runs into ``far`` before the base is through; ``far`` cannot be reached before
    ``near`` is gone (the base cannot stand between them) and no board can go sideways (the walls). As
    the folder's wall_namo_3 and decision_wall_namo_3 (two rows of posts 0.25 m apart)."""
    data = corridor(spare=False)
    data["bodies"].append(_body("far", (0.25, 0.0, 0.001), [_box((0.05, 0.3, 0.4), (0.0, 0.0, 0.4), color=(1, 0, 0))]))
    data["task"]["floor_object_names"].append("far")
    next(b for b in data["bodies"] if b["name"] == "blocker")["name"] = "near"
    data["task"]["floor_object_names"][0] = "near"
    return data


def test_a_push_carries_along_what_it_meets_head_on(tmp_path, monkeypatch):
    """push_pieces: ``near`` pushed 0.6 m meets ``far`` after about 0.15 m; from there both move with the
    base, one piece per chain, and they end touching, in line (the task level knows it as InLine)."""
    from dataclasses import replace

    from interlayer_pbjson import world as pbworld
    from interlayer_pbjson.world import PUSH_GAP

    p = load(tmp_path, two_rows())
    assert ("InLine", "near", "far") in p.init and ("InLine", "far", "near") in p.init
    g = p.geometry
    w = g.tucked(g.initial_world())
    d = g.contact_distance(w, "near", 0.0) + PUSH_GAP
    start = (-d, 0.0, 0.0)
    w = replace(w, base=start)
    after, why, pieces = g.push_pieces(w, "near", start, (start[0] + 0.6, 0.0, 0.0))
    assert why is None, why
    assert [chain for _, _, chain, _ in pieces] == [("near",), ("near", "far")]
    assert pieces[0][1][0] - start[0] == pytest.approx(0.15, abs=0.003)  # where near touches far
    near, far = after.objects["near"][:3, 3], after.objects["far"][:3, 3]
    assert near[0] == pytest.approx(0.6, abs=1e-9) and far[0] - near[0] == pytest.approx(0.1, abs=0.0015)
    assert far[1] == pytest.approx(0.0, abs=1e-9)
    # one object per push (as before): far is in the way
    monkeypatch.setattr(pbworld, "MAX_CHAIN", 1)
    _, why, _ = g.push_pieces(w, "near", start, (start[0] + 0.6, 0.0, 0.0))
    assert why is not None and why.objects == ("far",)


@pytest.fixture(scope="module")
def chained(tmp_path_factory):
    return solved(tmp_path_factory.mktemp("chained"), "two_rows", two_rows())


def test_two_boards_in_a_row_are_pushed_out_of_the_corridor_together(chained, tmp_path):
    """Before pushes carried what they meet, this scene timed out (120 s: push(near) ran into far, far could
    not be reached, epoch after epoch). Now near is pushed, far moves with it from where they touch, the
    base drives through; the validator re-checks the chain, and refuses the push without it."""
    result, out, traj = chained
    assert result.status == "solved", result.reason
    assert [s.action for s in result.plan][-1] == "go_to" and {s.args for s in result.plan if s.action == "push"} == {("near",)}
    assert api.validate(out) == []
    segs = [s for step in traj["steps"] for s in step["segments"] if s["kind"] == "push"]
    assert any([c["object"] for c in s.get("chain", [])] == ["far"] for s in segs)
    errors = _tampered(out, traj, tmp_path, lambda seg: seg.pop("chain", None), every=True)
    assert errors and "runs into far" in errors[0]


def pole_corridor():
    """A corridor 0.8 m wide (the base, 0.67 m, passes with 6 cm to spare) with a pole of 7 cm square and
    1.2 m tall (a floor obstacle the gripper can hold) in its middle: 0.365 m free on either side."""
    data = corridor(spare=False)
    for b in data["bodies"]:
        if b["name"] in ("north", "south"):
            b["point"]["y"] = 0.41 if b["name"] == "north" else -0.41
        elif b["name"] == "west":
            b["links"] = [[_box((0.01, 0.4, WALL_H), (0.0, 0.0, WALL_H))]]
    data["bodies"] = [b for b in data["bodies"] if b["name"] != "blocker"]
    data["bodies"].append(_body("pole", (-0.8, 0.0, 0.001), [_box((0.035, 0.035, 0.6), (0.0, 0.0, 0.6), color=(1, 0, 0))]))
    data["task"].update(floor_object_names=["pole"], goal_config=[1.5, 0.0, 0.0])
    data["robots"][0]["point"]["x"] = -1.6
    return data


def test_a_floor_obstacle_the_gripper_holds_is_picked_out_of_the_way(tmp_path):
    """The final drive fails on the pole; picking it clears the way as a push would (pick, like push, makes
    it FinalClear), and the robot carries it to the goal. Validated."""
    result, out, traj = solved(tmp_path, "pole", pole_corridor())
    assert result.status == "solved", result.reason
    assert [s.action for s in result.plan] == ["pick", "go_to"] and result.plan[0].args[0] == "pole"
    assert "(not (FinalClear pole))" in [logic.literal_str(f) for f in result.learned_facts]
    assert api.validate(out) == []
    assert result.problem.objects["pole"] == "item"


def test_a_floor_obstacle_met_off_centre_stops_the_push_and_is_named(tmp_path):
    """``far`` moved aside so that ``near`` meets it off its centre line: it does not come along. The
    refinement's check names it (the task planner learns PushBlocked); the sampler's coarse check, which
    leaves movables to the refinement, still offers the push (as before chains)."""
    from dataclasses import replace

    from interlayer_pbjson.world import PUSH_GAP

    data = two_rows()
    far = next(b for b in data["bodies"] if b["name"] == "far")
    far["point"]["y"] = 0.35  # 0.3 m wide now, from y = 0.2 to 0.5: near (to 0.3) meets its edge
    far["links"] = [[_box((0.05, 0.15, 0.4), (0.0, 0.0, 0.4), color=(1, 0, 0))]]
    g = load(tmp_path, data).geometry
    w = g.tucked(g.initial_world())
    start = (-g.contact_distance(w, "near", 0.0) - PUSH_GAP, 0.0, 0.0)
    w = replace(w, base=start)
    end = (start[0] + 0.6, 0.0, 0.0)
    _, why, _ = g.push_pieces(w, "near", start, end)
    assert why is not None and why.kind == "obstruction" and why.objects == ("far",)
    after, why, pieces = g.push_pieces(w, "near", start, end, movables=False)
    assert why is None and [chain for _, _, chain, _ in pieces] == [("near",)]


def test_a_push_forgets_the_drive_facts_of_what_it_may_carry_along(tmp_path):
    """At the task level a push of near forgets what was learned about far (InLine: near's push may carry
    it), not about an obstacle out of its line."""
    from interlayer.abstraction import abstract
    from interlayer.domain import GroundStep

    data = two_rows()
    data["bodies"].append(_body("aside", (-1.2, 0.45, 0.001), [_box((0.05, 0.05, 0.4), (0.0, 0.0, 0.4), color=(1, 0, 0))]))
    data["task"]["floor_object_names"].append("aside")
    model = abstract(load(tmp_path, data))
    assert ("InLine", "near", "far") in model.init and ("InLine", "near", "aside") not in model.init
    learned = {("FinalClear", o) for o in ("near", "far", "aside")}
    state = model.progress(model.init - learned, GroundStep("push", ("near",)))
    assert ("FinalClear", "near") in state and ("FinalClear", "far") in state and ("FinalClear", "aside") not in state
