"""Tests for interlayer_meshcat: self-contained animated HTML scenes.

Run: .venv/bin/python -m pytest tests/adapters -q -k meshcat
Browser tests need Debian's `chromium` (skipped otherwise).
"""

from __future__ import annotations

import importlib.metadata
import json
import math
import os
import re
import struct
import subprocess
import sys
import zlib
from html import unescape
from pathlib import Path

import numpy as np
import pytest

_HERE = Path(__file__).resolve()
for _p in (_HERE.parents[2] / "adapters" / "meshcat", _HERE.parents[1]):   # the adapter, tests/
    if str(_p) not in sys.path:
        sys.path.insert(0, str(_p))

import browser  # noqa: E402

pytest.importorskip("meshcat")

from interlayer_meshcat import Scene, add_pinocchio_robot, as_pose, as_rgba  # noqa: E402
from interlayer_meshcat.page import html_page, scene_embed, scene_iframe, write_page  # noqa: E402

ADAPTERS = Path(__file__).resolve().parents[2] / "adapters" / "meshcat"
PR2_PAGE_BUDGET = 5_000_000

# URLs that may appear in the inlined viewer JS without being fetched: XML
# namespace strings for createElementNS and the (unused) websocket template.
ALLOWED_URLS = {"http://www.w3.org/1999/xhtml", "ws://${location.host}"}


@pytest.fixture(scope="module")
def need_chromium():
    if browser.chromium_path() is None:
        pytest.skip(browser.CHROMIUM_MISSING)


def external_references(html: str) -> list[str]:
    """Network references a page could load: attributes/CSS/JS loaders that
    point at http(s)/ws(s)/protocol-relative URLs, <link>, <script src>, and
    any URL literal outside the allow-list."""
    pats = [
        r"""(?:src|href|action|poster|data|srcset|background)\s*=\s*["']?\s*(?:https?:|wss?:)?//""",
        r"""url\(\s*["']?\s*(?:https?:|wss?:)?//""",
        r"@import",
        r"<link\b",
        r"<script[^>]*\bsrc\s*=",
        r"""(?:fetch|XMLHttpRequest|WebSocket|EventSource|importScripts)\s*\(\s*["'`](?:https?|wss?):""",
    ]
    hits = []
    for p in pats:
        hits += [html[max(0, m.start() - 40):m.end() + 40] for m in re.finditer(p, html, re.I)]
    for url in re.findall(r"""(?:https?|wss?)://[^\s"'<>)`\\]*`?""", html):
        if url.rstrip("`") not in ALLOWED_URLS and url not in ALLOWED_URLS:
            hits.append(url)
    return hits


def red_mask(img):
    return (img[..., 0] > 150) & (img[..., 1] < 90) & (img[..., 2] < 90)


def blue_mask(img):
    return (img[..., 2] > 120) & (img[..., 0] < 90) & (img[..., 1] < 120)


def boxes_scene(autoplay=True) -> Scene:
    s = Scene("boxes and cylinders", grid=True)
    s.box("table", (1.2, 0.8, 0.04), [0.5, 0.0, 0.38], (0.55, 0.35, 0.2))
    s.box("block", 0.12, [0.2, 0.15, 0.46], "red")
    s.cylinder("can", 0.05, 0.2, [0.7, -0.2, 0.5], "blue")
    s.cylinder("lying", 0.03, 0.3, as_pose([0.6, 0.25, 0.43, np.sin(np.pi / 4), 0, 0, np.cos(np.pi / 4)]),
               "green")
    s.sphere("ball", 0.04, [0.9, 0.2, 0.44], "yellow")
    s.line("path", [[0.2 + 0.03 * i, 0.15, 0.55] for i in range(21)], "black")
    s.label("label", "block", [0.2, 0.15, 0.6])
    frames = [{"block": [0.2 + 0.03 * i, 0.15, 0.46]} for i in range(20)]
    s.animate(frames, fps=10, autoplay=autoplay, loop=False)
    return s


