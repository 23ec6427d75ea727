"""Drawer (O)/(N): the cabinet's prismatic joint, the (O)/(N) property, the learned fact, the validator."""
import copy
from dataclasses import replace

import numpy as np
import pytest

from interlayer.abstraction import abstract
from interlayer.domain import GroundStep
from interlayer.refine import Candidate


@pytest.fixture(scope="module")
def cabinet():
    from interlayer_drawer.scene import cabinet_placement, cabinet_urdf
    from interlayer_pinocchio import ArticulatedBody

    return ArticulatedBody("cabinet", cabinet_urdf(), cabinet_placement())


def test_prismatic_joint_moves_the_handle_and_the_drawer_geometry(cabinet):
    from interlayer_drawer.scene import FRONT
    from interlayer_pinocchio import CollisionWorld, Robot

    assert cabinet.joint_names == ("drawer_joint",)
    assert cabinet.lower.tolist() == [0.0] and cabinet.upper.tolist() == [0.4]
    closed = cabinet.shape_poses([0.0])
    for d in (0.0, 0.13, 0.4):
        H = cabinet.link_pose([d], "handle")
        assert np.allclose(H[:3, 3], [FRONT - d, 0.0, 0.0]) and np.allclose(H[:3, :3], np.eye(3))
        poses = cabinet.shape_poses([d])
        for s in cabinet.shapes:
            shift = -d if s.link in ("drawer", "handle") else 0.0
            assert np.allclose(poses[s.name][:3, 3], closed[s.name][:3, 3] + [shift, 0, 0]), s.name
    with pytest.raises(ValueError, match="outside"):
        cabinet.link_pose([0.5], "drawer")

    # the Coal geometry in a collision world follows the joint: a box 0.2 m in front of the drawer's
    # front plate is touched once the drawer is pulled that far, not before
    cw = CollisionWorld(Robot.load("pr2"))
    cabinet.add_to(cw, [0.0])
    cw.add_box("box", (0.05, 0.05, 0.05), _at(FRONT - 0.02 - 0.2 - 0.03, 0.1, 0.64), movable=True)
    assert cabinet.touching(cw, [0.15], ["box"]) == set()
    assert cabinet.touching(cw, [0.25], ["box"]) == {"box"}
    cabinet.update(cw, [0.25])
    plate = next(s.name for s in cabinet.shapes if s.link == "drawer")
    assert np.allclose(cw.pose(plate), cabinet.shape_poses([0.25])[plate])


def _at(x, y, z):
    T = np.eye(4)
    T[:3, 3] = (x, y, z)
    return T


def _problem(host, variant, seed):
    from interlayer import api

    return api.build_problem(host, api.resolve_config("examples/drawer.toml", [f"problem.variant={variant}",
                                                                               f"planner.seed={seed}"]))


def test_objects_in_the_drawer_move_with_it(host):
    g = _problem(host, "O", 0).geometry
    w = g.initial_world()
    w2 = g.with_joints(w, "cabinet", [0.3])
    assert np.allclose(w2.objects["inner"][:3, 3], w.objects["inner"][:3, 3] - [0.3, 0, 0])
    assert np.allclose(w2.objects["outer"], w.objects["outer"])  # on its stand, not in the drawer


@pytest.mark.parametrize("variant", ["O", "N"])
def test_constructed_scenes_have_their_property(host, variant):
    from interlayer_drawer.check import check_property
    from interlayer_drawer.world import DrawerGeometry

    for seed in (0, 1):
        problem = _problem(host, variant, seed)
        text = problem.geometry.describe()  # what `interlayer check` prints
        assert f"({variant}) holds" in text, text
        report = check_property(DrawerGeometry(problem.geometry.layout, padding=0.0))
        if variant == "O":
            d, base = report.witness
            assert report.first_exposed <= d <= report.pulls_free
        else:
            assert report.first_exposed is None or report.first_exposed > report.pulls_free


def test_the_check_catches_a_scene_without_its_property(host):
    """An (O) scene with the outer object moved up to the drawer's front is not (O)."""
    from interlayer_drawer.check import check_property
    from interlayer_drawer.scene import FRONT
    from interlayer_drawer.world import DrawerGeometry

    layout = _problem(host, "O", 0).geometry.layout
    outer, stand = layout.obj("outer"), layout.obj("stand")
    x = FRONT - 0.02 - 0.05 - outer.size[0]  # blocks the drawer after 5 cm
    layout = replace(layout, objects=[o if o.name != "outer" else replace(o, pose=(x, *o.pose[1:])) for o in layout.objects],
                     fixed=[o if o.name != "stand" else replace(o, pose=(x, *o.pose[1:])) for o in layout.fixed])
    report = check_property(DrawerGeometry(layout, padding=0.0))
    assert not report.holds and report.pulls_free < 0.06
    assert "does NOT hold" in report.summary()
    assert stand.name == "stand"


