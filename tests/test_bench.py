"""`interlayer bench` and `interlayer report`: isolation (timeout, memory cap), durability (resume
after a killed sweep), the Dask executor and the report. Real runs use Gripper-2D (about 2 s each)."""
import json
import os
import signal
import sqlite3
import subprocess
import sys
import time
from pathlib import Path

import pytest

from interlayer.bench import db
from interlayer.bench.report import write_report
from interlayer.bench.runner import plan_runs, run_suite
from interlayer.bench.suite import load_suite, mark_skipped, parse_combos, parse_seeds
from interlayer.cli import main
from interlayer.errors import UserError

ROOT = Path(__file__).resolve().parent.parent
GRIPPER = ROOT / "examples" / "gripper2d.toml"


def suite_file(tmp_path, name, rows, **top):
    """A suite TOML: rows are (name, config, [overrides], extra-toml-lines)."""
    lines = [f'name = "{name}"'] + [f"{k} = {json.dumps(v)}" for k, v in top.items()]
    for row in rows:
        rname, config, sets, *extra = row
        lines += ["[[rows]]", f'name = "{rname}"', f"config = {json.dumps(str(config))}", f"set = {json.dumps(sets)}",
                  *extra]
    path = tmp_path / f"suite-{name}.toml"
    path.write_text("\n".join(lines) + "\n")
    return path


def runs(db_path):
    con = sqlite3.connect(db_path)
    con.row_factory = sqlite3.Row
    out = [dict(r) for r in con.execute("SELECT * FROM runs ORDER BY row, combo, seed")]
    con.close()
    return out


@pytest.fixture
def fault_plugin(tmp_path, monkeypatch):
    """Make tests/bench_fault_plugin.py an installed plugin for this test (and its run processes)."""
    site = tmp_path / "site"
    info = site / "interlayer_bench_faults-0.0.dist-info"
    info.mkdir(parents=True)
    (info / "METADATA").write_text("Metadata-Version: 2.1\nName: interlayer-bench-faults\nVersion: 0.0\n")
    (info / "entry_points.txt").write_text("[interlayer.plugins]\nbench-faults = bench_fault_plugin\n")
    tests = str(Path(__file__).resolve().parent)
    monkeypatch.setenv("PYTHONPATH", os.pathsep.join([str(site), tests, os.environ.get("PYTHONPATH", "")]))
    monkeypatch.syspath_prepend(tests)
    monkeypatch.syspath_prepend(str(site))
    return tmp_path


def test_seeds_and_combos_parse():
    assert parse_seeds("0-2,5") == [0, 1, 2, 5]
    assert parse_combos(["planner.task=ff,pyperplan", "planner.motion=ompl:PRM"]) == [
        ("planner.task=ff planner.motion=ompl:PRM", ["planner.task=ff", "planner.motion=ompl:PRM"]),
        ("planner.task=pyperplan planner.motion=ompl:PRM", ["planner.task=pyperplan", "planner.motion=ompl:PRM"])]
    # a --set for every run names the combination: the runs without it are not taken as done
    suite = load_suite("gripper2d", combos=["planner.task=ff,pyperplan"], overrides=["problem.obstructions=2"])
    assert [label for label, _ in suite.combos] == ["planner.task=ff problem.obstructions=2",
                                                    "planner.task=pyperplan problem.obstructions=2"]
    assert suite.combos[0][1] == ["planner.task=ff", "problem.obstructions=2"]
    assert load_suite("gripper2d", overrides=["planner.task=ff"]).combos == [("planner.task=ff", ["planner.task=ff"])]
    with pytest.raises(UserError, match="0-9"):
        parse_seeds("zero")
    with pytest.raises(UserError, match="--combo planner.task"):
        parse_combos(["planner.task"])