# ----------------------------------------------------------------- pure python
def test_package_import_is_light():
    code = ("import sys, interlayer_meshcat, interlayer_meshcat.page; "
            "print([m for m in ('numpy', 'meshcat', 'pinocchio', 'zmq') if m in sys.modules])")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True,
                         env={**os.environ, "PYTHONPATH": f"{ADAPTERS}{os.pathsep}{os.environ.get('PYTHONPATH', '')}"})
    assert out.stdout.strip() == "[]"


def test_pose_and_color_helpers():
    T = as_pose([1, 2, 3])
    assert np.allclose(T[:3, 3], [1, 2, 3]) and np.allclose(T[:3, :3], np.eye(3))
    R = as_pose([0, 0, 0, 0, 0, np.sin(np.pi / 4), np.cos(np.pi / 4)])  # 90 deg about z
    assert np.allclose(R[:3, :3] @ [1, 0, 0], [0, 1, 0])
    pin = pytest.importorskip("pinocchio")
    M = pin.SE3.Random()
    assert np.allclose(as_pose(M), M.homogeneous)
    assert as_rgba("#ff000080")[3] == pytest.approx(128 / 255)
    assert as_rgba(0x00FF00) == (0.0, 1.0, 0.0, 1.0)
    assert as_rgba((255, 0, 0)) == (1.0, 0.0, 0.0, 1.0)
    assert as_rgba("red")[3] == 1.0


def _set_object(scene, name):
    path = "/meshcat/" + name
    return [c for c in scene.commands() if c["type"] == "set_object" and c["path"] == path][-1]


def test_cylinder_axis_is_z():
    s = Scene()
    s.cylinder("c", 0.1, 1.0)
    obj = _set_object(s, "c")["object"]
    M = np.array(obj["object"]["matrix"]).reshape(4, 4).T  # three.js arrays are column-major
    assert obj["geometries"][0]["type"] == "CylinderGeometry"
    assert np.allclose(M[:3, :3] @ [0, 1, 0], [0, 0, 1])  # meshcat's y axis -> our z axis


def test_command_log_keeps_final_state_only():
    s = Scene()
    s.box("g/a", 0.1)
    s.box("g/b", 0.1)
    for i in range(50):
        s.set_pose("g/a", [i, 0, 0])
    tf = [c for c in s.commands() if c["type"] == "set_transform" and c["path"] == "/meshcat/g/a"]
    assert len(tf) == 1 and np.allclose(tf[0]["matrix"][12:15], [49, 0, 0])
    s.set_color("g/a", "blue")
    s.set_color("g/a", "green")
    colors = [c for c in s.commands() if c["type"] == "set_property" and c["path"] == "/meshcat/g/a"]
    assert len(colors) == 1 and colors[0]["value"][:3] == list(as_rgba("green")[:3])
    s.delete("g")
    assert not [c for c in s.commands() if c.get("path", "").startswith("/meshcat/g/")]
    assert s.bounds()[0].shape == (3,)


def _track(clip, name):
    """(times, values) of a clip's track: float32 arrays as the page carries them."""
    t = next(t for t in clip["tracks"] if t["name"] == name)
    values = np.frombuffer(t["values"].data, "<f4")
    times = np.frombuffer(t["times"].data, "<f4")
    return times, values.reshape(len(times), -1)


def test_animation_tracks_hold_unmentioned_poses():
    s = Scene()
    s.box("a", 0.1)
    s.box("b", 0.1, [5, 0, 0])
    s.box("still", 0.1, [9, 9, 9])
    frames = [{"a": [0.1 * i, 0, 0]} for i in range(20)]
    frames[10]["b"] = [5, 1, 0]                       # b jumps at frame 10 and then holds
    frames[3]["still"] = [9, 9, 9]                    # same as its static pose: no track
    s.animate(frames, fps=20)
    cmd = [c for c in s.commands() if c["type"] == "set_animation"][-1]
    by_path = {a["path"]: a["clip"] for a in cmd["animations"]}
    assert set(by_path) == {"/meshcat/a", "/meshcat/b"}
    assert all(clip["fps"] == 20 for clip in by_path.values())
    times, values = _track(by_path["/meshcat/b"], ".position")
    assert times.tolist() == [0, 9, 10, 19]           # ends of the constant runs only
    assert np.allclose(values[1], [5, 0, 0]) and np.allclose(values[2], [5, 1, 0])
    times, values = _track(by_path["/meshcat/a"], ".position")
    assert len(times) == 20 and np.allclose(values[-1], [1.9, 0, 0])
    assert cmd["options"]["loopMode"] == 2201 and cmd["options"]["repetitions"] == float("inf")


