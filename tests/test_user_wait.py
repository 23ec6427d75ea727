"""What a user waits for and sees (issue 23): the shortcut reported where steps are counted, C++
library noise kept out of successful runs, the process's wall time and its parts, the status line."""
import json
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parent.parent


def cli(*args, **kw):
    proc = subprocess.run([sys.executable, "-m", "interlayer.cli", *args], capture_output=True, text=True, cwd=ROOT,
                          timeout=600, **kw)
    return proc.returncode, proc.stdout, proc.stderr


@pytest.fixture(scope="module")
def pr2_run(tmp_path_factory):
    """examples/pr2_pick.toml through the CLI: 6 steps refined, the shortcutting drops 2 base moves."""
    out = tmp_path_factory.mktemp("pr2") / "run"
    code, _, err = cli("plan", "examples/pr2_pick.toml", "--out", str(out))
    assert code == 0, err
    return out, err


def test_the_shortcut_is_reported_in_the_log_result_and_explain_page(pr2_run, tmp_path):
    out, err = pr2_run
    result = json.loads((out / "result.json").read_text())
    short = result["shortcut"]
    assert short["refined_steps"] == len(result["plan"]) + len(short["dropped"]) == 6
    assert [s["action"] for s in short["dropped"]] == ["move_base", "move_base"]
    dropped = "; ".join(f"{s['action']}({', '.join(s['args'])})" for s in short["dropped"])
    assert f"refined 6 steps, dropped 2 as not needed: {dropped}" in err
    assert result["counts"]["plan_length_before_shortcut"] == 6
    from interlayer.cli import main

    page = tmp_path / "explain.html"
    assert main(["explain", str(out), "-o", str(page)]) == 0
    html = page.read_text()
    assert "Refined 6 steps, dropped 2 as not needed" in html
    assert all(f"<code>{s['action']}({', '.join(s['args'])})</code>" in html for s in short["dropped"])


def test_a_run_without_shortcut_reports_nothing_dropped():
    from interlayer import api

    result = api.solve(str(ROOT / "examples" / "gripper2d.toml"), overrides=["planner.shortcut=false"])
    assert result.solved and result.to_json()["shortcut"] == {"refined_steps": len(result.plan), "dropped": []}
    assert not [e for e in result.trace.events if e["type"] == "shortened"]


# An OMPL query whose goal is in collision: OMPL's C++ code reports it on stderr ("Error: RRTConnect:
# Unable to sample any valid states for goal tree") while the search it is part of goes on.
OMPL_INVALID_GOAL = """
import logging, sys
import numpy as np
from interlayer.motion import ConfigSpace
from interlayer_ompl.planner import OMPLPlanner
if sys.argv[1] == "verbose":
    logging.getLogger("interlayer").setLevel(logging.INFO)  # what 'interlayer plan -v' does
space = ConfigSpace(kind="vector", lower=(0.0, 0.0), upper=(1.0, 1.0), circular=(False, False))
planner = OMPLPlanner("RRTConnect", time_limit=0.2)
planner.seed = 0
assert planner._plan(space, np.array([0.1, 0.1]), np.array([0.9, 0.9]), lambda q: bool(q[0] < 0.5), 0.2) is None
"""


def test_ompl_messages_only_in_verbose_mode():
    def stderr(mode):
        proc = subprocess.run([sys.executable, "-c", OMPL_INVALID_GOAL, mode], capture_output=True, text=True,
                              timeout=120)
        assert proc.returncode == 0, proc.stderr
        return proc.stderr

    assert "Unable to sample" not in stderr("quiet")
    assert "Unable to sample any valid states" in stderr("verbose")


def test_plan_verbose_turns_the_libraries_messages_on():
    from interlayer.cli import main

    import logging

    logger = logging.getLogger("interlayer")
    before = logger.level
    try:
        assert main(["plan", str(ROOT / "examples" / "gripper2d.toml"), "-q"]) == 0
        assert not logger.isEnabledFor(logging.INFO)
        assert main(["plan", str(ROOT / "examples" / "gripper2d.toml"), "-q", "-v"]) == 0
        assert logger.isEnabledFor(logging.INFO)
    finally:
        logger.setLevel(before)


# -- the wait after planning: trajectory timing ------------------------------------------------------

TIMING_IMPORTS = """
import sys
import numpy as np
from interlayer_optim.timing import time_parameterize
points = time_parameterize(np.array([[0.0, 0.0], [0.5, 0.1], [1.0, 0.15]]), 1.0, 2.0)
assert points[-1]["time_from_start"] > 0
print("matplotlib.figure" in sys.modules)
"""


