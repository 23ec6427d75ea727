"""No world-frame assumptions: a pybullet-planning scene moved rigidly (turned about z and shifted) plans
like the original; tables, surfaces and the base poses around them are taken in their own frames."""
import copy
import json
import math
from pathlib import Path
from types import SimpleNamespace

import numpy as np
import pytest
from interlayer import api

SHARED = Path(__file__).resolve().parents[2] / "shared" / "benchmarks" / "pybullet-planning-json"
needs_shared = pytest.mark.skipif(not SHARED.is_dir(), reason=f"{SHARED} (beside the checkout) is absent: "
                                  "the pybullet-planning JSON problems are not part of the project")


def _turned(node, angle, shift):
    """Move a {point, quat} node (or a [qw, qx, qy, qz, x, y, z] list) by the turn about z, then the shift."""
    c, s, h = math.cos(angle), math.sin(angle), (math.cos(angle / 2), math.sin(angle / 2))
    if isinstance(node, list):
        q, p = dict(zip("wxyz", node[:4])), dict(zip("xyz", node[4:]))
    else:
        q, p = node.get("quat", {"w": 1, "x": 0, "y": 0, "z": 0}), node.get("point", {"x": 0, "y": 0, "z": 0})
    w, x, y, z = (float(q[k]) for k in "wxyz")
    q = {"w": h[0] * w - h[1] * z, "x": h[0] * x - h[1] * y, "y": h[0] * y + h[1] * x, "z": h[0] * z + h[1] * w}
    p = {"x": c * p["x"] - s * p["y"] + shift[0], "y": s * p["x"] + c * p["y"] + shift[1], "z": p["z"]}
    return [q[k] for k in "wxyz"] + [p[k] for k in "xyz"] if isinstance(node, list) else {**node, "point": p, "quat": q}


def moved(data, angle, shift=(0.0, 0.0)):
    """The problem with every body, region, goal pose, base goal and the robot turned by ``angle`` about z,
    then shifted: the same problem in another world frame."""
    data = copy.deepcopy(data)
    data["bodies"] = [_turned(b, angle, shift) for b in data["bodies"]]
    data["robots"] = [_turned(r, angle, shift) for r in data["robots"]]
    task = data["task"]
    task["regions"] = [_turned(r, angle, shift) for r in task.get("regions") or []]
    task["goal_poses"] = {o: _turned(g, angle, shift) if isinstance(g, list) else g
                          for o, g in (task.get("goal_poses") or {}).items()}
    if isinstance(task.get("goal_config"), list):
        x, y, yaw = task["goal_config"]
        c, s = math.cos(angle), math.sin(angle)
        task["goal_config"] = [c * x - s * y + shift[0], s * x + c * y + shift[1], yaw + angle]
    return data


def test_moving_a_scene_moves_every_pose_it_holds(tmp_path):
    """The helper itself: a turned and shifted copy loads with every shape, surface and the base moved."""
    from interlayer.plugins import PluginHost
    from test_pbjson import scene

    def load(data, name):
        (tmp_path / name).write_text(json.dumps(data))
        return PluginHost().load_problem(tmp_path / name, {}, 0).geometry

    data = scene(goal_regions={"b": "goal"}, goal_poses={"a": [1, 0, 0, 0, 1.35, -0.2, 0.751]})
    a, b = load(data, "a.json"), load(moved(data, 0.7, (0.5, -0.3)), "b.json")
    c, s = math.cos(0.7), math.sin(0.7)
    W = np.array([[c, -s, 0, 0.5], [s, c, 0, -0.3], [0, 0, 1, 0], [0, 0, 0, 1.0]])
    for name, spec in a.specs.items():
        P = W @ np.array([*spec.pose[:3], 1.0])
        assert np.allclose(b.specs[name].pose[:3], P[:3]), name
    for name, surf in a.surfaces.items():
        want = [tuple((W @ np.array([x, y, 0, 1.0]))[:2]) for x, y in surf.polygon]
        assert np.allclose(sorted(b.surfaces[name].polygon), sorted(want), atol=1e-9), name
    assert np.allclose(b.layout.base[:2], (W @ np.array([*a.layout.base[:2], 0, 1.0]))[:2])
    assert math.isclose(b.layout.base[2], a.layout.base[2] + 0.7)
    assert np.allclose(b.layout.extra["goal_centres"]["a"], W @ a.layout.extra["goal_centres"]["a"])


