"""The "meshcat" visualizer: `interlayer viz` / `interlayer explain` pages of a real Gripper-2D run,
the domain drawing convention (draw_scene / animation_frames) and headless-Chromium renders."""
from __future__ import annotations

import json
import re
import shutil
import subprocess
import sys
from pathlib import Path

import pytest

sys.path.insert(0, str(Path(__file__).resolve().parent))  # tests/browser.py

import browser  # noqa: E402
from conftest import solved_run, write_pages

pytest.importorskip("meshcat")

ROOT = Path(__file__).resolve().parent.parent
EXAMPLE = ROOT / "examples" / "gripper2d.toml"
PAGE_BUDGET = 1_500_000  # bytes; the inlined viewer JS alone is ~0.85 MB
FACT = "(Obstructs b2 gp_b1 b1)"
ALLOWED_URLS = {"http://www.w3.org/1999/xhtml", "ws://${location.host}"}


@pytest.fixture(scope="module")
def out_dir(tmp_path_factory):
    return solved_run(tmp_path_factory, EXAMPLE, "g1")


@pytest.fixture(scope="module")
def pages(out_dir):
    return write_pages(out_dir)


@pytest.fixture(scope="module")
def unsolved_dir(out_dir):
    """The same run as if it had timed out after the first failure: no trajectory, not solved."""
    out = out_dir.parent / "unsolved"
    shutil.copytree(out_dir, out)
    (out / "trajectory.json").unlink()
    result = json.loads((out / "result.json").read_text())
    result.update(status="timeout", reason="the time limit was reached", plan=[])
    (out / "result.json").write_text(json.dumps(result))
    trace = json.loads((out / "trace.json").read_text())
    events = trace["events"]
    cut = next(i for i, e in enumerate(events) if e["type"] == "replan")
    trace["events"] = events[:cut] + [{"t": events[cut]["t"], "type": "end", "status": "timeout",
                                       "reason": "the time limit was reached"}]
    (out / "trace.json").write_text(json.dumps(trace))
    return out


def external_urls(html: str) -> list[str]:
    bad = [m for m in re.findall(r"""(?:src|href)\s*=\s*["']?\s*(?:https?:|wss?:)?//[^"' >]*""", html)]
    bad += re.findall(r"<link\b[^>]*>", html) + re.findall(r"<script[^>]*\bsrc\s*=[^>]*>", html)
    bad += [u for u in re.findall(r"""(?:https?|wss?)://[^\s"'`)<>\\]+""", html)
            if not any(u.startswith(a) or a.startswith(u) for a in ALLOWED_URLS)]
    return bad


# ------------------------------------------------------------------ plugin / convention
def test_plugin_module_is_import_light():
    code = ("import sys, interlayer_meshcat.plugin as p; "
            "print(json.dumps([m for m in ('meshcat', 'umsgpack', 'interlayer_meshcat.scene') if m in sys.modules]))")
    out = subprocess.run([sys.executable, "-c", "import json; " + code], capture_output=True, text=True, check=True)
    assert json.loads(out.stdout) == []


def test_visualizer_is_registered(host):
    viz = host["visualizers"].get("meshcat").factory({})
    for method in ("plan_page", "explain_page", "live"):
        assert callable(getattr(viz, method))


