"""Objects at the back of a deep table (issue 20: sink_stove_2_16, sink_stove_4_4): the arm reaches them only
from 1.0-1.1 m, the shoulder turned towards them, beyond Clutter's annulus (0.55-0.95 m, facing the spot). When
the annulus finds nothing, the pick and put-down generators draw bases where the reach map says the arm
reaches and the base can stand (interlayer_manip.reachmap.reaching_base)."""
import math
from dataclasses import replace

import numpy as np
from test_pbjson import _body, _box, load, scene


def deep_table(**goals):
    """A table 0.61 m deep (its front edge at x = 1.695) against a wall 0.2 m behind it; box ``a`` stands
    0.55 m in from the front edge: the base, 0.67 m wide, stands at least 0.89 m from it."""
    data = scene(**(goals or {"goal_holding": "a"}))
    walls = [_body("back", (2.5, 0.0, 0.0), [_box((0.01, 2.5, 0.2), (0.0, 0.0, 0.2))])]
    table = _body("counter", (2.0, 0.0, 0.385), [_box((0.305, 0.7515, 0.385))])
    a = _body("a", (2.244, 0.0, 0.771), [_box((0.0355, 0.025, 0.075), (0.0, 0.0, 0.075), color=(0, 0, 1))])
    data["bodies"] = [table, *walls, a]
    data["task"].update(object_names=["a"], table_names=["counter"], sink_names=[], stove_names=[], regions=[])
    return data


def test_an_object_at_the_back_of_a_deep_table_gets_grasps_in_every_epoch(tmp_path):
    """Mutation: grasp_candidates draws from the annulus alone (no reaching_base): no grasp in most epochs."""
    from interlayer.refine import stable_seed
    from interlayer_pbjson.samplers import PBSampler

    p = load(tmp_path, deep_table())
    w = p.geometry.initial_world()
    for epoch in range(3):
        sampler = PBSampler(stable_seed(0, epoch, PBSampler.__qualname__))
        for arm in ("left", "right"):
            found = sampler.grasp_candidates(p, w, "a", arm)
            assert found, (epoch, arm)


def test_a_goal_pose_at_the_back_of_a_deep_table_gets_put_downs(tmp_path):
    """Its initial pose is a's goal: held as a grasp from the front holds it, the put-down there is found.
    Mutation: _putdowns without its second search (bases from the reach map): no candidate."""
    from interlayer.domain import GroundStep
    from interlayer.refine import stable_seed
    from interlayer_pbjson.samplers import PBSampler

    p = load(tmp_path, deep_table(goal_poses={"a": "initial"}))
    g = p.geometry
    w0 = g.initial_world()
    sampler = PBSampler(stable_seed(0, 0, PBSampler.__qualname__))
    base, _, T, *_ = sampler.grasp_candidates(p, w0, "a", "left")[0]
    P = w0.objects["a"]
    w = replace(w0, base=base, objects={}, held={"left": ("a", np.linalg.inv(T) @ P)})
    w = w.with_arm("left", g.carry(w, "left", np.random.default_rng(0)))
    step = GroundStep("place_at_goal", ("a", "left", "bpfgp_a_left", "gpfgp_a_left"))
    found = list(sampler(p, step, w, np.random.default_rng(0)))
    assert found and all(g.at_goal_pose("a", np.asarray(c.values["object_pose"])) for c in found)


