"""``interlayer.solve`` from several threads at once (issue 22, item 8): nothing on the planning path is
process-wide (the working directory, Unified-Planning's expressions, OMPL's seed generator), so every
thread solves and gets the single-threaded run's plan and trajectory."""
import hashlib
import json
import threading

import pytest
from conftest import ROOT

# Motion budgets no query reaches: a wall-clock limit can decide a query's verdict on a loaded machine
# (issue 22, item 2, another matter); here only shared state could make a thread's run differ.
GENEROUS = {"motion_planner.time_limit": 120.0, "planner.time_limit": 600.0}


def fingerprint(result):
    from interlayer.api import _json_default

    trajectory = result.problem.geometry.trajectory_json(result.plan, result.refinement) if result.solved else None
    return (result.status, [str(step) for step in result.plan or []],
            hashlib.sha256(json.dumps(trajectory, default=_json_default).encode()).hexdigest())


def solve_at_once(sources):
    """Solve every source in its own thread, all started together: fingerprints, or the exceptions raised."""
    from interlayer import api

    out = [None] * len(sources)
    start = threading.Barrier(len(sources))

    def run(i):
        start.wait()
        try:
            out[i] = fingerprint(api.solve(sources[i], GENEROUS))
        except BaseException as exc:  # reported by the test, with the thread it ended
            out[i] = exc

    threads = [threading.Thread(target=run, args=(i,)) for i in range(len(sources))]
    for t in threads:
        t.start()
    for t in threads:
        t.join()
    return out


def check_threads_match_one(monkeypatch, sources):
    from interlayer import api

    monkeypatch.chdir(ROOT)  # relative paths: a thread that changes the working directory loses them
    alone = {source: fingerprint(api.solve(source, GENEROUS)) for source in set(sources)}
    assert all(fp[0] == "solved" for fp in alone.values()), alone
    together = solve_at_once(sources)
    for i, (source, got) in enumerate(zip(sources, together)):
        assert got == alone[source], f"thread {i} ({source}): {got!r}"


def test_four_threads_solve_gripper2d_as_one_does(monkeypatch):
    check_threads_match_one(monkeypatch, ["examples/gripper2d.toml"] * 4)


@pytest.mark.slow
def test_four_threads_solve_gripper2d_and_pr2_pick_as_one_does(monkeypatch):
    check_threads_match_one(monkeypatch, ["examples/pr2_pick.toml", "examples/gripper2d.toml"] * 2)


def test_ompl_queries_in_threads_draw_their_own_seeds(host):
    """OMPL seeds each query's RNGs from one process-wide generator: four threads planning at once,
    each state check handing the interpreter to another thread, get the paths each gets alone."""
    import time

    from test_motion import SE2, wall_query

    from interlayer.motion import MotionQuery

    def query():
        q = wall_query(movable_wall=False)

        def valid(x, check=q.is_valid):
            time.sleep(0)  # not a wait: lets another thread run here, between OMPL's seeding and its samplers
            return check(x)

        return MotionQuery(SE2, q.start, q.goal, valid, q.is_valid_static, q.movables_at)

    def paths(seed):
        planner = host["motion_planners"].get("ompl:RRTConnect").factory({"time_limit": 120.0})
        planner.seed = seed
        return [[p.tolist() for p in planner.plan(query()).path] for _ in range(5)]

    alone = [paths(seed) for seed in range(4)]
    assert len({json.dumps(p) for p in alone}) == 4  # the seeds matter
    together = [None] * 4
    start = threading.Barrier(4)

    def run(seed):
        start.wait()
        together[seed] = paths(seed)

    threads = [threading.Thread(target=run, args=(seed,)) for seed in range(4)]
    for t in threads:
        t.start()
    for t in threads:
        t.join()
    assert together == alone
