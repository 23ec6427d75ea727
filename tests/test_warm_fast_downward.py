"""Fast Downward's driver in a warm process (adapters/up/interlayer_up/warm.py, fd_worker.py): the same
answers as a new driver per call, its faults contained and reported in one sentence."""
import json
import logging
import os
import signal
import sys
import threading
import time
from pathlib import Path

import pytest

from test_task_planners import corridor

FD_ENGINES = ["fast-downward", "fast-downward-opt", "fast-downward-bjolp", "ff"]


def _driver(planner):
    """The warm driver a Fast Downward planner's calls go to (started as a run starts it)."""
    from interlayer_up.planner import _engine, _warm_driver

    with _engine(planner.engine, planner.params) as engine:
        return _warm_driver(engine)


def _driver_command(driver, folder: Path, domain: str, problem: str, alias="lama-first"):
    (folder / "domain.pddl").write_text(domain)
    (folder / "problem.pddl").write_text(problem)
    return [sys.executable, driver.script, "--plan-file", str(folder / "plan.txt"), "--alias", alias,
            str(folder / "domain.pddl"), str(folder / "problem.pddl")]


def _working_in(folder: Path) -> list:
    """Processes whose working directory is ``folder`` (Linux)."""
    found = []
    for proc in Path("/proc").iterdir():
        try:
            if proc.name.isdigit() and os.readlink(proc / "cwd") == str(folder):
                found.append(int(proc.name))
        except OSError:
            pass
    return found


def _gone(condition, wait=5.0) -> bool:
    end = time.monotonic() + wait
    while not condition():
        if time.monotonic() > end:
            return False
        time.sleep(0.05)
    return True


DOMAIN = """(define (domain walk) (:requirements :strips :typing) (:types room)
  (:predicates (at ?r - room) (link ?a ?b - room))
  (:action walk :parameters (?a ?b - room) :precondition (and (at ?a) (link ?a ?b))
   :effect (and (not (at ?a)) (at ?b))))"""
PROBLEM = """(define (problem p) (:domain walk) (:objects r0 r1 r2 - room)
  (:init (at r0) (link r0 r1) (link r1 r2)) (:goal (at r2)))"""


@pytest.mark.parametrize("name", FD_ENGINES)
def test_the_warm_process_gives_the_drivers_answers(host, name):
    model = corridor(5)
    warm = host["task_planners"].get(name).factory({})
    cold = host["task_planners"].get(name).factory({"warm": False})
    driver = _driver(warm)
    before = driver.requests
    dead = frozenset(a for a in model.init if a[0] != "At")  # the agent is nowhere: no plan
    for state in (model.init, dead):
        a, b = warm.plan(model, state, 30), cold.plan(model, state, 30)
        assert (a.status, a.plan, a.cost) == (b.status, b.plan, b.cost)
    assert a.status == "unsolvable" and len(b.plan) == 0
    assert driver.requests > before  # the warm process answered them, not a new driver


def test_the_translator_is_forked_from_the_warm_process(host, tmp_path):
    driver = _driver(host["task_planners"].get("fast-downward").factory({}))
    timed_out, (out, err), code = driver.run(_driver_command(driver, tmp_path, DOMAIN, PROBLEM), str(tmp_path), 30)
    assert (timed_out, code) == (False, 0), err
    assert "translator: forked from the warm process" in out[0]
    assert (tmp_path / "plan.txt").read_text().splitlines()[:2] == ["(walk r0 r1)", "(walk r1 r2)"]


def test_a_call_past_its_timeout_is_stopped_and_the_process_stays_warm(host):
    model = corridor(5)
    planner = host["task_planners"].get("fast-downward").factory({})
    driver = _driver(planner)
    pid = driver.proc.pid
    assert planner.plan(model, model.init, 0.001).status == "timeout"  # forking and translating take longer
    assert driver.proc.pid == pid and planner.plan(model, model.init, 30).status == "solved"


def test_a_warm_process_killed_during_a_call_is_reported_in_one_sentence(host, tmp_path):
    """The request reads its domain from a pipe nobody writes, so it runs until the process is killed."""
    driver = _driver(host["task_planners"].get("fast-downward").factory({}))
    cmd = _driver_command(driver, tmp_path, DOMAIN, PROBLEM)
    os.unlink(cmd[-2])
    os.mkfifo(cmd[-2])
    worker = driver.proc

    def kill_once_the_request_runs():
        _gone(lambda: _working_in(tmp_path), wait=30)
        worker.kill()

    threading.Thread(target=kill_once_the_request_runs, daemon=True).start()
    from interlayer_up.warm import WorkerFailed

    with pytest.raises(WorkerFailed) as failed:
        driver.run(cmd, str(tmp_path), 30)
    assert str(failed.value) == f"the warm Fast Downward process stopped unexpectedly (exit code {-signal.SIGKILL})"
    assert not driver.alive
    assert _gone(lambda: not _working_in(tmp_path))  # its request was stopped too
    driver.start()  # the next call gets a new one