def test_animation_keyframes_within_a_tolerance():
    """With a tolerance the page keeps only the keyframes interpolation needs: a straight line is two
    keys, a turning object keeps enough keys to stay within the angle, and a corner is kept exactly."""
    s = Scene()
    s.box("line", 0.1)
    s.box("turn", 0.1)
    s.box("corner", 0.1)
    n = 200
    frames = []
    for i in range(n):
        a = math.pi * (i / (n - 1)) ** 2                # half a turn about z, speeding up
        Rz = np.eye(4)
        Rz[:2, :2] = [[math.cos(a), -math.sin(a)], [math.sin(a), math.cos(a)]]
        frames.append({"line": [0.01 * i, 0, 0], "turn": Rz,
                       "corner": [min(i, 100) * 0.01, max(0, i - 100) * 0.01, 0]})
    s.animate(frames, fps=20, tolerance=(0.002, 0.01))
    cmd = [c for c in s.commands() if c["type"] == "set_animation"][-1]
    clips = {a["path"]: a["clip"] for a in cmd["animations"]}
    assert _track(clips["/meshcat/line"], ".position")[0].tolist() == [0, n - 1]
    times, values = _track(clips["/meshcat/corner"], ".position")
    assert times.tolist() == [0, 100, n - 1] and np.allclose(values[1], [1.0, 0, 0])
    times, q = _track(clips["/meshcat/turn"], ".quaternion")
    assert 10 < len(times) < n // 2
    # replay the kept keys as three.js does (slerp) and compare with every frame's rotation
    t = np.arange(n)
    k = np.clip(np.searchsorted(times, t, side="right") - 1, 0, len(times) - 2)
    u = (t - times[k]) / (times[k + 1] - times[k])
    q0, q1 = q[k], q[k + 1]
    th = np.arccos(np.clip(np.sum(q0 * q1, axis=1), -1, 1))[:, None]
    qi = (np.sin((1 - u[:, None]) * th) * q0 + np.sin(u[:, None] * th) * q1) / np.sin(th)
    yaw = 2 * np.arctan2(qi[:, 2], qi[:, 3])
    assert np.abs(yaw - math.pi * (t / (n - 1)) ** 2).max() < 0.01
    # without a tolerance every changing frame stays
    s.animate(frames, fps=20)
    cmd = [c for c in s.commands() if c["type"] == "set_animation"][-1]
    assert len(_track({a["path"]: a["clip"] for a in cmd["animations"]}["/meshcat/line"], ".position")[0]) == n


def _erd(rel: str) -> Path:
    robots = importlib.metadata.distribution("example-robot-data").locate_file(
        "cmeel.prefix/share/example-robot-data/robots")
    return Path(robots) / rel