def test_the_smallest_box_around_a_turned_rectangle_is_in_its_own_frame():
    from interlayer_pbjson.scene import oriented_box

    c, s = math.cos(0.7), math.sin(0.7)
    corners = [(2 + c * u - s * v, -1 + s * u + c * v) for u, v in ((-0.6, -0.3), (0.6, -0.3), (0.6, 0.3), (-0.6, 0.3))]
    cx, cy, yaw, hx, hy = oriented_box(corners)
    assert np.allclose((cx, cy, yaw, hx, hy), (2, -1, 0.7, 0.6, 0.3))
    # the same rectangle turned by 0.7 + 90 degrees: the same box, its axes named in [-45, 45] degrees
    turned = [(2 - (y + 1), -1 + (x - 2)) for x, y in corners]
    cx, cy, yaw, hx, hy = oriented_box(turned)
    assert np.allclose((cx, cy, yaw), (2, -1, 0.7)) and np.allclose(sorted((hx, hy)), (0.3, 0.6))


def test_put_down_spots_are_drawn_in_a_turned_region_s_own_frame():
    """A 1.0 x 0.1 m region turned by 45 degrees fills a tenth of its axis-aligned box: drawn in its own
    frame, every draw lands in it."""
    from interlayer_pbjson.scene import draw_in, inside

    c = math.sqrt(0.5)
    poly = [(1 + c * u - c * v, 2 + c * u + c * v) for u, v in ((-0.5, -0.05), (0.5, -0.05), (0.5, 0.05), (-0.5, 0.05))]
    pts = draw_in(poly, np.random.default_rng(0), 500)
    assert all(inside(poly, x, y, -1e-9) for x, y in pts)
    assert np.ptp(pts[:, 0]) > 0.6 and np.ptp(pts[:, 1]) > 0.6  # spread along its length


def _table_layout(yaw):
    """A 1.2 x 0.6 table centred at (2, -1), turned by ``yaw``, for the Clutter samplers."""
    from interlayer_manip.scene import Layout

    c, s = abs(math.cos(yaw)), abs(math.sin(yaw))
    hx, hy = c * 0.6 + s * 0.3, s * 0.6 + c * 0.3  # its axis-aligned box
    return Layout([], [], {"table": (2 - hx, 2 + hx, -1 - hy, -1 + hy)}, None, "hold", ("side",),
                  extra={"table_frame": (2.0, -1.0, yaw, 0.6, 0.3), "base_limits": ((-5.0, 9.0), (-8.0, 6.0))})


def test_base_poses_near_a_turned_table_stand_around_it_not_around_its_axis_aligned_box():
    """The base is kept 0.33 m off the table's sides in the table's own frame: beside a turned table's
    middle (inside its axis-aligned box, which the old check used) there is room."""
    from interlayer_clutter.samplers import base_near, in_frame

    yaw = 0.7
    geometry = SimpleNamespace(layout=_table_layout(yaw), robot=SimpleNamespace(mobile=True))
    frame = geometry.layout.extra["table_frame"]
    xmin, xmax, ymin, ymax = geometry.layout.regions["table"]
    rng = np.random.default_rng(0)
    # an object near the middle of the table's long side
    x, y = 2 + math.cos(yaw + math.pi / 2) * 0.25, -1 + math.sin(yaw + math.pi / 2) * 0.25
    bases = [b for b in (base_near(geometry, x, y, rng) for _ in range(200)) if b is not None]
    assert len(bases) > 100
    for bx, by, _ in bases:
        u, v = in_frame(frame, bx, by)
        assert abs(u) >= 0.6 + 0.33 or abs(v) >= 0.3 + 0.33, (bx, by)  # never under the table
    in_box = [b for b in bases if xmin - 0.33 < b[0] < xmax + 0.33 and ymin - 0.33 < b[1] < ymax + 0.33]
    assert len(in_box) > len(bases) / 2  # beside the long side, inside the axis-aligned box around it


def test_a_spot_s_distance_to_the_edge_is_taken_in_the_table_s_frame():
    from interlayer_clutter.samplers import ClutterSampler, from_frame

    world = SimpleNamespace(objects={})
    sampler = ClutterSampler(0)
    scores = []
    for yaw in (0.0, 0.7, 2.0):
        geometry = SimpleNamespace(layout=_table_layout(yaw), robot=SimpleNamespace(mobile=True))
        x, y = from_frame(geometry.layout.extra["table_frame"], 0.5, 0.1)  # 0.1 m from the short edge
        scores.append(sampler.spot_score(geometry, world, None, x, y))
    assert np.allclose(scores, scores[0])


