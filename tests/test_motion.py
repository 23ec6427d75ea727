"""Motion planners: configuration spaces, exact OMPL solutions, and GetMPErrors (obstructions)."""
import math

import numpy as np
import pytest

from interlayer.motion import ConfigSpace, MotionPlanner, MotionQuery

SE2 = ConfigSpace("se2", (-1, -1, -math.pi), (1, 1, math.pi), (False, False, True), 0.01)


def test_angles_wrap_the_short_way():
    a, b = np.array([0, 0, 3.1]), np.array([0, 0, -3.1])
    assert SE2.distance(a, b) == pytest.approx(2 * math.pi - 6.2)
    mid = SE2.interpolate(a, b, 0.5)
    assert abs(abs(mid[2]) - math.pi) < 1e-9
    dense = SE2.densify([a, np.array([0.5, 0, 3.1])])
    assert len(dense) == 51 and np.allclose(dense[-1], [0.5, 0, 3.1])


def test_densify_walks_interpolate_points_exactly():
    """The vectorised densify gives interpolate's points bit for bit, angles wrapped the short way."""
    space = ConfigSpace("vector", (-4,) * 3, (4,) * 3, (False, True, False), 0.02)
    path = [np.array([0.0, 3.0, 0.1]), np.array([0.3, -3.0, -0.2]), np.array([0.31, -2.9, -0.2])]
    dense = space.densify(path, 0.004)
    expected = [path[0]]
    for a, b in zip(path, path[1:]):
        n = math.ceil(space.distance(a, b) / 0.004)
        expected += [space.interpolate(a, b, k / n) for k in range(1, n + 1)]
    assert len(dense) == len(expected) > 50
    assert all(np.array_equal(p, q) for p, q in zip(dense, expected))
    assert max(abs(p[1]) for p in dense) <= math.pi


def wall_query(movable_wall: bool, start=(-0.5, 0, 0), goal=(0.5, 0, 0)):
    """A wall x in [-0.05, 0.05], |y| < 0.5; movable or fixed. Points are the 'robot'."""
    def in_wall(q):
        return abs(q[0]) < 0.05 and abs(q[1]) < 0.5

    return MotionQuery(
        SE2, np.array(start, float), np.array(goal, float),
        is_valid=lambda q: not in_wall(q),
        is_valid_static=lambda q: movable_wall or not in_wall(q),
        movables_at=lambda q: {"wall"} if movable_wall and in_wall(q) else set(),
    )


@pytest.mark.parametrize("name", ["interpolate", "ompl:RRTConnect", "ompl:PRM", "ompl:BITstar"])
def test_planners_go_around_or_report(host, name):
    planner = host["motion_planners"].get(name).factory({"time_limit": 0.5})
    plan = planner.plan(wall_query(movable_wall=False))
    if name == "interpolate":  # a straight line cannot go around: no movable object to blame
        assert not plan.ok and plan.obstructions == () and "ignored" in plan.reason
        return
    assert plan.ok
    for q in SE2.densify(plan.path):
        assert not (abs(q[0]) < 0.05 and abs(q[1]) < 0.5)
    assert np.allclose(plan.path[0], [-0.5, 0, 0]) and np.allclose(plan.path[-1], [0.5, 0, 0])


@pytest.mark.parametrize("yaws", [(math.pi, math.pi), (math.pi, 0.0), (-math.pi, math.pi)])
def test_ompl_takes_a_yaw_of_pi(host, yaws):
    """A base turned half round (yaw pi, as a file's quaternion gives it) is inside the space's closed
    bounds; OMPL's SO2 bounds are [-pi, pi): the adapter passes it on wrapped, and the path ends where
    the query says, to the number."""
    start, goal = (-0.5, 0, yaws[0]), (0.5, 0, yaws[1])
    plan = host["motion_planners"].get("ompl:RRTConnect").factory({"time_limit": 0.5}).plan(
        wall_query(movable_wall=False, start=start, goal=goal))
    assert plan.ok, plan.reason
    assert tuple(plan.path[0]) == start and tuple(plan.path[-1]) == goal


