"""The PR2 domain draws itself for the meshcat visualizer (interlayer_manip.draw): `interlayer viz` /
`interlayer explain` pages of a real pr2_pick run, the replayed animation, headless-Chromium renders."""
from __future__ import annotations

import sys
from pathlib import Path

import numpy as np
import pytest

sys.path.insert(0, str(Path(__file__).resolve().parent))  # tests/browser.py

import browser  # noqa: E402
from conftest import solved_run, write_pages

pytest.importorskip("meshcat")
pytest.importorskip("pinocchio")

ROOT = Path(__file__).resolve().parent.parent
EXAMPLE = ROOT / "examples" / "pr2_pick.toml"
PAGE_LIMIT = 2_000_000  # bytes (issue 23: pages of at most 2 MB)
TABLE_RGB = (204, 173, 133)  # draw.COLORS["table"], lit
RED_RGB = (230, 31, 31)  # the visualizer's OBSTRUCTING colour


@pytest.fixture(scope="module")
def out_dir(tmp_path_factory):
    return solved_run(tmp_path_factory, EXAMPLE, "hold")


@pytest.fixture(scope="module")
def run(out_dir):
    from interlayer_meshcat.visualizer import Run

    r = Run(out_dir)
    assert r.problem is not None, r.problem_error
    return r


@pytest.fixture(scope="module")
def pages(out_dir):
    return write_pages(out_dir)


@pytest.fixture(scope="module")
def need_chromium():
    if browser.chromium_path() is None:
        pytest.skip(browser.CHROMIUM_MISSING)


# ------------------------------------------------------------------ drawing convention
def test_the_visualizer_finds_the_pr2_drawer(run):
    from interlayer_meshcat.visualizer import drawer

    d, a = drawer(run.problem)
    assert d is not None and a is not None


def test_draw_scene_objects_robot_and_mapping(run):
    from interlayer_meshcat import Scene

    from interlayer_manip.draw import draw_scene

    geometry = run.problem.geometry
    scene = Scene("t")
    names = draw_scene(geometry, scene, None)
    for obj in ("target", "blocker", "can", "box", "table", "goal_spot", "pr2"):
        assert obj in names, obj
    info = scene._info
    assert names["blocker"] in info and names["target"] in info
    assert sum(k.startswith("pr2/") for k in info) > 20  # the robot's links
    # objects stand on the table, inside its footprint
    top = 0.72
    for obj in ("target", "blocker", "can", "box"):
        T = scene._world_pose(names[obj])
        assert 0.6 <= T[0, 3] <= 1.1 and abs(T[1, 3]) <= 0.8 and top < T[2, 3] < top + 0.15, obj
    # a failure snapshot: the robot stands where the snapshot says
    event = next(e for e in run.events if e.get("type") == "failure" and e.get("world"))
    scene2 = Scene("f")
    draw_scene(geometry, scene2, event["world"])
    x, y, _ = event["world"]["base"]
    assert np.allclose(scene2._world_pose("pr2")[:3, 3], [x, y, 0.0], atol=1e-9)


def test_animation_replays_base_arms_and_held_object(run):
    from interlayer_meshcat import Scene

    from interlayer_manip.draw import animation_frames, draw_scene

    geometry, traj = run.problem.geometry, run.trajectory
    scene = Scene("a")
    draw_scene(geometry, scene, traj["initial"])
    frames = animation_frames(geometry, scene, traj)
    assert 50 < len(frames) < 1500
    steps = [f["@step"] for f in frames]
    assert steps == sorted(steps) and steps[-1] == len(traj["steps"]) - 1
    bases = {tuple(np.round(f["pr2"][:2, 3], 4)) for f in frames}
    assert len(bases) > 3  # the base moves
    # the goal (hold): the target ends in a gripper, i.e. at a tool frame of the robot
    robot = geometry.robot
    last = traj["steps"][-1]
    arm = next(s["arm"] for s in last["segments"] if s.get("kind") == "grasp")
    T_end = frames[-1]["target"]
    T_start = frames[0]["target"]
    assert np.linalg.norm(T_end[:3, 3] - T_start[:3, 3]) > 0.05  # it was carried
    # replay the final arm state as the frames do and compare with the tool pose
    from interlayer_manip.draw import _State

    st = _State(geometry, traj["initial"])
    for s in traj["steps"]:
        for seg in s["segments"]:
            if seg.get("group") == "base":
                st.base = tuple(seg["points"][-1]["positions"])
            elif "points" in seg:
                st.arms[seg["group"].split("_")[0]] = tuple(seg["points"][-1]["positions"])
    tool = robot.tool_pose(st.q(), arm)
    grasp = np.asarray(next(s["grasp"] for s in last["segments"] if s.get("kind") == "grasp"))
    assert np.allclose(tool @ grasp, T_end, atol=1e-6)



def test_a_gripper_opened_only_as_wide_as_a_grasp_needs_is_drawn_at_that_width(run):
    from interlayer_manip.draw import _State

    geometry, traj = run.problem.geometry, run.trajectory
    robot = geometry.robot
    st = _State(geometry, {**traj["initial"], "grippers": {"left": ["open", 0.05], "right": "open"}})  # as JSON has them
    q = st.q()
    assert robot.gripper_opening(q, "left") == pytest.approx(0.05, abs=1e-3)
    assert robot.gripper_opening(q, "right") == pytest.approx(robot.max_gripper_opening, abs=1e-3)


# ------------------------------------------------------------------ pages
def test_pages_are_written_and_small(pages):
    explain = pages[1]
    for p in pages:
        assert p.exists() and 900_000 < p.stat().st_size < PAGE_LIMIT, (p, p.stat().st_size)
    html = explain.read_text()
    assert "Obstructs blocker" in html
    assert "obstructed by" in html and "blocker" in html


def test_views_of_a_page_share_the_robot(pages):
    """The explanation page has several 3D views of the PR2 (the solution, each failure): each
    command (the robot's meshes above all) is stored once and referenced by every view."""
    import re

    html = pages[1].read_text()
    stored = re.findall(r'id="il-blob-([0-9a-f]+)"', html)
    refs = re.findall(r'"#([0-9a-f]{20})"', html)
    assert html.count("InterlayerMeshcat.mount") >= 3  # mount + mountLazy calls: the solution and failures
    assert len(stored) == len(set(stored)) and set(refs) == set(stored)
    assert len(refs) > 1.5 * len(stored)


def test_pages_render_in_chromium(pages, need_chromium, tmp_path):
    plan, explain = pages
    png = browser.screenshot(plan, tmp_path / "plan.png", size=(1000, 700), budget_ms=3000)
    assert not browser.is_blank(png)
    img = browser.read_png(png)[230:, 100:900]  # the 3D view below the caption
    assert browser.color_fraction(img, TABLE_RGB, tol=45) > 0.05  # the table
    assert browser.color_fraction(img, (150, 153, 160), tol=45) > 0.05  # the (grey) robot
    png = browser.screenshot(explain, tmp_path / "explain.png", size=(1000, 1600), budget_ms=3000)
    assert not browser.is_blank(png)
    # the failure views (right half of the page; the text is on the left) show the blocker in red
    assert browser.color_fraction(browser.read_png(png)[:, 540:], RED_RGB, tol=60) > 0.0005