def test_timing_does_not_load_plotting():
    """toppra imports matplotlib.pyplot for its plots (a third of its import time): not loaded for timing."""
    import os

    proc = subprocess.run([sys.executable, "-c", TIMING_IMPORTS], capture_output=True, text=True, timeout=120,
                          env={**os.environ, "INTERLAYER_CACHE_DIR": "off"})  # timed here, not read back
    assert proc.returncode == 0, proc.stderr
    assert proc.stdout.strip() == "False"


def test_timing_solves_one_topp_ra_problem_per_piece(monkeypatch):
    """A path without corners is one piece: one TOPP-RA instance, whatever its number of points."""
    import numpy as np
    import toppra.algorithm

    from interlayer_optim.timing import _pieces, time_parameterize

    made = []

    class Counted(toppra.algorithm.TOPPRA):
        def __init__(self, *args, **kw):
            made.append(1)
            super().__init__(*args, **kw)

    monkeypatch.setattr(toppra.algorithm, "TOPPRA", Counted)
    monkeypatch.setenv("INTERLAYER_CACHE_DIR", "off")
    path = np.array([[0.0, 0.0], [0.3, 0.02], [0.6, 0.05], [0.9, 0.09], [1.2, 0.14]])
    assert len(_pieces(path)) == 1
    points = time_parameterize(path, 1.0, 2.0)
    assert len(made) == 1 and len(points) == len(path)
    assert [p["positions"] for p in points] == path.tolist()


# -- the whole wait, in result.json and the bench database ---------------------------------------------

def test_result_json_records_the_whole_wait_and_its_parts(pr2_run):
    out, _ = pr2_run
    result = json.loads((out / "result.json").read_text())
    wall = result["wall"]
    assert set(wall) == {"startup", "planning", "export", "writing", "other", "total"}
    assert wall["planning"] == result["times"]["total"]
    assert abs(sum(v for k, v in wall.items() if k != "total") - wall["total"]) < 1e-3
    assert wall["startup"] > 0 and wall["export"] > 0  # the PR2's trajectory is timed (TOPP-RA) on export


PROCESS_START = """
import time
time.sleep(0.3)  # before interlayer is imported: the process's start-up must still count it
from interlayer.trace import process_start
print(time.perf_counter() - process_start())
"""


def test_the_wait_starts_when_the_process_does():
    proc = subprocess.run([sys.executable, "-c", PROCESS_START], capture_output=True, text=True, timeout=120)
    assert proc.returncode == 0, proc.stderr
    assert float(proc.stdout) >= 0.3


def test_bench_records_the_wait_and_report_shows_it_beside_planner_time(tmp_path):
    from interlayer.bench import db
    from interlayer.bench.report import write_report
    from interlayer.bench.runner import run_suite
    from interlayer.bench.suite import load_suite

    suite = tmp_path / "suite.toml"
    suite.write_text(f'name = "wait"\nseeds = "0"\ntime_limit = 60\n[[rows]]\nname = "Gripper-2D"\n'
                     f'config = {json.dumps(str(ROOT / "examples" / "gripper2d.toml"))}\n')
    path = tmp_path / "r.sqlite"
    assert run_suite(load_suite(str(suite)), path, progress=False)["statuses"] == {"solved": 1}
    con = db.connect(path, create=False)
    (run,), _ = db.load(con)
    con.close()
    wall = run["wall"]
    assert {"startup", "planning", "export", "writing", "total", "process", "validation"} <= set(wall)
    assert wall["planning"] == run["time_total"] and wall["process"] == run["wall_time"] >= wall["total"]
    write_report(path, tmp_path / "report")
    lines = (tmp_path / "report" / "report.md").read_text().splitlines()
    at = next(i for i, x in enumerate(lines) if x.startswith("| problem | ") and "process wall" in x)
    header, line = lines[at].split(" | "), lines[at + 2].split(" | ")  # the row after the separator
    assert line[0] == "| Gripper-2D"
    assert line[header.index("total")] == f"{run['time_total']:.2f}"
    assert line[header.index("start-up")] == f"{wall['startup']:.2f}"
    assert line[header.index("validation process")] == f"{wall['validation']:.2f}"


def test_an_older_bench_database_gains_the_wall_column(tmp_path):
    import sqlite3

    from interlayer.bench import db

    path = tmp_path / "old.sqlite"
    with sqlite3.connect(path) as con:
        con.executescript(db.SCHEMA.replace("    wall TEXT,", ""))
    con = db.connect(path, create=False)
    assert "wall" in {r[1] for r in con.execute("PRAGMA table_info(runs)")}
    con.close()