def test_gripper2d_draws_itself(out_dir):
    from interlayer import api
    from interlayer.plugins import PluginHost
    from interlayer_meshcat import Scene
    from interlayer_meshcat.visualizer import drawer

    problem = api.build_problem(PluginHost(), api.resolve_config(out_dir))
    draw, frames_of = drawer(problem)
    assert draw is not None and frames_of is not None
    scene = Scene("t")
    names = draw(scene, None)
    assert {"b1", "b2", "S", "gripper"} <= set(names)
    assert {"gripper/palm", "gripper/finger_l", "gripper/finger_r", "b1/box", "b2/box", "S/area",
            "walls/wall_end", "table"} <= set(scene._info)
    traj = json.loads((out_dir / "trajectory.json").read_text())
    frames = frames_of(scene, traj)
    assert 20 < len(frames) < 1500  # subsampled
    assert [f["@step"] for f in frames][-1] == len(traj["steps"]) - 1
    # b1 ends in S (centre (-0.55, -0.55), size 0.2) and moved only while held
    x, y = frames[-1]["b1"][:2, 3]
    assert abs(x + 0.55) < 0.1 and abs(y + 0.55) < 0.1
    # while b2 is carried its pose relative to the gripper is constant
    import numpy as np

    rel = [np.linalg.inv(f["gripper"]) @ f["b2"] for f in frames if f["@step"] == 1]
    assert np.allclose(rel[0], rel[len(rel) // 3], atol=1e-9)


# --------------------------------------------------------------------------- pages
def test_plan_page_is_self_contained(pages):
    plan, _ = pages
    html = plan.read_text()
    assert plan.stat().st_size < PAGE_BUDGET
    assert external_urls(html) == []
    assert "pick(b2, init_pose, gp_b2, traj_init_pose_gp_b2)" in html  # the caption lists the plan
    assert html.count("data-interlayer-meshcat=") == 1


def test_explain_page_explains_the_replan(pages):
    _, explain = pages
    html = explain.read_text()
    assert explain.stat().st_size < PAGE_BUDGET
    assert external_urls(html) == []
    assert FACT in html
    assert re.search(r'<span class="fact">\s*' + re.escape(FACT) + r"\s*</span>", html)
    assert "Task plan #1" in html and "Task plan #2" in html
    assert 'class="tag added"' in html  # actions new in plan #2
    assert "obstructed by: <b" in html and ">b2</b>" in html
    assert "<details>" in html and "Replanned from step 0" in html
    assert "Where the time went" in html
    assert html.count("data-interlayer-meshcat=") == 2  # the solution + the failure view


def test_explain_and_viz_of_an_unsolved_run(unsolved_dir, tmp_path):
    from interlayer.cli import main

    assert main(["explain", str(unsolved_dir), "-o", str(tmp_path / "e.html")]) == 0
    html = (tmp_path / "e.html").read_text()
    assert "timeout" in html and FACT in html and "Final plan" not in html
    assert html.count("data-interlayer-meshcat=") == 1  # the failure view only
    assert main(["viz", str(unsolved_dir), "-o", str(tmp_path / "p.html")]) == 0
    assert "not solved" in (tmp_path / "p.html").read_text()


def test_missing_out_dir_is_a_user_error(tmp_path):
    from interlayer.cli import main

    assert main(["viz", str(tmp_path / "nope"), "-o", str(tmp_path / "p.html")]) == 2


# --------------------------------------------------------------------------- browser
@pytest.fixture(scope="module")
def need_chromium():
    if browser.chromium_path() is None:
        pytest.skip(browser.CHROMIUM_MISSING)


def test_pages_render_in_chromium(pages, need_chromium, tmp_path):
    plan, explain = pages
    png = browser.screenshot(plan, tmp_path / "plan.png", size=(1000, 700), budget_ms=3000)
    assert not browser.is_blank(png)
    img = browser.read_png(png)[200:, 150:850]  # the 3D view below the caption: the table is drawn
    assert browser.color_fraction(img, (237, 233, 222), tol=30) > 0.2
    png = browser.screenshot(explain, tmp_path / "explain.png", size=(1000, 1600), budget_ms=2500)
    assert not browser.is_blank(png)
    info = browser.probe_page(plan)
    assert info["errors"] == [] and [r for r in info["resources"] if not r.startswith("data:")] == []
    assert info["canvases"]


def test_the_step_list_stands_beside_the_view_and_folds(pages, need_chromium):
    """Issue 23: the step list covered the robot. It is beside the 3D view, and folding it gives the
    view the window's width."""
    plan, _ = pages
    rects = browser.evaluate(plan, """function () {
      function box(id) { var b = document.getElementById(id).getBoundingClientRect(); return [b.left, b.right, b.width]; }
      var before = [box("caption"), box("plan-view")];
      document.getElementById("fold").click();
      return before.concat([box("caption"), box("plan-view")]);
    }""", size=(1000, 700))
    caption, view, folded_caption, folded_view = rects
    assert caption[1] <= view[0] + 1 and view[2] > 550, rects          # side by side, the view the wider
    assert folded_caption[2] <= 32 and folded_view[2] > 960, rects     # folded: the view takes the width