def test_base_poses_stay_inside_a_turned_room_not_its_axis_aligned_box(tmp_path):
    """A square room turned by 0.7 rad: the corners of its axis-aligned box lie beyond the walls, where a
    base is collision-free but no drive reaches it; base poses are drawn inside the walls only."""
    from interlayer.plugins import PluginHost
    from interlayer_clutter.samplers import base_near
    from test_pbjson import _body, _box, scene

    data = scene(goal_regions={"b": "goal"})
    data["bodies"] += [_body(f"w{k}", (x, y, 0.2), [_box((sx / 2, sy / 2, 0.2))])
                       for k, (x, y, sx, sy) in enumerate([(0.6, -1.6, 4.2, 0.02), (0.6, 1.6, 4.2, 0.02),
                                                           (2.7, 0.0, 0.02, 3.2), (-1.5, 0.0, 0.02, 3.2)])]
    path = tmp_path / "room.json"
    path.write_text(json.dumps(moved(data, 0.7)))
    g = PluginHost().load_problem(path, {}, 0).geometry
    c, s = math.cos(0.7), math.sin(0.7)

    def in_room(x, y, margin):  # in the room's own frame: x from -1.5 to 2.7, y from -1.6 to 1.6
        u, v = c * x + s * y, -s * x + c * y
        return -1.5 + margin < u < 2.7 - margin and -1.6 + margin < v < 1.6 - margin

    rng = np.random.default_rng(0)
    corner = (c * 2.6 - s * 1.5, s * 2.6 + c * 1.5)  # a spot in the room's far corner: half its disk is beyond the walls
    bases = [b for b in (base_near(g, *corner, rng) for _ in range(300)) if b is not None]
    assert bases and all(in_room(x, y, 0.2) for x, y, _ in bases)  # the base's disk (0.3 m) inside the walls
    (lx, hx), (ly, hy) = g.layout.extra["base_limits"]
    beyond = [(x, y) for x, y in rng.uniform((lx, ly), (hx, hy), (2000, 2)) if not in_room(x, y, -0.05)]
    assert len(beyond) > 200 and not any(g.layout.extra["base_area"](x, y) for x, y in beyond)


def _shared_moved(tmp_path, name, angle, shift=(0.5, -0.3)):
    path = tmp_path / f"{Path(name).stem}_moved.json"
    path.write_text(json.dumps(moved(json.loads((SHARED / name).read_text()), angle, shift)))
    return path


@needs_shared
def test_a_turned_single_table_keeps_the_papers_put_down_sampler_and_its_spots_stay_on_it(tmp_path):
    """srivastava_table_r040 (the paper's scene, one table) turned by 0.7 rad: its table is still a rectangle,
    so Clutter's put-down sampler applies, and draws its spots on the turned table."""
    from interlayer.plugins import PluginHost
    from interlayer_clutter.samplers import _table_spots
    from interlayer_pbjson.scene import inside

    problem = PluginHost().load_problem(_shared_moved(tmp_path, "srivastava_table_r040.json", 0.7), {}, 0)
    g = problem.geometry
    table = g.layout.extra["clutter_table"]
    assert table == "table6"
    assert math.isclose(g.layout.extra["table_frame"][2], 0.7, abs_tol=1e-9)
    poly = g.surfaces[table].polygon
    world = g.initial_world()
    spots = [s for level in _table_spots(g, world, "object1", np.random.default_rng(0), 40) for s in level]
    assert len(spots) > 20
    m = g.specs["object1"].size[0]
    assert all(inside(poly, x, y, m) for x, y, _ in spots)


@needs_shared
@pytest.mark.parametrize("name, angle", [
    ("kitchen.json", 0.7),
    pytest.param("stacking.json", 2.0, marks=pytest.mark.slow),
    pytest.param("srivastava_table_r040.json", 0.7, marks=pytest.mark.slow),
])
def test_a_rigidly_moved_shared_file_solves_like_the_original(tmp_path, name, angle):
    """The file turned about z and shifted: solved and validated, as the original is (seed 0)."""
    result = api.solve(str(_shared_moved(tmp_path, name, angle)), ["planner.seed=0", "planner.time_limit=120"])
    assert result.status == "solved", result.reason
    api.write_outputs(result, tmp_path / "out")
    assert api.validate(tmp_path / "out") == []