def test_a_blocked_pull_teaches_pull_obstructs_outer(host):
    """The drawer running into the outer object fails open_drawer with a failure naming it, which the
    template translator turns into PullObstructs(outer, pull_top_drawer); picking outer deletes it."""
    from interlayer.builtin import translate_by_templates

    problem = _problem(host, "N", 0)
    g = problem.geometry
    model = abstract(problem)
    step = GroundStep("open_drawer", ("top_drawer", "right", "bpfo_top_drawer_right", "hg_top_drawer_right",
                                      "pull_top_drawer"))
    w = g.initial_world()
    v = np.asarray(w.arms["right"])
    block = g.layout.extra["block"]
    cand = Candidate(((v,), (np.append(v, 0.0), np.append(v, block + 0.05)), (v,)), {}, "test pull")
    out = g.refine_step(step, w, cand, motion=None)  # blocked before any motion is planned
    assert not out.ok and out.failure.kind == "obstruction" and out.failure.objects == ("outer",)
    facts = translate_by_templates(out.failure, step, model)
    assert facts == {("PullObstructs", "outer", "pull_top_drawer")}
    # a pull short of the outer object is not blocked by it
    short = Candidate(((v,), (np.append(v, 0.0), np.append(v, max(0.0, block - 0.03))), (v,)), {}, "short")
    assert g.sweep_blockers(w, "cabinet", short.waypoints[1][-1][7:]) == set()
    pick = GroundStep("pick", ("outer", "left", "bpfg_outer_left", "gpfg_outer_left"))
    state = model.init | facts | {("RobotAt", "bpfg_outer_left")}
    assert model.applicable(state, pick)
    assert ("PullObstructs", "outer", "pull_top_drawer") not in model.progress(state, pick)


@pytest.fixture(scope="module")
def pulled_without_outer(host):
    """An (N) scene's move_base + open_drawer refined as if the outer object were elsewhere, with the
    real motion planner: the pull runs the drawer through where the outer object really stands."""
    from interlayer import api
    from interlayer.refine import stable_seed

    problem = _problem(host, "N", 0)
    g = problem.geometry
    config = api.resolve_config("examples/drawer.toml", ["problem.variant=N"])
    task, motion = api.make_planners(host, config, api.Stats())
    w = g.initial_world()
    w = replace(w, objects={**w.objects, "outer": _at(0.0, -1.6, 0.56)})
    gens = api.generators_for(host, abstract(problem), config)
    plan = [GroundStep("move_base", ("bpfo_top_drawer_right",)),
            GroundStep("open_drawer", ("top_drawer", "right", "bpfo_top_drawer_right", "hg_top_drawer_right",
                                       "pull_top_drawer"))]
    rng = np.random.default_rng(stable_seed(0))
    for base in gens["move_base"](problem, plan[0], w, rng):
        first = g.refine_step(plan[0], w, base, motion)
        if not first.ok:
            continue
        for cand in gens["open_drawer"](problem, plan[1], first.world, rng):
            if cand.values["pull_top_drawer"] < g.layout.extra["block"] + 0.03:
                continue
            second = g.refine_step(plan[1], first.world, cand, motion)
            if second.ok:
                outcomes = [first, second]
                break
        else:
            continue
        break
    else:
        pytest.fail("no refinement of the pull")
    return problem, plan, outcomes


def test_validator_rejects_a_pull_through_the_outer_object(pulled_without_outer):
    from interlayer_drawer.world import DrawerGeometry

    problem, plan, outcomes = pulled_without_outer
    g = problem.geometry
    traj = copy.deepcopy(g.trajectory_json(plan, outcomes))  # edited below; the outcomes are shared
    pull = next(s for s in traj["steps"][1]["segments"] if s["kind"] == "pull")
    assert pull["joint_names"][-1] == "cabinet/drawer_joint" and pull["body"] == "cabinet"
    event = next(s for s in traj["steps"][1]["segments"] if s["kind"] == "articulation")
    assert event["positions"] == [pull["points"][-1]["positions"][-1]]
    errors = g.validate(plan, traj)
    assert len(errors) == 1 and "outer" in errors[0] and "pull" in errors[0], errors
    # the same trajectory with the outer object elsewhere is valid
    layout = g.layout
    moved = replace(layout, objects=[o if o.name != "outer" else replace(o, pose=(0.0, -1.6, *o.pose[2:]))
                                     for o in layout.objects])
    not_goal = [e for e in DrawerGeometry(moved).validate(plan, traj) if not e.startswith("goal not satisfied")]
    assert not_goal == []  # (the plan stops before the pick)
    # and a pull whose drawer runs ahead of the gripper is a slip
    pull["points"][-1]["positions"][-1] -= 0.02
    assert any("slips" in e for e in DrawerGeometry(moved).validate(plan, traj))


def test_the_animation_slides_the_drawer(pulled_without_outer):
    from interlayer_meshcat import Scene

    problem, plan, outcomes = pulled_without_outer
    g = problem.geometry
    traj = g.trajectory_json(plan, outcomes)
    scene = Scene("drawer")
    names = g.draw_scene(scene, None)
    assert names["top_drawer"] == "bodies/cabinet/drawer"
    frames = g.animation_frames(scene, traj)
    plate = "bodies/cabinet/drawer/0"
    xs = [f[plate][0, 3] for f in frames if plate in f]
    d = traj["steps"][1]["segments"][-1]  # tuck; the articulation event is before it
    final = next(s for s in traj["steps"][1]["segments"] if s["kind"] == "articulation")["positions"][0]
    assert xs[0] - xs[-1] == pytest.approx(final, abs=1e-6) and d["kind"] == "transit"
    inner = [f["inner"][0, 3] for f in frames]
    assert inner[0] - inner[-1] == pytest.approx(final, abs=1e-6)  # the object in the drawer rides along


@pytest.mark.slow
@pytest.mark.parametrize("variant", ["O", "N"])
def test_drawer_solves_and_validates(tmp_path, variant):
    """End to end with the real planners: (N) moves the outer object after learning that it blocks the
    pull; both validate."""
    import json

    from interlayer.cli import main

    out = tmp_path / variant
    assert main(["plan", "examples/drawer.toml", "--set", f"problem.variant={variant}", "--out", str(out)]) == 0
    assert main(["validate", str(out)]) == 0
    result = json.loads((out / "result.json").read_text())
    moved = any(s["action"] == "pick" and s["args"][0] == "outer" for s in result["plan"])
    if variant == "N":
        assert moved and "(PullObstructs outer pull_top_drawer)" in result["learned_facts"]