def test_mesh_inputs_and_decimation():
    from interlayer_meshcat.meshes import capsule_mesh, simplify_mesh

    V, F = capsule_mesh(0.05, 0.2)
    assert np.allclose(V.min(axis=0), [-0.05, -0.05, -0.15], atol=1e-6)
    assert np.allclose(V.max(axis=0), [0.05, 0.05, 0.15], atol=1e-6)
    edges = np.sort(np.concatenate([F[:, [0, 1]], F[:, [1, 2]], F[:, [2, 0]]]), axis=1)
    _, counts = np.unique(edges, axis=0, return_counts=True)
    assert (counts == 2).all()                       # closed, manifold surface

    dae = _erd("go1_description/meshes/thigh.dae")
    stl = _erd("pr2_description/meshes/base_v0/base_L.stl")
    s = Scene()
    s.mesh("dae_tri", dae, color="green")                       # coal/assimp -> float32 triangles
    s.mesh("dae_file", dae, color="blue", embed="file")         # raw Collada text
    s.mesh("stl_file", stl, scale=0.5, embed="file")            # raw STL bytes, scale in matrix
    s.mesh("dae_small", dae, max_faces=300)
    sizes = {n: len(json.dumps(_set_object(s, n), default=lambda o: "x" * len(getattr(o, "data", b""))))
             for n in ("dae_tri", "dae_file", "dae_small")}
    assert sizes["dae_small"] < sizes["dae_tri"] < sizes["dae_file"] / 3
    small = _set_object(s, "dae_small")["object"]["geometries"][0]["data"]["index"]
    assert len(small["array"].data) // 12 <= 300                # uint32 triangles
    m = np.array(_set_object(s, "stl_file")["object"]["object"]["matrix"]).reshape(4, 4).T
    assert np.allclose(np.diag(m), [0.5, 0.5, 0.5, 1])
    lo, hi = s.bounds()
    assert np.all(hi - lo < 1.0) and np.all(hi > lo)

    V = np.random.default_rng(1).normal(size=(2000, 3))
    F = np.random.default_rng(2).integers(0, 2000, size=(4000, 3))
    v2, f2 = simplify_mesh(V, F, 500)
    assert len(f2) <= 500 and f2.max() < len(v2)


def _png_bytes(img: np.ndarray) -> bytes:
    """Encode RGB uint8 with every PNG filter type (row y uses filter y % 5)."""
    h, w, c = img.shape
    bpp, raw, prev = c, bytearray(), np.zeros(w * c, np.int32)
    for y in range(h):
        cur = img[y].reshape(-1).astype(np.int32)
        left = np.concatenate([np.zeros(bpp, np.int32), cur[:-bpp]])
        upleft = np.concatenate([np.zeros(bpp, np.int32), prev[:-bpp]])
        f = y % 5
        if f == 0:
            out = cur
        elif f == 1:
            out = cur - left
        elif f == 2:
            out = cur - prev
        elif f == 3:
            out = cur - (left + prev) // 2
        else:
            p = left + prev - upleft
            pa, pb, pc = abs(p - left), abs(p - prev), abs(p - upleft)
            pred = np.where((pa <= pb) & (pa <= pc), left, np.where(pb <= pc, prev, upleft))
            out = cur - pred
        raw.append(f)
        raw += (out % 256).astype(np.uint8).tobytes()
        prev = cur

    def chunk(t, d):
        return struct.pack(">I", len(d)) + t + d + struct.pack(">I", zlib.crc32(t + d) & 0xFFFFFFFF)

    return (b"\x89PNG\r\n\x1a\n" + chunk(b"IHDR", struct.pack(">IIBBBBB", w, h, 8, 2, 0, 0, 0))
            + chunk(b"IDAT", zlib.compress(bytes(raw))) + chunk(b"IEND", b""))


def test_png_decoder_all_filters(tmp_path):
    rng = np.random.default_rng(0)
    img = rng.integers(0, 256, size=(23, 17, 3), dtype=np.uint8)
    p = tmp_path / "t.png"
    p.write_bytes(_png_bytes(img))
    assert np.array_equal(browser.read_png(p, use_pil=False), img)
    flat = np.full((20, 30, 3), 200, np.uint8)
    p.write_bytes(_png_bytes(flat))
    assert browser.is_blank(p)
    flat[5:10, 5:10] = 0
    flat[12:18, 10:28] = (255, 0, 0)
    p.write_bytes(_png_bytes(flat))
    assert not browser.is_blank(p)


# -------------------------------------------------------------- page content
def test_page_is_self_contained(tmp_path):
    s = boxes_scene()
    p = s.write_html(tmp_path / "boxes.html")
    html = p.read_text(encoding="utf-8")
    assert html.startswith("<!DOCTYPE html>")
    assert external_references(html) == []
    assert html.count("<script") == 3 and "MeshCat.Viewer" in html
    assert 800_000 < p.stat().st_size < 1_000_000
    # the inline viewer JS must not terminate its <script> early
    assert html.lower().count("</script") == 3