def test_a_grasp_the_arm_reaches_the_goal_pose_with_from_no_base_asks_for_a_regrasp(tmp_path):
    """Held across its long sides (the tool along the table's length), a goes to its goal pose from a base
    beside the table, against the wall: none stands there, so the put-down asks for a grasp from the front
    (BadGrasp, as a hand that hits a fixed obstacle does). Held from the front, it asks for nothing.
    Mutation: regrasps' fits() without the reach map (the hand's clearance alone): no regrasp asked."""
    from interlayer_manip.grasps import grasp_poses
    from interlayer_manip.state import pose4
    from interlayer_pbjson.samplers import PBSampler, _kind

    p = load(tmp_path, deep_table(goal_poses={"a": "initial"}))
    g = p.geometry
    w0 = g.initial_world()
    P = w0.objects["a"]
    C = g.layout.extra["goal_centres"]["a"]
    variants = [C, C @ pose4(0, 0, 0, math.pi)]
    asked = {}
    for heading in (0.0, math.pi / 2):  # the tool along x (from the front), along y (from the table's end)
        _, T = grasp_poses(g, "a", P, heading, ("side",), np.random.default_rng(0), n_side=1)[0]
        w = replace(w0, objects={}, held={"left": ("a", np.linalg.inv(T) @ P)})
        asked[heading] = PBSampler(0).regrasps(p, w, "a", "left", variants)
    assert asked[0.0] == []
    assert asked[math.pi / 2] and all(_kind(np.linalg.inv(F)) == "side" for F in asked[math.pi / 2])
    assert all(abs(math.cos(math.atan2(*(C @ np.linalg.inv(F))[1::-1, 0]))) > 0.9 for F in asked[math.pi / 2])


def test_a_pick_of_an_object_bound_for_a_goal_pose_ranks_the_grasps_that_fit_there_first(tmp_path):
    """a stands on a table open on every side; its goal pose is at the back of the deep counter, where only
    a grasp with the tool along the counter's depth is put down (test above). Among pick candidates with as
    many objects in the way, those with such a grasp come first (before: the shortest drive first).
    Mutation: PBSampler without its ranked_grasps (Clutter's ranking): a non-fitting grasp ranks first."""
    from interlayer.refine import stable_seed
    from interlayer_pbjson.samplers import PBSampler, _same_grasp

    data = deep_table(goal_poses={"a": [1, 0, 0, 0, 2.244, 0.0, 0.771]})
    data["bodies"][2]["point"] = {"x": 0.3, "y": 1.4, "z": 0.771}  # a on the open table
    data["bodies"].append(_body("open", (0.3, 1.4, 0.385), [_box((0.25, 0.25, 0.385))]))
    data["task"]["table_names"] = ["counter", "open"]
    p = load(tmp_path, data)
    w = p.geometry.initial_world()
    P = w.objects["a"]
    sampler = PBSampler(stable_seed(0, 0, PBSampler.__qualname__))
    fits = sampler.goal_grasps(p, "a")
    assert fits
    for arm in ("left", "right"):
        ranked = sampler.ranked_grasps(p, w, "a", arm)
        flags = [(c[0], not any(_same_grasp(p.geometry, "a", np.linalg.inv(c[4]) @ P, F) for F in fits)) for c in ranked]
        assert False in [f for _, f in flags] and True in [f for _, f in flags], flags  # both kinds offered
        assert flags == sorted(flags, key=lambda f: f), flags


