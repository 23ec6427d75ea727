"""ik:cartesian, trajopt and TOPP-RA timing: real Pinocchio / Coal / proxsuite / toppra, no mocks."""
import json
import math
import shutil

import numpy as np
import pytest

from interlayer import api
from interlayer.errors import UserError
from interlayer.motion import InterpolatingPlanner
from interlayer_optim.cartesian import CartesianPlanner
from interlayer_optim.timing import time_parameterize
from interlayer_optim.trajopt import TrajOptPlanner

from test_pr2_plan import EXAMPLE, hold_run  # noqa: F401  (module-scoped fixture: one solve)


def test_pr2_viewer_plays_motions_in_real_time(hold_run):
    from interlayer_meshcat.visualizer import FPS
    from interlayer_manip.draw import _in_real_time

    _, out = hold_run
    seg = _arm_segment(json.loads((out / "trajectory.json").read_text()))
    path = [np.asarray(p["positions"]) for p in seg["points"]]
    frames = _in_real_time(seg["points"], path, FPS)
    duration = seg["points"][-1]["time_from_start"]
    assert abs(len(frames) - duration * FPS) <= 1
    assert np.allclose(frames[-1], path[-1])


def test_timing_respects_velocity_and_acceleration_limits():
    path = np.array([[0.0, 0.0, 0.0], [1.0, 0.5, 0.0], [1.0, 1.5, 2.0], [0.2, 0.1, 0.3]])
    vmax, amax = np.array([0.5, 0.5, 1.0]), np.array([1.0, 1.0, 2.0])
    points = time_parameterize(path, vmax, amax)
    q = np.array([p["positions"] for p in points])
    t = np.array([p["time_from_start"] for p in points])
    v = np.array([p["velocities"] for p in points])
    a = np.array([p["accelerations"] for p in points])
    assert all(any(np.allclose(corner, x) for x in q) for corner in path)  # on the checked polyline
    assert np.all(np.diff(t) > 0)
    assert np.all(np.abs(np.diff(q, axis=0)) <= vmax * np.diff(t)[:, None] * 1.001 + 1e-9)
    assert np.all(np.abs(v) <= vmax * 1.001) and np.all(np.abs(a) <= amax * 1.001)
    assert not v[0].any() and not v[-1].any()
    # time-optimal, not merely slow: the longest joint move of the first corner-free piece at full speed
    assert t[-1] < 2.0 * sum(np.max(np.abs(np.diff(path, axis=0)) / vmax, axis=1))


def _arm_segment(traj):
    return next(s for step in traj["steps"] for s in step["segments"] if s.get("group", "").endswith("arm"))


def _slow_arm_segment(traj):
    """The first arm segment that stays below half its joints' velocity limits: twice as fast, only
    its accelerations break a limit."""
    from interlayer_pinocchio import Robot

    robot = Robot.load("pr2")
    for step in traj["steps"]:
        for s in step["segments"]:
            if s.get("group", "").endswith("arm"):
                limit = robot.velocity_limits(s["group"])
                peak = np.max(np.abs([p["velocities"][:len(limit)] for p in s["points"]]), axis=0)
                if np.all(2 * peak < limit):
                    return s
    raise AssertionError("no arm segment below half its velocity limits")


def test_validator_rejects_a_too_fast_segment(hold_run, tmp_path):
    _, out = hold_run
    assert api.validate(out) == []
    dst = tmp_path / "fast"
    shutil.copytree(out, dst)
    traj = json.loads((dst / "trajectory.json").read_text())
    seg = _arm_segment(traj)
    for p in seg["points"]:  # ten times faster, and no velocities claimed: positions and times alone tell
        p["time_from_start"] *= 0.1
        del p["velocities"], p["accelerations"]
    (dst / "trajectory.json").write_text(json.dumps(traj))
    errors = api.validate(dst)
    assert errors and "too fast" in errors[0], errors


def test_validator_rejects_velocities_changing_too_fast(hold_run, tmp_path):
    _, out = hold_run
    dst = tmp_path / "jerky"
    shutil.copytree(out, dst)
    traj = json.loads((dst / "trajectory.json").read_text())
    for p in _slow_arm_segment(traj)["points"]:  # twice as fast: velocities scale by 2, accelerations by 4
        p["time_from_start"] *= 0.5
        p["velocities"] = [2 * v for v in p["velocities"]]
    (dst / "trajectory.json").write_text(json.dumps(traj))
    errors = api.validate(dst)
    assert errors and ("accelerates faster" in errors[0] or "too fast" in errors[0]), errors


def test_validator_rejects_claimed_accelerations_beyond_the_limit(hold_run, tmp_path):
    _, out = hold_run
    dst = tmp_path / "acc"
    shutil.copytree(out, dst)
    traj = json.loads((dst / "trajectory.json").read_text())
    seg = next(s for step in traj["steps"] for s in step["segments"] if s.get("group") == "base")
    seg["points"][1]["accelerations"][0] = 5.0
    (dst / "trajectory.json").write_text(json.dumps(traj))
    errors = api.validate(dst)
    assert errors and "acceleration 5.000 exceeds" in errors[0], errors


