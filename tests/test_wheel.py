"""The README's tour from a built wheel: examples and benchmark suites ship inside the package.

The slow test builds the wheel, installs it with its dependencies into a fresh virtual environment
(through pip, as a user would) and runs the README's plan command and a quick bench suite in a
folder outside the checkout. .ci/run runs it as a step of its own."""
import json
import os
import sqlite3
import subprocess
import sys
import zipfile
from pathlib import Path

import pytest

from interlayer import api, shipped
from interlayer.bench.suite import find_suite
from interlayer.errors import UserError

ROOT = Path(__file__).resolve().parents[1]


def test_shipped_names_resolve_to_the_examples_and_suites(tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)  # no examples/ or benchmarks/ here
    example = ROOT / "examples" / "gripper2d.toml"
    for name in ("gripper2d", "gripper2d.toml", "examples/gripper2d.toml"):
        assert api.resolve_config(name) == api.resolve_config(example)
    assert find_suite("gripper2d").read_text() == (ROOT / "benchmarks" / "gripper2d.toml").read_text()
    assert shipped.names("examples") == sorted(p.stem for p in (ROOT / "examples").glob("*.toml"))
    with pytest.raises(UserError, match="No such file or folder: nope; the shipped examples are clutter, dinner"):
        api.resolve_config("nope")
    with pytest.raises(UserError, match=r"No such file or folder: elsewhere/gripper2d.toml\.$"):
        api.resolve_config("elsewhere/gripper2d.toml")  # a path elsewhere is not a shipped name


def test_a_plugin_distributions_examples_and_suites_are_found_in_its_package(tmp_path, monkeypatch):
    """An installed plugin package's examples/ and benchmarks/ (package data) are shipped names, from any folder."""
    import importlib

    site = tmp_path / "site"
    package = site / "il_shelf_data"
    for kind, text in (("examples", "[problem]\ndomain = \"gripper2d\"\n"), ("benchmarks", "name = \"il-suite\"\n")):
        (package / kind).mkdir(parents=True)
        (package / kind / f"il_{kind}.toml").write_text(text)
    (package / "__init__.py").write_text("")
    (site / "il_shelf_data-0.1.dist-info").mkdir()
    (site / "il_shelf_data-0.1.dist-info" / "METADATA").write_text("Metadata-Version: 2.1\nName: il-shelf-data\nVersion: 0.1\n")
    (site / "il_shelf_data-0.1.dist-info" / "entry_points.txt").write_text("[interlayer.plugins]\nil_shelf_data = il_shelf_data\n")
    monkeypatch.syspath_prepend(str(site))
    importlib.invalidate_caches()
    monkeypatch.chdir(tmp_path)
    assert shipped.find("examples", "il_examples") == package / "examples" / "il_examples.toml"
    assert "il_examples" in shipped.names("examples") and "gripper2d" in shipped.names("examples")
    assert api.resolve_config("examples/il_examples.toml")["problem"]["domain"] == "gripper2d"
    assert find_suite("il_benchmarks") == package / "benchmarks" / "il_benchmarks.toml"


def _run(args, **kw):
    proc = subprocess.run(args, capture_output=True, text=True, **kw)
    assert proc.returncode == 0, f"{' '.join(map(str, args))} exited {proc.returncode}:\n{proc.stderr[-3000:]}"
    return proc


@pytest.mark.slow
def test_the_wheel_carries_the_tour(tmp_path):
    dist, venv, user = tmp_path / "dist", tmp_path / "venv", tmp_path / "user"
    user.mkdir()
    _run([sys.executable, "-m", "pip", "wheel", "--no-deps", "-q", "-w", str(dist), str(ROOT)])
    wheel = next(dist.glob("interlayer-*.whl"))
    names = zipfile.ZipFile(wheel).namelist()
    assert "interlayer/examples/gripper2d.toml" in names and "interlayer/benchmarks/gripper2d.toml" in names
    _run([sys.executable, "-m", "venv", str(venv)])
    _run([str(venv / "bin" / "pip"), "install", "-q", str(wheel)])
    env = {k: v for k, v in os.environ.items() if k != "PYTHONPATH"}  # nothing from the checkout
    run = lambda *args: _run([str(venv / "bin" / "interlayer"), *args], cwd=user, env=env)  # noqa: E731
    where = _run([str(venv / "bin" / "python"), "-c", "import interlayer; print(interlayer.__file__)"], cwd=user, env=env)
    assert where.stdout.strip().startswith(str(venv))
    assert run("--version").stdout.strip() == f"interlayer {_version()}"
    run("plan", "examples/gripper2d.toml", "-q", "--out", "g")  # the README's first command, no examples/ here
    assert json.loads((user / "g" / "result.json").read_text())["status"] == "solved"
    run("plan", "pr2_pick", "-q", "--out", "pr2")
    assert json.loads((user / "pr2" / "result.json").read_text())["status"] == "solved"
    summary = json.loads(run("bench", "--suite", "gripper2d", "--quick", "--db", "g.sqlite", "--json").stdout)
    assert summary["statuses"] == {"solved": 4}
    with sqlite3.connect(user / "g.sqlite") as db:
        assert db.execute("select count(*) from runs where status = 'solved'").fetchone() == (4,)


def _version():
    from interlayer import __version__

    return __version__


def test_an_installed_copy_records_no_commit_of_a_repository_around_it(tmp_path):
    """A package installed inside some other git repository (a venv in a project) is no checkout of ours."""
    import shutil

    git = ["git", "-c", "user.name=t", "-c", "user.email=t@t", "-C", str(tmp_path)]
    _run([*git[:5], "init", "-q", str(tmp_path)])
    _run([*git, "commit", "-q", "--allow-empty", "-m", "theirs"])
    site = tmp_path / "venv" / "lib" / "python3" / "site-packages"
    shutil.copytree(ROOT / "core" / "interlayer", site / "interlayer", ignore=shutil.ignore_patterns("__pycache__"))
    env = {k: v for k, v in os.environ.items() if k != "PYTHONPATH"}
    env["PYTHONPATH"] = str(site)
    code = "from interlayer.bench.worker import _git_commit; print(repr(_git_commit()))"
    assert _run([sys.executable, "-c", code], env=env, cwd=tmp_path).stdout.strip() == "''"
    if (ROOT / ".git").exists():  # from the checkout: its own commit
        assert _run([sys.executable, "-c", code], cwd=ROOT).stdout.strip() != "''"