def test_html_page_helpers():
    s = Scene("tiny")
    s.box("b", 0.2, None, "red")
    embed = scene_embed(s, 320, 200, element_id="v1")
    frame = scene_iframe(s, 320, 200)
    page = html_page('Run <1> & "2"', "<h1>x</h1>" + embed + frame, extra_css="h1{color:red}")
    assert "<title>Run &lt;1&gt; &amp; &quot;2&quot;</title>" in page
    marker = "For license information please see main.min.js.LICENSE.txt"
    assert page.count(marker) == 2                    # <head> copy + the iframe's own page
    # viewer JS appears once in <head> and once (escaped) inside the srcdoc
    head = page.split("</head>")[0]
    assert "InterlayerMeshcat" in head and "mountLazy(\"v1\"" in page
    m = re.search(r'srcdoc="([^"]*)"', page)
    assert m and "&lt;!DOCTYPE html&gt;" in m.group(1) and "&quot;" in m.group(1)
    assert external_references(unescape(page)) == []     # also checks the srcdoc'd page
    assert html_page("plain", "<p>no 3d</p>").count("<script") == 0


# ------------------------------------------------------------------ rendering
def test_boxes_page_renders_and_animates(tmp_path, need_chromium):
    p = boxes_scene(autoplay=True).write_html(tmp_path / "boxes.html")
    # the frames at 0.3 s and 1.5 s (3/4 of the way), set by the test: no race with the page's clock
    early = browser.screenshot(browser.paused_at(p, 0.3, tmp_path / "early.html"), tmp_path / "early.png")
    late = browser.screenshot(browser.paused_at(p, 1.5, tmp_path / "late.html"), tmp_path / "late.png")
    for png in (early, late):
        assert not browser.is_blank(png)
        img = browser.read_png(png)
        assert red_mask(img).mean() > 0.003, "red block not visible"
        assert blue_mask(img).mean() > 0.002, "blue cylinder not visible"
    xs = [np.nonzero(red_mask(browser.read_png(png)))[1].mean() for png in (early, late)]
    assert abs(xs[1] - xs[0]) > 20, f"animation did not move the block: {xs}"
    probe = browser.probe_page(p)
    assert probe["errors"] == [] and probe["canvases"]
    assert [u for u in probe["resources"] if not u.startswith(("data:", "blob:", "file:"))] == []


def _pr2():
    pin = pytest.importorskip("pinocchio")
    robots = importlib.metadata.distribution("example-robot-data").locate_file(
        "cmeel.prefix/share/example-robot-data/robots")
    urdf = robots / "pr2_description" / "urdf" / "pr2.urdf"
    model, collision, visual = pin.buildModelsFromUrdf(
        str(urdf), package_dirs=[str(robots.parent.parent)], root_joint=pin.JointModelPlanar())
    return pin, model, collision, visual


def _pr2_motion(pin, model, n=20):
    q0 = pin.neutral(model)
    qs = []
    for i in range(n):
        q = q0.copy()
        q[0] = 0.03 * i                                               # planar base x
        for jn, v in (("torso_lift_joint", 0.015 * i), ("l_shoulder_pan_joint", 0.06 * i),
                      ("r_elbow_flex_joint", -0.05 * i)):
            q[model.joints[model.getJointId(jn)].idx_q] = v
        qs.append(q)
    return qs


def test_pr2_page(tmp_path, need_chromium):
    pin, model, collision, _ = _pr2()
    s = Scene("PR2")
    robot = add_pinocchio_robot(s, "pr2", model, collision)
    assert sum(n is not None for n in robot.names) == len(collision.geometryObjects)
    qs = _pr2_motion(pin, model)
    frame = robot.robot_frame(qs[5])
    assert set(frame) == {n for n in robot.names if n}
    robot.animate(qs, fps=10, autoplay=False)
    page = s.write_html(tmp_path / "pr2.html")
    size = page.stat().st_size
    assert size < PR2_PAGE_BUDGET, f"PR2 page is {size} bytes"
    assert external_references(page.read_text(encoding="utf-8")) == []

    empty = Scene("empty")
    empty.camera(*s.camera_or_auto())
    empty_page = empty.write_html(tmp_path / "empty.html")
    shot = browser.screenshot(page, tmp_path / "pr2.png")
    empty_shot = browser.screenshot(empty_page, tmp_path / "empty.png")
    assert not browser.is_blank(shot)
    changed = browser.diff_fraction(shot, empty_shot)
    assert changed > 0.03, f"robot covers only {changed:.2%} of the view"