EXIT_AFTER = """
import atexit
from interlayer.cli import exit_after

class Finalized:
    def __del__(self):
        print("torn down", flush=True)

kept = Finalized()

def entry():
    atexit.register(lambda: print("handler ran", flush=True))
    print("done", flush=True)
    return 3

exit_after(entry)
"""


def test_the_command_exits_without_tearing_the_interpreter_down():
    """The exit code and the atexit handlers stay; the module teardown (0.2-0.5 s) goes."""
    proc = subprocess.run([sys.executable, "-c", EXIT_AFTER], capture_output=True, text=True, timeout=120)
    assert proc.returncode == 3, proc.stderr
    assert proc.stdout.split() == ["done", "handler", "ran"]


# -- progress while planning ------------------------------------------------------------------------

def _plan_on_a_terminal(*args):
    """stderr on a pseudo-terminal, as in a user's shell: (exit code, what the terminal received)."""
    import os
    import pty

    master, slave = pty.openpty()
    proc = subprocess.Popen([sys.executable, "-m", "interlayer.cli", "plan", "examples/gripper2d.toml", *args],
                            cwd=ROOT, stdin=subprocess.DEVNULL, stdout=subprocess.PIPE, stderr=slave)
    os.close(slave)
    received = b""
    while True:
        try:
            chunk = os.read(master, 65536)
        except OSError:  # EIO: the process closed the terminal
            break
        if not chunk:
            break
        received += chunk
    os.close(master)
    proc.stdout.read()
    return proc.wait(timeout=300), received.decode()


def test_on_a_terminal_one_status_line_updates_in_place():
    code, tty = _plan_on_a_terminal()
    assert code == 0, tty
    redraws = [x for x in tty.split("\r\x1b[K") if x.startswith("[")]
    assert any("task-planner calls 2, replans 1" in x and "refined prefix 4/4" in x for x in redraws)
    assert any("error-free refinement | step " in x for x in redraws)
    assert any("partial refinement" in x for x in redraws)
    assert "task plan #2 from step 0" in tty and "Solved in" in tty  # the event lines, above the status line
    last = tty.rsplit("\r\x1b[K", 1)[1]
    assert last.lstrip("\r\n").startswith("Solved in")  # cleared before the summary


def test_quiet_on_a_terminal_and_plain_lines_elsewhere():
    code, tty = _plan_on_a_terminal("-q")
    assert code == 0 and "\x1b[K" not in tty and "task plan #" not in tty and "Solved in" in tty
    code, _, err = cli("plan", "examples/gripper2d.toml")
    assert code == 0 and "\r" not in err and "\x1b" not in err and "task plan #2 from step 0" in err


# -- the live viewer: streamed, on this machine only, stopped with the run --------------------------------

def _listening(pid):
    psutil = pytest.importorskip("psutil")
    return {(c.laddr.ip, c.laddr.port) for c in psutil.Process(pid).net_connections("tcp")
            if c.status == psutil.CONN_LISTEN}


@pytest.mark.parametrize("host", ["127.0.0.1", "127.0.0.2"])
def test_viz_streams_the_search_from_a_server_on_the_named_address_only(host):
    import urllib.request

    from interlayer import api
    from interlayer.viz import live_stream

    viewer = live_stream(host=host)
    shown = []

    def watch(event):  # after the viewer has seen the event: what its live viewer shows
        if viewer.scene is not None:
            shown.append((event["type"], viewer.scene.title, viewer.scene._live_window.get_scene().count("fetch(")))

    result = api.solve(str(ROOT / "examples" / "gripper2d.toml"), listeners=[viewer, watch])
    proc = viewer.scene._live_proc
    try:
        ports = _listening(proc.pid)
        assert ports and {ip for ip, _ in ports} == {host}  # ZeroMQ and the web server: not 0.0.0.0
        assert viewer.url.startswith(f"http://{host}:")
        with urllib.request.urlopen(viewer.url, timeout=30) as page:
            assert page.status == 200
        titles = [t for _, t, _ in shown]
        assert titles[0].endswith("initial world") and "failure at step 0" in titles
        failure = next(n for kind, t, n in shown if kind == "failure")
        assert failure > 0  # the failure's world reached the server
        viewer.finish(result, wait=False)
    finally:
        viewer.close()
    assert proc.wait(timeout=30) is not None  # stopped with the run
    with pytest.raises(OSError):
        urllib.request.urlopen(viewer.url, timeout=10)


