"""A mobile robot with one arm on one side of its base (the TIAGo Pro, issue 21): the base poses offered come
from where its arm reaches (reachmap.py), from the directions a cubby's mouth leaves open, and the drawer
scene's outer object fits its gripper."""
import math
from pathlib import Path

import numpy as np
import pytest

from interlayer import api
from interlayer.domain import GroundStep

ROOT = Path(__file__).resolve().parents[1]
CUBBY = ROOT / "examples" / "pr2_pick.toml"
DRAWER = ROOT / "examples" / "drawer.toml"


def _cubby(robot):
    return api.prepare(str(CUBBY), [f"problem.robot={robot}"]).problem


def test_the_tiago_finds_bases_from_which_its_arm_reaches_into_the_cubby():
    # The PR2's annulus (0.45 .. 0.80 m, facing the target) offered none on this seed: the TIAGo's arm needs
    # the target farther away for its pre-grasp, the table keeps its base back.
    from interlayer_manip.generators import move_base

    problem = _cubby("tiago")
    world = problem.geometry.initial_world()
    arm = problem.geometry.robot.arms[0]
    found = list(move_base(problem, GroundStep("move_base", (f"bpfg_target_{arm}",)), world, np.random.default_rng(0)))
    assert len(found) >= 3
    P = world.objects["target"]
    assert all(math.hypot(c.waypoints[0][0] - P[0, 3], c.waypoints[0][1] - P[1, 3]) > 0.6 for c in found)


def test_the_reach_map_keeps_the_cells_whose_pre_grasp_the_arm_also_reaches():
    from interlayer_manip.reachmap import reach_cells
    from interlayer_manip.state import PRE_GRASP

    robot = _cubby("tiago").geometry.robot
    cells = reach_cells(robot, robot.arms[0], 0.8)
    assert cells and min(r for r, _ in cells) - PRE_GRASP >= 0.35  # the arm folds no nearer than that


def test_a_cubby_leaves_open_only_the_directions_facing_its_mouth():
    from interlayer_manip.reachmap import open_bearings

    problem = _cubby("pr2")
    g = problem.geometry
    world = g.initial_world()
    into = open_bearings(g, world, "right", "target", world.objects["target"])
    # the cubby opens towards -x: a grasp comes from there, heading +x (within the mouth's fan)
    assert into and all(abs(b) < 0.8 for b in into)
    free = open_bearings(g, world, "right", "can", world.objects["can"])  # on the open table
    assert len(free) > 2 * len(into)


def test_the_drawer_scenes_outer_object_fits_the_robots_gripper():
    from interlayer_manip.state import OPEN_CLEARANCE

    for robot, width in (("pr2", 0.08), ("tiago", None)):
        problem = api.prepare(str(DRAWER), ["problem.variant=N", f"problem.robot={robot}"]).problem
        g = problem.geometry
        outer = g.specs["outer"]
        assert 2 * outer.size[0] + OPEN_CLEARANCE <= g.robot.max_gripper_opening + 1e-9
        if width is not None:  # the PR2's scene is as it was
            assert 2 * outer.size[0] == pytest.approx(width)


@pytest.mark.slow
@pytest.mark.parametrize("config, overrides", [(CUBBY, []), (DRAWER, ["problem.variant=N"])], ids=["cubby", "drawer-N"])
def test_the_tiago_solves_and_validates(tmp_path, config, overrides):
    result = api.solve(str(config), ["problem.robot=tiago", "planner.seed=0", "planner.time_limit=120", *overrides])
    assert result.status == "solved", result.reason
    api.write_outputs(result, tmp_path)
    assert api.validate(tmp_path) == []


def test_bases_come_from_the_annulus_when_no_cell_reaches_that_height():
    from interlayer_manip.reachmap import around

    g = _cubby("pr2").geometry
    rng = np.random.default_rng(0)
    bases = [around(g, "right", rng, 0.0, 0.0, 5.0) for _ in range(20)]  # 5 m up: out of any reach
    bases += [around(g, "right", rng, 0.0, 0.0, 0.8, level=False) for _ in range(20)]  # a top grasp: not measured
    assert all(0.45 - 1e-9 <= math.hypot(x, y) <= 0.80 + 1e-9 for x, y, _ in bases)


def test_a_domains_own_grasps_get_bases_from_the_annulus():
    # Drawer's top grasps into the open drawer: the reach map (level grasps) put the TIAGo 0.8 to 1.1 m away
    from interlayer_drawer.generators import move_base

    problem = api.prepare(str(DRAWER), ["problem.variant=O", "problem.robot=tiago", "planner.seed=1"]).problem
    g = problem.geometry
    world = g.with_joints(g.initial_world(), "cabinet", [0.35])
    arm = g.robot.arms[0]
    found = list(move_base(problem, GroundStep("move_base", (f"bpfg_inner_{arm}",)), world, np.random.default_rng(1)))
    P = world.objects["inner"]
    assert found and all(math.hypot(c.waypoints[0][0] - P[0, 3], c.waypoints[0][1] - P[1, 3]) <= 0.80 + 1e-9
                         for c in found)


def test_detailed_collision_meshes_are_checked_as_their_convex_hulls():
    import coal
    from interlayer_pinocchio.meshes import MAX_TRIANGLES

    tiago = _cubby("tiago").geometry.robot
    meshes = [go.geometry for go in tiago.collision_model.geometryObjects if isinstance(go.geometry, coal.BVHModelBase)]
    assert all(m.num_tris <= MAX_TRIANGLES for m in meshes)  # its fingertips had 10,772 triangles each
    assert sum(isinstance(go.geometry, coal.ConvexBase) for go in tiago.collision_model.geometryObjects) >= 20
    pr2 = _cubby("pr2").geometry.robot  # small meshes stay as they are
    assert not any(isinstance(go.geometry, coal.ConvexBase) for go in pr2.collision_model.geometryObjects)