def _blocked_request(host, tmp_path):
    """A new warm driver, sent a request whose translator waits forever on a pipe; (driver, child pid)."""
    from interlayer_up.warm import WarmDriver

    driver = WarmDriver(_driver(host["task_planners"].get("fast-downward").factory({})).script)
    driver.start()
    cmd = _driver_command(driver, tmp_path, DOMAIN, PROBLEM)
    os.unlink(cmd[-2])
    os.mkfifo(cmd[-2])
    driver.proc.stdin.write((json.dumps({"argv": cmd, "cwd": str(tmp_path)}) + "\n").encode())
    driver.proc.stdin.flush()
    child = driver._answer(time.monotonic() + 30)["pid"]
    assert _gone(lambda: len(_working_in(tmp_path)) == 2, wait=30)  # the driver and its translator
    return driver, child


def test_the_warm_process_stops_its_request_when_the_caller_goes_away(host, tmp_path):
    driver, child = _blocked_request(host, tmp_path)
    driver.proc.stdin.close()  # as when the caller dies
    assert driver.proc.wait(timeout=10) == 0
    assert _gone(lambda: not _working_in(tmp_path))
    driver.close()


def test_a_request_dies_with_its_warm_process(host, tmp_path):
    driver, child = _blocked_request(host, tmp_path)
    driver.proc.kill()  # no time to stop the request itself
    driver.proc.wait()
    assert _gone(lambda: not _working_in(tmp_path))
    driver.close()


def test_a_warm_process_that_cannot_start_is_reported_and_the_driver_runs_per_call(host, monkeypatch, caplog):
    from interlayer_up import warm

    model = corridor(5)
    planner = host["task_planners"].get("fast-downward").factory({})
    cold = host["task_planners"].get("fast-downward").factory({"warm": False}).plan(model, model.init, 30)
    driver = _driver(planner)
    monkeypatch.setattr(warm, "WORKER", "/nonexistent/fd_worker.py")  # the next start fails
    driver.proc.kill()
    driver.proc.wait()
    with caplog.at_level(logging.WARNING, logger="interlayer"):
        res = planner.plan(model, model.init, 30)
    assert (res.status, res.plan) == (cold.status, cold.plan)
    messages = [r.getMessage() for r in caplog.records]
    assert messages[0] == f"the warm Fast Downward process had stopped (exit code {-signal.SIGKILL}); starting a new one."
    assert messages[1].startswith("the warm Fast Downward process stopped unexpectedly (exit code 2) (")
    assert messages[1].endswith("; every Fast Downward call runs its own driver instead.") and len(messages) == 2
    assert driver.broken and _driver(planner) is None  # later calls run the driver per call, without retrying
    driver.broken = False  # other tests share the process-wide driver


def test_a_request_to_a_dead_warm_process_runs_the_driver_instead(host, monkeypatch, caplog):
    model = corridor(5)
    planner = host["task_planners"].get("fast-downward").factory({})
    cold = host["task_planners"].get("fast-downward").factory({"warm": False}).plan(model, model.init, 30)
    driver = _driver(planner)
    driver.proc.kill()
    driver.proc.wait()
    monkeypatch.setattr(driver, "start", lambda: None)  # fault injection: the request goes to the dead process
    with caplog.at_level(logging.WARNING, logger="interlayer"):
        res = planner.plan(model, model.init, 30)
    assert (res.status, res.plan) == (cold.status, cold.plan)
    assert [r.getMessage() for r in caplog.records] == [
        f"the warm Fast Downward process stopped unexpectedly (exit code {-signal.SIGKILL}); Fast Downward's own "
        "driver runs this call instead."]
    monkeypatch.undo()
    assert _driver(planner).alive  # the next call starts a new one


def test_the_dumped_pddl_is_what_fast_downward_got(host, tmp_path, monkeypatch):
    model = corridor(30)  # its initial atoms come in another order than UP's groundings
    planner = host["task_planners"].get("fast-downward").factory({})
    planner.pddl_dir = tmp_path / "pddl"
    driver = _driver(planner)
    got = []
    run = driver.run

    def reading_the_problem(cmd, cwd, timeout):
        got.append(Path(cmd[-1]).read_text())
        return run(cmd, cwd, timeout)

    monkeypatch.setattr(driver, "run", reading_the_problem)
    assert planner.plan(model, model.init, 30).status == "solved"
    assert got == [(tmp_path / "pddl" / "call-001-problem.pddl").read_text()]


def test_a_warm_option_that_is_not_a_boolean_is_a_user_error(host):
    from interlayer.errors import UserError

    with pytest.raises(UserError, match=r"^task_planner.fast-downward.warm must be true or false, got 'yes'.$"):
        host["task_planners"].get("fast-downward").factory({"warm": "yes"})