VIZ_KILLED = """
import os, signal, sys
from interlayer import api
from interlayer.viz import live_stream

viewer = live_stream()

def die(event):
    if event["type"] == "failure":
        print(viewer.scene._live_proc.pid, flush=True)
        os.kill(os.getpid(), signal.SIGKILL)  # no clean-up at all

api.solve(sys.argv[1], listeners=[viewer, die])
"""


def test_the_viewer_server_stops_when_its_run_is_killed():
    psutil = pytest.importorskip("psutil")
    proc = subprocess.run([sys.executable, "-c", VIZ_KILLED, str(ROOT / "examples" / "gripper2d.toml")],
                          capture_output=True, text=True, timeout=300)
    server = int(proc.stdout.split()[0])
    try:
        psutil.Process(server).wait(timeout=60)  # it watches its parent
    except psutil.NoSuchProcess:
        pass
    assert not psutil.pid_exists(server) or psutil.Process(server).status() == psutil.STATUS_ZOMBIE


TIMED_TWICE = """
import json, sys
import numpy as np
from interlayer_optim.timing import time_parameterize
points = time_parameterize(np.array([[0.0, 0.0], [0.5, 0.1], [1.0, 0.15], [1.0, 0.6]]), [1.0, 0.8], 2.0)
print(json.dumps({"points": points, "toppra": "toppra" in sys.modules}))
"""


def test_a_path_timed_again_comes_from_the_cache(tmp_path):
    import os

    def timed(cache):
        proc = subprocess.run([sys.executable, "-c", TIMED_TWICE], capture_output=True, text=True, timeout=120,
                              env={**os.environ, "INTERLAYER_CACHE_DIR": cache})
        assert proc.returncode == 0, proc.stderr
        return json.loads(proc.stdout)

    first, again = timed(str(tmp_path / "cache")), timed(str(tmp_path / "cache"))
    assert first["toppra"] and not again["toppra"]  # the second process needs no TOPP-RA
    assert again["points"] == first["points"]
    off = timed("off")
    assert off["toppra"] and off["points"] == first["points"] and len(list((tmp_path / "cache").rglob("*.json"))) == 1


EARLY_WORKER = """
import json, sys
from interlayer import api
from interlayer_up import planner, warm

run = api.prepare(sys.argv[1])
seen = {}
original = planner._import_up

def import_up():  # what is running when Unified-Planning starts to load
    if "unified_planning" not in sys.modules:
        seen["workers"] = [d.proc.pid for d in warm._drivers.values() if d.proc is not None]
    return original()

planner._import_up = import_up
run.task.prepare(run.model)
print(json.dumps({"before_up": seen.get("workers"), "after": [d.proc.pid for d in warm._drivers.values() if d.alive]}))
"""


def test_the_warm_fast_downward_process_starts_before_unified_planning_loads():
    proc = subprocess.run([sys.executable, "-c", EARLY_WORKER, str(ROOT / "examples" / "gripper2d.toml")],
                          capture_output=True, text=True, timeout=300, cwd=ROOT)
    assert proc.returncode == 0, proc.stderr
    data = json.loads(proc.stdout.splitlines()[-1])
    assert data["before_up"] and data["after"] == data["before_up"]  # that one process, ready


# -- start-up: plugins are discovered without importing every domain's libraries -----------------------

DISCOVERY = """
import json, sys
from interlayer.plugins import PluginHost
host = PluginHost()
heavy = ["pinocchio", "coal", "numpy", "interlayer_manip.generators", "interlayer_gripper2d.generators"]
before = [m for m in heavy if m in sys.modules]
pick = host["pose_generators"].get("pr2:pick").factory
print(json.dumps({"before": before, "after": "interlayer_manip.generators" in sys.modules, "module": pick.__module__}))
"""


def test_discovering_plugins_imports_no_domain_library():
    proc = subprocess.run([sys.executable, "-c", DISCOVERY], capture_output=True, text=True, timeout=120)
    assert proc.returncode == 0, proc.stderr
    data = json.loads(proc.stdout)
    assert data == {"before": [], "after": True, "module": "interlayer_manip.generators"}


def test_a_component_registered_by_name_that_cannot_be_imported_is_its_plugins_fault():
    from interlayer.faults import PluginFault
    from interlayer.plugins import Registry

    registry = Registry("pose_generators")
    registry.current_plugin = "my-plugin"
    registry.add("mine:pick", "my_plugin_that_is_not_there.generators:pick", "a pick")
    with pytest.raises(PluginFault) as fault:
        registry.get("mine:pick")
    assert fault.value.plugin == "my-plugin" and "mine:pick" in str(fault.value)