def test_table1_has_the_papers_rows_and_skips_missing_domains(monkeypatch, tmp_path):
    suite = load_suite("table1")
    assert [r.name for r in suite.rows] == ["Drawer (O)", "Drawer (N)", *(f"Clutter-{n}" for n in range(15, 45, 5)),
                                            "Dinner-2", "Dinner-4", "Dinner-6"]
    assert suite.time_limit == 600 and len(suite.rows[2].seeds) == 20 and len(suite.rows[0].seeds) == 10
    assert suite.rows[7].paper == {"solved": 63, "mean_time": 68}
    quick = load_suite("table1", quick=True)
    assert quick.time_limit == 60 and all(r.seeds == [0, 1] for r in quick.rows)
    # a row's domain that no plugin provides is skipped with the reason, not failed
    config = tmp_path / "other.toml"
    config.write_text('[problem]\ndomain = "no-such-domain"\n')
    path = suite_file(tmp_path, "s", [("missing", tmp_path / "nope.toml", []), ("unknown", config, []),
                                      ("ok", GRIPPER, [])])
    suite = load_suite(str(path))
    mark_skipped(suite)
    assert "nope.toml" in suite.rows[0].skipped
    assert "no-such-domain" in suite.rows[1].skipped
    assert suite.rows[2].skipped == ""


def test_hanging_run_is_killed_at_its_limit_and_recorded_as_timeout(fault_plugin):
    tmp = fault_plugin
    hang = tmp / "hang.toml"
    hang.write_text('[problem]\ndomain = "test-hang"\n')
    suite = load_suite(str(suite_file(tmp, "hang", [("hang", hang, [])], seeds="0", time_limit=1)))
    start = time.monotonic()
    summary = run_suite(suite, tmp / "r.sqlite", jobs=1, grace=2, progress=False)
    assert time.monotonic() - start < 20
    [run] = runs(tmp / "r.sqlite")
    assert summary["statuses"] == {"timeout": 1}
    assert run["status"] == "timeout" and "hard wall-clock limit of 3 s" in run["reason"]
    assert 2.5 < run["wall_time"] < 10


def test_memory_hog_is_recorded_as_killed(fault_plugin):
    tmp = fault_plugin
    hog = tmp / "hog.toml"
    hog.write_text('[problem]\ndomain = "test-hog"\n')
    suite = load_suite(str(suite_file(tmp, "hog", [("hog", hog, [])], seeds="0", time_limit=30)))
    run_suite(suite, tmp / "r.sqlite", jobs=1, memory_mb=1024, progress=False)
    [run] = runs(tmp / "r.sqlite")
    assert run["status"] == "killed" and "memory cap of 1024" in run["reason"]
    assert run["wall_time"] < 20


def _alive_with(token: str) -> list[int]:
    pids = []
    for proc in Path("/proc").iterdir():
        try:
            if proc.name.isdigit() and token in (proc / "cmdline").read_bytes().decode(errors="replace"):
                pids.append(int(proc.name))
        except OSError:
            pass
    return pids


def _some_run_finished(db_path) -> bool:
    try:
        return bool(db_path.exists() and runs(db_path))
    except sqlite3.OperationalError:  # the sweep has not created the schema yet
        return False