def test_a_grasp_put_down_from_a_base_off_straight_behind_the_tool_asks_for_no_regrasp(tmp_path):
    """a's goal is 0.1 m in from the front edge of a long counter. Held with the tool along the counter, the
    base straight behind the tool would stand under the counter, yet the put-down's own search stands it
    off that line (base_near: within SECTOR of straight behind) and finds one; so the held grasp fits there:
    no regrasp is asked, and goal_grasps counts that grasp as fitting (sink_stove_4_30: the pick ranked a
    grasp that put down only from 1.06 m, over two objects, before one that puts down from 0.9 m clear).
    Mutation: _fits asks standing() for the bases straight behind the tool alone (spread 0): a regrasp is
    asked."""
    from interlayer.domain import GroundStep
    from interlayer.refine import stable_seed
    from interlayer_manip.grasps import grasp_poses
    from interlayer_pbjson.samplers import PBSampler, _same_grasp, goal_variants

    data = deep_table(goal_poses={"a": "initial"})
    data["bodies"][0] = _body("counter", (2.0, 0.0, 0.385), [_box((0.305, 2.0, 0.385))])  # 4 m long
    data["bodies"][1] = _body("back", (2.5, 0.0, 0.0), [_box((0.01, 4.0, 0.2), (0.0, 0.0, 0.2))])
    data["bodies"][2]["point"] = {"x": 1.80, "y": 0.0, "z": 0.771}
    p = load(tmp_path, data)
    g = p.geometry
    w0 = g.initial_world()
    P = w0.objects["a"]
    _, T = grasp_poses(g, "a", P, math.pi / 2, ("side",), np.random.default_rng(0), n_side=1)[0]
    assert abs(T[1, 0]) > 0.99  # the tool along the counter
    F = np.linalg.inv(T) @ P
    w = replace(w0, objects={}, held={"left": ("a", F)})
    assert PBSampler(0).regrasps(p, w, "a", "left", goal_variants(g, "a")) == []
    assert any(_same_grasp(g, "a", F, H) for H in PBSampler(0).goal_grasps(p, "a"))
    # the put-down's search agrees: held so, a is put down there
    w = replace(w, base=(0.3, 0.0, 0.0))
    w = w.with_arm("left", g.carry(w, "left", np.random.default_rng(0)))
    step = GroundStep("place_at_goal", ("a", "left", "bpfgp_a_left", "gpfgp_a_left"))
    found = list(PBSampler(stable_seed(0, 0, PBSampler.__qualname__))(p, step, w, np.random.default_rng(0)))
    assert found and all(g.at_goal_pose("a", np.asarray(c.values["object_pose"])) for c in found)



def test_a_grasp_judged_to_fit_off_straight_behind_the_tool_is_put_down_from_there(tmp_path):
    """a (a box) stands 0.425 m in from the deep counter's front edge, turned 0.74 rad: every side grasp
    holds the tool 0.74 rad or more off straight into the counter. _fits counts bases off straight behind the
    tool (reachmap.behind: within SECTOR when NEAR) and judges the grasp with the tool at 0.74 rad to fit, so
    the put-down must find one there: the annulus's bases face the spot and the arm does not reach the
    turned tool from them, straight behind it the base stands under the counter; the bases off that line in
    the front, the shoulder turned to the spot, reach it (sink_stove_4_40: picks ranked such grasps first,
    then the put-down found nothing, 5 picks in a row, 18 replans and a timeout).
    Mutations: _putdowns without its off-line search, or reaching_base ignoring off_line: no candidate."""
    from interlayer.domain import GroundStep
    from interlayer.refine import stable_seed
    from interlayer_manip.grasps import grasp_poses
    from interlayer_manip.reachmap import behind
    from interlayer_pbjson.samplers import PBSampler, _fits

    yaw = 0.74
    data = deep_table(goal_poses={"a": "initial"})
    data["bodies"][2].update(point={"x": 2.12, "y": 0.0, "z": 0.771},
                             quat={"w": math.cos(yaw / 2), "x": 0.0, "y": 0.0, "z": math.sin(yaw / 2)})
    p = load(tmp_path, data)
    g = p.geometry
    w0 = g.initial_world()
    P = w0.objects["a"]
    _, T = grasp_poses(g, "a", P, 0.0, ("side",), np.random.default_rng(0), n_side=1)[0]
    heading = math.atan2(T[1, 0], T[0, 0])
    assert abs(heading - yaw) < 0.05  # the tool along a's x axis
    F = np.linalg.inv(T) @ P
    assert _fits(p, replace(w0, objects={}), "a", "left", T, F)
    assert any(o[2] != heading for o in behind(g, "left", *T[:3, 3], heading))  # off straight behind
    w = replace(w0, base=(0.3, 0.0, 0.0), objects={}, held={"left": ("a", F)})
    w = w.with_arm("left", g.carry(w, "left", np.random.default_rng(0)))
    step = GroundStep("place_at_goal", ("a", "left", "bpfgp_a_left", "gpfgp_a_left"))
    found = list(PBSampler(stable_seed(0, 0, PBSampler.__qualname__))(p, step, w, np.random.default_rng(0)))
    assert found and all(g.at_goal_pose("a", np.asarray(c.values["object_pose"])) for c in found)