def test_embedded_views_render(tmp_path, need_chromium):
    a = boxes_scene(autoplay=False)
    b = Scene("cyl")
    b.cylinder("c", 0.1, 0.4, [0, 0, 0.2], "blue")
    body = ("<h1>Timeline</h1>" + scene_embed(a, 360, 270, lazy=False) + scene_embed(b, 360, 270)
            + scene_iframe(b, 360, 270, lazy=False))
    p = write_page(tmp_path / "report.html", html_page("report", body, "body{margin:0} h1{margin:0;height:40px}"))
    shot = browser.read_png(browser.screenshot(p, tmp_path / "report.png", size=(1200, 400)))
    # three views side by side below a 40 px heading (inline-block + borders)
    views = [shot[60:300, x0:x0 + 340] for x0 in (10, 380, 745)]
    assert red_mask(views[0]).mean() > 0.003
    assert blue_mask(views[1]).mean() > 0.02
    assert blue_mask(views[2]).mean() > 0.02


def test_crowded_labels_do_not_overlap(tmp_path, need_chromium):
    """40 labelled cans packed on a table: every label is on the page, the tags shown in full do not
    overlap (the rest are dots with the name on hover), and the high-priority one is shown in full."""
    s = Scene("crowded")
    s.box("table", (0.8, 0.8, 0.05), [0, 0, -0.03], "brown")
    for i in range(40):
        x, y = -0.3 + 0.1 * (i % 7), -0.3 + 0.1 * (i // 7)
        s.cylinder(f"o{i}/shape", 0.03, 0.12, None, "blue")
        s.label(f"o{i}/label", f"object{i}", [0, 0, 0.09], priority=2 if i == 23 else 0)
        s.set_pose(f"o{i}", [x, y, 0.06])
    page = s.write_html(tmp_path / "crowded.html")
    boxes = browser.evaluate(page, """function () {
      return Array.prototype.map.call(document.querySelectorAll(".il-label"), function (e) {
        var b = e.getBoundingClientRect();
        return [e.textContent, e.classList.contains("il-dot"), b.left, b.top, b.right, b.bottom, e.style.display];
      });
    }""")
    assert sorted(b[0] for b in boxes) == sorted(f"object{i}" for i in range(40))
    shown = [b for b in boxes if not b[1] and b[6] != "none"]
    dots = [b for b in boxes if b[1]]
    assert len(shown) >= 8 and dots, (len(shown), len(dots))
    assert "object23" in [b[0] for b in shown]
    for i, a in enumerate(shown):
        for b in shown[i + 1:]:
            assert not (a[2] < b[4] and b[2] < a[4] and a[3] < b[5] and b[3] < a[5]), (a, b)


def test_live_viewer_loopback(tmp_path, capfd):
    """live(): meshcat server on 127.0.0.1, nothing on stdout, URL on stderr
    (plus a screenshot of the live viewer when chromium is installed)."""
    s = Scene("live")
    s.box("b", 0.3, [0, 0, 0.15], "red")
    try:
        url = s.live()
        assert url.startswith("http://127.0.0.1:")
        s.cylinder("c", 0.05, 0.3, [0.4, 0, 0.15], "blue")      # forwarded after going live
        html = s._live_window.get_scene()
        assert html.count("handle_command_bytearray") >= 4
        if browser.chromium_path() is not None:
            shot = browser.screenshot(url, tmp_path / "live.png")
            assert red_mask(browser.read_png(shot)).mean() > 0.01
    finally:
        s.close()
    out, err = capfd.readouterr()
    assert out == ""
    assert url in err