@pytest.fixture(scope="module")
def pr2_problem():
    from interlayer.plugins import PluginHost

    return api.build_problem(PluginHost(), api.resolve_config(EXAMPLE, []))


def _reach_query(problem):
    """Left arm: from an IK solution in front of the robot 16 cm straight forward and down."""
    from interlayer_manip.state import pose4

    g = problem.geometry
    w = g.initial_world()
    rng = np.random.default_rng(0)
    T0, T1 = pose4(0.45, 0.30, 1.10, 0.0), pose4(0.60, 0.25, 1.05, 0.0)
    a = g.ik(w, "left", T0, rng, movables=True)
    b = g.ik(w.with_arm("left", a), "left", T1, rng, movables=True, seed=a)
    return g.arm_query(w, "left", a, b, "reach", [0.0])


def _off_line(problem, query, path):
    tool = [query.tool(v)[0][:3, 3] for v in path]
    p0, p1 = tool[0], tool[-1]
    u = (p1 - p0) / np.linalg.norm(p1 - p0)
    return max(np.linalg.norm((p - p0) - ((p - p0) @ u) * u) for p in tool)


def test_cartesian_keeps_the_pr2_tool_on_the_straight_line(pr2_problem):
    query = _reach_query(pr2_problem)
    plan = CartesianPlanner().plan(query)
    assert plan.ok, plan.reason
    assert np.allclose(plan.path[0], query.start) and np.allclose(plan.path[-1], query.goal)
    assert _off_line(pr2_problem, query, query.space.densify(list(plan.path), 0.002)) < 0.003
    joint_line = InterpolatingPlanner().plan(query)
    dense = query.space.densify(list(joint_line.path))
    assert _off_line(pr2_problem, query, dense) > 0.005  # a joint-space line is not a tool line


def test_cartesian_names_the_movable_object_in_the_way(gripper_example):
    from interlayer.plugins import PluginHost

    problem = api.build_problem(PluginHost(), api.resolve_config(gripper_example, []))
    g = problem.geometry
    w = g.initial_world()
    bx, by, _ = w.blocks["b2"]
    plan = CartesianPlanner().plan(g.query(w, (bx - 0.4, by, 0.0), (bx + 0.06, by, 0.0), "push"))
    assert not plan.ok and plan.obstructions == ("b2",), plan


def test_cartesian_without_tool_kinematics_is_a_user_error(pr2_problem):
    g = pr2_problem.geometry
    w = g.initial_world()
    with pytest.raises(UserError, match="ik:cartesian"):
        CartesianPlanner().plan(g.base_query(w, w.base, (w.base[0] - 0.2, w.base[1], 0.0), "drive", [0.0]))


def test_pr2_clearance_gradients_match_finite_differences(pr2_problem):
    g = pr2_problem.geometry
    w = g.initial_world()
    query = _reach_query(pr2_problem)
    v = np.asarray(query.goal, float)
    found = query.clearances(v, True, 0.3)
    assert found
    for key, c in list(found.items())[:8]:
        fd = np.zeros(len(v))
        for j in range(len(v)):
            dv = v.copy()
            dv[j] += 1e-6
            fd[j] = (query.clearances(dv, True, 1.0)[key].distance - c.distance) / 1e-6
        assert np.allclose(c.gradient, fd, atol=2e-3), key
    assert w is not None


def test_trajopt_solves_gripper2d_and_learns_the_obstruction(gripper_example, tmp_path):
    result = api.solve(gripper_example, overrides=["planner.motion=trajopt", "motion_planner.time_limit=1.0"])
    assert result.status == "solved", result.reason
    assert ("Obstructs", "b2", "gp_b1", "b1") in result.learned_facts
    out = api.write_outputs(result, tmp_path / "run")
    assert api.validate(out) == []


def test_trajopt_pushes_the_straight_line_off_the_walls(gripper_example):
    from interlayer.plugins import PluginHost

    problem = api.build_problem(PluginHost(), api.resolve_config(gripper_example, []))
    g = problem.geometry
    query = g.query(g.initial_world(), (0.52, 0.2, 0.0), (0.52, 0.7, 0.0), "past the corridor's mouth")
    assert not InterpolatingPlanner().plan(query).ok  # the straight line clips the walls' ends
    plan = TrajOptPlanner(inits=1, time_limit=10.0).plan(query)  # the straight line is the only start
    assert plan.ok, plan.reason
    assert all(query.is_valid(q) for q in query.space.densify(list(plan.path)))


def test_unknown_trajopt_option_is_named(gripper_example):
    with pytest.raises(UserError, match="waypionts"):
        api.solve(gripper_example, overrides=["planner.motion=trajopt", "motion_planner.trajopt.waypionts=3"])