@pytest.mark.parametrize("name", ["interpolate", "ompl:RRTConnect"])
def test_blocked_by_a_movable_object_names_it(host, name):
    """A movable wall across the whole space: only the relaxed path exists, and it runs into 'wall'."""
    space = ConfigSpace("se2", (-1, -0.4, -math.pi), (1, 0.4, math.pi), (False, False, True), 0.01)
    q = wall_query(movable_wall=True)
    q.space = space
    plan = host["motion_planners"].get(name).factory({"time_limit": 0.3}).plan(q)
    assert not plan.ok and plan.obstructions == ("wall",) and not plan.goal_blocked


def test_ompl_vector_space(host):
    space = ConfigSpace("vector", (-1, -1, -1), (1, 1, 1), (False, False, True), 0.02)
    q = MotionQuery(space, np.zeros(3), np.array([0.9, 0.9, 3.0]), lambda q: np.linalg.norm(q[:2] - 0.4) > 0.2,
                    lambda q: True, lambda q: set())
    plan = host["motion_planners"].get("ompl:RRTConnect").factory({"time_limit": 1.0}).plan(q)
    assert plan.ok and all(np.linalg.norm(p[:2] - 0.4) > 0.2 for p in space.densify(plan.path))


def counting(planner):
    """``planner`` (a real one) counting the searches it runs."""
    planner.searches_run = 0
    search = planner._plan

    def counted(*args):
        planner.searches_run += 1
        return search(*args)

    planner._plan = counted
    return planner


def test_a_free_straight_line_is_the_answer_without_a_search(host):
    planner = counting(host["motion_planners"].get("ompl:RRTConnect").factory({"time_limit": 0.5}))
    q = wall_query(movable_wall=False, start=(-0.5, 0.7, 0), goal=(0.5, 0.7, 0))  # above the wall
    plan = planner.plan(q)
    assert plan.ok and len(plan.path) == 2 and planner.searches_run == 0
    assert planner.plan(q, straight=False).ok and planner.searches_run == 1  # asked for another path: searched


def test_a_goal_on_a_movable_object_is_its_obstruction_without_a_relaxed_search(host):
    """The movable 'box' sits on the goal, and a fixed wall cuts the straight line: the relaxed search
    would have to go around the wall; what collides with the goal obstructs every path anyway."""
    def in_wall(q):
        return abs(q[0]) < 0.05 and abs(q[1]) < 0.5

    def in_box(q):
        return abs(q[0] - 0.5) < 0.1 and abs(q[1]) < 0.1

    q = MotionQuery(SE2, np.array([-0.5, 0, 0]), np.array([0.5, 0, 0]),
                    is_valid=lambda q: not in_wall(q) and not in_box(q), is_valid_static=lambda q: not in_wall(q),
                    movables_at=lambda q: {"box"} if in_box(q) else set())
    planner = counting(host["motion_planners"].get("ompl:RRTConnect").factory({"time_limit": 0.5}))
    plan = planner.plan(q)
    assert not plan.ok and plan.obstructions == ("box",) and planner.searches_run == 0
    assert plan.goal_blocked  # from any start: TryRefine's backjumping may pass over steps that moved the robot


class FullSearchTimesOut(MotionPlanner):
    """Narrowly scoped stand-in (not a real planner): the search with movables fails as if it had run
    out of time; the relaxed one returns a path above the wall, which touches no movable object."""

    def _solve(self, query, relaxed, time_limit):
        return [query.start, (-0.5, 0.7, 0), (0.5, 0.7, 0), query.goal] if relaxed else None


