"""The core's own task planner, bfs: breadth-first search with no library (an install of the core alone
solves small domains), bounded by a count of expanded states."""
import pytest

from interlayer import api
from interlayer.abstraction import abstract
from interlayer.domain import ActionSpec, DomainSpec, Problem
from interlayer.errors import UserError
from interlayer.planning import check_plan

SPEC = DomainSpec(
    name="rooms", types={"room": None}, continuous_types=(),
    predicates={"At": ("room",), "Link": ("room", "room")},
    skolems=(),
    actions=(ActionSpec("walk", (("?a", "room"), ("?b", "room")), "(and (At ?a) (Link ?a ?b))", "(and (not (At ?a)) (At ?b))"),),
)


def corridor(n=5, links=None):
    rooms = [f"r{i}" for i in range(n)]
    links = frozenset(("Link", a, b) for a, b in (links if links is not None else zip(rooms, rooms[1:])))
    return abstract(Problem(SPEC, {r: "room" for r in rooms}, links | {("At", "r0")}, f"(At r{n - 1})", None, {}))


def bfs(host, **options):
    return host["task_planners"].get("bfs").factory(options)


def test_bfs_finds_the_shortest_plan(host):
    model = corridor(5, links=[("r0", "r1"), ("r1", "r2"), ("r2", "r3"), ("r3", "r4"), ("r0", "r3")])
    res = bfs(host).plan(model, model.init, 30)
    assert res.status == "solved" and check_plan(model, model.init, res.plan) == ""
    assert [s.args for s in res.plan] == [("r0", "r3"), ("r3", "r4")]  # the shortcut, not the corridor


def test_bfs_proves_unsolvable_and_stops_at_its_budget(host):
    model = corridor(4, links=[("r0", "r1"), ("r1", "r0"), ("r2", "r3")])
    res = bfs(host).plan(model, model.init, 30)
    assert res.status == "unsolvable" and "all 2 reachable states" in res.reason
    res = bfs(host, max_states=2).plan(corridor(6), corridor(6).init, 30)
    assert res.status == "incomplete" and "max_states = 2" in res.reason
    with pytest.raises(UserError, match=r"\[task_planner.bfs\] takes max_states, a positive whole number"):
        bfs(host, max_states=0)


def test_the_core_alone_solves_gripper2d_learning_the_obstruction(gripper_example):
    """What a core-only install runs: bfs and the interpolating planner (the refinement learns the
    obstruction, the replan moves b2 first)."""
    result = api.solve(gripper_example, {"planner.task": "bfs", "planner.motion": "interpolate"})
    assert result.status == "solved", result.reason
    assert [(s.action, s.args[0]) for s in result.plan] == [("pick", "b2"), ("place", "b2"), ("pick", "b1"), ("place", "b1")]