def test_resume_after_a_killed_sweep_keeps_finished_runs_and_redoes_the_rest(tmp_path):
    name = f"resume-sweep-{os.getpid()}"  # names this sweep's run processes (their spec holds it)
    path = suite_file(tmp_path, name, [("Gripper-2D", GRIPPER, [])], seeds="0-1", time_limit=30)
    db_path = tmp_path / "r.sqlite"
    cmd = [sys.executable, "-m", "interlayer.cli", "bench", "--suite", str(path), "--db", str(db_path), "--jobs", "1"]
    sweep = subprocess.Popen(cmd, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    deadline = time.monotonic() + 60
    while not _some_run_finished(db_path) and time.monotonic() < deadline:
        time.sleep(0.2)
    sweep.send_signal(signal.SIGKILL)  # mid-way: the second run is in progress
    sweep.wait()
    first = runs(db_path)
    assert len(first) == 1 and first[0]["status"] == "solved"
    deadline = time.monotonic() + 10  # the orphaned run notices that its coordinator is gone: it kills its group
    while _alive_with(name) and time.monotonic() < deadline:
        time.sleep(0.2)
    assert _alive_with(name) == []
    assert main(["bench", "--suite", str(path), "--db", str(db_path), "--jobs", "1", "--json"]) == 0
    after = runs(db_path)
    assert [r["seed"] for r in after] == [0, 1] and all(r["status"] == "solved" for r in after)
    kept = next(r for r in after if r["seed"] == first[0]["seed"])
    assert kept["started"] == first[0]["started"] and kept["finished"] == first[0]["finished"]
    # the same command once more does nothing
    assert run_suite(load_suite(str(path)), db_path, progress=False)["ran"] == 0


def test_two_coordinators_on_one_database_share_the_runs_and_make_none_twice(tmp_path):
    path = suite_file(tmp_path, "shared", [("Gripper-2D", GRIPPER, [])], seeds="0-3", time_limit=30)
    db_path = tmp_path / "r.sqlite"
    cmd = [sys.executable, "-m", "interlayer.cli", "bench", "--suite", str(path), "--db", str(db_path), "--jobs", "1",
           "--json"]
    both = [subprocess.Popen(cmd, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True) for _ in range(2)]
    outs = [proc.communicate(timeout=600) for proc in both]
    assert [proc.returncode for proc in both] == [0, 0], [err[-2000:] for _, err in outs]
    summaries = [json.loads(out) for out, _ in outs]
    assert sum(s["ran"] for s in summaries) == 4, summaries  # each run made once, by one of them
    assert [(r["seed"], r["status"]) for r in runs(db_path)] == [(seed, "solved") for seed in range(4)]
    with sqlite3.connect(db_path) as con:
        assert con.execute("SELECT COUNT(*) FROM claims").fetchone()[0] == 0


def test_a_running_coordinators_claim_is_left_to_it_and_a_gone_ones_retaken(tmp_path, capsys):
    path = suite_file(tmp_path, "claimed", [("Gripper-2D", GRIPPER, [])], seeds="0-2", time_limit=30)
    db_path = tmp_path / "r.sqlite"
    gone = subprocess.Popen([sys.executable, "-c", "pass"])
    gone.wait()
    # a process that waits for its input stands for a coordinator that is running seed 0
    running = subprocess.Popen([sys.executable, "-c", "import sys; sys.stdin.read()"], stdin=subprocess.PIPE)
    host, alive = db.me()[0], running.pid
    con = db.connect(db_path)
    assert db.claim(con, ("claimed", "Gripper-2D", "default", 0, 30.0), (host, alive)) is None
    assert db.claim(con, ("claimed", "Gripper-2D", "default", 1, 30.0), (host, gone.pid)) is None
    # and seed 2 by a coordinator whose pid the running process took over since (it started after the claim)
    assert db.claim(con, ("claimed", "Gripper-2D", "default", 2, 30.0), (host, alive)) is None
    with con:
        con.execute("UPDATE claims SET claimed = '2001-01-01T00:00:00+00:00' WHERE seed = 2")
    con.close()
    try:
        summary = run_suite(load_suite(str(path)), db_path, jobs=1, progress=False)
    finally:
        running.communicate(b"")
    assert summary["ran"] == 2 and summary["claimed_elsewhere"] == 1
    assert [r["seed"] for r in runs(db_path)] == [1, 2]
    assert f"1 run(s) left to the coordinator(s) that claimed them first (pid {alive} on {host})" in capsys.readouterr().err
    with sqlite3.connect(db_path) as con:  # seed 0's claim is still its coordinator's; the others ended with their runs
        assert con.execute("SELECT seed, pid FROM claims").fetchall() == [(0, alive)]


@pytest.fixture(scope="module")
def dask_db(tmp_path_factory):
    """A small sweep through a distributed.LocalCluster: Gripper-2D x two task planners x two seeds."""
    from distributed import LocalCluster

    tmp = tmp_path_factory.mktemp("dask")
    path = suite_file(tmp, "dask", [("Gripper-2D", GRIPPER, [], "paper = { solved = 100, mean_time = 10 }"),
                                    ("Drawer", tmp / "drawer.toml", [])], seeds="0-1", time_limit=30)
    db_path = tmp / "r.sqlite"
    with LocalCluster(n_workers=1, threads_per_worker=2, processes=False, protocol="tcp://",
                      dashboard_address=None) as cluster:
        address = cluster.scheduler_address.removeprefix("tcp://")
        code = main(["bench", "--suite", str(path), "--db", str(db_path), "--executor", f"dask://{address}",
                     "--combo", "planner.task=fast-downward,pyperplan", "--json"])
    assert code == 0
    return db_path


def test_dask_sweep_records_every_run(dask_db):
    rows = runs(dask_db)
    assert [(r["combo"], r["seed"]) for r in rows] == [("planner.task=fast-downward", 0), ("planner.task=fast-downward", 1),
                                                       ("planner.task=pyperplan", 0), ("planner.task=pyperplan", 1)]
    assert all(r["status"] == "solved" and r["plan_length"] == 4 and r["peak_memory_mb"] > 0 for r in rows)
    assert all("planner.task=pyperplan" in json.loads(r["overrides"]) for r in rows[2:])
    versions = json.loads(rows[0]["versions"])
    assert versions["interlayer"] and versions["python"]
    with sqlite3.connect(dask_db) as con:
        assert con.execute("PRAGMA journal_mode").fetchone()[0] == "wal"


def test_report_on_a_small_database(dask_db, tmp_path):
    out = tmp_path / "report"
    doc = tmp_path / "bench.md"
    doc.write_text("# Mine\n\nintro\n\n<!-- BENCH-REPORT BEGIN -->\nold\n<!-- BENCH-REPORT END -->\n\noutro\n")
    assert main(["report", str(dask_db), "--out", str(out), "--doc", str(doc)]) == 0
    md = (out / "report.md").read_text()
    rows = runs(dask_db)
    fd = [r["time_total"] for r in rows if r["combo"] == "planner.task=fast-downward"]
    mean = sum(fd) / 2
    line = next(x for x in md.splitlines() if x.startswith("| Gripper-2D [planner.task=fast-downward]"))
    assert line.split(" | ")[1:8] == ["2", "100", "100", f"{mean:.1f} / {mean:.1f}", "10", f"{mean / 10:.3f}", "4 / 4"]
    assert "| Drawer | 0 | skipped: No such file or folder" in md
    assert "planner combinations" in md and "histogram.png" in md and "time-split.png" in md
    for png in ("histogram.png", "time-split.png"):
        assert (out / png).read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    assert "data:image/png;base64," in (out / "report.html").read_text()
    text = doc.read_text()
    assert text.startswith("# Mine\n\nintro\n\n<!-- BENCH-REPORT BEGIN -->") and text.endswith("END -->\n\noutro\n")
    assert "\nold\n" not in text and "](report/histogram.png)" in text


def test_report_names_a_missing_database(tmp_path, capsys):
    assert main(["report", str(tmp_path / "none.sqlite"), "--out", str(tmp_path / "r")]) == 2
    assert "does not exist" in capsys.readouterr().err


def test_rows_of_one_name_in_two_suites_are_told_apart_in_the_plots():
    """The dinner suite repeats Table I's Dinner rows: the histogram and the time split name the suite
    (issue 23: the histogram showed Dinner-2/4/6 twice under the same titles)."""
    from interlayer.bench.report import _label

    groups = {("table1", "Dinner-2", "default", 120.0): [], ("dinner", "Dinner-2", "default", 120.0): [],
              ("table1", "Drawer (O)", "default", 120.0): []}
    assert _label(("dinner", "Dinner-2", "default", 120.0), groups) == "dinner: Dinner-2"
    assert _label(("table1", "Dinner-2", "default", 120.0), groups) == "table1: Dinner-2"
    assert _label(("table1", "Drawer (O)", "default", 120.0), groups) == "Drawer (O)"
    assert _label(("table1", "Dinner-2", "default", 120.0), groups, suite=False) == "Dinner-2"  # a suite's own table


def test_the_histogram_counts_the_slowest_run_of_every_row(tmp_path):
    """The last bin ends exactly at the slowest time: a row whose only run is the slowest is not drawn empty
    (with edges computed as top * i / 20 the last one fell below top for about one time in eleven)."""
    import warnings

    from interlayer.bench.report import histogram_png

    top = next(t / 1000 for t in range(1000, 100000) if (t / 1000) * 20 / 20 < t / 1000)
    runs = [{"status": "solved", "time_total": t, "suite": "s", "row": row, "combo": "c", "time_limit": 120.0}
            for row, t in (("a", 0.5), ("b", top))]
    with warnings.catch_warnings():
        warnings.simplefilter("error")  # matplotlib warns that a log axis has no positive value
        assert histogram_png(runs, tmp_path / "h.png")


def test_the_folder_suite_runs_every_file_of_the_users_folder_and_reports_each(tmp_path, capsys):
    """pbjson-folder: one row per *.json file of --problems DIR (a file the loaders refuse is 'refused',
    with check's sentence), with the work each run counted; the report gives every file not solved with its status and reason; a
    missing folder or one without JSON is one line, exit 2.
    Mutations: the rows no longer read from the folder (suite.py); UserError recorded as 'error' (worker.py)."""
    from test_pbjson import scene

    folder = tmp_path / "json"
    folder.mkdir()
    (folder / "hold.json").write_text(json.dumps(scene(goal_holding="a")))
    (folder / "notes.json").write_text('{"not": "a problem"}')
    (folder / "README.md").write_text("not a problem file")
    db_path = tmp_path / "f.sqlite"
    assert main(["bench", "--suite", "pbjson-folder", "--problems", str(folder), "--db", str(db_path),
                 "--time-limit", "60", "--jobs", "1"]) == 0
    got = {r["row"]: r for r in runs(db_path)}
    assert sorted(got) == ["hold", "notes"], got
    assert got["hold"]["status"] == "solved", got["hold"]["reason"]
    assert json.loads(got["hold"]["counts"])["refinement_attempts"] >= 1  # the work, not only the time
    assert got["notes"]["status"] == "refused" and "notes.json" in got["notes"]["reason"]
    assert main(["report", str(db_path), "--out", str(tmp_path / "report")]) == 0
    text = (tmp_path / "report" / "report.md").read_text()
    assert "2 runs: 1 refused, 1 solved." in text or "2 runs: 1 solved, 1 refused." in text
    assert "- notes [default] seed 0: refused: No installed plugin can read the problem file" in text
    capsys.readouterr()
    for problems, why in ((tmp_path / "nowhere", "does not exist"), (tmp_path / "report", "holds no *.json file")):
        assert main(["bench", "--suite", "pbjson-folder", "--problems", str(problems), "--db", str(db_path)]) == 2
        err = capsys.readouterr().err.strip()
        assert err.count("\n") == 0 and why in err, err
    assert main(["bench", "--suite", "pbjson-folder", "--db", str(db_path)]) == 2
    assert "give the folder with --problems DIR" in capsys.readouterr().err


def test_a_rows_own_time_limit_is_used_unless_the_command_line_sets_one(tmp_path):
    path = suite_file(tmp_path, "limits", [("slow", GRIPPER, [], "time_limit = 7"), ("fast", GRIPPER, [])],
                      seeds="0", time_limit=30)
    suite = load_suite(str(path))
    assert [r.time_limit for r in suite.rows] == [7, 30]
    specs = plan_runs(suite, set(), memory_mb=None, grace=None, keep_runs=None)
    assert [(s["row"], s["time_limit"]) for s in specs] == [("slow", 7), ("fast", 30)]
    assert "planner.time_limit=7" in specs[0]["overrides"]
    # a run already recorded at the row's own limit is done
    assert [s["row"] for s in plan_runs(suite, {("slow", "default", 0, 7)}, None, None, None)] == ["fast"]
    assert [r.time_limit for r in load_suite(str(path), time_limit=5).rows] == [5, 5]
    assert [r.time_limit for r in load_suite(str(path), quick=True).rows] == [60, 60]
    bad = suite_file(tmp_path, "bad", [("slow", GRIPPER, [], 'time_limit = "long"')])
    with pytest.raises(UserError, match="row 'slow'.*positive number of seconds"):
        load_suite(str(bad))


def test_a_database_written_before_the_wall_and_counts_columns_gains_them_and_keeps_its_runs(tmp_path):
    path = tmp_path / "old.sqlite"
    con = sqlite3.connect(path)
    old = db.SCHEMA.replace("    wall TEXT,", "").replace("    counts TEXT,", "")
    con.executescript(old)
    con.execute("INSERT INTO runs (suite, row, combo, seed, time_limit, config, overrides, status, reason) "
                "VALUES ('s', 'r', 'default', 0, 60, 'c.toml', '[]', 'solved', '')")
    con.commit()
    con.close()
    con = db.connect(path)
    assert {"wall", "counts"} <= {r[1] for r in con.execute("PRAGMA table_info(runs)")}
    assert [tuple(r) for r in con.execute("SELECT status FROM runs")] == [("solved",)]