def test_a_relaxed_path_clear_of_movables_is_the_answer():
    def in_box(q):  # a movable box below the fixed wall, away from the relaxed path
        return abs(q[0]) < 0.1 and abs(q[1] + 0.7) < 0.1

    fixed = wall_query(movable_wall=False)
    q = MotionQuery(SE2, fixed.start, fixed.goal, is_valid=lambda q: fixed.is_valid(q) and not in_box(q),
                    is_valid_static=fixed.is_valid, movables_at=lambda q: {"box"} if in_box(q) else set())
    plan = FullSearchTimesOut().plan(q)
    assert plan.ok and len(plan.path) == 4 and plan.obstructions == ()


def test_ompl_asks_about_each_state_once_per_query(host):
    """Rope shortcutting retries the same segments: within one query (the world does not change) each
    state's validity is computed once, and the answers are still right."""
    asked = []
    q = wall_query(movable_wall=False)
    wall_free = q.is_valid
    q.is_valid = lambda v: asked.append(tuple(v)) or wall_free(v)
    planner = host["motion_planners"].get("ompl:RRTConnect").factory({"time_limit": 0.5})
    plan = planner.plan(q, straight=False)
    assert plan.ok and all(wall_free(p) for p in SE2.densify(plan.path))
    searched = asked[2:]  # plan() itself checks the start and the goal first
    assert len(searched) > 100 and len(set(searched)) == len(searched)


def test_points_valid_settles_a_clear_block_by_its_middle_and_checks_the_rest_point_by_point():
    from interlayer.motion import WAIT, points_valid

    points = [np.array([x]) for x in np.linspace(0.0, 1.0, 21)]  # 0.05 apart
    checked = []

    def valid(q):
        checked.append(float(q[0]))
        return q[0] < 0.88

    assert points_valid(points, valid, clear=lambda q: True) and not checked  # every block certified
    assert not points_valid(points, valid) and len(checked) == 19  # no certificate: point by point to 0.9
    checked.clear()
    near = []  # clear only far (> 2 spacings) from the bad point at 0.9

    def clear(q):
        near.append(float(q[0]))
        return abs(q[0] - 0.9) > 0.1 + 1e-9

    assert not points_valid(points, valid, clear)
    assert near == pytest.approx([0.1, 0.35, 0.6, 0.85])  # block middles, until one is not clear
    assert checked == pytest.approx([0.75, 0.8, 0.85, 0.9])  # that block point by point
    checked.clear()
    assert points_valid(points[:18], valid, lambda q: abs(q[0] - 0.35) > 0.1 + 1e-9)  # 0.9 left out: valid
    assert checked == pytest.approx([0.25, 0.3, 0.35, 0.4, 0.45] + [0.5, 0.55, 0.6, 0.65, 0.7] * (WAIT > 0)
                                    + [0.75, 0.8, 0.85] * (WAIT > 1))  # the next WAIT blocks too


def test_ompl_checks_edges_a_block_at_a_time_where_the_query_certifies_them(host):
    """With ``clear_within`` (here: the point's distance to the wall), OMPL's edges are checked by the
    query's block-wise segment check instead of state by state: far fewer checks, paths still valid."""
    def gap(q):  # distance from (x, y) to the wall; the config-space distance bounds it
        dx, dy = max(abs(q[0]) - 0.05, 0.0), max(abs(q[1]) - 0.5, 0.0)
        return math.hypot(dx, dy)

    counts = {}
    for certified in (False, True):
        q = wall_query(movable_wall=False)
        wall_free, asked = q.is_valid, []
        q.is_valid = lambda v, f=wall_free, a=asked: a.append(1) or f(v)
        if certified:
            q.clear_within = lambda radius, relaxed: (lambda v: gap(v) > radius)
        plan = host["motion_planners"].get("ompl:RRTConnect").factory({"time_limit": 0.5}).plan(q, straight=False)
        assert plan.ok and all(wall_free(p) for p in SE2.densify(plan.path))
        counts[certified] = len(asked)
    assert counts[True] < 0.5 * counts[False]
